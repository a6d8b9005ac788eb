//! glTF 2.0 scenes made by the tests themselves (JSON with an external
//! buffer, and the same as a binary .glb): meshes instanced by nodes, node
//! animation with each interpolation, cameras, lights, strips and fans,
//! sparse accessors, and every refusal as a typed error naming the file and
//! the JSON path.

use std::path::{Path, PathBuf};

use glam::{Quat, Vec2, Vec3};
use openrt_accel::Ray;
use openrt_core::TextureWrap;
use openrt_scene::{GltfOptions, GltfPlayer, SceneError, ScenePlayer};
use serde_json::{Value, json};

#[path = "common/gltf_builder.rs"]
mod gltf_builder;
use gltf_builder::Builder;

/// A unit quad in the xy plane (two indexed triangles) as mesh 0.
fn quad(b: &mut Builder) -> Value {
    let pos = b.floats(
        &[-0.5, -0.5, 0.0, 0.5, -0.5, 0.0, 0.5, 0.5, 0.0, -0.5, 0.5, 0.0],
        "VEC3",
        3,
    );
    let idx = b.indices(&[0, 1, 2, 0, 2, 3]);
    json!([{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx, "material": 0}]}])
}

fn materials() -> Value {
    json!([{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.2, 0.1, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.5}}])
}

fn player(path: &Path) -> GltfPlayer {
    match ScenePlayer::open(Some(path)).unwrap_or_else(|e| panic!("{}: {e}", path.display())) {
        ScenePlayer::Gltf(g) => *g,
        _ => panic!("a .gltf opens as a glTF player"),
    }
}

/// The world box centre of each instance.
fn centres(p: &GltfPlayer) -> Vec<Vec3> {
    p.ctx
        .scene()
        .instances()
        .iter()
        .map(|r| (r.world_bounds.min + r.world_bounds.max) * 0.5)
        .collect()
}

#[test]
fn one_mesh_under_two_nodes_is_one_object_with_two_static_instances() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    let meshes = quad(&mut b);
    let doc = json!({
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"mesh": 0, "translation": [3.0, 0.0, 0.0]}],
        "meshes": meshes,
        "materials": materials(),
    });
    let path = b.write_gltf(dir.path(), "two", doc);
    let mut p = player(&path);
    let classes = p.motion_classes();
    assert_eq!((classes.static_instances, classes.affine_instances), (2, 0));
    assert_eq!(p.frames(), 1);
    p.set_time(0.0).unwrap();
    let scene = p.ctx.scene();
    assert_eq!(scene.instances().len(), 2);
    assert!(
        std::sync::Arc::ptr_eq(&scene.instances()[0].geometry, &scene.instances()[1].geometry),
        "real instancing: one object"
    );
    for x in [0.0, 3.0] {
        let hit = scene.intersect(&Ray::infinite(Vec3::new(x, 0.1, 5.0), -Vec3::Z));
        assert!(hit.is_some_and(|h| (h.t - 5.0).abs() < 1e-5), "x = {x}: {hit:?}");
    }
    assert!(
        scene
            .intersect(&Ray::infinite(Vec3::new(1.5, 0.0, 5.0), -Vec3::Z))
            .is_none()
    );
    // Without a camera the scene is framed; without lights one sits at the eye.
    let cam = p.camera(0.0);
    assert!((cam.at - Vec3::new(1.5, 0.0, 0.0)).length() < 1e-4, "{cam:?}");
    assert_eq!(p.env.lights.len(), 1);
    assert_eq!(p.env.lights[0].position, cam.from);
}

/// A node animated by `interpolation` on `property` with these keys, and a
/// child node under it; returns (path, the animated node's instance index).
#[allow(clippy::too_many_arguments)] // NOTE: the test matrix's axes, named at each call.
fn animated(
    dir: &Path,
    name: &str,
    path_kind: &str,
    interpolation: &str,
    times: &[f32],
    values: &[f32],
    comps: usize,
    glb: bool,
) -> PathBuf {
    let mut b = Builder::default();
    let meshes = quad(&mut b);
    let input = b.floats(times, "SCALAR", 1);
    let output = b.floats(values, if comps == 4 { "VEC4" } else { "VEC3" }, comps);
    // The output accessor of a VEC3 needs no bounds; drop them (they would
    // be the values' own, which is allowed anyway).
    let doc = json!({
        "scene": 0,
        "scenes": [{"nodes": [0, 2]}],
        "nodes": [
            {"mesh": 0, "children": [1]},
            {"mesh": 0, "translation": [0.0, 2.0, 0.0]},
            {"mesh": 0, "translation": [-5.0, 0.0, 0.0]}
        ],
        "meshes": meshes,
        "materials": materials(),
        "animations": [{
            "channels": [{"sampler": 0, "target": {"node": 0, "path": path_kind}}],
            "samplers": [{"input": input, "output": output, "interpolation": interpolation}]
        }],
    });
    if glb {
        b.write_glb(dir, name, doc)
    } else {
        b.write_gltf(dir, name, doc)
    }
}

#[test]
fn node_animation_moves_the_node_and_its_children_with_each_interpolation() {
    let dir = tempfile::tempdir().unwrap();
    let keys = [0.0, 0.0, 0.0, 2.0, 0.0, 0.0];
    for (interp, want_half) in [("LINEAR", 1.0), ("STEP", 0.0)] {
        for glb in [false, true] {
            let path = animated(
                dir.path(),
                &format!("t{interp}{glb}"),
                "translation",
                interp,
                &[0.0, 1.0],
                &keys,
                3,
                glb,
            );
            let mut p = player(&path);
            let classes = p.motion_classes();
            assert_eq!(
                (classes.static_instances, classes.affine_instances),
                (1, 2),
                "the node and its child move, the other stays"
            );
            assert_eq!(p.frames(), 31, "one second at 30 frames per second");
            p.set_time(0.5).unwrap();
            let c = centres(&p);
            // Instances in scene order: node 0, its child 1, node 2.
            assert!((c[0].x - want_half).abs() < 1e-5, "{interp} glb {glb}: {c:?}");
            assert!(
                (c[1] - Vec3::new(want_half, 2.0, 0.0)).length() < 1e-5,
                "the child follows: {c:?}"
            );
            assert!((c[2].x + 5.0).abs() < 1e-5, "{c:?}");
            p.set_time(1.0).unwrap();
            assert!((centres(&p)[0].x - 2.0).abs() < 1e-5);
            // The animation loops over its length.
            p.set_time(1.5).unwrap();
            assert!((centres(&p)[0].x - want_half).abs() < 1e-5);
        }
    }
    // A cubic spline: (in-tangent, value, out-tangent) per key.
    let spline = [
        0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0,
    ];
    let path = animated(
        dir.path(),
        "spline",
        "translation",
        "CUBICSPLINE",
        &[0.0, 1.0],
        &spline,
        3,
        false,
    );
    let mut p = player(&path);
    p.set_time(0.5).unwrap();
    // Hermite at s = 1/2: p1 / 2 + m0 * dt / 8 = 1 + 0.5.
    assert!((centres(&p)[0].x - 1.5).abs() < 1e-4, "{:?}", centres(&p));
    // Rotation by slerp: a quarter turn about z over one second.
    let q = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
    let rot = [0.0, 0.0, 0.0, 1.0, q.x, q.y, q.z, q.w];
    let path = animated(dir.path(), "rot", "rotation", "LINEAR", &[0.0, 1.0], &rot, 4, false);
    let mut p = player(&path);
    p.set_time(0.5).unwrap();
    // The child at (0, 2, 0) turned by an eighth of a turn about z.
    let want = Quat::from_rotation_z(std::f32::consts::FRAC_PI_4) * Vec3::new(0.0, 2.0, 0.0);
    assert!(
        (centres(&p)[1] - want).length() < 1e-4,
        "{:?} against {want}",
        centres(&p)
    );
}

#[test]
fn cameras_and_punctual_lights_come_from_their_nodes() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    let meshes = quad(&mut b);
    let doc = json!({
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1.0, 0.9, 0.8], "intensity": 10.0},
            {"type": "spot", "color": [0.5, 0.5, 0.5], "intensity": 5.0, "spot": {"outerConeAngle": 0.5}}
        ]}},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2, 3]}],
        "nodes": [
            {"mesh": 0},
            {"camera": 0, "translation": [0.0, 0.0, 5.0]},
            {"translation": [0.0, 3.0, 1.0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"translation": [1.0, 3.0, 1.0], "extensions": {"KHR_lights_punctual": {"light": 1}}}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.05}}],
        "meshes": meshes,
        "materials": materials(),
    });
    let path = b.write_gltf(dir.path(), "lit", doc);
    let p = player(&path);
    let cam = p.camera(0.0);
    assert_eq!(cam.from, Vec3::new(0.0, 0.0, 5.0));
    assert!(
        (cam.at - Vec3::new(0.0, 0.0, 4.0)).length() < 1e-6,
        "looks down -z: {cam:?}"
    );
    assert!((cam.fov_y_deg - 0.8f32.to_degrees()).abs() < 1e-4);
    assert_eq!(cam.near, 0.05);
    let lights: Vec<Vec3> = p.env.lights.iter().map(|l| l.position).collect();
    assert_eq!(lights, vec![Vec3::new(0.0, 3.0, 1.0), Vec3::new(1.0, 3.0, 1.0)]);
    assert_eq!(p.env.lights[0].color, Vec3::new(1.0, 0.9, 0.8));
    assert!(
        p.warnings().iter().any(|w| w.to_string().contains("spot light")),
        "the spot light is mapped with a warning: {:?}",
        p.warnings()
    );
}

#[test]
fn strips_fans_unindexed_and_sparse_primitives_are_drawn() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    // Four vertices of a unit square: as a strip (0 1 3 2 order) and a fan.
    let strip = b.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0], "VEC3", 3);
    let fan = b.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0], "VEC3", 3);
    // A sparse POSITION: a zero triangle whose vertex 2 is substituted.
    let base = b.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0], "VEC3", 3);
    let idx = b.indices(&[2, 0]);
    let vals = b.floats(&[0.0, 1.0, 0.0], "SCALAR", 1);
    let _ = vals;
    let sparse_view_idx = b.views.len() - 2;
    let sparse_view_val = b.views.len() - 1;
    let sparse = {
        let mut a = b.accessors[base].clone();
        a["max"] = json!([1.0, 1.0, 0.0]);
        a["sparse"] = json!({"count": 1, "indices": {"bufferView": sparse_view_idx, "componentType": 5123}, "values": {"bufferView": sparse_view_val}});
        b.accessors.push(a);
        b.accessors.len() - 1
    };
    let _ = idx;
    let doc = json!({
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [3.0, 0.0, 0.0]}, {"mesh": 2, "translation": [6.0, 0.0, 0.0]}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": strip}, "mode": 5}]},
            {"primitives": [{"attributes": {"POSITION": fan}, "mode": 6}]},
            {"primitives": [{"attributes": {"POSITION": sparse}}]}
        ],
    });
    let path = b.write_gltf(dir.path(), "modes", doc);
    let mut p = player(&path);
    p.set_time(0.0).unwrap();
    let scene = p.ctx.scene();
    for (x0, what) in [(0.0, "strip"), (3.0, "fan")] {
        for (u, v) in [(0.25, 0.75), (0.75, 0.25), (0.5, 0.5)] {
            let hit = scene.intersect(&Ray::infinite(Vec3::new(x0 + u, v, 5.0), -Vec3::Z));
            assert!(hit.is_some(), "{what}: both triangles drawn ({u}, {v})");
        }
    }
    // The sparse substitution made the triangle (0,0) (1,0) (0,1).
    assert!(
        scene
            .intersect(&Ray::infinite(Vec3::new(6.25, 0.25, 5.0), -Vec3::Z))
            .is_some()
    );
    assert!(
        scene
            .intersect(&Ray::infinite(Vec3::new(6.75, 0.75, 5.0), -Vec3::Z))
            .is_none()
    );
}

/// Loads `doc` and expects an error whose text holds every one of `want`.
fn refused(dir: &Path, name: &str, b: &mut Builder, doc: Value, want: &[&str]) {
    let path = b.write_gltf(dir, name, doc);
    let Err(e) = ScenePlayer::open(Some(&path)) else {
        panic!("{name}: loaded");
    };
    let text = e.to_string();
    assert!(text.contains(&format!("{name}.gltf")), "names the file: {text}");
    for w in want {
        assert!(text.contains(w), "{name}: '{w}' not in: {text}");
    }
}

#[test]
fn broken_and_unsupported_files_are_typed_errors_naming_the_place() {
    let dir = tempfile::tempdir().unwrap();
    let base = |b: &mut Builder| {
        let meshes = quad(b);
        json!({"scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}], "meshes": meshes, "materials": materials()})
    };
    let mut b = Builder::default();
    let mut doc = base(&mut b);
    doc["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    doc["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    refused(dir.path(), "draco", &mut b, doc, &["KHR_draco_mesh_compression"]);

    let mut b = Builder::default();
    let pos = b.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], "VEC3", 3);
    let idx = b.indices(&[0, 1, 7]);
    let doc = json!({"scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos}, "indices": idx}]}]});
    refused(
        dir.path(),
        "index",
        &mut b,
        doc,
        &["meshes[0].primitives[0]", "index 7", "3 vertices"],
    );

    for (name, times, rule) in [
        ("back", [1.0, 0.5], "must increase"),
        ("nan", [0.0, f32::NAN], "not finite"),
    ] {
        let mut b = Builder::default();
        let mut doc = base(&mut b);
        let input = b.floats(&times, "SCALAR", 1);
        let output = b.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0], "VEC3", 3);
        doc["animations"] = json!([{"channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}],
            "samplers": [{"input": input, "output": output}]}]);
        refused(dir.path(), name, &mut b, doc, &["animations[0].samplers[0]", rule]);
    }

    let mut b = Builder::default();
    let mut doc = base(&mut b);
    doc["nodes"] = json!([{"mesh": 0, "children": [1]}, {"children": [0]}]);
    doc["scenes"] = json!([{"nodes": [0]}]);
    refused(dir.path(), "cycle", &mut b, doc, &["nodes["]);

    // A missing file, a missing buffer and a truncated binary file.
    let missing = dir.path().join("nowhere.gltf");
    assert!(matches!(ScenePlayer::open(Some(&missing)), Err(SceneError::Io { .. })));
    let mut b = Builder::default();
    let doc = base(&mut b);
    let path = b.write_gltf(dir.path(), "nobin", doc);
    std::fs::remove_file(dir.path().join("nobin.bin")).unwrap();
    let e = ScenePlayer::open(Some(&path))
        .err()
        .expect("a missing buffer is an error");
    assert!(e.to_string().contains("nobin.gltf"), "{e}");
    let mut b = Builder::default();
    let doc = base(&mut b);
    let glb = b.write_glb(dir.path(), "cut", doc);
    let bytes = std::fs::read(&glb).unwrap();
    for keep in [0, 11, 20, bytes.len() / 2, bytes.len() - 1] {
        std::fs::write(&glb, &bytes[..keep]).unwrap();
        let e = ScenePlayer::open(Some(&glb))
            .err()
            .unwrap_or_else(|| panic!("{keep} bytes loaded"));
        assert!(e.to_string().contains("cut.glb"), "{keep} bytes: {e}");
    }
}

#[test]
fn transmission_and_ior_refract_and_emission_is_added() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    let meshes = quad(&mut b);
    let doc = json!({
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior"],
        "extensionsRequired": ["KHR_materials_transmission"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": meshes,
        "materials": [{
            "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.1},
            "emissiveFactor": [1.0, 0.5, 0.0],
            "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.75}, "KHR_materials_ior": {"ior": 1.33}}
        }],
    });
    let path = b.write_gltf(dir.path(), "glass", doc);
    let p = player(&path);
    let scene = p.ctx.scene();
    let glass = scene
        .materials()
        .iter()
        .find(|m| m.transmission > 0.0)
        .expect("a transmitting material");
    assert_eq!(glass.transmission, 0.75);
    assert_eq!(glass.ior, 1.33);
    assert!(
        (glass.diffuse - Vec3::new(0.125, 0.125, 0.25)).length() < 1e-6,
        "{glass:?}"
    );
    assert_eq!(glass.emission, Vec3::new(1.0, 0.5, 0.0));
    assert!(p.warnings().is_empty(), "{:?}", p.warnings());
}

#[test]
fn base_colour_textures_are_read_with_their_samplers_wrap_modes() {
    let dir = tempfile::tempdir().unwrap();
    image::RgbImage::from_fn(4, 2, |x, _| image::Rgb([x as u8 * 60, 200, 10]))
        .save(dir.path().join("tex.png"))
        .unwrap();
    let mut b = Builder::default();
    let pos = b.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], "VEC3", 3);
    let uv = b.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC2", 2);
    // One image under three textures: clamped along u, mirrored along v;
    // the same sampler again (shared); no sampler (repeat).
    let doc = json!({
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [{"mesh": 0}, {"mesh": 1}, {"mesh": 2}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "material": 1}]},
            {"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "material": 2}]}
        ],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
            {"pbrMetallicRoughness": {"baseColorTexture": {"index": 1}}},
            {"pbrMetallicRoughness": {"baseColorTexture": {"index": 2}}}
        ],
        "textures": [{"source": 0, "sampler": 0}, {"source": 0, "sampler": 0}, {"source": 0}],
        "samplers": [{"wrapS": 33071, "wrapT": 33648}],
        "images": [{"uri": "tex.png"}],
    });
    let path = b.write_gltf(dir.path(), "textured", doc);
    let p = player(&path);
    let scene = p.ctx.scene();
    let textures: Vec<_> = scene
        .materials()
        .iter()
        .filter_map(|m| m.texture)
        .map(|t| scene.textures()[t.index() as usize].clone())
        .collect();
    assert_eq!(textures.len(), 3, "the base colour textures are read");
    assert_eq!(scene.textures().len(), 2, "one texture per image and addressing");
    assert_eq!(
        textures[0].wrap(),
        [TextureWrap::ClampToEdge, TextureWrap::MirroredRepeat]
    );
    assert_eq!(textures[2].wrap(), [TextureWrap::Repeat; 2]);
    // Clamped along u: far right is the right edge texel (x = 3); repeated,
    // u = 1.375 is u = 0.375 (between texels 1 and 2).
    let right = Vec3::new(180.0, 200.0, 10.0) / 255.0;
    assert_eq!(textures[0].sample(Vec2::new(7.5, 0.25)), right);
    assert_ne!(textures[2].sample(Vec2::new(1.375, 0.25)), right);
    assert!(p.warnings().is_empty(), "{:?}", p.warnings());
}

/// Blender's exporter writes KHR_texture_transform (mapping nodes) and
/// KHR_materials_emissive_strength (emission above 1): both are read, as is
/// the emissive texture, and an optional extension that is not read is a
/// warning naming it.
#[test]
fn texture_transforms_emissive_textures_and_strength_are_read() {
    let dir = tempfile::tempdir().unwrap();
    image::RgbImage::from_fn(2, 2, |x, y| image::Rgb([x as u8 * 200, y as u8 * 200, 10]))
        .save(dir.path().join("tex.png"))
        .unwrap();
    let mut b = Builder::default();
    let pos = b.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], "VEC3", 3);
    let uvs = [[0.0f32, 0.0], [1.0, 0.0], [0.25, 0.5]];
    let uv = b.floats(&uvs.concat(), "VEC2", 2);
    let (offset, rotation, scale) = ([0.5f32, -0.25], 0.3f32, [2.0f32, 3.0]);
    let doc = json!({
        "extensionsUsed": ["KHR_texture_transform", "KHR_materials_emissive_strength", "EXT_made_up"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv}, "material": 0}]}],
        "materials": [{
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {
                "offset": offset, "rotation": rotation, "scale": scale}}}},
            "emissiveFactor": [0.5, 0.25, 0.0],
            "emissiveTexture": {"index": 0, "extensions": {"KHR_texture_transform": {
                "offset": offset, "rotation": rotation, "scale": scale}}},
            "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}
        }],
        "textures": [{"source": 0}],
        "images": [{"uri": "tex.png"}],
    });
    let path = b.write_gltf(dir.path(), "transformed", doc);
    let p = player(&path);
    let scene = p.ctx.scene();
    // The extension's matrix, written out: translation * rotation * scale.
    let (s, c) = rotation.sin_cos();
    let want: Vec<Vec2> = uvs
        .iter()
        .map(|[u, v]| {
            let (su, sv) = (u * scale[0], v * scale[1]);
            Vec2::new(offset[0] + c * su - s * sv, offset[1] + s * su + c * sv)
        })
        .collect();
    let got = scene.instances()[0].geometry.shading().uvs[0];
    for (g, w) in got.iter().zip(&want) {
        assert!((*g - *w).length() < 1e-6, "{got:?} against {want:?}");
    }
    let m = scene.materials().iter().find(|m| m.texture.is_some()).unwrap();
    assert_eq!(m.emission, Vec3::new(2.0, 1.0, 0.0), "the factor times the strength");
    assert_eq!(
        m.emission_texture, m.texture,
        "the emissive texture: the same image and sampler"
    );
    let w: Vec<String> = p.warnings().iter().map(ToString::to_string).collect();
    assert!(
        w.len() == 1 && w[0].contains("EXT_made_up") && w[0].contains("extensionsUsed"),
        "{w:?}"
    );
}

/// KHR_materials_unlit (Blender writes it for emission and background
/// shaders): the base colour shown as it is, lit by nothing: an emission
/// of the base colour, every reflectance zero; the image is that colour.
#[test]
fn unlit_materials_show_their_base_colour() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    let meshes = quad(&mut b);
    let doc = json!({
        "extensionsUsed": ["KHR_materials_unlit"],
        "extensionsRequired": ["KHR_materials_unlit"],
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0.0, 0.0, 2.0]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.01}}],
        "meshes": meshes,
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.75, 0.5, 0.25, 1.0]},
                       "extensions": {"KHR_materials_unlit": {}}}],
    });
    let path = b.write_gltf(dir.path(), "unlit", doc);
    let p = player(&path);
    let scene = p.ctx.scene();
    let m = &scene.materials()[scene.instances()[0].geometry.shading().materials[0].index() as usize];
    assert_eq!(m.emission, Vec3::new(0.75, 0.5, 0.25));
    assert_eq!((m.ambient, m.diffuse, m.specular), (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO));
    let settings = openrt_core::RenderSettings {
        width: 8,
        height: 8,
        ..openrt_core::RenderSettings::default()
    };
    let (img, _) = openrt_core::Renderer::new(1)
        .unwrap()
        .render(&scene, &p.env, &p.camera(0.0), &settings)
        .unwrap();
    let centre = img.pixels[4 * 8 + 4];
    assert!((centre - Vec3::new(0.75, 0.5, 0.25)).length() < 1e-6, "{centre}");
    assert!(p.warnings().is_empty(), "{:?}", p.warnings());
}

/// Valid files the `gltf` crate alone refuses, as Blender's exporter writes
/// them (its round-trip tests hold each): a scene without `nodes`, an
/// application-specific attribute, a KHR_animation_pointer channel (no
/// target node). They load, with a warning for what is not read.
#[test]
fn valid_files_the_crate_refuses_are_mended() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    let pos = b.floats(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0], "VEC3", 3);
    let pressure = b.floats(&[1.0, 2.0, 3.0], "SCALAR", 1);
    let input = b.floats(&[0.0, 1.0], "SCALAR", 1);
    let output = b.floats(&[0.0, 0.0, 0.0, 2.0, 0.0, 0.0], "VEC3", 3);
    let colour = b.floats(&[1.0, 1.0, 1.0, 0.0, 0.0, 1.0], "VEC3", 3);
    let doc = json!({
        "scene": 0,
        "scenes": [{"nodes": [0]}, {"name": "empty"}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "_PRESSURE": pressure}}]}],
        "animations": [{"channels": [
            {"sampler": 0, "target": {"node": 0, "path": "translation"}},
            {"sampler": 1, "target": {"path": "pointer", "extensions": {"KHR_animation_pointer": {"pointer": "/materials/0/emissiveFactor"}}}}
        ], "samplers": [{"input": input, "output": output}, {"input": input, "output": colour}]}],
    });
    let path = b.write_gltf(dir.path(), "mended", doc.clone());
    // The same as GLB: mended from its JSON chunk, its binary chunk kept.
    let glb = player(&b.write_glb(dir.path(), "mended", doc));
    assert_eq!(glb.warnings().len(), 2, "{:?}", glb.warnings());
    assert_eq!(glb.ctx.scene().instances().len(), 1);
    let mut p = player(&path);
    let w: Vec<String> = p.warnings().iter().map(ToString::to_string).collect();
    assert!(
        w.iter()
            .any(|w| w.contains("meshes[0].primitives[0]") && w.contains("not read")),
        "{w:?}"
    );
    assert!(
        w.iter()
            .any(|w| w.contains("animations[0]") && w.contains("KHR_animation_pointer")),
        "{w:?}"
    );
    // The node channel still plays.
    p.set_time(1.0).unwrap();
    assert!((centres(&p)[0].x - 2.5).abs() < 1e-5, "{:?}", centres(&p));
    let empty = GltfPlayer::load_with(
        &path,
        &GltfOptions {
            scene: Some(1),
            ..GltfOptions::default()
        },
    )
    .unwrap();
    assert!(
        empty.ctx.scene().instances().is_empty(),
        "the empty scene draws nothing"
    );
}

#[test]
fn lights_on_animated_nodes_move_with_them() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Builder::default();
    let meshes = quad(&mut b);
    let input = b.floats(&[0.0, 1.0], "SCALAR", 1);
    let output = b.floats(&[0.0, 0.0, 0.0, 4.0, 0.0, 0.0], "VEC3", 3);
    let doc = json!({
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1.0, 1.0, 1.0], "intensity": 1.0},
            {"type": "point", "color": [0.5, 0.5, 0.5], "intensity": 1.0}
        ]}},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 3]}],
        "nodes": [
            {"mesh": 0},
            {"children": [2]},
            {"translation": [0.0, 3.0, 1.0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"translation": [-1.0, 3.0, 1.0], "extensions": {"KHR_lights_punctual": {"light": 1}}}
        ],
        "meshes": meshes,
        "materials": materials(),
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}],
            "samplers": [{"input": input, "output": output}]}],
    });
    let path = b.write_gltf(dir.path(), "moving_light", doc);
    let mut p = player(&path);
    let at = |p: &GltfPlayer| p.env.lights.iter().map(|l| l.position).collect::<Vec<_>>();
    assert_eq!(at(&p), vec![Vec3::new(0.0, 3.0, 1.0), Vec3::new(-1.0, 3.0, 1.0)]);
    p.set_time(0.5).unwrap();
    assert_eq!(
        at(&p),
        vec![Vec3::new(2.0, 3.0, 1.0), Vec3::new(-1.0, 3.0, 1.0)],
        "the light under the animated node moves, the other stays"
    );
}
