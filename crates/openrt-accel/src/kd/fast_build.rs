//! The cheap kd-tree builder for objects with unstructured motion.
//!
//! Wald, Benthin & Slusallek (2003) rebuild the tree of an object whose
//! geometry changes every frame with a cheaper builder: a simpler cost
//! estimate, a shallower tree, and leaves allowed to grow with depth by a
//! constant factor. Here:
//! - SAH estimated on `bins` uniform bins of the longest axis of the cell,
//!   from the primitives' boxes (no event sorting, no perfect splits:
//!   straddling boxes are only clamped to the child cells);
//! - a leaf is made as soon as a node holds at most
//!   `min_leaf * leaf_growth^depth` primitives;
//! - depth limited to `depth_factor` times the SAH builder's limit.

use crate::error::AccelError;
use crate::geom::aabb::Aabb;
use crate::geom::triangle::{Triangle, is_valid_triangle};
use crate::kd::node::{KdNode, MAX_DEPTH, MAX_FIELD, MAX_NODES, stitch, too_many_nodes};
use crate::kd::sah_params::SahParams;
use crate::kd::sah_params::{BuiltTree, default_max_depth};

/// Parameters of the fast builder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FastParams {
    /// Number of bins on the split axis.
    pub bins: usize,
    /// Largest leaf at the root.
    pub min_leaf: f32,
    /// Factor by which the largest leaf grows at each level.
    pub leaf_growth: f32,
    /// Depth limit as a fraction of the SAH builder's.
    pub depth_factor: f32,
    /// Cost of one traversal step.
    pub traversal_cost: f32,
    /// Cost of one ray/triangle test.
    pub intersection_cost: f32,
    /// Build the top levels' subtrees on several threads (one level per
    /// doubling of the available cores).
    pub parallel: bool,
    /// [`crate::KdTree::refit_fast`] keeps a refitted tree while its SAH
    /// cost is at most this factor times the cost of the last full build
    /// in its line, and builds afresh beyond it.
    pub refit_cost_limit: f64,
}

/// Smallest node built in parallel: fast builds and refits of fewer
/// primitives run on one thread (see [`BspBuilder::install_build`](crate::BspBuilder::install_build)).
///
/// NOTE: 4,096 triangles refit in 0.25-0.27 ms on the committing thread
/// against 0.35 ms handed to a pool of two; 16,384 in about the same time
/// either way (docs/PERFORMANCE.md).
pub const PARALLEL_MIN: usize = 8192;

/// Default [`FastParams::refit_cost_limit`]: a refitted tree may cost 25%
/// more than the last full build before it is rebuilt (measured on the
/// museum's animart in docs/PERFORMANCE.md).
pub const DEFAULT_REFIT_COST_LIMIT: f64 = 1.25;

/// The primitives' boxes, coordinate by coordinate, indexed by primitive id.
///
/// A node's list holds primitive ids only: an item's box clipped to its
/// cell is its own box intersected with the cell (the cell is the
/// intersection of its ancestors' half-spaces, and the root cell bounds
/// every box), and the builder's decisions on clipped boxes are the same
/// on the boxes themselves (a partition's plane lies inside the cell, the
/// bins clamp to it; tested against clipping at every level), so a
/// partition moves 4 bytes per item and reads 8 (side by side: one load).
pub(crate) struct Boxes {
    /// Per axis, every primitive's lowest and highest coordinate.
    spans: [Vec<[f32; 2]>; 3],
}

impl Boxes {
    /// The lowest and highest coordinate on `axis` of every primitive.
    #[inline]
    fn axis(&self, axis: usize) -> &[[f32; 2]] {
        &self.spans[axis]
    }

    /// The spans of `boxes`, primitive `i` having box `boxes[i]`.
    #[cfg(test)]
    fn of(boxes: &[Aabb]) -> Self {
        Self {
            spans: std::array::from_fn(|a| boxes.iter().map(|b| [b.min[a], b.max[a]]).collect()),
        }
    }
}

/// The ids of the valid triangles ([`is_valid_triangle`], decided in the
/// same pass), every triangle's box, and the box around the valid ones.
pub(crate) fn items_of(tris: &[Triangle]) -> Result<(Vec<u32>, Boxes, Aabb), AccelError> {
    if tris.len() > MAX_FIELD as usize {
        return Err(AccelError::TooManyPrimitives {
            count: tris.len(),
            limit: MAX_FIELD as usize,
        });
    }
    let mut boxes = Boxes {
        spans: std::array::from_fn(|_| Vec::with_capacity(tris.len())),
    };
    let mut ids = Vec::with_capacity(tris.len());
    let mut bounds = Aabb::EMPTY;
    for (i, t) in tris.iter().enumerate() {
        let b = Aabb::from_points(t);
        for a in 0..3 {
            boxes.spans[a].push([b.min[a], b.max[a]]);
        }
        if is_valid_triangle(t) {
            ids.push(i as u32);
            bounds = bounds.union(b);
        }
    }
    Ok((ids, boxes, bounds))
}

/// The bins of a box's start and end on the planned axis: `(x - lo) *
/// scale` truncated, saturated to `0..=nb - 1` (NaN to 0), as
/// `(((x - lo) * scale) as usize).min(nb - 1)` (the scalar twin, tested).
///
/// PERF: both in one SSE register, clamped in floats before one
/// conversion; the saturating casts were most of the fast builder's bin
/// loop, itself a third of a museum16k build.
#[inline]
fn span_bins(span: [f32; 2], lo: f32, scale: f32, nb: usize) -> [usize; 2] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            _mm_cvtsi128_si32, _mm_cvttps_epi32, _mm_max_ps, _mm_min_ps, _mm_mul_ps, _mm_set_ps, _mm_set1_ps,
            _mm_setzero_ps, _mm_shuffle_epi32, _mm_sub_ps,
        };
        // SAFETY: SSE2 is part of every x86_64 CPU (the target's baseline);
        // the intrinsics touch registers only.
        let [a, b] = unsafe {
            let x = _mm_set_ps(0.0, 0.0, span[1], span[0]);
            let f = _mm_mul_ps(_mm_sub_ps(x, _mm_set1_ps(lo)), _mm_set1_ps(scale));
            // `maxps` answers its second operand (0) for NaN.
            let f = _mm_min_ps(_mm_max_ps(f, _mm_setzero_ps()), _mm_set1_ps((nb - 1) as f32));
            let i = _mm_cvttps_epi32(f);
            [_mm_cvtsi128_si32(i), _mm_cvtsi128_si32(_mm_shuffle_epi32::<0b01>(i))]
        };
        // The lanes hold 0..=nb - 1 (at most 63): the casts are exact.
        [a as usize, b as usize]
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        span.map(|x| (((x - lo) * scale) as usize).min(nb - 1))
    }
}

/// Whether work over `items` runs in parallel: from [`PARALLEL_MIN`] items,
/// on a pool's thread only (from any other thread rayon would hand the work
/// to its global pool and wait).
pub(crate) fn parallel_for(items: usize) -> bool {
    items >= PARALLEL_MIN && rayon::current_thread_index().is_some()
}

/// Levels of a tree built on two threads each: one per doubling of the
/// threads of the rayon pool the build runs in (the commit lends it its
/// pool, so no thread is spawned per build). None for fewer than
/// [`PARALLEL_MIN`] items, and none outside a pool's threads: a build on
/// any other thread never starts rayon's global pool.
pub(crate) fn parallel_levels(params: &FastParams, items: usize) -> u32 {
    if params.parallel && parallel_for(items) {
        rayon::current_num_threads().next_power_of_two().trailing_zeros()
    } else {
        0
    }
}

impl Default for FastParams {
    fn default() -> Self {
        Self {
            bins: 16,
            // NOTE: one SIMD block of leaf triangles (`leaf_blocks.rs`) costs
            // about one triangle test, so leaves start at a full block and a
            // reference costs what it costs in the SAH builder. Against the
            // earlier (2, 0.5): builds 10-25% faster and traces as fast or
            // faster on 1k-64k moving triangles (docs/PERFORMANCE.md).
            min_leaf: 4.0,
            leaf_growth: 1.15,
            depth_factor: 0.75,
            traversal_cost: 1.0,
            intersection_cost: 0.1,
            parallel: true,
            refit_cost_limit: DEFAULT_REFIT_COST_LIMIT,
        }
    }
}

pub(crate) fn build_fast(tris: &[Triangle], params: &FastParams) -> Result<BuiltTree, AccelError> {
    let (items, boxes, bounds) = items_of(tris)?;
    let valid = items.len();
    let mut b = Fast::new(params, &boxes, valid);
    if items.is_empty() {
        b.nodes.push(KdNode::leaf(0, 0));
    } else {
        let levels = parallel_levels(params, items.len());
        b.node_parallel(bounds, items, 0, levels)?;
    }
    Ok(b.finish(bounds, valid))
}

/// A planned split with its children.
pub(crate) struct Split {
    pub(crate) axis: usize,
    pub(crate) position: f32,
    pub(crate) lcell: Aabb,
    pub(crate) left: Vec<u32>,
    pub(crate) rcell: Aabb,
    pub(crate) right: Vec<u32>,
}

/// A tree under construction: depth-first nodes and leaf lists.
pub(crate) struct Fast<'b> {
    params: FastParams,
    /// Every primitive's box.
    boxes: &'b Boxes,
    pub(crate) nodes: Vec<KdNode>,
    pub(crate) prim_ids: Vec<u32>,
    pub(crate) max_depth: usize,
    pub(crate) depth_reached: usize,
    /// Sum over the nodes of cell area times node cost (a step for an
    /// interior node, a test per reference for a leaf, at the costs of
    /// [`KdTree::sah_cost`](crate::KdTree::sah_cost)).
    pub(crate) cost: f64,
    /// Item lists of finished leaves, given back for the next partitions'
    /// right lists (no allocation, no zeroing per partition).
    spare: Vec<Vec<u32>>,
}

impl<'b> Fast<'b> {
    /// An empty builder for `count` primitives of `boxes`.
    pub(crate) fn new(params: &FastParams, boxes: &'b Boxes, count: usize) -> Self {
        Self {
            params: *params,
            boxes,
            nodes: Vec::with_capacity(count),
            prim_ids: Vec::with_capacity(count * 2),
            max_depth: ((default_max_depth(count) as f32 * params.depth_factor) as usize).min(MAX_DEPTH - 1),
            depth_reached: 0,
            cost: 0.0,
            spare: Vec::new(),
        }
    }

    /// A builder for a subtree built on another thread.
    pub(crate) fn sub(&self) -> Self {
        Self {
            params: self.params,
            boxes: self.boxes,
            nodes: Vec::new(),
            prim_ids: Vec::new(),
            max_depth: self.max_depth,
            depth_reached: 0,
            cost: 0.0,
            spare: Vec::new(),
        }
    }

    /// The built tree, over `valid` valid triangles bounded by `bounds`.
    pub(crate) fn finish(self, bounds: Aabb, valid: usize) -> BuiltTree {
        let root = f64::from(bounds.surface_area());
        BuiltTree {
            nodes: self.nodes,
            prim_ids: self.prim_ids,
            bounds,
            depth: self.depth_reached,
            cost: Some(if root > 0.0 && root.is_finite() {
                self.cost / root
            } else {
                0.0
            }),
            valid,
        }
    }

    /// Counts an interior node of cell `cell` in [`Self::cost`].
    pub(crate) fn interior_cost(&mut self, cell: &Aabb) {
        self.cost += f64::from(SahParams::default().traversal_cost) * f64::from(cell.surface_area());
    }

    /// Largest leaf at `depth`.
    pub(crate) fn max_leaf(&self, depth: usize) -> f32 {
        self.params.min_leaf * self.params.leaf_growth.powi(depth as i32)
    }

    pub(crate) fn leaf(&mut self, cell: &Aabb, items: &[u32]) -> Result<(), AccelError> {
        self.cost +=
            f64::from(SahParams::default().intersection_cost) * items.len() as f64 * f64::from(cell.surface_area());
        let offset = self.prim_ids.len();
        if offset > u32::MAX as usize - items.len() || items.len() > MAX_FIELD as usize {
            return Err(too_many_nodes());
        }
        self.prim_ids.extend_from_slice(items);
        self.nodes.push(KdNode::leaf(offset as u32, items.len() as u32));
        Ok(())
    }

    /// [`Self::leaf`] of a list the builder is done with: the list is kept
    /// for a later partition.
    fn leaf_of(&mut self, cell: &Aabb, items: Vec<u32>) -> Result<(), AccelError> {
        let made = self.leaf(cell, &items);
        self.spare.push(items);
        made
    }

    /// The split of a node: `None` makes a leaf.
    fn plan(&self, cell: &Aabb, items: &[u32], depth: usize) -> Option<(usize, f32)> {
        let n = items.len();
        let p = self.params;
        if n as f32 <= self.max_leaf(depth) || depth >= self.max_depth {
            return None;
        }
        let axis = cell.longest_axis();
        let (lo, ext) = (cell.min[axis], cell.extent()[axis]);
        let sa = cell.surface_area();
        if ext <= 0.0 || sa.is_nan() || sa <= 0.0 {
            return None;
        }
        // Bin the box starts and ends.
        let nb = p.bins.max(2);
        let mut starts = [0u32; 64];
        let mut ends = [0u32; 64];
        let nb = nb.min(starts.len());
        let scale = nb as f32 / ext;
        // NOTE: the boxes are not clipped to the cell: `span_bins` sends what
        // lies below the cell to the first bin (a negative float converts to
        // 0) and what lies above it to the last, where its clipped coordinate
        // goes (tested).
        let spans = self.boxes.axis(axis);
        for &id in items {
            let [s, e] = span_bins(spans[id as usize], lo, scale, nb);
            starts[s] += 1;
            ends[e] += 1;
        }
        let ext3 = cell.extent();
        let (k1, k2) = ((axis + 1) % 3, (axis + 2) % 3);
        let (cross, perim) = (ext3[k1] * ext3[k2], ext3[k1] + ext3[k2]);
        let mut best = (f32::INFINITY, 0usize);
        let mut nl = 0u32;
        let mut nr = n as u32;
        for i in 1..nb {
            nl += starts[i - 1];
            nr -= ends[i - 1];
            let wl = ext * i as f32 / nb as f32;
            let pl = 2.0 * (cross + wl * perim) / sa;
            let pr = 2.0 * (cross + (ext - wl) * perim) / sa;
            let c = p.traversal_cost + p.intersection_cost * (pl * nl as f32 + pr * nr as f32);
            if c < best.0 {
                best = (c, i);
            }
        }
        if best.0 >= p.intersection_cost * n as f32 {
            return None;
        }
        let split = lo + ext * best.1 as f32 / nb as f32;
        if split <= cell.min[axis] || split >= cell.max[axis] {
            return None;
        }
        Some((axis, split))
    }

    /// Children cells and item lists; `Err` gives the list back when every
    /// item straddles the plane. `split` lies strictly inside the cell on
    /// `axis`, so an item's clipped box ends at or below it exactly when its
    /// own box does (and starts at or above it likewise).
    #[allow(clippy::type_complexity)]
    pub(crate) fn partition(
        &mut self,
        cell: &Aabb,
        items: Vec<u32>,
        axis: usize,
        split: f32,
    ) -> Result<(Aabb, Vec<u32>, Aabb, Vec<u32>), Vec<u32>> {
        debug_assert!(cell.min[axis] < split && split < cell.max[axis]);
        let n = items.len();
        let mut lcell = *cell;
        lcell.max[axis] = split;
        let mut rcell = *cell;
        rcell.min[axis] = split;
        let spans = self.boxes.axis(axis);
        // PERF: branch-free: every id is written to both lists and each
        // list's end moves past it when it belongs there (the side of a
        // triangle is unpredictable; with 4-byte ids the extra write costs
        // less than the misprediction). The left list takes the input's
        // place (each id read gives at most one left id, written at or
        // before the read position).
        // PERF: the right list is a finished leaf's list when there is one,
        // written without zeroing it first (refits of a 4k-triangle sphere
        // 0.93 of the time with a fresh zeroed list each, 16k 0.88-0.92).
        let mut right = self.spare.pop().unwrap_or_default();
        right.clear();
        right.reserve(n);
        let slots = &mut right.spare_capacity_mut()[..n];
        let mut items = items;
        let (mut w, mut r, mut both) = (0usize, 0usize, 0usize);
        for k in 0..n {
            let id = items[k];
            let [lo, hi] = spans[id as usize];
            let left = lo < split || hi <= split;
            let above = hi > split;
            items[w] = id;
            slots[r].write(id);
            w += usize::from(left);
            r += usize::from(above);
            both += usize::from(left & above);
        }
        if both == n {
            // Every item straddles: each was written over itself.
            self.spare.push(right);
            return Err(items);
        }
        // SAFETY: `r` never passes `k` at the write of step `k` and moves
        // only past a slot just written, so the first `r` slots (within the
        // capacity reserved above) hold ids.
        unsafe { right.set_len(r) };
        items.truncate(w);
        Ok((lcell, items, rcell, right))
    }

    /// Plans and partitions a node; `Ok(None)` when it became a leaf.
    pub(crate) fn split(&mut self, cell: &Aabb, items: Vec<u32>, depth: usize) -> Result<Option<Split>, AccelError> {
        self.depth_reached = self.depth_reached.max(depth);
        let Some((axis, split)) = self.plan(cell, &items, depth) else {
            return self.leaf_of(cell, items).map(|()| None);
        };
        match self.partition(cell, items, axis, split) {
            Ok((lcell, left, rcell, right)) => Ok(Some(Split {
                axis,
                position: split,
                lcell,
                left,
                rcell,
                right,
            })),
            Err(items) => self.leaf_of(cell, items).map(|()| None),
        }
    }

    pub(crate) fn node(&mut self, cell: Aabb, items: Vec<u32>, depth: usize) -> Result<(), AccelError> {
        let Some(Split {
            axis,
            position: split,
            lcell,
            left,
            rcell,
            right,
        }) = self.split(&cell, items, depth)?
        else {
            return Ok(());
        };
        let index = self.nodes.len();
        if index >= MAX_NODES as usize {
            return Err(too_many_nodes());
        }
        self.nodes.push(KdNode::interior(axis, split));
        self.interior_cost(&cell);
        self.node(lcell, left, depth + 1)?;
        let above = self.nodes.len() as u32;
        self.nodes[index].set_above_child(above);
        self.node(rcell, right, depth + 1)
    }

    /// Like [`Self::node`], building the two children on two threads for
    /// `levels` levels when the node is large (the commit runs while the
    /// render threads wait, so the cores are free).
    fn node_parallel(&mut self, cell: Aabb, items: Vec<u32>, depth: usize, levels: u32) -> Result<(), AccelError> {
        if levels == 0 || items.len() < PARALLEL_MIN {
            return self.node(cell, items, depth);
        }
        let Some(Split {
            axis,
            position: split,
            lcell,
            left,
            rcell,
            right,
        }) = self.split(&cell, items, depth)?
        else {
            return Ok(());
        };
        let (mut lb, mut rb) = (self.sub(), self.sub());
        let (lr, rr) = rayon::join(
            || lb.node_parallel(lcell, left, depth + 1, levels - 1),
            || rb.node_parallel(rcell, right, depth + 1, levels - 1),
        );
        lr?;
        rr?;
        self.interior_cost(&cell);
        self.stitch((axis, split), &lb, &rb)
    }

    /// Appends this node, the left subtree right after it, then the right subtree.
    pub(crate) fn stitch(&mut self, split: (usize, f32), lb: &Self, rb: &Self) -> Result<(), AccelError> {
        stitch(
            &mut self.nodes,
            &mut self.prim_ids,
            split,
            (&lb.nodes, &lb.prim_ids),
            (&rb.nodes, &rb.prim_ids),
        )?;
        self.depth_reached = self.depth_reached.max(lb.depth_reached).max(rb.depth_reached);
        self.cost += lb.cost + rb.cost;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use rand::{Rng, SeedableRng, rngs::SmallRng};

    use super::*;

    /// `span_bins` against its scalar twin: inside the cell, on bin borders,
    /// below and above it, NaN, infinities and huge scales.
    #[test]
    fn span_bins_match_the_saturating_casts() {
        let twin = |x: f32, lo: f32, scale: f32, nb: usize| (((x - lo) * scale) as usize).min(nb - 1);
        let mut rng = SmallRng::seed_from_u64(5);
        let specials = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -0.0,
            0.0,
            f32::MAX,
            -f32::MAX,
            1e-40,
        ];
        for round in 0..200_000 {
            let nb = [2, 8, 16, 32, 63, 64][round % 6];
            let lo = rng.random_range(-100.0f32..100.0);
            let ext = if round % 50 == 0 {
                1e-30
            } else {
                rng.random_range(1e-3f32..100.0)
            };
            let scale = nb as f32 / ext;
            let pick = |rng: &mut SmallRng| match rng.random_range(0..10) {
                0 => specials[rng.random_range(0..specials.len())],
                1 => lo + ext * (rng.random_range(0..=nb) as f32 / nb as f32),
                _ => lo + ext * rng.random_range(-0.5f32..1.5),
            };
            let span = [pick(&mut rng), pick(&mut rng)];
            let got = span_bins(span, lo, scale, nb);
            let want = span.map(|x| twin(x, lo, scale, nb));
            assert_eq!(got, want, "{span:?} lo {lo} scale {scale} nb {nb}");
        }
    }

    /// The partition written plainly, as before ids alone: two fresh lists
    /// of boxes clipped to their cells, each box compared as clipped.
    #[allow(clippy::type_complexity)]
    fn plain(
        cell: &Aabb,
        items: &[(u32, Aabb)],
        axis: usize,
        split: f32,
    ) -> (Vec<(u32, Aabb)>, Vec<(u32, Aabb)>, usize) {
        let (mut lcell, mut rcell) = (*cell, *cell);
        lcell.max[axis] = split;
        rcell.min[axis] = split;
        let (mut l, mut r, mut both) = (Vec::new(), Vec::new(), 0);
        for &(id, b) in items {
            let b = b.intersection(*cell);
            if b.max[axis] <= split {
                l.push((id, b));
            } else if b.min[axis] >= split {
                r.push((id, b));
            } else {
                l.push((id, b.intersection(lcell)));
                r.push((id, b.intersection(rcell)));
                both += 1;
            }
        }
        (l, r, both)
    }

    fn ids(list: &[(u32, Aabb)]) -> Vec<u32> {
        list.iter().map(|i| i.0).collect()
    }

    #[test]
    fn id_partition_matches_the_plain_clipped_one_and_gives_straddlers_back_whole() {
        let mut rng = SmallRng::seed_from_u64(12);
        // Boxes reach past the cell on every side, as an item's own box
        // reaches past the cells below the root.
        let cell = Aabb::new(Vec3::splat(1.0), Vec3::splat(9.0));
        let mut straddled = 0;
        for round in 0..200 {
            let n = rng.random_range(1..300);
            let axis = round % 3;
            let items: Vec<(u32, Aabb)> = (0..n)
                .map(|i| {
                    let p = Vec3::new(
                        rng.random_range(0.0..9.5),
                        rng.random_range(0.0..9.5),
                        rng.random_range(0.0..9.5),
                    );
                    let e = Vec3::splat(rng.random_range(0.0..1.5));
                    let mut b = Aabb::new(p, p + e);
                    // Some rounds split where every box straddles.
                    if round % 10 == 0 {
                        b.min[axis] = rng.random_range(0.0..4.0);
                        b.max[axis] = rng.random_range(5.0..10.0);
                    }
                    (i as u32, b)
                })
                .collect();
            let split = if round % 10 == 0 {
                4.5
            } else if round % 20 == 1 {
                // On a box's upper face, then on a box's lower face.
                items[0].1.max[axis].clamp(1.5, 8.5)
            } else if round % 20 == 11 {
                items[0].1.min[axis].clamp(1.5, 8.5)
            } else {
                rng.random_range(1.5..8.5)
            };
            let boxes = Boxes::of(&items.iter().map(|i| i.1).collect::<Vec<_>>());
            let mut b = Fast::new(&FastParams::default(), &boxes, n);
            // A finished leaf's list, shorter or longer than the node's,
            // makes the right list in some rounds: its old ids never show.
            match round % 3 {
                1 => b.spare.push(vec![u32::MAX; 3]),
                2 => b.spare.push(vec![u32::MAX; 2 * n + 7]),
                _ => {}
            }
            let (l, r, both) = plain(&cell, &items, axis, split);
            match b.partition(&cell, ids(&items), axis, split) {
                Ok((lcell, left, rcell, right)) => {
                    assert!(both < items.len());
                    assert_eq!((left, right), (ids(&l), ids(&r)));
                    assert_eq!((lcell.max[axis], rcell.min[axis]), (split, split));
                }
                Err(back) => {
                    straddled += 1;
                    assert_eq!(both, items.len());
                    assert_eq!(back, ids(&items), "every item straddles: the list comes back as it was");
                }
            }
        }
        assert_eq!(straddled, 20);
    }

    #[test]
    fn clipped_coordinates_are_the_ones_clipping_at_every_level_gave() {
        // A fast tree's leaves, rebuilt from the boxes clipped level by
        // level (the plain partition above), hold the same ids.
        let tris = crate::testing::meshgen::bumpy_sphere(3_000, 3, 0.4);
        let (items, boxes, bounds) = items_of(&tris).unwrap();
        let mut fast = Fast::new(&FastParams::default(), &boxes, items.len());
        let mut clipped: Vec<(u32, Aabb)> = items
            .iter()
            .map(|&i| (i, Aabb::from_points(&tris[i as usize])))
            .collect();
        let mut ids_now = items;
        let mut cell = bounds;
        for depth in 0..12 {
            let Some((axis, split)) = fast.plan(&cell, &ids_now, depth) else {
                break;
            };
            let (l, r, _) = plain(&cell, &clipped, axis, split);
            let Ok((lcell, left, rcell, right)) = fast.partition(&cell, ids_now, axis, split) else {
                panic!("a planned split leaves some item on one side");
            };
            assert_eq!((left.clone(), right.clone()), (ids(&l), ids(&r)));
            // Follow the larger side.
            (cell, ids_now, clipped) = if left.len() >= right.len() {
                (lcell, left, l)
            } else {
                (rcell, right, r)
            };
            // Binning the clipped boxes directly picks the same plane.
            let direct = {
                let mut all = vec![Aabb::EMPTY; tris.len()];
                for &(id, bx) in &clipped {
                    all[id as usize] = bx;
                }
                let b2 = Boxes::of(&all);
                Fast::new(&FastParams::default(), &b2, ids_now.len()).plan(&cell, &ids_now, depth + 1)
            };
            assert_eq!(fast.plan(&cell, &ids_now, depth + 1), direct);
        }
    }
}
