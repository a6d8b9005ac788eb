//! Rays with the per-ray constants that the kernels need.

use glam::Vec3;

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
#[derive(Clone, Copy, Debug, PartialEq)]
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
    /// Index of the dominant direction component (the shear's z axis), then x, y.
    pub(crate) kz: usize,
    pub(crate) kx: usize,
    pub(crate) ky: usize,
    /// Shear constants `(Sx, Sy, Sz)` of the watertight test.
    pub(crate) shear: Vec3,
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
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding of the projected triangle: swap when dir[kz] < 0.
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let dz = dir[kz];
        let valid = dz != 0.0 && dir.is_finite() && origin.is_finite();
        let shear = if valid {
            Vec3::new(dir[kx] / dz, dir[ky] / dz, 1.0 / dz)
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
            kz,
            kx,
            ky,
            shear,
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

    #[test]
    fn shear_axis_follows_the_dominant_component_and_keeps_winding() {
        let r = Ray::infinite(Vec3::ZERO, Vec3::new(0.1, -3.0, 0.5));
        assert_eq!(r.kz, 1);
        // dir[kz] < 0 swaps kx and ky.
        assert_eq!((r.kx, r.ky), (0, 2));
        assert!((r.shear.z + 1.0 / 3.0).abs() < 1e-7);
    }
}
