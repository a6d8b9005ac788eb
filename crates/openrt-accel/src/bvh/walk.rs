//! Single-ray traversal of the wide BVH: one SIMD test of a node's four
//! child boxes, children visited nearest first, a fixed stack.
//!
//! The node test is the robust slab test of Ize ("Robust BVH Ray
//! Traversal", JCGT 2013) for four boxes at once, as in Wald et al. 2008
//! ("Getting rid of packets") and the single-ray kernels of Embree: each
//! lane's far distance is widened by `1 + 2 gamma(3)`, so rounding never
//! drops a box the ray meets, and each near distance is lowered by
//! [`NEAR_SLACK`] relative, so that a triangle whose computed `t` lies a
//! rounding below its box's computed entry is still reached when the
//! closest hit lies in between. The scalar twin `node_test_scalar`
//! computes the same bits (tested).

use wide::f32x4;

use super::node::{BVH_WIDTH, BvhNode, EMPTY_SLOT, LEAF_BIT};
use super::node8::{BVH8_WIDTH, STACK8};
use crate::geom::numeric::gamma;
use crate::geom::ray::Ray;

/// Relative widening of a box's far distance (Ize 2013).
pub(crate) const FAR_WIDEN: f32 = 1.0 + 2.0 * gamma(3);

/// Relative lowering of a box's near distance: far above the rounding of
/// the slab distances (3 roundings) and of the triangle test's `t`, so a
/// triangle whose hit lies at most that far before its box's computed
/// entry is still tested. Visiting a box a little earlier changes no answer.
pub(crate) const NEAR_SLACK: f32 = 1.0 / 65_536.0;

/// A ray's constants for the node test, splatted once per query.
#[derive(Clone, Copy)]
pub(crate) struct NodeRay {
    o: [f32x4; 3],
    inv: [f32x4; 3],
    /// Per axis: the direction is negative (the box's maximum is met first).
    neg: [bool; 3],
    /// Per axis: the direction component is zero (either sign).
    parallel: [bool; 3],
    any_parallel: bool,
    t_min: f32x4,
}

impl NodeRay {
    pub(crate) fn new(ray: &Ray) -> Self {
        let o = ray.origin.to_array();
        let inv = ray.inv_dir.to_array();
        let d = ray.dir.to_array();
        let parallel = d.map(|x| x == 0.0);
        Self {
            o: o.map(f32x4::splat),
            inv: inv.map(f32x4::splat),
            neg: inv.map(f32::is_sign_negative),
            parallel,
            any_parallel: parallel.iter().any(|&p| p),
            t_min: f32x4::splat(ray.t_min),
        }
    }

    /// The children of `node` that the ray may meet before `closest`, as a
    /// mask, with their lowered entry distances.
    #[inline]
    pub(crate) fn test(&self, node: &BvhNode, closest: f32) -> (u32, f32x4) {
        let mut near = self.t_min;
        let mut far = f32x4::splat(f32::INFINITY);
        let mut inside = f32x4::splat(f32::from_bits(u32::MAX));
        for a in 0..3 {
            let (n, f) = if self.neg[a] {
                (node.hi[a], node.lo[a])
            } else {
                (node.lo[a], node.hi[a])
            };
            if self.any_parallel && self.parallel[a] {
                // A ray parallel to the slab: the origin alone decides.
                inside = inside & node.lo[a].simd_le(self.o[a]) & self.o[a].simd_le(node.hi[a]);
                continue;
            }
            near = near.fast_max((n - self.o[a]) * self.inv[a]);
            far = far.fast_min((f - self.o[a]) * self.inv[a]);
        }
        let far = (far * f32x4::splat(FAR_WIDEN)).fast_min(f32x4::splat(closest));
        let near = near - near.abs() * f32x4::splat(NEAR_SLACK);
        let mask = (near.simd_le(far) & inside).to_bitmask();
        (mask & ((1 << BVH_WIDTH) - 1), near)
    }
}

/// The scalar twin of [`NodeRay::test`]: the same operations lane by lane.
#[cfg(test)]
pub(crate) fn node_test_scalar(ray: &Ray, node: &BvhNode, closest: f32) -> (u32, [f32; BVH_WIDTH]) {
    let mut mask = 0;
    let mut nears = [0.0; BVH_WIDTH];
    for (i, slot_near) in nears.iter_mut().enumerate() {
        let (met, near) = box_test_scalar(ray, &node.child_box(i), closest);
        *slot_near = near;
        mask |= u32::from(met) << i;
    }
    (mask, nears)
}

/// One box of the node tests (four- and eight-wide), scalar: whether the
/// ray may meet it before `closest`, and its lowered entry distance. `max`
/// and `min` as `maxps` and `minps` compute them: the second operand
/// unless the first is greater (less).
#[cfg(test)]
pub(crate) fn box_test_scalar(ray: &Ray, b: &crate::geom::aabb::Aabb, closest: f32) -> (bool, f32) {
    let (o, inv, d) = (ray.origin.to_array(), ray.inv_dir.to_array(), ray.dir.to_array());
    let (lo, hi) = (b.min.to_array(), b.max.to_array());
    let (mut near, mut far, mut inside) = (ray.t_min, f32::INFINITY, true);
    for a in 0..3 {
        let (n, f) = if inv[a].is_sign_negative() {
            (hi[a], lo[a])
        } else {
            (lo[a], hi[a])
        };
        if d[a] == 0.0 {
            inside &= lo[a] <= o[a] && o[a] <= hi[a];
            continue;
        }
        let tn = (n - o[a]) * inv[a];
        let tf = (f - o[a]) * inv[a];
        near = if near > tn { near } else { tn };
        far = if far < tf { far } else { tf };
    }
    let far = far * FAR_WIDEN;
    let far = if far < closest { far } else { closest };
    let near = near - near.abs() * NEAR_SLACK;
    (inside && near <= far, near)
}

/// A deferred child: its slot value, triangle count and entry distance.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    count: u32,
    near: f32,
}

/// A wide node's slots as the single-ray walk reads them: child value and
/// triangle count.
pub(crate) trait SlotNode {
    fn slot(&self, i: usize) -> (u32, u32);
}

impl SlotNode for BvhNode {
    #[inline]
    fn slot(&self, i: usize) -> (u32, u32) {
        (self.child[i], self.count[i])
    }
}

/// Walks the children of `nodes` (root 0) that `ray` meets, nearest first,
/// and calls `leaf(offset, count, closest)` for each leaf reached before
/// `closest`, which the callback lowers on a hit; it returns `true` to stop
/// the walk (any hit). Deferred children that begin beyond `closest` are
/// skipped when popped. Returns `true` when the callback stopped the walk.
///
/// `root_box_hit`: the caller clipped the ray to the tree's box already.
#[inline]
pub(crate) fn walk<L>(nodes: &[BvhNode], ray: &Ray, closest: &mut f32, leaf: L) -> bool
where
    L: FnMut(u32, u32, &mut f32) -> bool,
{
    if nodes.is_empty() {
        return false;
    }
    let nr = NodeRay::new(ray);
    walk_nodes(
        nodes,
        closest,
        |node, closest| {
            let (mask, near) = nr.test(node, closest);
            let near = near.to_array();
            (mask, std::array::from_fn(|i| if i < BVH_WIDTH { near[i] } else { 0.0 }))
        },
        leaf,
    )
}

/// The walk of [`walk`] over nodes of up to [`BVH8_WIDTH`] slots:
/// `test(node, closest)` gives the slots the ray meets and their entry
/// distances. Inlined into the four-wide walk and the AVX2 eight-wide one
/// (`walk8.rs`).
#[inline(always)]
#[allow(clippy::inline_always)]
pub(crate) fn walk_nodes<Nd: SlotNode, T, L>(nodes: &[Nd], closest: &mut f32, mut test: T, mut leaf: L) -> bool
where
    T: FnMut(&Nd, f32) -> (u32, [f32; BVH8_WIDTH]),
    L: FnMut(u32, u32, &mut f32) -> bool,
{
    // PERF: the stack is not zeroed (a memset of kilobytes per ray):
    // entries are written before they are read.
    let mut stack = [std::mem::MaybeUninit::<Entry>::uninit(); STACK8];
    let mut sp = 0usize;
    let mut cur = Entry {
        child: 0,
        count: 0,
        near: f32::NEG_INFINITY,
    };
    loop {
        if cur.child & LEAF_BIT != 0 {
            if leaf(cur.child & !LEAF_BIT, cur.count, closest) {
                return true;
            }
        } else {
            let node = &nodes[cur.child as usize];
            let (mut mask, near) = test(node, *closest);
            let entry = |i: usize| {
                let (child, count) = node.slot(i);
                Entry {
                    child,
                    count,
                    near: near[i],
                }
            };
            if mask != 0 {
                // The nearest hit child goes on at once, the others are
                // pushed farthest first.
                if mask.is_power_of_two() {
                    cur = entry(mask.trailing_zeros() as usize);
                    continue;
                }
                let mut order = [0usize; BVH8_WIDTH];
                let mut n = 0;
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    // Insertion by entry distance, farthest first.
                    let mut j = n;
                    while j > 0 && near[order[j - 1]] < near[i] {
                        order[j] = order[j - 1];
                        j -= 1;
                    }
                    order[j] = i;
                    n += 1;
                }
                for &i in &order[..n - 1] {
                    stack[sp].write(entry(i));
                    sp += 1;
                }
                cur = entry(order[n - 1]);
                debug_assert!(cur.child != EMPTY_SLOT);
                continue;
            }
        }
        // Pop the next deferred child that begins before the closest hit.
        loop {
            if sp == 0 {
                return false;
            }
            sp -= 1;
            // SAFETY: entries below `sp` were written by the pushes above.
            cur = unsafe { stack[sp].assume_init() };
            if cur.near <= *closest {
                break;
            }
        }
    }
}
