//! The light loop: a hit's local colour from its material and the point
//! lights, two ways with the same bits.
//!
//! One hit alone (single rays, [`light_sum`]) takes its lights four at a
//! time ([`light_terms`]); the hits of a packet ([`light_sum_lanes`]) take
//! one light at a time for four hits, so a scene with one or two lights
//! fills every lane instead of a quarter or a half of them. Both reach each
//! (light, hit) pair through the same [`terms`] and [`highlight_power_lanes`]
//! operations, and sum a hit's lights in the lights' order with the same
//! products, so every colour is the same bits either way (tested).

use glam::{Vec3, Vec3A};
use openrt_accel::{MAX_LANES, lanes_of};
use wide::f32x4;

use crate::PointLight;
use crate::highlight::{highlight_power_lanes, highlight_powers};
use crate::light_quad::{Lanes, LightQuad, light_terms, terms};
use crate::simd::LaneF32;

/// What the light loop needs of one hit.
// PERF: vectors of four lanes (`Vec3A`): a packet's hits are written with
// one store per vector and taken four at a time by a transpose
// (`lanes_of_vectors`), where three-float vectors took three stores and a load per
// component.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct LitHit {
    /// Hit point.
    pub p: Vec3A,
    /// Geometric normal facing the incoming ray.
    pub nf: Vec3A,
    /// Shading normal on the side of `nf`.
    pub ns: Vec3A,
    /// Unit direction to the eye (the incoming ray reversed).
    pub view: Vec3A,
    /// Ambient light and emission: the colour before any light.
    pub base: Vec3A,
    /// Diffuse reflectance, times the texture.
    pub kd: Vec3A,
    /// Specular reflectance.
    pub specular: Vec3A,
    /// The highlight's exponent.
    pub shininess: f32,
    /// The base at or below which the highlight's power is exactly zero
    /// (`highlight::zero_power_below` of `shininess`).
    pub floor: f32,
    /// Whether the material has Phong highlights.
    pub highlights: bool,
}

/// The colour of `hit` lit by `lights` (laid out in `quads`), light `j`
/// left out where `blocked(j)`: four lights at a time.
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn light_sum(
    lights: &[PointLight],
    quads: &[LightQuad],
    hit: &LitHit,
    blocked: impl Fn(usize) -> bool,
) -> Vec3 {
    // PERF: the sums stay in the lights' order, three channels to a
    // register (`Vec3A`: the same products and sums).
    let (kd, specular) = (hit.kd, hit.specular);
    let mut color = hit.base;
    let (p, nf, ns, view) = (hit.p.into(), hit.nf.into(), hit.ns.into(), hit.view.into());
    for (q, quad) in quads.iter().enumerate() {
        let terms = light_terms(quad, p, nf, ns, view);
        // PERF: the four lights' highlight powers in one pass, no call
        // (`highlight.rs`), and none when every lit light's power would
        // be exactly zero: its base at most the material's floor
        // (`zero_power_below`; 0, facing away, when it has none). The
        // floor made kitchen GL-like frames 1.5-4% faster.
        let power = if hit.highlights {
            highlight_powers(f32x4::from(terms.rdv), terms.lit, hit.shininess, hit.floor)
        } else {
            [0.0; 4]
        };
        for i in lanes_of(terms.lit) {
            let j = 4 * q + i;
            if blocked(j) {
                continue;
            }
            let mut c = kd * terms.ndl[i].max(0.0);
            if hit.highlights {
                c += specular * power[i];
            }
            color += Vec3A::from(lights[j].color) * c;
        }
    }
    Vec3::from(color)
}

/// What the light loop needs of [`LaneF32::LANES`] hits, one hit to a lane
/// (the fields of [`LitHit`]).
#[derive(Clone, Copy)]
pub(crate) struct LitLanes<F> {
    /// Hit points.
    pub p: Lanes<F>,
    /// Geometric normals facing the incoming rays.
    pub nf: Lanes<F>,
    /// Shading normals on the side of `nf`.
    pub ns: Lanes<F>,
    /// Unit directions to the eye.
    pub view: Lanes<F>,
    /// Ambient light and emission.
    pub base: Lanes<F>,
    /// Diffuse reflectance, times the texture.
    pub kd: Lanes<F>,
    /// Specular reflectance.
    pub specular: Lanes<F>,
    /// The highlights' exponents.
    pub shininess: F,
    /// The bases at or below which the highlights' powers are exactly zero.
    pub floor: F,
    /// The lanes whose material has Phong highlights.
    pub bright: u32,
}

impl<F: LaneF32> LitLanes<F> {
    /// The first [`LaneF32::LANES`] of `hits`, one to a lane.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub fn of(hits: &[LitHit]) -> Self {
        let hits = &hits[..F::LANES];
        // NOTE: no closure makes lanes (simd.rs): `transposed` is inlined.
        Self {
            p: Lanes::transposed(|i| hits[i].p),
            nf: Lanes::transposed(|i| hits[i].nf),
            ns: Lanes::transposed(|i| hits[i].ns),
            view: Lanes::transposed(|i| hits[i].view),
            base: Lanes::transposed(|i| hits[i].base),
            kd: Lanes::transposed(|i| hits[i].kd),
            specular: Lanes::transposed(|i| hits[i].specular),
            shininess: F::from_fn(|i| hits[i].shininess),
            floor: F::from_fn(|i| hits[i].floor),
            bright: hits
                .iter()
                .enumerate()
                .fold(0, |m, (i, h)| m | (u32::from(h.highlights) << i)),
        }
    }
}

/// [`light_sum`] of up to [`LaneF32::LANES`] hits at once (four with
/// `f32x4`, eight with the AVX2 type), written to `out[i]` for `hits[i]`
/// where `lanes` has bit `i` (the other lanes' colours are not written);
/// `blocked(j)` gives the lanes whose shadow ray towards light `j` is
/// blocked. One light at a time, the hits one to a lane: lanes of
/// different materials are masked, not taken apart.
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn light_sum_lanes<F: LaneF32>(
    lights: &[PointLight],
    hits: &[LitHit],
    lanes: u32,
    blocked: impl Fn(usize) -> u32,
    out: &mut [Vec3],
) {
    let color = light_sum_of_lanes(lights, &LitLanes::<F>::of(hits), lanes, blocked);
    write_colors(&color, lanes, out);
}

/// `out[i]` of the lanes `i` of `color` that `lanes` has.
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn write_colors<F: LaneF32>(color: &Lanes<F>, lanes: u32, out: &mut [Vec3]) {
    let mut xyz = [[0.0; MAX_LANES]; 3];
    color.x.write_to(&mut xyz[0]);
    color.y.write_to(&mut xyz[1]);
    color.z.write_to(&mut xyz[2]);
    for i in lanes_of(lanes) {
        out[i] = Vec3::new(xyz[0][i], xyz[1][i], xyz[2][i]);
    }
}

/// [`light_sum_lanes`] of hits already in lanes: their colours, one to a
/// lane (the lanes outside `lanes` hold any value).
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn light_sum_of_lanes<F: LaneF32>(
    lights: &[PointLight],
    hits: &LitLanes<F>,
    lanes: u32,
    blocked: impl Fn(usize) -> u32,
) -> Lanes<F> {
    let LitLanes {
        p,
        nf,
        ns,
        view,
        base,
        kd,
        specular,
        shininess,
        floor,
        bright,
    } = *hits;
    let mut color = base;
    let bright = bright & lanes;
    let bright_mask = F::mask(bright);
    for (j, light) in lights.iter().enumerate() {
        let (ok, ndl, rdv) = terms(&Lanes::splat(light.position), &p, &nf, &ns, &view);
        let lit = ok.bitmask() & lanes & !blocked(j);
        if lit == 0 {
            continue;
        }
        // `f32::max(ndl, 0.0)`: `maxps` gives its second operand for a
        // NaN; a zero's sign may differ, which no sum below shows (every
        // term is added to a colour that is +0 or more).
        let cos = ndl.max_fast(F::splat(0.0));
        let mut c = Lanes {
            x: kd.x * cos,
            y: kd.y * cos,
            z: kd.z * cos,
        };
        if bright & lit != 0 {
            // As in `highlight_powers`: the powers only when some lit
            // lane's base lies above its floor; zeros (their exact value) otherwise.
            let power = if rdv.gt(floor).bitmask() & bright & lit != 0 {
                highlight_power_lanes(rdv, shininess)
            } else {
                F::splat(0.0)
            };
            let lit_c = Lanes {
                x: c.x + specular.x * power,
                y: c.y + specular.y * power,
                z: c.z + specular.z * power,
            };
            c = Lanes::select(bright_mask, &lit_c, &c);
        }
        let (m, lc) = (F::mask(lit), light.color);
        let sum = Lanes {
            x: color.x + F::splat(lc.x) * c.x,
            y: color.y + F::splat(lc.y) * c.y,
            z: color.z + F::splat(lc.z) * c.z,
        };
        color = Lanes::select(m, &sum, &color);
    }
    color
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::highlight::zero_power_below;
    use crate::light_quad::light_quads;
    use crate::light_quad::tests::unit;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    fn colour(rng: &mut SmallRng) -> Vec3 {
        match rng.random_range(0..4) {
            0 => Vec3::ZERO,
            1 => Vec3::splat(rng.random_range(0.0..1.0)),
            _ => Vec3::new(
                rng.random_range(0.0..1.0),
                rng.random_range(0.0..1.0),
                rng.random_range(0.0..1.0),
            ),
        }
    }

    /// A random hit: materials with and without highlights or diffuse
    /// light, shininess from the kitchen's to extremes, normals that agree
    /// or not, and lights near, far, behind and at the hit point.
    fn hit(rng: &mut SmallRng, lights: &[PointLight]) -> LitHit {
        let p = match rng.random_range(0..5) {
            0 => lights[rng.random_range(0..lights.len())].position,
            _ => unit(rng) * rng.random_range(0.0..3.0),
        };
        let nf = unit(rng);
        let ns = if rng.random_bool(0.3) { nf } else { unit(rng) };
        let shininess = match rng.random_range(0..4) {
            0 => 97.4304,
            1 => 0.0,
            _ => 10f32.powf(rng.random_range(-1.0..3.5)),
        };
        let specular = colour(rng);
        LitHit {
            p: p.into(),
            nf: nf.into(),
            ns: ns.into(),
            view: unit(rng).into(),
            base: colour(rng).into(),
            kd: colour(rng).into(),
            specular: specular.into(),
            shininess,
            floor: zero_power_below(shininess),
            highlights: shininess > 0.0 && specular != Vec3::ZERO,
        }
    }

    /// Four hits at a time (`f32x4`) and, on a CPU with AVX2, eight (the
    /// AVX2 type, run where the renderer runs it: in code compiled for
    /// AVX2) are each hit's own light loop bit for bit, with any lanes
    /// present and any shadow rays blocked, for 1 to 9 lights.
    #[test]
    fn hits_four_and_eight_at_a_time_are_each_hits_own_sum() {
        #[cfg(target_arch = "x86_64")]
        let avx2 = openrt_accel::avx2();
        #[cfg(not(target_arch = "x86_64"))]
        let avx2 = false;
        let mut rng = SmallRng::seed_from_u64(0x4c_6f6f70);
        let mut lit = 0;
        for round in 0..4_000 {
            let count = 1 + round % 9;
            let lights: Vec<PointLight> = (0..count)
                .map(|_| PointLight {
                    position: unit(&mut rng) * rng.random_range(0.0..4.0),
                    color: colour(&mut rng) * 2.0,
                })
                .collect();
            let quads = light_quads(&lights);
            let hits: [LitHit; 8] = std::array::from_fn(|_| hit(&mut rng, &lights));
            let lanes = rng.random_range(1..256u32);
            let blocked: Vec<u32> = (0..count)
                .map(|_| rng.random_range(0..256u32) & rng.random_range(0..256u32))
                .collect();
            let mut fours = [Vec3::NAN; 8];
            for c in 0..2 {
                let shifted = |m: u32| (m >> (4 * c)) & 0xf;
                light_sum_lanes::<f32x4>(
                    &lights,
                    &hits[4 * c..],
                    shifted(lanes),
                    |j| shifted(blocked[j]),
                    &mut fours[4 * c..],
                );
            }
            let mut eights = fours;
            #[cfg(target_arch = "x86_64")]
            if avx2 {
                eights = [Vec3::NAN; 8];
                // SAFETY: the CPU has AVX2 (detected).
                unsafe { eight_at_a_time(&lights, &hits, lanes, &blocked, &mut eights) };
            }
            for i in lanes_of(lanes) {
                let want = light_sum(&lights, &quads, &hits[i], |j| blocked[j] & (1 << i) != 0);
                for (got, width) in [(fours[i], 4), (eights[i], 8)] {
                    assert_eq!(
                        want.to_array().map(f32::to_bits),
                        got.to_array().map(f32::to_bits),
                        "round {round}, {width} lanes, lane {i}: {:?}",
                        hits[i]
                    );
                }
                lit += usize::from(want != Vec3::from(hits[i].base));
            }
        }
        // Most hits are lit by something.
        assert!(lit > 3_000, "{lit} lit hits");
    }

    /// The light loop eight hits at a time, compiled for AVX2 as the
    /// renderer's shading is.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn eight_at_a_time(lights: &[PointLight], hits: &[LitHit; 8], lanes: u32, blocked: &[u32], out: &mut [Vec3; 8]) {
        light_sum_lanes::<crate::simd::F32x8>(lights, hits, lanes, |j| blocked[j], out);
    }
}
