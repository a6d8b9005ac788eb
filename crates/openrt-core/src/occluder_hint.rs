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

/// Most packets in a row that skip their light's hint after tries of it
/// that settled no lane: after the `k`-th such try in a row the hint rests
/// for `min(2^k - 1, HINT_MAX_REST)` packets (1, 3, 7, 7, ...).
///
/// PERF: on terrain and in the museum most shadow packets start on scattered
/// foliage or moving triangles, and the last occluder settles no lane of
/// most of them (85% of terrain's hinted packets); in a lit stretch of the
/// kitchen none either. Backing off keeps the hint where it pays: shadow
/// queries, six alternations, medians: kitchen 150.4 -> 145.0 ms, terrain
/// 181.7 -> 173.1, museum1k 65.8 -> 60.5, museum16k 215.4 -> 211.1.
pub const HINT_MAX_REST: u8 = 7;

/// Where the last shadow ray towards one light was blocked (an instance
/// index and a leaf of its tree), or nothing yet. One per light per thread,
/// emptied for every tile and frame (it names the instances of one
/// committed scene; a hint from another scene is safe, only useless).
/// Packets back off from a hint that keeps settling nothing
/// ([`HINT_MAX_REST`]); single rays try it every time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OccluderHint {
    pub(crate) leaf: Option<(u32, openrt_accel::KdNode)>,
    /// Packets left before the next packet try.
    rest: u8,
    /// Packet tries in a row that settled no lane.
    misses: u8,
}

impl OccluderHint {
    /// An empty hint.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            leaf: None,
            rest: 0,
            misses: 0,
        }
    }

    /// A hint naming `leaf` of the instance at `instance` (for tests and
    /// probes: any value is safe).
    #[must_use]
    pub const fn naming(instance: u32, leaf: openrt_accel::KdNode) -> Self {
        Self {
            leaf: Some((instance, leaf)),
            rest: 0,
            misses: 0,
        }
    }

    /// The instance index and leaf held, if any.
    #[must_use]
    pub const fn get(&self) -> Option<(u32, openrt_accel::KdNode)> {
        self.leaf
    }

    /// Whether this packet tries the hint: it holds a leaf and is not
    /// resting (a packet that skips it counts down the rest).
    pub(crate) fn packet_turn(&mut self) -> bool {
        if self.rest > 0 {
            self.rest -= 1;
            return false;
        }
        self.leaf.is_some()
    }

    /// Records a packet try: whether it settled a lane.
    pub(crate) fn packet_tried(&mut self, settled: bool) {
        if settled {
            self.misses = 0;
        } else {
            self.misses = self.misses.saturating_add(1);
            self.rest = rest_after(self.misses);
        }
    }
}

/// The packets a hint rests after `misses` tries in a row settled nothing.
fn rest_after(misses: u8) -> u8 {
    let doubling = (1u32 << u32::from(misses.min(8))) - 1;
    u8::try_from(doubling.min(u32::from(HINT_MAX_REST))).unwrap_or(HINT_MAX_REST)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The packets at which a hint is tried, given which tries settle.
    fn tries(packets: usize, settles: impl Fn(usize) -> bool) -> Vec<usize> {
        let tri = [glam::Vec3::ZERO, glam::Vec3::X, glam::Vec3::Y];
        let tree = openrt_accel::KdTree::build_sah(vec![tri]).unwrap();
        let mut hint = OccluderHint::naming(0, tree.nodes()[0]);
        let mut at = Vec::new();
        for p in 0..packets {
            if hint.packet_turn() {
                at.push(p);
                hint.packet_tried(settles(at.len() - 1));
            }
        }
        at
    }

    #[test]
    fn packets_back_off_from_a_hint_that_settles_nothing() {
        // Rests of 1, 3, 7, then never more than HINT_MAX_REST.
        assert_eq!(tries(40, |_| false), [0, 2, 6, 14, 22, 30, 38]);
        assert_eq!(rest_after(u8::MAX), HINT_MAX_REST);
        assert!((1..=u8::MAX).all(|k| rest_after(k) <= HINT_MAX_REST));
        // A try that settles ends the rests: every packet tries again.
        assert_eq!(tries(6, |_| true), [0, 1, 2, 3, 4, 5]);
        // Settling after misses starts the doubling over.
        assert_eq!(tries(30, |k| k == 3), [0, 2, 6, 14, 15, 17, 21, 29]);
        // No leaf, no try.
        let mut empty = OccluderHint::new();
        assert!(!(0..10).any(|_| empty.packet_turn()));
    }
}
