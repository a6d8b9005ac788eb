//! Build and traversal throughput of the SAH kd-tree, optionally beside Embree 3.
//!
//! `cargo bench -p openrt-accel --bench kdtree` (add `--features embree` for
//! the peer). Set `OPENRT_BENCH_SIZES=10000,100000` to pick mesh sizes.
//! After criterion's figures it prints a summary table of medians measured
//! in the same run, with the kd-tree/Embree ratios.

use std::hint::black_box;
use std::time::Instant;

use criterion::{BenchmarkId, Criterion, Throughput};
use glam::Vec3;
use openrt_accel::oracle::BruteForce;
use openrt_accel::{Aabb, Bvh, Hit, KdTree, Ray, Triangle, meshgen};

fn sizes() -> Vec<usize> {
    std::env::var("OPENRT_BENCH_SIZES").ok().map_or_else(
        || vec![10_000, 100_000, 1_000_000],
        |s| s.split(',').filter_map(|x| x.trim().parse().ok()).collect(),
    )
}

fn mesh(n: usize) -> Vec<Triangle> {
    meshgen::bumpy_sphere(n, 42, 0.5)
}

fn ray_sets(tris: &[Triangle]) -> [(&'static str, Vec<Ray>); 2] {
    let b = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
    [
        (
            "camera",
            meshgen::camera_rays(Vec3::new(0.5, 0.8, -3.5), Vec3::ZERO, 256, 256, 50.0),
        ),
        ("random", meshgen::random_rays(65_536, 7, b)),
    ]
}

fn median_secs(reps: usize, mut f: impl FnMut()) -> f64 {
    let mut v: Vec<f64> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect();
    median(&mut v)
}

/// Seconds for one pass of `query` over `rays` (hits counted so nothing is optimised away).
fn pass_secs(rays: &[Ray], query: impl Fn(&Ray) -> bool) -> f64 {
    let t = Instant::now();
    black_box(rays.iter().filter(|r| query(r)).count());
    t.elapsed().as_secs_f64()
}

/// Seconds of one pass of the closest-hit (`closest`) or the any-hit query.
fn query_secs(rays: &[Ray], closest: bool, hit: impl Fn(&Ray) -> bool, any: impl Fn(&Ray) -> bool) -> f64 {
    if closest {
        pass_secs(rays, hit)
    } else {
        pass_secs(rays, any)
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn bench_build(c: &mut Criterion) {
    let mut g = c.benchmark_group("build_sah");
    g.sample_size(10);
    for n in sizes() {
        let tris = mesh(n);
        g.throughput(Throughput::Elements(tris.len() as u64));
        g.bench_with_input(BenchmarkId::from_parameter(n), &tris, |b, t| {
            b.iter(|| KdTree::build_sah(black_box(t.clone())).unwrap());
        });
    }
    g.finish();
}

fn bench_trace(c: &mut Criterion) {
    for n in sizes() {
        let tris = mesh(n);
        let tree = KdTree::build_sah(tris.clone()).unwrap();
        #[cfg(feature = "embree")]
        let emb = openrt_accel::EmbreeMesh::new(&tris, true).unwrap();
        let mut g = c.benchmark_group(format!("trace_{n}"));
        g.sample_size(10);
        for (kind, rays) in ray_sets(&tris) {
            g.throughput(Throughput::Elements(rays.len() as u64));
            g.bench_function(format!("kd_closest_{kind}"), |b| {
                b.iter(|| rays.iter().filter(|r| tree.intersect(r).is_some()).count());
            });
            g.bench_function(format!("kd_occluded_{kind}"), |b| {
                b.iter(|| rays.iter().filter(|r| tree.occluded(r)).count());
            });
            #[cfg(feature = "embree")]
            {
                g.bench_function(format!("embree_closest_{kind}"), |b| {
                    b.iter(|| rays.iter().filter(|r| emb.intersect(r).is_some()).count());
                });
                g.bench_function(format!("embree_occluded_{kind}"), |b| {
                    b.iter(|| rays.iter().filter(|r| emb.occluded(r)).count());
                });
            }
        }
        g.finish();
    }
}

/// Closest hits that disagree with the f64 oracle (`BruteForce::check_closest`)
/// among a sample of the bench's random rays and of `meshgen::hard_rays`
/// (aimed at vertices and edges), for each intersector: `(random, hard)`.
fn oracle_errors(tris: &[Triangle], random: &[Ray], query: impl Fn(&Ray) -> Option<Hit>) -> (usize, usize) {
    // NOTE: the oracle tests every triangle in f64; the sample keeps it to
    // about 2e8 triangle tests per set.
    let n = (200_000_000 / tris.len().max(1)).clamp(200, 2_000);
    let oracle = BruteForce::new(tris);
    let errors = |rays: &[Ray]| {
        rays.iter()
            .filter(|r| oracle.check_closest(r, query(r)).is_err())
            .count()
    };
    let step = (random.len() / n).max(1);
    let sample: Vec<Ray> = random.iter().step_by(step).copied().collect();
    (errors(&sample), errors(&meshgen::hard_rays(tris, n, 3)))
}

/// One table of medians from this run (7 repetitions each).
fn summary() {
    println!("\nsummary (median of 7, this run; ratio: median of 7 paired, interleaved passes;");
    println!("robust: against Embree with its ROBUST scene flag, watertight as the kd-tree is)");
    println!(
        "{:>9} {:>12} {:>8} {:>10} {:>10} {:>10} {:>7} {:>7} {:>10} {:>7} {:>7}",
        "tris", "build Mt/s", "rays", "query", "kd Mr/s", "embree", "ratio", "robust", "bvh Mr/s", "bvh/kd", "bvh/emb"
    );
    for n in sizes() {
        let tris = mesh(n);
        let reps = if n >= 1_000_000 { 3 } else { 7 };
        let mut tree = None;
        let s = median_secs(reps, || tree = Some(KdTree::build_sah(tris.clone()).unwrap()));
        let tree = tree.unwrap();
        let build = tris.len() as f64 / s / 1e6;
        let mut bvh = None;
        let bs = median_secs(reps, || bvh = Some(Bvh::build(tris.clone()).unwrap()));
        let bvh = bvh.unwrap();
        #[cfg(feature = "embree")]
        let embree_build = {
            let mut v: Vec<f64> = (0..reps)
                .map(|_| openrt_accel::embree_medium_build_secs(&tris).unwrap())
                .collect();
            format!("{:.2}", tris.len() as f64 / median(&mut v) / 1e6)
        };
        #[cfg(not(feature = "embree"))]
        let embree_build = "-".to_string();
        println!(
            "{:>9} build Mt/s, one thread: kd SAH {build:.2}, BVH {:.2}, Embree MEDIUM {embree_build} (goal: BVH >= Embree MEDIUM)",
            tris.len(),
            tris.len() as f64 / bs / 1e6
        );
        #[cfg(feature = "embree")]
        let emb = openrt_accel::EmbreeMesh::new(&tris, true).unwrap();
        #[cfg(feature = "embree")]
        let robust = openrt_accel::EmbreeMesh::with_flags(&tris, true, true).unwrap();
        let sets = ray_sets(&tris);
        for (kind, rays) in &sets {
            for query in ["closest", "occluded"] {
                let closest = query == "closest";
                // NOTE: kd and Embree passes alternate, and the ratio is the
                // median of the seven paired ratios: both sides of a pair see
                // the same machine load (this machine is shared and noisy).
                let (mut kd, mut peer, mut ratios, mut robust_ratios) =
                    (Vec::new(), Vec::new(), Vec::new(), Vec::new());
                let (mut wide, mut wide_kd, mut wide_peer) = (Vec::new(), Vec::new(), Vec::new());
                // NOTE: round 0 is a warm-up, not recorded: the first pass
                // after a build ran up to 20% slower (cold caches, and
                // Embree's build threads still winding down beside it).
                for round in 0..8 {
                    let k = query_secs(rays, closest, |r| tree.intersect(r).is_some(), |r| tree.occluded(r));
                    let b = query_secs(rays, closest, |r| bvh.intersect(r).is_some(), |r| bvh.occluded(r));
                    if round > 0 {
                        kd.push(k);
                        wide.push(b);
                        wide_kd.push(k / b);
                    }
                    #[cfg(feature = "embree")]
                    {
                        let e = query_secs(rays, closest, |r| emb.intersect(r).is_some(), |r| emb.occluded(r));
                        let er = query_secs(rays, closest, |r| robust.intersect(r).is_some(), |r| robust.occluded(r));
                        if round > 0 {
                            peer.push(e);
                            ratios.push(e / k);
                            wide_peer.push(e / b);
                            robust_ratios.push(er / k);
                        }
                    }
                }
                let kd_mrays = rays.len() as f64 / median(&mut kd) / 1e6;
                let (emb_s, ratio, robust_ratio) = if peer.is_empty() {
                    ("-".to_string(), "-".to_string(), "-".to_string())
                } else {
                    let e_mrays = rays.len() as f64 / median(&mut peer) / 1e6;
                    (
                        format!("{e_mrays:.2}"),
                        format!("{:.2}", median(&mut ratios)),
                        format!("{:.2}", median(&mut robust_ratios)),
                    )
                };
                let bvh_mrays = rays.len() as f64 / median(&mut wide) / 1e6;
                let bvh_kd = median(&mut wide_kd);
                let bvh_emb = if wide_peer.is_empty() {
                    "-".to_string()
                } else {
                    format!("{:.2}", median(&mut wide_peer))
                };
                println!(
                    "{:>9} {build:>12.2} {kind:>8} {query:>10} {kd_mrays:>10.2} {emb_s:>10} {ratio:>7} {robust_ratio:>7} {bvh_mrays:>10.2} {bvh_kd:>7.2} {bvh_emb:>7}",
                    tris.len()
                );
            }
        }
        let random = &sets[1].1;
        let (kd_r, kd_h) = oracle_errors(&tris, random, |r| tree.intersect(r));
        let (bvh_r, bvh_h) = oracle_errors(&tris, random, |r| bvh.intersect(r));
        #[cfg(feature = "embree")]
        let peers = [("Embree", &emb), ("Embree robust", &robust)]
            .map(|(name, peer)| {
                let (r, h) = oracle_errors(&tris, random, |ray| peer.intersect_hit(ray));
                format!(", {name} {r} + {h}")
            })
            .concat();
        #[cfg(not(feature = "embree"))]
        let peers = String::new();
        println!(
            "          closest hits off the f64 oracle (random + hard rays sampled): kd-tree {kd_r} + {kd_h}, BVH {bvh_r} + {bvh_h}{peers}"
        );
        let st = tree.stats();
        println!(
            "          tree: {} nodes, {} leaves ({} empty), {} refs ({:.2}/tri), depth {}, {:.1} MiB",
            st.nodes,
            st.leaves,
            st.empty_leaves,
            st.references,
            st.references as f64 / tris.len() as f64,
            st.depth,
            st.bytes as f64 / (1024.0 * 1024.0)
        );
    }
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    bench_build(&mut c);
    bench_trace(&mut c);
    c.final_summary();
    summary();
}
