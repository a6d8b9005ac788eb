//! # openrt-core
//!
//! The OpenRT-style API of OpenRT-rs and the two-level method of Wald,
//! Benthin & Slusallek ("A Flexible and Scalable Rendering Engine for
//! Interactive 3D Graphics", 2002; "Distributed Interactive Ray Tracing of
//! Dynamic Scenes", IEEE PVG 2003):
//! - objects are defined like OpenGL display lists (begin/end object,
//!   primitives, vertices under a matrix stack) and instanced with a transform;
//! - at [`Context::commit`] each object pays only for what changed: static and
//!   affinely moving objects keep their SAH kd-tree, redefined objects
//!   (unstructured motion) are rebuilt with the fast builder, and the
//!   top-level BSP over instance boxes is rebuilt every frame;
//! - [`Scene`] traces rays through both levels, transforming rays into object
//!   space.
//!
//! ```
//! use glam::{Mat4, Vec3};
//! use openrt_accel::Ray;
//! use openrt_core::{Context, PrimitiveKind};
//!
//! let mut ctx = Context::new();
//! // Object 1: a unit quad, built from a triangle strip.
//! let quad = ctx.gen_object();
//! ctx.begin_object(quad)?;
//! ctx.begin(PrimitiveKind::TriangleStrip)?;
//! for (x, y) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
//!     ctx.vertex(Vec3::new(x, y, 0.0))?;
//! }
//! ctx.end()?;
//! ctx.end_object()?;
//! // Object 2: a big floor triangle, placed once.
//! let floor = ctx.gen_object();
//! ctx.begin_object(floor)?;
//! ctx.begin(PrimitiveKind::Triangles)?;
//! for p in [Vec3::new(-10.0, -10.0, -1.0), Vec3::new(10.0, -10.0, -1.0), Vec3::new(0.0, 10.0, -1.0)] {
//!     ctx.vertex(p)?;
//! }
//! ctx.end()?;
//! ctx.end_object()?;
//! ctx.instantiate(floor)?;
//! // Three instances of the quad.
//! let mut quads = Vec::new();
//! for i in 0..3 {
//!     ctx.push_matrix()?;
//!     ctx.translate(Vec3::new(2.0 * i as f32, 0.0, 0.0))?;
//!     quads.push(ctx.instantiate(quad)?);
//!     ctx.pop_matrix()?;
//! }
//! // Animate: move the instances (affine motion) and render a few frames.
//! for frame in 0..3 {
//!     for (i, &q) in quads.iter().enumerate() {
//!         let m = Mat4::from_translation(Vec3::new(2.0 * i as f32, 0.5 * frame as f32, 0.0));
//!         ctx.set_instance_transform(q, m)?;
//!     }
//!     let stats = ctx.commit()?;
//!     assert_eq!(stats.instances, 4);
//!     // "Render": a small depth image seen from +z.
//!     let scene = ctx.scene();
//!     let mut covered = 0;
//!     for y in 0..24 {
//!         for x in 0..32 {
//!             let o = Vec3::new(-2.0 + x as f32 * 0.25, -2.0 + y as f32 * 0.25, 5.0);
//!             if let Some(hit) = scene.intersect(&Ray::infinite(o, -Vec3::Z)) {
//!                 covered += usize::from(hit.t < 5.5);
//!             }
//!         }
//!     }
//!     assert!(covered > 0, "the quads are visible in front of the floor");
//! }
//! # Ok::<(), openrt_core::CoreError>(())
//! ```

mod camera;
mod changes;
mod commit;
mod context;
#[cfg(feature = "embree")]
mod embree_backend;
mod error;
mod highlight;
mod ids;
mod image_file;
mod instance;
mod light;
mod light_loop;
mod light_quad;
mod limits;
mod material;
mod matrix_stack;
mod object;
mod occluder_hint;
mod phases;
mod pool;
mod primitive;
mod render;
mod scene;
mod shade;
mod shading_record;
mod simd;
mod surface_lanes;
mod texture;
mod top_level;
mod tracer;

pub use camera::Camera;
pub use changes::{ChangeSet, InstanceChange, MAX_SLOT_GROWTH, MaterialData, MeshData, ObjectChange, TextureData};
pub use commit::{BuildRecord, CommitStats, MAX_PROMOTIONS_IN_FLIGHT};
pub use context::{Context, VertexArrays};
#[cfg(feature = "embree")]
pub use embree_backend::EmbreeScene;
pub use error::CoreError;
pub use ids::{InstanceId, MaterialId, ObjectId, TextureId};
#[cfg(unix)]
pub use image_file::FINISHED_MODE;
pub use image_file::write_atomically;
pub use instance::{InstanceRecord, MIN_TRANSFORM_CONDITIONING};
pub use light::{Environment, PointLight};
pub use limits::{
    MAX_COORDINATE, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE, MAX_SHADE_DEPTH, MAX_SPP, MAX_THREADS, RENDER_STACK_BYTES,
    check_depth, check_image_size, check_spp, check_threads,
};
pub use material::Material;
pub use matrix_stack::{MATRIX_STACK_LIMIT, MatrixStack};
pub use object::{Accel, ObjectGeometry, ObjectMesh, ObjectTree, ShadingData};
pub use phases::PhaseTimes;
pub use pool::ThreadPool;
pub use primitive::PrimitiveKind;
pub use render::{
    Backend, FrameStats, Image, RenderSettings, RenderedTile, Renderer, TILE, assemble, assemble_into, tile_count,
};
pub use scene::{GLOBAL_AREA_SHARE, MAX_GLOBAL_INSTANCES, Scene, SceneHit, Surface};
pub use shade::{MIN_RAY_WEIGHT, RayCounts, RenderMode};
pub use texture::{Texture, TextureFilter, TextureWrap};
pub use top_level::{TOP_LEVEL_BVH_MIN, TopLevel};

/// What a program using the API needs, in one import:
/// `use openrt_core::prelude::*;` (with `glam`'s vector and matrix types and
/// the acceleration layer's [`Ray`](openrt_accel::Ray) for ray queries).
pub mod prelude {
    pub use crate::{
        Accel, Backend, Camera, Context, CoreError, Environment, Image, InstanceId, Material, MaterialId, ObjectId,
        PointLight, PrimitiveKind, RenderMode, RenderSettings, Renderer, Scene, SceneHit, Surface, Texture,
        TextureFilter, TextureId, TextureWrap, VertexArrays,
    };
    pub use glam::{Mat4, Vec2, Vec3};
    pub use openrt_accel::Ray;
}

/// The renderer's building blocks, public for the tools and tests that
/// measure or replay them (the bench, the ray-query probe, the backend
/// tests) and not needed to use the API: the shading offsets, the last
/// occluder of each light, a frame's pixel blocks and sample positions.
pub mod kernels {
    pub use crate::camera::CameraRays;
    pub use crate::occluder_hint::{HINT_MARGIN, HINT_MAX_REST, OccluderHint};
    pub use crate::render::{packet_block, sample_offset};
    pub use crate::shade::{OFFSET_ULPS, first_hit_shadow_ray, offset_ray_origin};
}
