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
//! Traversal uses the same 8-byte nodes and [`crate::traverse`] as object trees.
//!
//! PERF: the build makes two passes over a node's instances (choose the
//! plane, then partition and count), both without data-dependent branches,
//! into one stack-disciplined arena (no allocation per node); the upper
//! levels are built on several threads and stitched.

use crate::kdnode::{KdNode, MAX_DEPTH, MAX_FIELD, append_shifted};
use crate::sah_build::default_max_depth;
use crate::{Aabb, AccelError};

/// A kd-tree over instance world boxes.
#[derive(Clone, Debug, Default)]
pub struct InstanceBsp {
    nodes: Vec<KdNode>,
    items: Vec<u32>,
    bounds: Aabb,
    depth: usize,
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
            pool: None,
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
                continue;
            }
            let (axis, split) = (n.axis(), n.split());
            if !(split >= cell.min[axis] && split <= cell.max[axis]) || n.above_child() <= i + 1 {
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

/// An instance box and its index.
#[derive(Clone, Copy, Debug)]
struct Item {
    min: [f32; 3],
    max: [f32; 3],
    id: u32,
}

const FILLER: Item = Item {
    min: [0.0; 3],
    max: [0.0; 3],
    id: 0,
};

/// Nodes smaller than this are built on the calling thread.
const PARALLEL_MIN: usize = 2_048;

/// Rebuilds [`InstanceBsp`]s, keeping its scratch memory (the partition
/// arena and per-thread buffers) from one frame to the next.
///
/// PERF: with a fresh arena every frame, page faults took a quarter of the
/// build time at 100k instances. The upper levels are split on the calling
/// thread, the subtrees below them built on one thread each and stitched in
/// depth-first order; the tree does not depend on the thread count.
#[derive(Debug)]
pub struct BspBuilder {
    threads: usize,
    /// `[0]` splits the upper levels; `[1 + i]` builds task `i`.
    workers: Vec<Builder>,
    /// Persistent worker threads for the tasks (`None`: rayon's global pool,
    /// or the calling thread alone when `threads` is 1).
    ///
    /// PERF: spawning scoped threads every frame cost more than the tasks
    /// themselves at 10k instances on 16 cores; a rayon pool's threads wait
    /// between frames.
    pool: Option<rayon::ThreadPool>,
}

impl Default for BspBuilder {
    /// A builder for all cores.
    fn default() -> Self {
        Self::new(std::thread::available_parallelism().map_or(1, std::num::NonZero::get))
    }
}

/// The upper levels split on the calling thread; each `Task` is a subtree
/// built by its own worker.
enum Top {
    Split {
        axis: usize,
        plane: f32,
        left: Box<Top>,
        right: Box<Top>,
    },
    Task(usize),
}

/// A subtree to build: its cell, its instances in worker 0's arena, its depth.
struct Task {
    cell: Aabb,
    at: usize,
    n: usize,
    depth: usize,
}

impl BspBuilder {
    /// A builder using at most `threads` threads (rounded down to a power of two).
    #[must_use]
    pub fn new(threads: usize) -> Self {
        let threads = threads.max(1);
        let pool = (threads > 1)
            .then(|| rayon::ThreadPoolBuilder::new().num_threads(threads).build().ok())
            .flatten();
        Self {
            threads,
            workers: Vec::new(),
            pool,
        }
    }

    /// Builds the tree over `boxes`; item `i` of a leaf is an index into
    /// `boxes`. Empty or non-finite boxes are left out.
    pub fn build(&mut self, boxes: &[Aabb]) -> Result<InstanceBsp, AccelError> {
        use rayon::iter::{
            IndexedParallelIterator, IntoParallelRefIterator, IntoParallelRefMutIterator, ParallelIterator,
        };
        if boxes.len() > MAX_FIELD as usize {
            return Err(AccelError::TooManyPrimitives {
                count: boxes.len(),
                limit: MAX_FIELD as usize,
            });
        }
        let levels = self.threads.ilog2();
        let tasks_max = 1usize << levels;
        self.workers.resize_with(1 + tasks_max, Builder::default);
        let (main, task_workers) = self.workers.split_at_mut(1);
        let main = &mut main[0];
        main.arena.clear();
        main.arena.extend(
            boxes
                .iter()
                .enumerate()
                .filter(|(_, b)| !b.is_empty() && b.is_finite())
                .map(|(i, b)| Item {
                    min: b.min.to_array(),
                    max: b.max.to_array(),
                    id: i as u32,
                }),
        );
        let bounds = boxes
            .iter()
            .filter(|b| !b.is_empty() && b.is_finite())
            .fold(Aabb::EMPTY, |a, b| a.union(*b));
        let n = main.arena.len();
        let max_depth = default_max_depth(n).min(MAX_DEPTH - 1);
        for w in std::iter::once(&mut *main).chain(task_workers.iter_mut()) {
            w.nodes.clear();
            w.items.clear();
            w.depth = 0;
            w.max_depth = max_depth;
        }
        let (mut nodes, mut items, mut depth) = (Vec::new(), Vec::new(), 0);
        if n == 0 {
            nodes.push(KdNode::leaf(0, 0));
        } else {
            let mut tasks = Vec::new();
            let (top, _) = main.top(bounds, (0, n), n, 0, levels, &mut tasks);
            if let Top::Task(_) = top {
                main.node(bounds, 0, n, n, 0)?;
                nodes = std::mem::take(&mut main.nodes);
                items = std::mem::take(&mut main.items);
                depth = main.depth;
            } else {
                let src = &main.arena;
                // Each task copies its instances on its own thread (into that core's cache).
                let run = move |t: &Task, w: &mut Builder| {
                    w.arena.clear();
                    w.arena.extend_from_slice(&src[t.at..t.at + t.n]);
                    w.node(t.cell, 0, t.n, t.n, t.depth)
                };
                let results: Vec<Result<(), AccelError>> = match &self.pool {
                    Some(pool) => pool.install(|| {
                        tasks
                            .par_iter()
                            .zip(task_workers.par_iter_mut())
                            .map(|(t, w)| run(t, w))
                            .collect()
                    }),
                    None => tasks
                        .iter()
                        .zip(task_workers.iter_mut())
                        .map(|(t, w)| run(t, w))
                        .collect(),
                };
                results.into_iter().collect::<Result<(), _>>()?;
                nodes.reserve(task_workers.iter().map(|w| w.nodes.len() + 1).sum());
                items.reserve(task_workers.iter().map(|w| w.items.len()).sum());
                assemble(&top, task_workers, &mut nodes, &mut items)?;
                depth = task_workers.iter().map(|w| w.depth).max().unwrap_or(0).max(main.depth);
            }
        }
        let bsp = InstanceBsp {
            nodes,
            items,
            bounds,
            depth,
        };
        // NOTE: checked after every build in debug-assertion builds (all tests), up to a size.
        #[cfg(debug_assertions)]
        if boxes.len() <= 2_000
            && let Err(e) = bsp.validate(boxes)
        {
            panic!("instance BSP build produced an invalid tree: {e}");
        }
        Ok(bsp)
    }
}

/// Writes the upper levels and the tasks' subtrees in depth-first order.
fn assemble(top: &Top, workers: &[Builder], nodes: &mut Vec<KdNode>, items: &mut Vec<u32>) -> Result<(), AccelError> {
    match top {
        Top::Task(i) => append_shifted(nodes, items, &workers[*i].nodes, &workers[*i].items),
        Top::Split {
            axis,
            plane,
            left,
            right,
        } => {
            let index = nodes.len();
            nodes.push(KdNode::interior(*axis, *plane));
            assemble(left, workers, nodes, items)?;
            let above =
                u32::try_from(nodes.len())
                    .ok()
                    .filter(|&a| a <= MAX_FIELD)
                    .ok_or(AccelError::TooManyNodes {
                        limit: MAX_FIELD as usize,
                    })?;
            nodes[index].set_above_child(above);
            assemble(right, workers, nodes, items)
        }
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
        if offset > u32::MAX as usize - n || n > MAX_FIELD as usize || self.nodes.len() >= MAX_FIELD as usize {
            return Err(AccelError::TooManyNodes {
                limit: MAX_FIELD as usize,
            });
        }
        self.items.extend(self.arena[at..at + n].iter().map(|it| it.id));
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
        if index >= MAX_FIELD as usize {
            return Err(AccelError::TooManyNodes {
                limit: MAX_FIELD as usize,
            });
        }
        let (lcell, rcell) = halves(cell, axis, plane);
        let scratch = free + n + nr;
        self.nodes.push(KdNode::interior(axis, plane));
        self.node(lcell, free, nl, scratch, depth + 1)?;
        let above = self.nodes.len() as u32;
        self.nodes[index].set_above_child(above);
        self.node(rcell, free + n, nr, scratch, depth + 1)
    }

    /// Splits the upper `levels` levels (the same planes [`Self::node`]
    /// would choose), leaving the rest to tasks. Returns the upper levels
    /// and the end of the arena they use: tasks run later, so a right
    /// subtree's scratch begins past everything its left sibling kept.
    fn top(
        &mut self,
        cell: Aabb,
        (at, n): (usize, usize),
        free: usize,
        depth: usize,
        levels: u32,
        tasks: &mut Vec<Task>,
    ) -> (Top, usize) {
        let task = |tasks: &mut Vec<Task>| {
            tasks.push(Task { cell, at, n, depth });
            (Top::Task(tasks.len() - 1), free)
        };
        if levels == 0 || n < PARALLEL_MIN || depth >= self.max_depth {
            return task(tasks);
        }
        self.depth = self.depth.max(depth);
        let Some(Split { axis, plane, nl, nr }) = self.split(&cell, at, n, free) else {
            return task(tasks);
        };
        let (lcell, rcell) = halves(cell, axis, plane);
        let (left, end) = self.top(lcell, (free, nl), free + 2 * n, depth + 1, levels - 1, tasks);
        let (right, end) = self.top(rcell, (free + n, nr), end, depth + 1, levels - 1, tasks);
        (
            Top::Split {
                axis,
                plane,
                left: Box::new(left),
                right: Box::new(right),
            },
            end,
        )
    }

    /// Algorithm 1's plane: on the axis of largest extent (the others only
    /// when it has no valid plane), the box boundary strictly inside the cell
    /// nearest the centre on the side holding more instances, else the one
    /// on the other side. Partitions into the arena at `free` as it tests.
    fn split(&mut self, cell: &Aabb, at: usize, n: usize, free: usize) -> Option<Split> {
        if self.arena.len() < free + 2 * n {
            self.arena.resize(free + 2 * n, FILLER);
        }
        let ext = cell.extent();
        for axis in axes_by_extent(ext) {
            let (src, dst) = self.arena.split_at_mut(free);
            let src = &src[at..at + n];
            let cands = candidates(src, cell, axis);
            let Some(first) = cands[0].or(cands[1]) else {
                continue;
            };
            let planes = [first, cands[1].unwrap_or(first)];
            let counts = side_counts(src, axis, planes);
            // Valid: both sides lose instances and at most half of them
            // straddle (a plane that duplicates more costs more than it separates).
            let valid = |(nl, nr): (usize, usize)| nl < n && nr < n && 2 * (nl + nr - n) <= n;
            if let Some(k) = (0..2).find(|&k| valid(counts[k])) {
                let plane = planes[k];
                let (nl, nr) = partition(src, &mut dst[..2 * n], axis, plane);
                debug_assert_eq!((nl, nr), counts[k]);
                return Some(Split { axis, plane, nl, nr });
            }
        }
        None
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

/// Algorithm 1's two candidates on `axis`, best first: the boundary
/// strictly inside the cell nearest the centre on the crowded side, then
/// the nearest on the other side.
fn candidates(items: &[Item], cell: &Aabb, axis: usize) -> [Option<f32>; 2] {
    let (lo, hi) = (cell.min[axis], cell.max[axis]);
    if hi <= lo {
        return [None, None];
    }
    let centre = 0.5 * (lo + hi);
    // The largest boundary at or below the centre and the smallest at or
    // above it; they lie strictly inside the cell exactly when they are
    // beyond `lo` and `hi` (so no inside test per boundary).
    // PERF: plain compare-selects compile to maxss/minss and blends, without
    // the NaN handling of f32::max (boundaries are finite) and without
    // data-dependent branches. (Deriving the side counts in this same pass
    // from counts against the centre was tried: the extra counters spill
    // and it ran 1.8x slower than this pass plus `side_counts`.)
    let (mut left_of_centre, mut best_l, mut best_r) = (0usize, f32::NEG_INFINITY, f32::INFINITY);
    for it in items {
        let (bmin, bmax) = (it.min[axis], it.max[axis]);
        left_of_centre += usize::from(bmin + bmax < 2.0 * centre);
        let l0 = if bmin <= centre { bmin } else { f32::NEG_INFINITY };
        let l1 = if bmax <= centre { bmax } else { f32::NEG_INFINITY };
        let r0 = if bmin >= centre { bmin } else { f32::INFINITY };
        let r1 = if bmax >= centre { bmax } else { f32::INFINITY };
        let (l, r) = (if l0 > l1 { l0 } else { l1 }, if r0 < r1 { r0 } else { r1 });
        best_l = if l > best_l { l } else { best_l };
        best_r = if r < best_r { r } else { best_r };
    }
    let l = (best_l > lo).then_some(best_l);
    let r = (best_r < hi).then_some(best_r);
    if 2 * left_of_centre >= items.len() {
        [l, r]
    } else {
        [r, l]
    }
}

/// Instances left and right of each of two planes (straddlers and boxes
/// flat in a plane count on both sides), in one pass.
#[expect(
    clippy::needless_bitwise_bool,
    reason = "PERF: non-short-circuit `&` keeps the loop branch-free"
)]
fn side_counts(items: &[Item], axis: usize, planes: [f32; 2]) -> [(usize, usize); 2] {
    let [p, q] = planes;
    let (mut pl, mut pr, mut ql, mut qr) = (0usize, 0usize, 0usize, 0usize);
    for it in items {
        let (bmin, bmax) = (it.min[axis], it.max[axis]);
        let flat_p = (bmin == p) & (bmax == p);
        pl += usize::from((bmin < p) | flat_p);
        pr += usize::from((bmax > p) | flat_p);
        let flat_q = (bmin == q) & (bmax == q);
        ql += usize::from((bmin < q) | flat_q);
        qr += usize::from((bmax > q) | flat_q);
    }
    [(pl, pr), (ql, qr)]
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
    let (left, right) = dst.split_at_mut(n);
    let (mut nl, mut nr) = (0usize, 0usize);
    // PERF: branch-free: every item is written to both sides and the
    // cursors advance by the side tests (item k lands at most at slot k).
    for (k, it) in src.iter().enumerate() {
        let (bmin, bmax) = (it.min[axis], it.max[axis]);
        let flat_on_plane = (bmin == plane) & (bmax == plane);
        left[nl.min(k)] = *it;
        nl += usize::from((bmin < plane) | flat_on_plane);
        right[nr.min(k)] = *it;
        nr += usize::from((bmax > plane) | flat_on_plane);
    }
    (nl, nr)
}
