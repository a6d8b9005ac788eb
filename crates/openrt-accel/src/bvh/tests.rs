//! The BVH against its scalar twin, the kd-tree and the f64 oracle.

use glam::Vec3;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use super::walk::{NodeRay, node_test_scalar};
use super::*;
use crate::kd::tree::KdTree;
use crate::testing::meshgen;
use crate::testing::oracle::BruteForce;

/// Every answer of `bvh` equals the kd-tree's over the same triangles, bit
/// for bit, and passes the oracle.
fn same_as_kd_and_oracle(tris: &[Triangle], rays: &[Ray], seed: u64) -> usize {
    let plain = Bvh::build(tris.to_vec()).expect("build");
    plain.validate().expect("valid");
    let split = Bvh::build_presplit(tris.to_vec()).expect("pre-split build");
    split.validate().expect("valid pre-split tree");
    let kd = KdTree::build_sah(tris.to_vec()).expect("kd build");
    let oracle = BruteForce::new(tris);
    let mut hits = 0;
    for bvh in [&plain, &split] {
        hits = same_answers(bvh, &kd, &oracle, tris, rays, seed);
    }
    hits
}

/// [`same_as_kd_and_oracle`] for one tree.
fn same_answers(bvh: &Bvh, kd: &KdTree, oracle: &BruteForce, tris: &[Triangle], rays: &[Ray], seed: u64) -> usize {
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut hits = 0;
    for (i, ray) in rays.iter().enumerate() {
        let got = bvh.intersect(ray);
        hits += usize::from(got.is_some());
        let want = kd.intersect(ray);
        assert_eq!(
            got,
            want,
            "ray {i} {ray:?}: BVH and kd-tree differ ({:?} / {:?})",
            got.map(|h| tris[h.prim as usize]),
            want.map(|h| tris[h.prim as usize])
        );
        oracle
            .check_closest(ray, got)
            .unwrap_or_else(|e| panic!("ray {i}: {e}"));
        let cut = Ray::new(ray.origin, ray.dir, 0.0, rng.random_range(0.0..6.0));
        let blocked = bvh.occluded(&cut);
        assert_eq!(blocked, kd.occluded(&cut), "shadow ray {i}");
        oracle
            .check_occluded(&cut, blocked)
            .unwrap_or_else(|e| panic!("shadow ray {i}: {e}"));
        // A bound from elsewhere (another instance's hit) is respected.
        let bound = got.map_or(ray.t_max, |h| h.t * 1.5);
        let (mut a, mut b) = (bound, bound);
        assert_eq!(
            bvh.intersect_within(ray, &mut a),
            kd.intersect_within(ray, &mut b),
            "ray {i}: bounded"
        );
        assert_eq!(a.to_bits(), b.to_bits());
    }
    hits
}

#[test]
fn closed_meshes_soups_and_grids_match_the_kd_tree_and_the_oracle() {
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
        rays.extend(meshgen::hard_rays(&tris, 500, seed));
        assert!(same_as_kd_and_oracle(&tris, &rays, seed) > 1000);
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let soup = meshgen::random_soup(1500, seed, b, 0.2);
        let rays = meshgen::random_rays(1500, seed + 100, b);
        assert!(same_as_kd_and_oracle(&soup, &rays, seed) > 200);
    }
    let grid = meshgen::grid(24, 24);
    let mut rays = meshgen::camera_rays(Vec3::new(12.0, 9.0, -20.0), Vec3::new(12.0, 12.0, 0.0), 48, 48, 60.0);
    rays.extend(meshgen::hard_rays(&grid, 500, 9));
    assert!(same_as_kd_and_oracle(&grid, &rays, 4) > 1000);
}

#[test]
fn coplanar_overlaps_give_the_same_triangle_in_both_structures() {
    // Two grids in one plane, offset by a third of a cell: every ray hits
    // two triangles at the same distance, often bit for bit, and the tie
    // rule (lower index) must decide it in both structures alike.
    let mut tris = meshgen::grid(12, 12);
    let shifted: Vec<Triangle> = tris.iter().map(|t| t.map(|v| v + Vec3::new(0.37, 0.29, 0.0))).collect();
    tris.extend(shifted);
    let mut rays = meshgen::camera_rays(Vec3::new(5.0, 4.0, -9.0), Vec3::new(6.0, 6.0, 0.0), 64, 64, 50.0);
    rays.extend(meshgen::camera_rays(
        Vec3::new(6.0, 6.0, 9.0),
        Vec3::new(6.0, 6.0, 0.0),
        64,
        64,
        50.0,
    ));
    let bvh = Bvh::build(tris.clone()).unwrap();
    let mut ties = 0;
    for r in &rays {
        if let Some(h) = bvh.intersect(r) {
            let other = tris.iter().enumerate().any(|(p, t)| {
                p as u32 != h.prim
                    && crate::geom::triangle::intersect_triangle(r, t, f32::INFINITY).is_some_and(|x| x.0 == h.t)
            });
            ties += usize::from(other);
        }
    }
    assert!(ties > 500, "only {ties} exact ties: the test proves little");
    assert!(same_as_kd_and_oracle(&tris, &rays, 2) > 4000);
}

#[test]
fn axis_parallel_rays_along_faces_match_the_kd_tree() {
    // Rays with zero direction components running in the planes of
    // axis-aligned faces: the node test's parallel path decides them.
    let mut tris = meshgen::cube(Vec3::ZERO, Vec3::ONE);
    tris.extend(meshgen::cube(Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 1.0)));
    tris.extend(meshgen::grid(4, 4));
    let mut rays = Vec::new();
    for &x in &[-0.0f32, 0.0, 0.5, 1.0, 2.0] {
        for &y in &[0.0f32, 0.25, 1.0] {
            for d in [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z] {
                rays.push(Ray::infinite(Vec3::new(x, y, -3.0) - d * 3.0, d));
                rays.push(Ray::infinite(Vec3::new(-1.0, x, y) - d * 3.0, d));
                rays.push(Ray::infinite(Vec3::new(x, 0.5, y) - d * 3.0, d));
            }
        }
    }
    assert!(same_as_kd_and_oracle(&tris, &rays, 1) > 50);
}

/// A box in [-2, 4]^3; `flat`: of zero extent along one axis, as
/// axis-aligned triangles make.
fn random_box(rng: &mut SmallRng, flat: bool) -> Aabb {
    let a = Vec3::new(
        rng.random_range(-2.0..2.0),
        rng.random_range(-2.0..2.0),
        rng.random_range(-2.0..2.0),
    );
    let mut e = Vec3::new(
        rng.random_range(0.0..2.0),
        rng.random_range(0.0..2.0),
        rng.random_range(0.0..2.0),
    );
    if flat {
        e[rng.random_range(0..3)] = 0.0;
    }
    Aabb::new(a, a + e)
}

/// A ray from around the boxes of [`random_box`] towards them; every
/// seventh `k` with a zero direction component (either sign). `None` when
/// the ray is degenerate.
fn random_ray(rng: &mut SmallRng, k: usize) -> Option<Ray> {
    let o = Vec3::new(
        rng.random_range(-4.0..4.0),
        rng.random_range(-4.0..4.0),
        rng.random_range(-4.0..4.0),
    );
    let aim = Vec3::new(
        rng.random_range(-2.0..2.0),
        rng.random_range(-2.0..2.0),
        rng.random_range(-2.0..2.0),
    );
    let mut d = aim - o;
    if k.is_multiple_of(7) {
        d[k / 7 % 3] = if k.is_multiple_of(2) { 0.0 } else { -0.0 };
    }
    let ray = Ray::new(o, d, rng.random_range(-1.0..1.0), f32::INFINITY);
    ray.is_valid().then_some(ray)
}

#[test]
fn the_node_test_equals_its_scalar_twin_bit_for_bit() {
    let mut rng = SmallRng::seed_from_u64(11);
    let (mut hits, mut clipped) = (0, 0);
    for k in 0..20_000usize {
        let mut node = BvhNode::empty();
        let used = rng.random_range(1..=BVH_WIDTH);
        for i in 0..used {
            node.set_box(i, &random_box(&mut rng, k.is_multiple_of(5)));
            node.child[i] = 0;
        }
        let Some(ray) = random_ray(&mut rng, k) else {
            continue;
        };
        let closest = rng.random_range(0.0..8.0);
        let (mask, near) = NodeRay::new(&ray).test(&node, closest);
        let (want, want_near) = node_test_scalar(&ray, &node, closest);
        assert_eq!(mask, want, "case {k}");
        for (i, (got, want)) in near.to_array().iter().zip(want_near).enumerate() {
            if mask & (1 << i) != 0 {
                assert_eq!(got.to_bits(), want.to_bits(), "case {k} lane {i}");
            }
        }
        assert_eq!(mask >> used, 0, "an unused slot was hit");
        for i in 0..used {
            // Never less than the robust clip of one box (`Aabb::clip`).
            if node.child_box(i).clip(&ray.with_interval(ray.t_min, closest)).is_some() {
                assert!(
                    mask & (1 << i) != 0,
                    "case {k} slot {i}: a box the clip meets is skipped"
                );
                clipped += 1;
            }
        }
        hits += mask.count_ones();
    }
    assert!(
        hits > 1_500 && clipped > 1_500,
        "{hits} box hits ({clipped} clipped): the sweep tests too little"
    );
}

/// The first-active-lane test of all four children at once gives, child by
/// child, the lane's bits of the group test and of the single-ray test; the
/// lanes read from the packet's layout (`LaneRays::from_laid`) give the
/// same bits.
#[test]
fn the_lane_test_of_four_children_equals_the_group_and_single_ray_tests() {
    let mut rng = SmallRng::seed_from_u64(17);
    let mut v = |lo: f32, hi: f32| {
        Vec3::new(
            rng.random_range(lo..hi),
            rng.random_range(lo..hi),
            rng.random_range(lo..hi),
        )
    };
    let mut met = 0;
    for k in 0..3_000 {
        let mut node = BvhNode::empty();
        let used = 1 + k % BVH_WIDTH;
        for i in 0..used {
            let a = v(-2.0, 2.0);
            let e = v(0.0, 2.0);
            node.set_box(i, &Aabb::new(a, a + e));
            node.child[i] = 0;
        }
        let o = v(-4.0, 4.0);
        let rays: [Ray; 16] = std::array::from_fn(|_| Ray::new(o, v(-2.0, 2.0) - o, 0.0, f32::INFINITY));
        let closest: [f32; 16] = std::array::from_fn(|l| {
            if l % 3 == 0 {
                f32::INFINITY
            } else {
                1.0 + l as f32 * 0.4
            }
        });
        let lr = packet::LaneRays::new(&rays);
        // The same lanes read from the packet's layout.
        let laid = packet::LaneRays::from_laid(&crate::packet::boxes::PacketBoxes::new(&rays, u32::MAX >> 16));
        for (l, ray) in rays.iter().enumerate() {
            if !ray.is_valid() || ray.dir.cmpeq(Vec3::ZERO).any() {
                continue;
            }
            let (mask, near) = lr.test_lane(&node, l, closest[l]);
            let (laid_mask, laid_near) = laid.test_lane(&node, l, closest[l]);
            assert_eq!(mask, laid_mask, "case {k} lane {l}: from the layout");
            assert_eq!(
                near.to_array().map(f32::to_bits),
                laid_near.to_array().map(f32::to_bits)
            );
            let mask = mask & ((1 << used) - 1);
            let (g, j) = (l / 4, l % 4);
            let bound = wide::f32x4::new(std::array::from_fn(|i| closest[g * 4 + i]));
            for i in 0..used {
                let (hits, nears) = lr.test(&node, i, g, bound);
                let (laid_hits, laid_nears) = laid.test(&node, i, g, bound);
                assert_eq!(hits, laid_hits, "case {k} lane {l} child {i}: from the layout");
                assert_eq!(
                    nears.to_array().map(f32::to_bits),
                    laid_nears.to_array().map(f32::to_bits)
                );
                assert_eq!(mask >> i & 1, hits >> j & 1, "case {k} lane {l} child {i}");
                if mask >> i & 1 != 0 {
                    assert_eq!(
                        near.to_array()[i].to_bits(),
                        nears.to_array()[j].to_bits(),
                        "case {k} lane {l} child {i}"
                    );
                }
            }
            let (single, _) = NodeRay::new(ray).test(&node, closest[l]);
            assert_eq!(mask, single, "case {k} lane {l}: not the single-ray test");
            met += mask.count_ones();
        }
    }
    assert!(met > 5_000, "{met} boxes met: the sweep tests too little");
}

/// A build on a pool's thread (subtrees from `BVH_TASK_MIN` references
/// as tasks) and one on another thread (sequential) give the same tree:
/// the same nodes in the same order, the same leaves.
#[test]
fn builds_in_parallel_and_alone_agree() {
    let tris = meshgen::bumpy_sphere(8 * super::build::BVH_TASK_MIN, 6, 0.2);
    let alone = Bvh::build(tris.clone()).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
    let pooled = pool.install(|| Bvh::build(tris)).unwrap();
    let layout = |b: &Bvh| {
        b.nodes()
            .iter()
            .flat_map(|n| (0..BVH_WIDTH).map(move |i| (n.slot(i), n.child_box(i))))
            .map(|(slot, a)| (slot, [a.min, a.max].map(|v| v.to_array().map(f32::to_bits))))
            .collect::<Vec<_>>()
    };
    // Enough triangles that the root's grandchildren are tasks.
    assert!(alone.triangles().len() >= 4 * super::build::BVH_TASK_MIN);
    assert_eq!(layout(&alone), layout(&pooled));
    assert_eq!(alone.prim_ids, pooled.prim_ids);
    pooled.validate().unwrap();
}

/// A refit on a pool's thread (parallel, from `PARALLEL_MIN` triangles)
/// and one on another thread (sequential) give the same tree.
#[test]
fn refits_in_parallel_and_alone_agree() {
    let tris = meshgen::bumpy_sphere(3 * crate::kd::fast_build::PARALLEL_MIN, 6, 0.2);
    let first = Bvh::build(tris.clone()).unwrap();
    let moved: Vec<Triangle> = tris.iter().map(|t| t.map(|v| v * (1.0 + 0.05 * v.x.cos()))).collect();
    let alone = Bvh::refit(&first, moved.clone(), BVH_REFIT_COST_LIMIT).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let pooled = pool
        .install(|| Bvh::refit(&first, moved, BVH_REFIT_COST_LIMIT))
        .unwrap();
    assert!(alone.stats().refitted && pooled.stats().refitted);
    let bits = |b: &Bvh| {
        b.nodes()
            .iter()
            .flat_map(|n| (0..BVH_WIDTH).map(|i| n.child_box(i)))
            .flat_map(|a| [a.min, a.max].map(|v| v.to_array().map(f32::to_bits)))
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&alone), bits(&pooled));
    assert_eq!(alone.blocks.len(), pooled.blocks.len());
    pooled.validate().unwrap();
    // Leaf boxes come from the packed blocks, lane by lane: exactly the
    // union of the leaf's triangles' boxes.
    for b in [&alone, &pooled] {
        for node in b.nodes() {
            for i in 0..BVH_WIDTH {
                let slot = node.slot(i);
                if matches!(slot, BvhSlot::Leaf { .. }) {
                    let want = b.leaf_primitives(slot).iter().fold(Aabb::EMPTY, |a, &p| {
                        a.union(Aabb::from_points(&b.triangles()[p as usize]))
                    });
                    assert_eq!(node.child_box(i), want);
                }
            }
        }
    }
}

#[test]
fn pre_split_trees_refit_to_whole_triangles() {
    // A refit takes each leaf's box from its triangles (whole, not the
    // pieces): still a valid tree, the oracle's answers.
    let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
    let soup = meshgen::random_soup(2000, 12, b, 0.4);
    let split = Bvh::build_presplit(soup.clone()).unwrap();
    assert!(split.stats().presplit > 0);
    let moved: Vec<Triangle> = soup
        .iter()
        .map(|t| t.map(|v| v + Vec3::new(0.02 * v.y.sin(), 0.0, 0.01)))
        .collect();
    let refit = Bvh::refit(&split, moved.clone(), f64::INFINITY).unwrap();
    assert!(refit.stats().refitted);
    refit.validate().unwrap();
    let oracle = BruteForce::new(&moved);
    for ray in &meshgen::random_rays(2000, 13, b) {
        oracle.check_closest(ray, refit.intersect(ray)).unwrap();
        oracle.check_occluded(ray, refit.occluded(ray)).unwrap();
    }
}

#[test]
fn refits_follow_moving_triangles_and_rebuild_when_the_tree_degrades() {
    let tris = meshgen::bumpy_sphere(4000, 3, 0.2);
    let first = Bvh::build(tris.clone()).unwrap();
    // A gentle deformation: refitted, and the same answers as a fresh build.
    let moved: Vec<Triangle> = tris.iter().map(|t| t.map(|v| v * (1.0 + 0.1 * v.y.sin()))).collect();
    let refit = Bvh::refit(&first, moved.clone(), BVH_REFIT_COST_LIMIT).unwrap();
    assert!(refit.stats().refitted);
    refit.validate().unwrap();
    let fresh = Bvh::build(moved.clone()).unwrap();
    let rays = meshgen::random_rays(3000, 5, Aabb::new(Vec3::splat(-1.5), Vec3::splat(1.5)));
    let oracle = BruteForce::new(&moved);
    for ray in &rays {
        assert_eq!(refit.intersect(ray), fresh.intersect(ray));
        assert_eq!(refit.occluded(ray), fresh.occluded(ray));
        oracle.check_closest(ray, refit.intersect(ray)).unwrap();
    }
    // Triangles scattered far from their neighbours: the refitted boxes
    // overlap everywhere, its cost passes the limit and it is rebuilt.
    let mut rng = SmallRng::seed_from_u64(8);
    let scattered: Vec<Triangle> = tris
        .iter()
        .map(|t| {
            let s = Vec3::new(
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
            );
            t.map(|v| v + s)
        })
        .collect();
    let again = Bvh::refit(&refit, scattered.clone(), BVH_REFIT_COST_LIMIT).unwrap();
    assert!(!again.stats().refitted, "a degraded refit must be rebuilt");
    again.validate().unwrap();
    // With no limit the degraded refit is kept, and still correct.
    let kept = Bvh::refit(&refit, scattered.clone(), f64::INFINITY).unwrap();
    assert!(kept.stats().refitted && kept.stats().sah_cost > again.stats().sah_cost * BVH_REFIT_COST_LIMIT);
    kept.validate().unwrap();
    let oracle = BruteForce::new(&scattered);
    for ray in rays.iter().take(500) {
        oracle.check_closest(ray, kept.intersect(ray)).unwrap();
    }
    // A triangle that turns degenerate changes the leaves: rebuilt.
    let mut flat = moved;
    flat[7] = [flat[7][0]; 3];
    let rebuilt = Bvh::refit(&first, flat.clone(), BVH_REFIT_COST_LIMIT).unwrap();
    assert!(!rebuilt.stats().refitted && rebuilt.stats().dropped == 1);
    rebuilt.validate().unwrap();
    // From a tree that dropped a triangle, both triangle lists are tested:
    // refitted while the same one stays degenerate, rebuilt when it turns
    // valid again or when another one turns degenerate instead.
    let mut still = flat.clone();
    still[7] = [still[7][0] * 1.01; 3];
    let kept = Bvh::refit(&rebuilt, still, BVH_REFIT_COST_LIMIT).unwrap();
    assert!(kept.stats().refitted && kept.stats().dropped == 1);
    kept.validate().unwrap();
    let mut healed = flat.clone();
    healed[7] = tris[7];
    let again = Bvh::refit(&rebuilt, healed, BVH_REFIT_COST_LIMIT).unwrap();
    assert!(!again.stats().refitted && again.stats().dropped == 0);
    again.validate().unwrap();
    let mut moved_flat = flat;
    moved_flat[7] = tris[7];
    moved_flat[8] = [moved_flat[8][1]; 3];
    let other = Bvh::refit(&rebuilt, moved_flat, BVH_REFIT_COST_LIMIT).unwrap();
    assert!(!other.stats().refitted && other.stats().dropped == 1);
    other.validate().unwrap();
}

#[test]
fn hostile_inputs_build_valid_shallow_trees() {
    // Identical triangles (every centre the same point), a geometric
    // progression of sizes (binning separates one at a time), degenerate
    // and non-finite triangles, and nothing at all.
    let same = vec![[Vec3::ZERO, Vec3::X, Vec3::Y]; 5000];
    let progression: Vec<Triangle> = (0..3000)
        .map(|i| {
            let s = 1.5f32.powi(-(i % 60)) + i as f32 * 1e-3;
            [
                Vec3::splat(s),
                Vec3::splat(s) + Vec3::X * s,
                Vec3::splat(s) + Vec3::Y * s,
            ]
        })
        .collect();
    let mut junk = meshgen::bumpy_sphere(500, 1, 0.1);
    junk.push([Vec3::ONE; 3]);
    junk.push([Vec3::NAN, Vec3::X, Vec3::Y]);
    junk.push([Vec3::INFINITY, Vec3::X, Vec3::Y]);
    for (name, tris) in [
        ("same", same),
        ("progression", progression),
        ("junk", junk),
        ("empty", Vec::new()),
    ] {
        for bvh in [
            Bvh::build(tris.clone()).unwrap(),
            Bvh::build_presplit(tris.clone()).unwrap(),
        ] {
            bvh.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(bvh.stats().depth <= BVH_MAX_DEPTH, "{name}");
            let rays = meshgen::random_rays(300, 2, Aabb::new(Vec3::splat(-1.0), Vec3::splat(2.0)));
            let oracle = BruteForce::new(&tris);
            for ray in &rays {
                oracle
                    .check_closest(ray, bvh.intersect(ray))
                    .unwrap_or_else(|e| panic!("{name}: {e}"));
            }
        }
    }
    let junk_stats = Bvh::build(meshgen::bumpy_sphere(10, 1, 0.1)).unwrap();
    assert_eq!(junk_stats.stats().dropped, 0);
}

#[test]
fn the_primitive_limit_is_checked() {
    assert!(check_count(BVH_MAX_PRIMITIVES).is_ok());
    assert_eq!(
        check_count(BVH_MAX_PRIMITIVES + 1),
        Err(AccelError::TooManyPrimitives {
            count: BVH_MAX_PRIMITIVES + 1,
            limit: BVH_MAX_PRIMITIVES
        })
    );
}

#[test]
fn validate_catches_broken_trees() {
    let bvh = Bvh::build(meshgen::bumpy_sphere(2000, 4, 0.1)).unwrap();
    bvh.validate().unwrap();
    let mut shrunk = bvh.clone();
    let b = shrunk.nodes[0].child_box(0);
    shrunk.nodes[0].set_box(0, &Aabb::new(b.min, b.min + (b.max - b.min) * 0.5));
    assert!(shrunk.validate().is_err(), "a box that no longer holds its subtree");
    let mut lost = bvh.clone();
    let leaf = lost.prim_ids.iter().position(|&p| p == 17).unwrap();
    lost.prim_ids[leaf] = 18;
    assert!(lost.validate().is_err(), "a triangle in no leaf");
    let mut moved = bvh;
    let last = moved.tris.len() - 1;
    moved.tris[last][0].x += 1e-3;
    assert!(moved.validate().is_err(), "a block that differs from its triangle");
    // A pre-split tree whose leaf boxes no longer hold their pieces: shrunk
    // to their lower halves, parents unchanged (still holding them).
    let split = Bvh::build_presplit(meshgen::random_soup(500, 4, Aabb::new(Vec3::ZERO, Vec3::ONE), 0.5)).unwrap();
    split.validate().unwrap();
    assert!(split.stats().presplit > 0);
    let mut cut = split;
    for node in &mut cut.nodes {
        for i in 0..BVH_WIDTH {
            if matches!(node.slot(i), BvhSlot::Leaf { .. }) {
                let b = node.child_box(i);
                node.set_box(i, &Aabb::new(b.min, b.min + (b.max - b.min) * 0.5));
            }
        }
    }
    let e = cut.validate().unwrap_err().to_string();
    assert!(e.contains("no leaf box") || e.contains("misses"), "{e}");
}

/// Packets of `N` lanes (masked at random) answer as the single-ray walk,
/// bit for bit, closest and any hit.
fn packets_as_single_rays<const N: usize>(bvh: &Bvh, rays: &[Ray], seed: u64) -> usize {
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut hits = 0;
    for chunk in rays.chunks(N) {
        let pk: [Ray; N] = std::array::from_fn(|l| chunk[l % chunk.len()]);
        let mut lanes = crate::packet::width::lanes_mask(chunk.len());
        if rng.random_range(0..4) == 0 {
            lanes &= rng.random::<u32>();
        }
        let mut closest = pk.map(|r| r.t_max);
        let mut got = [None; N];
        let found = bvh.intersect_packet_in(&pk, lanes, &mut closest, &mut got, None, None);
        let (blocked, leaf) = bvh.occluder_packet_in(&pk, lanes, None, None);
        for l in 0..N {
            let on = lanes & (1 << l) != 0;
            let want = if on { bvh.intersect(&pk[l]) } else { None };
            assert_eq!(got[l], want, "lane {l} of {N}: {:?}", pk[l]);
            assert_eq!(found & (1 << l) != 0, want.is_some());
            assert_eq!(blocked & (1 << l) != 0, on && bvh.occluded(&pk[l]), "lane {l} occluded");
            hits += usize::from(want.is_some());
        }
        if let Some(leaf) = leaf {
            assert!(bvh.lists().owns(leaf), "the named leaf is one of the tree's");
        }
    }
    hits
}

#[test]
fn packets_answer_as_single_rays() {
    let tris = meshgen::bumpy_sphere(4000, 6, 0.3);
    let bvh = Bvh::build(tris.clone()).unwrap();
    let b = Aabb::new(Vec3::splat(-1.3), Vec3::splat(1.3));
    // Coherent camera packets (a frustum), shadow-like packets ending at
    // one point, scattered rays (lane by lane for closest hits, intervals
    // for any hit), rays with zero components.
    let camera = meshgen::camera_rays(Vec3::new(0.2, 0.1, -4.0), Vec3::ZERO, 32, 32, 50.0);
    let light = Vec3::new(3.0, 4.0, -2.0);
    let shadow: Vec<Ray> = meshgen::random_rays(1024, 3, b)
        .iter()
        .map(|r| Ray::new(r.origin, light - r.origin, 0.0, 1.0))
        .collect();
    let random = meshgen::random_rays(1024, 4, b);
    // Camera rays mirrored by a plane through the sphere and by a large
    // sphere behind it (lines near a virtual apex: `Frustum::through`).
    let mut mirrored = meshgen::mirrored_rays(&camera, Vec3::new(0.0, 0.0, 0.3), Vec3::new(0.1, 0.0, -1.0).normalize());
    mirrored.extend(meshgen::sphere_mirrored_rays(&camera, Vec3::new(0.0, 0.0, 30.0), 29.5));
    let with_apex = mirrored
        .chunks_exact(16)
        .filter(|c| crate::packet::frustum::Frustum::through(&<[Ray; 16]>::try_from(*c).unwrap(), 0xffff).is_some())
        .count();
    assert!(
        with_apex * 2 > mirrored.len() / 16,
        "{with_apex} mirrored packets with a frustum"
    );
    let mut axis = Vec::new();
    for k in 0..256 {
        let o = Vec3::new((k % 16) as f32 * 0.15 - 1.2, (k / 16) as f32 * 0.15 - 1.2, -3.0);
        axis.push(Ray::infinite(
            o,
            if k % 3 == 0 {
                Vec3::Z
            } else {
                Vec3::new(0.01, 0.02, 1.0)
            },
        ));
    }
    let mut coplanar = meshgen::grid(12, 12);
    let shifted: Vec<Triangle> = coplanar
        .iter()
        .map(|t| t.map(|v| v + Vec3::new(0.37, 0.29, 0.0)))
        .collect();
    coplanar.extend(shifted);
    let grid = Bvh::build(coplanar).unwrap();
    // A pre-split soup, every triangle twice (each hit an exact tie that
    // the tie rule decides, in whichever leaves the pieces went).
    let soup = meshgen::random_soup(1500, 8, b, 0.4);
    let mut twice = soup.clone();
    twice.extend(soup);
    let split = Bvh::build_presplit(twice).unwrap();
    split.validate().unwrap();
    assert!(split.stats().presplit > 100, "{} pieces", split.stats().presplit);
    let grid_rays = meshgen::camera_rays(Vec3::new(5.0, 4.0, -9.0), Vec3::new(6.0, 6.0, 0.0), 32, 32, 50.0);
    for (name, bvh, rays, least) in [
        ("camera", &bvh, &camera, 200),
        ("shadow", &bvh, &shadow, 100),
        ("random", &bvh, &random, 80),
        ("axis", &bvh, &axis, 50),
        ("mirrored", &bvh, &mirrored, 200),
        ("coplanar", &grid, &grid_rays, 500),
        ("camera, pre-split", &split, &camera, 200),
        ("shadow, pre-split", &split, &shadow, 100),
        ("random, pre-split", &split, &random, 80),
        ("mirrored, pre-split", &split, &mirrored, 200),
    ] {
        for (n, h) in [
            (4, packets_as_single_rays::<4>(bvh, rays, 1)),
            (8, packets_as_single_rays::<8>(bvh, rays, 2)),
            (16, packets_as_single_rays::<16>(bvh, rays, 3)),
            (32, packets_as_single_rays::<32>(bvh, rays, 4)),
        ] {
            assert!(h >= least, "{name} N={n}: {h} hits");
        }
    }
}

/// The eight-wide node test (AVX2) equals its scalar twin bit for bit, on
/// random boxes (flat ones too), unused slots and axis-parallel rays.
#[test]
fn the_eight_wide_node_test_equals_its_scalar_twin_bit_for_bit() {
    #[cfg(target_arch = "x86_64")]
    {
        use super::node8::{BVH8_WIDTH, Node8};
        use super::walk8::{node8_test_avx2, node8_test_scalar};
        if !crate::packet::width::avx2() {
            eprintln!("no AVX2 on this CPU: the eight-wide walk is never used here");
            return;
        }
        let mut rng = SmallRng::seed_from_u64(23);
        let mut hits = 0;
        for k in 0..20_000usize {
            let mut node = BvhNode::empty();
            let mut other = BvhNode::empty();
            let used = rng.random_range(1..=BVH8_WIDTH);
            for i in 0..used {
                let half = if i < BVH_WIDTH { &mut node } else { &mut other };
                half.set_box(i % BVH_WIDTH, &random_box(&mut rng, k.is_multiple_of(5)));
                half.child[i % BVH_WIDTH] = LEAF_BIT;
                half.count[i % BVH_WIDTH] = 1;
            }
            // Two four-wide nodes under one root, collapsed into one eight-wide node.
            let mut root = BvhNode::empty();
            for (i, n) in [&node, &other].into_iter().enumerate() {
                if n.child[0] != EMPTY_SLOT {
                    root.set_box(i, &n.bounds());
                    root.child[i] = i as u32 + 1;
                }
            }
            let eight: Vec<Node8> = super::node8::collapse(&[root, node, other]);
            assert_eq!(eight.len(), 1, "case {k}: two four-wide nodes fit in one");
            let Some(ray) = random_ray(&mut rng, k) else {
                continue;
            };
            let closest = rng.random_range(0.0..8.0);
            let (mask, near) = node8_test_avx2(&ray, &eight[0], closest).expect("AVX2");
            let (want, want_near) = node8_test_scalar(&ray, &eight[0], closest);
            assert_eq!(mask, want, "case {k}");
            for i in 0..BVH8_WIDTH {
                if mask & (1 << i) != 0 {
                    assert_eq!(near[i].to_bits(), want_near[i].to_bits(), "case {k} lane {i}");
                }
            }
            // The four-wide test of the same boxes takes the same ones.
            let (m4, _) = NodeRay::new(&ray).test(&node, closest);
            let (m4b, _) = NodeRay::new(&ray).test(&other, closest);
            let slot_of =
                |b: Aabb| (0..BVH8_WIDTH).find(|&i| eight[0].child_box(i) == b && eight[0].child[i] != EMPTY_SLOT);
            for (n, m) in [(&node, m4), (&other, m4b)] {
                for i in (0..BVH_WIDTH).filter(|&i| n.child[i] != EMPTY_SLOT) {
                    let s = slot_of(n.child_box(i)).expect("every box is in the eight-wide node");
                    assert_eq!(m & (1 << i) != 0, mask & (1 << s) != 0, "case {k} box {i}");
                }
            }
            hits += mask.count_ones();
        }
        assert!(hits > 3_000, "{hits} box hits: the sweep tests too little");
    }
}

/// The eight-wide copy has fewer, fuller nodes than the four-wide tree, and
/// single rays through it answer as through the four-wide nodes, bit for
/// bit, closest and any hit, bounded too.
#[test]
fn the_eight_wide_walk_answers_as_the_four_wide_one() {
    let mut tris = meshgen::bumpy_sphere(20_000, 3, 0.3);
    tris.extend(
        meshgen::bumpy_sphere(500, 9, 0.0)
            .into_iter()
            .map(|t| t.map(|v| v * 0.2 + Vec3::X)),
    );
    let bvh = Bvh::build(tris).expect("build");
    bvh.validate().expect("valid");
    if bvh.nodes8.is_empty() {
        eprintln!("no eight-wide copy on this CPU (no AVX2, or OPENRT_BVH_WIDTH=4)");
        return;
    }
    assert!(
        bvh.nodes8.len() * 3 < bvh.nodes.len() * 2,
        "{} eight-wide nodes for {} four-wide ones",
        bvh.nodes8.len(),
        bvh.nodes.len()
    );
    let mut four = bvh.clone();
    four.nodes8.clear();
    let b = Aabb::new(Vec3::splat(-1.5), Vec3::splat(1.5));
    let mut rays = meshgen::random_rays(4000, 5, b);
    rays.extend(meshgen::camera_rays(Vec3::new(0.3, 0.2, 3.0), Vec3::ZERO, 40, 40, 50.0));
    rays.push(Ray::new(Vec3::new(-3.0, 0.0, 0.0), Vec3::X, 0.0, f32::INFINITY));
    let (mut hits, mut blocked) = (0, 0);
    for (i, ray) in rays.iter().enumerate() {
        let got = bvh.intersect(ray);
        assert_eq!(got, four.intersect(ray), "ray {i}");
        hits += usize::from(got.is_some());
        // Just before the closest hit (not blocked) or just past it (blocked).
        let end = if i % 2 == 0 { 0.999 } else { 1.001 };
        let cut = ray.with_interval(ray.t_min, got.map_or(2.0, |h| h.t * end));
        let o = bvh.occluded(&cut);
        assert_eq!(o, four.occluded(&cut), "shadow ray {i}");
        blocked += usize::from(o);
        let bound = got.map_or(ray.t_max, |h| h.t * 1.5);
        let (mut a, mut c) = (bound, bound);
        assert_eq!(
            bvh.intersect_within(ray, &mut a),
            four.intersect_within(ray, &mut c),
            "ray {i}: bounded"
        );
        assert_eq!(a.to_bits(), c.to_bits());
    }
    assert!(hits > 1000 && blocked > 100, "{hits} hits, {blocked} blocked: too few");
    // A refitted tree walks its four-wide nodes (no copy to keep in step).
    let moved: Vec<Triangle> = bvh.triangles().iter().map(|t| t.map(|v| v * 1.02)).collect();
    let refitted = Bvh::refit(&bvh, moved, 10.0).expect("refit");
    assert!(refitted.stats().refitted && refitted.nodes8.is_empty());
    refitted.validate().expect("valid refit");
}

#[test]
fn validate_catches_a_broken_eight_wide_copy() {
    let bvh = Bvh::build(meshgen::bumpy_sphere(3000, 4, 0.1)).unwrap();
    bvh.validate().unwrap();
    if bvh.nodes8.is_empty() {
        return;
    }
    let mut lost = bvh.clone();
    let node = lost
        .nodes8
        .iter_mut()
        .find(|n| n.child.iter().any(|&c| c != EMPTY_SLOT && c & LEAF_BIT != 0))
        .unwrap();
    let slot = node
        .child
        .iter()
        .position(|&c| c != EMPTY_SLOT && c & LEAF_BIT != 0)
        .unwrap();
    node.child[slot] = EMPTY_SLOT;
    assert!(lost.validate().is_err(), "a leaf missing from the copy");
    let mut shrunk = bvh.clone();
    shrunk.nodes8[0].hi[0][0] = shrunk.nodes8[0].lo[0][0];
    assert!(shrunk.validate().is_err(), "a box that no longer holds its child");
    let mut gone = bvh;
    gone.nodes8.clear();
    assert!(gone.validate().is_err(), "no copy on a CPU that walks it");
}

#[test]
fn any_hit_packets_leave_few_lanes_to_walk_alone() {
    // At most one lane in `ALONE_SHARE`: 2 of 8, 5 of 16, 1 of 4.
    assert!(few::<8>(0b11) && !few::<8>(0b111));
    assert!(few::<16>(0x1F) && !few::<16>(0x3F));
    assert!(few::<4>(0b1) && !few::<4>(0b11));
    // Sparse shadow packets answer as single rays (and name a leaf of the tree).
    let tris = meshgen::bumpy_sphere(3000, 9, 0.3);
    let bvh = Bvh::build(tris).unwrap();
    let light = Vec3::new(3.0, 4.0, -2.0);
    let rays: Vec<Ray> = meshgen::random_rays(512, 10, Aabb::new(Vec3::splat(-1.3), Vec3::splat(1.3)))
        .iter()
        .map(|r| Ray::new(r.origin, light - r.origin, 0.0, 1.0))
        .collect();
    let mut blocked = 0;
    for chunk in rays.chunks_exact(8) {
        let pk: [Ray; 8] = std::array::from_fn(|l| chunk[l]);
        for lanes in [0b1u32, 0b1000_0001, 0b0110_0000] {
            let (got, leaf) = bvh.occluder_packet_in(&pk, lanes, None, None);
            for (l, ray) in pk.iter().enumerate() {
                let want = lanes & (1 << l) != 0 && bvh.occluded(ray);
                assert_eq!(got & (1 << l) != 0, want, "lane {l} of {lanes:#b}");
                blocked += usize::from(want);
            }
            assert_eq!(leaf.is_some(), got != 0);
            if let Some(leaf) = leaf {
                assert!(bvh.lists().owns(leaf));
            }
        }
    }
    assert!(blocked > 50, "{blocked} blocked lanes");
}

/// Closest-hit packets with few lanes entering (each walks alone) give each
/// lane the single ray's hit bit for bit, closer hits only below the lane's
/// bound, and touch no lane outside the mask.
#[test]
fn closest_hit_packets_leave_few_lanes_to_walk_alone() {
    let tris = meshgen::bumpy_sphere(3000, 9, 0.3);
    let bvh = Bvh::build_presplit(tris).unwrap();
    let rays = meshgen::random_rays(1024, 11, Aabb::new(Vec3::splat(-1.3), Vec3::splat(1.3)));
    let mut hit = 0;
    for chunk in rays.chunks_exact(8) {
        let pk: [Ray; 8] = std::array::from_fn(|l| chunk[l]);
        for lanes in [0b1u32, 0b1000_0001, 0b0110_0000, 0b1111_1111] {
            let mut closest: [f32; 8] = std::array::from_fn(|l| pk[l].t_max);
            let mut hits = [None; 8];
            let found = bvh.intersect_packet_in(&pk, lanes, &mut closest, &mut hits, None, None);
            for (l, ray) in pk.iter().enumerate() {
                let want = if lanes & (1 << l) != 0 {
                    bvh.intersect(ray)
                } else {
                    None
                };
                assert_eq!(found & (1 << l) != 0, want.is_some(), "lane {l} of {lanes:#b}");
                assert_eq!(
                    hits[l].map(|h: Hit| (h.prim, h.t.to_bits(), h.b1.to_bits(), h.b2.to_bits())),
                    want.map(|h| (h.prim, h.t.to_bits(), h.b1.to_bits(), h.b2.to_bits())),
                    "lane {l} of {lanes:#b}"
                );
                let bound = want.map_or(ray.t_max, |h| h.t);
                assert_eq!(closest[l].to_bits(), bound.to_bits(), "lane {l} of {lanes:#b}");
                hit += usize::from(want.is_some() && lanes.count_ones() < 3);
            }
        }
    }
    assert!(hit > 40, "{hit} hits of sparse packets");
}

/// Shadow packets from scattered points towards one light spread wide, so
/// their leaves take only the lanes that meet their boxes
/// (`EXACT_LEAF_SPREAD`); every lane still answers as its single ray.
#[test]
fn scattered_shadow_packets_answer_as_single_rays() {
    let bvh = Bvh::build(meshgen::bumpy_sphere(4000, 6, 0.3)).unwrap();
    let b = Aabb::new(Vec3::splat(-1.3), Vec3::splat(1.3));
    let light = Vec3::new(3.0, 4.0, -2.0);
    let rays: Vec<Ray> = meshgen::random_rays(2048, 7, b)
        .iter()
        .map(|r| Ray::new(r.origin, light - r.origin, 0.0, 1.0))
        .collect();
    let (mut wide, mut blocked) = (0, 0);
    for c in rays.chunks_exact(32) {
        let pk: [Ray; 32] = std::array::from_fn(|l| c[l]);
        let f = crate::packet::frustum::Frustum::for_occluded(&pk, u32::MAX);
        wide += usize::from(f.is_some_and(|f| f.spread() > super::EXACT_LEAF_SPREAD));
        let (got, _) = bvh.occluder_packet_in(&pk, u32::MAX, None, None);
        for (l, ray) in pk.iter().enumerate() {
            assert_eq!(got & (1 << l) != 0, bvh.occluded(ray), "lane {l}");
        }
        blocked += got.count_ones();
    }
    assert!(wide >= 48, "{wide} of 64 packets spread wide");
    assert!(blocked > 100, "{blocked} blocked lanes");
}
