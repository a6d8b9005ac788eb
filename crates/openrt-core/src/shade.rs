//! Whitted ray tracing and the "OpenGL-like" local shading mode.

use glam::{Vec2, Vec3, Vec3A};
use openrt_accel::{MAX_LANES, Ray, lanes_mask, lanes_of, rays_from_lanes, sign_groups};
use wide::f32x4;

use crate::highlight::{highlight_powers, log2_above_one};
use crate::light_loop::{LitHit, LitLanes, light_sum, light_sum_lanes, light_sum_of_lanes, write_colors};
use crate::light_quad::{Lanes, LightQuad, light_terms, towards};
use crate::occluder_hint::OccluderHint;
use crate::phases::{Phase, PhaseClock};
use crate::simd::LaneF32;
use crate::surface_lanes::Facing;
use crate::surface_lanes::MAX_SURFACE_LANES;
use crate::surface_lanes::{SurfaceLanes, dot as dot_lanes, vectors};
use crate::tracer::Tracer;
use crate::{Environment, MaterialId, PointLight, Scene, SceneHit, Surface, TextureFilter};

/// What a frame computes per pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum RenderMode {
    /// Primary rays and local Phong shading from every light, no shadows:
    /// the paper's "OpenGL-like" mode.
    GlLike,
    /// Full Whitted ray tracing: shadow rays to every light, reflection and
    /// refraction (with total internal reflection) up to a depth.
    #[default]
    Whitted,
}

/// Rays traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera rays.
    pub primary: u64,
    /// Rays towards lights.
    pub shadow: u64,
    /// Mirror rays (total internal reflection included).
    pub reflection: u64,
    /// Transmitted rays.
    pub refraction: u64,
}

impl RayCounts {
    /// All rays.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.primary + self.shadow + self.reflection + self.refraction
    }

    /// One bounce of kind `k` (0 refraction, 1 reflection) counted when it
    /// was made and then left untraced ([`MIN_RAY_WEIGHT`]).
    fn untrace(&mut self, k: usize) {
        if k == 0 {
            self.refraction -= 1;
        } else {
            self.reflection -= 1;
        }
    }

    /// Adds another count.
    pub fn add(&mut self, o: &Self) {
        self.primary += o.primary;
        self.shadow += o.shadow;
        self.reflection += o.reflection;
        self.refraction += o.refraction;
    }
}

/// Ulps by which a secondary ray's origin is moved off the surface.
///
/// NOTE: Wächter & Binder use 256. Here the hit point is interpolated from
/// world-space vertices (error: a few ulps of the largest coordinate), and
/// the kernel rejects hits within their own rounding error of `t = 0`, so
/// 16 ulps is a margin of 4 or more. 256 ulps is 16 units at 1e6, more than
/// a unit-sized scene: shadows and reflections vanish there (measured).
pub const OFFSET_ULPS: f32 = 16.0;

/// Moves `p` off the surface along `n` (the side the new ray leaves on) by
/// an amount that scales with the magnitude of the hit point. After Wächter
/// & Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray
/// Tracing Gems, ch. 6, 2019: each coordinate moves by [`OFFSET_ULPS`] ulps
/// in integer space; a coordinate close to zero instead moves by an absolute
/// amount of the same number of ulps of `scale`.
///
/// NOTE: the paper's "close to zero" threshold (1/32) and absolute offset
/// (1/65536) assume scenes of unit size; here both are relative to `scale`,
/// the magnitude of the coordinates the hit point was computed from (the
/// largest |coordinate| of the triangle's world vertices and of `p`), so a
/// scene scaled by 1e-4 or 1e5 is offset exactly as the unit-sized one.
#[must_use]
pub fn offset_ray_origin(p: Vec3, n: Vec3, scale: f32) -> Vec3 {
    let scale = scale.max(p.abs().max_element()).max(f32::MIN_POSITIVE);
    let origin = scale / 32.0;
    let float_offset = OFFSET_ULPS * scale * f32::EPSILON;
    let mut out = p;
    for a in 0..3 {
        if p[a].abs() < origin {
            out[a] = p[a] + float_offset * n[a];
        } else {
            let of = (OFFSET_ULPS * n[a]) as i32;
            let bits = p[a].to_bits() as i32;
            let moved = if p[a] < 0.0 { bits - of } else { bits + of };
            out[a] = f32::from_bits(moved as u32);
        }
    }
    out
}

/// [`offset_ray_origin`] lane by lane for points `p`, normals `n` and
/// scales `scale` that are all finite (the same operations: the largest
/// magnitude, the threshold near zero, the float step there and the
/// integer step elsewhere): the same bits (tested).
#[allow(clippy::inline_always)]
#[inline(always)]
fn offset_lanes<F: LaneF32>(p: &Lanes<F>, n: &Lanes<F>, scale: F) -> Lanes<F> {
    // NOTE: every operand of these maxima is +0 or more and finite, where
    // `maxps` is `f32::max`.
    let largest = p.x.abs().max_fast(p.y.abs().max_fast(p.z.abs()));
    let scale = scale.max_fast(largest).max_fast(F::splat(f32::MIN_POSITIVE));
    let origin = scale / F::splat(32.0);
    let float_offset = F::splat(OFFSET_ULPS) * scale * F::splat(f32::EPSILON);
    Lanes {
        x: offset_axis(p.x, n.x, origin, float_offset),
        y: offset_axis(p.y, n.y, origin, float_offset),
        z: offset_axis(p.z, n.z, origin, float_offset),
    }
}

/// One coordinate of [`offset_lanes`].
#[allow(clippy::inline_always)]
#[inline(always)]
fn offset_axis<F: LaneF32>(p: F, n: F, origin: F, float_offset: F) -> F {
    let near = p.abs().lt(origin);
    let moved = p + float_offset * n;
    // `(16 n) as i32`: |16 n| <= 16 for a unit or zero normal.
    let of = (F::splat(OFFSET_ULPS) * n).trunc_int();
    let bits = p.to_bits();
    let stepped = p
        .lt(F::splat(0.0))
        .select(F::from_bits(bits - of), F::from_bits(bits + of));
    near.select(moved, stepped)
}

/// The origins of rays leaving hit points `p` on the side of `n`
/// ([`offset_ray_origin`]) in the lanes `lanes`: in lanes where every input
/// is finite ([`offset_lanes`]), one lane at a time otherwise.
#[allow(clippy::inline_always)]
#[inline(always)]
fn offset_origins<F: LaneF32>(p: &Lanes<F>, n: &Lanes<F>, scale: F, lanes: u32) -> Lanes<F> {
    // NOTE: no closure holds lane arithmetic (simd.rs).
    let inf = F::splat(f32::INFINITY);
    let all = p.x.abs().lt(inf)
        & p.y.abs().lt(inf)
        & p.z.abs().lt(inf)
        & n.x.abs().lt(inf)
        & n.y.abs().lt(inf)
        & n.z.abs().lt(inf)
        & scale.abs().lt(inf);
    if all.bitmask() & lanes == lanes {
        return offset_lanes(p, n, scale);
    }
    let (pv, nv) = (vectors(p), vectors(n));
    let mut sv = [0.0; MAX_SURFACE_LANES];
    scale.write_to(&mut sv);
    Lanes::transposed(|i| offset_ray_origin(pv[i], nv[i], sv[i]).into())
}

/// The shadow ray from `from` towards a point light at `light`, ending just
/// short of it (the interval `[0, SHADOW_RAY_END]` of `light - from`).
// PERF: the ray built in place (`Ray::new_inline`): kitchen Whitted frames
// 1.7% faster.
#[inline]
fn towards_light(from: Vec3, light: Vec3) -> Ray {
    Ray::new_inline(from, light - from, 0.0, SHADOW_RAY_END)
}

/// Where a shadow ray's interval ends, in units of `light - from`: just
/// short of the light, so that the light's own position never blocks it.
const SHADOW_RAY_END: f32 = 1.0 - 1e-4;

/// The shadow ray from `ray`'s first hit in `scene` towards a point light at
/// `light`, as Whitted mode makes it: from the hit point moved off the
/// surface on the side the ray arrives from (without passing one-sided
/// back faces); from `ray`'s origin when it hits nothing. For measuring a
/// frame's shadow rays without shading it (`openrt bench`, profiling probes).
#[must_use]
pub fn first_hit_shadow_ray(scene: &Scene, ray: &Ray, light: Vec3) -> Ray {
    let from = scene
        .intersect(ray)
        .and_then(|h| scene.surface(ray, &h).ok())
        .map_or(ray.origin, |s| {
            let n = if s.geometric_normal.dot(ray.dir) > 0.0 {
                -s.geometric_normal
            } else {
                s.geometric_normal
            };
            offset_ray_origin(s.point, n, s.error_scale)
        });
    towards_light(from, light)
}

/// Per-frame shading state.
pub(crate) struct Shader<'a, T: Tracer = Scene> {
    pub scene: &'a Scene,
    /// Finds the hits: the scene's own kd-trees, or a peer.
    pub tracer: &'a T,
    pub env: &'a Environment,
    pub mode: RenderMode,
    pub max_depth: u32,
    pub filter: TextureFilter,
    pub counts: RayCounts,
    /// The last occluder of each light (shadow cache), emptied per tile.
    pub occluders: Vec<OccluderHint>,
    /// The lights four to a register, for the light loop.
    pub light_quads: Vec<LightQuad>,
    /// Per material, the base at or below which its highlight power is
    /// exactly zero (`highlight::zero_power_below`).
    pub zero_power: Vec<f32>,
    /// Bit `j`: light `j` (of the first 64) has a finite colour, so a zero
    /// times it is a zero ([`Shader::silent_lights`]).
    pub finite_lights: u64,
    /// The time by phase, when the renderer asks for it.
    pub clock: PhaseClock,
    /// Whitted packets stay in lanes ([`Shader::shade_whitted_lanes`]): no
    /// material of the scene is one-sided or has an emission texture.
    whitted_lanes: bool,
}

impl<'a, T: Tracer> Shader<'a, T> {
    /// A frame's shader: what it needs of the lights and materials made
    /// once (light quads, highlight floors, finite light colours), no ray
    /// counted yet, every light's last occluder empty.
    pub fn new(
        scene: &'a Scene,
        tracer: &'a T,
        env: &'a Environment,
        mode: RenderMode,
        max_depth: u32,
        filter: TextureFilter,
    ) -> Self {
        Self {
            scene,
            tracer,
            env,
            mode,
            max_depth,
            filter,
            counts: RayCounts::default(),
            occluders: vec![OccluderHint::new(); env.lights.len()],
            light_quads: crate::light_quad::light_quads(&env.lights),
            zero_power: scene
                .materials()
                .iter()
                .map(|m| crate::highlight::zero_power_below(m.shininess))
                .collect(),
            finite_lights: env
                .lights
                .iter()
                .take(64)
                .enumerate()
                .fold(0, |m, (j, l)| m | (u64::from(l.color.is_finite()) << j)),
            clock: PhaseClock::default(),
            whitted_lanes: scene
                .materials()
                .iter()
                .all(|m| !m.one_sided && m.emission_texture.is_none()),
        }
    }
}

/// A ray cone (Akenine-Möller et al., "Texture Level of Detail Strategies
/// for Real-Time Ray Tracing", Ray Tracing Gems, 2019): the width of the
/// footprint at the ray's origin and its spread angle. Primary rays start
/// with width 0 and the angle of one pixel (or of one sample); at a hit the
/// width grows by `spread * distance`, and reflection and refraction rays
/// carry the width on with the same spread (surfaces are taken as flat:
/// their curvature does not widen the cone).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Cone {
    pub width: f32,
    pub spread: f32,
}

impl Cone {
    /// The cone's width where `ray` reaches `t`.
    #[inline]
    fn width_at(self, ray: &Ray, t: f32) -> f32 {
        self.width_for(t, ray.dir.length())
    }

    /// [`Cone::width_at`] for a ray whose direction has length `len`.
    #[inline]
    fn width_for(self, t: f32, len: f32) -> f32 {
        self.width + self.spread * t * len
    }
}

/// How many back sides of one-sided surfaces a ray may pass before it gives up.
const MAX_PASS_THROUGH: u32 = 16;

/// A primary or secondary hit made ready for shading: everything the light
/// loop and the bounces need, computed once. Splitting shading here lets a
/// packet of pixels trace its shadow rays together between [`Shader::prepare`]
/// and [`Shader::finish_as`], with the same arithmetic as one pixel alone.
pub(crate) struct Prepared {
    surf: Surface,
    /// Unit direction of the incoming ray.
    d: Vec3,
    /// `true` when the ray arrives at the back of the geometric normal.
    back: bool,
    /// Geometric normal facing the incoming ray.
    nf: Vec3,
    /// Shading normal on the side of `nf`.
    ns: Vec3,
    /// Origin of rays leaving on the incoming side (shadow and mirror rays;
    /// the hit point itself in GL-like mode, which traces none).
    p_out: Vec3,
    /// The ray cone at the hit: its footprint, and the cone of the bounces.
    cone: Cone,
    /// Bit `j`: light `j` adds exactly nothing to this hit's colour, lit or
    /// not, so its shadow ray need not be traced ([`Shader::silent_lights`]).
    silent: u64,
}

impl<T: Tracer> Shader<'_, T> {
    /// Radiance along `ray` with its cone (`depth` = number of bounces so far).
    pub fn trace(&mut self, ray: &Ray, cone: Cone, depth: u32) -> Vec3 {
        self.trace_weighted(ray, cone, depth, Vec3::ONE)
    }

    /// [`Shader::trace`] of a ray whose radiance reaches the pixel times
    /// `weight` (the product of the weights of the bounces that led to it):
    /// its own bounces are traced only where their weight stays at or
    /// above [`MIN_RAY_WEIGHT`] ([`bounce_weight`]).
    fn trace_weighted(&mut self, ray: &Ray, cone: Cone, depth: u32, weight: Vec3) -> Vec3 {
        if self.clock.on {
            self.trace_as::<true>(ray, cone, depth, weight)
        } else {
            self.trace_as::<false>(ray, cone, depth, weight)
        }
    }

    /// [`Shader::trace_weighted`] with the phase clock on (`ON`) or compiled out.
    fn trace_as<const ON: bool>(&mut self, ray: &Ray, cone: Cone, depth: u32, weight: Vec3) -> Vec3 {
        let t = PhaseClock::start::<ON>();
        let hit = self.tracer.intersect(ray);
        let t = self.clock.stop::<ON>(t, query_phase(depth));
        let prep = self.prepare(ray, cone, hit.as_ref());
        let t = self.clock.stop::<ON>(t, Phase::Surface);
        let Some(prep) = prep else {
            return self.env.background;
        };
        // PERF: one bit per light on the stack; a scene with more lights
        // than bits keeps a list.
        let lights = &self.env.lights;
        let mut bits = 0u64;
        let mut list = Vec::new();
        if lights.len() > 64 {
            list.resize(lights.len(), false);
        }
        for (j, light) in lights.iter().enumerate() {
            if let Some(shadow) = self.shadow_ray(&prep, j, light) {
                self.counts.shadow += 1;
                if self.tracer.occluded_hinted(&shadow, &mut self.occluders[j]) {
                    if let Some(b) = list.get_mut(j) {
                        *b = true;
                    } else {
                        bits |= 1 << j;
                    }
                }
            }
        }
        if self.mode == RenderMode::Whitted {
            self.clock.stop::<ON>(t, Phase::Shadow);
        }
        self.finish_as::<ON>(
            &prep,
            |j| list.get(j).copied().unwrap_or(bits & (1 << (j & 63)) != 0),
            depth,
            weight,
        )
    }

    /// The surface that `ray` shades, given its first hit: one-sided
    /// surfaces seen from the back are passed through (traced again from
    /// behind them, up to [`MAX_PASS_THROUGH`] times). `None` when the ray
    /// leaves the scene.
    // PERF: the first hit by reference: a copy made by the caller for the
    // call was read back before its stores had landed (failed store
    // forwarding).
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub fn prepare(&self, ray: &Ray, cone: Cone, first: Option<&SceneHit>) -> Option<Prepared> {
        let scene = self.scene;
        // PERF: the ray is not copied; only a pass-through makes a new one
        // (with the same direction).
        let mut passed: Option<Ray> = None;
        let mut again: Option<SceneHit>;
        let mut h = first?;
        let mut passes = 0;
        let mut cone = cone;
        let surf = loop {
            let cur = passed.as_ref().unwrap_or(ray);
            cone.width = cone.width_at(cur, h.t);
            // NOTE: the tracer's hits come from this scene, so this never fails.
            let surf = scene.own_surface(cur, h)?;
            if passes < MAX_PASS_THROUGH && self.passes_through(&surf, ray.dir) {
                passes += 1;
                // The ray leaves through the back: move along the normal, the side it goes to.
                let o = offset_ray_origin(surf.point, surf.geometric_normal, surf.error_scale);
                let next = Ray::new(o, ray.dir, 0.0, f32::INFINITY);
                again = self.tracer.intersect(&next);
                passed = Some(next);
                h = again.as_ref()?;
                continue;
            }
            break surf;
        };
        Some(self.prepared(ray, cone, surf))
    }

    /// Whether a hit on `surf` by a ray of direction `dir` is passed
    /// through: a one-sided surface seen from the back.
    #[inline]
    fn passes_through(&self, surf: &Surface, dir: Vec3) -> bool {
        let mat = &self.scene.materials()[surf.material.index() as usize];
        mat.one_sided && surf.geometric_normal.dot(dir) > 0.0
    }

    /// [`Shader::prepare`] of a packet's `lanes` into `preps`: the surfaces
    /// `F::LANES` lanes at a time ([`Scene::own_surfaces`]); a lane that
    /// passes through a one-sided surface goes on alone.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn prepare_lanes<const N: usize, F: LaneF32>(
        &self,
        rays: &[Ray; N],
        cones: &[Cone; N],
        hits: &[Option<SceneHit>; N],
        lanes: u32,
        preps: &mut [Option<Prepared>; N],
    ) {
        let w = F::LANES;
        for c in 0..N / w {
            let bits = (lanes >> (w * c)) & lanes_mask(w);
            if bits == 0 {
                continue;
            }
            let hit = |i: usize| hits[w * c + i].as_ref().filter(|_| bits & (1 << i) != 0);
            let some: [&Ray; MAX_SURFACE_LANES] = std::array::from_fn(|i| &rays[(w * c + i) % N]);
            let their: [Option<&SceneHit>; MAX_SURFACE_LANES] =
                std::array::from_fn(|i| if i < w { hit(i) } else { None });
            self.scene.own_surfaces::<F>(&some, &their, |i, surf, facing| {
                let l = w * c + i;
                let Some(h) = hit(i) else {
                    return;
                };
                preps[l] = if self.passes_through(&surf, rays[l].dir) {
                    self.prepare(&rays[l], cones[l], Some(h))
                } else {
                    let mut cone = cones[l];
                    cone.width = cone.width_for(h.t, facing.len);
                    Some(self.prepared_facing(cone, surf, facing))
                };
            });
        }
    }

    /// The rest of [`Shader::prepare`] once the surface is found: normals
    /// facing the ray, the origin of rays leaving it and the silent lights.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn prepared(&self, ray: &Ray, cone: Cone, surf: Surface) -> Prepared {
        let facing = Facing::of(ray.dir, &surf);
        self.prepared_facing(cone, surf, &facing)
    }

    /// [`Shader::prepared`] with the ray's [`Facing`] known.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn prepared_facing(&self, cone: Cone, surf: Surface, facing: &Facing) -> Prepared {
        let Facing { d, back, nf, ns, .. } = *facing;
        // PERF: only Whitted mode traces rays from the hit.
        let p_out = if self.mode == RenderMode::Whitted {
            offset_ray_origin(surf.point, nf, surf.error_scale)
        } else {
            surf.point
        };
        // PERF: only Whitted mode traces shadow rays.
        let silent = if self.mode == RenderMode::Whitted {
            self.silent_lights(surf.material, surf.point, d, nf, ns)
        } else {
            0
        };
        Prepared {
            surf,
            d,
            back,
            nf,
            ns,
            p_out,
            cone,
            silent,
        }
    }

    /// The lights (of the first 64) that add exactly nothing to the colour
    /// of a hit on `surf` (unit ray direction `d`, normals `nf` and `ns` as
    /// in [`Prepared`]), whether their shadow rays are blocked or not: on a
    /// material without diffuse reflection (the kitchen's metals), a light
    /// whose highlight power is exactly zero, or every light when the
    /// material has no highlight. Their contribution in [`Shader::local`]
    /// is `light.color * (0 * max(n·l, 0) + specular * 0)`, a zero, and
    /// adding a zero leaves the sum as it is (up to the sign of a zero sum,
    /// which no pixel shows), so not tracing their shadow rays changes no
    /// byte. The powers are [`Shader::local`]'s own ([`light_terms`] and
    /// [`highlight_powers`] on the same values), so the decision is exact.
    /// Lights of non-finite colour are never silent (their product with a
    /// zero is NaN).
    ///
    /// PERF: a kitchen Whitted frame (400) traces 3.35 million shadow rays
    /// instead of 3.80 million, the same bytes; frames 400..402 4-7% faster
    /// side by side (docs/PERFORMANCE.md). Other materials cost one compare.
    #[inline]
    fn silent_lights(&self, material: MaterialId, point: Vec3, d: Vec3, nf: Vec3, ns: Vec3) -> u64 {
        let mat = &self.scene.materials()[material.index() as usize];
        if mat.diffuse != Vec3::ZERO {
            return 0;
        }
        let (highlights, floor) = self.highlights_of(material);
        let mut silent = 0u64;
        for (q, quad) in self.light_quads.iter().enumerate().take(16) {
            let quiet = if highlights {
                let terms = light_terms(quad, point, nf, ns, -d);
                let power = highlight_powers(wide::f32x4::from(terms.rdv), terms.lit, mat.shininess, floor);
                (0..4).fold(0u64, |m, i| {
                    m | (u64::from(terms.lit & (1 << i) == 0 || power[i] == 0.0) << i)
                })
            } else {
                0xf
            };
            silent |= quiet << (4 * q);
        }
        silent & self.finite_lights
    }

    /// Whether the material of `surf` has Phong highlights, and the floor
    /// of their powers ([`crate::highlight::zero_power_below`], made once
    /// per frame): the light loop's and [`Shader::silent_lights`]' shared
    /// view of it.
    #[inline]
    fn highlights(&self, surf: &Surface) -> (bool, f32) {
        self.highlights_of(surf.material)
    }

    /// [`Shader::highlights`] of a material.
    #[inline]
    fn highlights_of(&self, material: MaterialId) -> (bool, f32) {
        let index = material.index() as usize;
        let mat = &self.scene.materials()[index];
        let floor = self.zero_power.get(index).copied().unwrap_or(0.0);
        (mat.shininess > 0.0 && mat.specular != Vec3::ZERO, floor)
    }

    /// The shadow ray towards `light` that Whitted mode traces for a
    /// prepared hit (`light` is light `j`), `None` when no ray is traced
    /// (local mode, a silent light, or the light lies behind the surface or
    /// at the hit point).
    pub fn shadow_ray(&self, prep: &Prepared, j: usize, light: &PointLight) -> Option<Ray> {
        let silent = j < 64 && prep.silent & (1 << j) != 0;
        if self.mode != RenderMode::Whitted || silent || lit_side(prep, light).is_none() {
            return None;
        }
        Some(towards_light(prep.p_out, light.position))
    }

    /// The radiance of a prepared hit, with `blocked(j)` telling whether
    /// light `j`'s shadow ray (from [`Shader::shadow_ray`]) is occluded;
    /// traces the reflection and refraction rays below `max_depth`; the
    /// phase clock on (`ON`) or compiled out.
    fn finish_as<const ON: bool>(
        &mut self,
        prep: &Prepared,
        blocked: impl Fn(usize) -> bool,
        depth: u32,
        path: Vec3,
    ) -> Vec3 {
        let mut bounces = [None; 2];
        let mut color = self.local_as::<ON>(prep, blocked, depth, &mut bounces);
        for (k, bounce) in bounces.into_iter().enumerate() {
            let Some((weight, ray)) = bounce else {
                continue;
            };
            match bounce_weight(path, weight) {
                Some(next) => color += weight * self.trace_as::<ON>(&ray, prep.cone, depth + 1, next),
                None => self.counts.untrace(k),
            }
        }
        color
    }

    /// The local part of [`Shader::finish_as`]: ambient and lights; the
    /// bounces still to trace are written to `bounces`, refraction first,
    /// each with the weight of its radiance (added in this order by the
    /// caller), `None` where there is none.
    // PERF: the bounces are written in place: returned with the colour,
    // each lane's pair was copied by a `memcpy` call (in GL-like frames
    // too, where they are always `None`).
    // NOTE: single rays and lone bounces; a packet's hits take the passes
    // of `shade_block` (texels, then the light loop four lanes at a time).
    #[cfg_attr(not(test), allow(dead_code))]
    pub fn local(
        &mut self,
        prep: &Prepared,
        blocked: impl Fn(usize) -> bool,
        depth: u32,
        bounces: &mut Bounces,
    ) -> Vec3 {
        if self.clock.on {
            self.local_as::<true>(prep, blocked, depth, bounces)
        } else {
            self.local_as::<false>(prep, blocked, depth, bounces)
        }
    }

    /// [`Shader::local`] with the phase clock on (`ON`) or compiled out.
    // PERF: not marked inline, as `local` was before it was split in two.
    fn local_as<const ON: bool>(
        &mut self,
        prep: &Prepared,
        blocked: impl Fn(usize) -> bool,
        depth: u32,
        bounces: &mut Bounces,
    ) -> Vec3 {
        let t = PhaseClock::start::<ON>();
        let tex = self.texel(prep);
        let t = self.clock.stop::<ON>(t, Phase::Textures);
        let color = self.local_lit(prep, tex, blocked, depth, bounces);
        self.clock.stop::<ON>(t, Phase::Lights);
        color
    }

    /// The texture's colour at a prepared hit (white without a texture):
    /// the level of detail from the ray cone, then the filtered lookup.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub fn texel(&self, prep: &Prepared) -> Vec3 {
        let scene = self.scene;
        let mat = &scene.materials()[prep.surf.material.index() as usize];
        mat.texture
            .and_then(|t| scene.textures().get(t.index() as usize))
            .map_or(Vec3::ONE, |t| self.lookup(prep, t))
    }

    /// [`Shader::lookup`] for an emission texture, out of line: the light
    /// loop around it stays as small as without emission textures.
    #[cold]
    #[inline(never)]
    fn emission_texel(&self, prep: &Prepared, t: &crate::Texture) -> Vec3 {
        self.lookup(prep, t)
    }

    /// Texture `t` at a prepared hit: the level of detail from the ray
    /// cone, then the filtered lookup.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn lookup(&self, prep: &Prepared, t: &crate::Texture) -> Vec3 {
        let surf = &prep.surf;
        if self.filter != TextureFilter::Trilinear {
            return t.sample_filtered(surf.uv, 0.0, self.filter);
        }
        let lod = lods(&[prep; 4], [t; 4]).to_array()[0];
        t.sample_filtered(surf.uv, lod, self.filter)
    }

    /// [`Shader::texel`] of a packet's prepared hits, four lanes at a time:
    /// trilinear lookups with repeat addressing through
    /// [`crate::texture::trilinear_lanes`] (the same bits), the others one
    /// lane at a time.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn texels_lanes<const N: usize, F: LaneF32>(&self, preps: &[Option<Prepared>; N], texels: &mut [Vec3; N]) {
        let scene = self.scene;
        let trilinear = self.filter == TextureFilter::Trilinear;
        for c in 0..N / 4 {
            let mut four: [Option<(&Prepared, &crate::Texture)>; 4] = [None; 4];
            for (i, slot) in four.iter_mut().enumerate() {
                let l = 4 * c + i;
                let Some(p) = &preps[l] else {
                    continue;
                };
                let mat = &scene.materials()[p.surf.material.index() as usize];
                match mat.texture.and_then(|t| scene.textures().get(t.index() as usize)) {
                    Some(t) if trilinear && crate::texture::takes_lanes(t, p.surf.uv) => *slot = Some((p, &**t)),
                    Some(t) => texels[l] = self.lookup(p, t),
                    None => texels[l] = Vec3::ONE,
                }
            }
            // Lanes without a lookup repeat the first one's (not kept).
            let Some(first) = four.iter().flatten().next().copied() else {
                continue;
            };
            let each = four.map(|x| x.unwrap_or(first));
            let (preps4, texs) = (each.map(|x| x.0), each.map(|x| x.1));
            let lod = lods(&preps4, texs);
            let got = crate::texture::trilinear_lanes::<F>(texs, preps4.map(|p| p.surf.uv), lod);
            for (i, x) in four.iter().enumerate() {
                if x.is_some() {
                    texels[4 * c + i] = got[i].into();
                }
            }
        }
    }

    /// [`Shader::local`] with the hit's texel ([`Shader::texel`]) given.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub fn local_lit(
        &mut self,
        prep: &Prepared,
        tex: Vec3,
        blocked: impl Fn(usize) -> bool,
        depth: u32,
        bounces: &mut Bounces,
    ) -> Vec3 {
        let hit = self.lit_hit(prep, tex);
        let whitted = self.mode == RenderMode::Whitted;
        let color = light_sum(&self.env.lights, &self.light_quads, &hit, |j| whitted && blocked(j));
        self.bounces(prep, depth, bounces);
        color
    }

    /// What the light loop needs of a prepared hit whose texel is `tex`.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn lit_hit(&self, prep: &Prepared, tex: Vec3) -> LitHit {
        let scene = self.scene;
        let surf = &prep.surf;
        let mat = &scene.materials()[surf.material.index() as usize];
        let (highlights, floor) = self.highlights(surf);
        // Emission is added unlit (zero adds nothing: the same bits), times
        // its texture when it has one.
        let emission = match mat
            .emission_texture
            .and_then(|t| scene.textures().get(t.index() as usize))
        {
            Some(t) => mat.emission * self.emission_texel(prep, t),
            None => mat.emission,
        };
        // Vectors of four lanes: the same products, one per component.
        let (tex, a) = (Vec3A::from(tex), Vec3A::from);
        LitHit {
            p: surf.point.into(),
            nf: prep.nf.into(),
            ns: prep.ns.into(),
            view: a(-prep.d),
            base: a(self.env.ambient) * (a(mat.ambient) * tex) + a(emission),
            kd: a(mat.diffuse) * tex,
            specular: mat.specular.into(),
            shininess: mat.shininess,
            floor,
            highlights,
        }
    }

    /// The bounces a prepared hit still traces, written to `bounces`
    /// (refraction first, each with the weight of its radiance; `None`
    /// where there is none): Whitted mode below `max_depth` only.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn bounces(&mut self, prep: &Prepared, depth: u32, bounces: &mut Bounces) {
        bounces[0] = None;
        bounces[1] = None;
        self.bounces_with(prep, depth, |k, w, r| bounces[k] = Some((w, r)));
    }

    /// The bounces of [`Shader::bounces`], each handed to `put` with its
    /// kind (0 refraction, 1 reflection), its weight and its ray.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn bounces_with(&mut self, prep: &Prepared, depth: u32, mut put: impl FnMut(usize, Vec3, Ray)) {
        let surf = &prep.surf;
        let (d, back, nf, ns, p_out) = (prep.d, prep.back, prep.nf, prep.ns, prep.p_out);
        let mat = &self.scene.materials()[surf.material.index() as usize];
        if self.mode != RenderMode::Whitted || depth >= self.max_depth {
            return;
        }
        let mut mirror_weight = mat.specular;
        if mat.transmission > 0.0 {
            // Entering or leaving is decided by the geometric normal; the
            // direction bends about the shading normal (smooth glass), unless
            // that would send the ray back to the incoming side.
            let eta = if back { mat.ior } else { 1.0 / mat.ior };
            let refracted = refract(d, ns, eta)
                .filter(|t| t.dot(nf) < 0.0)
                .or_else(|| refract(d, nf, eta));
            if let Some(t) = refracted {
                self.counts.refraction += 1;
                let p_in = offset_ray_origin(surf.point, -nf, surf.error_scale);
                // NOTE: `splat(w) * c` is `w * c` bit for bit (one product per channel).
                put(0, Vec3::splat(mat.transmission), Ray::new(p_in, t, 0.0, f32::INFINITY));
            } else {
                // Total internal reflection: the transmitted share is reflected.
                mirror_weight += Vec3::splat(mat.transmission);
            }
        }
        if mirror_weight != Vec3::ZERO {
            let mut r = reflect(d, ns);
            if r.dot(nf) <= 0.0 {
                r = reflect(d, nf);
            }
            self.counts.reflection += 1;
            put(1, mirror_weight, Ray::new(p_out, r, 0.0, f32::INFINITY));
        }
    }

    /// `true` when hits may trace reflection or refraction rays (Whitted
    /// mode below a depth of 1).
    pub fn traces_bounces(&self) -> bool {
        self.mode == RenderMode::Whitted && self.max_depth > 0
    }

    /// The radiance of the `lanes` of a packet of rays (`depth` bounces so
    /// far) up to their bounces, written to `block`: first hits as a packet,
    /// then per light the shadow rays as a packet, then each lane's local
    /// shading and the bounces it still traces ([`Shader::bounce_blocks`]
    /// traces them). With its bounces, each lane's colour is the bytes of
    /// [`Shader::trace`] on its ray.
    // PERF: written in place: a block returned by value (3 KB with its
    // bounces) made GL-like kitchen frames 3% slower.
    pub fn shade_block<const N: usize>(
        &mut self,
        rays: &[Ray; N],
        cones: &[Cone; N],
        lanes: u32,
        depth: u32,
        block: &mut ShadedBlock<N>,
    ) {
        // PERF: packets of 8 lanes and more (32 are chosen for a CPU with
        // AVX2 or AVX-512) are shaded by code compiled for AVX2; 4-lane packets, the
        // portable width, by the SSE build. Rust never fuses a product and a
        // sum, so both give the same bits (the packet-width test renders
        // every width against single rays). Kitchen GL-like frames 0.97 of
        // the time side by side, 0.90 with eight lanes to a register.
        let packet = BlockIn {
            rays,
            cones,
            lanes,
            depth,
        };
        // Every path sets the bounces of its lanes from here.
        block.bouncing = [0; 2];
        #[cfg(target_arch = "x86_64")]
        if N >= 8 && openrt_accel::avx2() {
            // SAFETY: the CPU has AVX2 (detected at run time).
            unsafe { self.shade_block_avx2(&packet, block) };
            return;
        }
        self.shade_block_in::<N, f32x4>(&packet, block);
    }

    /// [`Shader::shade_block`] compiled for AVX2: its body and what that
    /// inlines (surfaces, textures, light loop) in VEX encoding, eight
    /// lanes to a register where written over [`LaneF32`].
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn shade_block_avx2<const N: usize>(&mut self, packet: &BlockIn<'_, N>, block: &mut ShadedBlock<N>) {
        self.shade_block_in::<N, crate::simd::F32x8>(packet, block);
    }

    /// [`Shader::shade_block`] with `F` the lanes of its light loop and
    /// surfaces, the phase clock on or compiled out, for whichever
    /// instruction set the caller is compiled for.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn shade_block_in<const N: usize, F: LaneF32>(&mut self, packet: &BlockIn<'_, N>, block: &mut ShadedBlock<N>) {
        if self.clock.on {
            self.shade_block_as::<N, true, F>(packet, block);
        } else {
            self.shade_block_as::<N, false, F>(packet, block);
        }
    }

    /// [`Shader::shade_block_in`] with the phase clock on (`ON`) or off.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn shade_block_as<const N: usize, const ON: bool, F: LaneF32>(
        &mut self,
        packet: &BlockIn<'_, N>,
        block: &mut ShadedBlock<N>,
    ) {
        let &BlockIn {
            rays,
            cones,
            lanes,
            depth,
        } = packet;
        let t = PhaseClock::start::<ON>();
        let hits = self.tracer.intersect_packet(rays, lanes);
        let t = self.clock.stop::<ON>(t, query_phase(depth));
        if self.mode != RenderMode::Whitted {
            self.shade_local_lanes::<N, ON, F>(packet, &hits, block, t);
            return;
        }
        if self.whitted_lanes {
            self.shade_whitted_lanes::<N, ON, F>(packet, &hits, block, t);
            return;
        }
        // PERF: filled in place (`from_fn` moved each lane's result twice).
        let mut preps: [Option<Prepared>; N] = [const { None }; N];
        self.prepare_lanes::<N, F>(rays, cones, &hits, lanes, &mut preps);
        let t = self.clock.stop::<ON>(t, Phase::Surface);
        let blocked = if self.mode == RenderMode::Whitted {
            self.trace_shadows(&ShadowLanes::gather(&preps), rays)
        } else {
            Vec::new()
        };
        // GL-like frames trace no shadow rays: no span for them.
        let t = if self.mode == RenderMode::Whitted {
            self.clock.stop::<ON>(t, Phase::Shadow)
        } else {
            t
        };
        block.lanes = lanes;
        // The texels of every lane, then the light loop four lanes at a
        // time, then each lane's bounces.
        let mut texels = [Vec3::ONE; N];
        self.texels_lanes::<N, F>(&preps, &mut texels);
        let mut hits = [LitHit::default(); N];
        let mut have = 0u32;
        for l in lanes_of(lanes) {
            if let Some(p) = &preps[l] {
                hits[l] = self.lit_hit(p, texels[l]);
                have |= 1 << l;
            }
        }
        let t = self.clock.stop::<ON>(t, Phase::Textures);
        let whitted = self.mode == RenderMode::Whitted;
        // The light loop `F::LANES` hits at a time (a divisor of `N`).
        let w = F::LANES;
        debug_assert_eq!(N % w, 0, "{w} lanes do not divide a packet of {N}");
        for c in 0..N / w {
            let bits = (have >> (w * c)) & lanes_mask(w);
            if bits == 0 {
                continue;
            }
            let blocked = |j: usize| {
                if whitted {
                    blocked.get(j).map_or(0, |m| (m >> (w * c)) & lanes_mask(w))
                } else {
                    0
                }
            };
            light_sum_lanes::<F>(
                &self.env.lights,
                &hits[w * c..],
                bits,
                blocked,
                &mut block.color[w * c..],
            );
        }
        for l in lanes_of(lanes) {
            if let Some(p) = &preps[l] {
                self.bounces_with(p, depth, |k, w, r| block.set_bounce(k, l, w, r));
                block.cones[l] = p.cone;
            } else {
                block.color[l] = self.env.background;
            }
        }
        self.clock.stop::<ON>(t, Phase::Lights);
    }

    /// The lanes whose shadow ray towards each light is blocked, per light
    /// (Whitted mode): the rays of `chunks` ([`ShadowLanes::rays`]) traced
    /// towards the light as one packet.
    // PERF: the shadow rays four lanes at a time: the hits' points, facing
    // normals and ray origins gathered once for every light, the lit side
    // decided and the rays made in registers (`ShadowLanes::rays`: each lane
    // is `shadow_ray`'s ray). Lanes without a ray keep a camera ray of
    // `rays`, never read.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn trace_shadows<const N: usize>(&mut self, chunks: &[ShadowLanes; QUADS], rays: &[Ray; N]) -> Vec<u32> {
        let mut blocked = Vec::with_capacity(self.env.lights.len());
        let mut shadow = *rays;
        for (j, light) in self.env.lights.iter().enumerate() {
            let mut mask = 0u32;
            for (c, chunk) in chunks.iter().enumerate().take(N / 4) {
                mask |= chunk.rays(j, light.position, &mut shadow[4 * c..]) << (4 * c);
            }
            self.counts.shadow += u64::from(mask.count_ones());
            blocked.push(if mask == 0 {
                0
            } else {
                self.tracer
                    .occluded_packet_toward_hinted(&shadow, mask, light.position, &mut self.occluders[j])
            });
        }
        blocked
    }

    /// [`Shader::shade_block_as`] of Whitted packets, kept in lanes where
    /// no per-hit struct is needed: a chunk's surfaces ([`Scene::surface_lanes`])
    /// give the shadow rays' origins ([`offset_origins`]) and the light
    /// loop's inputs ([`Shader::lit_lanes`]) in lanes; only hits whose
    /// material reflects or refracts, below the last depth, get a
    /// [`Prepared`] for their bounces. Each lane is the bytes of the
    /// per-hit path (the same operations). Scenes with one-sided materials
    /// or emission textures take that path ([`Shader::whitted_lanes`]).
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn shade_whitted_lanes<const N: usize, const ON: bool, F: LaneF32>(
        &mut self,
        packet: &BlockIn<'_, N>,
        hits: &[Option<SceneHit>; N],
        block: &mut ShadedBlock<N>,
        t: Option<quanta::Instant>,
    ) {
        const M: usize = MAX_SURFACE_LANES;
        let &BlockIn {
            rays,
            cones,
            lanes,
            depth,
        } = packet;
        let scene = self.scene;
        let w = F::LANES;
        debug_assert_eq!(N % w, 0, "{w} lanes do not divide a packet of {N}");
        block.lanes = lanes;
        let bouncing = depth < self.max_depth;
        let mut preps: [Option<Prepared>; N] = [const { None }; N];
        let mut lits: [Option<LitLanes<F>>; QUADS] = [None; QUADS];
        let mut shadows = [ShadowLanes::default(); QUADS];
        let mut have = 0u32;
        let mut t = t;
        for c in 0..N / w {
            let bits = (lanes >> (w * c)) & lanes_mask(w);
            if bits == 0 {
                continue;
            }
            let (some, their) = chunk_of::<N, F>(rays, hits, c, bits);
            let Some(surf) = scene.surface_lanes::<F>(&some, &their) else {
                continue;
            };
            let mut found = 0u32;
            let (mut quiet, mut bounce, mut refracts) = (0u32, 0u32, 0u32);
            let mut specular = [Vec3::ZERO; M];
            for (i, f) in surf.found.iter().enumerate().take(w) {
                let Some((_, _, material)) = f else {
                    continue;
                };
                let m = &scene.materials()[material.index() as usize];
                found |= 1 << i;
                quiet |= u32::from(m.diffuse == Vec3::ZERO) << i;
                bounce |= u32::from(bouncing && (m.transmission > 0.0 || m.specular != Vec3::ZERO)) << i;
                refracts |= u32::from(m.transmission > 0.0) << i;
                specular[i] = m.specular;
            }
            let width = cone_widths::<N, F>(cones, c, &surf);
            let mut widths = [0.0; M];
            width.write_to(&mut widths);
            let p = surf.points(&some);
            let p_out = offset_origins(&p, &surf.facing.nf, surf.error_scale, found);
            // Silent lights (materials without diffuse light only), and a
            // `Prepared` for each hit that bounces.
            let mut silent = [0u64; M];
            if quiet != 0 {
                let (pv, dv) = (vectors(&p), vectors(&surf.facing.d));
                let (nfv, nsv) = (vectors(&surf.facing.nf), vectors(&surf.facing.ns));
                for i in lanes_of(quiet) {
                    if let Some((_, _, material)) = surf.found[i] {
                        silent[i] = self.silent_lights(material, pv[i], dv[i], nfv[i], nsv[i]);
                    }
                }
            }
            if bounce != 0 {
                let ov = vectors(&p_out);
                // Mirrors: the reflected rays of `Shader::bounces`, in lanes.
                let mirror = bounce & !refracts;
                if mirror != 0 {
                    let f = &surf.facing;
                    let r = reflect_lanes(&f.d, &f.ns);
                    let n = dot_lanes(&r, &f.nf);
                    let zero = F::splat(0.0);
                    let inward = F::mask(n.lt(zero).bitmask() | n.eq(zero).bitmask());
                    let r = vectors(&Lanes::select(inward, &reflect_lanes(&f.d, &f.nf), &r));
                    for i in lanes_of(mirror) {
                        self.counts.reflection += 1;
                        let ray = Ray::new(ov[i], r[i], 0.0, f32::INFINITY);
                        block.set_bounce(1, w * c + i, specular[i], ray);
                    }
                }
                surf.each(&some, bounce & refracts, &mut |i, surface, facing| {
                    preps[w * c + i] = Some(Prepared {
                        surf: surface,
                        d: facing.d,
                        back: facing.back,
                        nf: facing.nf,
                        ns: facing.ns,
                        p_out: ov[i],
                        cone: Cone {
                            width: widths[i],
                            spread: cones[w * c + i].spread,
                        },
                        silent: silent[i],
                    });
                });
            }
            for q in 0..w / 4 {
                let part = |v: &Lanes<F>| quarter(v, q);
                shadows[w * c / 4 + q] = ShadowLanes {
                    p: part(&p),
                    nf: part(&surf.facing.nf),
                    out: part(&p_out),
                    silent: std::array::from_fn(|k| silent[4 * q + k]),
                    lanes: (found >> (4 * q)) & 0xf,
                };
            }
            set_cones(block, cones, w * c, &widths, found);
            have |= found << (w * c);
            t = self.clock.stop::<ON>(t, Phase::Surface);
            lits[c] = Some(self.lit_lanes(&surf, p, width, found));
            t = self.clock.stop::<ON>(t, Phase::Textures);
        }
        let blocked = self.trace_shadows(&shadows, rays);
        let t = self.clock.stop::<ON>(t, Phase::Shadow);
        for (c, lit) in lits.iter().enumerate() {
            let Some(lit) = lit else {
                continue;
            };
            let bits = (have >> (w * c)) & lanes_mask(w);
            let blocked = |j: usize| blocked.get(j).map_or(0, |m| (m >> (w * c)) & lanes_mask(w));
            let color = light_sum_of_lanes(&self.env.lights, lit, bits, blocked);
            write_colors(&color, bits, &mut block.color[w * c..]);
        }
        for l in lanes_of(lanes) {
            if let Some(p) = &preps[l] {
                self.bounces_with(p, depth, |k, w, r| block.set_bounce(k, l, w, r));
            } else if have & (1 << l) == 0 {
                block.color[l] = self.env.background;
            }
        }
        self.clock.stop::<ON>(t, Phase::Lights);
    }

    /// [`Shader::shade_block_as`] of GL-like frames, whose hits are shaded
    /// by their material and the lights alone (no shadow or bounce rays),
    /// kept in lanes from the surfaces to the colours: the surfaces of
    /// `F::LANES` hits at a time ([`Scene::surface_lanes`]), their texels,
    /// the light loop on them ([`light_sum_of_lanes`]). Each lane's colour is
    /// the bytes of [`Shader::trace`]: the same operations as
    /// [`Shader::prepare`], [`Shader::texel`] and [`Shader::lit_hit`],
    /// without their per-lane structs. Lanes that pass through a one-sided
    /// surface or have an emission texture are shaded one by one.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn shade_local_lanes<const N: usize, const ON: bool, F: LaneF32>(
        &mut self,
        packet: &BlockIn<'_, N>,
        hits: &[Option<SceneHit>; N],
        block: &mut ShadedBlock<N>,
        t: Option<quanta::Instant>,
    ) {
        const M: usize = MAX_SURFACE_LANES;
        let &BlockIn { rays, cones, lanes, .. } = packet;
        let scene = self.scene;
        let w = F::LANES;
        debug_assert_eq!(N % w, 0, "{w} lanes do not divide a packet of {N}");
        block.lanes = lanes;
        // PERF: each chunk of lanes goes from its surfaces to its colours
        // before the next: kept for a later phase, a chunk's lanes (1 KB)
        // were moved by `memcpy` (1.4% of a kitchen GL-like frame).
        let mut alone = 0u32;
        let mut have = 0u32;
        let mut t = t;
        for c in 0..N / w {
            let bits = (lanes >> (w * c)) & lanes_mask(w);
            if bits == 0 {
                continue;
            }
            // Surfaces, their cones' widths, and the lanes left to the
            // one-by-one path.
            let (some, their) = chunk_of::<N, F>(rays, hits, c, bits);
            let Some(surf) = scene.surface_lanes::<F>(&some, &their) else {
                continue;
            };
            let dirs = Lanes::<F>::transposed(|i| some[i].dir.into());
            let behind = dot_lanes(&surf.geometric, &dirs).gt(F::splat(0.0)).bitmask();
            let mut found = 0u32;
            for (i, f) in surf.found.iter().enumerate().take(w) {
                let Some((_, _, material)) = f else {
                    continue;
                };
                let mat = &scene.materials()[material.index() as usize];
                if (mat.one_sided && behind & (1 << i) != 0) || mat.emission_texture.is_some() {
                    alone |= 1 << (w * c + i);
                } else {
                    found |= 1 << i;
                }
            }
            let width = cone_widths::<N, F>(cones, c, &surf);
            have |= found << (w * c);
            t = self.clock.stop::<ON>(t, Phase::Surface);
            if found == 0 {
                continue;
            }
            // Texels and material terms, then the light loop.
            let lit = self.lit_lanes(&surf, surf.points(&some), width, found);
            t = self.clock.stop::<ON>(t, Phase::Textures);
            let color = light_sum_of_lanes(&self.env.lights, &lit, found, |_| 0);
            write_colors(&color, found, &mut block.color[w * c..]);
            let mut widths = [0.0; M];
            width.write_to(&mut widths);
            set_cones(block, cones, w * c, &widths, found);
            t = self.clock.stop::<ON>(t, Phase::Lights);
        }
        for l in lanes_of(lanes & !have & !alone) {
            block.color[l] = self.env.background;
        }
        if alone != 0 {
            self.shade_local_alone(rays, cones, hits, alone, block);
            self.clock.stop::<ON>(t, Phase::Surface);
        }
    }

    /// What the light loop needs of the `lanes` of a chunk of surfaces at
    /// points `p` ([`SurfaceLanes::points`]) whose cones are `width` wide: [`Shader::texel`] and [`Shader::lit_hit`] of
    /// each lane, in lanes (the same bits).
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn lit_lanes<F: LaneF32>(&self, surf: &SurfaceLanes<'_, F>, p: Lanes<F>, width: F, lanes: u32) -> LitLanes<F> {
        const M: usize = MAX_SURFACE_LANES;
        let scene = self.scene;
        let mat = |i: usize| surf.found[i].map(|(_, _, m)| &scene.materials()[m.index() as usize]);
        // PERF: each lane's texture looked up once, for the lane mask, the
        // level of detail and the lookup.
        let texs: [Option<&crate::Texture>; M] = std::array::from_fn(|i| {
            (i < F::LANES)
                .then(|| {
                    mat(i)?
                        .texture
                        .and_then(|t| scene.textures().get(t.index() as usize).map(|t| &**t))
                })
                .flatten()
        });
        let mut texels = [Vec3A::ONE; M];
        let tex_lanes = lanes_of(lanes).fold(0u32, |m, i| m | (u32::from(texs[i].is_some()) << i));
        if tex_lanes != 0 {
            let (mut uvx, mut uvy) = ([0.0; M], [0.0; M]);
            surf.uv[0].write_to(&mut uvx);
            surf.uv[1].write_to(&mut uvy);
            let uv = |i: usize| Vec2::new(uvx[i], uvy[i]);
            let trilinear = self.filter == TextureFilter::Trilinear;
            // `lods` lane by lane: the texture's texels over the
            // triangle's, from the cone's width and the slant.
            let mut lod = [0.0; M];
            if trilinear {
                let size = F::from_fn(|i| texs[i].map_or(1.0, |t| (t.width() * t.height()) as f32));
                let texel_area = surf.uv_area * size;
                let cos = dot_lanes(&surf.facing.d, &surf.facing.nf);
                let x = texel_area * width * width / (surf.world_area * cos * cos);
                (F::splat(0.5) * log2_above_one(x)).write_to(&mut lod);
            }
            for q in 0..F::LANES / 4 {
                let mut four: [Option<&crate::Texture>; 4] = [None; 4];
                for (k, slot) in four.iter_mut().enumerate() {
                    let i = 4 * q + k;
                    let Some(t) = texs[i].filter(|_| tex_lanes & (1 << i) != 0) else {
                        continue;
                    };
                    if trilinear && crate::texture::takes_lanes(t, uv(i)) {
                        *slot = Some(t);
                    } else {
                        texels[i] = t
                            .sample_filtered(uv(i), if trilinear { lod[i] } else { 0.0 }, self.filter)
                            .into();
                    }
                }
                // Lanes without a lookup repeat the first one's (not kept).
                let Some((k0, first)) = four.iter().enumerate().find_map(|(k, t)| t.map(|t| (k, t))) else {
                    continue;
                };
                let at = |k: usize| if four[k].is_some() { 4 * q + k } else { 4 * q + k0 };
                let got = crate::texture::trilinear_lanes::<F>(
                    four.map(|t| t.unwrap_or(first)),
                    std::array::from_fn(|k| uv(at(k))),
                    wide::f32x4::from(std::array::from_fn::<f32, 4, _>(|k| lod[at(k)])),
                );
                for (k, x) in four.iter().enumerate() {
                    if x.is_some() {
                        texels[4 * q + k] = got[k];
                    }
                }
            }
        }
        // `lit_hit`'s material terms, lane by lane.
        let ambient = Vec3A::from(self.env.ambient);
        let (mut base, mut kd, mut specular) = ([Vec3A::ZERO; M], [Vec3A::ZERO; M], [Vec3A::ZERO; M]);
        let (mut shininess, mut floor) = ([0.0; M], [0.0; M]);
        let mut bright = 0u32;
        for i in lanes_of(lanes) {
            let Some((_, _, m)) = surf.found[i] else {
                continue;
            };
            let mat = &scene.materials()[m.index() as usize];
            let tex = texels[i];
            base[i] = ambient * (Vec3A::from(mat.ambient) * tex) + Vec3A::from(mat.emission);
            kd[i] = Vec3A::from(mat.diffuse) * tex;
            specular[i] = mat.specular.into();
            let (highlights, zero_below) = self.highlights_of(m);
            shininess[i] = mat.shininess;
            floor[i] = zero_below;
            bright |= u32::from(highlights) << i;
        }
        let all = F::mask(lanes_mask(F::LANES));
        LitLanes {
            p,
            nf: surf.facing.nf,
            ns: surf.facing.ns,
            view: Lanes {
                x: surf.facing.d.x.flip_sign(all),
                y: surf.facing.d.y.flip_sign(all),
                z: surf.facing.d.z.flip_sign(all),
            },
            base: Lanes::transposed(|i| base[i]),
            kd: Lanes::transposed(|i| kd[i]),
            specular: Lanes::transposed(|i| specular[i]),
            shininess: F::from_fn(|i| shininess[i]),
            floor: F::from_fn(|i| floor[i]),
            bright,
        }
    }

    /// The GL-like colours of the `lanes` of a packet that
    /// [`Shader::shade_local_lanes`] leaves out, one lane at a time through
    /// [`Shader::prepare`], [`Shader::texel`] and [`light_sum`].
    #[cold]
    #[inline(never)]
    fn shade_local_alone<const N: usize>(
        &self,
        rays: &[Ray; N],
        cones: &[Cone; N],
        hits: &[Option<SceneHit>; N],
        lanes: u32,
        block: &mut ShadedBlock<N>,
    ) {
        for l in lanes_of(lanes) {
            if let Some(p) = self.prepare(&rays[l], cones[l], hits[l].as_ref()) {
                let hit = self.lit_hit(&p, self.texel(&p));
                block.color[l] = light_sum(&self.env.lights, &self.light_quads, &hit, |_| false);
                block.cones[l] = p.cone;
            } else {
                block.color[l] = self.env.background;
            }
        }
    }

    /// The bounces of shaded `blocks` ([`Shader::shade_block`], a tile's):
    /// their refraction rays, then their reflection rays, each added to its
    /// lane's colour in that order. Per block, the lanes of a kind that all
    /// share direction signs go on as a packet; the others of equal signs
    /// are pooled across the blocks and go on as packets of up to `N`
    /// lanes, from [`POOLED_MIN`] lanes up; the rest go alone. The packets
    /// of one depth are shaded together and their own bounces traced the
    /// same way, depth by depth. Every lane gets the bytes of
    /// [`Shader::trace`] either way: the same rays, and the same sums in the
    /// same order.
    pub fn bounce_blocks<const N: usize>(
        &mut self,
        blocks: &mut [ShadedBlock<N>],
        depth: u32,
        pool: &mut Vec<Vec<ShadedBlock<N>>>,
    ) {
        let level = depth as usize;
        if pool.len() <= level {
            pool.resize_with(level + 1, Vec::new);
        }
        for k in 0..2 {
            // The next depth's packets: blocks whose lanes all bounce with
            // the same signs (their rays as they lie in the block), then
            // packets gathered from the pooled lanes.
            let mut next: Vec<NextPacket> = Vec::new();
            let mut gathered: Vec<Gathered<N>> = Vec::new();
            // By direction signs, the (block, lane) of bounces left out of
            // their block's packets; then those that go alone.
            let mut pooled: [Vec<(usize, usize)>; 8] = Default::default();
            let mut alone: Vec<(usize, usize)> = Vec::new();
            for (bi, b) in blocks.iter_mut().enumerate() {
                // PERF: nothing to group when no lane bounces (every GL-like
                // packet, most Whitted ones at their last depth).
                if b.bouncing[k] == 0 {
                    continue;
                }
                // Bounces too faint to matter are not traced (`MIN_RAY_WEIGHT`).
                for l in lanes_of(b.bouncing[k]) {
                    let path = if depth == 0 { Vec3::ONE } else { b.path[l] };
                    if let Some(next) = bounce_weight(path, b.weights[k][l]) {
                        b.next_path[k][l] = next;
                    } else {
                        b.bouncing[k] &= !(1 << l);
                        self.counts.untrace(k);
                    }
                }
                let mask = b.bouncing[k];
                if mask == 0 {
                    continue;
                }
                // Regrouped by direction signs: when every lane of the
                // packet has a bounce of this kind with the same signs (a
                // mirror or a pane) it goes on as a packet; smaller groups
                // are pooled with the other blocks'.
                // PERF: packets from a quarter of one block's lanes up made
                // museum16k Whitted frames 6% slower than single rays; pooled
                // ones from 8 lanes up made the kitchen's 8% faster
                // (docs/PERFORMANCE.md).
                let (groups, zero) = sign_groups(&b.rays[k], mask);
                for (gi, &g) in groups.iter().enumerate() {
                    if g.count_ones() as usize == N {
                        next.push(NextPacket::Whole(bi));
                    } else {
                        pooled[gi].extend(lanes_of(g).map(|l| (bi, l)));
                    }
                }
                alone.extend(lanes_of(zero).map(|l| (bi, l)));
            }
            for group in &pooled {
                for chunk in group.chunks(N) {
                    if chunk.len() < POOLED_MIN.min(N) {
                        alone.extend_from_slice(chunk);
                        continue;
                    }
                    let ray = |(bi, l): (usize, usize)| blocks[bi].rays[k][l];
                    let filler = ray(chunk[0]);
                    let mut g = Gathered {
                        rays: [filler; N],
                        cones: [blocks[chunk[0].0].cones[chunk[0].1]; N],
                        lanes: u32::MAX >> (32 - chunk.len()),
                        from: [chunk[0]; N],
                    };
                    for (i, &(bi, l)) in chunk.iter().enumerate() {
                        g.rays[i] = ray((bi, l));
                        g.cones[i] = blocks[bi].cones[l];
                        g.from[i] = (bi, l);
                    }
                    next.push(NextPacket::Gathered(gathered.len()));
                    gathered.push(g);
                }
            }
            for (bi, l) in alone {
                let b = &blocks[bi];
                let (w, r, next) = (b.weights[k][l], b.rays[k][l], b.next_path[k][l]);
                let c = self.trace_weighted(&r, b.cones[l], depth + 1, next);
                blocks[bi].color[l] += w * c;
            }
            if next.is_empty() {
                continue;
            }
            // PERF: the next depth's blocks are the pool's, kept from tile
            // to tile (`shade_block` writes every field its lanes read).
            let mut next_blocks = std::mem::take(&mut pool[level]);
            if next_blocks.len() < next.len() {
                next_blocks.resize_with(next.len(), ShadedBlock::new);
            }
            let next_blocks_here = &mut next_blocks[..next.len()];
            for (packet, nb) in next.iter().zip(next_blocks_here.iter_mut()) {
                match *packet {
                    NextPacket::Whole(bi) => {
                        let b = &blocks[bi];
                        self.shade_block(&b.rays[k], &b.cones, b.bouncing[k], depth + 1, nb);
                        nb.path = b.next_path[k];
                    }
                    NextPacket::Gathered(gi) => {
                        let g = &gathered[gi];
                        self.shade_block(&g.rays, &g.cones, g.lanes, depth + 1, nb);
                        for (i, &(bi, l)) in g.from.iter().enumerate() {
                            nb.path[i] = blocks[bi].next_path[k][l];
                        }
                    }
                }
            }
            self.bounce_blocks(next_blocks_here, depth + 1, pool);
            for (packet, nb) in next.iter().zip(next_blocks_here.iter()) {
                match *packet {
                    NextPacket::Whole(bi) => {
                        let b = &mut blocks[bi];
                        for l in lanes_of(b.bouncing[k]) {
                            b.color[l] += b.weights[k][l] * nb.color[l];
                        }
                    }
                    NextPacket::Gathered(gi) => {
                        let g = &gathered[gi];
                        for i in lanes_of(g.lanes) {
                            let (bi, l) = g.from[i];
                            let b = &mut blocks[bi];
                            b.color[l] += b.weights[k][l] * nb.color[i];
                        }
                    }
                }
            }
            pool[level] = next_blocks;
        }
    }
}

/// The inputs of [`Shader::shade_block`]: a packet's rays, their cones,
/// its lanes and their depth.
struct BlockIn<'r, const N: usize> {
    rays: &'r [Ray; N],
    cones: &'r [Cone; N],
    lanes: u32,
    depth: u32,
}

/// A packet of bounces for the next depth ([`Shader::bounce_blocks`]).
#[derive(Clone, Copy)]
enum NextPacket {
    /// Every lane of block `.0`, its bounce rays as they lie.
    Whole(usize),
    /// The pooled packet `.0` ([`Gathered`]).
    Gathered(usize),
}

/// Bounces pooled from several blocks into one packet: its rays, their
/// cones, its lanes, and the (block, lane) each lane's radiance goes back to.
struct Gathered<const N: usize> {
    rays: [Ray; N],
    cones: [Cone; N],
    lanes: u32,
    from: [(usize, usize); N],
}

/// Bounces of equal direction signs pooled across a tile's blocks go on as
/// a packet from this many lanes up ([`Shader::bounce_blocks`]).
pub(crate) const POOLED_MIN: usize = 8;

/// A packet shaded up to its bounces ([`Shader::shade_block`]): each lane's
/// local colour, the bounces it still traces, and the cone they carry.
/// Bounces of kind `k` (0 refraction, 1 reflection) lie lane by lane in
/// `rays[k]` and `weights[k]` for the lanes of `bouncing[k]`, so that a
/// block's bounces go on as a packet without a copy; other lanes hold
/// stale values, never read.
pub(crate) struct ShadedBlock<const N: usize> {
    pub color: [Vec3; N],
    pub rays: [[Ray; N]; 2],
    pub weights: [[Vec3; N]; 2],
    pub bouncing: [u32; 2],
    /// The weight of each lane's radiance in its pixel (the product of
    /// the bounce weights that led to it) below the first depth, where it
    /// is one; written by [`Shader::bounce_blocks`].
    pub path: [Vec3; N],
    /// The path weight of each lane's bounce of kind `k`, for the lanes of
    /// `bouncing[k]` ([`Shader::bounce_blocks`]).
    pub next_path: [[Vec3; N]; 2],
    pub cones: [Cone; N],
    pub lanes: u32,
}

impl<const N: usize> ShadedBlock<N> {
    /// A block of no lanes, to be written by [`Shader::shade_block`].
    pub fn new() -> Self {
        Self {
            color: [Vec3::ZERO; N],
            rays: [[Ray::infinite(Vec3::ZERO, Vec3::X); N]; 2],
            weights: [[Vec3::ZERO; N]; 2],
            bouncing: [0; 2],
            path: [Vec3::ONE; N],
            next_path: [[Vec3::ONE; N]; 2],
            cones: [Cone::default(); N],
            lanes: 0,
        }
    }

    /// Lane `l`'s bounce of kind `k`: its weight `w` and ray `r`.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn set_bounce(&mut self, k: usize, l: usize, w: Vec3, r: Ray) {
        self.rays[k][l] = r;
        self.weights[k][l] = w;
        self.bouncing[k] |= 1 << l;
    }
}

/// A bounce is traced only where the weight of its radiance in the pixel
/// (the product of the bounce weights along its path, per channel) reaches
/// this in some channel: below it, the bounce could add at most this share
/// of its radiance to the pixel, under half a step of an 8-bit channel for
/// radiance up to one. Ray-tree pruning (Hall & Greenberg 1983); POV-Ray's
/// `adc_bailout` has the same default. Single rays and packets prune alike,
/// so they keep giving the same bytes.
pub const MIN_RAY_WEIGHT: f32 = 1.0 / 255.0;

/// The path weight of a bounce of `weight` from a ray of path weight
/// `path`, or `None` when it falls below [`MIN_RAY_WEIGHT`] in every
/// channel (or is NaN) and the bounce is not traced.
#[inline]
fn bounce_weight(path: Vec3, weight: Vec3) -> Option<Vec3> {
    let next = path * weight;
    (next.max_element() >= MIN_RAY_WEIGHT).then_some(next)
}

/// The reflection and refraction rays a hit still traces, refraction first:
/// the weight of each one's radiance and the ray.
pub(crate) type Bounces = [Option<(Vec3, Ray)>; 2];

/// The unit direction to `light` when it lies on the side of the surface
/// the ray came from (and not at the hit point): only then does it light
/// the hit.
#[inline]
fn lit_side(prep: &Prepared, light: &PointLight) -> Option<Vec3> {
    let to_light = light.position - prep.surf.point;
    to_light.try_normalize().filter(|l| l.dot(prep.nf) > 0.0)
}

/// The rays and hits of chunk `c` of a packet (`F::LANES` lanes), the
/// hits of lanes outside `bits` left out: [`Scene::surface_lanes`]' input.
#[allow(clippy::inline_always)]
#[inline(always)]
fn chunk_of<'r, const N: usize, F: LaneF32>(
    rays: &'r [Ray; N],
    hits: &'r [Option<SceneHit>; N],
    c: usize,
    bits: u32,
) -> ([&'r Ray; MAX_SURFACE_LANES], [Option<&'r SceneHit>; MAX_SURFACE_LANES]) {
    let w = F::LANES;
    (
        std::array::from_fn(|i| &rays[(w * c + i) % N]),
        std::array::from_fn(|i| hits[(w * c + i) % N].as_ref().filter(|_| i < w && bits & (1 << i) != 0)),
    )
}

/// [`Cone::width_for`] of chunk `c`'s lanes at their hits.
#[allow(clippy::inline_always)]
#[inline(always)]
fn cone_widths<const N: usize, F: LaneF32>(cones: &[Cone; N], c: usize, surf: &SurfaceLanes<'_, F>) -> F {
    let cone = |i: usize| cones[(F::LANES * c + i) % N];
    let t = F::from_fn(|i| surf.found[i].map_or(0.0, |f| f.0.t));
    F::from_fn(|i| cone(i).width) + F::from_fn(|i| cone(i).spread) * t * surf.facing.len
}

/// The cones of a chunk's `lanes` at their hits: widths `widths` (lane
/// `i` of the chunk starting at packet lane `first`), their rays' spreads.
#[allow(clippy::inline_always)]
#[inline(always)]
fn set_cones<const N: usize>(block: &mut ShadedBlock<N>, cones: &[Cone; N], first: usize, widths: &[f32], lanes: u32) {
    for i in lanes_of(lanes) {
        block.cones[first + i] = Cone {
            width: widths[i],
            spread: cones[first + i].spread,
        };
    }
}

/// Lanes `4 q..4 q + 4` of `v` as four-lane vectors.
#[allow(clippy::inline_always)]
#[inline(always)]
fn quarter<F: LaneF32>(v: &Lanes<F>, q: usize) -> Lanes {
    let (mut x, mut y, mut z) = (
        [0.0; MAX_SURFACE_LANES],
        [0.0; MAX_SURFACE_LANES],
        [0.0; MAX_SURFACE_LANES],
    );
    v.x.write_to(&mut x);
    v.y.write_to(&mut y);
    v.z.write_to(&mut z);
    let four = |a: &[f32; MAX_SURFACE_LANES]| f32x4::from([a[4 * q], a[4 * q + 1], a[4 * q + 2], a[4 * q + 3]]);
    Lanes {
        x: four(&x),
        y: four(&y),
        z: four(&z),
    }
}

/// Chunks of four lanes in the widest packet.
const QUADS: usize = MAX_LANES / 4;

/// Four lanes of a packet's prepared hits as the shadow rays need them:
/// hit points, facing normals and the origins of rays leaving them, with
/// each lane's silent lights.
#[derive(Clone, Copy, Default)]
struct ShadowLanes {
    p: Lanes,
    nf: Lanes,
    out: Lanes,
    silent: [u64; 4],
    /// The lanes with a prepared hit.
    lanes: u32,
}

impl ShadowLanes {
    /// The chunks of four lanes of `preps` (up to [`MAX_LANES`]).
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn gather<const N: usize>(preps: &[Option<Prepared>; N]) -> [Self; QUADS] {
        let mut chunks = [Self::default(); QUADS];
        for (c, chunk) in chunks.iter_mut().enumerate().take(N / 4) {
            let (mut p, mut nf, mut out) = ([Vec3::ZERO; 4], [Vec3::ZERO; 4], [Vec3::ZERO; 4]);
            for i in 0..4 {
                if let Some(prep) = &preps[4 * c + i] {
                    (p[i], nf[i], out[i]) = (prep.surf.point, prep.nf, prep.p_out);
                    chunk.silent[i] = prep.silent;
                    chunk.lanes |= 1 << i;
                }
            }
            (chunk.p, chunk.nf, chunk.out) = (Lanes::from_vecs(p), Lanes::from_vecs(nf), Lanes::from_vecs(out));
        }
        chunks
    }

    /// [`Shader::shadow_ray`] towards light `j` at `light` for the four
    /// lanes (Whitted mode), written to `out[i]` for each lane `i` of the
    /// returned mask: not silent, the light on the lit side ([`towards`],
    /// `lit_side`'s decision), and the ray `towards_light` makes
    /// ([`rays_from_lanes`], its bits).
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn rays(&self, j: usize, light: Vec3, out: &mut [Ray]) -> u32 {
        if self.lanes == 0 {
            return 0;
        }
        let at = Lanes::splat(light);
        let (lit, _) = towards(&at, &self.p, &self.nf);
        let silent = (0..4).fold(0, |m, i| m | (u32::from(j < 64 && self.silent[i] & (1 << j) != 0) << i));
        let mask = lit.to_bitmask() & self.lanes & !silent;
        if mask != 0 {
            let o = &self.out;
            let dir = [at.x - o.x, at.y - o.y, at.z - o.z];
            rays_from_lanes(out, mask, [o.x, o.y, o.z], dir, 0.0, SHADOW_RAY_END);
        }
        mask
    }
}

/// Snell refraction of unit `d` through unit normal `n` facing the incoming
/// side, with `eta = n_incoming / n_transmitted`; `None` on total internal reflection.
#[inline]
fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = -d.dot(n);
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    (k >= 0.0).then(|| (d * eta + n * (eta * cos_i - k.sqrt())).normalize())
}

/// Mirror `d` about the plane with unit normal `n`.
#[inline]
fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

/// [`reflect`] lane by lane: the same operations, the same bits.
#[allow(clippy::inline_always)]
#[inline(always)]
fn reflect_lanes<F: LaneF32>(d: &Lanes<F>, n: &Lanes<F>) -> Lanes<F> {
    let k = F::splat(2.0) * dot_lanes(d, n);
    Lanes {
        x: d.x - k * n.x,
        y: d.y - k * n.y,
        z: d.z - k * n.z,
    }
}

/// The texture level of detail of four prepared hits on textures `texs`
/// (ray cones, RTG ch. 20, eq. 34): half the log2 of the texel to world
/// area ratio of the triangle times the cone's width squared over the
/// obliquity squared; lookups of packets and of single rays both take it.
// PERF: one log2 of the product instead of three, for four lanes at once
// and without a library call (`log2_above_one`).
#[allow(clippy::inline_always)]
#[inline(always)]
fn lods(preps: &[&Prepared; 4], texs: [&crate::Texture; 4]) -> f32x4 {
    let lane = |f: &dyn Fn(usize) -> f32| f32x4::from(std::array::from_fn::<f32, 4, _>(f));
    let texel_area = lane(&|i| preps[i].surf.uv_area) * lane(&|i| (texs[i].width() * texs[i].height()) as f32);
    let w = lane(&|i| preps[i].cone.width);
    let cos = lane(&|i| preps[i].d.dot(preps[i].nf));
    let world_area = lane(&|i| preps[i].surf.world_area);
    f32x4::splat(0.5) * log2_above_one(texel_area * w * w / (world_area * cos * cos))
}

/// The query phase of a ray `depth` bounces deep.
#[inline]
fn query_phase(depth: u32) -> Phase {
    if depth == 0 { Phase::Primary } else { Phase::Bounce }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_scale_with_magnitude_and_follow_the_normal() {
        for p in [
            Vec3::splat(1e-6),
            Vec3::splat(1.0),
            Vec3::splat(1e5),
            Vec3::new(-1e6, 3.0, 1e-3),
        ] {
            let scale = p.abs().max_element();
            let o = offset_ray_origin(p, Vec3::Y, scale);
            assert!(o.y > p.y, "{p}: moved along +y");
            assert_eq!((o.x, o.z), (p.x, p.z));
            assert!((o.y - p.y) / scale < 1e-4, "{p}: offset relative to the scene scale");
            let o = offset_ray_origin(p, -Vec3::Y, scale);
            assert!(o.y < p.y);
        }
    }

    /// Lights a hit's shader calls silent change no bit of its colour when
    /// blocked, whatever other lights are blocked; the others do. Hits on
    /// bumpy spheres with smooth normals (so shading and geometric normals
    /// differ) of materials without diffuse reflection (the kitchen's
    /// metals, broad highlights, no highlight) and one with it (never
    /// silent), lit by six lights around them, one of infinite colour.
    /// A light's shadow rays made four lanes at a time are `shadow_ray`'s
    /// rays bit for bit (compared through `Debug`, zeros' signs included),
    /// with the same lanes: lights on either side of the surfaces, at a
    /// hit point, far away, metals with silent lights, and any lanes of a
    /// 16-lane packet with or without a hit.
    #[test]
    fn shadow_rays_four_lanes_at_a_time_are_each_lanes_own() {
        use crate::{Context, Material, PrimitiveKind};
        use rand::rngs::SmallRng;
        use rand::{Rng, SeedableRng};
        let mut ctx = Context::new();
        let metal = ctx
            .create_material(Material {
                diffuse: Vec3::ZERO,
                specular: Vec3::splat(0.9),
                shininess: 97.4304,
                ..Material::default()
            })
            .unwrap();
        for k in 0..2u64 {
            let obj = ctx.gen_object();
            ctx.begin_object(obj).unwrap();
            if k == 1 {
                ctx.material(metal).unwrap();
            }
            ctx.begin(PrimitiveKind::Triangles).unwrap();
            for t in openrt_accel::meshgen::bumpy_sphere(500, k, 0.2) {
                for v in t {
                    ctx.vertex(v + Vec3::X * 3.0 * k as f32).unwrap();
                }
            }
            ctx.end().unwrap();
            ctx.end_object().unwrap();
            ctx.instantiate(obj).unwrap();
        }
        ctx.commit().unwrap();
        let scene = ctx.scene();
        let mut rng = SmallRng::seed_from_u64(0x5ad0);
        let mut compared = 0;
        for round in 0..2_000 {
            let centre = Vec3::X * 3.0 * (round % 2) as f32;
            let rays: [Ray; 16] = std::array::from_fn(|_| {
                let o = centre + Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 3.0);
                let aim = centre + Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
                Ray::new(o, aim - o, 0.0, f32::INFINITY)
            });
            let hits: [Option<SceneHit>; 16] = std::array::from_fn(|l| scene.intersect(&rays[l]));
            let mut lights: Vec<PointLight> = (0..5)
                .map(|_| PointLight {
                    position: centre + Vec3::new(rng.random(), rng.random(), rng.random()) * 8.0 - 4.0,
                    color: Vec3::ONE,
                })
                .collect();
            if let Some(h) = hits.iter().flatten().next() {
                lights.push(PointLight {
                    position: rays[0].at(h.t),
                    color: Vec3::ONE,
                });
            }
            lights.push(PointLight {
                position: Vec3::splat(1e30),
                color: Vec3::ONE,
            });
            let env = Environment {
                lights,
                ..Environment::default()
            };
            let shader = Shader::new(&scene, &*scene, &env, RenderMode::Whitted, 0, TextureFilter::Trilinear);
            let lanes: u32 = rng.random_range(0..=u32::MAX) & 0xffff;
            let mut preps: [Option<Prepared>; 16] = [const { None }; 16];
            shader.prepare_lanes::<16, f32x4>(&rays, &[Cone::default(); 16], &hits, lanes, &mut preps);
            let chunks = ShadowLanes::gather(&preps);
            for (j, light) in env.lights.iter().enumerate() {
                let keep = rays[0];
                let mut got = [keep; 16];
                let mut mask = 0;
                for (c, chunk) in chunks.iter().enumerate().take(16 / 4) {
                    mask |= chunk.rays(j, light.position, &mut got[4 * c..]) << (4 * c);
                }
                for l in 0..16 {
                    let want = preps[l].as_ref().and_then(|p| shader.shadow_ray(p, j, light));
                    assert_eq!(
                        want.is_some(),
                        mask & (1 << l) != 0,
                        "round {round}, light {j}, lane {l}"
                    );
                    if let Some(want) = want {
                        assert_eq!(
                            format!("{:?}", got[l]),
                            format!("{want:?}"),
                            "round {round}, light {j}, lane {l}"
                        );
                        compared += 1;
                    }
                }
            }
        }
        assert!(compared > 15_000, "{compared} rays compared");
    }

    #[test]
    fn silent_lights_change_no_bit_of_the_colour() {
        use crate::{Context, Material, PrimitiveKind};
        use rand::rngs::SmallRng;
        use rand::{Rng, SeedableRng};
        let metal = |specular: f32, shininess: f32| Material {
            diffuse: Vec3::ZERO,
            specular: Vec3::splat(specular),
            shininess,
            ..Material::default()
        };
        let materials = [
            metal(0.9, 97.4304),
            metal(0.5, 6.0),
            metal(0.5, 0.0),
            Material {
                diffuse: Vec3::splat(0.6),
                specular: Vec3::splat(0.3),
                shininess: 40.0,
                ..Material::default()
            },
        ];
        let centre = |k: usize| Vec3::X * 3.0 * k as f32;
        let mut ctx = Context::new();
        for (k, m) in materials.iter().enumerate() {
            let id = ctx.create_material(m.clone()).unwrap();
            let obj = ctx.gen_object();
            ctx.begin_object(obj).unwrap();
            ctx.material(id).unwrap();
            ctx.begin(PrimitiveKind::Triangles).unwrap();
            for t in openrt_accel::meshgen::bumpy_sphere(600, k as u64, 0.1) {
                for v in t {
                    ctx.normal(v.normalize()).unwrap();
                    ctx.vertex(v + centre(k)).unwrap();
                }
            }
            ctx.end().unwrap();
            ctx.end_object().unwrap();
            ctx.instantiate(obj).unwrap();
        }
        ctx.commit().unwrap();
        let scene = ctx.scene();
        let mut rng = SmallRng::seed_from_u64(11);
        let mut around = |r: f32| {
            Vec3::new(
                rng.random_range(-r..r),
                rng.random_range(-r..r),
                rng.random_range(-r..r),
            )
        };
        // The last light's colour is infinite: never silent (its product
        // with a zero is NaN, so blocking it does change the colour).
        let lights: Vec<PointLight> = (0..6)
            .map(|j| PointLight {
                position: centre(2) + around(6.0),
                color: Vec3::splat(if j == 5 { f32::INFINITY } else { 0.4 }),
            })
            .collect();
        let env = Environment {
            lights,
            ..Environment::default()
        };
        let mut shader = Shader::new(&scene, &*scene, &env, RenderMode::Whitted, 0, TextureFilter::Trilinear);
        let (mut silent, mut loud_changed, mut diffuse_silent) = (0, 0, 0);
        let mut rng = SmallRng::seed_from_u64(12);
        for _ in 0..20_000 {
            let k = rng.random_range(0..materials.len());
            let dir = Vec3::new(rng.random(), rng.random(), rng.random()) * 2.0 - 1.0;
            let o = centre(k) + dir.normalize_or(Vec3::Y) * 4.0;
            let aim = centre(k) + Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
            let ray = Ray::new(o, aim - o, 0.0, f32::INFINITY);
            let hit = scene.intersect(&ray);
            let Some(prep) = shader.prepare(&ray, Cone::default(), hit.as_ref()) else {
                continue;
            };
            let others: u64 = rng.random();
            let mut b = [None; 2];
            for j in 0..env.lights.len() {
                let bit = 1u64 << j;
                let with = shader.local(&prep, |i| (others | bit) & (1 << i) != 0, 0, &mut b);
                let without = shader.local(&prep, |i| (others & !bit) & (1 << i) != 0, 0, &mut b);
                if prep.silent & bit != 0 {
                    silent += 1;
                    diffuse_silent +=
                        usize::from(scene.materials()[prep.surf.material.index() as usize].diffuse != Vec3::ZERO);
                    assert_eq!(
                        with.to_array().map(f32::to_bits),
                        without.to_array().map(f32::to_bits),
                        "light {j} of {:?} is silent",
                        prep.surf.point
                    );
                } else if with != without {
                    loud_changed += 1;
                }
            }
        }
        assert!(
            silent > 10_000 && loud_changed > 10_000,
            "{silent} silent, {loud_changed} changed"
        );
        assert_eq!(diffuse_silent, 0, "a diffuse material has no silent light");
    }

    /// Ray origins four and eight lanes at a time are `offset_ray_origin`'s
    /// bits: points near zero and far from it, of both signs, on any
    /// scale, unit and zero normals, scales below and above the points'.
    #[test]
    fn offsets_in_lanes_are_each_lanes_own() {
        use rand::rngs::SmallRng;
        use rand::{Rng, SeedableRng};
        let mut rng = SmallRng::seed_from_u64(0x0ff_5e7);
        let coord = |rng: &mut SmallRng| {
            let m = 10f32.powf(rng.random_range(-42.0..30.0));
            match rng.random_range(0..6) {
                0 => 0.0,
                1 => -0.0,
                _ => m * rng.random_range(-1.0..1.0),
            }
        };
        for round in 0..20_000 {
            let p: [Vec3; 8] = std::array::from_fn(|_| Vec3::new(coord(&mut rng), coord(&mut rng), coord(&mut rng)));
            let n: [Vec3; 8] = std::array::from_fn(|_| {
                if rng.random_bool(0.1) {
                    Vec3::ZERO
                } else {
                    Vec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    )
                    .normalize_or_zero()
                }
            });
            let scale: [f32; 8] = std::array::from_fn(|i| p[i].abs().max_element() * rng.random_range(0.0..4.0));
            let want: [Vec3; 8] = std::array::from_fn(|i| offset_ray_origin(p[i], n[i], scale[i]));
            let bits = |v: Vec3| v.to_array().map(f32::to_bits);
            for c in 0..2 {
                let lanes = |v: &[Vec3; 8]| Lanes::<f32x4>::transposed(|i| v[4 * c + i].into());
                let got = offset_lanes(&lanes(&p), &lanes(&n), f32x4::from_fn(|i| scale[4 * c + i]));
                let got = crate::surface_lanes::vectors(&got);
                for i in 0..4 {
                    assert_eq!(
                        bits(got[i]),
                        bits(want[4 * c + i]),
                        "round {round}: {:?} {:?}",
                        p[4 * c + i],
                        n[4 * c + i]
                    );
                }
            }
            #[cfg(target_arch = "x86_64")]
            if openrt_accel::avx2() {
                // SAFETY: the CPU has AVX2 (detected).
                let got = unsafe { offsets_eight(&p, &n, &scale) };
                for i in 0..8 {
                    assert_eq!(bits(got[i]), bits(want[i]), "round {round}, eight lanes: {:?}", p[i]);
                }
            }
        }
    }

    /// [`offset_lanes`] eight lanes at a time, compiled for AVX2 as the
    /// renderer's shading is.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn offsets_eight(p: &[Vec3; 8], n: &[Vec3; 8], scale: &[f32; 8]) -> [Vec3; 8] {
        use crate::simd::F32x8;
        let got = offset_lanes(
            &Lanes::<F32x8>::transposed(|i| p[i].into()),
            &Lanes::<F32x8>::transposed(|i| n[i].into()),
            F32x8::from_fn(|i| scale[i]),
        );
        let v = crate::surface_lanes::vectors(&got);
        std::array::from_fn(|i| v[i])
    }

    #[test]
    fn a_bounce_is_kept_while_one_channel_of_its_path_weight_reaches_the_limit() {
        let w = MIN_RAY_WEIGHT;
        assert_eq!(
            bounce_weight(Vec3::ONE, Vec3::new(0.0, w, 0.0)),
            Some(Vec3::new(0.0, w, 0.0))
        );
        assert_eq!(
            bounce_weight(Vec3::splat(0.5), Vec3::new(2.0 * w, 0.0, 0.0)),
            Some(Vec3::X * w)
        );
        assert_eq!(bounce_weight(Vec3::splat(0.5), Vec3::splat(w)), None);
        assert_eq!(bounce_weight(Vec3::ONE, Vec3::ZERO), None);
        assert_eq!(bounce_weight(Vec3::ONE, Vec3::NAN), None);
        // One NaN channel does not hide a heavy one.
        assert_eq!(
            bounce_weight(Vec3::ONE, Vec3::new(f32::NAN, 0.5, 0.0)).map(|v| v.y),
            Some(0.5)
        );
    }

    #[test]
    fn offsets_are_scale_invariant() {
        let n = Vec3::new(0.6, 0.0, 0.8);
        let p = Vec3::new(0.3, 0.0, -0.7);
        let base = offset_ray_origin(p, n, 4.0) - p;
        // Powers of two: ulps scale exactly with them.
        for s in [2f32.powi(-13), 2f32.powi(-7), 2f32.powi(10), 2f32.powi(17)] {
            let moved = offset_ray_origin(p * s, n, 4.0 * s) - p * s;
            let rel = (moved / s - base).abs().max_element() / base.abs().max_element();
            assert!(rel < 1e-3, "scale {s}: {moved} vs {base}");
        }
    }
}
