//! Distributed rendering over MPI (feature `mpi`): rank 0 runs the
//! application; the other ranks keep replicas of its context and render
//! tiles (Wald, Benthin & Slusallek 2003: the application "knows nothing of
//! the distributed rendering").
//!
//! Per frame, rank 0 broadcasts one message: the change set of its last
//! commit ([`openrt_core::ChangeSet`]: only what changed), the camera, the
//! lights and the render settings. Each worker applies the changes to its
//! replica and commits (building its own trees, in parallel with the other
//! workers), then asks rank 0 for tiles; rank 0 hands them out a few at a
//! time as workers ask, and assembles the image. A tile's pixels are the
//! bytes the single-process renderer computes, so the image is the same.
//!
//! Faults: a worker whose replica fails (a build error) reports it and
//! rank 0 returns an error naming the rank; a worker that stops answering
//! for [`timeout`] makes rank 0 return an error naming it. A worker process
//! that exits makes Open MPI's runtime end the whole job within about a
//! second, with the worker's exit code, naming its rank (tested): Open MPI
//! 4.1 without ULFM has no way for rank 0 to outlive a dead rank, and
//! `mpirun --enable-recovery`, which keeps the others running, also keeps
//! `MPI_Abort` from ending the job (a failing worker then hangs it), so it
//! is not used.

use std::time::{Duration, Instant};

use glam::Vec3;
use mpi::point_to_point::MatchedReceiveVec;
use mpi::topology::{Communicator, SimpleCommunicator};
use mpi::traits::{Destination, Root, Source};
use openrt_core::{
    Backend, Camera, ChangeSet, Context, Environment, Image, PointLight, RenderMode, RenderSettings, Renderer,
    TextureFilter,
};
use serde::{Deserialize, Serialize};

/// Tag of a worker's request for tiles (with the tiles it rendered).
const TAG_REQUEST: i32 = 1;
/// Tag of rank 0's answer: the next tiles (none: the frame is done).
const TAG_TILES: i32 = 2;
/// Broadcast length that ends the workers.
const STOP: u64 = u64::MAX;
/// The most threads of a worker that its batch of tiles grows with (a
/// worker reporting more is given this many threads' batch).
pub const MAX_BATCH_THREADS: u32 = 256;

/// Tiles per request of a worker with `threads` render threads, for a frame
/// of `n` tiles shared by `workers`: a few per thread (a batch is rendered
/// like a frame, one task per thread), enough to keep every thread busy
/// between requests, few enough to balance at the end of the frame.
fn tile_batch(n: u32, workers: u32, threads: u32) -> u32 {
    let per_thread = (n / (workers.max(1) * 16)).clamp(1, 8);
    per_thread * threads.clamp(1, MAX_BATCH_THREADS)
}

/// How long rank 0 waits for a worker before it reports it
/// (`OPENRT_MPI_TIMEOUT_S`, default 60 s).
#[must_use]
pub fn timeout() -> Duration {
    std::env::var("OPENRT_MPI_TIMEOUT_S")
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .filter(|s| *s > 0.0)
        .map_or(Duration::from_mins(1), Duration::from_secs_f64)
}

/// One frame, as rank 0 broadcasts it.
#[derive(Serialize, Deserialize)]
struct FrameMsg {
    changes: Vec<u8>,
    camera: [f32; 11],
    /// Lights, ambient and background, when they changed.
    env: Option<EnvMsg>,
    /// width, height, depth, spp, first sample.
    sizes: [u32; 5],
    whitted: bool,
    filter: String,
    backend: String,
}

/// Lights, ambient light and background.
#[derive(Serialize, Deserialize, Clone, PartialEq)]
struct EnvMsg {
    lights: Vec<[f32; 6]>,
    ambient: [f32; 3],
    background: [f32; 3],
}

impl EnvMsg {
    fn of(env: &Environment) -> Self {
        Self {
            lights: env
                .lights
                .iter()
                .map(|l| {
                    [
                        l.position.x,
                        l.position.y,
                        l.position.z,
                        l.color.x,
                        l.color.y,
                        l.color.z,
                    ]
                })
                .collect(),
            ambient: env.ambient.to_array(),
            background: env.background.to_array(),
        }
    }

    fn env(&self) -> Environment {
        Environment {
            lights: self
                .lights
                .iter()
                .map(|l| PointLight {
                    position: Vec3::new(l[0], l[1], l[2]),
                    color: Vec3::new(l[3], l[4], l[5]),
                })
                .collect(),
            ambient: Vec3::from_array(self.ambient),
            background: Vec3::from_array(self.background),
        }
    }
}

/// A worker's request: the tiles it rendered since the last one.
#[derive(Serialize, Deserialize, Default)]
struct Request {
    error: Option<String>,
    commit_ms: f64,
    tiles: Vec<(u32, Vec<[f32; 3]>)>,
    rays: [u64; 4],
    /// The worker's render threads: its batches of tiles grow with them.
    threads: u32,
}

/// Figures of one distributed frame.
#[derive(Clone, Copy, Debug, Default)]
pub struct NetStats {
    /// Bytes broadcast (the frame message, once per worker).
    pub bytes_sent: u64,
    /// Broadcast time, ms.
    pub broadcast_ms: f64,
    /// Slowest worker commit, ms.
    pub worker_commit_ms: f64,
    /// From the end of the broadcast to the last tile, ms.
    pub render_ms: f64,
    /// Bytes of tiles received.
    pub bytes_gathered: u64,
    /// Rays traced by the workers: primary, shadow, reflection, refraction.
    pub rays: [u64; 4],
    /// Static order: tiles taken from another rank's share.
    pub stolen: u32,
}

/// The tiles of a frame still to hand out.
///
/// Dynamic (the default): one queue, in order; each request takes the next
/// few. Static (`--mpi-tiles static`): tile `t` belongs to rank `t mod r`
/// of the `r` rendering ranks; a rank whose share is done steals from the
/// end of the largest share left.
struct TileQueue {
    queues: Vec<std::collections::VecDeque<u32>>,
    stolen: u32,
}

impl TileQueue {
    fn new(n: u32, ranks: usize, static_order: bool, root_renders: bool) -> Self {
        let mut queues = vec![std::collections::VecDeque::new(); ranks];
        if static_order {
            let first = usize::from(!root_renders);
            let owners = ranks - first;
            for t in 0..n {
                queues[first + t as usize % owners].push_back(t);
            }
        } else {
            queues[0].extend(0..n);
        }
        Self { queues, stolen: 0 }
    }

    fn is_empty(&self) -> bool {
        self.queues.iter().all(std::collections::VecDeque::is_empty)
    }

    /// Up to `batch` tiles for `rank`.
    fn take(&mut self, rank: usize, batch: u32) -> Vec<u32> {
        let batch = batch as usize;
        let shared = self.queues.iter().skip(1).all(std::collections::VecDeque::is_empty) && rank != 0;
        let own = if shared { 0 } else { rank };
        if !self.queues[own].is_empty() {
            let k = batch.min(self.queues[own].len());
            return self.queues[own].drain(..k).collect();
        }
        // Steal from the end of the largest share.
        let Some(victim) = (0..self.queues.len()).max_by_key(|&i| self.queues[i].len()) else {
            return Vec::new();
        };
        let k = batch.min(self.queues[victim].len());
        let at = self.queues[victim].len() - k;
        self.stolen += k as u32;
        self.queues[victim].drain(at..).collect()
    }
}

/// The MPI world when this process runs under `mpirun` with more than one rank.
pub struct Cluster {
    _universe: mpi::environment::Universe,
    world: SimpleCommunicator,
    /// The environment the workers have (sent again only when it changes).
    sent_env: std::cell::RefCell<Option<EnvMsg>>,
    /// Rank 0 renders tiles too (`openrt --mpi-root-renders`); by default it
    /// only coordinates.
    root_renders: bool,
    /// Static tile order with stealing (`--mpi-tiles static`), else dynamic.
    static_tiles: bool,
}

impl Cluster {
    /// Starts MPI; `None` with a single rank (everything runs as without the
    /// feature). `root_renders`: rank 0 renders tiles too.
    #[must_use]
    pub fn start(root_renders: bool, static_tiles: bool) -> Option<Self> {
        let universe = mpi::initialize()?;
        let world = universe.world();
        (world.size() > 1).then_some(Self {
            _universe: universe,
            world,
            sent_env: std::cell::RefCell::new(None),
            root_renders,
            static_tiles,
        })
    }

    /// This process's rank.
    #[must_use]
    pub fn rank(&self) -> i32 {
        self.world.rank()
    }

    /// Workers: ranks 1 and up.
    #[must_use]
    pub fn workers(&self) -> i32 {
        self.world.size() - 1
    }

    fn broadcast(&self, bytes: Option<&[u8]>) -> Option<Vec<u8>> {
        let root = self.world.process_at_rank(0);
        let mut len = [bytes.map_or(STOP, |b| b.len() as u64)];
        root.broadcast_into(&mut len[..]);
        if len[0] == STOP {
            return None;
        }
        let mut buf = bytes.map_or_else(|| vec![0u8; len[0] as usize], <[u8]>::to_vec);
        root.broadcast_into(&mut buf[..]);
        Some(buf)
    }

    /// Rank 0: renders a frame on the workers. `changes` is the change set
    /// of the commit that made the frame's scene.
    ///
    /// # Errors
    /// A worker's error, or a worker that stopped answering, by rank.
    pub fn render(
        &self,
        changes: &ChangeSet,
        camera: &Camera,
        env: &std::sync::Arc<Environment>,
        settings: &RenderSettings,
        local: Option<(&Renderer, &std::sync::Arc<openrt_core::Scene>)>,
    ) -> Result<(Image, NetStats), String> {
        let backend = local.map_or(Backend::default(), |l| l.0.backend());
        let msg = FrameMsg {
            changes: changes.to_bytes()?,
            camera: [
                camera.from.x,
                camera.from.y,
                camera.from.z,
                camera.at.x,
                camera.at.y,
                camera.at.z,
                camera.up.x,
                camera.up.y,
                camera.up.z,
                camera.fov_y_deg,
                camera.near,
            ],
            env: {
                let now = EnvMsg::of(env);
                let mut sent = self.sent_env.borrow_mut();
                (sent.as_ref() != Some(&now)).then(|| {
                    *sent = Some(now.clone());
                    now
                })
            },
            sizes: [
                settings.width,
                settings.height,
                settings.max_depth,
                settings.spp,
                settings.first_sample,
            ],
            whitted: settings.mode == RenderMode::Whitted,
            filter: settings.texture_filter.name().into(),
            backend: backend.name().into(),
        };
        let bytes = postcard::to_allocvec(&msg).map_err(|e| e.to_string())?;
        let t0 = Instant::now();
        self.broadcast(Some(&bytes));
        let mut stats = NetStats {
            bytes_sent: bytes.len() as u64 * self.workers() as u64,
            broadcast_ms: t0.elapsed().as_secs_f64() * 1e3,
            ..NetStats::default()
        };
        let t1 = Instant::now();
        let n = openrt_core::tile_count(settings);
        let batch = |threads: u32| tile_batch(n, self.workers().unsigned_abs(), threads);
        let mut threads = vec![1u32; self.world.size() as usize];
        let mut queue = TileQueue::new(n, self.world.size() as usize, self.static_tiles, self.root_renders);
        let mut tiles: Vec<(u32, Vec<Vec3>)> = Vec::with_capacity(n as usize);
        let mut finished = vec![false; self.world.size() as usize];
        finished[0] = true;
        let mut heard = Instant::now();
        let mut failure = None;
        while finished.iter().any(|f| !f) {
            let Some(probed) = self.world.any_process().immediate_matched_probe_with_tag(TAG_REQUEST) else {
                // With `--mpi-root-renders`, rank 0 takes a batch itself
                // whenever no worker is asking.
                if let Some((r, scene)) = local.filter(|_| self.root_renders && !queue.is_empty() && failure.is_none())
                {
                    // One thread's batch, whatever rank 0's threads: while
                    // it renders, it answers no worker's request.
                    let give = queue.take(0, batch(1));
                    let (done, _) = r
                        .render_tiles(scene, env, camera, settings, Some(&give))
                        .map_err(|e| e.to_string())?;
                    tiles.extend(done);
                    continue;
                }
                if heard.elapsed() > timeout() {
                    let silent: Vec<String> = (1..self.world.size())
                        .filter(|&r| !finished[r as usize])
                        .map(|r| r.to_string())
                        .collect();
                    return Err(format!(
                        "MPI rank {} stopped answering (no reply for {:.0} s; OPENRT_MPI_TIMEOUT_S)",
                        silent.join(", rank "),
                        timeout().as_secs_f64()
                    ));
                }
                std::thread::sleep(Duration::from_micros(50));
                continue;
            };
            heard = Instant::now();
            let (buf, status) = probed.matched_receive_vec::<u8>();
            let rank = status.source_rank();
            stats.bytes_gathered += buf.len() as u64;
            let req: Request =
                postcard::from_bytes(&buf).map_err(|e| format!("MPI rank {rank}: malformed reply: {e}"))?;
            if let Some(e) = req.error {
                failure.get_or_insert(format!("MPI rank {rank}: {e}"));
            }
            stats.worker_commit_ms = stats.worker_commit_ms.max(req.commit_ms);
            threads[rank as usize] = req.threads;
            for (a, b) in stats.rays.iter_mut().zip(req.rays) {
                *a += b;
            }
            for (i, px) in req.tiles {
                tiles.push((i, px.into_iter().map(Vec3::from_array).collect()));
            }
            let give: Vec<u32> = if failure.is_some() {
                Vec::new()
            } else {
                queue.take(rank as usize, batch(threads[rank as usize]))
            };
            if give.is_empty() {
                finished[rank as usize] = true;
            }
            self.world.process_at_rank(rank).send_with_tag(&give[..], TAG_TILES);
        }
        if let Some(e) = failure {
            return Err(e);
        }
        stats.render_ms = t1.elapsed().as_secs_f64() * 1e3;
        stats.stolen = queue.stolen;
        if tiles.len() != n as usize {
            return Err(format!("{} of {n} tiles came back", tiles.len()));
        }
        Ok((
            openrt_core::assemble(settings, tiles.iter().map(|(i, p)| (*i, p.as_slice()))),
            stats,
        ))
    }

    /// Rank 0: ends the workers.
    pub fn stop(&self) {
        self.broadcast(None);
    }

    /// Ends the whole job (after rank 0 reported an error it cannot recover
    /// from, such as a worker that stopped answering).
    pub fn abort(&self, code: i32) -> ! {
        self.world.abort(code)
    }

    /// Ranks 1 and up: keep a replica and render tiles until rank 0 stops.
    ///
    /// # Errors
    /// A render pool that cannot start.
    pub fn work(&self, threads: usize) -> Result<(), String> {
        let mut replica = Context::new();
        // One pool: the replica's commit and the tiles.
        replica.set_threads(threads).map_err(|e| e.to_string())?;
        let mut renderer = crate::new_renderer(replica.pool().map_err(|e| e.to_string())?);
        // Sent with every request: rank 0 sizes this worker's batches by it.
        let reported = u32::try_from(threads).unwrap_or(MAX_BATCH_THREADS);
        let root = self.world.process_at_rank(0);
        let fault = std::env::var("OPENRT_MPI_FAULT").ok();
        let mut env: Option<std::sync::Arc<Environment>> = None;
        while let Some(bytes) = self.broadcast(None) {
            if fault.as_deref() == Some(&format!("exit:{}", self.rank())) {
                // Tests: a worker process that dies.
                std::process::exit(3);
            }
            if fault.as_deref() == Some(&format!("hang:{}", self.rank())) {
                // Tests: a worker that stops answering.
                loop {
                    std::thread::sleep(Duration::from_hours(1));
                }
            }
            let mut req = Request {
                threads: reported,
                ..Request::default()
            };
            let frame = postcard::from_bytes::<FrameMsg>(&bytes)
                .map_err(|e| e.to_string())
                .and_then(|msg| {
                    let t = Instant::now();
                    let set = ChangeSet::from_bytes(&msg.changes)?;
                    if fault.as_deref() == Some(&format!("fail:{}", self.rank())) {
                        return Err("injected build failure (OPENRT_MPI_FAULT)".to_string());
                    }
                    replica.apply_changes(&set).map_err(|e| e.to_string())?;
                    req.commit_ms = t.elapsed().as_secs_f64() * 1e3;
                    Ok(msg)
                });
            let msg = match frame {
                Ok(m) => Some(m),
                Err(e) => {
                    req.error = Some(e);
                    None
                }
            };
            if let Some(e) = msg.as_ref().and_then(|m| m.env.as_ref()) {
                env = Some(std::sync::Arc::new(e.env()));
            }
            loop {
                let out = postcard::to_allocvec(&std::mem::take(&mut req)).map_err(|e| e.to_string())?;
                req.threads = reported;
                root.send_with_tag(&out[..], TAG_REQUEST);
                let (give, _) = root.receive_vec_with_tag::<u32>(TAG_TILES);
                if give.is_empty() {
                    break;
                }
                let (Some(m), Some(env)) = (&msg, &env) else { continue };
                let c = m.camera;
                let camera = Camera {
                    from: Vec3::new(c[0], c[1], c[2]),
                    at: Vec3::new(c[3], c[4], c[5]),
                    up: Vec3::new(c[6], c[7], c[8]),
                    fov_y_deg: c[9],
                    near: c[10],
                };
                let settings = RenderSettings {
                    width: m.sizes[0],
                    height: m.sizes[1],
                    max_depth: m.sizes[2],
                    spp: m.sizes[3],
                    first_sample: m.sizes[4],
                    mode: if m.whitted {
                        RenderMode::Whitted
                    } else {
                        RenderMode::GlLike
                    },
                    texture_filter: m.filter.parse::<TextureFilter>().unwrap_or_default(),
                };
                renderer.set_backend(m.backend.parse::<Backend>().unwrap_or_default());
                match renderer.render_tiles(&replica.scene(), env, &camera, &settings, Some(&give)) {
                    Ok((tiles, rays)) => {
                        req.tiles = tiles
                            .into_iter()
                            .map(|(i, px)| (i, px.iter().map(Vec3::to_array).collect()))
                            .collect();
                        req.rays = [rays.primary, rays.shadow, rays.reflection, rays.refraction];
                    }
                    Err(e) => req.error = Some(e.to_string()),
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::{MAX_BATCH_THREADS, tile_batch};

    #[test]
    fn batches_grow_with_the_workers_threads() {
        // 640x480 in 16x16 tiles.
        let n = 1200;
        // One thread per worker: as many tiles as before threads counted.
        assert_eq!(tile_batch(n, 16, 1), 4);
        assert_eq!(tile_batch(n, 2, 1), 8);
        // A worker of 16 threads gets 16 threads' share, so that every
        // thread has tiles between two requests.
        assert_eq!(tile_batch(n, 1, 16), 128);
        assert_eq!(tile_batch(n, 4, 4), 4 * 8);
        // Tiny frames: at least one tile a thread; no worker, no division by zero.
        assert_eq!(tile_batch(3, 8, 2), 2);
        assert_eq!(tile_batch(n, 0, 1), 8);
        // A thread count of 0 (an old worker) counts as 1; a huge one is capped.
        assert_eq!(tile_batch(n, 2, 0), 8);
        assert_eq!(tile_batch(n, 2, u32::MAX), 8 * MAX_BATCH_THREADS);
    }
}
