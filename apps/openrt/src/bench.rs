//! `openrt bench`: the paper's frame-rate table on this machine, speed
//! against error, and the component figures, written to docs/BENCHMARKS.md.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use openrt_accel::oracle::BruteForce;
use openrt_accel::{BuilderKind, Hit};
use openrt_accel::{PacketWidth, Ray};
use openrt_core::kernels::{OccluderHint, first_hit_shadow_ray};
use openrt_core::{Accel, Backend, Image, RenderMode, RenderSettings, Renderer, TextureFilter, ThreadPool};
use openrt_scene::ScenePlayer;

/// Options of a benchmark run.
pub struct BenchOptions {
    pub scenes: Vec<String>,
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    pub threads: Vec<usize>,
    pub out: PathBuf,
    pub command: String,
}

/// The paper's figures (Wald, Benthin & Slusallek 2003), fps for 1, 2, 4, 8
/// and 16 rendering clients of 2 CPUs each (2 to 32 CPUs); NaN where the
/// paper gives no figure (the robots: only the ends of the range).
const PAPER: &[(&str, &str, [f64; 5])] = &[
    ("robots", "Whitted", [0.24, f64::NAN, f64::NAN, f64::NAN, 4.0]),
    ("robots", "GL-like", [1.25, f64::NAN, f64::NAN, f64::NAN, 20.0]),
    ("kitchen", "Whitted", [0.25, 0.5, 1.05, 2.0, 4.0]),
    ("kitchen", "GL-like", [1.7, 3.4, 6.8, 13.6, 26.0]),
    ("terrain", "Whitted", [0.3, 0.6, 1.19, 2.29, 4.26]),
    ("museum1k", "Whitted", [0.6, 1.2, 2.4, 4.8, 9.3]),
    ("museum4k", "Whitted", [0.55, 1.1, 2.2, 4.2, 2.5]),
    ("museum16k", "Whitted", [0.45, 0.9, 1.65, 0.98, 0.53]),
];

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Per scene, mode and thread count: the medians over the sampled frames.
struct Row {
    scene: String,
    mode: &'static str,
    backend: &'static str,
    threads: usize,
    commit_ms: f64,
    toplevel_ms: f64,
    fast_ms: f64,
    promotions: usize,
    render_ms: f64,
    rays: f64,
    triangles: usize,
    instances: usize,
}

impl Row {
    fn fps(&self) -> f64 {
        1000.0 / (self.commit_ms + self.render_ms)
    }
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

/// How one backend's image of a frame differs from the `kd` backend's.
struct ImageDiff {
    scene: String,
    mode: &'static str,
    backend: &'static str,
    /// The RGB bytes are identical.
    identical: bool,
    /// Share of pixels with a channel off by more than 8/255.
    off_share: f64,
}

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

/// The name of a backend's rows: with BVHs under the instances, the kd
/// backends' packets and single rays are `bvh` and `bvh-single`.
fn label(accel: Accel, b: Backend) -> &'static str {
    match (accel, b) {
        (Accel::Bvh, Backend::Kd) => "bvh",
        (Accel::Bvh, Backend::KdSingle) => "bvh-single",
        _ => b.name(),
    }
}

/// One scene's frames through every backend of the build, with `accel`
/// under the instances (with BVHs, only the backends that traverse them).
/// `reference`: the `kd` images of the first sampled frame, written by the
/// kd pass and compared with by the BVH pass.
fn measure_scene(
    o: &BenchOptions,
    name: &str,
    accel: Accel,
    rows: &mut Vec<Row>,
    diffs: &mut Vec<ImageDiff>,
    reference: &mut Vec<Image>,
) -> Result<(), String> {
    let mut player = ScenePlayer::open(Some(&scene_path(name))).map_err(|e| e.to_string())?;
    player.ctx_mut().set_accel(accel);
    let n = player.frames();
    // Warm-up: the first commit builds every tree.
    player.set_time(player.time_of(0)).map_err(|e| e.to_string())?;
    let samples: Vec<u32> = (0..o.frames)
        .map(|k| ((k as u64 + 1) * u64::from(n) / (o.frames as u64 + 1)) as u32)
        .collect();
    // One pool per thread count, shared by the commit and a renderer per
    // backend (packets first).
    let pools: Vec<(usize, ThreadPool)> = o
        .threads
        .iter()
        .map(|&t| ThreadPool::new(t).map(|p| (t, p)).map_err(|e| e.to_string()))
        .collect::<Result<_, String>>()?;
    let renderers: Vec<(usize, Renderer)> = pools
        .iter()
        .flat_map(|(t, pool)| {
            Backend::ALL
                .iter()
                .filter(move |&&b| accel == Accel::Kd || matches!(b, Backend::Kd | Backend::KdSingle))
                .map(move |&b| {
                    let mut r = crate::new_renderer(pool.clone());
                    r.set_backend(b);
                    (*t, r)
                })
        })
        .collect();
    // Warm-up: a peer backend builds its own scene on its first frame,
    // as the kd trees were built by the warm-up commit above.
    {
        let scene = player.ctx().scene();
        let tiny = RenderSettings {
            width: 8,
            height: 8,
            ..settings(o, RenderMode::GlLike, 0)
        };
        for (_, r) in &renderers {
            r.render(&scene, &player.env(), &player.camera(player.time_of(0)), &tiny)
                .map_err(|e| e.to_string())?;
        }
    }
    let mut acc: Vec<Acc> = vec![Default::default(); 2 * renderers.len()];
    let mut images: Vec<Image> = vec![Image::default(); 2 * renderers.len()];
    let (mut tri, mut inst) = (0, 0);
    // Commit and render on the same number of threads: each thread count
    // plays the sampled frames with a commit pool of its size.
    for (threads, pool) in &pools {
        let threads = *threads;
        player.ctx_mut().set_pool(pool);
        player.set_time(player.time_of(0)).map_err(|e| e.to_string())?;
        let mut kd_images: Vec<Image> = Vec::new();
        for &f in &samples {
            let t = player.time_of(f);
            let c = player.set_time(t).map_err(|e| e.to_string())?;
            let scene = player.ctx().scene();
            (tri, inst) = (scene.instanced_triangles(), scene.instances().len());
            let cam = player.camera(t);
            let env = player.env();
            for (ri, (_, r)) in renderers.iter().enumerate().filter(|(_, (rt, _))| *rt == threads) {
                for (mi, mode) in [RenderMode::GlLike, RenderMode::Whitted].into_iter().enumerate() {
                    // Each backend and mode renders into its own image, as
                    // `play` and an interactive loop do (the buffer reused).
                    let img = &mut images[2 * ri + mi];
                    let st = r
                        .render_into(&scene, &env, &cam, &settings(o, mode, 3), img)
                        .map_err(|e| e.to_string())?;
                    // The first sampled frame's images on the fewest threads, against kd's.
                    if f == samples[0] && threads == o.threads[0] {
                        let against = if accel == Accel::Kd { &kd_images } else { &*reference };
                        if accel == Accel::Kd && r.backend() == Backend::Kd {
                            kd_images.push(img.clone());
                            reference.push(img.clone());
                        } else if let Some(kd) = against.get(mi) {
                            let (identical, off_share) = image_diff(kd, img);
                            diffs.push(ImageDiff {
                                scene: name.to_string(),
                                mode: ["GL-like", "Whitted"][mi],
                                backend: label(accel, r.backend()),
                                identical,
                                off_share,
                            });
                        }
                    }
                    let a = &mut acc[2 * ri + mi];
                    a.0.push(c.total_ms);
                    a.1.push(c.toplevel_ms);
                    a.2.push(c.build_ms(BuilderKind::Fast));
                    a.3 += c.promotions_swapped.len();
                    a.4.push(st.render_ms);
                    a.5.push(st.rays.total() as f64);
                }
            }
        }
    }
    for (ri, (threads, r)) in renderers.iter().enumerate() {
        for (mi, mode) in ["GL-like", "Whitted"].into_iter().enumerate() {
            let a = acc[2 * ri + mi].clone();
            rows.push(Row {
                scene: name.to_string(),
                mode,
                backend: label(accel, r.backend()),
                threads: *threads,
                commit_ms: median(a.0),
                toplevel_ms: median(a.1),
                fast_ms: median(a.2),
                promotions: a.3,
                render_ms: median(a.4),
                rays: median(a.5),
                triangles: tri,
                instances: inst,
            });
        }
    }
    Ok(())
}

/// One ray kind of a frame: (kind, Mrays/s single, Mrays/s packets, rays).
struct KindRow {
    kind: &'static str,
    single: f64,
    packet: f64,
    /// Embree one by one and in packets (builds with `--features embree`).
    embree: Option<(f64, f64)>,
    /// The same queries with BVHs under the instances: one by one, packets.
    bvh: (f64, f64),
    rays: usize,
}

/// Ray queries alone, one thread, no shading: a frame's primary rays
/// (closest hit) in the renderer's pixel blocks, and the shadow rays from
/// their hits to each light (any hit, with each light's last occluder tried
/// first, as the renderer does), through `Scene::intersect`/`occluded_hinted`
/// one by one and through the packet queries. Medians of 5 passes.
fn ray_kinds(o: &BenchOptions, name: &str) -> Result<Vec<KindRow>, String> {
    let mut player = ScenePlayer::open(Some(&scene_path(name))).map_err(|e| e.to_string())?;
    let t = player.time_of(player.frames() / 2);
    player.set_time(player.time_of(0)).map_err(|e| e.to_string())?;
    player.set_time(t).map_err(|e| e.to_string())?;
    let scene = player.ctx().scene();
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
        };
        let single = time(&mut || single_of(&scene));
        let packet = time(&mut || packet_of(&scene));
        let bvh = (
            n / time(&mut || single_of(&bvh_scene)) / 1e6,
            n / time(&mut || packet_of(&bvh_scene)) / 1e6,
        );
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
            });
            Some((n / one / 1e6, n / pk / 1e6))
        };
        out.push(KindRow {
            kind,
            single: n / single / 1e6,
            packet: n / packet / 1e6,
            embree,
            bvh,
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
fn rmse_psnr(a: &Image, b: &Image) -> (f64, f64) {
    let mut se = 0.0;
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        let d = (p.clamp(Vec3::ZERO, Vec3::ONE) - q.clamp(Vec3::ZERO, Vec3::ONE)).as_dvec3();
        se += d.length_squared() / 3.0;
    }
    let mse = se / a.pixels.len() as f64;
    (mse.sqrt(), if mse > 0.0 { -10.0 * mse.log10() } else { f64::INFINITY })
}

/// Nearest-neighbour upsampling to `w` x `h` (`image::imageops::resize`).
fn upsample(img: &Image, w: u32, h: u32) -> Image {
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

struct Quality {
    scene: String,
    label: String,
    ms: f64,
    rmse: f64,
    psnr: f64,
}

/// Samples per pixel of the speed-against-error reference.
const REFERENCE_SPP: u32 = 64;
/// PSNR that counts as "close to the reference" in the report.
const CLOSE_DB: f64 = 35.0;

fn speed_vs_error(o: &BenchOptions, name: &str, out: &mut String) -> Result<Vec<Quality>, String> {
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
    let _ = writeln!(
        out,
        "\n### {name} (frame {f})\n\nReference: Whitted depth 8, {REFERENCE_SPP} samples per pixel, trilinear textures ({reference_s:.0} s to render). Every row differs from the default (Whitted depth 3, 1 sample per pixel, trilinear) in one setting; lower resolutions are upsampled (nearest) before comparison.\n\n| setting | render ms | RMSE | PSNR dB |\n|---|---:|---:|---:|"
    );
    for x in &q {
        let _ = writeln!(out, "| {} | {:.1} | {:.4} | {:.1} |", x.label, x.ms, x.rmse, x.psnr);
    }
    let cheapest = q
        .iter()
        .filter(|x| x.psnr >= CLOSE_DB)
        .min_by(|a, b| a.ms.total_cmp(&b.ms));
    if let Some(c) = cheapest {
        let _ = writeln!(
            out,
            "\nThe cheapest setting within {CLOSE_DB} dB of the reference: **{}** ({:.1} ms, {:.1} dB).",
            c.label, c.ms, c.psnr
        );
    } else {
        let best = q.iter().max_by(|a, b| a.psnr.total_cmp(&b.psnr));
        let _ = writeln!(
            out,
            "\nNo setting is within {CLOSE_DB} dB of the reference; the closest is {}.",
            best.map_or("-".into(), |b| format!(
                "{} ({:.1} dB, {:.1} ms)",
                b.label, b.psnr, b.ms
            ))
        );
    }
    let row = |l: &str| q.iter().find(|x| x.label.starts_with(l));
    if let (Some(tri), Some(bi)) = (row("Whitted depth 3 (trilinear"), row("depth 3, bilinear")) {
        let (e, c) = (tri.rmse / bi.rmse, tri.ms / bi.ms);
        let goal = if name == "robots" {
            format!(
                " (goal for the robots: error at most x0.5 for at most x1.15: {})",
                if e <= 0.5 && c <= 1.15 { "met" } else { "**not met**" }
            )
        } else {
            String::new()
        };
        let _ = writeln!(
            out,
            "Trilinear against bilinear at 1 sample: error x{e:.2}, frame time x{c:.2}{goal}."
        );
    }
    if let Some((rmse, label, img)) = worst {
        let file = format!("bench-diff-{name}.png");
        let diff: Vec<u8> = img
            .pixels
            .iter()
            .zip(&reference.pixels)
            .flat_map(|(a, b)| {
                let d = (a.clamp(Vec3::ZERO, Vec3::ONE) - b.clamp(Vec3::ZERO, Vec3::ONE)).abs() * 4.0;
                d.to_array().map(|c| (c.min(1.0) * 255.0) as u8)
            })
            .collect();
        let path = o.out.with_file_name(&file);
        match image::save_buffer(&path, &diff, o.width, o.height, image::ColorType::Rgb8) {
            Ok(()) => {
                let _ = writeln!(
                    out,
                    "\nThe worst row, {label} (RMSE {rmse:.4}), against the reference, differences x4:\n\n![{name}: worst row against the reference]({file})"
                );
            }
            Err(e) => {
                let _ = writeln!(out, "\n(difference image not written: {e})");
            }
        }
    }
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
    let _ = writeln!(
        out,
        "\nNumerical error of the accelerated path on {name} (frame {f}): {checked} sampled primary rays checked against the brute-force f64 oracle over {} world-space triangles: **{failed} disagree beyond rounding tolerance ({:.3}%)**; {other_prim} ({:.2}%) report a different first triangle than the exact f64 answer, all within the tolerance (shared edges, coplanar overlaps, grazing hits).",
        world.len(),
        100.0 * failed as f64 / checked.max(1) as f64,
        100.0 * other_prim as f64 / checked.max(1) as f64
    );
    Ok(q)
}

/// Fast (refitted or afresh) vs SAH trees for the moving triangles of
/// `name`: commit and render time per frame. Each sampled frame is committed
/// right after the frame before it, as when the animation plays, so that a
/// refit starts from the last frame's tree. The three players take turns
/// frame by frame (and the first of them changes from frame to frame), so
/// that the machine's slow and fast phases fall on all of them alike; the
/// render ratio is the median of the per-frame ratios. Returns the median
/// over the frames of refitted-tree render time / afresh-tree render time.
/// Returns the median per-frame ratios of Whitted render time with
/// refitted trees to trees built afresh: kd-trees, then BVHs.
fn builders(o: &BenchOptions, name: &str, out: &mut String) -> Result<(f64, f64), String> {
    let _ = writeln!(
        out,
        "\n| moving-object builder | commit ms (median) | Whitted render ms | frame ms |\n|---|---:|---:|---:|"
    );
    let variants = [
        ("fast, refitted (default)", BuilderKind::Fast, true, Accel::Kd),
        ("fast, afresh", BuilderKind::Fast, false, Accel::Kd),
        ("SAH", BuilderKind::Sah, false, Accel::Kd),
        ("BVH, refitted", BuilderKind::Fast, true, Accel::Bvh),
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
    let n = o.frames.max(3);
    let (mut commits, mut renders) = (vec![Vec::new(); variants.len()], vec![Vec::new(); variants.len()]);
    for k in 0..n {
        for turn in 0..variants.len() {
            let v = (turn + k) % variants.len();
            let (player, r) = &mut players[v];
            let f = ((k + 1) * player.frames() as usize / (n + 1)) as u32;
            for g in f.saturating_sub(2)..f {
                player.set_time(player.time_of(g)).map_err(|e| e.to_string())?;
            }
            let t = player.time_of(f);
            let st = player.set_time(t).map_err(|e| e.to_string())?;
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
    let ratios = (ratio(0, 1), ratio(3, 4));
    for ((label, ..), (c, rt)) in variants.iter().zip(commits.into_iter().zip(renders)) {
        let (c, rt) = (median(c), median(rt));
        let _ = writeln!(out, "| {label} | {c:.2} | {rt:.1} | {:.1} |", c + rt);
    }
    Ok(ratios)
}

/// One museum's moving triangles rebuilt three ways on the same frames
/// (every other frame of the animation, in order, so that refits see the
/// motion of a played animation): the fast builder afresh, the fast tree
/// refitted from the last frame's (with its quality check), and with
/// `--features embree` Embree's LOW build; each on `threads` threads.
struct Rebuild {
    scene: String,
    triangles: usize,
    fresh_ms: f64,
    refit_ms: f64,
    refits: usize,
    frames: usize,
    fresh_cost: f64,
    refit_cost: f64,
    embree_ms: Option<f64>,
    /// The BVH: built afresh, refitted (`Bvh::refit`), refitted frames.
    bvh_ms: f64,
    bvh_refit_ms: f64,
    bvh_refits: usize,
}

fn rebuild_figures(name: &str, threads: usize) -> Result<Rebuild, String> {
    use openrt_accel::{BspBuilder, FastParams, KdTree};
    let mut player = ScenePlayer::open(Some(&scene_path(name))).map_err(|e| e.to_string())?;
    player.ctx_mut().set_promote_after(None);
    let pool = BspBuilder::new(threads);
    let params = FastParams::default();
    let (mut fresh, mut refit) = (Vec::new(), Vec::new());
    #[cfg(feature = "embree")]
    let mut emb = Vec::new();
    #[cfg(not(feature = "embree"))]
    let emb: Vec<f64> = Vec::new();
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
            let t0 = Instant::now();
            let m = openrt_accel::EmbreeMesh::new(&tris, false)?;
            emb.push(t0.elapsed().as_secs_f64() * 1e3);
            drop(m);
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
        bvh_ms: median(bvh_fresh),
        bvh_refit_ms: median(bvh_refit),
        bvh_refits,
    })
}

/// The rebuild table of the museums in `o`; returns its rows.
fn rebuilds(o: &BenchOptions, out: &mut String) -> Result<Vec<Rebuild>, String> {
    let threads = *o.threads.iter().max().unwrap_or(&1);
    let names: Vec<&String> = o.scenes.iter().filter(|s| s.starts_with("museum")).collect();
    if names.is_empty() {
        return Ok(Vec::new());
    }
    let _ = writeln!(
        out,
        "\n## Rebuilding the moving triangles ({threads} threads)\n\nEvery other frame of each museum's animation, in order; per frame the moving triangles (handed over as a commit hands them: moved, so their copy is not timed; Embree copies them into its own buffer, timed), each build run where a commit runs it (on the {threads}-thread pool from {} triangles up, below that on the calling thread: `BspBuilder::install_build`), are built afresh by the fast builder, refitted on the last frame's tree (`KdTree::refit_fast`: the old split planes with the new triangles, leaves that overflow split further, rebuilt afresh when the SAH cost exceeds {:.2}x the last full build's; what a commit does by default), and{} built by Embree at LOW quality; medians. SAH cost: expected steps and tests per ray (`KdTree::sah_cost`), mean over the frames. The BVH columns: the same triangles built afresh (`Bvh::build`) and refitted on the last frame's BVH (`Bvh::refit`, rebuilt past {:.2}x the last build's SAH cost); goal: BVH refit <= Embree LOW.\n\n| scene | triangles | fast afresh ms | refit ms | refitted frames | Embree LOW ms | Embree / refit | SAH cost afresh | SAH cost refit | BVH afresh ms | BVH refit ms | BVH refitted frames | Embree LOW / BVH refit | goal |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
        openrt_accel::PARALLEL_MIN,
        openrt_accel::DEFAULT_REFIT_COST_LIMIT,
        if cfg!(feature = "embree") {
            ""
        } else {
            " (with `--features embree`)"
        },
        openrt_accel::BVH_REFIT_COST_LIMIT
    );
    let mut rows = Vec::new();
    for name in names {
        eprintln!("bench: rebuilds on {name}");
        let r = rebuild_figures(name, threads)?;
        let (e, ratio) = match r.embree_ms {
            Some(e) => (format!("{e:.3}"), format!("{:.2}", e / r.refit_ms.max(1e-9))),
            None => ("-".into(), "-".into()),
        };
        let (bvh_ratio, goal) = match r.embree_ms {
            Some(e) => (
                format!("{:.2}", e / r.bvh_refit_ms.max(1e-9)),
                if r.bvh_refit_ms <= e { "met" } else { "**not met**" },
            ),
            None => ("-".into(), "not measured (build without Embree)"),
        };
        let _ = writeln!(
            out,
            "| {} | {} | {:.3} | {:.3} | {} / {} | {e} | {ratio} | {:.2} | {:.2} | {:.3} | {:.3} | {} / {} | {bvh_ratio} | {goal} |",
            r.scene,
            r.triangles,
            r.fresh_ms,
            r.refit_ms,
            r.refits,
            r.frames,
            r.fresh_cost,
            r.refit_cost,
            r.bvh_ms,
            r.bvh_refit_ms,
            r.bvh_refits,
            r.frames
        );
        rows.push(r);
    }
    Ok(rows)
}

/// The same frames and primary rays through an Embree two-level scene:
/// per-frame rebuild time and single-ray throughput, one thread each.
#[cfg(feature = "embree")]
fn embree_side_by_side(o: &BenchOptions, name: &str, out: &mut String) -> Result<(), String> {
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
    let _ = writeln!(
        out,
        "| {name} | {oc:.2} | {ec:.2} | {:.2} | {orr:.2} | {er:.2} | {:.2} |",
        ec / oc.max(1e-9),
        orr / er
    );
    Ok(())
}

/// Registers DejaVu Sans as the plots' "sans-serif" font.
pub(crate) fn register_plot_font() -> Result<(), String> {
    use plotters::prelude::FontStyle;
    let font = ["/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"]
        .iter()
        .find_map(|p| std::fs::read(p).ok())
        .ok_or("no DejaVuSans.ttf for the plot's labels (apt-get install fonts-dejavu-core)")?;
    plotters::style::register_font("sans-serif", FontStyle::Normal, Box::leak(font.into_boxed_slice()))
        .map_err(|_| "cannot load the plot font".to_string())
}

fn plot(path: &Path, q: &[Quality]) -> Result<(), String> {
    use plotters::prelude::*;
    register_plot_font()?;
    let root = SVGBackend::new(path, (720, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let max_ms = q.iter().map(|x| x.ms).fold(1.0, f64::max) * 1.15;
    let max_err = q.iter().map(|x| x.rmse).fold(0.01, f64::max) * 1.15;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "frame time against error (RMSE vs a 64-spp depth-8 reference)",
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..max_ms, 0.0..max_err)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("render time per frame (ms)")
        .y_desc("RMSE")
        .draw()
        .map_err(|e| e.to_string())?;
    chart
        .draw_series(q.iter().map(|x| {
            EmptyElement::at((x.ms, x.rmse))
                + Circle::new((0, 0), 4, BLUE.filled())
                + Text::new(format!("{}: {}", x.scene, x.label), (6, -6), ("sans-serif", 10))
        }))
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}

/// The machine, as far as the standard library tells: cores and system (the
/// report adds the architecture)
/// (no CPU model: that would take a crate, and the core count is what the
/// figures depend on).
fn machine() -> String {
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    format!("{cores} cores, {}", std::env::consts::OS)
}

/// Runs everything and writes the report.
pub fn run(o: &BenchOptions) -> Result<(), String> {
    let start = Instant::now();
    let mut rows = Vec::new();
    let mut diffs = Vec::new();
    for s in &o.scenes {
        eprintln!("bench: {s}");
        let mut reference = Vec::new();
        measure_scene(o, s, Accel::Kd, &mut rows, &mut diffs, &mut reference)?;
        measure_scene(o, s, Accel::Bvh, &mut rows, &mut diffs, &mut reference)?;
    }
    let mut md = String::new();
    let _ = writeln!(
        md,
        "# Benchmarks\n\nGenerated {} by `{}` ({}) on {} ({}); {}x{}, Whitted depth 3, medians over {} frames sampled across each animation. Frame time = commit (top-level rebuild, fast rebuilds, promotions) + render; fps = 1000 / frame time.\n",
        humantime::format_rfc3339_seconds(std::time::SystemTime::now()),
        o.command,
        if cfg!(feature = "embree") {
            "a build with `--features embree`"
        } else {
            "a build without Embree"
        },
        machine(),
        std::env::consts::ARCH,
        o.width,
        o.height,
        o.frames
    );
    let _ = writeln!(
        md,
        "## Frame rates on this machine\n\n| scene | mode | backend | threads | fps | commit ms | top-level ms | fast rebuild ms | promotions | render ms | rays/frame | instances | triangles |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for r in &rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.2} | {:.2} | {:.3} | {:.2} | {} | {:.1} | {:.0} | {} | {} |",
            r.scene,
            r.mode,
            r.backend,
            r.threads,
            r.fps(),
            r.commit_ms,
            r.toplevel_ms,
            r.fast_ms,
            r.promotions,
            r.render_ms,
            r.rays,
            r.instances,
            r.triangles
        );
    }
    let _ = writeln!(
        md,
        "\n## Ray packets against single rays, and against Embree\n\nThe same frames through every backend of this build: `kd` (packets of {} lanes on this CPU), `kd-single`, and with `--features embree` Embree 3 one ray at a time (`embree`: rtcIntersect1/rtcOccluded1) and in packets of the same width (`embree-packet`: rtcIntersect4/8/16, rtcOccluded4/8/16), one Embree scene per object (HIGH quality, LOW for redefined objects) under a top-level scene committed every frame, its build counted in its render time. The kd images are the same bytes (tested in `crates/openrt-scene/tests/backends.rs`); Embree's differ only by its own hits. fps = 1000 / (commit + render). `bvh` and `bvh-single`: the kd backends' packets and single rays with 4-wide BVHs under the instances (`--accel bvh`), the same bytes.\n\n| scene | mode | threads | kd fps | kd-single fps | kd / kd-single | embree fps | embree-packet fps | kd / embree-packet | goal kd >= embree-packet | bvh fps | bvh-single fps | bvh / embree-packet | goal bvh >= embree-packet |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---|",
        crate::packet_width().lanes()
    );
    let find = |r: &Row, b: &str| {
        rows.iter()
            .find(|q| q.backend == b && q.scene == r.scene && q.mode == r.mode && q.threads == r.threads)
            .map(Row::fps)
    };
    for r in rows.iter().filter(|r| r.backend == Backend::Kd.name()) {
        let f = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.2}"));
        let ratio = |v: Option<f64>| v.map_or("-".into(), |v| format!("{:.2}x", r.fps() / v));
        let (single, em, emp) = (find(r, "kd-single"), find(r, "embree"), find(r, "embree-packet"));
        let goal = |fps: Option<f64>| match (fps, emp) {
            (Some(f), Some(e)) if f >= e => "met",
            (Some(_), Some(_)) => "**not met**",
            (None, _) => "not measured",
            (_, None) => "not measured (build without Embree)",
        };
        let verdict = goal(Some(r.fps()));
        let (bvh, bvh_single) = (find(r, "bvh"), find(r, "bvh-single"));
        let bvh_ratio = match (bvh, emp) {
            (Some(b), Some(e)) => format!("{:.2}x", b / e),
            _ => "-".into(),
        };
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2} | {} | {} | {} | {} | {} | {verdict} | {} | {} | {bvh_ratio} | {} |",
            r.scene,
            r.mode,
            r.threads,
            r.fps(),
            f(single),
            ratio(single),
            f(em),
            f(emp),
            ratio(emp),
            f(bvh),
            f(bvh_single),
            goal(bvh),
        );
    }
    let _ = writeln!(
        md,
        "\nImages against the `kd` image of the same frame (first sampled frame of each scene):\n\n| scene | mode | backend | same bytes | pixels off by more than 8/255 |\n|---|---|---|---|---:|"
    );
    for d in &diffs {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.3}% |",
            d.scene,
            d.mode,
            d.backend,
            if d.identical { "yes" } else { "no" },
            100.0 * d.off_share
        );
    }
    let mut kind_rows: Vec<(String, KindRow)> = Vec::new();
    if !o.scenes.is_empty() {
        let lanes = crate::packet_width().lanes();
        let _ = writeln!(
            md,
            "\nRay queries alone, per scene (middle frame, one thread, no shading; medians of 5 passes): primary rays in the renderer's pixel blocks ({lanes} lanes), closest hit; the shadow rays from their hits to each light, any hit (the kd and BVH backends try each light's last occluder first, as in a frame; Embree's any-hit query names no occluder). `bvh-single` and `bvh`: the same queries with 4-wide BVHs under the instances (`--accel bvh`); goal: `bvh` >= `embree-packet`.\n\n| scene | rays | count | kd-single Mrays/s | kd Mrays/s | kd / kd-single | goal 3x | embree Mrays/s | embree-packet Mrays/s | kd / embree-packet | bvh-single Mrays/s | bvh Mrays/s | bvh / embree-packet | goal bvh >= embree-packet |\n|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---|"
        );
        for name in &o.scenes {
            eprintln!("bench: ray kinds on {name}");
            for k in ray_kinds(o, name)? {
                let ratio = k.packet / k.single;
                let verdict = if ratio >= 3.0 { "met" } else { "**not met**" };
                let (em, emp, vs) = k.embree.map_or(("-".into(), "-".into(), "-".into()), |(a, b)| {
                    (format!("{a:.2}"), format!("{b:.2}"), format!("{:.2}x", k.packet / b))
                });
                let (bs, bp) = k.bvh;
                let (bvs, bgoal) = k
                    .embree
                    .map_or(("-".into(), "not measured (build without Embree)"), |(_, b)| {
                        (format!("{:.2}x", bp / b), if bp >= b { "met" } else { "**not met**" })
                    });
                let _ = writeln!(
                    md,
                    "| {name} | {} | {} | {:.2} | {:.2} | {ratio:.2}x | {verdict} | {em} | {emp} | {vs} | {bs:.2} | {bp:.2} | {bvs} | {bgoal} |",
                    k.kind, k.rays, k.single, k.packet
                );
                kind_rows.push((name.clone(), k));
            }
        }
    }
    // The tables below use the default backend.
    let rows: Vec<Row> = rows.into_iter().filter(|r| r.backend == Backend::Kd.name()).collect();
    let _ = writeln!(
        md,
        "\n## Beside the paper (Wald, Benthin & Slusallek 2003)\n\nThe paper's columns count rendering clients of 2 CPUs each: its \"1\" is 2 CPUs and its \"16\" is 32. Per CPU, its single client gave half its frame rate; compare that with one thread here.\n\n| scene | mode | paper, 1 client (2 CPUs) | 2 (4) | 4 (8) | 8 (16) | 16 (32) | paper per CPU | here, 1 thread | here, max threads | scaling |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for (scene, mode, p) in PAPER {
        let here: Vec<&Row> = rows.iter().filter(|r| r.scene == *scene && r.mode == *mode).collect();
        let one = here.iter().find(|r| r.threads == 1).map(|r| r.fps());
        let max = here.iter().max_by_key(|r| r.threads).map(|r| (r.threads, r.fps()));
        let f = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.2}"));
        let scaling = match (one, max) {
            (Some(a), Some((t, b))) if t > 1 => format!("{:.2}x on {t}", b / a),
            _ => "-".into(),
        };
        let paper = |v: f64| if v.is_nan() { "-".to_string() } else { format!("{v}") };
        let _ = writeln!(
            md,
            "| {scene} | {mode} | {} | {} | {} | {} | {} | {:.3} | {} | {} | {scaling} |",
            paper(p[0]),
            paper(p[1]),
            paper(p[2]),
            paper(p[3]),
            paper(p[4]),
            p[0] / 2.0,
            f(one),
            f(max.map(|m| m.1))
        );
    }
    // Thread scaling: every measured thread count, beside the paper's 1..16 CPUs.
    let counts: Vec<usize> = {
        let mut c: Vec<usize> = rows.iter().map(|r| r.threads).collect();
        c.sort_unstable();
        c.dedup();
        c
    };
    if counts.len() > 2 {
        let heads: Vec<String> = counts.iter().map(|t| format!("{t} thr")).collect();
        let _ = writeln!(
            md,
            "\n## Thread scaling (fps; speedup and parallel efficiency against 1 thread)\n\n| scene | mode | {} | speedup | efficiency | paper speedup 1 -> 16 clients (2 -> 32 CPUs) |\n|---|---|{}---:|---:|---:|",
            heads.join(" | "),
            "---:|".repeat(counts.len())
        );
        let mut pairs: Vec<(&str, &str)> = Vec::new();
        for r in &rows {
            if !pairs.contains(&(r.scene.as_str(), r.mode)) {
                pairs.push((r.scene.as_str(), r.mode));
            }
        }
        for (scene, mode) in pairs {
            let at = |t: usize| {
                rows.iter()
                    .find(|r| r.scene == scene && r.mode == mode && r.threads == t)
                    .map(Row::fps)
            };
            let cells: Vec<String> = counts
                .iter()
                .map(|&t| at(t).map_or("-".into(), |v| format!("{v:.2}")))
                .collect();
            let max = *counts.last().unwrap_or(&1);
            let (speedup, eff) = match (at(1), at(max)) {
                (Some(a), Some(b)) if a > 0.0 => {
                    (format!("{:.2}x", b / a), format!("{:.0}%", 100.0 * b / a / max as f64))
                }
                _ => ("-".into(), "-".into()),
            };
            let paper = PAPER
                .iter()
                .find(|(s, m, _)| *s == scene && *m == mode)
                .map_or("-".into(), |(_, _, p)| format!("{:.2}x", p[4] / p[0]));
            let _ = writeln!(
                md,
                "| {scene} | {mode} | {} | {speedup} | {eff} | {paper} |",
                cells.join(" | ")
            );
        }
    }
    // Targets.
    let fps = |s: &str, m: &str| {
        rows.iter()
            .filter(|r| r.scene == s && r.mode == m)
            .max_by_key(|r| r.threads)
            .map(Row::fps)
    };
    let mut rebuild_md = String::new();
    let rebuild_rows = rebuilds(o, &mut rebuild_md)?;
    // Fast (refitted or afresh) and SAH trees for each museum's moving
    // triangles: commit against render.
    let mut builder_md = String::new();
    let mut builder_rows = Vec::new();
    if o.scenes.iter().any(|s| s.starts_with("museum")) {
        let _ = writeln!(
            builder_md,
            "\n## Moving objects: fast, refitted and SAH trees\n\nThe museums' moving triangles under each builder (`Context::set_refit`, `Context::set_redefinition_builder`; the BVH rows with `Context::set_accel`), each sampled frame committed right after the two frames before it, as when the animation plays; same triangles, so the cost moves between commit and render. The builders take turns frame by frame (the first of them changing from frame to frame), so that the machine's phases fall on all of them alike."
        );
    }
    for name in o.scenes.iter().filter(|s| s.starts_with("museum")) {
        eprintln!("bench: builders on {name}");
        let _ = writeln!(builder_md, "\n### {name}");
        builder_rows.push((name.clone(), builders(o, name, &mut builder_md)?));
    }
    let _ = writeln!(md, "\n## Targets (this machine)\n");
    let mut target = |what: &str, got: Option<f64>, goal: f64, unit: &str, higher: bool| {
        let line = match got {
            Some(g) if (higher && g >= goal) || (!higher && g <= goal) => {
                format!("- {what}: {g:.2} {unit} (goal {goal} {unit}): met")
            }
            Some(g) => format!(
                "- {what}: {g:.2} {unit} (goal {goal} {unit}): **not met**, {:.2}x short",
                if higher { goal / g } else { g / goal }
            ),
            None => format!("- {what}: not measured in this run"),
        };
        let _ = writeln!(md, "{line}");
    };
    target("kitchen full Whitted", fps("kitchen", "Whitted"), 4.3, "fps", true);
    target("kitchen GL-like", fps("kitchen", "GL-like"), 26.0, "fps", true);
    let m16 = rows.iter().find(|r| r.scene == "museum16k").map(|r| r.fast_ms);
    target("museum 16k rebuild", m16, 2.0, "ms", false);
    for r in &rebuild_rows {
        target(
            &format!(
                "{} moving triangles, Embree LOW build time / our refit time (rebuild table)",
                r.scene
            ),
            r.embree_ms.map(|e| e / r.refit_ms.max(1e-9)),
            1.0,
            "x",
            true,
        );
    }
    for (name, (kd, bvh)) in &builder_rows {
        for (what, ratio) in [("kd-trees", kd), ("BVHs", bvh)] {
            target(
                &format!(
                    "{name} Whitted render with refitted {what} / with {what} built afresh (builders table, median of the per-frame ratios)"
                ),
                Some(*ratio),
                1.05,
                "x",
                false,
            );
        }
    }
    let scal = rows
        .iter()
        .filter(|r| r.scene == "kitchen" && r.mode == "Whitted")
        .fold((None, None), |(a, b), r| {
            if r.threads == 1 {
                (Some(r.render_ms), b)
            } else if r.threads == 2 {
                (a, Some(r.render_ms))
            } else {
                (a, b)
            }
        });
    target(
        "render thread scaling 1 -> 2 (kitchen Whitted)",
        scal.0.zip(scal.1).map(|(a, b)| a / b),
        1.9,
        "x",
        true,
    );
    // Packets against single rays, per ray kind over the scenes.
    for kind in ["primary", "shadow"] {
        let of_kind: Vec<(&String, f64)> = kind_rows
            .iter()
            .filter(|(_, k)| k.kind == kind)
            .map(|(n, k)| (n, k.packet / k.single))
            .collect();
        if of_kind.is_empty() {
            continue;
        }
        let met: Vec<&str> = of_kind
            .iter()
            .filter(|(_, r)| *r >= 3.0)
            .map(|(n, _)| n.as_str())
            .collect();
        let lo = of_kind.iter().map(|(_, r)| *r).fold(f64::INFINITY, f64::min);
        let hi = of_kind.iter().map(|(_, r)| *r).fold(0.0, f64::max);
        let verdict = if met.len() == of_kind.len() {
            "met on every scene".to_string()
        } else if met.is_empty() {
            "**not met** on any scene".to_string()
        } else {
            format!(
                "**not met** on {} of {} scenes (met on {})",
                of_kind.len() - met.len(),
                of_kind.len(),
                met.join(", ")
            )
        };
        let _ = writeln!(
            md,
            "- {kind} rays in packets against single rays (ray queries table): {lo:.2}-{hi:.2}x over {} scenes (goal 3 x): {verdict}",
            of_kind.len()
        );
    }
    let _ = writeln!(
        md,
        "- ray throughput against Embree: single mesh in docs/PERFORMANCE.md (`cargo bench -p openrt-accel --bench kdtree --features embree`, which measures it); two-level scenes in the side-by-side table below."
    );

    // Speed against error: the kitchen and the robots (or the first scene).
    let mut err_scenes: Vec<String> = o
        .scenes
        .iter()
        .filter(|s| s.as_str() == "kitchen" || s.as_str() == "robots")
        .cloned()
        .collect();
    if err_scenes.is_empty() {
        err_scenes.extend(o.scenes.first().cloned());
    }
    let _ = writeln!(md, "\n## Speed against error (middle frame, {}x{})", o.width, o.height);
    let mut q = Vec::new();
    for s in &err_scenes {
        eprintln!("bench: speed against error on {s}");
        q.extend(speed_vs_error(o, s, &mut md)?);
    }
    md.push_str(&builder_md);
    md.push_str(&rebuild_md);
    #[cfg(feature = "embree")]
    {
        let _ = writeln!(
            md,
            "\n## Side by side with Embree 3 (two-level, single rays, 1 thread)\n\nSame frames, same primary rays; Embree: one scene per object (HIGH quality, LOW for objects rebuilt every frame) instanced in a top-level scene updated per frame.\n\n| scene | OpenRT-rs commit ms | Embree update ms | commit ratio (Embree/ours) | OpenRT-rs Mrays/s | Embree Mrays/s | throughput ratio (ours/Embree) |\n|---|---:|---:|---:|---:|---:|---:|"
        );
        for s in o
            .scenes
            .iter()
            .filter(|s| s.as_str() == "kitchen" || s.starts_with("museum"))
        {
            eprintln!("bench: embree on {s}");
            embree_side_by_side(o, s, &mut md)?;
        }
    }
    let svg = o.out.with_file_name("bench-speed-error.svg");
    match plot(&svg, &q) {
        Ok(()) => {
            let _ = writeln!(md, "\n![frame time against error](bench-speed-error.svg)");
        }
        Err(e) => {
            let _ = writeln!(md, "\n(plot not written: {e})");
        }
    }
    let _ = writeln!(md, "\nThe whole run took {:.0} s.", start.elapsed().as_secs_f64());
    std::fs::write(&o.out, md).map_err(|e| format!("{}: {e}", o.out.display()))?;
    eprintln!("bench: wrote {} and {}", o.out.display(), svg.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_metrics_and_upsampling() {
        let a = Image {
            width: 2,
            height: 1,
            pixels: vec![Vec3::ZERO, Vec3::ONE],
        };
        assert_eq!(rmse_psnr(&a, &a).0, 0.0);
        let b = Image {
            width: 2,
            height: 1,
            pixels: vec![Vec3::ONE, Vec3::ONE],
        };
        let (rmse, psnr) = rmse_psnr(&a, &b);
        assert!((rmse - 0.5f64.sqrt()).abs() < 1e-9 && (psnr - 3.0103).abs() < 1e-3);
        let u = upsample(&a, 4, 2);
        assert_eq!(
            u.pixels,
            vec![
                Vec3::ZERO,
                Vec3::ZERO,
                Vec3::ONE,
                Vec3::ONE,
                Vec3::ZERO,
                Vec3::ZERO,
                Vec3::ONE,
                Vec3::ONE
            ]
        );
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
    }
}
