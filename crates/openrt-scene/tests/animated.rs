//! RON format version 2: keyframed instances, morphing objects, OBJ files,
//! camera keys, and their errors.

use std::path::{Path, PathBuf};

use openrt_accel::BuilderKind;
use openrt_scene::{SceneError, ScenePlayer, load_ron};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn the_animated_example_moves_the_right_things() {
    let mut p = ScenePlayer::open(Some(&repo().join("scenes/animated.ron"))).unwrap();
    assert_eq!(p.frames(), 120);
    assert_eq!(p.time_range(), (0.0, 4.0));
    let first = p.set_time(0.0).unwrap();
    assert_eq!(first.instances, 3);
    let before: Vec<_> = p.ctx().scene().instances().iter().map(|i| i.to_world).collect();
    let st = p.set_time(1.0).unwrap();
    // Only the morphing flag is rebuilt, with the fast builder.
    assert_eq!(st.builds.len(), 1);
    assert_eq!((st.builds[0].builder, st.builds[0].triangles), (BuilderKind::Fast, 4));
    let after: Vec<_> = p.ctx().scene().instances().iter().map(|i| i.to_world).collect();
    assert_eq!(before[0], after[0], "the floor is static");
    assert_ne!(before[1], after[1], "the tetrahedron is keyframed");
    // Catmull-Rom through the keys: at t = 2 the translation key is exact.
    p.set_time(2.0).unwrap();
    let m = p.ctx().scene().instances()[1].to_world;
    assert!((m.translation.y - 1.3).abs() < 1e-4, "{}", m.translation);
    // Camera keys.
    assert!((p.camera(2.0).from - glam::Vec3::new(4.0, 2.5, 5.0)).length() < 1e-4);
    assert_ne!(p.camera(0.0).from, p.camera(1.0).from);
}

#[test]
fn obj_files_load_through_tobj_and_bad_ones_are_reported() {
    let s = load_ron(&repo().join("scenes/animated.ron")).unwrap();
    let scene = s.ctx.scene();
    assert_eq!(scene.instances()[1].geometry.tree.triangles().len(), 4);
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let write_scene = |obj: &str| {
        std::fs::write(dir.join("m.obj"), obj).unwrap();
        let scene = dir.join("s.ron");
        std::fs::write(
            &scene,
            r#"(version: 2, objects: {"m": Obj(path: "m.obj")}, instances: [(object: "m")])"#,
        )
        .unwrap();
        load_ron(&scene)
    };
    // A face with an index beyond the vertices, a malformed number, a missing file.
    for bad in [
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
        "v 0 0 zero\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    ] {
        let e = write_scene(bad).err().expect("malformed OBJ");
        assert!(e.to_string().contains("m.obj"), "{e}");
    }
    std::fs::remove_file(dir.join("m.obj")).unwrap();
    let scene = dir.join("s.ron");
    let e = load_ron(&scene).err().unwrap();
    assert!(e.to_string().contains("m.obj"), "{e}");
    // NaN in an OBJ is caught by the API.
    let e = write_scene("v 0 0 0\nv 1 0 NaN\nv 0 1 0\nf 1 2 3\n")
        .err()
        .expect("NaN vertex");
    assert!(matches!(e, SceneError::Core { .. } | SceneError::Invalid { .. }), "{e}");
}

#[test]
fn version_2_features_are_gated_and_checked() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let load = |text: &str| {
        let p = dir.join("s.ron");
        std::fs::write(&p, text).unwrap();
        load_ron(&p).err().map(|e| e.to_string())
    };
    let e =
        load("(version: 1, animation: Some((start: 0.0, end: 1.0, frames: 10)), objects: {}, instances: [])").unwrap();
    assert!(e.contains("version: 2"), "{e}");
    let e = load("(version: 2, animation: Some((start: 1.0, end: 0.0, frames: 10)))").unwrap();
    assert!(e.contains("empty"), "{e}");
    let e = load(r#"(version: 2, objects: {"f": Morph(triangles: [(0, 1, 2)], keys: [(0.0, [(0,0,0), (1,0,0), (0,1,0)]), (1.0, [(0,0,0)])])}, instances: [])"#).unwrap();
    assert!(e.contains("key 1 has 1 vertices"), "{e}");
    let e = load(r#"(version: 2, objects: {"f": Morph(triangles: [(0, 1, 5)], keys: [(0.0, [(0,0,0), (1,0,0), (0,1,0)])])}, instances: [])"#).unwrap();
    assert!(e.contains("uses vertex 5"), "{e}");
    let e =
        load(r#"(version: 2, bart: Some((file: "x.aff")), objects: {"a": Box(min: (0,0,0), max: (1,1,1))})"#).unwrap();
    assert!(e.contains("cannot also define"), "{e}");
}
