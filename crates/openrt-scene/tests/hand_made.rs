//! Public data built by hand, not by the parser: an inconsistent
//! `AffScene`, keys out of order or NaN, animated triangles with uneven
//! lists. Each gives an error or a defined answer, never a panic.

use std::path::Path;

use glam::Vec3;
use openrt_scene::aff::{AffPlayer, RotKey, Tcb, VecKey, interpolate_rot, interpolate_vec, parse_aff};

fn sample() -> openrt_scene::aff::AffScene {
    parse_aff(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/sample.aff")).expect("the fixture parses")
}

/// A change that breaks a parsed scene.
type Break = Box<dyn Fn(&mut openrt_scene::aff::AffScene)>;

#[test]
fn an_inconsistent_aff_scene_is_refused_by_the_player() {
    let ok = sample();
    ok.validate().unwrap();
    assert!(AffPlayer::new(ok.clone()).is_ok());
    let broken: Vec<(&str, Break)> = vec![
        ("material", Box::new(|s| s.static_mesh.materials[0] = 999)),
        ("lists", Box::new(|s| s.static_mesh.normals.truncate(1))),
        ("texture", Box::new(|s| s.materials[0].texture = Some(77))),
        ("parent", Box::new(|s| s.nodes[0].parent = Some(0))),
        ("animated", Box::new(|s| s.animated[0].times.clear())),
        ("animated material", Box::new(|s| s.animated[0].material = 1 << 40)),
    ];
    for (what, f) in broken {
        let mut s = ok.clone();
        f(&mut s);
        let e = AffPlayer::new(s).err().unwrap_or_else(|| panic!("{what}: accepted"));
        assert!(e.to_string().contains("inconsistent AFF scene"), "{what}: {e}");
    }
    // Out-of-range and cyclic nodes have no transform, and no panic.
    let mut s = ok.clone();
    assert!(s.node_transform(0, 1.0).is_some());
    assert!(s.node_transform(999, 1.0).is_none());
    s.nodes[0].parent = Some(0);
    assert!(s.node_transform(0, 1.0).is_none());
}

#[test]
fn keys_out_of_order_or_nan_interpolate_without_panicking() {
    let v = |time: f32, x: f32| VecKey {
        time,
        value: Vec3::new(x, 0.0, 0.0),
        tcb: Tcb::default(),
    };
    let r = |time: f32| RotKey {
        time,
        axis: Vec3::Y,
        degrees: time * 10.0,
        tcb: Tcb::default(),
    };
    for times in [
        vec![3.0, 1.0, 2.0, 0.0, 5.0],
        vec![f32::NAN, 1.0, 2.0, 3.0],
        vec![0.0, f32::INFINITY, f32::NEG_INFINITY, 1.0],
        vec![2.0, 2.0, 2.0, 2.0],
    ] {
        let vk: Vec<VecKey> = times.iter().map(|&t| v(t, t)).collect();
        let rk: Vec<RotKey> = times.iter().map(|&t| r(t)).collect();
        for t in [-1.0, 0.5, 2.0, 10.0, f32::NAN] {
            assert!(interpolate_vec(&vk, t).is_some());
            assert!(interpolate_rot(&rk, t).is_some());
        }
    }
    assert!(interpolate_vec(&[], 1.0).is_none());
}

#[test]
fn animated_triangles_with_uneven_lists_stay_defined() {
    let mut t = sample().animated[0].clone();
    t.vertices.pop();
    let (v, _) = t.at(10.0);
    assert!(v.iter().all(|p| p.is_finite()));
    t.times.clear();
    assert_eq!(t.at(1.0).0, [Vec3::ZERO; 3]);
}
