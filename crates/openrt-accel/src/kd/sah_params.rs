//! The SAH builders' parameters and output, shared by the exact builder
//! (`sah_build.rs`), the binned one (`binned_sah.rs`) and the fast one.

use crate::geom::aabb::Aabb;
use crate::kd::node::{KdNode, MAX_DEPTH};

/// Cost constants of the surface area heuristic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SahParams {
    /// Cost of one traversal step.
    pub traversal_cost: f32,
    /// Cost of one ray/triangle test.
    ///
    /// NOTE: the default 0.1 comes from `examples/sah_sweep.rs` and the
    /// interleaved runs of `examples/ab_ki.rs` (10k/100k/1M-tri meshes, one
    /// core). Leaves test their triangles four at a time (`leaf_blocks.rs`),
    /// so a reference costs less than a scalar test: against the earlier
    /// 0.25 it builds in about half the time with 0.3x the nodes and traces
    /// 10-20% faster; 0.08 no longer gains consistently. Figures in
    /// docs/PERFORMANCE.md.
    pub intersection_cost: f32,
    /// Factor (< 1) applied to the cost of a split with an empty side.
    pub empty_bonus: f32,
    /// Depth limit; `None` means `8 + 1.3 log2 N` (capped by the traversal stack).
    pub max_depth: Option<usize>,
    /// Nodes with more references than this (at most 64: larger values act
    /// as 64) choose their plane among binned candidates, smaller ones among
    /// every reference boundary
    /// (module `binned_sah`); `None` builds the whole tree with Wald &
    /// Havran's O(N log N) event lists (exact everywhere, several times
    /// slower to build; the reference the binned trees are measured against).
    pub binned_above: Option<usize>,
}

impl Default for SahParams {
    fn default() -> Self {
        Self {
            traversal_cost: 1.0,
            intersection_cost: 0.1,
            empty_bonus: 0.8,
            max_depth: None,
            binned_above: Some(DEFAULT_BINNED_ABOVE),
        }
    }
}

/// Default of [`SahParams::binned_above`].
pub const DEFAULT_BINNED_ABOVE: usize = 16;

/// The default depth limit for `n` primitives.
#[must_use]
pub fn default_max_depth(n: usize) -> usize {
    let d = 8.0 + 1.3 * (n.max(1) as f32).log2();
    (d.round() as usize).min(MAX_DEPTH - 1)
}

/// Output of a build: nodes, leaf primitive lists, root cell and statistics.
pub(crate) struct BuiltTree {
    pub nodes: Vec<KdNode>,
    pub prim_ids: Vec<u32>,
    pub bounds: Aabb,
    pub depth: usize,
    /// The tree's SAH cost as the fast builder estimates it while it
    /// builds (`None`: not estimated).
    pub cost: Option<f64>,
    /// How many of the triangles are valid (the rest are left out).
    pub valid: usize,
}
