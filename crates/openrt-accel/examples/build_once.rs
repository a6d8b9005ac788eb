//! Builds SAH trees (for profiling): `build_once [N] [binned_above|exact|bvh]`;
//! without a mode, the kd-tree's default parameters; `bvh` builds BVHs
//! (one thread) and prints the median of seven builds.
fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let mode = std::env::args().nth(2).unwrap_or_else(|| "default".into());
    if mode == "bvh" {
        let tris = openrt_accel::meshgen::bumpy_sphere(n, 42, 0.5);
        let mut ms: Vec<f64> = (0..7)
            .map(|_| openrt_accel::Bvh::build(tris.clone()).unwrap().stats().build_ms)
            .collect();
        ms.sort_by(f64::total_cmp);
        let bvh = openrt_accel::Bvh::build(tris).unwrap();
        println!(
            "bvh: {:.2} ms median ({:.2} Mtris/s), SAH cost {:.3}, {} nodes",
            ms[3],
            n as f64 / ms[3] / 1e3,
            bvh.sah_cost(),
            bvh.stats().nodes
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
