//! Motion classes: which builder runs when, promotion, and mailboxing.

use glam::{Mat4, Vec3};
use openrt_accel::{BuilderKind, Ray, meshgen};
use openrt_core::{Context, PrimitiveKind};

fn define_sphere(ctx: &mut Context, id: openrt_core::ObjectId, n: usize, wobble: f32) {
    ctx.begin_object(id).unwrap();
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    for t in meshgen::bumpy_sphere(n, 1, 0.2) {
        for v in t {
            ctx.vertex(v * (1.0 + wobble)).unwrap();
        }
    }
    ctx.end().unwrap();
    ctx.end_object().unwrap();
}

#[test]
fn each_object_pays_only_for_what_changed_and_settled_objects_are_promoted() {
    let mut ctx = Context::new();
    // Promotions replace a kd-tree's fast build (a BVH has one builder).
    ctx.set_accel(openrt_core::Accel::Kd);
    ctx.set_promote_after(Some(3));
    let still = ctx.gen_object();
    let moving = ctx.gen_object();
    let morphing = ctx.gen_object();
    for id in [still, moving, morphing] {
        define_sphere(&mut ctx, id, 2000, 0.0);
    }
    let _ = ctx.instantiate(still).unwrap();
    let m = ctx.instantiate(moving).unwrap();
    let _ = ctx.instantiate(morphing).unwrap();
    let s = ctx.commit().unwrap();
    assert_eq!(s.build_count(BuilderKind::Sah), 3);
    for f in 1..4 {
        ctx.set_instance_transform(m, Mat4::from_translation(Vec3::X * f as f32))
            .unwrap();
        define_sphere(&mut ctx, morphing, 2000, 0.01 * f as f32);
        let s = ctx.commit().unwrap();
        assert_eq!(s.builds.len(), 1, "only the redefined object is rebuilt");
        assert_eq!((s.builds[0].object, s.builds[0].builder), (morphing, BuilderKind::Fast));
        assert!(s.toplevel_ms >= 0.0 && s.toplevel_nodes >= 1);
        assert!(!s.toplevel_reused, "boxes moved: the top level is rebuilt");
    }
    assert_eq!(ctx.object_builder(morphing).unwrap(), Some(BuilderKind::Fast));
    assert_eq!(ctx.object_builder(moving).unwrap(), Some(BuilderKind::Sah));
    // Unchanged for 3 commits: promotion starts on the third.
    let mut started = false;
    for _ in 0..3 {
        let s = ctx.commit().unwrap();
        assert!(s.builds.is_empty());
        assert!(s.toplevel_reused, "nothing moved: the top level is kept");
        started |= s.promotions_started.contains(&morphing);
    }
    assert!(started);
    let before = ctx.scene();
    ctx.wait_for_promotions();
    let s = ctx.commit().unwrap();
    assert_eq!(s.promotions_swapped, vec![morphing]);
    assert_eq!(ctx.object_builder(morphing).unwrap(), Some(BuilderKind::Sah));
    // Same geometry, same answers.
    let after = ctx.scene();
    for ray in meshgen::camera_rays(Vec3::new(0.0, 0.0, -6.0), Vec3::ZERO, 32, 32, 40.0) {
        let (a, b) = (before.intersect(&ray), after.intersect(&ray));
        assert_eq!(a.map(|h| (h.instance, h.prim)), b.map(|h| (h.instance, h.prim)));
    }
    // A redefinition during a promotion discards it.
    define_sphere(&mut ctx, morphing, 2000, 0.5);
    ctx.commit().unwrap();
    assert_eq!(ctx.object_builder(morphing).unwrap(), Some(BuilderKind::Fast));
}

/// A floor (the square [-50, 50]^2 at y = 0; with `wall`, also a wall
/// 10 high in a corner, so that the floor's box holds the balls), then
/// `balls` instances of a ball of `detail` triangles above it in a row along
/// x, the floor instance first; with `far`, one more ball 400 away, so
/// that the floor's box is not most of the scene's (it is walked in the
/// BSP, not tested before it: `MAX_GLOBAL_INSTANCES`).
fn floor_and_balls(balls: usize, wall: bool, detail: usize, far: bool) -> Context {
    let mut ctx = Context::new();
    // The BSP's cells and mailbox are what these tests are about.
    ctx.set_top_level(openrt_core::TopLevel::Bsp);
    let floor = ctx.gen_object();
    ctx.begin_object(floor).unwrap();
    ctx.begin(PrimitiveKind::Quads).unwrap();
    for (x, z) in [(-50.0, -50.0), (50.0, -50.0), (50.0, 50.0), (-50.0, 50.0)] {
        ctx.vertex(Vec3::new(x, 0.0, z)).unwrap();
    }
    if wall {
        for (x, y, z) in [
            (50.0, 0.0, 49.0),
            (50.0, 0.0, 50.0),
            (50.0, 10.0, 50.0),
            (50.0, 10.0, 49.0),
        ] {
            ctx.vertex(Vec3::new(x, y, z)).unwrap();
        }
    }
    ctx.end().unwrap();
    ctx.end_object().unwrap();
    let ball = ctx.gen_object();
    define_sphere(&mut ctx, ball, detail, 0.0);
    ctx.instantiate(floor).unwrap();
    for i in 0..balls {
        ctx.load_matrix(Mat4::from_translation(Vec3::new(
            -45.0 + 90.0 * i as f32 / balls as f32,
            2.0,
            (i % 5) as f32 * 7.0 - 14.0,
        )))
        .unwrap();
        ctx.instantiate(ball).unwrap();
    }
    if far {
        ctx.load_matrix(Mat4::from_translation(Vec3::new(400.0, 2.0, 0.0)))
            .unwrap();
        ctx.instantiate(ball).unwrap();
    }
    ctx
}

#[test]
fn an_instance_spanning_many_cells_is_intersected_once_per_ray_and_missed_boxes_not_at_all() {
    let mut ctx = floor_and_balls(20, false, 200, true);
    ctx.commit().unwrap();
    let scene = ctx.scene();
    assert!(scene.bsp().nodes().len() > 10, "the floor spans many cells");
    // A ray in the floor's plane crosses every cell the floor is in and
    // stays in the floor's box all along (a ray above it would not reach the
    // box and never be tested against the floor), missing the floor itself.
    let ray = Ray::infinite(Vec3::new(-60.0, 0.0, 0.3), Vec3::new(1.0, 0.0, 0.0));
    let mut tests = 0;
    let _ = scene.intersect_counted(&ray, &mut tests);
    // The balls' boxes lie above the ray: only the floor is tested, once
    // (without the mailbox, once per cell: 11 times).
    assert_eq!(tests, 1, "{tests} instance tests: the mailbox must stop repeats");
    // Above the floor's box and below the balls' boxes a ray reaches no
    // instance's world box: none is moved into its object space.
    let above = Ray::infinite(Vec3::new(-60.0, 0.5, 0.3), Vec3::new(1.0, 0.0, 0.0));
    let mut tests = 0;
    assert!(scene.intersect_counted(&above, &mut tests).is_none());
    assert_eq!(tests, 0, "{tests} instances tested whose world box the ray misses");
}

#[test]
fn instances_whose_boxes_a_ray_misses_do_not_push_a_tested_one_out_of_the_mailbox() {
    // As above with more balls than mailbox slots (64: balls 64, 128 and
    // 192 share the floor's slot) and a wall in a corner of the floor, so
    // that the floor's box holds the balls and is in every cell (the BART
    // robots' city). The ray misses the balls' boxes; were they put in the
    // mailbox as they were met, the floor (tested in the first cell) would
    // be pushed out and tested again in the next cell.
    let mut ctx = floor_and_balls(200, true, 60, true);
    ctx.commit().unwrap();
    let scene = ctx.scene();
    let cells = scene
        .bsp()
        .nodes()
        .iter()
        .filter(|n| n.is_leaf() && scene.bsp().leaf_items(**n).contains(&0));
    assert!(cells.count() > 10, "the floor is in many cells");
    let ray = Ray::infinite(Vec3::new(-60.0, 0.5, 0.3), Vec3::new(1.0, 0.0, 0.0));
    let mut tests = 0;
    let _ = scene.intersect_counted(&ray, &mut tests);
    assert_eq!(tests, 1, "{tests} instance tests: the floor was tested again");
    // The packet walk gives the same answers lane by lane.
    let rays: [Ray; 4] = std::array::from_fn(|l| Ray::infinite(Vec3::new(-60.0, 0.5, 0.3 + l as f32), Vec3::X));
    let packet = scene.intersect_packet(&rays, 0xF);
    for (r, p) in rays.iter().zip(packet) {
        assert_eq!(scene.intersect(r).map(|h| h.t.to_bits()), p.map(|h| h.t.to_bits()));
    }
}

#[test]
fn an_instance_spanning_the_scene_is_tested_before_the_walk_with_the_walks_answers() {
    // The floor with its wall spans the balls' box: tested before the walk,
    // and in no cell of the BSP.
    let mut ctx = floor_and_balls(200, true, 60, false);
    ctx.commit().unwrap();
    let scene = ctx.scene();
    let bsp = scene.bsp();
    assert!(bsp.nodes().len() > 10, "the balls are walked");
    assert!(
        bsp.nodes()
            .iter()
            .all(|n| !n.is_leaf() || !bsp.leaf_items(*n).contains(&0)),
        "the floor is in a cell"
    );
    // Packets and single rays give the same hits, floor and balls, against
    // the f64 oracle's instance.
    let rays = meshgen::camera_rays(Vec3::new(0.0, 30.0, -80.0), Vec3::new(0.0, 0.0, 0.0), 32, 32, 60.0);
    let (mut floors, mut balls) = (0, 0);
    for c in rays.chunks_exact(16) {
        let packet: [Ray; 16] = std::array::from_fn(|l| c[l]);
        let got = scene.intersect_packet(&packet, 0xFFFF);
        for (r, p) in packet.iter().zip(got) {
            let single = scene.intersect(r);
            assert_eq!(
                single.map(|h| (h.t.to_bits(), h.instance, h.prim)),
                p.map(|h| (h.t.to_bits(), h.instance, h.prim))
            );
            match single {
                Some(h) if h.instance == 0 => floors += 1,
                Some(_) => balls += 1,
                None => {}
            }
            // Any-hit agrees.
            assert_eq!(scene.occluded(r), single.is_some());
        }
    }
    assert!(floors > 100 && balls > 10, "floor {floors}, balls {balls}");
    // The floor is tested once per ray that reaches its box.
    let mut tests = 0;
    let down = Ray::infinite(Vec3::new(3.0, 20.0, 45.0), Vec3::new(0.0, -1.0, 0.0));
    let hit = scene.intersect_counted(&down, &mut tests).unwrap();
    assert_eq!((hit.instance, tests), (0, 1));
}

/// One triangle of the square [-1, 1]^2 at z = 0: the lower-left half or
/// the upper-right one (the same bounding box).
fn half_square(ctx: &mut Context, id: openrt_core::ObjectId, upper: bool) {
    let s = if upper { -1.0 } else { 1.0 };
    ctx.begin_object(id).unwrap();
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    for (x, y) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0)] {
        ctx.vertex(Vec3::new(s * x, s * y, 0.0)).unwrap();
    }
    ctx.end().unwrap();
    ctx.end_object().unwrap();
}

#[test]
fn an_unchanged_box_list_keeps_the_top_level_tree_and_new_geometry_is_seen() {
    let mut ctx = Context::new();
    let obj = ctx.gen_object();
    half_square(&mut ctx, obj, false);
    let a = ctx.instantiate(obj).unwrap();
    ctx.translate(Vec3::new(5.0, 0.0, 0.0)).unwrap();
    let _ = ctx.instantiate(obj).unwrap();
    let s = ctx.commit().unwrap();
    assert!(!s.toplevel_reused, "the first commit builds");
    let down = |x: f32| Ray::infinite(Vec3::new(x, 0.5, 3.0), Vec3::NEG_Z);
    assert!(ctx.scene().intersect(&down(0.5)).is_none());
    // Redefined with the same bounds: the object tree is rebuilt, the top
    // level is kept, and rays see the new triangle in both instances.
    half_square(&mut ctx, obj, true);
    let s = ctx.commit().unwrap();
    assert!(s.toplevel_reused);
    assert_eq!(s.builds.len(), 1);
    for x in [0.5, 5.5] {
        let hit = ctx.scene().intersect(&down(x)).expect("the upper half is hit");
        assert!((hit.t - 3.0).abs() < 1e-5);
    }
    // A moved instance rebuilds the top level.
    ctx.set_instance_transform(a, Mat4::from_translation(Vec3::new(0.0, 10.0, 0.0)))
        .unwrap();
    let s = ctx.commit().unwrap();
    assert!(!s.toplevel_reused);
    assert!(ctx.scene().intersect(&down(0.5)).is_none());
    assert!(ctx.scene().intersect(&down(5.5)).is_some());
}

#[test]
fn large_commits_make_their_records_in_parallel_as_small_ones_do() {
    // Over the parallel threshold (2,048 records), with moves, removals
    // and a new instance between commits; each record is compared with the
    // one a single-instance scene makes (the serial path) for the same
    // object and transform, bit for bit.
    let mut ctx = Context::new();
    let (a, b) = (ctx.gen_object(), ctx.gen_object());
    define_sphere(&mut ctx, a, 64, 0.0);
    define_sphere(&mut ctx, b, 32, 0.3);
    let place = |i: usize, frame: usize| {
        let t = Vec3::new((i % 60) as f32 * 3.0, (i / 60) as f32 * 3.0, 0.0);
        let moved = i.is_multiple_of(3);
        let f = if moved { frame as f32 } else { 0.0 };
        Mat4::from_translation(t + Vec3::Z * f) * Mat4::from_scale(Vec3::new(1.0, 1.0 + 0.1 * f, -1.0))
    };
    let mut live: Vec<_> = (0..3_000)
        .map(|i| {
            ctx.load_matrix(place(i, 0)).unwrap();
            (
                i,
                if i.is_multiple_of(7) { b } else { a },
                ctx.instantiate(if i.is_multiple_of(7) { b } else { a }).unwrap(),
            )
        })
        .collect();
    ctx.commit().unwrap();
    let single = |object_is_b: bool, m: Mat4| {
        let mut one = Context::new();
        let (oa, ob) = (one.gen_object(), one.gen_object());
        define_sphere(&mut one, oa, 64, 0.0);
        define_sphere(&mut one, ob, 32, 0.3);
        one.load_matrix(m).unwrap();
        one.instantiate(if object_is_b { ob } else { oa }).unwrap();
        one.commit().unwrap();
        one.scene().instances()[0].clone()
    };
    for frame in 1..3 {
        for &(i, _, id) in &live {
            ctx.set_instance_transform(id, place(i, frame)).unwrap();
        }
        let gone = live.remove(100 * frame);
        ctx.remove_instance(gone.2).unwrap();
        ctx.load_matrix(place(5_000 + frame, frame)).unwrap();
        live.push((5_000 + frame, a, ctx.instantiate(a).unwrap()));
        let stats = ctx.commit().unwrap();
        assert!(!stats.toplevel_reused);
        let scene = ctx.scene();
        let records = scene.instances();
        assert_eq!(records.len(), live.len());
        let mut by_id: Vec<_> = live.clone();
        by_id.sort_by_key(|&(_, _, id)| id.index());
        for (r, &(i, object, id)) in records.iter().zip(&by_id) {
            assert_eq!((r.id, r.object), (id, object), "frame {frame}: records in slot order");
            assert_eq!(r.to_world, glam::Affine3A::from_mat4(place(i, frame)));
        }
        for r in records.iter().step_by(97) {
            let (i, object, _) = by_id.iter().find(|e| e.2 == r.id).copied().unwrap();
            let want = single(object == b, place(i, frame));
            let bits = |x: &openrt_core::InstanceRecord| {
                (
                    x.world_bounds.min.to_array(),
                    x.world_bounds.max.to_array(),
                    x.to_object.to_cols_array(),
                    x.det_sign,
                )
            };
            assert_eq!(bits(r), bits(&want), "frame {frame}, instance {i}");
        }
    }
}

#[test]
fn redefined_objects_refit_their_fast_trees_unless_told_not_to() {
    for refit in [true, false] {
        let mut ctx = Context::new();
        ctx.set_promote_after(None);
        ctx.set_refit(refit);
        let morphing = ctx.gen_object();
        define_sphere(&mut ctx, morphing, 2000, 0.0);
        let _ = ctx.instantiate(morphing).unwrap();
        ctx.commit().unwrap();
        let mut refitted = Vec::new();
        for f in 1..5 {
            define_sphere(&mut ctx, morphing, 2000, 0.01 * f as f32);
            let s = ctx.commit().unwrap();
            assert_eq!(s.builds[0].builder, BuilderKind::Fast);
            refitted.push(s.builds[0].refitted);
            // The refitted tree answers as a fresh one would.
            let scene = ctx.scene();
            let fresh = scene.instances()[0].geometry.tree.triangles().to_vec();
            let fresh = openrt_accel::KdTree::build_fast(fresh).unwrap();
            for ray in meshgen::random_rays(300, f, openrt_accel::Aabb::new(Vec3::splat(-2.0), Vec3::splat(2.0))) {
                assert_eq!(
                    scene.intersect(&ray).map(|h| (h.t.to_bits(), h.prim)),
                    fresh.intersect(&ray).map(|h| (h.t.to_bits(), h.prim))
                );
            }
        }
        // The first redefinition follows an SAH tree: built afresh; the
        // next ones refit the fast tree before them.
        let want: Vec<bool> = (1..5).map(|f| refit && f > 1).collect();
        assert_eq!(refitted, want, "refit {refit}");
    }
}
