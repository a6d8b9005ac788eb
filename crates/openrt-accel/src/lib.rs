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

mod aabb;
mod binned_sah;
mod box_quad;
mod bvh;
mod error;
mod fast_build;
mod frustum;
mod hit;
mod kdnode;
mod kdtree;
mod leaf_blocks;
mod numeric;
mod packet;
mod packet_boxes;
mod packet_interval;
mod ray;
mod refit;
mod sah_build;
mod toplevel;
mod traverse;
mod traverse_packet;
mod tri_mailbox;
mod triangle;
mod triangle_packet;

#[cfg(feature = "embree")]
mod embree_peer;
pub mod meshgen;
pub mod oracle;

pub use aabb::Aabb;
pub use box_quad::BoxQuad;
pub use bvh::{
    BVH_MAX_DEPTH, BVH_MAX_LEAF, BVH_MAX_PRIMITIVES, BVH_REFIT_COST_LIMIT, BVH_WIDTH, Bvh, BvhNode, BvhSlot, BvhStats,
};
#[cfg(feature = "embree")]
pub use embree_peer::{EmbreeMesh, EmbreeTwoLevel};
pub use error::AccelError;
pub use fast_build::{DEFAULT_REFIT_COST_LIMIT, FastParams, PARALLEL_MIN};
pub use frustum::{FRUSTUM_MARGIN, Frustum, NO_FRUSTUM_ENV};
pub use hit::Hit;
pub use kdnode::{KdNode, MAX_DEPTH};
pub use kdtree::{BuilderKind, KdTree, TreeStats};
pub use packet::{LANES_ENV, MAX_LANES, PacketWidth, lanes_mask, lanes_of, sign_groups};
pub use packet_boxes::{BOX_SLACK, PacketBoxes, ray_reaches};
pub use packet_interval::PacketInterval;
pub use ray::Ray;
pub use sah_build::{DEFAULT_BINNED_ABOVE, SahParams, default_max_depth};
pub use toplevel::{BspBuilder, InstanceBsp};
pub use traverse::traverse;
pub use traverse_packet::traverse_packet;
pub use triangle::{TriHit, Triangle, intersect_triangle, is_valid_triangle};
