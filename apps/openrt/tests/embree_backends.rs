//! The Embree backends of the renderer (build with `--features embree`):
//! the same frames as the `kd` backend up to Embree's own hit differences,
//! and Embree's packet backend equal to its single-ray backend.
//!
//! `cargo test -p openrt --features embree --test embree_backends`
#![cfg(feature = "embree")]

use std::path::Path;

use openrt_core::{Backend, RenderMode, RenderSettings, Renderer};
use openrt_scene::ScenePlayer;

fn render(player: &ScenePlayer, t: f32, mode: RenderMode, r: &Renderer) -> Vec<u8> {
    let s = RenderSettings {
        width: 120,
        height: 90,
        mode,
        max_depth: 3,
        ..RenderSettings::default()
    };
    let (img, _) = r
        .render(&player.ctx().scene(), &player.env(), &player.camera(t), &s)
        .unwrap();
    img.to_rgb8()
}

/// Share of pixels with a channel off by more than 8/255.
fn off_share(a: &[u8], b: &[u8]) -> f64 {
    let off = a
        .chunks(3)
        .zip(b.chunks(3))
        .filter(|(p, q)| p.iter().zip(*q).any(|(x, y)| x.abs_diff(*y) > 8))
        .count();
    off as f64 / (a.len() / 3) as f64
}

#[test]
fn embree_frames_match_the_kd_frames() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    for name in ["room", "slab", "textured", "animated"] {
        let mut p = ScenePlayer::open(Some(&repo.join(format!("scenes/{name}.ron")))).unwrap();
        // One pool per backend for both frames, as an application keeps it.
        let [kd_r, one_r, packet_r] = [Backend::Packets, Backend::Embree, Backend::EmbreePacket].map(|b| {
            let mut r = Renderer::new(2).expect("a render pool");
            r.set_backend(b);
            r
        });
        // Two frames: the second updates the Embree scene instead of building it.
        for f in [0, p.frames() / 2] {
            let t = p.time_of(f);
            p.set_time(t).unwrap();
            for mode in [RenderMode::GlLike, RenderMode::Whitted] {
                let kd = render(&p, t, mode, &kd_r);
                let one = render(&p, t, mode, &one_r);
                let packet = render(&p, t, mode, &packet_r);
                let share = off_share(&kd, &one);
                assert!(
                    share < 0.01,
                    "{name} frame {f} {mode:?}: {share} of pixels differ from kd"
                );
                assert!(
                    off_share(&one, &packet) < 0.002,
                    "{name} frame {f} {mode:?}: Embree packets differ from Embree single rays"
                );
                assert!(kd.iter().any(|&b| b != kd[0]), "{name}: a blank image proves nothing");
            }
        }
    }
}
