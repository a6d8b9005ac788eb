//! The OpenRT-style API: semantics, no side effects, and one test per misuse error.

use glam::{Mat4, Vec2, Vec3};
use openrt_accel::{BuilderKind, Ray};
use openrt_core::{Context, CoreError, MATRIX_STACK_LIMIT, Material, PrimitiveKind};

fn tri_object(ctx: &mut Context, z: f32) -> openrt_core::ObjectId {
    let id = ctx.gen_object();
    ctx.begin_object(id).unwrap();
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    for p in [
        Vec3::new(-1.0, -1.0, z),
        Vec3::new(1.0, -1.0, z),
        Vec3::new(0.0, 1.0, z),
    ] {
        ctx.vertex(p).unwrap();
    }
    ctx.end().unwrap();
    ctx.end_object().unwrap();
    id
}

fn down(x: f32, y: f32) -> Ray {
    Ray::infinite(Vec3::new(x, y, 10.0), -Vec3::Z)
}

#[test]
fn redefinition_replaces_geometry_and_changes_no_other_object() {
    let mut ctx = Context::new();
    let a = tri_object(&mut ctx, 0.0);
    let b = tri_object(&mut ctx, 1.0);
    ctx.instantiate(a).unwrap();
    ctx.translate(Vec3::new(5.0, 0.0, 0.0)).unwrap();
    ctx.instantiate(b).unwrap();
    ctx.load_identity();
    ctx.commit().unwrap();
    let s1 = ctx.scene();
    assert!((s1.intersect(&down(0.0, 0.0)).unwrap().t - 10.0).abs() < 1e-5);
    // Redefine a: now a quad at z = 3.
    ctx.begin_object(a).unwrap();
    ctx.begin(PrimitiveKind::Quads).unwrap();
    for (x, y) in [(-2.0, -2.0), (2.0, -2.0), (2.0, 2.0), (-2.0, 2.0)] {
        ctx.vertex(Vec3::new(x, y, 3.0)).unwrap();
    }
    ctx.end().unwrap();
    ctx.end_object().unwrap();
    let stats = ctx.commit().unwrap();
    assert_eq!(stats.builds.len(), 1, "only the redefined object is rebuilt");
    assert_eq!(stats.builds[0].object, a);
    assert_eq!(stats.builds[0].builder, BuilderKind::Fast);
    let s2 = ctx.scene();
    assert!((s2.intersect(&down(0.0, 0.0)).unwrap().t - 7.0).abs() < 1e-5);
    assert!(
        s2.intersect(&down(-1.8, 1.8)).is_some(),
        "the quad's corner is new geometry"
    );
    // b unchanged; the old snapshot still sees the old a.
    assert!((s2.intersect(&down(5.0, 0.0)).unwrap().t - 9.0).abs() < 1e-5);
    assert!((s1.intersect(&down(0.0, 0.0)).unwrap().t - 10.0).abs() < 1e-5);
}

#[test]
fn state_set_inside_a_definition_does_not_leak() {
    let mut ctx = Context::new();
    let red = ctx
        .create_material(Material {
            diffuse: Vec3::X,
            ..Material::default()
        })
        .unwrap();
    ctx.translate(Vec3::new(1.0, 2.0, 3.0)).unwrap();
    let outer = ctx.current_matrix();
    let id = ctx.gen_object();
    ctx.begin_object(id).unwrap();
    assert_eq!(
        ctx.current_matrix(),
        Mat4::IDENTITY,
        "definitions start in object space"
    );
    ctx.material(red).unwrap();
    ctx.push_matrix().unwrap();
    ctx.scale(Vec3::splat(2.0)).unwrap();
    ctx.rotate(30.0, Vec3::Z).unwrap();
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    ctx.normal(Vec3::Z).unwrap();
    ctx.tex_coord(Vec2::new(0.5, 0.5)).unwrap();
    for p in [Vec3::ZERO, Vec3::X, Vec3::Y] {
        ctx.vertex(p).unwrap();
    }
    ctx.end().unwrap();
    // Leave a pushed matrix on purpose: end_object restores the whole stack.
    ctx.end_object().unwrap();
    assert_eq!(ctx.current_matrix(), outer);
    assert_eq!(ctx.matrix_depth(), 1);
    assert_eq!(ctx.current_material(), openrt_core::MaterialId::DEFAULT);
    // Normal and texcoord state is per definition too: a new object has none.
    let id2 = ctx.gen_object();
    ctx.begin_object(id2).unwrap();
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    for p in [Vec3::ZERO, Vec3::X, Vec3::Y] {
        ctx.vertex(p).unwrap();
    }
    ctx.end().unwrap();
    ctx.end_object().unwrap();
    ctx.load_identity();
    ctx.instantiate(id).unwrap();
    ctx.translate(Vec3::new(0.0, 0.0, -5.0)).unwrap();
    ctx.instantiate(id2).unwrap();
    ctx.commit().unwrap();
    let scene = ctx.scene();
    let ray = Ray::infinite(Vec3::new(0.3, 0.3, 10.0), -Vec3::Z);
    let h = scene.intersect(&ray).unwrap();
    let s = scene.surface(&ray, &h).expect("a hit of this scene");
    assert_eq!(s.material, red);
    assert!((s.uv - Vec2::splat(0.5)).length() < 1e-6);
    let ray2 = Ray::infinite(Vec3::new(0.1, 0.1, -4.0), -Vec3::Z);
    let h2 = scene.intersect(&ray2).unwrap();
    let s2 = scene.surface(&ray2, &h2).expect("a hit of this scene");
    assert_eq!(s2.material, openrt_core::MaterialId::DEFAULT);
    assert_eq!(s2.uv, Vec2::ZERO);
}

#[test]
fn degenerate_triangles_are_dropped_and_counted() {
    let mut ctx = Context::new();
    let id = ctx.gen_object();
    ctx.begin_object(id).unwrap();
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    for p in [Vec3::ZERO, Vec3::X, Vec3::X * 2.0, Vec3::ZERO, Vec3::X, Vec3::Y] {
        ctx.vertex(p).unwrap();
    }
    ctx.end().unwrap();
    assert_eq!(ctx.end_object().unwrap(), 1);
    ctx.instantiate(id).unwrap();
    let st = ctx.commit().unwrap();
    assert_eq!((st.builds[0].triangles, st.builds[0].dropped), (1, 1));
}

#[test]
fn misuse_errors_name_the_call() {
    let mut ctx = Context::new();
    let id = tri_object(&mut ctx, 0.0);
    // end_object without begin_object
    assert_eq!(ctx.end_object(), Err(CoreError::NotInObject { call: "end_object" }));
    // primitives outside an object
    assert_eq!(
        ctx.begin(PrimitiveKind::Triangles),
        Err(CoreError::NotInObject { call: "begin" })
    );
    assert!(matches!(
        ctx.vertex(Vec3::ZERO),
        Err(CoreError::NotInObject { call: "vertex" })
    ));
    // nested objects
    let other = ctx.gen_object();
    ctx.begin_object(other).unwrap();
    assert!(matches!(ctx.begin_object(id), Err(CoreError::NestedObject { .. })));
    // instantiate / commit / delete-self inside a definition
    assert!(matches!(
        ctx.instantiate(id),
        Err(CoreError::InsideObject {
            call: "instantiate",
            ..
        })
    ));
    assert!(matches!(
        ctx.commit(),
        Err(CoreError::InsideObject { call: "commit", .. })
    ));
    assert!(matches!(
        ctx.delete_object(other),
        Err(CoreError::InsideObject {
            call: "delete_object",
            ..
        })
    ));
    // vertex outside begin/end, end without begin
    assert!(matches!(
        ctx.vertex(Vec3::ZERO),
        Err(CoreError::NotInPrimitive { call: "vertex" })
    ));
    assert!(matches!(ctx.end(), Err(CoreError::NotInPrimitive { call: "end" })));
    // nested begin, end_object with an open primitive, incomplete primitive
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    assert!(matches!(
        ctx.begin(PrimitiveKind::Quads),
        Err(CoreError::PrimitiveOpen { call: "begin", .. })
    ));
    assert!(matches!(
        ctx.end_object(),
        Err(CoreError::PrimitiveOpen { call: "end_object", .. })
    ));
    ctx.vertex(Vec3::ZERO).unwrap();
    assert!(matches!(
        ctx.end(),
        Err(CoreError::IncompletePrimitive { count: 1, .. })
    ));
    // NaN and infinity
    assert!(matches!(
        ctx.vertex(Vec3::new(f32::NAN, 0.0, 0.0)),
        Err(CoreError::NonFinite { call: "vertex", .. })
    ));
    assert!(matches!(
        ctx.normal(Vec3::splat(f32::INFINITY)),
        Err(CoreError::NonFinite { call: "normal", .. })
    ));
    assert!(matches!(
        ctx.tex_coord(Vec2::new(f32::NAN, 0.0)),
        Err(CoreError::NonFinite { call: "tex_coord", .. })
    ));
    ctx.vertex(Vec3::X).unwrap();
    ctx.vertex(Vec3::Y).unwrap();
    ctx.end().unwrap();
    ctx.end_object().unwrap();
    // unknown material
    assert!(matches!(ctx.material(openrt_core::MaterialId::DEFAULT), Ok(())));
    let bogus = {
        let mut c2 = Context::new();
        c2.create_material(Material::default()).unwrap();
        c2.create_material(Material::default()).unwrap()
    };
    assert!(matches!(ctx.material(bogus), Err(CoreError::UnknownMaterial { .. })));
    assert!(matches!(
        ctx.create_material(Material {
            ior: f32::NAN,
            ..Material::default()
        }),
        Err(CoreError::NonFinite {
            call: "create_material",
            ..
        })
    ));
    // matrices: NaN, projective, zero axis, singular instance transform
    assert!(matches!(
        ctx.load_matrix(Mat4::from_scale(Vec3::splat(f32::NAN))),
        Err(CoreError::NonFinite {
            call: "load_matrix",
            ..
        })
    ));
    let mut proj = Mat4::IDENTITY;
    proj.w_axis.w = 2.0;
    proj.x_axis.w = 1.0;
    assert!(matches!(
        ctx.mult_matrix(proj),
        Err(CoreError::NotAffine {
            call: "mult_matrix",
            ..
        })
    ));
    assert!(matches!(
        ctx.rotate(10.0, Vec3::ZERO),
        Err(CoreError::NonFinite { call: "rotate", .. })
    ));
    ctx.scale(Vec3::new(1.0, 0.0, 1.0)).unwrap();
    assert!(matches!(
        ctx.instantiate(id),
        Err(CoreError::SingularTransform {
            call: "instantiate",
            ..
        })
    ));
    ctx.load_identity();
    let inst = ctx.instantiate(id).unwrap();
    assert!(matches!(
        ctx.set_instance_transform(inst, Mat4::from_scale(Vec3::new(1.0, 1.0, 1e-12))),
        Err(CoreError::SingularTransform {
            call: "set_instance_transform",
            ..
        })
    ));
    // stack underflow and overflow
    assert_eq!(ctx.pop_matrix(), Err(CoreError::StackUnderflow));
    for _ in 1..MATRIX_STACK_LIMIT {
        ctx.push_matrix().unwrap();
    }
    assert_eq!(
        ctx.push_matrix(),
        Err(CoreError::StackOverflow {
            limit: MATRIX_STACK_LIMIT
        })
    );
    // unknown / deleted ids
    let never = ctx.gen_object();
    assert!(matches!(
        ctx.instantiate(never),
        Err(CoreError::UndefinedObject {
            call: "instantiate",
            ..
        })
    ));
    ctx.delete_object(never).unwrap();
    assert!(matches!(
        ctx.begin_object(never),
        Err(CoreError::UnknownObject {
            call: "begin_object",
            ..
        })
    ));
    assert!(matches!(ctx.delete_object(never), Err(CoreError::UnknownObject { .. })));
    let recycled = ctx.gen_object();
    assert_eq!(recycled.index(), never.index());
    assert_ne!(recycled, never, "a recycled slot has a new generation");
    ctx.remove_instance(inst).unwrap();
    assert!(matches!(
        ctx.remove_instance(inst),
        Err(CoreError::UnknownInstance {
            call: "remove_instance",
            ..
        })
    ));
    assert!(matches!(
        ctx.set_instance_transform(inst, Mat4::IDENTITY),
        Err(CoreError::UnknownInstance { .. })
    ));
}

#[test]
fn instances_of_a_deleted_object_fail_the_commit_not_the_process() {
    let mut ctx = Context::new();
    let id = tri_object(&mut ctx, 0.0);
    let inst = ctx.instantiate(id).unwrap();
    ctx.commit().unwrap();
    let before = ctx.scene();
    ctx.delete_object(id).unwrap();
    let err = ctx.commit().unwrap_err();
    assert!(matches!(err, CoreError::InstanceOfDeletedObject { instance, object } if instance == inst && object == id));
    assert!(err.to_string().contains("remove the instance"));
    assert_eq!(ctx.scene().frame(), before.frame(), "the previous scene stays current");
    ctx.remove_instance(inst).unwrap();
    ctx.commit().unwrap();
    assert!(ctx.scene().intersect(&down(0.0, 0.0)).is_none());
}

#[test]
fn every_primitive_kind_makes_the_expected_surface() {
    let mut ctx = Context::new();
    for (kind, verts) in [
        (
            PrimitiveKind::Triangles,
            vec![(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 0.0), (1.0, 1.0), (0.0, 1.0)],
        ),
        (
            PrimitiveKind::TriangleStrip,
            vec![(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)],
        ),
        (
            PrimitiveKind::TriangleFan,
            vec![(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)],
        ),
        (
            PrimitiveKind::Quads,
            vec![(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)],
        ),
        (
            PrimitiveKind::QuadStrip,
            vec![(0.0, 0.0), (1.0, 0.0), (0.0, 0.5), (1.0, 0.5), (0.0, 1.0), (1.0, 1.0)],
        ),
        (
            PrimitiveKind::Polygon,
            vec![(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.5, 1.2), (0.0, 1.0)],
        ),
    ] {
        let id = ctx.gen_object();
        ctx.begin_object(id).unwrap();
        ctx.begin(kind).unwrap();
        for (x, y) in verts {
            ctx.vertex(Vec3::new(x, y, 0.0)).unwrap();
        }
        ctx.end().unwrap();
        ctx.end_object().unwrap();
        let inst = ctx.instantiate(id).unwrap();
        ctx.commit().unwrap();
        let scene = ctx.scene();
        for (x, y) in [(0.1, 0.1), (0.9, 0.1), (0.5, 0.5), (0.1, 0.9), (0.9, 0.9)] {
            assert!(scene.intersect(&down(x, y)).is_some(), "{kind:?} covers ({x}, {y})");
        }
        assert!(scene.intersect(&down(1.5, 0.5)).is_none());
        ctx.remove_instance(inst).unwrap();
    }
}
