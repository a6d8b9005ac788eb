//! Whitted frames of a scene's moving objects with refitted BVHs against
//! BVHs built afresh, as the bench's builders table measures them: two
//! players take turns frame by frame (each sampled frame committed right
//! after the two before it, so a refit starts from the last frame's tree),
//! 640x480, depth 3; prints the median of the per-frame render-time ratios
//! (refitted / afresh). `single`: single rays (the `kd-single` and
//! `bvh-single` backends).
//!
//! `cargo run --release -p openrt-scene --example refit_frames -- scenes/museum16k.ron FRAMES THREADS [kd] [single]`
use openrt_accel::BuilderKind;
use openrt_core::{Accel, RenderMode, RenderSettings, Renderer};
use openrt_scene::ScenePlayer;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = std::path::PathBuf::from(&args[1]);
    let n: usize = args.get(2).map_or(9, |s| s.parse().unwrap());
    let threads: usize = args.get(3).map_or(1, |s| s.parse().unwrap());
    let accel = if args.iter().any(|s| s == "kd") {
        Accel::Kd
    } else {
        Accel::Bvh
    };
    let single = args.iter().any(|s| s == "single");
    let mut players: Vec<(ScenePlayer, Renderer)> = [true, false]
        .into_iter()
        .map(|refit| {
            let mut p = ScenePlayer::open(Some(&path)).unwrap();
            let ctx = p.ctx_mut();
            ctx.set_accel(accel);
            ctx.set_redefinition_builder(BuilderKind::Fast);
            ctx.set_refit(refit);
            ctx.set_promote_after(None);
            ctx.set_threads(threads).unwrap();
            let mut r = Renderer::with_pool(ctx.pool().unwrap());
            r.set_packet_width(openrt_accel::PacketWidth::detect());
            if single {
                r.set_backend(openrt_core::Backend::Single);
            }
            p.set_time(p.time_of(0)).unwrap();
            (p, r)
        })
        .collect();
    let settings = RenderSettings {
        width: 640,
        height: 480,
        mode: RenderMode::Whitted,
        max_depth: 3,
        ..RenderSettings::default()
    };
    let mut ms = [Vec::new(), Vec::new()];
    for k in 0..n {
        for turn in 0..2 {
            let v = (turn + k) % 2;
            let (player, r) = &mut players[v];
            let f = ((k + 1) * player.frames() as usize / (n + 1)) as u32;
            for g in f.saturating_sub(2)..=f {
                player.set_time(player.time_of(g)).unwrap();
            }
            let t = player.time_of(f);
            let (_, fs) = r
                .render(&player.ctx().scene(), &player.env(), &player.camera(t), &settings)
                .unwrap();
            ms[v].push(fs.render_ms);
        }
    }
    let mut ratios: Vec<f64> = ms[0].iter().zip(&ms[1]).map(|(a, b)| a / b).collect();
    ratios.sort_by(f64::total_cmp);
    println!(
        "{n} frames: refitted / afresh render time, median {:.3} (q25 {:.3}, q75 {:.3})",
        ratios[n / 2],
        ratios[n / 4],
        ratios[3 * n / 4]
    );
}
