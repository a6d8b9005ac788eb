//! Sweeps SAH cost constants: build time, tree size and trace speed.
//! `cargo run --release -p openrt-accel --example sah_sweep`
use std::time::Instant;

use glam::Vec3;
use openrt_accel::{Aabb, KdTree, SahParams, meshgen};

fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let tris = meshgen::bumpy_sphere(n, 42, 0.5);
    let b = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
    let cam = meshgen::camera_rays(Vec3::new(0.5, 0.8, -3.5), Vec3::ZERO, 256, 256, 50.0);
    let rnd = meshgen::random_rays(65_536, 7, b);
    println!(
        "{:>5} {:>5} {:>19} {:>9} {:>9} {:>7} {:>6} {:>9} {:>9}",
        "KT", "KI", "bonus/depth/binned", "build ms", "nodes", "refs/t", "depth", "cam Mr/s", "rnd Mr/s"
    );
    for (kt, ki, bonus, md, binned) in [
        (1.0, 0.5, 0.8, None, Some(16)),
        (1.0, 0.25, 0.8, None, Some(16)),
        (1.0, 0.2, 0.8, None, Some(16)),
        (1.0, 0.15, 0.8, None, Some(16)),
        (1.0, 0.12, 0.8, None, Some(16)),
        (1.0, 0.1, 0.8, None, Some(16)),
        (1.0, 0.08, 0.8, None, Some(16)),
        (1.0, 0.25, 0.8, None, Some(64)),
    ] {
        let p = SahParams {
            traversal_cost: kt,
            intersection_cost: ki,
            empty_bonus: bonus,
            max_depth: md,
            binned_above: binned,
        };
        // Best of three builds and of seven trace passes: the least disturbed.
        let mut build = f64::INFINITY;
        let mut tree = None;
        for _ in 0..3 {
            let t0 = Instant::now();
            tree = Some(KdTree::build_sah_with(tris.clone(), &p).unwrap());
            build = build.min(t0.elapsed().as_secs_f64() * 1e3);
        }
        let tree = tree.unwrap();
        let speed = |rays: &[openrt_accel::Ray]| {
            let t0 = Instant::now();
            let c = rays.iter().filter(|r| tree.intersect(r).is_some()).count();
            std::hint::black_box(c);
            rays.len() as f64 / t0.elapsed().as_secs_f64() / 1e6
        };
        let best = |rays: &[openrt_accel::Ray]| (0..7).map(|_| speed(rays)).fold(0.0, f64::max);
        let (c, r) = (best(&cam), best(&rnd));
        let s = tree.stats();
        println!(
            "{kt:>5} {ki:>5} {:>19} {build:>9.1} {:>9} {:>7.2} {:>6} {c:>9.2} {r:>9.2}",
            format!("{bonus}/{md:?}/{binned:?}"),
            s.nodes,
            s.references as f64 / n as f64,
            s.depth
        );
    }
}
