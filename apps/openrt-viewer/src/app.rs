//! The viewer's window: image, controls, overlay.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use eframe::egui;
use egui_file_dialog::FileDialog;
use openrt_accel::BuilderKind;
use openrt_core::{Accel, Backend, Camera, RenderMode, RenderSettings, TopLevel};
use openrt_scene::GltfAnimation;

use crate::orbit;
use crate::worker::{FrameResult, Reply, Request, SceneInfo, Worker};

/// Samples per pixel that a still view refines to, one frame each.
const PROGRESSIVE_SAMPLES: u32 = 64;

/// Options from the command line.
pub struct Options {
    pub scene: Option<PathBuf>,
    pub screenshot: Option<PathBuf>,
    pub frames: u32,
    pub threads: usize,
    /// With `screenshot`: keep the view still (refine it) instead of playing.
    pub still: bool,
    /// Set to the error that ends a `--screenshot` run (the exit status).
    pub failure: Arc<Mutex<Option<String>>>,
}

// NOTE: the flags are independent UI toggles (playing, looping, following the
// scene camera, a frame in flight...); a state machine would not simplify them.
#[allow(clippy::struct_excessive_bools)]
pub struct ViewerApp {
    worker: Worker,
    dialog: FileDialog,
    info: Option<SceneInfo>,
    error: Option<String>,
    texture: Option<egui::TextureHandle>,
    last: Option<FrameResult>,
    in_flight: bool,
    dirty: bool,
    // Animation.
    time: f32,
    playing: bool,
    speed: f32,
    looping: bool,
    // Camera.
    follow_scene_camera: bool,
    camera: Option<Camera>,
    moving_until: Instant,
    // Quality.
    mode: RenderMode,
    depth: u32,
    backend: Backend,
    /// The structure under the objects.
    accel: Accel,
    top_level: TopLevel,
    threads: usize,
    scale: f32,
    // Statistics.
    frames_rendered: u64,
    frame_times: Vec<f64>,
    last_frame_at: Instant,
    // Progressive refinement while nothing changes: the sum of the frames
    // of one view (time, camera, settings), one sample each.
    accum: Vec<glam::Vec3>,
    accum_samples: u32,
    accum_key: Option<(u32, Camera, RenderSettings)>,
    // Headless screenshot mode.
    screenshot: Option<PathBuf>,
    screenshot_after: u32,
    screenshot_requested: bool,
    failure: Arc<Mutex<Option<String>>>,
    /// The render thread has stopped (reported once).
    worker_dead: bool,
    status: String,
}

impl ViewerApp {
    pub fn new(cc: &eframe::CreationContext<'_>, opts: Options) -> Self {
        let ctx = cc.egui_ctx.clone();
        let worker = Worker::start(move || ctx.request_repaint());
        // A send fails only if the render thread is gone: `receive` reports it.
        let _ = worker.tx.send(Request::Open(opts.scene, GltfAnimation::First));
        Self {
            worker,
            dialog: FileDialog::new()
                .add_file_filter_extensions("Scenes (.ron, .aff, .gltf, .glb)", vec!["ron", "aff", "gltf", "glb"])
                .default_file_filter("Scenes (.ron, .aff, .gltf, .glb)"),
            info: None,
            error: None,
            texture: None,
            last: None,
            in_flight: false,
            dirty: true,
            time: 0.0,
            playing: opts.screenshot.is_some() && !opts.still,
            speed: 1.0,
            looping: true,
            follow_scene_camera: true,
            camera: None,
            moving_until: Instant::now(),
            mode: RenderMode::GlLike,
            depth: 3,
            backend: Backend::default(),
            accel: Accel::default(),
            top_level: TopLevel::default(),
            threads: opts.threads,
            scale: 0.5,
            frames_rendered: 0,
            frame_times: Vec::new(),
            last_frame_at: Instant::now(),
            accum: Vec::new(),
            accum_samples: 0,
            accum_key: None,
            screenshot: opts.screenshot,
            screenshot_after: opts.frames.max(1),
            screenshot_requested: false,
            failure: opts.failure,
            worker_dead: false,
            status: String::new(),
        }
    }

    fn scene_settings(&self) -> RenderSettings {
        self.info.as_ref().map_or_else(RenderSettings::default, |i| i.settings)
    }

    /// The resolution scale: reduced while the camera moves, full when it stops.
    fn effective_scale(&self) -> f32 {
        if Instant::now() < self.moving_until {
            self.scale.min(0.25)
        } else {
            self.scale
        }
    }

    /// The settings of the next frame (its first sample aside).
    fn wanted_settings(&self) -> RenderSettings {
        let base = self.scene_settings();
        let s = self.effective_scale();
        RenderSettings {
            width: ((base.width as f32 * s) as u32).max(8),
            height: ((base.height as f32 * s) as u32).max(8),
            mode: self.mode,
            max_depth: self.depth,
            ..RenderSettings::default()
        }
    }

    /// `true` when the last frame shows the current view and the next
    /// request may add a sample to it: nothing moves or plays.
    fn can_refine(&self) -> bool {
        !self.playing
            && Instant::now() >= self.moving_until
            && self.accum_samples > 0
            && self.accum_samples < PROGRESSIVE_SAMPLES
            && self.accum_key.is_some_and(|(t, cam, s)| {
                t == self.time.to_bits()
                    && (self.follow_scene_camera || Some(cam) == self.camera)
                    && s == self.wanted_settings()
            })
    }

    fn request_frame(&mut self) {
        if self.in_flight || self.info.is_none() {
            return;
        }
        let mut settings = self.wanted_settings();
        if self.can_refine() {
            settings.first_sample = self.accum_samples;
        }
        let camera = if self.follow_scene_camera { None } else { self.camera };
        let req = Request::Render {
            time: self.time,
            camera,
            settings,
            threads: self.threads,
            backend: self.backend,
            accel: self.accel,
            top_level: self.top_level,
        };
        if self.worker.tx.send(req).is_ok() {
            self.in_flight = true;
            self.dirty = false;
        }
    }

    /// Shows an error; in screenshot mode it also ends the run with it.
    fn fail(&mut self, ctx: &egui::Context, e: String) {
        if self.screenshot.is_some() {
            eprintln!("error: {e}");
            *self.failure.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(e.clone());
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
        self.error = Some(e);
        self.in_flight = false;
    }

    fn receive(&mut self, ctx: &egui::Context) {
        loop {
            let reply = match self.worker.rx.try_recv() {
                Ok(r) => r,
                Err(crossbeam::channel::TryRecvError::Empty) => break,
                Err(crossbeam::channel::TryRecvError::Disconnected) => {
                    if !self.worker_dead {
                        self.worker_dead = true;
                        let why = self.error.take().map_or_else(String::new, |e| format!(" ({e})"));
                        self.fail(ctx, format!("the render thread has stopped{why}; restart the viewer"));
                    }
                    break;
                }
            };
            match reply {
                Reply::Opened(info) => {
                    self.accel = info.accel;
                    self.top_level = info.top_level;
                    self.time = info.time_range.0;
                    self.info = Some(info);
                    self.camera = None;
                    self.follow_scene_camera = true;
                    self.error = None;
                    self.dirty = true;
                }
                Reply::Error(e) => self.fail(ctx, e),
                Reply::Frame(f) => {
                    self.in_flight = false;
                    self.frames_rendered += 1;
                    let now = Instant::now();
                    self.frame_times
                        .push(now.duration_since(self.last_frame_at).as_secs_f64());
                    if self.frame_times.len() > 30 {
                        self.frame_times.remove(0);
                    }
                    self.last_frame_at = now;
                    let key = (
                        f.time.to_bits(),
                        f.camera,
                        RenderSettings {
                            first_sample: 0,
                            ..f.settings
                        },
                    );
                    if f.settings.first_sample > 0
                        && self.accum_key == Some(key)
                        && f.settings.first_sample == self.accum_samples
                    {
                        for (a, p) in self.accum.iter_mut().zip(&f.image.pixels) {
                            *a += *p;
                        }
                        self.accum_samples += 1;
                    } else {
                        self.accum.clone_from(&f.image.pixels);
                        self.accum_samples = 1;
                        self.accum_key = Some(key);
                    }
                    let n = self.accum_samples as f32;
                    let shown = openrt_core::Image {
                        width: f.image.width,
                        height: f.image.height,
                        pixels: self.accum.iter().map(|p| *p / n).collect(),
                    };
                    let img =
                        egui::ColorImage::from_rgb([shown.width as usize, shown.height as usize], &shown.to_rgb8());
                    match &mut self.texture {
                        Some(t) => t.set(img, egui::TextureOptions::LINEAR),
                        None => self.texture = Some(ctx.load_texture("frame", img, egui::TextureOptions::LINEAR)),
                    }
                    if self.camera.is_none() || self.follow_scene_camera {
                        self.camera = Some(f.camera);
                    }
                    self.last = Some(*f);
                    if self.playing {
                        self.advance(1.0 / 30.0);
                    }
                }
            }
        }
    }

    fn advance(&mut self, dt: f32) {
        let Some(info) = &self.info else { return };
        let (a, b) = info.time_range;
        if info.frames <= 1 || b <= a {
            return;
        }
        // In screenshot mode, exactly one animation frame per rendered frame.
        let step = if self.screenshot.is_some() {
            (b - a) / (info.frames - 1) as f32
        } else {
            dt * self.speed
        };
        self.time += step;
        if self.time > b {
            if self.looping {
                self.time = a + (self.time - b) % (b - a);
            } else {
                self.time = b;
                self.playing = false;
            }
        }
        self.dirty = true;
    }

    fn overlay_text(&self) -> String {
        let Some(f) = &self.last else {
            return "no frame yet".into();
        };
        let fps = if self.frame_times.is_empty() {
            0.0
        } else {
            self.frame_times.len() as f64 / self.frame_times.iter().sum::<f64>().max(1e-9)
        };
        let r = f.stats.rays;
        format!(
            "{fps:.1} fps | {:.2} Mrays/s | {} frames rendered | {} of {PROGRESSIVE_SAMPLES} samples\nrays: primary {} shadow {} reflection {} refraction {}\ncommit {:.2} ms: top-level {:.3} ms{}, fast {} ({:.2} ms), SAH {} ({:.2} ms), promoted {}\n{} instances, {} objects, {} triangles | {}x{} | t = {:.3}\nmotion: {}",
            f.stats.mrays_per_s,
            self.frames_rendered,
            self.accum_samples,
            r.primary,
            r.shadow,
            r.reflection,
            r.refraction,
            f.commit.total_ms,
            f.commit.toplevel_ms,
            if f.commit.toplevel_reused { " (kept)" } else { "" },
            f.commit.build_count(BuilderKind::Fast),
            f.commit.build_ms(BuilderKind::Fast),
            f.commit.build_count(BuilderKind::Sah),
            f.commit.build_ms(BuilderKind::Sah),
            f.commit.promotions_swapped.len(),
            f.instances,
            f.objects,
            f.triangles,
            f.image.width,
            f.image.height,
            f.time,
            self.info.as_ref().map_or_else(String::new, |i| i.motion.to_string())
        )
    }

    fn save_frame_png(&mut self) {
        let Some(f) = &self.last else { return };
        let name = format!(
            "openrt-{}.png",
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs())
        );
        self.status = match image::save_buffer(
            &name,
            &f.image.to_rgb8(),
            f.image.width,
            f.image.height,
            image::ColorType::Rgb8,
        ) {
            Ok(()) => format!("saved {name}"),
            Err(e) => format!("{name}: {e}"),
        };
    }

    /// A glTF file's animations: the one played, or all, or none (the
    /// file is opened again with the choice).
    fn animation_chooser(&mut self, ui: &mut egui::Ui) {
        let Some(info) = self.info.as_ref().filter(|i| !i.animations.is_empty()) else {
            return;
        };
        let name = |a: &GltfAnimation| match a {
            GltfAnimation::First => format!("first ({})", info.animations[0]),
            GltfAnimation::Index(k) => format!("{k}: {}", info.animations.get(*k).map_or("", String::as_str)),
            GltfAnimation::Name(n) => n.clone(),
            GltfAnimation::All => "all together".into(),
            GltfAnimation::None => "none (at rest)".into(),
        };
        let mut chosen = info.animation.clone();
        let mut choices: Vec<GltfAnimation> = (0..info.animations.len()).map(GltfAnimation::Index).collect();
        choices.extend([GltfAnimation::All, GltfAnimation::None]);
        egui::ComboBox::from_label("glTF animation")
            .selected_text(name(&chosen))
            .show_ui(ui, |ui| {
                for c in choices {
                    let label = name(&c);
                    ui.selectable_value(&mut chosen, c, label);
                }
            });
        if chosen != info.animation {
            let _ = self.worker.tx.send(Request::Open(info.path.clone(), chosen));
        }
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        ui.heading("OpenRT-rs");
        if let Some(i) = &self.info {
            ui.label(format!("scene: {}", i.name));
        }
        ui.horizontal(|ui| {
            if ui.button("Open…").clicked() {
                self.dialog.pick_file();
            }
            if ui.button("Default scene").clicked() {
                let _ = self.worker.tx.send(Request::Open(None, GltfAnimation::First));
            }
        });
        ui.separator();
        ui.label("Animation");
        self.animation_chooser(ui);
        let (a, b, frames) = self
            .info
            .as_ref()
            .map_or((0.0, 0.0, 1), |i| (i.time_range.0, i.time_range.1, i.frames));
        ui.horizontal(|ui| {
            if ui.button(if self.playing { "Pause" } else { "Play" }).clicked() {
                self.playing = !self.playing;
                self.dirty = true;
            }
            if ui.button("Step").clicked() && frames > 1 {
                self.time = (self.time + (b - a) / (frames - 1) as f32).min(b);
                self.dirty = true;
            }
            ui.checkbox(&mut self.looping, "loop");
        });
        if ui
            .add(egui::Slider::new(&mut self.time, a..=b.max(a)).text("time"))
            .changed()
        {
            self.dirty = true;
        }
        ui.add(
            egui::Slider::new(&mut self.speed, 0.05..=4.0)
                .logarithmic(true)
                .text("speed"),
        );
        ui.separator();
        ui.label("Camera");
        if ui
            .checkbox(&mut self.follow_scene_camera, "follow the scene's camera")
            .changed()
        {
            self.dirty = true;
        }
        ui.horizontal(|ui| {
            if ui.button("Reset").clicked() {
                self.follow_scene_camera = true;
                self.dirty = true;
            }
            if ui.button("Copy camera").clicked()
                && let Some(c) = self.camera
            {
                let text = format!(
                    "camera: (from: ({}, {}, {}), at: ({}, {}, {}), up: ({}, {}, {}), fov: {}),",
                    c.from.x, c.from.y, c.from.z, c.at.x, c.at.y, c.at.z, c.up.x, c.up.y, c.up.z, c.fov_y_deg
                );
                println!("{text}");
                ui.ctx().copy_text(text);
                self.status = "camera copied".into();
            }
        });
        ui.label("drag: orbit, right/middle drag: pan, wheel: zoom, WASD/arrows, Q/E: fly");
        ui.separator();
        ui.label("Quality");
        ui.horizontal(|ui| {
            self.dirty |= ui
                .radio_value(&mut self.mode, RenderMode::GlLike, "OpenGL-like")
                .changed();
            self.dirty |= ui.radio_value(&mut self.mode, RenderMode::Whitted, "Whitted").changed();
        });
        ui.horizontal(|ui| {
            ui.label("traversal");
            for &b in Backend::ALL {
                self.dirty |= ui.radio_value(&mut self.backend, b, b.name()).changed();
            }
        });
        ui.horizontal(|ui| {
            ui.label("objects");
            for a in Accel::ALL {
                self.dirty |= ui.radio_value(&mut self.accel, a, a.name()).changed();
            }
        });
        ui.horizontal(|ui| {
            ui.label("top level");
            for t in TopLevel::ALL {
                self.dirty |= ui.radio_value(&mut self.top_level, t, t.name()).changed();
            }
        });
        self.dirty |= ui
            .add(egui::Slider::new(&mut self.depth, 0..=openrt_core::MAX_SHADE_DEPTH.min(8)).text("reflection depth"))
            .changed();
        let max_threads =
            (std::thread::available_parallelism().map_or(1, std::num::NonZero::get) * 2).min(openrt_core::MAX_THREADS);
        self.dirty |= ui
            .add(egui::Slider::new(&mut self.threads, 1..=max_threads).text("threads"))
            .changed();
        self.dirty |= ui
            .add(egui::Slider::new(&mut self.scale, 0.125..=1.0).text("resolution scale"))
            .changed();
        ui.separator();
        if ui.button("Screenshot (PNG)").clicked() {
            self.save_frame_png();
        }
        if !self.status.is_empty() {
            ui.label(&self.status);
        }
        if let Some(e) = &self.error {
            ui.colored_label(egui::Color32::LIGHT_RED, e);
        }
        if let Some(info) = self.info.as_ref().filter(|i| !i.warnings.is_empty()) {
            egui::CollapsingHeader::new(
                egui::RichText::new(format!("{} load warnings", info.warnings.len())).color(egui::Color32::YELLOW),
            )
            .show(ui, |ui| {
                for w in &info.warnings {
                    ui.label(w);
                }
            });
        }
    }

    /// Mouse and keyboard on the image move the camera (and stop following the scene's).
    fn camera_input(&mut self, ui: &egui::Ui, response: &egui::Response) {
        let Some(mut cam) = self.camera else { return };
        let mut moved = false;
        if response.dragged_by(egui::PointerButton::Primary) {
            let d = response.drag_delta();
            orbit::orbit(&mut cam, d.x, d.y);
            moved = true;
        }
        if response.dragged_by(egui::PointerButton::Secondary) || response.dragged_by(egui::PointerButton::Middle) {
            let d = response.drag_delta();
            orbit::pan(&mut cam, d.x, d.y, response.rect.height());
            moved = true;
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                orbit::zoom(&mut cam, scroll);
                moved = true;
            }
        }
        let (f, r, u, dt) = ui.input(|i| {
            let k = |a: egui::Key, b: egui::Key| f32::from(u8::from(i.key_down(a) || i.key_down(b)));
            (
                k(egui::Key::W, egui::Key::ArrowUp) - k(egui::Key::S, egui::Key::ArrowDown),
                k(egui::Key::D, egui::Key::ArrowRight) - k(egui::Key::A, egui::Key::ArrowLeft),
                k(egui::Key::E, egui::Key::E) - k(egui::Key::Q, egui::Key::Q),
                i.stable_dt.min(0.1),
            )
        });
        if !ui.ctx().egui_wants_keyboard_input() && (f != 0.0 || r != 0.0 || u != 0.0) {
            orbit::fly(&mut cam, f, r, u, dt);
            moved = true;
        }
        if moved {
            self.camera = Some(cam);
            self.follow_scene_camera = false;
            self.moving_until = Instant::now() + std::time::Duration::from_millis(250);
            self.dirty = true;
            ui.ctx().request_repaint();
        }
    }
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        self.receive(&ctx);
        self.dialog.update(&ctx);
        if let Some(path) = self.dialog.take_picked() {
            let _ = self.worker.tx.send(Request::Open(Some(path), GltfAnimation::First));
        }
        // Screenshot of the real window after enough frames.
        if let Some(path) = self.screenshot.clone() {
            if !self.screenshot_requested && self.frames_rendered >= u64::from(self.screenshot_after) {
                self.screenshot_requested = true;
                ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(egui::UserData::default()));
            }
            let shot = ctx.input(|i| {
                i.raw.events.iter().find_map(|e| match e {
                    egui::Event::Screenshot { image, .. } => Some(image.clone()),
                    _ => None,
                })
            });
            if let Some(img) = shot {
                let [w, h] = img.size;
                let bytes: Vec<u8> = img.pixels.iter().flat_map(|c| [c.r(), c.g(), c.b()]).collect();
                let result = image::save_buffer(&path, &bytes, w as u32, h as u32, image::ColorType::Rgb8);
                let sidecar = serde_json::json!({
                    "frames_rendered": self.frames_rendered,
                    "overlay": self.overlay_text(),
                    "window": [w, h],
                    "ok": result.is_ok(),
                });
                let _ = std::fs::write(path.with_extension("json"), sidecar.to_string());
                if let Err(e) = result {
                    eprintln!("{}: {e}", path.display());
                }
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
        }
        egui::Panel::left("controls").resizable(true).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| self.controls(ui));
        });
        egui::CentralPanel::default().show(ui, |ui| {
            // An error stays in view above the last good frame.
            if self.texture.is_some()
                && let Some(e) = &self.error
            {
                ui.colored_label(egui::Color32::LIGHT_RED, format!("error: {e}"));
            }
            let avail = ui.available_size();
            if let Some(tex) = &self.texture {
                let [w, h] = tex.size().map(|v| v as f32);
                let s = (avail.x / w).min(avail.y / h);
                let resp =
                    ui.add(egui::Image::new((tex.id(), egui::vec2(w * s, h * s))).sense(egui::Sense::click_and_drag()));
                self.camera_input(ui, &resp);
                let painter = ui.painter_at(resp.rect);
                let text = self.overlay_text();
                let galley = painter.layout_no_wrap(text, egui::FontId::monospace(12.0), egui::Color32::WHITE);
                let rect = egui::Rect::from_min_size(
                    resp.rect.min + egui::vec2(6.0, 6.0),
                    galley.size() + egui::vec2(8.0, 8.0),
                );
                painter.rect_filled(rect, 4.0, egui::Color32::from_black_alpha(170));
                painter.galley(rect.min + egui::vec2(4.0, 4.0), galley, egui::Color32::WHITE);
            } else {
                ui.centered_and_justified(|ui| ui.label(self.error.clone().unwrap_or_else(|| "loading…".into())));
            }
        });
        if self.playing && !self.in_flight {
            self.dirty = true;
        }
        // Refine after the camera stops moving.
        if Instant::now() >= self.moving_until
            && self.last.as_ref().is_some_and(|f| {
                let base = self.scene_settings();
                f.image.width < ((base.width as f32 * self.scale) as u32).max(8)
            })
        {
            self.dirty = true;
        }
        // Refine sample by sample while the view stays still.
        if !self.in_flight && self.can_refine() {
            self.dirty = true;
        }
        if self.dirty {
            self.request_frame();
        }
        if self.playing || self.in_flight || Instant::now() < self.moving_until || self.can_refine() {
            ctx.request_repaint();
        }
    }
}
