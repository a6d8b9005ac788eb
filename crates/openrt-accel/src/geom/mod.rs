//! Geometry: rays, boxes, the watertight triangle test and its SIMD blocks,
//! hit records and the rounding bounds they rest on.

pub(crate) mod aabb;
pub(crate) mod box_quad;
pub(crate) mod hit;
pub(crate) mod numeric;
pub(crate) mod ray;
pub(crate) mod tri_block;
pub(crate) mod triangle;
pub(crate) mod watertight4;
#[cfg(target_arch = "x86_64")]
pub(crate) mod watertight8;
