//! The watertight ray/triangle test four at a time (Woop, Benthin & Wald,
//! JCGT 2013), whatever the four lanes are: four rays against one triangle
//! (a packet's leaf test, `packet/triangle/`) or one ray against the four
//! triangles of a leaf block (single rays, `leaf/blocks.rs`).
//!
//! NOTE: each lane repeats [`crate::geom::triangle::intersect_triangle`]'s
//! operations one for one (the same subtractions and products in the same
//! order, no fused multiply-add, comparisons written so that NaN goes the
//! same way), so a lane's decision, `t` and barycentrics are the scalar
//! kernel's bits. The one case it leaves open is an edge function that is
//! exactly zero (a ray through an edge or a vertex), which the scalar kernel
//! recomputes in f64 under its tie rule: such lanes come back in
//! [`Decided4::edge`] for the caller to hand to it.

use wide::f32x4;

use crate::geom::numeric::gamma;

/// Four lanes' translated, sheared vertices and edge functions: the scalar
/// kernel's first operations.
#[derive(Clone, Copy)]
pub(crate) struct Edges4 {
    za: f32x4,
    zb: f32x4,
    zc: f32x4,
    ax: f32x4,
    ay: f32x4,
    bx: f32x4,
    by: f32x4,
    cx: f32x4,
    cy: f32x4,
    u: f32x4,
    v: f32x4,
    w: f32x4,
}

/// What [`Edges4::decide`] found, lane by lane.
#[derive(Clone, Copy)]
pub(crate) struct Decided4 {
    /// Lanes (bits 0..4) that hit inside `(t_min, t_max)`: `t`, `b1` and
    /// `b2` hold the scalar kernel's hit.
    pub(crate) hit: u32,
    /// Lanes with an edge function exactly zero and not of mixed signs:
    /// only the scalar kernel decides them (never in `hit`).
    pub(crate) edge: u32,
    pub(crate) t: f32x4,
    pub(crate) b1: f32x4,
    pub(crate) b2: f32x4,
    /// The scaled distance, oriented (`t_scaled * sgn`): a hit stays inside
    /// a lower bound `b` exactly when `ts < b * abs_det`, as in the scalar
    /// kernel.
    pub(crate) ts: f32x4,
    /// `|det|`.
    pub(crate) abs_det: f32x4,
}

impl Edges4 {
    /// The edge functions of triangles `(a, b, c)`, each vertex given in the
    /// ray's axis permutation `(x, y, z)`, for rays of origin `o` (permuted
    /// too) and shear `(sx, sy)`.
    #[allow(clippy::inline_always, clippy::many_single_char_names)]
    #[inline(always)]
    pub(crate) fn new(a: &[f32x4; 3], b: &[f32x4; 3], c: &[f32x4; 3], o: &[f32x4; 3], sx: f32x4, sy: f32x4) -> Self {
        let za = a[2] - o[2];
        let zb = b[2] - o[2];
        let zc = c[2] - o[2];
        let ax = a[0] - o[0] - sx * za;
        let ay = a[1] - o[1] - sy * za;
        let bx = b[0] - o[0] - sx * zb;
        let by = b[1] - o[1] - sy * zb;
        let cx = c[0] - o[0] - sx * zc;
        let cy = c[1] - o[1] - sy * zc;
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
            u: cx * by - cy * bx,
            v: ax * cy - ay * cx,
            w: bx * ay - by * ax,
        }
    }

    /// Lanes whose edge functions have mixed signs: certain misses (the
    /// pre-test, all ones where a lane is out).
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub(crate) fn mixed(&self) -> f32x4 {
        let zero = f32x4::ZERO;
        let neg = self.u.simd_lt(zero) | self.v.simd_lt(zero) | self.w.simd_lt(zero);
        let pos = self.u.simd_gt(zero) | self.v.simd_gt(zero) | self.w.simd_gt(zero);
        neg & pos
    }

    /// The rest of the test after the edge functions (`mixed` from
    /// [`Edges4::mixed`]), with the rays' `sz` shear, over `(t_min, t_max)`.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub(crate) fn decide(&self, mixed: f32x4, sz: f32x4, t_min: f32x4, t_max: f32x4) -> Decided4 {
        let zero = f32x4::ZERO;
        let (u, v, w) = (self.u, self.v, self.w);
        let on_edge = u.simd_eq(zero) | v.simd_eq(zero) | w.simd_eq(zero);
        let det = u + v + w;
        // `1.0f32.copysign(det)`.
        let sgn = f32x4::ONE | (det & f32x4::splat(-0.0));
        let outside = (u * sgn).simd_lt(zero) | (v * sgn).simd_lt(zero) | (w * sgn).simd_lt(zero);
        let (az, bz, cz) = (sz * self.za, sz * self.zb, sz * self.zc);
        let t_scaled = u * az + v * bz + w * cz;
        let abs_det = det.abs();
        let ts = t_scaled * sgn;
        let within = ts.simd_gt(t_min * abs_det) & ts.simd_lt(t_max * abs_det);
        let rcp_det = f32x4::ONE / det;
        let t = t_scaled * rcp_det;
        // PERF: `fast_max` (one `maxps`) where `f32::max` would need NaN
        // handling: a NaN in any of these inputs makes `det` or `t_scaled`
        // NaN, and the lane is rejected whatever the bound.
        let max3 = |p: f32x4, q: f32x4, r: f32x4| p.abs().fast_max(q.abs()).fast_max(r.abs());
        let max_zt = max3(az, bz, cz);
        let max_zu = max3(self.za, self.zb, self.zc);
        let delta_z = f32x4::splat(gamma(3)) * max_zt;
        let max_xt = max3(self.ax, self.bx, self.cx);
        let max_yt = max3(self.ay, self.by, self.cy);
        let delta_x = f32x4::splat(gamma(5)) * (max_xt + max_zu);
        let delta_y = f32x4::splat(gamma(5)) * (max_yt + max_zu);
        let delta_e =
            f32x4::splat(2.0) * (f32x4::splat(gamma(2)) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
        let max_e = max3(u, v, w);
        let delta_t = f32x4::splat(3.0)
            * (f32x4::splat(gamma(3)) * max_e * max_zt + delta_e * max_zt + delta_z * max_e)
            * rcp_det.abs();
        // The scalar kernel's rejections, in its terms: mixed signs, `det`
        // zero or NaN, outside, beyond the interval, `t` within its error of
        // zero or not finite (`!(t <= delta_t)`: a NaN `delta_t` rejects
        // nothing, as there).
        let rejected = mixed
            | on_edge
            | det.simd_eq(zero)
            | det.is_nan()
            | outside
            | !within
            | t.simd_le(delta_t)
            | !t.is_finite();
        Decided4 {
            hit: (!rejected).to_bitmask() & 0xF,
            edge: (on_edge & !mixed).to_bitmask() & 0xF,
            t,
            b1: v * rcp_det,
            b2: w * rcp_det,
            ts,
            abs_det,
        }
    }
}
