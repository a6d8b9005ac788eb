//! The top-level BSP over object instances, rebuilt every frame.
//!
//! Wald, Benthin & Slusallek, "Distributed Interactive Ray Tracing of
//! Dynamic Scenes" (IEEE PVG 2003), Algorithm 1: split the axis of largest
//! extent (the next axis only if that one has no valid plane); candidate planes lie only at instance box boundaries; the plane is
//! the candidate nearest the cell centre on the side that holds more
//! instances (between the spatial and the object median); instances that
//! straddle the plane go to both sides; a node becomes a leaf when no valid
//! plane is found. Valid here means: strictly inside the cell, both children
//! hold fewer instances than the parent, and at most half of the instances
//! straddle (beyond that, duplication costs more than the split saves).
//!
//! Traversal uses the same 8-byte nodes and [`crate::kd::traverse`] as object trees.
//!
//! PERF: per node, one SIMD pass finds the candidates on all three axes at
//! once and rules out the axes on which all instances overlap (most nodes
//! that end as leaves stop there); on an axis tried, one pass partitions
//! the instances at the first candidate and counts both sides, kept when
//! the plane is valid (else the second candidate is tried), all without
//! data-dependent branches, into one stack-disciplined arena (no allocation
//! per node); the upper levels are built on several threads and stitched.

use crate::error::AccelError;
use crate::geom::aabb::Aabb;
use crate::geom::box_quad::BoxQuad;
use crate::kd::fast_build::PARALLEL_MIN;
use crate::kd::node::{KdNode, MAX_DEPTH, MAX_FIELD, MAX_NODES, shift_into, too_many_nodes};
use crate::kd::sah_params::default_max_depth;
use crate::kd::tree::BuilderKind;

/// A kd-tree over instance world boxes.
#[derive(Clone, Debug, Default)]
pub struct InstanceBsp {
    nodes: Vec<KdNode>,
    items: Vec<u32>,
    bounds: Aabb,
    depth: usize,
    /// Each leaf's boxes, four to a quad, leaf after leaf.
    quads: Vec<BoxQuad>,
    /// Per item offset, the first quad of the leaf whose list starts there.
    quad_start: Vec<u32>,
}

impl InstanceBsp {
    /// Builds the tree over `boxes` on all cores (rayon's global pool);
    /// item `i` of a leaf is an index into `boxes`. Empty or non-finite
    /// boxes are left out. A caller that rebuilds every frame keeps a
    /// [`BspBuilder`] instead, which reuses its scratch memory and threads.
    pub fn build(boxes: &[Aabb]) -> Result<Self, AccelError> {
        BspBuilder {
            threads: rayon::current_num_threads(),
            workers: Vec::new(),
            input: Vec::new(),
            pool: None,
            buffers: Vec::new(),
        }
        .build(boxes)
    }

    /// The flat node array (root at 0).
    #[must_use]
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// The instances of a leaf node.
    #[inline]
    #[must_use]
    pub fn leaf_items(&self, leaf: KdNode) -> &[u32] {
        let off = leaf.prim_offset() as usize;
        &self.items[off..off + leaf.prim_count() as usize]
    }

    /// The boxes of a leaf's instances, four to a [`BoxQuad`], in the
    /// order of [`InstanceBsp::leaf_items`] (the last quad padded with
    /// repeats of the last box).
    #[inline]
    #[must_use]
    pub fn leaf_box_quads(&self, leaf: KdNode) -> &[BoxQuad] {
        let off = leaf.prim_offset() as usize;
        let n = (leaf.prim_count() as usize).div_ceil(4);
        let first = self.quad_start.get(off).map_or(usize::MAX, |&q| q as usize);
        self.quads.get(first..first + n).unwrap_or(&[])
    }

    /// Union of the instance boxes (the root cell).
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Deepest leaf.
    #[must_use]
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Number of instance references in leaves.
    #[must_use]
    pub fn references(&self) -> usize {
        self.items.len()
    }

    /// Checks the tree against the boxes it was built from: structure, split
    /// planes inside their cells, and every non-empty box referenced by every
    /// leaf whose cell it overlaps with positive volume or touches.
    pub fn validate(&self, boxes: &[Aabb]) -> Result<(), AccelError> {
        let err = |s: String| Err(AccelError::Invalid(s));
        let mut seen = vec![false; self.nodes.len()];
        let mut stack = vec![(0u32, self.bounds, 0usize)];
        while let Some((i, cell, depth)) = stack.pop() {
            let Some(&n) = self.nodes.get(i as usize) else {
                return err(format!("node index {i} out of range"));
            };
            if std::mem::replace(&mut seen[i as usize], true) || depth >= MAX_DEPTH {
                return err(format!("node {i} reached twice or too deep"));
            }
            if n.is_leaf() {
                let Some(list) = self
                    .items
                    .get(n.prim_offset() as usize..(n.prim_offset() + n.prim_count()) as usize)
                else {
                    return err(format!("leaf {i} range outside the item array"));
                };
                for (j, b) in boxes.iter().enumerate() {
                    if b.is_empty() || !b.is_finite() {
                        if list.contains(&(j as u32)) {
                            return err(format!("leaf {i} names empty box {j}"));
                        }
                        continue;
                    }
                    let overlaps = (0..3).all(|a| {
                        if b.min[a] == b.max[a] {
                            b.min[a] >= cell.min[a] && b.min[a] <= cell.max[a]
                        } else {
                            b.min[a] < cell.max[a] && b.max[a] > cell.min[a]
                        }
                    });
                    if overlaps && !list.contains(&(j as u32)) {
                        return err(format!("box {j} overlaps leaf {i} but is not in it"));
                    }
                }
                // The leaf's quads hold its boxes in its order.
                let quads = self.leaf_box_quads(n);
                let want = list.chunks(4).map(|c| {
                    let b: Vec<Aabb> = c.iter().filter_map(|&j| boxes.get(j as usize).copied()).collect();
                    BoxQuad::pack(&b)
                });
                if quads.len() != list.len().div_ceil(4) || !quads.iter().zip(want).all(|(q, w)| q.same_bits(&w)) {
                    return err(format!("leaf {i}: box quads differ from its boxes"));
                }
                continue;
            }
            let (axis, split) = (n.axis(), n.split());
            if !(split >= cell.min[axis] && split <= cell.max[axis]) || n.above_child() <= i + 1 || n.below_empty() {
                return err(format!("node {i}: bad split {split} or child {}", n.above_child()));
            }
            let (mut l, mut r) = (cell, cell);
            l.max[axis] = split;
            r.min[axis] = split;
            stack.push((i + 1, l, depth + 1));
            stack.push((n.above_child(), r, depth + 1));
        }
        if seen.iter().any(|s| !s) {
            return err("unreachable node".into());
        }
        Ok(())
    }
}

/// An instance box and its index, laid out for SIMD loads: lane `a` of
/// `lo` and `hi` is the box on axis `a`.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct Item {
    /// Box minimum; lane 3 holds the instance index's bits plus [`ID_BIAS`].
    lo: [f32; 4],
    /// Box maximum; lane 3 is zero.
    hi: [f32; 4],
}

/// Added to an instance index stored in a float lane so that the lane is a
/// normal float (exponent field at least 1, and below the infinities for
/// every index up to `MAX_FIELD`).
///
/// PERF: small indices are denormal floats as they are, and the SIMD pass
/// adds lane 3 along with the others; some CPUs handle denormal operands or
/// results in microcode, which would slow every box. Same speed here (AMD
/// EPYC, `bsp_once 10000 200 1`), same tree.
const ID_BIAS: u32 = 1 << 23;

impl Item {
    fn new(b: &Aabb, id: u32) -> Self {
        debug_assert!(id <= MAX_FIELD);
        Self {
            lo: [b.min.x, b.min.y, b.min.z, f32::from_bits(id + ID_BIAS)],
            hi: [b.max.x, b.max.y, b.max.z, 0.0],
        }
    }

    /// The instance index.
    #[inline]
    fn id(&self) -> u32 {
        self.lo[3].to_bits() - ID_BIAS
    }
}

const FILLER: Item = Item {
    lo: [0.0; 4],
    hi: [0.0; 4],
};

/// Builds of fewer instances run on the calling thread alone.
const POOL_MIN: usize = 2_048;

/// In a parallel build, a node of fewer instances is one task (its whole
/// subtree built by one worker).
///
/// PERF: 512 instead of 2,048 (the pool threshold): more, smaller tasks
/// balance better. On the 16-core device, 10k instances on 16 threads
/// (`bsp_once`, threads awake): median 0.74 ms against 0.99 ms, same run;
/// no change on 8 threads.
const TASK_MIN: usize = 512;

/// Rebuilds [`InstanceBsp`]s, keeping its scratch memory (the partition
/// arena and per-thread buffers) from one frame to the next.
///
/// PERF: with a fresh arena every frame, page faults took a quarter of the
/// build time at 100k instances. The upper levels are split in parallel
/// (`rayon::join`), the subtrees below them built by one worker each and
/// stitched in depth-first order; the tree does not depend on the thread
/// count.
#[derive(Debug)]
pub struct BspBuilder {
    threads: usize,
    /// Idle subtree workers, their buffers kept between frames.
    workers: Vec<Builder>,
    /// The instances of the current build, kept between frames.
    input: Vec<Item>,
    /// Persistent worker threads for the tasks (`None`: rayon's global pool,
    /// or the calling thread alone when `threads` is 1).
    ///
    /// PERF: spawning scoped threads every frame cost more than the tasks
    /// themselves at 10k instances on 16 cores; a rayon pool's threads wait
    /// between frames.
    pool: Option<std::sync::Arc<rayon::ThreadPool>>,
    /// Partition buffers of the parallel upper levels, kept between frames.
    buffers: Vec<Vec<Item>>,
}

impl Default for BspBuilder {
    /// A builder for all cores.
    fn default() -> Self {
        Self::new(std::thread::available_parallelism().map_or(1, std::num::NonZero::get))
    }
}

/// The upper levels, split in parallel; each `Task` is a subtree built by
/// the worker it holds.
enum Top {
    Split {
        axis: usize,
        plane: f32,
        depth: usize,
        left: Box<Top>,
        right: Box<Top>,
    },
    Task(Box<Builder>),
}

impl BspBuilder {
    /// A builder using at most `threads` threads.
    #[must_use]
    pub fn new(threads: usize) -> Self {
        let threads = threads.max(1);
        let pool = (threads > 1)
            .then(|| rayon::ThreadPoolBuilder::new().num_threads(threads).build().ok())
            .flatten()
            .map(std::sync::Arc::new);
        Self {
            threads,
            workers: Vec::new(),
            input: Vec::new(),
            pool,
            buffers: Vec::new(),
        }
    }

    /// A builder running on `pool` (shared with whoever else holds it).
    #[must_use]
    pub fn with_pool(pool: std::sync::Arc<rayon::ThreadPool>) -> Self {
        Self {
            threads: pool.current_num_threads(),
            workers: Vec::new(),
            input: Vec::new(),
            pool: Some(pool),
            buffers: Vec::new(),
        }
    }

    /// Threads the builder may use.
    #[must_use]
    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Runs `f` on the builder's threads (on the calling thread when it has
    /// none): other per-frame parallel work (rayon iterators inside `f`)
    /// shares them, and the pool wakes once for it and the build after it.
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.pool {
            Some(pool) => pool.install(f),
            None => f(),
        }
    }

    /// Runs `f`, the build of an object of `triangles` triangles with
    /// `builder`: on the builder's threads when the build can use more than
    /// one (a fast build or refit of at least [`PARALLEL_MIN`] triangles),
    /// otherwise on the calling thread, which waits for it either way.
    /// The same tree; handing a one-thread build to the pool would cost a
    /// wake-up there and another here (measured in docs/PERFORMANCE.md).
    pub fn install_build<R: Send>(&self, builder: BuilderKind, triangles: usize, f: impl FnOnce() -> R + Send) -> R {
        if builder == BuilderKind::Fast && triangles >= PARALLEL_MIN {
            self.install(f)
        } else {
            f()
        }
    }

    /// Runs `f` on one of the builder's threads in the background (on
    /// rayon's global pool when the builder has none).
    pub fn spawn(&self, f: impl FnOnce() + Send + 'static) {
        match &self.pool {
            Some(pool) => pool.spawn(f),
            None => rayon::spawn(f),
        }
    }

    /// Builds the tree over `boxes`; item `i` of a leaf is an index into
    /// `boxes`. Empty or non-finite boxes are left out.
    pub fn build(&mut self, boxes: &[Aabb]) -> Result<InstanceBsp, AccelError> {
        if boxes.len() > MAX_FIELD as usize {
            return Err(AccelError::TooManyPrimitives {
                count: boxes.len(),
                limit: MAX_FIELD as usize,
            });
        }
        // NOTE: handing a small build to the pool costs more than it saves
        // (a 1k-instance build ran 1.4x slower on 16 threads).
        let parallel = self.threads > 1 && boxes.len() >= POOL_MIN;
        // PERF: one `install` for every phase: the pool's threads wake once
        // per build, not once per phase. (The pool is taken out for the
        // call, which needs the rest of the builder.)
        let pool = self.pool.take();
        let bsp = match (&pool, parallel) {
            (Some(pool), true) => pool.install(|| self.phases(boxes, true)),
            _ => self.phases(boxes, parallel),
        };
        self.pool = pool;
        let bsp = bsp?;
        // NOTE: checked after every build in debug-assertion builds (all tests), up to a size.
        #[cfg(debug_assertions)]
        if boxes.len() <= 2_000
            && let Err(e) = bsp.validate(boxes)
        {
            panic!("instance BSP build produced an invalid tree: {e}");
        }
        Ok(bsp)
    }

    /// Gathers the boxes, splits the upper levels and builds the subtrees,
    /// and assembles the tree; `parallel`: on the current rayon pool.
    fn phases(&mut self, boxes: &[Aabb], parallel: bool) -> Result<InstanceBsp, AccelError> {
        let (n, bounds) = gather(boxes, &mut self.input, parallel);
        let items = &self.input[..n];
        // NOTE: two levels more than the thread count needs: subtrees differ
        // in size and rayon's work stealing balances the spare ones.
        let levels = if parallel { self.threads.ilog2() + 2 } else { 0 };
        let max_depth = default_max_depth(n).min(MAX_DEPTH - 1);
        let spare = std::sync::Mutex::new(std::mem::take(&mut self.workers));
        let buffers = std::sync::Mutex::new(std::mem::take(&mut self.buffers));
        let ctx = TopCtx {
            spare: &spare,
            buffers: &buffers,
            max_depth,
        };
        let top = if n == 0 {
            Ok(None)
        } else {
            ctx.top(bounds, items, 0, levels).map(Some)
        };
        self.workers = spare.into_inner().unwrap_or_default();
        self.buffers = buffers.into_inner().unwrap_or_default();
        let (mut nodes, mut items) = (Vec::new(), Vec::new());
        let mut depth = 0;
        match top? {
            None => nodes.push(KdNode::leaf(0, 0)),
            // PERF: a tree built by one worker is its arrays as they are
            // (child indices and list offsets already final): they are moved
            // out and the worker gets empty ones of the same capacity,
            // instead of a copy that shifts every node by zero.
            Some(Top::Task(mut w)) => {
                let (node_cap, item_cap) = (w.nodes.capacity(), w.items.capacity());
                nodes = std::mem::replace(&mut w.nodes, Vec::with_capacity(node_cap));
                items = std::mem::replace(&mut w.items, Vec::with_capacity(item_cap));
                depth = w.depth;
                self.workers.push(*w);
            }
            Some(top) => depth = assemble(top, &mut nodes, &mut items, &mut self.workers)?,
        }
        let (quads, quad_start) = box_quads(&nodes, &items, boxes);
        Ok(InstanceBsp {
            nodes,
            items,
            bounds,
            depth,
            quads,
            quad_start,
        })
    }
}

/// Each leaf's boxes four to a quad, leaf after leaf, and where each
/// leaf's quads start (indexed by the leaf's item offset).
fn box_quads(nodes: &[KdNode], items: &[u32], boxes: &[Aabb]) -> (Vec<BoxQuad>, Vec<u32>) {
    let mut quads = Vec::new();
    let mut start = vec![u32::MAX; items.len() + 1];
    let mut leaf_boxes = Vec::new();
    for n in nodes.iter().filter(|n| n.is_leaf() && n.prim_count() > 0) {
        let off = n.prim_offset() as usize;
        let Some(list) = items.get(off..off + n.prim_count() as usize) else {
            continue;
        };
        leaf_boxes.clear();
        leaf_boxes.extend(list.iter().map(|&i| boxes[i as usize]));
        start[off] = quads.len() as u32;
        quads.extend(leaf_boxes.chunks(4).map(BoxQuad::pack));
    }
    (quads, start)
}

/// Fills `input` with the usable boxes (neither empty nor non-finite) as
/// items, in order; returns their count and bounds. `input` keeps its
/// length between frames (scratch past the count).
///
/// PERF: on 16 threads the serial loop took a tenth of a 10k-instance
/// build; `parallel` gathers chunks on the current rayon pool, each
/// written compactly at its chunk's start, then closes the gaps.
fn gather(boxes: &[Aabb], input: &mut Vec<Item>, parallel: bool) -> (usize, Aabb) {
    use rayon::prelude::*;
    const CHUNK: usize = 1_024;
    fn chunk(src: &[Aabb], dst: &mut [Item], first: usize) -> (usize, Aabb) {
        let (mut n, mut bounds) = (0, Aabb::EMPTY);
        for (i, b) in src.iter().enumerate() {
            if !b.is_empty() && b.is_finite() {
                bounds = bounds.union(*b);
                dst[n] = Item::new(b, (first + i) as u32);
                n += 1;
            }
        }
        (n, bounds)
    }
    if input.len() < boxes.len() {
        input.resize(boxes.len(), FILLER);
    }
    let dst = &mut input[..boxes.len()];
    if !parallel {
        return chunk(boxes, dst, 0);
    }
    let counts: Vec<(usize, Aabb)> = boxes
        .par_chunks(CHUNK)
        .zip(dst.par_chunks_mut(CHUNK))
        .enumerate()
        .map(|(c, (src, dst))| chunk(src, dst, c * CHUNK))
        .collect();
    let (mut n, mut bounds) = (0, Aabb::EMPTY);
    for (c, &(count, b)) in counts.iter().enumerate() {
        if n < c * CHUNK {
            input.copy_within(c * CHUNK..c * CHUNK + count, n);
        }
        n += count;
        bounds = bounds.union(b);
    }
    (n, bounds)
}

/// A task's subtree and where it lands in the assembled arrays.
struct Placed {
    worker: Box<Builder>,
    node_at: usize,
    item_at: usize,
}

/// Lays the upper levels out depth-first from `next` (node and leaf-entry
/// counters): each split's node goes to `splits` with its final index and
/// above child, each task to `tasks`; returns the deepest leaf's depth.
fn lay_out(top: Top, next: &mut (usize, usize), splits: &mut Vec<(usize, KdNode)>, tasks: &mut Vec<Placed>) -> usize {
    match top {
        Top::Task(worker) => {
            let (node_at, item_at) = *next;
            next.0 += worker.nodes.len();
            next.1 += worker.items.len();
            let depth = worker.depth;
            tasks.push(Placed {
                worker,
                node_at,
                item_at,
            });
            depth
        }
        Top::Split {
            axis,
            plane,
            depth,
            left,
            right,
        } => {
            let index = next.0;
            next.0 += 1;
            let dl = lay_out(*left, next, splits, tasks);
            let mut node = KdNode::interior(axis, plane);
            // NOTE: the index fits: `assemble` checks the node count first.
            node.set_above_child(u32::try_from(next.0).unwrap_or(MAX_NODES).min(MAX_NODES));
            splits.push((index, node));
            let dr = lay_out(*right, next, splits, tasks);
            depth.max(dl).max(dr)
        }
    }
}

/// Writes the upper levels and the tasks' subtrees in depth-first order
/// into `nodes` and `items`, each subtree copied (shifted) in parallel on
/// the current rayon pool, and hands the workers back to `spare`; returns
/// the deepest leaf's depth.
///
/// PERF: assembled serially, the copy took a fifth of a 10k-instance build
/// on 16 threads.
fn assemble(
    top: Top,
    nodes: &mut Vec<KdNode>,
    items: &mut Vec<u32>,
    spare: &mut Vec<Builder>,
) -> Result<usize, AccelError> {
    use rayon::prelude::*;
    let (mut next, mut splits, mut tasks) = ((0, 0), Vec::new(), Vec::new());
    let depth = lay_out(top, &mut next, &mut splits, &mut tasks);
    let (n_nodes, n_items) = next;
    let result = if n_nodes > MAX_NODES as usize || n_items > u32::MAX as usize {
        Err(too_many_nodes())
    } else {
        nodes.resize(n_nodes, KdNode::leaf(0, 0));
        items.resize(n_items, 0);
        for &(index, node) in &splits {
            nodes[index] = node;
        }
        // The tasks' ranges, in order, are disjoint: cut them out one by one.
        let mut jobs = Vec::with_capacity(tasks.len());
        let (mut rest_nodes, mut rest_items) = (&mut nodes[..], &mut items[..]);
        let mut cut = 0;
        for t in &tasks {
            let tail = std::mem::take(&mut rest_nodes).split_at_mut(t.node_at - cut).1;
            let (dst_nodes, tail) = tail.split_at_mut(t.worker.nodes.len());
            let (dst_items, tail_items) = std::mem::take(&mut rest_items).split_at_mut(t.worker.items.len());
            (rest_nodes, rest_items) = (tail, tail_items);
            cut = t.node_at + t.worker.nodes.len();
            jobs.push((t, dst_nodes, dst_items));
        }
        jobs.into_par_iter()
            .map(|(t, dst_nodes, dst_items)| {
                dst_items.copy_from_slice(&t.worker.items);
                shift_into(dst_nodes, &t.worker.nodes, t.node_at as u32, t.item_at as u32)
            })
            .collect::<Result<(), AccelError>>()
    };
    spare.extend(tasks.into_iter().map(|t| *t.worker));
    result.map(|()| depth)
}

/// What the parallel upper levels share.
struct TopCtx<'a> {
    /// Idle workers (their buffers kept from earlier frames).
    spare: &'a std::sync::Mutex<Vec<Builder>>,
    /// Idle partition buffers of the upper levels.
    buffers: &'a std::sync::Mutex<Vec<Vec<Item>>>,
    max_depth: usize,
}

impl TopCtx<'_> {
    /// Builds the subtree over `items` on one worker.
    fn task(&self, cell: Aabb, items: &[Item], depth: usize) -> Result<Top, AccelError> {
        let poisoned = || AccelError::Invalid("a parallel build panicked".into());
        let mut w = self.spare.lock().map_err(|_| poisoned())?.pop().unwrap_or_default();
        w.nodes.clear();
        w.items.clear();
        w.depth = 0;
        w.max_depth = self.max_depth;
        let n = items.len();
        // PERF: the arena keeps its length between frames: it is scratch.
        // Growing it again from empty zero-filled ~1.6 MB per 10k-instance
        // build (about 4% of its instructions under callgrind, 2-4% of its time).
        if w.arena.len() < n {
            w.arena.resize(n, FILLER);
        }
        w.arena[..n].copy_from_slice(items);
        match w.node(cell, 0, n, n, depth) {
            Ok(()) => Ok(Top::Task(Box::new(w))),
            Err(e) => {
                self.spare.lock().map_err(|_| poisoned())?.push(w);
                Err(e)
            }
        }
    }

    /// Splits the upper `levels` levels (the same planes [`Builder::node`]
    /// would choose), building the two children of each split in parallel
    /// (`rayon::join`) and the subtrees below them as tasks.
    fn top(&self, cell: Aabb, items: &[Item], depth: usize, levels: u32) -> Result<Top, AccelError> {
        let n = items.len();
        if levels == 0 || n < TASK_MIN || depth >= self.max_depth {
            return self.task(cell, items, depth);
        }
        let poisoned = || AccelError::Invalid("a parallel build panicked".into());
        // PERF: children buffers come from the builder's pool: allocating and
        // filling fresh ones moved megabytes per frame at 10k instances.
        let mut children = self.buffers.lock().map_err(|_| poisoned())?.pop().unwrap_or_default();
        if children.len() < 2 * n {
            children.resize(2 * n, FILLER);
        }
        let Some(Split { axis, plane, nl, nr }) = choose_and_partition(items, &mut children[..2 * n], &cell) else {
            self.buffers.lock().map_err(|_| poisoned())?.push(children);
            return self.task(cell, items, depth);
        };
        let (lcell, rcell) = halves(cell, axis, plane);
        let (left, right) = children[..2 * n].split_at(n);
        let (l, r) = rayon::join(
            || self.top(lcell, &left[..nl], depth + 1, levels - 1),
            || self.top(rcell, &right[..nr], depth + 1, levels - 1),
        );
        self.buffers.lock().map_err(|_| poisoned())?.push(children);
        Ok(Top::Split {
            axis,
            plane,
            depth,
            left: Box::new(l?),
            right: Box::new(r?),
        })
    }
}

/// A chosen plane and the children it produced in the arena.
struct Split {
    axis: usize,
    plane: f32,
    /// Left children at `arena[free..free + nl]`, right at `arena[free + n..free + n + nr]`.
    nl: usize,
    nr: usize,
}

/// The build state of one thread. A node's instances are
/// `arena[at..at + n]`; everything from `free` on is scratch for its
/// children (stack discipline: a child's scratch begins past both
/// children's ranges).
#[derive(Debug, Default)]
struct Builder {
    nodes: Vec<KdNode>,
    items: Vec<u32>,
    arena: Vec<Item>,
    depth: usize,
    max_depth: usize,
}

impl Builder {
    fn leaf(&mut self, at: usize, n: usize) -> Result<(), AccelError> {
        let offset = self.items.len();
        if offset > u32::MAX as usize - n || n > MAX_FIELD as usize || self.nodes.len() >= MAX_NODES as usize {
            return Err(too_many_nodes());
        }
        self.items.extend(self.arena[at..at + n].iter().map(Item::id));
        self.nodes.push(KdNode::leaf(offset as u32, n as u32));
        Ok(())
    }

    fn node(&mut self, cell: Aabb, at: usize, n: usize, free: usize, depth: usize) -> Result<(), AccelError> {
        self.depth = self.depth.max(depth);
        if n <= 1 || depth >= self.max_depth {
            return self.leaf(at, n);
        }
        let Some(Split { axis, plane, nl, nr }) = self.split(&cell, at, n, free) else {
            return self.leaf(at, n);
        };
        let index = self.nodes.len();
        if index >= MAX_NODES as usize {
            return Err(too_many_nodes());
        }
        let (lcell, rcell) = halves(cell, axis, plane);
        let scratch = free + n + nr;
        self.nodes.push(KdNode::interior(axis, plane));
        self.node(lcell, free, nl, scratch, depth + 1)?;
        let above = self.nodes.len() as u32;
        self.nodes[index].set_above_child(above);
        self.node(rcell, free + n, nr, scratch, depth + 1)
    }

    /// Algorithm 1's plane: on the axis of largest extent (the others only
    /// when it has no valid plane), the box boundary strictly inside the cell
    /// nearest the centre on the side holding more instances, else the one
    /// on the other side. Partitions into the arena at `free` as it tests.
    fn split(&mut self, cell: &Aabb, at: usize, n: usize, free: usize) -> Option<Split> {
        if self.arena.len() < free + 2 * n {
            self.arena.resize(free + 2 * n, FILLER);
        }
        let (src, dst) = self.arena.split_at_mut(free);
        choose_and_partition(&src[at..at + n], &mut dst[..2 * n], cell)
    }
}

/// Algorithm 1's plane for `src` in `cell` (see [`Builder::split`]);
/// partitions into `dst` (`2 * src.len()` long) as [`partition`] does.
fn choose_and_partition(src: &[Item], dst: &mut [Item], cell: &Aabb) -> Option<Split> {
    let n = src.len();
    let cands = candidates(src, cell);
    // PERF: a node with no candidate on any axis (most nodes that end as
    // leaves) stops here, before the axes are ordered.
    if cands.is_empty() {
        return None;
    }
    for axis in axes_by_extent(cell.extent()) {
        let [c0, c1] = cands.on_axis(axis);
        let Some(first) = c0.or(c1) else {
            continue;
        };
        let second = c1.filter(|&p| p != first);
        // PERF: partitioning at once, and again at the second candidate when
        // the first is not valid, is cheaper than a counting pass first: the
        // first candidate is valid at 12.6k of 16.3k nodes tried (10k
        // instances); interleaved `bsp_once 10000 200 1` medians 2.27-2.36
        // ms against 2.50-2.63 with the counting pass; same tree.
        for plane in std::iter::once(first).chain(second) {
            let (nl, nr) = partition(src, dst, axis, plane);
            if is_valid_split(n, nl, nr) {
                return Some(Split { axis, plane, nl, nr });
            }
        }
    }
    None
}

/// Whether a plane that sends `nl` of `n` instances left and `nr` right is
/// valid: both sides lose instances and at most half of them straddle (a
/// plane that duplicates more costs more than it separates).
fn is_valid_split(n: usize, nl: usize, nr: usize) -> bool {
    nl < n && nr < n && 2 * (nl + nr - n) <= n
}

/// Algorithm 1's two candidates on each axis, best first: the boundary
/// strictly inside the cell nearest the centre on the crowded side, then
/// the nearest on the other side; none on an axis on which all boxes share
/// an open interval (it has no valid plane).
///
/// NOTE: a valid plane p needs a box wholly right of it (min >= p) and one
/// wholly left (max <= p), so the largest minimum reaches the smallest
/// maximum. When it does not (the usual case at the bottom of the tree) the
/// axis is skipped without a partition: exact, the same tree.
///
/// PERF: one SIMD pass for the three axes at once (lane = axis; an item's
/// box is two aligned loads). It replaced a pass for the early-out plus a
/// scalar candidate pass per axis tried, about 40 instructions per box
/// and axis (callgrind). Same tree; interleaved `bsp_once N 300 1`: 10k
/// instances median 2.51-2.55 ms against 2.72-2.83, 100k 19.8 against 23.6.
/// The per-axis choice is made in the lanes as well and returned as
/// bitmasks, so a node without candidates leaves at once: best 1.83-1.86
/// ms against 1.97-2.01 (four interleaved rounds of `bsp_once 10000 300 1`).
fn candidates(items: &[Item], cell: &Aabb) -> Candidates {
    use wide::{f32x4, i32x4};
    let lo = f32x4::from([cell.min.x, cell.min.y, cell.min.z, 0.0]);
    let hi = f32x4::from([cell.max.x, cell.max.y, cell.max.z, 0.0]);
    let centre = f32x4::splat(0.5) * (lo + hi);
    let twice = f32x4::splat(2.0) * centre;
    let (ninf, inf) = (f32x4::splat(f32::NEG_INFINITY), f32x4::splat(f32::INFINITY));
    let (mut max_min, mut min_max) = (ninf, inf);
    // The largest boundary at or below the centre and the smallest at or
    // above it; they lie strictly inside the cell exactly when they are
    // beyond the cell's faces (so no inside test per boundary).
    let (mut best_l, mut best_r) = (ninf, inf);
    let mut left_of_centre = i32x4::ZERO;
    for it in items {
        let (bmin, bmax) = (f32x4::from(it.lo), f32x4::from(it.hi));
        max_min = max_min.fast_max(bmin);
        min_max = min_max.fast_min(bmax);
        // A true mask lane is -1 as an integer.
        left_of_centre -= wide::bytemuck::cast::<f32x4, i32x4>((bmin + bmax).simd_lt(twice));
        let l0 = bmin.simd_le(centre).bitselect(bmin, ninf);
        let l1 = bmax.simd_le(centre).bitselect(bmax, ninf);
        let r0 = bmin.simd_ge(centre).bitselect(bmin, inf);
        let r1 = bmax.simd_ge(centre).bitselect(bmax, inf);
        best_l = best_l.fast_max(l0.fast_max(l1));
        best_r = best_r.fast_min(r0.fast_min(r1));
    }
    // PERF: the choice per axis is made in the lanes too (no branches).
    let skip = max_min.simd_lt(min_max) | hi.simd_le(lo);
    let l_ok = best_l.simd_gt(lo) & !skip;
    let r_ok = best_r.simd_lt(hi) & !skip;
    // Lane a: 2 * (boxes left of the centre) >= n, i.e. the left side is crowded.
    let half = i32::try_from(items.len().div_ceil(2)).unwrap_or(i32::MAX);
    let crowded = wide::bytemuck::cast::<i32x4, f32x4>(left_of_centre.simd_gt(i32x4::splat(half - 1)));
    let (first, second) = (crowded.bitselect(best_l, best_r), crowded.bitselect(best_r, best_l));
    let (first_ok, second_ok) = (crowded.bitselect(l_ok, r_ok), crowded.bitselect(r_ok, l_ok));
    let (first_ok, second_ok) = (first_ok.to_bitmask() & 7, second_ok.to_bitmask() & 7);
    Candidates {
        first: first.to_array(),
        second: second.to_array(),
        first_ok,
        second_ok,
    }
}

/// Algorithm 1's candidates on the three axes, as found by [`candidates`].
struct Candidates {
    /// Lane `a`: the best candidate on axis `a` (valid where `first_ok` has bit `a`).
    first: [f32; 4],
    /// Lane `a`: the other candidate (valid where `second_ok` has bit `a`).
    second: [f32; 4],
    first_ok: u32,
    second_ok: u32,
}

impl Candidates {
    /// `true` when no axis has a candidate.
    fn is_empty(&self) -> bool {
        self.first_ok | self.second_ok == 0
    }

    /// The two candidates on `axis`, best first.
    fn on_axis(&self, axis: usize) -> [Option<f32>; 2] {
        let pick = |ok: u32, v: &[f32; 4]| (ok & (1 << axis) != 0).then_some(v[axis]);
        [pick(self.first_ok, &self.first), pick(self.second_ok, &self.second)]
    }
}

/// The three axes, largest extent first (ties: lower axis first).
///
/// PERF: three compare-swaps; a general sort here was 4% of the build.
fn axes_by_extent(ext: glam::Vec3) -> [usize; 3] {
    let mut a = [0usize, 1, 2];
    let mut swap_if_smaller = |i: usize, j: usize| {
        if ext[a[i]] < ext[a[j]] {
            a.swap(i, j);
        }
    };
    swap_if_smaller(0, 1);
    swap_if_smaller(1, 2);
    swap_if_smaller(0, 1);
    a
}

/// The two child cells of `cell` split on `axis` at `plane`.
fn halves(cell: Aabb, axis: usize, plane: f32) -> (Aabb, Aabb) {
    let (mut l, mut r) = (cell, cell);
    l.max[axis] = plane;
    r.min[axis] = plane;
    (l, r)
}

/// Copies the instances left of `plane` to `dst[..nl]` and those right of
/// it to `dst[n..n + nr]` (straddlers to both; boxes flat in the plane to
/// both); returns `(nl, nr)`.
#[expect(
    clippy::needless_bitwise_bool,
    reason = "PERF: non-short-circuit `&` keeps the loop branch-free"
)]
fn partition(src: &[Item], dst: &mut [Item], axis: usize, plane: f32) -> (usize, usize) {
    let n = src.len();
    assert!(dst.len() >= 2 * n, "partition needs room for both sides");
    let (left, right) = dst.split_at_mut(n);
    let (left, right) = (left.as_mut_ptr(), right.as_mut_ptr());
    let (mut nl, mut nr) = (0usize, 0usize);
    // PERF: branch-free: every item is written to both sides and the
    // cursors advance by the side tests. Unchecked writes: the bounds checks
    // were a fifth of the loop's instructions; without them 10k instances
    // build 2-3% faster (five interleaved `bsp_once 10000 200 1` rounds,
    // medians 2.17-2.22 ms against 2.21-2.29).
    for it in src {
        let (bmin, bmax) = (it.lo[axis], it.hi[axis]);
        let flat_on_plane = (bmin == plane) & (bmax == plane);
        // SAFETY: before item k both cursors count items among the first k,
        // so `nl, nr <= k < n`, and each half of `dst` holds at least `n`
        // items (asserted above).
        unsafe {
            left.add(nl).write(*it);
            right.add(nr).write(*it);
        }
        nl += usize::from((bmin < plane) | flat_on_plane);
        nr += usize::from((bmax > plane) | flat_on_plane);
    }
    (nl, nr)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// Builds go to the pool only when they can use its threads.
    #[test]
    fn only_builds_that_can_use_threads_are_handed_to_the_pool() {
        let pool = BspBuilder::new(2);
        // A pool thread has an index; the calling thread (not a worker) none.
        let on_pool = |builder, n| pool.install_build(builder, n, || rayon::current_thread_index().is_some());
        assert!(!on_pool(BuilderKind::Fast, PARALLEL_MIN - 1));
        assert!(on_pool(BuilderKind::Fast, PARALLEL_MIN));
        assert!(!on_pool(BuilderKind::Sah, 10 * PARALLEL_MIN));
        // Below the threshold a fast build joins nothing, so it runs the same
        // outside any pool.
        let tris = crate::testing::meshgen::bumpy_sphere(PARALLEL_MIN / 2, 4, 0.3);
        let inline = pool.install_build(BuilderKind::Fast, tris.len(), || {
            crate::kd::tree::KdTree::build_fast(tris.clone())
        });
        let pooled = pool.install(|| crate::kd::tree::KdTree::build_fast(tris.clone()));
        assert_eq!(inline.unwrap().nodes(), pooled.unwrap().nodes());
    }

    /// An instance index survives the trip through a float lane, and the
    /// lane is a normal float (no denormal arithmetic in the SIMD pass).
    #[test]
    fn instance_index_round_trips_through_a_normal_float_lane() {
        let b = Aabb::new(glam::Vec3::ZERO, glam::Vec3::ONE);
        for id in [0, 1, 2, 12_345, 1 << 23, MAX_FIELD - 1, MAX_FIELD] {
            let it = Item::new(&b, id);
            assert_eq!(it.id(), id);
            assert!(it.lo[3].is_normal(), "index {id} stored as {:e}", it.lo[3]);
        }
    }

    /// Algorithm 1's candidates on one axis, one box at a time (the scalar
    /// code the SIMD pass replaced): the oracle for [`candidates`].
    fn candidates_on_axis(items: &[Item], cell: &Aabb, axis: usize) -> [Option<f32>; 2] {
        let (lo, hi) = (cell.min[axis], cell.max[axis]);
        let centre = 0.5 * (lo + hi);
        let bounds = items.iter().flat_map(|it| [it.lo[axis], it.hi[axis]]);
        let best_l = bounds
            .clone()
            .filter(|&b| b <= centre)
            .fold(f32::NEG_INFINITY, f32::max);
        let best_r = bounds.filter(|&b| b >= centre).fold(f32::INFINITY, f32::min);
        let left = items
            .iter()
            .filter(|it| it.lo[axis] + it.hi[axis] < 2.0 * centre)
            .count();
        let (l, r) = ((best_l > lo).then_some(best_l), (best_r < hi).then_some(best_r));
        if 2 * left >= items.len() { [l, r] } else { [r, l] }
    }

    /// The SIMD pass gives the scalar candidates on every axis, except
    /// where the early-out fires (all boxes share an open interval on the
    /// axis), and there no box boundary strictly inside the cell is a valid
    /// plane (tried by brute force). Fails if the early-out's comparison is
    /// made non-strict (boxes that only touch would be skipped).
    #[test]
    fn candidates_match_the_scalar_pass_and_the_early_out_hides_no_valid_plane() {
        let mut rng = SmallRng::seed_from_u64(11);
        let mut early_outs = 0;
        for _ in 0..20_000 {
            let n = rng.random_range(2..9);
            let items: Vec<Item> = (0..n)
                .map(|id| {
                    // Coarse integer coordinates: shared boundaries, flat boxes and nesting are common.
                    let (p, q): (glam::Vec3, glam::Vec3) = (
                        std::array::from_fn(|_| rng.random_range(0..8) as f32).into(),
                        std::array::from_fn(|_| rng.random_range(0..8) as f32).into(),
                    );
                    Item::new(&Aabb::new(p.min(q), p.max(q)), id)
                })
                .collect();
            let lo = glam::Vec3::from(std::array::from_fn(|_| rng.random_range(0..2) as f32));
            let cell = Aabb::new(lo, glam::Vec3::splat(7.0));
            let cands = candidates(&items, &cell);
            let fast: [_; 3] = std::array::from_fn(|a| cands.on_axis(a));
            for axis in 0..3 {
                let scalar = candidates_on_axis(&items, &cell, axis);
                if fast[axis] == scalar {
                    continue;
                }
                assert_eq!(
                    fast[axis],
                    [None, None],
                    "axis {axis}: SIMD {fast:?}, scalar {scalar:?}"
                );
                early_outs += 1;
                for p in items.iter().flat_map(|it| [it.lo[axis], it.hi[axis]]) {
                    if p <= cell.min[axis] || p >= cell.max[axis] {
                        continue;
                    }
                    let mut dst = vec![FILLER; 2 * items.len()];
                    let (nl, nr) = partition(&items, &mut dst, axis, p);
                    assert!(
                        !is_valid_split(items.len(), nl, nr),
                        "plane {p} on axis {axis} is valid"
                    );
                }
            }
        }
        assert!(
            early_outs > 1_000,
            "the sweep exercised the early-out {early_outs} times"
        );
    }
}
