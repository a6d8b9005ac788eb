//! The default SAH kd-tree builder: binned SAH for large nodes, an exact
//! sweep for small ones.
//!
//! - Large nodes (more than [`SahParams::binned_above`] references) choose
//!   their plane among the boundaries of equal bins on each axis, counted
//!   with min-max binning in one pass over the references (Hunt, Mark &
//!   Stoll, "Fast kd-tree construction with an adaptive error-bounded
//!   heuristic", IEEE RT 2006; Shevtsov, Soupikov & Kapustin, "Highly
//!   parallel fast kd-tree construction for interactive ray tracing of
//!   dynamic scenes", Eurographics 2007). This is O(N) per level.
//! - Small nodes sort their references' bounds and sweep every candidate
//!   plane exactly as Wald & Havran 2006 do, with planar primitives tried on
//!   either side: the same planes and costs as the full-SAH builder.
//! - Straddling references are clipped to each child cell ("perfect
//!   splits") at every level, and the same SAH costs, empty bonus, depth
//!   limit and leaf rule as [`crate::sah_build`] apply.
//!
//! PERF: references live in one stack-disciplined arena (a node's children
//! are written past the node's own range; no allocation per node) and the
//! sweep's sort buffers are reused.

use crate::kdnode::{KdNode, MAX_DEPTH, MAX_FIELD};
use crate::sah_build::{BuiltTree, SahParams, clipped_bounds, default_max_depth};
use crate::{Aabb, AccelError, Triangle};

/// Bins per axis in a binned node.
const BINS: usize = 32;

/// A primitive's bounds clipped to the current cell.
#[derive(Clone, Copy, Debug)]
struct Ref {
    b: Aabb,
    prim: u32,
}

const FILLER: Ref = Ref {
    b: Aabb::EMPTY,
    prim: 0,
};

/// The chosen plane.
#[derive(Clone, Copy, Debug)]
struct Plane {
    axis: usize,
    pos: f32,
    planar_left: bool,
    cost: f32,
}

/// Builds the tree over the valid triangles (`valid[i]`).
pub(crate) fn build_binned_sah(
    tris: &[Triangle],
    valid: &[bool],
    params: &SahParams,
    binned_above: usize,
) -> Result<BuiltTree, AccelError> {
    if tris.len() > MAX_FIELD as usize {
        return Err(AccelError::TooManyPrimitives {
            count: tris.len(),
            limit: MAX_FIELD as usize,
        });
    }
    let mut arena: Vec<Ref> = tris
        .iter()
        .enumerate()
        .filter(|&(i, _)| valid[i])
        .map(|(i, t)| Ref {
            b: Aabb::from_points(t),
            prim: i as u32,
        })
        .collect();
    let n = arena.len();
    let bounds = arena.iter().fold(Aabb::EMPTY, |a, r| a.union(r.b));
    arena.reserve(4 * n);
    let max_depth = params
        .max_depth
        .unwrap_or_else(|| default_max_depth(n))
        .min(MAX_DEPTH - 1);
    let mut b = Builder {
        tris,
        params: *params,
        binned_above: binned_above.max(1),
        arena,
        nodes: Vec::with_capacity(2 * n + 1),
        prim_ids: Vec::with_capacity(2 * n),
        max_depth,
        depth_reached: 0,
        sweep: [Vec::new(), Vec::new(), Vec::new()],
    };
    if n == 0 {
        b.nodes.push(KdNode::leaf(0, 0));
    } else {
        b.node(bounds, 0, n, n, 0)?;
    }
    Ok(BuiltTree {
        nodes: b.nodes,
        prim_ids: b.prim_ids,
        bounds,
        depth: b.depth_reached,
    })
}

struct Builder<'a> {
    tris: &'a [Triangle],
    params: SahParams,
    binned_above: usize,
    /// A node's references are `arena[at..at + n]`; from `free` on is scratch.
    arena: Vec<Ref>,
    nodes: Vec<KdNode>,
    prim_ids: Vec<u32>,
    max_depth: usize,
    depth_reached: usize,
    /// Sort buffers of the exact sweep: starts, ends, planar positions.
    sweep: [Vec<u32>; 3],
}

impl Builder<'_> {
    fn node(&mut self, cell: Aabb, at: usize, n: usize, free: usize, depth: usize) -> Result<(), AccelError> {
        self.depth_reached = self.depth_reached.max(depth);
        let leaf_cost = self.params.intersection_cost * n as f32;
        // No split costs less than a traversal step (times the empty bonus):
        // a node cheaper than that as a leaf needs no sweep.
        let floor = self.params.traversal_cost * self.params.empty_bonus.min(1.0);
        let plane = if depth >= self.max_depth || leaf_cost <= floor {
            None
        } else if n > self.binned_above {
            self.binned_plane(&cell, at, n)
        } else {
            self.exact_plane(&cell, at, n)
        };
        let Some(plane) = plane.filter(|p| p.cost < leaf_cost) else {
            return self.leaf(at, n);
        };
        let (mut lcell, mut rcell) = (cell, cell);
        lcell.max[plane.axis] = plane.pos;
        rcell.min[plane.axis] = plane.pos;
        let (nl, nr, straddled) = self.partition(at, n, free, plane, &lcell, &rcell);
        if straddled == n {
            // Every primitive straddles: splitting can not separate anything.
            return self.leaf(at, n);
        }
        let index = self.nodes.len();
        if index >= MAX_FIELD as usize {
            return Err(AccelError::TooManyNodes {
                limit: MAX_FIELD as usize,
            });
        }
        let scratch = free + 2 * n;
        self.nodes.push(KdNode::interior(plane.axis, plane.pos));
        self.node(lcell, free, nl, scratch, depth + 1)?;
        let above = self.nodes.len() as u32;
        self.nodes[index].set_above_child(above);
        self.node(rcell, free + n, nr, scratch, depth + 1)
    }

    fn leaf(&mut self, at: usize, n: usize) -> Result<(), AccelError> {
        let offset = self.prim_ids.len();
        if offset > u32::MAX as usize - n || n > MAX_FIELD as usize {
            return Err(AccelError::TooManyNodes {
                limit: MAX_FIELD as usize,
            });
        }
        self.prim_ids.extend(self.arena[at..at + n].iter().map(|r| r.prim));
        self.nodes.push(KdNode::leaf(offset as u32, n as u32));
        Ok(())
    }

    /// The SAH cost of a split, with the empty-side bonus.
    #[inline]
    fn cost(&self, pl: f32, pr: f32, nl: usize, nr: usize) -> f32 {
        let p = &self.params;
        let c = p.traversal_cost + p.intersection_cost * (pl * nl as f32 + pr * nr as f32);
        if nl == 0 || nr == 0 { c * p.empty_bonus } else { c }
    }

    /// The cheapest bin boundary over the three axes (min-max binning).
    fn binned_plane(&self, cell: &Aabb, at: usize, n: usize) -> Option<Plane> {
        let sa = cell.surface_area();
        if sa <= 0.0 || !sa.is_finite() {
            return None;
        }
        let ext = cell.extent();
        let mut starts = [[0u32; BINS]; 3];
        let mut ends = [[0u32; BINS]; 3];
        let scale: [f32; 3] = std::array::from_fn(|k| if ext[k] > 0.0 { BINS as f32 / ext[k] } else { 0.0 });
        let lo = cell.min;
        // PERF: one pass bins all three axes; `as usize` saturates negatives
        // to 0 and `min` clamps the top.
        for r in &self.arena[at..at + n] {
            for k in 0..3 {
                let b0 = (((r.b.min[k] - lo[k]) * scale[k]) as usize).min(BINS - 1);
                let b1 = (((r.b.max[k] - lo[k]) * scale[k]) as usize).min(BINS - 1);
                starts[k][b0] += 1;
                ends[k][b1] += 1;
            }
        }
        let inv_sa = 1.0 / sa;
        let mut best: Option<Plane> = None;
        for k in 0..3 {
            if ext[k] <= 0.0 {
                continue;
            }
            let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
            let (cross, perim) = (ext[k1] * ext[k2], ext[k1] + ext[k2]);
            let (mut nl, mut nr) = (0usize, n);
            for i in 1..BINS {
                nl += starts[k][i - 1] as usize;
                nr -= ends[k][i - 1] as usize;
                let pos = lo[k] + ext[k] * (i as f32 / BINS as f32);
                if !(pos > cell.min[k] && pos < cell.max[k]) {
                    continue;
                }
                let (wl, wr) = (pos - cell.min[k], cell.max[k] - pos);
                let pl = 2.0 * (cross + wl * perim) * inv_sa;
                let pr = 2.0 * (cross + wr * perim) * inv_sa;
                let c = self.cost(pl, pr, nl, nr);
                if best.is_none_or(|b| c < b.cost) {
                    best = Some(Plane {
                        axis: k,
                        pos,
                        planar_left: true,
                        cost: c,
                    });
                }
            }
        }
        best
    }

    /// The cheapest plane among all reference boundaries (Wald & Havran's
    /// sweep over sorted bounds, planar primitives tried on either side).
    fn exact_plane(&mut self, cell: &Aabb, at: usize, n: usize) -> Option<Plane> {
        let sa = cell.surface_area();
        if sa <= 0.0 || !sa.is_finite() {
            return None;
        }
        let inv_sa = 1.0 / sa;
        let ext = cell.extent();
        let mut best: Option<Plane> = None;
        let [mut starts, mut ends, mut planar] = std::mem::take(&mut self.sweep);
        for k in 0..3 {
            if ext[k] <= 0.0 {
                continue;
            }
            starts.clear();
            ends.clear();
            planar.clear();
            for r in &self.arena[at..at + n] {
                let (a, b) = (r.b.min[k], r.b.max[k]);
                if a == b {
                    planar.push(order_key(a));
                } else {
                    starts.push(order_key(a));
                    ends.push(order_key(b));
                }
            }
            // PERF: integer keys sort markedly faster than f32 with total_cmp.
            for v in [&mut starts, &mut ends, &mut planar] {
                v.sort_unstable();
            }
            let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
            let (cross, perim) = (ext[k1] * ext[k2], ext[k1] + ext[k2]);
            let (mut nl, mut nr) = (0usize, n);
            let (mut i, mut j, mut m) = (0usize, 0usize, 0usize);
            loop {
                let key = starts
                    .get(i)
                    .copied()
                    .unwrap_or(u32::MAX)
                    .min(ends.get(j).copied().unwrap_or(u32::MAX))
                    .min(planar.get(m).copied().unwrap_or(u32::MAX));
                if key == u32::MAX {
                    break;
                }
                let p = from_order_key(key);
                let (i0, j0, m0) = (i, j, m);
                while j < ends.len() && ends[j] == key {
                    j += 1;
                }
                while m < planar.len() && planar[m] == key {
                    m += 1;
                }
                while i < starts.len() && starts[i] == key {
                    i += 1;
                }
                let (pe, pp, ps) = (j - j0, m - m0, i - i0);
                nr -= pp + pe;
                if p > cell.min[k] && p < cell.max[k] {
                    let (wl, wr) = (p - cell.min[k], cell.max[k] - p);
                    let pl = 2.0 * (cross + wl * perim) * inv_sa;
                    let pr = 2.0 * (cross + wr * perim) * inv_sa;
                    let c_left = self.cost(pl, pr, nl + pp, nr);
                    let c_right = self.cost(pl, pr, nl, nr + pp);
                    let (c, planar_left) = if c_left <= c_right {
                        (c_left, true)
                    } else {
                        (c_right, false)
                    };
                    if best.is_none_or(|b| c < b.cost) {
                        best = Some(Plane {
                            axis: k,
                            pos: p,
                            planar_left,
                            cost: c,
                        });
                    }
                }
                nl += ps + pp;
            }
        }
        self.sweep = [starts, ends, planar];
        best
    }

    /// Writes the left references to `arena[free..]` and the right ones to
    /// `arena[free + n..]`, clipping straddlers to each child cell (a side
    /// where nothing of the triangle remains drops it). Returns the child
    /// counts and how many references straddled.
    fn partition(
        &mut self,
        at: usize,
        n: usize,
        free: usize,
        plane: Plane,
        lcell: &Aabb,
        rcell: &Aabb,
    ) -> (usize, usize, usize) {
        if self.arena.len() < free + 2 * n {
            self.arena.resize(free + 2 * n, FILLER);
        }
        let (src, dst) = self.arena.split_at_mut(free);
        let (left, right) = dst.split_at_mut(n);
        let (k, p) = (plane.axis, plane.pos);
        let (mut nl, mut nr, mut straddled) = (0usize, 0usize, 0usize);
        for r in &src[at..at + n] {
            let (a, b) = (r.b.min[k], r.b.max[k]);
            if a == b {
                if a < p || (a == p && plane.planar_left) {
                    left[nl] = *r;
                    nl += 1;
                } else {
                    right[nr] = *r;
                    nr += 1;
                }
            } else if b <= p {
                left[nl] = *r;
                nl += 1;
            } else if a >= p {
                right[nr] = *r;
                nr += 1;
            } else {
                straddled += 1;
                let tri = &self.tris[r.prim as usize];
                let lb = clipped_bounds(tri, &r.b.intersection(*lcell));
                if !lb.is_empty() {
                    left[nl] = Ref { b: lb, prim: r.prim };
                    nl += 1;
                }
                let rb = clipped_bounds(tri, &r.b.intersection(*rcell));
                if !rb.is_empty() {
                    right[nr] = Ref { b: rb, prim: r.prim };
                    nr += 1;
                }
            }
        }
        (nl, nr, straddled)
    }
}

/// A key whose unsigned order is the order of the finite floats, with -0.0
/// and +0.0 equal (NaN never occurs: bounds are finite). `u32::MAX` is left
/// free as the end marker: it would be a NaN.
#[inline]
fn order_key(x: f32) -> u32 {
    let b = (x + 0.0).to_bits();
    if b & 0x8000_0000 != 0 { !b } else { b | 0x8000_0000 }
}

/// The float of an [`order_key`].
#[inline]
fn from_order_key(k: u32) -> f32 {
    f32::from_bits(if k & 0x8000_0000 != 0 { k & 0x7fff_ffff } else { !k })
}

#[cfg(test)]
mod tests {
    use super::{from_order_key, order_key};
    use crate::{KdTree, SahParams, meshgen};

    #[test]
    fn order_keys_sort_like_the_floats_and_round_trip() {
        let xs = [
            -f32::MAX,
            -1e30,
            -1.0,
            -f32::MIN_POSITIVE,
            -1e-45,
            -0.0,
            0.0,
            1e-45,
            f32::MIN_POSITIVE,
            1.0,
            1.0 + f32::EPSILON,
            1e30,
            f32::MAX,
        ];
        for w in xs.windows(2) {
            let (a, b) = (order_key(w[0]), order_key(w[1]));
            if w[0] == w[1] {
                assert_eq!(a, b, "{} and {} are equal floats", w[0], w[1]);
            } else {
                assert!(a < b, "{} < {} but keys {a:#x} >= {b:#x}", w[0], w[1]);
            }
        }
        for x in xs {
            let y = from_order_key(order_key(x));
            assert!(y == x, "{x} round-trips to {y}");
            assert_ne!(order_key(x), u32::MAX, "the end marker is never a key");
        }
        assert_eq!(from_order_key(order_key(-0.0)).to_bits(), 0.0f32.to_bits());
    }

    /// Binned planes may cost a little tree quality, never much: the SAH
    /// cost of the default tree stays within 5% of the exact builder's.
    #[test]
    fn binned_trees_cost_within_five_percent_of_exact_ones() {
        for (n, seed) in [(5_000, 1), (20_000, 2)] {
            let tris = meshgen::bumpy_sphere(n, seed, 0.5);
            let exact = KdTree::build_sah_with(
                tris.clone(),
                &SahParams {
                    binned_above: None,
                    ..SahParams::default()
                },
            )
            .unwrap();
            let binned = KdTree::build_sah(tris).unwrap();
            exact.validate().unwrap();
            binned.validate().unwrap();
            let (e, b) = (exact.sah_cost(), binned.sah_cost());
            assert!(e > 0.0 && b > 0.0);
            assert!(b <= e * 1.05, "{n} tris: binned cost {b:.2} vs exact {e:.2}");
        }
    }

    /// Input the binned planes can not separate (every reference spans the
    /// cell) still ends in leaves, within the depth limit.
    #[test]
    fn identical_triangles_end_in_one_leaf() {
        let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]].map(glam::Vec3::from_array);
        for binned_above in [Some(0), Some(64)] {
            let params = SahParams {
                binned_above,
                ..SahParams::default()
            };
            let tree = KdTree::build_sah_with(vec![t; 300], &params).unwrap();
            tree.validate().unwrap();
            assert_eq!(
                tree.stats().references,
                300,
                "{binned_above:?}: copies were split or lost"
            );
        }
    }
}
