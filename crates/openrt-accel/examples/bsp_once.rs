//! Builds the top-level instance BSP repeatedly (for profiling):
//! `bsp_once [instances] [rounds] [threads]`, boxes laid out as in the
//! commit bench (a crowd of 2x4x2 boxes, every 97th one large).
use std::time::Instant;

use openrt_accel::BspBuilder;

fn main() {
    let arg = |i: usize, d: usize| std::env::args().nth(i).and_then(|s| s.parse().ok()).unwrap_or(d);
    let (n, rounds, threads) = (arg(1, 10_000), arg(2, 200), arg(3, 1));
    let boxes = openrt_accel::meshgen::instance_crowd(n, n as u64);
    let mut builder = BspBuilder::new(threads);
    let mut times: Vec<f64> = (0..rounds)
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(builder.build(&boxes).unwrap());
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let bsp = builder.build(&boxes).unwrap();
    println!(
        "{n} instances, {threads} threads: median {:.3} ms, min {:.3} ms, {} nodes, {} references, depth {}",
        times[times.len() / 2],
        times[0],
        bsp.nodes().len(),
        bsp.references(),
        bsp.depth()
    );
}
