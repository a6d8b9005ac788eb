//! The packet triangle test eight lanes to an AVX2 register: the four-lane
//! kernel ([`PacketBlockRay::intersect_block`]) with the same operations in
//! the same order, for CPUs with AVX2 (chosen at run time by the leaf loop,
//! `leaf/blocks.rs`).
//!
//! NOTE: bit for bit the four-lane kernel's answer: the same products and
//! sums without fused multiply-adds, `vmaxps` with the operands in
//! `f32x4::fast_max`'s order (the second one wins on NaN), ordered
//! comparisons (false on NaN) where `wide` uses `cmpltps`, `cmpleps`,
//! `cmpeqps` and swapped `cmpltps`, and a finite test that is false on NaN
//! and on both infinities. Tested against the four-lane kernel (and through
//! it the scalar one) in `super::tests`.

use core::arch::x86_64::{
    __m256, _CMP_EQ_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_UNORD_Q, _mm256_add_ps, _mm256_and_ps,
    _mm256_andnot_ps, _mm256_cmp_ps, _mm256_div_ps, _mm256_loadu_ps, _mm256_max_ps, _mm256_movemask_ps, _mm256_mul_ps,
    _mm256_or_ps, _mm256_set1_ps, _mm256_setzero_ps, _mm256_storeu_ps, _mm256_sub_ps,
};

use wide::f32x4;

use super::{LaneHits, PacketBlockRay};
use crate::geom::numeric::gamma;
use crate::geom::tri_block::TriBlock;

/// Lanes per AVX2 register.
const WIDE: usize = 8;

/// Eight lanes of a chunk array, from lane `8 k` on.
///
/// # Safety
/// `8 k + 8` lanes must lie within `a` (`[f32x4]` is contiguous `f32`).
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn load(a: &[f32x4], k: usize) -> __m256 {
    debug_assert!((k + 1) * WIDE <= a.len() * 4);
    // SAFETY: `f32x4` is sixteen bytes of four `f32` without padding, so
    // the array is contiguous `f32`; the caller keeps the eight lanes read
    // inside it.
    unsafe { _mm256_loadu_ps(a.as_ptr().cast::<f32>().add(k * WIDE)) }
}

/// Writes eight lanes of a chunk array from lane `8 k` on.
///
/// # Safety
/// As [`load`].
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn store(a: &mut [f32x4], k: usize, v: __m256) {
    debug_assert!((k + 1) * WIDE <= a.len() * 4);
    // SAFETY: as in `load`, for writing.
    unsafe { _mm256_storeu_ps(a.as_mut_ptr().cast::<f32>().add(k * WIDE), v) };
}

impl<const N: usize> PacketBlockRay<N> {
    /// [`PacketBlockRay::intersect_block`] eight lanes at a time: the same
    /// [`LaneHits`] (`hit`, `edge`, and every hit lane's `t`, `b1`, `b2`,
    /// bit for bit). Lanes outside `lanes` may hold other values than the
    /// four-lane kernel leaves there; nothing reads them.
    ///
    /// # Safety
    /// The CPU must have AVX2, and `N` must be a multiple of eight.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) unsafe fn intersect_block8(&self, block: &TriBlock, j: usize, lanes: u32, t_max: &[f32; N]) -> LaneHits {
        debug_assert!(N.is_multiple_of(WIDE));
        let mut out = LaneHits::none();
        let splat = |vert: usize, axis: usize| _mm256_set1_ps(block.coord(vert, axis).as_array()[j]);
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let (a, b, c) = (
            [splat(0, kx), splat(0, ky), splat(0, kz)],
            [splat(1, kx), splat(1, ky), splat(1, kz)],
            [splat(2, kx), splat(2, ky), splat(2, kz)],
        );
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        let sign = _mm256_set1_ps(-0.0);
        let (add, sub, mul) = (_mm256_add_ps, _mm256_sub_ps, _mm256_mul_ps);
        let (or, and) = (_mm256_or_ps, _mm256_and_ps);
        let lt = |p, q| _mm256_cmp_ps::<_CMP_LT_OQ>(p, q);
        let gt = |p, q| _mm256_cmp_ps::<_CMP_GT_OQ>(p, q);
        let abs = |p| _mm256_andnot_ps(sign, p);
        let max3 = |p, q, r| _mm256_max_ps(_mm256_max_ps(abs(p), abs(q)), abs(r));
        let bits = |m| _mm256_movemask_ps(m).cast_unsigned();
        for k in 0..N / WIDE {
            let part = (lanes >> (k * WIDE)) & 0xFF;
            if part == 0 {
                continue;
            }
            // SAFETY (every `load` and `store` below): `k < N / 8` and the
            // arrays hold `MAX_LANES >= N` lanes.
            let (ox, oy, oz) = unsafe { (load(&self.ox, k), load(&self.oy, k), load(&self.oz, k)) };
            let (sx, sy) = unsafe { (load(&self.sx, k), load(&self.sy, k)) };
            let za = sub(a[2], oz);
            let zb = sub(b[2], oz);
            let zc = sub(c[2], oz);
            let ax = sub(sub(a[0], ox), mul(sx, za));
            let ay = sub(sub(a[1], oy), mul(sy, za));
            let bx = sub(sub(b[0], ox), mul(sx, zb));
            let by = sub(sub(b[1], oy), mul(sy, zb));
            let cx = sub(sub(c[0], ox), mul(sx, zc));
            let cy = sub(sub(c[1], oy), mul(sy, zc));
            let u = sub(mul(cx, by), mul(cy, bx));
            let v = sub(mul(ax, cy), mul(ay, cx));
            let w = sub(mul(bx, ay), mul(by, ax));
            let neg = or(or(lt(u, zero), lt(v, zero)), lt(w, zero));
            let pos = or(or(gt(u, zero), gt(v, zero)), gt(w, zero));
            let mixed = and(neg, pos);
            // The pre-test: lanes with mixed signs are certain misses.
            if !bits(mixed) & part == 0 {
                continue;
            }
            let eq = |p| _mm256_cmp_ps::<_CMP_EQ_OQ>(p, zero);
            let on_edge = or(or(eq(u), eq(v)), eq(w));
            let det = add(add(u, v), w);
            let sgn = or(one, and(det, sign));
            let outside = or(or(lt(mul(u, sgn), zero), lt(mul(v, sgn), zero)), lt(mul(w, sgn), zero));
            let sz = unsafe { load(&self.sz, k) };
            let (az, bz, cz) = (mul(sz, za), mul(sz, zb), mul(sz, zc));
            let t_scaled = add(add(mul(u, az), mul(v, bz)), mul(w, cz));
            let abs_det = abs(det);
            let ts = mul(t_scaled, sgn);
            // SAFETY: lanes `8 k..8 k + 8` of the `N` bounds.
            let hi = unsafe { _mm256_loadu_ps(t_max.as_ptr().add(k * WIDE)) };
            let t_min = unsafe { load(&self.t_min, k) };
            let within = and(gt(ts, mul(t_min, abs_det)), lt(ts, mul(hi, abs_det)));
            let rcp_det = _mm256_div_ps(one, det);
            let t = mul(t_scaled, rcp_det);
            let g = |n: u32| _mm256_set1_ps(gamma(n));
            let max_zt = max3(az, bz, cz);
            let max_zu = max3(za, zb, zc);
            let delta_z = mul(g(3), max_zt);
            let max_xt = max3(ax, bx, cx);
            let max_yt = max3(ay, by, cy);
            let delta_x = mul(g(5), add(max_xt, max_zu));
            let delta_y = mul(g(5), add(max_yt, max_zu));
            let delta_e = mul(
                _mm256_set1_ps(2.0),
                add(
                    add(mul(mul(g(2), max_xt), max_yt), mul(delta_y, max_xt)),
                    mul(delta_x, max_yt),
                ),
            );
            let max_e = max3(u, v, w);
            let delta_t = mul(
                mul(
                    _mm256_set1_ps(3.0),
                    add(
                        add(mul(mul(g(3), max_e), max_zt), mul(delta_e, max_zt)),
                        mul(delta_z, max_e),
                    ),
                ),
                abs(rcp_det),
            );
            // The four-lane kernel's rejections, in its order.
            let finite = lt(abs(t), _mm256_set1_ps(f32::INFINITY));
            let rejected = or(
                or(or(mixed, on_edge), or(eq(det), _mm256_cmp_ps::<_CMP_UNORD_Q>(det, det))),
                or(outside, _mm256_cmp_ps::<_CMP_LE_OQ>(t, delta_t)),
            );
            let kept = !bits(rejected) & bits(within) & bits(finite) & 0xFF;
            out.hit |= kept << (k * WIDE);
            out.edge |= bits(_mm256_andnot_ps(mixed, on_edge)) << (k * WIDE);
            unsafe {
                store(&mut out.t, k, t);
                store(&mut out.b1, k, mul(v, rcp_det));
                store(&mut out.b2, k, mul(w, rcp_det));
            }
        }
        out.hit &= lanes;
        out.edge &= lanes;
        out
    }
}
