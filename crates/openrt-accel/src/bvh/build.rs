//! The binned SAH build of the wide BVH.
//!
//! Wald, "On fast construction of SAH-based bounding volume hierarchies"
//! (IEEE RT 2007): triangles binned by their box centres into
//! [`BINS`] bins per axis ([`SMALL_BINS`] for short ranges), the cheapest of
//! the `3 (BINS - 1)` planes by the surface area heuristic. The wide node is grown directly (as collapsing a
//! binary tree would, Wald et al. 2008): a node starts with its whole range
//! as one child and splits its child of largest surface area until it has
//! four or none can be split. Deep down (past [`MEDIAN_DEPTH`]) or where
//! binning cannot separate the centres, the split is the median, so the
//! depth stays logarithmic for any input. Subtrees of at least
//! [`BVH_TASK_MIN`] triangles are built as tasks of the pool the build
//! runs in.

use glam::{BVec3A, Vec3, Vec3A, Vec4};

use super::node::{BVH_WIDTH, BvhNode, LEAF_BIT};
use crate::geom::aabb::Aabb;
use crate::leaf::blocks::LANES;

/// Bins per axis.
pub(crate) const BINS: usize = 16;

/// Bins per axis for ranges of fewer than [`SMALL_RANGE`] references.
///
/// PERF: most splits are of short ranges (a museum16k build makes about
/// 4,400, two thirds of them of 8 to 31 references), where clearing and
/// sweeping 16 bins cost more than binning; with 8 the museum16k builds
/// took 0.85 of the time for 0.1% more SAH cost.
pub(crate) const SMALL_BINS: usize = 8;

/// Ranges shorter than this are binned into [`SMALL_BINS`] bins.
pub(crate) const SMALL_RANGE: usize = 32;

/// Most triangles in a leaf (two blocks of four).
pub const BVH_MAX_LEAF: usize = 8;

/// Fewest references of a subtree built as a task of the pool (when two or
/// more of a node's interior children hold as many), for builds that run
/// on a pool's thread.
///
/// PERF: museum16k's moving triangles (16,384) on two threads: 0.75x the
/// build time of tasks from [`crate::kd::fast_build::PARALLEL_MIN`] (8,192)
/// up, where only the root's two halves ran side by side (512 to 2,048
/// within noise of each other; `museum_bvh` example, alternating rounds).
pub(crate) const BVH_TASK_MIN: usize = 1024;

/// Wide depth from which every split is the median.
pub(crate) const MEDIAN_DEPTH: usize = 32;

/// Cost of a node visit relative to one triangle block's test.
const TRAVERSAL_COST: f32 = 1.0;

/// A triangle as the builder sees it: its box, 32 bytes, with its index
/// in the corners' fourth lanes.
///
/// PERF: each corner is one SSE register (`Vec4`, read as `Vec3A`), so
/// the builder's box unions and centres are `minps`/`maxps`/`addps`; the
/// index rides in the spare lanes (a third less memory per pass than a
/// separate field: the 1M build moves its references a few times over
/// through memory). It is split into two exact floats below 2^16, so that
/// the arithmetic the lanes share never meets a subnormal (a slow path on
/// some CPUs).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Ref {
    lo: Vec4,
    hi: Vec4,
}

/// Bits of the index in the low corner's lane; the rest (at most 16, as
/// [`super::BVH_MAX_PRIMITIVES`] is 2^28) in the high corner's.
const ID_LOW_BITS: u32 = 12;
const _: () = assert!(super::BVH_MAX_PRIMITIVES <= 1 << (ID_LOW_BITS + 16));

impl Ref {
    /// The reference of triangle `id` (below [`super::BVH_MAX_PRIMITIVES`])
    /// with box `lo..hi`.
    pub(crate) fn new(lo: Vec3, hi: Vec3, id: u32) -> Self {
        debug_assert!((id as usize) < super::BVH_MAX_PRIMITIVES);
        Self {
            lo: lo.extend((id & ((1 << ID_LOW_BITS) - 1)) as f32),
            hi: hi.extend((id >> ID_LOW_BITS) as f32),
        }
    }

    /// The triangle's index.
    pub(crate) fn id(&self) -> u32 {
        (self.lo.w as u32) | ((self.hi.w as u32) << ID_LOW_BITS)
    }

    #[inline]
    fn lo(&self) -> Vec3A {
        Vec3A::from_vec4(self.lo)
    }

    #[inline]
    fn hi(&self) -> Vec3A {
        Vec3A::from_vec4(self.hi)
    }

    #[inline]
    fn centre(&self) -> Vec3A {
        (self.lo() + self.hi()) * 0.5
    }

    #[inline]
    fn bounds(&self) -> Box3A {
        Box3A(self.lo(), self.hi())
    }

    /// The reference's box.
    #[cfg(test)]
    pub(crate) fn aabb(&self) -> Aabb {
        self.bounds().aabb()
    }
}

/// A box as two `Vec3A` corners (empty: `+inf` / `-inf`).
#[derive(Clone, Copy)]
pub(crate) struct Box3A(Vec3A, Vec3A);

impl Box3A {
    const EMPTY: Self = Self(Vec3A::INFINITY, Vec3A::NEG_INFINITY);

    #[inline]
    fn union(self, o: Self) -> Self {
        Self(self.0.min(o.0), self.1.max(o.1))
    }

    /// Surface area of a box that holds a point (the empty box's would
    /// be garbage): [`Aabb::surface_area`]'s arithmetic in one register.
    #[inline]
    fn area(self) -> f32 {
        let e = self.1 - self.0;
        let [x, y, z] = (e * Vec3A::new(e.y, e.z, e.x)).to_array();
        2.0 * (x + y + z)
    }

    fn aabb(self) -> Aabb {
        Aabb {
            min: Vec3::from(self.0),
            max: Vec3::from(self.1),
        }
    }
}

/// Bounds of a range of references.
pub(crate) fn bounds_of(refs: &[Ref]) -> Aabb {
    refs.iter().fold(Box3A::EMPTY, |b, r| b.union(r.bounds())).aabb()
}

/// Leaf cost of `n` triangles: blocks of [`LANES`] are tested at once.
#[inline]
fn leaf_cost(n: usize) -> f32 {
    n.div_ceil(LANES) as f32
}

/// A candidate child of the node being grown.
#[derive(Clone, Copy)]
struct Kid {
    start: usize,
    end: usize,
    bounds: Aabb,
    known: Known,
    leaf: bool,
}

/// What the builder already knows of a range.
#[derive(Clone, Copy)]
enum Known {
    Nothing,
    /// The bounds of its box centres (found by the split that made it).
    Centres(Box3A),
    /// Its split, made already (the range is partitioned).
    Split(usize, Option<Sides>),
}

impl Known {
    fn centres(c: Option<Box3A>) -> Self {
        c.map_or(Self::Nothing, Self::Centres)
    }
}

/// What a binned split learns of its two sides: their bounds and the
/// bounds of their box centres.
#[derive(Clone, Copy)]
struct Sides {
    left: Aabb,
    right: Aabb,
    centres: (Box3A, Box3A),
}

/// Where to split a range: at `mid` after partitioning (with what binning
/// learnt of the two sides), or not at all.
#[derive(Clone, Copy)]
enum Split {
    Leaf,
    At(usize, Option<Sides>),
}

/// Bounds of the box centres of a range of references.
fn centres_of(refs: &[Ref]) -> Box3A {
    refs.iter().fold(Box3A::EMPTY, |b, r| {
        let c = r.centre();
        Box3A(b.0.min(c), b.1.max(c))
    })
}

/// The best SAH split of `refs` (partitioned in place), or a leaf;
/// `centres` bounds the box centres when the caller knows them.
fn split(refs: &mut [Ref], bounds: &Aabb, centres: Option<Box3A>, depth: usize) -> Split {
    let n = refs.len();
    // Up to one block, a leaf costs one block test, and any split at least
    // a node visit and a block test: a leaf, without binning.
    if n <= LANES {
        return Split::Leaf;
    }
    let Box3A(clo, chi) = centres.unwrap_or_else(|| centres_of(refs));
    let ext = chi - clo;
    let usable = ext.cmpgt(Vec3A::ZERO) & ext.is_finite_mask();
    let bins = if n < SMALL_RANGE { SMALL_BINS } else { BINS };
    let scale = Vec3A::select(usable, bins as f32 / ext, Vec3A::ZERO);
    let best = if depth >= MEDIAN_DEPTH || !usable.any() {
        None
    } else if bins == SMALL_BINS {
        best_bin::<SMALL_BINS>(refs, clo, scale, usable)
    } else {
        best_bin::<BINS>(refs, clo, scale, usable)
    };
    if let Some(best) = best {
        let area = bounds.surface_area().max(f32::MIN_POSITIVE);
        let split_cost = TRAVERSAL_COST + best.cost / area;
        if n <= BVH_MAX_LEAF && split_cost >= leaf_cost(n) {
            return Split::Leaf;
        }
        let (axis, bin) = (best.axis, best.bin);
        let (lo, scale, next) = (clo[axis], scale[axis], (bin + 1) as f32);
        let (mid, lc, rc) = partition(refs, |c| left_of(c[axis], lo, scale, next));
        if mid > 0 && mid < n {
            return Split::At(
                mid,
                Some(Sides {
                    left: best.left,
                    right: best.right,
                    centres: (lc, rc),
                }),
            );
        }
    } else if n <= 2 {
        return Split::Leaf;
    }
    // The median along the widest spread of centres (or of the order
    // given, when every centre is the same point).
    let axis = if ext.max_element() > 0.0 { ext.max_position() } else { 0 };
    let mid = n / 2;
    refs.select_nth_unstable_by(mid, |a, b| a.centre()[axis].total_cmp(&b.centre()[axis]));
    Split::At(mid, None)
}

/// The bins of a centre on the three axes: `(c - lo) * scale` clamped to
/// `0..=BINS - 1` and truncated (NaN, from an axis that bins nothing, goes
/// to bin 0). Binning and partitioning both call it, so they agree.
///
/// PERF: one SSE conversion for the three axes; a saturating `as usize`
/// per axis was a sixth of the build's time.
#[inline]
fn bins_of(c: Vec3A, lo: Vec3A, scale: Vec3A, bins: usize) -> [usize; 3] {
    // `max` first: SSE's `maxps` answers its second operand (0) for NaN,
    // as `f32::max` does.
    let f = ((c - lo) * scale).max(Vec3A::ZERO).min(Vec3A::splat((bins - 1) as f32));
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128, _mm_cvtsi128_si32, _mm_cvttps_epi32, _mm_shuffle_epi32};
        // SAFETY: SSE2 is part of every x86_64 CPU (the target's baseline);
        // the intrinsics touch registers only.
        let [x, y, z] = unsafe {
            let i = _mm_cvttps_epi32(__m128::from(f));
            [
                _mm_cvtsi128_si32(i),
                _mm_cvtsi128_si32(_mm_shuffle_epi32::<0b01>(i)),
                _mm_cvtsi128_si32(_mm_shuffle_epi32::<0b10>(i)),
            ]
        };
        // The lanes hold 0..=BINS - 1: the casts are exact.
        [x as usize, y as usize, z as usize]
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        f.to_array().map(|x| x as usize)
    }
}

/// Whether a centre's coordinate `c` falls in a bin before `next` (at
/// most `bins - 1`, as the sweep's planes are): `bins_of(..)[axis] <
/// next` on one axis, without the clamps (a coordinate past the last bin
/// is past `next` unclamped too, and NaN, which `bins_of` puts in bin 0,
/// fails the comparison).
#[inline]
fn left_of(c: f32, lo: f32, scale: f32, next: f32) -> bool {
    let f = (c - lo) * scale;
    f < next || f.is_nan()
}

/// The cheapest binned plane.
struct BestBin {
    axis: usize,
    /// Last bin of the left side.
    bin: usize,
    /// `A_left N_left + A_right N_right` (counts in blocks).
    cost: f32,
    /// The two sides' bounds (unions of their bins' boxes).
    left: Aabb,
    right: Aabb,
}

/// The cheapest binned plane over the three axes, binned in one pass over
/// the references; `None` when no axis separates the centres.
fn best_bin<const BINS: usize>(refs: &[Ref], clo: Vec3A, scale: Vec3A, usable: BVec3A) -> Option<BestBin> {
    const { assert!(BINS.is_power_of_two()) };
    let mut boxes = [[Box3A::EMPTY; BINS]; 3];
    let mut counts = [[0u32; BINS]; 3];
    for r in refs {
        let bins = bins_of(r.centre(), clo, scale, BINS);
        for a in 0..3 {
            // PERF: `bins_of` answers below `BINS` (a power of two): the
            // mask lets the compiler drop the bounds checks.
            let b = bins[a] & (BINS - 1);
            counts[a][b] += 1;
            boxes[a][b] = boxes[a][b].union(r.bounds());
        }
    }
    let mut best: Option<BestBin> = None;
    for axis in (0..3).filter(|&a| usable.test(a)) {
        let (boxes, counts) = (&boxes[axis], &counts[axis]);
        // Right-to-left sweep of the right sides' boxes and counts.
        let mut right_box = [Box3A::EMPTY; BINS];
        let mut right_n = [0usize; BINS];
        let (mut acc, mut n) = (Box3A::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc = acc.union(boxes[b]);
            n += counts[b] as usize;
            right_box[b] = acc;
            right_n[b] = n;
        }
        let (mut acc, mut n) = (Box3A::EMPTY, 0);
        for b in 0..BINS - 1 {
            // An empty bin leaves both sides as the plane before it left
            // them: no cheaper plane (and most bins of a small range are
            // empty).
            if counts[b] == 0 {
                continue;
            }
            acc = acc.union(boxes[b]);
            n += counts[b] as usize;
            if right_n[b + 1] == 0 {
                continue;
            }
            let cost = acc.area() * leaf_cost(n) + right_box[b + 1].area() * leaf_cost(right_n[b + 1]);
            if best.as_ref().is_none_or(|x| cost < x.cost) {
                best = Some(BestBin {
                    axis,
                    bin: b,
                    cost,
                    left: acc.aabb(),
                    right: right_box[b + 1].aabb(),
                });
            }
        }
    }
    best
}

/// Partitions `refs` so that those for which `left` holds come first;
/// returns how many they are and the bounds of the two sides' box centres
/// (PERF: the children's splits need not pass over their ranges for them).
fn partition(refs: &mut [Ref], left: impl Fn(Vec3A) -> bool) -> (usize, Box3A, Box3A) {
    let (mut lc, mut rc) = (Box3A::EMPTY, Box3A::EMPTY);
    let mut l = 0;
    // PERF: without branches (Lomuto's scheme: every reference swapped
    // with the first right one, the left count raised by the test), as the
    // side of a reference is a coin toss to the branch predictor on
    // scattered triangles (museum16k builds: 0.80 of the time).
    for i in 0..refs.len() {
        let r = refs[i];
        let c = r.centre();
        let is_left = left(c);
        let m = BVec3A::splat(is_left);
        lc = Box3A(
            lc.0.min(Vec3A::select(m, c, Vec3A::INFINITY)),
            lc.1.max(Vec3A::select(m, c, Vec3A::NEG_INFINITY)),
        );
        rc = Box3A(
            rc.0.min(Vec3A::select(m, Vec3A::INFINITY, c)),
            rc.1.max(Vec3A::select(m, Vec3A::NEG_INFINITY, c)),
        );
        refs[i] = refs[l];
        refs[l] = r;
        l += usize::from(is_left);
    }
    (l, lc, rc)
}

/// Grows the node's children: the range split at its child of largest
/// area until there are [`BVH_WIDTH`] or none splits.
fn grow(refs: &mut [Ref], bounds: Aabb, known: Known, depth: usize) -> ([Kid; BVH_WIDTH], usize) {
    let mut kids = [Kid {
        start: 0,
        end: 0,
        bounds: Aabb::EMPTY,
        known: Known::Nothing,
        leaf: true,
    }; BVH_WIDTH];
    kids[0] = Kid {
        start: 0,
        end: refs.len(),
        bounds,
        known,
        leaf: refs.len() <= LANES,
    };
    let mut n = 1;
    while n < BVH_WIDTH {
        let Some(k) = (0..n)
            .filter(|&k| !kids[k].leaf)
            .max_by(|&a, &b| kids[a].bounds.surface_area().total_cmp(&kids[b].bounds.surface_area()))
        else {
            break;
        };
        let Kid {
            start,
            end,
            bounds,
            known,
            ..
        } = kids[k];
        let made = match known {
            Known::Split(mid, sides) => Split::At(mid, sides),
            Known::Centres(c) => split(&mut refs[start..end], &bounds, Some(c), depth),
            Known::Nothing => split(&mut refs[start..end], &bounds, None, depth),
        };
        match made {
            Split::Leaf => kids[k].leaf = true,
            Split::At(mid, sides) => {
                let (l, r) = (start..start + mid, start + mid..end);
                let (lb, rb, lc, rc) = match sides {
                    Some(s) => (s.left, s.right, Some(s.centres.0), Some(s.centres.1)),
                    None => (bounds_of(&refs[l.clone()]), bounds_of(&refs[r.clone()]), None, None),
                };
                kids[k] = Kid {
                    start: l.start,
                    end: l.end,
                    bounds: lb,
                    known: Known::centres(lc),
                    leaf: l.len() <= LANES,
                };
                kids[n] = Kid {
                    start: r.start,
                    end: r.end,
                    bounds: rb,
                    known: Known::centres(rc),
                    leaf: r.len() <= LANES,
                };
                n += 1;
            }
        }
    }
    // Children left unsplit at the width limit: small ones become leaves
    // where the SAH says so; a split made here is kept for the child's node
    // (PERF: three in four such children split; split again, they were a
    // sixth of the museums' splits).
    for kid in &mut kids[..n] {
        let count = kid.end - kid.start;
        if !kid.leaf && count <= BVH_MAX_LEAF {
            let centres = match kid.known {
                Known::Centres(c) => Some(c),
                _ => None,
            };
            match split(&mut refs[kid.start..kid.end], &kid.bounds, centres, depth + 1) {
                Split::Leaf => kid.leaf = true,
                Split::At(mid, sides) => kid.known = Known::Split(mid, sides),
            }
        }
    }
    kids[..n].sort_by_key(|k| k.start);
    (kids, n)
}

/// Builds the subtree of `refs` (whose first entry is entry `base` of the
/// whole array) into `nodes`, its root first; leaves hold
/// `LEAF_BIT | (base + start)` for now. `centres` bounds the box centres
/// when the parent's split found them. Where two or more interior children
/// hold at least `task_min` references each, they are built as tasks of
/// the current rayon pool (`usize::MAX`: never), their nodes appended after
/// in child order: the same tree on any number of threads. Returns the
/// deepest wide level.
pub(crate) fn build_into(
    refs: &mut [Ref],
    base: usize,
    bounds: Aabb,
    centres: Option<Box3A>,
    depth: usize,
    task_min: usize,
    nodes: &mut Vec<BvhNode>,
) -> usize {
    build_node(refs, base, bounds, Known::centres(centres), depth, task_min, nodes)
}

/// [`build_into`] with what the parent's node learnt of the range.
fn build_node(
    refs: &mut [Ref],
    base: usize,
    bounds: Aabb,
    known: Known,
    depth: usize,
    task_min: usize,
    nodes: &mut Vec<BvhNode>,
) -> usize {
    let me = nodes.len();
    nodes.push(BvhNode::empty());
    let (kids, n) = grow(refs, bounds, known, depth);
    let mut deepest = depth + 1;
    let big = kids[..n]
        .iter()
        .filter(|k| !k.leaf && k.end - k.start >= task_min)
        .count()
        > 1;
    if big {
        // The interior children as tasks, each into its own array,
        // appended after with their indices moved.
        let mut subs: Vec<(usize, Vec<BvhNode>, usize)> = Vec::new();
        let mut rest: &mut [Ref] = refs;
        let mut slices = Vec::new();
        let mut at = 0;
        for (i, k) in kids[..n].iter().enumerate() {
            let (_, tail) = rest.split_at_mut(k.start - at);
            let (mine, tail) = tail.split_at_mut(k.end - k.start);
            rest = tail;
            at = k.end;
            if !k.leaf {
                slices.push((i, mine));
            }
        }
        let done: Vec<(usize, Vec<BvhNode>, usize)> = {
            use rayon::prelude::*;
            slices
                .into_par_iter()
                .map(|(i, mine)| {
                    let k = kids[i];
                    let mut sub = Vec::new();
                    let d = build_node(mine, base + k.start, k.bounds, k.known, depth + 1, task_min, &mut sub);
                    (i, sub, d)
                })
                .collect()
        };
        subs.extend(done);
        for (i, k) in kids[..n].iter().enumerate() {
            nodes[me].set_box(i, &k.bounds);
            if k.leaf {
                nodes[me].child[i] = LEAF_BIT | (base + k.start) as u32;
                nodes[me].count[i] = (k.end - k.start) as u32;
            }
        }
        for (i, sub, d) in subs {
            let shift = nodes.len() as u32;
            nodes[me].child[i] = shift;
            deepest = deepest.max(d);
            nodes.extend(sub.into_iter().map(|mut node| {
                for c in &mut node.child {
                    if *c & LEAF_BIT == 0 {
                        *c += shift;
                    }
                }
                node
            }));
        }
        return deepest;
    }
    for (i, k) in kids[..n].iter().enumerate() {
        nodes[me].set_box(i, &k.bounds);
        if k.leaf {
            nodes[me].child[i] = LEAF_BIT | (base + k.start) as u32;
            nodes[me].count[i] = (k.end - k.start) as u32;
        } else {
            let child = nodes.len() as u32;
            nodes[me].child[i] = child;
            let d = build_node(
                &mut refs[k.start..k.end],
                base + k.start,
                k.bounds,
                k.known,
                depth + 1,
                task_min,
                nodes,
            );
            deepest = deepest.max(d);
        }
    }
    deepest
}

#[cfg(test)]
mod tests {
    use glam::Vec3A;
    use rand::{Rng, SeedableRng, rngs::SmallRng};

    use super::{BINS, Ref, SMALL_BINS, bins_of, left_of};

    #[test]
    fn references_keep_their_index_and_box() {
        let (lo, hi) = (glam::Vec3::new(-1.0, 2.0, -3.5), glam::Vec3::new(4.0, 2.0, 1e30));
        for id in [
            0,
            1,
            4095,
            4096,
            4097,
            123_456_789,
            (crate::bvh::BVH_MAX_PRIMITIVES - 1) as u32,
        ] {
            let r = Ref::new(lo, hi, id);
            assert_eq!(r.id(), id);
            assert_eq!((r.lo(), r.hi()), (lo.into(), hi.into()));
            assert_eq!(r.centre(), ((lo + hi) * 0.5).into());
        }
    }

    /// The scalar twin: one axis, `as usize` saturating (NaN to 0).
    fn bin_scalar(c: f32, lo: f32, scale: f32) -> usize {
        (((c - lo) * scale) as usize).min(BINS - 1)
    }

    fn check(c: Vec3A, lo: Vec3A, scale: Vec3A) {
        let got = bins_of(c, lo, scale, BINS);
        for a in 0..3 {
            assert_eq!(
                got[a],
                bin_scalar(c[a], lo[a], scale[a]),
                "axis {a}: c {c:?} lo {lo:?} scale {scale:?}"
            );
        }
        // The partition's side test agrees with the bins on every plane
        // the sweep can choose, at both bin counts.
        for bins in [BINS, SMALL_BINS] {
            let got = bins_of(c, lo, scale * (bins as f32 / BINS as f32), bins);
            for a in 0..3 {
                for bin in 0..bins - 1 {
                    let s = scale[a] * (bins as f32 / BINS as f32);
                    assert_eq!(
                        left_of(c[a], lo[a], s, (bin + 1) as f32),
                        got[a] <= bin,
                        "{bins} bins, plane after bin {bin}: c {c:?} lo {lo:?} scale {s}"
                    );
                }
            }
        }
    }

    #[test]
    fn bins_of_matches_the_scalar_twin() {
        let mut rng = SmallRng::seed_from_u64(11);
        for _ in 0..100_000 {
            let lo = Vec3A::from_array(std::array::from_fn(|_| rng.random_range(-100.0..100.0)));
            let ext = Vec3A::from_array(std::array::from_fn(|_| rng.random_range(1e-6f32..50.0)));
            let c = lo + ext * Vec3A::from_array(std::array::from_fn(|_| rng.random_range(0.0f32..=1.0)));
            check(c, lo, BINS as f32 / ext);
        }
        // The ends of the range, exact bin borders, unusable axes (scale 0),
        // and the NaN an overflowing axis gives.
        let lo = Vec3A::new(-1.0, 0.0, 3.0);
        let ext = Vec3A::new(2.0, 16.0, 0.5);
        let scale = BINS as f32 / ext;
        for k in 0..=BINS {
            let c = lo + ext * (k as f32 / BINS as f32);
            check(c, lo, scale);
            check(c, lo, Vec3A::ZERO);
        }
        check(Vec3A::splat(f32::MAX), Vec3A::splat(-f32::MAX), Vec3A::ZERO);
        check(Vec3A::splat(f32::MAX), Vec3A::splat(-f32::MAX), Vec3A::splat(1e-30));
        check(Vec3A::splat(f32::NAN), Vec3A::ZERO, Vec3A::ONE);
        check(Vec3A::splat(1e30), Vec3A::ZERO, Vec3A::splat(1e30));
    }
}
