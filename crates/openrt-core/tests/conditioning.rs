//! Ill-conditioned instance transforms: every accepted transform gives
//! object-space rays accurate enough to agree with the f64 oracle, and a
//! transform below [`MIN_TRANSFORM_CONDITIONING`] is refused.

use glam::{Mat4, Quat, Vec3};
use openrt_accel::oracle::BruteForce;
use openrt_accel::{Hit, Ray, meshgen};
use openrt_core::{Context, CoreError, MIN_TRANSFORM_CONDITIONING, PrimitiveKind};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// A rotation, a squash of one axis by `s`, and another rotation: its
/// conditioning `|det| / longest column^3` is `s`.
fn squash(rng: &mut SmallRng, s: f32) -> Mat4 {
    let mut q = || {
        let axis = Vec3::new(rng.random(), rng.random(), rng.random::<f32>() + 0.1).normalize();
        Quat::from_axis_angle(axis, rng.random_range(0.0..6.0))
    };
    Mat4::from_translation(Vec3::new(0.3, -0.2, 0.1))
        * Mat4::from_quat(q())
        * Mat4::from_scale(Vec3::new(1.0, 1.0, s))
        * Mat4::from_quat(q())
}

fn instance(m: Mat4, tris: &[[Vec3; 3]]) -> Result<Context, CoreError> {
    let mut ctx = Context::new();
    let o = ctx.gen_object();
    ctx.begin_object(o)?;
    ctx.begin(PrimitiveKind::Triangles)?;
    for t in tris {
        for &v in t {
            ctx.vertex(v)?;
        }
    }
    ctx.end()?;
    ctx.end_object()?;
    ctx.load_matrix(m)?;
    ctx.instantiate(o)?;
    ctx.commit()?;
    Ok(ctx)
}

#[test]
fn rays_aimed_inside_squashed_triangles_agree_with_the_oracle() {
    let mut disagree = 0;
    let mut total = 0;
    for (shape, tris) in [
        ("bumpy sphere", meshgen::bumpy_sphere(200, 1, 0.1)),
        ("bumpy sphere 2", meshgen::bumpy_sphere(800, 9, 0.3)),
        ("cube", meshgen::cube(Vec3::splat(-0.5), Vec3::splat(0.5))),
    ] {
        let mut rng = SmallRng::seed_from_u64(3);
        // Just above the limit, and well above it.
        for s in [MIN_TRANSFORM_CONDITIONING * 1.05, MIN_TRANSFORM_CONDITIONING * 4.0, 1.0] {
            for _ in 0..12 {
                let m = squash(&mut rng, s);
                let ctx = instance(m, &tris).unwrap_or_else(|e| panic!("{shape}, conditioning {s}: {e}"));
                let scene = ctx.scene();
                let md = m.as_dmat4();
                let world: Vec<[Vec3; 3]> = tris
                    .iter()
                    .map(|t| t.map(|v| md.transform_point3(v.as_dvec3()).as_vec3()))
                    .collect();
                let oracle = BruteForce::new(&world);
                for t in &world {
                    // From 3 units along the normal to the centre of the triangle.
                    let c = (t[0] + t[1] + t[2]) / 3.0;
                    let Some(n) = (t[1] - t[0]).cross(t[2] - t[0]).try_normalize() else {
                        continue;
                    };
                    let from = c + n * 3.0 + Vec3::new(0.01, 0.02, 0.0);
                    let ray = Ray::new(from, c - from, 0.0, f32::INFINITY);
                    let hit = scene.intersect(&ray).map(|h| Hit {
                        t: h.t,
                        prim: h.prim,
                        b1: h.b1,
                        b2: h.b2,
                    });
                    total += 1;
                    if let Err(e) = oracle.check_closest(&ray, hit) {
                        disagree += 1;
                        eprintln!("{shape}, conditioning {s}: {e}");
                    }
                }
            }
        }
    }
    assert!(total > 20_000, "{total} rays");
    assert_eq!(disagree, 0, "{disagree} of {total} rays disagree with the oracle");
}

#[test]
fn transforms_below_the_conditioning_limit_are_refused() {
    let mut rng = SmallRng::seed_from_u64(4);
    let tris = meshgen::cube(Vec3::splat(-0.5), Vec3::splat(0.5));
    for s in [MIN_TRANSFORM_CONDITIONING * 0.9, 1e-6, 1e-12, 0.0] {
        let m = squash(&mut rng, s);
        let e = instance(m, &tris).err().expect("refused");
        assert!(matches!(e, CoreError::SingularTransform { .. }), "{e}");
        assert!(e.to_string().contains("MIN_TRANSFORM_CONDITIONING"), "{e}");
        let mut ctx = instance(Mat4::IDENTITY, &tris).expect("identity");
        let id = ctx.scene().instances()[0].id;
        assert!(ctx.set_instance_transform(id, m).is_err());
    }
}
