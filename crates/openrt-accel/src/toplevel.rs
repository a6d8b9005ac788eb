//! The top-level BSP over object instances, rebuilt every frame.
//!
//! Wald, Benthin & Slusallek, "Distributed Interactive Ray Tracing of
//! Dynamic Scenes" (IEEE PVG 2003), Algorithm 1: split the axis of largest
//! extent; candidate planes lie only at instance box boundaries; the plane is
//! the candidate nearest the cell centre on the side that holds more
//! instances (between the spatial and the object median); instances that
//! straddle the plane go to both sides; a node becomes a leaf when no valid
//! plane is found (no candidate inside the cell, or one that separates
//! nothing).
//!
//! Traversal uses the same 8-byte nodes and [`crate::traverse`] as object trees.

use crate::kdnode::{KdNode, MAX_DEPTH, MAX_FIELD};
use crate::sah_build::default_max_depth;
use crate::{Aabb, AccelError};

/// A kd-tree over instance world boxes.
#[derive(Clone, Debug, Default)]
pub struct InstanceBsp {
    nodes: Vec<KdNode>,
    items: Vec<u32>,
    bounds: Aabb,
    depth: usize,
}

impl InstanceBsp {
    /// Builds the tree over `boxes`; item `i` of a leaf is an index into
    /// `boxes`. Empty or non-finite boxes are left out.
    pub fn build(boxes: &[Aabb]) -> Result<Self, AccelError> {
        if boxes.len() > MAX_FIELD as usize {
            return Err(AccelError::TooManyPrimitives {
                count: boxes.len(),
                limit: MAX_FIELD as usize,
            });
        }
        let items: Vec<u32> = (0..boxes.len() as u32)
            .filter(|&i| {
                let b = &boxes[i as usize];
                !b.is_empty() && b.is_finite()
            })
            .collect();
        let bounds = items.iter().fold(Aabb::EMPTY, |a, &i| a.union(boxes[i as usize]));
        let mut b = Self {
            nodes: Vec::with_capacity(2 * items.len() + 1),
            items: Vec::with_capacity(2 * items.len()),
            bounds,
            depth: 0,
        };
        let max_depth = default_max_depth(items.len()).min(MAX_DEPTH - 1);
        if items.is_empty() {
            b.nodes.push(KdNode::leaf(0, 0));
        } else {
            b.node(boxes, bounds, items, 0, max_depth)?;
        }
        Ok(b)
    }

    fn leaf(&mut self, items: &[u32]) -> Result<(), AccelError> {
        let offset = self.items.len();
        if offset > u32::MAX as usize - items.len() || items.len() > MAX_FIELD as usize {
            return Err(AccelError::TooManyNodes {
                limit: MAX_FIELD as usize,
            });
        }
        self.items.extend_from_slice(items);
        self.nodes.push(KdNode::leaf(offset as u32, items.len() as u32));
        Ok(())
    }

    fn node(
        &mut self,
        boxes: &[Aabb],
        cell: Aabb,
        items: Vec<u32>,
        depth: usize,
        max_depth: usize,
    ) -> Result<(), AccelError> {
        self.depth = self.depth.max(depth);
        if items.len() <= 1 || depth >= max_depth {
            return self.leaf(&items);
        }
        let axis = cell.longest_axis();
        let (lo, hi) = (cell.min[axis], cell.max[axis]);
        let centre = 0.5 * (lo + hi);
        let left_of_centre = items
            .iter()
            .filter(|&&i| boxes[i as usize].center()[axis] < centre)
            .count();
        let prefer_left = 2 * left_of_centre >= items.len();
        let Some(plane) = nearest_candidate(boxes, &items, axis, lo, hi, centre, prefer_left)
            .or_else(|| nearest_candidate(boxes, &items, axis, lo, hi, centre, !prefer_left))
        else {
            return self.leaf(&items);
        };
        let (mut left, mut right) = (Vec::with_capacity(items.len()), Vec::with_capacity(items.len()));
        for &i in &items {
            let b = &boxes[i as usize];
            let (bmin, bmax) = (b.min[axis], b.max[axis]);
            if bmin < plane || (bmin == plane && bmax == plane) {
                left.push(i);
            }
            if bmax > plane || (bmin == plane && bmax == plane) {
                right.push(i);
            }
        }
        let mut lcell = cell;
        lcell.max[axis] = plane;
        let mut rcell = cell;
        rcell.min[axis] = plane;
        let index = self.nodes.len();
        if index >= MAX_FIELD as usize {
            return Err(AccelError::TooManyNodes {
                limit: MAX_FIELD as usize,
            });
        }
        self.nodes.push(KdNode::interior(axis, plane));
        drop(items);
        self.node(boxes, lcell, left, depth + 1, max_depth)?;
        let above = self.nodes.len() as u32;
        self.nodes[index].set_above_child(above);
        self.node(boxes, rcell, right, depth + 1, max_depth)
    }

    /// The flat node array (root at 0).
    #[must_use]
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// The instances of a leaf node.
    #[inline]
    #[must_use]
    pub fn leaf_items(&self, leaf: KdNode) -> &[u32] {
        let off = leaf.prim_offset() as usize;
        &self.items[off..off + leaf.prim_count() as usize]
    }

    /// Union of the instance boxes (the root cell).
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Deepest leaf.
    #[must_use]
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Number of instance references in leaves.
    #[must_use]
    pub fn references(&self) -> usize {
        self.items.len()
    }

    /// Checks the tree against the boxes it was built from: structure, split
    /// planes inside their cells, and every non-empty box referenced by every
    /// leaf whose cell it overlaps with positive volume or touches.
    pub fn validate(&self, boxes: &[Aabb]) -> Result<(), AccelError> {
        let err = |s: String| Err(AccelError::Invalid(s));
        let mut seen = vec![false; self.nodes.len()];
        let mut stack = vec![(0u32, self.bounds, 0usize)];
        while let Some((i, cell, depth)) = stack.pop() {
            let Some(&n) = self.nodes.get(i as usize) else {
                return err(format!("node index {i} out of range"));
            };
            if std::mem::replace(&mut seen[i as usize], true) || depth >= MAX_DEPTH {
                return err(format!("node {i} reached twice or too deep"));
            }
            if n.is_leaf() {
                let Some(list) = self
                    .items
                    .get(n.prim_offset() as usize..(n.prim_offset() + n.prim_count()) as usize)
                else {
                    return err(format!("leaf {i} range outside the item array"));
                };
                for (j, b) in boxes.iter().enumerate() {
                    if b.is_empty() || !b.is_finite() {
                        if list.contains(&(j as u32)) {
                            return err(format!("leaf {i} names empty box {j}"));
                        }
                        continue;
                    }
                    let overlaps = (0..3).all(|a| {
                        if b.min[a] == b.max[a] {
                            b.min[a] >= cell.min[a] && b.min[a] <= cell.max[a]
                        } else {
                            b.min[a] < cell.max[a] && b.max[a] > cell.min[a]
                        }
                    });
                    if overlaps && !list.contains(&(j as u32)) {
                        return err(format!("box {j} overlaps leaf {i} but is not in it"));
                    }
                }
                continue;
            }
            let (axis, split) = (n.axis(), n.split());
            if !(split >= cell.min[axis] && split <= cell.max[axis]) || n.above_child() <= i + 1 {
                return err(format!("node {i}: bad split {split} or child {}", n.above_child()));
            }
            let (mut l, mut r) = (cell, cell);
            l.max[axis] = split;
            r.min[axis] = split;
            stack.push((i + 1, l, depth + 1));
            stack.push((n.above_child(), r, depth + 1));
        }
        if seen.iter().any(|s| !s) {
            return err("unreachable node".into());
        }
        Ok(())
    }
}

/// The box boundary strictly inside `(lo, hi)` on the requested side of
/// the centre and nearest to it, provided it separates something.
#[allow(clippy::too_many_arguments)]
fn nearest_candidate(
    boxes: &[Aabb],
    items: &[u32],
    axis: usize,
    lo: f32,
    hi: f32,
    centre: f32,
    left: bool,
) -> Option<f32> {
    let mut best: Option<f32> = None;
    for &i in items {
        let b = &boxes[i as usize];
        for v in [b.min[axis], b.max[axis]] {
            let on_side = if left { v <= centre } else { v >= centre };
            if v > lo && v < hi && on_side && best.is_none_or(|p| (v - centre).abs() < (p - centre).abs()) {
                best = Some(v);
            }
        }
    }
    let p = best?;
    // Valid only if some instance lies entirely on one side.
    let n = items.len();
    let nl = items
        .iter()
        .filter(|&&i| {
            let b = &boxes[i as usize];
            b.min[axis] < p || (b.min[axis] == p && b.max[axis] == p)
        })
        .count();
    let nr = items
        .iter()
        .filter(|&&i| {
            let b = &boxes[i as usize];
            b.max[axis] > p || (b.min[axis] == p && b.max[axis] == p)
        })
        .count();
    (nl < n || nr < n).then_some(p)
}
