//! The `Context` API driven by arbitrary call sequences: misuse, NaN, inf
//! and huge values, redefinitions, deletions, stale handles, commits, ray
//! queries and tiny renders. Beyond "no panic", it checks what the API
//! promises: a failed commit keeps the last scene; a hit's surface is
//! found; any-hit agrees with closest hit; packets give the single-ray
//! answers bit for bit.

#![no_main]

use std::sync::{Arc, Mutex, OnceLock};

use arbitrary::Arbitrary;
use glam::{Mat4, Vec2, Vec3};
use libfuzzer_sys::fuzz_target;
use openrt_accel::Ray;
use openrt_core::{
    Camera, Context, CoreError, Environment, InstanceId, Material, MaterialId, ObjectId, PointLight, PrimitiveKind,
    RenderMode, RenderSettings, Renderer, Texture,
};

#[derive(Arbitrary, Debug)]
enum Call {
    GenObject,
    BeginObject(u8),
    EndObject,
    AbortObject,
    DeleteObject(u8),
    Begin(u8),
    End,
    Vertex([f32; 3]),
    Normal([f32; 3]),
    ClearNormal,
    TexCoord([f32; 2]),
    CreateTexture(u8, u8, [f32; 3]),
    CreateMaterial([f32; 3], f32, f32, f32, Option<u8>, bool),
    Material(u8),
    Translate([f32; 3]),
    Rotate(f32, [f32; 3]),
    Scale([f32; 3]),
    LoadMatrix([f32; 16]),
    MultMatrix([f32; 16]),
    LoadIdentity,
    PushMatrix,
    PopMatrix,
    Instantiate(u8),
    SetInstanceTransform(u8, [f32; 16]),
    RemoveInstance(u8),
    SetPromoteAfter(Option<u8>),
    WaitForPromotions,
    Commit,
    Rays([f32; 3], [f32; 3], f32, f32),
    Render(u8, u8, u8, bool),
}

const KINDS: [PrimitiveKind; 6] = [
    PrimitiveKind::Triangles,
    PrimitiveKind::TriangleStrip,
    PrimitiveKind::TriangleFan,
    PrimitiveKind::Quads,
    PrimitiveKind::QuadStrip,
    PrimitiveKind::Polygon,
];

fn renderer() -> &'static Mutex<Renderer> {
    static R: OnceLock<Mutex<Renderer>> = OnceLock::new();
    R.get_or_init(|| Mutex::new(Renderer::new(1).expect("one render thread")))
}

fn pick<T: Copy>(list: &[T], i: u8) -> Option<T> {
    (!list.is_empty()).then(|| list[i as usize % list.len()])
}

/// Closest hit, any hit and 4-lane packets (sharing an origin, or an end
/// for shadow rays) agree on the rays around `o`.
fn check_rays(ctx: &Context, o: Vec3, d: Vec3, t0: f32, t1: f32) {
    let scene = ctx.scene();
    let rays: [Ray; 4] = std::array::from_fn(|k| {
        let jitter = Vec3::new(k as f32 * 0.01, (k as f32 * 0.7).sin() * 0.01, 0.0);
        Ray::new(o, d + jitter, t0, t1)
    });
    let packet = scene.intersect_packet(&rays, 0b1111);
    let occluded = scene.occluded_packet(&rays, 0b1111);
    // Shadow-like rays: from points around `o` to one target, as the
    // renderer's shadow packets (culled with the frustum of their end).
    let target = o + d;
    let shadow: [Ray; 4] = std::array::from_fn(|k| {
        let p = o + Vec3::new(0.0, k as f32 * 0.013, (k as f32).cos() * 0.011);
        Ray::new(p, target - p, t0.max(0.0), 1.0 - 1e-4)
    });
    let toward = scene.occluded_packet_toward(&shadow, 0b1111, target);
    for (k, r) in shadow.iter().enumerate() {
        assert_eq!(scene.occluded(r), toward & (1 << k) != 0, "shadow packet lane {k}");
    }
    for (k, r) in rays.iter().enumerate() {
        let hit = scene.intersect(r);
        assert_eq!(hit, packet[k], "packet lane {k} differs from the single ray");
        assert_eq!(scene.occluded(r), occluded & (1 << k) != 0, "occluded packet lane {k}");
        if let Some(h) = hit {
            assert!(scene.occluded(r), "a closest hit but no any-hit");
            assert!(h.t > 0.0 && h.t > r.t_min && h.t < r.t_max, "hit outside the interval");
            scene.surface(r, &h).expect("a hit of this scene has a surface");
        }
    }
}

fuzz_target!(|calls: Vec<Call>| {
    let mut ctx = Context::new();
    ctx.set_promote_after(None);
    let mut objects: Vec<ObjectId> = Vec::new();
    let mut instances: Vec<InstanceId> = Vec::new();
    let mut materials: Vec<MaterialId> = vec![MaterialId::DEFAULT];
    let mut textures = Vec::new();
    for call in calls.into_iter().take(400) {
        match call {
            Call::GenObject => objects.push(ctx.gen_object()),
            Call::BeginObject(i) => {
                if let Some(o) = pick(&objects, i) {
                    let _ = ctx.begin_object(o);
                }
            }
            Call::EndObject => {
                let _ = ctx.end_object();
            }
            Call::AbortObject => {
                let _ = ctx.abort_object();
            }
            Call::DeleteObject(i) => {
                if let Some(o) = pick(&objects, i) {
                    let _ = ctx.delete_object(o);
                }
            }
            Call::Begin(k) => {
                let _ = ctx.begin(KINDS[k as usize % KINDS.len()]);
            }
            Call::End => {
                let _ = ctx.end();
            }
            Call::Vertex(p) => {
                let _ = ctx.vertex(Vec3::from_array(p));
            }
            Call::Normal(n) => {
                let _ = ctx.normal(Vec3::from_array(n));
            }
            Call::ClearNormal => {
                let _ = ctx.clear_normal();
            }
            Call::TexCoord(uv) => {
                let _ = ctx.tex_coord(Vec2::from_array(uv));
            }
            Call::CreateTexture(w, h, c) => {
                let (w, h) = (usize::from(w % 8), usize::from(h % 8));
                if let Some(t) = Texture::new(w, h, vec![Vec3::from_array(c); w * h]) {
                    textures.push(ctx.create_texture(t));
                }
            }
            Call::CreateMaterial(diffuse, specular, transmission, ior, texture, one_sided) => {
                let m = Material {
                    diffuse: Vec3::from_array(diffuse),
                    specular: Vec3::splat(specular),
                    transmission,
                    ior,
                    texture: texture.and_then(|t| pick(&textures, t)),
                    one_sided,
                    ..Material::default()
                };
                if let Ok(id) = ctx.create_material(m) {
                    materials.push(id);
                }
            }
            Call::Material(i) => {
                let _ = ctx.material(pick(&materials, i).unwrap_or(MaterialId::DEFAULT));
            }
            Call::Translate(t) => {
                let _ = ctx.translate(Vec3::from_array(t));
            }
            Call::Rotate(deg, axis) => {
                let _ = ctx.rotate(deg, Vec3::from_array(axis));
            }
            Call::Scale(s) => {
                let _ = ctx.scale(Vec3::from_array(s));
            }
            Call::LoadMatrix(m) => {
                let _ = ctx.load_matrix(Mat4::from_cols_array(&m));
            }
            Call::MultMatrix(m) => {
                let _ = ctx.mult_matrix(Mat4::from_cols_array(&m));
            }
            Call::LoadIdentity => ctx.load_identity(),
            Call::PushMatrix => {
                let _ = ctx.push_matrix();
            }
            Call::PopMatrix => {
                let _ = ctx.pop_matrix();
            }
            Call::Instantiate(i) => {
                if let Some(o) = pick(&objects, i)
                    && let Ok(id) = ctx.instantiate(o)
                {
                    instances.push(id);
                }
            }
            Call::SetInstanceTransform(i, m) => {
                if let Some(id) = pick(&instances, i) {
                    let _ = ctx.set_instance_transform(id, Mat4::from_cols_array(&m));
                }
            }
            Call::RemoveInstance(i) => {
                if let Some(id) = pick(&instances, i) {
                    let _ = ctx.remove_instance(id);
                }
            }
            Call::SetPromoteAfter(n) => ctx.set_promote_after(n.map(u32::from)),
            Call::WaitForPromotions => ctx.wait_for_promotions(),
            Call::Commit => {
                let before = ctx.scene();
                if ctx.commit().is_err() {
                    assert!(Arc::ptr_eq(&before, &ctx.scene()), "a failed commit changed the scene");
                }
            }
            Call::Rays(o, d, t0, t1) => check_rays(&ctx, Vec3::from_array(o), Vec3::from_array(d), t0, t1),
            Call::Render(w, h, depth, whitted) => {
                let settings = RenderSettings {
                    width: u32::from(w % 6),
                    height: u32::from(h % 5),
                    mode: if whitted { RenderMode::Whitted } else { RenderMode::GlLike },
                    max_depth: u32::from(depth % 20),
                    ..RenderSettings::default()
                };
                let env = Arc::new(Environment {
                    lights: vec![PointLight {
                        position: Vec3::new(1.0, 3.0, 2.0),
                        color: Vec3::ONE,
                    }],
                    ..Environment::default()
                });
                let r = renderer().lock().unwrap_or_else(std::sync::PoisonError::into_inner);
                match r.render(&ctx.scene(), &env, &Camera::default(), &settings) {
                    Err(CoreError::RenderThread { reason }) => panic!("render thread failed: {reason}"),
                    Err(_) => {}
                    Ok((img, _)) => assert!(img.pixels.iter().all(|c| c.is_finite())),
                }
            }
        }
    }
});
