//! The BART scenes: data integrity, documented counts, golden frames,
//! motion classes, and malformed AFF input.
//!
//! The data is found through `OPENRT_BART_DIR` (default `../shared/bart`
//! from the repository root). Without it these tests fail when `CI` is set
//! and are listed as ignored, with the reason, otherwise (see build.rs).

mod bart_dir;
mod common;

use bart_dir::bart;

use std::path::{Path, PathBuf};

use openrt_accel::BuilderKind;
use openrt_core::{RenderMode, RenderSettings, Renderer};
use openrt_scene::SceneError;
use openrt_scene::aff::{AffPlayer, parse_aff};
use sha2::{Digest, Sha256};

#[test]
#[cfg_attr(not(bart_data), ignore = "BART data not found: set OPENRT_BART_DIR")]
fn the_data_matches_its_checksums() {
    let Some(dir) = bart() else { return };
    let sums = std::fs::read_to_string(dir.join("SHA256SUMS")).unwrap();
    let mut checked = 0;
    for line in sums.lines().filter(|l| !l.trim().is_empty()) {
        let (hash, name) = line.split_once(char::is_whitespace).unwrap();
        let name = name.trim().trim_start_matches('*');
        let bytes = std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let got = Sha256::digest(&bytes).iter().fold(String::new(), |mut s, b| {
            use std::fmt::Write;
            let _ = write!(s, "{b:02x}");
            s
        });
        assert_eq!(got, hash, "{name} is corrupt");
        checked += 1;
    }
    assert!(checked > 60);
}

#[test]
#[cfg_attr(not(bart_data), ignore = "BART data not found: set OPENRT_BART_DIR")]
fn kitchen_and_museum5_have_the_documented_counts() {
    let Some(dir) = bart() else { return };
    let k = parse_aff(&dir.join("kitchen/kitchen.aff")).unwrap();
    assert_eq!(k.counts.mesh_triangles, 110_561);
    assert_eq!(k.counts.mesh_instances, 393);
    assert_eq!(k.counts.lights, 6);
    assert_eq!(k.counts.animated_node_names, 5);
    assert_eq!(k.animation.unwrap().frames, 800);
    assert!(k.tracks.contains_key("camera"));
    let m = parse_aff(&dir.join("museum/museum5.aff")).unwrap();
    assert_eq!(m.counts.mesh_triangles, 10_000);
    assert_eq!(m.counts.polygons, 133);
    assert_eq!(m.counts.textured_triangles, 10);
    assert_eq!(m.counts.cones, 8);
    assert_eq!(m.counts.animated_triangles, 1024);
    assert!(
        m.animated
            .iter()
            .all(|t| t.times.len() == 5 && t.times[0] == 0.0 && t.times[4] == 4.0)
    );
    assert_eq!(m.counts.lights, 2);
    assert_eq!(m.animation.unwrap().frames, 300);
}

fn frame(player: &mut AffPlayer, f: u32) -> openrt_core::Image {
    let t = player.time_of(f);
    player.set_time(t).unwrap();
    let s = RenderSettings {
        width: 160,
        height: 120,
        mode: RenderMode::Whitted,
        max_depth: 3,
        ..RenderSettings::default()
    };
    Renderer::new(2)
        .expect("a render pool")
        .render(&player.ctx.scene(), &player.env, &player.camera(t), &s)
        .unwrap()
        .0
}

#[test]
#[cfg_attr(not(bart_data), ignore = "BART data not found: set OPENRT_BART_DIR")]
fn kitchen_frame_0_and_museum_frame_200_match_their_goldens() {
    let Some(dir) = bart() else { return };
    let mut k = AffPlayer::load(&dir.join("kitchen/kitchen.aff")).unwrap();
    common::check_golden("kitchen-f0", &frame(&mut k, 0), 1.5, 0.01);
    let mut m = AffPlayer::load(&dir.join("museum/museum5.aff")).unwrap();
    common::check_golden("museum5-f200", &frame(&mut m, 200), 1.5, 0.01);
}

#[test]
#[cfg_attr(not(bart_data), ignore = "BART data not found: set OPENRT_BART_DIR")]
fn playback_moves_the_car_and_rebuilds_only_the_animated_triangles() {
    let Some(dir) = bart() else { return };
    let mut k = AffPlayer::load(&dir.join("kitchen/kitchen.aff")).unwrap();
    let first = k.set_time(k.time_of(0)).unwrap();
    assert_eq!(
        first.build_count(BuilderKind::Sah),
        first.builds.len(),
        "first frame: SAH trees only"
    );
    let car_before = k.ctx.scene().instances().iter().map(|i| i.to_world).collect::<Vec<_>>();
    let later = k.set_time(k.time_of(300)).unwrap();
    assert!(later.builds.is_empty(), "the kitchen has only affine motion");
    let car_after = k.ctx.scene().instances().iter().map(|i| i.to_world).collect::<Vec<_>>();
    assert_ne!(car_before, car_after, "the toy car moved");
    // The camera follows its track.
    assert_ne!(k.camera(k.time_of(0)).from, k.camera(k.time_of(300)).from);

    let mut m = AffPlayer::load(&dir.join("museum/museum5.aff")).unwrap();
    m.set_time(m.time_of(0)).unwrap();
    for f in [100, 101, 102] {
        let st = m.set_time(m.time_of(f)).unwrap();
        assert_eq!(st.builds.len(), 1, "only the animated triangles are rebuilt");
        assert_eq!(st.builds[0].builder, BuilderKind::Fast);
        assert_eq!(st.builds[0].triangles, 1024);
    }
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn parse_err(text: &str) -> SceneError {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "t.aff", text);
    match parse_aff(&p) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e,
    }
}

fn assert_parse_error(text: &str, line: usize, needle: &str) {
    let e = parse_err(text);
    match &e {
        SceneError::Parse { line: l, path, .. } => {
            assert_eq!(*l, line, "{e}");
            assert!(path.ends_with("t.aff"), "{e}");
            assert!(e.to_string().contains(needle), "'{needle}' not in: {e}");
        }
        other => panic!("not a parse error: {other}"),
    }
}

#[test]
fn malformed_aff_files_give_file_and_line() {
    // Truncated mesh: the file ends inside the triangle list.
    assert_parse_error(
        "m\n vertices 3\n 0 0 0\n 1 0 0\n 0 1 0\n triangles 2\n 0 1 2\n",
        7,
        "file ends",
    );
    // Wrong count: fewer vertices than announced, so a keyword is read as a number.
    assert_parse_error(
        "m\nvertices 4\n0 0 0\n1 0 0\n0 1 0\ntriangles 1\n0 1 2\n",
        6,
        "expected vertex",
    );
    // Bad index.
    assert_parse_error(
        "m\nvertices 3\n0 0 0\n1 0 0\n0 1 0\ntriangles 1\n0 1 3\n",
        7,
        "out of range",
    );
    // NaN and infinity.
    assert_parse_error("p 3\n0 0 0\n1 nan 0\n0 1 0\n", 3, "not a finite number");
    assert_parse_error("l 1 2 inf\n", 1, "not a finite number");
    // Unknown command, unmatched braces, bad xs.
    assert_parse_error("b 0 0 0\nq 1 2 3\n", 2, "unknown command 'q'");
    assert_parse_error("xs 1 1 1 0 1 0 0 0 0 0\n{\n p 3 0 0 0 1 0 0 0 1 0\n", 3, "'}' expected");
    assert_parse_error("}\n", 1, "without a matching");
    assert_parse_error("x {\n}\n", 1, "needs a name");
    // tpa without samples.
    assert_parse_error("tpa 0\n", 1, "sample count");
    // A missing include names the file at the include line.
    assert_parse_error("b 0 0 0\ni 0 nothere.aff\n", 2, "nothere.aff");
}

#[test]
fn include_cycles_and_missing_textures_are_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    write(dir, "a.aff", "i 0 b.aff\n");
    let b = write(dir, "b.aff", "i 0 a.aff\n");
    let e = parse_aff(&b).err().unwrap();
    assert!(e.to_string().contains("deeper than"), "{e}");
    let t = write(dir, "tex.aff", "tt missing.ppm\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n");
    let e = AffPlayer::load(&t).err().unwrap();
    assert!(
        matches!(e, SceneError::Texture { .. }) && e.to_string().contains("missing.ppm"),
        "{e}"
    );
}

/// With `CI` set, the BART data must be there: the data tests are not
/// allowed to be ignored in CI.
#[test]
fn ci_runs_have_the_bart_data() {
    let found = cfg!(bart_data);
    assert!(
        found || std::env::var_os("CI").is_none(),
        "CI is set but the BART data was not found (set OPENRT_BART_DIR)"
    );
}

/// A key that goes back in time is dropped with a warning at its line (the
/// BART robots repeat a run of keys); `open_strict` makes it the error.
#[test]
fn keys_going_back_in_time_are_dropped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(
        dir.path(),
        "k.aff",
        "v\nfrom 0 0 5\nat 0 0 0\nup 0 1 0\nangle 45\nhither 0.1\nresolution 8 8\na 0 3 4\nx n {\n p 3 0 0 0 1 0 0 0 1 0\n}\n\
         k n {\n transl 4\n 0 0 0 0 0 0 0\n 2 1 0 0 0 0 0\n 1 5 0 0 0 0 0\n 3 2 0 0 0 0 0\n}\n",
    );
    let scene = parse_aff(&p).unwrap();
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    let w = scene.warnings[0].to_string();
    assert!(w.contains("k.aff:16:") && w.contains("time 1 after 2 dropped"), "{w}");
    assert_eq!(scene.tracks["n"].translation.len(), 3, "the other keys are kept");
    let player = openrt_scene::ScenePlayer::open(Some(&p)).unwrap();
    assert_eq!(player.warnings().len(), 1);
    let e = openrt_scene::ScenePlayer::open_strict(Some(&p))
        .err()
        .expect("strict refuses")
        .to_string();
    assert!(e.contains("k.aff:16:") && e.contains("--strict"), "{e}");
}

/// The robots as the data's README describes them, with the keys of
/// `Robot1.aff` that go back in time dropped with warnings.
#[test]
#[cfg_attr(not(bart_data), ignore = "BART data not found: set OPENRT_BART_DIR")]
fn robots_have_the_documented_counts() {
    let Some(dir) = bart() else { return };
    let r = parse_aff(&dir.join("robots/Robot.aff")).unwrap();
    assert_eq!(
        r.counts.mesh_triangles, 71_708,
        "triangles once the includes are expanded"
    );
    assert_eq!(r.counts.mesh_instances, 1849);
    assert_eq!(r.counts.lights, 1);
    assert_eq!(r.counts.animated_node_names, 190);
    assert_eq!(r.textures.len(), 44, "44 PPM textures");
    assert_eq!(r.animation.unwrap().frames, 800);
    assert_eq!(r.warnings.len(), 12);
    assert!(
        r.warnings
            .iter()
            .all(|w| w.path.ends_with("Robot1.aff") && w.msg.contains("gun_rot1")),
        "{:?}",
        r.warnings
    );
    let mut p = openrt_scene::ScenePlayer::open(Some(&repo_scene("robots"))).unwrap();
    p.set_time(p.time_of(0)).unwrap();
    let s = p.ctx().scene();
    assert_eq!(s.instances().len(), 161, "161 instances");
    assert_eq!(s.instanced_triangles(), 71_580, "71.6k triangles once instanced");
    // Distinct geometry: about 15.5k triangles in the objects.
    let mut seen = std::collections::HashSet::new();
    let distinct: usize = s
        .instances()
        .iter()
        .filter(|i| seen.insert(i.object))
        .map(|i| i.geometry.tree.triangles().len())
        .sum();
    assert!((15_000..16_000).contains(&distinct), "{distinct} distinct triangles");
}

fn repo_scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../scenes/{name}.ron"))
}

#[test]
#[cfg_attr(not(bart_data), ignore = "BART data not found: set OPENRT_BART_DIR")]
fn robots_frame_400_matches_its_golden() {
    let Some(dir) = bart() else { return };
    let mut r = AffPlayer::load(&dir.join("robots/Robot.aff")).unwrap();
    common::check_golden("robots-f400", &frame(&mut r, 400), 1.5, 0.01);
}
