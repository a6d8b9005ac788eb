//! The measurements of `openrt bench`: each function runs scenes and
//! returns typed results (`results.rs`); nothing here formats the report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use openrt_accel::oracle::BruteForce;
use openrt_accel::{BuilderKind, Hit};
use openrt_accel::{PacketWidth, Ray};
use openrt_core::kernels::{OccluderHint, first_hit_shadow_ray};
use openrt_core::{Accel, Backend, Image, RenderMode, RenderSettings, Renderer, TextureFilter, ThreadPool, TopLevel};
use openrt_scene::ScenePlayer;

use super::BenchOptions;
use super::goals::REFERENCE_SPP;
#[cfg(feature = "embree")]
use super::results::EmbreeRow;
use super::results::{
    BuilderRow, BuilderRun, DeformRow, ImageDiff, KindRow, OracleCheck, PhaseRow, Quality, QualityRun, Rebuild,
    Results, Row, WorstDiff,
};

pub(super) fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn scene_path(name: &str) -> PathBuf {
    let p = PathBuf::from(name);
    if p.extension().is_some() {
        p
    } else {
        Path::new("scenes").join(format!("{name}.ron"))
    }
}

fn settings(o: &BenchOptions, mode: RenderMode, depth: u32) -> RenderSettings {
    RenderSettings {
        width: o.width,
        height: o.height,
        mode,
        max_depth: depth,
        ..RenderSettings::default()
    }
}

/// Samples gathered per (threads, mode): commit, top-level, fast-build ms, promotions, render ms, rays.
type Acc = (Vec<f64>, Vec<f64>, Vec<f64>, usize, Vec<f64>, Vec<f64>);

/// Compares `img` with the `kd` image of the same frame.
fn image_diff(kd: &Image, img: &Image) -> (bool, f64) {
    let (a, b) = (kd.to_rgb8(), img.to_rgb8());
    let off = a
        .chunks(3)
        .zip(b.chunks(3))
        .filter(|(p, q)| p.iter().zip(*q).any(|(x, y)| x.abs_diff(*y) > 8))
        .count();
    (a == b, off as f64 / (a.len() / 3).max(1) as f64)
}

/// Commits frame `f` of `player` right after the two frames before it
/// (untimed), as a played animation does, so that a refit starts from the
/// last frame's tree rather than after a jump across the animation; the
/// stats of frame `f`'s commit.
fn commit_played(player: &mut ScenePlayer, f: u32) -> Result<openrt_core::CommitStats, String> {
    for g in f.saturating_sub(2)..f {
        player.set_time(player.time_of(g)).map_err(|e| e.to_string())?;
    }
    player.set_time(player.time_of(f)).map_err(|e| e.to_string())
}

/// The bench scene `name` with `accel` under its objects, its first frame
/// committed (the warm-up commit builds every tree).
fn open_player(name: &str, accel: Accel) -> Result<ScenePlayer, String> {
    let mut player = ScenePlayer::open(Some(&scene_path(name))).map_err(|e| e.to_string())?;
    player.ctx_mut().set_accel(accel);
    player.set_time(player.time_of(0)).map_err(|e| e.to_string())?;
    Ok(player)
}

/// One structure's side of [`measure_scene`]: its own player (the scene
/// committed with `accel` under the instances), renderers and samples.
struct Side {
    accel: Accel,
    player: ScenePlayer,
    renderers: Vec<(usize, Renderer)>,
    acc: Vec<Acc>,
    images: Vec<Image>,
    tri: usize,
    inst: usize,
}

impl Side {
    /// Opens the scene with `accel`, builds its trees (the first commit)
    /// and makes a renderer per thread count and backend: every backend
    /// of the build with kd-trees, only those that traverse them with BVHs.
    fn open(o: &BenchOptions, name: &str, accel: Accel, pools: &[(usize, ThreadPool)]) -> Result<Self, String> {
        let player = open_player(name, accel)?;
        let renderers: Vec<(usize, Renderer)> = pools
            .iter()
            .flat_map(|(t, pool)| {
                Backend::ALL
                    .iter()
                    .filter(move |&&b| accel == Accel::Kd || matches!(b, Backend::Packets | Backend::Single))
                    // The device run: packets only (the default backend and Embree's).
                    .filter(move |&&b| !o.device || b.packets())
                    .map(move |&b| {
                        let mut r = crate::new_renderer(pool.clone());
                        r.set_backend(b);
                        (*t, r)
                    })
            })
            .collect();
        // Warm-up: a peer backend builds its own scene on its first frame,
        // as the trees were built by the warm-up commit above. The first
        // thread count's renderers, measured first, render a whole frame of
        // each mode: measured cold, their frames came out slow (1 -> 2 threads
        // over 2x faster, on 2 cores and on 16).
        {
            let scene = player.ctx().scene();
            let tiny = RenderSettings {
                width: 8,
                height: 8,
                ..settings(o, RenderMode::GlLike, 0)
            };
            let cam = player.camera(player.time_of(0));
            for (t, r) in &renderers {
                if *t == o.threads[0] {
                    for mode in [RenderMode::GlLike, RenderMode::Whitted] {
                        r.render(&scene, &player.env(), &cam, &settings(o, mode, 3))
                            .map_err(|e| e.to_string())?;
                    }
                } else {
                    r.render(&scene, &player.env(), &cam, &tiny)
                        .map_err(|e| e.to_string())?;
                }
            }
        }
        let n = 2 * renderers.len();
        Ok(Self {
            accel,
            player,
            renderers,
            acc: vec![Default::default(); n],
            images: vec![Image::default(); n],
            tri: 0,
            inst: 0,
        })
    }

    /// Commits frame `f` (after the two before it) and renders it through
    /// this side's renderers of `threads`, in both modes, sampling their
    /// times. On the first sampled frame of the fewest threads the images
    /// are compared with `reference`, the `kd` backend's with kd-trees
    /// (which this side writes when it is that).
    fn play(
        &mut self,
        name: &str,
        o: &BenchOptions,
        (threads, f, first): (usize, u32, bool),
        diffs: &mut Vec<ImageDiff>,
        reference: &mut Vec<Image>,
    ) -> Result<(), String> {
        let c = commit_played(&mut self.player, f)?;
        let t = self.player.time_of(f);
        let scene = self.player.ctx().scene();
        (self.tri, self.inst) = (scene.instanced_triangles(), scene.instances().len());
        let cam = self.player.camera(t);
        let env = self.player.env();
        for (ri, (_, r)) in self.renderers.iter().enumerate().filter(|(_, (rt, _))| *rt == threads) {
            for (mi, mode) in [RenderMode::GlLike, RenderMode::Whitted].into_iter().enumerate() {
                // Each backend and mode renders into its own image, as
                // `play` and an interactive loop do (the buffer reused).
                let img = &mut self.images[2 * ri + mi];
                let st = r
                    .render_into(&scene, &env, &cam, &settings(o, mode, 3), img)
                    .map_err(|e| e.to_string())?;
                if first && threads == o.threads[0] {
                    if self.accel == Accel::Kd && r.backend() == Backend::Packets {
                        reference.push(img.clone());
                    } else if let Some(kd) = reference.get(mi) {
                        let (identical, off_share) = image_diff(kd, img);
                        diffs.push(ImageDiff {
                            scene: name.to_string(),
                            mode: ["GL-like", "Whitted"][mi],
                            backend: r.backend().label(self.accel),
                            identical,
                            off_share,
                        });
                    }
                }
                let a = &mut self.acc[2 * ri + mi];
                a.0.push(c.total_ms);
                a.1.push(c.toplevel_ms);
                a.2.push(c.build_ms(BuilderKind::Fast));
                a.3 += c.promotions_swapped.len();
                a.4.push(st.render_ms);
                a.5.push(st.rays.total() as f64);
            }
        }
        Ok(())
    }

    /// The frames table's rows of this side: medians of its samples.
    fn rows(&self, name: &str, rows: &mut Vec<Row>) {
        for (ri, (threads, r)) in self.renderers.iter().enumerate() {
            for (mi, mode) in ["GL-like", "Whitted"].into_iter().enumerate() {
                let a = self.acc[2 * ri + mi].clone();
                rows.push(Row {
                    scene: name.to_string(),
                    mode,
                    backend: r.backend().label(self.accel),
                    threads: *threads,
                    commit_ms: median(a.0),
                    toplevel_ms: median(a.1),
                    fast_ms: median(a.2),
                    promotions: a.3,
                    render_ms: median(a.4),
                    rays: median(a.5),
                    triangles: self.tri,
                    instances: self.inst,
                });
            }
        }
    }
}

/// One scene's frames through every backend of the build, with each of
/// `accels` under the instances (kd first: its `kd` images are the
/// reference the others are compared with). Each structure has its own
/// player; they play the sampled frames in turn, frame by frame, the
/// first of them changing from frame to frame, so that the machine's
/// slow phases fall on both alike (the kd-vs-BVH verdict on the default
/// compares their frames).
fn measure_scene(
    o: &BenchOptions,
    name: &str,
    accels: &[Accel],
    rows: &mut Vec<Row>,
    diffs: &mut Vec<ImageDiff>,
) -> Result<(), String> {
    // One pool per thread count, shared by the commits and a renderer per
    // backend (packets first).
    let pools: Vec<(usize, ThreadPool)> = o
        .threads
        .iter()
        .map(|&t| ThreadPool::new(t).map(|p| (t, p)).map_err(|e| e.to_string()))
        .collect::<Result<_, String>>()?;
    let mut sides: Vec<Side> = accels
        .iter()
        .map(|&a| Side::open(o, name, a, &pools))
        .collect::<Result<_, String>>()?;
    let n = sides.first().map_or(0, |s| s.player.frames());
    let samples: Vec<u32> = (0..o.frames)
        .map(|k| ((k as u64 + 1) * u64::from(n) / (o.frames as u64 + 1)) as u32)
        .collect();
    let mut reference = Vec::new();
    // Commit and render on the same number of threads: each thread count
    // plays the sampled frames with a commit pool of its size.
    for (threads, pool) in &pools {
        for side in &mut sides {
            side.player.ctx_mut().set_pool(pool);
            side.player
                .set_time(side.player.time_of(0))
                .map_err(|e| e.to_string())?;
        }
        for (k, &f) in samples.iter().enumerate() {
            let first = k == 0;
            // The reference (kd first) on the first frame; then in turn.
            for i in 0..sides.len() {
                let s = if k % 2 == 0 { i } else { sides.len() - 1 - i };
                sides[s].play(name, o, (*threads, f, first), diffs, &mut reference)?;
            }
        }
    }
    for side in &sides {
        side.rows(name, rows);
    }
    Ok(())
}

/// Ray queries alone, one thread, no shading: a frame's primary rays
/// (closest hit) in the renderer's pixel blocks, and the shadow rays from
/// their hits to each light (any hit, with each light's last occluder tried
/// first, as the renderer does), through `Scene::intersect`/`occluded_hinted`
/// one by one and through the packet queries. Medians of 5 passes.
fn ray_kinds(o: &BenchOptions, name: &str) -> Result<Vec<KindRow>, String> {
    let mut player = open_player(name, Accel::Kd)?;
    let t = player.time_of(player.frames() / 2);
    player.set_time(t).map_err(|e| e.to_string())?;
    let scene = player.ctx().scene();
    // The same frame under each top level.
    let mut tops = Vec::new();
    for top in [TopLevel::Bsp, TopLevel::Bvh] {
        player.ctx_mut().set_top_level(top);
        player.set_time(t).map_err(|e| e.to_string())?;
        tops.push(player.ctx().scene());
    }
    player.ctx_mut().set_top_level(TopLevel::Auto);
    // The same frame with BVHs under the instances.
    player.ctx_mut().set_accel(Accel::Bvh);
    player.set_time(t).map_err(|e| e.to_string())?;
    let bvh_scene = player.ctx().scene();
    let env = player.env();
    let cam = player.camera(t).rays(o.width, o.height).map_err(|e| e.to_string())?;
    let lanes = crate::packet_width().lanes();
    let (bw, bh) = openrt_core::kernels::packet_block(lanes);
    // Pixel blocks in the renderer's order, each padded to full lanes.
    let mut primary = Vec::new();
    for by in (0..o.height).step_by(bh as usize) {
        for bx in (0..o.width).step_by(bw as usize) {
            for l in 0..lanes as u32 {
                let (x, y) = (bx + l % bw, by + l / bw);
                primary.push(cam.ray(x.min(o.width - 1), y.min(o.height - 1)));
            }
        }
    }
    let mut shadow = Vec::new();
    for block in primary.chunks(lanes) {
        for light in &env.lights {
            for r in block {
                shadow.push(first_hit_shadow_ray(&scene, r, light.position));
            }
        }
    }
    let time = |f: &mut dyn FnMut() -> usize| {
        let mut v = Vec::new();
        let mut sink = 0;
        for _ in 0..5 {
            let s = Instant::now();
            sink += f();
            v.push(s.elapsed().as_secs_f64());
        }
        std::hint::black_box(sink);
        median(v)
    };
    let mut out = Vec::new();
    // One Embree scene for both kinds (one device per process run).
    #[cfg(feature = "embree")]
    let em = {
        let mut em = openrt_core::EmbreeScene::default();
        em.sync(&scene).map_err(|e| e.to_string())?;
        em
    };
    for (kind, rays) in [("primary", &primary), ("shadow", &shadow)] {
        // A scene without lights has no shadow rays to time.
        if rays.is_empty() {
            continue;
        }
        let n = rays.len() as f64;
        let closest = kind == "primary";
        // Shadow rays try the last occluder of their light first, as the
        // renderer's do (`OccluderHint`, one per light, in the rays' order).
        let nl = env.lights.len().max(1);
        let single_of = |scene: &openrt_core::Scene| {
            let mut hints = vec![OccluderHint::new(); nl];
            rays.iter()
                .enumerate()
                .filter(|(k, r)| {
                    if closest {
                        scene.intersect(r).is_some()
                    } else {
                        scene.occluded_hinted(r, &mut hints[(k / lanes) % nl])
                    }
                })
                .count()
        };
        // Shadow packets hold one block's rays to one light (blocks in
        // order, lights in order within a block), as the renderer traces
        // them: towards the light.
        let lights: Vec<Vec3> = env.lights.iter().map(|l| l.position).collect();
        let packet_of = |scene: &openrt_core::Scene| match crate::packet_width() {
            PacketWidth::W4 => packets::<4>(scene, rays, closest, &lights),
            PacketWidth::W8 => packets::<8>(scene, rays, closest, &lights),
            PacketWidth::W16 => packets::<16>(scene, rays, closest, &lights),
            PacketWidth::W32 => packets::<32>(scene, rays, closest, &lights),
        };
        let single = time(&mut || single_of(&scene));
        let packet = time(&mut || packet_of(&scene));
        let bvh = (
            n / time(&mut || single_of(&bvh_scene)) / 1e6,
            n / time(&mut || packet_of(&bvh_scene)) / 1e6,
        );
        let top = [
            n / time(&mut || single_of(&tops[0])) / 1e6,
            n / time(&mut || single_of(&tops[1])) / 1e6,
            n / time(&mut || packet_of(&tops[0])) / 1e6,
            n / time(&mut || packet_of(&tops[1])) / 1e6,
        ];
        #[cfg(not(feature = "embree"))]
        let embree = None;
        #[cfg(feature = "embree")]
        let embree = {
            let one = time(&mut || {
                rays.iter()
                    .filter(|r| {
                        if closest {
                            em.intersect(r).is_some()
                        } else {
                            em.occluded(r)
                        }
                    })
                    .count()
            });
            let pk = time(&mut || match crate::packet_width() {
                PacketWidth::W4 => embree_packets::<4>(&em, rays, closest),
                PacketWidth::W8 => embree_packets::<8>(&em, rays, closest),
                PacketWidth::W16 => embree_packets::<16>(&em, rays, closest),
                PacketWidth::W32 => embree_packets::<32>(&em, rays, closest),
            });
            Some((n / one / 1e6, n / pk / 1e6))
        };
        out.push(KindRow {
            scene: name.to_string(),
            kind,
            single: n / single / 1e6,
            packet: n / packet / 1e6,
            embree,
            bvh,
            top,
            top_default: (scene.top_level().name(), scene.instances().len()),
            rays: rays.len(),
        });
    }
    Ok(out)
}

/// Hits (or blocked rays) of `rays` traced in packets of `N`; packet `k`
/// of shadow rays goes towards `lights[k % lights.len()]`.
fn packets<const N: usize>(scene: &openrt_core::Scene, rays: &[Ray], closest: bool, lights: &[Vec3]) -> usize {
    let full = u32::MAX >> (32 - N);
    let mut k = 0;
    let mut hints = vec![OccluderHint::new(); lights.len()];
    packets_with::<N>(rays, |pk| {
        k += 1;
        if closest {
            scene.intersect_packet(pk, full).iter().flatten().count()
        } else {
            let j = (k - 1) % lights.len().max(1);
            scene
                .occluded_packet_toward_hinted(pk, full, lights[j], &mut hints[j])
                .count_ones() as usize
        }
    })
}

/// Hits (or blocked rays) of `rays` through Embree's packet kernels of width `N`.
#[cfg(feature = "embree")]
fn embree_packets<const N: usize>(em: &openrt_core::EmbreeScene, rays: &[Ray], closest: bool) -> usize {
    let full = u32::MAX >> (32 - N);
    packets_with::<N>(rays, |pk| {
        if closest {
            em.intersect_packet(pk, full).iter().flatten().count()
        } else {
            em.occluded_packet(pk, full).count_ones() as usize
        }
    })
}

/// `query` over `rays` cut into packets of `N`, its answers summed.
fn packets_with<const N: usize>(rays: &[Ray], mut query: impl FnMut(&[Ray; N]) -> usize) -> usize {
    rays.chunks_exact(N)
        .map(|c| query(&std::array::from_fn(|l| c[l])))
        .sum()
}

/// Root-mean-square error (0..1 scale) and PSNR in dB between two images of the same size.
pub(super) fn rmse_psnr(a: &Image, b: &Image) -> (f64, f64) {
    let mut se = 0.0;
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        let d = (p.clamp(Vec3::ZERO, Vec3::ONE) - q.clamp(Vec3::ZERO, Vec3::ONE)).as_dvec3();
        se += d.length_squared() / 3.0;
    }
    let mse = se / a.pixels.len() as f64;
    (mse.sqrt(), if mse > 0.0 { -10.0 * mse.log10() } else { f64::INFINITY })
}

/// Nearest-neighbour upsampling to `w` x `h` (`image::imageops::resize`).
pub(super) fn upsample(img: &Image, w: u32, h: u32) -> Image {
    let buf: image::Rgb32FImage = image::ImageBuffer::from_fn(img.width, img.height, |x, y| {
        image::Rgb(img.pixels[(y * img.width + x) as usize].to_array())
    });
    let big = image::imageops::resize(&buf, w, h, image::imageops::FilterType::Nearest);
    Image {
        width: w,
        height: h,
        pixels: big.pixels().map(|p| Vec3::from_array(p.0)).collect(),
    }
}

/// Speed against error on `name`'s middle frame: every setting's render time
/// and its error against a 64-spp reference, the worst setting's difference
/// image (written beside the report), and sampled primary rays checked
/// against the f64 oracle.
fn speed_vs_error(o: &BenchOptions, name: &str) -> Result<QualityRun, String> {
    let mut player = ScenePlayer::open(Some(&scene_path(name))).map_err(|e| e.to_string())?;
    let threads = *o.threads.iter().max().unwrap_or(&1);
    player.ctx_mut().set_threads(threads).map_err(|e| e.to_string())?;
    let r = crate::new_renderer(player.ctx_mut().pool().map_err(|e| e.to_string())?);
    let f = player.frames() / 2;
    let t = player.time_of(f);
    player.set_time(player.time_of(0)).map_err(|e| e.to_string())?;
    player.set_time(t).map_err(|e| e.to_string())?;
    let scene = player.ctx().scene();
    let (cam, env) = (player.camera(t), player.env());
    let full = RenderSettings {
        spp: REFERENCE_SPP,
        texture_filter: TextureFilter::Trilinear,
        ..settings(o, RenderMode::Whitted, 8)
    };
    let start = Instant::now();
    let (reference, _) = r.render(&scene, &env, &cam, &full).map_err(|e| e.to_string())?;
    let reference_s = start.elapsed().as_secs_f64();
    let mut q = Vec::new();
    let d3 = settings(o, RenderMode::Whitted, 3);
    let cases: Vec<(String, RenderSettings)> = vec![
        ("GL-like".into(), settings(o, RenderMode::GlLike, 0)),
        ("shadows only (depth 0)".into(), settings(o, RenderMode::Whitted, 0)),
        ("Whitted depth 1".into(), settings(o, RenderMode::Whitted, 1)),
        ("Whitted depth 2".into(), settings(o, RenderMode::Whitted, 2)),
        ("Whitted depth 3 (trilinear, 1 spp)".into(), d3),
        (
            "depth 3, nearest".into(),
            RenderSettings {
                texture_filter: TextureFilter::Nearest,
                ..d3
            },
        ),
        (
            "depth 3, bilinear".into(),
            RenderSettings {
                texture_filter: TextureFilter::Bilinear,
                ..d3
            },
        ),
        ("depth 3, 4 spp".into(), RenderSettings { spp: 4, ..d3 }),
        ("depth 3, 16 spp".into(), RenderSettings { spp: 16, ..d3 }),
        (
            "depth 3, 1/2 resolution".into(),
            RenderSettings {
                width: o.width / 2,
                height: o.height / 2,
                ..d3
            },
        ),
        (
            "depth 3, 1/4 resolution".into(),
            RenderSettings {
                width: o.width / 4,
                height: o.height / 4,
                ..d3
            },
        ),
    ];
    let mut worst: Option<(f64, String, Image)> = None;
    for (label, s) in cases {
        let mut times = Vec::new();
        let mut img = None;
        // Multi-sample rows take long enough to be timed once.
        for _ in 0..if s.spp > 1 { 1 } else { 3 } {
            let (im, st) = r.render(&scene, &env, &cam, &s).map_err(|e| e.to_string())?;
            times.push(st.render_ms);
            img = Some(im);
        }
        let img = upsample(&img.expect("rendered"), o.width, o.height);
        let (rmse, psnr) = rmse_psnr(&reference, &img);
        if worst.as_ref().is_none_or(|w| rmse > w.0) {
            worst = Some((rmse, label.clone(), img));
        }
        q.push(Quality {
            scene: name.to_string(),
            label,
            ms: median(times),
            rmse,
            psnr,
        });
    }
    let worst = worst.map(|(rmse, label, img)| WorstDiff {
        file: write_diff(o, name, &img, &reference),
        label,
        rmse,
    });
    let oracle = oracle_check(o, &scene, &cam)?;
    Ok(QualityRun {
        scene: name.to_string(),
        frame: f,
        reference_s,
        rows: q,
        worst,
        oracle,
    })
}

/// Writes the difference image of `img` against `reference` (x4) beside the
/// report; returns its file name, or why it was not written.
fn write_diff(o: &BenchOptions, name: &str, img: &Image, reference: &Image) -> Result<String, String> {
    let file = format!("bench-diff-{name}.png");
    let diff = Image {
        width: img.width,
        height: img.height,
        pixels: img
            .pixels
            .iter()
            .zip(&reference.pixels)
            .map(|(a, b)| {
                ((a.clamp(Vec3::ZERO, Vec3::ONE) - b.clamp(Vec3::ZERO, Vec3::ONE)).abs() * 4.0).min(Vec3::ONE)
            })
            .collect(),
    };
    diff.save_png(o.out.with_file_name(&file)).map_err(|e| e.to_string())?;
    Ok(file)
}

/// Sampled primary rays of the frame (about 800) against the f64 oracle.
fn oracle_check(
    o: &BenchOptions,
    scene: &openrt_core::Scene,
    cam: &openrt_core::Camera,
) -> Result<OracleCheck, String> {
    // Numerical error of the accelerated path: sampled primary rays against the f64 oracle.
    let (world, origin) = scene.world_triangles();
    let oracle = BruteForce::new(&world);
    let rays = cam.rays(o.width, o.height).map_err(|e| e.to_string())?;
    let (mut checked, mut failed, mut other_prim) = (0usize, 0usize, 0usize);
    let step = ((o.width * o.height) as usize / 800).max(1);
    let index: std::collections::HashMap<(u32, u32), u32> =
        origin.iter().enumerate().map(|(i, &o)| (o, i as u32)).collect();
    for p in (0..(o.width * o.height) as usize).step_by(step) {
        let ray = rays.ray(p as u32 % o.width, p as u32 / o.width);
        let got = scene.intersect(&ray).map(|h| Hit {
            t: h.t,
            prim: index[&(h.instance, h.prim)],
            b1: h.b1,
            b2: h.b2,
        });
        checked += 1;
        if oracle.check_closest(&ray, got).is_err() {
            failed += 1;
        }
        if got.map(|h| h.prim) != oracle.closest(&ray).map(|h| h.prim) {
            other_prim += 1;
        }
    }
    Ok(OracleCheck {
        triangles: world.len(),
        checked,
        failed,
        other_prim,
    })
}

/// Frames sampled at least by the builders table: its refitted / afresh
/// render ratio is a median of per-frame ratios, and with 3 frames it
/// swung 0.86-1.13 between runs of the same build on the 2-core machine
/// (9 frames: 0.93-1.06; `refit_frames` example).
pub(super) const BUILDER_FRAMES: usize = 9;

/// kd-trees (fast, refitted or afresh; SAH) and BVHs (refitted or afresh)
/// for the moving triangles of `name`: commit and render time per frame.
/// Each sampled frame is committed right after the two frames before it, as
/// when the animation plays, so that a refit starts from the last frame's
/// tree. The players (one per builder) take turns frame by frame (and the
/// first of them changes from frame to frame), so that the machine's slow
/// and fast phases fall on all of them alike. Returns the median per-frame
/// ratios of Whitted render time with refitted trees to trees built
/// afresh: kd-trees, then BVHs.
fn builders(o: &BenchOptions, name: &str) -> Result<BuilderRun, String> {
    let variants = [
        ("kd, fast, refitted", BuilderKind::Fast, true, Accel::Kd),
        ("kd, fast, afresh", BuilderKind::Fast, false, Accel::Kd),
        ("kd, SAH", BuilderKind::Sah, false, Accel::Kd),
        ("BVH, refitted (default)", BuilderKind::Fast, true, Accel::Bvh),
        ("BVH, afresh", BuilderKind::Fast, false, Accel::Bvh),
    ];
    let mut players = Vec::new();
    for &(_, b, refit, accel) in &variants {
        let mut player = ScenePlayer::open(Some(&scene_path(name))).map_err(|e| e.to_string())?;
        player.ctx_mut().set_accel(accel);
        player.ctx_mut().set_redefinition_builder(b);
        player.ctx_mut().set_refit(refit);
        player.ctx_mut().set_promote_after(None);
        player
            .ctx_mut()
            .set_threads(*o.threads.iter().max().unwrap_or(&1))
            .map_err(|e| e.to_string())?;
        let r = crate::new_renderer(player.ctx_mut().pool().map_err(|e| e.to_string())?);
        player.set_time(player.time_of(0)).map_err(|e| e.to_string())?;
        players.push((player, r));
    }
    let n = o.frames.max(BUILDER_FRAMES);
    let (mut commits, mut renders) = (vec![Vec::new(); variants.len()], vec![Vec::new(); variants.len()]);
    for k in 0..n {
        for turn in 0..variants.len() {
            let v = (turn + k) % variants.len();
            let (player, r) = &mut players[v];
            let f = ((k + 1) * player.frames() as usize / (n + 1)) as u32;
            let st = commit_played(player, f)?;
            let t = player.time_of(f);
            commits[v].push(st.total_ms);
            let (_, fs) = r
                .render(
                    &player.ctx().scene(),
                    &player.env(),
                    &player.camera(t),
                    &settings(o, RenderMode::Whitted, 3),
                )
                .map_err(|e| e.to_string())?;
            renders[v].push(fs.render_ms);
        }
    }
    let ratio = |a: usize, b: usize| {
        median(
            renders[a]
                .iter()
                .zip(&renders[b])
                .map(|(x, y)| x / y.max(1e-9))
                .collect(),
        )
    };
    let rows = variants
        .iter()
        .zip(commits.into_iter().zip(renders.iter()))
        .map(|((label, ..), (c, rt))| BuilderRow {
            label,
            commit_ms: median(c),
            render_ms: median(rt.clone()),
        })
        .collect();
    Ok(BuilderRun {
        scene: name.to_string(),
        rows,
        kd_ratio: ratio(0, 1),
        bvh_ratio: ratio(3, 4),
    })
}

/// One museum's moving triangles rebuilt three ways on the same frames
/// (every other frame of the animation, in order, so that refits see the
/// motion of a played animation): the fast builder afresh, the fast tree
/// refitted from the last frame's (with its quality check), and with
/// `--features embree` Embree's LOW build; each on `threads` threads.
fn rebuild_figures(name: &str, threads: usize) -> Result<Rebuild, String> {
    use openrt_accel::{BspBuilder, FastParams, KdTree};
    let mut player = ScenePlayer::open(Some(&scene_path(name))).map_err(|e| e.to_string())?;
    player.ctx_mut().set_promote_after(None);
    let pool = BspBuilder::new(threads);
    let params = FastParams::default();
    let (mut fresh, mut refit) = (Vec::new(), Vec::new());
    #[cfg(feature = "embree")]
    let (mut emb, embree) = (Vec::new(), openrt_accel::EmbreeLowBuilds::new(threads)?);
    #[cfg(not(feature = "embree"))]
    let emb: Vec<f64> = Vec::new();
    // Embree's refits: its scene made on the first frame (untimed), then
    // refitted to each frame's triangles.
    #[cfg(feature = "embree")]
    let (mut emb_refit, mut embree_refits) = (Vec::new(), None::<openrt_accel::EmbreeRefits>);
    #[cfg(not(feature = "embree"))]
    let emb_refit: Vec<f64> = Vec::new();
    let (mut fresh_cost, mut refit_cost, mut refits, mut triangles) = (0.0, 0.0, 0, 0);
    let mut prev: Option<KdTree> = None;
    let (mut bvh_fresh, mut bvh_refit, mut bvh_refits) = (Vec::new(), Vec::new(), 0);
    let mut bvh_prev: Option<openrt_accel::Bvh> = None;
    let frames: Vec<u32> = (0..player.frames()).step_by(2).collect();
    for &f in &frames {
        let st = player.set_time(player.time_of(f)).map_err(|e| e.to_string())?;
        let scene = player.ctx().scene();
        let Some(tris) = st
            .builds
            .iter()
            .filter(|b| b.builder == BuilderKind::Fast)
            .find_map(|b| scene.instances().iter().find(|i| i.object == b.object))
            .map(|i| i.geometry.tree.triangles().to_vec())
        else {
            continue;
        };
        triangles = tris.len();
        // NOTE: the builders take the triangles by value, as a commit hands
        // them over (moved, not copied); the copies made here for the
        // three builds are not timed.
        let owned = tris.clone();
        let t0 = Instant::now();
        // As a commit runs them: on the pool when they can use its threads.
        let n = owned.len();
        let a = pool
            .install_build(BuilderKind::Fast, n, || KdTree::build_fast(owned))
            .map_err(|e| e.to_string())?;
        fresh.push(t0.elapsed().as_secs_f64() * 1e3);
        let owned = tris.clone();
        let t0 = Instant::now();
        let b = pool
            .install_build(BuilderKind::Fast, n, || match &prev {
                Some(p) => KdTree::refit_fast(p, owned, &params),
                None => KdTree::build_fast(owned),
            })
            .map_err(|e| e.to_string())?;
        refit.push(t0.elapsed().as_secs_f64() * 1e3);
        refits += usize::from(b.stats().refitted);
        fresh_cost += a.sah_cost();
        refit_cost += b.sah_cost();
        prev = Some(b);
        let owned = tris.clone();
        let t0 = Instant::now();
        let c = pool
            .install_build(BuilderKind::Fast, n, || openrt_accel::Bvh::build(owned))
            .map_err(|e| e.to_string())?;
        bvh_fresh.push(t0.elapsed().as_secs_f64() * 1e3);
        drop(c);
        let owned = tris.clone();
        let t0 = Instant::now();
        let d = pool
            .install_build(BuilderKind::Fast, n, || match &bvh_prev {
                Some(p) => openrt_accel::Bvh::refit(p, owned, openrt_accel::BVH_REFIT_COST_LIMIT),
                None => openrt_accel::Bvh::build(owned),
            })
            .map_err(|e| e.to_string())?;
        bvh_refit.push(t0.elapsed().as_secs_f64() * 1e3);
        bvh_refits += usize::from(d.stats().refitted);
        bvh_prev = Some(d);
        #[cfg(feature = "embree")]
        {
            emb.push(embree.secs(&tris)? * 1e3);
            match &mut embree_refits {
                Some(r) => emb_refit.push(r.secs(&tris)? * 1e3),
                None => embree_refits = Some(openrt_accel::EmbreeRefits::new(&tris, threads)?),
            }
        }
    }
    let n = fresh.len();
    if n == 0 {
        return Err(format!("{name}: no object was rebuilt with the fast builder"));
    }
    Ok(Rebuild {
        scene: name.to_string(),
        triangles,
        fresh_ms: median(fresh),
        refit_ms: median(refit),
        refits,
        frames: n,
        fresh_cost: fresh_cost / n as f64,
        refit_cost: refit_cost / n as f64,
        embree_ms: (!emb.is_empty()).then(|| median(emb)),
        embree_refit_ms: (!emb_refit.is_empty()).then(|| median(emb_refit)),
        bvh_ms: median(bvh_fresh),
        bvh_refit_ms: median(bvh_refit),
        bvh_refits,
    })
}

/// The moving triangles of the museums in `o` rebuilt by each builder.
fn rebuilds(o: &BenchOptions) -> Result<Vec<Rebuild>, String> {
    let threads = *o.threads.iter().max().unwrap_or(&1);
    let names: Vec<&String> = o.scenes.iter().filter(|s| s.starts_with("museum")).collect();
    if names.is_empty() {
        return Ok(Vec::new());
    }
    let mut rows = Vec::new();
    for name in names {
        eprintln!("bench: rebuilds on {name}");
        rows.push(rebuild_figures(name, threads)?);
    }
    Ok(rows)
}

/// Frames played of each skinned figure (after the first, which builds).
pub(super) const DEFORM_FRAMES: u32 = 8;

/// A skinned glTF figure of each size in `o.deform_sizes` (the generator
/// of `scenes/walker.glb`, 8 joints) played for [`DEFORM_FRAMES`] frames
/// on each thread count, with kd-trees and with BVHs: skinning, the API's
/// redefinition, the refit in the commit and the rest of the commit.
fn deforming(o: &BenchOptions) -> Result<Vec<DeformRow>, String> {
    let mut rows = Vec::new();
    for &n in &o.deform_sizes {
        let bytes = openrt_scene::skinned_figure_glb(n, 8);
        for &threads in &o.threads {
            for accel in Accel::ALL {
                eprintln!(
                    "bench: skinned figure, {n} triangles, {threads} threads, {}",
                    accel.name()
                );
                let mut p = openrt_scene::GltfPlayer::from_slice(&bytes).map_err(|e| e.to_string())?;
                p.ctx.set_threads(threads).map_err(|e| e.to_string())?;
                p.ctx.set_promote_after(None);
                p.ctx.set_accel(accel);
                p.set_deforming_accel(None).map_err(|e| e.to_string())?;
                p.set_time(0.0).map_err(|e| e.to_string())?;
                let (mut skin, mut define, mut build, mut other) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
                let mut refitted = 0;
                let mut triangles = 0;
                for f in 1..=DEFORM_FRAMES {
                    let st = p.set_time(p.time_of(f)).map_err(|e| e.to_string())?;
                    let d = p.deform_times();
                    let b: f64 = st.builds.iter().map(|b| b.ms).sum();
                    refitted += usize::from(st.builds.iter().all(|b| b.refitted));
                    triangles = st.builds.iter().map(|b| b.triangles).sum();
                    skin.push(d.skin_ms);
                    define.push(d.define_ms);
                    build.push(b);
                    other.push(st.total_ms - b);
                }
                rows.push(DeformRow {
                    triangles,
                    threads,
                    accel: accel.name(),
                    skin_ms: median(skin),
                    define_ms: median(define),
                    build_ms: median(build),
                    other_commit_ms: median(other),
                    refitted,
                    frames: DEFORM_FRAMES as usize,
                });
            }
        }
    }
    Ok(rows)
}

/// The same frames and primary rays through an Embree two-level scene:
/// per-frame rebuild time and single-ray throughput, one thread each.
#[cfg(feature = "embree")]
fn embree_side_by_side(o: &BenchOptions, name: &str) -> Result<EmbreeRow, String> {
    use std::sync::Arc;

    use openrt_accel::EmbreeTwoLevel;
    let mut player = ScenePlayer::open(Some(&scene_path(name))).map_err(|e| e.to_string())?;
    player.set_time(player.time_of(0)).map_err(|e| e.to_string())?;
    // Objects rebuilt between two frames move without structure.
    let moving: Vec<_> = player
        .set_time(player.time_of(1))
        .map_err(|e| e.to_string())?
        .builds
        .iter()
        .map(|b| b.object)
        .collect();
    let scene = player.ctx().scene();
    let mut objects: Vec<Arc<openrt_core::ObjectGeometry>> = Vec::new();
    let mut object_ids = Vec::new();
    let mut inst = Vec::new();
    for i in scene.instances() {
        let k = objects
            .iter()
            .position(|g| Arc::ptr_eq(g, &i.geometry))
            .unwrap_or_else(|| {
                objects.push(Arc::clone(&i.geometry));
                object_ids.push(i.object);
                objects.len() - 1
            });
        inst.push((k, glam::Mat4::from(i.to_world).to_cols_array()));
    }
    let descs: Vec<(&[openrt_accel::Triangle], bool)> = objects
        .iter()
        .zip(&object_ids)
        .map(|(g, id)| (g.tree.triangles(), moving.contains(id)))
        .collect();
    let mut emb = EmbreeTwoLevel::new(&descs, &inst)?;
    let (mut ours_c, mut emb_c, mut ours_r, mut emb_r) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut n_rays = 0;
    for k in 0..o.frames {
        let f = ((k + 1) * player.frames() as usize / (o.frames + 1)) as u32;
        let t = player.time_of(f);
        let c = player.set_time(t).map_err(|e| e.to_string())?;
        ours_c.push(c.total_ms);
        let scene = player.ctx().scene();
        let transforms: Vec<[f32; 16]> = scene
            .instances()
            .iter()
            .map(|i| glam::Mat4::from(i.to_world).to_cols_array())
            .collect();
        let redefined: Vec<(usize, &[openrt_accel::Triangle])> = c
            .builds
            .iter()
            .filter_map(|b| {
                let k = object_ids.iter().position(|id| *id == b.object)?;
                let g = scene.instances().iter().find(|i| i.object == b.object)?;
                Some((k, g.geometry.tree.triangles()))
            })
            .collect();
        let t0 = Instant::now();
        emb.update(&transforms, &redefined)?;
        emb_c.push(t0.elapsed().as_secs_f64() * 1e3);
        let cam = player.camera(t).rays(o.width, o.height).map_err(|e| e.to_string())?;
        let rays: Vec<_> = (0..o.height)
            .flat_map(|y| (0..o.width).map(move |x| (x, y)))
            .map(|(x, y)| cam.ray(x, y))
            .collect();
        n_rays = rays.len();
        let t0 = Instant::now();
        let a = rays.iter().filter(|r| scene.intersect(r).is_some()).count();
        ours_r.push(t0.elapsed().as_secs_f64());
        let t0 = Instant::now();
        let b = rays.iter().filter(|r| emb.intersect(r).is_some()).count();
        emb_r.push(t0.elapsed().as_secs_f64());
        if a.abs_diff(b) * 100 > rays.len() {
            return Err(format!(
                "{name}: OpenRT-rs hits {a} rays, Embree {b}: the scenes differ"
            ));
        }
    }
    let (oc, ec) = (median(ours_c), median(emb_c));
    let (orr, er) = (
        n_rays as f64 / median(ours_r) / 1e6,
        n_rays as f64 / median(emb_r) / 1e6,
    );
    Ok(EmbreeRow {
        scene: name.to_string(),
        ours_commit_ms: oc,
        embree_update_ms: ec,
        ours_mrays: orr,
        embree_mrays: er,
    })
}

/// The machine, as far as the standard library tells: cores and system (the
/// report adds the architecture)
/// (no CPU model: that would take a crate, and the core count is what the
/// figures depend on).
fn machine() -> String {
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    // The processor's name where the system says it (Linux).
    let cpu = std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|s| {
        s.lines()
            .find(|l| l.starts_with("model name"))
            .and_then(|l| l.split_once(':'))
            .map(|(_, v)| format!("{}, ", v.trim()))
    });
    format!("{}{cores} cores, {}", cpu.unwrap_or_default(), std::env::consts::OS)
}

/// Runs every measurement of the bench for `o`.
pub(super) fn all(o: &BenchOptions) -> Result<Results, String> {
    let (mut frames, mut diffs) = (Vec::new(), Vec::new());
    for s in &o.scenes {
        eprintln!("bench: {s}");
        measure_scene(o, s, &Accel::ALL, &mut frames, &mut diffs)?;
    }
    if o.device {
        return Ok(Results {
            frames,
            diffs,
            rebuild_threads: *o.threads.iter().max().unwrap_or(&1),
            lanes: crate::packet_width().lanes(),
            machine: machine(),
            ..Results::default()
        });
    }
    let mut kinds = Vec::new();
    let mut phase_rows = Vec::new();
    for name in &o.scenes {
        eprintln!("bench: ray kinds and phases on {name}");
        kinds.extend(ray_kinds(o, name)?);
        phase_rows.extend(phases(o, name)?);
    }
    let rebuilds = rebuilds(o)?;
    let mut builder_runs = Vec::new();
    for name in o.scenes.iter().filter(|s| s.starts_with("museum")) {
        eprintln!("bench: builders on {name}");
        builder_runs.push(builders(o, name)?);
    }
    // Speed against error: the kitchen and the robots (or the first scene).
    let mut err_scenes: Vec<&String> = o
        .scenes
        .iter()
        .filter(|s| s.as_str() == "kitchen" || s.as_str() == "robots")
        .collect();
    if err_scenes.is_empty() {
        err_scenes.extend(o.scenes.first());
    }
    let mut quality = Vec::new();
    for s in err_scenes {
        eprintln!("bench: speed against error on {s}");
        quality.push(speed_vs_error(o, s)?);
    }
    #[cfg_attr(not(feature = "embree"), allow(unused_mut))]
    let mut embree = Vec::new();
    #[cfg(feature = "embree")]
    for s in o
        .scenes
        .iter()
        .filter(|s| s.as_str() == "kitchen" || s.starts_with("museum"))
    {
        eprintln!("bench: embree on {s}");
        embree.push(embree_side_by_side(o, s)?);
    }
    let deforming = deforming(o)?;
    Ok(Results {
        frames,
        phases: phase_rows,
        deforming,
        diffs,
        kinds,
        quality,
        builders: builder_runs,
        builder_frames: o.frames.max(BUILDER_FRAMES),
        rebuild_threads: *o.threads.iter().max().unwrap_or(&1),
        rebuilds,
        embree,
        lanes: crate::packet_width().lanes(),
        machine: machine(),
    })
}

/// A backend's frames of one mode in the phase table: (frame ms, phases)
/// with the clocks on, frame ms with them off.
type PhaseSamples = (Vec<(f64, openrt_core::PhaseTimes)>, Vec<f64>);

/// The middle frame of `name` split into phases, one thread: each mode
/// through the default backend over kd-trees and over BVHs, single rays,
/// and Embree's packets (builds with `--features embree`). Each is rendered
/// three times with the phase clocks on and three times off, alternating,
/// in rounds that take every backend once (so that the machine's slow
/// phases fall on all alike); the median timed frame's phases are reported.
fn phases(o: &BenchOptions, name: &str) -> Result<Vec<PhaseRow>, String> {
    const ROUNDS: usize = 3;
    let modes = [(RenderMode::GlLike, 0), (RenderMode::Whitted, 3)];
    // A player per structure, committed at the middle frame.
    let mut players = Vec::new();
    for accel in Accel::ALL {
        let mut player = open_player(name, accel)?;
        player.ctx_mut().set_threads(1).map_err(|e| e.to_string())?;
        let t = player.time_of(player.frames() / 2);
        player.set_time(t).map_err(|e| e.to_string())?;
        players.push((accel, player, t));
    }
    // Every (structure, backend, mode) of the table, warmed up (a peer
    // builds its scene on its first frame).
    let mut runs = Vec::new();
    for (p, (accel, player, t)) in players.iter_mut().enumerate() {
        let backends: Vec<Backend> = Backend::ALL
            .iter()
            .copied()
            .filter(|&b| match *accel {
                Accel::Kd => b.name() != "embree",
                Accel::Bvh => b == Backend::Packets,
            })
            .collect();
        let (scene, env, cam) = (player.ctx().scene(), player.env(), player.camera(*t));
        for backend in backends {
            let mut r = crate::new_renderer(player.ctx_mut().pool().map_err(|e| e.to_string())?);
            r.set_backend(backend);
            for (mode, depth) in modes {
                r.render(&scene, &env, &cam, &settings(o, mode, depth))
                    .map_err(|e| e.to_string())?;
            }
            runs.push((p, *accel, backend, r));
        }
    }
    // The timed frames in rounds, every run once a round (the order
    // reversed every other round), so that the machine's slow phases fall
    // on all backends alike; each timed frame beside an untimed one.
    let mut samples: Vec<[PhaseSamples; 2]> = vec![Default::default(); runs.len()];
    for round in 0..ROUNDS {
        for k in 0..runs.len() {
            let i = if round % 2 == 0 { k } else { runs.len() - 1 - k };
            let (p, _, _, r) = &mut runs[i];
            let (_, player, t) = &players[*p];
            let (scene, env, cam) = (player.ctx().scene(), player.env(), player.camera(*t));
            for (m, (mode, depth)) in modes.into_iter().enumerate() {
                let s = settings(o, mode, depth);
                r.set_phase_timing(true);
                let (_, st) = r.render(&scene, &env, &cam, &s).map_err(|e| e.to_string())?;
                samples[i][m].0.push((st.render_ms, st.phases.unwrap_or_default()));
                r.set_phase_timing(false);
                samples[i][m]
                    .1
                    .push(r.render(&scene, &env, &cam, &s).map_err(|e| e.to_string())?.1.render_ms);
            }
        }
    }
    let mut out = Vec::new();
    for ((_, accel, backend, _), mut sample) in runs.iter().zip(samples) {
        for (m, (mode, depth)) in modes.into_iter().enumerate() {
            let s = settings(o, mode, depth);
            let (mut timed, untimed) = std::mem::take(&mut sample[m]);
            timed.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (timed_ms, phases) = timed[timed.len() / 2];
            out.push(PhaseRow {
                scene: name.to_string(),
                mode: mode_name(mode),
                backend: backend.label(*accel),
                timed_ms,
                untimed_ms: median(untimed),
                phases,
                pixels: u64::from(s.width) * u64::from(s.height),
            });
        }
    }
    Ok(out)
}

/// The report's name of a mode.
fn mode_name(mode: RenderMode) -> &'static str {
    match mode {
        RenderMode::GlLike => "GL-like",
        RenderMode::Whitted => "Whitted",
    }
}
