//! Hit records.

/// The closest intersection found along a ray.
///
/// Barycentrics follow the usual convention: the hit point is
/// `(1 - b1 - b2) * v0 + b1 * v1 + b2 * v2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Index of the primitive that was hit.
    pub prim: u32,
    /// Barycentric weight of the second vertex.
    pub b1: f32,
    /// Barycentric weight of the third vertex.
    pub b2: f32,
}
