//! Packets walking the wide BVH together (Wald, Boulos & Shirley, "Ray
//! tracing deformable scenes using dynamic bounding volume hierarchies",
//! ACM TOG 2007): one node fetch per packet, whole-packet culling of a
//! node's four children by the packet's frustum (shared origin or end
//! point) or, without one, by interval arithmetic over the lanes, then the
//! first-active-lane test per child: lanes are tested four at a time until
//! a group has a hit; earlier lanes miss and are dropped, later ones are
//! carried into the child untested. Leaves test each triangle against all
//! carried lanes at once (`leaf_blocks.rs`), each lane over its own bound.
//!
//! Every lane's answer is the single-ray walk's: the lane tests are the
//! single-ray node test lane by lane (the same operations, the same
//! decisions), the culling tests reject only boxes no lane reaches, carried
//! lanes only test more triangles, and the tie rule makes the closest hit
//! independent of the order in which triangles are met (tested against
//! the single-ray walk on every shipped scene).

use wide::f32x4;

use super::node::{BVH_WIDTH, BvhNode, EMPTY_SLOT, LEAF_BIT, STACK};
use super::walk::{FAR_WIDEN, NEAR_SLACK};
use crate::geom::box_quad::BoxQuad;
use crate::geom::ray::Ray;
use crate::packet::boxes::PacketBoxes;
use crate::packet::frustum::Frustum;
use crate::packet::interval::PacketInterval;

/// Lane groups of four in the widest packet.
const MAX_GROUPS: usize = crate::packet::width::MAX_LANES / 4;

/// A packet's rays four lanes to a register, for the lane test.
pub(crate) struct LaneRays {
    o: [[f32x4; MAX_GROUPS]; 3],
    inv: [[f32x4; MAX_GROUPS]; 3],
    t_min: [f32x4; MAX_GROUPS],
    groups: usize,
}

/// Lanes with a zero direction component (either sign): their slab tests
/// need the origin-only rule of the single-ray test, so they walk alone.
pub(crate) fn parallel_lanes<const N: usize>(rays: &[Ray; N], lanes: u32) -> u32 {
    crate::packet::width::lanes_of(lanes).fold(0, |m, l| {
        m | (u32::from(rays[l].dir.cmpeq(glam::Vec3::ZERO).any()) << l)
    })
}

impl LaneRays {
    pub(crate) fn new<const N: usize>(rays: &[Ray; N]) -> Self {
        let groups = N / 4;
        let lanes4 = |f: &dyn Fn(&Ray) -> f32| -> [f32x4; MAX_GROUPS] {
            std::array::from_fn(|g| {
                if g < groups {
                    f32x4::new(std::array::from_fn(|i| f(&rays[g * 4 + i])))
                } else {
                    f32x4::ZERO
                }
            })
        };
        Self {
            o: [
                lanes4(&|r| r.origin.x),
                lanes4(&|r| r.origin.y),
                lanes4(&|r| r.origin.z),
            ],
            inv: [
                lanes4(&|r| r.inv_dir.x),
                lanes4(&|r| r.inv_dir.y),
                lanes4(&|r| r.inv_dir.z),
            ],
            t_min: lanes4(&|r| r.t_min),
            groups,
        }
    }

    /// [`LaneRays::new`] from the packet's lanes already laid out (the same
    /// values: `PacketBoxes` holds the rays' origins, reciprocals and near
    /// bounds lane by lane), four lanes to a load instead of a gather from
    /// each ray.
    pub(crate) fn from_laid<const N: usize>(b: &PacketBoxes<N>) -> Self {
        let groups = N / 4;
        let lanes4 = |v: &[f32; N]| -> [f32x4; MAX_GROUPS] {
            std::array::from_fn(|g| {
                if g < groups {
                    f32x4::new([v[4 * g], v[4 * g + 1], v[4 * g + 2], v[4 * g + 3]])
                } else {
                    f32x4::ZERO
                }
            })
        };
        Self {
            o: [lanes4(&b.o[0]), lanes4(&b.o[1]), lanes4(&b.o[2])],
            inv: [lanes4(&b.inv[0]), lanes4(&b.inv[1]), lanes4(&b.inv[2])],
            t_min: lanes4(&b.t_min),
            groups,
        }
    }

    /// The single-ray node test of child `i` of `node` for the four lanes
    /// of group `g`, each up to its `closest`: the lanes that may meet the
    /// box, and their lowered entry distances.
    ///
    /// NOTE: `min`/`max` of the two slab distances pick what the single-ray
    /// test picks by the direction's sign (for a box with `lo <= hi` and a
    /// non-zero reciprocal, rounding keeps the order), so the decisions are
    /// the same.
    #[inline]
    pub(super) fn test(&self, node: &BvhNode, i: usize, g: usize, closest: f32x4) -> (u32, f32x4) {
        let mut near = self.t_min[g];
        let mut far = f32x4::splat(f32::INFINITY);
        for a in 0..3 {
            let lo = f32x4::splat(node.lo[a].to_array()[i]);
            let hi = f32x4::splat(node.hi[a].to_array()[i]);
            let t1 = (lo - self.o[a][g]) * self.inv[a][g];
            let t2 = (hi - self.o[a][g]) * self.inv[a][g];
            near = near.fast_max(t1.fast_min(t2));
            far = far.fast_min(t1.fast_max(t2));
        }
        decide(near, far, closest)
    }

    /// The lanes of `lanes` whose test against child `i` of `node` meets
    /// it ([`LaneRays::test`] group by group, each lane up to its `closest`).
    #[inline]
    pub(super) fn meeting<const N: usize>(&self, node: &BvhNode, i: usize, lanes: u32, closest: &[f32; N]) -> u32 {
        let mut met = 0;
        for g in 0..self.groups {
            let want = (lanes >> (4 * g)) & 0xF;
            if want != 0 {
                let bound = f32x4::new(std::array::from_fn(|k| closest[g * 4 + k]));
                met |= (self.test(node, i, g, bound).0 & want) << (4 * g);
            }
        }
        met
    }

    /// The same test for one lane `l` against all four children of `node`
    /// at once: lane `l`'s bits of [`LaneRays::test`] child by child.
    #[inline]
    pub(super) fn test_lane(&self, node: &BvhNode, l: usize, closest: f32) -> (u32, f32x4) {
        let (g, i) = (l / 4, l % 4);
        let pick = |v: f32x4| f32x4::splat(v.to_array()[i]);
        let mut near = pick(self.t_min[g]);
        let mut far = f32x4::splat(f32::INFINITY);
        for a in 0..3 {
            let (o, inv) = (pick(self.o[a][g]), pick(self.inv[a][g]));
            let t1 = (node.lo[a] - o) * inv;
            let t2 = (node.hi[a] - o) * inv;
            near = near.fast_max(t1.fast_min(t2));
            far = far.fast_min(t1.fast_max(t2));
        }
        decide(near, far, f32x4::splat(closest))
    }
}

/// The end of both lane tests: the far distances widened (Ize 2013) and
/// cut at `closest`, the near ones lowered by [`NEAR_SLACK`]; the boxes
/// met and their entries.
#[inline]
fn decide(near: f32x4, far: f32x4, closest: f32x4) -> (u32, f32x4) {
    let far = (far * f32x4::splat(FAR_WIDEN)).fast_min(closest);
    let near = near - near.abs() * f32x4::splat(NEAR_SLACK);
    (near.simd_le(far).to_bitmask() & 0xF, near)
}

/// Whole-packet culling of a node's children, and whether leaves take only
/// the lanes that meet their boxes.
pub(crate) struct Cull<'a> {
    by: CullBy<'a>,
    /// Lanes carried into a leaf child are tested against its box first
    /// (scattered packets: `super::EXACT_LEAF_SPREAD`).
    exact_leaves: bool,
}

/// What culls a packet's children.
enum CullBy<'a> {
    /// The lanes' frustum.
    Frustum(&'a Frustum),
    /// Interval arithmetic over the lanes (and the largest bound of the packet).
    Interval(PacketInterval),
    /// None (every child goes on to the lane test).
    None,
}

impl Cull<'_> {
    /// The packet's culling: its frustum, else intervals over its lanes.
    /// (`boxes`: the lanes laid out, needed only without a frustum).
    pub(crate) fn of<'a, const N: usize>(
        frustum: Option<&'a Frustum>,
        boxes: Option<&PacketBoxes<N>>,
        lanes: u32,
    ) -> Cull<'a> {
        let by = match (frustum, boxes) {
            (Some(f), _) => CullBy::Frustum(f),
            (None, Some(b)) => PacketInterval::new(b, lanes).map_or(CullBy::None, CullBy::Interval),
            (None, None) => CullBy::None,
        };
        Cull {
            by,
            exact_leaves: false,
        }
    }

    /// The same culling, with leaves taking only the lanes that meet their
    /// boxes when `on`.
    pub(crate) fn with_exact_leaves(self, on: bool) -> Self {
        Self {
            exact_leaves: on,
            ..self
        }
    }

    /// The children of `node` that no lane reaches; `t_max()`: the
    /// farthest bound of the lanes, asked for only by the intervals.
    #[inline]
    fn rejects(&self, node: &BvhNode, t_max: impl FnOnce() -> f32) -> u32 {
        let quad = || BoxQuad {
            min: node.lo,
            max: node.hi,
        };
        match &self.by {
            CullBy::Frustum(f) => f.rejects_box_quad(&quad()),
            CullBy::Interval(iv) => iv.rejects_box_quad(&quad(), t_max()),
            CullBy::None => 0,
        }
    }
}

/// A deferred child and the lanes carried into it.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    count: u32,
    lanes: u32,
}

/// Walks the packet's `lanes` through `nodes` (see the module docs) and
/// calls `leaf(offset, count, lanes, closest)` for each leaf reached with
/// the lanes carried into it (only those whose lane test meets the leaf's
/// box, for a `cull` with exact leaves); the callback lowers `closest` for
/// its hits and returns the lanes that are done (any hit), which leave the
/// walk.
/// Returns the lanes done.
#[inline]
pub(crate) fn walk_packet<const N: usize, L>(
    nodes: &[BvhNode],
    lr: &LaneRays,
    lanes: u32,
    closest: &mut [f32; N],
    cull: &Cull<'_>,
    mut leaf: L,
) -> u32
where
    L: FnMut(u32, u32, u32, &mut [f32; N]) -> u32,
{
    if nodes.is_empty() || lanes == 0 {
        return 0;
    }
    let exact_leaves = cull.exact_leaves;
    let mut live = lanes;
    // PERF: not zeroed; entries are written before they are read.
    let mut stack = [std::mem::MaybeUninit::<Entry>::uninit(); STACK];
    let mut sp = 0usize;
    let mut cur = Entry {
        child: 0,
        count: 0,
        lanes,
    };
    loop {
        let active = cur.lanes & live;
        if active != 0 {
            if cur.child & LEAF_BIT != 0 {
                live &= !leaf(cur.child & !LEAF_BIT, cur.count, active, closest);
                if live == 0 {
                    return lanes;
                }
            } else {
                let node = &nodes[cur.child as usize];
                // PERF: the lanes' farthest bound only for the intervals
                // (a frustum does not use it): folding it at every node was
                // a tenth of kitchen's primary queries.
                let far = || crate::packet::width::lanes_of(active).fold(f32::NEG_INFINITY, |m, l| m.max(closest[l]));
                let occupied = (0..BVH_WIDTH).fold(0u32, |m, i| m | (u32::from(node.child[i] != EMPTY_SLOT) << i));
                let mut kids = [(0u32, 0.0f32, 0usize); BVH_WIDTH];
                let mut n = 0;
                // The first active lane against all four children at once
                // (Wald, Boulos & Shirley 2007): a child it meets takes
                // every active lane along; the others, unless the packet's
                // culling rejects them, search on by groups.
                // NOTE: `occupied` first: the min/max slab test passes the
                // empty boxes of unused slots.
                let first = active.trailing_zeros() as usize;
                let (met, near) = lr.test_lane(node, first, closest[first]);
                let near = near.to_array();
                let mut along = occupied & met;
                let rest = occupied & !met;
                let mut cand = if rest == 0 { 0 } else { rest & !cull.rejects(node, far) };
                while along != 0 {
                    let i = along.trailing_zeros() as usize;
                    along &= along - 1;
                    // Only the lanes that meet a leaf's box, when exact.
                    let lanes_in = if exact_leaves && node.child[i] & LEAF_BIT != 0 {
                        (1 << first) | lr.meeting(node, i, active & !(1 << first), closest)
                    } else {
                        active
                    };
                    kids[n] = (lanes_in, near[i], i);
                    n += 1;
                }
                while cand != 0 {
                    let i = cand.trailing_zeros() as usize;
                    cand &= cand - 1;
                    // First active lane group with a hit: earlier lanes
                    // miss, that group's lanes are exact, later ones carried.
                    for g in first / 4..lr.groups {
                        let want = (active >> (4 * g)) & 0xF;
                        if want == 0 {
                            continue;
                        }
                        let bound = f32x4::new(std::array::from_fn(|i| closest[g * 4 + i]));
                        let (hit, near) = lr.test(node, i, g, bound);
                        let hit = hit & want;
                        if hit != 0 {
                            let mut later = if 4 * g + 4 >= 32 {
                                0
                            } else {
                                active & !((1u32 << (4 * g + 4)) - 1)
                            };
                            if exact_leaves && node.child[i] & LEAF_BIT != 0 {
                                later = lr.meeting(node, i, later, closest);
                            }
                            let first = hit.trailing_zeros() as usize;
                            kids[n] = ((hit << (4 * g)) | later, near.to_array()[first], i);
                            n += 1;
                            break;
                        }
                    }
                }
                if n > 0 {
                    // Nearest first lane's entry last on the stack.
                    // PERF: insertion in place (at most four), not a call
                    // of the slice sort.
                    for j in 1..n {
                        let k = kids[j];
                        let mut m = j;
                        while m > 0 && kids[m - 1].1.total_cmp(&k.1).is_lt() {
                            kids[m] = kids[m - 1];
                            m -= 1;
                        }
                        kids[m] = k;
                    }
                    let entry = |k: (u32, f32, usize)| Entry {
                        child: node.child[k.2],
                        count: node.count[k.2],
                        lanes: k.0,
                    };
                    for &k in &kids[..n - 1] {
                        stack[sp].write(entry(k));
                        sp += 1;
                    }
                    cur = entry(kids[n - 1]);
                    continue;
                }
            }
        }
        if sp == 0 {
            return lanes & !live;
        }
        sp -= 1;
        // SAFETY: entries below `sp` were written by the pushes above.
        cur = unsafe { stack[sp].assume_init() };
    }
}
