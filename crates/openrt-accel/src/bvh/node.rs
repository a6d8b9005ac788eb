//! The wide BVH node: four child boxes in SIMD order.

use wide::f32x4;

use crate::geom::aabb::Aabb;

/// Children per node: one SSE register per box coordinate.
pub const BVH_WIDTH: usize = 4;

/// Wide levels a BVH may have; the builder switches to median splits deep
/// down so that no tree reaches it (checked by [`crate::Bvh::validate`]),
/// and it sizes the traversal stack.
pub const BVH_MAX_DEPTH: usize = 64;

/// Entries of the fixed traversal stack: a node pushes at most
/// `BVH_WIDTH - 1` children and visits the nearest at once.
pub(crate) const STACK: usize = BVH_MAX_DEPTH * (BVH_WIDTH - 1) + 1;

/// `child` value of an unused slot.
pub(crate) const EMPTY_SLOT: u32 = u32::MAX;

/// Flag of a leaf in `child`; the low bits hold the leaf's offset in the
/// tree's index array (a multiple of the block width).
pub(crate) const LEAF_BIT: u32 = 1 << 31;

/// A node of four children, their boxes coordinate by coordinate:
/// `lo[axis]` holds that minimum of each child's box (lane = child).
///
/// An unused slot has an empty box (`+inf` minima, `-inf` maxima) that no
/// ray meets, so the node test needs no occupancy mask. `child[i]` is an
/// interior node's index, or `LEAF_BIT | offset` with `count[i]` triangles.
///
/// PERF: 128 bytes, two cache lines, aligned; the six box rows are read as
/// six SSE loads.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct BvhNode {
    pub(crate) lo: [f32x4; 3],
    pub(crate) hi: [f32x4; 3],
    pub(crate) child: [u32; BVH_WIDTH],
    pub(crate) count: [u32; BVH_WIDTH],
}

const _: () = assert!(size_of::<BvhNode>() == 128);

impl BvhNode {
    /// A node with every slot unused.
    pub(crate) fn empty() -> Self {
        Self {
            lo: [f32x4::splat(f32::INFINITY); 3],
            hi: [f32x4::splat(f32::NEG_INFINITY); 3],
            child: [EMPTY_SLOT; BVH_WIDTH],
            count: [0; BVH_WIDTH],
        }
    }

    /// Box of child `i` (empty for an unused slot).
    #[must_use]
    pub fn child_box(&self, i: usize) -> Aabb {
        let lo = self.lo.map(|v| v.to_array()[i]);
        let hi = self.hi.map(|v| v.to_array()[i]);
        Aabb {
            min: glam::Vec3::from_array(lo),
            max: glam::Vec3::from_array(hi),
        }
    }

    /// Sets child `i`'s box.
    pub(crate) fn set_box(&mut self, i: usize, b: &Aabb) {
        let (lo, hi) = (b.min.to_array(), b.max.to_array());
        for a in 0..3 {
            let mut l = self.lo[a].to_array();
            let mut h = self.hi[a].to_array();
            l[i] = lo[a];
            h[i] = hi[a];
            self.lo[a] = f32x4::from(l);
            self.hi[a] = f32x4::from(h);
        }
    }

    /// The union of the used children's boxes.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        (0..BVH_WIDTH)
            .filter(|&i| self.child[i] != EMPTY_SLOT)
            .fold(Aabb::EMPTY, |b, i| b.union(self.child_box(i)))
    }

    /// What slot `i` holds.
    #[must_use]
    pub fn slot(&self, i: usize) -> BvhSlot {
        let c = self.child[i];
        if c == EMPTY_SLOT {
            BvhSlot::Empty
        } else if c & LEAF_BIT != 0 {
            BvhSlot::Leaf {
                offset: c & !LEAF_BIT,
                count: self.count[i],
            }
        } else {
            BvhSlot::Node(c)
        }
    }
}

/// The content of a node's slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BvhSlot {
    /// Unused.
    Empty,
    /// An interior node, by index.
    Node(u32),
    /// A leaf: `count` entries of the tree's index array from `offset`.
    Leaf {
        /// First entry (a multiple of the block width).
        offset: u32,
        /// Triangles.
        count: u32,
    },
}
