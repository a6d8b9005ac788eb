//! Refitting a BVH to moved triangles (unstructured motion).
//!
//! Wald, Boulos & Shirley (ACM TOG 2007): a deforming mesh keeps its tree's
//! topology, and only the boxes are recomputed bottom-up, which costs a
//! fraction of a build. Leaves' boxes and blocks are recomputed in parallel
//! on the pool the refit runs in; interior boxes in one backward pass over
//! the node array (children always follow their parent). When the refitted
//! tree's SAH cost has grown past `cost_limit` times the last full build's,
//! or a triangle changed validity, the tree is built afresh.

use std::time::Instant;

use rayon::prelude::*;

use super::node::{BVH_WIDTH, BvhNode, EMPTY_SLOT, LEAF_BIT};
use super::{Bvh, LANES, TriBlock};
use crate::error::AccelError;
use crate::geom::aabb::Aabb;
use crate::geom::triangle::Triangle;
use crate::geom::triangle::is_valid_triangle;
use crate::kd::fast_build::parallel_for;

/// Nodes or blocks per parallel task.
const CHUNK: usize = 1024;

impl Bvh {
    /// The BVH of `tris` (the triangles of `prev`'s object after they moved,
    /// as many as before) on `prev`'s topology with new boxes; built afresh
    /// when the count or any triangle's validity changed, or when the SAH
    /// cost exceeds `cost_limit` times [`super::BvhStats::base_cost`] of
    /// `prev`. [`super::BvhStats::refitted`] tells which.
    pub fn refit(prev: &Bvh, tris: Vec<Triangle>, cost_limit: f64) -> Result<Self, AccelError> {
        let start = Instant::now();
        // PERF: parallel only on a pool's thread and for large objects:
        // from another thread rayon hands the work to its global pool and
        // waits (museum1k, 1k triangles: 0.103 ms a refit with, 0.023
        // without; bench rebuild table).
        let parallel = parallel_for(tris.len());
        let same = |(a, b): (&Triangle, &Triangle)| is_valid_triangle(a) == is_valid_triangle(b);
        // PERF: when the last tree dropped nothing (triangles from the API,
        // which drops invalid ones), only the new triangles are tested:
        // half the validity tests.
        let same_validity = tris.len() == prev.tris.len()
            && match (prev.stats.dropped == 0, parallel) {
                (true, true) => tris.par_iter().all(is_valid_triangle),
                (true, false) => tris.iter().all(is_valid_triangle),
                (false, true) => tris.par_iter().zip(prev.tris.par_iter()).all(same),
                (false, false) => tris.iter().zip(&prev.tris).all(same),
            };
        if !same_validity {
            let mut fresh = Self::build(tris)?;
            fresh.stats.build_ms = start.elapsed().as_secs_f64() * 1e3;
            return Ok(fresh);
        }
        let ids = &prev.prim_ids;
        // Each node copied with its leaf boxes recomputed (in parallel; an
        // indexed iterator, so `collect` writes the nodes in place).
        let leaf_boxes = |node: &BvhNode| {
            let mut node = *node;
            for i in 0..BVH_WIDTH {
                let c = node.child[i];
                if c != EMPTY_SLOT && c & LEAF_BIT != 0 {
                    let off = (c & !LEAF_BIT) as usize;
                    let n = node.count[i] as usize;
                    let b = ids[off..off + n]
                        .iter()
                        .fold(Aabb::EMPTY, |b, &p| b.union(Aabb::from_points(&tris[p as usize])));
                    node.set_box(i, &b);
                }
            }
            node
        };
        let mut nodes: Vec<BvhNode> = if parallel {
            prev.nodes.par_iter().with_min_len(CHUNK).map(leaf_boxes).collect()
        } else {
            prev.nodes.iter().map(leaf_boxes).collect()
        };
        // Interior boxes, children before parents.
        for k in (0..nodes.len()).rev() {
            for i in 0..BVH_WIDTH {
                let c = nodes[k].child[i];
                if c & LEAF_BIT == 0 {
                    let b = nodes[c as usize].bounds();
                    nodes[k].set_box(i, &b);
                }
            }
        }
        // NOTE: an indexed parallel iterator, so `collect` writes each block
        // in place (chunks of blocks collected and then concatenated were
        // copied twice).
        let blocks: Vec<TriBlock> = if parallel {
            ids.par_chunks(LANES)
                .with_min_len(CHUNK)
                .map(|b| TriBlock::pack(b, &tris))
                .collect()
        } else {
            ids.chunks(LANES).map(|b| TriBlock::pack(b, &tris)).collect()
        };
        let bounds = nodes.first().map_or(Aabb::EMPTY, BvhNode::bounds);
        let mut bvh = Self {
            nodes,
            nodes8: Vec::new(),
            prim_ids: prev.prim_ids.clone(),
            blocks,
            tris,
            bounds,
            stats: prev.stats,
        };
        bvh.stats.sah_cost = bvh.sah_cost();
        if bvh.stats.sah_cost > prev.stats.base_cost * cost_limit {
            let mut fresh = Self::build(bvh.tris)?;
            fresh.stats.build_ms = start.elapsed().as_secs_f64() * 1e3;
            return Ok(fresh);
        }
        bvh.stats.refitted = true;
        bvh.finish(start);
        Ok(bvh)
    }
}
