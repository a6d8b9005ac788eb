//! The Phong highlight's power `max(x, 0)^s` for four lights at once.
//!
//! `powf` was a library call per lit light in the middle of the light
//! loop: besides its own work, every call made the loop spill and reload
//! the vector registers it keeps live (the calling convention saves none
//! of them); left out, a GL-like kitchen frame took 17% less time. Here
//! the four lanes of a light quad take one pass of plain arithmetic,
//! `2^(s log2 x)`: `log2` from the exponent bits and the `atanh` series of
//! the centred mantissa (1e-8 relative), `2^y` from `y` rounded to an
//! integer and a degree-6 polynomial on the rest (2e-8). The result lies
//! within a few units in the last place of the exact power plus the
//! rounding of the product `s log2 x`, which grows with its magnitude as
//! in any single-precision power (tested against f64 `powf`). Powers below
//! `2^-126` are flushed to zero and exponents above 127 saturate (finite).
//! Every lane is a fixed sequence of IEEE operations, so the single-ray
//! path and the packets, which both shade through this function, give the
//! same bits.

use wide::f32x4;

use crate::simd::{LaneF32, LaneI32};

/// The least exponent `s log2 x` taken: below it (and below -126, where
/// the result would not be a normal number) the power is zero.
const LOWEST_EXPONENT: f32 = -150.0;

/// Above this the power saturates at `2^127` (bases above one by rounding,
/// with a huge exponent).
const HIGHEST_EXPONENT: f32 = 127.0;

/// `2^f` on `[-1/2, 1/2]`: the degree-6 polynomial through the Chebyshev
/// nodes, lowest power first (2e-8 relative).
const EXP2_FIT: [f32; 7] = [
    1.0,
    std::f32::consts::LN_2,
    0.240_226_5,
    0.055_503_27,
    0.009_618_025,
    0.001_340_043_3,
    0.000_154_697_32,
];

/// The exponent `s log2 x` at or below which the light loop takes a
/// highlight power as zero without computing it ([`zero_power_below`]):
/// more than three units beyond the -126.5 where [`highlight_power`]
/// rounds to the zero below the normal range, far more than the rounding
/// of the product and the logarithm's 1e-8 error.
const ZERO_POWER_EXPONENT: f32 = -130.0;

/// The base at or below which [`highlight_power`] is exactly zero for the
/// exponent `s` (a material's shininess): `2^(ZERO_POWER_EXPONENT / s)`. The
/// light loop skips a quad of lights whose bases all lie there and gets the
/// same bits. Zero (only bases facing away skipped) for an `s` that is not
/// finite and positive, or below `130 / 149`, where the floor underflows.
#[must_use]
pub(crate) fn zero_power_below(s: f32) -> f32 {
    if s.is_finite() && s > 0.0 {
        (ZERO_POWER_EXPONENT / s).exp2()
    } else {
        0.0
    }
}

/// The highlight powers of a quad of lights for the light loop: lane `i`
/// is `highlight_power(rdv, s)`'s where `lit` has bit `i` (the other lanes
/// are never read), computed only when some lit lane's base lies above
/// `floor` ([`zero_power_below`] of `s`, or 0): otherwise every lit lane's
/// power is exactly zero, and zeros are returned without the arithmetic.
#[inline]
pub(crate) fn highlight_powers(rdv: f32x4, lit: u32, s: f32, floor: f32) -> [f32; 4] {
    if rdv.simd_gt(f32x4::splat(floor)).to_bitmask() & lit != 0 {
        highlight_power(rdv, s).to_array()
    } else {
        [0.0; 4]
    }
}

/// `max(x, 0)^s` lane by lane, for a finite `s > 0` (a material's
/// shininess): zero for a NaN, zero or negative `x`.
#[must_use]
#[inline]
pub(crate) fn highlight_power(x: f32x4, s: f32) -> f32x4 {
    highlight_power_lanes(x, f32x4::splat(s))
}

/// [`highlight_power`] with an exponent per lane (the lane-parallel light
/// loop's hits of different materials): lane `i` is `max(x_i, 0)^s_i`, the
/// same operations as with one exponent.
#[must_use]
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn highlight_power_lanes<F: LaneF32>(x: F, s: F) -> F {
    // PERF: no selects on the common path (an SSE2 select is three
    // operations): the mantissa is centred by integer arithmetic, the
    // exponent clamped by `minps`/`maxps`, and NaN or non-positive bases
    // masked at the end; subnormal bases take a rare branch.
    let positive = x.gt(F::splat(0.0));
    let tiny = x.lt(F::splat(f32::MIN_POSITIVE));
    let log2x = if (tiny & positive).bitmask() != 0 {
        subnormal_log2(x)
    } else {
        log2_normal(x)
    };
    let y = (s * log2x)
        .max_fast(F::splat(LOWEST_EXPONENT))
        .min_fast(F::splat(HIGHEST_EXPONENT));
    // 2^y = 2^n 2^f, n = y rounded to even, |f| <= 1/2: 2^f by a degree-6
    // fit (Chebyshev nodes, 2e-8 relative; exactly 1 at f = 0), its terms
    // grouped to shorten the chain (Estrin).
    let n = y.round_int();
    let f = y - F::from_int(n);
    let [c0, c1, c2, c3, c4, c5, c6] = [
        F::splat(EXP2_FIT[0]),
        F::splat(EXP2_FIT[1]),
        F::splat(EXP2_FIT[2]),
        F::splat(EXP2_FIT[3]),
        F::splat(EXP2_FIT[4]),
        F::splat(EXP2_FIT[5]),
        F::splat(EXP2_FIT[6]),
    ];
    let f2 = f * f;
    let p = (c0 + c1 * f) + f2 * ((c2 + c3 * f) + f2 * ((c4 + c5 * f) + f2 * c6));
    // 2^n from the exponent bits; below the normal range, zero.
    let normal = n.gt(F::I::splat(-127));
    let scale = F::from_bits((n + F::I::splat(127)).shl23());
    (p * scale) & normal & positive
}

/// `log2 x` for `x > 1`, lane by lane ([`log2_normal`]'s arithmetic, 1e-8
/// relative; above 127 for infinity), and 0 for `x <= 1` and NaN: the
/// texture level of detail's logarithm, whose result is only used clamped
/// to `[0, levels - 1]`, so that every `x <= 1` may give 0.
#[must_use]
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn log2_above_one<F: LaneF32>(x: F) -> F {
    log2_normal(x) & x.gt(F::splat(1.0))
}

/// `log2 x` for positive normal `x` (other lanes: any finite value): the
/// exponent, and `2 atanh(t) / ln 2` of the mantissa `m` moved to
/// `[sqrt(1/2), sqrt(2))`, `t = (m - 1) / (m + 1)` (`|t| < 0.172`), by the
/// series' terms to `t^9` (1e-8 relative), grouped as in the caller.
#[allow(clippy::inline_always)]
#[inline(always)]
fn log2_normal<F: LaneF32>(x: F) -> F {
    const SQRT_HALF_BITS: i32 = 0x3f35_04f3;
    let bits = x.to_bits();
    // Subtracting the bits of sqrt(1/2) moves the exponent's boundary to
    // the mantissa's centre: the arithmetic shift gives the exponent of
    // `x / sqrt(1/2)` rounded down, the low bits the mantissa's offset.
    let shifted = bits - F::I::splat(SQRT_HALF_BITS);
    let e = F::from_int(shifted.shr23());
    let m = F::from_bits((shifted & F::I::splat(0x007f_ffff)) + F::I::splat(SQRT_HALF_BITS));
    let one = F::splat(1.0);
    let t = (m - one) / (m + one);
    let t2 = t * t;
    let t4 = t2 * t2;
    let k = |j: f64| (2.0 / (std::f64::consts::LN_2 * j)) as f32;
    let [k1, k3, k5, k7, k9] = [
        F::splat(k(1.0)),
        F::splat(k(3.0)),
        F::splat(k(5.0)),
        F::splat(k(7.0)),
        F::splat(k(9.0)),
    ];
    let series = (k1 + t2 * k3) + t4 * ((k5 + t2 * k7) + t4 * k9);
    e + t * series
}

/// `log2 x` of a quad with a subnormal base: those lanes are scaled by
/// `2^24` into the normal range, and their logarithm moved back.
#[cold]
#[inline(never)]
fn subnormal_log2<F: LaneF32>(x: F) -> F {
    let tiny = x.lt(F::splat(f32::MIN_POSITIVE));
    let scaled = tiny.select(x * F::splat(16_777_216.0), x);
    log2_normal(scaled) - (tiny & F::splat(24.0))
}

#[cfg(test)]
const ERROR_PER_EXPONENT: f64 = 2e-7;

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// Relative error of the four-lane power against f64 `powf`.
    fn error(x: f32, s: f32) -> f64 {
        let got = f64::from(highlight_power(f32x4::splat(x), s).to_array()[0]);
        let want = f64::from(x.max(0.0)).powf(f64::from(s));
        if want < f64::from(f32::MIN_POSITIVE) {
            // Flushed: zero, or at most the smallest normal.
            return if got <= f64::from(f32::MIN_POSITIVE) {
                0.0
            } else {
                f64::INFINITY
            };
        }
        (got - want).abs() / want
    }

    #[test]
    fn close_to_the_exact_power() {
        let mut rng = SmallRng::seed_from_u64(5);
        let mut worst: f64 = 0.0;
        for i in 0..400_000 {
            let x: f32 = if i % 2 == 0 {
                rng.random_range(0.0..=1.0)
            } else {
                // Near one, where highlights peak.
                1.0 - rng.random_range(0.0..1e-3f32)
            };
            let s: f32 = 10f32.powf(rng.random_range(-1.0..3.0));
            // A few units in the last place, plus the rounding of the
            // product `s log2 x`, which grows with it (`ERROR_PER_EXPONENT`).
            let y = f64::from(s) * f64::from(x).log2();
            let bound = 4e-7 + ERROR_PER_EXPONENT * y.abs();
            worst = worst.max(error(x, s) / bound);
        }
        assert!(worst < 1.0, "worst error {worst} of the bound");
        assert!(worst > 0.05, "the bound is loose: {worst}");
    }

    #[test]
    fn hard_bases_and_exponents() {
        let p = |x: f32, s: f32| highlight_power(f32x4::splat(x), s).to_array()[0];
        // Exact at one and zero, nothing for NaN and negative bases.
        for s in [0.5, 1.0, 8.0, 1e6, f32::MAX] {
            assert_eq!(p(1.0, s), 1.0, "1^{s}");
            assert_eq!(p(0.0, s), 0.0);
            assert_eq!(p(-0.0, s), 0.0);
            assert_eq!(p(-0.5, s), 0.0);
            assert_eq!(p(f32::NAN, s), 0.0);
            assert_eq!(p(f32::NEG_INFINITY, s), 0.0);
        }
        // One as the exponent gives the base back within rounding.
        for x in [0.25f32, 0.5, 0.75, 0.999_999_9] {
            assert!((p(x, 1.0) - x).abs() <= 2.0 * f32::EPSILON * x, "{x}");
        }
        // Subnormal bases: scaled, not lost (the square root of 2^-140 is 2^-70).
        let sub = f32::from_bits(1 << 9);
        assert!((f64::from(p(sub, 0.5)) / f64::from(sub).sqrt() - 1.0).abs() < 1e-6);
        // Underflow flushes to zero; a base above one by rounding saturates.
        assert_eq!(p(0.5, 200.0), 0.0);
        assert_eq!(p(1e-30, 100.0), 0.0);
        assert_eq!(p(1.000_000_1, f32::MAX), 2f32.powi(HIGHEST_EXPONENT as i32));
        // The normal range's end: 2^-125.5 is kept, 2^-126.6 flushed, and
        // so is everything past the clamp.
        let kept = f64::from(p(0.5, 125.5));
        assert!((kept / 2f64.powf(-125.5) - 1.0).abs() < 1e-5, "{kept}");
        assert_eq!(p(0.5, 126.6), 0.0);
        assert_eq!(p(0.5, -LOWEST_EXPONENT * 2.0), 0.0);
        // The lanes are independent.
        let four = highlight_power(f32x4::from([0.5, -1.0, 1.0, 0.25]), 2.0).to_array();
        assert_eq!(four[1], 0.0);
        assert_eq!(four[2], 1.0);
        assert!((four[0] - 0.25).abs() < 1e-7 && (four[3] - 0.0625).abs() < 1e-8);
    }

    #[test]
    fn the_power_is_exactly_zero_at_and_below_its_floor() {
        let p = |x: f32, s: f32| highlight_power(f32x4::splat(x), s).to_array()[0];
        let mut rng = SmallRng::seed_from_u64(17);
        let mut tried = 0;
        for i in 0..100_000 {
            // Shininess from 0.1 to 10,000, and the kitchen's own values.
            let s: f32 = match i % 4 {
                0 => 97.4304,
                1 => 112.561_844,
                _ => 10f32.powf(rng.random_range(-1.0..4.0)),
            };
            let floor = zero_power_below(s);
            assert!((0.0..1.0).contains(&floor), "floor {floor} for {s}");
            if floor == 0.0 {
                // A small exponent: its floor underflows (`2^(-130 / s)` is
                // below the least subnormal for `s < 130 / 149`), so only
                // bases facing away are skipped.
                assert!(s < 0.9, "no floor for {s}");
                continue;
            }
            // At the floor, just below it, and anywhere below it.
            let below = f32::from_bits(floor.to_bits() - 1);
            for x in [floor, below, rng.random_range(0.0..floor), floor * 0.5] {
                assert_eq!(p(x, s).to_bits(), 0, "{x}^{s} under the floor {floor}");
                tried += 1;
            }
        }
        assert!(tried > 330_000, "{tried}");
        // The floor is not needlessly low: a little above it the power is
        // still tiny but not zero for exponents whose powers stay normal.
        assert!(p(zero_power_below(100.0) * 1.03, 100.0) > 0.0);
        // No floor (nothing skipped) for exponents that are not positive and finite.
        for s in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert_eq!(zero_power_below(s), 0.0);
        }
    }

    #[test]
    fn the_light_loop_powers_are_the_same_bits_with_the_floor_and_without() {
        let mut rng = SmallRng::seed_from_u64(23);
        let mut skipped = 0;
        for i in 0..200_000 {
            let s: f32 = if i % 2 == 0 {
                97.4304
            } else {
                10f32.powf(rng.random_range(-1.0..3.5))
            };
            let floor = zero_power_below(s);
            // Bases around the floor and across the whole range, some NaN.
            let rdv = f32x4::new(std::array::from_fn(|_| match rng.random_range(0..4) {
                0 => floor * rng.random_range(0.5..1.5),
                1 => rng.random_range(-1.0..=1.0),
                2 => 1.0 - rng.random_range(0.0..0.01),
                _ => {
                    if rng.random_bool(0.1) {
                        f32::NAN
                    } else {
                        rng.random_range(0.0..0.5)
                    }
                }
            }));
            let lit: u32 = rng.random_range(0..16);
            let (with, without) = (highlight_powers(rdv, lit, s, floor), highlight_powers(rdv, lit, s, 0.0));
            let exact = highlight_power(rdv, s).to_array();
            for l in 0..4 {
                if lit & (1 << l) != 0 {
                    assert_eq!(with[l].to_bits(), without[l].to_bits(), "{rdv:?} lit {lit:b} ^{s}");
                    assert_eq!(with[l].to_bits(), exact[l].to_bits());
                }
            }
            let base = rdv.simd_gt(f32x4::ZERO).to_bitmask() & lit;
            skipped += u32::from(base != 0 && rdv.simd_gt(f32x4::splat(floor)).to_bitmask() & lit == 0);
        }
        // The floor skips quads that facing away alone would not.
        assert!(skipped > 10_000, "{skipped}");
    }
}
