//! The examples run as tests (CI runs `cargo test`): each is included as a
//! module and its `run` called, and what it produced is checked.

use std::collections::HashSet;

#[allow(dead_code)]
#[path = "../examples/hello.rs"]
mod hello;

#[allow(dead_code)]
#[path = "../examples/deform.rs"]
mod deform;

#[allow(dead_code)]
#[path = "../examples/queries.rs"]
mod queries;

fn png(path: &std::path::Path) -> image::RgbImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8()
}

#[test]
fn hello_renders_an_animated_instance() {
    let dir = tempfile::tempdir().unwrap();
    let files = hello::run(dir.path()).unwrap();
    assert_eq!(files.len(), 4);
    let frames: Vec<_> = files.iter().map(|f| png(f)).collect();
    for f in &frames {
        assert_eq!(f.dimensions(), (320, 240));
        // Red cubes, a lit floor and the sky: more than a handful of colours.
        let colours: HashSet<[u8; 3]> = f.pixels().map(|p| p.0).collect();
        assert!(colours.len() > 50, "{} colours", colours.len());
        assert!(
            f.pixels().any(|p| p.0[0] > 2 * p.0[1] && p.0[0] > 60),
            "a red cube is visible"
        );
    }
    // The spinning instance changes the image; nothing else moves.
    assert_ne!(frames[0].as_raw(), frames[1].as_raw());
}

#[test]
fn deform_rebuilds_only_the_redefined_object() {
    let dir = tempfile::tempdir().unwrap();
    let commits = deform::run(dir.path()).unwrap();
    assert_eq!(commits.len(), 4);
    assert_eq!(commits[0].builds.len(), 2, "both objects are built once");
    for c in &commits[1..] {
        assert_eq!(c.builds.len(), 1, "only the sheet is rebuilt: {:?}", c.builds);
        assert_eq!(c.builds[0].builder, openrt_accel::BuilderKind::Fast);
    }
    assert!(
        commits[2..].iter().all(|c| c.builds[0].refitted),
        "later frames refit the sheet"
    );
    let (a, b) = (
        png(&dir.path().join("deform_1.png")),
        png(&dir.path().join("deform_2.png")),
    );
    assert_ne!(a.as_raw(), b.as_raw(), "the sheet ripples");
}

#[test]
fn queries_follow_the_moving_crate() {
    let lines = queries::run().unwrap();
    assert_eq!(lines.len(), 9, "{lines:#?}");
    assert!(
        lines[0].contains("meets InstanceId(2") && lines[0].contains("t = 0.500"),
        "{}",
        lines[0]
    );
    assert!(lines[1].contains("hidden"), "{}", lines[1]);
    assert!(
        lines[3].contains("meets InstanceId(3") && lines[3].contains("t = 2.500"),
        "{}",
        lines[3]
    );
    assert!(lines[4].contains("see each other"), "{}", lines[4]);
}
