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
        "{:>5} {:>5} {:>5} {:>9} {:>9} {:>7} {:>6} {:>9} {:>9}",
        "KT", "KI", "bonus", "build ms", "nodes", "refs/t", "depth", "cam Mr/s", "rnd Mr/s"
    );
    for (kt, ki, bonus, md) in [
        (1.0, 1.5, 0.8, None),
        (1.0, 0.5, 0.8, None),
        (1.0, 0.5, 1.0, None),
        (1.0, 0.3, 0.8, None),
        (1.0, 0.5, 0.8, Some(24)),
        (1.0, 0.3, 1.0, Some(24)),
    ] {
        let p = SahParams {
            traversal_cost: kt,
            intersection_cost: ki,
            empty_bonus: bonus,
            max_depth: md,
            ..SahParams::default()
        };
        let t0 = Instant::now();
        let tree = KdTree::build_sah_with(tris.clone(), &p).unwrap();
        let build = t0.elapsed().as_secs_f64() * 1e3;
        let speed = |rays: &[openrt_accel::Ray]| {
            let t0 = Instant::now();
            let c = rays.iter().filter(|r| tree.intersect(r).is_some()).count();
            std::hint::black_box(c);
            rays.len() as f64 / t0.elapsed().as_secs_f64() / 1e6
        };
        let (c, r) = (speed(&cam).max(speed(&cam)), speed(&rnd).max(speed(&rnd)));
        let s = tree.stats();
        println!(
            "{kt:>5} {ki:>5} {bonus:>5}/{md:?} {build:>9.1} {:>9} {:>7.2} {:>6} {c:>9.2} {r:>9.2}",
            s.nodes,
            s.references as f64 / n as f64,
            s.depth
        );
    }
}
