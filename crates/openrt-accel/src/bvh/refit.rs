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

use glam::{Vec3, Vec4};
use rayon::prelude::*;
use wide::f32x4;

use super::node::{BVH_WIDTH, BvhNode, EMPTY_SLOT, LEAF_BIT};
use super::{Bvh, LANES, TriBlock};
use crate::error::AccelError;
use crate::geom::aabb::Aabb;
use crate::geom::triangle::Triangle;
use crate::geom::triangle::is_valid_triangle;
use crate::kd::fast_build::parallel_for;

/// Nodes or blocks per parallel task.
const CHUNK: usize = 1024;

/// The box of a leaf's blocks (padding lanes repeat a triangle of the
/// leaf): their lanes' boxes merged lane by lane, then across the lanes.
/// The triangles are valid (finite), so `fast_min` and `fast_max` (no NaN
/// handling) answer as `min` and `max`.
fn blocks_bounds(blocks: &[TriBlock]) -> Aabb {
    let inf = f32x4::splat(f32::INFINITY);
    let (mut lo, mut hi) = ([inf; 3], [-inf; 3]);
    for b in blocks {
        let (l, h) = b.lane_bounds();
        for k in 0..3 {
            lo[k] = lo[k].fast_min(l[k]);
            hi[k] = hi[k].fast_max(h[k]);
        }
    }
    let least = |v: f32x4| Vec4::from_array(v.to_array()).min_element();
    let most = |v: f32x4| Vec4::from_array(v.to_array()).max_element();
    Aabb {
        min: Vec3::new(least(lo[0]), least(lo[1]), least(lo[2])),
        max: Vec3::new(most(hi[0]), most(hi[1]), most(hi[2])),
    }
}

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
        let ids = &prev.prim_ids;
        // When the last tree dropped nothing (triangles from the API, which
        // drops invalid ones), its blocks hold every triangle: they are
        // packed first and tested four at a time. Otherwise each triangle's
        // validity is compared with its old one first.
        let all_kept = tris.len() == prev.tris.len() && prev.stats.dropped == 0;
        if !all_kept {
            let same = |(a, b): (&Triangle, &Triangle)| is_valid_triangle(a) == is_valid_triangle(b);
            let same_validity = tris.len() == prev.tris.len()
                && if parallel {
                    tris.par_iter().zip(prev.tris.par_iter()).all(same)
                } else {
                    tris.iter().zip(&prev.tris).all(same)
                };
            if !same_validity {
                return Self::afresh(tris, start);
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
        if all_kept {
            let valid = if parallel {
                blocks.par_iter().with_min_len(CHUNK).all(TriBlock::all_valid)
            } else {
                blocks.iter().all(TriBlock::all_valid)
            };
            if !valid {
                return Self::afresh(tris, start);
            }
        }
        // Each node copied with its leaf boxes recomputed from the leaves'
        // blocks (in parallel; an indexed iterator, so `collect` writes the
        // nodes in place).
        let leaf_boxes = |node: &BvhNode| {
            let mut node = *node;
            for i in 0..BVH_WIDTH {
                let c = node.child[i];
                if c != EMPTY_SLOT && c & LEAF_BIT != 0 {
                    // Leaves begin on a block (`pack` pads each one).
                    let off = (c & !LEAF_BIT) as usize;
                    debug_assert_eq!(off % LANES, 0);
                    let first = off / LANES;
                    let n = (node.count[i] as usize).div_ceil(LANES);
                    node.set_box(i, &blocks_bounds(&blocks[first..first + n]));
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
            return Self::afresh(bvh.tris, start);
        }
        bvh.stats.refitted = true;
        bvh.finish(start);
        Ok(bvh)
    }

    /// The refit's fallback: `tris` built afresh, timed from `start`.
    fn afresh(tris: Vec<Triangle>, start: Instant) -> Result<Self, AccelError> {
        let mut fresh = Self::build(tris)?;
        fresh.stats.build_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(fresh)
    }
}
