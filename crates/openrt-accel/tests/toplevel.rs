//! The top-level instance BSP (Algorithm 1 of Wald, Benthin & Slusallek 2003).

use glam::Vec3;
use openrt_accel::{Aabb, BspBuilder, InstanceBsp, Ray, traverse};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

fn random_boxes(n: usize, seed: u64, max_size: f32) -> Vec<Aabb> {
    let mut rng = SmallRng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let c = Vec3::new(
                rng.random_range(-50.0..50.0),
                rng.random_range(-50.0..50.0),
                rng.random_range(-5.0..5.0),
            );
            let h = Vec3::new(
                rng.random_range(0.1..max_size),
                rng.random_range(0.1..max_size),
                rng.random_range(0.1..max_size),
            );
            Aabb::new(c - h, c + h)
        })
        .collect()
}

#[test]
fn builds_valid_trees_over_random_and_overlapping_boxes() {
    for (n, size) in [(1, 1.0), (2, 1.0), (100, 2.0), (1000, 4.0), (500, 60.0)] {
        let boxes = random_boxes(n, n as u64, size);
        let bsp = InstanceBsp::build(&boxes).unwrap();
        bsp.validate(&boxes).unwrap_or_else(|e| panic!("{n} boxes: {e}"));
        assert!(bsp.references() >= n);
    }
}

#[test]
fn empty_and_degenerate_inputs() {
    let bsp = InstanceBsp::build(&[]).unwrap();
    assert_eq!(bsp.nodes().len(), 1);
    let boxes = vec![
        Aabb::EMPTY,
        Aabb::new(Vec3::ZERO, Vec3::ONE),
        Aabb::new(Vec3::splat(f32::NAN), Vec3::ONE),
    ];
    let bsp = InstanceBsp::build(&boxes).unwrap();
    bsp.validate(&boxes).unwrap();
    // Identical boxes: no plane separates them; one leaf.
    let same = vec![Aabb::new(Vec3::ZERO, Vec3::ONE); 50];
    let bsp = InstanceBsp::build(&same).unwrap();
    assert_eq!(bsp.nodes().len(), 1);
    bsp.validate(&same).unwrap();
    // Flat boxes lying in one plane.
    let flat: Vec<Aabb> = (0..20)
        .map(|i| Aabb::new(Vec3::new(i as f32, 0.0, 0.0), Vec3::new(i as f32 + 0.5, 1.0, 0.0)))
        .collect();
    let bsp = InstanceBsp::build(&flat).unwrap();
    bsp.validate(&flat).unwrap();
}

#[test]
fn planes_are_at_box_boundaries_nearest_the_centre_on_the_crowded_side() {
    // Three boxes crowd the left; the root plane must be the boundary
    // nearest the centre on the left side.
    let boxes = vec![
        Aabb::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 1.0)),
        Aabb::new(Vec3::new(1.5, 0.0, 0.0), Vec3::new(2.0, 1.0, 1.0)),
        Aabb::new(Vec3::new(3.0, 0.0, 0.0), Vec3::new(4.0, 1.0, 1.0)),
        Aabb::new(Vec3::new(9.0, 0.0, 0.0), Vec3::new(10.0, 1.0, 1.0)),
    ];
    let bsp = InstanceBsp::build(&boxes).unwrap();
    let root = bsp.nodes()[0];
    assert!(!root.is_leaf());
    assert_eq!(root.axis(), 0);
    assert_eq!(root.split(), 4.0, "nearest boundary to the centre 5 on the left");
    bsp.validate(&boxes).unwrap();
}

#[test]
fn traversal_finds_every_box_a_ray_crosses_front_to_back() {
    let boxes = random_boxes(400, 9, 3.0);
    let bsp = InstanceBsp::build(&boxes).unwrap();
    let mut rng = SmallRng::seed_from_u64(10);
    for _ in 0..300 {
        let o = Vec3::new(
            rng.random_range(-60.0..60.0),
            rng.random_range(-60.0..60.0),
            rng.random_range(-8.0..8.0),
        );
        let d = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-0.2..0.2),
        );
        let ray = Ray::infinite(o, d);
        let expected: Vec<u32> = (0..boxes.len() as u32)
            .filter(|&i| boxes[i as usize].clip(&ray).is_some())
            .collect();
        let mut found = Vec::new();
        if let Some((t0, t1)) = bsp.bounds().clip(&ray) {
            let mut closest = f32::INFINITY;
            traverse(bsp.nodes(), &ray, t0, t1, &mut closest, |leaf, _| {
                found.extend(
                    bsp.leaf_items(leaf)
                        .iter()
                        .copied()
                        .filter(|&i| boxes[i as usize].clip(&ray).is_some()),
                );
                false
            });
        }
        found.sort_unstable();
        found.dedup();
        assert_eq!(found, expected);
    }
}

#[test]
fn the_tree_does_not_depend_on_the_thread_count_and_builders_reuse_memory() {
    // Large enough for the upper levels to be split and built in parallel.
    let boxes = random_boxes(12_000, 77, 1.5);
    let reference = BspBuilder::new(1).build(&boxes).unwrap();
    reference.validate(&boxes).unwrap();
    for threads in [1, 2, 3, 4, 8, 16] {
        let mut builder = BspBuilder::new(threads);
        for round in 0..2 {
            // A second build with the same builder reuses its scratch.
            let bsp = builder.build(&boxes).unwrap();
            assert_eq!(bsp.nodes(), reference.nodes(), "{threads} threads, round {round}");
            assert_eq!(bsp.references(), reference.references());
            assert_eq!(bsp.depth(), reference.depth());
            for &leaf in bsp.nodes().iter().filter(|n| n.is_leaf()) {
                assert_eq!(bsp.leaf_items(leaf), reference.leaf_items(leaf));
            }
        }
        // And then a smaller scene with the same builder.
        let small = random_boxes(300, 5, 2.0);
        let bsp = builder.build(&small).unwrap();
        bsp.validate(&small).unwrap();
        assert_eq!(bsp.nodes(), BspBuilder::new(1).build(&small).unwrap().nodes());
    }
}

#[test]
fn unusable_boxes_are_left_out_of_parallel_builds_as_of_serial_ones() {
    // Empty and non-finite boxes scattered over the input, a whole run of
    // them included, large enough for the parallel gathering of the boxes.
    let mut boxes = random_boxes(6_000, 9, 1.5);
    boxes[0] = Aabb::EMPTY;
    for i in (1_000..2_100).step_by(7) {
        boxes[i] = Aabb::EMPTY;
    }
    for b in &mut boxes[3_000..4_200] {
        b.min.x = f32::NAN;
    }
    boxes[5_999].max.y = f32::INFINITY;
    // The oracle: the same tree over the usable boxes alone, its leaf
    // lists mapped back to the input's indices.
    let usable: Vec<u32> = (0..boxes.len() as u32)
        .filter(|&i| !boxes[i as usize].is_empty() && boxes[i as usize].is_finite())
        .collect();
    let kept: Vec<Aabb> = usable.iter().map(|&i| boxes[i as usize]).collect();
    let reference = BspBuilder::new(1).build(&kept).unwrap();
    for threads in [1, 2, 4] {
        let bsp = BspBuilder::new(threads).build(&boxes).unwrap();
        assert_eq!(bsp.nodes(), reference.nodes(), "{threads} threads");
        assert_eq!(bsp.bounds(), reference.bounds());
        for &leaf in bsp.nodes().iter().filter(|n| n.is_leaf()) {
            let mapped: Vec<u32> = reference.leaf_items(leaf).iter().map(|&i| usable[i as usize]).collect();
            assert_eq!(bsp.leaf_items(leaf), mapped, "{threads} threads");
        }
    }
    BspBuilder::new(4).build(&boxes).unwrap().validate(&boxes).unwrap();
}
