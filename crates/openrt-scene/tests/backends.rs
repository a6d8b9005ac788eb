//! The packet backend against the single-ray path on real scenes.
//!
//! - Every packet answer of the two-level scene equals the single-ray answer
//!   bit for bit (t, instance, triangle, barycentrics; occlusion), for the
//!   primary, shadow, reflection and refraction rays of real frames, in
//!   coherent packets and in shuffled ones that mix direction signs, at
//!   every packet width.
//! - Shadow rays with last-occluder hints (kept as the renderer keeps them,
//!   and every leaf of the scene as the hint) answer as the plain queries.
//! - `Backend::Packets` and `Backend::Single` render the same bytes for every
//!   shipped small scene, in both modes, on 1 and 2 threads and at every
//!   packet width; the BART kitchen, museum and robots frames too, when the data is
//!   there (see `bart.rs` for how it is found).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use openrt_accel::{PacketWidth, Ray, lanes_mask};
use openrt_core::kernels::{HINT_MARGIN, OccluderHint, offset_ray_origin};
use openrt_core::{
    Accel, Backend, Camera, Environment, RenderMode, RenderSettings, Renderer, Scene, SceneHit, TopLevel,
};
use openrt_scene::ScenePlayer;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

mod bart_dir;

use bart_dir::bart;

const WIDTHS: [PacketWidth; 4] = [PacketWidth::W4, PacketWidth::W8, PacketWidth::W16, PacketWidth::W32];

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn bits(h: Option<SceneHit>) -> Option<(u32, u32, u32, u32, u32)> {
    h.map(|h| (h.t.to_bits(), h.instance, h.prim, h.b1.to_bits(), h.b2.to_bits()))
}

/// The rays of a frame at `w` x `h`: primary rays, then from each hit a
/// shadow ray per light, a mirror ray and a refracted ray (index 1.5).
fn frame_rays(scene: &Scene, env: &Environment, cam: &Camera, w: u32, h: u32) -> [Vec<Ray>; 4] {
    let cr = cam.rays(w, h).unwrap();
    let primary: Vec<Ray> = (0..h)
        .flat_map(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| cr.ray(x, y))
        .collect();
    let (mut shadow, mut mirror, mut refr) = (Vec::new(), Vec::new(), Vec::new());
    for r in &primary {
        let Some(hit) = scene.intersect(r) else { continue };
        let s = scene.surface(r, &hit).expect("a hit of this scene");
        let d = r.dir.normalize();
        let n = if s.geometric_normal.dot(d) > 0.0 {
            -s.geometric_normal
        } else {
            s.geometric_normal
        };
        let out = offset_ray_origin(s.point, n, s.error_scale);
        for l in &env.lights {
            shadow.push(Ray::new(out, l.position - out, 0.0, 1.0 - 1e-4));
        }
        mirror.push(Ray::infinite(out, d - 2.0 * d.dot(n) * n));
        let (eta, c) = (1.0 / 1.5, -d.dot(n));
        let k = 1.0 - eta * eta * (1.0 - c * c);
        if k >= 0.0 {
            let t = (d * eta + n * (eta * c - k.sqrt())).normalize();
            refr.push(Ray::infinite(offset_ray_origin(s.point, -n, s.error_scale), t));
        }
    }
    [primary, shadow, mirror, refr]
}

/// Every packet answer against the single-ray one; returns (hits, lanes).
fn compare<const N: usize>(name: &str, scene: &Scene, rays: &[Ray], seed: u64) -> (usize, usize) {
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut shuffled = rays.to_vec();
    for i in (1..shuffled.len()).rev() {
        shuffled.swap(i, rng.random_range(0..=i));
    }
    let (mut hits, mut lanes_seen) = (0, 0);
    for set in [rays, &shuffled[..]] {
        for chunk in set.chunks(N) {
            let pk: [Ray; N] = std::array::from_fn(|l| chunk[l % chunk.len()]);
            let mut lanes = lanes_mask(chunk.len());
            if rng.random_range(0..8) == 0 {
                lanes &= rng.random::<u32>();
            }
            let got = scene.intersect_packet(&pk, lanes);
            let occ = scene.occluded_packet(&pk, lanes);
            for l in 0..N {
                if lanes & (1 << l) == 0 {
                    assert!(
                        got[l].is_none() && occ & (1 << l) == 0,
                        "{name}: inactive lane {l} answered"
                    );
                    continue;
                }
                let want = scene.intersect(&pk[l]);
                assert_eq!(bits(got[l]), bits(want), "{name} N={N}: lane {l} {:?}", pk[l]);
                assert_eq!(
                    occ & (1 << l) != 0,
                    scene.occluded(&pk[l]),
                    "{name} N={N}: occluded {l}"
                );
                hits += usize::from(want.is_some());
                lanes_seen += 1;
            }
        }
    }
    (hits, lanes_seen)
}

/// Shadow rays (light by light, in the order of `frame_rays`) answered
/// with last-occluder hints equal the plain answers: hints kept as the
/// renderer keeps them (one per light, single rays and packets towards the
/// light), and every leaf of every instance (a spread of 1,500 of them in
/// larger scenes) as the hint of a sample of the rays. Returns how many
/// (ray, leaf) pairs a leaf settled.
fn hinted(name: &str, scene: &Scene, env: &Environment, shadow: &[Ray]) -> usize {
    let lights = env.lights.len();
    let mut running = vec![OccluderHint::new(); lights];
    for (k, r) in shadow.iter().enumerate() {
        let want = scene.occluded(r);
        assert_eq!(
            scene.occluded_hinted(r, &mut running[k % lights]),
            want,
            "{name}: shadow ray {k}"
        );
    }
    for (j, light) in env.lights.iter().enumerate() {
        let mine: Vec<Ray> = shadow.iter().skip(j).step_by(lights).copied().collect();
        let mut hint = OccluderHint::new();
        for chunk in mine.chunks(16) {
            let pk: [Ray; 16] = std::array::from_fn(|l| chunk[l.min(chunk.len() - 1)]);
            let lanes = lanes_mask(chunk.len());
            let want = scene.occluded_packet_toward(&pk, lanes, light.position);
            let got = scene.occluded_packet_toward_hinted(&pk, lanes, light.position, &mut hint);
            assert_eq!(got, want, "{name}: light {j} packet");
        }
    }
    let mut every: Vec<OccluderHint> = scene
        .instances()
        .iter()
        .enumerate()
        .flat_map(|(i, inst)| {
            let leaves = inst.geometry.tree.leaves();
            leaves.into_iter().map(move |n| OccluderHint::naming(i as u32, n))
        })
        .collect();
    let stride = every.len().div_ceil(1_500);
    every = every.into_iter().step_by(stride.max(1)).collect();
    // Hints that name nothing of this scene.
    let some_leaf = every.first().and_then(OccluderHint::get).map(|h| h.1);
    if let Some(leaf) = some_leaf {
        every.push(OccluderHint::naming(u32::MAX, leaf));
    }
    let mut settled = 0;
    for r in shadow.iter().step_by(shadow.len().div_ceil(300).max(1)) {
        let want = scene.occluded(r);
        for h in &every {
            let mut hint = *h;
            assert_eq!(scene.occluded_hinted(r, &mut hint), want, "{name}: hint {h:?}");
            if let Some((i, leaf)) = h.get().filter(|(i, _)| (*i as usize) < scene.instances().len()) {
                let inst = &scene.instances()[i as usize];
                settled += usize::from(inst.geometry.tree.leaf_blocks(
                    &inst.ray_to_object(r, r.t_max),
                    leaf,
                    HINT_MARGIN,
                ));
            }
        }
    }
    settled
}

fn sweep(name: &str, player: &mut ScenePlayer, frames: &[u32], w: u32, h: u32) {
    for &f in frames {
        let t = player.time_of(f);
        player.set_time(t).unwrap();
        let scene = player.ctx().scene();
        let env = player.env();
        let kinds = frame_rays(&scene, &env, &player.camera(t), w, h);
        let settled = hinted(&format!("{name} frame {f}"), &scene, &env, &kinds[1]);
        // Every shipped scene has shadows somewhere.
        assert!(
            settled > 0 || kinds[1].is_empty(),
            "{name} frame {f}: no hint settled a shadow ray"
        );
        for (kind, rays) in ["primary", "shadow", "reflection", "refraction"].iter().zip(&kinds) {
            let tag = format!("{name} frame {f} {kind}");
            // Lanes are masked at random, so counts differ between widths.
            for (h, n) in [
                compare::<4>(&tag, &scene, rays, u64::from(f) + 1),
                compare::<8>(&tag, &scene, rays, u64::from(f) + 2),
                compare::<16>(&tag, &scene, rays, u64::from(f) + 3),
                compare::<32>(&tag, &scene, rays, u64::from(f) + 4),
            ] {
                if *kind == "primary" {
                    assert!(h > 0 && h <= n, "{tag}: {h} hits in {n} lanes");
                }
            }
        }
    }
}

#[test]
fn packets_answer_as_single_rays_on_the_shipped_scenes() {
    for name in ["room", "slab", "textured", "animated"] {
        let mut p = ScenePlayer::open(Some(&repo().join(format!("scenes/{name}.ron")))).unwrap();
        let frames: Vec<u32> = [0, p.frames() / 2, p.frames().saturating_sub(1)].into();
        sweep(name, &mut p, &frames, 64, 48);
        // The same with BVHs under the instances.
        p.ctx_mut().set_accel(Accel::Bvh);
        sweep(&format!("{name} (bvh)"), &mut p, &frames, 64, 48);
    }
}

#[test]
#[cfg_attr(not(bart_data), ignore = "BART data not found: set OPENRT_BART_DIR")]
fn packets_answer_as_single_rays_on_the_bart_scenes() {
    let Some(dir) = bart() else { return };
    let mut k = ScenePlayer::open(Some(&dir.join("kitchen/kitchen.aff"))).unwrap();
    sweep("kitchen", &mut k, &[0, 400], 80, 60);
    let mut m = ScenePlayer::open(Some(&dir.join("museum/museum5.aff"))).unwrap();
    sweep("museum5", &mut m, &[0, 200], 80, 60);
    // 161 instances under affine motion: the packets' world-box and frustum
    // culling of instances.
    let mut r = ScenePlayer::open(Some(&dir.join("robots/Robot.aff"))).unwrap();
    sweep("robots", &mut r, &[0, 400], 80, 60);
}

fn render(
    player: &ScenePlayer,
    t: f32,
    mode: RenderMode,
    threads: usize,
    backend: Backend,
    width: PacketWidth,
) -> Vec<u8> {
    let mut r = Renderer::new(threads).expect("a render pool");
    r.set_backend(backend);
    r.set_packet_width(width);
    let s = RenderSettings {
        width: 93,
        height: 61,
        mode,
        max_depth: 3,
        ..RenderSettings::default()
    };
    let env: Arc<Environment> = player.env();
    let (img, stats) = r.render(&player.ctx().scene(), &env, &player.camera(t), &s).unwrap();
    assert_eq!(stats.rays.primary, 93 * 61);
    img.to_rgb8()
}

fn same_bytes(name: &str, player: &mut ScenePlayer, frame: u32) {
    let t = player.time_of(frame);
    player.set_time(t).unwrap();
    for mode in [RenderMode::GlLike, RenderMode::Whitted] {
        let want = render(player, t, mode, 1, Backend::Single, PacketWidth::W4);
        for threads in [1, 2] {
            for w in WIDTHS {
                let got = render(player, t, mode, threads, Backend::Packets, w);
                assert!(
                    got == want,
                    "{name} frame {frame} {mode:?}: kd ({w:?}, {threads} threads) differs"
                );
            }
        }
        assert!(
            want.iter().any(|&b| b != want[0]),
            "{name}: a blank image proves nothing"
        );
        // BVHs under the instances: the kd-tree's bytes, single rays and packets.
        player.ctx_mut().set_accel(Accel::Bvh);
        player.set_time(t).unwrap();
        assert!(
            player
                .ctx()
                .scene()
                .instances()
                .iter()
                .all(|i| i.geometry.tree.accel() == Accel::Bvh)
        );
        for (backend, w) in [
            (Backend::Single, PacketWidth::W8),
            (Backend::Packets, PacketWidth::W8),
            (Backend::Packets, PacketWidth::W32),
        ] {
            let got = render(player, t, mode, 2, backend, w);
            assert!(
                got == want,
                "{name} frame {frame} {mode:?}: BVH with {backend:?} ({w:?}) differs from kd"
            );
        }
        player.ctx_mut().set_accel(Accel::Kd);
        // The other top level: a BVH over the instances (or the BSP, where
        // the default took the BVH).
        let default = player.ctx().scene().top_level();
        let other = if default == TopLevel::Bvh {
            TopLevel::Bsp
        } else {
            TopLevel::Bvh
        };
        player.ctx_mut().set_top_level(other);
        player.set_time(t).unwrap();
        assert_eq!(player.ctx().scene().top_level(), other);
        for backend in [Backend::Single, Backend::Packets] {
            let got = render(player, t, mode, 2, backend, PacketWidth::W8);
            assert!(
                got == want,
                "{name} frame {frame} {mode:?}: a {} top level with {backend:?} differs",
                other.name()
            );
        }
        player.ctx_mut().set_top_level(TopLevel::Auto);
        player.set_time(t).unwrap();
    }
}

#[test]
fn kd_and_kd_single_render_the_same_bytes() {
    for name in ["room", "slab", "textured", "animated"] {
        let mut p = ScenePlayer::open(Some(&repo().join(format!("scenes/{name}.ron")))).unwrap();
        let last = p.frames().saturating_sub(1);
        same_bytes(name, &mut p, last / 2);
    }
}

#[test]
#[cfg_attr(not(bart_data), ignore = "BART data not found: set OPENRT_BART_DIR")]
fn kd_and_kd_single_render_the_same_bytes_on_the_bart_scenes() {
    let Some(dir) = bart() else { return };
    let mut k = ScenePlayer::open(Some(&dir.join("kitchen/kitchen.aff"))).unwrap();
    same_bytes("kitchen", &mut k, 100);
    let mut m = ScenePlayer::open(Some(&dir.join("museum/museum5.aff"))).unwrap();
    same_bytes("museum5", &mut m, 100);
    let mut r = ScenePlayer::open(Some(&dir.join("robots/Robot.aff"))).unwrap();
    same_bytes("robots", &mut r, 400);
}

/// Kd-trees and BVHs give the same hit (t, instance, triangle) for every
/// ray of a Whitted kitchen frame's first hits and mirror bounces: the
/// kitchen's coplanar overlaps tie at exactly equal `t` (a kernel bound of
/// `next_up(closest)` for ties lost some of them in one structure).
#[test]
#[cfg_attr(not(bart_data), ignore = "BART data not found: set OPENRT_BART_DIR")]
fn kd_and_bvh_agree_on_the_kitchens_ties() {
    let Some(dir) = bart() else { return };
    let mut a = ScenePlayer::open(Some(&dir.join("kitchen/kitchen.aff"))).unwrap();
    let mut b = ScenePlayer::open(Some(&dir.join("kitchen/kitchen.aff"))).unwrap();
    b.ctx_mut().set_accel(Accel::Bvh);
    let t = a.time_of(200);
    a.set_time(t).unwrap();
    b.set_time(t).unwrap();
    let (sa, sb) = (a.ctx().scene(), b.ctx().scene());
    let [primary, _, mirror, _] = frame_rays(&sa, &a.env(), &a.camera(t), 640, 480);
    let mut hits = 0;
    for r in primary.iter().chain(&mirror) {
        let (x, y) = (sa.intersect(r), sb.intersect(r));
        assert_eq!(bits(x), bits(y), "{r:?}");
        hits += usize::from(x.is_some());
    }
    assert!(hits > 300_000, "{hits} hits");
}

#[test]
fn backends_parse_from_their_names() {
    for &b in Backend::ALL {
        assert_eq!(b.name().parse::<Backend>(), Ok(b));
    }
    let e = "embree-x".parse::<Backend>().unwrap_err();
    assert!(e.contains("packets, single"), "{e}");
}

/// Several samples per pixel and every texture filter: packets and single
/// rays, 1 and 2 threads, give the same bytes; more samples change the image.
#[test]
fn samples_and_filters_render_the_same_bytes_on_both_kd_backends() {
    let mut p = ScenePlayer::open(Some(&repo().join("scenes/textured.ron"))).unwrap();
    p.set_time(p.time_of(0)).unwrap();
    let env: Arc<Environment> = p.env();
    let cam = p.camera(p.time_of(0));
    let image = |backend: Backend, threads: usize, spp: u32, filter: openrt_core::TextureFilter| {
        let mut r = Renderer::new(threads).expect("a render pool");
        r.set_backend(backend);
        let s = RenderSettings {
            width: 61,
            height: 45,
            texture_filter: filter,
            spp,
            ..RenderSettings::default()
        };
        let (img, stats) = r.render(&p.ctx().scene(), &env, &cam, &s).unwrap();
        assert_eq!(stats.rays.primary, 61 * 45 * u64::from(spp));
        img.to_rgb8()
    };
    let mut seen = Vec::new();
    for filter in openrt_core::TextureFilter::ALL {
        for spp in [1, 4] {
            let want = image(Backend::Single, 1, spp, filter);
            assert_eq!(image(Backend::Packets, 2, spp, filter), want, "{filter:?}, {spp} spp");
            assert_eq!(
                image(Backend::Single, 2, spp, filter),
                want,
                "{filter:?}, {spp} spp, 2 threads"
            );
            assert!(
                !seen.contains(&want),
                "{filter:?}, {spp} spp: the same image as another setting"
            );
            seen.push(want);
        }
    }
}
