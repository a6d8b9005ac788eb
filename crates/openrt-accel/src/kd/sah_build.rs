//! Full-SAH kd-tree construction in O(N log N).
//!
//! Wald & Havran, "On building fast kd-trees for ray tracing, and on doing
//! that in O(N log N)", IEEE Symposium on Interactive Ray Tracing 2006:
//! - one event list per axis (start, planar and end events of the
//!   primitives' bounds) is sorted once at the root;
//! - each node sweeps its three lists to evaluate the SAH at every candidate
//!   plane, with planar primitives tried on either side;
//! - the lists of the children are obtained by splitting the parent's lists,
//!   which keeps them sorted; only the primitives that straddle the plane are
//!   clipped to each child cell ("perfect splits"), and their few new events
//!   are sorted and merged in.
//!
//! Termination: the SAH leaf test (splitting must be cheaper than
//! intersecting everything), the depth limit `8 + 1.3 log2 N`, and a split
//! that would leave every primitive on both sides (duplicates,
//! unsplittable input) ends in a leaf.

use glam::Vec3;

use crate::error::AccelError;
use crate::geom::aabb::Aabb;
use crate::geom::triangle::Triangle;
use crate::kd::node::{KdNode, MAX_DEPTH, MAX_FIELD, MAX_NODES, too_many_nodes};
use crate::kd::sah_params::{BuiltTree, SahParams, default_max_depth};

const END: u32 = 0;
const PLANAR: u32 = 1;
const START: u32 = 2;

const SIDE_BOTH: u8 = 0;
const SIDE_LEFT: u8 = 1;
const SIDE_RIGHT: u8 = 2;

/// A primitive's bound on one axis: position, then `prim << 2 | kind`.
#[derive(Clone, Copy, Debug)]
struct Event {
    pos: f32,
    key: u32,
}

impl Event {
    fn new(pos: f32, prim: u32, kind: u32) -> Self {
        // `+ 0.0` turns -0.0 into +0.0 so that equal positions sort together.
        Self {
            pos: pos + 0.0,
            key: (prim << 2) | kind,
        }
    }
    #[inline]
    fn kind(self) -> u32 {
        self.key & 3
    }
    #[inline]
    fn prim(self) -> usize {
        (self.key >> 2) as usize
    }
    /// Sort key: position (total order of the bits), then kind.
    #[inline]
    fn order(self) -> u64 {
        let b = self.pos.to_bits();
        let s = if b & 0x8000_0000 != 0 { !b } else { b | 0x8000_0000 };
        (u64::from(s) << 2) | u64::from(self.kind())
    }
}

type Events = [Vec<Event>; 3];

/// Builds an SAH kd-tree over the valid triangles (`valid[i]`).
pub(crate) fn build_sah(tris: &[Triangle], valid: &[bool], params: &SahParams) -> Result<BuiltTree, AccelError> {
    if let Some(binned_above) = params.binned_above {
        return crate::kd::binned_sah::build_binned_sah(tris, valid, params, binned_above);
    }
    let n_valid = valid.iter().filter(|&&v| v).count();
    if tris.len() > MAX_FIELD as usize {
        return Err(AccelError::TooManyPrimitives {
            count: tris.len(),
            limit: MAX_FIELD as usize,
        });
    }
    let mut bounds = Aabb::EMPTY;
    let mut events: Events = [
        Vec::with_capacity(2 * n_valid),
        Vec::with_capacity(2 * n_valid),
        Vec::with_capacity(2 * n_valid),
    ];
    for (i, tri) in tris.iter().enumerate() {
        if !valid[i] {
            continue;
        }
        let b = Aabb::from_points(tri);
        bounds = bounds.union(b);
        push_events(&mut events, &b, i as u32);
    }
    for e in &mut events {
        e.sort_unstable_by_key(|e| e.order());
    }
    let max_depth = params
        .max_depth
        .unwrap_or_else(|| default_max_depth(n_valid))
        .min(MAX_DEPTH - 1);
    let mut b = Builder {
        tris,
        params: *params,
        side: vec![SIDE_BOTH; tris.len()],
        nodes: Vec::with_capacity(2 * n_valid / 2 + 1),
        prim_ids: Vec::with_capacity(n_valid * 2),
        max_depth,
        depth_reached: 0,
    };
    if n_valid == 0 {
        b.nodes.push(KdNode::leaf(0, 0));
    } else {
        b.node(bounds, events, n_valid, 0)?;
    }
    Ok(BuiltTree {
        nodes: b.nodes,
        prim_ids: b.prim_ids,
        bounds,
        depth: b.depth_reached,
        cost: None,
        valid: n_valid,
    })
}

fn push_events(events: &mut Events, b: &Aabb, prim: u32) {
    for (k, list) in events.iter_mut().enumerate() {
        if b.min[k] == b.max[k] {
            list.push(Event::new(b.min[k], prim, PLANAR));
        } else {
            list.push(Event::new(b.min[k], prim, START));
            list.push(Event::new(b.max[k], prim, END));
        }
    }
}

struct Builder<'a> {
    tris: &'a [Triangle],
    params: SahParams,
    side: Vec<u8>,
    nodes: Vec<KdNode>,
    prim_ids: Vec<u32>,
    max_depth: usize,
    depth_reached: usize,
}

/// The best plane found by the sweep.
#[derive(Clone, Copy)]
struct Plane {
    axis: usize,
    pos: f32,
    planar_left: bool,
    cost: f32,
}

impl Builder<'_> {
    fn node(&mut self, cell: Aabb, events: Events, n: usize, depth: usize) -> Result<(), AccelError> {
        self.depth_reached = self.depth_reached.max(depth);
        let leaf_cost = self.params.intersection_cost * n as f32;
        let plane = if depth >= self.max_depth {
            None
        } else {
            self.find_plane(&cell, &events, n)
        };
        let Some(plane) = plane.filter(|p| p.cost < leaf_cost) else {
            return self.leaf(&events);
        };
        // Classify the primitives against the plane.
        let (nl, nr, both) = self.classify(&events, n, plane);
        if nl == n && nr == n {
            // Every primitive straddles: splitting can not separate anything.
            return self.leaf(&events);
        }
        let mut left_cell = cell;
        left_cell.max[plane.axis] = plane.pos;
        let mut right_cell = cell;
        right_cell.min[plane.axis] = plane.pos;
        let (el, er) = self.split_events(events, &both, &left_cell, &right_cell);

        let index = self.nodes.len();
        if index >= MAX_NODES as usize {
            return Err(too_many_nodes());
        }
        self.nodes.push(KdNode::interior(plane.axis, plane.pos));
        self.node(left_cell, el, nl, depth + 1)?;
        let above = self.nodes.len() as u32;
        self.nodes[index].set_above_child(above);
        self.node(right_cell, er, nr, depth + 1)
    }

    fn leaf(&mut self, events: &Events) -> Result<(), AccelError> {
        let offset = self.prim_ids.len();
        for e in &events[0] {
            if e.kind() != END {
                self.prim_ids.push(e.prim() as u32);
            }
        }
        let count = self.prim_ids.len() - offset;
        if offset > u32::MAX as usize || count > MAX_FIELD as usize {
            return Err(too_many_nodes());
        }
        self.nodes.push(KdNode::leaf(offset as u32, count as u32));
        Ok(())
    }

    /// Sweeps the three event lists and returns the cheapest plane.
    fn find_plane(&self, cell: &Aabb, events: &Events, n: usize) -> Option<Plane> {
        let sa = cell.surface_area();
        if sa <= 0.0 || !sa.is_finite() {
            return None;
        }
        let inv_sa = 1.0 / sa;
        let ext = cell.extent();
        let (kt, ki, bonus) = (
            self.params.traversal_cost,
            self.params.intersection_cost,
            self.params.empty_bonus,
        );
        let cost = |pl: f32, pr: f32, nl: usize, nr: usize| -> f32 {
            let c = kt + ki * (pl * nl as f32 + pr * nr as f32);
            if nl == 0 || nr == 0 { c * bonus } else { c }
        };
        let mut best: Option<Plane> = None;
        for (k, list) in events.iter().enumerate() {
            if ext[k] <= 0.0 {
                continue;
            }
            let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
            let cross = ext[k1] * ext[k2];
            let perim = ext[k1] + ext[k2];
            let (mut nl, mut nr) = (0usize, n);
            let mut i = 0;
            while i < list.len() {
                let p = list[i].pos;
                let (mut pe, mut pp, mut ps) = (0usize, 0usize, 0usize);
                while i < list.len() && list[i].pos == p && list[i].kind() == END {
                    pe += 1;
                    i += 1;
                }
                while i < list.len() && list[i].pos == p && list[i].kind() == PLANAR {
                    pp += 1;
                    i += 1;
                }
                while i < list.len() && list[i].pos == p && list[i].kind() == START {
                    ps += 1;
                    i += 1;
                }
                nr -= pp + pe;
                if p > cell.min[k] && p < cell.max[k] {
                    let wl = p - cell.min[k];
                    let wr = cell.max[k] - p;
                    let pl = 2.0 * (cross + wl * perim) * inv_sa;
                    let pr = 2.0 * (cross + wr * perim) * inv_sa;
                    let c_left = cost(pl, pr, nl + pp, nr);
                    let c_right = cost(pl, pr, nl, nr + pp);
                    let (c, planar_left) = if c_left <= c_right {
                        (c_left, true)
                    } else {
                        (c_right, false)
                    };
                    if best.is_none_or(|b| c < b.cost) {
                        best = Some(Plane {
                            axis: k,
                            pos: p,
                            planar_left,
                            cost: c,
                        });
                    }
                }
                nl += ps + pp;
            }
        }
        best
    }

    /// Marks each primitive left, right or both; returns the child counts
    /// and the straddling primitives.
    fn classify(&mut self, events: &Events, n: usize, plane: Plane) -> (usize, usize, Vec<u32>) {
        for e in &events[0] {
            if e.kind() != END {
                self.side[e.prim()] = SIDE_BOTH;
            }
        }
        let (mut only_l, mut only_r) = (0usize, 0usize);
        for e in &events[plane.axis] {
            let s = match e.kind() {
                END if e.pos <= plane.pos => SIDE_LEFT,
                START if e.pos >= plane.pos => SIDE_RIGHT,
                PLANAR if e.pos < plane.pos || (e.pos == plane.pos && plane.planar_left) => SIDE_LEFT,
                PLANAR => SIDE_RIGHT,
                _ => continue,
            };
            self.side[e.prim()] = s;
            if s == SIDE_LEFT {
                only_l += 1;
            } else {
                only_r += 1;
            }
        }
        let mut both = Vec::with_capacity(n - only_l - only_r);
        for e in &events[0] {
            if e.kind() != END && self.side[e.prim()] == SIDE_BOTH {
                both.push(e.prim() as u32);
            }
        }
        let nb = both.len();
        (only_l + nb, only_r + nb, both)
    }

    /// Splits the parent's lists into the children's, clipping the
    /// straddling primitives to each child cell.
    fn split_events(&self, events: Events, both: &[u32], left: &Aabb, right: &Aabb) -> (Events, Events) {
        let mut new_l: Events = Default::default();
        let mut new_r: Events = Default::default();
        for &p in both {
            let tri = &self.tris[p as usize];
            let lb = clipped_bounds(tri, left);
            if !lb.is_empty() {
                push_events(&mut new_l, &lb, p);
            }
            let rb = clipped_bounds(tri, right);
            if !rb.is_empty() {
                push_events(&mut new_r, &rb, p);
            }
        }
        let mut out_l: Events = Default::default();
        let mut out_r: Events = Default::default();
        for (k, list) in events.into_iter().enumerate() {
            let mut l = Vec::with_capacity(list.len());
            let mut r = Vec::with_capacity(list.len());
            for e in list {
                match self.side[e.prim()] {
                    SIDE_LEFT => l.push(e),
                    SIDE_RIGHT => r.push(e),
                    _ => {}
                }
            }
            let nl = std::mem::take(&mut new_l[k]);
            let nr = std::mem::take(&mut new_r[k]);
            out_l[k] = merge(l, nl);
            out_r[k] = merge(r, nr);
        }
        (out_l, out_r)
    }
}

/// Sorts `extra` and merges it into the sorted `base`.
fn merge(base: Vec<Event>, mut extra: Vec<Event>) -> Vec<Event> {
    if extra.is_empty() {
        return base;
    }
    extra.sort_unstable_by_key(|e| e.order());
    let mut out = Vec::with_capacity(base.len() + extra.len());
    let (mut i, mut j) = (0, 0);
    while i < base.len() && j < extra.len() {
        if base[i].order() <= extra[j].order() {
            out.push(base[i]);
            i += 1;
        } else {
            out.push(extra[j]);
            j += 1;
        }
    }
    out.extend_from_slice(&base[i..]);
    out.extend_from_slice(&extra[j..]);
    out
}

/// Bounds of the part of `tri` inside `cell` (Sutherland–Hodgman against the
/// six planes), widened by one ulp so rounding never shrinks them, and
/// clamped to the cell. Falls back to the triangle's bounds clamped to the
/// cell if clipping loses everything through rounding.
pub(crate) fn clipped_bounds(tri: &Triangle, cell: &Aabb) -> Aabb {
    let mut poly = [Vec3::ZERO; 9];
    let mut tmp = [Vec3::ZERO; 9];
    poly[..3].copy_from_slice(tri);
    let mut n = 3usize;
    for axis in 0..3 {
        for upper in [false, true] {
            let bound = if upper { cell.max[axis] } else { cell.min[axis] };
            let inside = |p: Vec3| if upper { p[axis] <= bound } else { p[axis] >= bound };
            let mut m = 0usize;
            for i in 0..n {
                let p = poly[i];
                let q = poly[(i + 1) % n];
                let (ip, iq) = (inside(p), inside(q));
                if ip {
                    tmp[m] = p;
                    m += 1;
                }
                if ip != iq && m < tmp.len() {
                    let t = (bound - p[axis]) / (q[axis] - p[axis]);
                    let mut x = p + (q - p) * t;
                    x[axis] = bound;
                    tmp[m] = x;
                    m += 1;
                }
            }
            n = m;
            poly[..n].copy_from_slice(&tmp[..n]);
            if n == 0 {
                break;
            }
        }
        if n == 0 {
            break;
        }
    }
    let clipped = if n == 0 {
        Aabb::from_points(tri).intersection(*cell)
    } else {
        Aabb::from_points(&poly[..n]).enlarged_ulps(1).intersection(*cell)
    };
    if clipped.is_empty() {
        Aabb::from_points(tri).intersection(*cell)
    } else {
        clipped
    }
}
