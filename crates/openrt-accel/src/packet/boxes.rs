//! A packet's rays laid out lane by lane for quick, conservative box tests.
//!
//! In the two-level walk, each instance a packet meets costs every lane an
//! object-space ray (a transform and [`Ray::new`]) and a box clip before
//! the object's tree is entered. Most lanes that reach a top-level leaf
//! miss most of its instances. [`PacketBoxes::reaching`] tests the whole
//! packet against an instance's world box at once, so the lanes that cannot
//! reach it skip that work.
//!
//! [`PacketBoxes::clip`] is the exact clip of [`Aabb::clip_lanes`] on the
//! same layout: the bits of the lane-by-lane clip, without gathering each
//! lane's fields from its [`Ray`] again for every box.
//!
//! NOTE: the quick test only ever keeps too many lanes, never too few: the box
//! is widened by [`BOX_SLACK`] of the largest coordinate of the box and
//! the rays' origins (far beyond the rounding of the transforms that take
//! rays to object space and of this test), each lane's far bound by a
//! relative 1e-5, and lanes with a zero or non-finite reciprocal
//! direction component always pass (the exact clip decides them).

use wide::f32x4;

use crate::geom::aabb::Aabb;
use crate::geom::box_quad::BoxQuad;
use crate::geom::numeric::gamma;
use crate::geom::ray::Ray;

/// Relative widening of the boxes tested by [`PacketBoxes::reaching`].
pub const BOX_SLACK: f32 = 1e-4;

/// The lanes of a packet in structure-of-arrays order.
pub struct PacketBoxes<const N: usize> {
    pub(crate) o: [[f32; N]; 3],
    pub(crate) inv: [[f32; N]; 3],
    /// The directions (a zero component is decided by the origin alone).
    dir: [[f32; N]; 3],
    pub(crate) t_min: [f32; N],
    /// The rays' own far bounds (an invalid ray keeps its empty interval).
    t_max: [f32; N],
    /// Lanes whose ray is valid ([`Ray::is_valid`]).
    valid: u32,
    /// Lanes with three finite, non-zero reciprocal direction components.
    pub(crate) testable: u32,
    /// Largest coordinate of the lanes' origins.
    pub(crate) scale: f32,
}

/// A packet's rays transposed: each field's values lane by lane.
struct Laid<const N: usize> {
    o: [[f32; N]; 3],
    dir: [[f32; N]; 3],
    inv: [[f32; N]; 3],
    t_min: [f32; N],
    t_max: [f32; N],
    /// Lanes whose ray is valid ([`Ray::is_valid`]: a non-zero shear).
    valid: u32,
}

impl<const N: usize> Laid<N> {
    /// The lanes of `rays`, four at a time: the ray's fields lie in the
    /// order `origin, dir, t_min, t_max, inv_dir, shear` (`Ray` is
    /// `repr(C)`), so each ray gives four rows of four adjacent floats,
    /// transposed into four lanes of each field.
    #[inline]
    fn new(rays: &[Ray; N]) -> Self {
        let mut out = Self {
            o: [[0.0; N]; 3],
            dir: [[0.0; N]; 3],
            inv: [[0.0; N]; 3],
            t_min: [0.0; N],
            t_max: [0.0; N],
            valid: 0,
        };
        let mut chunks = rays.chunks_exact(4);
        for (k, c) in chunks.by_ref().enumerate() {
            let rows = |f: &dyn Fn(&Ray) -> [f32; 4]| f32x4::transpose(std::array::from_fn(|i| f32x4::new(f(&c[i]))));
            let a = rows(&|r| [r.origin.x, r.origin.y, r.origin.z, r.dir.x]);
            let b = rows(&|r| [r.dir.y, r.dir.z, r.t_min, r.t_max]);
            let v = rows(&|r| [r.inv_dir.x, r.inv_dir.y, r.inv_dir.z, r.shear.x]);
            let s = rows(&|r| [r.shear.y, r.shear.z, 0.0, 0.0]);
            let at = 4 * k..4 * k + 4;
            let put = |row: &mut [f32; N], v: f32x4| row[at.clone()].copy_from_slice(v.as_array());
            put(&mut out.o[0], a[0]);
            put(&mut out.o[1], a[1]);
            put(&mut out.o[2], a[2]);
            put(&mut out.dir[0], a[3]);
            put(&mut out.dir[1], b[0]);
            put(&mut out.dir[2], b[1]);
            put(&mut out.t_min, b[2]);
            put(&mut out.t_max, b[3]);
            put(&mut out.inv[0], v[0]);
            put(&mut out.inv[1], v[1]);
            put(&mut out.inv[2], v[2]);
            // `shear != Vec3::ZERO`: some component not equal to zero.
            let zero = f32x4::ZERO;
            let nonzero = !(v[3].simd_eq(zero) & s[0].simd_eq(zero) & s[1].simd_eq(zero));
            out.valid |= (nonzero.to_bitmask() & 0xf) << (4 * k);
        }
        let done = N - chunks.remainder().len();
        for (l, r) in rays.iter().enumerate().skip(done) {
            for a in 0..3 {
                out.o[a][l] = r.origin[a];
                out.dir[a][l] = r.dir[a];
                out.inv[a][l] = r.inv_dir[a];
            }
            out.t_min[l] = r.t_min;
            out.t_max[l] = r.t_max;
            out.valid |= u32::from(r.is_valid()) << l;
        }
        out
    }
}

impl<const N: usize> PacketBoxes<N> {
    /// The `lanes` of `rays`.
    #[must_use]
    pub fn new(rays: &[Ray; N], lanes: u32) -> Self {
        let Laid {
            o,
            dir,
            inv,
            t_min,
            t_max,
            valid,
        } = Laid::new(rays);
        // Testable lanes and the largest coordinate of their origins.
        // PERF: four lanes at a time on the laid-out values (a lane loop of
        // finiteness tests was half of this function's samples).
        let (mut testable, mut scale) = (0u32, f32x4::ZERO);
        let quad = |v: &[f32; N], c: usize| f32x4::new([v[c], v[c + 1], v[c + 2], v[c + 3]]);
        for c in (0..N - N % 4).step_by(4) {
            let mut ok = f32x4::splat(f32::from_bits(u32::MAX));
            let mut m = f32x4::ZERO;
            for a in 0..3 {
                let (ov, iv) = (quad(&o[a], c), quad(&inv[a], c));
                ok = ok & ov.is_finite() & iv.is_finite() & iv.simd_ne(f32x4::ZERO);
                m = m.fast_max(ov.abs());
            }
            let bits = ok.to_bitmask() & (lanes >> c) & 0xf;
            testable |= bits << c;
            let keep = f32x4::new(std::array::from_fn(|i| {
                f32::from_bits(if bits & (1 << i) != 0 { u32::MAX } else { 0 })
            }));
            scale = keep.bitselect(scale.fast_max(m), scale);
        }
        let mut scale = scale.to_array().into_iter().fold(0.0f32, f32::max);
        for l in crate::packet::width::lanes_of(lanes).filter(|&l| l >= N - N % 4) {
            let r = &rays[l];
            if r.inv_dir.is_finite() && r.origin.is_finite() && r.inv_dir.cmpne(glam::Vec3::ZERO).all() {
                testable |= 1 << l;
                scale = scale.max(r.origin.abs().max_element());
            }
        }
        Self {
            o,
            inv,
            dir,
            t_min,
            t_max,
            valid,
            testable,
            scale,
        }
    }

    /// The lanes of `lanes` that may reach `bounds` before `t_max[l]`: every
    /// lane whose ray meets the box in that interval, and perhaps a few
    /// that pass close to it.
    #[must_use]
    #[inline]
    pub fn reaching(&self, bounds: &Aabb, lanes: u32, t_max: &[f32; N]) -> u32 {
        let check = lanes & self.testable;
        if check == 0 {
            return lanes;
        }
        let slack = BOX_SLACK * bounds.min.abs().max(bounds.max.abs()).max_element().max(self.scale);
        if !slack.is_finite() {
            return lanes;
        }
        let lo = (bounds.min - slack).to_array();
        let hi = (bounds.max + slack).to_array();
        let mut near = self.t_min;
        let mut far: [f32; N] = std::array::from_fn(|l| t_max[l] * (1.0 + 1e-5));
        for a in 0..3 {
            for l in 0..N {
                let t0 = (lo[a] - self.o[a][l]) * self.inv[a][l];
                let t1 = (hi[a] - self.o[a][l]) * self.inv[a][l];
                // PERF: selects, not `f32::max`/`min` (whose NaN rules
                // compile to several instructions per lane): 12% of a robots
                // primary-ray profile. `t0` and `t1` are never NaN here (a
                // testable lane has a finite origin and a finite, non-zero
                // reciprocal direction), and a NaN `near` or `far` gives way
                // to them as with `max`/`min`.
                let (first, last) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
                near[l] = if near[l] >= first { near[l] } else { first };
                far[l] = if far[l] <= last { far[l] } else { last };
            }
        }
        let mut hit = 0u32;
        // PERF: four lanes at a time from aligned loads: as a lane loop the
        // compiler peeled lane 0 and read lanes 1-4, 5-8, ... across two of
        // the stores just made (failed store forwarding: 11% of the
        // function's samples on robots).
        for c in (0..N).step_by(4) {
            let load = |v: &[f32; N]| {
                f32x4::from(std::array::from_fn::<f32, 4, _>(|i| {
                    v.get(c + i).copied().unwrap_or(0.0)
                }))
            };
            // NOTE: a NaN bound keeps the lane (the exact clip decides it).
            let keep = load(&near).simd_le(load(&far)) | load(t_max).is_nan();
            hit |= keep.to_bitmask() << c;
        }
        // Lanes that could not be tested pass.
        (hit & check) | (lanes & !self.testable)
    }
}

impl<const N: usize> PacketBoxes<N> {
    /// The laid-out origins, directions and the rays' own bounds.
    #[allow(clippy::type_complexity)]
    pub(crate) fn rows(&self) -> (&[[f32; N]; 3], &[[f32; N]; 3], &[f32; N], &[f32; N]) {
        (&self.o, &self.dir, &self.t_min, &self.t_max)
    }

    /// [`crate::sign_groups`] of the rays these boxes were made from, read
    /// from the laid-out directions: the same groups, bit for bit.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    #[must_use]
    pub(crate) fn sign_groups(&self, mask: u32) -> ([u32; 8], u32) {
        crate::packet::width::sign_groups_of::<N>(|a, l| self.dir[a][l], mask)
    }
}

/// [`PacketBoxes::reaching`] for one ray: `false` only when `ray` cannot
/// meet `bounds` before `t_max` (with the same slack, the ray's origin
/// setting the scale as a packet's lanes do); a ray with a zero or
/// non-finite reciprocal direction component, or a non-finite origin,
/// always passes. The answer of a packet made of this ray alone, bit for
/// bit (tested), with no layout to make.
#[must_use]
#[inline]
pub fn ray_reaches(bounds: &Aabb, ray: &Ray, t_max: f32) -> bool {
    let (o, inv) = (ray.origin, ray.inv_dir);
    if !(inv.is_finite() && o.is_finite() && inv.cmpne(glam::Vec3::ZERO).all()) {
        return true;
    }
    let slack = BOX_SLACK
        * bounds
            .min
            .abs()
            .max(bounds.max.abs())
            .max_element()
            .max(0.0f32.max(o.abs().max_element()));
    if !slack.is_finite() {
        return true;
    }
    let (lo, hi) = ((bounds.min - slack).to_array(), (bounds.max + slack).to_array());
    let (o, inv) = (o.to_array(), inv.to_array());
    let mut near = ray.t_min;
    let mut far = t_max * (1.0 + 1e-5);
    for a in 0..3 {
        let t0 = (lo[a] - o[a]) * inv[a];
        let t1 = (hi[a] - o[a]) * inv[a];
        // The selects of `reaching`, in its order.
        let (first, last) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
        near = if near >= first { near } else { first };
        far = if far <= last { far } else { last };
    }
    near <= far || t_max.is_nan()
}

/// [`ray_reaches`] for the four boxes of `quad` at once (bit `i`: box `i`
/// may be reached): the same operations box by box, so the same answers
/// for boxes without NaN coordinates, empty ones included (tested).
#[must_use]
#[inline]
pub fn ray_reaches_quad(quad: &BoxQuad, ray: &Ray, t_max: f32) -> u32 {
    let (o, inv) = (ray.origin, ray.inv_dir);
    if !(inv.is_finite() && o.is_finite() && inv.cmpne(glam::Vec3::ZERO).all()) {
        return 0xF;
    }
    let (lo, hi) = (quad.min, quad.max);
    let scale = quad
        .largest_coordinate()
        .fast_max(f32x4::splat(0.0f32.max(o.abs().max_element())));
    let slack = f32x4::splat(BOX_SLACK) * scale;
    let (o, inv) = (o.to_array(), inv.to_array());
    let mut near = f32x4::splat(ray.t_min);
    let mut far = f32x4::splat(t_max * (1.0 + 1e-5));
    for a in 0..3 {
        let (oa, ia) = (f32x4::splat(o[a]), f32x4::splat(inv[a]));
        let t0 = (lo[a] - slack - oa) * ia;
        let t1 = (hi[a] + slack - oa) * ia;
        let order = t0.simd_lt(t1);
        let (first, last) = (order.bitselect(t0, t1), order.bitselect(t1, t0));
        near = near.simd_ge(first).bitselect(near, first);
        far = far.simd_le(last).bitselect(far, last);
    }
    let pass = if t_max.is_nan() { 0xF } else { 0 };
    ((near.simd_le(far) | !slack.is_finite()).to_bitmask() & 0xF) | pass
}

impl<const N: usize> PacketBoxes<N> {
    /// [`Aabb::clip_lanes`] of `bounds` for the rays these boxes were made
    /// from: the same entries, exits and lanes, bit for bit (the same
    /// operations lane by lane, in the same order, with the same selects),
    /// for any `lanes` (not only those given to [`PacketBoxes::new`]).
    #[must_use]
    #[inline]
    pub fn clip(&self, bounds: &Aabb, lanes: u32, t_max: &[f32; N]) -> ([f32; N], [f32; N], u32) {
        let mut t0 = [0.0f32; N];
        let mut t1 = [0.0f32; N];
        if lanes == 0 || bounds.is_empty() {
            return (t0, t1, 0);
        }
        let (lo, hi) = (bounds.min.to_array(), bounds.max.to_array());
        let widen = f32x4::splat(1.0 + 2.0 * gamma(3));
        let (zero, neg_inf, inf) = (
            f32x4::ZERO,
            f32x4::splat(f32::NEG_INFINITY),
            f32x4::splat(f32::INFINITY),
        );
        let mut live = 0u32;
        // PERF: four lanes at a time with SSE masks and selects (the lane
        // loop with `bool`s compiled to mask shuffling: 7% of a kitchen
        // primary-ray profile).
        for c in (0..N).step_by(4) {
            // Lanes past `N` read zeros and are masked off below.
            let load = |v: &[f32; N]| {
                f32x4::from(std::array::from_fn::<f32, 4, _>(|i| {
                    v.get(c + i).copied().unwrap_or(0.0)
                }))
            };
            let valid = f32x4::from(std::array::from_fn::<f32, 4, _>(|i| {
                f32::from_bits(if self.valid & (1 << (c + i)) != 0 { u32::MAX } else { 0 })
            }));
            let mut near = load(&self.t_min);
            let mut far = valid.bitselect(load(t_max), load(&self.t_max));
            let mut outside = zero;
            for a in 0..3 {
                let (o, inv, d) = (load(&self.o[a]), load(&self.inv[a]), load(&self.dir[a]));
                let (l, h) = (f32x4::splat(lo[a]), f32x4::splat(hi[a]));
                let x = (l - o) * inv;
                let y = (h - o) * inv;
                // `if x > y { (y, x) } else { (x, y) }`.
                let n = lt_else(y, x);
                let f = gt_else(x, y) * widen;
                let parallel = d.simd_eq(zero);
                outside |= parallel & (o.simd_lt(l) | o.simd_gt(h));
                let n = parallel.bitselect(neg_inf, n);
                let f = parallel.bitselect(inf, f);
                near = gt_else(n, near);
                far = lt_else(f, far);
            }
            // `clip`'s `t0 > t1` rejection (a NaN bound does not reject).
            let miss = (outside | near.simd_gt(far)).to_bitmask();
            let hit = !miss & (lanes >> c) & 0xf;
            // PERF: each array written with one 16-byte store (the walk
            // reads them back 16 bytes at a time at once; four lane stores
            // would fail store forwarding); lanes off are `0.0`.
            let on = f32x4::from(std::array::from_fn::<f32, 4, _>(|i| {
                f32::from_bits(if hit & (1 << i) != 0 { u32::MAX } else { 0 })
            }));
            let (near, far) = ((near & on).to_array(), (far & on).to_array());
            let n = 4.min(N - c);
            t0[c..c + n].copy_from_slice(&near[..n]);
            t1[c..c + n].copy_from_slice(&far[..n]);
            live |= hit << c;
        }
        (t0, t1, live)
    }
}

/// `if a > b { a } else { b }` lane by lane (`b` when either is NaN).
// PERF: one `maxps` on SSE, whose rule this is, for three instructions of a
// compare and a select (kitchen primary queries: the clips were 7% of them).
#[allow(clippy::inline_always)]
#[inline(always)]
fn gt_else(a: f32x4, b: f32x4) -> f32x4 {
    #[cfg(target_feature = "sse")]
    {
        a.fast_max(b)
    }
    #[cfg(not(target_feature = "sse"))]
    {
        a.simd_gt(b).bitselect(a, b)
    }
}

/// `if a < b { a } else { b }` lane by lane (`b` when either is NaN): one
/// `minps` on SSE, as [`gt_else`].
#[allow(clippy::inline_always)]
#[inline(always)]
fn lt_else(a: f32x4, b: f32x4) -> f32x4 {
    #[cfg(target_feature = "sse")]
    {
        a.fast_min(b)
    }
    #[cfg(not(target_feature = "sse"))]
    {
        a.simd_lt(b).bitselect(a, b)
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    use super::*;
    use crate::testing::meshgen;

    /// Rays of random and hard components: zeros of either sign, NaN,
    /// infinities, subnormals, huge values (valid rays and invalid ones).
    fn hard_rays(rng: &mut SmallRng, n: usize) -> Vec<Ray> {
        let special = [0.0, -0.0, 1.0, -1.0, f32::NAN, f32::INFINITY, 1e-40, -3e38, 0.5];
        let c = |rng: &mut SmallRng| {
            if rng.random_range(0..3) == 0 {
                special[rng.random_range(0..special.len())]
            } else {
                rng.random_range(-4.0..4.0)
            }
        };
        (0..n)
            .map(|_| {
                let o = Vec3::new(c(rng), c(rng), c(rng));
                let d = Vec3::new(c(rng), c(rng), c(rng));
                let t = [0.0, f32::NAN, 1.0, -2.0][rng.random_range(0..4)];
                Ray::new(o, d, t, [f32::INFINITY, 5.0, f32::NAN][rng.random_range(0..3)])
            })
            .collect()
    }

    /// The transposed lanes are each ray's own fields, bit for bit, and its
    /// validity, four lanes at a time and in a remainder of fewer.
    fn laid_is_each_rays_fields<const N: usize>(rng: &mut SmallRng) {
        for _ in 0..200 {
            let v = hard_rays(rng, N);
            let rays: [Ray; N] = std::array::from_fn(|l| v[l]);
            let laid = Laid::new(&rays);
            for (l, r) in rays.iter().enumerate() {
                for a in 0..3 {
                    assert_eq!(laid.o[a][l].to_bits(), r.origin[a].to_bits(), "{N}: origin {l}");
                    assert_eq!(laid.dir[a][l].to_bits(), r.dir[a].to_bits(), "{N}: dir {l}");
                    assert_eq!(laid.inv[a][l].to_bits(), r.inv_dir[a].to_bits(), "{N}: inv {l}");
                }
                assert_eq!(laid.t_min[l].to_bits(), r.t_min.to_bits());
                assert_eq!(laid.t_max[l].to_bits(), r.t_max.to_bits());
                assert_eq!(laid.valid & (1 << l) != 0, r.is_valid(), "{N}: lane {l} valid {r:?}");
            }
        }
    }

    #[test]
    fn rays_laid_out_are_their_fields() {
        let mut rng = SmallRng::seed_from_u64(0x1a1d);
        laid_is_each_rays_fields::<4>(&mut rng);
        laid_is_each_rays_fields::<6>(&mut rng);
        laid_is_each_rays_fields::<16>(&mut rng);
        laid_is_each_rays_fields::<32>(&mut rng);
        // Some of those rays were invalid, some valid.
        let v = hard_rays(&mut rng, 64);
        assert!(v.iter().any(Ray::is_valid) && !v.iter().all(Ray::is_valid));
    }

    /// A box of random centre and half-sizes inside the test world.
    fn random_box(rng: &mut SmallRng) -> Aabb {
        let c = Vec3::new(
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
        );
        let h = Vec3::new(
            rng.random_range(0.0..1.0),
            rng.random_range(0.0..1.0),
            rng.random_range(0.0..0.5),
        );
        Aabb::new(c - h, c + h)
    }

    /// The testable lanes and the origins' scale, four lanes at a time, are
    /// those of a lane loop: on random rays, zero, infinite and NaN direction
    /// components, huge and NaN origins, partial lane masks, and widths with
    /// lanes left over.
    #[test]
    fn testable_lanes_and_scale_are_the_lane_loops() {
        fn check<const N: usize>(rng: &mut SmallRng) {
            let world = Aabb::new(Vec3::splat(-4.0), Vec3::splat(4.0));
            let rays: [Ray; N] = std::array::from_fn(|_| {
                let r = meshgen::random_rays(1, rng.random(), world)[0];
                let (mut o, mut d) = (r.origin, r.dir);
                match rng.random_range(0..10) {
                    0 => d.y = if rng.random() { 0.0 } else { -0.0 },
                    1 => d.x = f32::INFINITY,
                    2 => d.z = f32::NAN,
                    3 => o.x = f32::NAN,
                    4 => o.y = -3e38,
                    5 => o.z = f32::INFINITY,
                    6 => d.x = 1e-45,
                    _ => {}
                }
                Ray::new(o, d, 0.0, f32::INFINITY)
            });
            let lanes = rng.random::<u32>() & (u32::MAX >> (32 - N));
            let (mut testable, mut scale) = (0u32, 0.0f32);
            for l in crate::packet::width::lanes_of(lanes) {
                let r = &rays[l];
                if r.inv_dir.is_finite() && r.origin.is_finite() && r.inv_dir.cmpne(Vec3::ZERO).all() {
                    testable |= 1 << l;
                    scale = scale.max(r.origin.abs().max_element());
                }
            }
            let b = PacketBoxes::new(&rays, lanes);
            assert_eq!(
                (b.testable, b.scale.to_bits()),
                (testable, scale.to_bits()),
                "{N} lanes {lanes:#x}"
            );
        }
        let mut rng = SmallRng::seed_from_u64(12);
        for _ in 0..3000 {
            check::<32>(&mut rng);
            check::<16>(&mut rng);
            check::<8>(&mut rng);
            check::<6>(&mut rng);
        }
    }

    /// The laid-out sign groups are the rays' ([`crate::sign_groups`]):
    /// random lanes with zero (0.0 and -0.0), infinite and NaN direction
    /// components, partial masks, widths with lanes left over.
    #[test]
    fn laid_out_sign_groups_are_the_rays() {
        fn check<const N: usize>(rng: &mut SmallRng) {
            let world = Aabb::new(Vec3::splat(-4.0), Vec3::splat(4.0));
            let rays: [Ray; N] = std::array::from_fn(|_| {
                let r = meshgen::random_rays(1, rng.random(), world)[0];
                let mut d = r.dir;
                match rng.random_range(0..8) {
                    0 => d.y = 0.0,
                    1 => d.x = -0.0,
                    2 => d.z = f32::NEG_INFINITY,
                    3 => d.z = f32::NAN,
                    4 => d.x = -f32::NAN,
                    _ => {}
                }
                Ray::new(r.origin, d, 0.0, f32::INFINITY)
            });
            let lanes = rng.random::<u32>() & (u32::MAX >> (32 - N));
            let b = PacketBoxes::new(&rays, rng.random::<u32>() & (u32::MAX >> (32 - N)));
            assert_eq!(
                b.sign_groups(lanes),
                crate::packet::width::sign_groups(&rays, lanes),
                "{N} lanes {lanes:#x}"
            );
        }
        let mut rng = SmallRng::seed_from_u64(19);
        for _ in 0..3000 {
            check::<32>(&mut rng);
            check::<16>(&mut rng);
            check::<8>(&mut rng);
            check::<6>(&mut rng);
        }
    }

    /// The laid-out clip is the lane-by-lane clip, bit for bit: random and
    /// axis-parallel lanes (0.0 and -0.0), invalid rays, NaN and infinite
    /// bounds, origins on the box's faces, boxes flat on an axis.
    #[test]
    fn laid_out_clips_are_the_lane_by_lane_clips() {
        let mut rng = SmallRng::seed_from_u64(5);
        let world = Aabb::new(Vec3::splat(-4.0), Vec3::splat(4.0));
        for round in 0..2000 {
            let mut rays: [Ray; 16] = std::array::from_fn(|_| meshgen::random_rays(1, rng.random(), world)[0]);
            let mut b = random_box(&mut rng);
            let c = b.center();
            match round % 8 {
                0 => {
                    rays[0] = Ray::new(rays[0].origin, Vec3::new(0.0, -0.0, 1.0), 0.0, f32::INFINITY);
                    rays[1] = Ray::new(Vec3::new(b.min.x, c.y, c.z), Vec3::new(0.0, 1.0, -0.0), -1.0, 5.0);
                }
                // An invalid ray inside the box keeps its empty interval.
                1 => rays[2] = Ray::new(c, Vec3::ZERO, 0.0, 1.0),
                2 => rays[3] = Ray::new(rays[3].origin, Vec3::X, f32::NAN, 1.0),
                3 => b.max.y = b.min.y,
                4 => rays[4] = Ray::new(b.max, -Vec3::ONE, 0.0, f32::INFINITY),
                5 => b = Aabb::EMPTY,
                _ => {}
            }
            let mut t_max: [f32; 16] = std::array::from_fn(|_| rng.random_range(0.5..20.0));
            t_max[5] = [f32::NAN, f32::INFINITY, 0.0, -1.0][round % 4];
            let made = rng.random::<u32>() & u32::from(u16::MAX);
            let pb = PacketBoxes::new(&rays, made);
            let lanes = rng.random::<u32>() & u32::from(u16::MAX);
            let (a0, a1, alive) = b.clip_lanes(&rays, lanes, &t_max);
            let (b0, b1, blive) = pb.clip(&b, lanes, &t_max);
            assert_eq!(alive, blive, "round {round}");
            assert_eq!(a0.map(f32::to_bits), b0.map(f32::to_bits), "round {round}");
            assert_eq!(a1.map(f32::to_bits), b1.map(f32::to_bits), "round {round}");
        }
    }

    #[test]
    fn every_lane_that_meets_a_box_is_kept() {
        let mut rng = SmallRng::seed_from_u64(3);
        let world = Aabb::new(Vec3::splat(-4.0), Vec3::splat(4.0));
        let (mut kept, mut dropped) = (0, 0);
        for round in 0..400 {
            let mut rays: [Ray; 16] = std::array::from_fn(|_| meshgen::random_rays(1, rng.random(), world)[0]);
            // Axis-parallel lanes and lanes far from the world's origin.
            if round % 4 == 0 {
                rays[0] = Ray::new(rays[0].origin, Vec3::new(0.0, -0.0, 1.0), 0.0, f32::INFINITY);
            }
            if round % 4 == 1 {
                rays[1] = Ray::new(rays[1].origin + Vec3::splat(1e5), rays[1].dir, 0.0, f32::INFINITY);
            }
            let mut t_max: [f32; 16] = std::array::from_fn(|_| rng.random_range(0.5..20.0));
            if round % 4 == 2 {
                t_max[2] = f32::NAN;
            }
            let pb = PacketBoxes::new(&rays, u32::from(u16::MAX));
            let b = random_box(&mut rng);
            let lanes = rng.random::<u32>() & u32::from(u16::MAX);
            let got = pb.reaching(&b, lanes, &t_max);
            assert_eq!(got & !lanes, 0, "only lanes of the mask");
            let (_, _, exact) = b.clip_lanes(&rays, lanes, &t_max);
            assert_eq!(exact & !got, 0, "round {round}: a lane that meets the box was dropped");
            if round % 4 == 2 {
                assert_eq!(got & lanes & 4, lanes & 4, "a NaN bound keeps its lane");
            }
            kept += got.count_ones();
            dropped += (lanes & !got).count_ones();
        }
        // It does cull: most random lanes miss a small box.
        assert!(dropped > kept, "{dropped} dropped, {kept} kept");
    }

    /// One ray's test is the answer of a packet holding that ray alone, on
    /// random rays and boxes, axis-parallel rays (0.0 and -0.0), NaN,
    /// infinite and huge origins and directions, NaN, infinite, zero and
    /// negative bounds; and it never drops a ray that meets the box.
    #[test]
    fn one_ray_is_a_packet_of_one_lane() {
        let mut rng = SmallRng::seed_from_u64(0x0e_ac4);
        let world = Aabb::new(Vec3::splat(-4.0), Vec3::splat(4.0));
        let (mut kept, mut dropped) = (0, 0);
        for round in 0..20_000 {
            let mut rays: [Ray; 16] = std::array::from_fn(|_| meshgen::random_rays(1, rng.random(), world)[0]);
            let l = rng.random_range(0..16);
            let (mut o, mut d) = (rays[l].origin, rays[l].dir);
            match round % 12 {
                0 => d.y = if rng.random() { 0.0 } else { -0.0 },
                1 => d.x = f32::INFINITY,
                2 => d.z = f32::NAN,
                3 => o.x = f32::NAN,
                4 => o.y = -3e38,
                5 => o += Vec3::splat(1e5),
                6 => d.x = 1e-45,
                _ => {}
            }
            rays[l] = Ray::new(o, d, rng.random_range(-1.0..0.5), f32::INFINITY);
            let t_max = match round % 9 {
                0 => f32::NAN,
                1 => f32::INFINITY,
                2 => 0.0,
                3 => -1.0,
                _ => rng.random_range(0.5..20.0),
            };
            let mut t = [1.0f32; 16];
            t[l] = t_max;
            let b = if round % 50 == 0 {
                Aabb::new(Vec3::splat(-f32::INFINITY), Vec3::splat(f32::INFINITY))
            } else {
                random_box(&mut rng)
            };
            let pb = PacketBoxes::new(&rays, 1 << l);
            let packet = pb.reaching(&b, 1 << l, &t) != 0;
            let one = ray_reaches(&b, &rays[l], t_max);
            assert_eq!(one, packet, "round {round}: {:?} to {t_max} against {b:?}", rays[l]);
            // Four boxes at once: this box in lane `round % 4`, others beside it.
            let mut four = [
                random_box(&mut rng),
                random_box(&mut rng),
                Aabb::EMPTY,
                random_box(&mut rng),
            ];
            four[round % 4] = b;
            let quad = ray_reaches_quad(&BoxQuad::pack(&four), &rays[l], t_max);
            for (i, bi) in four.iter().enumerate() {
                let want = ray_reaches(bi, &rays[l], t_max);
                assert_eq!(quad >> i & 1 != 0, want, "round {round} box {i}: quad against {bi:?}");
            }
            let (_, _, exact) = b.clip_lanes(&rays, 1 << l, &t);
            assert!(one || exact == 0, "round {round}: a ray that meets the box was dropped");
            if one {
                kept += 1;
            } else {
                dropped += 1;
            }
        }
        assert!(dropped > kept / 2, "it culls: {dropped} dropped, {kept} kept");
    }
}
