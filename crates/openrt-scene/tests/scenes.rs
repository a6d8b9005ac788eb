//! Shipped scenes against golden images, and malformed input.
//!
//! Goldens live in `tests/golden/` at the repository root; regenerate them
//! with `OPENRT_BLESS=1 cargo test -p openrt-scene --test scenes` after an
//! intended change, and look at them before committing.

use std::path::{Path, PathBuf};

mod common;

use openrt_core::{Image, RenderMode, RenderSettings, Renderer};
use openrt_scene::{SceneError, load_ron, load_ron_str};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn render(scene: &Path, mode: RenderMode) -> Image {
    let s = load_ron(scene).unwrap_or_else(|e| panic!("{e}"));
    frame(&s.ctx.scene(), &s.env, &s.camera, mode)
}

/// A 160 x 120 frame of depth 3 on two threads, as the goldens are made.
fn frame(
    scene: &openrt_core::Scene,
    env: &openrt_core::Environment,
    camera: &openrt_core::Camera,
    mode: RenderMode,
) -> Image {
    let settings = RenderSettings {
        width: 160,
        height: 120,
        mode,
        max_depth: 3,
        ..RenderSettings::default()
    };
    Renderer::new(2)
        .expect("a render pool")
        .render(scene, env, camera, &settings)
        .unwrap()
        .0
}

#[test]
fn shipped_scenes_match_their_golden_images() {
    for scene in ["room", "slab", "textured"] {
        for (mode, tag) in [(RenderMode::GlLike, "gl"), (RenderMode::Whitted, "whitted")] {
            let img = render(&repo().join(format!("scenes/{scene}.ron")), mode);
            common::check_golden(&format!("{scene}-{tag}"), &img, 1.0, 0.005);
        }
    }
}

/// The shipped glTF scene mid-animation (the tube skinned and bent, the
/// crate turned) against its golden frame.
#[test]
fn the_shipped_gltf_scene_matches_its_golden_frame() {
    let mut p = openrt_scene::ScenePlayer::open(Some(&repo().join("scenes/walker.glb"))).unwrap();
    let t = p.time_of(12);
    p.set_time(t).unwrap();
    for (mode, tag) in [(RenderMode::GlLike, "gl"), (RenderMode::Whitted, "whitted")] {
        let img = frame(&p.ctx().scene(), &p.env(), &p.camera(t), mode);
        common::check_golden(&format!("walker-f12-{tag}"), &img, 1.0, 0.005);
    }
}

/// The shipped RON scene with glTF figures: the room with two instances of
/// one skinned figure mid-stride (redefined every frame), one turned on
/// its keys, against golden frames.
#[test]
fn the_walker_room_matches_its_golden_frames() {
    let mut s = load_ron(&repo().join("scenes/walker-room.ron")).unwrap_or_else(|e| panic!("{e}"));
    let m = s.motion_classes();
    assert_eq!((m.affine_instances, m.deforming_objects), (1, 1), "{m}");
    let t = s.animation.expect("an animated scene").time(15);
    s.set_time(t).unwrap();
    for (mode, tag) in [(RenderMode::GlLike, "gl"), (RenderMode::Whitted, "whitted")] {
        let img = frame(&s.ctx.scene(), &s.env, &s.camera_at(t), mode);
        common::check_golden(&format!("walker-room-f15-{tag}"), &img, 1.0, 0.005);
    }
}

#[test]
fn the_golden_check_catches_a_changed_image() {
    let mut img = render(&repo().join("scenes/room.ron"), RenderMode::GlLike);
    for p in img.pixels.iter_mut().take(2000) {
        *p = glam::Vec3::ONE - *p;
    }
    let r = std::panic::catch_unwind(|| common::compare_golden("room-gl", &img, 1.0, 0.005));
    assert!(r.is_err());
}

#[test]
fn the_built_in_scene_is_the_shipped_room() {
    let text = std::fs::read_to_string(repo().join("scenes/room.ron")).unwrap();
    assert_eq!(text, openrt_scene::DEFAULT_SCENE_RON);
    let s = openrt_scene::default_scene().unwrap();
    assert_eq!(s.ctx.scene().instances().len(), 8);
}

fn err(text: &str) -> SceneError {
    match load_ron_str(text, Path::new("bad.ron")) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e,
    }
}

#[test]
fn a_missing_texture_names_the_file() {
    let text = r#"(version: 1, textures: {"t": "no/such/wood.ppm"}, materials: {"m": (texture: Some("t"))},
                  objects: {}, instances: [])"#;
    let e = err(text);
    let msg = e.to_string();
    assert!(matches!(e, SceneError::Texture { .. }), "{msg}");
    assert!(msg.contains("no/such/wood.ppm") && msg.contains("bad.ron"), "{msg}");
}

#[test]
fn emission_textures_are_read_and_an_unknown_one_is_named() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("glow.ppm"), b"P6\n1 1\n255\n\xff\x80\x00").unwrap();
    let text = r#"(version: 1, textures: {"glow": "glow.ppm"},
                  materials: {"m": (emission: (1.0, 1.0, 1.0), emission_texture: Some("glow"))},
                  objects: {}, instances: [])"#;
    let s = load_ron_str(text, &dir.path().join("s.ron")).unwrap_or_else(|e| panic!("{e}"));
    let scene = s.ctx.scene();
    let m = scene
        .materials()
        .iter()
        .find(|m| m.emission_texture.is_some())
        .expect("read");
    assert_eq!(m.texture, None);
    let e = err(r#"(version: 1, materials: {"m": (emission_texture: Some("nowhere"))}, objects: {}, instances: [])"#);
    assert!(
        matches!(e, SceneError::Undefined { .. }) && e.to_string().contains("nowhere"),
        "{e}"
    );
}

#[test]
fn a_corrupt_texture_is_an_error_not_a_panic() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::write(dir.join("bad.ppm"), b"P6\n64 64\n255\n\x01\x02").unwrap();
    let scene = dir.join("s.ron");
    std::fs::write(
        &scene,
        r#"(version: 1, textures: {"t": "bad.ppm"}, objects: {}, instances: [])"#,
    )
    .unwrap();
    let e = load_ron(&scene).err().expect("truncated PPM");
    assert!(e.to_string().contains("bad.ppm"), "{e}");
}

#[test]
fn malformed_scenes_give_file_line_and_column() {
    let e = err("(version: 1,\n  objects: {},\n  instances: [ (object: ] )");
    match &e {
        SceneError::Parse { line, col, .. } => assert_eq!((*line, *col > 0), (3, true), "{e}"),
        other => panic!("{other}"),
    }
    assert!(e.to_string().starts_with("bad.ron:3:"), "{e}");
    // Unknown field: a typo is reported, not ignored.
    assert!(matches!(
        err("(version: 1, objcts: {}, instances: [])"),
        SceneError::Parse { .. }
    ));
    assert!(matches!(
        err("(version: 7, objects: {}, instances: [])"),
        SceneError::Version { found: 7, .. }
    ));
    assert!(matches!(
        err("(version: 1, objects: {}, instances: [(object: \"ghost\")])"),
        SceneError::Undefined { what: "object", .. }
    ));
    assert!(matches!(
        err("(version: 1, objects: {\"a\": Box(min: (0,0,0), max: (1,1,1), material: Some(\"nope\"))}, instances: [])"),
        SceneError::Undefined { what: "material", .. }
    ));
    // Bad index, NaN vertex, wrong counts.
    assert!(matches!(
        err(
            "(version: 1, objects: {\"m\": Mesh(vertices: [(0,0,0), (1,0,0), (0,1,0)], triangles: [(0, 1, 3)])}, instances: [])"
        ),
        SceneError::Invalid { .. }
    ));
    assert!(matches!(
        err(
            "(version: 1, objects: {\"m\": Mesh(vertices: [(0,0,0), (1,0,0), (NaN,1,0)], triangles: [(0, 1, 2)])}, instances: [])"
        ),
        SceneError::Core {
            source: openrt_core::CoreError::NonFinite { call: "vertex", .. },
            ..
        }
    ));
    assert!(matches!(
        err(
            "(version: 1, objects: {\"m\": Mesh(vertices: [(0,0,0), (1,0,0), (0,1,0)], triangles: [(0, 1, 2)], normals: Some([(0,0,1)]))}, instances: [])"
        ),
        SceneError::Invalid { .. }
    ));
    assert!(matches!(
        err("(version: 1, objects: {\"q\": Quad(corners: [(0,0,0), (1,0,0), (1,1,0)])}, instances: [])"),
        SceneError::Invalid { .. }
    ));
    assert!(matches!(
        err(
            "(version: 1, objects: {\"b\": Box(min: (0,0,0), max: (1,1,1))}, instances: [(object: \"b\", transform: [Scale((1, 0, 1))])])"
        ),
        SceneError::Core {
            source: openrt_core::CoreError::SingularTransform { .. },
            ..
        }
    ));
    assert!(matches!(
        err("(version: 1, camera: (from: (0,0,0), at: (0,0,0)), objects: {}, instances: [])"),
        SceneError::Invalid { .. }
    ));
    // A missing scene file names the file.
    let e = load_ron(Path::new("/no/such/scene.ron")).err().unwrap();
    assert!(e.to_string().contains("/no/such/scene.ron"));
}

/// `accel: Kd` in a scene file puts kd-trees under its objects (BVHs by
/// default), and the image is the BVH scene's, byte for byte.
#[test]
fn a_scene_file_chooses_its_structure() {
    let text = std::fs::read_to_string(repo().join("scenes/room.ron")).unwrap();
    let bvh = load_ron_str(&text, &repo().join("scenes/room.ron")).unwrap();
    let end = text.rfind(')').expect("a RON struct");
    let with_kd = format!("{}, accel: Kd)", text[..end].trim_end().trim_end_matches(','));
    let kd = load_ron_str(&with_kd, &repo().join("scenes/room.ron")).unwrap();
    let accels = |s: &openrt_scene::LoadedScene| -> Vec<openrt_core::Accel> {
        s.ctx
            .scene()
            .instances()
            .iter()
            .map(|i| i.geometry.tree.accel())
            .collect()
    };
    assert!(accels(&kd).iter().all(|a| *a == openrt_core::Accel::Kd));
    assert!(!accels(&bvh).is_empty() && accels(&bvh).iter().all(|a| *a == openrt_core::Accel::Bvh));
    let settings = RenderSettings {
        width: 80,
        height: 60,
        max_depth: 3,
        ..RenderSettings::default()
    };
    let img = |s: &openrt_scene::LoadedScene| {
        Renderer::new(2)
            .expect("a render pool")
            .render(&s.ctx.scene(), &s.env, &s.camera, &settings)
            .unwrap()
            .0
            .to_rgb8()
    };
    assert!(img(&kd) == img(&bvh), "the kd scene renders other bytes");
    let e = err(&format!(
        "{}, accel: Octree)",
        text[..end].trim_end().trim_end_matches(',')
    ));
    assert!(e.to_string().contains("Octree"), "{e}");
}
