//! Packet traversal against its scalar twin: every lane's answer must equal
//! the single-ray answer bit for bit (t, triangle, barycentrics, the closest
//! distance left behind, any-hit), for coherent, incoherent and hard rays,
//! mirrored packets (lines through a virtual apex), packets that mix
//! direction signs, zero and -0.0 components, NaN and
//! empty-interval lanes and inactive lanes, at every packet width.

use glam::Vec3;
use openrt_accel::{Aabb, Hit, KdTree, Ray, Triangle, lanes_mask, meshgen};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

fn bits(h: Option<Hit>) -> Option<(u32, u32, u32, u32)> {
    h.map(|h| (h.t.to_bits(), h.prim, h.b1.to_bits(), h.b2.to_bits()))
}

/// Rays of every kind the renderer and the hard-case suite make.
fn ray_set(tris: &[Triangle], seed: u64) -> Vec<Ray> {
    let b = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
    let c = b.center();
    let r = b.extent().max_element();
    let mut rays = meshgen::camera_rays(c + Vec3::new(0.3, 0.4, 2.0) * r, c, 48, 32, 50.0);
    rays.extend(meshgen::camera_rays(c - Vec3::new(1.5, -0.2, 0.7) * r, c, 24, 16, 70.0));
    // Bounces off a plane mirror through the mesh and off a sphere around
    // it: packets whose lines pass near one point (`Frustum::through`).
    let eye = c + Vec3::new(0.2, 0.3, 2.5) * r;
    let camera = meshgen::camera_rays(eye, c, 32, 16, 60.0);
    rays.extend(meshgen::mirrored_rays(
        &camera,
        c + Vec3::Z * 0.1 * r,
        Vec3::new(0.0, 0.1, 1.0).normalize(),
    ));
    rays.extend(meshgen::sphere_mirrored_rays(&camera, c - Vec3::Z * 20.0 * r, 19.5 * r));
    rays.extend(meshgen::random_rays(600, seed, b));
    rays.extend(meshgen::hard_rays(tris, 600, seed));
    let mut rng = SmallRng::seed_from_u64(seed);
    // Zero and -0.0 components, aimed at vertices and edges.
    for p in meshgen::hard_points(tris, 200, seed) {
        let d = match rng.random_range(0..4) {
            0 => Vec3::new(0.0, -0.0, 1.0),
            1 => Vec3::new(-0.0, 1.0, 0.3),
            2 => Vec3::new(0.5, 0.0, -1.0),
            _ => Vec3::new(-1.0, -0.2, 0.0),
        };
        rays.push(Ray::new(p - d * 3.0, d, 0.0, f32::INFINITY));
    }
    // NaN and empty intervals, NaN origins, zero directions, negative t_min.
    rays.push(Ray::new(c, Vec3::X, f32::NAN, 1.0));
    rays.push(Ray::new(c, Vec3::X, 2.0, 1.0));
    rays.push(Ray::new(Vec3::splat(f32::NAN), Vec3::X, 0.0, 1.0));
    rays.push(Ray::new(c, Vec3::ZERO, 0.0, 1.0));
    rays.push(Ray::new(c + Vec3::Z * r * 3.0, -Vec3::Z, -1.0, f32::INFINITY));
    rays.push(Ray::new(c + Vec3::Z * r * 3.0, -Vec3::Z, -f32::INFINITY, r));
    rays
}

fn check<const N: usize>(name: &str, tree: &KdTree, rays: &[Ray], seed: u64) -> (usize, usize) {
    let mut rng = SmallRng::seed_from_u64(seed);
    let (mut hits, mut total) = (0, 0);
    // Shuffled once so that some packets mix signs, kept in order for coherent ones.
    let mut mixed = rays.to_vec();
    for i in (1..mixed.len()).rev() {
        mixed.swap(i, rng.random_range(0..=i));
    }
    for set in [rays, &mixed[..]] {
        for chunk in set.chunks(N) {
            let pk: [Ray; N] = std::array::from_fn(|l| chunk[l % chunk.len()]);
            // Some lanes inactive, and some lanes start with a closer bound.
            let mut lanes = lanes_mask(chunk.len());
            if rng.random_range(0..4) == 0 {
                lanes &= rng.random::<u32>();
            }
            let start: [f32; N] = std::array::from_fn(|l| {
                if rng.random_range(0..5) == 0 {
                    rng.random_range(0.0..4.0)
                } else {
                    pk[l].t_max
                }
            });
            let mut closest = start;
            let mut got = [None; N];
            let found = tree.intersect_packet(&pk, lanes, &mut closest, &mut got);
            let occluded = tree.occluded_packet(&pk, lanes);
            for l in 0..N {
                if lanes & (1 << l) == 0 {
                    assert_eq!(got[l], None, "{name}: inactive lane {l} written");
                    assert_eq!(closest[l].to_bits(), start[l].to_bits());
                    assert_eq!(occluded & (1 << l), 0);
                    continue;
                }
                let mut c = start[l];
                let want = tree.intersect_within(&pk[l], &mut c);
                assert_eq!(bits(got[l]), bits(want), "{name} N={N}: lane {l} {:?}", pk[l]);
                assert_eq!(closest[l].to_bits(), c.to_bits(), "{name}: closest of lane {l}");
                assert_eq!(found & (1 << l) != 0, want.is_some());
                assert_eq!(
                    occluded & (1 << l) != 0,
                    tree.occluded(&pk[l]),
                    "{name}: occluded lane {l}"
                );
                total += 1;
                hits += usize::from(want.is_some());
            }
        }
    }
    (hits, total)
}

#[test]
fn packets_answer_as_single_rays_bit_for_bit() {
    let stack: Vec<Triangle> = (0..40)
        .map(|i| {
            let x = i as f32 / 20.0 - 1.0;
            [
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(1.0, -1.0, 0.0),
                Vec3::new(x, 1.0, 0.0),
            ]
        })
        .collect();
    for (name, tris) in [
        ("sphere", meshgen::bumpy_sphere(6_000, 3, 0.3)),
        ("grid", meshgen::grid(30, 30)),
        ("cube", meshgen::cube(Vec3::splat(-1.0), Vec3::splat(1.0))),
        (
            "soup",
            meshgen::random_soup(3_000, 8, Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0)), 0.2),
        ),
        ("stack", stack),
    ] {
        for tree in [
            KdTree::build_sah(tris.clone()).unwrap(),
            KdTree::build_fast(tris.clone()).unwrap(),
        ] {
            let rays = ray_set(&tris, 21);
            let (h4, n4) = check::<4>(name, &tree, &rays, 1);
            let (h8, n8) = check::<8>(name, &tree, &rays, 2);
            let (h16, n16) = check::<16>(name, &tree, &rays, 3);
            let (h32, n32) = check::<32>(name, &tree, &rays, 4);
            for (h, n) in [(h4, n4), (h8, n8), (h16, n16), (h32, n32)] {
                assert!(
                    h > 100 && h < n,
                    "{name}: {h} hits of {n} lanes: the sweep must hit and miss"
                );
            }
        }
    }
}
