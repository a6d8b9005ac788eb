//! # openrt-scene
//!
//! Scene formats for OpenRT-rs, all driving the `openrt-core` API:
//! - a versioned RON format ([`load_ron`], reference in `docs/SCENE-FORMAT.md`);
//! - BART's AFF format ([`aff`]): reader, keyframe animation, player;
//! - texture files (PPM and PNG) through the `image` crate;
//! - the built-in default scene ([`default_scene`]).
//!
//! ```
//! let scene = openrt_scene::default_scene().unwrap();
//! assert!(scene.ctx.scene().instances().len() > 3);
//! ```

pub mod aff;
mod builtin;
mod error;
pub mod generate;
mod gltf_scene;
mod limits;
mod loader;
mod obj;
mod player;
mod ron_format;
mod shapes;
mod texture_io;

pub use builtin::{DEFAULT_SCENE_RON, default_scene};
pub use error::{SceneError, SceneWarning};
pub use gltf_scene::{
    DeformTimes, GLTF_DEFORMING_ACCEL, GLTF_FRAME_RATE, GLTF_MAX_INFLUENCES, GLTF_SUPPORTED_REQUIRED, GltfAnimation,
    GltfOptions, GltfPlayer, MAX_FIGURE_TRIANGLES, MotionClasses, skinned_figure_glb,
};
pub use limits::{
    MAX_ANIMART_TRIANGLES, MAX_BLOCK_NESTING, MAX_FILE_BYTES, MAX_FRAMES, MAX_HEADER_COUNT, MAX_INCLUDE_DEPTH,
    MAX_INCLUDES, MAX_SCENE_TRIANGLES, MAX_SPHERE_SEGMENTS, MAX_TERRAIN_GRID, MAX_TEXTURE_SIDE, MAX_TEXTURE_TEXELS,
    MAX_TREE_TRIANGLES, MAX_TREES,
};
pub use loader::{LoadedScene, RonScene, load_ron, load_ron_any, load_ron_str};
pub use obj::parse_obj;
pub use player::ScenePlayer;
pub use ron_format::{
    AnimationDesc, BartDesc, CameraDesc, CameraKeys, GeneratorDesc, InstanceDesc, InstanceKeys, LightDesc,
    MaterialDesc, ObjectDesc, SUPPORTED_VERSIONS, SceneFile, TransformOp,
};
pub use shapes::{emit_box, emit_sphere};
pub use texture_io::{decode_texture, load_texture};
