//! Where the kd-tree loses to Embree: the kdtree bench's camera and random
//! rays, split into rays that enter the mesh box and rays that miss it,
//! timed per ray through both (closest hit, passes alternating, best of 5).
//! `cargo run --release -p openrt-accel --features embree --example embree_split -- [N]`
use std::time::Instant;

use glam::Vec3;
use openrt_accel::{Aabb, EmbreeMesh, KdTree, Ray, meshgen};

/// Nanoseconds per ray of one pass of `query` over `rays`, repeated to
/// about a million rays.
fn pass_ns(rays: &[Ray], query: impl Fn(&Ray) -> bool) -> f64 {
    let reps = (1_000_000 / rays.len()).max(1);
    let t = Instant::now();
    let mut hits = 0usize;
    for _ in 0..reps {
        hits += rays.iter().filter(|r| query(r)).count();
    }
    std::hint::black_box(hits);
    t.elapsed().as_secs_f64() * 1e9 / (reps * rays.len()) as f64
}

fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let tris = meshgen::bumpy_sphere(n, 42, 0.5);
    let bounds = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
    let embree = EmbreeMesh::new(&tris, true).expect("Embree device");
    let tree = KdTree::build_sah(tris).expect("kd-tree build");
    let camera = meshgen::camera_rays(Vec3::new(0.5, 0.8, -3.5), Vec3::ZERO, 256, 256, 50.0);
    let random = meshgen::random_rays(65_536, 7, bounds);
    for (kind, rays) in [("camera", camera), ("random", random)] {
        let (enter, miss): (Vec<Ray>, Vec<Ray>) = rays.into_iter().partition(|r| tree.bounds().clip(r).is_some());
        for (set, what) in [(&enter, "enter the box"), (&miss, "miss the box")] {
            if set.is_empty() {
                continue;
            }
            let (mut kd, mut em) = (f64::INFINITY, f64::INFINITY);
            for _ in 0..5 {
                kd = kd.min(pass_ns(set, |r| tree.intersect(r).is_some()));
                em = em.min(pass_ns(set, |r| embree.intersect(r).is_some()));
            }
            println!(
                "{n} triangles, {kind} rays that {what} ({} rays): kd-tree {kd:.1} ns, Embree {em:.1} ns per ray, \
                 ratio {:.2}",
                set.len(),
                em / kd
            );
        }
    }
}
