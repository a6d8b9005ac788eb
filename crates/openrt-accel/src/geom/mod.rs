//! Geometry: rays, boxes, the watertight triangle test and its SIMD blocks,
//! hit records and the rounding bounds they rest on.

pub(crate) mod aabb;
pub(crate) mod box_quad;
pub(crate) mod hit;
pub(crate) mod numeric;
pub(crate) mod ray;
pub(crate) mod tri_block;
pub(crate) mod triangle;
