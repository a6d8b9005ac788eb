//! Triangle storage and the watertight ray/triangle test.
//!
//! Woop, Benthin & Wald, "Watertight Ray/Triangle Intersection", JCGT 2(1),
//! 2013: the ray is made the +z axis by a permutation and a shear computed
//! once per ray; the triangle is translated, sheared and projected, and the
//! three 2D edge functions decide the hit. Adjacent triangles evaluate the
//! edge functions of their shared edge from bit-identical inputs, so a ray
//! through an edge or a vertex can not slip between them.
//!
//! Conventions (tested in this crate):
//! - Triangles are two-sided here; one-sided shading is the renderer's job.
//! - A ray coplanar with a triangle does not hit it (the projected triangle
//!   has zero area: `det == 0`).
//! - A ray exactly through an edge or a vertex hits exactly one of the
//!   triangles around it, for consistently oriented meshes: a zero edge
//!   function is resolved by a tie-breaking rule on the direction of that
//!   edge in the projected plane (the "top-left" rule of rasterisers), so
//!   a closed mesh is entered and left once, never twice.
//! - Zero-area triangles never hit (`det == 0`).
//! - The returned `t` is conservatively positive: after pbrt-v3's error
//!   analysis of this test, a `t` within its own rounding error of 0 is
//!   rejected.

use glam::Vec3;
use wide::f32x4;

use crate::geom::numeric::gamma;
use crate::geom::ray::Ray;

/// A triangle stored as its three vertices.
///
/// PERF: the watertight test needs the raw vertices (any precomputed plane or
/// edge data would be rounded differently in adjacent triangles and break
/// watertightness), so a triangle is 36 contiguous bytes read in one go.
/// Kd-tree leaves keep a bit-identical copy of their triangles' vertices in
/// SIMD blocks for the edge pre-test (`leaf_blocks.rs`), and traversal reads
/// the few triangles that pass it from there too, not from this array.
pub type Triangle = [Vec3; 3];

/// Result of the triangle kernel: `(t, b1, b2)`.
pub type TriHit = (f32, f32, f32);

/// Tests `ray` against triangle `(v0, v1, v2)` over `(ray.t_min, t_max)`.
// PERF: forced inline into the leaf loops (as a call it was its own 13% hotspot in perf).
#[allow(clippy::inline_always)]
#[inline(always)]
#[must_use]
pub fn intersect_triangle(ray: &Ray, tri: &Triangle, t_max: f32) -> Option<TriHit> {
    let [kx, ky, kz] = ray.axes();
    let s = ray.shear;
    let a = (tri[0] - ray.origin).to_array();
    let b = (tri[1] - ray.origin).to_array();
    let c = (tri[2] - ray.origin).to_array();
    // Shear and scale the vertices.
    let ax = a[kx] - s.x * a[kz];
    let ay = a[ky] - s.y * a[kz];
    let bx = b[kx] - s.x * b[kz];
    let by = b[ky] - s.y * b[kz];
    let cx = c[kx] - s.x * c[kz];
    let cy = c[ky] - s.y * c[kz];

    // Scaled barycentric coordinates (2D edge functions).
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;

    // PERF: most tests are misses with edge functions of mixed sign: leave
    // before anything else.
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    // NOTE: exact zero tests: only a true zero needs the exact recomputation.
    let on_edge = u == 0.0 || v == 0.0 || w == 0.0;
    if on_edge {
        // The products of two f32 are exact in f64 and the difference is
        // correctly rounded, so the sign of each edge function is exact.
        let e = |px: f32, py: f32, qx: f32, qy: f32| -> f32 {
            let r = f64::from(px) * f64::from(qy) - f64::from(py) * f64::from(qx);
            // Keep the sign and a magnitude usable for the barycentrics.
            if r == 0.0 {
                0.0
            } else {
                let f = r as f32;
                if f == 0.0 {
                    f32::MIN_POSITIVE.copysign(r as f32)
                } else {
                    f
                }
            }
        };
        u = e(cx, cy, bx, by);
        v = e(ax, ay, cx, cy);
        w = e(bx, by, ax, ay);
    }

    let det = u + v + w;
    if det == 0.0 || det.is_nan() {
        return None;
    }
    // Orientation of the projected triangle: +1 counter-clockwise.
    let sgn = 1.0f32.copysign(det);
    // u, v, w are the edge functions of C->B, A->C and B->A.
    if on_edge
        && !(inside(u * sgn, (bx - cx) * sgn, (by - cy) * sgn)
            && inside(v * sgn, (cx - ax) * sgn, (cy - ay) * sgn)
            && inside(w * sgn, (ax - bx) * sgn, (ay - by) * sgn))
    {
        return None;
    }
    if !on_edge && (u * sgn < 0.0 || v * sgn < 0.0 || w * sgn < 0.0) {
        return None;
    }

    // Scaled hit distance and the interval test without a division.
    let az = s.z * a[kz];
    let bz = s.z * b[kz];
    let cz = s.z * c[kz];
    let t_scaled = u * az + v * bz + w * cz;
    let abs_det = det.abs();
    let ts = t_scaled * sgn;
    if !(ts > ray.t_min * abs_det && ts < t_max * abs_det) {
        return None;
    }
    let rcp_det = 1.0 / det;
    let t = t_scaled * rcp_det;

    // Conservative t > 0 (pbrt-v3, section 3.9.6, applied to this test).
    // NOTE: the x/y shear error involves the *unscaled* z (|Sx|, |Sy| <= 1);
    // pbrt uses the z scaled by Sz, which is only bounded for unit-length
    // directions and rejects valid hits for short direction vectors.
    let max_zt = az.abs().max(bz.abs()).max(cz.abs());
    let max_zu = a[kz].abs().max(b[kz].abs()).max(c[kz].abs());
    let delta_z = gamma(3) * max_zt;
    let max_xt = ax.abs().max(bx.abs()).max(cx.abs());
    let max_yt = ay.abs().max(by.abs()).max(cy.abs());
    let delta_x = gamma(5) * (max_xt + max_zu);
    let delta_y = gamma(5) * (max_yt + max_zu);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = u.abs().max(v.abs()).max(w.abs());
    let delta_t = 3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * rcp_det.abs();
    if t <= delta_t || !t.is_finite() {
        return None;
    }
    Some((t, v * rcp_det, w * rcp_det))
}

/// One edge test: strictly inside, or exactly on the edge and the edge wins
/// the tie. `(dx, dy)` is the edge direction in the projected plane, already
/// oriented so that the interior is on its left.
#[inline]
fn inside(e: f32, dx: f32, dy: f32) -> bool {
    e > 0.0 || (e == 0.0 && (dy > 0.0 || (dy == 0.0 && dx > 0.0)))
}

/// `true` when the triangle has finite vertices and a non-zero area.
#[must_use]
#[inline]
pub fn is_valid_triangle(tri: &Triangle) -> bool {
    if !(tri[0].is_finite() && tri[1].is_finite() && tri[2].is_finite()) {
        return false;
    }
    // PERF: the f32 normal decides nearly every triangle (7% of a 16k-triangle
    // refit was the f64 test alone); only where it cannot does f64 decide.
    clearly_not_flat(tri) || not_flat_f64(tri)
}

/// The normal's components in f64 (edges and products rounded to 53 bits:
/// zero only for a flat triangle or one flatter than f64 can tell).
#[inline]
fn not_flat_f64(tri: &Triangle) -> bool {
    let d = |p: Vec3| p.as_dvec3();
    let n = (d(tri[1]) - d(tri[0])).cross(d(tri[2]) - d(tri[0]));
    n != glam::DVec3::ZERO
}

/// The relative error bound [`clearly_not_flat`] allows a normal's component.
const FLAT_BOUND: f32 = 8.0 * f32::EPSILON;

/// Below this a normal's products may be subnormal, where relative bounds
/// fail: [`clearly_not_flat`] leaves such triangles to f64.
const FLAT_SMALLEST: f32 = 1e-30;

/// `true` only when a component of the f32 normal exceeds its rounding
/// error bound, so that the exact normal (and the f64 one of
/// [`not_flat_f64`], whose error is 2^29 times smaller) is not zero either.
///
/// Each component is `a * b - c * d` of edges rounded once: its error is at
/// most about `4u (|ab| + |cd|)` (u = 2^-24); the bound used is four times
/// that. Products near underflow or overflow are left to f64.
#[inline]
fn clearly_not_flat(tri: &Triangle) -> bool {
    use glam::Vec3Swizzles;
    let (e1, e2) = (tri[1] - tri[0], tri[2] - tri[0]);
    let n = e1.cross(e2);
    let mag = (e1.yzx() * e2.zxy()).abs() + (e1.zxy() * e2.yzx()).abs();
    let certain = n.abs().cmpgt(mag * FLAT_BOUND) & mag.cmpge(Vec3::splat(FLAT_SMALLEST)) & mag.is_finite_mask();
    certain.any()
}

/// [`is_valid_triangle`] of four triangles at once, given coordinate by
/// coordinate (`v[vertex][axis]`, a lane per triangle, as in
/// [`crate::geom::tri_block::TriBlock`]): bit `i` of the answer is lane
/// `i`'s validity.
///
/// The twin of the scalar test, lane by lane: the same edges, products and
/// bound (so the same f32 decisions; tested), and lanes the f32 normal cannot
/// decide go to the f64 test one by one. PERF: the validity tests were a
/// quarter of a 16k-triangle BVH refit one triangle at a time.
pub(crate) fn valid_lanes(v: &[[f32x4; 3]; 3]) -> u32 {
    let (finite, certain) = decided_lanes(v);
    let mut valid = finite & certain;
    for i in 0..4 {
        if (finite & !valid) >> i & 1 == 1 {
            let lane = |k: usize| Vec3::new(v[k][0].to_array()[i], v[k][1].to_array()[i], v[k][2].to_array()[i]);
            valid |= u32::from(not_flat_f64(&[lane(0), lane(1), lane(2)])) << i;
        }
    }
    valid
}

/// The lanes' finite vertices and [`clearly_not_flat`] decisions, as bit
/// masks.
#[inline]
fn decided_lanes(v: &[[f32x4; 3]; 3]) -> (u32, u32) {
    let max = f32x4::splat(f32::MAX);
    let mut finite = f32x4::splat(f32::from_bits(u32::MAX));
    for c in v.iter().flatten() {
        finite &= c.abs().simd_le(max);
    }
    let e1: [f32x4; 3] = std::array::from_fn(|a| v[1][a] - v[0][a]);
    let e2: [f32x4; 3] = std::array::from_fn(|a| v[2][a] - v[0][a]);
    let mut certain = f32x4::ZERO;
    for a in 0..3 {
        // Component `a` of the normal: `p - q`, as `Vec3::cross` forms it.
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        let (p, q) = (e1[b] * e2[c], e1[c] * e2[b]);
        let mag = p.abs() + q.abs();
        certain |= (p - q).abs().simd_gt(mag * f32x4::splat(FLAT_BOUND))
            & mag.simd_ge(f32x4::splat(FLAT_SMALLEST))
            & mag.simd_le(max);
    }
    (finite.to_bitmask(), certain.to_bitmask())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform numbers in `[0, 1)` from a xorshift generator seeded `s`.
    fn uniform(mut s: u64) -> impl FnMut() -> f64 {
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The four-lane validity test answers as the scalar one, lane by lane,
    /// on general, flat, sliver, huge, tiny and non-finite triangles.
    #[test]
    fn valid_lanes_matches_the_scalar_test() {
        let mut next = uniform(0x2545_f491_4f6c_dd1d);
        let mut tris = Vec::new();
        for i in 0..40_000 {
            let scale = 10f64.powi((i % 80) - 40) as f32;
            let mut p = || Vec3::new((next() - 0.5) as f32, (next() - 0.5) as f32, (next() - 0.5) as f32) * scale;
            let a = p();
            let (mut b, mut c) = (a + p(), a + p());
            match i % 9 {
                0 => c = a + (b - a) * 0.5,
                1 => c = a + (b - a) * 3.0 + Vec3::splat(scale * 1e-7),
                2 => b = a + Vec3::X * f32::from_bits(1 + (i as u32 % 100)),
                3 => b.y = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][i as usize % 3],
                4 => c = Vec3::new(3e38, -3e38, 3e38),
                5 => b = a,
                _ => {}
            }
            tris.push([a, b, c]);
        }
        tris.push([Vec3::ZERO, Vec3::new(3e38, 0.0, 0.0), Vec3::new(0.0, 3e38, 0.0)]);
        let (mut valid, mut invalid) = (0, 0);
        for quad in tris.chunks(4) {
            let lane = |i: usize| quad[i.min(quad.len() - 1)];
            let v: [[f32x4; 3]; 3] =
                std::array::from_fn(|k| std::array::from_fn(|a| f32x4::from(std::array::from_fn(|i| lane(i)[k][a]))));
            let got = valid_lanes(&v);
            let (finite, certain) = decided_lanes(&v);
            for i in 0..4 {
                let t = lane(i);
                let want = is_valid_triangle(&t);
                assert_eq!(got >> i & 1 == 1, want, "{t:?}");
                assert_eq!(finite >> i & 1 == 1, t.iter().all(|p| p.is_finite()), "{t:?}");
                assert_eq!(certain >> i & 1 == 1, clearly_not_flat(&t), "{t:?}");
                valid += usize::from(want);
                invalid += usize::from(!want);
            }
        }
        assert!(valid > 10_000 && invalid > 5_000, "{valid} valid, {invalid} invalid");
    }

    /// The fast f32 decision never contradicts f64 (it may only defer to
    /// it): slivers, collinear points, huge and tiny coordinates, subnormal
    /// and overflowing products.
    #[test]
    fn validity_fast_path_agrees_with_f64() {
        let mut next = uniform(0x9e37_79b9_7f4a_7c15);
        let (mut flat, mut general, mut fast) = (0, 0, 0);
        for i in 0..200_000 {
            let exponent = (i % 80) - 40;
            let scale = 10f64.powi(exponent) as f32;
            let mut p = |k: f64| {
                Vec3::new((next() - 0.5) as f32, (next() - 0.5) as f32, (next() - 0.5) as f32) * (scale * k as f32)
            };
            let a = p(1.0) + Vec3::splat(scale * (i % 7) as f32 * 1e3);
            let mut b = a + p(1.0);
            let mut c = a + p(1.0);
            match i % 5 {
                // Collinear (exactly or up to rounding), and slivers.
                0 => c = a + (b - a) * 0.5,
                1 => c = a + (b - a) * 3.0 + Vec3::splat(scale * 1e-7),
                2 => b = a + Vec3::X * f32::from_bits(1 + (i as u32 % 100)),
                _ => {}
            }
            let t = [a, b, c];
            let decided = clearly_not_flat(&t);
            if decided {
                assert!(not_flat_f64(&t), "{t:?}: f32 says not flat, f64 says flat");
            }
            flat += usize::from(!not_flat_f64(&t));
            if i % 5 >= 3 && exponent.abs() <= 12 {
                general += 1;
                fast += usize::from(decided);
            }
        }
        // Flat triangles occur, and f32 decides every general one of moderate size.
        assert!(flat > 1_000, "{flat} flat");
        assert_eq!(fast, general, "decided in f32");
        // Overflowing products go to f64.
        let big = [Vec3::ZERO, Vec3::new(3e38, 0.0, 0.0), Vec3::new(0.0, 3e38, 0.0)];
        assert!(!clearly_not_flat(&big) && is_valid_triangle(&big));
    }

    fn tri() -> Triangle {
        [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ]
    }

    #[test]
    fn hits_the_interior_with_correct_barycentrics() {
        let r = Ray::infinite(Vec3::new(0.25, 0.5, 1.0), -Vec3::Z);
        let (t, b1, b2) = intersect_triangle(&r, &tri(), f32::INFINITY).unwrap();
        assert!((t - 1.0).abs() < 1e-6);
        assert!((b1 - 0.25).abs() < 1e-6 && (b2 - 0.5).abs() < 1e-6);
        // Back side hits too (two-sided).
        let r = Ray::infinite(Vec3::new(0.25, 0.5, -1.0), Vec3::Z);
        assert!(intersect_triangle(&r, &tri(), f32::INFINITY).is_some());
    }

    #[test]
    fn respects_the_interval() {
        let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, 0.0, 0.5);
        assert!(intersect_triangle(&r, &tri(), 0.5).is_none());
        let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, 1.5, 9.0);
        assert!(intersect_triangle(&r, &tri(), 9.0).is_none());
        // Behind the origin.
        let r = Ray::infinite(Vec3::new(0.25, 0.25, 1.0), Vec3::Z);
        assert!(intersect_triangle(&r, &tri(), f32::INFINITY).is_none());
    }

    #[test]
    fn coplanar_ray_misses() {
        let r = Ray::infinite(Vec3::new(-1.0, 0.25, 0.0), Vec3::X);
        assert!(intersect_triangle(&r, &tri(), f32::INFINITY).is_none());
    }

    #[test]
    fn degenerate_triangles_never_hit() {
        let line = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        let point = [Vec3::ONE; 3];
        for t in [line, point] {
            assert!(!is_valid_triangle(&t));
            for d in [Vec3::Z, Vec3::new(0.3, 0.1, -1.0), Vec3::X] {
                let r = Ray::infinite(Vec3::new(1.0, 0.0, 1.0) - d, d);
                assert!(intersect_triangle(&r, &t, f32::INFINITY).is_none());
            }
        }
    }

    #[test]
    fn a_shared_edge_is_hit_exactly_once_from_both_sides() {
        // Quad split along its diagonal, consistently wound.
        let a = Vec3::new(0.0, 0.0, 0.0);
        let b = Vec3::new(1.0, 0.0, 0.0);
        let c = Vec3::new(1.0, 1.0, 0.0);
        let d = Vec3::new(0.0, 1.0, 0.0);
        let t1 = [a, b, c];
        let t2 = [a, c, d];
        for dir in [-Vec3::Z, Vec3::Z, Vec3::new(0.2, -0.1, -1.0)] {
            for k in 0..=16 {
                let p = Vec3::splat(k as f32 / 16.0).with_z(0.0);
                let r = Ray::infinite(p - dir, dir);
                let n = [t1, t2]
                    .iter()
                    .filter(|t| intersect_triangle(&r, t, f32::INFINITY).is_some())
                    .count();
                if k == 0 || k == 16 {
                    assert!(n <= 1, "corner {k}");
                } else {
                    assert_eq!(n, 1, "diagonal point {k} dir {dir}");
                }
            }
        }
    }
}
