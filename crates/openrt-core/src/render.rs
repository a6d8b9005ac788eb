//! Parallel frame rendering: a persistent pool of worker threads taking
//! tiles from a shared counter.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::thread::JoinHandle;
use std::time::Instant;

use crossbeam::channel::{Receiver, Sender, unbounded};
use glam::Vec3;

use crate::camera::CameraRays;
use crate::shade::Shader;
use crate::{Camera, CoreError, Environment, RayCounts, RenderMode, Scene};

/// Tile edge in pixels.
pub const TILE: u32 = 16;

/// How a frame is rendered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Shading mode.
    pub mode: RenderMode,
    /// Largest number of reflection/refraction bounces (Whitted mode).
    pub max_depth: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            mode: RenderMode::Whitted,
            max_depth: 3,
        }
    }
}

/// A rendered image in linear RGB.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels row by row, top row first.
    pub pixels: Vec<Vec3>,
}

impl Image {
    /// 8-bit RGB bytes (values clamped to `[0, 1]`, no gamma: NFF colours are display values).
    #[must_use]
    pub fn to_rgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|p| p.to_array().map(|c| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8))
            .collect()
    }
}

/// Figures about one rendered frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Rays by kind.
    pub rays: RayCounts,
    /// Wall-clock render time in milliseconds.
    pub render_ms: f64,
    /// Millions of rays (all kinds) per second.
    pub mrays_per_s: f64,
    /// Worker threads used.
    pub threads: usize,
}

struct FrameJob {
    scene: Arc<Scene>,
    env: Arc<Environment>,
    cam: CameraRays,
    settings: RenderSettings,
    tiles_x: u32,
    n_tiles: usize,
    next: AtomicUsize,
    results: Sender<TileResult>,
}

struct TileResult {
    index: usize,
    pixels: Vec<Vec3>,
    counts: RayCounts,
}

/// A persistent pool of render threads. Images are bit-identical whatever
/// the number of threads: every pixel is computed by the same code from the
/// same inputs, only the assignment of tiles to threads varies.
pub struct Renderer {
    jobs: Option<Sender<Arc<FrameJob>>>,
    workers: Vec<JoinHandle<()>>,
}

impl Renderer {
    /// Starts `threads` workers (at least one).
    #[must_use]
    pub fn new(threads: usize) -> Self {
        let (tx, rx) = unbounded::<Arc<FrameJob>>();
        let workers = (0..threads.max(1))
            .map(|i| {
                let rx: Receiver<Arc<FrameJob>> = rx.clone();
                std::thread::Builder::new()
                    .name(format!("openrt-render-{i}"))
                    .spawn(move || {
                        while let Ok(job) = rx.recv() {
                            render_tiles(&job);
                        }
                    })
                    .expect("spawning a render thread")
            })
            .collect();
        Self {
            jobs: Some(tx),
            workers,
        }
    }

    /// Number of worker threads.
    #[must_use]
    pub fn threads(&self) -> usize {
        self.workers.len()
    }

    /// Renders one frame of `scene` seen by `camera`.
    pub fn render(
        &self,
        scene: &Arc<Scene>,
        env: &Arc<Environment>,
        camera: &Camera,
        settings: &RenderSettings,
    ) -> Result<(Image, FrameStats), CoreError> {
        let cam = camera.rays(settings.width, settings.height)?;
        let start = Instant::now();
        let tiles_x = settings.width.div_ceil(TILE);
        let tiles_y = settings.height.div_ceil(TILE);
        let n_tiles = (tiles_x * tiles_y) as usize;
        let (rtx, rrx) = unbounded();
        let job = Arc::new(FrameJob {
            scene: Arc::clone(scene),
            env: Arc::clone(env),
            cam,
            settings: *settings,
            tiles_x,
            n_tiles,
            next: AtomicUsize::new(0),
            results: rtx,
        });
        let jobs = self.jobs.as_ref().expect("the pool lives until drop");
        for _ in 0..self.workers.len() {
            jobs.send(Arc::clone(&job)).expect("render threads are alive");
        }
        drop(job);
        let mut pixels = vec![Vec3::ZERO; (settings.width * settings.height) as usize];
        let mut rays = RayCounts::default();
        for _ in 0..n_tiles {
            let tile = rrx.recv().expect("every tile is rendered");
            let (tx, ty) = (tile.index as u32 % tiles_x, tile.index as u32 / tiles_x);
            let (x0, y0) = (tx * TILE, ty * TILE);
            let w = TILE.min(settings.width - x0);
            for (row, chunk) in tile.pixels.chunks(w as usize).enumerate() {
                let start = ((y0 + row as u32) * settings.width + x0) as usize;
                pixels[start..start + chunk.len()].copy_from_slice(chunk);
            }
            rays.add(&tile.counts);
        }
        let secs = start.elapsed().as_secs_f64();
        let stats = FrameStats {
            rays,
            render_ms: secs * 1e3,
            mrays_per_s: rays.total() as f64 / secs.max(1e-9) / 1e6,
            threads: self.workers.len(),
        };
        Ok((
            Image {
                width: settings.width,
                height: settings.height,
                pixels,
            },
            stats,
        ))
    }
}

impl Drop for Renderer {
    fn drop(&mut self) {
        self.jobs = None;
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

fn render_tiles(job: &FrameJob) {
    let mut shader = Shader {
        scene: &job.scene,
        env: &job.env,
        mode: job.settings.mode,
        max_depth: job.settings.max_depth,
        counts: RayCounts::default(),
    };
    loop {
        let index = job.next.fetch_add(1, Ordering::Relaxed);
        if index >= job.n_tiles {
            return;
        }
        shader.counts = RayCounts::default();
        let (tx, ty) = (index as u32 % job.tiles_x, index as u32 / job.tiles_x);
        let (x0, y0) = (tx * TILE, ty * TILE);
        let (x1, y1) = (
            (x0 + TILE).min(job.settings.width),
            (y0 + TILE).min(job.settings.height),
        );
        let mut pixels = Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize);
        for y in y0..y1 {
            for x in x0..x1 {
                shader.counts.primary += 1;
                let c = shader.trace(&job.cam.ray(x, y), 0);
                pixels.push(if c.is_finite() { c } else { Vec3::ZERO });
            }
        }
        // The receiver only goes away if render() panicked; nothing to do then.
        let _ = job.results.send(TileResult {
            index,
            pixels,
            counts: shader.counts,
        });
    }
}
