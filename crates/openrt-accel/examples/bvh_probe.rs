//! Times single-ray queries on one mesh with the kd-tree and the BVH, for
//! profiling (`perf record`): `cargo run --release -p openrt-accel
//! --example bvh_probe -- [bvh|kd] [camera|random] [triangles] [passes]`.

use std::hint::black_box;
use std::time::Instant;

use glam::Vec3;
use openrt_accel::{Aabb, Bvh, KdTree, meshgen};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).map_or("bvh", String::as_str);
    let kind = args.get(2).map_or("camera", String::as_str);
    let n: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let passes: usize = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(20);
    let tris = meshgen::bumpy_sphere(n, 42, 0.5);
    let b = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
    let rays = if kind == "random" {
        meshgen::random_rays(65_536, 7, b)
    } else {
        meshgen::camera_rays(Vec3::new(0.5, 0.8, -3.5), Vec3::ZERO, 256, 256, 50.0)
    };
    let kd = (which == "kd").then(|| KdTree::build_sah(tris.clone()).unwrap());
    let bvh = (which == "bvh").then(|| Bvh::build(tris.clone()).unwrap());
    let t = Instant::now();
    let mut hits = 0;
    for _ in 0..passes {
        hits += rays
            .iter()
            .filter(|r| match (&kd, &bvh) {
                (Some(k), _) => k.intersect(r).is_some(),
                (_, Some(b)) => b.intersect(r).is_some(),
                _ => false,
            })
            .count();
    }
    let s = t.elapsed().as_secs_f64();
    println!(
        "{which} {kind}: {:.2} Mrays/s ({} hits)",
        (rays.len() * passes) as f64 / s / 1e6,
        black_box(hits)
    );
}
