//! Floating-point error bounds.

/// The machine epsilon of `f32` halved (unit roundoff).
pub(crate) const UNIT_ROUNDOFF: f32 = f32::EPSILON * 0.5;

/// `gamma(n) = n u / (1 - n u)`, the bound on the relative error of `n`
/// consecutive rounded operations (Higham; used by pbrt and Woop et al. 2013).
#[inline]
pub(crate) const fn gamma(n: u32) -> f32 {
    let nu = n as f32 * UNIT_ROUNDOFF;
    nu / (1.0 - nu)
}
