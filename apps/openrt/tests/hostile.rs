//! Crafted hostile input to the `openrt` command: each must end with exit
//! status 1 and a one-line error naming the problem, within seconds, never
//! with a panic, an abort or a hang.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Runs `openrt args`, killing it after 20 s; returns (exit code, stderr).
fn openrt(args: &[&str], dir: &Path) -> (Option<i32>, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_openrt"))
        .args(args)
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("openrt starts");
    let start = Instant::now();
    loop {
        if child.try_wait().expect("wait").is_some() {
            break;
        }
        if start.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            panic!("openrt {args:?} hangs");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().expect("output");
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn crafted_inputs_give_errors_not_crashes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let view = "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0.1\nresolution 32 32\n";
    let n = 100_000;
    std::fs::write(
        d.join("nest.aff"),
        format!(
            "{view}{}p 3 0 0 0 1 0 0 0 1 0\n{}",
            "xs 1 1 1 0 0 1 0 0 0 0 {\n".repeat(n),
            "}\n".repeat(n)
        ),
    )
    .unwrap();
    std::fs::write(d.join("res.ron"), "(version: 1, resolution: (4000000000, 4000000000))").unwrap();
    std::fs::write(
        d.join("terrain.ron"),
        "(version: 2, generators: [Terrain(size: 10.0, grid: 4000000000, height: 1.0, trees: 4000000000, \
         tree_triangles: 4000000000, tree_size: 1.0, sway_degrees: 0.0, seed: 1)])",
    )
    .unwrap();
    std::fs::write(
        d.join("keys.ron"),
        "(version: 2, objects: { \"b\": Box(min: (0.0, 0.0, 0.0), max: (1.0, 1.0, 1.0)) }, \
         animation: Some((start: 0.0, end: 1.0, frames: 3)), \
         instances: [(object: \"b\", keys: Some((translate: [(1.0, (0.0, 0.0, 0.0)), (NaN, (1.0, 0.0, 0.0))])))])",
    )
    .unwrap();
    std::fs::write(
        d.join("anim.ron"),
        "(version: 2, objects: { \"b\": Box(min: (0.0, 0.0, 0.0), max: (1.0, 1.0, 1.0)) }, \
         animation: Some((start: 0.0, end: 1.0, frames: 3)), instances: [(object: \"b\")])",
    )
    .unwrap();
    let cases: &[(&[&str], &str)] = &[
        (&["render", "nest.aff", "-o", "a.png"], "MAX_BLOCK_NESTING"),
        (
            &[
                "render", "--depth", "100000", "--width", "8", "--height", "8", "-o", "a.png",
            ],
            "depth",
        ),
        (
            &["render", "--width", "1000000", "--height", "1000000", "-o", "a.png"],
            "image side",
        ),
        (&["render", "terrain.ron", "-o", "a.png"], "Terrain"),
        (&["render", "res.ron", "-o", "a.png"], "resolution"),
        (&["render", "--threads", "100000000", "-o", "a.png"], "thread count"),
        (&["render", "--threads", "0", "-o", "a.png"], "thread count"),
        (&["render", "keys.ron", "-o", "a.png"], "not finite"),
        (&["play", "anim.ron", "--frames", "0..=4294967295"], "--frames"),
        (&["play", "anim.ron", "--frames", "2..1"], "--frames"),
        (&["render", "anim.ron", "--frame", "3", "-o", "a.png"], "--frame 3"),
        (&["render", "missing.aff", "-o", "a.png"], "missing.aff"),
        (&["bench", "--frames", "100000000", "--scenes", "slab"], "--frames"),
        (&["render", "--spp", "0", "-o", "a.png"], "samples per pixel"),
        (&["render", "--spp", "100000", "-o", "a.png"], "samples per pixel"),
        (
            &["render", "anim.ron", "--animation", "1", "-o", "a.png"],
            "glTF files only",
        ),
        (
            &["render", "walker.glb", "--animation", "run", "-o", "a.png"],
            "no animation has that name",
        ),
        (&["render", "walker.glb", "--scene", "3", "-o", "a.png"], "--scene 3"),
        (&["render", "walker.glb", "--camera", "9", "-o", "a.png"], "--camera 9"),
    ];
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/walker.glb"),
        d.join("walker.glb"),
    )
    .unwrap();
    for (args, expect) in cases {
        let (code, err) = openrt(args, d);
        assert_eq!(code, Some(1), "openrt {args:?}: exit {code:?}, stderr:\n{err}");
        assert!(err.starts_with("error: "), "openrt {args:?}: {err}");
        assert!(
            err.contains(expect),
            "openrt {args:?}: '{err}' should mention '{expect}'"
        );
        assert!(!err.contains("panicked"), "openrt {args:?}: {err}");
    }
}

/// `openrt soak` plays a scene in a loop and reports memory and frame time
/// (the 10,000-frame runs are in docs/ROBUSTNESS.md).
#[test]
fn soak_reports_memory_and_frame_time() {
    let dir = tempfile::tempdir().unwrap();
    let scene = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/animated.ron");
    let out = Command::new(env!("CARGO_BIN_EXE_openrt"))
        .arg("soak")
        .arg(&scene)
        .args([
            "--frames",
            "400",
            "--every",
            "10",
            "--width",
            "32",
            "--height",
            "24",
            "--threads",
            "1",
            "-o",
        ])
        .arg(dir.path().join("soak.jsonl"))
        .output()
        .expect("openrt runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        stdout.contains("resident memory") && stdout.contains("drift"),
        "{stdout}"
    );
    let lines = std::fs::read_to_string(dir.path().join("soak.jsonl")).unwrap();
    assert_eq!(lines.lines().count(), 40);
    let last: serde_json::Value = serde_json::from_str(lines.lines().last().unwrap()).unwrap();
    assert_eq!(last["frame"], 400);
    assert!(last["rss_mb"].as_f64().unwrap() > 1.0);
}

/// Without `OPENRT_BART_DIR`, the BART folder is found beside the
/// repository whatever the current folder; when it is not there, the error
/// names the paths tried.
#[test]
fn the_bart_folder_is_found_from_any_folder_or_named_in_the_error() {
    let dir = tempfile::tempdir().unwrap();
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let default = repo.join("../shared/bart/kitchen/kitchen.aff");
    let out = Command::new(env!("CARGO_BIN_EXE_openrt"))
        .env_remove("OPENRT_BART_DIR")
        .current_dir(dir.path())
        .arg("render")
        .arg(repo.join("scenes/kitchen.ron"))
        .args(["--width", "16", "--height", "12", "-o", "k.png"])
        .output()
        .expect("openrt runs");
    let err = String::from_utf8_lossy(&out.stderr);
    if default.is_file() {
        assert!(out.status.success(), "{err}");
        assert!(dir.path().join("k.png").is_file());
    } else {
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains("also tried") && err.contains("OPENRT_BART_DIR"), "{err}");
    }
    let out = Command::new(env!("CARGO_BIN_EXE_openrt"))
        .env("OPENRT_BART_DIR", dir.path().join("nowhere"))
        .arg("render")
        .arg(repo.join("scenes/kitchen.ron"))
        .output()
        .expect("openrt runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("nowhere/kitchen/kitchen.aff not found"), "{err}");
}

#[test]
fn play_failing_part_way_keeps_every_finished_frame() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("frames");
    std::fs::create_dir_all(&out).unwrap();
    // Frame 2's image cannot be put in place (a folder holds its name), as a
    // full disk would refuse it: frames 0 and 1 must survive whole, with their
    // statistics, and nothing half-written may be left.
    std::fs::create_dir(out.join("frame_00002.png")).unwrap();
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/animated.ron");
    let (code, err) = openrt(
        &[
            "play",
            scene.to_str().unwrap(),
            "--frames",
            "0..5",
            "--width",
            "32",
            "--height",
            "24",
            "-o",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains("frame_00002.png") && err.contains("2 frame(s) completed"),
        "{err}"
    );
    let stats = std::fs::read_to_string(out.join("stats.jsonl")).unwrap();
    let frames: Vec<u64> = stats
        .lines()
        .map(|l| {
            serde_json::from_str::<serde_json::Value>(l).unwrap()["frame"]
                .as_u64()
                .unwrap()
        })
        .collect();
    assert_eq!(frames, vec![0, 1], "the finished frames' statistics are flushed");
    for f in 0..2 {
        let png = image::open(out.join(format!("frame_{f:05}.png"))).unwrap();
        assert_eq!((png.width(), png.height()), (32, 24));
    }
    let mut names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        ["frame_00000.png", "frame_00001.png", "frame_00002.png", "stats.jsonl"],
        "no partial files"
    );
}
