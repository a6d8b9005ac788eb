//! The render thread: owns the scene and the renderer, so the UI never
//! blocks on a frame. The UI sends requests; only the newest is rendered.

use std::path::PathBuf;
use std::sync::Arc;
use std::thread::JoinHandle;

use crossbeam::channel::{Receiver, Sender, unbounded};
use openrt_core::{Accel, Backend, Camera, CommitStats, FrameStats, Image, RenderSettings, Renderer, TopLevel};
use openrt_scene::{GltfAnimation, GltfOptions, MotionClasses, ScenePlayer};

/// What the UI asks for.
pub enum Request {
    /// Open a scene (`None`: the built-in default scene), for a glTF file
    /// with the chosen animation.
    Open(Option<PathBuf>, GltfAnimation),
    /// Render the scene at `time` with `camera` (`None`: the scene's own camera).
    Render {
        time: f32,
        camera: Option<Camera>,
        settings: RenderSettings,
        threads: usize,
        backend: Backend,
        /// The structure under the objects (a change rebuilds them).
        accel: Accel,
        /// The structure over the instances.
        top_level: TopLevel,
    },
}

/// Facts about the open scene.
#[derive(Clone, Debug)]
pub struct SceneInfo {
    pub name: String,
    /// What the load accepted leniently, with file and line.
    pub warnings: Vec<String>,
    pub frames: u32,
    pub time_range: (f32, f32),
    pub settings: RenderSettings,
    /// The structure the scene file asks for.
    pub accel: Accel,
    /// The top level the scene file asks for.
    pub top_level: TopLevel,
    /// The file it came from (`None`: the built-in scene).
    pub path: Option<PathBuf>,
    /// Instances and objects by motion class.
    pub motion: MotionClasses,
    /// A glTF file's animations by index (their names), and the one played.
    pub animations: Vec<String>,
    pub animation: GltfAnimation,
}

/// What the render thread sends back.
pub enum Reply {
    Opened(SceneInfo),
    Frame(Box<FrameResult>),
    Error(String),
}

/// A finished frame with its figures.
pub struct FrameResult {
    pub image: Image,
    pub stats: FrameStats,
    pub commit: CommitStats,
    pub camera: Camera,
    pub time: f32,
    /// The settings it was rendered with (its samples among them).
    pub settings: RenderSettings,
    pub objects: usize,
    pub instances: usize,
    pub triangles: usize,
}

pub struct Worker {
    pub tx: Sender<Request>,
    pub rx: Receiver<Reply>,
    handle: Option<JoinHandle<()>>,
}

impl Worker {
    pub fn start(repaint: impl Fn() + Send + 'static) -> Self {
        let (tx, req_rx) = unbounded::<Request>();
        let (reply_tx, rx) = unbounded::<Reply>();
        let handle = std::thread::Builder::new()
            .name("openrt-viewer-render".into())
            .spawn(move || {
                // A panic is a bug: it is reported to the window, then the
                // thread ends and the window sees the channel close.
                let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(&req_rx, &reply_tx, &repaint)));
                if let Err(p) = r {
                    let what = p
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| p.downcast_ref::<&str>().map(ToString::to_string))
                        .unwrap_or_default();
                    let _ = reply_tx.send(Reply::Error(format!("the render thread panicked: {what}")));
                    repaint();
                }
            });
        // Without a render thread the window still opens and reports it.
        let handle = match handle {
            Ok(h) => Some(h),
            Err(e) => {
                eprintln!("error: cannot start the render thread: {e}");
                None
            }
        };
        Self { tx, rx, handle }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        // Closing the request channel ends the thread.
        let (dead, _) = unbounded();
        self.tx = dead;
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

/// Gives the scene's context a pool of `threads` threads (when its pool
/// has another size) and makes sure the renderer runs on that same pool:
/// one set of threads commits and renders.
fn share_pool(
    player: &mut ScenePlayer,
    renderer: &mut Option<Renderer>,
    threads: usize,
) -> Result<(), openrt_core::CoreError> {
    let mut pool = player.ctx_mut().pool()?;
    if pool.threads() != threads {
        // The old pool goes first, so its threads are not counted twice.
        *renderer = None;
        player.ctx_mut().set_threads(threads)?;
        pool = player.ctx_mut().pool()?;
    }
    if !renderer.as_ref().is_some_and(|r| r.pool().same(&pool)) {
        let backend = renderer.as_ref().map(Renderer::backend);
        let mut r = Renderer::with_pool(pool);
        if let Some(b) = backend {
            r.set_backend(b);
        }
        *renderer = Some(r);
    }
    Ok(())
}

fn run(requests: &Receiver<Request>, replies: &Sender<Reply>, repaint: &dyn Fn()) {
    let mut player: Option<ScenePlayer> = None;
    let mut renderer: Option<Renderer> = None;
    while let Ok(first) = requests.recv() {
        // Coalesce: an Open always runs; of the renders only the newest.
        let mut pending = vec![first];
        pending.extend(requests.try_iter());
        let last_render = pending.iter().rposition(|r| matches!(r, Request::Render { .. }));
        for (i, req) in pending.into_iter().enumerate() {
            let reply = match req {
                Request::Open(path, animation) => match open(path.as_deref(), &animation) {
                    Ok(p) => {
                        let info = SceneInfo {
                            name: path
                                .as_ref()
                                .map_or_else(|| "built-in room".into(), |p| p.display().to_string()),
                            warnings: p.warnings().iter().map(ToString::to_string).collect(),
                            frames: p.frames(),
                            time_range: p.time_range(),
                            settings: p.settings(),
                            accel: p.ctx().accel(),
                            top_level: p.ctx().top_level(),
                            path: path.clone(),
                            motion: p.motion_classes(),
                            animations: p.animation_names(),
                            animation,
                        };
                        player = Some(p);
                        Reply::Opened(info)
                    }
                    Err(e) => Reply::Error(e.to_string()),
                },
                Request::Render { .. } if Some(i) != last_render => continue,
                Request::Render {
                    time,
                    camera,
                    settings,
                    threads,
                    backend,
                    accel,
                    top_level,
                } => {
                    let Some(p) = player.as_mut() else { continue };
                    p.ctx_mut().set_accel(accel);
                    p.ctx_mut().set_top_level(top_level);
                    let pool = share_pool(p, &mut renderer, threads).map_err(|e| e.to_string());
                    match (pool, renderer.as_mut()) {
                        (Err(e), _) => Reply::Error(e),
                        (Ok(()), None) => Reply::Error("render: no render pool".into()),
                        (Ok(()), Some(r)) => {
                            r.set_backend(backend);
                            match render(p, r, time, camera, &settings) {
                                Ok(f) => Reply::Frame(Box::new(f)),
                                Err(e) => Reply::Error(e),
                            }
                        }
                    }
                }
            };
            if replies.send(reply).is_err() {
                return;
            }
            repaint();
        }
    }
}

fn render(
    p: &mut ScenePlayer,
    r: &Renderer,
    time: f32,
    camera: Option<Camera>,
    settings: &RenderSettings,
) -> Result<FrameResult, String> {
    let commit = p.set_time(time).map_err(|e| e.to_string())?;
    let camera = camera.unwrap_or_else(|| p.camera(time));
    let scene = p.ctx().scene();
    let env: Arc<_> = p.env();
    let (image, stats) = r.render(&scene, &env, &camera, settings).map_err(|e| e.to_string())?;
    let mut objects: Vec<_> = scene.instances().iter().map(|i| i.object).collect();
    objects.sort_unstable();
    objects.dedup();
    Ok(FrameResult {
        image,
        stats,
        commit,
        camera,
        time,
        settings: *settings,
        objects: objects.len(),
        instances: scene.instances().len(),
        triangles: scene.instanced_triangles(),
    })
}

/// Opens a scene; a glTF file plays `animation`.
fn open(path: Option<&std::path::Path>, animation: &GltfAnimation) -> Result<ScenePlayer, openrt_scene::SceneError> {
    let is_gltf = path
        .and_then(|p| p.extension())
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"));
    let options = GltfOptions {
        animation: if is_gltf {
            animation.clone()
        } else {
            GltfAnimation::First
        },
        ..GltfOptions::default()
    };
    ScenePlayer::open_with(path, &options)
}
