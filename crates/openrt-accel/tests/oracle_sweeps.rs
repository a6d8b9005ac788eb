//! Seeded sweeps and property tests: kd-tree answers == brute-force f64 oracle.

use glam::Vec3;
use openrt_accel::oracle::BruteForce;
use openrt_accel::{Aabb, KdTree, Ray, SahParams, Triangle, meshgen};
use proptest::prelude::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

/// The SAH builder's three modes: the default (binned planes for large
/// nodes, the exact sweep for small ones), binned everywhere, and Wald &
/// Havran's exact event lists everywhere.
fn builder_modes() -> [SahParams; 3] {
    [
        SahParams::default(),
        SahParams {
            binned_above: Some(0),
            ..SahParams::default()
        },
        SahParams {
            binned_above: None,
            ..SahParams::default()
        },
    ]
}

/// Builds with every builder mode, validates, and checks every ray (closest
/// and any-hit with a random cut-off); returns the closest hits per mode.
fn check_all(tris: &[Triangle], rays: &[Ray], seed: u64) -> usize {
    let mut hits = None;
    for params in builder_modes() {
        let tree = KdTree::build_sah_with(tris.to_vec(), &params).expect("build");
        tree.validate().expect("valid tree");
        let h = check_tree(&tree, tris, rays, seed);
        assert!(
            hits.is_none_or(|prev| prev == h),
            "{params:?}: {h} hits, other modes {hits:?}"
        );
        hits = Some(h);
    }
    hits.unwrap_or(0)
}

fn check_tree(tree: &KdTree, tris: &[Triangle], rays: &[Ray], seed: u64) -> usize {
    let oracle = BruteForce::new(tris);
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut hits = 0;
    for (i, ray) in rays.iter().enumerate() {
        let got = tree.intersect(ray);
        hits += usize::from(got.is_some());
        if let Err(e) = oracle.check_closest(ray, got) {
            panic!("ray {i} {ray:?}: {e}");
        }
        let cut = Ray::new(ray.origin, ray.dir, 0.0, rng.random_range(0.0..6.0));
        if let Err(e) = oracle.check_occluded(&cut, tree.occluded(&cut)) {
            panic!("shadow ray {i} {cut:?}: {e}");
        }
    }
    hits
}

#[test]
fn random_soups_match_the_oracle() {
    for seed in 0..6 {
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let tris = meshgen::random_soup(1500, seed, b, 0.2);
        let rays = meshgen::random_rays(1500, seed + 100, b);
        let hits = check_all(&tris, &rays, seed);
        assert!(hits > 200, "seed {seed}: only {hits} hits, the sweep tests too little");
    }
}

#[test]
fn closed_meshes_match_the_oracle() {
    for seed in 0..3 {
        let tris = meshgen::bumpy_sphere(3000, seed, 0.3);
        let b = Aabb::new(Vec3::splat(-1.3), Vec3::splat(1.3));
        let mut rays = meshgen::random_rays(1500, seed + 7, b);
        rays.extend(meshgen::camera_rays(
            Vec3::new(0.3, 0.4, -4.0),
            Vec3::ZERO,
            40,
            30,
            40.0,
        ));
        let hits = check_all(&tris, &rays, seed);
        assert!(hits > 500);
    }
}

#[test]
fn camera_rays_over_a_grid_match_the_oracle() {
    let tris = meshgen::grid(24, 24);
    let rays = meshgen::camera_rays(Vec3::new(12.0, 9.0, -20.0), Vec3::new(12.0, 12.0, 0.0), 48, 48, 60.0);
    let hits = check_all(&tris, &rays, 3);
    assert!(hits > 1000);
}

fn coord() -> impl Strategy<Value = f32> {
    -4.0f32..4.0
}

fn vec3() -> impl Strategy<Value = Vec3> {
    (coord(), coord(), coord()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn triangle() -> impl Strategy<Value = Triangle> {
    (vec3(), vec3(), vec3()).prop_map(|(a, b, c)| [a, b, c])
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn tree_agrees_with_oracle(tris in prop::collection::vec(triangle(), 1..80),
                               rays in prop::collection::vec((vec3(), vec3()), 1..40)) {
        let tree = KdTree::build_sah(tris.clone()).unwrap();
        prop_assert!(tree.validate().is_ok(), "{:?}", tree.validate());
        let oracle = BruteForce::new(&tris);
        for (o, d) in rays {
            let ray = Ray::infinite(o * 2.0, d);
            if !ray.is_valid() { continue; }
            let r = oracle.check_closest(&ray, tree.intersect(&ray));
            prop_assert!(r.is_ok(), "{:?}", r);
            let r = oracle.check_occluded(&ray, tree.occluded(&ray));
            prop_assert!(r.is_ok(), "{:?}", r);
        }
    }

    #[test]
    fn axis_aligned_rays_agree_with_oracle(tris in prop::collection::vec(triangle(), 1..60),
                                           o in vec3(), axis in 0usize..3, neg in any::<bool>(),
                                           zero_signs in any::<[bool; 3]>()) {
        // Snap vertices to a coarse lattice so rays often lie in split planes
        // and run along triangle edges.
        let snap = |v: Vec3| (v * 2.0).round() / 2.0;
        let tris: Vec<Triangle> = tris.iter().map(|t| t.map(snap)).collect();
        let tree = KdTree::build_sah(tris.clone()).unwrap();
        prop_assert!(tree.validate().is_ok());
        let mut d = Vec3::new(
            if zero_signs[0] { -0.0 } else { 0.0 },
            if zero_signs[1] { -0.0 } else { 0.0 },
            if zero_signs[2] { -0.0 } else { 0.0 });
        d[axis] = if neg { -1.0 } else { 1.0 };
        let ray = Ray::infinite(snap(o), d);
        let oracle = BruteForce::new(&tris);
        let r = oracle.check_closest(&ray, tree.intersect(&ray));
        prop_assert!(r.is_ok(), "{:?}", r);
        let r = oracle.check_occluded(&ray, tree.occluded(&ray));
        prop_assert!(r.is_ok(), "{:?}", r);
    }
}

#[test]
fn fast_builder_trees_match_the_oracle() {
    for seed in 0..4 {
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let mut tris = meshgen::random_soup(2000, seed, b, 0.15);
        tris.extend(meshgen::bumpy_sphere(2000, seed, 0.3));
        tris.extend(
            meshgen::grid(8, 8)
                .iter()
                .map(|t| t.map(|v| v * 0.25 - Vec3::new(1.0, 1.0, 0.0))),
        );
        let tree = KdTree::build_fast(tris.clone()).unwrap();
        tree.validate().unwrap();
        assert_eq!(tree.stats().builder, openrt_accel::BuilderKind::Fast);
        let sah = KdTree::build_sah(tris.clone()).unwrap();
        assert!(tree.stats().depth <= sah.stats().depth, "fast trees are shallower");
        let oracle = BruteForce::new(&tris);
        for ray in meshgen::random_rays(1500, seed + 50, b) {
            oracle.check_closest(&ray, tree.intersect(&ray)).unwrap();
            oracle.check_occluded(&ray, tree.occluded(&ray)).unwrap();
        }
    }
}

#[test]
fn the_parallel_fast_build_equals_the_serial_one() {
    let b = Aabb::new(Vec3::splat(-2.0), Vec3::splat(2.0));
    let tris = meshgen::random_soup(20_000, 11, b, 0.05);
    let moved: Vec<_> = tris.iter().map(|t| t.map(|v| v * 1.01 + Vec3::X * 0.02)).collect();
    // In a pool of four threads the top levels are built on several; on
    // this thread (no pool) and with `parallel: false`, on one.
    let pool = openrt_accel::BspBuilder::new(4);
    let par_params = openrt_accel::FastParams::default();
    let ser_params = openrt_accel::FastParams {
        parallel: false,
        ..Default::default()
    };
    let same = |a: &KdTree, b: &KdTree| {
        assert_eq!(a.nodes(), b.nodes());
        for n in a.nodes() {
            assert_eq!(a.leaf_primitives(*n), b.leaf_primitives(*n));
        }
        assert_eq!(a.stats().depth, b.stats().depth);
    };
    let (par, par_refit) = pool.install(|| {
        let t = KdTree::build_fast_with(tris.clone(), &par_params).unwrap();
        let r = KdTree::refit_fast(&t, moved.clone(), &par_params).unwrap();
        (t, r)
    });
    let ser = KdTree::build_fast_with(tris.clone(), &ser_params).unwrap();
    let outside = KdTree::build_fast_with(tris, &par_params).unwrap();
    same(&par, &ser);
    same(&par, &outside);
    let ser_refit = KdTree::refit_fast(&ser, moved, &ser_params).unwrap();
    assert!(par_refit.stats().refitted);
    same(&par_refit, &ser_refit);
}

/// Every non-empty leaf of `tree` (by list offset) with its cell.
fn leaf_cells(tree: &KdTree) -> Vec<(u32, Aabb)> {
    tree.cells()
        .into_iter()
        .filter(|(n, _)| n.is_leaf() && n.prim_count() > 0)
        .map(|(n, cell)| (n.prim_offset(), cell))
        .collect()
}

/// The parameter interval, in f64, over which `ray` (from `t = 0`) lies in
/// `cell` grown by `grow` on every side.
fn f64_interval(ray: &Ray, cell: &Aabb, grow: f64) -> (f64, f64) {
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for k in 0..3 {
        let (o, d) = (f64::from(ray.origin[k]), f64::from(ray.dir[k]));
        let (lo, hi) = (f64::from(cell.min[k]) - grow, f64::from(cell.max[k]) + grow);
        if d == 0.0 {
            if o < lo || o > hi {
                return (1.0, 0.0);
            }
            continue;
        }
        let (a, b) = ((lo - o) / d, (hi - o) / d);
        (t0, t1) = (t0.max(a.min(b)), t1.min(a.max(b)));
    }
    (t0, t1)
}

/// Traversal visits every leaf whose cell the ray runs through and no leaf
/// whose cell it misses by more than a rounding margin: a step that takes a
/// wrong child (an empty cell's flag ignored, the near and far children
/// swapped) still finds the right hits but walks cells the ray never enters.
#[test]
fn traversal_visits_exactly_the_leaves_the_ray_runs_through() {
    let tris = meshgen::bumpy_sphere(3_000, 5, 0.5);
    let b = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
    let tree = KdTree::build_sah(tris).expect("build");
    let cells = leaf_cells(&tree);
    let eps = 1e-4 * f64::from(b.extent().max_element());
    let mut checked = 0;
    for ray in meshgen::random_rays(3_000, 9, b) {
        let Some((t0, t1)) = tree.bounds().clip(&ray) else {
            continue;
        };
        let mut visited = Vec::new();
        let mut never = f32::INFINITY;
        openrt_accel::traverse(tree.nodes(), &ray, t0, t1, &mut never, |leaf, _| {
            visited.push(leaf.prim_offset());
            false
        });
        for (off, cell) in &cells {
            let (inner0, inner1) = f64_interval(&ray, cell, -eps);
            let (outer0, outer1) = f64_interval(&ray, cell, eps);
            let seen = visited.contains(off);
            assert!(
                seen || inner0 > inner1,
                "ray {ray:?} runs through leaf {off} but did not visit it"
            );
            assert!(
                !seen || outer0 <= outer1,
                "ray {ray:?} visited leaf {off}, whose cell it misses"
            );
            checked += usize::from(seen);
        }
    }
    assert!(checked > 1_000, "only {checked} leaf visits checked");
}
