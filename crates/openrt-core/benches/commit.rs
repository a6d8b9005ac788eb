//! Commit costs of the two-level method.
//!
//! - top-level BSP rebuild for 100, 1k, 10k, 100k instances (goal: 10k < 1 ms);
//! - whole commits of 10k instances: every instance moved, and none (the
//!   top level is then kept);
//! - fast vs SAH object build for 1k/4k/16k/64k moving triangles, with the
//!   trace speed each tree gives (the paper's trade-off for unstructured motion).
//!
//! `cargo bench -p openrt-core --bench commit`; a summary table of medians
//! from the same run follows criterion's output.

use std::hint::black_box;
use std::time::Instant;

use criterion::{BenchmarkId, Criterion, Throughput};
use glam::Vec3;
use openrt_accel::{Aabb, BspBuilder, BuilderKind, KdTree, Triangle, meshgen};

/// Triangles of an animart-like object: `n` small triangles spread in a box.
fn moving_triangles(n: usize) -> Vec<Triangle> {
    let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
    meshgen::random_soup(n, n as u64, b, 0.6 / (n as f32).cbrt())
}

fn median(reps: usize, mut f: impl FnMut()) -> f64 {
    let mut v: Vec<f64> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect();
    v.sort_by(f64::total_cmp);
    v[reps / 2]
}

fn bench_toplevel(c: &mut Criterion) {
    let mut g = c.benchmark_group("toplevel_rebuild");
    for n in [100, 1_000, 10_000, 100_000] {
        let boxes = meshgen::instance_crowd(n, n as u64);
        g.throughput(Throughput::Elements(n as u64));
        let mut builder = BspBuilder::default();
        g.bench_with_input(BenchmarkId::from_parameter(n), &boxes, |b, boxes| {
            b.iter(|| builder.build(black_box(boxes)).unwrap());
        });
    }
    g.finish();
}

fn bench_object_builders(c: &mut Criterion) {
    let mut g = c.benchmark_group("object_build");
    g.sample_size(10);
    for n in [1_024, 4_096, 16_384, 65_536] {
        let tris = moving_triangles(n);
        g.throughput(Throughput::Elements(n as u64));
        for kind in [BuilderKind::Fast, BuilderKind::Sah] {
            g.bench_with_input(BenchmarkId::new(format!("{kind:?}"), n), &tris, |b, t| {
                b.iter(|| KdTree::build(black_box(t.clone()), kind).unwrap());
            });
        }
    }
    g.finish();
}

fn summary() {
    println!("\nsummary (medians of this run)");
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    println!(
        "{:>9} {:>14} {:>14} {:>8} {:>8} {:>10}",
        "instances",
        "1 thread ms",
        format!("{cores} threads ms"),
        "speedup",
        "nodes",
        "refs/inst"
    );
    for n in [100, 1_000, 10_000, 100_000] {
        let boxes = meshgen::instance_crowd(n, n as u64);
        // Interleaved: one build with each builder per round (noisy machine).
        let (mut one, mut all) = (BspBuilder::new(1), BspBuilder::new(cores));
        let (mut t1, mut tn) = (Vec::new(), Vec::new());
        let mut bsp = None;
        for _ in 0..15 {
            t1.push(median(1, || bsp = Some(one.build(&boxes).unwrap())));
            tn.push(median(1, || bsp = Some(all.build(&boxes).unwrap())));
        }
        let med = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (s1, sn) = (med(t1), med(tn));
        let bsp = bsp.unwrap();
        println!(
            "{n:>9} {:>14.3} {:>14.3} {:>8.2} {:>8} {:>10.2}",
            s1 * 1e3,
            sn * 1e3,
            s1 / sn,
            bsp.nodes().len(),
            bsp.references() as f64 / n as f64
        );
    }
    commit_summary(openrt_core::TopLevel::Bsp);
    commit_summary(openrt_core::TopLevel::Bvh);
    println!(
        "\n{:>7} {:>6} {:>9} {:>9} {:>7} {:>10}",
        "tris", "build", "ms", "Mtris/s", "depth", "trace Mr/s"
    );
    let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
    let rays = meshgen::random_rays(50_000, 3, b);
    for n in [1_024, 4_096, 16_384, 65_536] {
        let tris = moving_triangles(n);
        for kind in [BuilderKind::Fast, BuilderKind::Sah] {
            let mut tree = None;
            let s = median(7, || tree = Some(KdTree::build(tris.clone(), kind).unwrap()));
            let tree = tree.unwrap();
            let tr = median(5, || {
                black_box(rays.iter().filter(|r| tree.intersect(r).is_some()).count());
            });
            println!(
                "{n:>7} {:>6} {:>9.2} {:>9.2} {:>7} {:>10.2}",
                format!("{kind:?}"),
                s * 1e3,
                n as f64 / s / 1e6,
                tree.stats().depth,
                rays.len() as f64 / tr / 1e6
            );
        }
    }
}

/// Whole commits of a 10k-instance crowd (one small object) under the
/// `level` top level: all moved versus none moved, interleaved, medians of 15.
fn commit_summary(level: openrt_core::TopLevel) {
    use openrt_core::{Context, PrimitiveKind};
    let n = 10_000;
    let mut ctx = Context::new();
    ctx.set_top_level(level);
    let obj = ctx.gen_object();
    ctx.begin_object(obj).unwrap();
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    for t in meshgen::bumpy_sphere(64, 1, 0.2) {
        for v in t {
            ctx.vertex(v).unwrap();
        }
    }
    ctx.end().unwrap();
    ctx.end_object().unwrap();
    let centres: Vec<Vec3> = meshgen::instance_crowd(n, n as u64).iter().map(Aabb::center).collect();
    let ids: Vec<_> = centres
        .iter()
        .map(|&c| {
            ctx.load_identity();
            ctx.translate(c).unwrap();
            ctx.instantiate(obj).unwrap()
        })
        .collect();
    ctx.commit().unwrap();
    let (mut moved, mut still, mut top) = (Vec::new(), Vec::new(), Vec::new());
    for frame in 0..15 {
        for (&id, &c) in ids.iter().zip(&centres) {
            let offset = Vec3::new(0.0, 0.01 * (frame + 1) as f32, 0.0);
            ctx.set_instance_transform(id, glam::Mat4::from_translation(c + offset))
                .unwrap();
        }
        let s = ctx.commit().unwrap();
        assert!(!s.toplevel_reused);
        moved.push(s.total_ms);
        top.push(s.toplevel_ms);
        let s = ctx.commit().unwrap();
        assert!(s.toplevel_reused);
        still.push(s.total_ms);
    }
    let med = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "\ncommit of {n} instances, {} top level: all moved {:.3} ms (top level {:.3} ms), none moved {:.3} ms (top level kept)",
        level.name(),
        med(moved),
        med(top),
        med(still)
    );
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    bench_toplevel(&mut c);
    bench_object_builders(&mut c);
    c.final_summary();
    summary();
}
