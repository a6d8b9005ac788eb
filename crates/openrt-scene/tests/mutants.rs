//! Mutation tests: every shipped input (and glTF files made here), mutated
//! thousands of times (flipped bytes, truncation, deleted or duplicated
//! lines, numbers replaced by nan, inf, 1e39, -0 or 4294967296), gives a
//! typed error or a valid scene that commits and renders. Never a panic.
//! The slowest mutant of each format is printed; the work each can cause
//! is bounded by the loaders' named limits, not by a clock here.
//!
//! Seeded, so a failure names a mutant that can be replayed:
//! `OPENRT_MUTANT=format:index cargo test --test mutants -- --nocapture`.

use std::fmt::Write;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde_json::json;

#[path = "common/gltf_builder.rs"]
mod gltf_builder;

use openrt_core::{CoreError, RenderMode, RenderSettings, Renderer};
use openrt_scene::{ScenePlayer, load_texture};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// Mutants per format.
const MUTANTS: usize = 5000;

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
    /// The slowest mutant and its time (printed, not judged).
    slowest: (usize, Duration),
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
        slowest: (0, Duration::ZERO),
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
            Ok(Err(e)) if e.contains("failed inside") => {
                report.failures.push(format!("{format}:{i}: {e}"));
            }
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
        if took > report.slowest.1 {
            report.slowest = (i, took);
        }
    }
    report
}

fn check(report: &Report) {
    println!(
        "{}: {} mutants loaded and rendered, {} gave errors, {} failed; the slowest, {}:{}, took {:?}",
        report.format,
        report.ok,
        report.errors,
        report.failures.len(),
        report.format,
        report.slowest.0,
        report.slowest.1
    );
    for f in &report.failures {
        println!("{f}");
    }
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

/// Silences the panics the mutants are caught in (a replayed mutant,
/// `OPENRT_MUTANT`, shows its panic and backtrace).
fn quiet_panics() {
    if std::env::var_os("OPENRT_MUTANT").is_none() {
        std::panic::set_hook(Box::new(|_| {}));
    }
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

/// A small animated glTF scene: three meshes, nodes (one animated with a
/// child), a camera, a point light, a material, and a skinned and morphed
/// mesh with its joints and weights animated.
fn gltf_scene(b: &mut gltf_builder::Builder) -> serde_json::Value {
    let pos = b.floats(
        &[-0.5, -0.5, 0.0, 0.5, -0.5, 0.0, 0.5, 0.5, 0.0, -0.5, 0.5, 0.0],
        "VEC3",
        3,
    );
    let nrm = b.floats(&[0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0], "VEC3", 3);
    let idx = b.indices(&[0, 1, 2, 0, 2, 3]);
    let fan = b.floats(
        &[0.0, 0.0, -1.0, 1.0, 0.0, -1.0, 1.0, 1.0, -1.0, 0.0, 1.0, -1.0],
        "VEC3",
        3,
    );
    let input = b.floats(&[0.0, 0.5, 1.0], "SCALAR", 1);
    // Cubic spline keys: in-tangent, value, out-tangent per key.
    let output = b.floats(
        &[
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, //
            0.0, 1.0, 0.0, 1.0, 0.5, 0.0, 0.0, -1.0, 0.0, //
            0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        ],
        "VEC3",
        3,
    );
    // A skinned, morphed quad: two joints (nodes 6 and 7), a morph target,
    // a rotation of joint 7 and the morph weight animated.
    let joints = b.shorts(&[0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0], "VEC4", 4);
    let weights = b.floats(
        &[
            1.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.7, 0.3, 0.0, 0.0,
        ],
        "VEC4",
        4,
    );
    let ibm = b.floats(
        &[
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, //
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 1.0,
        ],
        "MAT4",
        16,
    );
    let target = b.floats(&[0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 0.0], "VEC3", 3);
    let turn = b.floats(
        &[
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            std::f32::consts::FRAC_1_SQRT_2,
            std::f32::consts::FRAC_1_SQRT_2,
        ],
        "VEC4",
        4,
    );
    let times = b.floats(&[0.0, 1.0], "SCALAR", 1);
    let morph = b.floats(&[0.0, 1.0], "SCALAR", 1);
    json!({
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "color": [1.0, 1.0, 1.0], "intensity": 1.0}]}},
        "scene": 0,
        "scenes": [{"nodes": [0, 2, 3, 4, 5, 6]}],
        "nodes": [
            {"mesh": 0, "children": [1]},
            {"mesh": 1, "translation": [0.0, 1.0, 0.0], "scale": [0.5, 0.5, 0.5]},
            {"mesh": 0, "rotation": [0.0, 0.382_683_43, 0.0, 0.923_879_5], "translation": [-2.0, 0.0, 0.0]},
            {"camera": 0, "translation": [0.0, 0.5, 4.0]},
            {"translation": [1.0, 3.0, 2.0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"mesh": 2, "skin": 0},
            {"children": [7], "translation": [0.0, -1.0, 0.0]},
            {"translation": [1.0, 0.0, 0.0]}
        ],
        "skins": [{"joints": [6, 7], "inverseBindMatrices": ibm, "skeleton": 6}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.01}}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm}, "indices": idx, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": fan}, "mode": 6}]},
            {"primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm, "JOINTS_0": joints, "WEIGHTS_0": weights},
                "indices": idx, "targets": [{"POSITION": target}]}], "weights": [0.0]}
        ],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.6, 0.2, 1.0], "metallicFactor": 0.5, "roughnessFactor": 0.3}, "doubleSided": true}],
        "animations": [{"channels": [
                {"sampler": 0, "target": {"node": 0, "path": "translation"}},
                {"sampler": 1, "target": {"node": 7, "path": "rotation"}},
                {"sampler": 2, "target": {"node": 5, "path": "weights"}}
            ],
            "samplers": [
                {"input": input, "output": output, "interpolation": "CUBICSPLINE"},
                {"input": times, "output": turn},
                {"input": times, "output": morph, "interpolation": "STEP"}
            ]}]
    })
}

/// Counts the leaves of `v` that `pick` selects, or replaces the `k`-th
/// of them with `with` (when given); returns the count seen.
fn leaf(
    v: &mut serde_json::Value,
    pick: &dyn Fn(&serde_json::Value) -> bool,
    k: &mut usize,
    with: Option<&serde_json::Value>,
) -> bool {
    use serde_json::Value;
    match v {
        Value::Array(a) => a.iter_mut().any(|x| leaf(x, pick, k, with)),
        Value::Object(o) => o.values_mut().any(|x| leaf(x, pick, k, with)),
        other if pick(other) => {
            if *k == 0 {
                if let Some(w) = with {
                    *other = w.clone();
                }
                return with.is_some();
            }
            *k -= 1;
            false
        }
        _ => false,
    }
}

/// Removes a random member of a random object in `v`.
fn drop_member(rng: &mut SmallRng, v: &mut serde_json::Value) {
    use serde_json::Value;
    match v {
        Value::Object(o) if !o.is_empty() => {
            let keys: Vec<String> = o.keys().cloned().collect();
            let key = &keys[rng.random_range(0..keys.len())];
            if rng.random_bool(0.4) || !o[key].is_object() && !o[key].is_array() {
                o.remove(key);
            } else if let Some(inner) = o.get_mut(key) {
                drop_member(rng, inner);
            }
        }
        Value::Array(a) if !a.is_empty() => {
            let i = rng.random_range(0..a.len());
            drop_member(rng, &mut a[i]);
        }
        _ => {}
    }
}

/// One to three semantic mutations of a glTF document and its binary data:
/// numbers and names replaced by valid but hostile ones, members dropped,
/// bytes of the data flipped or set to NaN, the data cut short.
fn mutate_gltf(rng: &mut SmallRng, doc: &serde_json::Value, bin: &[u8]) -> (serde_json::Value, Vec<u8>) {
    const NUMS: &[f64] = &[
        -1.0,
        0.0,
        1.0,
        2.0,
        3.0,
        5.0,
        0.5,
        -0.0,
        1e39,
        -1e39,
        4_294_967_296.0,
        65535.0,
        1e-45,
        7.0,
    ];
    const NAMES: &[&str] = &[
        "SCALAR",
        "VEC2",
        "VEC3",
        "VEC4",
        "MAT4",
        "LINEAR",
        "STEP",
        "CUBICSPLINE",
        "rotation",
        "translation",
        "scale",
        "weights",
        "point",
        "spot",
        "directional",
        "perspective",
        "orthographic",
        "BLEND",
        "MASK",
    ];
    let (mut doc, mut bin) = (doc.clone(), bin.to_vec());
    for _ in 0..rng.random_range(1..=3) {
        match rng.random_range(0..10) {
            0..=3 => {
                let mut n = usize::MAX;
                leaf(&mut doc, &|v| v.is_number(), &mut n, None);
                let count = usize::MAX - n;
                let mut k = rng.random_range(0..count.max(1));
                let x = NUMS[rng.random_range(0..NUMS.len())];
                // Whole numbers as JSON integers too (indices, counts, enums).
                let with = if x.fract() == 0.0 && x.abs() < 1e15 && rng.random_bool(0.7) {
                    serde_json::json!(x as i64)
                } else {
                    serde_json::json!(x)
                };
                leaf(&mut doc, &|v| v.is_number(), &mut k, Some(&with));
            }
            4 => {
                let mut n = usize::MAX;
                leaf(&mut doc, &|v| v.is_string(), &mut n, None);
                let mut k = rng.random_range(0..(usize::MAX - n).max(1));
                let with = serde_json::json!(NAMES[rng.random_range(0..NAMES.len())]);
                leaf(&mut doc, &|v| v.is_string(), &mut k, Some(&with));
            }
            5 => drop_member(rng, &mut doc),
            6 | 7 if !bin.is_empty() => {
                for _ in 0..rng.random_range(1..8) {
                    let i = rng.random_range(0..bin.len());
                    bin[i] ^= 1 << rng.random_range(0..8);
                }
            }
            8 if bin.len() >= 4 => {
                let slot = 4 * rng.random_range(0..bin.len() / 4);
                let v = [f32::NAN, f32::INFINITY, -1e38, 1e-42][rng.random_range(0..4)];
                bin[slot..slot + 4].copy_from_slice(&v.to_le_bytes());
            }
            _ => {
                let keep = rng.random_range(0..=bin.len());
                bin.truncate(keep);
            }
        }
    }
    (doc, bin)
}

/// `doc` and `bin` as a binary glTF (its buffer taken from the BIN chunk).
fn glb_bytes(mut doc: serde_json::Value, bin: &[u8]) -> Vec<u8> {
    if let Some(b) = doc.pointer_mut("/buffers/0").and_then(|b| b.as_object_mut()) {
        b.remove("uri");
    }
    let mut json = serde_json::to_vec(&doc).unwrap();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&((28 + json.len() + bin.len()) as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

#[test]
fn gltf_mutants() {
    quiet_panics();
    let dir = tempfile::tempdir().unwrap();
    let mut b = gltf_builder::Builder::default();
    let scene = gltf_scene(&mut b);
    let doc = b.finish(scene, Some("scene.bin"));
    let bin = b.bin.clone();
    let renderer = Renderer::new(1).unwrap();
    let (gltf_path, glb_path) = (dir.path().join("scene.gltf"), dir.path().join("scene.glb"));
    let report = run("gltf", MUTANTS, |rng| {
        let (d, data) = mutate_gltf(rng, &doc, &bin);
        // Mostly semantic mutants; some raw byte mutants of either form.
        let raw = rng.random_bool(0.15);
        if rng.random_bool(0.5) {
            let mut text = serde_json::to_vec_pretty(&d).unwrap();
            if raw {
                text = mutate(rng, &text);
            }
            std::fs::write(&gltf_path, text).unwrap();
            std::fs::write(dir.path().join("scene.bin"), &data).unwrap();
            exercise(&gltf_path, &renderer)
        } else {
            let mut bytes = glb_bytes(d, &data);
            if raw {
                bytes = mutate(rng, &bytes);
            }
            std::fs::write(&glb_path, bytes).unwrap();
            exercise(&glb_path, &renderer)
        }
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
