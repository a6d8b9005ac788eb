//! Surfaces of four hits at once: [`Scene::own_surface`] lane-parallel.
//!
//! A packet's hits are reconstructed four to a register: each lane's
//! vertices, vertex normals and texture coordinates are gathered straight
//! into lane arrays (a packet's lanes mostly share one instance, whose
//! transform is broadcast), then normals, the hit point, its error scale
//! and the areas for the texture's level of detail are computed for the
//! four lanes together with the scalar function's operations in its order:
//! every field is its bits (tested against it on seeded scenes).

use glam::{Affine3A, Mat3, Vec2, Vec3};
use openrt_accel::Ray;
use wide::f32x4;

use crate::light_quad::{Lanes, mask_of};
use crate::{Scene, SceneHit, Surface};

/// Four 3x3 matrices, one lane each, by columns.
#[derive(Clone, Copy)]
struct Mat3Lanes([Lanes; 3]);

impl Mat3Lanes {
    #[inline]
    fn new(m: [Mat3; 4]) -> Self {
        Self([0, 1, 2].map(|c| Lanes::from_vecs(m.map(|m| m.col(c)))))
    }

    /// `Mat3 * Vec3`: `(x_axis * v.x + y_axis * v.y) + z_axis * v.z`.
    #[inline]
    fn mul(&self, v: &Lanes) -> Lanes {
        let [a, b, c] = &self.0;
        Lanes {
            x: a.x * v.x + b.x * v.y + c.x * v.z,
            y: a.y * v.x + b.y * v.y + c.y * v.z,
            z: a.z * v.x + b.z * v.y + c.z * v.z,
        }
    }
}

#[inline]
fn sub(a: &Lanes, b: &Lanes) -> Lanes {
    Lanes {
        x: a.x - b.x,
        y: a.y - b.y,
        z: a.z - b.z,
    }
}

#[inline]
fn cross(a: &Lanes, r: &Lanes) -> Lanes {
    Lanes {
        x: a.y * r.z - r.y * a.z,
        y: a.z * r.x - r.z * a.x,
        z: a.x * r.y - r.x * a.y,
    }
}

#[inline]
fn dot(a: &Lanes, b: &Lanes) -> f32x4 {
    a.x * b.x + a.y * b.y + a.z * b.z
}

/// `Vec3::normalize_or_zero`, four lanes.
#[inline]
fn normalize_or_zero(v: &Lanes) -> Lanes {
    let rcp = f32x4::ONE / dot(v, v).sqrt();
    let ok = rcp.simd_gt(f32x4::ZERO) & rcp.simd_lt(f32x4::splat(f32::INFINITY));
    Lanes {
        x: (v.x * rcp) & ok,
        y: (v.y * rcp) & ok,
        z: (v.z * rcp) & ok,
    }
}

/// `a * b0 + b * b1 + c * b2`, left to right.
#[inline]
fn interpolate(v: &[Lanes; 3], b: &[f32x4; 3]) -> Lanes {
    Lanes {
        x: v[0].x * b[0] + v[1].x * b[1] + v[2].x * b[2],
        y: v[0].y * b[0] + v[1].y * b[1] + v[2].y * b[2],
        z: v[0].z * b[0] + v[1].z * b[1] + v[2].z * b[2],
    }
}

/// `Vec3::abs().max_element()` (`if a > b { a } else { b }`, which `maxps`
/// is operand for operand).
#[inline]
fn abs_max_element(v: &Lanes) -> f32x4 {
    v.x.abs().fast_max(v.y.abs().fast_max(v.z.abs()))
}

/// How a ray meets its hit's surface: the unit direction it arrives in,
/// its direction's length, the side of the geometric normal it arrives
/// at, and both normals turned to face it. The shading's first step for
/// every hit; [`Facing::of`] for one hit, [`Scene::own_surfaces`] for four
/// at once with the same bits.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
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

/// [`Facing::of`] for four lanes: directions `dir`, geometric normals `g`
/// and shading normals `s` (the same operations: `normalize` is
/// `dir * (1 / sqrt(dir·dir))`, negation a flip of the sign bit).
#[inline]
fn facing_lanes(dir: &Lanes, g: &Lanes, s: &Lanes) -> [Facing; 4] {
    let len = dot(dir, dir).sqrt();
    let rcp = f32x4::ONE / len;
    let d = Lanes {
        x: dir.x * rcp,
        y: dir.y * rcp,
        z: dir.z * rcp,
    };
    let back = dot(g, &d).simd_gt(f32x4::ZERO);
    let sign = f32x4::splat(-0.0);
    let flip = |v: &Lanes, m: f32x4| Lanes {
        x: v.x ^ (m & sign),
        y: v.y ^ (m & sign),
        z: v.z ^ (m & sign),
    };
    let nf = flip(g, back);
    let ns = flip(s, dot(s, &nf).simd_lt(f32x4::ZERO));
    let (d, nf, ns, len, back) = (
        d.to_vecs(),
        nf.to_vecs(),
        ns.to_vecs(),
        len.to_array(),
        back.to_bitmask(),
    );
    std::array::from_fn(|i| Facing {
        d: d[i],
        len: len[i],
        back: back & (1 << i) != 0,
        nf: nf[i],
        ns: ns[i],
    })
}

impl Scene {
    /// [`Scene::own_surface`] of the hits of four rays at once: `emit(i,
    /// surface, facing)` for each lane `i` whose hit is this scene's, the
    /// same bits as `own_surface` and [`Facing::of`].
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub(crate) fn own_surfaces(
        &self,
        rays: [&Ray; 4],
        hits: [Option<&SceneHit>; 4],
        mut emit: impl FnMut(usize, Surface, &Facing),
    ) {
        let mut found = [None; 4];
        let mut tri = [[Vec3::ZERO; 4]; 3];
        let mut nrm = [[Vec3::ZERO; 4]; 3];
        let mut uvs = [[Vec2::ZERO; 4]; 3];
        let mut has_normals = 0u32;
        let (mut b1, mut b2) = ([0.0; 4], [0.0; 4]);
        for i in 0..4 {
            let Some(hit) = hits[i].filter(|h| h.frame == self.frame) else {
                continue;
            };
            let Some(inst) = self.instances.get(hit.instance as usize) else {
                continue;
            };
            let p = hit.prim as usize;
            let Some(t) = inst.geometry.tree.triangles().get(p) else {
                continue;
            };
            let sh = &inst.geometry.shading;
            let (n, uv) = (&sh.normals[p], &sh.uvs[p]);
            for k in 0..3 {
                tri[k][i] = t[k];
                nrm[k][i] = n[k];
                uvs[k][i] = uv[k];
            }
            has_normals |= u32::from(sh.has_normals[p]) << i;
            (b1[i], b2[i]) = (hit.b1, hit.b2);
            found[i] = Some((hit, inst, sh.materials[p]));
        }
        let Some(first) = found.iter().flatten().next().map(|f| f.1) else {
            return;
        };
        let (b1, b2) = (f32x4::from(b1), f32x4::from(b2));
        let b = [f32x4::ONE - b1 - b2, b1, b2];
        let tri = tri.map(Lanes::from_vecs);
        // PERF: a packet's lanes mostly hit one instance: its transform is
        // broadcast, and an identity transform skips the products.
        let shared = found.iter().flatten().all(|f| std::ptr::eq(f.1, first));
        let transform = if shared && first.identity {
            None
        } else {
            let each = |f: &dyn Fn(usize) -> Affine3A| std::array::from_fn::<Affine3A, 4, _>(f);
            let inst = |i: usize| found[i].map_or(first, |f| f.1);
            let to_world = each(&|i| inst(i).to_world);
            Some((
                mask_of((0..4).fold(0, |m, i| m | (u32::from(inst(i).identity) << i))),
                Mat3Lanes::new(std::array::from_fn(|i| inst(i).normal_matrix)),
                f32x4::from(std::array::from_fn::<f32, 4, _>(|i| inst(i).det_sign)),
                Mat3Lanes::new(to_world.map(|a| Mat3::from(a.matrix3))),
                Lanes::from_vecs(to_world.map(|a| Vec3::from(a.translation))),
            ))
        };
        let ng_obj = cross(&sub(&tri[1], &tri[0]), &sub(&tri[2], &tri[0]));
        let interpolated = interpolate(&nrm.map(Lanes::from_vecs), &b);
        let (geometric, ns, w) = match &transform {
            None => (normalize_or_zero(&ng_obj), normalize_or_zero(&interpolated), tri),
            Some((identity, normal, det, linear, translation)) => {
                let g = normal.mul(&ng_obj);
                let g = Lanes {
                    x: g.x * *det,
                    y: g.y * *det,
                    z: g.z * *det,
                };
                let world = |v: &Lanes| {
                    let l = linear.mul(v);
                    let moved = Lanes {
                        x: l.x + translation.x,
                        y: l.y + translation.y,
                        z: l.z + translation.z,
                    };
                    Lanes::select(*identity, v, &moved)
                };
                (
                    Lanes::select(*identity, &normalize_or_zero(&ng_obj), &normalize_or_zero(&g)),
                    normalize_or_zero(&Lanes::select(*identity, &interpolated, &normal.mul(&interpolated))),
                    [world(&tri[0]), world(&tri[1]), world(&tri[2])],
                )
            }
        };
        let zero = ns.x.simd_eq(f32x4::ZERO) & ns.y.simd_eq(f32x4::ZERO) & ns.z.simd_eq(f32x4::ZERO);
        let shading = Lanes::select(zero, &geometric, &Lanes::select(mask_of(has_normals), &ns, &geometric));
        let point = interpolate(&w, &b);
        let inf = f32x4::splat(f32::INFINITY);
        let finite =
            (point.x.abs().simd_lt(inf) & point.y.abs().simd_lt(inf) & point.z.abs().simd_lt(inf)).to_bitmask();
        let error_scale = w.iter().fold(f32x4::ZERO, |acc, v| abs_max_element(v).fast_max(acc));
        let u = |k: usize, a: fn(Vec2) -> f32| f32x4::from(uvs[k].map(a));
        let (ux, uy) = (u(0, |v| v.x), u(0, |v| v.y));
        let (ax, ay, cx, cy) = (
            u(1, |v| v.x) - ux,
            u(1, |v| v.y) - uy,
            u(2, |v| v.x) - ux,
            u(2, |v| v.y) - uy,
        );
        let uv_area = (ax * cy - ay * cx).abs().to_array();
        let e = cross(&sub(&w[1], &w[0]), &sub(&w[2], &w[0]));
        let world_area = dot(&e, &e).sqrt().to_array();
        let uvx = (ux * b[0] + u(1, |v| v.x) * b[1] + u(2, |v| v.x) * b[2]).to_array();
        let uvy = (uy * b[0] + u(1, |v| v.y) * b[1] + u(2, |v| v.y) * b[2]).to_array();
        let dirs = Lanes::from_vecs(rays.map(|r| r.dir));
        let facing = facing_lanes(&dirs, &geometric, &shading);
        let (geometric, shading, point) = (geometric.to_vecs(), shading.to_vecs(), point.to_vecs());
        let error_scale = error_scale.to_array();
        for i in 0..4 {
            let Some((hit, inst, material)) = found[i] else {
                continue;
            };
            emit(
                i,
                Surface {
                    point: if finite & (1 << i) != 0 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Context, PrimitiveKind};
    use glam::{Mat4, Quat};
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

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

    /// Four lanes at once are each lane's own surface bit for bit: objects
    /// with and without vertex normals, instances without a transform,
    /// rotated and moved far, mirrored, squashed, lanes of one instance
    /// (the broadcast transform) and of several, lanes without a hit.
    #[test]
    fn four_lanes_are_each_lanes_own_surface() {
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
        for round in 0..20_000 {
            // Every other round the four lanes aim at one instance.
            let one = rng.random_range(0..centres.len());
            let rays: [Ray; 4] = std::array::from_fn(|_| {
                let c = centres[if round % 2 == 0 {
                    one
                } else {
                    rng.random_range(0..centres.len())
                }];
                let o = c + Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 1.0).normalize() * 5.0;
                let aim = c + Vec3::new(rng.random(), rng.random(), rng.random()) - 0.5;
                Ray::new(o, aim - o, 0.0, f32::INFINITY)
            });
            let hits: [Option<SceneHit>; 4] = std::array::from_fn(|i| scene.intersect(&rays[i]));
            let mut got: [Option<Surface>; 4] = [None; 4];
            let mut faces = [None; 4];
            scene.own_surfaces(
                std::array::from_fn(|i| &rays[i]),
                std::array::from_fn(|i| hits[i].as_ref()),
                |i, s, f| {
                    got[i] = Some(s);
                    faces[i] = Some(*f);
                },
            );
            let instances: Vec<u32> = hits.iter().flatten().map(|h| h.instance).collect();
            mixed += usize::from(instances.windows(2).any(|w| w[0] != w[1]));
            for i in 0..4 {
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
            compared > 40_000 && mixed > 5_000,
            "{compared} surfaces, {mixed} mixed packets"
        );
    }
}
