//! The eight-wide node of single rays on AVX2 CPUs, collapsed from the
//! four-wide tree.
//!
//! A four-wide node's children are pulled up into its slots, the largest
//! interior child first (by surface area, the SAH's measure of how often a
//! ray meets it), while its children fit in the eight slots: the collapse of
//! a binary or narrow tree into a wide one that Embree and Wald et al. 2008
//! ("Getting rid of packets") use, here from four to eight. The leaves stay
//! the four-wide tree's (same offsets into the same blocks), so a walk over
//! either tree tests the same triangles with the same kernel and gives the
//! same answers; only the number of node steps falls.

use super::node::{BVH_MAX_DEPTH, BVH_WIDTH, BvhNode, EMPTY_SLOT, LEAF_BIT};
use crate::geom::aabb::Aabb;

/// Children of an eight-wide node: one AVX register per box coordinate.
pub(crate) const BVH8_WIDTH: usize = 8;

/// Entries of the eight-wide walk's fixed stack: a node pushes at most seven
/// children, and the collapsed tree is no deeper than the four-wide one.
pub(crate) const STACK8: usize = BVH_MAX_DEPTH * (BVH8_WIDTH - 1) + 1;

/// Eight children, their boxes coordinate by coordinate (`lo[axis][child]`),
/// as [`BvhNode`] with twice the slots; unused slots have empty boxes.
///
/// PERF: 256 bytes, four cache lines, aligned; the six box rows are six AVX
/// loads.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct Node8 {
    pub(crate) lo: [[f32; BVH8_WIDTH]; 3],
    pub(crate) hi: [[f32; BVH8_WIDTH]; 3],
    pub(crate) child: [u32; BVH8_WIDTH],
    pub(crate) count: [u32; BVH8_WIDTH],
}

const _: () = assert!(size_of::<Node8>() == 256);

impl Node8 {
    fn empty() -> Self {
        Self {
            lo: [[f32::INFINITY; BVH8_WIDTH]; 3],
            hi: [[f32::NEG_INFINITY; BVH8_WIDTH]; 3],
            child: [EMPTY_SLOT; BVH8_WIDTH],
            count: [0; BVH8_WIDTH],
        }
    }

    /// Box of child `i` (empty for an unused slot).
    pub(crate) fn child_box(&self, i: usize) -> Aabb {
        Aabb {
            min: glam::Vec3::new(self.lo[0][i], self.lo[1][i], self.lo[2][i]),
            max: glam::Vec3::new(self.hi[0][i], self.hi[1][i], self.hi[2][i]),
        }
    }

    fn set(&mut self, i: usize, slot: &Slot) {
        let (lo, hi) = (slot.bounds.min.to_array(), slot.bounds.max.to_array());
        for a in 0..3 {
            self.lo[a][i] = lo[a];
            self.hi[a][i] = hi[a];
        }
        self.child[i] = slot.child;
        self.count[i] = slot.count;
    }
}

/// A used slot of a four-wide node: box, child value and triangle count.
#[derive(Clone, Copy)]
struct Slot {
    bounds: Aabb,
    child: u32,
    count: u32,
}

fn slots_of(node: &BvhNode) -> impl Iterator<Item = Slot> + '_ {
    (0..BVH_WIDTH).filter(|&i| node.child[i] != EMPTY_SLOT).map(|i| Slot {
        bounds: node.child_box(i),
        child: node.child[i],
        count: node.count[i],
    })
}

/// The eight-wide tree of a four-wide `nodes` (root 0): each node's slots
/// are filled by pulling up the largest interior child whose children fit.
/// Interior children follow their parents, as in the four-wide array.
pub(crate) fn collapse(nodes: &[BvhNode]) -> Vec<Node8> {
    let mut out = Vec::with_capacity(nodes.len() / 2 + 1);
    let Some(root) = nodes.first() else {
        return out;
    };
    out.push(Node8::empty());
    // (index in `out`, the slots it will hold)
    let mut work: Vec<(usize, Vec<Slot>)> = vec![(0, slots_of(root).collect())];
    while let Some((at, mut slots)) = work.pop() {
        loop {
            let used = |s: &Slot| slots_of(&nodes[s.child as usize]).count();
            let pick = slots
                .iter()
                .enumerate()
                .filter(|(_, s)| s.child & LEAF_BIT == 0 && slots.len() - 1 + used(s) <= BVH8_WIDTH)
                .max_by(|(_, a), (_, b)| a.bounds.surface_area().total_cmp(&b.bounds.surface_area()))
                .map(|(i, _)| i);
            let Some(i) = pick else { break };
            let pulled = slots.swap_remove(i);
            slots.extend(slots_of(&nodes[pulled.child as usize]));
        }
        let mut node = Node8::empty();
        for (i, s) in slots.iter().enumerate() {
            let mut s = *s;
            if s.child & LEAF_BIT == 0 {
                let child = out.len();
                out.push(Node8::empty());
                work.push((child, slots_of(&nodes[s.child as usize]).collect()));
                s.child = child as u32;
            }
            node.set(i, &s);
        }
        out[at] = node;
    }
    out
}
