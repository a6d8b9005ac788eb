//! Trilinear lookups of four hits at once, each lane the bits of
//! [`Texture::sample_filtered`].
//!
//! The arithmetic of a trilinear lookup (clamping the level of detail,
//! floors, texel coordinates, repeat addressing and weights of both levels)
//! is done for four lanes together; then each lane reads its eight texels
//! and blends them with the scalar lookup's products ([`Level::blend`]).
//! Lanes may sample different textures. Only repeat addressing and finite
//! coordinates take this path; the caller sends other lanes to the scalar
//! lookup.

use glam::{Vec2, Vec3A};
use wide::{f32x4, i32x4};

use super::{Level, Taps, Texture, TextureWrap};
use crate::simd::LaneF32;

/// `wrap` of [`super`] for indices at most one period outside `[0, n)`.
#[inline]
fn wrap4(i: i32x4, n: i32x4) -> i32x4 {
    let below = i.simd_lt(i32x4::ZERO);
    let above = !i.simd_lt(n);
    below.select(i + n, above.select(i - n, i))
}

/// The taps of four bilinear lookups with repeat addressing at `(u, v)`
/// (already wrapped into `[0, 1]`) in levels of `w x h` texels: the
/// arithmetic of `Level::bilinear`, lane by lane.
#[inline]
fn taps4<F: LaneF32>(u: f32x4, v: f32x4, w: i32x4, h: i32x4) -> Taps {
    let half = f32x4::splat(0.5);
    let x = u * f32x4::from_i32x4(w) - half;
    let y = v * f32x4::from_i32x4(h) - half;
    let (x0, y0) = (F::floor4(x), F::floor4(y));
    let (fx, fy) = ((x - x0).to_array(), (y - y0).to_array());
    // Exact: the coordinates lie within one texel of the level.
    let (xi, yi) = (x0.trunc_int(), y0.trunc_int());
    let one = i32x4::splat(1);
    let (xa, xb) = (wrap4(xi, w).to_array(), wrap4(xi + one, w).to_array());
    let (ya, yb) = (wrap4(yi, h).to_array(), wrap4(yi + one, h).to_array());
    Taps {
        xa: xa.map(i32::cast_unsigned),
        xb: xb.map(i32::cast_unsigned),
        ya: ya.map(i32::cast_unsigned),
        yb: yb.map(i32::cast_unsigned),
        fx,
        fy,
    }
}

/// Whether a lookup of `t` at `uv` may take [`trilinear_lanes`]: repeat
/// addressing on both axes and finite coordinates.
#[inline]
pub(crate) fn takes_lanes(t: &Texture, uv: Vec2) -> bool {
    t.wrap == [TextureWrap::Repeat; 2] && uv.is_finite()
}

/// Trilinear lookups of four lanes at once: lane `i` is
/// `texs[i].sample_filtered(uv[i], lod[i], Trilinear)`, bit for bit, for
/// lanes that [`takes_lanes`] (others: any value); the floors in `F`'s
/// instruction set ([`LaneF32::floor4`]).
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn trilinear_lanes<F: LaneF32>(texs: [&Texture; 4], uv: [Vec2; 4], lod: f32x4) -> [Vec3A; 4] {
    let top = f32x4::from(texs.map(|t| (t.levels.len() - 1) as f32));
    // NOTE: max/min, not clamp: a NaN lod becomes 0 (`maxps` gives its
    // second operand for a NaN, as `f32::max` gives the number).
    let lod = lod.fast_max(f32x4::ZERO).fast_min(top);
    let base = F::floor4(lod);
    let f = (lod - base).to_array();
    let i = base.trunc_int().to_array().map(|i| i.unsigned_abs() as usize);
    // The level below the lod and the next (the same where there is none:
    // its taps are not read).
    let levels: [[&Level; 2]; 4] = std::array::from_fn(|l| {
        let below = &texs[l].levels[i[l]];
        [below, texs[l].levels.get(i[l] + 1).unwrap_or(below)]
    });
    let size =
        |k: usize, a: fn(&Level) -> usize| i32x4::from(levels.map(|l| i32::try_from(a(l[k])).unwrap_or(i32::MAX)));
    let (x, y) = (f32x4::from(uv.map(|c| c.x)), f32x4::from(uv.map(|c| c.y)));
    let (u, v) = (x - F::floor4(x), y - F::floor4(y));
    let below = taps4::<F>(u, v, size(0, |l| l.width), size(0, |l| l.height));
    let above = taps4::<F>(u, v, size(1, |l| l.width), size(1, |l| l.height));
    let mut out = [Vec3A::ZERO; 4];
    for (l, o) in out.iter_mut().enumerate() {
        let a = levels[l][0].blend(&below, l);
        *o = if f[l] == 0.0 || i[l] + 1 >= texs[l].levels.len() {
            a
        } else {
            a.lerp(levels[l][1].blend(&above, l), f[l])
        };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::TextureFilter;
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    fn texture(rng: &mut SmallRng) -> Texture {
        let (w, h) = match rng.random_range(0..4) {
            0 => (1, rng.random_range(1..9)),
            1 => (rng.random_range(1..40), 1),
            _ => (rng.random_range(1..70), rng.random_range(1..70)),
        };
        let texels = (0..w * h)
            .map(|_| glam::Vec3::new(rng.random(), rng.random(), rng.random()))
            .collect();
        Texture::new(w, h, texels).unwrap()
    }

    fn coordinate(rng: &mut SmallRng) -> f32 {
        match rng.random_range(0..8) {
            0 => f32::from(rng.random_range(-3i16..4)),
            1 => -1e-9,
            2 => 1.0 - f32::EPSILON / 2.0,
            3 => rng.random_range(-1e9..1e9),
            _ => rng.random_range(-3.0..3.0),
        }
    }

    fn lod(rng: &mut SmallRng) -> f32 {
        match rng.random_range(0..8) {
            0 => f32::NAN,
            1 => -0.0,
            2 => f32::INFINITY,
            3 => f32::from(rng.random_range(0u8..9)),
            4 => rng.random_range(-5.0..0.0),
            _ => rng.random_range(0.0..9.0),
        }
    }

    /// Every lane is the scalar trilinear lookup's bits, on textures of
    /// many sizes (one texel wide or high, odd sizes), coordinates on and
    /// near integers, far outside the unit square, and levels of detail
    /// that are NaN, negative, whole, or above the last level.
    #[test]
    fn four_lanes_are_the_scalar_lookups() {
        let mut rng = SmallRng::seed_from_u64(0x7e_7e15);
        let mut blended = 0;
        for round in 0..20_000 {
            let pool: Vec<Texture> = (0..2).map(|_| texture(&mut rng)).collect();
            let texs: [&Texture; 4] = std::array::from_fn(|_| &pool[rng.random_range(0..2)]);
            let uv: [Vec2; 4] = std::array::from_fn(|_| Vec2::new(coordinate(&mut rng), coordinate(&mut rng)));
            let lods: [f32; 4] = std::array::from_fn(|_| lod(&mut rng));
            let got = trilinear_lanes::<f32x4>(texs, uv, f32x4::from(lods));
            // The AVX2 code's lookups (SSE4.1 floors) give the same bits.
            #[cfg(target_arch = "x86_64")]
            if openrt_accel::avx2() {
                // SAFETY: the CPU has AVX2 (detected at run time).
                let eight = unsafe { lookups_avx2(texs, uv, f32x4::from(lods)) };
                for l in 0..4 {
                    assert_eq!(
                        got[l].to_array().map(f32::to_bits),
                        eight[l].to_array().map(f32::to_bits),
                        "round {round}, lane {l}: AVX2 lookup"
                    );
                }
            }
            for l in 0..4 {
                assert!(takes_lanes(texs[l], uv[l]));
                let want = texs[l].sample_filtered(uv[l], lods[l], TextureFilter::Trilinear);
                assert_eq!(
                    want.to_array().map(f32::to_bits),
                    got[l].to_array().map(f32::to_bits),
                    "round {round}, lane {l}: uv {} lod {}",
                    uv[l],
                    lods[l]
                );
                blended += usize::from(lods[l].fract() != 0.0 && lods[l] > 0.0 && texs[l].levels() > 1);
            }
        }
        assert!(blended > 10_000, "{blended} lanes between two levels");
    }

    /// [`trilinear_lanes`] as the AVX2-compiled shading runs it.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn lookups_avx2(texs: [&Texture; 4], uv: [Vec2; 4], lod: f32x4) -> [Vec3A; 4] {
        trilinear_lanes::<crate::simd::F32x8>(texs, uv, lod)
    }
}
