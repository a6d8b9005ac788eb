//! The lane types of the shading kernels: four lanes (`wide::f32x4`, SSE,
//! the portable build) and, on x86-64 CPUs with AVX2, eight ([`F32x8`]),
//! chosen at run time. The kernels written over [`LaneF32`] (the light
//! loop's geometry and highlight powers, the surfaces of a packet's hits)
//! perform the same IEEE operations in the same order in every lane
//! whatever the width, so every width gives the same bits (tested against
//! the four-lane type).
//!
//! `wide` chooses its eight-lane type's instructions when the crate is
//! compiled (two SSE halves in a portable build), so the eight-lane type
//! here is a thin wrapper of `core::arch`'s AVX2 intrinsics whose
//! operations inline into the renderer's AVX2-compiled shading
//! (`Shader::shade_block_avx2`).

// NOTE: every lane operation is forced inline: an operation left as a call
// would pass its registers through memory, and the AVX2 type's would run
// outside the AVX2-compiled code that may execute it. For the same reason
// the kernels over `LaneF32` keep lane arithmetic out of closures (a
// closure is a function of its own, compiled without AVX2 unless inlined,
// and then every intrinsic in it is a call; so is the cold, never inlined
// `highlight::subnormal_log2`, the only caller of `core_arch`'s AVX
// functions in the binary, `objdump -d` shows).
#![allow(clippy::inline_always)]

use std::ops::{Add, BitAnd, Div, Mul, Neg, Sub};

use glam::Vec3A;
use wide::{bytemuck, f32x4, i32x4};

/// Lanes of `f32` for the shading kernels; comparisons give masks (every
/// bit of a lane set or clear) of the same type.
pub(crate) trait LaneF32:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + BitAnd<Output = Self>
{
    /// The matching lanes of `i32`.
    type I: LaneI32<F = Self>;
    /// How many lanes.
    const LANES: usize;
    /// `v` in every lane.
    fn splat(v: f32) -> Self;
    /// Lane `i` from `f(i)`.
    fn from_fn(f: impl Fn(usize) -> f32) -> Self;
    /// The lanes written to `out[..LANES]`.
    fn write_to(self, out: &mut [f32]);
    /// Correctly rounded square roots.
    #[must_use]
    fn sqrt(self) -> Self;
    /// `self > o`, a mask (false for NaN).
    #[must_use]
    fn gt(self, o: Self) -> Self;
    /// `self < o`, a mask (false for NaN).
    #[must_use]
    fn lt(self, o: Self) -> Self;
    /// `self == o`, a mask (false for NaN).
    #[must_use]
    fn eq(self, o: Self) -> Self;
    /// The sign bits cleared.
    #[must_use]
    fn abs(self) -> Self;
    /// The sign bits flipped where the mask `m` is set.
    #[must_use]
    fn flip_sign(self, m: Self) -> Self;
    /// `maxps`: `o` where either lane is NaN.
    #[must_use]
    fn max_fast(self, o: Self) -> Self;
    /// `minps`: `o` where either lane is NaN.
    #[must_use]
    fn min_fast(self, o: Self) -> Self;
    /// `a` where the mask `self` is set, `b` elsewhere.
    #[must_use]
    fn select(self, a: Self, b: Self) -> Self;
    /// One bit per lane of a mask.
    fn bitmask(self) -> u32;
    /// Rounded to the nearest integer, ties to even.
    fn round_int(self) -> Self::I;
    /// Truncated towards zero, as `f32 as i32` for values inside the range
    /// of `i32` (out of range and NaN: any value, unlike `as`).
    fn trunc_int(self) -> Self::I;
    /// The integers converted.
    fn from_int(i: Self::I) -> Self;
    /// The bits as integers.
    fn to_bits(self) -> Self::I;
    /// Integers' bits as floats.
    fn from_bits(i: Self::I) -> Self;
    /// The mask of the lanes whose bit is set in `bits`.
    fn mask(bits: u32) -> Self;
    /// The coordinates of the vectors `v(i)`, one to a lane.
    fn transpose(v: impl Fn(usize) -> Vec3A) -> [Self; 3];
    /// `f32::floor` of four lanes, bit for bit, in the instruction set of
    /// the code this lane type runs in (the texture lookups' floors).
    #[must_use]
    fn floor4(x: f32x4) -> f32x4;
}

/// `f32::floor` of four lanes with SSE2 alone: the same bits (signed
/// zeros, NaN and infinities included); the portable [`LaneF32::floor4`].
#[inline]
fn floor4_sse2(x: f32x4) -> f32x4 {
    // Every float of magnitude 2^23 or more is an integer; NaN and the
    // infinities are kept as they are.
    let keep = !x.abs().simd_lt(f32x4::splat(8_388_608.0));
    let t = f32x4::from_i32x4(x.trunc_int());
    let down = t.simd_gt(x).bitselect(t - f32x4::ONE, t);
    let exact = t.simd_eq(x);
    (keep | exact).bitselect(x, down)
}

/// Lanes of `i32` beside a [`LaneF32`].
pub(crate) trait LaneI32: Copy + Add<Output = Self> + Sub<Output = Self> + BitAnd<Output = Self> {
    /// The matching float lanes.
    type F: LaneF32<I = Self>;
    /// `v` in every lane.
    fn splat(v: i32) -> Self;
    /// Arithmetic shift right by 23 (a float's exponent field).
    #[must_use]
    fn shr23(self) -> Self;
    /// Shift left by 23.
    #[must_use]
    fn shl23(self) -> Self;
    /// `self > o`, a float mask.
    fn gt(self, o: Self) -> Self::F;
}

impl LaneF32 for f32x4 {
    type I = i32x4;
    const LANES: usize = 4;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        f32x4::splat(v)
    }
    #[inline(always)]
    fn from_fn(f: impl Fn(usize) -> f32) -> Self {
        f32x4::from([f(0), f(1), f(2), f(3)])
    }
    #[inline(always)]
    fn write_to(self, out: &mut [f32]) {
        out[..4].copy_from_slice(&self.to_array());
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32x4::sqrt(self)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self {
        self.simd_gt(o)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Self {
        self.simd_lt(o)
    }
    #[inline(always)]
    fn eq(self, o: Self) -> Self {
        self.simd_eq(o)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32x4::abs(self)
    }
    #[inline(always)]
    fn flip_sign(self, m: Self) -> Self {
        self ^ (m & f32x4::splat(-0.0))
    }
    #[inline(always)]
    fn max_fast(self, o: Self) -> Self {
        self.fast_max(o)
    }
    #[inline(always)]
    fn min_fast(self, o: Self) -> Self {
        self.fast_min(o)
    }
    #[inline(always)]
    fn select(self, a: Self, b: Self) -> Self {
        self.bitselect(a, b)
    }
    #[inline(always)]
    fn bitmask(self) -> u32 {
        self.to_bitmask()
    }
    #[inline(always)]
    fn round_int(self) -> i32x4 {
        self.fast_round_int()
    }
    #[inline(always)]
    fn trunc_int(self) -> i32x4 {
        self.fast_trunc_int()
    }
    #[inline(always)]
    fn from_int(i: i32x4) -> Self {
        f32x4::from_i32x4(i)
    }
    #[inline(always)]
    fn to_bits(self) -> i32x4 {
        bytemuck::cast(self)
    }
    #[inline(always)]
    fn from_bits(i: i32x4) -> Self {
        bytemuck::cast(i)
    }
    #[inline(always)]
    fn mask(bits: u32) -> Self {
        let lane = i32x4::from([1, 2, 4, 8]);
        bytemuck::cast((i32x4::splat(bits.cast_signed()) & lane).simd_eq(lane))
    }
    #[inline(always)]
    fn floor4(x: f32x4) -> f32x4 {
        floor4_sse2(x)
    }
    #[inline(always)]
    fn transpose(v: impl Fn(usize) -> Vec3A) -> [Self; 3] {
        let each = |i: usize| f32x4::from(<[f32; 4]>::from(v(i).extend(0.0)));
        let [x, y, z, _] = f32x4::transpose([each(0), each(1), each(2), each(3)]);
        [x, y, z]
    }
}

impl LaneI32 for i32x4 {
    type F = f32x4;
    #[inline(always)]
    fn splat(v: i32) -> Self {
        i32x4::splat(v)
    }
    #[inline(always)]
    fn shr23(self) -> Self {
        self >> 23
    }
    #[inline(always)]
    fn shl23(self) -> Self {
        self << 23
    }
    #[inline(always)]
    fn gt(self, o: Self) -> f32x4 {
        bytemuck::cast(self.simd_gt(o))
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx2::F32x8;

#[cfg(target_arch = "x86_64")]
mod avx2 {
    // SAFETY (every `unsafe` block of this module): an `F32x8` or `I32x8`
    // is only made in code reached from `Shader::shade_block_avx2` (or the
    // tests' AVX2 functions), which runs after `openrt_accel::avx2()` found
    // AVX2 on the CPU, and the operations
    // are register intrinsics without memory access except the store of
    // `write_to`, whose slice is cut to eight lanes (bounds-checked) first. PERF: `wide::f32x8` takes AVX only when
    // the crate is compiled for it; these inline into the AVX2-compiled
    // shading, where the light loop takes eight hits to a register
    // instead of four.
    use std::arch::x86_64::{
        __m128, __m256, __m256i, _CMP_EQ_OQ, _CMP_GT_OQ, _CMP_LT_OQ, _mm_blendv_ps, _mm_cmpunord_ps, _mm_floor_ps,
        _mm256_add_epi32, _mm256_add_ps, _mm256_and_ps, _mm256_and_si256, _mm256_andnot_ps, _mm256_castps_si256,
        _mm256_castsi256_ps, _mm256_cmp_ps, _mm256_cmpeq_epi32, _mm256_cmpgt_epi32, _mm256_cvtepi32_ps,
        _mm256_cvtps_epi32, _mm256_cvttps_epi32, _mm256_div_ps, _mm256_max_ps, _mm256_min_ps, _mm256_movemask_ps,
        _mm256_mul_ps, _mm256_or_ps, _mm256_set_m128, _mm256_set1_epi32, _mm256_set1_ps, _mm256_setr_epi32,
        _mm256_setr_ps, _mm256_slli_epi32, _mm256_sqrt_ps, _mm256_srai_epi32, _mm256_storeu_ps, _mm256_sub_epi32,
        _mm256_sub_ps, _mm256_xor_ps,
    };
    use std::ops::{Add, BitAnd, Div, Mul, Neg, Sub};

    use glam::Vec3A;
    use wide::{bytemuck, f32x4};

    use super::{LaneF32, LaneI32};

    /// Eight `f32` lanes in an AVX register.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct F32x8(__m256);

    /// Eight `i32` lanes in an AVX register.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct I32x8(__m256i);

    macro_rules! binary {
        ($t:ident, $tr:ident, $f:ident, $op:ident) => {
            impl $tr for $t {
                type Output = Self;
                #[inline(always)]
                fn $f(self, o: Self) -> Self {
                    Self(unsafe { $op(self.0, o.0) })
                }
            }
        };
    }
    binary!(F32x8, Add, add, _mm256_add_ps);
    binary!(F32x8, Sub, sub, _mm256_sub_ps);
    binary!(F32x8, Mul, mul, _mm256_mul_ps);
    binary!(F32x8, Div, div, _mm256_div_ps);
    binary!(F32x8, BitAnd, bitand, _mm256_and_ps);
    binary!(I32x8, Add, add, _mm256_add_epi32);
    binary!(I32x8, Sub, sub, _mm256_sub_epi32);
    binary!(I32x8, BitAnd, bitand, _mm256_and_si256);

    impl Neg for F32x8 {
        type Output = Self;
        /// The sign flipped (`wide`'s negation: an exclusive or with -0).
        #[inline(always)]
        fn neg(self) -> Self {
            Self(unsafe { _mm256_xor_ps(self.0, _mm256_set1_ps(-0.0)) })
        }
    }

    impl LaneF32 for F32x8 {
        type I = I32x8;
        const LANES: usize = 8;
        #[inline(always)]
        fn splat(v: f32) -> Self {
            Self(unsafe { _mm256_set1_ps(v) })
        }
        #[inline(always)]
        fn from_fn(f: impl Fn(usize) -> f32) -> Self {
            Self(unsafe { _mm256_setr_ps(f(0), f(1), f(2), f(3), f(4), f(5), f(6), f(7)) })
        }
        #[inline(always)]
        fn write_to(self, out: &mut [f32]) {
            let out = &mut out[..8];
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) }
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            Self(unsafe { _mm256_sqrt_ps(self.0) })
        }
        #[inline(always)]
        fn gt(self, o: Self) -> Self {
            Self(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn lt(self, o: Self) -> Self {
            Self(unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn eq(self, o: Self) -> Self {
            Self(unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn abs(self) -> Self {
            // `wide`'s: the sign bits cleared by a mask.
            Self(unsafe { _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        fn flip_sign(self, m: Self) -> Self {
            Self(unsafe { _mm256_xor_ps(self.0, _mm256_and_ps(m.0, _mm256_set1_ps(-0.0))) })
        }
        #[inline(always)]
        fn max_fast(self, o: Self) -> Self {
            Self(unsafe { _mm256_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn min_fast(self, o: Self) -> Self {
            Self(unsafe { _mm256_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn select(self, a: Self, b: Self) -> Self {
            // Bitwise, as `wide`'s `bitselect`.
            Self(unsafe { _mm256_or_ps(_mm256_and_ps(a.0, self.0), _mm256_andnot_ps(self.0, b.0)) })
        }
        #[inline(always)]
        fn bitmask(self) -> u32 {
            unsafe { _mm256_movemask_ps(self.0) }.cast_unsigned()
        }
        #[inline(always)]
        fn round_int(self) -> I32x8 {
            I32x8(unsafe { _mm256_cvtps_epi32(self.0) })
        }
        #[inline(always)]
        fn trunc_int(self) -> I32x8 {
            I32x8(unsafe { _mm256_cvttps_epi32(self.0) })
        }
        #[inline(always)]
        fn from_int(i: I32x8) -> Self {
            Self(unsafe { _mm256_cvtepi32_ps(i.0) })
        }
        #[inline(always)]
        fn to_bits(self) -> I32x8 {
            I32x8(unsafe { _mm256_castps_si256(self.0) })
        }
        #[inline(always)]
        fn from_bits(i: I32x8) -> Self {
            Self(unsafe { _mm256_castsi256_ps(i.0) })
        }
        #[inline(always)]
        fn mask(bits: u32) -> Self {
            let lane = unsafe { _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128) };
            let set = unsafe { _mm256_and_si256(_mm256_set1_epi32(bits.cast_signed()), lane) };
            Self(unsafe { _mm256_castsi256_ps(_mm256_cmpeq_epi32(set, lane)) })
        }
        #[inline(always)]
        fn transpose(v: impl Fn(usize) -> Vec3A) -> [Self; 3] {
            let [lx, ly, lz] = <f32x4 as LaneF32>::transpose(&v);
            let [hx, hy, hz] = <f32x4 as LaneF32>::transpose(|i| v(4 + i));
            let (lx, ly, lz): (__m128, __m128, __m128) = (bytemuck::cast(lx), bytemuck::cast(ly), bytemuck::cast(lz));
            let (hx, hy, hz): (__m128, __m128, __m128) = (bytemuck::cast(hx), bytemuck::cast(hy), bytemuck::cast(hz));
            unsafe {
                [
                    Self(_mm256_set_m128(hx, lx)),
                    Self(_mm256_set_m128(hy, ly)),
                    Self(_mm256_set_m128(hz, lz)),
                ]
            }
        }
        /// PERF: SSE4.1's `roundps` (AVX2 implies it), rounding toward
        /// minus infinity as `floor` does (signed zeros and infinities
        /// kept), and NaN lanes passed through as they are (`roundps`
        /// would quiet a signaling NaN): three instructions where the
        /// portable build spends nine.
        #[inline(always)]
        fn floor4(x: f32x4) -> f32x4 {
            let x: __m128 = bytemuck::cast(x);
            bytemuck::cast(unsafe { _mm_blendv_ps(_mm_floor_ps(x), x, _mm_cmpunord_ps(x, x)) })
        }
    }

    impl LaneI32 for I32x8 {
        type F = F32x8;
        #[inline(always)]
        fn splat(v: i32) -> Self {
            Self(unsafe { _mm256_set1_epi32(v) })
        }
        #[inline(always)]
        fn shr23(self) -> Self {
            Self(unsafe { _mm256_srai_epi32::<23>(self.0) })
        }
        #[inline(always)]
        fn shl23(self) -> Self {
            Self(unsafe { _mm256_slli_epi32::<23>(self.0) })
        }
        #[inline(always)]
        fn gt(self, o: Self) -> F32x8 {
            F32x8(unsafe { _mm256_castsi256_ps(_mm256_cmpgt_epi32(self.0, o.0)) })
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::highlight::highlight_power_lanes;
    use crate::light_quad::{Lanes, towards};
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// The eight-lane kernels, compiled for AVX2 as the renderer's shading.
    #[target_feature(enable = "avx2")]
    fn eight(x: &[f32; 8], s: &[f32; 8], p: &[Vec3A; 8], light: glam::Vec3) -> ([f32; 8], u32, [[f32; 8]; 3]) {
        let (x, s) = (F32x8::from_fn(|i| x[i]), F32x8::from_fn(|i| s[i]));
        let mut power = [0.0; 8];
        highlight_power_lanes(x, s).write_to(&mut power);
        let p = Lanes::<F32x8>::transposed(|i| p[i]);
        let (ok, l) = towards(&Lanes::splat(light), &p, &p);
        let mut dirs = [[0.0; 8]; 3];
        for (k, v) in [l.x, l.y, l.z].into_iter().enumerate() {
            v.write_to(&mut dirs[k]);
        }
        (power, ok.bitmask(), dirs)
    }

    /// Each of the eight lanes is the four-lane kernel's bits: highlight
    /// powers of hard bases (zero, negative, subnormal, NaN, infinite, near
    /// one) and exponents, and the directions to a light with their masks.
    #[test]
    fn eight_lanes_are_the_four_lane_bits() {
        if !openrt_accel::avx2() {
            return;
        }
        let mut rng = SmallRng::seed_from_u64(0x5eed_0008);
        let hard = [0.0, -0.0, -1.0, 1e-40, 1e-45, f32::NAN, f32::INFINITY, 1.0, 0.999_999];
        let mut subnormal = 0;
        for round in 0..20_000 {
            let x: [f32; 8] = std::array::from_fn(|_| {
                if rng.random_bool(0.3) {
                    hard[rng.random_range(0..hard.len())]
                } else {
                    rng.random_range(-0.2..1.0)
                }
            });
            let s: [f32; 8] = std::array::from_fn(|_| 10f32.powf(rng.random_range(-1.0..3.5)));
            let p: [Vec3A; 8] = std::array::from_fn(|_| {
                Vec3A::new(
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                )
            });
            let light = if round % 7 == 0 {
                p[0].into()
            } else {
                glam::Vec3::new(rng.random_range(-2.0..2.0), 1.0, 0.5)
            };
            // SAFETY: the CPU has AVX2 (checked above).
            let (power, ok, dirs) = unsafe { eight(&x, &s, &p, light) };
            for c in 0..2 {
                let four = |v: &[f32; 8]| f32x4::from_fn(|i| v[4 * c + i]);
                let want = highlight_power_lanes(four(&x), four(&s)).to_array();
                let q = Lanes::<f32x4>::transposed(|i| p[4 * c + i]);
                let (want_ok, l) = towards(&Lanes::splat(light), &q, &q);
                for (i, want) in want.iter().enumerate() {
                    let lane = 4 * c + i;
                    subnormal += usize::from(x[lane] > 0.0 && x[lane] < f32::MIN_POSITIVE);
                    assert_eq!(
                        power[lane].to_bits(),
                        want.to_bits(),
                        "round {round}, lane {lane}: {} ^ {}",
                        x[lane],
                        s[lane]
                    );
                    assert_eq!(
                        (ok >> lane) & 1,
                        (want_ok.bitmask() >> i) & 1,
                        "round {round}, lane {lane}"
                    );
                    for (k, v) in [l.x, l.y, l.z].into_iter().enumerate() {
                        assert_eq!(
                            dirs[k][lane].to_bits(),
                            v.to_array()[i].to_bits(),
                            "round {round}, lane {lane}"
                        );
                    }
                }
            }
        }
        // The subnormal bases' branch is taken.
        assert!(subnormal > 1_000, "{subnormal} subnormal bases");
    }

    /// [`LaneF32::floor4`] of the AVX2 lanes (`roundps`).
    #[target_feature(enable = "avx2")]
    fn floor_avx2(x: f32x4) -> f32x4 {
        <F32x8 as LaneF32>::floor4(x)
    }

    #[test]
    fn the_lane_floor_is_floor_bit_for_bit() {
        let mut rng = SmallRng::seed_from_u64(3);
        let special = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            1e30,
            -1e30,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
        ];
        let check = |x: [f32; 4]| {
            let got = <f32x4 as LaneF32>::floor4(f32x4::from(x)).to_array();
            for (a, b) in x.iter().zip(got) {
                assert_eq!(a.floor().to_bits(), b.to_bits(), "floor({a})");
            }
            if openrt_accel::avx2() {
                // SAFETY: the CPU has AVX2 (detected at run time).
                let got = unsafe { floor_avx2(f32x4::from(x)) }.to_array();
                for (a, b) in x.iter().zip(got) {
                    assert_eq!(a.floor().to_bits(), b.to_bits(), "AVX2 floor({a})");
                }
            }
        };
        for c in special.chunks(4) {
            check([c[0], c[1], c[2], c[3]]);
        }
        for _ in 0..50_000 {
            check(std::array::from_fn(|_| f32::from_bits(rng.random())));
        }
    }
}
