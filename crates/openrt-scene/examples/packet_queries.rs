//! Ray queries alone, in a loop, for profiling (`perf record`): the
//! middle frame of a scene at 640x480, its camera rays in the renderer's
//! pixel blocks of the CPU's packet width (closest hit; `lanes=16` or another
//! width forces one), or the shadow rays from their hits
//! towards each light (`shadow`: any hit, a packet per block and light,
//! each light's last occluder tried first as in a frame), or the mirror
//! bounces of the primary hits on materials with a specular colour
//! (`bounce`: closest hit, packed in the order of their pixels; with
//! `shadow`, the shadow rays of their hits),
//! through the packet queries or one by one (`single`), with the scene's
//! structure under the instances (BVHs unless it says otherwise), or
//! kd-trees (`kd`) or BVHs (`bvh`); no shading. The
//! rays are those of `openrt bench`'s query table. Prints the best pass.
//!
//! `cargo run --release -p openrt-scene --example packet_queries -- scenes/kitchen.ron 5 [shadow|bounce] [single] [kd|bvh] [lanes=N]`
use glam::Vec3;
use openrt_accel::Ray;
use openrt_core::kernels::{OccluderHint, first_hit_shadow_ray, offset_ray_origin};
use openrt_scene::ScenePlayer;
use std::time::Instant;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let width = args
        .iter()
        .find_map(|a| a.strip_prefix("lanes="))
        .map_or_else(openrt_accel::PacketWidth::detect, |v| {
            openrt_accel::PacketWidth::parse(v).expect("lanes=4, 8, 16 or 32")
        });
    match width {
        openrt_accel::PacketWidth::W4 => run::<4>(&args),
        openrt_accel::PacketWidth::W8 => run::<8>(&args),
        openrt_accel::PacketWidth::W16 => run::<16>(&args),
        openrt_accel::PacketWidth::W32 => run::<32>(&args),
    }
}

fn run<const N: usize>(args: &[String]) {
    let path = std::path::PathBuf::from(&args[1]);
    let secs: f64 = args.get(2).map_or(5.0, |s| s.parse().unwrap());
    let single = args.iter().any(|s| s == "single");
    let shadow = args.iter().any(|s| s == "shadow");
    let bounce = args.iter().any(|s| s == "bounce");
    let mut player = ScenePlayer::open(Some(&path)).unwrap();
    for (name, accel) in [("kd", openrt_core::Accel::Kd), ("bvh", openrt_core::Accel::Bvh)] {
        if args.iter().any(|s| s == name) {
            player.set_accel(accel).unwrap();
        }
    }
    let t = player.time_of(player.frames() / 2);
    player.set_time(player.time_of(0)).unwrap();
    player.set_time(t).unwrap();
    let scene = player.ctx().scene();
    let (w, h) = (640u32, 480u32);
    let cam = player.camera(t).rays(w, h).unwrap();
    let (bw, bh) = openrt_core::kernels::packet_block(N);
    let mut primary = Vec::new();
    for by in (0..h).step_by(bh as usize) {
        for bx in (0..w).step_by(bw as usize) {
            for l in 0..N as u32 {
                let (x, y) = (bx + l % bw, by + l / bw);
                primary.push(cam.ray(x.min(w - 1), y.min(h - 1)));
            }
        }
    }
    let lights: Vec<Vec3> = player.env().lights.iter().map(|l| l.position).collect();
    let mut shadows = Vec::new();
    for block in primary.chunks(N) {
        for &light in &lights {
            for r in block {
                shadows.push((first_hit_shadow_ray(&scene, r, light), light));
            }
        }
    }
    let nl = lights.len().max(1);
    let rays: Vec<Ray> = if shadow && !bounce {
        shadows.iter().map(|s| s.0).collect()
    } else if bounce {
        let mut out: Vec<Ray> = primary
            .iter()
            .filter_map(|r| {
                let hit = scene.intersect(r)?;
                let s = scene.surface(r, &hit).ok()?;
                if scene.materials()[s.material.index() as usize].specular == Vec3::ZERO {
                    return None;
                }
                let d = r.dir.normalize();
                let n = if d.dot(s.shading_normal) > 0.0 {
                    -s.shading_normal
                } else {
                    s.shading_normal
                };
                let dir = d - 2.0 * d.dot(n) * n;
                let o = offset_ray_origin(s.point, n, s.error_scale);
                Some(Ray::new(o, dir, 0.0, f32::INFINITY))
            })
            .collect();
        out.truncate(out.len() / N * N);
        println!("{} bounce rays", out.len());
        if shadow {
            // Their hits' shadow rays, a packet per block and light.
            let mut s = Vec::new();
            for block in out.chunks(N) {
                for &light in &lights {
                    s.extend(block.iter().map(|r| first_hit_shadow_ray(&scene, r, light)));
                }
            }
            s
        } else {
            out
        }
    } else {
        primary
    };
    let start = Instant::now();
    let mut passes = 0;
    let mut hits = 0usize;
    let mut best = f64::MAX;
    while start.elapsed().as_secs_f64() < secs {
        let s = Instant::now();
        match (single, shadow) {
            (true, false) => hits += rays.iter().filter(|r| scene.intersect(r).is_some()).count(),
            (true, true) => {
                let mut hints = vec![OccluderHint::new(); nl];
                hits += rays
                    .iter()
                    .enumerate()
                    .filter(|(k, r)| scene.occluded_hinted(r, &mut hints[(k / N) % nl]))
                    .count();
            }
            (false, false) => {
                for c in rays.chunks_exact(N) {
                    let pk: [Ray; N] = std::array::from_fn(|l| c[l]);
                    hits += scene
                        .intersect_packet(&pk, openrt_accel::lanes_mask(N))
                        .iter()
                        .flatten()
                        .count();
                }
            }
            (false, true) => {
                let mut hints = vec![OccluderHint::new(); nl];
                for (k, c) in rays.chunks_exact(N).enumerate() {
                    let pk: [Ray; N] = std::array::from_fn(|l| c[l]);
                    let j = k % nl;
                    hits += scene
                        .occluded_packet_toward_hinted(&pk, openrt_accel::lanes_mask(N), lights[j], &mut hints[j])
                        .count_ones() as usize;
                }
            }
        }
        best = best.min(s.elapsed().as_secs_f64());
        passes += 1;
    }
    println!(
        "passes {passes} hits {hits} best {:.2} ms  {:.2} Mrays/s",
        best * 1e3,
        rays.len() as f64 / best / 1e6
    );
}
