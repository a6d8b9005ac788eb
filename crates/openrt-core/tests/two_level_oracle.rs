//! Every frame of random animated scenes: two-level closest hit and
//! occlusion == brute force over the flattened world-space triangles.

use glam::{Mat4, Quat, Vec3};
use openrt_accel::oracle::BruteForce;
use openrt_accel::{Aabb, Hit, Ray, Triangle, meshgen};
use openrt_core::{Context, InstanceId, ObjectId, TOP_LEVEL_BVH_MIN, TopLevel};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

mod common;
use common::define;

fn random_transform(rng: &mut SmallRng) -> Mat4 {
    let axis = Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
    .try_normalize()
    .unwrap_or(Vec3::Y);
    let rot = Quat::from_axis_angle(axis, rng.random_range(0.0..6.3));
    let mut scale = Vec3::new(
        rng.random_range(0.3..3.0),
        rng.random_range(0.3..3.0),
        rng.random_range(0.3..3.0),
    );
    if rng.random_bool(0.3) {
        scale.x = -scale.x; // mirror
    }
    let t = Vec3::new(
        rng.random_range(-4.0..4.0),
        rng.random_range(-4.0..4.0),
        rng.random_range(-4.0..4.0),
    );
    Mat4::from_scale_rotation_translation(scale, rot, t)
}

enum Motion {
    Static,
    Affine,
    Unstructured,
}

#[test]
fn animated_scenes_match_the_flattened_oracle_every_frame() {
    for seed in 0..6u64 {
        let mut rng = SmallRng::seed_from_u64(seed);
        let mut ctx = Context::new();
        ctx.set_promote_after(Some(2));
        // Both top levels (a handful of instances: `Auto` is the BSP).
        ctx.set_top_level(if seed % 2 == 0 { TopLevel::Auto } else { TopLevel::Bvh });
        let unit = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let mut objects: Vec<(ObjectId, Vec<Triangle>, Motion)> = Vec::new();
        for k in 0..5 {
            let tris = match k % 3 {
                0 => meshgen::bumpy_sphere(600, seed + k, 0.3),
                1 => meshgen::random_soup(400, seed * 10 + k, unit, 0.3),
                _ => meshgen::grid(6, 6)
                    .iter()
                    .map(|t| t.map(|v| v / 3.0 - Vec3::new(1.0, 1.0, 0.0)))
                    .collect(),
            };
            let motion = match k % 3 {
                0 => Motion::Static,
                1 => Motion::Unstructured,
                _ => Motion::Affine,
            };
            let id = ctx.gen_object();
            define(&mut ctx, id, &tris);
            objects.push((id, tris, motion));
        }
        let mut instances: Vec<(InstanceId, usize)> = Vec::new();
        for (k, (id, _, _)) in objects.iter().enumerate() {
            for _ in 0..rng.random_range(1..4) {
                ctx.load_matrix(random_transform(&mut rng)).unwrap();
                instances.push((ctx.instantiate(*id).unwrap(), k));
            }
        }
        ctx.load_identity();
        for frame in 0..6 {
            if frame == 2 {
                // Slot reuse: a removed instance's slot comes back with a
                // new generation and must not keep the old record.
                let (inst, k) = instances.remove(0);
                ctx.remove_instance(inst).unwrap();
                ctx.load_matrix(random_transform(&mut rng)).unwrap();
                instances.push((ctx.instantiate(objects[k].0).unwrap(), k));
                ctx.load_identity();
            }
            // Frame 5 moves nothing: records and the top level are kept.
            if frame > 0 && frame < 5 {
                for &(inst, k) in &instances {
                    if matches!(objects[k].2, Motion::Affine) {
                        ctx.set_instance_transform(inst, random_transform(&mut rng)).unwrap();
                    }
                }
                for (id, tris, motion) in &mut objects {
                    if matches!(motion, Motion::Unstructured) && frame < 4 {
                        for t in tris.iter_mut() {
                            for v in t.iter_mut() {
                                *v += Vec3::new(rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05), 0.0);
                            }
                        }
                        define(&mut ctx, *id, tris);
                    }
                }
            }
            let stats = ctx.commit().unwrap();
            if frame == 0 {
                assert_eq!(stats.build_count(openrt_accel::BuilderKind::Sah), 5);
            } else if frame < 4 {
                assert_eq!(stats.build_count(openrt_accel::BuilderKind::Fast), 2, "frame {frame}");
                assert_eq!(stats.build_count(openrt_accel::BuilderKind::Sah), 0);
            }
            if frame == 5 {
                assert!(stats.toplevel_reused, "nothing moved in frame 5");
                ctx.wait_for_promotions();
            }
            let scene = ctx.scene();
            scene.validate_top_level().unwrap();
            let want = if seed % 2 == 0 { TopLevel::Bsp } else { TopLevel::Bvh };
            assert_eq!(scene.top_level(), want);
            let (world, origin) = scene.world_triangles();
            let index_of = |inst: u32, prim: u32| world_index(&origin, inst, prim);
            let oracle = BruteForce::new(&world);
            let bounds = Aabb::new(Vec3::splat(-7.0), Vec3::splat(7.0));
            let mut rays = meshgen::random_rays(500, seed * 100 + frame, bounds);
            rays.extend(meshgen::camera_rays(
                Vec3::new(1.0, 2.0, -14.0),
                Vec3::ZERO,
                24,
                20,
                50.0,
            ));
            let mut hits = 0;
            for (r, ray) in rays.iter().enumerate() {
                let got = scene.intersect(ray).map(|h| {
                    hits += 1;
                    world_hit(&origin, &h)
                });
                oracle
                    .check_closest(ray, got)
                    .unwrap_or_else(|e| panic!("seed {seed} frame {frame} ray {r}: {e}"));
                let shadow = Ray::new(ray.origin, ray.dir, 0.0, rng.random_range(0.5..12.0));
                oracle
                    .check_occluded(&shadow, scene.occluded(&shadow))
                    .unwrap_or_else(|e| panic!("seed {seed} frame {frame} shadow ray {r}: {e}"));
                // Geometric normals follow the world-space winding, mirrors included.
                if let Some(h) = scene.intersect(ray) {
                    let s = scene.surface(ray, &h).expect("a hit of this scene");
                    let w = world[index_of(h.instance, h.prim) as usize];
                    let n = (w[1] - w[0]).cross(w[2] - w[0]).normalize();
                    assert!(
                        s.geometric_normal.dot(n) > 0.999,
                        "normal {} vs world {n}",
                        s.geometric_normal
                    );
                }
            }
            assert!(
                hits > 50,
                "seed {seed} frame {frame}: {hits} hits is too few to test anything"
            );
        }
    }
}

/// The index among the flattened world triangles (`Scene::world_triangles`'
/// origins) of triangle `prim` of instance `inst`.
fn world_index(origin: &[(u32, u32)], inst: u32, prim: u32) -> u32 {
    origin.iter().position(|&o| o == (inst, prim)).unwrap() as u32
}

/// A scene's hit as the oracle over the flattened triangles names it.
fn world_hit(origin: &[(u32, u32)], h: &openrt_core::SceneHit) -> Hit {
    Hit {
        t: h.t,
        prim: world_index(origin, h.instance, h.prim),
        b1: h.b1,
        b2: h.b2,
    }
}

/// `bits` of a closest hit, for comparisons across structures.
fn hit_bits(h: Option<openrt_core::SceneHit>) -> Option<(u32, u32, u32, u32, u32)> {
    h.map(|h| (h.t.to_bits(), h.instance, h.prim, h.b1.to_bits(), h.b2.to_bits()))
}

/// Hundreds of instances (`Auto` takes the BVH), some overlapping, some
/// spanning the scene (a global instance), one flat: the BVH top level
/// and the BSP give every ray, packet lane and shadow packet the same
/// answers, bit for bit, and the oracle's.
#[test]
fn the_bvh_and_bsp_top_levels_give_the_same_answers() {
    let mut rng = SmallRng::seed_from_u64(77);
    let build = |top: TopLevel, rng: &mut SmallRng| {
        let mut ctx = Context::new();
        ctx.set_top_level(top);
        let ball = meshgen::bumpy_sphere(200, 3, 0.2);
        let flat: Vec<Triangle> = meshgen::grid(4, 4)
            .iter()
            .map(|t| t.map(|v| v - Vec3::new(0.5, 0.5, 0.0)))
            .collect();
        let (a, b) = (ctx.gen_object(), ctx.gen_object());
        define(&mut ctx, a, &ball);
        define(&mut ctx, b, &flat);
        for k in 0..TOP_LEVEL_BVH_MIN + 40 {
            let t = Vec3::new(
                rng.random_range(-20.0..20.0),
                rng.random_range(-20.0..20.0),
                rng.random_range(-3.0..3.0),
            );
            let s = rng.random_range(0.2..1.5);
            ctx.load_matrix(Mat4::from_scale_rotation_translation(
                Vec3::splat(s),
                Quat::from_rotation_z(k as f32),
                t,
            ))
            .unwrap();
            ctx.instantiate(if k % 7 == 0 { b } else { a }).unwrap();
        }
        // A floor under everything: spans the scene.
        ctx.load_matrix(Mat4::from_scale_rotation_translation(
            Vec3::new(60.0, 60.0, 1.0),
            Quat::IDENTITY,
            Vec3::new(0.0, 0.0, -4.0),
        ))
        .unwrap();
        ctx.instantiate(b).unwrap();
        ctx.load_identity();
        ctx.commit().unwrap();
        ctx
    };
    let seed = rng.random();
    let bsp = build(TopLevel::Bsp, &mut SmallRng::seed_from_u64(seed));
    let bvh = build(TopLevel::Auto, &mut SmallRng::seed_from_u64(seed));
    let (s0, s1) = (bsp.scene(), bvh.scene());
    assert_eq!((s0.top_level(), s1.top_level()), (TopLevel::Bsp, TopLevel::Bvh));
    assert!(!s1.global_instances().is_empty(), "the floor is global");
    s0.validate_top_level().unwrap();
    s1.validate_top_level().unwrap();
    let (world, origin) = s1.world_triangles();
    let oracle = BruteForce::new(&world);
    let bounds = Aabb::new(Vec3::new(-22.0, -22.0, -5.0), Vec3::new(22.0, 22.0, 5.0));
    let mut rays = meshgen::random_rays(1600, 5, bounds);
    rays.extend(meshgen::camera_rays(
        Vec3::new(0.0, -30.0, 12.0),
        Vec3::ZERO,
        32,
        24,
        60.0,
    ));
    // Axis-parallel rays (a zero direction component walks alone in a packet).
    for k in 0..64 {
        let o = Vec3::new(k as f32 * 0.6 - 19.0, -25.0, (k % 5) as f32 - 2.0);
        rays.push(Ray::new(o, Vec3::Y, 0.0, f32::INFINITY));
        rays.push(Ray::new(o + Vec3::Z * 10.0, -Vec3::Z, 0.0, f32::INFINITY));
    }
    let mut hits = 0;
    for (r, ray) in rays.iter().enumerate() {
        let (a, b) = (s0.intersect(ray), s1.intersect(ray));
        assert_eq!(hit_bits(a), hit_bits(b), "ray {r}");
        hits += usize::from(b.is_some());
        if r % 4 == 0 {
            let got = b.map(|h| world_hit(&origin, &h));
            oracle
                .check_closest(ray, got)
                .unwrap_or_else(|e| panic!("ray {r}: {e}"));
        }
        let shadow = Ray::new(ray.origin, ray.dir, 0.0, 8.0 + (r % 9) as f32);
        assert_eq!(s0.occluded(&shadow), s1.occluded(&shadow), "shadow ray {r}");
    }
    assert!(hits > 800, "{hits} hits");
    for (p, chunk) in rays.chunks_exact(16).enumerate() {
        let pk: [Ray; 16] = std::array::from_fn(|l| chunk[l]);
        let lanes = if p % 3 == 0 { 0xFFFF } else { 0xA5F3 };
        let (a, b) = (s0.intersect_packet(&pk, lanes), s1.intersect_packet(&pk, lanes));
        for l in 0..16 {
            let single = if lanes & (1 << l) != 0 {
                hit_bits(s1.intersect(&pk[l]))
            } else {
                None
            };
            assert_eq!(hit_bits(b[l]), single, "packet {p} lane {l}: not the single ray's");
            assert_eq!(hit_bits(a[l]), hit_bits(b[l]), "packet {p} lane {l}");
        }
        // Shadow packets towards one point, and bounces' (no shared point).
        let light = Vec3::new(3.0, -2.0, 15.0);
        let towards: [Ray; 16] = std::array::from_fn(|l| {
            let o = pk[l].origin + pk[l].dir.normalize_or_zero() * 5.0;
            Ray::new(o, light - o, 1e-3, 1.0)
        });
        let (a, b) = (
            s0.occluded_packet_toward(&towards, lanes, light),
            s1.occluded_packet_toward(&towards, lanes, light),
        );
        let single = (0..16)
            .filter(|l| lanes & (1 << l) != 0 && s1.occluded(&towards[*l]))
            .fold(0, |m, l| m | (1 << l));
        assert_eq!((a, b), (single, single), "shadow packet {p}");
        let (a, b) = (s0.occluded_packet(&pk, lanes), s1.occluded_packet(&pk, lanes));
        assert_eq!(a, b, "any-hit packet {p}");
    }
}
