//! `openrt soak`: plays a scene in a loop for many frames and samples the
//! resident memory and the frame time, to show that neither grows.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use openrt_core::{RenderSettings, Renderer};
use openrt_scene::{GltfOptions, ScenePlayer};

/// What to play and how often to sample.
pub struct SoakOptions {
    /// The scene.
    pub scene: PathBuf,
    /// For a glTF scene: the scene, animation and camera played.
    pub gltf: GltfOptions,
    /// Frames in all (the animation loops).
    pub frames: u64,
    /// Frames per sample.
    pub every: u64,
    /// JSON lines, one per sample.
    pub output: Option<PathBuf>,
    /// An SVG plot of memory and frame time.
    pub plot: Option<PathBuf>,
}

/// One sample: the state after `frame` frames.
struct Sample {
    frame: u64,
    rss_mb: f64,
    median_ms: f64,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_unstable_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

fn rss_mb() -> f64 {
    memory_stats::memory_stats().map_or(0.0, |m| m.physical_mem as f64 / (1024.0 * 1024.0))
}

/// Plays, samples, prints a summary; returns it as Markdown lines.
pub fn run(o: &SoakOptions, settings: &RenderSettings, renderer: &Renderer) -> Result<String, String> {
    if o.every == 0 || o.frames < 10 * o.every {
        return Err("soak: --every must be at least 1 and --frames at least 10 samples".into());
    }
    let mut player = ScenePlayer::open_with(Some(&o.scene), &o.gltf).map_err(|e| e.to_string())?;
    // One pool commits and renders.
    player.ctx_mut().set_pool(renderer.pool());
    let mut sink: Option<Box<dyn std::io::Write>> = match &o.output {
        Some(p) => Some(Box::new(std::io::BufWriter::new(
            std::fs::File::create(p).map_err(|e| format!("{}: {e}", p.display()))?,
        ))),
        None => None,
    };
    let n = player.frames().max(1);
    let mut window = Vec::with_capacity(o.every as usize);
    let mut all = Vec::with_capacity(usize::try_from(o.frames).unwrap_or(0).min(1 << 24));
    let mut samples = Vec::new();
    let start = Instant::now();
    for f in 0..o.frames {
        let t = player.time_of((f % u64::from(n)) as u32);
        let t0 = Instant::now();
        player.set_time(t).map_err(|e| format!("frame {f}: {e}"))?;
        renderer
            .render(&player.ctx().scene(), &player.env(), &player.camera(t), settings)
            .map_err(|e| format!("frame {f}: {e}"))?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        window.push(ms);
        all.push(ms);
        if (f + 1) % o.every == 0 {
            let s = Sample {
                frame: f + 1,
                rss_mb: rss_mb(),
                median_ms: median(&mut window),
            };
            window.clear();
            if let Some(w) = &mut sink {
                writeln!(
                    w,
                    "{}",
                    serde_json::json!({"frame": s.frame, "rss_mb": s.rss_mb, "median_frame_ms": s.median_ms})
                )
                .map_err(|e| e.to_string())?;
            }
            eprint!(
                "\rsoak: {} frames, {:.1} MB, {:.2} ms/frame   ",
                s.frame, s.rss_mb, s.median_ms
            );
            samples.push(s);
        }
    }
    eprintln!();
    if let Some(w) = &mut sink {
        w.flush().map_err(|e| e.to_string())?;
    }
    // Warm-up: the first tenth of the samples (trees promoted, caches and
    // allocator pools filled).
    let warm = (samples.len() / 10).max(1);
    let after = &samples[warm..];
    let (lo, hi) = after
        .iter()
        .fold((f64::MAX, 0.0f64), |(lo, hi), s| (lo.min(s.rss_mb), hi.max(s.rss_mb)));
    // Frame time: the same animation frames are compared, the first whole
    // loop after the warm-up against the last whole loop.
    let n = n as usize;
    let loops = all.len() / n;
    let first_loop = (samples[warm - 1].frame as usize).div_ceil(n);
    if loops < first_loop + 2 {
        return Err(format!(
            "soak: {} frames hold {loops} loops of the {n}-frame animation; at least {} are needed",
            o.frames,
            first_loop + 2
        ));
    }
    let first = median(&mut all[first_loop * n..(first_loop + 1) * n].to_vec());
    let last = median(&mut all[(loops - 1) * n..loops * n].to_vec());
    let spread = (hi - lo) / lo * 100.0;
    let drift = (last / first - 1.0) * 100.0;
    let mut md = String::new();
    let _ = writeln!(
        md,
        "{}: {} frames ({} s), {}x{} {:?} depth {} on {} threads; after {} warm-up frames: resident memory {lo:.1}..{hi:.1} MB (spread {spread:.2}%, {}), median frame time {first:.2} ms in loop {first_loop} of the animation and {last:.2} ms in loop {} (drift {drift:+.1}%, {})",
        o.scene.display(),
        o.frames,
        start.elapsed().as_secs(),
        settings.width,
        settings.height,
        settings.mode,
        settings.max_depth,
        renderer.threads(),
        samples[warm - 1].frame,
        if spread <= 2.0 { "within 2%" } else { "MORE than 2%" },
        loops - 1,
        if drift.abs() <= 5.0 {
            "within 5%"
        } else {
            "MORE than 5%"
        },
    );
    if let Some(p) = &o.plot {
        plot(p, &o.scene, &samples)?;
    }
    Ok(md)
}

fn plot(path: &Path, scene: &Path, samples: &[Sample]) -> Result<(), String> {
    use plotters::prelude::*;
    crate::bench::register_plot_font()?;
    let root = SVGBackend::new(path, (720, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let frames = samples.last().map_or(1, |s| s.frame) as f64;
    let max_mb = samples.iter().map(|s| s.rss_mb).fold(1.0, f64::max) * 1.2;
    let max_ms = samples.iter().map(|s| s.median_ms).fold(1.0, f64::max) * 1.2;
    let name = scene
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("soak: {name}, resident memory and frame time"),
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .right_y_label_area_size(60)
        .build_cartesian_2d(0.0..frames, 0.0..max_mb)
        .map_err(|e| e.to_string())?
        .set_secondary_coord(0.0..frames, 0.0..max_ms);
    chart
        .configure_mesh()
        .x_desc("frames played")
        .y_desc("resident memory (MB)")
        .draw()
        .map_err(|e| e.to_string())?;
    chart
        .configure_secondary_axes()
        .y_desc("median frame time per 100 frames (ms)")
        .draw()
        .map_err(|e| e.to_string())?;
    chart
        .draw_series(LineSeries::new(
            samples.iter().map(|s| (s.frame as f64, s.rss_mb)),
            &BLUE,
        ))
        .map_err(|e| e.to_string())?
        .label("memory (MB)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLUE));
    chart
        .draw_secondary_series(LineSeries::new(
            samples.iter().map(|s| (s.frame as f64, s.median_ms)),
            &RED,
        ))
        .map_err(|e| e.to_string())?
        .label("frame time (ms)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], RED));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}
