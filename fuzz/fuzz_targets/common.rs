//! What every scene target does with a scene that loaded: plays two times
//! and renders a tiny frame on one render thread. Errors are fine; a panic,
//! an abort or a hang is a finding.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use openrt_core::{CoreError, RenderMode, RenderSettings, Renderer};
use openrt_scene::ScenePlayer;

fn renderer() -> &'static Mutex<Renderer> {
    static R: OnceLock<Mutex<Renderer>> = OnceLock::new();
    R.get_or_init(|| Mutex::new(Renderer::new(1).expect("one render thread")))
}

/// A scratch folder holding the files scenes may refer to: the fixtures'
/// include file and texture, and the shipped scenes' textures and models.
pub fn scratch() -> &'static Path {
    static D: OnceLock<tempfile::TempDir> = OnceLock::new();
    D.get_or_init(|| {
        let d = tempfile::tempdir().expect("scratch folder");
        let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let data = repo.join("crates/openrt-scene/tests/data");
        for f in ["sample_inc.aff", "sample.ppm", "sample.obj"] {
            std::fs::copy(data.join(f), d.path().join(f)).expect("fixture");
        }
        for sub in ["textures", "models"] {
            std::fs::create_dir_all(d.path().join(sub)).expect("folder");
            for e in std::fs::read_dir(repo.join("scenes").join(sub)).expect("scenes") {
                let e = e.expect("entry");
                std::fs::copy(e.path(), d.path().join(sub).join(e.file_name())).expect("copy");
            }
        }
        d
    })
    .path()
}

/// Writes `bytes` to `name` in the scratch folder.
pub fn write(name: &str, bytes: &[u8]) -> PathBuf {
    let p = scratch().join(name);
    std::fs::write(&p, bytes).expect("scratch write");
    p
}

/// Plays and renders a loaded scene.
pub fn exercise(mut p: ScenePlayer) {
    let r = renderer().lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    for f in [0, p.frames() / 2] {
        let t = p.time_of(f);
        if p.set_time(t).is_err() {
            return;
        }
        let settings = RenderSettings {
            width: 6,
            height: 4,
            mode: RenderMode::Whitted,
            max_depth: 3,
            ..RenderSettings::default()
        };
        match r.render(&p.ctx().scene(), &p.env(), &p.camera(t), &settings) {
            Err(CoreError::RenderThread { reason }) => panic!("render thread failed: {reason}"),
            Err(_) => return,
            Ok((img, _)) => assert!(img.pixels.iter().all(|c| c.is_finite()), "non-finite pixel"),
        }
    }
}
