//! [`super::watertight4`] eight lanes to an AVX2 register, for CPUs with
//! AVX2 (chosen at run time by the callers): eight rays against one
//! triangle (`packet/triangle/avx2.rs`) or one ray against two leaf blocks
//! (`leaf/blocks.rs`).
//!
//! NOTE: bit for bit the four-lane test's answer: the same products and
//! sums without fused multiply-adds, `vmaxps` with the operands in
//! `f32x4::fast_max`'s order (the second one wins on NaN), ordered
//! comparisons (false on NaN) where `wide` uses `cmpltps`, `cmpleps`,
//! `cmpeqps` and swapped `cmpltps`, and a finite test that is false on NaN
//! and on both infinities. Tested against the four-lane test through both
//! callers' tests.

use core::arch::x86_64::{
    __m256, _CMP_EQ_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_UNORD_Q, _mm256_add_ps, _mm256_and_ps,
    _mm256_andnot_ps, _mm256_cmp_ps, _mm256_div_ps, _mm256_max_ps, _mm256_movemask_ps, _mm256_mul_ps, _mm256_or_ps,
    _mm256_set1_ps, _mm256_setzero_ps, _mm256_sub_ps,
};

use crate::geom::numeric::gamma;

/// Eight lanes' translated, sheared vertices and edge functions.
#[derive(Clone, Copy)]
pub(crate) struct Edges8 {
    za: __m256,
    zb: __m256,
    zc: __m256,
    ax: __m256,
    ay: __m256,
    bx: __m256,
    by: __m256,
    cx: __m256,
    cy: __m256,
    u: __m256,
    v: __m256,
    w: __m256,
}

/// What [`Edges8::decide`] found, lane by lane (as
/// [`super::watertight4::Decided4`]).
#[derive(Clone, Copy)]
pub(crate) struct Decided8 {
    /// Lanes (bits 0..8) that hit inside `(t_min, t_max)`.
    pub(crate) hit: u32,
    /// Lanes with an edge function exactly zero and not of mixed signs.
    pub(crate) edge: u32,
    pub(crate) t: __m256,
    pub(crate) b1: __m256,
    pub(crate) b2: __m256,
    /// `t_scaled * sgn`.
    pub(crate) ts: __m256,
    /// `|det|`.
    pub(crate) abs_det: __m256,
}

impl Edges8 {
    /// [`super::watertight4::Edges4::new`], eight lanes.
    #[target_feature(enable = "avx2")]
    #[inline]
    #[allow(clippy::many_single_char_names)]
    pub(crate) fn new(
        a: &[__m256; 3],
        b: &[__m256; 3],
        c: &[__m256; 3],
        o: &[__m256; 3],
        sx: __m256,
        sy: __m256,
    ) -> Self {
        let (sub, mul) = (_mm256_sub_ps, _mm256_mul_ps);
        let za = sub(a[2], o[2]);
        let zb = sub(b[2], o[2]);
        let zc = sub(c[2], o[2]);
        let ax = sub(sub(a[0], o[0]), mul(sx, za));
        let ay = sub(sub(a[1], o[1]), mul(sy, za));
        let bx = sub(sub(b[0], o[0]), mul(sx, zb));
        let by = sub(sub(b[1], o[1]), mul(sy, zb));
        let cx = sub(sub(c[0], o[0]), mul(sx, zc));
        let cy = sub(sub(c[1], o[1]), mul(sy, zc));
        Self {
            za,
            zb,
            zc,
            ax,
            ay,
            bx,
            by,
            cx,
            cy,
            u: sub(mul(cx, by), mul(cy, bx)),
            v: sub(mul(ax, cy), mul(ay, cx)),
            w: sub(mul(bx, ay), mul(by, ax)),
        }
    }

    /// Lanes whose edge functions have mixed signs (all ones): certain
    /// misses.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn mixed(&self) -> __m256 {
        let zero = _mm256_setzero_ps();
        let or = _mm256_or_ps;
        let lt = |p, q| _mm256_cmp_ps::<_CMP_LT_OQ>(p, q);
        let gt = |p, q| _mm256_cmp_ps::<_CMP_GT_OQ>(p, q);
        let neg = or(or(lt(self.u, zero), lt(self.v, zero)), lt(self.w, zero));
        let pos = or(or(gt(self.u, zero), gt(self.v, zero)), gt(self.w, zero));
        _mm256_and_ps(neg, pos)
    }

    /// [`super::watertight4::Edges4::decide`], eight lanes.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) fn decide(&self, mixed: __m256, sz: __m256, t_min: __m256, t_max: __m256) -> Decided8 {
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        let sign = _mm256_set1_ps(-0.0);
        let (add, mul) = (_mm256_add_ps, _mm256_mul_ps);
        let (or, and) = (_mm256_or_ps, _mm256_and_ps);
        let lt = |p, q| _mm256_cmp_ps::<_CMP_LT_OQ>(p, q);
        let gt = |p, q| _mm256_cmp_ps::<_CMP_GT_OQ>(p, q);
        let eq = |p| _mm256_cmp_ps::<_CMP_EQ_OQ>(p, zero);
        let abs = |p| _mm256_andnot_ps(sign, p);
        let max3 = |p, q, r| _mm256_max_ps(_mm256_max_ps(abs(p), abs(q)), abs(r));
        let bits = |m| _mm256_movemask_ps(m).cast_unsigned();
        let (u, v, w) = (self.u, self.v, self.w);
        let on_edge = or(or(eq(u), eq(v)), eq(w));
        let det = add(add(u, v), w);
        let sgn = or(one, and(det, sign));
        let outside = or(or(lt(mul(u, sgn), zero), lt(mul(v, sgn), zero)), lt(mul(w, sgn), zero));
        let (az, bz, cz) = (mul(sz, self.za), mul(sz, self.zb), mul(sz, self.zc));
        let t_scaled = add(add(mul(u, az), mul(v, bz)), mul(w, cz));
        let abs_det = abs(det);
        let ts = mul(t_scaled, sgn);
        let within = and(gt(ts, mul(t_min, abs_det)), lt(ts, mul(t_max, abs_det)));
        let rcp_det = _mm256_div_ps(one, det);
        let t = mul(t_scaled, rcp_det);
        let g = |n: u32| _mm256_set1_ps(gamma(n));
        let max_zt = max3(az, bz, cz);
        let max_zu = max3(self.za, self.zb, self.zc);
        let delta_z = mul(g(3), max_zt);
        let max_xt = max3(self.ax, self.bx, self.cx);
        let max_yt = max3(self.ay, self.by, self.cy);
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
        // The four-lane test's rejections.
        let finite = lt(abs(t), _mm256_set1_ps(f32::INFINITY));
        let rejected = or(
            or(or(mixed, on_edge), or(eq(det), _mm256_cmp_ps::<_CMP_UNORD_Q>(det, det))),
            or(outside, _mm256_cmp_ps::<_CMP_LE_OQ>(t, delta_t)),
        );
        Decided8 {
            hit: !bits(rejected) & bits(within) & bits(finite) & 0xFF,
            edge: bits(_mm256_andnot_ps(mixed, on_edge)),
            t,
            b1: mul(v, rcp_det),
            b2: mul(w, rcp_det),
            ts,
            abs_det,
        }
    }
}
