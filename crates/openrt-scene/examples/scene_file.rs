//! Open a scene file (RON, or BART's AFF) and render one frame of it to PNG:
//! the file supplies the objects, their motion, the camera, the lights and
//! the image size.
//!
//! ```sh
//! cargo run --release -p openrt-scene --example scene_file -- [SCENE [FRAME [OUT.png]]]
//! # default: the built-in room scene, frame 0, target/scene_file.png
//! cargo run --release -p openrt-scene --example scene_file -- scenes/animated.ron 10 animated.png
//! ```

use std::path::{Path, PathBuf};

use openrt_core::prelude::*;
use openrt_scene::ScenePlayer;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let scene_path = args.next().map(PathBuf::from);
    let frame: u32 = args.next().map_or(Ok(0), |f| f.parse())?;
    let out = args.next().unwrap_or_else(|| "target/scene_file.png".into());
    let line = run(scene_path.as_deref(), frame, Path::new(&out), None)?;
    println!("{line}");
    Ok(())
}

/// Renders `frame` of the scene at `scene` (the built-in scene for `None`)
/// to `out`, at `size` when given (else the scene's); returns a summary.
pub fn run(
    scene_path: Option<&Path>,
    frame: u32,
    out: &Path,
    size: Option<(u32, u32)>,
) -> Result<String, Box<dyn std::error::Error>> {
    // Errors name the file and, where known, the line (a typed SceneError).
    let mut player = ScenePlayer::open(scene_path)?;
    for warning in player.warnings() {
        eprintln!("warning: {warning}");
    }
    let time = player.time_of(frame.min(player.frames().saturating_sub(1)));
    // Moves every instance and redefines deforming objects for that time,
    // then commits.
    let stats = player.set_time(time)?;

    let renderer = Renderer::with_pool(player.ctx_mut().pool()?);
    let mut settings = player.settings();
    if let Some((width, height)) = size {
        (settings.width, settings.height) = (width, height);
    }
    let (image, frame_stats) =
        renderer.render(&player.ctx().scene(), &player.env(), &player.camera(time), &settings)?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    image.save_png(out)?;
    Ok(format!(
        "{}: {}x{}, {} instances, commit {:.2} ms, render {:.1} ms ({:.2} Mrays/s)",
        out.display(),
        image.width,
        image.height,
        stats.instances,
        stats.total_ms,
        frame_stats.render_ms,
        frame_stats.mrays_per_s
    ))
}
