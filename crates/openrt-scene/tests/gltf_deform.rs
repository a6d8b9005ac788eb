//! glTF skins and morph targets, made by the tests themselves: a two-bone
//! skin and an animated morph target whose deformed vertices are checked
//! against positions computed here from the glTF specification's formulas
//! (not with the loader's code); the motion classes they fall into; the
//! scene, animation and camera choices; and every refusal as a typed error
//! naming the file and the JSON path.

use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec3};
use openrt_scene::{GltfAnimation, GltfOptions, GltfPlayer, MotionClasses, ScenePlayer};
use serde_json::{Value, json};

#[path = "common/gltf_builder.rs"]
mod gltf_builder;
use gltf_builder::Builder;

/// Every world-space triangle vertex of the scene.
fn world_vertices(p: &GltfPlayer) -> Vec<Vec3> {
    scene_vertices(&p.ctx.scene())
}

/// Every world-space triangle vertex of `scene`, instance by instance.
fn scene_vertices(scene: &openrt_core::Scene) -> Vec<Vec3> {
    scene
        .instances()
        .iter()
        .flat_map(|r| {
            let m = r.to_world;
            r.geometry
                .tree
                .triangles()
                .iter()
                .flat_map(move |t| t.map(|v| m.transform_point3(v)))
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Asserts that every point of `want` is a vertex of the scene (1e-5).
fn has_vertices(p: &GltfPlayer, want: &[Vec3], what: &str) {
    let got = world_vertices(p);
    for w in want {
        assert!(
            got.iter().any(|g| (*g - *w).length() < 1e-5),
            "{what}: no vertex at {w}; the scene has {got:?}"
        );
    }
}

/// A strip of two quads along x (x = 0, 1, 2; y = +-0.5) skinned to two
/// joints: joint 0 at the origin, joint 1 its child at x = 1, rotated by
/// `rotation` keys (LINEAR, at t = 0 and 1). The mesh node sits at x = 100:
/// skinned meshes ignore their node's transform.
fn two_bone(b: &mut Builder, weights: &[f32], joints: &[u16]) -> Value {
    let pos = b.floats(
        &[
            0.0, -0.5, 0.0, 0.0, 0.5, 0.0, 1.0, -0.5, 0.0, 1.0, 0.5, 0.0, 2.0, -0.5, 0.0, 2.0, 0.5, 0.0,
        ],
        "VEC3",
        3,
    );
    let nrm = b.floats(&[0.0, 0.0, 1.0].repeat(6), "VEC3", 3);
    let idx = b.indices(&[0, 2, 3, 0, 3, 1, 2, 4, 5, 2, 5, 3]);
    let j = b.shorts(joints, "VEC4", 4);
    let w = b.floats(weights, "VEC4", 4);
    let ibm = {
        let mut m = Mat4::IDENTITY.to_cols_array().to_vec();
        m.extend(Mat4::from_translation(Vec3::new(-1.0, 0.0, 0.0)).to_cols_array());
        b.floats(&m, "MAT4", 16)
    };
    let q = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
    let input = b.floats(&[0.0, 1.0], "SCALAR", 1);
    let output = b.floats(&[0.0, 0.0, 0.0, 1.0, q.x, q.y, q.z, q.w], "VEC4", 4);
    json!({
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [
            {"mesh": 0, "skin": 0, "translation": [100.0, 0.0, 0.0]},
            {"children": [2]},
            {"translation": [1.0, 0.0, 0.0]}
        ],
        "skins": [{"joints": [1, 2], "inverseBindMatrices": ibm}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm, "JOINTS_0": j, "WEIGHTS_0": w}, "indices": idx}]}],
        "animations": [{"name": "bend", "channels": [{"sampler": 0, "target": {"node": 2, "path": "rotation"}}],
            "samplers": [{"input": input, "output": output}]}]
    })
}

/// Weights: x = 0 on joint 0, x = 1 half and half, x = 2 on joint 1.
const WEIGHTS: [f32; 24] = [
    1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0,
    0.0,
];
const JOINTS: [u16; 24] = [0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0];

fn open(path: &Path) -> GltfPlayer {
    match ScenePlayer::open(Some(path)).unwrap_or_else(|e| panic!("{}: {e}", path.display())) {
        ScenePlayer::Gltf(g) => *g,
        _ => panic!("a .gltf opens as a glTF player"),
    }
}

#[test]
fn a_two_bone_skin_bends_with_its_joints_as_the_specification_computes() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    let doc = two_bone(&mut b, &WEIGHTS, &JOINTS);
    let path = b.write_gltf(dir.path(), "skin", doc);
    let mut p = open(&path);
    assert!(p.warnings().is_empty(), "{:?}", p.warnings());
    assert_eq!(
        p.motion_classes(),
        MotionClasses {
            static_instances: 0,
            affine_instances: 0,
            deforming_objects: 1,
            deforming_triangles: 4
        }
    );
    assert_eq!(p.frames(), 31);
    // At rest the bind pose: the mesh as given, not moved to x = 100.
    let rest: Vec<Vec3> = [0.0f32, 1.0, 2.0]
        .iter()
        .flat_map(|&x| [Vec3::new(x, -0.5, 0.0), Vec3::new(x, 0.5, 0.0)])
        .collect();
    has_vertices(&p, &rest, "rest");
    for t in [0.25f32, 0.5, 1.0] {
        let stats = p.set_time(t).unwrap();
        assert_eq!(stats.builds.len(), 1, "only the skinned object is redefined");
        // The specification's sum: v' = sum_i w_i * world(joint_i) * IBM_i * v.
        let j0 = Mat4::IDENTITY;
        let j1 = Mat4::from_translation(Vec3::X)
            * Mat4::from_quat(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2 * t))
            * Mat4::from_translation(-Vec3::X);
        let want: Vec<Vec3> = rest
            .iter()
            .map(|&v| {
                let w1 = (v.x / 2.0).clamp(0.0, 1.0);
                j0.transform_point3(v) * (1.0 - w1) + j1.transform_point3(v) * w1
            })
            .collect();
        has_vertices(&p, &want, &format!("t = {t}"));
    }
    // At t = 1 the tip is turned by a quarter: (2, 0.5) -> (0.5, 1).
    has_vertices(&p, &[Vec3::new(0.5, 1.0, 0.0)], "tip");
    // Later frames refit the redefined object's last tree.
    let again = p.set_time(0.5).unwrap();
    assert!(again.builds.iter().all(|b| b.refitted), "{:?}", again.builds);
}

#[test]
fn morph_targets_follow_their_animated_weights_and_rest_weights_deform_once() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    let pos = b.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0], "VEC3", 3);
    let idx = b.indices(&[0, 1, 2, 0, 2, 3]);
    // Target 0 lifts vertex 2 by 1 in z; target 1 moves vertex 3 by -1 in x.
    let t0 = b.floats(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], "VEC3", 3);
    let t1 = b.floats(
        &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0],
        "VEC3",
        3,
    );
    let input = b.floats(&[0.0, 2.0], "SCALAR", 1);
    let output = b.floats(&[0.0, 0.0, 1.0, 0.5], "SCALAR", 1);
    let doc = json!({
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [
            {"mesh": 0, "translation": [0.0, 0.0, -3.0]},
            {"mesh": 0, "translation": [5.0, 0.0, 0.0], "weights": [0.0, 1.0]},
            {"mesh": 0, "translation": [-5.0, 0.0, 0.0]}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx, "targets": [{"POSITION": t0}, {"POSITION": t1}]}],
            "weights": [0.0, 0.0]}],
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
            "samplers": [{"input": input, "output": output}]}]
    });
    let path = b.write_glb(dir.path(), "morph", doc);
    let mut p = open(&path);
    assert_eq!(
        p.motion_classes(),
        MotionClasses {
            static_instances: 2,
            affine_instances: 0,
            deforming_objects: 1,
            deforming_triangles: 2
        },
        "node 0 deforms; node 1's rest weights deform it once; node 2 shares the mesh's object"
    );
    assert_eq!(p.frames(), 61, "a morph-weight animation alone sets the length: 2 s");
    // Node 1 at rest weights (0, 1): vertex 3 moved to x = -1.
    has_vertices(&p, &[Vec3::new(4.0, 1.0, 0.0)], "node 1 at its rest weights");
    for (t, w0, w1) in [(0.0, 0.0, 0.0), (1.0, 0.5, 0.25), (2.0, 1.0, 0.5)] {
        p.set_time(t).unwrap();
        has_vertices(
            &p,
            &[
                Vec3::new(1.0, 1.0, -3.0 + w0),
                Vec3::new(-w1, 1.0, -3.0),
                Vec3::new(-4.0, 1.0, 0.0),
            ],
            &format!("t = {t}"),
        );
    }
    let scene = p.ctx.scene();
    let objects: std::collections::HashSet<_> = scene.instances().iter().map(|r| r.object).collect();
    assert_eq!(
        objects.len(),
        3,
        "two deformed nodes have objects of their own, one shares the mesh's"
    );
}

/// Loads with `options`, expecting an error holding every one of `want`.
fn refused_with(path: &Path, options: &GltfOptions, want: &[&str]) {
    let Err(e) = GltfPlayer::load_with(path, options) else {
        panic!("{options:?}: loaded");
    };
    let text = e.to_string();
    assert!(
        text.contains(&path.file_name().unwrap().to_string_lossy().to_string()),
        "{text}"
    );
    for w in want {
        assert!(text.contains(w), "'{w}' not in: {text}");
    }
}

fn write(dir: &Path, name: &str, b: &mut Builder, doc: Value) -> PathBuf {
    b.write_gltf(dir, name, doc)
}

#[test]
fn broken_skins_and_morphs_are_typed_errors_naming_the_place() {
    let dir = tempfile::tempdir().unwrap();
    let none = GltfOptions::default();
    // A vertex naming joint 5 of a two-joint skin.
    let mut joints = JOINTS;
    joints[9] = 5;
    let mut b = Builder::default();
    let doc = two_bone(&mut b, &WEIGHTS, &joints);
    let path = write(dir.path(), "joint", &mut b, doc);
    refused_with(
        &path,
        &none,
        &["meshes[0].primitives[0]", "joint 5", "skins[0]", "2 joints"],
    );
    // Weights summing to zero; negative weights.
    for (name, bad, rule) in [("zero", 0.0, "sum to zero"), ("negative", -0.5, "negative")] {
        let mut w = WEIGHTS;
        w[0] = bad;
        let mut b = Builder::default();
        let doc = two_bone(&mut b, &w, &JOINTS);
        let path = write(dir.path(), name, &mut b, doc);
        refused_with(&path, &none, &["meshes[0].primitives[0]", "vertex 0", rule]);
    }
    // Weights that do not sum to one are normalized, with a warning.
    let mut w = WEIGHTS;
    w[8] = 0.25;
    let mut b = Builder::default();
    let doc = two_bone(&mut b, &w, &JOINTS);
    let path = write(dir.path(), "unnormalized", &mut b, doc);
    let p = GltfPlayer::load(&path).unwrap();
    assert!(
        p.warnings().iter().any(|w| w.to_string().contains("normalized")),
        "{:?}",
        p.warnings()
    );
    // JOINTS_0 without WEIGHTS_0.
    let mut b = Builder::default();
    let mut doc = two_bone(&mut b, &WEIGHTS, &JOINTS);
    doc["meshes"][0]["primitives"][0]["attributes"]
        .as_object_mut()
        .unwrap()
        .remove("WEIGHTS_0");
    let path = write(dir.path(), "noweights", &mut b, doc);
    refused_with(&path, &none, &["JOINTS_0 and WEIGHTS_0 must come together"]);
    // A skinned node whose mesh has no influences.
    let mut b = Builder::default();
    let mut doc = two_bone(&mut b, &WEIGHTS, &JOINTS);
    let attrs = doc["meshes"][0]["primitives"][0]["attributes"].as_object_mut().unwrap();
    attrs.remove("WEIGHTS_0");
    attrs.remove("JOINTS_0");
    let path = write(dir.path(), "unskinned", &mut b, doc);
    refused_with(&path, &none, &["nodes[0] is skinned by skins[0]", "no JOINTS_0"]);
    // Too few inverse bind matrices.
    let mut b = Builder::default();
    let mut doc = two_bone(&mut b, &WEIGHTS, &JOINTS);
    doc["skins"][0]["joints"] = json!([1, 2, 0]);
    let path = write(dir.path(), "ibm", &mut b, doc);
    refused_with(&path, &none, &["skins[0]", "2 inverse bind matrices for 3 joints"]);
    // Joints given as floats: the wrong accessor type.
    let mut b = Builder::default();
    let mut doc = two_bone(&mut b, &WEIGHTS, &JOINTS);
    doc["meshes"][0]["primitives"][0]["attributes"]["JOINTS_0"] =
        doc["meshes"][0]["primitives"][0]["attributes"]["WEIGHTS_0"].clone();
    let path = write(dir.path(), "floatjoints", &mut b, doc);
    refused_with(&path, &none, &["meshes[0].primitives[0]", "Vec4"]);
}

#[test]
fn scenes_animations_and_cameras_are_chosen_by_index_or_name() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    let mut doc = two_bone(&mut b, &WEIGHTS, &JOINTS);
    // A second animation, "slide", moving a second node over three seconds,
    // and a second scene holding only that node; two cameras.
    let input = b.floats(&[0.0, 3.0], "SCALAR", 1);
    let output = b.floats(&[0.0, 0.0, 0.0, 6.0, 0.0, 0.0], "VEC3", 3);
    let quad = b.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], "VEC3", 3);
    doc["meshes"]
        .as_array_mut()
        .unwrap()
        .push(json!({"primitives": [{"attributes": {"POSITION": quad}}]}));
    let nodes = doc["nodes"].as_array_mut().unwrap();
    nodes.push(json!({"mesh": 1, "translation": [0.0, 5.0, 0.0]}));
    nodes.push(json!({"camera": 0, "translation": [0.0, 0.0, 9.0]}));
    nodes.push(json!({"camera": 1, "translation": [0.0, 0.0, 7.0]}));
    doc["cameras"] = json!([
        {"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.1}},
        {"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1}}
    ]);
    doc["scenes"] = json!([{"nodes": [0, 1, 3, 4, 5]}, {"nodes": [3, 5]}]);
    doc["animations"].as_array_mut().unwrap().push(json!({"name": "slide",
        "channels": [{"sampler": 0, "target": {"node": 3, "path": "translation"}}],
        "samplers": [{"input": input, "output": output}]}));
    let path = write(dir.path(), "choices", &mut b, doc);

    let first = GltfPlayer::load(&path).unwrap();
    assert!(first.warnings().iter().any(|w| w.to_string().contains("2 animations")));
    assert_eq!(first.frames(), 31, "the first animation: one second");
    assert_eq!(first.camera(0.0).from.z, 9.0, "the first camera met");
    let with = |animation: GltfAnimation, scene: Option<usize>, camera: Option<usize>| {
        GltfPlayer::load_with(
            &path,
            &GltfOptions {
                scene,
                animation,
                camera,
            },
        )
        .unwrap()
    };
    let slide = with("slide".parse().unwrap(), None, None);
    assert_eq!(slide.frames(), 91, "three seconds");
    assert_eq!(slide.motion_classes().affine_instances, 1);
    assert_eq!(
        slide.motion_classes().deforming_objects,
        0,
        "the skin's joints are still"
    );
    assert_eq!(with(GltfAnimation::Index(1), None, None).frames(), 91);
    let all = with(GltfAnimation::All, None, None);
    assert_eq!(all.frames(), 91, "looping over the longest");
    assert_eq!(all.motion_classes().deforming_objects, 1);
    assert_eq!(all.motion_classes().affine_instances, 1);
    let still = with(GltfAnimation::None, None, None);
    assert_eq!(still.frames(), 1);
    assert_eq!(still.motion_classes().static_instances, 2);
    let second = with(GltfAnimation::First, Some(1), Some(1));
    assert_eq!(second.ctx.scene().instances().len(), 1, "scene 1 holds one mesh node");
    assert_eq!(second.camera(0.0).from.z, 7.0, "camera 1");

    refused_with(
        &path,
        &GltfOptions {
            animation: "walk".parse().unwrap(),
            ..GltfOptions::default()
        },
        &["animations", "\"walk\"", "0 \"bend\", 1 \"slide\""],
    );
    refused_with(
        &path,
        &GltfOptions {
            animation: GltfAnimation::Index(2),
            ..GltfOptions::default()
        },
        &["--animation 2", "2 animations"],
    );
    refused_with(
        &path,
        &GltfOptions {
            scene: Some(2),
            ..GltfOptions::default()
        },
        &["--scene 2", "2 scenes"],
    );
    refused_with(
        &path,
        &GltfOptions {
            scene: Some(1),
            camera: Some(0),
            ..GltfOptions::default()
        },
        &["--camera 0", "[1]"],
    );
}

#[test]
fn a_gltf_object_in_a_ron_scene_plays_its_file_and_moves_with_its_instance() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    std::fs::copy(root.join("scenes/walker.glb"), dir.path().join("walker.glb")).unwrap();
    let ron = dir.path().join("room.ron");
    // "rest" is the file at rest (static), "walk" plays its first animation
    // (redefined every frame), each moved by its instance's keys.
    std::fs::write(
        &ron,
        r#"(version: 2, animation: Some((start: 0.0, end: 1.0, frames: 2)),
            materials: {"green": (diffuse: (0.2, 0.7, 0.3))},
            objects: {
                "rest": Gltf(path: "walker.glb", material: Some("green"), animation: Some("none")),
                "walk": Gltf(path: "walker.glb", material: Some("green")),
            },
            instances: [
                (object: "rest", keys: Some((translate: [(0.0, (0.0, 0.0, 0.0)), (1.0, (5.0, 0.0, 0.0))]))),
                (object: "walk"),
            ])"#,
    )
    .unwrap();
    let mut scene = openrt_scene::load_ron(&ron).unwrap_or_else(|e| panic!("{e}"));
    let walker = root.join("scenes/walker.glb");
    // The oracles: the glTF player's own world-space triangles, at rest and playing.
    let at_rest = GltfPlayer::load_with(
        &walker,
        &GltfOptions {
            animation: GltfAnimation::None,
            ..GltfOptions::default()
        },
    )
    .unwrap();
    let mut playing = GltfPlayer::load(&walker).unwrap();
    let sorted = |v: Vec<Vec3>| {
        let mut v: Vec<[f32; 3]> = v.iter().map(Vec3::to_array).collect();
        v.sort_by(|a, b| a.partial_cmp(b).unwrap());
        v
    };
    // The two instances' vertices: "rest" first (instances in file order).
    let split = |s: &openrt_scene::LoadedScene| -> (Vec<Vec3>, Vec<Vec3>) {
        let sc = s.ctx.scene();
        let v = scene_vertices(&sc);
        let n = sc.instances()[0].geometry.tree.triangles().len() * 3;
        (v[..n].to_vec(), v[n..].to_vec())
    };
    let want_rest = sorted(world_vertices(&at_rest));
    let (rest0, walk0) = split(&scene);
    assert!(
        sorted(rest0.clone()) == want_rest,
        "at rest: the file's triangles in its world space"
    );
    assert!(
        sorted(walk0.clone()) == sorted(world_vertices(&playing)),
        "playing: the file's pose at the start time"
    );
    let m = scene.motion_classes();
    assert_eq!(m.deforming_objects, 1, "{m}");
    assert_eq!(m.deforming_triangles * 3, walk0.len(), "{m}");
    scene.set_time(1.0).unwrap();
    playing.set_time(1.0).unwrap();
    let (rest1, walk1) = split(&scene);
    assert_eq!(rest1.len(), rest0.len());
    assert!(
        rest1
            .iter()
            .zip(&rest0)
            .all(|(a, b)| (*a - *b - Vec3::X * 5.0).length() < 1e-5),
        "the instance key moves the figure at rest"
    );
    let walk1 = sorted(walk1);
    assert!(
        walk1 == sorted(world_vertices(&playing)),
        "playing: the file's pose at t = 1"
    );
    assert!(walk1 != sorted(walk0), "the figure deforms");
    // A choice the file lacks names what it has.
    std::fs::write(
        &ron,
        r#"(version: 2, objects: {"f": Gltf(path: "walker.glb", animation: Some("Dance"))}, instances: [(object: "f")])"#,
    )
    .unwrap();
    let e = openrt_scene::load_ron(&ron)
        .err()
        .expect("an unknown animation is an error");
    assert!(e.to_string().contains("Dance"), "{e}");
    // A missing file names it.
    std::fs::write(
        &ron,
        r#"(version: 2, objects: {"f": Gltf(path: "nowhere.glb")}, instances: [(object: "f")])"#,
    )
    .unwrap();
    let e = openrt_scene::load_ron(&ron)
        .err()
        .expect("a missing glTF file is an error");
    assert!(e.to_string().contains("nowhere.glb"), "{e}");
}

/// A RON file can wrap a whole glTF scene (its cameras, lights, materials
/// and animation), as it wraps BART scenes: the same player as opening the
/// file itself with the same choices.
#[test]
fn a_ron_file_wraps_a_whole_gltf_scene() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    std::fs::copy(root.join("scenes/walker.glb"), dir.path().join("walker.glb")).unwrap();
    let ron = dir.path().join("wrap.ron");
    let write = |text: &str| std::fs::write(&ron, text).unwrap();
    write(r#"(version: 2, gltf: Some((path: "walker.glb", scene: Some(0), animation: Some("walk"))), accel: Bvh)"#);
    let mut wrapped = match ScenePlayer::open(Some(&ron)).unwrap_or_else(|e| panic!("{e}")) {
        ScenePlayer::Gltf(g) => *g,
        _ => panic!("a glTF wrapper opens as a glTF player"),
    };
    let mut direct = GltfPlayer::load(&root.join("scenes/walker.glb")).unwrap();
    assert_eq!(wrapped.frames(), direct.frames());
    assert_eq!(wrapped.motion_classes(), direct.motion_classes());
    wrapped.set_time(0.7).unwrap();
    direct.set_time(0.7).unwrap();
    assert_eq!(world_vertices(&wrapped), world_vertices(&direct), "the same pose");
    assert_eq!(wrapped.camera(0.7), direct.camera(0.7));
    // The wrapper's choices and refusals.
    write(r#"(version: 2, gltf: Some((path: "walker.glb", animation: Some("none"))))"#);
    assert_eq!(ScenePlayer::open(Some(&ron)).unwrap().frames(), 1, "at rest");
    for (text, needle) in [
        (r#"(version: 1, gltf: Some((path: "walker.glb")))"#, "version: 2"),
        (r#"(version: 2, gltf: Some((path: "nowhere.glb")))"#, "nowhere.glb"),
        (
            r#"(version: 2, gltf: Some((path: "walker.glb", camera: Some(7))))"#,
            "--camera 7",
        ),
        (
            r#"(version: 2, gltf: Some((path: "walker.glb")), objects: {"b": Box(min: (0.0, 0.0, 0.0), max: (1.0, 1.0, 1.0))})"#,
            "cannot also",
        ),
    ] {
        write(text);
        let e = ScenePlayer::open(Some(&ron))
            .err()
            .unwrap_or_else(|| panic!("accepted: {text}"));
        assert!(e.to_string().contains(needle), "{text}: {e}");
    }
    write(r#"(version: 2, gltf: Some((path: "walker.glb")))"#);
    assert!(openrt_scene::load_ron(&ron).is_err(), "load_ron names the wrapper");
}
