//! A replica context that only applies the change sets of another context
//! reaches the same scene every frame: the same images, byte for byte,
//! for every motion class; and a frame of affine motion sends little.

use std::path::Path;
use std::sync::Arc;

use openrt_core::{ChangeSet, Context, Environment, RenderSettings, Renderer};
use openrt_scene::ScenePlayer;

mod bart_dir;

fn scene(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../scenes/{name}.ron"))
}

/// Plays `frames` of the scene; returns the bytes of each frame's change set.
fn replicate(name: &str, frames: &[u32]) -> Vec<usize> {
    let mut master = ScenePlayer::open(Some(&scene(name))).unwrap();
    master.ctx_mut().record_changes();
    let mut replica = Context::new();
    let r = Renderer::new(2).unwrap();
    let s = RenderSettings {
        width: 48,
        height: 36,
        ..RenderSettings::default()
    };
    let env: Arc<Environment> = master.env();
    let mut sizes = Vec::new();
    for &f in frames {
        let t = master.time_of(f);
        master.set_time(t).unwrap();
        let set = master
            .ctx_mut()
            .take_changes()
            .expect("a recording context leaves a set per commit");
        let bytes = set.to_bytes().unwrap();
        sizes.push(bytes.len());
        replica.apply_changes(&ChangeSet::from_bytes(&bytes).unwrap()).unwrap();
        let cam = master.camera(t);
        let (a, _) = r.render(&master.ctx().scene(), &env, &cam, &s).unwrap();
        let (b, _) = r.render(&replica.scene(), &env, &cam, &s).unwrap();
        assert!(
            a.to_rgb8() == b.to_rgb8(),
            "{name} frame {f}: the replica renders other bytes"
        );
        assert_eq!(master.ctx().scene().frame(), replica.scene().frame());
    }
    sizes
}

#[test]
fn replicas_render_the_same_bytes_on_the_shipped_scenes() {
    for name in ["room", "textured", "animated", "slab"] {
        let sizes = replicate(name, &[0, 10, 11, 40]);
        assert!(sizes[0] > 100, "{name}: the first set holds the scene");
    }
}

#[test]
#[cfg_attr(not(bart_data), ignore = "BART data not found: set OPENRT_BART_DIR")]
fn replicas_follow_the_bart_scenes_and_affine_frames_send_little() {
    let Some(_) = bart_dir::bart() else { return };
    let k = replicate("kitchen", &[0, 100, 101, 102, 300]);
    assert!(
        k[0] > 1_000_000,
        "the kitchen's first set holds its geometry: {} bytes",
        k[0]
    );
    for (i, &b) in k.iter().enumerate().skip(1) {
        assert!(b < 1024, "kitchen frame set {i}: {b} bytes (goal: under 1 kB)");
    }
    let m = replicate("museum1k", &[0, 100, 101]);
    assert!(
        m[1] > 1000 * 36,
        "the museum sends its moving triangles every frame: {} bytes",
        m[1]
    );
    replicate("robots", &[0, 400, 401]);
}

#[test]
fn malformed_or_out_of_order_sets_are_errors() {
    let mut replica = Context::new();
    assert!(ChangeSet::from_bytes(&[0xFF; 7]).is_err());
    let late = ChangeSet {
        frame: 5,
        ..ChangeSet::default()
    };
    assert!(replica.apply_changes(&late).is_err());
    let far = ChangeSet {
        frame: 1,
        instances: vec![openrt_core::InstanceChange::Removed {
            index: u32::MAX,
            generation: 0,
        }],
        ..ChangeSet::default()
    };
    assert!(replica.apply_changes(&far).is_err());
}
