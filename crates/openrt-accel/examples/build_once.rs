//! Builds SAH trees (for profiling): `build_once [N] [binned_above|exact]`;
//! without a mode, the default parameters.
fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let mode = std::env::args().nth(2).unwrap_or_else(|| "default".into());
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
