//! # openrt-accel
//!
//! The kernels of OpenRT-rs: rays, boxes, the watertight ray/triangle test,
//! object kd-trees built with the full SAH, and iterative front-to-back
//! traversal (closest hit and any hit). It knows nothing of scenes, objects
//! or shading; the two-level layer in `openrt-core` sits on top of it.
//! Leaves test their triangles four at a time (SIMD edge functions, then the
//! exact scalar test for the few that pass), with results bit-identical to
//! one scalar test per triangle.
//!
//! Papers behind it:
//! - Woop, Benthin & Wald, *Watertight Ray/Triangle Intersection*, JCGT 2013.
//! - Wald & Havran, *On building fast kd-trees for ray tracing, and on doing
//!   that in O(N log N)*, IEEE RT 2006.
//! - Hunt, Mark & Stoll, *Fast kd-tree construction with an adaptive
//!   error-bounded heuristic*, IEEE RT 2006 (binned SAH of the default builder).
//! - Wald, Benthin & Slusallek, *A Flexible and Scalable Rendering Engine for
//!   Interactive 3D Graphics* / *Distributed Interactive Ray Tracing of
//!   Dynamic Scenes* (2002/2003), for the two-level method this crate serves.
//!
//! ```
//! use glam::Vec3;
//! use openrt_accel::{KdTree, Ray, meshgen};
//!
//! let tree = KdTree::build_sah(meshgen::bumpy_sphere(2_000, 7, 0.1)).unwrap();
//! tree.validate().unwrap();
//! let ray = Ray::infinite(Vec3::new(0.0, 0.0, -5.0), Vec3::Z);
//! let hit = tree.intersect(&ray).expect("the sphere is in front of the ray");
//! assert!(hit.t > 2.5 && hit.t < 4.5);
//! assert!(tree.occluded(&ray));
//! ```
#![cfg_attr(docsrs, feature(doc_cfg))]

mod bvh;
mod error;
mod geom;
mod kd;
mod leaf;
mod packet;
#[cfg(feature = "embree")]
mod peers;
pub mod testing;
mod toplevel;

pub use bvh::{
    BVH_MAX_DEPTH, BVH_MAX_LEAF, BVH_MAX_PRIMITIVES, BVH_PRESPLIT_BUDGET, BVH_PRESPLIT_MAX_PIECES,
    BVH_PRESPLIT_MIN_WASTE, BVH_REFIT_COST_LIMIT, BVH_WIDTH, Bvh, BvhNode, BvhSlot, BvhStats, INSTANCE_BVH_MAX,
    INSTANCE_BVH_POOL_MIN, INSTANCE_BVH_TASK_MIN, InstanceBvh,
};
pub use error::AccelError;
pub use geom::aabb::Aabb;
pub use geom::box_quad::BoxQuad;
pub use geom::hit::Hit;
pub use geom::ray::{Ray, rays_from_lanes};
pub use geom::triangle::{TriHit, Triangle, intersect_triangle, is_valid_triangle};
pub use kd::fast_build::{DEFAULT_REFIT_COST_LIMIT, FastParams, PARALLEL_MIN};
pub use kd::node::{KdNode, MAX_DEPTH};
pub use kd::sah_params::{DEFAULT_BINNED_ABOVE, SahParams, default_max_depth};
pub use kd::traverse::traverse;
pub use kd::tree::{BuilderKind, KdTree, TreeStats};
pub use packet::boxes::{BOX_SLACK, PacketBoxes, ray_reaches, ray_reaches_quad};
pub use packet::frustum::{FRUSTUM_MARGIN, Frustum, THROUGH_RADIUS, frustum_culling, set_frustum_culling};
pub use packet::interval::PacketInterval;
pub use packet::traverse::{traverse_packet, traverse_packet_laid};
#[cfg(target_arch = "x86_64")]
pub use packet::width::avx2;
pub use packet::width::{MAX_LANES, PacketWidth, lanes_mask, lanes_of, sign_groups};
#[cfg(feature = "embree")]
pub use peers::embree::{EmbreeLowBuilds, EmbreeMesh, EmbreeRefits, EmbreeTwoLevel, embree_medium_build_secs};
pub use testing::{meshgen, oracle};
pub use toplevel::bsp::{BspBuilder, InstanceBsp};
