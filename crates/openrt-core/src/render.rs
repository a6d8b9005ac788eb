//! Parallel frame rendering: tasks on the context's thread pool taking
//! tiles from a shared counter.

use std::panic::AssertUnwindSafe;
#[cfg(feature = "embree")]
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use glam::Vec3;
use openrt_accel::{PacketWidth, lanes_of};
use parking_lot::Mutex;

use crate::camera::CameraRays;
use crate::occluder_hint::OccluderHint;
use crate::phases::{Phase, PhaseClock, PhaseTimes};
use crate::shade::{Cone, ShadedBlock, Shader};
use crate::tracer::Tracer;
use crate::{
    Camera, CoreError, Environment, RayCounts, RenderMode, Scene, TextureFilter, ThreadPool, check_depth,
    check_image_size, check_spp,
};

/// Tile edge in pixels.
pub const TILE: u32 = 16;

/// How rays find their hits; the shading, the rays and the image are the
/// same for every backend (byte for byte between the packet and single-ray
/// backends over either object structure, tested).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Backend {
    /// This crate's traversal through both levels (the objects' structure:
    /// kd-trees or BVHs, [`Accel`](crate::Accel)), coherent rays in packets
    /// ([`Scene::intersect_packet`]): primary rays in blocks of pixels and,
    /// per light, their shadow rays.
    #[default]
    Packets,
    /// This crate's traversal through both levels, one ray at a time.
    Single,
    /// Embree 3, one ray at a time (rtcIntersect1/rtcOccluded1), on the
    /// same rays and shading (feature `embree`).
    #[cfg(feature = "embree")]
    Embree,
    /// Embree 3 packets of the renderer's width (rtcIntersect4/8/16,
    /// rtcOccluded4/8/16), on the same packets (feature `embree`).
    #[cfg(feature = "embree")]
    EmbreePacket,
}

impl Backend {
    /// The name used on command lines (`packets`, `single`, `embree`,
    /// `embree-packet`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Packets => "packets",
            Self::Single => "single",
            #[cfg(feature = "embree")]
            Self::Embree => "embree",
            #[cfg(feature = "embree")]
            Self::EmbreePacket => "embree-packet",
        }
    }

    /// The name of this backend over objects built with `accel`: `kd`,
    /// `kd-single`, `bvh` or `bvh-single` for this crate's traversal, the
    /// peer's own name for Embree (which builds its own structure).
    #[must_use]
    pub fn label(self, accel: crate::Accel) -> &'static str {
        match (self, accel) {
            (Self::Packets, crate::Accel::Kd) => "kd",
            (Self::Single, crate::Accel::Kd) => "kd-single",
            (Self::Packets, crate::Accel::Bvh) => "bvh",
            (Self::Single, crate::Accel::Bvh) => "bvh-single",
            #[cfg(feature = "embree")]
            (b, _) => b.name(),
        }
    }

    /// The backend and structure that [`Backend::label`] names `label`
    /// (`kd`, `kd-single`, `bvh`, `bvh-single`), if any.
    #[must_use]
    pub fn from_label(label: &str) -> Option<(Self, crate::Accel)> {
        crate::Accel::ALL
            .into_iter()
            .flat_map(|a| [Self::Packets, Self::Single].map(|b| (b, a)))
            .find(|&(b, a)| b.label(a) == label)
    }

    /// `true` for the backends that trace coherent rays in packets.
    #[must_use]
    pub fn packets(self) -> bool {
        match self {
            Self::Packets => true,
            Self::Single => false,
            #[cfg(feature = "embree")]
            Self::Embree => false,
            #[cfg(feature = "embree")]
            Self::EmbreePacket => true,
        }
    }

    /// Every backend of this build.
    #[cfg(not(feature = "embree"))]
    pub const ALL: &[Self] = &[Self::Packets, Self::Single];
    /// Every backend of this build.
    #[cfg(feature = "embree")]
    pub const ALL: &[Self] = &[Self::Packets, Self::Single, Self::Embree, Self::EmbreePacket];
}

impl std::str::FromStr for Backend {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.iter().copied().find(|b| b.name() == s).ok_or_else(|| {
            let names: Vec<_> = Self::ALL.iter().map(|b| b.name()).collect();
            format!("unknown backend '{s}' (this build has: {})", names.join(", "))
        })
    }
}

/// How a frame is rendered.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Shading mode.
    pub mode: RenderMode,
    /// Largest number of reflection/refraction bounces (Whitted mode); a
    /// bounce whose weight in the pixel falls below
    /// [`MIN_RAY_WEIGHT`](crate::MIN_RAY_WEIGHT) is not traced.
    pub max_depth: u32,
    /// Texture filtering (trilinear by default, with ray-cone level of detail).
    pub texture_filter: TextureFilter,
    /// Samples per pixel, averaged (at most [`MAX_SPP`](crate::MAX_SPP)).
    pub spp: u32,
    /// Index of the first sample: a frame renders samples
    /// `first_sample..first_sample + spp` of [`sample_offset`]'s sequence,
    /// so that frames of 1 sample each can be accumulated progressively.
    pub first_sample: u32,
}

impl RenderSettings {
    /// Checks the image size ([`MAX_IMAGE_SIDE`](crate::MAX_IMAGE_SIDE),
    /// [`MAX_IMAGE_PIXELS`](crate::MAX_IMAGE_PIXELS)) and the depth
    /// ([`MAX_SHADE_DEPTH`](crate::MAX_SHADE_DEPTH)); `call` names the caller in the error.
    ///
    /// # Errors
    /// [`CoreError::Limit`] naming the limit broken.
    pub fn validate(&self, call: &'static str) -> Result<(), CoreError> {
        check_image_size(call, self.width, self.height)?;
        check_depth(call, self.max_depth)?;
        check_spp(call, self.spp)
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            mode: RenderMode::Whitted,
            max_depth: 3,
            texture_filter: TextureFilter::default(),
            spp: 1,
            first_sample: 0,
        }
    }
}

/// A rendered image in linear RGB (the default: 0 x 0).
#[derive(Clone, Debug, Default, PartialEq)]
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
    /// The frame's time by phase, summed over the threads, when the renderer
    /// times phases ([`Renderer::set_phase_timing`]); `None` otherwise.
    pub phases: Option<PhaseTimes>,
}

struct FrameJob<'a> {
    scene: &'a Scene,
    env: &'a Environment,
    cam: CameraRays,
    settings: RenderSettings,
    backend: Backend,
    width: PacketWidth,
    #[cfg(feature = "embree")]
    embree: Arc<std::sync::RwLock<crate::embree_backend::EmbreeScene>>,
    tiles_x: u32,
    n_tiles: usize,
    /// The tiles to render (all `n_tiles` of the frame when `None`).
    list: Option<Vec<u32>>,
    next: AtomicUsize,
    /// Time the phases of each tile.
    timing: bool,
}

struct TileResult {
    index: usize,
    pixels: Vec<Vec3>,
    counts: RayCounts,
    phases: PhaseTimes,
}

/// Renders frames on a [`ThreadPool`]. Images are bit-identical whatever
/// the number of threads: every pixel is computed by the same code from the
/// same inputs, only the assignment of tiles to threads varies.
pub struct Renderer {
    pool: ThreadPool,
    backend: Backend,
    width: PacketWidth,
    timing: bool,
    /// The Embree scene kept in step with the frames (Embree backends).
    #[cfg(feature = "embree")]
    embree: Arc<std::sync::RwLock<crate::embree_backend::EmbreeScene>>,
}

impl Renderer {
    /// A renderer on a pool of its own with `threads` threads.
    ///
    /// # Errors
    /// As [`ThreadPool::new`]: [`CoreError::Limit`] for 0 or more than
    /// [`MAX_THREADS`](crate::MAX_THREADS) threads, [`CoreError::RenderThread`]
    /// when the system refuses a thread.
    pub fn new(threads: usize) -> Result<Self, CoreError> {
        crate::check_threads("Renderer::new", threads)?;
        Ok(Self::with_pool(ThreadPool::new(threads)?))
    }

    /// A renderer on `pool`, typically the context's
    /// ([`Context::pool`](crate::Context::pool)): commit, background builds
    /// and rendering then share one set of threads.
    #[must_use]
    pub fn with_pool(pool: ThreadPool) -> Self {
        Self {
            pool,
            backend: Backend::default(),
            width: PacketWidth::detect(),
            timing: false,
            #[cfg(feature = "embree")]
            embree: Arc::default(),
        }
    }

    /// Chooses how rays find their hits (default [`Backend::Packets`]).
    pub fn set_backend(&mut self, backend: Backend) {
        self.backend = backend;
    }

    /// The backend in use.
    #[must_use]
    pub fn backend(&self) -> Backend {
        self.backend
    }

    /// Chooses the packet width of [`Backend::Packets`] (default: the CPU's,
    /// [`PacketWidth::detect`]); images do not depend on it.
    pub fn set_packet_width(&mut self, width: PacketWidth) {
        self.width = width;
    }

    /// Times each frame's phases ([`FrameStats::phases`]): camera rays,
    /// queries by kind, surfaces, textures, the light loop, the image. Off by
    /// default; when off, each clock costs one predictable branch. The
    /// images are the same bytes either way.
    pub fn set_phase_timing(&mut self, on: bool) {
        self.timing = on;
    }

    /// The packet width in use.
    #[must_use]
    pub fn packet_width(&self) -> PacketWidth {
        self.width
    }

    /// Number of threads of the pool.
    #[must_use]
    pub fn threads(&self) -> usize {
        self.pool.threads()
    }

    /// The pool the renderer runs on.
    #[must_use]
    pub fn pool(&self) -> &ThreadPool {
        &self.pool
    }

    /// Renders one frame of `scene` seen by `camera`.
    pub fn render(
        &self,
        scene: &Scene,
        env: &Environment,
        camera: &Camera,
        settings: &RenderSettings,
    ) -> Result<(Image, FrameStats), CoreError> {
        let mut image = Image::default();
        let stats = self.render_into(scene, env, camera, settings, &mut image)?;
        Ok((image, stats))
    }

    /// [`Renderer::render`] into `image`, reusing its pixel buffer when it
    /// has the frame's size: a loop that renders frame after frame keeps
    /// one image (a new 640x480 buffer, with its page faults, cost about
    /// 1 ms of a 40 ms frame on two threads). The same pixels either way.
    ///
    /// # Errors
    /// As [`Renderer::render`]; `image` is left as it was then.
    pub fn render_into(
        &self,
        scene: &Scene,
        env: &Environment,
        camera: &Camera,
        settings: &RenderSettings,
        image: &mut Image,
    ) -> Result<FrameStats, CoreError> {
        let start = Instant::now();
        let (tiles, rays, mut phases) = self.render_tiles_timed(scene, env, camera, settings, None)?;
        let assembly = Instant::now();
        self.pool
            .rayon()
            .install(|| assemble_into(settings, tiles.iter().map(|t| (t.0, t.1.as_slice())), image));
        phases.image_ns = u64::try_from(assembly.elapsed().as_nanos()).unwrap_or(u64::MAX);
        let secs = start.elapsed().as_secs_f64();
        Ok(FrameStats {
            rays,
            render_ms: secs * 1e3,
            mrays_per_s: rays.total() as f64 / secs.max(1e-9) / 1e6,
            threads: self.pool.threads(),
            phases: self.timing.then_some(phases),
        })
    }

    /// Renders the tiles `only` of a frame (all of them for `None`), in any
    /// order: each tile's pixels, row by row, with its index (tiles are
    /// [`TILE`] pixels square, numbered row by row: [`tile_count`]). A tile's
    /// pixels are the bytes [`Renderer::render`] puts in the image, so parts
    /// of a frame rendered anywhere assemble into the same image
    /// ([`assemble`]). Also returns the rays traced.
    ///
    /// # Errors
    /// As [`Renderer::render`]; a tile index out of range is a [`CoreError::Limit`].
    pub fn render_tiles(
        &self,
        scene: &Scene,
        env: &Environment,
        camera: &Camera,
        settings: &RenderSettings,
        only: Option<&[u32]>,
    ) -> Result<(Vec<RenderedTile>, RayCounts), CoreError> {
        self.render_tiles_timed(scene, env, camera, settings, only)
            .map(|(tiles, rays, _)| (tiles, rays))
    }

    /// [`Renderer::render_tiles`] with the tiles' phase times (zero unless
    /// the renderer times phases).
    fn render_tiles_timed(
        &self,
        scene: &Scene,
        env: &Environment,
        camera: &Camera,
        settings: &RenderSettings,
        only: Option<&[u32]>,
    ) -> Result<(Vec<RenderedTile>, RayCounts, PhaseTimes), CoreError> {
        settings.validate("render")?;
        let cam = camera.rays(settings.width, settings.height)?;
        // The Embree peer's own commit counts as part of its frame.
        #[cfg(feature = "embree")]
        if matches!(self.backend, Backend::Embree | Backend::EmbreePacket) {
            self.embree
                .write()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .sync(scene)?;
        }
        let tiles_x = settings.width.div_ceil(TILE);
        let all = tile_count(settings);
        if let Some(&bad) = only.and_then(|o| o.iter().find(|&&t| t >= all)) {
            return Err(CoreError::Limit {
                call: "render_tiles",
                what: "tile index".into(),
                value: u64::from(bad),
                limit: u64::from(all) - 1,
            });
        }
        let list: Option<Vec<u32>> = only.map(<[u32]>::to_vec);
        let n_tiles = list.as_ref().map_or(all as usize, Vec::len);
        let job = FrameJob {
            scene,
            env,
            cam,
            settings: *settings,
            backend: self.backend,
            width: self.width,
            #[cfg(feature = "embree")]
            embree: Arc::clone(&self.embree),
            tiles_x,
            n_tiles,
            list,
            next: AtomicUsize::new(0),
            timing: self.timing,
        };
        let results: Mutex<Vec<TileResult>> = Mutex::new(Vec::with_capacity(n_tiles));
        let failure: Mutex<Option<String>> = Mutex::new(None);
        // One task per thread, each taking tiles until none is left and
        // adding them to the results once (not once per tile).
        let tasks = self.pool.threads();
        self.pool.rayon().install(|| {
            rayon::scope(|s| {
                for i in 0..tasks {
                    let (job, results, failure) = (&job, &results, &failure);
                    s.spawn(move |_| {
                        // A panic is a bug; it fails this frame with an
                        // error naming the task, and the pool lives on.
                        match std::panic::catch_unwind(AssertUnwindSafe(|| render_tiles(job))) {
                            Ok(tiles) => results.lock().extend(tiles),
                            Err(p) => {
                                let what = p
                                    .downcast_ref::<&str>()
                                    .map(ToString::to_string)
                                    .or_else(|| p.downcast_ref::<String>().cloned())
                                    .unwrap_or_else(|| "unknown panic".into());
                                failure
                                    .lock()
                                    .get_or_insert(format!("render task {i} panicked: {what}"));
                            }
                        }
                    });
                }
            });
        });
        if let Some(reason) = failure.into_inner() {
            return Err(CoreError::RenderThread { reason });
        }
        let tiles = results.into_inner();
        if tiles.len() != n_tiles {
            return Err(CoreError::RenderThread {
                reason: format!("only {} of {n_tiles} tiles came back", tiles.len()),
            });
        }
        let mut rays = RayCounts::default();
        let mut phases = PhaseTimes::default();
        let mut out = Vec::with_capacity(n_tiles);
        for tile in tiles {
            rays.add(&tile.counts);
            phases.merge(&tile.phases);
            out.push((tile.index as u32, tile.pixels));
        }
        Ok((out, rays, phases))
    }
}

/// A rendered tile: its index and its pixels, row by row.
pub type RenderedTile = (u32, Vec<Vec3>);

/// Number of tiles of a frame (numbered row by row).
#[must_use]
pub fn tile_count(settings: &RenderSettings) -> u32 {
    settings.width.div_ceil(TILE) * settings.height.div_ceil(TILE)
}

/// The image of a frame from its tiles ([`Renderer::render_tiles`]); tiles
/// not given stay black (of a tile given twice, the last counts; pixels a
/// tile lacks stay black, and those past its size are dropped).
#[must_use]
pub fn assemble<'a>(settings: &RenderSettings, tiles: impl IntoIterator<Item = (u32, &'a [Vec3])>) -> Image {
    let mut image = Image::default();
    assemble_into(settings, tiles, &mut image);
    image
}

/// [`assemble`] into `image`, whose pixel buffer is reused when it already
/// has the frame's size (every pixel is written either way).
///
/// PERF: one band of tile rows per task on the current rayon pool (the
/// renderer's when called from [`Renderer::render_into`]). A new buffer per
/// frame, zeroed and copied into on one thread, took 1.2 ms of a 40 ms
/// kitchen GL-like frame on two threads, most of it the new buffer.
pub fn assemble_into<'a>(
    settings: &RenderSettings,
    tiles: impl IntoIterator<Item = (u32, &'a [Vec3])>,
    image: &mut Image,
) {
    use rayon::prelude::*;
    let tiles_x = settings.width.div_ceil(TILE) as usize;
    let mut by_index: Vec<Option<&[Vec3]>> = vec![None; tile_count(settings) as usize];
    for (index, tile) in tiles {
        if let Some(slot) = by_index.get_mut(index as usize) {
            *slot = Some(tile);
        }
    }
    let (width, height) = (settings.width as usize, settings.height as usize);
    image.width = settings.width;
    image.height = settings.height;
    if image.pixels.len() != width * height {
        image.pixels.clear();
        image.pixels.resize(width * height, Vec3::ZERO);
    }
    if width == 0 {
        return;
    }
    let t = TILE as usize;
    image
        .pixels
        .par_chunks_mut(width * t)
        .zip(by_index.par_chunks(tiles_x))
        .for_each(|(band, row_of_tiles)| {
            let rows = band.len() / width;
            for (tx, tile) in row_of_tiles.iter().enumerate() {
                let x0 = tx * t;
                let w = t.min(width - x0);
                let src = tile.unwrap_or(&[]);
                for row in 0..rows {
                    let dst = &mut band[row * width + x0..row * width + x0 + w];
                    let have = src.get(row * w..).map_or(&[][..], |r| &r[..r.len().min(w)]);
                    dst[..have.len()].copy_from_slice(have);
                    dst[have.len()..].fill(Vec3::ZERO);
                }
            }
        });
}

fn render_tiles(job: &FrameJob<'_>) -> Vec<TileResult> {
    match job.backend {
        Backend::Packets | Backend::Single => tiles(job, job.scene),
        #[cfg(feature = "embree")]
        Backend::Embree | Backend::EmbreePacket => {
            let guard = job.embree.read().unwrap_or_else(std::sync::PoisonError::into_inner);
            tiles(job, &*guard)
        }
    }
}

/// Takes tiles until none is left, tracing with `tracer`; returns them.
fn tiles<T: Tracer>(job: &FrameJob<'_>, tracer: &T) -> Vec<TileResult> {
    let mut shader = Shader::new(
        job.scene,
        tracer,
        job.env,
        job.settings.mode,
        job.settings.max_depth,
        job.settings.texture_filter,
    );
    let spp = job.settings.spp.max(1);
    // Each sample's cone covers its share of the pixel.
    let cone = Cone {
        width: 0.0,
        spread: job.cam.pixel_spread() / (spp as f32).sqrt(),
    };
    let offsets: Vec<(f32, f32)> = (0..spp).map(|i| sample_offset(job.settings.first_sample + i)).collect();
    let mut done = Vec::new();
    // Shaded blocks kept from tile to tile, one pool per packet width.
    let (mut pool4, mut pool8, mut pool16, mut pool32) =
        (BlockPool::new(), BlockPool::new(), BlockPool::new(), BlockPool::new());
    loop {
        let k = job.next.fetch_add(1, Ordering::Relaxed);
        if k >= job.n_tiles {
            return done;
        }
        let index = job.list.as_ref().map_or(k, |l| l[k] as usize);
        shader.counts = RayCounts::default();
        shader.clock = PhaseClock {
            on: job.timing,
            times: PhaseTimes::default(),
        };
        // NOTE: a tile's hints start empty, so that they depend on nothing
        // outside the tile (they never change an answer either way).
        shader.occluders.fill(OccluderHint::new());
        let (tx, ty) = (index as u32 % job.tiles_x, index as u32 / job.tiles_x);
        let (x0, y0) = (tx * TILE, ty * TILE);
        let (x1, y1) = (
            (x0 + TILE).min(job.settings.width),
            (y0 + TILE).min(job.settings.height),
        );
        let tile = Tile { x0, y0, x1, y1 };
        let mut pixels = vec![Vec3::ZERO; ((x1 - x0) * (y1 - y0)) as usize];
        match (job.backend.packets(), job.width) {
            (false, _) => {
                for y in y0..y1 {
                    for x in x0..x1 {
                        let mut sum = Vec3::ZERO;
                        for &(ox, oy) in &offsets {
                            shader.counts.primary += 1;
                            let ray = if job.timing {
                                let t = PhaseClock::start::<true>();
                                let ray = job.cam.ray_at(x, y, ox, oy);
                                shader.clock.stop::<true>(t, Phase::Camera);
                                ray
                            } else {
                                job.cam.ray_at(x, y, ox, oy)
                            };
                            sum += shader.trace(&ray, cone, 0);
                        }
                        pixels[tile.index(x, y)] = average(sum, spp);
                    }
                }
            }
            (true, PacketWidth::W4) => {
                packet_tile::<4, T>(&mut shader, job, tile, cone, &offsets, &mut pixels, &mut pool4);
            }
            (true, PacketWidth::W8) => {
                packet_tile::<8, T>(&mut shader, job, tile, cone, &offsets, &mut pixels, &mut pool8);
            }
            (true, PacketWidth::W16) => {
                packet_tile::<16, T>(&mut shader, job, tile, cone, &offsets, &mut pixels, &mut pool16);
            }
            (true, PacketWidth::W32) => {
                packet_tile::<32, T>(&mut shader, job, tile, cone, &offsets, &mut pixels, &mut pool32);
            }
        }
        for p in &mut pixels {
            if !p.is_finite() {
                *p = Vec3::ZERO;
            }
        }
        done.push(TileResult {
            index,
            pixels,
            counts: shader.counts,
            phases: shader.clock.times,
        });
    }
}

/// The pixel rectangle `[x0, x1) x [y0, y1)` of a tile.
#[derive(Clone, Copy)]
struct Tile {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

impl Tile {
    /// Index of pixel `(x, y)` in the tile's row-major buffer.
    fn index(self, x: u32, y: u32) -> usize {
        ((y - self.y0) * (self.x1 - self.x0) + (x - self.x0)) as usize
    }
}

/// Width and height of the pixel block that fills a packet of `n` lanes
/// (8x4 for 32, 4x4 for 16, 4x2 for 8, 2x2 for 4): the renderer's primary packets.
#[must_use]
pub const fn packet_block(n: usize) -> (u32, u32) {
    match n {
        4 => (2, 2),
        8 => (4, 2),
        16 => (4, 4),
        _ => (8, 4),
    }
}

/// Shaded blocks of `N` lanes that a render thread keeps from tile to tile
/// ([`packet_tile`]): the tile's blocks, and the bounces' blocks of each
/// depth ([`Shader::bounce_blocks`]). A block is written by
/// [`Shader::shade_block`] before it is read, so none is cleared.
struct BlockPool<const N: usize> {
    shaded: Vec<ShadedBlock<N>>,
    levels: Vec<Vec<ShadedBlock<N>>>,
}

impl<const N: usize> BlockPool<N> {
    fn new() -> Self {
        Self {
            shaded: Vec::new(),
            levels: Vec::new(),
        }
    }
}

/// Renders a tile in packets of `N` primary rays (blocks of pixels):
/// [`Shader::shade_block`] for each block, then [`Shader::bounce_blocks`]
/// for the bounces of all the tile's blocks at once (those of equal
/// direction signs pooled into packets across blocks). Every pixel gets the
/// bytes the single-ray path gives it: the packet queries answer each lane
/// as the single-ray queries do, and the shading is the same code.
fn packet_tile<const N: usize, T: Tracer>(
    shader: &mut Shader<'_, T>,
    job: &FrameJob<'_>,
    tile: Tile,
    cone: Cone,
    offsets: &[(f32, f32)],
    pixels: &mut [Vec3],
    pool: &mut BlockPool<N>,
) {
    let (bw, bh) = packet_block(N);
    let cones = [cone; N];
    // The tile's blocks: each lane's pixel, and the lanes inside the tile.
    let mut blocks: Vec<([(u32, u32); N], u32)> = Vec::new();
    for by in (tile.y0..tile.y1).step_by(bh as usize) {
        for bx in (tile.x0..tile.x1).step_by(bw as usize) {
            let mut at = [(0u32, 0u32); N];
            let mut lanes = 0u32;
            for (l, slot) in at.iter_mut().enumerate() {
                let (x, y) = (bx + l as u32 % bw, by + l as u32 / bw);
                if x < tile.x1 && y < tile.y1 {
                    *slot = (x, y);
                    lanes |= 1 << l;
                }
            }
            blocks.push((at, lanes));
        }
    }
    let mut sum = vec![[Vec3::ZERO; N]; blocks.len()];
    // PERF: without bounces (GL-like frames, depth 0) each block is shaded
    // and summed at once in one block's space (a tile's blocks kept side by
    // side made GL-like kitchen frames 2% slower); with them, the tile's
    // blocks are shaded first, then their bounces traced together, so that
    // bounces of equal direction signs from different blocks can share
    // packets.
    let bounces = shader.traces_bounces();
    let need = if bounces { blocks.len() } else { 1 };
    if pool.shaded.len() < need {
        pool.shaded.resize_with(need, ShadedBlock::new);
    }
    let shaded = &mut pool.shaded[..need];
    // Lanes outside the tile keep a valid ray, never read.
    let mut rays = [job.cam.ray(tile.x0, tile.y0); N];
    for &(ox, oy) in offsets {
        // One packet per block and sample: the block's rays through the
        // same sub-pixel position stay coherent.
        for (b, ((at, lanes), s)) in blocks.iter().zip(&mut sum).enumerate() {
            let t = if job.timing { PhaseClock::start::<true>() } else { None };
            job.cam.rays_at(at, *lanes, ox, oy, &mut rays);
            if job.timing {
                shader.clock.stop::<true>(t, Phase::Camera);
            }
            shader.counts.primary += u64::from(lanes.count_ones());
            let out = &mut shaded[if bounces { b } else { 0 }];
            shader.shade_block(&rays, &cones, *lanes, 0, out);
            if !bounces {
                for l in lanes_of(*lanes) {
                    s[l] += out.color[l];
                }
            }
        }
        if bounces {
            shader.bounce_blocks(shaded, 0, &mut pool.levels);
            for (s, b) in sum.iter_mut().zip(shaded.iter()) {
                for l in lanes_of(b.lanes) {
                    s[l] += b.color[l];
                }
            }
        }
    }
    for ((at, lanes), s) in blocks.iter().zip(&sum) {
        for l in lanes_of(*lanes) {
            pixels[tile.index(at[l].0, at[l].1)] = average(s[l], offsets.len() as u32);
        }
    }
}

/// The mean of `n` samples summed (exactly the sample for one).
#[inline]
fn average(sum: Vec3, n: u32) -> Vec3 {
    if n == 1 { sum } else { sum / n as f32 }
}

/// Sub-pixel position of sample `i` of every pixel: the R2 low-discrepancy
/// sequence (Roberts 2018, the plastic-number generalisation of the golden
/// ratio), started at the pixel centre, so one sample is the centre and
/// any run of samples `first..first + n` covers the pixel evenly. The
/// positions depend only on `i`: the bytes are the same for any thread count.
#[must_use]
pub fn sample_offset(i: u32) -> (f32, f32) {
    const G1: f64 = 0.754_877_666_246_692_7;
    const G2: f64 = 0.569_840_290_998_053_2;
    let i = f64::from(i);
    ((0.5 + G1 * i).fract() as f32, (0.5 + G2 * i).fract() as f32)
}

#[cfg(test)]
mod tests {
    use super::Backend;
    use crate::Accel;

    /// Every (traversal, structure) pair of this crate has its own label;
    /// Embree's backends keep their names whatever the structure.
    #[test]
    fn labels_name_the_traversal_and_the_structure() {
        let ours: Vec<&str> = Accel::ALL
            .into_iter()
            .flat_map(|a| [Backend::Packets, Backend::Single].map(|b| b.label(a)))
            .collect();
        assert_eq!(ours, ["kd", "kd-single", "bvh", "bvh-single"]);
        for (l, want) in ours.iter().zip([
            (Backend::Packets, Accel::Kd),
            (Backend::Single, Accel::Kd),
            (Backend::Packets, Accel::Bvh),
            (Backend::Single, Accel::Bvh),
        ]) {
            assert_eq!(Backend::from_label(l), Some(want), "{l}");
        }
        assert_eq!(Backend::from_label("packets"), None);
        for &b in Backend::ALL
            .iter()
            .filter(|b| !matches!(b, Backend::Packets | Backend::Single))
        {
            assert_eq!(b.label(Accel::Kd), b.name());
            assert_eq!(b.label(Accel::Bvh), b.name());
        }
        assert_eq!(Backend::default(), Backend::Packets);
        assert_eq!(Accel::default(), Accel::Bvh, "BVHs are the default structure");
    }
}
