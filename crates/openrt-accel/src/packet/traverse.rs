//! Front-to-back kd-tree traversal of a ray packet, shared by object trees
//! and the top-level instance tree: the scalar walk of [`crate::traverse`]
//! made lane-parallel, one node load and one decision per step for the
//! whole packet.
//!
//! Wald, Benthin, Wagner & Slusallek, "Interactive Rendering with Coherent
//! Ray Tracing" (Eurographics 2001): the lanes share the order of every
//! split (common direction signs), each lane keeps its own parameter
//! interval, and a subtree is entered with the lanes that need it.
//!
//! NOTE: every lane makes exactly the decisions of its scalar walk, in the
//! same arithmetic (the split distance, the `BOUND` widening, the interval
//! updates and the pop test), and meets its leaves in the same order, so a
//! lane's hits are bit-identical to [`crate::traverse`]'s (tested against
//! it). One care: a lane that the scalar walk sends to the far child alone
//! goes there at once, without the pop test against its closest hit; here it
//! waits on the stack behind the near subtree, so its entry carries it in an
//! `unchecked` mask that the pop test lets through.

use crate::geom::ray::Ray;
use crate::kd::node::{KdNode, MAX_DEPTH};
use crate::kd::traverse::{traverse, widen_down, widen_up};
use crate::packet::boxes::PacketBoxes;
use crate::packet::width::MAX_LANES;
use crate::packet::width::{by_axis, lanes_of, sign_groups};

/// A deferred far child with the lanes that visit it and their intervals.
#[derive(Clone, Copy)]
struct Entry<const N: usize> {
    node: u32,
    /// Lanes that visit the far child.
    mask: u32,
    /// Lanes among those that the scalar walk sends there without the pop test.
    unchecked: u32,
    t_min: [f32; N],
    t_max: [f32; N],
}

/// The bits of the lanes where `f(lane)` holds.
// PERF: forced inline so that the lane loop and `f` compile to one vector compare.
#[allow(clippy::inline_always)]
#[inline(always)]
fn bits<const N: usize>(f: impl Fn(usize) -> bool) -> u32 {
    let mut m = 0u32;
    for l in 0..N {
        m |= u32::from(f(l)) << l;
    }
    m
}

/// Walks the cells pierced by the rays of the `lanes` mask, each over its
/// `[t0, t1]`, front to back, and calls `leaf(node, lanes, closest)` for each
/// non-empty leaf with the lanes that visit it, where `closest[l]` is lane
/// `l`'s closest hit distance, which the callback lowers when it finds a
/// closer hit. The callback returns the lanes that are done (any-hit
/// queries); they take no further part. Returns the lanes the callback
/// finished.
///
/// Lanes that share direction signs walk together; lanes with a zero
/// direction component walk alone through [`crate::traverse`]. For each lane
/// the leaves met, their order and the closest distances seen are those of
/// [`crate::traverse`] on that lane's ray alone.
pub fn traverse_packet<const N: usize, L>(
    nodes: &[KdNode],
    rays: &[Ray; N],
    lanes: u32,
    t0: &[f32; N],
    t1: &[f32; N],
    closest: &mut [f32; N],
    leaf: L,
) -> u32
where
    L: FnMut(KdNode, u32, &mut [f32; N]) -> u32,
{
    traverse_packet_laid(nodes, rays, None, lanes, t0, t1, closest, leaf)
}

/// [`traverse_packet`] with the rays' origins, reciprocal directions and
/// direction signs read from `laid` (the same rays laid out lane by lane)
/// when given, instead of gathered from the rays again. The same walk.
#[allow(clippy::too_many_arguments)]
pub fn traverse_packet_laid<const N: usize, L>(
    nodes: &[KdNode],
    rays: &[Ray; N],
    laid: Option<&PacketBoxes<N>>,
    lanes: u32,
    t0: &[f32; N],
    t1: &[f32; N],
    closest: &mut [f32; N],
    mut leaf: L,
) -> u32
where
    L: FnMut(KdNode, u32, &mut [f32; N]) -> u32,
{
    const { assert!(N <= MAX_LANES) };
    if nodes.is_empty() {
        return 0;
    }
    // The scalar walk's own early exit, per lane.
    let lanes = lanes & bits::<N>(|l| !(t0[l].is_nan() || t1[l].is_nan() || t0[l] > t1[l]));
    let (groups, alone) = match laid {
        Some(b) => b.sign_groups(lanes),
        None => sign_groups(rays, lanes),
    };
    let mut done = 0;
    // Origins and safe reciprocal directions, axis by axis, gathered when a
    // group first needs them (lanes outside a group compute with whatever
    // they hold and are never looked at).
    let mut gathered = None;
    for (signs, &group) in groups.iter().enumerate() {
        match group.count_ones() {
            0 => {}
            // PERF: a lone lane takes the scalar walk (no lane loops).
            1 => done |= alone_walk(nodes, rays, group, t0, t1, closest, &mut leaf),
            _ => {
                let (org, inv) = if let Some(b) = laid {
                    (&b.o, &b.inv)
                } else {
                    let (org, inv) =
                        gathered.get_or_insert_with(|| (by_axis(rays, |r| r.origin), by_axis(rays, |r| r.inv_dir)));
                    (&*org, &*inv)
                };
                done |= walk_for_cpu(nodes, org, inv, group, signs as u32, t0, t1, closest, &mut leaf);
            }
        }
    }
    for l in lanes_of(alone) {
        done |= alone_walk(nodes, rays, 1 << l, t0, t1, closest, &mut leaf);
    }
    done
}

/// The scalar walk of the one lane in `lane`, reporting to the packet callback.
fn alone_walk<const N: usize, L>(
    nodes: &[KdNode],
    rays: &[Ray; N],
    lane: u32,
    t0: &[f32; N],
    t1: &[f32; N],
    closest: &mut [f32; N],
    leaf: &mut L,
) -> u32
where
    L: FnMut(KdNode, u32, &mut [f32; N]) -> u32,
{
    let l = lane.trailing_zeros() as usize;
    let mut c = closest[l];
    let stopped = traverse(nodes, &rays[l], t0[l], t1[l], &mut c, |n, cl| {
        closest[l] = *cl;
        let stop = leaf(n, lane, closest) & lane != 0;
        *cl = closest[l];
        stop
    });
    closest[l] = c;
    if stopped { lane } else { 0 }
}

/// [`walk`] compiled for the CPU: on CPUs with AVX2, packets of 8 lanes
/// and more take a copy compiled for AVX2, whose lane loops run eight lanes to
/// a register (the same operations lane by lane, so the same bits: tested
/// against the portable copy).
// PERF: kitchen primary packet queries 0.96 of the portable walk's time
// with 16 lanes (measured when it was written).
#[allow(clippy::too_many_arguments)]
#[inline]
fn walk_for_cpu<const N: usize, L>(
    nodes: &[KdNode],
    org: &[[f32; N]; 3],
    inv: &[[f32; N]; 3],
    lanes: u32,
    signs: u32,
    t0: &[f32; N],
    t1: &[f32; N],
    closest: &mut [f32; N],
    leaf: &mut L,
) -> u32
where
    L: FnMut(KdNode, u32, &mut [f32; N]) -> u32,
{
    #[cfg(target_arch = "x86_64")]
    if N >= 8 && crate::packet::width::avx2() {
        // SAFETY: the CPU has AVX2.
        return unsafe { walk_avx2(nodes, org, inv, lanes, signs, t0, t1, closest, leaf) };
    }
    walk(nodes, org, inv, lanes, signs, t0, t1, closest, leaf)
}

/// [`walk`] compiled for AVX2.
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
unsafe fn walk_avx2<const N: usize, L>(
    nodes: &[KdNode],
    org: &[[f32; N]; 3],
    inv: &[[f32; N]; 3],
    lanes: u32,
    signs: u32,
    t0: &[f32; N],
    t1: &[f32; N],
    closest: &mut [f32; N],
    leaf: &mut L,
) -> u32
where
    L: FnMut(KdNode, u32, &mut [f32; N]) -> u32,
{
    walk(nodes, org, inv, lanes, signs, t0, t1, closest, leaf)
}

/// The packet walk of `lanes`, which share the direction signs `signs`
/// (bit `k`: component `k` negative) and have no zero component.
#[allow(clippy::too_many_arguments, clippy::inline_always)]
#[inline(always)]
fn walk<const N: usize, L>(
    nodes: &[KdNode],
    org: &[[f32; N]; 3],
    inv: &[[f32; N]; 3],
    lanes: u32,
    signs: u32,
    t0: &[f32; N],
    t1: &[f32; N],
    closest: &mut [f32; N],
    leaf: &mut L,
) -> u32
where
    L: FnMut(KdNode, u32, &mut [f32; N]) -> u32,
{
    let mut t_min: [f32; N] = std::array::from_fn(|l| widen_down(t0[l]));
    let mut t_max: [f32; N] = std::array::from_fn(|l| widen_up(t1[l]));
    // PERF: the stack is not zeroed: entries are written before they are read.
    let mut stack = [std::mem::MaybeUninit::<Entry<N>>::uninit(); MAX_DEPTH];
    let mut sp = 0usize;
    let mut node = 0u32;
    let mut active = lanes;
    let mut done = 0u32;
    'walk: loop {
        let n = nodes[node as usize];
        'cell: {
            if n.is_leaf() {
                if n.prim_count() > 0 {
                    let d = leaf(n, active, closest) & active;
                    if d != 0 {
                        done |= d;
                        if done == lanes {
                            return done;
                        }
                    }
                }
                break 'cell;
            }
            let axis = n.axis();
            let split = n.split();
            let (o, iv) = (&org[axis], &inv[axis]);
            let below = (node + 1, n.below_empty());
            let above = (n.above_child(), n.above_child() == 0);
            let ((near, near_empty), (far, far_empty)) = if (signs >> axis) & 1 != 0 {
                (above, below)
            } else {
                (below, above)
            };
            let t_split: [f32; N] = std::array::from_fn(|l| (split - o[l]) * iv[l]);
            // The plane lies before / beyond each lane's interval (false for NaN).
            let before = bits::<N>(|l| t_split[l] < t_min[l]);
            let beyond = bits::<N>(|l| t_split[l] > t_max[l]);
            let go_near = if near_empty { 0 } else { active & !before };
            let go_far = if far_empty { 0 } else { active & !beyond };
            // Each lane's far interval starts at its widened split distance
            // (the scalar walk's `lo`), whether the far cell waits or is next.
            // PERF: computed only when the far cell is visited (most steps
            // send the whole packet to one child).
            let far_min = |t_min: &[f32; N]| -> [f32; N] {
                std::array::from_fn(|l| {
                    let lo = widen_down(t_split[l]);
                    if lo > t_min[l] { lo } else { t_min[l] }
                })
            };
            if go_near != 0 {
                if go_far != 0 {
                    stack[sp].write(Entry {
                        node: far,
                        mask: go_far,
                        unchecked: go_far & !go_near,
                        t_min: far_min(&t_min),
                        t_max,
                    });
                    sp += 1;
                }
                for l in 0..N {
                    let hi = widen_up(t_split[l]);
                    t_max[l] = if hi < t_max[l] { hi } else { t_max[l] };
                }
                active = go_near;
                node = near;
                continue 'walk;
            }
            if go_far != 0 {
                t_min = far_min(&t_min);
                active = go_far;
                node = far;
                continue 'walk;
            }
        }
        // Pop, skipping lanes whose cell starts beyond their closest hit.
        loop {
            if sp == 0 {
                return done;
            }
            sp -= 1;
            // SAFETY: entries below `sp` were written by a push.
            let e = unsafe { stack[sp].assume_init_ref() };
            let near_enough = bits::<N>(|l| e.t_min[l] <= closest[l]);
            let m = e.mask & !done & (near_enough | e.unchecked);
            if m != 0 {
                node = e.node;
                active = m;
                t_min = e.t_min;
                t_max = e.t_max;
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::geom::aabb::Aabb;
    use crate::kd::tree::KdTree;
    use crate::testing::meshgen;

    /// What a walk told its leaf callback, bit for bit: per leaf its
    /// range, the lanes and their closest distances; then the lanes done.
    type Visits = (Vec<(u32, u32, u32, Vec<u32>)>, u32);

    /// Walks `lanes` (one sign group) with `avx2` or the portable copy; the
    /// callback lowers some lanes' closest distances and, in an any-hit
    /// walk, finishes some lanes, as a query would.
    fn visits<const N: usize>(tree: &KdTree, rays: &[Ray; N], lanes: u32, signs: u32, any: bool, avx2: bool) -> Visits {
        let t0 = [0.0f32; N];
        let t1: [f32; N] = std::array::from_fn(|l| if l % 3 == 1 { 3.0 } else { rays[l].t_max });
        let mut closest: [f32; N] = std::array::from_fn(|l| rays[l].t_max);
        let (org, inv) = (by_axis(rays, |r| r.origin), by_axis(rays, |r| r.inv_dir));
        let mut seen = Vec::new();
        let mut leaf = |n: KdNode, active: u32, closest: &mut [f32; N]| {
            seen.push((
                n.prim_offset(),
                n.prim_count(),
                active,
                closest.iter().map(|c| c.to_bits()).collect(),
            ));
            let k = seen.len() as u32;
            let mut done = 0;
            for l in lanes_of(active) {
                if (k + l as u32).is_multiple_of(4) {
                    closest[l] = closest[l].min(1.0 + 0.25 * (n.prim_offset() % 16) as f32);
                    done |= u32::from(any) << l;
                }
            }
            done
        };
        #[cfg(target_arch = "x86_64")]
        if avx2 {
            // SAFETY: the caller checked that the CPU has AVX2.
            let done = unsafe {
                walk_avx2(
                    tree.nodes(),
                    &org,
                    &inv,
                    lanes,
                    signs,
                    &t0,
                    &t1,
                    &mut closest,
                    &mut leaf,
                )
            };
            return (seen, done);
        }
        let done = walk(
            tree.nodes(),
            &org,
            &inv,
            lanes,
            signs,
            &t0,
            &t1,
            &mut closest,
            &mut leaf,
        );
        (seen, done)
    }

    fn compare<const N: usize>(tree: &KdTree, rays: &[Ray]) -> usize {
        let mut leaves = 0;
        for chunk in rays.chunks_exact(N) {
            let pk: [Ray; N] = std::array::from_fn(|l| chunk[l]);
            let (groups, _) = sign_groups(&pk, crate::packet::width::lanes_mask(N));
            for (signs, &group) in groups.iter().enumerate() {
                if group.count_ones() < 2 {
                    continue;
                }
                for any in [false, true] {
                    let want = visits(tree, &pk, group, signs as u32, any, false);
                    let got = visits(tree, &pk, group, signs as u32, any, true);
                    assert_eq!(got, want, "N={N}, lanes {group:#x}, any {any}");
                    leaves += want.0.len();
                }
            }
        }
        leaves
    }

    /// A walk reading the lanes laid out ([`traverse_packet_laid`]) meets
    /// the leaves of the walk gathering them from the rays, with the same
    /// lanes and closest distances, bit for bit (every sign group, lone
    /// lanes and lanes with a zero direction component included).
    #[test]
    fn the_laid_out_walk_is_the_rays_walk() {
        let tris = meshgen::bumpy_sphere(4_000, 7, 0.4);
        let tree = KdTree::build_sah(tris).unwrap();
        let mut rays = meshgen::camera_rays(Vec3::new(0.4, 0.3, 3.0), Vec3::ZERO, 32, 32, 60.0);
        rays.extend(meshgen::random_rays(
            1024,
            9,
            Aabb::new(Vec3::splat(-1.5), Vec3::splat(1.5)),
        ));
        for (k, r) in rays.iter_mut().enumerate().filter(|(k, _)| k % 37 == 0) {
            *r = Ray::infinite(
                r.origin,
                Vec3::new(r.dir.x, if k % 2 == 0 { 0.0 } else { -0.0 }, r.dir.z),
            );
        }
        let mut leaves = 0;
        for (k, chunk) in rays.chunks_exact(16).enumerate() {
            let pk: [Ray; 16] = std::array::from_fn(|l| chunk[l]);
            let lanes = if k % 3 == 0 { 0xffff } else { 0x5a5a | k as u32 & 0xffff };
            let laid = PacketBoxes::new(&pk, lanes);
            let walk = |laid: Option<&PacketBoxes<16>>| {
                let (t0, t1, live) = laid.map_or_else(
                    || tree.bounds().clip_lanes(&pk, lanes, &[f32::INFINITY; 16]),
                    |b| b.clip(&tree.bounds(), lanes, &[f32::INFINITY; 16]),
                );
                let mut closest = [f32::INFINITY; 16];
                let mut seen = Vec::new();
                let done =
                    traverse_packet_laid(tree.nodes(), &pk, laid, live, &t0, &t1, &mut closest, |n, active, c| {
                        seen.push((n.prim_offset(), active, c.map(f32::to_bits)));
                        let l = active.trailing_zeros() as usize;
                        c[l] = c[l].min(1.0 + 0.25 * (n.prim_offset() % 16) as f32);
                        active & u32::from(seen.len() % 5 == 0)
                    });
                (seen, done)
            };
            let want = walk(None);
            assert_eq!(walk(Some(&laid)), want, "packet {k}");
            leaves += want.0.len();
        }
        assert!(leaves > 500, "the walks meet leaves: {leaves}");
    }

    #[test]
    fn the_avx2_walk_meets_the_portable_walks_leaves_bit_for_bit() {
        #[cfg(target_arch = "x86_64")]
        if !crate::packet::width::avx2() {
            return;
        }
        let tris = meshgen::bumpy_sphere(4_000, 7, 0.4);
        let tree = KdTree::build_sah(tris).unwrap();
        let mut rays = meshgen::camera_rays(Vec3::new(0.4, 0.3, 3.0), Vec3::ZERO, 32, 32, 60.0);
        rays.extend(meshgen::random_rays(
            1024,
            5,
            Aabb::new(Vec3::splat(-1.5), Vec3::splat(1.5)),
        ));
        let leaves = compare::<32>(&tree, &rays)
            + compare::<16>(&tree, &rays)
            + compare::<8>(&tree, &rays)
            + compare::<4>(&tree, &rays);
        assert!(leaves > 1_000, "the walks meet leaves: {leaves}");
    }
}
