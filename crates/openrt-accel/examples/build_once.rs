//! Builds one SAH tree (for profiling): `build_once [N]`.
fn main() {
    let n: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(100_000);
    let tris = openrt_accel::meshgen::bumpy_sphere(n, 42, 0.5);
    for _ in 0..3 {
        let t = openrt_accel::KdTree::build_sah(tris.clone()).unwrap();
        println!("{:.1} ms, {} nodes", t.stats().build_ms, t.stats().nodes);
    }
}
