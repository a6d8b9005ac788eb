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

/// `x` moved `k` representable values up (`k > 0`) or down (`k < 0`),
/// saturating at the infinities; NaN stays NaN. The value `k` calls of
/// `f32::next_up` (or `next_down`) give, except that a zero result is +0.0.
///
/// PERF: floats ordered as integers (both zeros at 0), one add: the loop of
/// `next_up`/`next_down` calls cost ~390 instructions per world box of an
/// instance (4 ulps, 6 sides), a third of a 10k-instance commit's record pass.
#[inline]
#[must_use]
pub(crate) fn step_ulps(x: f32, k: i32) -> f32 {
    const INF: i32 = 0x7F80_0000;
    if x.is_nan() {
        return x;
    }
    // NOTE: the sign-magnitude bits, read as `i32`, map onto a line on which
    // -0.0 and +0.0 both sit at 0 and the order is the floats' order.
    let order = |b: i32| if b < 0 { i32::MIN - b } else { b };
    let key = order(x.to_bits().cast_signed()).saturating_add(k).clamp(-INF, INF);
    f32::from_bits(order(key).cast_unsigned())
}

#[cfg(test)]
mod step_tests {
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    use super::step_ulps;

    #[test]
    fn stepping_ulps_matches_next_up_and_next_down() {
        let mut v = vec![
            0.0,
            -0.0,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1.0,
            -1.0,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1e6,
            -3.5e-3,
        ];
        let mut rng = SmallRng::seed_from_u64(0x2545_F491);
        v.extend((0..2_000).map(|_| f32::from_bits(rng.random())));
        for x in v {
            for k in 0..6 {
                let (mut up, mut down) = (x, x);
                for _ in 0..k {
                    up = up.next_up();
                    down = down.next_down();
                }
                for (got, want) in [(step_ulps(x, k), up), (step_ulps(x, -k), down)] {
                    let same = if want == 0.0 {
                        got.to_bits() == 0
                    } else {
                        got.to_bits() == want.to_bits() || got.is_nan() && want.is_nan()
                    };
                    assert!(same, "{x:e} ({:#x}) by {k}: {got:e} against {want:e}", x.to_bits());
                }
            }
        }
    }
}
