//! Traces camera and random rays through one SAH tree (for profiling): `trace_once [N]`.
use glam::Vec3;
use openrt_accel::{Aabb, KdTree, meshgen};
fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let tris = meshgen::bumpy_sphere(n, 42, 0.5);
    let b = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
    let tree = KdTree::build_sah(tris).unwrap();
    let mut rays = meshgen::camera_rays(Vec3::new(0.5, 0.8, -3.5), Vec3::ZERO, 256, 256, 50.0);
    rays.extend(meshgen::random_rays(65_536, 7, b));
    let t0 = std::time::Instant::now();
    let mut hits = 0;
    for _ in 0..10 {
        hits += rays.iter().filter(|r| tree.intersect(r).is_some()).count();
    }
    let s = t0.elapsed().as_secs_f64();
    println!("{hits} hits, {:.2} Mrays/s", 10.0 * rays.len() as f64 / s / 1e6);
}
