//! Interleaved A/B of the SAH intersection cost: builds one tree per value
//! and alternates trace passes over them, so every tree sees the same
//! machine load; prints the best pass of each.
//! `cargo run --release -p openrt-accel --example ab_ki -- [N] [KI...]`
//! (default 100,000 triangles and KI 0.25 0.15 0.12 0.1 0.08).
use glam::Vec3;
use openrt_accel::{Aabb, KdTree, Ray, SahParams, meshgen};

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let mut kis: Vec<f32> = args.filter_map(|s| s.parse().ok()).collect();
    if kis.is_empty() {
        kis = vec![0.25, 0.15, 0.12, 0.1, 0.08];
    }
    let tris = meshgen::bumpy_sphere(n, 42, 0.5);
    let b = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
    let trees: Vec<KdTree> = kis
        .iter()
        .map(|&ki| {
            let p = SahParams {
                intersection_cost: ki,
                ..SahParams::default()
            };
            KdTree::build_sah_with(tris.clone(), &p).unwrap()
        })
        .collect();
    let cam = meshgen::camera_rays(Vec3::new(0.5, 0.8, -3.5), Vec3::ZERO, 256, 256, 50.0);
    let rnd = meshgen::random_rays(65_536, 7, b);
    for (name, rays) in [("camera", &cam), ("random", &rnd)] {
        let mrays = |f: &dyn Fn(&Ray) -> bool| {
            let t0 = std::time::Instant::now();
            std::hint::black_box(rays.iter().filter(|r| f(r)).count());
            rays.len() as f64 / t0.elapsed().as_secs_f64() / 1e6
        };
        let mut closest = vec![0.0f64; kis.len()];
        let mut occluded = vec![0.0f64; kis.len()];
        for _ in 0..15 {
            for (i, t) in trees.iter().enumerate() {
                closest[i] = closest[i].max(mrays(&|r| t.intersect(r).is_some()));
                occluded[i] = occluded[i].max(mrays(&|r| t.occluded(r)));
            }
        }
        for (i, ki) in kis.iter().enumerate() {
            println!(
                "{name} KI {ki}: closest {:.2} Mrays/s, occluded {:.2} Mrays/s, {} nodes",
                closest[i],
                occluded[i],
                trees[i].stats().nodes
            );
        }
    }
}
