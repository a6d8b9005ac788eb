//! Builds SAH trees (for profiling): `build_once [N] [binned_above|exact|bvh|bvhsplit|refit|bvhrefit [THREADS]]`;
//! without a mode, the kd-tree's default parameters; `bvh` builds BVHs
//! (one thread) and prints the median of seven builds (`bvhsplit`: pre-split
//! builds, `Bvh::build_presplit`, of a soup of slivers); `refit` refits a
//! fast tree to 200 frames of a smooth motion (one thread) and prints the
//! median refit time; `bvhrefit` refits a BVH to the same motion on a pool
//! of THREADS (default 1).
fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let mode = std::env::args().nth(2).unwrap_or_else(|| "default".into());
    let tris = openrt_accel::meshgen::bumpy_sphere(n, 42, 0.5);
    // A wave along x and a drift along z, as the museum's pieces move.
    let moved = |time: f32| -> Vec<openrt_accel::Triangle> {
        tris.iter()
            .map(|t| t.map(|v| v + glam::Vec3::new(0.05 * (3.0 * v.y + time).sin(), 0.0, 0.02 * time)))
            .collect()
    };
    if mode == "bvhrefit" {
        let threads: usize = std::env::args().nth(3).and_then(|s| s.parse().ok()).unwrap_or(1);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut bvh = openrt_accel::Bvh::build(moved(0.0)).unwrap();
        let mut ms = Vec::new();
        let mut refitted = 0;
        for f in 1..=100 {
            let next = moved(f as f32 * 0.01);
            bvh = pool
                .install(|| openrt_accel::Bvh::refit(&bvh, next, openrt_accel::BVH_REFIT_COST_LIMIT))
                .unwrap();
            ms.push(bvh.stats().build_ms);
            refitted += usize::from(bvh.stats().refitted);
        }
        ms.sort_by(f64::total_cmp);
        println!(
            "bvh refit, {threads} threads: {:.3} ms median, {refitted} / 100 refitted",
            ms[ms.len() / 2]
        );
        return;
    }
    if mode == "refit" {
        let params = openrt_accel::FastParams::default();
        let mut tree = openrt_accel::KdTree::build_fast_with(moved(0.0), &params).unwrap();
        let mut ms = Vec::new();
        let mut refitted = 0;
        for f in 1..=200 {
            let next = moved(f as f32 * 0.01);
            tree = openrt_accel::KdTree::refit_fast(&tree, next, &params).unwrap();
            ms.push(tree.stats().build_ms);
            refitted += usize::from(tree.stats().refitted);
        }
        ms.sort_by(f64::total_cmp);
        println!("refit: {:.3} ms median, {refitted} / 200 refitted", ms[ms.len() / 2]);
        return;
    }
    if mode == "bvh" || mode == "bvhsplit" {
        let tris = if mode == "bvh" {
            openrt_accel::meshgen::bumpy_sphere(n, 42, 0.5)
        } else {
            let b = openrt_accel::Aabb::new(glam::Vec3::splat(-1.0), glam::Vec3::splat(1.0));
            openrt_accel::meshgen::random_soup(n, 42, b, 0.05)
        };
        let build = |t: Vec<openrt_accel::Triangle>| {
            if mode == "bvh" {
                openrt_accel::Bvh::build(t)
            } else {
                openrt_accel::Bvh::build_presplit(t)
            }
            .unwrap()
        };
        let mut ms: Vec<f64> = (0..7).map(|_| build(tris.clone()).stats().build_ms).collect();
        ms.sort_by(f64::total_cmp);
        if mode == "bvhsplit" {
            let mut plain: Vec<f64> = (0..7)
                .map(|_| openrt_accel::Bvh::build(tris.clone()).unwrap().stats().build_ms)
                .collect();
            plain.sort_by(f64::total_cmp);
            println!("the same soup without pre-splitting: {:.2} ms median", plain[3]);
        }
        let bvh = build(tris);
        println!(
            "{mode}: {:.2} ms median ({:.2} Mtris/s), SAH cost {:.3}, {} nodes, {} references added",
            ms[3],
            n as f64 / ms[3] / 1e3,
            bvh.sah_cost(),
            bvh.stats().nodes,
            bvh.stats().presplit
        );
        return;
    }
    let defaults = openrt_accel::SahParams::default();
    let params = openrt_accel::SahParams {
        binned_above: if mode == "default" {
            defaults.binned_above
        } else {
            mode.parse().ok()
        },
        ..defaults
    };
    let tris = openrt_accel::meshgen::bumpy_sphere(n, 42, 0.5);
    for _ in 0..3 {
        let t = openrt_accel::KdTree::build_sah_with(tris.clone(), &params).unwrap();
        println!(
            "{mode}: {:.1} ms, {} nodes, {} refs, SAH cost {:.2}",
            t.stats().build_ms,
            t.stats().nodes,
            t.stats().references,
            t.sah_cost()
        );
    }
}
