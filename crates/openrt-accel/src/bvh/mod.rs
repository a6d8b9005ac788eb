//! The wide BVH: an object structure beside the kd-tree.
//!
//! Four children per node with their boxes in SIMD order (`node.rs`), a
//! binned SAH build grown directly into wide nodes (`build.rs`), single-ray
//! traversal testing a node's four boxes at once (`walk.rs`), on AVX2 CPUs
//! an eight-wide copy for single rays (`node8.rs`, `walk8.rs`), and refits
//! for deforming objects (`refit.rs`). Leaves reuse the kd-tree's triangle
//! blocks and kernels, so a BVH finds the same hits, bit for bit, as a
//! kd-tree over the same triangles (tested against each other and the f64
//! oracle).
//!
//! Papers: Wald, Boulos & Shirley, *Ray tracing deformable scenes using
//! dynamic bounding volume hierarchies* (ACM TOG 2007: BVHs refitted for
//! deforming objects); Wald, *On fast construction of SAH-based bounding
//! volume hierarchies* (IEEE RT 2007: binning); Wald, Benthin & Boulos,
//! *Getting rid of packets* (IEEE RT 2008) and Ernst & Greiner, *Multi
//! bounding volume hierarchies* (IEEE RT 2008: wide nodes for single rays).

mod build;
mod instances;
mod node;
mod node8;
mod packet;
mod presplit;
mod refit;
mod walk;
#[cfg(target_arch = "x86_64")]
mod walk8;

use std::time::Instant;

pub use build::BVH_MAX_LEAF;
pub use instances::{INSTANCE_BVH_MAX, INSTANCE_BVH_POOL_MIN, INSTANCE_BVH_TASK_MIN, InstanceBvh};
pub use node::{BVH_MAX_DEPTH, BVH_WIDTH, BvhNode, BvhSlot};
pub use presplit::{BVH_PRESPLIT_BUDGET, BVH_PRESPLIT_MAX_PIECES, BVH_PRESPLIT_MIN_WASTE};

use crate::error::AccelError;
use crate::geom::aabb::Aabb;
use crate::geom::hit::Hit;
use crate::geom::ray::Ray;
use crate::geom::triangle::Triangle;
use crate::geom::triangle::is_valid_triangle;
use crate::kd::node::KdNode;
use crate::leaf::blocks::{BlockRay, LANES, LeafLists, NO_TIE, TriBlock, leaf_any, leaf_closest, leaf_packet};
use crate::packet::boxes::PacketBoxes;
use crate::packet::frustum::Frustum;
use crate::packet::triangle::PacketBlockRay;
use crate::packet::width::lanes_of;
use build::{Ref, bounds_of, build_into};
use node::{EMPTY_SLOT, LEAF_BIT};
use node8::Node8;

/// Whether single rays walk an eight-wide copy of each BVH: on x86-64 CPUs
/// with AVX2, unless `OPENRT_BVH_WIDTH=4` (read once; for measurements side
/// by side).
fn wide8() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static WIDE8: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *WIDE8.get_or_init(|| crate::packet::width::avx2() && std::env::var("OPENRT_BVH_WIDTH").as_deref() != Ok("4"))
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// Walks `bvh`'s eight-wide copy when it has one, else its four-wide nodes
/// (`walk::walk`'s contract).
#[inline]
fn walk_single<L>(bvh: &Bvh, ray: &Ray, closest: &mut f32, leaf: L) -> bool
where
    L: FnMut(u32, u32, &mut f32) -> bool,
{
    #[cfg(target_arch = "x86_64")]
    if !bvh.nodes8.is_empty() {
        // SAFETY: the copy is made only on CPUs with AVX2 (`wide8`).
        return unsafe { walk8::walk8(&bvh.nodes8, ray, closest, leaf) };
    }
    walk::walk(&bvh.nodes, ray, closest, leaf)
}

/// Most triangles a BVH takes: leaf offsets and node indices stay below
/// bit 31 with room for the blocks' padding.
pub const BVH_MAX_PRIMITIVES: usize = 1 << 28;

/// Refits whose SAH cost grew past this factor of the last full build's are
/// rebuilt afresh (the kd-tree's refit uses the same factor).
///
/// PERF: at 1.5 the museums' Whitted frames with refitted BVHs took 1.08x
/// and 1.16x (museum4k, museum16k) those with fresh ones; at 1.25 they
/// match them (0.93-0.99x, bench builders table) while most frames are
/// still refits.
pub const BVH_REFIT_COST_LIMIT: f64 = crate::kd::fast_build::DEFAULT_REFIT_COST_LIMIT;

/// Largest tree validated automatically after its build in debug-assertion builds.
#[cfg(debug_assertions)]
const DEBUG_VALIDATE_LIMIT: usize = 20_000;

/// Figures about a built BVH.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhStats {
    /// Triangles given.
    pub triangles: usize,
    /// Triangles left out: zero area or non-finite vertices.
    pub dropped: usize,
    /// Wide nodes.
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Deepest wide level (the root is level 1).
    pub depth: usize,
    /// Build or refit time in milliseconds.
    pub build_ms: f64,
    /// Made by [`Bvh::refit`] from an earlier tree.
    pub refitted: bool,
    /// SAH cost (expected node visits and triangle blocks per ray).
    pub sah_cost: f64,
    /// SAH cost of the last full build in this tree's line of refits.
    pub base_cost: f64,
    /// Heap bytes: nodes, leaf indices, blocks and triangles.
    pub bytes: usize,
    /// References added by pre-splitting ([`Bvh::build_presplit`]); 0
    /// for a plain build.
    pub presplit: usize,
}

/// A wide BVH over triangles (see the module docs). `Hit::prim` is the
/// index of the triangle in the slice given to the builder.
#[derive(Clone, Debug)]
pub struct Bvh {
    nodes: Vec<BvhNode>,
    /// The same tree collapsed to eight-wide nodes for single rays, on CPUs
    /// with AVX2 (`node8.rs`, `walk8.rs`); empty elsewhere.
    nodes8: Vec<Node8>,
    prim_ids: Vec<u32>,
    blocks: Vec<TriBlock>,
    tris: Vec<Triangle>,
    bounds: Aabb,
    stats: BvhStats,
}

/// `true` when enough of a packet's lanes reach a leaf for the test across
/// lanes (one triangle, all lanes) to beat each lane's own (four triangles,
/// one lane): a third of the lanes, as in the kd-tree's packets.
#[inline]
fn dense<const N: usize>(active: u32) -> bool {
    active.count_ones() as usize * 3 >= N
}

/// Packets of which at most one lane in [`ALONE_SHARE`] enters the tree
/// walk those lanes alone, one by one.
///
/// PERF: the single-ray walk (eight boxes a step on AVX2 CPUs, no lane
/// bookkeeping) answers a few lanes sooner: shadow queries museum4k 0.93,
/// kitchen 0.97 of the time; primary queries terrain 0.96-0.98 (its trees'
/// foliage parts the lanes), kitchen, robots and museum4k within noise;
/// walking every lane alone made kitchen shadows 1.7x slower (terrain's
/// 0.7x); alone at half the lanes: terrain primary no better.
const ALONE_SHARE: usize = 3;

/// Any-hit packets whose frustum spreads wider than this
/// ([`Frustum::spread`], units of the dominant axis) give each leaf only the
/// lanes that meet its box ([`packet::Cull::with_exact_leaves`]).
///
/// PERF: scattered shadow rays towards one light (bounce hits) carried
/// lanes into leaves their rays miss: 4.8 leaf visits and 24.5 triangle
/// tests per lane, against a single ray's 1.8 and 8.4 (kitchen). Whitted
/// frames (ab-alternate): kitchen 0.98, terrain 0.95, museum1k 0.99, robots
/// and museum4k 1.00-1.01; at 0 (every any-hit packet) the coherent shadow
/// rays of primary hits lost 4-5% (kitchen, museum4k query table), at 0.05
/// the terrain gained nothing.
pub(crate) const EXACT_LEAF_SPREAD: f32 = 0.01;

/// `true` when few enough of the `N` lanes are `live` to walk alone.
#[inline]
fn few<const N: usize>(live: u32) -> bool {
    live.count_ones() as usize * ALONE_SHARE <= N
}

/// What a packet walk needs made once: the frustum (the caller's, else
/// one made from the rays: [`Frustum::for_intersect`] or
/// [`Frustum::for_occluded`]) and, for
/// packets without one, the lanes laid out for the interval culling (the
/// caller's, else made here).
struct Prepared<'a, const N: usize> {
    given: Option<&'a Frustum>,
    own: Option<Frustum>,
    laid_out: Option<&'a PacketBoxes<N>>,
    own_boxes: Option<PacketBoxes<N>>,
}

impl<'a, const N: usize> Prepared<'a, N> {
    fn new(
        rays: &[Ray; N],
        live: u32,
        given: Option<&'a Frustum>,
        laid_out: Option<&'a PacketBoxes<N>>,
        make: impl FnOnce(&[Ray; N], Option<&PacketBoxes<N>>, u32) -> Option<Frustum>,
    ) -> Self {
        let own = given.is_none().then(|| make(rays, laid_out, live)).flatten();
        // PERF: the lanes are laid out only for the intervals, which a
        // packet with a frustum does not use (an instance with a transform
        // laid them out at every entry: terrain packets).
        let needs_boxes = given.is_none() && own.is_none() && laid_out.is_none();
        let own_boxes = needs_boxes.then(|| PacketBoxes::new(rays, live));
        Self {
            given,
            own,
            laid_out,
            own_boxes,
        }
    }

    fn frustum(&self) -> Option<&Frustum> {
        self.given.or(self.own.as_ref())
    }

    /// The packet's culling: its frustum, else intervals over its lanes.
    fn cull(&self, live: u32) -> packet::Cull<'_> {
        packet::Cull::of(self.frustum(), self.laid_out.or(self.own_boxes.as_ref()), live)
    }
}

/// Refuses more than [`BVH_MAX_PRIMITIVES`] triangles.
fn check_count(count: usize) -> Result<(), AccelError> {
    if count > BVH_MAX_PRIMITIVES {
        return Err(AccelError::TooManyPrimitives {
            count,
            limit: BVH_MAX_PRIMITIVES,
        });
    }
    Ok(())
}

/// The references of the valid triangles.
fn refs_of(tris: &[Triangle]) -> Vec<Ref> {
    tris.iter()
        .enumerate()
        .filter(|(_, t)| is_valid_triangle(t))
        .map(|(i, t)| Ref::new(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]), i as u32))
        .collect()
}

impl Bvh {
    /// Builds a BVH with the binned SAH (`build.rs`); on a pool's thread,
    /// large subtrees are built in parallel on that pool.
    ///
    /// Zero-area triangles and triangles with non-finite vertices are left
    /// out (counted in [`BvhStats::dropped`]).
    pub fn build(tris: Vec<Triangle>) -> Result<Self, AccelError> {
        Self::build_with(tris, 0.0)
    }

    /// [`Bvh::build`] after pre-splitting the triangles whose boxes waste
    /// the most area (`presplit.rs`; up to [`BVH_PRESPLIT_BUDGET`] extra
    /// references per triangle): for objects built once. A triangle may
    /// then sit in several leaves; every query's answer is the same.
    pub fn build_presplit(tris: Vec<Triangle>) -> Result<Self, AccelError> {
        Self::build_with(tris, BVH_PRESPLIT_BUDGET)
    }

    /// The build with `budget` extra references per triangle.
    fn build_with(tris: Vec<Triangle>, budget: f32) -> Result<Self, AccelError> {
        let start = Instant::now();
        check_count(tris.len())?;
        let mut refs = refs_of(&tris);
        let bounds = bounds_of(&refs);
        let valid = refs.len();
        // Truncated: a whole number of references, within the index limit.
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            clippy::cast_precision_loss
        )]
        let extra = ((valid as f32 * budget) as usize).min(BVH_MAX_PRIMITIVES.saturating_sub(valid));
        if extra > 0 {
            refs = presplit::presplit(&tris, refs, &bounds, extra);
        }
        let presplit = refs.len() - valid;
        let mut nodes = Vec::with_capacity(refs.len() / 2 + 1);
        let mut depth = 0;
        if !refs.is_empty() {
            let task_min = if rayon::current_thread_index().is_some() {
                build::BVH_TASK_MIN
            } else {
                usize::MAX
            };
            depth = build_into(&mut refs, 0, bounds, None, 0, task_min, &mut nodes);
        }
        let ids: Vec<u32> = refs.iter().map(Ref::id).collect();
        let (prim_ids, blocks, leaves) = pack(&mut nodes, &ids, &tris);
        let mut bvh = Self {
            nodes,
            nodes8: Vec::new(),
            prim_ids,
            blocks,
            bounds,
            stats: BvhStats {
                triangles: tris.len(),
                dropped: tris.len() - valid,
                nodes: 0,
                leaves,
                depth,
                build_ms: 0.0,
                refitted: false,
                sah_cost: 0.0,
                base_cost: 0.0,
                bytes: 0,
                presplit,
            },
            tris,
        };
        bvh.stats.sah_cost = bvh.sah_cost();
        bvh.stats.base_cost = bvh.stats.sah_cost;
        bvh.finish(start);
        Ok(bvh)
    }

    /// Fills in the figures every build and refit reports, and checks the
    /// tree in debug-assertion builds.
    ///
    /// A built tree gets its eight-wide copy here; a refitted one keeps the
    /// four-wide walk (PERF: a collapse costs about half a refit: 2 ms at
    /// 100k triangles).
    fn finish(&mut self, start: Instant) {
        self.nodes8 = if wide8() && !self.stats.refitted {
            node8::collapse(&self.nodes)
        } else {
            Vec::new()
        };
        self.stats.nodes = self.nodes.len();
        self.stats.bytes = size_of_val(self.nodes.as_slice())
            + size_of_val(self.nodes8.as_slice())
            + size_of_val(self.prim_ids.as_slice())
            + size_of_val(self.blocks.as_slice())
            + size_of_val(self.tris.as_slice());
        self.stats.build_ms = start.elapsed().as_secs_f64() * 1e3;
        #[cfg(debug_assertions)]
        if self.tris.len() <= DEBUG_VALIDATE_LIMIT
            && let Err(e) = self.validate()
        {
            panic!("BVH build produced an invalid tree: {e}");
        }
    }

    /// Bounds of the valid triangles.
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
    pub fn stats(&self) -> &BvhStats {
        &self.stats
    }

    /// The flat node array (node 0 is the root).
    #[must_use]
    pub fn nodes(&self) -> &[BvhNode] {
        &self.nodes
    }

    /// The triangle indices of a leaf (empty for a slot that is no leaf of
    /// this tree).
    #[must_use]
    pub fn leaf_primitives(&self, slot: BvhSlot) -> &[u32] {
        match slot {
            BvhSlot::Leaf { offset, count } => self
                .prim_ids
                .get(offset as usize..offset as usize + count as usize)
                .unwrap_or(&[]),
            _ => &[],
        }
    }

    /// Every leaf, named as [`Bvh::occluder`] names them (for hints).
    #[must_use]
    pub fn leaves(&self) -> Vec<KdNode> {
        self.nodes
            .iter()
            .flat_map(|n| (0..BVH_WIDTH).map(|i| n.slot(i)))
            .filter_map(|s| match s {
                BvhSlot::Leaf { offset, count } => Some(KdNode::leaf(offset, count)),
                _ => None,
            })
            .collect()
    }

    /// SAH cost: expected node visits plus triangle blocks tested per ray
    /// entering the root box.
    #[must_use]
    pub fn sah_cost(&self) -> f64 {
        let root = f64::from(self.bounds.surface_area());
        if self.nodes.is_empty() || root <= 0.0 || !root.is_finite() {
            return 0.0;
        }
        let mut cost = 1.0;
        for node in &self.nodes {
            for i in 0..BVH_WIDTH {
                let a = f64::from(node.child_box(i).surface_area()) / root;
                match node.slot(i) {
                    BvhSlot::Empty => {}
                    BvhSlot::Node(_) => cost += a,
                    BvhSlot::Leaf { count, .. } => cost += a * f64::from(count.div_ceil(LANES as u32)),
                }
            }
        }
        cost
    }

    /// The closest hit in `(ray.t_min, ray.t_max)`.
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut closest = ray.t_max;
        self.intersect_within(ray, &mut closest)
    }

    /// The closest hit closer than `*closest` (which it lowers on a hit):
    /// the answer of [`crate::KdTree::intersect_within`] over the same
    /// triangles.
    #[inline]
    pub fn intersect_within(&self, ray: &Ray, closest: &mut f32) -> Option<Hit> {
        self.bounds.clip(&ray.with_interval(ray.t_min, *closest))?;
        let mut best: Option<Hit> = None;
        let br = BlockRay::new(ray);
        walk_single(self, ray, closest, |off, count, closest| {
            let leaf = KdNode::leaf(off, count);
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

    /// [`Bvh::occluded`] naming the leaf where the ray was blocked, as a
    /// leaf node for [`Bvh::leaf_blocks`] (the occluder hints of shadow rays).
    #[must_use]
    pub fn occluder(&self, ray: &Ray) -> Option<KdNode> {
        self.bounds.clip(ray)?;
        let mut closest = ray.t_max;
        let br = BlockRay::new(ray);
        let mut found = None;
        walk_single(self, ray, &mut closest, |off, count, closest| {
            let leaf = KdNode::leaf(off, count);
            let hit = leaf_any(ray, &br, leaf, &self.prim_ids, &self.blocks, *closest);
            if hit {
                found = Some(leaf);
            }
            hit
        });
        found
    }

    /// As [`crate::KdTree::leaf_blocks`], for a leaf that [`Bvh::occluder`] named.
    #[must_use]
    pub fn leaf_blocks(&self, ray: &Ray, leaf: KdNode, margin: f32) -> bool {
        self.lists().blocks_ray(ray, leaf, margin)
    }

    /// As [`crate::KdTree::leaf_blocks_packet`].
    #[must_use]
    pub fn leaf_blocks_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32, leaf: KdNode, margin: f32) -> u32 {
        self.lists().blocks_packet(rays, lanes, leaf, margin)
    }

    fn lists(&self) -> LeafLists<'_> {
        LeafLists {
            ids: &self.prim_ids,
            blocks: &self.blocks,
        }
    }

    /// [`Bvh::intersect_within`] for the `lanes` of a packet, with the
    /// signature of [`crate::KdTree::intersect_packet_in`]: lane `l` gets
    /// exactly `intersect_within(&rays[l], &mut closest[l])`, written to
    /// `hits[l]` when there is one; returns the lanes that found a closer
    /// hit. The lanes walk the tree together (`packet.rs`); `frustum`: the
    /// packet's when the caller has it (else made from the rays when they
    /// share an origin, real or virtual), `laid_out`: the rays laid out.
    /// Packets without a frustum, and those of which few lanes enter the
    /// tree, walk it lane by lane.
    pub fn intersect_packet_in<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        closest: &mut [f32; N],
        hits: &mut [Option<Hit>; N],
        frustum: Option<&Frustum>,
        laid_out: Option<&PacketBoxes<N>>,
    ) -> u32 {
        let (_, _, live) = match laid_out {
            Some(b) => b.clip(&self.bounds, lanes, closest),
            None => self.bounds.clip_lanes(rays, lanes, closest),
        };
        let few_lanes = N < 4 || few::<N>(live);
        // The packet's frustum: the caller's, else one made from the rays
        // (none for lanes that go alone).
        let own = (frustum.is_none() && !few_lanes && live != 0)
            .then(|| match laid_out {
                Some(b) => Frustum::for_intersect_laid(rays, b, live),
                None => Frustum::for_intersect(rays, live),
            })
            .flatten();
        let frustum = frustum.or(own.as_ref());
        // PERF: lanes without a frustum (scattered bounces: no shared
        // origin, real or virtual) walk alone, eight boxes a step: kitchen
        // Whitted bounce queries 0.78 of the time in the packet walk with
        // interval culling (docs/PERFORMANCE.md).
        let alone = if few_lanes || frustum.is_none() {
            live
        } else {
            packet::parallel_lanes(rays, live)
        };
        let mut found = 0u32;
        for l in lanes_of(alone) {
            if let Some(h) = self.intersect_within(&rays[l], &mut closest[l]) {
                hits[l] = Some(h);
                found |= 1 << l;
            }
        }
        let live = live & !alone;
        if live == 0 {
            return found;
        }
        let cull = packet::Cull::of(frustum, laid_out, live);
        let lr = laid_out.map_or_else(|| packet::LaneRays::new(rays), packet::LaneRays::from_laid);
        let pbr = PacketBlockRay::new_in(rays, laid_out, live);
        let mut brs: Option<[BlockRay; N]> = None;
        let mut ties = [NO_TIE; N];
        packet::walk_packet(&self.nodes, &lr, live, closest, &cull, |off, count, active, closest| {
            let leaf = KdNode::leaf(off, count);
            if let Some(pbr) = pbr.as_ref().filter(|_| dense::<N>(active)) {
                leaf_packet(
                    pbr,
                    rays,
                    frustum,
                    active,
                    leaf,
                    &self.prim_ids,
                    &self.blocks,
                    closest,
                    Some(&mut ties),
                    None,
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
            let brs = brs.get_or_insert_with(|| std::array::from_fn(|l| BlockRay::new(&rays[l])));
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
        });
        found
    }

    /// [`Bvh::occluder`] for the `lanes` of a packet, with the signature of
    /// [`crate::KdTree::occluder_packet_in`]: the blocked lanes and the leaf
    /// where one of them was blocked.
    #[must_use]
    pub fn occluder_packet_in<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        frustum: Option<&Frustum>,
        laid_out: Option<&PacketBoxes<N>>,
    ) -> (u32, Option<KdNode>) {
        let mut closest: [f32; N] = std::array::from_fn(|l| rays[l].t_max);
        let (_, _, live) = match laid_out {
            Some(b) => b.clip(&self.bounds, lanes, &closest),
            None => self.bounds.clip_lanes(rays, lanes, &closest),
        };
        let alone = if N < 4 || few::<N>(live) {
            live
        } else {
            packet::parallel_lanes(rays, live)
        };
        let mut blocked = 0u32;
        let mut found = None;
        for l in lanes_of(alone) {
            if let Some(leaf) = self.occluder(&rays[l]) {
                blocked |= 1 << l;
                found = found.or(Some(leaf));
            }
        }
        let live = live & !alone;
        if live == 0 {
            return (blocked, found);
        }
        let prep = Prepared::new(rays, live, frustum, laid_out, |rays, laid, live| match laid {
            Some(b) => Frustum::for_occluded_laid(rays, b, live),
            None => Frustum::for_occluded(rays, live),
        });
        let frustum = prep.frustum();
        let cull = prep
            .cull(live)
            .with_exact_leaves(frustum.is_some_and(|f| f.spread() > EXACT_LEAF_SPREAD));
        let lr = laid_out.map_or_else(|| packet::LaneRays::new(rays), packet::LaneRays::from_laid);
        let pbr = PacketBlockRay::new_in(rays, laid_out, live);
        let mut brs: Option<[BlockRay; N]> = None;
        blocked |= packet::walk_packet(
            &self.nodes,
            &lr,
            live,
            &mut closest,
            &cull,
            |off, count, active, closest| {
                let leaf = KdNode::leaf(off, count);
                let hit = if let Some(pbr) = pbr.as_ref().filter(|_| dense::<N>(active)) {
                    leaf_packet(
                        pbr,
                        rays,
                        frustum,
                        active,
                        leaf,
                        &self.prim_ids,
                        &self.blocks,
                        closest,
                        None,
                        None,
                        |h, _, _| h.hit,
                    )
                } else {
                    let brs = brs.get_or_insert_with(|| std::array::from_fn(|l| BlockRay::new(&rays[l])));
                    lanes_of(active).fold(0, |m, l| {
                        m | (u32::from(leaf_any(
                            &rays[l],
                            &brs[l],
                            leaf,
                            &self.prim_ids,
                            &self.blocks,
                            closest[l],
                        )) << l)
                    })
                };
                if hit != 0 {
                    found = found.or(Some(leaf));
                }
                hit
            },
        );
        (blocked, found)
    }

    /// Checks every invariant: nodes reached once each from the root, only
    /// forward; child boxes holding their subtrees (leaf triangles' boxes
    /// exactly); unused slots empty; leaves on block boundaries with 1 to
    /// [`BVH_MAX_LEAF`] triangles, every valid triangle in exactly one leaf
    /// (pre-split: in one or more, whose boxes meet the triangle's and hold
    /// each of its vertices), blocks equal to their triangles bit for bit; depth within
    /// [`BVH_MAX_DEPTH`].
    pub fn validate(&self) -> Result<(), AccelError> {
        let bad = |m: String| Err(AccelError::Invalid(format!("BVH: {m}")));
        let valid = self.tris.iter().filter(|t| is_valid_triangle(t)).count();
        if self.nodes.is_empty() {
            return if valid == 0 {
                Ok(())
            } else {
                bad(format!("no nodes for {valid} valid triangles"))
            };
        }
        let mut seen = vec![0u8; self.tris.len()];
        // Pre-split trees: a triangle in one or more leaves, its vertices
        // each in the box of a leaf naming it (bit per vertex).
        let split = self.stats.presplit > 0;
        let mut corners = vec![0u8; if split { self.tris.len() } else { 0 }];
        let mut reached = vec![false; self.nodes.len()];
        let mut stack = vec![(0u32, 1usize)];
        reached[0] = true;
        let mut deepest = 0;
        while let Some((n, depth)) = stack.pop() {
            deepest = deepest.max(depth);
            if depth > BVH_MAX_DEPTH {
                return bad(format!("depth {depth} exceeds {BVH_MAX_DEPTH}"));
            }
            let node = &self.nodes[n as usize];
            for i in 0..BVH_WIDTH {
                let b = node.child_box(i);
                match node.slot(i) {
                    BvhSlot::Empty => {
                        if !(b.min.cmpeq(glam::Vec3::INFINITY).all() && b.max.cmpeq(glam::Vec3::NEG_INFINITY).all()) {
                            return bad(format!("node {n} slot {i}: unused slot with a box {b:?}"));
                        }
                    }
                    BvhSlot::Node(c) => {
                        if c <= n || c as usize >= self.nodes.len() || reached[c as usize] {
                            return bad(format!("node {n} slot {i}: child {c} out of order or reached twice"));
                        }
                        reached[c as usize] = true;
                        if !b.contains_box(&self.nodes[c as usize].bounds()) {
                            return bad(format!("node {n} slot {i}: box does not hold child {c}"));
                        }
                        stack.push((c, depth + 1));
                    }
                    BvhSlot::Leaf { offset, count } => {
                        let (off, cnt) = (offset as usize, count as usize);
                        if cnt == 0
                            || cnt > BVH_MAX_LEAF
                            || !off.is_multiple_of(LANES)
                            || off + cnt > self.prim_ids.len()
                        {
                            return bad(format!("node {n} slot {i}: leaf ({off}, {cnt}) malformed"));
                        }
                        for (k, &p) in self.prim_ids[off..off + cnt].iter().enumerate() {
                            let Some(t) = self.tris.get(p as usize) else {
                                return bad(format!("leaf names triangle {p} of {}", self.tris.len()));
                            };
                            if !is_valid_triangle(t) {
                                return bad(format!("leaf names the invalid triangle {p}"));
                            }
                            let tb = Aabb::from_points(t);
                            if split {
                                // A piece: the box meets the triangle's.
                                if b.intersection(tb).is_empty() {
                                    return bad(format!("node {n} slot {i}: box misses triangle {p}"));
                                }
                                for (v, &corner) in t.iter().enumerate() {
                                    corners[p as usize] |= u8::from(b.contains(corner)) << v;
                                }
                            } else if !b.contains_box(&tb) {
                                return bad(format!("node {n} slot {i}: box does not hold triangle {p}"));
                            }
                            let stored = self.blocks[(off + k) / LANES].triangle((off + k) % LANES);
                            if stored.map(|v| v.to_array().map(f32::to_bits))
                                != t.map(|v| v.to_array().map(f32::to_bits))
                            {
                                return bad(format!("triangle {p}'s block copy differs"));
                            }
                            seen[p as usize] = seen[p as usize].saturating_add(1);
                        }
                    }
                }
            }
        }
        if let Some(n) = reached.iter().position(|r| !r) {
            return bad(format!("node {n} is not reached from the root"));
        }
        self.validate8()?;
        if deepest != self.stats.depth && !self.stats.refitted {
            return bad(format!("depth {deepest} but the figures say {}", self.stats.depth));
        }
        for (p, t) in self.tris.iter().enumerate() {
            let want = u8::from(is_valid_triangle(t));
            if split {
                if (seen[p] > 0) != (want > 0) {
                    return bad(format!("triangle {p} is in {} leaves (valid: {})", seen[p], want > 0));
                }
                if want > 0 && corners[p] != 0b111 {
                    return bad(format!("a vertex of triangle {p} is in no leaf box naming it"));
                }
            } else if seen[p] != want {
                return bad(format!("triangle {p} is in {} leaves, not {want}", seen[p]));
            }
        }
        Ok(())
    }
}

impl Bvh {
    /// The eight-wide copy, where there is one: every interior child after
    /// its parent and reached once, boxes holding their children, no deeper
    /// than [`BVH_MAX_DEPTH`], and exactly the four-wide tree's leaves with
    /// the same boxes, bit for bit.
    fn validate8(&self) -> Result<(), AccelError> {
        let bad = |m: String| Err(AccelError::Invalid(format!("BVH, eight-wide copy: {m}")));
        if self.nodes8.is_empty() {
            return if wide8() && !self.nodes.is_empty() && !self.stats.refitted {
                bad("missing on a CPU that walks it".into())
            } else {
                Ok(())
            };
        }
        let leaf_key = |b: Aabb, child: u32, count: u32| {
            let bits = [b.min.to_array(), b.max.to_array()].map(|v| v.map(f32::to_bits));
            (child, count, bits)
        };
        let mut want = Vec::new();
        for node in &self.nodes {
            for i in 0..BVH_WIDTH {
                if node.child[i] != EMPTY_SLOT && node.child[i] & LEAF_BIT != 0 {
                    want.push(leaf_key(node.child_box(i), node.child[i], node.count[i]));
                }
            }
        }
        let mut got = Vec::new();
        let mut reached = vec![false; self.nodes8.len()];
        let mut stack = vec![(0u32, 1usize)];
        reached[0] = true;
        while let Some((n, depth)) = stack.pop() {
            if depth > BVH_MAX_DEPTH {
                return bad(format!("depth {depth} exceeds {BVH_MAX_DEPTH}"));
            }
            let node = &self.nodes8[n as usize];
            for i in 0..node8::BVH8_WIDTH {
                let (c, b) = (node.child[i], node.child_box(i));
                if c == EMPTY_SLOT {
                    continue;
                }
                if c & LEAF_BIT != 0 {
                    got.push(leaf_key(b, c, node.count[i]));
                    continue;
                }
                if c <= n || c as usize >= self.nodes8.len() || reached[c as usize] {
                    return bad(format!("node {n} slot {i}: child {c} out of order or reached twice"));
                }
                reached[c as usize] = true;
                let inner = &self.nodes8[c as usize];
                let held = (0..node8::BVH8_WIDTH)
                    .filter(|&k| inner.child[k] != EMPTY_SLOT)
                    .all(|k| b.contains_box(&inner.child_box(k)));
                if !held {
                    return bad(format!("node {n} slot {i}: box does not hold child {c}"));
                }
                stack.push((c, depth + 1));
            }
        }
        if let Some(n) = reached.iter().position(|r| !r) {
            return bad(format!("node {n} is not reached from the root"));
        }
        want.sort_unstable();
        got.sort_unstable();
        if got != want {
            return bad(format!(
                "{} leaves, not the four-wide tree's {} (or with other boxes)",
                got.len(),
                want.len()
            ));
        }
        Ok(())
    }
}

/// Lays the leaves out on block boundaries (each leaf's range padded with
/// its last index) and packs their blocks; the leaves' slots get their new
/// offsets. Returns the index array, the blocks and the number of leaves.
fn pack(nodes: &mut [BvhNode], ids: &[u32], tris: &[Triangle]) -> (Vec<u32>, Vec<TriBlock>, usize) {
    let mut new_ids = Vec::with_capacity(ids.len() + ids.len() / 2);
    let mut blocks = Vec::with_capacity(ids.len() / 2);
    let mut leaves = 0;
    for node in nodes.iter_mut() {
        for i in 0..BVH_WIDTH {
            let c = node.child[i];
            if c == EMPTY_SLOT || c & LEAF_BIT == 0 {
                continue;
            }
            leaves += 1;
            let (off, cnt) = ((c & !LEAF_BIT) as usize, node.count[i] as usize);
            node.child[i] = LEAF_BIT | new_ids.len() as u32;
            // Pieces of one pre-split triangle in one leaf: named once.
            let mut mine = [0u32; BVH_MAX_LEAF];
            let mut n = 0;
            for &id in &ids[off..off + cnt] {
                if !mine[..n].contains(&id) {
                    mine[n] = id;
                    n += 1;
                }
            }
            node.count[i] = n as u32;
            for chunk in mine[..n].chunks(LANES) {
                blocks.push(TriBlock::pack(chunk, tris));
                new_ids.extend_from_slice(chunk);
                let last = chunk[chunk.len() - 1];
                new_ids.resize(new_ids.len() + LANES - chunk.len(), last);
            }
        }
    }
    (new_ids, blocks, leaves)
}

#[cfg(test)]
mod tests;
