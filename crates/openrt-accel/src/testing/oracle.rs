//! The brute-force f64 reference intersector that every acceleration
//! structure is tested against.
//!
//! It tests every triangle in double precision (Möller & Trumbore 1997) and
//! classifies each candidate as a *solid* hit (inside by a margin), a
//! *possible* hit (inside within the margin) or a miss. An accelerated
//! result is accepted when it agrees with the oracle wherever the answer is
//! not decided by rounding: see [`BruteForce::check_closest`].

use glam::{DVec3, Vec3};

use crate::geom::hit::Hit;
use crate::geom::ray::Ray;
use crate::geom::triangle::Triangle;

/// Relative tolerance on `t` when comparing against the oracle.
pub const T_REL_TOL: f64 = 1e-4;

/// An exact-as-f64 candidate intersection with one triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OracleHit {
    /// Triangle index.
    pub prim: u32,
    /// Ray parameter (f64).
    pub t: f64,
    /// Smallest barycentric coordinate (negative: outside).
    pub min_bary: f64,
    /// Barycentric margin under which the f32 kernel may decide either way.
    pub bary_tol: f64,
    /// Tolerance on `t` for this triangle and ray.
    pub t_tol: f64,
}

/// Brute-force reference over a triangle slice.
#[derive(Clone, Copy, Debug)]
pub struct BruteForce<'a> {
    tris: &'a [Triangle],
}

impl<'a> BruteForce<'a> {
    /// The oracle over `tris` (indices are `Hit::prim`).
    #[must_use]
    pub fn new(tris: &'a [Triangle]) -> Self {
        Self { tris }
    }

    /// Every candidate intersection of the ray's line with a triangle's
    /// plane (any `t`, barycentrics possibly negative).
    #[must_use]
    pub fn candidates(&self, ray: &Ray) -> Vec<OracleHit> {
        let o = ray.origin.as_dvec3();
        let d = ray.dir.as_dvec3();
        self.tris
            .iter()
            .enumerate()
            .filter_map(|(i, tri)| {
                candidate(o, d, ray.origin, tri).map(|(t, mb, bt, tt)| OracleHit {
                    prim: i as u32,
                    t,
                    min_bary: mb,
                    bary_tol: bt,
                    t_tol: tt,
                })
            })
            .collect()
    }

    /// The closest hit in f64 with no tolerance (strictly inside, `t` in the ray interval).
    #[must_use]
    pub fn closest(&self, ray: &Ray) -> Option<OracleHit> {
        self.candidates(ray)
            .into_iter()
            .filter(|h| h.min_bary >= 0.0 && h.t > f64::from(ray.t_min).max(0.0) && h.t < f64::from(ray.t_max))
            .min_by(|a, b| a.t.total_cmp(&b.t))
    }

    /// Checks an accelerated closest hit against the oracle:
    /// - a reported hit must be a *possible* hit of the oracle on the same
    ///   triangle with `t` within tolerance, inside the ray interval;
    /// - no *solid* oracle hit may lie closer than the reported one by more
    ///   than the tolerance;
    /// - a miss is only allowed when the oracle has no solid hit.
    pub fn check_closest(&self, ray: &Ray, got: Option<Hit>) -> Result<(), String> {
        let cands = self.candidates(ray);
        // Hits lie at t > 0 whatever t_min (the contract of `Ray`).
        let (lo, hi) = (f64::from(ray.t_min).max(0.0), f64::from(ray.t_max));
        let solid = |h: &&OracleHit| h.min_bary >= h.bary_tol && h.t > lo + h.t_tol && h.t < hi - h.t_tol;
        match got {
            None => match cands.iter().filter(solid).min_by(|a, b| a.t.total_cmp(&b.t)) {
                Some(h) => Err(format!(
                    "missed: oracle hits triangle {} at t={} (bary margin {})",
                    h.prim, h.t, h.min_bary
                )),
                None => Ok(()),
            },
            Some(hit) => {
                if !hit.t.is_finite() || !hit.b1.is_finite() || !hit.b2.is_finite() {
                    return Err(format!("non-finite hit {hit:?}"));
                }
                let t = f64::from(hit.t);
                let Some(c) = cands.iter().find(|c| c.prim == hit.prim) else {
                    return Err(format!("hit triangle {} that the ray's line does not cross", hit.prim));
                };
                if c.min_bary < -c.bary_tol {
                    return Err(format!("hit triangle {} outside it (bary {})", hit.prim, c.min_bary));
                }
                if (c.t - t).abs() > c.t_tol {
                    return Err(format!(
                        "triangle {}: t={} but oracle t={} (tol {})",
                        hit.prim, t, c.t, c.t_tol
                    ));
                }
                if t < lo - c.t_tol || t > hi + c.t_tol {
                    return Err(format!("hit t={t} outside the ray interval ({lo}, {hi})"));
                }
                if let Some(b) = cands.iter().filter(solid).find(|b| b.t < t - b.t_tol - c.t_tol) {
                    return Err(format!(
                        "not the closest: got triangle {} at t={t}, oracle has triangle {} at t={}",
                        hit.prim, b.prim, b.t
                    ));
                }
                Ok(())
            }
        }
    }

    /// Checks an any-hit answer: `true` needs a possible hit in the
    /// interval, `false` needs no solid hit.
    pub fn check_occluded(&self, ray: &Ray, got: bool) -> Result<(), String> {
        let cands = self.candidates(ray);
        // Hits lie at t > 0 whatever t_min (the contract of `Ray`).
        let (lo, hi) = (f64::from(ray.t_min).max(0.0), f64::from(ray.t_max));
        if got {
            let possible = cands
                .iter()
                .any(|h| h.min_bary >= -h.bary_tol && h.t > lo - h.t_tol && h.t < hi + h.t_tol);
            if possible {
                Ok(())
            } else {
                Err("occluded, but the oracle finds nothing".into())
            }
        } else {
            match cands
                .iter()
                .find(|h| h.min_bary >= h.bary_tol && h.t > lo + h.t_tol && h.t < hi - h.t_tol)
            {
                Some(h) => Err(format!("not occluded, but triangle {} is hit at t={}", h.prim, h.t)),
                None => Ok(()),
            }
        }
    }
}

/// f64 Möller–Trumbore without culling or bounds: `(t, min_bary, bary_tol, t_tol)`.
fn candidate(o: DVec3, d: DVec3, of: Vec3, tri: &Triangle) -> Option<(f64, f64, f64, f64)> {
    let [v0, v1, v2] = tri.map(|v| v.as_dvec3());
    if !(v0.is_finite() && v1.is_finite() && v2.is_finite()) {
        return None;
    }
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = d.cross(e2);
    let det = e1.dot(p);
    let n = e1.cross(e2);
    let area2 = n.length();
    if area2 == 0.0 || det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = o - v0;
    let b1 = s.dot(p) * inv;
    let q = s.cross(e1);
    let b2 = d.dot(q) * inv;
    let t = e2.dot(q) * inv;
    let b0 = 1.0 - b1 - b2;
    // Error model: the f32 kernel works on coordinates of magnitude `scale`,
    // so positions are uncertain by a few ulps of `scale`. In barycentric
    // units that is `pos_err / min_altitude`; in `t` units `pos_err / |d|`,
    // magnified by 1/|cos| for grazing rays.
    let scale = [v0, v1, v2, of.as_dvec3()]
        .iter()
        .map(|v| v.abs().max_element())
        .fold(0.0, f64::max);
    let pos_err = 64.0 * f64::from(f32::EPSILON) * scale;
    let longest = e1.length().max(e2.length()).max((v2 - v1).length());
    let min_alt = area2 / longest;
    let bary_tol = 1e-5 + pos_err / min_alt;
    let cos = (det.abs() / (d.length() * area2)).max(1e-12);
    let t_tol = T_REL_TOL * t.abs() + pos_err / (d.length() * cos);
    Some((t, b0.min(b1).min(b2), bary_tol, t_tol))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_planes() -> Vec<Triangle> {
        let q = |z: f32| {
            [
                Vec3::new(-1.0, -1.0, z),
                Vec3::new(3.0, -1.0, z),
                Vec3::new(-1.0, 3.0, z),
            ]
        };
        vec![q(1.0), q(2.0)]
    }

    #[test]
    fn the_oracle_rejects_wrong_answers() {
        let tris = two_planes();
        let o = BruteForce::new(&tris);
        let ray = Ray::infinite(Vec3::ZERO, Vec3::Z);
        let near = Hit {
            t: 1.0,
            prim: 0,
            b1: 0.0,
            b2: 0.0,
        };
        assert!(o.check_closest(&ray, Some(near)).is_ok());
        // Farther triangle reported: not the closest.
        let far = Hit {
            t: 2.0,
            prim: 1,
            b1: 0.25,
            b2: 0.25,
        };
        assert!(o.check_closest(&ray, Some(far)).is_err());
        // Miss reported: missed.
        assert!(o.check_closest(&ray, None).is_err());
        // Right triangle, wrong distance.
        assert!(o.check_closest(&ray, Some(Hit { t: 1.01, ..near })).is_err());
        // NaN.
        assert!(o.check_closest(&ray, Some(Hit { t: f32::NAN, ..near })).is_err());
        // Any-hit both ways.
        assert!(o.check_occluded(&ray, true).is_ok());
        assert!(o.check_occluded(&ray, false).is_err());
        let short = Ray::new(Vec3::ZERO, Vec3::Z, 0.0, 0.5);
        assert!(o.check_occluded(&short, true).is_err());
        assert!(o.check_closest(&short, None).is_ok());
    }
}
