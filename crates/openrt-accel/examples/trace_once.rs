//! Traces camera and random rays through one SAH tree (for profiling and
//! A/B runs): `trace_once [N] [PASSES]`.
//!
//! Passes of the tree's own closest-hit query (SIMD leaf blocks) alternate
//! with passes of a scalar leaf loop written here on the public API (one
//! `intersect_triangle` per reference, as before the blocks), so both see
//! the same machine noise; the best pass of each is printed.
use glam::Vec3;
use openrt_accel::{Aabb, Hit, KdTree, Ray, intersect_triangle, meshgen, traverse};

/// Closest hit with one scalar triangle test per leaf reference.
fn scalar_intersect(tree: &KdTree, ray: &Ray) -> Option<Hit> {
    let mut closest = ray.t_max;
    let (t0, t1) = tree.bounds().clip(ray)?;
    let tris = tree.triangles();
    let mut best = None;
    traverse(tree.nodes(), ray, t0, t1, &mut closest, |leaf, closest| {
        for &p in tree.leaf_primitives(leaf) {
            if let Some((t, b1, b2)) = intersect_triangle(ray, &tris[p as usize], *closest) {
                *closest = t;
                best = Some(Hit { t, prim: p, b1, b2 });
            }
        }
        false
    });
    best
}

fn main() {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let passes: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(10);
    let tris = meshgen::bumpy_sphere(n, 42, 0.5);
    let b = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
    let t0 = std::time::Instant::now();
    let tree = KdTree::build_sah(tris).unwrap();
    println!("build {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
    let cam = meshgen::camera_rays(Vec3::new(0.5, 0.8, -3.5), Vec3::ZERO, 256, 256, 50.0);
    let rnd = meshgen::random_rays(65_536, 7, b);
    for (name, rays) in [("camera", &cam), ("random", &rnd)] {
        let (mut blocks, mut scalar, mut occluded) = (0.0f64, 0.0f64, 0.0f64);
        let mrays = |f: &dyn Fn(&Ray) -> bool| {
            let t0 = std::time::Instant::now();
            std::hint::black_box(rays.iter().filter(|r| f(r)).count());
            rays.len() as f64 / t0.elapsed().as_secs_f64() / 1e6
        };
        for _ in 0..passes {
            blocks = blocks.max(mrays(&|r| tree.intersect(r).is_some()));
            scalar = scalar.max(mrays(&|r| scalar_intersect(&tree, r).is_some()));
            occluded = occluded.max(mrays(&|r| tree.occluded(r)));
        }
        println!(
            "{name}: closest {blocks:.2} Mrays/s (scalar leaves {scalar:.2}, x{:.2}), occluded {occluded:.2} Mrays/s",
            blocks / scalar
        );
    }
}
