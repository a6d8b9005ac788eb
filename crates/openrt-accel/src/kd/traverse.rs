//! Iterative front-to-back kd-tree traversal, shared by object trees and the
//! top-level instance tree.

use crate::geom::numeric::gamma;
use crate::geom::ray::Ray;
use crate::kd::node::{KdNode, MAX_DEPTH};

/// Relative margin by which a split distance is widened on both sides.
///
/// NOTE: `t_split = (split - o) * inv_dir` carries three roundings; a cell
/// whose true interval touches the ray by less than that error would be
/// skipped and a triangle in it missed. Widening every cell's parameter
/// interval by `2 gamma(3)` relative (Woop et al., JCGT 2013, section 4
/// for boxes; the same argument for kd cells) visits such cells instead.
const ENLARGE: f32 = 2.0 * gamma(3);

/// Relative margin of the interval bounds the walk carries: the box
/// clip's entry and exit and every split distance that becomes a bound are
/// widened by `BOUND`, so that the near/far decision compares the raw split
/// distance with them.
///
/// NOTE: `t_split > b + |b| BOUND` implies `t_split - |t_split| ENLARGE >
/// b + |b| ENLARGE` for either sign of `b` (`(1 + B)(1 - E) >= 1 + E` needs
/// `B >= 2E / (1 - E)`; the extra `2 EPSILON` absorbs the roundings of the
/// widening), and the mirror for lower bounds: every cell that comparing
/// split distances widened by `ENLARGE` on both sides would visit is visited
/// (tested below).
const BOUND: f32 = 2.0 * ENLARGE + 2.0 * f32::EPSILON;

/// `t` widened upwards by [`BOUND`] relative.
#[inline]
pub(crate) fn widen_up(t: f32) -> f32 {
    t + t.abs() * BOUND
}

/// `t` widened downwards by [`BOUND`] relative.
#[inline]
pub(crate) fn widen_down(t: f32) -> f32 {
    t - t.abs() * BOUND
}

/// A deferred far child with its parameter interval.
#[derive(Clone, Copy)]
struct StackEntry {
    node: u32,
    t_min: f32,
    t_max: f32,
}

/// Walks the cells pierced by `ray` over `[t0, t1]` front to back and calls
/// `leaf(node, closest)` for each non-empty leaf, where `closest` is the
/// current closest hit distance, which the callback lowers when it finds a
/// closer hit. A hit found in a leaf may lie beyond that leaf's cell, so
/// traversal does not stop at the first hit: it pops and skips every deferred
/// cell that begins beyond `closest`.
///
/// The callback returns `true` to stop at once (any-hit queries).
/// Returns `true` when the callback stopped the walk.
///
/// Node indices must form a valid tree (checked by the trees' `validate`).
#[inline]
pub fn traverse<L>(nodes: &[KdNode], ray: &Ray, t0: f32, t1: f32, closest: &mut f32, leaf: L) -> bool
where
    L: FnMut(KdNode, &mut f32) -> bool,
{
    if nodes.is_empty() || t0.is_nan() || t1.is_nan() || t0 > t1 {
        return false;
    }
    // PERF: a ray without zero direction components (nearly every ray) runs
    // a copy of the walk without the zero test in its interior step.
    if ray.dir.cmpeq(glam::Vec3::ZERO).any() {
        walk::<true, L>(nodes, ray, t0, t1, closest, leaf)
    } else {
        walk::<false, L>(nodes, ray, t0, t1, closest, leaf)
    }
}

/// [`traverse`] for a ray with (`ZERO`) or without zero direction components.
#[inline]
fn walk<const ZERO: bool, L>(nodes: &[KdNode], ray: &Ray, t0: f32, t1: f32, closest: &mut f32, mut leaf: L) -> bool
where
    L: FnMut(KdNode, &mut f32) -> bool,
{
    // PERF: the stack is not zeroed: entries are written before they are read.
    let mut stack = [std::mem::MaybeUninit::<StackEntry>::uninit(); MAX_DEPTH];
    let mut sp = 0usize;
    let mut node = 0u32;
    let (mut t_min, mut t_max) = (widen_down(t0), widen_up(t1));
    let org = ray.origin.to_array();
    let dir = ray.dir.to_array();
    // Bit `k` set: the direction's component `k` is negative.
    let negative = ray.dir.is_negative_bitmask();
    let inv = ray.inv_dir.to_array();
    'walk: loop {
        // NOTE: kept bounds-checked: `traverse` is public and safe, so a
        // caller may pass any slice; the check is one predictable branch.
        let n = nodes[node as usize];
        'cell: {
            if n.is_leaf() {
                if n.prim_count() > 0 && leaf(n, closest) {
                    return true;
                }
                break 'cell;
            }
            let axis = n.axis();
            let split = n.split();
            let o = org[axis];
            let d = dir[axis];
            // An empty cell has no node (`KdNode::below_empty`, above index 0).
            let below = (node + 1, n.below_empty());
            let above = (n.above_child(), n.above_child() == 0);
            // Goes on to `child`, or pops when its cell is empty.
            macro_rules! go {
                ($child:expr) => {{
                    let (index, empty) = $child;
                    node = index;
                    if empty {
                        break 'cell;
                    }
                    continue 'walk;
                }};
            }
            // NOTE: exact test: a ray with a zero component (either sign) never
            // crosses this plane; its side is the origin's, both if it lies in it.
            if ZERO && d == 0.0 {
                if o < split {
                    go!(below);
                } else if o > split {
                    go!(above);
                }
                if !above.1 {
                    stack[sp].write(StackEntry {
                        node: above.0,
                        t_min,
                        t_max,
                    });
                    sp += 1;
                }
                go!(below);
            }
            let t_split = (split - o) * inv[axis];
            // PERF: the branches compare the raw split distance with the
            // widened bounds (`BOUND`), not a widened split distance with
            // them: the margin's operations stay off the path from the node
            // load to the branch, which a mispredicted step waits for.
            let (lo, hi) = (widen_down(t_split), widen_up(t_split));
            // NOTE: the near child is chosen by the sign of the direction, not
            // by the side of the origin (pbrt): a ray whose origin lies beyond
            // the plane has `t_split < 0` and takes the far child alone. One
            // unpredictable branch less per step for incoherent rays, and the
            // same cells for every `t` interval, negative ones included.
            // PERF: written as two expansions of one body so that the
            // near/far choice stays a branch: as a select it puts the child's
            // index behind the node load, and camera rays, whose branches are
            // predicted, ran 22-34% slower (docs/PERFORMANCE.md).
            // The step visits the near child unless the plane lies before the
            // interval or the near cell is empty, the far child unless the
            // plane lies beyond the interval or the far cell is empty: two
            // branches, each on a flag computed without one (three before:
            // near only / far only / both, then the chosen cell's emptiness).
            // A NaN `t_split` (a zero times an infinite reciprocal) visits
            // both children over the whole interval.
            macro_rules! step {
                ($near:expr, $far:expr) => {{
                    let (near, far): ((u32, bool), (u32, bool)) = ($near, $far);
                    // The plane lies before / beyond the interval (false for NaN).
                    let (before, beyond) = (t_split < t_min, t_split > t_max);
                    let go_near = !before & !near.1;
                    let go_far = !beyond & !far.1;
                    let lo = if lo > t_min { lo } else { t_min };
                    let hi = if hi < t_max { hi } else { t_max };
                    if go_near {
                        // PERF: the far entry is written every time and kept
                        // only when the far cell is visited (no branch).
                        stack[sp].write(StackEntry {
                            node: far.0,
                            t_min: lo,
                            t_max,
                        });
                        sp += usize::from(go_far);
                        t_max = hi;
                        node = near.0;
                        continue 'walk;
                    }
                    if go_far {
                        t_min = lo;
                        node = far.0;
                        continue 'walk;
                    }
                    break 'cell;
                }};
            }
            if (negative >> axis) & 1 != 0 {
                step!(above, below);
            }
            step!(below, above);
        }
        // Pop, skipping cells that start beyond the closest hit.
        loop {
            if sp == 0 {
                return false;
            }
            sp -= 1;
            // SAFETY: entries below `sp` were written by a push.
            let e = unsafe { stack[sp].assume_init() };
            if e.t_min <= *closest {
                node = e.node;
                t_min = e.t_min;
                t_max = e.t_max;
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    use super::*;

    /// A decision made by comparing a raw split distance with bounds widened
    /// by `BOUND` is one that comparing split distances widened by
    /// `ENLARGE` on both sides also makes, for both signs, at the scales
    /// and the distances in ulps where rounding decides.
    #[test]
    fn widened_bounds_are_at_least_as_conservative_as_the_margins() {
        let mut rng = SmallRng::seed_from_u64(5);
        let (mut beyond, mut before) = (0, 0);
        for _ in 0..200_000 {
            let mag = 10f32.powi(rng.random_range(-12..=12)) * rng.random_range(1.0..2.0f32);
            let b = if rng.random() { mag } else { -mag };
            // A split distance a few ulps to a few margins away from `b`.
            let s = crate::geom::numeric::step_ulps(b, rng.random_range(-160..=160));
            let margin = |t: f32| t.abs() * ENLARGE;
            if s > widen_up(b) {
                assert!(s - margin(s) > b + margin(b), "{s} beyond widen_up({b})");
                beyond += 1;
            }
            if s < widen_down(b) {
                assert!(s + margin(s) < b - margin(b), "{s} before widen_down({b})");
                before += 1;
            }
        }
        // Both decisions must have been exercised near their thresholds.
        assert!(beyond > 1_000 && before > 1_000, "{beyond} beyond, {before} before");
    }
}
