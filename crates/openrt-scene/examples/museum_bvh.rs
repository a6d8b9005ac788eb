//! BVH builds and refits of a museum's moving triangles, in a loop (for
//! profiling and side-by-side timing): the triangles of every other frame
//! are gathered first, then each pass builds them all afresh (`fresh`) or
//! refits frame to frame as a commit does (`refit`) on a pool of THREADS;
//! `kd` and `kdrefit` do the same with the kd-tree's fast builder and its
//! refit. Prints each pass's median and the least median over the passes.
//!
//! `cargo run --release -p openrt-scene --example museum_bvh -- scenes/museum16k.ron THREADS PASSES fresh|refit|kd|kdrefit`
use openrt_accel::{BspBuilder, BuilderKind, Bvh};
use openrt_scene::ScenePlayer;
use std::time::Instant;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = std::path::PathBuf::from(&args[1]);
    let threads: usize = args.get(2).map_or(2, |s| s.parse().unwrap());
    let passes: usize = args.get(3).map_or(1, |s| s.parse().unwrap());
    let refit = args.get(4).is_some_and(|s| s.ends_with("refit"));
    if args.get(4).is_some_and(|s| s.starts_with("kd")) {
        return kd(&path, threads, passes, refit);
    }
    let frames = moving_triangles(&path);
    let pool = BspBuilder::new(threads);
    let mut least = f64::INFINITY;
    for _ in 0..passes {
        let (mut ms, mut refitted, mut cost, mut only) = (Vec::new(), 0, 0.0, Vec::new());
        let mut prev: Option<Bvh> = None;
        for tris in &frames {
            let owned = tris.clone();
            let t0 = Instant::now();
            let bvh = pool
                .install_build(BuilderKind::Fast, tris.len(), || match (&prev, refit) {
                    (Some(p), true) => Bvh::refit(p, owned, openrt_accel::BVH_REFIT_COST_LIMIT),
                    _ => Bvh::build(owned),
                })
                .unwrap();
            ms.push(t0.elapsed().as_secs_f64() * 1e3);
            cost += bvh.sah_cost();
            refitted += usize::from(bvh.stats().refitted);
            if bvh.stats().refitted {
                only.push(ms[ms.len() - 1]);
            }
            prev = Some(bvh);
        }
        ms.sort_by(f64::total_cmp);
        let k = ms.len();
        only.sort_by(f64::total_cmp);
        let only = only.get(only.len() / 2).copied().unwrap_or(f64::NAN);
        least = least.min(if refit { only } else { ms[k / 2] });
        println!(
            "{k} frames of {} triangles: median {:.3} ms (q25 {:.3}, q75 {:.3}), {refitted} refitted (median {only:.3} ms), mean SAH cost {:.3}",
            frames[0].len(),
            ms[k / 2],
            ms[k / 4],
            ms[3 * k / 4],
            cost / k as f64
        );
    }
    println!(
        "least median {least:.3} ms{}",
        if refit { " (refitted frames)" } else { "" }
    );
}

/// The moving triangles of every other frame.
fn moving_triangles(path: &std::path::Path) -> Vec<Vec<openrt_accel::Triangle>> {
    let mut player = ScenePlayer::open(Some(path)).unwrap();
    player.ctx_mut().set_promote_after(None);
    let mut frames = Vec::new();
    for f in (0..player.frames()).step_by(2) {
        let st = player.set_time(player.time_of(f)).unwrap();
        let scene = player.ctx().scene();
        if let Some(t) = st
            .builds
            .iter()
            .filter(|b| b.builder == BuilderKind::Fast)
            .find_map(|b| scene.instances().iter().find(|i| i.object == b.object))
            .map(|i| i.geometry.tree.triangles().to_vec())
        {
            frames.push(t);
        }
    }
    frames
}

/// The same with the kd-tree's fast builder and its refit.
fn kd(path: &std::path::Path, threads: usize, passes: usize, refit: bool) {
    use openrt_accel::{FastParams, KdTree};
    let frames = moving_triangles(path);
    let pool = BspBuilder::new(threads);
    let params = FastParams::default();
    let mut least = f64::INFINITY;
    for _ in 0..passes {
        let (mut ms, mut only, mut refitted, mut cost) = (Vec::new(), Vec::new(), 0, 0.0);
        let mut prev: Option<KdTree> = None;
        for tris in &frames {
            let owned = tris.clone();
            let t0 = Instant::now();
            let tree = pool
                .install_build(BuilderKind::Fast, tris.len(), || match (&prev, refit) {
                    (Some(p), true) => KdTree::refit_fast(p, owned, &params),
                    _ => KdTree::build_fast(owned),
                })
                .unwrap();
            let t = t0.elapsed().as_secs_f64() * 1e3;
            ms.push(t);
            cost += tree.sah_cost();
            if tree.stats().refitted {
                only.push(t);
                refitted += 1;
            }
            prev = Some(tree);
        }
        ms.sort_by(f64::total_cmp);
        only.sort_by(f64::total_cmp);
        let k = ms.len();
        let o = only.get(only.len() / 2).copied().unwrap_or(f64::NAN);
        least = least.min(ms[k / 2]);
        println!(
            "kd: median {:.3} ms (q25 {:.3}, q75 {:.3}), {refitted} refitted (median {o:.3} ms), mean SAH cost {:.3}",
            ms[k / 2],
            ms[k / 4],
            ms[3 * k / 4],
            cost / k as f64
        );
    }
    println!("least median {least:.3} ms");
}
