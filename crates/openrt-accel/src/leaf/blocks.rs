//! Leaf triangles repacked in SIMD blocks, tested four at a time.
//!
//! Each leaf's triangles are copied, [`LANES`] to a block, in
//! structure-of-arrays order, so one pass of SIMD arithmetic runs the
//! watertight test (Woop, Benthin & Wald, JCGT 2013) of a whole block
//! against a ray (`geom/watertight4.rs`; on AVX2 CPUs two blocks to a
//! register, `pairs_avx2.rs`). Most tests are misses decided by the signs of
//! the three 2D edge functions: the blocks' edge functions are computed
//! first (the pre-test), and only a block with a lane whose edge functions
//! do not have mixed signs runs the rest of the test. Lanes with an edge
//! function exactly zero go to the scalar [`intersect_triangle`], which alone
//! decides those.
//!
//! NOTE: the block test repeats the scalar kernel's operations one for one
//! (the same subtractions and products, in the same order, without fused
//! multiply-adds), so it decides each lane as the scalar kernel does, with
//! the same `t` and barycentrics: results do not change, watertightness
//! included (tested against the scalar loop in this module and by every
//! oracle test of the crate).

use std::cmp::Ordering;

use wide::f32x4;

use crate::error::AccelError;
use crate::geom::ray::Ray;
use crate::geom::triangle::Triangle;
use crate::geom::triangle::{TriHit, intersect_triangle};
use crate::geom::watertight4::{Decided4, Edges4};
use crate::kd::node::KdNode;
use crate::leaf::mailbox::TriMailbox;
use crate::packet::frustum::Frustum;
use crate::packet::triangle::{LaneHits, PacketBlockRay};

pub(crate) use crate::geom::tri_block::{LANES, TriBlock};

/// Re-lays out the leaves of a built tree so that each leaf's index range
/// starts at a multiple of [`LANES`] (padding entries repeat the leaf's last
/// index and belong to no leaf range), and packs the blocks: block `k` holds
/// the triangles of `ids[k * LANES..]`. Fails when the padded index array
/// outgrows the leaves' 32-bit offsets.
pub(crate) fn pack_leaves(
    nodes: &mut [KdNode],
    ids: &[u32],
    tris: &[Triangle],
) -> Result<(Vec<u32>, Vec<TriBlock>), AccelError> {
    let padded: usize = nodes
        .iter()
        .filter(|n| n.is_leaf())
        .map(|n| (n.prim_count() as usize).div_ceil(LANES) * LANES)
        .sum();
    if u32::try_from(padded).is_err() {
        return Err(AccelError::TooManyNodes {
            limit: u32::MAX as usize,
        });
    }
    let mut new_ids = Vec::with_capacity(padded);
    let mut blocks = Vec::with_capacity(padded / LANES);
    for n in nodes.iter_mut().filter(|n| n.is_leaf()) {
        let (off, cnt) = (n.prim_offset() as usize, n.prim_count() as usize);
        let list = &ids[off..off + cnt];
        *n = KdNode::leaf(new_ids.len() as u32, cnt as u32);
        for chunk in list.chunks(LANES) {
            blocks.push(TriBlock::pack(chunk, tris));
            new_ids.extend_from_slice(chunk);
            let last = chunk[chunk.len() - 1];
            new_ids.resize(new_ids.len() + LANES - chunk.len(), last);
        }
    }
    Ok((new_ids, blocks))
}

/// The per-ray constants of the block test, splatted once per query.
#[derive(Clone, Copy)]
pub(crate) struct BlockRay {
    /// The origin in the ray's axis permutation.
    pub(super) o: [f32x4; 3],
    pub(super) sx: f32x4,
    pub(super) sy: f32x4,
    pub(super) sz: f32x4,
    pub(super) t_min: f32x4,
    pub(super) kx: usize,
    pub(super) ky: usize,
    pub(super) kz: usize,
}

impl BlockRay {
    pub(crate) fn new(ray: &Ray) -> Self {
        let o = ray.origin.to_array();
        let [kx, ky, kz] = ray.axes();
        Self {
            o: [f32x4::splat(o[kx]), f32x4::splat(o[ky]), f32x4::splat(o[kz])],
            sx: f32x4::splat(ray.shear.x),
            sy: f32x4::splat(ray.shear.y),
            sz: f32x4::splat(ray.shear.z),
            t_min: f32x4::splat(ray.t_min),
            kx,
            ky,
            kz,
        }
    }

    /// The edge functions of the block's four triangles.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn edges(&self, b: &TriBlock) -> Edges4 {
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let p = |v: &[f32x4; 3]| [v[kx], v[ky], v[kz]];
        Edges4::new(&p(&b.v[0]), &p(&b.v[1]), &p(&b.v[2]), &self.o, self.sx, self.sy)
    }

    /// Bit `i` set: lane `i`'s edge functions do not have mixed signs, so
    /// the rest of the test must decide it. A clear bit is a certain miss.
    #[inline]
    fn candidates(&self, b: &TriBlock) -> u32 {
        !self.edges(b).mixed().to_bitmask() & ((1 << LANES) - 1)
    }

    /// The whole test of the block's four triangles over `(t_min, t_max)`:
    /// lane by lane `intersect_triangle`'s answer, except for the lanes of
    /// [`Decided4::edge`], which only it decides.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn intersect(&self, b: &TriBlock, t_max: f32) -> Decided4 {
        let e = self.edges(b);
        e.decide(e.mixed(), self.sz, self.t_min, f32x4::splat(t_max))
    }
}

/// Blocks whose candidate masks fit one `u64`.
const CHUNK: usize = 64 / LANES;

/// Calls `visit(prim, hit, bound)` for each triangle of `leaf` that `ray`
/// hits over `(t_min, bound)`, in leaf order, until `visit` returns `true`
/// (then returns `true`); `visit` may lower `bound` for the triangles after
/// it. The hits are those of [`intersect_triangle`] over each triangle in
/// turn with the bound of its turn, bit for bit. `ids` and `blocks` are as
/// made by [`pack_leaves`].
///
/// The blocks' edge functions are computed first (the pre-test); a block
/// with a candidate is then tested whole, four triangles to a register
/// ([`Edges4`]), and only the lanes exactly on an edge go to the scalar
/// kernel (Embree tests a ray against several triangles the same way).
///
/// A lane the block test accepted under the bound of its block's turn is
/// kept under a lower bound only if `ts < bound * |det|` still holds (the
/// scalar kernel's own comparison); a bound raised since (a tie's slack)
/// sends the block's candidates to the scalar kernel instead (`Found::visit`).
/// Leaves of two blocks or more take the AVX2 loop on CPUs that have it.
/// Against the pre-test and a scalar test per candidate (1.8-2.5 per primary
/// ray, three quarters of them hits): see docs/PERFORMANCE.md.
#[inline]
fn for_each_hit(
    ray: &Ray,
    br: &BlockRay,
    leaf: KdNode,
    ids: &[u32],
    blocks: &[TriBlock],
    bound: f32,
    visit: impl FnMut(u32, TriHit, &mut f32) -> bool,
) -> bool {
    #[cfg(target_arch = "x86_64")]
    let count = (leaf.prim_count() as usize).div_ceil(LANES);
    #[cfg(target_arch = "x86_64")]
    if count >= 2 && crate::packet::width::avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { super::pairs_avx2::for_each_hit_avx2(ray, br, leaf, ids, blocks, bound, visit) };
    }
    for_each_hit_portable(ray, br, leaf, ids, blocks, bound, visit)
}

/// [`for_each_hit`] a block at a time, four triangles to an SSE register
/// (every CPU; the AVX2 loop's twin).
///
/// PERF: the masks of up to `CHUNK` blocks are gathered before any of them
/// is looked at, so that the pre-tests of a leaf run without a branch on
/// their results between them; a candidate's triangle is read back from its
/// block (bit-identical to the triangle array's copy, checked by
/// `validate`), not from the triangle array, one cache miss fewer.
#[inline]
fn for_each_hit_portable(
    ray: &Ray,
    br: &BlockRay,
    leaf: KdNode,
    ids: &[u32],
    blocks: &[TriBlock],
    mut bound: f32,
    mut visit: impl FnMut(u32, TriHit, &mut f32) -> bool,
) -> bool {
    let (off, first, n, count) = leaf_range(leaf);
    for (c, chunk) in blocks[first..first + count].chunks(CHUNK).enumerate() {
        let mut m = 0u64;
        for (k, b) in chunk.iter().enumerate() {
            m |= u64::from(br.candidates(b) & !padding(n, c * CHUNK + k)) << (k * LANES);
        }
        while m != 0 {
            let k = m.trailing_zeros() as usize / LANES;
            let lanes = (m >> (k * LANES)) as u32 & ((1 << LANES) - 1);
            m &= !(((1u64 << LANES) - 1) << (k * LANES));
            let block = &chunk[k];
            let start = bound;
            let d = br.intersect(block, start);
            let found = Found {
                hit: d.hit,
                edge: d.edge,
                t: d.t.to_array(),
                b1: d.b1.to_array(),
                b2: d.b2.to_array(),
                ts: d.ts.to_array(),
                abs_det: d.abs_det.to_array(),
            };
            let base = off + (c * CHUNK + k) * LANES;
            let tri = |lane: usize| block.triangle(lane);
            if found.visit(ray, lanes, start, &mut bound, tri, |lane| ids[base + lane], &mut visit) {
                return true;
            }
        }
    }
    false
}

/// A leaf's place in the blocks: `(offset of its first index, its first
/// block, triangles, blocks)`.
#[inline]
pub(super) fn leaf_range(leaf: KdNode) -> (usize, usize, usize, usize) {
    let off = leaf.prim_offset() as usize;
    let n = leaf.prim_count() as usize;
    (off, off / LANES, n, n.div_ceil(LANES))
}

/// A block test's answers for `W` lanes (one block, or two with AVX2).
pub(super) struct Found<const W: usize> {
    pub(super) hit: u32,
    pub(super) edge: u32,
    pub(super) t: [f32; W],
    pub(super) b1: [f32; W],
    pub(super) b2: [f32; W],
    pub(super) ts: [f32; W],
    pub(super) abs_det: [f32; W],
}

impl<const W: usize> Found<W> {
    /// Calls `visit(id(lane), hit, bound)` for each of the `lanes` (in
    /// order) that the scalar kernel finds hit under the bound of its turn,
    /// until `visit` returns `true` (then returns `true`); the block test
    /// ran under `start`. Lanes on an edge, and every lane once the bound
    /// has risen above `start` (or is NaN), take the scalar kernel
    /// (triangle `tri(lane)`); a lane the block test accepted is kept while
    /// `ts < bound * |det|` (the scalar kernel's own comparison).
    #[allow(clippy::inline_always, clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn visit(
        &self,
        ray: &Ray,
        mut lanes: u32,
        start: f32,
        bound: &mut f32,
        tri: impl Fn(usize) -> Triangle,
        id: impl Fn(usize) -> u32,
        visit: &mut impl FnMut(u32, TriHit, &mut f32) -> bool,
    ) -> bool {
        while lanes != 0 {
            let lane = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            let bit = 1 << lane;
            // NOTE: a NaN bound goes to the scalar kernel too.
            let raised = !matches!((*bound).partial_cmp(&start), Some(Ordering::Less | Ordering::Equal));
            let got = if self.edge & bit != 0 || raised {
                intersect_triangle(ray, &tri(lane), *bound)
            } else if self.hit & bit != 0 && self.ts[lane] < *bound * self.abs_det[lane] {
                Some((self.t[lane], self.b1[lane], self.b2[lane]))
            } else {
                None
            };
            if let Some(h) = got
                && visit(id(lane), h, bound)
            {
                return true;
            }
        }
        false
    }
}

/// The lanes of block `k` of a leaf of `n` triangles that only repeat its
/// last triangle (the padding of its last block). Skipping them changes no
/// answer: a repeat meets the ray exactly as the triangle itself did (the
/// same bits, the same index).
#[inline]
pub(super) fn padding(n: usize, k: usize) -> u32 {
    let real = n.saturating_sub(k * LANES).min(LANES);
    ((1u32 << LANES) - 1) & !((1u32 << real) - 1)
}

/// `true` when a hit of triangle `prim` at `t` beats the walk's best so
/// far, `(closest, tie)`: nearer, or at exactly the same distance on a
/// triangle of lower index (the tie rule that makes every structure give
/// the same answer where triangles overlap). `tie == NO_TIE`: no hit yet,
/// any hit the kernel reports within the bound wins.
#[inline]
pub(crate) fn beats(t: f32, prim: u32, closest: f32, tie: u32) -> bool {
    tie == NO_TIE || t < closest || (t == closest && prim < tie)
}

/// `tie` of a walk without a hit yet.
pub(crate) const NO_TIE: u32 = u32::MAX;

/// The kernel's bound for a walk at `(closest, tie)`: a little above a hit
/// already found, so that an exact tie reaches [`beats`].
///
/// NOTE: the kernel compares the scaled distance `t det` with `bound det`,
/// and `t` itself is rounded twice from it: a hit whose `t` equals
/// `closest` bit for bit can fail the scaled test against `next_up(closest)`
/// (seen on the kitchen's coplanar overlaps). [`TIE_SLACK`] relative is far
/// above those roundings; hits it lets through beyond `closest` lose in
/// [`beats`].
#[inline]
pub(crate) fn tie_bound(closest: f32, tie: u32) -> f32 {
    if tie == NO_TIE {
        closest
    } else {
        closest + closest.abs() * TIE_SLACK
    }
}

/// See [`tie_bound`].
pub(crate) const TIE_SLACK: f32 = 1.0 / 1_048_576.0;

/// Tests the triangles of one leaf and returns the hit that beats the
/// walk's best `(t_max, tie)` by [`beats`], with its triangle index.
#[inline]
pub(crate) fn leaf_closest(
    ray: &Ray,
    br: &BlockRay,
    leaf: KdNode,
    ids: &[u32],
    blocks: &[TriBlock],
    mut t_max: f32,
    mut tie: u32,
) -> Option<(u32, TriHit)> {
    let mut best = None;
    for_each_hit(ray, br, leaf, ids, blocks, tie_bound(t_max, tie), |p, h, bound| {
        if beats(h.0, p, t_max, tie) {
            t_max = h.0;
            tie = p;
            best = Some((p, h));
            *bound = tie_bound(t_max, tie);
        }
        false
    });
    best
}

/// `true` when some triangle of the leaf is hit below `t_max`.
#[inline]
pub(crate) fn leaf_any(ray: &Ray, br: &BlockRay, leaf: KdNode, ids: &[u32], blocks: &[TriBlock], t_max: f32) -> bool {
    for_each_hit(ray, br, leaf, ids, blocks, t_max, |_, _, _| true)
}

/// Calls `accept(hit)` for the leaf's triangles hit below `ray.t_max`, in
/// leaf order, until it returns `true`.
pub(crate) fn leaf_occluder_where(
    ray: &Ray,
    br: &BlockRay,
    leaf: KdNode,
    ids: &[u32],
    blocks: &[TriBlock],
    mut accept: impl FnMut(TriHit) -> bool,
) {
    for_each_hit(ray, br, leaf, ids, blocks, ray.t_max, |_, h, _| accept(h));
}

/// Tests the triangles of `leaf` against the `lanes` of `rays`, each lane
/// over `(t_min, closest[l])`, in leaf order (the last block's padding
/// skipped), and calls `visit(hits, prim, closest)` for each triangle that
/// some lane hits; `visit` lowers `closest` to the hits it keeps (a
/// closest-hit walk keeps every hit it is given) and returns the lanes that
/// are done, which take no further part. Returns the lanes done. With a
/// mailbox (`tested`, one per walk), a lane skips the triangles it tested
/// in the walk's earlier leaves. Per lane, the hits reaching `visit` and
/// their order are those of the scalar kernel over the leaf's triangles for
/// that lane's ray alone, less those a mailbox skips, which could not lower
/// its bound.
///
/// On CPUs with AVX2, packets of 8 lanes and more run a copy of the loop
/// compiled for AVX2 whose triangle test takes eight lanes to a register
/// (`PacketBlockRay::intersect_block8`, bit for bit the four-lane test):
/// the same calls of `visit` with the same hits.
#[inline]
#[allow(clippy::too_many_arguments)]
pub(crate) fn leaf_packet<const N: usize>(
    pbr: &PacketBlockRay<N>,
    rays: &[Ray; N],
    frustum: Option<&Frustum>,
    lanes: u32,
    leaf: KdNode,
    ids: &[u32],
    blocks: &[TriBlock],
    closest: &mut [f32; N],
    ties: Option<&mut [u32; N]>,
    tested: Option<&mut TriMailbox>,
    visit: impl FnMut(&LaneHits, u32, &mut [f32; N]) -> u32,
) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if N.is_multiple_of(8) && crate::packet::width::avx2() {
        // SAFETY: the CPU has AVX2 and `N` is a multiple of eight.
        return unsafe {
            leaf_packet_avx2(
                pbr, rays, frustum, lanes, leaf, ids, blocks, closest, ties, tested, visit,
            )
        };
    }
    leaf_packet_with::<N, false>(
        pbr, rays, frustum, lanes, leaf, ids, blocks, closest, ties, tested, visit,
    )
}

/// [`leaf_packet`] compiled for AVX2, with the eight-lane triangle test.
///
/// # Safety
/// The CPU must have AVX2, and `N` must be a multiple of eight.
// PERF: kitchen primary packet queries 0.94 of the four-lane loop's time,
// robots 0.91-0.93, kitchen shadows 0.92 (measured when it was written).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn leaf_packet_avx2<const N: usize>(
    pbr: &PacketBlockRay<N>,
    rays: &[Ray; N],
    frustum: Option<&Frustum>,
    lanes: u32,
    leaf: KdNode,
    ids: &[u32],
    blocks: &[TriBlock],
    closest: &mut [f32; N],
    ties: Option<&mut [u32; N]>,
    tested: Option<&mut TriMailbox>,
    visit: impl FnMut(&LaneHits, u32, &mut [f32; N]) -> u32,
) -> u32 {
    leaf_packet_with::<N, true>(
        pbr, rays, frustum, lanes, leaf, ids, blocks, closest, ties, tested, visit,
    )
}

/// One triangle of a block against the lanes: the eight-lane test when
/// `WIDE`, else the four-lane one.
#[allow(clippy::inline_always)]
#[inline(always)]
fn lane_test<const N: usize, const WIDE: bool>(
    pbr: &PacketBlockRay<N>,
    b: &TriBlock,
    j: usize,
    lanes: u32,
    bound: &[f32; N],
) -> LaneHits {
    #[cfg(target_arch = "x86_64")]
    if WIDE {
        // SAFETY: only `leaf_packet_avx2` sets `WIDE`, which runs where the
        // CPU has AVX2, with `N` a multiple of eight.
        return unsafe { pbr.intersect_block8(b, j, lanes, bound) };
    }
    pbr.intersect_block(b, j, lanes, bound)
}

/// The body of [`leaf_packet`], inlined into its portable and AVX2 copies.
#[allow(clippy::inline_always, clippy::too_many_arguments)]
#[inline(always)]
fn leaf_packet_with<const N: usize, const WIDE: bool>(
    pbr: &PacketBlockRay<N>,
    rays: &[Ray; N],
    frustum: Option<&Frustum>,
    lanes: u32,
    leaf: KdNode,
    ids: &[u32],
    blocks: &[TriBlock],
    closest: &mut [f32; N],
    mut ties: Option<&mut [u32; N]>,
    mut tested: Option<&mut TriMailbox>,
    mut visit: impl FnMut(&LaneHits, u32, &mut [f32; N]) -> u32,
) -> u32 {
    let (off, first, n, count) = leaf_range(leaf);
    let mut live = lanes;
    // The kernel's bounds: each lane's `tie_bound` in a closest-hit walk.
    let mut bound = *closest;
    if let Some(ties) = ties.as_deref() {
        for l in crate::packet::width::lanes_of(lanes) {
            bound[l] = tie_bound(closest[l], ties[l]);
        }
    }
    for (k, b) in blocks[first..first + count].iter().enumerate() {
        // Triangles no lane can hit are skipped for the whole packet, and
        // so is the last block's padding.
        let skip = frustum.map_or(0, |f| f.rejects(b)) | padding(n, k);
        if skip == (1 << LANES) - 1 {
            continue;
        }
        for j in 0..LANES {
            if skip & (1 << j) != 0 {
                continue;
            }
            // Lanes that tested this triangle in another leaf of the walk
            // get nothing new from it (`TriMailbox`).
            let prim = ids[off + k * LANES + j];
            let todo = tested.as_mut().map_or(live, |m| m.untested(prim, live));
            if todo == 0 {
                continue;
            }
            let mut h = lane_test::<N, WIDE>(pbr, b, j, todo, &bound);
            if h.edge != 0 {
                h.settle_edges(rays, &b.triangle(j), &bound);
            }
            if let Some(ties) = ties.as_deref_mut() {
                // Only hits that beat the lane's best go on (the tie rule).
                for l in crate::packet::width::lanes_of(h.hit) {
                    if beats(h.lane(l).0, prim, closest[l], ties[l]) {
                        ties[l] = prim;
                    } else {
                        h.hit &= !(1 << l);
                    }
                }
            }
            if h.hit != 0 {
                live &= !visit(&h, prim, closest);
                if live == 0 {
                    return lanes;
                }
                if ties.is_some() {
                    for l in crate::packet::width::lanes_of(h.hit) {
                        bound[l] = tie_bound(closest[l], 0);
                    }
                }
            }
        }
    }
    lanes & !live
}

/// `true` when the hit `(t, b1, b2)` of `ray` lies at least `margin` inside
/// the ray's finite interval (relative to its length) and inside the
/// triangle (each barycentric coordinate).
fn well_inside(ray: &Ray, (t, b1, b2): (f32, f32, f32), margin: f32) -> bool {
    let span = ray.t_max - ray.t_min;
    let m = margin * span;
    span.is_finite() && t > ray.t_min + m && t < ray.t_max - m && b1 > margin && b2 > margin && 1.0 - b1 - b2 > margin
}

/// A tree's leaf lists (index array and blocks, as [`pack_leaves`] makes
/// them), for the queries that kd-trees and BVHs share: the occluder
/// hint's test of one leaf.
#[derive(Clone, Copy)]
pub(crate) struct LeafLists<'a> {
    pub(crate) ids: &'a [u32],
    pub(crate) blocks: &'a [TriBlock],
}

impl LeafLists<'_> {
    /// `true` for a leaf whose range lies in these lists.
    pub(crate) fn owns(&self, leaf: KdNode) -> bool {
        let (off, count) = (leaf.prim_offset() as usize, leaf.prim_count() as usize);
        leaf.is_leaf()
            && count > 0
            && off.is_multiple_of(LANES)
            && off + count.div_ceil(LANES) * LANES <= self.ids.len()
            && off / LANES + count.div_ceil(LANES) <= self.blocks.len()
    }

    /// `true` when a triangle of `leaf` blocks `ray` at least `margin`
    /// inside its interval and inside the triangle; `false` for a leaf
    /// these lists do not hold.
    pub(crate) fn blocks_ray(&self, ray: &Ray, leaf: KdNode, margin: f32) -> bool {
        if !self.owns(leaf) {
            return false;
        }
        let br = BlockRay::new(ray);
        let mut inside = false;
        leaf_occluder_where(ray, &br, leaf, self.ids, self.blocks, |h| {
            inside = well_inside(ray, h, margin);
            inside
        });
        inside
    }

    /// [`LeafLists::blocks_ray`] for the `lanes` of a packet: the lanes
    /// blocked so.
    pub(crate) fn blocks_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32, leaf: KdNode, margin: f32) -> u32 {
        if !self.owns(leaf) || lanes == 0 {
            return 0;
        }
        let Some(pbr) = PacketBlockRay::new(rays, lanes) else {
            return crate::packet::width::lanes_of(lanes)
                .fold(0, |m, l| m | (u32::from(self.blocks_ray(&rays[l], leaf, margin)) << l));
        };
        let mut closest: [f32; N] = std::array::from_fn(|l| rays[l].t_max);
        let mut got = 0u32;
        // One leaf names no triangle twice: no mailbox.
        // PERF: no frustum: a leaf's few triangles cost less than making one.
        leaf_packet(
            &pbr,
            rays,
            None,
            lanes,
            leaf,
            self.ids,
            self.blocks,
            &mut closest,
            None,
            None,
            |h, _, _| {
                for l in crate::packet::width::lanes_of(h.hit) {
                    if well_inside(&rays[l], h.lane(l), margin) {
                        got |= 1 << l;
                    }
                }
                // Settled lanes leave; the others try the leaf's other triangles.
                got & h.hit
            },
        );
        got
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::geom::aabb::Aabb;
    use crate::kd::tree::KdTree;
    use crate::testing::meshgen;

    /// The leaves of `tree` with more than `n` triangles.
    fn leaves_over(tree: &KdTree, n: u32) -> Vec<KdNode> {
        tree.nodes()
            .iter()
            .copied()
            .filter(|l| l.is_leaf() && l.prim_count() > n)
            .collect()
    }

    /// The scalar loop the blocks replace.
    fn scalar_closest(ray: &Ray, list: &[u32], tris: &[Triangle], t_max: f32) -> Option<(u32, TriHit)> {
        scalar_closest_tied(ray, list, tris, t_max, NO_TIE)
    }

    /// The scalar loop, from a walk's best so far `(t_max, tie)`.
    fn scalar_closest_tied(
        ray: &Ray,
        list: &[u32],
        tris: &[Triangle],
        mut t_max: f32,
        mut tie: u32,
    ) -> Option<(u32, TriHit)> {
        let mut best = None;
        for &p in list {
            if let Some(h) = intersect_triangle(ray, &tris[p as usize], tie_bound(t_max, tie))
                && beats(h.0, p, t_max, tie)
            {
                tie = p;
                t_max = h.0;
                best = Some((p, h));
            }
        }
        best
    }

    /// Rays aimed at vertices and edge midpoints (zero edge functions) and
    /// random rays, from random origins.
    fn rays(tris: &[Triangle], n: usize, seed: u64) -> Vec<Ray> {
        let b = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
        let mut out = meshgen::random_rays(n, seed, b);
        out.extend(meshgen::hard_rays(tris, n, seed));
        // Axis-parallel: zero direction components of either sign.
        out.extend(
            meshgen::hard_points(tris, n, seed)
                .into_iter()
                .map(|p| Ray::new(p - Vec3::Z * 4.0, Vec3::new(-0.0, 0.0, 1.0), 0.0, f32::INFINITY)),
        );
        out
    }

    #[test]
    fn blocks_give_the_scalar_loops_results_bit_for_bit() {
        for (name, tris) in [
            ("sphere", meshgen::bumpy_sphere(3_000, 5, 0.5)),
            ("grid", meshgen::grid(20, 20)),
            ("fan", meshgen::fan(Vec3::ZERO, 7, 1.0)),
            (
                "soup",
                meshgen::random_soup(2_000, 9, Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0)), 0.3),
            ),
            // One plane, one box: no split separates them, so one leaf holds
            // all 150 (more than one 64-lane chunk of masks), overlapping, so
            // the order of equal hits decides the result.
            (
                "stack",
                (0..150)
                    .map(|i| {
                        let x = i as f32 / 75.0 - 1.0;
                        [
                            Vec3::new(-1.0, -1.0, 0.0),
                            Vec3::new(1.0, -1.0, 0.0),
                            Vec3::new(x, 1.0, 0.0),
                        ]
                    })
                    .collect(),
            ),
        ] {
            let tree = KdTree::build_sah(tris.clone()).unwrap();
            let leaves = leaves_over(&tree, 0);
            if name == "stack" {
                assert!(
                    leaves.iter().any(|n| n.prim_count() as usize > 64),
                    "{name}: no leaf over 64"
                );
            }
            let (mut tested, mut hits) = (0usize, 0usize);
            for ray in rays(&tris, 300, 11) {
                let br = BlockRay::new(&ray);
                for &leaf in &leaves {
                    for t_max in [ray.t_max, 1.5] {
                        let list = tree.leaf_primitives(leaf);
                        let want = scalar_closest(&ray, list, &tris, t_max);
                        let got = leaf_closest(&ray, &br, leaf, &tree.prim_ids, &tree.blocks, t_max, NO_TIE);
                        let bits = |h: Option<(u32, TriHit)>| {
                            h.map(|(p, (t, u, v))| (p, t.to_bits(), u.to_bits(), v.to_bits()))
                        };
                        assert_eq!(bits(got), bits(want), "{name}: closest differs for {ray:?}");
                        let any = leaf_any(&ray, &br, leaf, &tree.prim_ids, &tree.blocks, t_max);
                        assert_eq!(any, want.is_some(), "{name}: any-hit differs for {ray:?}");
                        tested += 1;
                        hits += usize::from(want.is_some());
                    }
                }
            }
            // The sweep must exercise hits, not only misses.
            assert!(
                hits > 100 && hits < tested,
                "{name}: {hits} hits in {tested} leaf tests"
            );
        }
    }

    type Bits = Option<(u32, u32, u32, u32)>;

    fn hit_bits(h: Option<(u32, TriHit)>) -> Bits {
        h.map(|(p, (t, u, v))| (p, t.to_bits(), u.to_bits(), v.to_bits()))
    }

    /// The whole block test's bookkeeping where it matters most: bounds
    /// right at a hit (a hit's tie slack then raises the bound above the
    /// block's: those lanes go to the scalar kernel), walks that arrive
    /// with a tie, stacks of triangles at one distance, and the occluder
    /// visits in leaf order. Every answer against the scalar loop.
    #[test]
    fn block_tests_keep_the_scalar_loops_bounds_and_ties() {
        // Coplanar stacks at z = 0 and z = 0.5 (equal distances), and a
        // grid, all in few leaves.
        let mut tris = meshgen::grid(6, 6);
        for i in 0..40 {
            let x = i as f32 / 20.0 - 1.0;
            for z in [0.0, 0.5, 0.5 + f32::EPSILON] {
                tris.push([Vec3::new(-1.0, -1.0, z), Vec3::new(1.0, -1.0, z), Vec3::new(x, 1.0, z)]);
            }
        }
        let tree = KdTree::build_sah(tris.clone()).unwrap();
        let leaves = leaves_over(&tree, 0);
        let (mut raised, mut tied, mut occluders) = (0usize, 0usize, 0usize);
        for ray in rays(&tris, 200, 5) {
            let br = BlockRay::new(&ray);
            for &leaf in &leaves {
                let list = tree.leaf_primitives(leaf);
                let Some((p0, (t0, _, _))) = scalar_closest(&ray, list, &tris, ray.t_max) else {
                    continue;
                };
                // Bounds just above and at the nearest hit, and below it.
                for t_max in [t0.next_up(), t0 + t0.abs() * TIE_SLACK * 0.5, t0, t0.next_down()] {
                    for tie in [NO_TIE, p0, 0, u32::MAX - 1] {
                        let want = scalar_closest_tied(&ray, list, &tris, t_max, tie);
                        let got = leaf_closest(&ray, &br, leaf, &tree.prim_ids, &tree.blocks, t_max, tie);
                        assert_eq!(hit_bits(got), hit_bits(want), "closest at ({t_max}, {tie}) for {ray:?}");
                        raised += usize::from(tie == NO_TIE && want.is_some() && t_max > t0);
                        tied += usize::from(tie != NO_TIE && want.is_some());
                    }
                }
                // The occluder visits: every hit below the ray's bound, in
                // leaf order, until one is accepted.
                for stop_at in [usize::MAX, 1, 2] {
                    let mut want = Vec::new();
                    for &p in list {
                        if let Some(h) = intersect_triangle(&ray, &tris[p as usize], ray.t_max) {
                            want.push(h.0.to_bits());
                            if want.len() == stop_at {
                                break;
                            }
                        }
                    }
                    let mut got = Vec::new();
                    leaf_occluder_where(&ray, &br, leaf, &tree.prim_ids, &tree.blocks, |h| {
                        got.push(h.0.to_bits());
                        got.len() == stop_at
                    });
                    assert_eq!(got, want, "occluder visits for {ray:?}");
                    occluders += got.len();
                }
            }
        }
        assert!(
            raised > 100 && tied > 100 && occluders > 100,
            "{raised} {tied} {occluders}"
        );
    }

    /// Every call of a leaf loop's visitor, as bits: (triangle, t, b1, b2).
    type HitVisits = Vec<(u32, u32, u32, u32)>;

    /// The visits of one leaf loop as a closest-hit walk would make them
    /// (lowering the bound by the tie rule on each hit).
    fn visits_of(
        each: impl FnOnce(f32, &mut dyn FnMut(u32, TriHit, &mut f32) -> bool) -> bool,
        t_max: f32,
    ) -> HitVisits {
        let mut out = Vec::new();
        let (mut best, mut tie) = (t_max, NO_TIE);
        each(tie_bound(t_max, tie), &mut |p, h, bound| {
            out.push((p, h.0.to_bits(), h.1.to_bits(), h.2.to_bits()));
            if beats(h.0, p, best, tie) {
                (best, tie) = (h.0, p);
                *bound = tie_bound(best, tie);
            }
            false
        });
        out
    }

    /// The AVX2 loop (two blocks to a register) against the portable one
    /// on leaves of many blocks, odd and even counts, with padding: the same
    /// visits, hit for hit.
    #[test]
    fn the_avx2_pair_loop_visits_as_the_portable_one() {
        if !crate::packet::width::avx2() {
            eprintln!("skipped: this CPU has no AVX2");
            return;
        }
        let mut tris = meshgen::bumpy_sphere(2_000, 3, 0.4);
        tris.extend(meshgen::fan(Vec3::ZERO, 9, 1.0));
        for i in 0..45 {
            let x = i as f32 / 22.0 - 1.0;
            tris.push([
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(1.0, -1.0, 0.0),
                Vec3::new(x, 1.0, 0.0),
            ]);
        }
        let tree = KdTree::build_sah(tris.clone()).unwrap();
        let leaves = leaves_over(&tree, 4);
        let odd = leaves.iter().filter(|l| l.prim_count().div_ceil(4) % 2 == 1).count();
        assert!(odd > 5 && odd < leaves.len(), "{odd} odd of {}", leaves.len());
        let mut visits = 0usize;
        for ray in rays(&tris, 150, 3) {
            let br = BlockRay::new(&ray);
            for &leaf in &leaves {
                for t_max in [ray.t_max, 1.2] {
                    let (ids, blocks) = (&tree.prim_ids[..], &tree.blocks[..]);
                    let portable = visits_of(|b, v| for_each_hit_portable(&ray, &br, leaf, ids, blocks, b, v), t_max);
                    // SAFETY: the CPU has AVX2 (checked above).
                    let wide = visits_of(
                        |b, v| unsafe {
                            super::super::pairs_avx2::for_each_hit_avx2(&ray, &br, leaf, ids, blocks, b, v)
                        },
                        t_max,
                    );
                    assert_eq!(wide, portable, "leaf of {} for {ray:?}", leaf.prim_count());
                    visits += portable.len();
                }
            }
        }
        assert!(visits > 500, "{visits} visits");
    }

    /// What the leaf loop told its visitor, bit for bit: per call the
    /// triangle, the hit lanes and their hits; then the lanes done.
    type Visits = (Vec<(u32, u32, Vec<(u32, u32, u32)>)>, u32);

    /// Runs the leaf loop `WIDE` over `leaf` for a packet, as a closest-hit
    /// walk with the tie rule (`any == false`) or an any-hit walk.
    fn leaf_visits<const N: usize, const WIDE: bool>(
        tree: &KdTree,
        rays: &[Ray; N],
        lanes: u32,
        leaf: KdNode,
        any: bool,
    ) -> Visits {
        let pbr = PacketBlockRay::new(rays, lanes).expect("one permutation");
        let mut closest: [f32; N] = std::array::from_fn(|l| if l % 5 == 2 { 2.0 } else { rays[l].t_max });
        let mut ties = [NO_TIE; N];
        let mut seen = Vec::new();
        let done = leaf_packet_with::<N, WIDE>(
            &pbr,
            rays,
            None,
            lanes,
            leaf,
            &tree.prim_ids,
            &tree.blocks,
            &mut closest,
            (!any).then_some(&mut ties),
            None,
            |h, prim, closest| {
                let lanes: Vec<_> = crate::packet::width::lanes_of(h.hit)
                    .map(|l| {
                        let (t, b1, b2) = h.lane(l);
                        if !any {
                            closest[l] = t;
                        }
                        (t.to_bits(), b1.to_bits(), b2.to_bits())
                    })
                    .collect();
                seen.push((prim, h.hit, lanes));
                if any { h.hit } else { 0 }
            },
        );
        (seen, done)
    }

    #[test]
    fn the_avx2_leaf_loop_visits_as_the_portable_one() {
        #[cfg(target_arch = "x86_64")]
        if !crate::packet::width::avx2() {
            return;
        }
        let tris = meshgen::bumpy_sphere(3_000, 5, 0.5);
        let tree = KdTree::build_sah(tris.clone()).unwrap();
        let leaves = leaves_over(&tree, 0);
        // Camera packets of 16 and 8 lanes through the sphere, and packets
        // aimed at its vertices (exact edge lanes).
        let cam = meshgen::camera_rays(Vec3::new(0.3, 0.2, 3.0), Vec3::ZERO, 32, 32, 50.0);
        let hard = meshgen::hard_rays(&tris, 512, 3);
        let (mut visits, mut hits) = (0usize, 0usize);
        for rays in cam.chunks_exact(16).chain(hard.chunks_exact(16)).step_by(3) {
            let r16: [Ray; 16] = std::array::from_fn(|l| rays[l]);
            let r8: [Ray; 8] = std::array::from_fn(|l| rays[l]);
            if PacketBlockRay::new(&r16, u32::from(u16::MAX)).is_none() {
                continue;
            }
            for &leaf in leaves.iter().step_by(7) {
                for any in [false, true] {
                    for lanes in [0xFFFF, 0x0FF0, 0x8001, 0x00FF] {
                        let want = leaf_visits::<16, false>(&tree, &r16, lanes, leaf, any);
                        let got = leaf_visits::<16, true>(&tree, &r16, lanes, leaf, any);
                        assert_eq!(got, want, "16 lanes {lanes:#x}, any {any}");
                        visits += want.0.len();
                        hits += want.0.iter().map(|v| v.2.len()).sum::<usize>();
                    }
                    let want = leaf_visits::<8, false>(&tree, &r8, 0xFF, leaf, any);
                    assert_eq!(leaf_visits::<8, true>(&tree, &r8, 0xFF, leaf, any), want, "8 lanes");
                }
            }
        }
        assert!(
            visits > 100 && hits > 400,
            "the sweep hits: {visits} visits, {hits} lane hits"
        );
    }

    #[test]
    fn only_the_last_blocks_repeats_count_as_padding() {
        assert_eq!(padding(1, 0), 0b1110);
        assert_eq!(padding(3, 0), 0b1000);
        assert_eq!(padding(4, 0), 0);
        assert_eq!(padding(5, 0), 0);
        assert_eq!(padding(5, 1), 0b1110);
        assert_eq!(padding(8, 1), 0);
        assert_eq!(padding(11, 2), 0b1000);
        // Every slot is either a triangle of the leaf or padding.
        for n in 1usize..40 {
            let real: u32 = (0..n.div_ceil(LANES))
                .map(|k| LANES as u32 - padding(n, k).count_ones())
                .sum();
            assert_eq!(real as usize, n);
        }
    }

    #[test]
    fn padding_repeats_the_last_triangle_and_validate_checks_blocks() {
        let tris = meshgen::bumpy_sphere(2_000, 3, 0.3);
        let mut tree = KdTree::build_sah(tris).unwrap();
        let padded = tree
            .nodes()
            .iter()
            .find(|n| n.is_leaf() && !(n.prim_count() as usize).is_multiple_of(LANES))
            .copied();
        let leaf = padded.expect("some leaf has a partial block");
        let (off, cnt) = (leaf.prim_offset() as usize, leaf.prim_count() as usize);
        assert_eq!(off % LANES, 0);
        let last_block = (off + cnt - 1) / LANES;
        let b = tree.blocks[last_block];
        let last = tree.tris[tree.prim_ids[off + cnt - 1] as usize];
        for lane in cnt % LANES..LANES {
            assert_eq!(b.triangle(lane), last);
        }
        tree.validate().unwrap();
        // A block that no longer matches its triangle is an invalid tree.
        tree.blocks[last_block].v[1][2] += f32x4::splat(1e-3);
        let e = tree.validate().unwrap_err().to_string();
        assert!(e.contains("block lane"), "{e}");
    }
}
