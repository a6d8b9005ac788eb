//! `openrt`: headless rendering of OpenRT-rs scenes.
//!
//! ```text
//! openrt render [SCENE.ron] -o out.png [--width W --height H --mode gl|whitted --depth N --threads N --frame N]
//! ```
//! Without a scene file the built-in default scene is rendered.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

use clap::{Parser, Subcommand, ValueEnum};
use openrt_core::{RenderMode, Renderer};

#[derive(Parser)]
#[command(
    name = "openrt",
    version,
    about = "Interactive ray tracing of dynamic scenes, headless"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, ValueEnum)]
enum Mode {
    /// Primary rays and local shading, no shadows.
    Gl,
    /// Whitted ray tracing: shadows, reflection, refraction.
    Whitted,
}

#[derive(Subcommand)]
enum Command {
    /// Renders one frame of a scene to a PNG file.
    Render {
        /// Scene file (.ron); the built-in default scene when omitted.
        scene: Option<PathBuf>,
        /// Output PNG.
        #[arg(short, long, default_value = "out.png")]
        output: PathBuf,
        /// Image width (default: the scene's).
        #[arg(long)]
        width: Option<u32>,
        /// Image height (default: the scene's).
        #[arg(long)]
        height: Option<u32>,
        /// Shading mode.
        #[arg(long, value_enum, default_value_t = Mode::Whitted)]
        mode: Mode,
        /// Reflection/refraction depth.
        #[arg(long, default_value_t = 3)]
        depth: u32,
        /// Render threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Frame of an animated scene (static scenes have only frame 0).
        #[arg(long, default_value_t = 0)]
        frame: u32,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<(), String> {
    match cli.command {
        Command::Render {
            scene,
            output,
            width,
            height,
            mode,
            depth,
            threads,
            frame,
        } => {
            let loaded = match &scene {
                Some(p) => openrt_scene::load_ron(p),
                None => openrt_scene::default_scene(),
            }
            .map_err(|e| e.to_string())?;
            if frame != 0 {
                return Err(format!("--frame {frame}: this scene is static and has only frame 0"));
            }
            let mut settings = loaded.settings;
            settings.width = width.unwrap_or(settings.width);
            settings.height = height.unwrap_or(settings.height);
            settings.mode = match mode {
                Mode::Gl => RenderMode::GlLike,
                Mode::Whitted => RenderMode::Whitted,
            };
            settings.max_depth = depth;
            let threads = threads
                .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, std::num::NonZero::get))
                .max(1);
            let renderer = Renderer::new(threads);
            let scene3 = loaded.ctx.scene();
            let env = Arc::new(loaded.env);
            let (img, stats) = renderer
                .render(&scene3, &env, &loaded.camera, &settings)
                .map_err(|e| e.to_string())?;
            save_png(&output, &img)?;
            let r = stats.rays;
            println!(
                "{}: {}x{} {:?} depth {} on {} threads: {:.1} ms, {:.2} Mrays/s (primary {}, shadow {}, reflection {}, refraction {}); {} instances, {} triangles",
                output.display(),
                settings.width,
                settings.height,
                settings.mode,
                settings.max_depth,
                stats.threads,
                stats.render_ms,
                stats.mrays_per_s,
                r.primary,
                r.shadow,
                r.reflection,
                r.refraction,
                scene3.instances().len(),
                scene3.instanced_triangles()
            );
            Ok(())
        }
    }
}

fn save_png(path: &Path, img: &openrt_core::Image) -> Result<(), String> {
    image::save_buffer(path, &img.to_rgb8(), img.width, img.height, image::ColorType::Rgb8)
        .map_err(|e| format!("{}: cannot write PNG: {e}", path.display()))
}
