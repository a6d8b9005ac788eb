//! The last occluder of a light: a shadow cache for shadow rays.
//!
//! Neighbouring shadow rays towards one light are often blocked by the same
//! surface (a wall, a lamp shade, a robot's body). Testing the triangles of
//! the leaf where the last ray was blocked first answers such a ray with one
//! leaf's tests instead of a walk through both levels of the scene (Haines & Greenberg, "The Light Buffer:
//! A Shadow-Testing Accelerator", IEEE CG&A 1986, keep such a cache per
//! light). [`Scene::occluded_hinted`](crate::Scene::occluded_hinted) and
//! [`Scene::occluded_packet_toward_hinted`](crate::Scene::occluded_packet_toward_hinted)
//! use it.
//!
//! NOTE: the hint never changes an answer. It only says "blocked" when one
//! of its leaf's triangles is hit (by the same watertight test on the same object-space
//! ray the walk would use) at least [`HINT_MARGIN`] inside the ray's
//! interval and inside the triangle (every barycentric coordinate), where
//! the walk, whose cells and intervals are conservative to within far less,
//! meets that triangle too; otherwise the ray takes the walk. So the images
//! do not depend on what a hint holds, nor on which thread or tile kept it
//! (tested against the plain queries with every leaf as the hint).

/// Relative margin inside the ray's interval and inside the hint's triangle
/// (barycentric) within which a hit of the hint settles a shadow ray.
pub const HINT_MARGIN: f32 = 1e-3;

/// Where the last shadow ray towards one light was blocked (an instance
/// index and a leaf of its tree), or nothing yet. One per light per thread,
/// emptied for every tile and frame (it names the instances of one
/// committed scene; a hint from another scene is safe, only useless).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OccluderHint(pub(crate) Option<(u32, openrt_accel::KdNode)>);

impl OccluderHint {
    /// An empty hint.
    #[must_use]
    pub const fn new() -> Self {
        Self(None)
    }

    /// A hint naming `leaf` of the instance at `instance` (for tests and
    /// probes: any value is safe).
    #[must_use]
    pub const fn naming(instance: u32, leaf: openrt_accel::KdNode) -> Self {
        Self(Some((instance, leaf)))
    }

    /// The instance index and leaf held, if any.
    #[must_use]
    pub const fn get(&self) -> Option<(u32, openrt_accel::KdNode)> {
        self.0
    }
}
