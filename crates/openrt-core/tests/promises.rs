//! The API keeps its promises under misuse and extreme input: every
//! limit gives a typed error naming the call, nothing panics, and a failing
//! call leaves the context usable.

use std::sync::Arc;

use glam::{Mat4, Vec3};
use openrt_accel::oracle::BruteForce;
use openrt_accel::{Hit, Ray, meshgen};
use openrt_core::{
    Camera, Context, CoreError, Environment, MAX_COORDINATE, MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE, MAX_SHADE_DEPTH,
    MAX_THREADS, Material, PointLight, PrimitiveKind, RenderMode, RenderSettings, Renderer,
};

mod common;
use common::new_object as define;

fn limit_of(e: &CoreError) -> u64 {
    match e {
        CoreError::Limit { limit, .. } => *limit,
        other => panic!("expected a limit error, got {other}"),
    }
}

#[test]
fn a_zero_rotation_axis_is_an_error_and_changes_nothing() {
    let mut ctx = Context::new();
    ctx.translate(Vec3::X).unwrap();
    let before = ctx.current_matrix();
    for axis in [Vec3::ZERO, Vec3::splat(-0.0), Vec3::splat(1e-40)] {
        let e = ctx.rotate(30.0, axis).unwrap_err();
        assert!(e.to_string().starts_with("rotate:"), "{e}");
        assert_eq!(ctx.current_matrix(), before);
    }
}

#[test]
fn vertices_and_instances_beyond_the_coordinate_limit_are_refused() {
    let mut ctx = Context::new();
    let id = ctx.gen_object();
    ctx.begin_object(id).unwrap();
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    for p in [
        Vec3::new(f32::MAX, 0.0, 0.0),
        Vec3::splat(MAX_COORDINATE * 2.0),
        Vec3::new(0.0, -3e38, 0.0),
    ] {
        let e = ctx.vertex(p).unwrap_err();
        match &e {
            CoreError::CoordinateLimit { call, value, limit, .. } => {
                assert_eq!(*call, "vertex");
                // The value as given, not clamped to an integer type.
                assert_eq!(*value, f64::from(p.abs().max_element()));
                assert_eq!(*limit, f64::from(MAX_COORDINATE));
            }
            other => panic!("expected a coordinate limit, got {other}"),
        }
        let text = e.to_string();
        assert!(text.starts_with("vertex:"), "{text}");
        assert!(
            text.contains(&format!("{:e}", f64::from(p.abs().max_element()))),
            "shows the value: {text}"
        );
        assert!(!text.contains("18446744073709551615"), "{text}");
    }
    let _ = ctx.abort_object().unwrap();
    // A big object that is fine alone, and a normal one beside it.
    let big = MAX_COORDINATE * 0.5;
    let big_obj = define(
        &mut ctx,
        &[[
            Vec3::new(-big, -1.0, -5.0),
            Vec3::new(big, -1.0, -5.0),
            Vec3::new(0.0, big, -5.0),
        ]],
    );
    let small = define(&mut ctx, &meshgen::cube(Vec3::splat(-0.5), Vec3::splat(0.5)));
    ctx.instantiate(big_obj).unwrap();
    ctx.instantiate(small).unwrap();
    ctx.commit().unwrap();
    let ok = ctx.scene();
    // Scaled up, the big object leaves the range: commit refuses it and
    // the scene stays the last one.
    ctx.load_matrix(Mat4::from_scale(Vec3::splat(1e6))).unwrap();
    let moved = ctx.instantiate(big_obj).unwrap();
    let e = ctx.commit().unwrap_err();
    assert!(e.to_string().contains(&moved.to_string()), "names the instance: {e}");
    assert!(Arc::ptr_eq(&ok, &ctx.scene()), "the previous scene stays current");
    // The refusal names the instance and object in typed fields: a program
    // removes what it names and commits again.
    let CoreError::InstanceOutOfRange {
        instance,
        object,
        largest,
        limit,
        ..
    } = e
    else {
        panic!("expected an instance out of range, got {e}");
    };
    assert_eq!((instance, object), (moved, big_obj));
    assert!(
        largest > limit && limit == f64::from(MAX_COORDINATE),
        "{largest} {limit}"
    );
    ctx.remove_instance(instance).unwrap();
    ctx.commit().unwrap();
    // Within the limit, both the big and the normal triangles are hit as
    // the f64 oracle says.
    let scene = ctx.scene();
    let (world, _) = scene.world_triangles();
    let oracle = BruteForce::new(&world);
    let mut hits = 0;
    for r in meshgen::random_rays(2000, 5, openrt_accel::Aabb::new(Vec3::splat(-2.0), Vec3::splat(2.0))) {
        let got = scene.intersect(&r);
        hits += usize::from(got.is_some());
        let flat = got.map(|h| {
            // world_triangles lists instance 0's triangles, then instance 1's.
            let base: u32 = scene.instances()[..h.instance as usize]
                .iter()
                .map(|i| i.geometry.tree.triangles().len() as u32)
                .sum();
            Hit {
                t: h.t,
                prim: base + h.prim,
                b1: h.b1,
                b2: h.b2,
            }
        });
        oracle.check_closest(&r, flat).unwrap();
    }
    assert!(hits > 200, "{hits} of 2000 rays hit");
}

#[test]
fn surface_refuses_hits_of_another_frame_or_out_of_range() {
    let mut ctx = Context::new();
    let a = define(&mut ctx, &meshgen::cube(Vec3::splat(-0.5), Vec3::splat(0.5)));
    ctx.instantiate(a).unwrap();
    ctx.commit().unwrap();
    let old = ctx.scene();
    let ray = Ray::infinite(Vec3::new(0.1, 0.2, 5.0), -Vec3::Z);
    let hit = old.intersect(&ray).unwrap();
    assert!(old.surface(&ray, &hit).is_ok());
    // A new frame with fewer triangles: the old hit is foreign.
    ctx.begin_object(a).unwrap();
    ctx.end_object().unwrap();
    ctx.commit().unwrap();
    let new = ctx.scene();
    assert!(matches!(new.surface(&ray, &hit), Err(CoreError::ForeignHit { .. })));
    for bad in [
        openrt_core::SceneHit { instance: 7, ..hit },
        openrt_core::SceneHit { prim: u32::MAX, ..hit },
    ] {
        assert!(matches!(old.surface(&ray, &bad), Err(CoreError::ForeignHit { .. })));
    }
}

#[test]
fn define_object_rolls_back_a_failed_definition() {
    let mut ctx = Context::new();
    let a = define(&mut ctx, &meshgen::cube(Vec3::splat(-0.5), Vec3::splat(0.5)));
    ctx.instantiate(a).unwrap();
    ctx.commit().unwrap();
    ctx.translate(Vec3::X).unwrap();
    let m = ctx.current_matrix();
    let r: Result<usize, CoreError> = ctx.define_object(a, |ctx| {
        ctx.material(openrt_core::MaterialId::DEFAULT)?;
        ctx.translate(Vec3::Y)?;
        ctx.begin(PrimitiveKind::Triangles)?;
        ctx.vertex(Vec3::ZERO)?;
        ctx.vertex(Vec3::new(f32::NAN, 0.0, 0.0))?;
        ctx.end()
    });
    assert!(matches!(r, Err(CoreError::NonFinite { call: "vertex", .. })));
    assert_eq!(ctx.current_matrix(), m, "the matrix stack is restored");
    // The context is usable: no definition is open, and the object keeps
    // its geometry.
    let stats = ctx.commit().unwrap();
    assert!(stats.builds.is_empty());
    assert_eq!(ctx.scene().instances()[0].geometry.tree.triangles().len(), 12);
    assert!(matches!(ctx.abort_object(), Err(CoreError::NotInObject { .. })));
    // abort_object by hand, inside a definition.
    ctx.begin_object(a).unwrap();
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    assert_eq!(ctx.abort_object().unwrap(), a);
    ctx.commit().unwrap();
    assert_eq!(ctx.scene().instances()[0].geometry.tree.triangles().len(), 12);
}

fn mirror_box() -> (Context, Camera, Arc<Environment>) {
    // Two facing mirrors: every bounce goes on to the maximum depth.
    let mut ctx = Context::new();
    let mirror = ctx
        .create_material(Material {
            specular: Vec3::splat(0.9),
            diffuse: Vec3::splat(0.1),
            ..Material::default()
        })
        .unwrap();
    ctx.material(mirror).unwrap();
    let quad = |z: f32| {
        let (a, b, c, d) = (
            Vec3::new(-50.0, -50.0, z),
            Vec3::new(50.0, -50.0, z),
            Vec3::new(50.0, 50.0, z),
            Vec3::new(-50.0, 50.0, z),
        );
        [[a, b, c], [a, c, d]]
    };
    let mut tris = quad(-1.0).to_vec();
    tris.extend(quad(1.0));
    let id = ctx.gen_object();
    ctx.begin_object(id).unwrap();
    ctx.material(mirror).unwrap();
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    for t in &tris {
        for &v in t {
            ctx.vertex(v).unwrap();
        }
    }
    ctx.end().unwrap();
    ctx.end_object().unwrap();
    ctx.instantiate(id).unwrap();
    ctx.commit().unwrap();
    let cam = Camera {
        from: Vec3::new(0.0, 0.0, 0.5),
        at: Vec3::new(0.2, 0.1, -1.0),
        ..Camera::default()
    };
    let env = Environment {
        lights: vec![PointLight {
            position: Vec3::new(0.0, 0.0, 0.0),
            color: Vec3::ONE,
        }],
        ..Environment::default()
    };
    (ctx, cam, Arc::new(env))
}

#[test]
fn render_limits_are_errors_and_the_deepest_recursion_fits() {
    let (ctx, cam, env) = mirror_box();
    let r = Renderer::new(2).unwrap();
    let settings = |width, height, max_depth| RenderSettings {
        width,
        height,
        mode: RenderMode::Whitted,
        max_depth,
        ..RenderSettings::default()
    };
    for (s, limit) in [
        (settings(MAX_IMAGE_SIDE + 1, 8, 3), u64::from(MAX_IMAGE_SIDE)),
        (settings(u32::MAX, u32::MAX, 3), u64::from(MAX_IMAGE_SIDE)),
        (settings(MAX_IMAGE_SIDE, MAX_IMAGE_SIDE, 3), MAX_IMAGE_PIXELS),
        (settings(0, 8, 3), 1),
        (settings(8, 8, MAX_SHADE_DEPTH + 1), u64::from(MAX_SHADE_DEPTH)),
        (settings(8, 8, u32::MAX), u64::from(MAX_SHADE_DEPTH)),
    ] {
        let e = r.render(&ctx.scene(), &env, &cam, &s).unwrap_err();
        assert_eq!(limit_of(&e), limit, "{e}");
        assert!(e.to_string().starts_with("render:"), "{e}");
    }
    // The deepest recursion: every ray bounces MAX_SHADE_DEPTH times, on
    // the render threads' stacks, in packets and one by one.
    for backend in [openrt_core::Backend::Packets, openrt_core::Backend::Single] {
        let mut r = Renderer::new(2).unwrap();
        r.set_backend(backend);
        let (img, stats) = r
            .render(&ctx.scene(), &env, &cam, &settings(16, 16, MAX_SHADE_DEPTH))
            .unwrap();
        assert_eq!(
            stats.rays.reflection,
            16 * 16 * u64::from(MAX_SHADE_DEPTH),
            "{backend:?}"
        );
        assert!(img.pixels.iter().all(|p| p.is_finite()));
    }
}

#[test]
fn thread_limits_are_errors() {
    for n in [0, MAX_THREADS + 1, usize::MAX] {
        let e = Renderer::new(n).err().expect("refused");
        assert_eq!(limit_of(&e), MAX_THREADS as u64);
        assert!(e.to_string().contains("Renderer::new"), "{e}");
    }
}
