//! `openrt`: headless rendering and playback of OpenRT-rs scenes.
//!
//! ```text
//! openrt render [SCENE] -o out.png [--width W --height H --mode gl|whitted --depth N --threads N (--frame N | --time T)]
//! openrt play SCENE [--frames A..B] [-o DIR] [--stats stats.jsonl] [...same quality options]
//! ```
//! SCENE is a `.ron` or `.aff` file; without one the built-in default scene is used.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

mod bench;
#[cfg(feature = "mpi")]
mod distributed;
mod soak;

/// Where frames are rendered: here, or on the MPI workers (feature `mpi`,
/// under `mpirun` with more than one rank).
#[cfg(feature = "mpi")]
type Cluster = distributed::Cluster;
/// Where frames are rendered: always here in a build without `mpi`.
#[cfg(not(feature = "mpi"))]
enum Cluster {}

/// Renders the current frame of `player` at time `t` into `img` (its
/// buffer reused frame after frame): here, or on the cluster (its replicas
/// get the change set of the player's last commit).
fn render_frame(
    player: &mut ScenePlayer,
    t: f32,
    s: &RenderSettings,
    renderer: &Renderer,
    cluster: Option<&Cluster>,
    img: &mut Image,
) -> Result<(openrt_core::FrameStats, Option<serde_json::Value>), String> {
    #[cfg(feature = "mpi")]
    if let Some(c) = cluster {
        let changes = player
            .ctx_mut()
            .take_changes()
            .ok_or("the scene's context does not record its changes")?;
        let scene = player.ctx().scene();
        let (frame, net) = c.render(&changes, &player.camera(t), &player.env(), s, Some((renderer, &scene)))?;
        *img = frame;
        let rays = openrt_core::RayCounts {
            primary: net.rays[0],
            shadow: net.rays[1],
            reflection: net.rays[2],
            refraction: net.rays[3],
        };
        let stats = openrt_core::FrameStats {
            rays,
            render_ms: net.render_ms,
            mrays_per_s: rays.total() as f64 / (net.render_ms * 1e3).max(1e-3),
            threads: renderer.threads(),
            phases: None,
        };
        let figures = serde_json::json!({
            "ranks": c.workers() + 1,
            "bytes_sent": net.bytes_sent,
            "broadcast_ms": net.broadcast_ms,
            "worker_commit_ms": net.worker_commit_ms,
            "render_gather_ms": net.render_ms,
            "bytes_gathered": net.bytes_gathered,
            "tiles_stolen": net.stolen,
        });
        return Ok((stats, Some(figures)));
    }
    #[cfg(not(feature = "mpi"))]
    let _ = cluster;
    let st = renderer
        .render_into(&player.ctx().scene(), &player.env(), &player.camera(t), s, img)
        .map_err(|e| e.to_string())?;
    Ok((st, None))
}

/// Most frames `openrt bench --frames` samples per scene.
const MAX_BENCH_FRAMES: usize = 1000;

use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use openrt_accel::BuilderKind;
use openrt_core::{Accel, Backend, Image, RenderMode, RenderSettings, Renderer, TextureFilter, TopLevel};
use openrt_scene::{GltfAnimation, GltfOptions, ScenePlayer};

#[derive(Parser)]
#[command(
    name = "openrt",
    version,
    about = "Interactive ray tracing of dynamic scenes, headless"
)]
struct Cli {
    /// Treat load warnings (such as AFF keys that go back in time, which are
    /// dropped) as errors.
    #[arg(long, global = true)]
    strict: bool,
    /// Under mpirun (builds with `--features mpi`): rank 0 renders tiles too,
    /// besides coordinating the workers.
    #[arg(long, global = true)]
    mpi_root_renders: bool,
    /// Under mpirun: how rank 0 hands out tiles: `dynamic` (workers ask for
    /// the next few) or `static` (interleaved shares, with stealing at the end).
    #[arg(long, global = true, default_value = "dynamic", value_parser = ["dynamic", "static"])]
    mpi_tiles: String,
    /// glTF files: the scene played, `scenes[N]` (default: the file's default scene).
    #[arg(long = "scene", global = true, value_name = "N")]
    gltf_scene: Option<usize>,
    /// glTF files: the animation played, by name or index, `all` (together,
    /// looping over the longest) or `none` (default: the first).
    #[arg(long, global = true, value_name = "NAME|INDEX|all|none")]
    animation: Option<GltfAnimation>,
    /// glTF files: the camera, `cameras[N]` (default: the first perspective camera met).
    #[arg(long, global = true, value_name = "N")]
    camera: Option<usize>,
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

#[derive(Args, Clone)]
struct Quality {
    /// Image width (default: the scene's).
    #[arg(long)]
    width: Option<u32>,
    /// Image height (default: the scene's).
    #[arg(long)]
    height: Option<u32>,
    /// Shading mode.
    #[arg(long, value_enum, default_value_t = Mode::Whitted)]
    mode: Mode,
    /// Reflection/refraction depth (a bounce whose weight in the pixel is below
    /// 1/255 in every channel stops sooner: `openrt_core::MIN_RAY_WEIGHT`).
    #[arg(long, default_value_t = 3)]
    depth: u32,
    /// Render threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Texture filter: `trilinear` (mipmaps, level of detail from ray cones), `bilinear` or `nearest`.
    #[arg(long, default_value = "trilinear")]
    texture_filter: TextureFilter,
    /// Samples per pixel (low-discrepancy positions, the same for any thread count).
    #[arg(long, default_value_t = 1)]
    spp: u32,
    /// Traversal backend: `packets` (ray packets) or `single` (one ray at a time) over the
    /// objects' structure (`--accel`); `kd`, `kd-single`, `bvh` and `bvh-single` name the
    /// structure too; builds with `--features embree` add `embree` and `embree-packet`.
    #[arg(long, default_value = "packets")]
    backend: BackendChoice,
    /// Object structure: `bvh` (wide BVHs: 4-wide packets, 8-wide single rays on AVX2) or `kd`
    /// (the paper's kd-trees); the same images (default: the scene's `accel`, else `bvh`).
    #[arg(long)]
    accel: Option<Accel>,
    /// Top level over the instances: `auto` (the paper's BSP, a BVH from 64 instances), `bsp` or `bvh`;
    /// the same images (default: the scene's `top_level`, else `auto`).
    #[arg(long)]
    top_level: Option<TopLevel>,
}

#[derive(Subcommand)]
enum Command {
    /// Renders one frame of a scene to a PNG file.
    Render {
        /// Scene file (.ron, .aff, .gltf or .glb); the built-in default scene when omitted.
        scene: Option<PathBuf>,
        /// Output PNG.
        #[arg(short, long, default_value = "out.png")]
        output: PathBuf,
        #[command(flatten)]
        quality: Quality,
        /// Frame of an animated scene.
        #[arg(long, conflicts_with = "time")]
        frame: Option<u32>,
        /// Scene time of an animated scene.
        #[arg(long)]
        time: Option<f32>,
        /// Prints the frame's time split by phase (camera rays, queries by
        /// kind, surfaces, textures, light loop, image); the same image.
        #[arg(long)]
        phases: bool,
    },
    /// Measures the paper's table, speed against error and builder trade-offs; writes docs/BENCHMARKS.md.
    Bench {
        /// Scenes (names in scenes/ or files), comma-separated; the first is used for speed against error.
        #[arg(
            long,
            default_value = "kitchen,robots,museum1k,museum4k,museum16k,terrain",
            value_delimiter = ','
        )]
        scenes: Vec<String>,
        /// Frames sampled across each animation.
        #[arg(long, default_value_t = 5)]
        frames: usize,
        /// Image width.
        #[arg(long, default_value_t = 640)]
        width: u32,
        /// Image height.
        #[arg(long, default_value_t = 480)]
        height: u32,
        /// Thread counts, comma-separated (default: 1 and all cores).
        #[arg(long, value_delimiter = ',')]
        threads: Option<Vec<usize>>,
        /// Triangles of the skinned glTF figures whose per-frame cost is
        /// measured, comma-separated (`0` measures none).
        #[arg(long, default_value = "10000,100000,1000000", value_delimiter = ',')]
        deform_sizes: Vec<usize>,
        /// Report file (default: docs/BENCHMARKS.md; with `--device`, docs/BENCHMARKS-DEVICE.md).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// A run on a larger machine (the 16-core device): thread counts
        /// 1, 2, 4, 8 and 16 (up to the cores), the paper's range, and the
        /// report written to docs/BENCHMARKS-DEVICE.md, which says when and
        /// on what machine it ran.
        #[arg(long)]
        device: bool,
    },
    /// Plays a scene in a loop for many frames, sampling resident memory and frame time.
    Soak {
        /// Scene file (.ron, .aff, .gltf or .glb).
        scene: PathBuf,
        /// Frames in all (the animation loops).
        #[arg(long, default_value_t = 10_000)]
        frames: u64,
        /// Frames per sample.
        #[arg(long, default_value_t = 100)]
        every: u64,
        /// Samples as JSON lines.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// SVG plot of memory and frame time.
        #[arg(long)]
        plot: Option<PathBuf>,
        #[command(flatten)]
        quality: Quality,
    },
    /// Plays an animation headless, writing frames and per-frame statistics.
    Play {
        /// Scene file (.ron, .aff, .gltf or .glb).
        scene: PathBuf,
        /// Frames to play, `A..B` (B exclusive) or `A..=B`; default all.
        #[arg(long)]
        frames: Option<String>,
        /// Folder for the frames as PNG (none written when omitted).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Per-frame statistics as JSON lines (default: DIR/stats.jsonl, or stdout without DIR).
        #[arg(long)]
        stats: Option<PathBuf>,
        #[command(flatten)]
        quality: Quality,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Err(e) = check_lanes_env() {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    openrt_accel::set_frustum_culling(std::env::var_os(NO_FRUSTUM_ENV).is_none());
    #[cfg(feature = "mpi")]
    if let Some(cluster) = distributed::Cluster::start(cli.mpi_root_renders, cli.mpi_tiles == "static") {
        return run_mpi(cli, &cluster);
    }
    match run(cli, None) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Under `mpirun`: rank 0 runs the command with the other ranks as its
/// renderers; they work until it stops them.
#[cfg(feature = "mpi")]
fn run_mpi(cli: Cli, cluster: &Cluster) -> ExitCode {
    if cluster.rank() > 0 {
        let threads = match &cli.command {
            Command::Render { quality, .. } | Command::Play { quality, .. } | Command::Soak { quality, .. } => {
                threads(quality)
            }
            Command::Bench { .. } => std::thread::available_parallelism().map_or(1, std::num::NonZero::get),
        };
        return match cluster.work(threads) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("error: MPI rank {}: {e}", cluster.rank());
                ExitCode::FAILURE
            }
        };
    }
    let r = run(cli, Some(cluster));
    match r {
        Ok(()) => {
            cluster.stop();
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            // Workers may be busy or gone: end the whole job.
            cluster.abort(1)
        }
    }
}

/// Opens a scene (with the glTF choices of `gltf`); its load warnings are
/// printed once (or, with `--strict`, the first one is the error).
pub fn open_scene(path: Option<&Path>, strict: bool, gltf: &GltfOptions) -> Result<ScenePlayer, String> {
    let player = if strict {
        ScenePlayer::open_strict_with(path, gltf).map_err(|e| e.to_string())?
    } else {
        ScenePlayer::open_with(path, gltf).map_err(|e| e.to_string())?
    };
    print_warnings(&player);
    Ok(player)
}

/// Prints a scene's load warnings, the first [`MAX_PRINTED_WARNINGS`] of them.
fn print_warnings(player: &ScenePlayer) {
    let w = player.warnings();
    for warning in w.iter().take(MAX_PRINTED_WARNINGS) {
        eprintln!("warning: {warning}");
    }
    if w.len() > MAX_PRINTED_WARNINGS {
        eprintln!(
            "warning: {} more warnings not shown (--strict makes the first an error)",
            w.len() - MAX_PRINTED_WARNINGS
        );
    }
}

/// `--backend`: a traversal backend, and for `kd`, `kd-single`, `bvh` and
/// `bvh-single` the structure under the objects too.
#[derive(Clone, Copy, Debug)]
struct BackendChoice {
    backend: Backend,
    accel: Option<Accel>,
}

impl std::str::FromStr for BackendChoice {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (backend, accel) = match Backend::from_label(s) {
            Some((b, a)) => (b, Some(a)),
            None => (
                s.parse::<Backend>()
                    .map_err(|e| format!("{e}, kd, kd-single, bvh, bvh-single"))?,
                None,
            ),
        };
        Ok(Self { backend, accel })
    }
}

/// Load warnings printed one by one; the rest are counted.
const MAX_PRINTED_WARNINGS: usize = 20;

fn settings(player: &ScenePlayer, q: &Quality) -> RenderSettings {
    let mut s = player.settings();
    s.width = q.width.unwrap_or(s.width);
    s.height = q.height.unwrap_or(s.height);
    s.mode = match q.mode {
        Mode::Gl => RenderMode::GlLike,
        Mode::Whitted => RenderMode::Whitted,
    };
    s.max_depth = q.depth;
    s.texture_filter = q.texture_filter;
    s.spp = q.spp;
    s
}

/// Gives the scene's commit pool the render thread count (`--threads`).
fn commit_threads(player: &mut ScenePlayer, q: &Quality) -> Result<(), String> {
    // The scene's objects are rebuilt with this structure at the next commit.
    if let Some(a) = q.accel.or(q.backend.accel) {
        player.set_accel(a).map_err(|e| e.to_string())?;
    }
    if let Some(t) = q.top_level {
        player.ctx_mut().set_top_level(t);
    }
    player
        .ctx_mut()
        .set_threads(threads(q))
        .map_err(|e| format!("--threads: {e}"))
}

/// The renderer for the quality options (backend), on the scene's pool
/// (`commit_threads` sized it): one pool commits and renders.
fn renderer(player: &mut ScenePlayer, q: &Quality) -> Result<Renderer, String> {
    let pool = player.ctx_mut().pool().map_err(|e| format!("--threads: {e}"))?;
    let mut r = new_renderer(pool);
    r.set_backend(q.backend.backend);
    Ok(r)
}

/// A renderer of its own pool (`--threads`), for a run that opens its scene itself.
fn own_renderer(q: &Quality) -> Result<Renderer, String> {
    let mut r = Renderer::new(threads(q)).map_err(|e| format!("--threads: {e}"))?;
    r.set_packet_width(packet_width());
    r.set_backend(q.backend.backend);
    Ok(r)
}

/// Environment variable that forces the packet width (4, 8, 16 or 32) of every
/// renderer the CLI makes; the library itself reads no environment.
pub(crate) const LANES_ENV: &str = "OPENRT_PACKET_LANES";

/// Environment variable that turns frustum culling off (A/B runs: the
/// images are the same bytes either way).
pub(crate) const NO_FRUSTUM_ENV: &str = "OPENRT_NO_FRUSTUM";

/// Refuses a [`LANES_ENV`] that names no packet width (set but empty,
/// not a number, or another count of lanes), before any work starts.
fn check_lanes_env() -> Result<(), String> {
    match std::env::var_os(LANES_ENV) {
        None => Ok(()),
        Some(v) => match v.to_str().and_then(openrt_accel::PacketWidth::parse) {
            Some(_) => Ok(()),
            None => Err(format!(
                "{LANES_ENV}={}: a packet has 4, 8, 16 or 32 lanes (unset it for the CPU's width)",
                v.to_string_lossy()
            )),
        },
    }
}

/// The packet width: [`LANES_ENV`] when it names one (4, 8, 16 or 32), else
/// the CPU's.
pub(crate) fn packet_width() -> openrt_accel::PacketWidth {
    std::env::var(LANES_ENV)
        .ok()
        .and_then(|v| openrt_accel::PacketWidth::parse(&v))
        .unwrap_or_else(openrt_accel::PacketWidth::detect)
}

/// A renderer on `pool` with the CLI's packet width ([`packet_width`]).
pub(crate) fn new_renderer(pool: openrt_core::ThreadPool) -> Renderer {
    let mut r = Renderer::with_pool(pool);
    r.set_packet_width(packet_width());
    r
}

fn threads(q: &Quality) -> usize {
    q.threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, std::num::NonZero::get))
}

/// Parses `A..B` or `A..=B` into a half-open range clamped to `n` frames.
fn frame_range(spec: Option<&str>, n: u32) -> Result<std::ops::Range<u32>, String> {
    let Some(spec) = spec else { return Ok(0..n) };
    let bad = || format!("--frames {spec}: expected A..B or A..=B with A <= B");
    let (a, b, inclusive) = if let Some((a, b)) = spec.split_once("..=") {
        (a, b, true)
    } else if let Some((a, b)) = spec.split_once("..") {
        (a, b, false)
    } else {
        return Err(bad());
    };
    let a: u32 = if a.is_empty() { 0 } else { a.parse().map_err(|_| bad())? };
    let b: u32 = if b.is_empty() {
        n
    } else {
        b.parse::<u32>()
            .ok()
            .and_then(|b| b.checked_add(u32::from(inclusive)))
            .ok_or_else(bad)?
    };
    if a > b {
        return Err(bad());
    }
    if b > n {
        return Err(format!("--frames {spec}: the scene has {n} frames (0..{n})"));
    }
    Ok(a..b)
}

fn run(cli: Cli, cluster: Option<&Cluster>) -> Result<(), String> {
    let strict = cli.strict;
    let gltf = GltfOptions {
        scene: cli.gltf_scene,
        animation: cli.animation.clone().unwrap_or_default(),
        camera: cli.camera,
    };
    match cli.command {
        Command::Render {
            scene,
            output,
            quality,
            frame,
            time,
            phases,
        } => {
            let mut player = open_scene(scene.as_deref(), strict, &gltf)?;
            commit_threads(&mut player, &quality)?;
            if cluster.is_some() {
                player.ctx_mut().record_changes();
            }
            let t = match (frame, time) {
                (Some(f), _) if f >= player.frames() => {
                    return Err(format!("--frame {f}: the scene has {} frames", player.frames()));
                }
                (Some(f), _) => player.time_of(f),
                (None, Some(t)) if !t.is_finite() => return Err(format!("--time {t} is not finite")),
                (None, Some(t)) => t,
                (None, None) => player.time_of(0),
            };
            let commit = player.set_time(t).map_err(|e| e.to_string())?;
            let s = settings(&player, &quality);
            let mut renderer = renderer(&mut player, &quality)?;
            renderer.set_phase_timing(phases);
            let mut img = Image::default();
            let (stats, net) = render_frame(&mut player, t, &s, &renderer, cluster, &mut img)?;
            save_png(&output, &img)?;
            if let Some(p) = stats.phases {
                let spans: Vec<String> = p
                    .named()
                    .iter()
                    .map(|&(name, ns)| format!("{name} {:.2}", ns as f64 / 1e6))
                    .collect();
                println!("phases (ms, summed over threads): {}", spans.join(", "));
            } else if phases {
                println!("phases: not timed (a distributed frame is timed by its ranks)");
            }
            if let Some(net) = net {
                println!("distributed: {net}");
            }
            let scene = player.ctx().scene();
            let r = stats.rays;
            println!(
                "{}: t={t} {}x{} {:?} depth {} on {} threads, backend {} over {} objects under a {} top level: render {:.1} ms, {:.2} Mrays/s (primary {}, shadow {}, reflection {}, refraction {}); commit {:.1} ms; {} instances, {} triangles; {}",
                output.display(),
                s.width,
                s.height,
                s.mode,
                s.max_depth,
                stats.threads,
                renderer.backend().name(),
                player.ctx().accel().name(),
                scene.top_level().name(),
                stats.render_ms,
                stats.mrays_per_s,
                r.primary,
                r.shadow,
                r.reflection,
                r.refraction,
                commit.total_ms,
                scene.instances().len(),
                scene.instanced_triangles(),
                player.motion_classes()
            );
            Ok(())
        }
        Command::Bench {
            scenes,
            frames,
            width,
            height,
            threads,
            deform_sizes,
            output,
            device,
        } => {
            let all = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
            let mut threads = threads.unwrap_or_else(|| {
                if device {
                    [1, 2, 4, 8, 16].into_iter().filter(|&t| t <= all).collect()
                } else {
                    vec![1, all]
                }
            });
            let output = output.unwrap_or_else(|| {
                PathBuf::from(if device {
                    "docs/BENCHMARKS-DEVICE.md"
                } else {
                    "docs/BENCHMARKS.md"
                })
            });
            threads.sort_unstable();
            threads.dedup();
            if threads.contains(&0) || frames == 0 || width < 4 || height < 4 {
                return Err("bench: threads and frames must be at least 1, the image at least 4x4".into());
            }
            if let Some(&n) = deform_sizes.iter().find(|&&n| n > openrt_scene::MAX_FIGURE_TRIANGLES) {
                return Err(format!(
                    "bench --deform-sizes {n}: at most {} triangles (MAX_FIGURE_TRIANGLES)",
                    openrt_scene::MAX_FIGURE_TRIANGLES
                ));
            }
            if frames > MAX_BENCH_FRAMES {
                return Err(format!(
                    "bench --frames {frames}: at most {MAX_BENCH_FRAMES} frames are sampled (MAX_BENCH_FRAMES)"
                ));
            }
            let command = std::env::args()
                .map(|a| if a.contains(' ') { format!("'{a}'") } else { a })
                .collect::<Vec<_>>()
                .join(" ");
            bench::run(&bench::BenchOptions {
                scenes,
                frames,
                width,
                height,
                threads,
                deform_sizes: deform_sizes.into_iter().filter(|&n| n > 0).collect(),
                out: output,
                command,
                device,
            })
        }
        Command::Soak {
            scene,
            frames,
            every,
            output,
            plot,
            quality,
        } => {
            let player = open_scene(Some(&scene), strict, &gltf)?;
            let s = settings(&player, &quality);
            drop(player);
            let summary = soak::run(
                &soak::SoakOptions {
                    scene,
                    gltf,
                    frames,
                    every,
                    output,
                    plot,
                },
                &s,
                &own_renderer(&quality)?,
            )?;
            print!("{summary}");
            Ok(())
        }
        Command::Play {
            scene,
            frames,
            output,
            stats,
            quality,
        } => play(
            &scene,
            frames.as_deref(),
            output.as_deref(),
            stats,
            &quality,
            (strict, &gltf),
            cluster,
        ),
    }
}

/// `openrt play`: frames as PNGs (written atomically) and one statistics line
/// per frame (flushed as written); a failure says how many frames finished.
fn play(
    scene: &Path,
    frames: Option<&str>,
    output: Option<&Path>,
    stats: Option<PathBuf>,
    quality: &Quality,
    (strict, gltf): (bool, &GltfOptions),
    cluster: Option<&Cluster>,
) -> Result<(), String> {
    let mut player = open_scene(Some(scene), strict, gltf)?;
    commit_threads(&mut player, quality)?;
    if cluster.is_some() {
        player.ctx_mut().record_changes();
    }
    let range = frame_range(frames, player.frames())?;
    if let Some(dir) = &output {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let stats_path = stats.or_else(|| output.as_ref().map(|d| d.join("stats.jsonl")));
    let mut sink = match &stats_path {
        Some(p) => StatsLines::new(
            Box::new(std::fs::File::create(p).map_err(|e| format!("{}: {e}", p.display()))?),
            p.display().to_string(),
        ),
        None => StatsLines::new(Box::new(std::io::stdout()), "standard output".into()),
    };
    let s = settings(&player, quality);
    let renderer = renderer(&mut player, quality)?;
    let bar = ProgressBar::new(u64::from(range.end - range.start));
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} frames, {per_sec}, eta {eta} {msg}")
            .map_err(|e| e.to_string())?,
    );
    // One image for the whole run: its buffer is reused.
    let mut img = Image::default();
    let first = range.start;
    // A failure names what failed and how many frames were finished
    // (their images written, their statistics flushed).
    let done = |f: u32, e: String| {
        format!(
            "{e}; {} frame(s) completed before it (frames {first}..{f}), their statistics in {}",
            f - first,
            sink_name(stats_path.as_deref())
        )
    };
    for f in range {
        let t = player.time_of(f);
        let c = player.set_time(t).map_err(|e| done(f, e.to_string()))?;
        let (st, net) = render_frame(&mut player, t, &s, &renderer, cluster, &mut img).map_err(|e| done(f, e))?;
        if let Some(dir) = &output {
            save_png(&dir.join(format!("frame_{f:05}.png")), &img).map_err(|e| done(f, e))?;
        }
        let line = serde_json::json!({
            "frame": f,
            "time": t,
            "commit_ms": c.total_ms,
            "toplevel_ms": c.toplevel_ms,
            "toplevel_reused": c.toplevel_reused,
            "fast_builds": c.build_count(BuilderKind::Fast),
            "fast_build_ms": c.build_ms(BuilderKind::Fast),
            "sah_builds": c.build_count(BuilderKind::Sah),
            "sah_build_ms": c.build_ms(BuilderKind::Sah),
            "promotions_started": c.promotions_started.len(),
            "promotions_swapped": c.promotions_swapped.len(),
            "render_ms": st.render_ms,
            "mrays_per_s": st.mrays_per_s,
            "rays": {"primary": st.rays.primary, "shadow": st.rays.shadow, "reflection": st.rays.reflection, "refraction": st.rays.refraction},
            "instances": c.instances,
            "distributed": net,
        });
        sink.line(&line).map_err(|e| done(f, e))?;
        bar.set_message(format!("{:.1} ms/frame", c.total_ms + st.render_ms));
        bar.inc(1);
    }
    bar.finish();
    Ok(())
}

/// Writes a PNG atomically (`Image::save_png`: a failed write leaves no
/// truncated file).
fn save_png(path: &Path, img: &Image) -> Result<(), String> {
    img.save_png(path).map_err(|e| e.to_string())
}

fn sink_name(stats: Option<&Path>) -> String {
    stats.map_or_else(|| "standard output".into(), |p| p.display().to_string())
}

/// `play`'s per-frame statistics: one JSON line per frame, flushed as soon
/// as it is written, so a run that fails later keeps every finished frame's
/// line.
struct StatsLines {
    out: Box<dyn Write>,
    name: String,
}

impl StatsLines {
    fn new(out: Box<dyn Write>, name: String) -> Self {
        Self { out, name }
    }

    /// Writes and flushes one line.
    fn line(&mut self, value: &serde_json::Value) -> Result<(), String> {
        writeln!(self.out, "{value}")
            .and_then(|()| self.out.flush())
            .map_err(|e| format!("{}: cannot write statistics: {e}", self.name))
    }
}

#[cfg(test)]
mod tests {
    use super::{Accel, Backend, BackendChoice, frame_range};

    /// `--backend`: `packets` and `single` keep the scene's structure; the
    /// labelled names choose it too; anything else is refused with the names.
    #[test]
    fn backend_names_choose_the_traversal_and_the_structure() {
        let parse = |s: &str| s.parse::<BackendChoice>().map(|c| (c.backend, c.accel));
        assert_eq!(parse("packets"), Ok((Backend::Packets, None)));
        assert_eq!(parse("single"), Ok((Backend::Single, None)));
        assert_eq!(parse("kd"), Ok((Backend::Packets, Some(Accel::Kd))));
        assert_eq!(parse("kd-single"), Ok((Backend::Single, Some(Accel::Kd))));
        assert_eq!(parse("bvh"), Ok((Backend::Packets, Some(Accel::Bvh))));
        assert_eq!(parse("bvh-single"), Ok((Backend::Single, Some(Accel::Bvh))));
        for &b in Backend::ALL {
            assert_eq!(parse(b.name()).map(|c| c.0), Ok(b));
        }
        let e = parse("octree").unwrap_err();
        assert!(
            e.contains("packets") && e.contains("kd-single") && e.contains("bvh-single"),
            "{e}"
        );
    }

    #[test]
    fn frame_ranges_parse_and_are_checked() {
        assert_eq!(frame_range(None, 10).unwrap(), 0..10);
        assert_eq!(frame_range(Some("2..5"), 10).unwrap(), 2..5);
        assert_eq!(frame_range(Some("2..=5"), 10).unwrap(), 2..6);
        assert_eq!(frame_range(Some("..3"), 10).unwrap(), 0..3);
        assert_eq!(frame_range(Some("7.."), 10).unwrap(), 7..10);
        for bad in [
            "5..2",
            "a..b",
            "3",
            "0..11",
            "0..=4294967295",
            "-1..2",
            "0..99999999999",
        ] {
            assert!(frame_range(Some(bad), 10).is_err(), "{bad}");
        }
    }
}
