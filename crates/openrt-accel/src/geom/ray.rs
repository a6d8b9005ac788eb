//! Rays with the per-ray constants that the kernels need.

use glam::Vec3;
use wide::f32x4;

/// A ray `origin + t * dir` restricted to the open interval `(t_min, t_max)`.
///
/// **Hits lie in front of the origin.** Every query reports hits at `t > 0`
/// only, so the interval searched is `(max(t_min, 0), t_max)`: a negative
/// `t_min` is allowed and means the same as `0`. (The watertight test's
/// conservative `t > 0` check rejects hits at or behind the origin; the f64
/// oracle follows the same rule.) A NaN bound, a zero or non-finite direction,
/// or a non-finite origin gives a ray that hits nothing.
///
/// The constructor precomputes everything that does not depend on the
/// primitive being tested:
/// - `inv_dir`, a reciprocal direction that is *safe* for `0.0` and `-0.0`
///   components: such a component gets `±f32::MAX` (sign of the zero) instead
///   of an infinity, so `(plane - origin) * inv_dir` is never `0 * inf = NaN`.
///   Kernels still branch on `dir[axis] == 0.0` where the side of a plane must
///   be decided by the origin alone (a ray lying in a split plane).
/// - the axis permutation and shear of Woop, Benthin & Wald, "Watertight
///   Ray/Triangle Intersection", JCGT 2(1), 2013, so that the triangle test
///   does no per-triangle division.
///
/// `dir` is not normalised: `t` is measured in units of `dir`, which keeps
/// `t` meaningful when a ray is transformed into an object's space.
// PERF: laid out as written (`repr(C)`), 60 bytes: a packet's lanes are
// read four floats at a time (origin and `dir.x`, the rest of `dir` and the
// interval, `inv_dir` and `shear.x`: `PacketBoxes::new`), and blocks of
// rays are copied whole by the shading.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Ray {
    /// Ray origin.
    pub origin: Vec3,
    /// Ray direction (any non-zero length).
    pub dir: Vec3,
    /// Hits must satisfy `t > t_min` (and `t > 0`: see the type docs).
    pub t_min: f32,
    /// Hits must satisfy `t < t_max`.
    pub t_max: f32,
    /// Safe reciprocal of `dir` (see the type docs).
    pub(crate) inv_dir: Vec3,
    /// Shear constants `(Sx, Sy, Sz)` of the watertight test.
    pub(crate) shear: Vec3,
    /// Index of the dominant direction component (the shear's z axis), then x, y.
    pub(crate) kz: u8,
    pub(crate) kx: u8,
    pub(crate) ky: u8,
}

impl Ray {
    /// Builds a ray and its precomputed constants.
    ///
    /// A zero or non-finite direction gives a ray that hits nothing (its
    /// interval is made empty); callers that must report such input as an
    /// error check [`Ray::is_valid`] first.
    // PERF: inlined (`#[inline]`, left to the compiler): robots Whitted
    // frames 4% faster side by side, the other scenes and modes the same.
    #[must_use]
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Self {
        Self::new_inline(origin, dir, t_min, t_max)
    }

    /// [`Ray::new`] forced inline, for callers that make many rays and
    /// store each at once (a light's shadow rays): a call's ray came back
    /// through memory and was copied on before its stores had landed
    /// (failed store forwarding). [`Ray::new`] is only `#[inline]`, which
    /// leaves the choice to the compiler.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    #[must_use]
    pub fn new_inline(origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Self {
        let inv_dir = Vec3::new(safe_rcp(dir.x), safe_rcp(dir.y), safe_rcp(dir.z));
        let a = dir.abs();
        let kz: u8 = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding of the projected triangle: swap when dir[kz] < 0.
        let dz = dir[usize::from(kz)];
        if dz < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let valid = dz != 0.0 && dir.is_finite() && origin.is_finite();
        let shear = if valid {
            Vec3::new(dir[usize::from(kx)] / dz, dir[usize::from(ky)] / dz, 1.0 / dz)
        } else {
            Vec3::ZERO
        };
        let (t_min, t_max) = if valid && !t_min.is_nan() && !t_max.is_nan() {
            (t_min, t_max)
        } else {
            (1.0, 0.0)
        };
        Self {
            origin,
            dir,
            t_min,
            t_max,
            inv_dir,
            shear,
            kz,
            kx,
            ky,
        }
    }

    /// A ray over `(0, +inf)`.
    #[must_use]
    pub fn infinite(origin: Vec3, dir: Vec3) -> Self {
        Self::new(origin, dir, 0.0, f32::INFINITY)
    }

    /// The same ray with a new interval (the precomputed constants are reused).
    #[must_use]
    pub fn with_interval(mut self, t_min: f32, t_max: f32) -> Self {
        if self.is_valid() {
            self.t_min = t_min;
            self.t_max = t_max;
        }
        self
    }

    /// The watertight test's axes `[kx, ky, kz]` (`kz` the dominant one).
    #[inline]
    pub(crate) fn axes(&self) -> [usize; 3] {
        [usize::from(self.kx), usize::from(self.ky), usize::from(self.kz)]
    }

    /// `true` when origin and direction are finite and the direction is non-zero.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        self.shear != Vec3::ZERO
    }

    /// The point at parameter `t`.
    #[must_use]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }

    /// The safe reciprocal direction (see the type docs).
    #[must_use]
    pub fn inv_dir(&self) -> Vec3 {
        self.inv_dir
    }
}

/// Four rays at once, [`Ray::new`]'s bits lane by lane: lane `i` of
/// `origin` and `dir` (x, y and z registers) is written to `out[i]` where
/// `lanes` has bit `i`; the other rays are left as they are. The
/// reciprocals and the shear take one vector division per component for
/// the four rays, the dominant axis is chosen by compares, and every value
/// is the scalar constructor's operation on the same operands (tested).
/// For callers that make a packet's rays (camera rays, a light's shadow
/// rays) with their coordinates already in registers.
///
/// # Panics
/// When `out` holds fewer than four rays.
#[allow(clippy::inline_always, clippy::similar_names)]
#[inline(always)]
pub fn rays_from_lanes(out: &mut [Ray], lanes: u32, origin: [f32x4; 3], dir: [f32x4; 3], t_min: f32, t_max: f32) {
    let out = &mut out[..4];
    let [dx, dy, dz] = dir;
    let (zero, one, inf) = (f32x4::ZERO, f32x4::ONE, f32x4::splat(f32::INFINITY));
    // `safe_rcp`: a zero component (either sign) gives `±f32::MAX`.
    let rcp = |x: f32x4| {
        let max = f32x4::splat(f32::MAX) | (x & f32x4::splat(-0.0));
        x.simd_eq(zero).bitselect(max, one / x)
    };
    let inv = [rcp(dx), rcp(dy), rcp(dz)];
    // The dominant axis as `Ray::new` picks it: x when |x| >= |y| and
    // |x| >= |z|, else y when |y| >= |z|, else z (NaN compares false).
    let (ax, ay, az) = (dx.abs(), dy.abs(), dz.abs());
    let is_x = ax.simd_ge(ay) & ax.simd_ge(az);
    let y_over_z = ay.simd_ge(az);
    let d_kz = is_x.bitselect(dx, y_over_z.bitselect(dy, dz));
    // Before the swap: kz = x takes (y, z), y takes (z, x), z takes (x, y).
    let first = is_x.bitselect(dy, y_over_z.bitselect(dz, dx));
    let second = is_x.bitselect(dz, y_over_z.bitselect(dx, dy));
    let swap = d_kz.simd_lt(zero);
    let (d_kx, d_ky) = (swap.bitselect(second, first), swap.bitselect(first, second));
    let finite = |v: [f32x4; 3]| v[0].abs().simd_lt(inf) & v[1].abs().simd_lt(inf) & v[2].abs().simd_lt(inf);
    let valid = d_kz.simd_ne(zero) & finite(dir) & finite(origin);
    let shear = [(d_kx / d_kz) & valid, (d_ky / d_kz) & valid, (one / d_kz) & valid];
    let (valid, is_x, y_over_z, swap) = (
        valid.to_bitmask(),
        is_x.to_bitmask(),
        y_over_z.to_bitmask(),
        swap.to_bitmask(),
    );
    let interval = !t_min.is_nan() && !t_max.is_nan();
    let arrays = |v: [f32x4; 3]| v.map(f32x4::to_array);
    let (o, d, inv, shear) = (arrays(origin), arrays(dir), arrays(inv), arrays(shear));
    let vec = |v: &[[f32; 4]; 3], i: usize| Vec3::new(v[0][i], v[1][i], v[2][i]);
    for (i, ray) in out.iter_mut().enumerate() {
        if lanes & (1 << i) == 0 {
            continue;
        }
        let bit = |m: u32| m & (1 << i) != 0;
        let kz: u8 = if bit(is_x) {
            0
        } else if bit(y_over_z) {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if bit(swap) {
            std::mem::swap(&mut kx, &mut ky);
        }
        let (t_min, t_max) = if bit(valid) && interval {
            (t_min, t_max)
        } else {
            (1.0, 0.0)
        };
        *ray = Ray {
            origin: vec(&o, i),
            dir: vec(&d, i),
            t_min,
            t_max,
            inv_dir: vec(&inv, i),
            shear: vec(&shear, i),
            kz,
            kx,
            ky,
        };
    }
}

/// `1/x`, with `±f32::MAX` for `±0.0` so that products never make NaN.
#[inline]
fn safe_rcp(x: f32) -> f32 {
    if x == 0.0 { f32::MAX.copysign(x) } else { 1.0 / x }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_and_negative_zero_components_give_signed_finite_reciprocals() {
        let r = Ray::infinite(Vec3::ZERO, Vec3::new(0.0, -0.0, 1.0));
        assert_eq!(r.inv_dir.x, f32::MAX);
        assert_eq!(r.inv_dir.y, -f32::MAX);
        assert_eq!(r.inv_dir.z, 1.0);
        // A plane through the origin gives t = 0, never NaN.
        assert_eq!((0.0 - r.origin.x) * r.inv_dir.x, 0.0);
        assert_eq!(r.kz, 2);
    }

    #[test]
    fn invalid_rays_have_an_empty_interval() {
        let r = Ray::infinite(Vec3::ZERO, Vec3::ZERO);
        assert!(!r.is_valid());
        assert!(r.t_min > r.t_max);
        let r = Ray::infinite(Vec3::splat(f32::NAN), Vec3::X);
        assert!(!r.is_valid());
        let r = Ray::new(Vec3::ZERO, Vec3::X, f32::NAN, 1.0);
        assert!(r.t_min > r.t_max);
    }

    /// The layout `PacketBoxes::new` reads four floats at a time: 60 bytes,
    /// the floats in the order origin, dir, t_min, t_max, inv_dir, shear.
    #[test]
    fn rays_are_laid_out_as_the_packet_layout_reads_them() {
        use std::mem::{offset_of, size_of};
        assert_eq!(size_of::<Ray>(), 60);
        let at = [
            offset_of!(Ray, origin),
            offset_of!(Ray, dir),
            offset_of!(Ray, t_min),
            offset_of!(Ray, t_max),
            offset_of!(Ray, inv_dir),
            offset_of!(Ray, shear),
        ];
        assert_eq!(at, [0, 12, 24, 28, 32, 44]);
    }

    /// Every field of a ray as bits (NaN equal to itself).
    fn bits(r: &Ray) -> ([u32; 14], [u8; 3]) {
        let v = [r.origin, r.dir, r.inv_dir, r.shear];
        let mut f = [0u32; 14];
        for (k, x) in v.iter().flat_map(Vec3::to_array).enumerate() {
            f[k] = x.to_bits();
        }
        (f[12], f[13]) = (r.t_min.to_bits(), r.t_max.to_bits());
        (f, [r.kz, r.kx, r.ky])
    }

    /// Four rays at once are `Ray::new`'s bits lane by lane, on random rays
    /// and on the hard components (zeros of either sign, ties between the
    /// dominant axes, NaN, infinities, subnormals, huge values), with NaN
    /// intervals and any lanes masked off (those rays left as they were).
    #[test]
    fn four_rays_at_once_are_the_scalar_constructor() {
        use rand::rngs::SmallRng;
        use rand::{Rng, SeedableRng};
        let mut rng = SmallRng::seed_from_u64(0x4a7e_5001);
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::NAN,
            f32::INFINITY,
            -f32::INFINITY,
            1e-40,
            -3e38,
            0.5,
        ];
        let comp = |rng: &mut SmallRng| match rng.random_range(0..4) {
            0 => special[rng.random_range(0..special.len())],
            1 => [1.0f32, -1.0][rng.random_range(0..2)] * 2.0,
            _ => rng.random_range(-10.0..10.0),
        };
        let mut valid = 0;
        for round in 0..50_000 {
            let lanes3 = |rng: &mut SmallRng| {
                let mut v = [[0f32; 4]; 3];
                for lane in 0..4 {
                    for axis in &mut v {
                        axis[lane] = comp(rng);
                    }
                }
                v
            };
            let (o, d) = (lanes3(&mut rng), lanes3(&mut rng));
            let t_min = if round % 97 == 0 {
                f32::NAN
            } else {
                rng.random_range(-1.0..1.0)
            };
            let t_max = if round % 89 == 0 {
                f32::NAN
            } else {
                rng.random_range(1.0..100.0)
            };
            let mask = rng.random_range(0..16u32);
            let keep = Ray::infinite(Vec3::splat(7.0), Vec3::X);
            let mut out = [keep; 4];
            rays_from_lanes(&mut out, mask, o.map(f32x4::from), d.map(f32x4::from), t_min, t_max);
            for i in 0..4 {
                let at = |v: &[[f32; 4]; 3]| Vec3::new(v[0][i], v[1][i], v[2][i]);
                let want = if mask & (1 << i) != 0 {
                    Ray::new(at(&o), at(&d), t_min, t_max)
                } else {
                    keep
                };
                valid += usize::from(want.is_valid() && mask & (1 << i) != 0);
                assert_eq!(bits(&out[i]), bits(&want), "round {round}, lane {i}: {:?}", out[i]);
            }
        }
        // The sweep reaches valid rays, not only rejected ones.
        assert!(valid > 20_000, "{valid} valid rays");
    }

    #[test]
    fn shear_axis_follows_the_dominant_component_and_keeps_winding() {
        let r = Ray::infinite(Vec3::ZERO, Vec3::new(0.1, -3.0, 0.5));
        assert_eq!(r.kz, 1);
        // dir[kz] < 0 swaps kx and ky.
        assert_eq!((r.kx, r.ky), (0, 2));
        assert!((r.shear.z + 1.0 / 3.0).abs() < 1e-7);
    }
}
