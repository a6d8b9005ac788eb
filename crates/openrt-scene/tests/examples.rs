//! The `scene_file` example runs as a test: it opens shipped scenes and
//! renders a frame, and a missing file is a typed error naming it. The
//! shipped glTF example is the `walker` example's output, and plays.

#[allow(dead_code)]
#[path = "../examples/scene_file.rs"]
mod scene_file;

#[allow(dead_code)]
#[path = "../examples/walker.rs"]
mod walker;

use std::path::Path;

#[test]
fn scene_file_renders_shipped_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    for (scene, frame) in [(None, 0), (Some(root.join("scenes/animated.ron")), 10)] {
        let out = dir.path().join(format!("frame_{frame}.png"));
        let line = scene_file::run(scene.as_deref(), frame, &out, Some((96, 64))).unwrap();
        assert!(line.contains("96x64"), "{line}");
        let img = image::open(&out).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (96, 64));
        let first = img.get_pixel(0, 0);
        assert!(img.pixels().any(|p| p != first), "{line}: the frame is not blank");
    }
    let missing = dir.path().join("no_such_scene.ron");
    let e = scene_file::run(Some(&missing), 0, &dir.path().join("x.png"), None).unwrap_err();
    assert!(e.to_string().contains("no_such_scene.ron"), "{e}");
}

#[test]
fn the_shipped_walker_is_the_generators_output_and_deforms_as_it_plays() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let shipped = std::fs::read(root.join("scenes/walker.glb")).unwrap();
    assert!(
        shipped == walker::walker(),
        "scenes/walker.glb differs from the generator: cargo run -p openrt-scene --example walker"
    );
    let dir = tempfile::tempdir().unwrap();
    let mut frames = Vec::new();
    for frame in [0, 15] {
        let out = dir.path().join(format!("walker_{frame}.png"));
        let line = scene_file::run(Some(&root.join("scenes/walker.glb")), frame, &out, Some((64, 48))).unwrap();
        frames.push(image::open(&out).unwrap().to_rgb8().into_raw());
        assert!(line.contains("64x48"), "{line}");
    }
    assert_ne!(frames[0], frames[1], "the figure moves");
    let mut p = openrt_scene::ScenePlayer::open(Some(&root.join("scenes/walker.glb"))).unwrap();
    let classes = p.motion_classes();
    assert_eq!(
        (
            classes.static_instances,
            classes.affine_instances,
            classes.deforming_objects
        ),
        (1, 1, 1)
    );
    let stats = p.set_time(0.5).unwrap();
    assert_eq!(
        stats.builds.len(),
        1,
        "only the skinned tube is rebuilt: {:?}",
        stats.builds
    );
}
