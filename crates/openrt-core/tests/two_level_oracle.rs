//! Every frame of random animated scenes: two-level closest hit and
//! occlusion == brute force over the flattened world-space triangles.

use glam::{Mat4, Quat, Vec3};
use openrt_accel::oracle::BruteForce;
use openrt_accel::{Aabb, Hit, Ray, Triangle, meshgen};
use openrt_core::{Context, InstanceId, ObjectId};
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
    for seed in 0..4u64 {
        let mut rng = SmallRng::seed_from_u64(seed);
        let mut ctx = Context::new();
        ctx.set_promote_after(Some(2));
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
            let (world, origin) = scene.world_triangles();
            let index_of = |inst: u32, prim: u32| origin.iter().position(|&o| o == (inst, prim)).unwrap() as u32;
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
                    Hit {
                        t: h.t,
                        prim: index_of(h.instance, h.prim),
                        b1: h.b1,
                        b2: h.b2,
                    }
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
