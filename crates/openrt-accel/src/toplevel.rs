//! The top-level BSP over object instances, rebuilt every frame.
//!
//! Wald, Benthin & Slusallek, "Distributed Interactive Ray Tracing of
//! Dynamic Scenes" (IEEE PVG 2003), Algorithm 1: split the axis of largest
//! extent (the next axis only if that one has no valid plane); candidate planes lie only at instance box boundaries; the plane is
//! the candidate nearest the cell centre on the side that holds more
//! instances (between the spatial and the object median); instances that
//! straddle the plane go to both sides; a node becomes a leaf when no valid
//! plane is found. Valid here means: strictly inside the cell, both children
//! hold fewer instances than the parent, and at most half of the instances
//! straddle (beyond that, duplication costs more than the split saves).
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
        let items: Vec<Item> = boxes
            .iter()
            .enumerate()
            .filter(|(_, b)| !b.is_empty() && b.is_finite())
            .map(|(i, b)| Item { b: *b, id: i as u32 })
            .collect();
        let bounds = items.iter().fold(Aabb::EMPTY, |a, it| a.union(it.b));
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
            b.node(bounds, items, 0, max_depth)?;
        }
        // NOTE: checked after every build in debug-assertion builds (all tests), up to a size.
        #[cfg(debug_assertions)]
        if boxes.len() <= 2_000
            && let Err(e) = b.validate(boxes)
        {
            panic!("instance BSP build produced an invalid tree: {e}");
        }
        Ok(b)
    }

    fn leaf(&mut self, items: &[Item]) -> Result<(), AccelError> {
        let offset = self.items.len();
        if offset > u32::MAX as usize - items.len() || items.len() > MAX_FIELD as usize {
            return Err(AccelError::TooManyNodes {
                limit: MAX_FIELD as usize,
            });
        }
        self.items.extend(items.iter().map(|it| it.id));
        self.nodes.push(KdNode::leaf(offset as u32, items.len() as u32));
        Ok(())
    }

    fn node(&mut self, cell: Aabb, items: Vec<Item>, depth: usize, max_depth: usize) -> Result<(), AccelError> {
        self.depth = self.depth.max(depth);
        if items.len() <= 1 || depth >= max_depth {
            return self.leaf(&items);
        }
        // The axis of largest extent first; the others only when it has no valid plane.
        let ext = cell.extent();
        let mut axes = [0usize, 1, 2];
        axes.sort_by(|&a, &b| ext[b].total_cmp(&ext[a]));
        let Some((axis, plane)) = axes
            .into_iter()
            .find_map(|axis| choose_plane(&items, &cell, axis).map(|p| (axis, p)))
        else {
            return self.leaf(&items);
        };
        let (nl, nr) = side_counts(&items, axis, plane);
        // PERF: branch-free partition into exactly sized buffers.
        let filler = Item { b: Aabb::EMPTY, id: 0 };
        let (mut left, mut right) = (vec![filler; nl + 1], vec![filler; nr + 1]);
        let (mut il, mut ir) = (0usize, 0usize);
        for it in &items {
            let (bmin, bmax) = (it.b.min[axis], it.b.max[axis]);
            let flat_on_plane = bmin == plane && bmax == plane;
            left[il] = *it;
            il += usize::from(bmin < plane || flat_on_plane);
            right[ir] = *it;
            ir += usize::from(bmax > plane || flat_on_plane);
        }
        left.truncate(il);
        right.truncate(ir);
        drop(items);
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
        self.node(lcell, left, depth + 1, max_depth)?;
        let above = self.nodes.len() as u32;
        self.nodes[index].set_above_child(above);
        self.node(rcell, right, depth + 1, max_depth)
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

/// An instance box and its index.
#[derive(Clone, Copy)]
struct Item {
    b: Aabb,
    id: u32,
}

/// Algorithm 1's plane on `axis`: the box boundary strictly inside the cell
/// nearest the centre on the side holding more instances (the other side
/// if that one is not valid), or `None`.
fn choose_plane(items: &[Item], cell: &Aabb, axis: usize) -> Option<f32> {
    let (lo, hi) = (cell.min[axis], cell.max[axis]);
    if hi <= lo {
        return None;
    }
    let centre = 0.5 * (lo + hi);
    // One pass: which side is crowded, and the nearest boundary on each side.
    // PERF: written without data-dependent branches (random boxes make
    // them unpredictable); the selects compile to min/max and blends.
    let (mut left_of_centre, mut best_l, mut best_r) = (0usize, f32::NEG_INFINITY, f32::INFINITY);
    for it in items {
        let (bmin, bmax) = (it.b.min[axis], it.b.max[axis]);
        left_of_centre += usize::from(bmin + bmax < 2.0 * centre);
        for v in [bmin, bmax] {
            let inside = v > lo && v < hi;
            best_l = best_l.max(if inside && v <= centre { v } else { f32::NEG_INFINITY });
            best_r = best_r.min(if inside && v >= centre { v } else { f32::INFINITY });
        }
    }
    let (first, second) = if 2 * left_of_centre >= items.len() {
        (best_l, best_r)
    } else {
        (best_r, best_l)
    };
    [first, second]
        .into_iter()
        .filter(|p| p.is_finite())
        .find(|&p| valid(items, axis, p))
}

/// Both sides lose instances and at most half of them straddle: a plane
/// that duplicates more costs more than it separates.
fn valid(items: &[Item], axis: usize, p: f32) -> bool {
    let n = items.len();
    let (nl, nr) = side_counts(items, axis, p);
    nl < n && nr < n && 2 * (nl + nr - n) <= n
}

/// Instances that go left and right of plane `p` (straddlers count twice).
fn side_counts(items: &[Item], axis: usize, p: f32) -> (usize, usize) {
    let (mut nl, mut nr) = (0usize, 0usize);
    for it in items {
        let (bmin, bmax) = (it.b.min[axis], it.b.max[axis]);
        let flat_on_plane = bmin == p && bmax == p;
        nl += usize::from(bmin < p || flat_on_plane);
        nr += usize::from(bmax > p || flat_on_plane);
    }
    (nl, nr)
}
