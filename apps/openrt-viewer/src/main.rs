//! `openrt-viewer`: the interactive viewer of OpenRT-rs.
//!
//! ```text
//! openrt-viewer [SCENE.ron|SCENE.aff] [--threads N] [--screenshot out.png --frames N]
//! ```
//! Renders continuously on a background thread and shows each finished
//! frame; with `--screenshot`, plays N frames, saves a screenshot of the
//! window (and `out.json` with what the overlay reported) and exits.

mod app;
mod orbit;
mod worker;

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use clap::Parser;

#[derive(Parser)]
#[command(name = "openrt-viewer", version, about = "Interactive ray tracing of dynamic scenes")]
struct Cli {
    /// Scene file (.ron, .aff, .gltf or .glb); the built-in default scene when omitted.
    scene: Option<PathBuf>,
    /// Render threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Play the animation, save a screenshot of the window to this PNG after `--frames` frames, and exit.
    #[arg(long)]
    screenshot: Option<PathBuf>,
    /// Frames to render before the screenshot.
    #[arg(long, default_value_t = 10)]
    frames: u32,
    /// With `--screenshot`: hold the first frame still, so that each frame adds a sample, instead of playing.
    #[arg(long, requires = "screenshot")]
    still: bool,
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    let threads = cli
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, std::num::NonZero::get));
    if let Err(e) = openrt_core::check_threads("--threads", threads) {
        eprintln!("error: {e}");
        return std::process::ExitCode::FAILURE;
    }
    let failure = Arc::new(Mutex::new(None));
    let options = eframe::NativeOptions {
        viewport: eframe::egui::ViewportBuilder::default()
            .with_inner_size([1100.0, 700.0])
            .with_title("OpenRT-rs"),
        ..Default::default()
    };
    let opts = app::Options {
        scene: cli.scene,
        screenshot: cli.screenshot,
        frames: cli.frames,
        threads,
        still: cli.still,
        failure: Arc::clone(&failure),
    };
    match eframe::run_native(
        "OpenRT-rs",
        options,
        Box::new(move |cc| Ok(Box::new(app::ViewerApp::new(cc, opts)))),
    ) {
        // The error was printed when it happened.
        Ok(()) if failure.lock().is_ok_and(|f| f.is_some()) => std::process::ExitCode::FAILURE,
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
