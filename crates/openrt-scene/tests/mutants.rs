//! Mutation tests: every shipped input, mutated thousands of times
//! (flipped bytes, truncation, deleted or duplicated lines, numbers replaced
//! by nan, inf, 1e39, -0 or 4294967296), gives a typed error or a valid
//! scene that commits and renders. Never a panic, and never a slow case.
//!
//! Seeded, so a failure names a mutant that can be replayed:
//! `OPENRT_MUTANT=format:index cargo test --test mutants -- --nocapture`.

use std::fmt::Write;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use openrt_core::{CoreError, RenderMode, RenderSettings, Renderer};
use openrt_scene::{ScenePlayer, load_texture};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// Mutants per format.
const MUTANTS: usize = 5000;
/// A mutant slower than this counts as a failure (a hang in the making).
const SLOW: Duration = Duration::from_secs(2);

const NUMBERS: &[&str] = &[
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e39",
    "-1e39",
    "-0",
    "0",
    "4294967296",
    "-1",
    "1e-45",
    "18446744073709551616",
];

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

fn scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

/// One mutation of `input`.
fn mutate_once(rng: &mut SmallRng, input: &[u8]) -> Vec<u8> {
    let mut b = input.to_vec();
    if b.is_empty() {
        return b;
    }
    let line_starts: Vec<usize> = std::iter::once(0)
        .chain(b.iter().enumerate().filter(|(_, c)| **c == b'\n').map(|(i, _)| i + 1))
        .filter(|&i| i < b.len())
        .collect();
    let line = |rng: &mut SmallRng| {
        let k = rng.random_range(0..line_starts.len());
        let s = line_starts[k];
        let e = line_starts.get(k + 1).copied().unwrap_or(b.len());
        (s, e)
    };
    match rng.random_range(0..6) {
        0 => {
            let i = rng.random_range(0..b.len());
            b[i] ^= rng.random_range(1..=255u8);
        }
        1 => b.truncate(rng.random_range(0..b.len())),
        2 => {
            let (s, e) = line(rng);
            b.drain(s..e);
        }
        3 => {
            let (s, e) = line(rng);
            let copy = b[s..e].to_vec();
            b.splice(s..s, copy);
        }
        _ => {
            // Replace a number (a run of digits, signs, dots and exponents).
            let is_num = |c: u8| c.is_ascii_digit() || c == b'.' || c == b'-' || c == b'e' || c == b'+';
            let starts: Vec<usize> = (0..b.len())
                .filter(|&i| b[i].is_ascii_digit() && (i == 0 || !is_num(b[i - 1])))
                .collect();
            if starts.is_empty() {
                b.truncate(b.len() / 2);
            } else {
                let s = starts[rng.random_range(0..starts.len())];
                let e = (s..b.len()).find(|&i| !is_num(b[i])).unwrap_or(b.len());
                let with = NUMBERS[rng.random_range(0..NUMBERS.len())];
                b.splice(s..e, with.bytes());
            }
        }
    }
    b
}

/// One to three mutations.
fn mutate(rng: &mut SmallRng, input: &[u8]) -> Vec<u8> {
    let mut b = mutate_once(rng, input);
    for _ in 0..rng.random_range(0..3) {
        b = mutate_once(rng, &b);
    }
    b
}

/// Opens a scene, plays two times and renders a tiny frame; an error is
/// fine, a panic (in this thread or a render thread) is not.
fn exercise(path: &Path, renderer: &Renderer) -> Result<(), String> {
    let mut p = match ScenePlayer::open(Some(path)) {
        Ok(p) => p,
        Err(e) => return Err(e.to_string()),
    };
    for f in [0, p.frames() / 2] {
        let t = p.time_of(f);
        p.set_time(t).map_err(|e| e.to_string())?;
        let settings = RenderSettings {
            width: 6,
            height: 4,
            mode: RenderMode::Whitted,
            max_depth: 3,
            ..RenderSettings::default()
        };
        match renderer.render(&p.ctx().scene(), &p.env(), &p.camera(t), &settings) {
            Err(CoreError::RenderThread { reason }) => panic!("render thread failed: {reason}"),
            Err(e) => return Err(e.to_string()),
            Ok((img, _)) => assert!(img.pixels.iter().all(|c| c.is_finite()), "non-finite pixel"),
        }
    }
    Ok(())
}

struct Report {
    format: &'static str,
    ok: usize,
    errors: usize,
    failures: Vec<String>,
}

/// Runs `count` mutants of one format; `case(rng, index)` makes and checks one.
fn run(format: &'static str, count: usize, mut case: impl FnMut(&mut SmallRng) -> Result<(), String>) -> Report {
    let only: Option<usize> = std::env::var("OPENRT_MUTANT")
        .ok()
        .and_then(|v| v.strip_prefix(&format!("{format}:")).and_then(|i| i.parse().ok()));
    let mut report = Report {
        format,
        ok: 0,
        errors: 0,
        failures: Vec::new(),
    };
    for i in 0..count {
        if only.is_some_and(|o| o != i) {
            continue;
        }
        let mut rng = SmallRng::seed_from_u64(0x6D75_7461_6E74 ^ (i as u64) ^ (format.len() as u64) << 40);
        let start = Instant::now();
        let r = catch_unwind(AssertUnwindSafe(|| case(&mut rng)));
        let took = start.elapsed();
        match r {
            Ok(Ok(())) => report.ok += 1,
            Ok(Err(e)) => {
                report.errors += 1;
                if only.is_some() {
                    println!("{format}:{i}: {e}");
                }
            }
            Err(p) => {
                let msg = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(ToString::to_string))
                    .unwrap_or_default();
                report.failures.push(format!("{format}:{i}: panic: {msg}"));
            }
        }
        if took > SLOW {
            report.failures.push(format!("{format}:{i}: took {took:?}"));
        }
    }
    report
}

fn check(report: &Report) {
    println!(
        "{}: {} mutants loaded and rendered, {} gave errors, {} failed",
        report.format,
        report.ok,
        report.errors,
        report.failures.len()
    );
    assert!(report.failures.is_empty(), "{:#?}", report.failures);
    if std::env::var("OPENRT_MUTANT").is_err() {
        assert_eq!(report.ok + report.errors, MUTANTS);
        // Both outcomes must occur, or the mutants test nothing.
        assert!(
            report.ok > MUTANTS / 20 && report.errors > MUTANTS / 20,
            "{} ok, {} errors",
            report.ok,
            report.errors
        );
    }
}

fn quiet_panics() {
    std::panic::set_hook(Box::new(|_| {}));
}

#[test]
fn aff_mutants() {
    quiet_panics();
    let dir = tempfile::tempdir().unwrap();
    for f in ["sample.aff", "sample_inc.aff", "sample.ppm"] {
        std::fs::copy(data().join(f), dir.path().join(f)).unwrap();
    }
    let main = std::fs::read(data().join("sample.aff")).unwrap();
    let inc = std::fs::read(data().join("sample_inc.aff")).unwrap();
    let renderer = Renderer::new(1).unwrap();
    let path = dir.path().join("sample.aff");
    let report = run("aff", MUTANTS, |rng| {
        // Mostly the main file; sometimes the include.
        let (m, i) = if rng.random_bool(0.8) {
            (mutate(rng, &main), inc.clone())
        } else {
            (main.clone(), mutate(rng, &inc))
        };
        std::fs::write(&path, m).unwrap();
        std::fs::write(dir.path().join("sample_inc.aff"), i).unwrap();
        exercise(&path, &renderer)
    });
    check(&report);
}

#[test]
fn ron_mutants() {
    quiet_panics();
    let dir = tempfile::tempdir().unwrap();
    for sub in ["textures", "models"] {
        std::fs::create_dir_all(dir.path().join(sub)).unwrap();
        for e in std::fs::read_dir(scenes().join(sub)).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), dir.path().join(sub).join(e.file_name())).unwrap();
        }
    }
    let sources: Vec<Vec<u8>> = ["room.ron", "textured.ron", "animated.ron", "slab.ron"]
        .iter()
        .map(|f| std::fs::read(scenes().join(f)).unwrap())
        .chain(std::iter::once(openrt_scene::DEFAULT_SCENE_RON.as_bytes().to_vec()))
        .collect();
    let renderer = Renderer::new(1).unwrap();
    let path = dir.path().join("m.ron");
    let report = run("ron", MUTANTS, |rng| {
        let src = &sources[rng.random_range(0..sources.len())];
        std::fs::write(&path, mutate(rng, src)).unwrap();
        exercise(&path, &renderer)
    });
    check(&report);
}

#[test]
fn obj_mutants() {
    quiet_panics();
    let dir = tempfile::tempdir().unwrap();
    let sources = [
        std::fs::read(data().join("sample.obj")).unwrap(),
        std::fs::read(scenes().join("models/tetra.obj")).unwrap(),
    ];
    std::fs::write(
        dir.path().join("m.ron"),
        "(version: 2, camera: (from: (0.0, 1.0, 6.0), at: (0.0, 0.3, 0.0)), lights: [(position: (3.0, 5.0, 4.0))], \
         objects: { \"o\": Obj(path: \"m.obj\") }, instances: [(object: \"o\")])",
    )
    .unwrap();
    let renderer = Renderer::new(1).unwrap();
    let scene = dir.path().join("m.ron");
    let report = run("obj", MUTANTS, |rng| {
        let src = &sources[rng.random_range(0..sources.len())];
        std::fs::write(dir.path().join("m.obj"), mutate(rng, src)).unwrap();
        // The parser alone, then through the scene.
        let _ = openrt_scene::parse_obj(&std::fs::read(dir.path().join("m.obj")).unwrap());
        exercise(&scene, &renderer)
    });
    check(&report);
}

#[test]
fn texture_mutants() {
    quiet_panics();
    let dir = tempfile::tempdir().unwrap();
    let ppm = std::fs::read(data().join("sample.ppm")).unwrap();
    let ascii = {
        let mut s = String::from("P3\n# ascii\n4 4\n255\n");
        for v in &ppm[ppm.len() - 48..] {
            write!(s, "{v} ").unwrap();
        }
        s.into_bytes()
    };
    let png = {
        let img = image::RgbImage::from_fn(5, 3, |x, y| image::Rgb([x as u8 * 40, y as u8 * 80, 7]));
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, image::ImageFormat::Png).unwrap();
        out.into_inner()
    };
    let checker = std::fs::read(scenes().join("textures/checker.ppm")).unwrap();
    let sources = [ppm, ascii, png, checker];
    let path = dir.path().join("t.img");
    let user = dir.path().join("scene.aff");
    let report = run("texture", MUTANTS, |rng| {
        let src = &sources[rng.random_range(0..sources.len())];
        std::fs::write(&path, mutate(rng, src)).unwrap();
        let t = load_texture(&path, &user).map_err(|e| e.to_string())?;
        // A loaded texture samples to finite colours anywhere.
        for _ in 0..16 {
            let uv = glam::Vec2::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
            assert!(t.sample(uv).is_finite());
        }
        Ok(())
    });
    check(&report);
}

/// Fuzz findings, kept as regression tests: each input must give an error
/// or a scene, never a panic.
#[test]
fn fuzz_findings_stay_fixed() {
    // obj: tobj 4.0.5 multiplied an out-of-range relative texture index
    // unchecked (overflow panic in debug builds).
    let obj = std::fs::read(data().join("fuzz-obj-tobj-overflow.obj")).unwrap();
    let e = openrt_scene::parse_obj(&obj).unwrap_err();
    assert!(e.contains("texture coordinate index"), "{e}");
}
