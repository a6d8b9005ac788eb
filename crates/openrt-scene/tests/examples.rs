//! The `scene_file` example runs as a test: it opens shipped scenes and
//! renders a frame, and a missing file is a typed error naming it.

#[allow(dead_code)]
#[path = "../examples/scene_file.rs"]
mod scene_file;

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
