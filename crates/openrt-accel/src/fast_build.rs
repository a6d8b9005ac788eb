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

use crate::SahParams;
use crate::kdnode::{KdNode, MAX_DEPTH, MAX_FIELD, MAX_NODES, stitch, too_many_nodes};
use crate::sah_build::{BuiltTree, default_max_depth};
use crate::{Aabb, AccelError, Triangle};

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

/// Smallest node built in parallel.
pub(crate) const PARALLEL_MIN: usize = 4096;

/// Default [`FastParams::refit_cost_limit`]: a refitted tree may cost 25%
/// more than the last full build before it is rebuilt (measured on the
/// museum's animart in docs/PERFORMANCE.md).
pub const DEFAULT_REFIT_COST_LIMIT: f64 = 1.25;

/// A primitive and its box clipped to the current cell.
pub(crate) type Item = (u32, Aabb);

/// The valid triangles as items, with the box around them.
pub(crate) fn items_of(tris: &[Triangle], valid: &[bool]) -> Result<(Vec<Item>, Aabb), AccelError> {
    if tris.len() > MAX_FIELD as usize {
        return Err(AccelError::TooManyPrimitives {
            count: tris.len(),
            limit: MAX_FIELD as usize,
        });
    }
    let item = |(i, t): (usize, &Triangle)| valid[i].then(|| (i as u32, Aabb::from_points(t)));
    let items: Vec<Item> = tris.iter().enumerate().filter_map(item).collect();
    let bounds = items.iter().fold(Aabb::EMPTY, |b, i| b.union(i.1));
    Ok((items, bounds))
}

/// Levels of a tree built on two threads each: one per doubling of the
/// threads of the rayon pool the build runs in (the commit lends it its
/// pool, so no thread is spawned per build).
pub(crate) fn parallel_levels(params: &FastParams) -> u32 {
    if params.parallel {
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

pub(crate) fn build_fast(tris: &[Triangle], valid: &[bool], params: &FastParams) -> Result<BuiltTree, AccelError> {
    let (items, bounds) = items_of(tris, valid)?;
    let mut b = Fast::new(params, items.len());
    if items.is_empty() {
        b.nodes.push(KdNode::leaf(0, 0));
    } else {
        b.node_parallel(bounds, items, 0, parallel_levels(params))?;
    }
    Ok(b.finish(bounds))
}

/// A planned split with its children.
pub(crate) struct Split {
    pub(crate) axis: usize,
    pub(crate) position: f32,
    pub(crate) lcell: Aabb,
    pub(crate) left: Vec<Item>,
    pub(crate) rcell: Aabb,
    pub(crate) right: Vec<Item>,
}

/// A tree under construction: depth-first nodes and leaf lists.
pub(crate) struct Fast {
    params: FastParams,
    pub(crate) nodes: Vec<KdNode>,
    pub(crate) prim_ids: Vec<u32>,
    pub(crate) max_depth: usize,
    pub(crate) depth_reached: usize,
    /// Sum over the nodes of cell area times node cost (a step for an
    /// interior node, a test per reference for a leaf, at the costs of
    /// [`KdTree::sah_cost`](crate::KdTree::sah_cost)).
    pub(crate) cost: f64,
}

impl Fast {
    /// An empty builder for `count` primitives.
    pub(crate) fn new(params: &FastParams, count: usize) -> Self {
        Self {
            params: *params,
            nodes: Vec::with_capacity(count),
            prim_ids: Vec::with_capacity(count * 2),
            max_depth: ((default_max_depth(count) as f32 * params.depth_factor) as usize).min(MAX_DEPTH - 1),
            depth_reached: 0,
            cost: 0.0,
        }
    }

    /// A builder for a subtree built on another thread.
    pub(crate) fn sub(&self) -> Self {
        Self {
            params: self.params,
            nodes: Vec::new(),
            prim_ids: Vec::new(),
            max_depth: self.max_depth,
            depth_reached: 0,
            cost: 0.0,
        }
    }

    pub(crate) fn finish(self, bounds: Aabb) -> BuiltTree {
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

    pub(crate) fn leaf(&mut self, cell: &Aabb, items: &[Item]) -> Result<(), AccelError> {
        self.cost +=
            f64::from(SahParams::default().intersection_cost) * items.len() as f64 * f64::from(cell.surface_area());
        let offset = self.prim_ids.len();
        if offset > u32::MAX as usize - items.len() || items.len() > MAX_FIELD as usize {
            return Err(too_many_nodes());
        }
        self.prim_ids.extend(items.iter().map(|i| i.0));
        self.nodes.push(KdNode::leaf(offset as u32, items.len() as u32));
        Ok(())
    }

    /// The split of a node: `None` makes a leaf.
    fn plan(&self, cell: &Aabb, items: &[Item], depth: usize) -> Option<(usize, f32)> {
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
        let bin = |x: f32| (((x - lo) * scale) as usize).min(nb - 1);
        for (_, b) in items {
            starts[bin(b.min[axis])] += 1;
            ends[bin(b.max[axis])] += 1;
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

    /// Children cells and item lists; `None` when every item straddles.
    #[allow(clippy::type_complexity)]
    pub(crate) fn partition(
        cell: &Aabb,
        items: Vec<Item>,
        axis: usize,
        split: f32,
    ) -> Result<(Aabb, Vec<Item>, Aabb, Vec<Item>), Vec<Item>> {
        let n = items.len();
        let mut lcell = *cell;
        lcell.max[axis] = split;
        let mut rcell = *cell;
        rcell.min[axis] = split;
        let mut both = 0usize;
        // PERF: the left list takes the input's place (each item read gives
        // at most one left item, written at or before the read position);
        // the right list is allocated once at its largest size (no growth:
        // reallocations and their copies were 7% of a refit).
        let mut right = Vec::with_capacity(n);
        let mut items = items;
        let mut w = 0usize;
        for r in 0..n {
            let (id, b) = items[r];
            if b.max[axis] <= split {
                items[w] = (id, b);
                w += 1;
            } else if b.min[axis] >= split {
                right.push((id, b));
            } else {
                items[w] = (id, b.intersection(lcell));
                w += 1;
                right.push((id, b.intersection(rcell)));
                both += 1;
            }
        }
        if both == n {
            // Every item straddles: its left half overwrote it. An item's
            // box lies inside its cell (the root cell bounds every box, a
            // child's items are clipped to it), so the two halves' union is
            // the box again, bit for bit: the list goes back as it came.
            for (k, it) in right.iter().enumerate() {
                items[k].1 = items[k].1.union(it.1);
            }
            return Err(items);
        }
        items.truncate(w);
        Ok((lcell, items, rcell, right))
    }

    /// Plans and partitions a node; `Ok(None)` when it became a leaf.
    pub(crate) fn split(&mut self, cell: &Aabb, items: Vec<Item>, depth: usize) -> Result<Option<Split>, AccelError> {
        self.depth_reached = self.depth_reached.max(depth);
        let Some((axis, split)) = self.plan(cell, &items, depth) else {
            return self.leaf(cell, &items).map(|()| None);
        };
        match Self::partition(cell, items, axis, split) {
            Ok((lcell, left, rcell, right)) => Ok(Some(Split {
                axis,
                position: split,
                lcell,
                left,
                rcell,
                right,
            })),
            Err(items) => self.leaf(cell, &items).map(|()| None),
        }
    }

    pub(crate) fn node(&mut self, cell: Aabb, items: Vec<Item>, depth: usize) -> Result<(), AccelError> {
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
    fn node_parallel(&mut self, cell: Aabb, items: Vec<Item>, depth: usize, levels: u32) -> Result<(), AccelError> {
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

    /// The partition written plainly: two fresh lists.
    fn plain(cell: &Aabb, items: &[Item], axis: usize, split: f32) -> (Vec<Item>, Vec<Item>, usize) {
        let (mut lcell, mut rcell) = (*cell, *cell);
        lcell.max[axis] = split;
        rcell.min[axis] = split;
        let (mut l, mut r, mut both) = (Vec::new(), Vec::new(), 0);
        for &(id, b) in items {
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

    #[test]
    fn in_place_partition_matches_the_plain_one_and_gives_straddlers_back_whole() {
        let mut rng = SmallRng::seed_from_u64(12);
        let cell = Aabb::new(Vec3::ZERO, Vec3::splat(10.0));
        for round in 0..200 {
            let n = rng.random_range(1..300);
            let items: Vec<Item> = (0..n)
                .map(|i| {
                    let p = Vec3::new(
                        rng.random_range(0.0..9.0),
                        rng.random_range(0.0..9.0),
                        rng.random_range(0.0..9.0),
                    );
                    let e = Vec3::splat(rng.random_range(0.0..1.0));
                    (i as u32, Aabb::new(p, (p + e).min(Vec3::splat(10.0))))
                })
                .collect();
            let axis = round % 3;
            // Some rounds split where every box straddles.
            let split = if round % 10 == 0 {
                4.5
            } else {
                rng.random_range(0.5..9.5)
            };
            let items = if round % 10 == 0 {
                items
                    .into_iter()
                    .map(|(id, mut b)| {
                        b.min[axis] = 4.0;
                        b.max[axis] = 5.0;
                        (id, b)
                    })
                    .collect()
            } else {
                items
            };
            let (l, r, both) = plain(&cell, &items, axis, split);
            match Fast::partition(&cell, items.clone(), axis, split) {
                Ok((_, left, _, right)) => {
                    assert!(both < items.len());
                    assert_eq!((left, right), (l, r));
                }
                Err(back) => {
                    assert_eq!(both, items.len());
                    assert_eq!(back, items, "every item straddles: the list comes back as it was");
                }
            }
        }
    }
}
