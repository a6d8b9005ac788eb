//! The light loop's geometry for four point lights at once.
//!
//! A hit is lit by each light through the same few products: the unit
//! direction to the light, its side of the surface, `n·l` and the mirrored
//! light direction against the view. The lights are fixed for a frame, so
//! they are laid out four to a register once, and a hit's own values are
//! broadcast: four lights cost one square root, one division and one pass
//! of products, with no gathering. Each lane performs the scalar code's
//! operations in its order (no fused multiply-add), so every value is the
//! bits of its scalar twin, `light_terms_scalar` in the tests.

use glam::{Vec3, Vec3A};
use wide::f32x4;

use crate::PointLight;
use crate::simd::LaneF32;

/// Four lights' positions, one lane each; lanes past the last light hold
/// the origin and are masked off.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LightQuad {
    x: f32x4,
    y: f32x4,
    z: f32x4,
    /// One bit per lane that holds a light.
    lanes: u32,
}

/// What the light loop needs of one hit for four lights: `lit` has bit `i`
/// set when light `i` of the quad lies on the side the ray arrives from
/// (and not at the hit point); then `ndl[i]` is `n_s · l` and `rdv[i]` is
/// the mirrored light direction against the view (before clamping).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LightTerms {
    pub lit: u32,
    pub ndl: [f32; 4],
    pub rdv: [f32; 4],
}

/// The lights laid out four to a [`LightQuad`].
pub(crate) fn light_quads(lights: &[PointLight]) -> Vec<LightQuad> {
    lights
        .chunks(4)
        .map(|c| {
            let lane = |a: usize| f32x4::from(std::array::from_fn(|i| c.get(i).map_or(0.0, |l| l.position[a])));
            LightQuad {
                x: lane(0),
                y: lane(1),
                z: lane(2),
                lanes: (1 << c.len()) - 1,
            }
        })
        .collect()
}

/// The light terms of a hit at `p` (facing normal `nf`, shading normal
/// `ns`, unit direction to the eye `view`) for the lights of `q`.
#[inline]
pub(crate) fn light_terms(q: &LightQuad, p: Vec3, nf: Vec3, ns: Vec3, view: Vec3) -> LightTerms {
    let s = |v: Vec3| Lanes::splat(v);
    let (ok, ndl, rdv) = terms(&Lanes { x: q.x, y: q.y, z: q.z }, &s(p), &s(nf), &s(ns), &s(view));
    LightTerms {
        lit: ok.to_bitmask() & q.lanes,
        ndl: ndl.to_array(),
        rdv: rdv.to_array(),
    }
}

/// Three coordinates of four (or [`LaneF32::LANES`]) vectors, one lane each.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Lanes<F = f32x4> {
    pub x: F,
    pub y: F,
    pub z: F,
}

impl<F: LaneF32> Lanes<F> {
    /// One vector in every lane.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub fn splat(v: Vec3) -> Self {
        Self {
            x: F::splat(v.x),
            y: F::splat(v.y),
            z: F::splat(v.z),
        }
    }

    /// Lanes where `m` is set from `a`, the others from `b`.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub fn select(m: F, a: &Self, b: &Self) -> Self {
        Self {
            x: m.select(a.x, b.x),
            y: m.select(a.y, b.y),
            z: m.select(a.z, b.z),
        }
    }

    /// The vectors `v(i)`, one to a lane.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub fn transposed(v: impl Fn(usize) -> Vec3A) -> Self {
        let [x, y, z] = F::transpose(v);
        Self { x, y, z }
    }
}

impl Lanes {
    /// Four vectors, one to a lane.
    #[inline]
    pub fn from_vecs(v: [Vec3; 4]) -> Self {
        Self {
            x: f32x4::from(v.map(|v| v.x)),
            y: f32x4::from(v.map(|v| v.y)),
            z: f32x4::from(v.map(|v| v.z)),
        }
    }
}

/// The light terms of four (light, hit) pairs, one to a lane: lights at
/// `light`, hits at `p` with facing normals `nf`, shading normals `ns` and
/// unit directions to the eye `view`. Returns the lit lanes as a mask, `n·l`
/// and `r·v`. Four lights of one hit ([`light_terms`]) and one light of four
/// hits (the lane-parallel light loop) both come here, so every lane is the
/// same sequence of operations either way.
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn terms<F: LaneF32>(
    light: &Lanes<F>,
    p: &Lanes<F>,
    nf: &Lanes<F>,
    ns: &Lanes<F>,
    view: &Lanes<F>,
) -> (F, F, F) {
    let s = F::splat;
    let (lit, Lanes { x: lx, y: ly, z: lz }) = towards(light, p, nf);
    let ndl = ns.x * lx + ns.y * ly + ns.z * lz;
    // `reflect(-l, ns)`: `d - (2 * d·n) * n` with `d = -l`.
    let (dx, dy, dz) = (-lx, -ly, -lz);
    let k = s(2.0) * (dx * ns.x + dy * ns.y + dz * ns.z);
    let (rx, ry, rz) = (dx - k * ns.x, dy - k * ns.y, dz - k * ns.z);
    let rdv = rx * view.x + ry * view.y + rz * view.z;
    (lit, ndl, rdv)
}

/// The lanes whose light at `light` lies on the side of the facing normal
/// `nf` at hit points `p` (and not at the point), as a mask, and the unit
/// directions to the light: the shading's `lit_side` (`try_normalize`,
/// then `l·nf > 0`) four lanes at a time, its operations in its order.
/// The light loop ([`terms`]) and the shadow rays' set-up both decide here.
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn towards<F: LaneF32>(light: &Lanes<F>, p: &Lanes<F>, nf: &Lanes<F>) -> (F, Lanes<F>) {
    let s = F::splat;
    // The direction to the light, normalized as `Vec3::try_normalize` does:
    // `((x*x + y*y) + z*z)`, a square root, `1 / len`, then three products.
    let (tx, ty, tz) = (light.x - p.x, light.y - p.y, light.z - p.z);
    let rcp = s(1.0) / (tx * tx + ty * ty + tz * tz).sqrt();
    // `rcp.is_finite() && rcp > 0.0`; a NaN fails both compares.
    let ok = rcp.gt(s(0.0)) & rcp.lt(s(f32::INFINITY));
    let (lx, ly, lz) = (tx * rcp, ty * rcp, tz * rcp);
    let facing = (lx * nf.x + ly * nf.y + lz * nf.z).gt(s(0.0));
    (ok & facing, Lanes { x: lx, y: ly, z: lz })
}

/// The scalar twin of [`light_terms`] for one light: `Some((n·l, r·v))`
/// when the light lies on the lit side, with glam's vector operations.
#[cfg(test)]
pub(crate) fn light_terms_scalar(light: Vec3, p: Vec3, nf: Vec3, ns: Vec3, view: Vec3) -> Option<(f32, f32)> {
    let l = (light - p).try_normalize().filter(|l| l.dot(nf) > 0.0)?;
    let d = -l;
    let r = d - 2.0 * d.dot(ns) * ns;
    Some((ns.dot(l), r.dot(view)))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// A random unit vector (the light loop's tests share it).
    pub(crate) fn unit(rng: &mut SmallRng) -> Vec3 {
        loop {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if let Some(u) = v.try_normalize() {
                return u;
            }
        }
    }

    /// Every lane is the scalar twin's bits, on random hits and on the hard
    /// cases: a light at the hit point, in the surface's plane, behind it,
    /// far away and very close (a squared distance that underflows), and NaN
    /// or infinite positions.
    #[test]
    fn four_lights_at_once_are_the_scalar_terms() {
        let mut rng = SmallRng::seed_from_u64(0x11_6475);
        let mut lit = 0;
        for round in 0..20_000 {
            // Every fifth round near the origin, where a light 1e-30 away
            // leaves a squared length that underflows (an infinite `1 / len`).
            let scale = if round % 5 == 4 {
                1e-25
            } else {
                10f32.powi(rng.random_range(-6..7))
            };
            let p = unit(&mut rng) * rng.random_range(0.0..2.0) * scale;
            let nf = unit(&mut rng);
            let ns = if round % 3 == 0 { nf } else { unit(&mut rng) };
            let view = unit(&mut rng);
            let count = 1 + round % 7;
            let lights: Vec<PointLight> = (0..count)
                .map(|i| {
                    let position = match (round + i) % 11 {
                        0 => p,
                        1 => p + nf.any_orthonormal_vector() * scale,
                        2 => p - nf * scale,
                        3 => p + Vec3::splat(f32::NAN),
                        4 => Vec3::new(f32::INFINITY, 0.0, 0.0),
                        5 => p + unit(&mut rng) * 1e-30,
                        6 => p + unit(&mut rng) * 1e30,
                        _ => p + unit(&mut rng) * rng.random_range(0.0..3.0) * scale,
                    };
                    PointLight {
                        position,
                        color: Vec3::ONE,
                    }
                })
                .collect();
            for (qi, q) in light_quads(&lights).iter().enumerate() {
                let t = light_terms(q, p, nf, ns, view);
                for i in 0..4 {
                    let Some(light) = lights.get(qi * 4 + i) else {
                        assert_eq!(t.lit & (1 << i), 0, "round {round}: a lane without a light is lit");
                        continue;
                    };
                    let want = light_terms_scalar(light.position, p, nf, ns, view);
                    let got = (t.lit & (1 << i) != 0).then(|| (t.ndl[i], t.rdv[i]));
                    assert_eq!(
                        want.map(|(a, b)| (a.to_bits(), b.to_bits())),
                        got.map(|(a, b)| (a.to_bits(), b.to_bits())),
                        "round {round}, light {}: {light:?} from {p}",
                        qi * 4 + i
                    );
                    lit += usize::from(want.is_some());
                }
            }
        }
        // The sweep reaches both answers.
        assert!(lit > 10_000, "{lit} lit lanes");
    }
}
