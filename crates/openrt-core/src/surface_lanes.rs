//! Surfaces of four (or eight) hits at once: [`Scene::own_surface`]
//! lane-parallel.
//!
//! A packet's hits are reconstructed [`LaneF32::LANES`] to a register (four
//! with `f32x4`, eight with the AVX2 type in the AVX2-compiled shading):
//! each lane's vertices, vertex normals and texture coordinates are
//! gathered straight into lane arrays (a packet's lanes mostly share one
//! instance, whose transform is broadcast), then normals, the hit point,
//! its error scale and the areas for the texture's level of detail are
//! computed for the lanes together with the scalar function's operations
//! in its order: every field is its bits (tested against it on seeded
//! scenes, four and eight lanes).

use glam::{Mat3, Vec2, Vec3, Vec3A};
use openrt_accel::Ray;

use crate::instance::InstanceRecord;
use crate::light_quad::Lanes;
use crate::simd::LaneF32;
use crate::{MaterialId, Scene, SceneHit, Surface};

/// The most lanes [`Scene::own_surfaces`] takes at once.
pub(crate) const MAX_SURFACE_LANES: usize = 8;

/// 3x3 matrices, one lane each, by columns.
#[derive(Clone, Copy)]
struct Mat3Lanes<F>([Lanes<F>; 3]);

impl<F: LaneF32> Mat3Lanes<F> {
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn new(m: impl Fn(usize) -> Mat3) -> Self {
        Self([
            Lanes::transposed(|i| Vec3A::from(m(i).x_axis)),
            Lanes::transposed(|i| Vec3A::from(m(i).y_axis)),
            Lanes::transposed(|i| Vec3A::from(m(i).z_axis)),
        ])
    }

    /// `m` in every lane.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn splat(m: &Mat3) -> Self {
        Self([Lanes::splat(m.x_axis), Lanes::splat(m.y_axis), Lanes::splat(m.z_axis)])
    }

    /// `Mat3 * Vec3`: `(x_axis * v.x + y_axis * v.y) + z_axis * v.z`.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn mul(&self, v: &Lanes<F>) -> Lanes<F> {
        let [a, b, c] = &self.0;
        Lanes {
            x: a.x * v.x + b.x * v.y + c.x * v.z,
            y: a.y * v.x + b.y * v.y + c.y * v.z,
            z: a.z * v.x + b.z * v.y + c.z * v.z,
        }
    }
}

#[allow(clippy::inline_always)]
#[inline(always)]
fn sub<F: LaneF32>(a: &Lanes<F>, b: &Lanes<F>) -> Lanes<F> {
    Lanes {
        x: a.x - b.x,
        y: a.y - b.y,
        z: a.z - b.z,
    }
}

#[allow(clippy::inline_always)]
#[inline(always)]
fn cross<F: LaneF32>(a: &Lanes<F>, r: &Lanes<F>) -> Lanes<F> {
    Lanes {
        x: a.y * r.z - r.y * a.z,
        y: a.z * r.x - r.z * a.x,
        z: a.x * r.y - r.x * a.y,
    }
}

/// `a·b` lane by lane: `(x * x' + y * y') + z * z'`, glam's order.
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn dot<F: LaneF32>(a: &Lanes<F>, b: &Lanes<F>) -> F {
    a.x * b.x + a.y * b.y + a.z * b.z
}

/// `Vec3::normalize_or_zero`, lane by lane.
#[allow(clippy::inline_always)]
#[inline(always)]
fn normalize_or_zero<F: LaneF32>(v: &Lanes<F>) -> Lanes<F> {
    let rcp = F::splat(1.0) / dot(v, v).sqrt();
    let ok = rcp.gt(F::splat(0.0)) & rcp.lt(F::splat(f32::INFINITY));
    Lanes {
        x: (v.x * rcp) & ok,
        y: (v.y * rcp) & ok,
        z: (v.z * rcp) & ok,
    }
}

/// `a * b0 + b * b1 + c * b2`, left to right.
#[allow(clippy::inline_always)]
#[inline(always)]
fn interpolate<F: LaneF32>(v: &[Lanes<F>; 3], b: &[F; 3]) -> Lanes<F> {
    Lanes {
        x: v[0].x * b[0] + v[1].x * b[1] + v[2].x * b[2],
        y: v[0].y * b[0] + v[1].y * b[1] + v[2].y * b[2],
        z: v[0].z * b[0] + v[1].z * b[1] + v[2].z * b[2],
    }
}

/// `Vec3::abs().max_element()` (`if a > b { a } else { b }`, which `maxps`
/// is operand for operand).
#[allow(clippy::inline_always)]
#[inline(always)]
fn abs_max_element<F: LaneF32>(v: &Lanes<F>) -> F {
    v.x.abs().max_fast(v.y.abs().max_fast(v.z.abs()))
}

/// The lanes' vectors, `out[i]` for lane `i`.
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn vectors<F: LaneF32>(v: &Lanes<F>) -> [Vec3; MAX_SURFACE_LANES] {
    let (x, y, z) = (lane_values(v.x), lane_values(v.y), lane_values(v.z));
    std::array::from_fn(|i| Vec3::new(x[i], y[i], z[i]))
}

/// The lanes' values, `out[i]` for lane `i`.
#[allow(clippy::inline_always)]
#[inline(always)]
fn lane_values<F: LaneF32>(v: F) -> [f32; MAX_SURFACE_LANES] {
    let mut out = [0.0; MAX_SURFACE_LANES];
    v.write_to(&mut out);
    out
}

/// How a ray meets its hit's surface: the unit direction it arrives in,
/// its direction's length, the side of the geometric normal it arrives
/// at, and both normals turned to face it. The shading's first step for
/// every hit; [`Facing::of`] for one hit, [`Scene::own_surfaces`] for a
/// packet's lanes at once with the same bits.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
// PERF: 16-byte aligned, as `Surface` (copied in 16-byte moves).
#[repr(align(16))]
pub(crate) struct Facing {
    /// `ray.dir.normalize()`.
    pub d: Vec3,
    /// `ray.dir.length()` (the ray cone's scale).
    pub len: f32,
    /// `true` when the ray arrives at the back of the geometric normal.
    pub back: bool,
    /// Geometric normal facing the incoming ray.
    pub nf: Vec3,
    /// Shading normal on the side of `nf`.
    pub ns: Vec3,
}

impl Facing {
    /// How a ray of direction `dir` meets `surf` (the scalar twin).
    #[inline]
    pub fn of(dir: Vec3, surf: &Surface) -> Self {
        let d = dir.normalize();
        let back = surf.geometric_normal.dot(d) > 0.0;
        let nf = if back {
            -surf.geometric_normal
        } else {
            surf.geometric_normal
        };
        let mut ns = surf.shading_normal;
        if ns.dot(nf) < 0.0 {
            ns = -ns;
        }
        Self {
            d,
            len: dir.length(),
            back,
            nf,
            ns,
        }
    }
}

/// `v` with its signs flipped in the lanes of the mask `m`.
#[allow(clippy::inline_always)]
#[inline(always)]
fn flip<F: LaneF32>(v: &Lanes<F>, m: F) -> Lanes<F> {
    Lanes {
        x: v.x.flip_sign(m),
        y: v.y.flip_sign(m),
        z: v.z.flip_sign(m),
    }
}

/// `linear * v + translation`.
#[allow(clippy::inline_always)]
#[inline(always)]
fn to_world<F: LaneF32>(linear: &Mat3Lanes<F>, translation: &Lanes<F>, v: &Lanes<F>) -> Lanes<F> {
    let l = linear.mul(v);
    Lanes {
        x: l.x + translation.x,
        y: l.y + translation.y,
        z: l.z + translation.z,
    }
}

/// Coordinate `a` of the lanes' texture coordinates of vertex `k`.
#[allow(clippy::inline_always)]
#[inline(always)]
fn uv_lanes<F: LaneF32>(uvs: &[[Vec2; MAX_SURFACE_LANES]; 3], k: usize, a: fn(Vec2) -> f32) -> F {
    F::from_fn(|i| a(uvs[k][i]))
}

/// [`Facing::of`] of a packet's lanes, one vector coordinate to a register.
#[derive(Clone, Copy)]
pub(crate) struct FacingLanes<F> {
    /// `ray.dir.normalize()`.
    pub d: Lanes<F>,
    /// `ray.dir.length()`.
    pub len: F,
    /// Set in the lanes whose ray arrives at the back of the geometric normal.
    pub back: F,
    /// Geometric normals facing the incoming rays.
    pub nf: Lanes<F>,
    /// Shading normals on the side of `nf`.
    pub ns: Lanes<F>,
}

/// [`Facing::of`] lane by lane: directions `dir`, geometric normals `g`
/// and shading normals `s` (the same operations: `normalize` is
/// `dir * (1 / sqrt(dir·dir))`, negation a flip of the sign bit).
#[allow(clippy::inline_always)]
#[inline(always)]
fn facing_lanes<F: LaneF32>(dir: &Lanes<F>, g: &Lanes<F>, s: &Lanes<F>) -> FacingLanes<F> {
    let len = dot(dir, dir).sqrt();
    let rcp = F::splat(1.0) / len;
    let d = Lanes {
        x: dir.x * rcp,
        y: dir.y * rcp,
        z: dir.z * rcp,
    };
    let back = dot(g, &d).gt(F::splat(0.0));
    let nf = flip(g, back);
    let ns = flip(s, dot(s, &nf).lt(F::splat(0.0)));
    FacingLanes { d, len, back, nf, ns }
}

/// Each lane's [`Facing`] of `f`, `out[i]` for lane `i`.
#[allow(clippy::inline_always)]
#[inline(always)]
fn facings<F: LaneF32>(f: &FacingLanes<F>) -> [Facing; MAX_SURFACE_LANES] {
    let (d, nf, ns, len, back) = (
        vectors(&f.d),
        vectors(&f.nf),
        vectors(&f.ns),
        lane_values(f.len),
        f.back.bitmask(),
    );
    std::array::from_fn(|i| Facing {
        d: d[i],
        len: len[i],
        back: back & (1 << i) != 0,
        nf: nf[i],
        ns: ns[i],
    })
}

/// A lane's hit, its instance and the hit triangle's material.
pub(crate) type FoundLane<'s> = (&'s SceneHit, &'s InstanceRecord, MaterialId);

/// [`Scene::own_surface`] of up to [`MAX_SURFACE_LANES`] hits, one
/// coordinate to a register ([`Scene::surface_lanes`]), and how each ray
/// meets its surface.
#[derive(Clone, Copy)]
pub(crate) struct SurfaceLanes<'s, F> {
    /// Each lane's hit, instance and material; `None` where the lane has
    /// no surface of this scene.
    pub found: [Option<FoundLane<'s>>; MAX_SURFACE_LANES],
    /// Hit points where they are finite ([`SurfaceLanes::points`]).
    pub point: Lanes<F>,
    /// The lanes whose `point` is finite; the others take the ray's point
    /// at the hit's distance.
    pub finite: u32,
    /// [`Surface::error_scale`].
    pub error_scale: F,
    /// Unit geometric normals.
    pub geometric: Lanes<F>,
    /// Unit shading normals.
    pub shading: Lanes<F>,
    /// Texture coordinates.
    pub uv: [F; 2],
    /// [`Surface::uv_area`].
    pub uv_area: F,
    /// [`Surface::world_area`].
    pub world_area: F,
    /// How the rays meet the surfaces ([`Facing`]).
    pub facing: FacingLanes<F>,
}

impl<F: LaneF32> SurfaceLanes<'_, F> {
    /// The hit points, each lane's [`Surface::point`]: the interpolated
    /// point, or where it is not finite the ray's point at the hit's
    /// distance.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub fn points(&self, rays: &[&Ray]) -> Lanes<F> {
        let present = (0..F::LANES).fold(0u32, |m, i| m | (u32::from(self.found[i].is_some()) << i));
        if self.finite & present == present {
            return self.point;
        }
        let at = Lanes::transposed(|i| self.found[i].map_or(Vec3A::ZERO, |f| rays[i].at(f.0.t).into()));
        Lanes::select(F::mask(self.finite), &self.point, &at)
    }
}

impl Scene {
    /// [`Scene::own_surface`] of the hits of `F::LANES` rays at once (the
    /// first of `rays` and `hits`): `emit(i, surface, facing)` for each
    /// lane `i` whose hit is this scene's, the same bits as `own_surface`
    /// and [`Facing::of`].
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub(crate) fn own_surfaces<F: LaneF32>(
        &self,
        rays: &[&Ray],
        hits: &[Option<&SceneHit>],
        mut emit: impl FnMut(usize, Surface, &Facing),
    ) {
        if let Some(lanes) = self.surface_lanes::<F>(rays, hits) {
            lanes.each(rays, u32::MAX, &mut emit);
        }
    }
}

impl<F: LaneF32> SurfaceLanes<'_, F> {
    /// `emit(i, surface, facing)` for each lane `i` of `lanes` that has a
    /// surface: the lanes taken apart ([`Scene::own_surfaces`]).
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub(crate) fn each(&self, rays: &[&Ray], lanes: u32, emit: &mut impl FnMut(usize, Surface, &Facing)) {
        let lanes_in = lanes;
        let lanes = self;
        let facing = facings(&lanes.facing);
        let (geometric, shading, point) = (
            vectors(&lanes.geometric),
            vectors(&lanes.shading),
            vectors(&lanes.point),
        );
        let (error_scale, uv_area, world_area) = (
            lane_values(lanes.error_scale),
            lane_values(lanes.uv_area),
            lane_values(lanes.world_area),
        );
        let (uvx, uvy) = (lane_values(lanes.uv[0]), lane_values(lanes.uv[1]));
        for i in 0..F::LANES {
            let Some((hit, inst, material)) = lanes.found[i].filter(|_| lanes_in & (1 << i) != 0) else {
                continue;
            };
            emit(
                i,
                Surface {
                    point: if lanes.finite & (1 << i) != 0 {
                        point[i]
                    } else {
                        rays[i].at(hit.t)
                    },
                    error_scale: error_scale[i],
                    geometric_normal: geometric[i],
                    shading_normal: shading[i],
                    uv: Vec2::new(uvx[i], uvy[i]),
                    uv_area: uv_area[i],
                    world_area: world_area[i],
                    material,
                    instance: inst.id,
                    object: inst.object,
                },
                &facing[i],
            );
        }
    }
}

impl Scene {
    /// [`Scene::own_surfaces`] kept in lanes: the surfaces of the hits of
    /// `F::LANES` rays, one coordinate to a register, each lane the bits of
    /// [`Scene::own_surface`] and [`Facing::of`]; `None` when no lane's hit
    /// is this scene's.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub(crate) fn surface_lanes<'s, F: LaneF32>(
        &'s self,
        rays: &[&Ray],
        hits: &[Option<&'s SceneHit>],
    ) -> Option<SurfaceLanes<'s, F>> {
        const M: usize = MAX_SURFACE_LANES;
        let n = F::LANES;
        let mut found = [None; M];
        let mut tri = [[Vec3A::ZERO; M]; 3];
        let mut nrm = [[Vec3A::ZERO; M]; 3];
        let mut uvs = [[Vec2::ZERO; M]; 3];
        let (mut b1, mut b2) = ([0.0; M], [0.0; M]);
        for i in 0..n {
            let Some(hit) = hits[i].filter(|h| h.frame == self.frame) else {
                continue;
            };
            let Some(inst) = self.instances.get(hit.instance as usize) else {
                continue;
            };
            let p = hit.prim as usize;
            let (Some(t), Some(rec)) = (inst.geometry.tree.triangles().get(p), inst.geometry.records.get(p)) else {
                continue;
            };
            for k in 0..3 {
                tri[k][i] = t[k].into();
                nrm[k][i] = rec.normals[k].into();
                uvs[k][i] = rec.uvs[k];
            }
            (b1[i], b2[i]) = (hit.b1, hit.b2);
            found[i] = Some((hit, inst, rec.material));
        }
        let first = found.iter().flatten().next().map(|f| f.1)?;
        let (b1, b2) = (F::from_fn(|i| b1[i]), F::from_fn(|i| b2[i]));
        let b = [F::splat(1.0) - b1 - b2, b1, b2];
        // NOTE: no closure makes lanes (simd.rs).
        let tri = [
            Lanes::<F>::transposed(|i| tri[0][i]),
            Lanes::transposed(|i| tri[1][i]),
            Lanes::transposed(|i| tri[2][i]),
        ];
        // PERF: a packet's lanes mostly hit one instance: its transform is
        // broadcast (not gathered lane by lane), and an identity transform
        // skips the products; lanes of several instances blend object space
        // into the identity ones only where there are any.
        let shared = found.iter().flatten().all(|f| std::ptr::eq(f.1, first));
        let transform = if shared && first.identity {
            None
        } else if shared {
            Some((
                0,
                Mat3Lanes::splat(&first.normal_matrix),
                F::splat(first.det_sign),
                Mat3Lanes::splat(&Mat3::from(first.to_world.matrix3)),
                Lanes::splat(first.to_world.translation.into()),
            ))
        } else {
            let inst = |i: usize| found[i].map_or(first, |f| f.1);
            Some((
                (0..n).fold(0, |m, i| m | (u32::from(inst(i).identity) << i)),
                Mat3Lanes::new(|i| inst(i).normal_matrix),
                F::from_fn(|i| inst(i).det_sign),
                Mat3Lanes::new(|i| Mat3::from(inst(i).to_world.matrix3)),
                Lanes::transposed(|i| inst(i).to_world.translation),
            ))
        };
        let ng_obj = cross(&sub(&tri[1], &tri[0]), &sub(&tri[2], &tri[0]));
        let nrm = [
            Lanes::transposed(|i| nrm[0][i]),
            Lanes::transposed(|i| nrm[1][i]),
            Lanes::transposed(|i| nrm[2][i]),
        ];
        let interpolated = interpolate(&nrm, &b);
        let (geometric, ns, w) = match &transform {
            None => (normalize_or_zero(&ng_obj), normalize_or_zero(&interpolated), tri),
            Some((identity, normal, det, linear, translation)) => {
                let g = normal.mul(&ng_obj);
                let g = Lanes {
                    x: g.x * *det,
                    y: g.y * *det,
                    z: g.z * *det,
                };
                let moved = normal.mul(&interpolated);
                let w = [
                    to_world(linear, translation, &tri[0]),
                    to_world(linear, translation, &tri[1]),
                    to_world(linear, translation, &tri[2]),
                ];
                if *identity == 0 {
                    (normalize_or_zero(&g), normalize_or_zero(&moved), w)
                } else {
                    // Lanes of identity instances keep object space.
                    let id = F::mask(*identity);
                    (
                        Lanes::select(id, &normalize_or_zero(&ng_obj), &normalize_or_zero(&g)),
                        normalize_or_zero(&Lanes::select(id, &interpolated, &moved)),
                        std::array::from_fn(|k| Lanes::select(id, &tri[k], &w[k])),
                    )
                }
            }
        };
        let zero = F::splat(0.0);
        let zero = ns.x.eq(zero) & ns.y.eq(zero) & ns.z.eq(zero);
        // NOTE: triangles without vertex normals have zero normals in their
        // records: they take the geometric normal here.
        let shading = Lanes::select(zero, &geometric, &ns);
        let point = interpolate(&w, &b);
        let inf = F::splat(f32::INFINITY);
        let finite = (point.x.abs().lt(inf) & point.y.abs().lt(inf) & point.z.abs().lt(inf)).bitmask();
        // The fold over the three vertices, written out.
        let error_scale = abs_max_element(&w[2])
            .max_fast(abs_max_element(&w[1]).max_fast(abs_max_element(&w[0]).max_fast(F::splat(0.0))));
        let u = |k: usize, a: fn(Vec2) -> f32| uv_lanes::<F>(&uvs, k, a);
        let (ux, uy) = (u(0, |v| v.x), u(0, |v| v.y));
        let (ax, ay, cx, cy) = (
            u(1, |v| v.x) - ux,
            u(1, |v| v.y) - uy,
            u(2, |v| v.x) - ux,
            u(2, |v| v.y) - uy,
        );
        let uv_area = (ax * cy - ay * cx).abs();
        let e = cross(&sub(&w[1], &w[0]), &sub(&w[2], &w[0]));
        let world_area = dot(&e, &e).sqrt();
        let uvx = ux * b[0] + u(1, |v| v.x) * b[1] + u(2, |v| v.x) * b[2];
        let uvy = uy * b[0] + u(1, |v| v.y) * b[1] + u(2, |v| v.y) * b[2];
        let dirs = Lanes::transposed(|i| rays[i].dir.into());
        let facing = facing_lanes(&dirs, &geometric, &shading);
        Some(SurfaceLanes {
            found,
            point,
            finite,
            error_scale,
            geometric,
            shading,
            uv: [uvx, uvy],
            uv_area,
            world_area,
            facing,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Context, PrimitiveKind};
    use glam::{Mat4, Quat};
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};
    use wide::f32x4;

    /// Every field's bits, for comparing surfaces exactly.
    fn bits(s: &Surface) -> Vec<u32> {
        let mut v: Vec<u32> = [s.point, s.geometric_normal, s.shading_normal]
            .iter()
            .flat_map(Vec3::to_array)
            .chain(s.uv.to_array())
            .chain([s.error_scale, s.uv_area, s.world_area])
            .map(f32::to_bits)
            .collect();
        v.extend([s.material.index(), s.instance.index(), s.object.index()]);
        v
    }

    /// Every field of a facing's bits.
    fn facing_bits(f: &Facing) -> Vec<u32> {
        let mut v: Vec<u32> = [f.d, f.nf, f.ns]
            .iter()
            .flat_map(Vec3::to_array)
            .chain([f.len])
            .map(f32::to_bits)
            .collect();
        v.push(u32::from(f.back));
        v
    }

    /// Four and eight lanes at once are each lane's own surface bit for bit: objects
    /// with and without vertex normals, instances without a transform,
    /// rotated and moved far, mirrored, squashed, lanes of one instance
    /// (the broadcast transform) and of several, lanes without a hit.
    #[test]
    fn four_and_eight_lanes_are_each_lanes_own_surface() {
        let mut ctx = Context::new();
        let mut objects = Vec::new();
        for k in 0..2u64 {
            let obj = ctx.gen_object();
            ctx.begin_object(obj).unwrap();
            ctx.begin(PrimitiveKind::Triangles).unwrap();
            for t in openrt_accel::meshgen::bumpy_sphere(400, k, 0.2) {
                for v in t {
                    if k == 0 {
                        ctx.normal(v.normalize()).unwrap();
                    }
                    ctx.tex_coord(Vec2::new(v.x * 3.0, v.y - v.z)).unwrap();
                    ctx.vertex(v).unwrap();
                }
            }
            ctx.end().unwrap();
            ctx.end_object().unwrap();
            objects.push(obj);
        }
        let transforms = [
            Mat4::IDENTITY,
            Mat4::from_scale_rotation_translation(Vec3::ONE, Quat::from_rotation_y(0.7), Vec3::new(3.0, 0.0, 0.0)),
            Mat4::from_scale_rotation_translation(Vec3::new(-1.0, 1.0, 1.0), Quat::IDENTITY, Vec3::new(6.0, 0.0, 0.0)),
            Mat4::from_scale_rotation_translation(
                Vec3::new(1.0, 0.2, 3.0),
                Quat::from_rotation_x(1.1),
                Vec3::new(9.0, 0.0, 0.0),
            ),
            Mat4::from_translation(Vec3::new(12.0, 1e4, 0.0)),
        ];
        let mut centres = Vec::new();
        for (i, m) in transforms.iter().enumerate() {
            ctx.load_matrix(*m).unwrap();
            ctx.instantiate(objects[i % 2]).unwrap();
            centres.push(m.transform_point3(Vec3::ZERO));
        }
        ctx.commit().unwrap();
        let scene = ctx.scene();
        let mut rng = SmallRng::seed_from_u64(0x5ef);
        let (mut compared, mut mixed) = (0, 0);
        #[cfg(target_arch = "x86_64")]
        let avx2 = openrt_accel::avx2();
        #[cfg(not(target_arch = "x86_64"))]
        let avx2 = false;
        for round in 0..10_000 {
            // Every other round the eight lanes aim at one instance.
            let one = rng.random_range(0..centres.len());
            let rays: [Ray; 8] = std::array::from_fn(|_| {
                let c = centres[if round % 2 == 0 {
                    one
                } else {
                    rng.random_range(0..centres.len())
                }];
                let o = c + Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 1.0).normalize() * 5.0;
                let aim = c + Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
                Ray::new(o, aim - o, 0.0, f32::INFINITY)
            });
            let hits: [Option<SceneHit>; 8] = std::array::from_fn(|i| scene.intersect(&rays[i]));
            let (ray_refs, hit_refs): ([&Ray; 8], [Option<&SceneHit>; 8]) = (
                std::array::from_fn(|i| &rays[i]),
                std::array::from_fn(|i| hits[i].as_ref()),
            );
            let mut got: [Option<Surface>; 8] = [None; 8];
            let mut faces = [None; 8];
            for c in 0..2 {
                scene.own_surfaces::<f32x4>(&ray_refs[4 * c..], &hit_refs[4 * c..], |i, s, f| {
                    got[4 * c + i] = Some(s);
                    faces[4 * c + i] = Some(*f);
                });
            }
            // The points kept in lanes are each surface's point, also where a
            // lane takes the ray's point instead of the interpolated one.
            for c in 0..2 {
                let (rays4, hits4) = (&ray_refs[4 * c..], &hit_refs[4 * c..]);
                let Some(lanes) = scene.surface_lanes::<f32x4>(rays4, hits4) else {
                    continue;
                };
                let fallback = SurfaceLanes {
                    finite: lanes.finite & !(1 << (round % 4)),
                    ..lanes
                };
                for (l, finite) in [(lanes, lanes.finite), (fallback, fallback.finite)] {
                    let p = vectors(&l.points(rays4));
                    for i in 0..4 {
                        let Some(want) = got[4 * c + i] else {
                            continue;
                        };
                        let want = if finite & (1 << i) != 0 {
                            want.point
                        } else {
                            rays4[i].at(hits[4 * c + i].map_or(0.0, |h| h.t))
                        };
                        assert_eq!(p[i].to_array().map(f32::to_bits), want.to_array().map(f32::to_bits));
                    }
                }
            }
            let (mut got8, mut faces8) = (got, faces);
            if avx2 {
                (got8, faces8) = ([None; 8], [None; 8]);
                // SAFETY: the CPU has AVX2 (detected).
                #[cfg(target_arch = "x86_64")]
                unsafe {
                    eight_at_a_time(&scene, &ray_refs, &hit_refs, &mut got8, &mut faces8);
                }
            }
            let instances: Vec<u32> = hits.iter().flatten().map(|h| h.instance).collect();
            mixed += usize::from(instances.windows(2).any(|w| w[0] != w[1]));
            for i in 0..8 {
                assert_eq!(
                    got[i].as_ref().map(bits),
                    got8[i].as_ref().map(bits),
                    "round {round}, lane {i} of 8"
                );
                assert_eq!(
                    faces[i].as_ref().map(facing_bits),
                    faces8[i].as_ref().map(facing_bits),
                    "round {round}, lane {i} of 8"
                );
                let want = hits[i].as_ref().and_then(|h| scene.own_surface(&rays[i], h));
                assert_eq!(
                    want.as_ref().map(bits),
                    got[i].as_ref().map(bits),
                    "round {round}, lane {i}"
                );
                let facing = want.as_ref().map(|s| facing_bits(&Facing::of(rays[i].dir, s)));
                assert_eq!(facing, faces[i].as_ref().map(facing_bits), "round {round}, lane {i}");
                compared += usize::from(want.is_some());
            }
        }
        assert!(
            compared > 40_000 && mixed > 4_000,
            "{compared} surfaces, {mixed} mixed packets"
        );
    }

    /// [`Scene::own_surfaces`] eight lanes at a time, compiled for AVX2 as
    /// the renderer's shading is.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn eight_at_a_time(
        scene: &Scene,
        rays: &[&Ray; 8],
        hits: &[Option<&SceneHit>; 8],
        got: &mut [Option<Surface>; 8],
        faces: &mut [Option<Facing>; 8],
    ) {
        scene.own_surfaces::<crate::simd::F32x8>(rays, hits, |i, s, f| {
            got[i] = Some(s);
            faces[i] = Some(*f);
        });
    }
}
