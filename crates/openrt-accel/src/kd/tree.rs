//! The object kd-tree: build, traversal and invariant checks.

use std::time::Instant;

use crate::error::AccelError;
use crate::geom::aabb::Aabb;
use crate::geom::hit::Hit;
use crate::geom::ray::Ray;
use crate::geom::triangle::Triangle;
use crate::geom::triangle::is_valid_triangle;
use crate::kd::fast_build::{FastParams, build_fast};
use crate::kd::node::{KdNode, MAX_DEPTH, elide_empty_leaves};
use crate::kd::sah_build::{build_sah, clipped_bounds};
use crate::kd::sah_params::{BuiltTree, SahParams};
use crate::kd::traverse::traverse;
use crate::leaf::blocks::{
    BlockRay, LANES, LeafLists, NO_TIE, TriBlock, leaf_any, leaf_closest, leaf_packet, pack_leaves,
};
use crate::leaf::mailbox::TriMailbox;
use crate::packet::boxes::PacketBoxes;
use crate::packet::frustum::Frustum;
use crate::packet::traverse::traverse_packet_laid;
use crate::packet::triangle::{LaneHits, PacketBlockRay};
use crate::packet::width::lanes_of;

/// Largest tree validated automatically after its build in debug-assertion builds.
#[cfg(debug_assertions)]
const DEBUG_VALIDATE_LIMIT: usize = 20_000;

/// `true` when enough of a packet's lanes reach a leaf for the pre-test
/// across lanes (one triangle, `N` lanes) to beat each lane's own pre-test
/// (four triangles, one lane): a third of the lanes (six of 16). Measured
/// on the ray-query probe, alternating: shadow queries 3-9% faster than
/// from a quarter (kitchen, museum4k, terrain), primary ones the same.
#[inline]
fn dense<const N: usize>(active: u32) -> bool {
    active.count_ones() as usize * DENSE_SHARE >= N
}

/// See [`dense`].
const DENSE_SHARE: usize = 3;

/// The packet's frustum for whole-packet triangle culling (`frustum.rs`):
/// the caller's (`given`), else one made from the rays on the first call
/// (`own` keeps it by `make`): [`Frustum::for_intersect`] or
/// [`Frustum::for_occluded`].
fn packet_frustum<'a>(
    given: Option<&'a Frustum>,
    own: &'a std::cell::OnceCell<Option<Frustum>>,
    make: impl FnOnce() -> Option<Frustum>,
) -> Option<&'a Frustum> {
    given.or_else(|| own.get_or_init(make).as_ref())
}

/// Each lane's own pre-test constants.
fn block_rays<const N: usize>(rays: &[Ray; N]) -> [BlockRay; N] {
    std::array::from_fn(|l| BlockRay::new(&rays[l]))
}

/// Which builder made a tree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BuilderKind {
    /// SAH (static and affine objects): binned for large nodes, exact below
    /// (Wald & Havran 2006 costs and planes); see [`SahParams`].
    Sah,
    /// The cheap builder for unstructured motion.
    Fast,
}

/// Figures about a built tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TreeStats {
    /// Which builder made it.
    pub builder: BuilderKind,
    /// Triangles given.
    pub triangles: usize,
    /// Triangles left out: zero area or non-finite vertices.
    pub dropped: usize,
    /// Nodes in the flat array (empty cells have none).
    pub nodes: usize,
    /// Leaf cells, empty ones included.
    pub leaves: usize,
    /// Empty leaf cells among those: flagged in their parent, without a node.
    pub empty_leaves: usize,
    /// Primitive references in leaves (a triangle can be in several).
    pub references: usize,
    /// Deepest leaf.
    pub depth: usize,
    /// Build time in milliseconds.
    pub build_ms: f64,
    /// Made by [`KdTree::refit_fast`] on the planes of an earlier tree
    /// (`false`: built afresh).
    pub refitted: bool,
    /// SAH cost of the last full fast build in this tree's line, as the
    /// builder estimates it ([`KdTree::sah_cost`], also counting interior
    /// nodes whose cells turned out empty): the tree's own cost when it was
    /// built afresh, the cost of the tree it was refitted from otherwise;
    /// 0 for SAH trees, which are never refitted.
    pub base_cost: f64,
    /// Heap bytes held by the tree: nodes, leaf indices (with block
    /// padding), leaf blocks and triangles.
    pub bytes: usize,
}

/// A kd-tree over triangles, in a flat node array with 8-byte nodes.
///
/// The tree owns its triangles; `Hit::prim` is the index of the triangle in
/// the slice given to the builder.
///
/// PERF: besides the triangle array, each leaf's triangles are copied in
/// SIMD blocks of four (144 bytes per block; with ~1.9 references per
/// triangle a tree takes about 120 bytes per triangle, see
/// [`TreeStats::bytes`]) so that a leaf's misses are rejected four at a
/// time; see `leaf_blocks.rs`.
#[derive(Clone, Debug)]
pub struct KdTree {
    nodes: Vec<KdNode>,
    /// Leaf index ranges, each starting at a multiple of the block width;
    /// padding entries between ranges repeat the previous index.
    pub(crate) prim_ids: Vec<u32>,
    /// Block `k` holds the triangles of `prim_ids[k * LANES..][..LANES]`.
    pub(crate) blocks: Vec<TriBlock>,
    /// The triangles as given (`Hit::prim` indexes them); traversal reads
    /// the blocks, validation and the API read these.
    pub(crate) tris: Vec<Triangle>,
    bounds: Aabb,
    stats: TreeStats,
}

impl KdTree {
    /// Builds an SAH tree with default costs: binned planes for nodes above
    /// [`crate::kd::sah_params::DEFAULT_BINNED_ABOVE`] references, every candidate plane of
    /// Wald & Havran 2006 below.
    ///
    /// Zero-area triangles and triangles with non-finite vertices are left
    /// out (counted in [`TreeStats::dropped`]); they can never be hit.
    pub fn build_sah(tris: Vec<Triangle>) -> Result<Self, AccelError> {
        Self::build_sah_with(tris, &SahParams::default())
    }

    /// Builds a full-SAH tree with the given costs.
    pub fn build_sah_with(tris: Vec<Triangle>, params: &SahParams) -> Result<Self, AccelError> {
        let start = Instant::now();
        let valid: Vec<bool> = tris.iter().map(is_valid_triangle).collect();
        let built = build_sah(&tris, &valid, params)?;
        Self::finish(tris, built, BuilderKind::Sah, start)
    }

    /// Builds a tree with the cheap builder for unstructured motion
    /// (binned SAH, leaves growing with depth, shallower; see [`FastParams`]).
    pub fn build_fast(tris: Vec<Triangle>) -> Result<Self, AccelError> {
        Self::build_fast_with(tris, &FastParams::default())
    }

    /// Builds a tree with the cheap builder and the given parameters.
    pub fn build_fast_with(tris: Vec<Triangle>, params: &FastParams) -> Result<Self, AccelError> {
        let start = Instant::now();
        let built = build_fast(&tris, params)?;
        Self::finish(tris, built, BuilderKind::Fast, start)
    }

    /// The tree of `tris` (the triangles of `prev`'s object after they
    /// moved) on the split planes of `prev`, a tree from the fast builder:
    /// see `refit.rs`. When the result's SAH cost exceeds
    /// `params.refit_cost_limit` times [`TreeStats::base_cost`] of `prev`,
    /// or `prev` came from another builder, the tree is built afresh with
    /// [`Self::build_fast_with`]; [`TreeStats::refitted`] tells which.
    pub fn refit_fast(prev: &KdTree, tris: Vec<Triangle>, params: &FastParams) -> Result<Self, AccelError> {
        let start = Instant::now();
        if prev.stats.builder != BuilderKind::Fast {
            return Self::build_fast_with(tris, params);
        }
        let built = crate::kd::refit::refit(&prev.nodes, &tris, params)?;
        let cost = built.cost.unwrap_or(f64::INFINITY);
        if cost > prev.stats.base_cost * params.refit_cost_limit {
            let mut tree = Self::build_fast_with(tris, params)?;
            tree.stats.build_ms = start.elapsed().as_secs_f64() * 1e3;
            return Ok(tree);
        }
        let mut tree = Self::finish(tris, built, BuilderKind::Fast, start)?;
        tree.stats.refitted = true;
        tree.stats.base_cost = prev.stats.base_cost;
        Ok(tree)
    }

    /// Builds with the given builder and its default parameters.
    pub fn build(tris: Vec<Triangle>, builder: BuilderKind) -> Result<Self, AccelError> {
        match builder {
            BuilderKind::Sah => Self::build_sah(tris),
            BuilderKind::Fast => Self::build_fast(tris),
        }
    }

    pub(crate) fn finish(
        tris: Vec<Triangle>,
        built: BuiltTree,
        builder: BuilderKind,
        start: Instant,
    ) -> Result<Self, AccelError> {
        let BuiltTree {
            mut nodes,
            prim_ids,
            bounds,
            depth,
            cost,
            valid,
        } = built;
        let references = prim_ids.len();
        let (prim_ids, blocks) = pack_leaves(&mut nodes, &prim_ids, &tris)?;
        let leaves = nodes.iter().filter(|n| n.is_leaf()).count();
        let empty_leaves = nodes.iter().filter(|n| n.is_leaf() && n.prim_count() == 0).count();
        let nodes = elide_empty_leaves(&nodes)?;
        let stats = TreeStats {
            builder,
            triangles: tris.len(),
            dropped: tris.len() - valid,
            nodes: nodes.len(),
            leaves,
            empty_leaves,
            references,
            depth,
            build_ms: start.elapsed().as_secs_f64() * 1e3,
            refitted: false,
            base_cost: 0.0,
            bytes: size_of_val(nodes.as_slice())
                + size_of_val(prim_ids.as_slice())
                + size_of_val(blocks.as_slice())
                + size_of_val(tris.as_slice()),
        };
        let mut tree = Self {
            nodes,
            prim_ids,
            blocks,
            tris,
            bounds,
            stats,
        };
        tree.stats.base_cost = cost.unwrap_or(0.0);
        // NOTE: every build in a debug-assertion build (all tests) is checked,
        // up to a size where the O(N depth) check stays cheap.
        #[cfg(debug_assertions)]
        if tree.tris.len() <= DEBUG_VALIDATE_LIMIT
            && let Err(e) = tree.validate()
        {
            panic!("{builder:?} build produced an invalid tree: {e}");
        }
        Ok(tree)
    }

    /// Bounds of the valid triangles (the root cell).
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The triangles, indexed by `Hit::prim`.
    #[must_use]
    pub fn triangles(&self) -> &[Triangle] {
        &self.tris
    }

    /// Build figures.
    #[must_use]
    pub fn stats(&self) -> &TreeStats {
        &self.stats
    }

    /// The flat node array (node 0 is the root).
    #[must_use]
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// The triangle indices of a leaf node (empty for interior nodes).
    #[must_use]
    pub fn leaf_primitives(&self, leaf: KdNode) -> &[u32] {
        if !leaf.is_leaf() {
            return &[];
        }
        let off = leaf.prim_offset() as usize;
        self.prim_ids.get(off..off + leaf.prim_count() as usize).unwrap_or(&[])
    }

    /// The closest hit in `(ray.t_min, ray.t_max)`.
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut closest = ray.t_max;
        self.intersect_within(ray, &mut closest)
    }

    /// The closest hit closer than `*closest` (which it lowers on a hit).
    /// Two-level traversal calls this with the distance of the best hit so far.
    #[inline]
    pub fn intersect_within(&self, ray: &Ray, closest: &mut f32) -> Option<Hit> {
        let (t0, t1) = self.bounds.clip(&ray.with_interval(ray.t_min, *closest))?;
        let mut best: Option<Hit> = None;
        let br = BlockRay::new(ray);
        traverse(&self.nodes, ray, t0, t1, closest, |leaf, closest| {
            let tie = best.map_or(NO_TIE, |h| h.prim);
            if let Some((prim, (t, b1, b2))) = leaf_closest(ray, &br, leaf, &self.prim_ids, &self.blocks, *closest, tie)
            {
                *closest = t;
                best = Some(Hit { t, prim, b1, b2 });
            }
            false
        });
        best
    }

    /// `true` when anything is hit in `(ray.t_min, ray.t_max)` (shadow rays).
    #[must_use]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.occluder(ray).is_some()
    }

    /// [`KdTree::occluded`] naming where the ray is blocked: the leaf in
    /// which the walk found a triangle hit in `(ray.t_min, ray.t_max)` (not
    /// necessarily the closest hit's), for [`KdTree::leaf_blocks`].
    #[must_use]
    pub fn occluder(&self, ray: &Ray) -> Option<KdNode> {
        let (t0, t1) = self.bounds.clip(ray)?;
        let mut closest = ray.t_max;
        let br = BlockRay::new(ray);
        let mut found = None;
        traverse(&self.nodes, ray, t0, t1, &mut closest, |leaf, closest| {
            let hit = leaf_any(ray, &br, leaf, &self.prim_ids, &self.blocks, *closest);
            if hit {
                found = Some(leaf);
            }
            hit
        });
        found
    }

    /// `true` when a triangle of `leaf` (a leaf as [`KdTree::occluder`]
    /// names them; a node that is not a leaf, or whose lists do not lie in
    /// this tree's, gives `false`) is hit by `ray` at least `margin` inside
    /// the ray's interval (relative to its length) and inside the triangle
    /// (each barycentric coordinate): a hit that no rounding of the walk can
    /// lose, so [`KdTree::occluded`] is `true` for that ray too. A finite
    /// interval is required.
    #[must_use]
    pub fn leaf_blocks(&self, ray: &Ray, leaf: KdNode, margin: f32) -> bool {
        self.lists().blocks_ray(ray, leaf, margin)
    }

    /// [`KdTree::leaf_blocks`] for the `lanes` of a packet: the lanes blocked
    /// so.
    #[must_use]
    pub fn leaf_blocks_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32, leaf: KdNode, margin: f32) -> u32 {
        self.lists().blocks_packet(rays, lanes, leaf, margin)
    }

    /// The leaf lists, for the queries shared with the BVH.
    fn lists(&self) -> LeafLists<'_> {
        LeafLists {
            ids: &self.prim_ids,
            blocks: &self.blocks,
        }
    }

    /// [`KdTree::intersect_within`] for the rays of the `lanes` mask at
    /// once: lane `l` gets exactly the answer of
    /// `intersect_within(&rays[l], &mut closest[l])`, written to `hits[l]`
    /// when there is one (other entries are left as they are). Returns the
    /// lanes that found a closer hit.
    ///
    /// Lanes that share direction signs walk the tree as a packet
    /// ([`crate::traverse_packet`]); each lane tests its leaves' triangles
    /// with the scalar kernel's exact arithmetic.
    pub fn intersect_packet<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        closest: &mut [f32; N],
        hits: &mut [Option<Hit>; N],
    ) -> u32 {
        self.intersect_packet_in(rays, lanes, closest, hits, None, None)
    }

    /// [`KdTree::intersect_packet`] with the packet's frustum when the
    /// caller has it (one of the rays of a larger mask, such as the world
    /// frustum of a packet that an instance without a transform sees as
    /// it is); `None`: made from the rays when a leaf first needs it. Likewise
    /// `laid_out`: `rays` laid out lane by lane, which clips them to the
    /// tree's box without reading them again ([`PacketBoxes::clip`]).
    pub fn intersect_packet_in<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        closest: &mut [f32; N],
        hits: &mut [Option<Hit>; N],
        frustum: Option<&Frustum>,
        laid_out: Option<&PacketBoxes<N>>,
    ) -> u32 {
        let (t0, t1, live) = match laid_out {
            Some(b) => b.clip(&self.bounds, lanes, closest),
            None => self.bounds.clip_lanes(rays, lanes, closest),
        };
        if live == 0 {
            return 0;
        }
        let mut found = 0u32;
        // PERF: lanes sharing the axis permutation (nearly every coherent
        // packet) pre-test each triangle against all lanes at once, unless
        // few lanes reach the leaf: then each lane pre-tests four
        // triangles at a time on its own (`dense`).
        let pbr = PacketBlockRay::new_in(rays, laid_out, live);
        let own = std::cell::OnceCell::new();
        // PERF: made on the first sparse leaf only (dense leaves need none).
        let mut brs: Option<[BlockRay; N]> = None;
        let mut tested = TriMailbox::new();
        // Each lane's best triangle in this walk, for the tie rule.
        let mut ties = [NO_TIE; N];
        traverse_packet_laid(
            &self.nodes,
            rays,
            laid_out,
            live,
            &t0,
            &t1,
            closest,
            |leaf, active, closest| {
                if let Some(pbr) = pbr.as_ref().filter(|_| dense::<N>(active)) {
                    let f = packet_frustum(frustum, &own, || Frustum::for_intersect(rays, live));
                    self.leaf_packet(
                        pbr,
                        rays,
                        f,
                        active,
                        leaf,
                        closest,
                        Some(&mut ties),
                        Some(&mut tested),
                        |h, prim, closest| {
                            for l in lanes_of(h.hit) {
                                let (t, b1, b2) = h.lane(l);
                                closest[l] = t;
                                hits[l] = Some(Hit { t, prim, b1, b2 });
                            }
                            found |= h.hit;
                            0
                        },
                    );
                    return 0;
                }
                let brs = brs.get_or_insert_with(|| block_rays(rays));
                for l in lanes_of(active) {
                    if let Some((prim, (t, b1, b2))) = leaf_closest(
                        &rays[l],
                        &brs[l],
                        leaf,
                        &self.prim_ids,
                        &self.blocks,
                        closest[l],
                        ties[l],
                    ) {
                        ties[l] = prim;
                        closest[l] = t;
                        hits[l] = Some(Hit { t, prim, b1, b2 });
                        found |= 1 << l;
                    }
                }
                0
            },
        );
        found
    }

    /// [`KdTree::occluded`] for the rays of the `lanes` mask at once: the
    /// mask of the lanes whose ray hits something in its interval.
    #[must_use]
    pub fn occluded_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> u32 {
        self.occluded_packet_in(rays, lanes, None)
    }

    /// [`KdTree::occluded_packet`] with the packet's frustum when the caller
    /// has it (see [`KdTree::intersect_packet_in`]).
    #[must_use]
    pub fn occluded_packet_in<const N: usize>(&self, rays: &[Ray; N], lanes: u32, frustum: Option<&Frustum>) -> u32 {
        self.occluder_packet_in(rays, lanes, frustum, None).0
    }

    /// [`KdTree::occluded_packet_in`], also naming the leaf where one of
    /// the blocked lanes was blocked (the first found), as [`KdTree::occluder`].
    #[must_use]
    pub fn occluder_packet_in<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        frustum: Option<&Frustum>,
        laid_out: Option<&PacketBoxes<N>>,
    ) -> (u32, Option<KdNode>) {
        let mut closest: [f32; N] = std::array::from_fn(|l| rays[l].t_max);
        let (t0, t1, live) = match laid_out {
            Some(b) => b.clip(&self.bounds, lanes, &closest),
            None => self.bounds.clip_lanes(rays, lanes, &closest),
        };
        if live == 0 {
            return (0, None);
        }
        let pbr = PacketBlockRay::new_in(rays, laid_out, live);
        let own = std::cell::OnceCell::new();
        // PERF: made on the first sparse leaf only (dense leaves need none).
        let mut brs: Option<[BlockRay; N]> = None;
        let mut found = None;
        let mut tested = TriMailbox::new();
        let blocked = traverse_packet_laid(
            &self.nodes,
            rays,
            laid_out,
            live,
            &t0,
            &t1,
            &mut closest,
            |leaf, active, closest| {
                if let Some(pbr) = pbr.as_ref().filter(|_| dense::<N>(active)) {
                    let f = packet_frustum(frustum, &own, || Frustum::for_occluded(rays, live));
                    let hit = self.leaf_packet(
                        pbr,
                        rays,
                        f,
                        active,
                        leaf,
                        closest,
                        None,
                        Some(&mut tested),
                        |h, _, _| h.hit,
                    );
                    if hit != 0 {
                        found = found.or(Some(leaf));
                    }
                    return hit;
                }
                let brs = brs.get_or_insert_with(|| block_rays(rays));
                let mut hit = 0u32;
                for l in lanes_of(active) {
                    if leaf_any(&rays[l], &brs[l], leaf, &self.prim_ids, &self.blocks, closest[l]) {
                        hit |= 1 << l;
                        found = found.or(Some(leaf));
                    }
                }
                hit
            },
        );
        (blocked, found)
    }

    /// [`leaf_packet`] over this tree's leaf lists and blocks.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn leaf_packet<const N: usize>(
        &self,
        pbr: &PacketBlockRay<N>,
        rays: &[Ray; N],
        frustum: Option<&Frustum>,
        lanes: u32,
        leaf: KdNode,
        closest: &mut [f32; N],
        ties: Option<&mut [u32; N]>,
        tested: Option<&mut TriMailbox>,
        visit: impl FnMut(&LaneHits, u32, &mut [f32; N]) -> u32,
    ) -> u32 {
        leaf_packet(
            pbr,
            rays,
            frustum,
            lanes,
            leaf,
            &self.prim_ids,
            &self.blocks,
            closest,
            ties,
            tested,
            visit,
        )
    }

    /// The tree's expected cost under the surface area heuristic with the
    /// default costs: each interior node costs a traversal step and each
    /// leaf a test per reference, weighted by the probability that a random
    /// ray hitting the root cell hits the node's cell. Lower is better;
    /// compares trees over the same triangles.
    #[must_use]
    pub fn sah_cost(&self) -> f64 {
        let p = SahParams::default();
        let root_sa = f64::from(self.bounds.surface_area());
        if root_sa <= 0.0 || !root_sa.is_finite() {
            return 0.0;
        }
        let mut cost = 0.0;
        for (n, cell) in self.cells() {
            let w = f64::from(cell.surface_area()) / root_sa;
            cost += w * if n.is_leaf() {
                f64::from(p.intersection_cost) * f64::from(n.prim_count())
            } else {
                f64::from(p.traversal_cost)
            };
        }
        cost
    }

    /// Every node with its cell, depth first (empty cells have no node).
    #[must_use]
    pub fn cells(&self) -> Vec<(KdNode, Aabb)> {
        let mut out = Vec::with_capacity(self.nodes.len());
        let mut stack = vec![(0u32, self.bounds)];
        while let Some((i, cell)) = stack.pop() {
            let n = self.nodes[i as usize];
            out.push((n, cell));
            if n.is_leaf() {
                continue;
            }
            let (mut below, mut above) = (cell, cell);
            below.max[n.axis()] = n.split();
            above.min[n.axis()] = n.split();
            let [b, a] = n.children(i);
            stack.extend(a.map(|a| (a, above)));
            stack.extend(b.map(|b| (b, below)));
        }
        out
    }

    /// Checks every structural invariant of the tree:
    /// - child indices point forward and inside the array, every node is
    ///   reached exactly once, depth stays under the traversal stack;
    /// - split planes are finite and lie inside their cell;
    /// - leaf ranges lie inside the index array, indices name valid triangles,
    ///   no leaf names a triangle twice, every reference overlaps its cell;
    /// - every valid triangle is referenced, and every point sampled on a
    ///   triangle (vertices, edge midpoints, centroid) lies in a leaf that
    ///   references it; degenerate triangles are never referenced.
    pub fn validate(&self) -> Result<(), AccelError> {
        let err = |s: String| Err(AccelError::Invalid(s));
        if self.nodes.is_empty() {
            return err("no root node".into());
        }
        let valid: Vec<bool> = self.tris.iter().map(is_valid_triangle).collect();
        let mut seen = vec![false; self.nodes.len()];
        let mut referenced = vec![false; self.tris.len()];
        let mut stack = vec![(0u32, self.bounds, 0usize)];
        while let Some((i, cell, depth)) = stack.pop() {
            let iu = i as usize;
            if iu >= self.nodes.len() {
                return err(format!("node index {i} out of range"));
            }
            if std::mem::replace(&mut seen[iu], true) {
                return err(format!("node {i} reached twice"));
            }
            if depth >= MAX_DEPTH {
                return err(format!("depth {depth} exceeds the stack of {MAX_DEPTH}"));
            }
            let n = self.nodes[iu];
            if n.is_leaf() {
                let (off, cnt) = (n.prim_offset() as usize, n.prim_count() as usize);
                if cnt == 0 && i != 0 {
                    return err(format!("leaf {i} is empty: empty cells have no node"));
                }
                let Some(list) = self.prim_ids.get(off..off + cnt) else {
                    return err(format!("leaf {i} range {off}+{cnt} outside the index array"));
                };
                if off % LANES != 0 {
                    return err(format!("leaf {i} range starts at {off}, not at a block boundary"));
                }
                let Some(padded) = self.prim_ids.get(off..off + cnt.div_ceil(LANES) * LANES) else {
                    return err(format!("leaf {i}: padded range {off}+{cnt} outside the index array"));
                };
                for (k, &p) in padded.iter().enumerate() {
                    let expect = list[k.min(cnt - 1)];
                    let block = self.blocks.get((off + k) / LANES);
                    let same = block.is_some_and(|b| {
                        let packed = b.triangle(k % LANES);
                        let stored = self.tris.get(p as usize);
                        stored.is_some_and(|t| {
                            (0..3).all(|v| packed[v].to_array().map(f32::to_bits) == t[v].to_array().map(f32::to_bits))
                        })
                    });
                    if p != expect || !same {
                        return err(format!("leaf {i}: block lane {k} does not hold triangle {expect}"));
                    }
                }
                let mut sorted = list.to_vec();
                sorted.sort_unstable();
                if sorted.windows(2).any(|w| w[0] == w[1]) {
                    return err(format!("leaf {i} names a triangle twice"));
                }
                for &p in list {
                    let pu = p as usize;
                    if pu >= self.tris.len() || !valid[pu] {
                        return err(format!("leaf {i} names invalid triangle {p}"));
                    }
                    referenced[pu] = true;
                    if Aabb::from_points(&self.tris[pu]).intersection(cell).is_empty() {
                        return err(format!("leaf {i}: triangle {p} does not overlap its cell"));
                    }
                }
                continue;
            }
            let (axis, split) = (n.axis(), n.split());
            if !split.is_finite() || split < cell.min[axis] || split > cell.max[axis] {
                return err(format!("node {i}: split {split} on axis {axis} outside its cell"));
            }
            let (above, first) = (n.above_child(), if n.below_empty() { i + 1 } else { i + 2 });
            match n.children(i) {
                [None, None] => return err(format!("node {i}: both cells empty, not a leaf")),
                [_, Some(a)] if a < first => {
                    return err(format!("node {i}: above child {a} does not point past its below child"));
                }
                [None, Some(a)] if a != i + 1 => {
                    return err(format!("node {i}: below cell empty but above child {a} is not next"));
                }
                _ => {}
            }
            let (mut l, mut r) = (cell, cell);
            l.max[axis] = split;
            r.min[axis] = split;
            if !n.below_empty() {
                stack.push((i + 1, l, depth + 1));
            }
            if above != 0 {
                stack.push((above, r, depth + 1));
            }
        }
        if let Some(i) = seen.iter().position(|s| !s) {
            return err(format!("node {i} is unreachable"));
        }
        if let Some(p) = (0..self.tris.len()).find(|&p| valid[p] && !referenced[p]) {
            return err(format!("triangle {p} is in no leaf"));
        }
        for (p, tri) in self.tris.iter().enumerate() {
            if !valid[p] {
                continue;
            }
            // Sample points in f64 so they lie exactly on the triangle.
            let [a, b, c] = tri.map(|v| v.as_dvec3());
            let samples = [a, b, c, (a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5, (a + b + c) / 3.0];
            for s in samples {
                if !self.point_leaves_reference(s, p as u32) {
                    return err(format!("point {s} of triangle {p} lies in no leaf that names it"));
                }
            }
        }
        Ok(())
    }

    /// `true` when some leaf whose closed cell contains `p` references `prim`.
    fn point_leaves_reference(&self, p: glam::DVec3, prim: u32) -> bool {
        let mut stack = vec![0u32];
        while let Some(i) = stack.pop() {
            let n = self.nodes[i as usize];
            if n.is_leaf() {
                let off = n.prim_offset() as usize;
                if self.prim_ids[off..off + n.prim_count() as usize].contains(&prim) {
                    return true;
                }
                continue;
            }
            let (axis, split) = (n.axis(), f64::from(n.split()));
            let [below, above] = n.children(i);
            if p[axis] <= split {
                stack.extend(below);
            }
            if p[axis] >= split {
                stack.extend(above);
            }
        }
        false
    }

    /// Bounds of the part of triangle `prim` inside `cell` (for tests and tools).
    #[must_use]
    pub fn clipped_triangle_bounds(&self, prim: u32, cell: &Aabb) -> Aabb {
        clipped_bounds(&self.tris[prim as usize], cell)
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::testing::meshgen;

    /// Every non-empty leaf of `tree`.
    fn leaves(tree: &KdTree) -> Vec<KdNode> {
        tree.nodes()
            .iter()
            .copied()
            .filter(|n| n.is_leaf() && n.prim_count() > 0)
            .collect()
    }

    #[test]
    fn a_leaf_settles_only_hits_well_inside_and_never_one_the_walk_misses() {
        let tris = meshgen::bumpy_sphere(2_000, 21, 0.3);
        let tree = KdTree::build_sah(tris.clone()).unwrap();
        let b = tree.bounds();
        let margin = 1e-3;
        let mut settled = 0;
        // Segments from outside the sphere to points around it (shadow rays).
        let rays: Vec<Ray> = meshgen::random_rays(300, 5, b)
            .into_iter()
            .map(|r| Ray::new(r.origin, r.dir * 3.0, 0.0, 1.0 - 1e-4))
            .chain(
                meshgen::hard_rays(&tris, 100, 6)
                    .into_iter()
                    .map(|r| Ray::new(r.origin, r.dir, 0.0, 50.0)),
            )
            .collect();
        for r in &rays {
            let walk = tree.occluded(r);
            assert_eq!(tree.occluder(r).is_some(), walk);
            for leaf in leaves(&tree) {
                if tree.leaf_blocks(r, leaf, margin) {
                    settled += 1;
                    assert!(walk, "a leaf settled {r:?}, which the walk finds unblocked");
                }
            }
            // A blocked ray's own leaf: settles it unless its hits lie near
            // an edge or an end of the interval.
            if let Some(leaf) = tree.occluder(r) {
                assert!(tree.lists().owns(leaf));
            }
        }
        assert!(settled > 100, "{settled} settlements");
        // Not a leaf of the tree: nothing, and no panic.
        let r = &rays[0];
        for bogus in [
            KdNode::leaf(u32::MAX - 64, 7),
            KdNode::leaf(1, 3),
            KdNode::interior(0, 0.5),
        ] {
            assert!(!tree.leaf_blocks(r, bogus, margin));
            let pk: [Ray; 4] = std::array::from_fn(|l| rays[l]);
            assert_eq!(tree.leaf_blocks_packet(&pk, 0xF, bogus, margin), 0);
        }
    }

    #[test]
    fn the_margin_keeps_hits_near_an_edge_or_an_end_of_the_interval_out() {
        // One triangle in the plane z = 0 with vertices (0,0), (1,0), (0,1).
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let tree = KdTree::build_sah(vec![tri]).unwrap();
        let leaf = leaves(&tree)[0];
        let down = |x: f32, y: f32, t_max: f32| Ray::new(Vec3::new(x, y, 1.0), Vec3::new(0.0, 0.0, -2.0), 0.0, t_max);
        let m = 1e-3;
        // The middle of the triangle, half way along the segment.
        assert!(tree.leaf_blocks(&down(0.25, 0.25, 1.0), leaf, m));
        // Near an edge (b1 = 1e-4), and a hit at 0.9999 of the interval.
        assert!(!tree.leaf_blocks(&down(1e-4, 0.25, 1.0), leaf, m));
        assert!(tree.leaf_blocks(&down(1e-4, 0.25, 1.0), leaf, 0.0));
        assert!(!tree.leaf_blocks(&down(0.25, 0.25, 0.50005), leaf, m));
        assert!(tree.leaf_blocks(&down(0.25, 0.25, 0.50005), leaf, 0.0));
        // An infinite interval has no inside.
        assert!(!tree.leaf_blocks(
            &Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, 0.0, f32::INFINITY),
            leaf,
            m
        ));
        // The packet form, lane by lane.
        let pk = [
            down(0.25, 0.25, 1.0),
            down(1e-4, 0.25, 1.0),
            down(0.25, 0.25, 0.50005),
            down(0.3, 0.2, 1.0),
        ];
        assert_eq!(tree.leaf_blocks_packet(&pk, 0xF, leaf, m), 0b1001);
        assert_eq!(tree.leaf_blocks_packet(&pk, 0b0110, leaf, m), 0);
    }
}
