//! Phase timing (`Renderer::set_phase_timing`) reports every phase a frame
//! goes through and leaves the image's bytes as they are.

use std::path::Path;

use openrt_core::{Backend, RenderMode, RenderSettings, Renderer};
use openrt_scene::ScenePlayer;

#[test]
fn timed_frames_have_the_untimed_bytes_and_every_phase() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    for scene in ["room.ron", "textured.ron"] {
        let mut player = ScenePlayer::open(Some(&root.join(scene))).unwrap();
        player.set_time(0.0).unwrap();
        for backend in [Backend::Packets, Backend::Single] {
            for mode in [RenderMode::GlLike, RenderMode::Whitted] {
                let mut r = Renderer::new(2).unwrap();
                r.set_backend(backend);
                let s = RenderSettings {
                    width: 96,
                    height: 64,
                    mode,
                    ..player.settings()
                };
                let (scene_now, env, cam) = (player.ctx().scene(), player.env(), player.camera(0.0));
                let (plain, st) = r.render(&scene_now, &env, &cam, &s).unwrap();
                assert!(st.phases.is_none(), "untimed frames report no phases");
                r.set_phase_timing(true);
                let (timed, st) = r.render(&scene_now, &env, &cam, &s).unwrap();
                assert_eq!(plain.to_rgb8(), timed.to_rgb8(), "{scene} {backend:?} {mode:?}");
                let p = st.phases.expect("timed frames report their phases");
                let what = format!("{scene} {backend:?} {mode:?}: {p:?}");
                assert!(p.camera_ns > 0 && p.primary_ns > 0 && p.surface_ns > 0, "{what}");
                assert!(p.textures_ns > 0 && p.lights_ns > 0 && p.image_ns > 0, "{what}");
                if mode == RenderMode::Whitted {
                    assert!(p.shadow_ns > 0, "{what}");
                } else {
                    assert_eq!(
                        p.shadow_ns + p.bounce_ns,
                        0,
                        "GL-like frames trace no shadow or bounce rays: {what}"
                    );
                }
            }
        }
    }
}
