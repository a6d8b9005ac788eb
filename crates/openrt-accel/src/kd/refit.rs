//! Refitting a fast tree to triangles that moved: last frame's split planes,
//! this frame's contents.
//!
//! A kd-tree cannot be refitted like a BVH (its cells partition space, so
//! there are no boxes to grow), but its planes can be kept. The museum's
//! triangles move smoothly between keys, so last frame's planes still cut
//! this frame's triangles well: the triangles are pushed down the old
//! planes (one partition pass per level, no binning), a node left with at
//! most a leaf's worth of triangles becomes a leaf, and an old leaf (or
//! empty cell) that now holds too many is split further by the fast
//! builder. The tree's SAH cost is then compared with the cost of the last
//! full build in its line: beyond [`FastParams::refit_cost_limit`] times
//! that cost, it is built afresh (the quality check that bounds how far a
//! refitted tree may degrade). BVHs for deforming scenes make the same
//! trade-off: refit every frame, rebuild when a quality measure says the
//! tree has degraded (Lauterbach et al., "RT-DEFORM", 2006; Wald, Boulos &
//! Shirley, "Ray tracing deformable scenes using dynamic bounding volume
//! hierarchies", 2007).

use crate::error::AccelError;
use crate::geom::aabb::Aabb;
use crate::geom::triangle::Triangle;
use crate::kd::fast_build::{Fast, FastParams, PARALLEL_MIN, items_of, parallel_levels};
use crate::kd::node::{KdNode, MAX_NODES, too_many_nodes};
use crate::kd::sah_params::BuiltTree;

/// The tree of `tris` on the planes of `old` (an elided node array).
pub(crate) fn refit(old: &[KdNode], tris: &[Triangle], params: &FastParams) -> Result<BuiltTree, AccelError> {
    let (items, boxes, bounds) = items_of(tris)?;
    let valid = items.len();
    let mut b = Fast::new(params, &boxes, valid);
    if items.is_empty() {
        b.nodes.push(KdNode::leaf(0, 0));
    } else {
        let root = (!old.is_empty()).then_some(0);
        let levels = parallel_levels(params, items.len());
        b.refit_node(old, root, bounds, items, 0, levels)?;
    }
    Ok(b.finish(bounds, valid))
}

impl Fast<'_> {
    /// Rebuilds the subtree of cell `cell` holding `items` on the planes
    /// below old node `at` (`None`: the old cell was empty); the two
    /// children of the top `levels` levels are built on two threads.
    fn refit_node(
        &mut self,
        old: &[KdNode],
        at: Option<u32>,
        cell: Aabb,
        items: Vec<u32>,
        depth: usize,
        levels: u32,
    ) -> Result<(), AccelError> {
        let Some(i) = at else {
            return self.node(cell, items, depth);
        };
        let n = old[i as usize];
        if n.is_leaf() || depth >= self.max_depth || items.len() as f32 <= self.max_leaf(depth) {
            // NOTE: `node` makes a leaf of a small list without binning it.
            return self.node(cell, items, depth);
        }
        let (axis, split) = (n.axis(), n.split());
        let [below, above] = n.children(i);
        // A plane that no longer cuts the cell (the root box changes every
        // frame) is dropped: the cell lies on one side of it.
        if split.is_nan() || split <= cell.min[axis] {
            return self.refit_node(old, above, cell, items, depth, levels);
        }
        if split >= cell.max[axis] {
            return self.refit_node(old, below, cell, items, depth, levels);
        }
        self.depth_reached = self.depth_reached.max(depth);
        let count = items.len();
        let (lcell, left, rcell, right) = match self.partition(&cell, items, axis, split) {
            Ok(parts) => parts,
            // Every triangle straddles the plane: the fast builder decides.
            Err(items) => return self.node(cell, items, depth),
        };
        if levels > 0 && count >= PARALLEL_MIN {
            let (mut lb, mut rb) = (self.sub(), self.sub());
            let (lr, rr) = rayon::join(
                || lb.refit_node(old, below, lcell, left, depth + 1, levels - 1),
                || rb.refit_node(old, above, rcell, right, depth + 1, levels - 1),
            );
            lr?;
            rr?;
            self.interior_cost(&cell);
            return self.stitch((axis, split), &lb, &rb);
        }
        let index = self.nodes.len();
        if index >= MAX_NODES as usize {
            return Err(too_many_nodes());
        }
        self.nodes.push(KdNode::interior(axis, split));
        self.interior_cost(&cell);
        self.refit_node(old, below, lcell, left, depth + 1, 0)?;
        let above_at = self.nodes.len() as u32;
        self.nodes[index].set_above_child(above_at);
        self.refit_node(old, above, rcell, right, depth + 1, 0)
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use crate::geom::aabb::Aabb;
    use crate::geom::triangle::Triangle;
    use crate::kd::fast_build::FastParams;
    use crate::kd::tree::{BuilderKind, KdTree};
    use crate::testing::meshgen;
    use crate::testing::oracle::BruteForce;

    /// `tris` moved smoothly at `time`: a wave along x, a drift along z.
    fn moved(tris: &[Triangle], time: f32) -> Vec<Triangle> {
        tris.iter()
            .map(|t| t.map(|v| v + Vec3::new(0.2 * (3.0 * v.y + time).sin(), 0.0, 0.5 * time)))
            .collect()
    }

    fn check(tree: &KdTree, tris: &[Triangle], seed: u64) {
        tree.validate().unwrap();
        let oracle = BruteForce::new(tris);
        let b = tree.bounds();
        for ray in meshgen::random_rays(400, seed, b)
            .into_iter()
            .chain(meshgen::hard_rays(tris, 200, seed + 1))
        {
            oracle.check_closest(&ray, tree.intersect(&ray)).unwrap();
            oracle.check_occluded(&ray, tree.occluded(&ray)).unwrap();
        }
    }

    #[test]
    fn refits_follow_smooth_motion_and_agree_with_the_oracle() {
        let base = meshgen::bumpy_sphere(3000, 5, 0.3);
        let mut tree = KdTree::build_fast(base.clone()).unwrap();
        let mut refitted = 0;
        for f in 1..=12 {
            let tris = moved(&base, f as f32 * 0.1);
            tree = KdTree::refit_fast(&tree, tris.clone(), &FastParams::default()).unwrap();
            assert_eq!(tree.stats().builder, BuilderKind::Fast);
            refitted += usize::from(tree.stats().refitted);
            check(&tree, &tris, 100 + f);
        }
        // Smooth motion keeps the planes good: most frames are refits.
        assert!(refitted >= 10, "{refitted} of 12 frames refitted");
    }

    #[test]
    fn a_tree_refitted_to_other_triangles_is_rebuilt_unless_allowed() {
        let a = meshgen::bumpy_sphere(2000, 7, 0.2);
        let old = KdTree::build_fast(a).unwrap();
        // The fine planes of the small triangles of a sphere cut large
        // triangles in the same box into many references: too costly, so
        // built afresh...
        let b = meshgen::random_soup(2000, 8, old.bounds(), 1.5);
        let t = KdTree::refit_fast(&old, b.clone(), &FastParams::default()).unwrap();
        assert!(!t.stats().refitted);
        check(&t, &b, 1);
        // ...unless any cost is accepted; the hits stay exact.
        let any = FastParams {
            refit_cost_limit: f64::INFINITY,
            ..FastParams::default()
        };
        let t = KdTree::refit_fast(&old, b.clone(), &any).unwrap();
        assert!(t.stats().refitted);
        check(&t, &b, 2);
        // Far away, no old plane cuts the triangles: every one is dropped
        // and the fast builder splits the old leaf further, as afresh.
        let far = meshgen::random_soup(2000, 8, Aabb::new(Vec3::splat(5.0), Vec3::new(9.0, 7.0, 6.0)), 0.1);
        let t = KdTree::refit_fast(&old, far.clone(), &FastParams::default()).unwrap();
        let fresh = KdTree::build_fast(far.clone()).unwrap();
        assert!(t.stats().refitted && t.stats().depth > 3);
        assert_eq!(t.nodes(), fresh.nodes());
        check(&t, &far, 4);
    }

    #[test]
    fn refit_needs_a_fast_tree_and_handles_empty_lists() {
        let a = meshgen::bumpy_sphere(500, 9, 0.2);
        let sah = KdTree::build_sah(a.clone()).unwrap();
        let t = KdTree::refit_fast(&sah, a.clone(), &FastParams::default()).unwrap();
        assert!(!t.stats().refitted && t.stats().builder == BuilderKind::Fast);
        let empty = KdTree::refit_fast(&t, Vec::new(), &FastParams::default()).unwrap();
        assert!(
            empty
                .intersect(&meshgen::random_rays(1, 1, Aabb::new(Vec3::ZERO, Vec3::ONE))[0])
                .is_none()
        );
        let back = KdTree::refit_fast(&empty, a.clone(), &FastParams::default()).unwrap();
        check(&back, &a, 3);
        // Degenerate and non-finite triangles are left out as in a build.
        let mut bad = a.clone();
        bad[0] = [Vec3::ZERO; 3];
        bad[1][2] = Vec3::NAN;
        let t2 = KdTree::refit_fast(&t, bad, &FastParams::default()).unwrap();
        assert_eq!(t2.stats().dropped, 2);
    }

    #[test]
    fn refitted_costs_stay_near_fresh_ones_on_smooth_motion() {
        let base = meshgen::bumpy_sphere(4000, 11, 0.3);
        let mut tree = KdTree::build_fast(base.clone()).unwrap();
        for f in 1..=8 {
            let tris = moved(&base, f as f32 * 0.05);
            tree = KdTree::refit_fast(&tree, tris.clone(), &FastParams::default()).unwrap();
            let fresh = KdTree::build_fast(tris).unwrap();
            let ratio = tree.sah_cost() / fresh.sah_cost();
            assert!(
                ratio < FastParams::default().refit_cost_limit * 1.05,
                "frame {f}: cost x{ratio:.3}"
            );
        }
    }
}
