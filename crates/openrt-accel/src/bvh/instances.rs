//! A wide BVH over instance boxes: the top level as a BVH, beside the
//! paper's BSP (`toplevel/bsp.rs`).
//!
//! The object BVH's builder (binned SAH grown into four-wide nodes) over
//! the instances' world boxes; a leaf holds one instance (two where the
//! builder's leaf held more than four), its box laid out in a [`BoxQuad`]
//! for the caller's per-instance test. The extra level stays far below
//! `BVH_MAX_DEPTH` (SAH splits to depth 32, then median splits). Each instance sits in exactly one leaf, so a walk meets it at
//! most once (no mailbox). Single rays walk it with the object BVH's node
//! test (`walk.rs`), packets with its packet walk (`packet.rs`: first
//! active lane, frustum or interval culling), lanes with a zero direction
//! component alone; callers test each instance's box per lane, so the set
//! of instances a lane tests is the set whose box it reaches before its
//! closest hit, as with the BSP.

use super::build::{Ref, bounds_of, build_into};
use glam::Vec3;

use super::node::{BVH_WIDTH, BvhNode, EMPTY_SLOT, LEAF_BIT};
use super::packet::{Cull, LaneRays, parallel_lanes, walk_packet};
use super::walk::walk;
use crate::error::AccelError;
use crate::geom::aabb::Aabb;
use crate::geom::box_quad::BoxQuad;
use crate::geom::ray::Ray;
use crate::packet::boxes::{BOX_SLACK, PacketBoxes};
use crate::packet::frustum::Frustum;
use crate::packet::width::lanes_of;

/// Most instances an [`InstanceBvh`] takes (leaf offsets stay below bit 31).
pub const INSTANCE_BVH_MAX: usize = 1 << 26;

/// Instances from which [`InstanceBvh::build`], called on a rayon pool's
/// thread, builds subtrees as tasks of that pool.
// PERF: below it the tasks' hand-over costs more than the second thread
// saves.
pub const INSTANCE_BVH_POOL_MIN: usize = 2048;

/// Instances in a subtree built as a task of its own (see
/// [`INSTANCE_BVH_POOL_MIN`]).
pub const INSTANCE_BVH_TASK_MIN: usize = 512;

/// Refuses more than [`INSTANCE_BVH_MAX`] instances.
fn check_count(count: usize) -> Result<(), AccelError> {
    if count > INSTANCE_BVH_MAX {
        return Err(AccelError::TooManyPrimitives {
            count,
            limit: INSTANCE_BVH_MAX,
        });
    }
    Ok(())
}

/// A wide BVH over instance world boxes (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct InstanceBvh {
    nodes: Vec<BvhNode>,
    /// Instance indices, each leaf's padded to a multiple of four with
    /// repeats of its last (never visited: a leaf's count bounds its loop).
    items: Vec<u32>,
    /// The boxes of `items`, four to a quad.
    quads: Vec<BoxQuad>,
    bounds: Aabb,
}

impl InstanceBvh {
    /// The BVH of `boxes` (instance `i` has box `boxes[i]`); empty and
    /// non-finite boxes are left out (an instance no ray can reach). On a
    /// rayon pool's thread, from [`INSTANCE_BVH_POOL_MIN`] boxes, subtrees
    /// are built as tasks of that pool (the same tree on any number of its
    /// threads).
    ///
    /// # Errors
    /// [`AccelError::TooManyPrimitives`] past [`INSTANCE_BVH_MAX`] boxes.
    pub fn build(boxes: &[Aabb]) -> Result<Self, AccelError> {
        check_count(boxes.len())?;
        // NOTE: each box widened by the box part of `ray_reaches`' slack,
        // so that a node test passes wherever the caller's per-instance
        // test could.
        let widened = |b: &Aabb| {
            let slack = Vec3::splat(BOX_SLACK * b.min.abs().max(b.max.abs()).max_element());
            Aabb::new(b.min - slack, b.max + slack)
        };
        let mut refs: Vec<Ref> = boxes
            .iter()
            .enumerate()
            .filter(|(_, b)| !b.is_empty() && b.is_finite())
            .map(|(i, b)| {
                let w = widened(b);
                Ref::new(w.min, w.max, i as u32)
            })
            .collect();
        let bounds = bounds_of(&refs);
        let mut nodes = Vec::with_capacity(refs.len() / 2 + 1);
        if !refs.is_empty() {
            // Large trees on a pool's thread: subtrees as its tasks.
            let task_min = if refs.len() >= INSTANCE_BVH_POOL_MIN && rayon::current_thread_index().is_some() {
                INSTANCE_BVH_TASK_MIN
            } else {
                usize::MAX
            };
            build_into(&mut refs, 0, bounds, None, 0, task_min, &mut nodes);
        }
        let ids: Vec<u32> = refs.iter().map(Ref::id).collect();
        // Leaves of several instances become nodes of single instances (of
        // two, past four), so that the node test orders them front to back
        // and culls each (tested in index order, terrain primary packets
        // took 204 ms against 199).
        for k in 0..nodes.len() {
            for i in 0..BVH_WIDTH {
                let (c, n) = (nodes[k].child[i], nodes[k].count[i] as usize);
                if c == EMPTY_SLOT || c & LEAF_BIT == 0 || n < 2 {
                    continue;
                }
                let off = (c & !LEAF_BIT) as usize;
                let per = n.div_ceil(BVH_WIDTH);
                let mut node = BvhNode::empty();
                for (j, start) in (off..off + n).step_by(per).enumerate() {
                    let end = (start + per).min(off + n);
                    let b = ids[start..end]
                        .iter()
                        .fold(Aabb::EMPTY, |a, &id| a.union(widened(&boxes[id as usize])));
                    node.set_box(j, &b);
                    node.child[j] = LEAF_BIT | start as u32;
                    node.count[j] = (end - start) as u32;
                }
                nodes[k].child[i] = nodes.len() as u32;
                nodes[k].count[i] = 0;
                nodes.push(node);
            }
        }
        let mut items = Vec::with_capacity(ids.len() * 4);
        let mut quads = Vec::with_capacity(ids.len());
        for node in &mut nodes {
            for i in 0..BVH_WIDTH {
                let c = node.child[i];
                if c == EMPTY_SLOT || c & LEAF_BIT == 0 {
                    continue;
                }
                let (off, n) = ((c & !LEAF_BIT) as usize, node.count[i] as usize);
                node.child[i] = LEAF_BIT | items.len() as u32;
                for four in ids[off..off + n].chunks(4) {
                    let mut b = [Aabb::EMPTY; 4];
                    for (slot, &k) in b.iter_mut().zip(four) {
                        *slot = boxes[k as usize];
                    }
                    quads.push(BoxQuad::pack(&b[..four.len()]));
                    items.extend_from_slice(four);
                    items.resize(items.len() + 4 - four.len(), four[four.len() - 1]);
                }
            }
        }
        let bvh = Self {
            nodes,
            items,
            quads,
            bounds,
        };
        debug_assert!(bvh.validate(boxes).is_ok(), "{:?}", bvh.validate(boxes));
        Ok(bvh)
    }

    /// The box around every instance in the tree.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Wide nodes (none for a tree without instances).
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The instances of a leaf and their box quads.
    #[inline]
    fn leaf(&self, off: u32, count: u32) -> (&[u32], &[BoxQuad]) {
        let (off, n) = (off as usize, count as usize);
        (&self.items[off..off + n], &self.quads[off / 4..(off + n).div_ceil(4)])
    }

    /// Walks `ray` front to back up to `*closest` and calls
    /// `leaf(instances, quads, closest)` for each leaf whose box it may
    /// meet (the leaf's instances, at most four per quad of their boxes,
    /// in the same order); `leaf` lowers `closest` for its hits and
    /// returns `true` to stop. Returns whether it was stopped.
    #[inline]
    pub fn walk<L>(&self, ray: &Ray, closest: &mut f32, mut leaf: L) -> bool
    where
        L: FnMut(&[u32], &[BoxQuad], &mut f32) -> bool,
    {
        walk(&self.nodes, ray, closest, |off, count, closest| {
            let (items, quads) = self.leaf(off, count);
            leaf(items, quads, closest)
        })
    }

    /// Walks the packet's `lanes` (each up to its `closest`) and calls
    /// `leaf(instances, quads, lanes, closest)` for each leaf reached with
    /// the lanes that may meet its box (a superset: callers test each
    /// instance's box per lane); `leaf` lowers `closest` for its hits and
    /// returns the lanes it finished, which leave the walk. `frustum`: the
    /// lanes' frustum when they share an origin or end point; else the
    /// packet is culled by the intervals of its lanes (`boxes`). Lanes with
    /// a zero direction component walk alone. Returns the lanes finished.
    #[inline]
    pub fn walk_packet<const N: usize, L>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        closest: &mut [f32; N],
        frustum: Option<&Frustum>,
        boxes: &PacketBoxes<N>,
        mut leaf: L,
    ) -> u32
    where
        L: FnMut(&[u32], &[BoxQuad], u32, &mut [f32; N]) -> u32,
    {
        if self.nodes.is_empty() || lanes == 0 {
            return 0;
        }
        let alone = if N < 4 { lanes } else { parallel_lanes(rays, lanes) };
        let mut finished = 0;
        for l in lanes_of(alone) {
            let mut c = closest[l];
            let mut done = 0;
            walk(&self.nodes, &rays[l], &mut c, |off, count, c| {
                let (items, quads) = self.leaf(off, count);
                closest[l] = *c;
                done = leaf(items, quads, 1 << l, closest) & (1 << l);
                *c = closest[l];
                done != 0
            });
            finished |= done;
        }
        let live = lanes & !alone;
        if live == 0 {
            return finished;
        }
        let lr = LaneRays::from_laid(boxes);
        let cull = Cull::of(frustum, Some(boxes), live);
        finished
            | walk_packet(&self.nodes, &lr, live, closest, &cull, |off, count, active, closest| {
                let (items, quads) = self.leaf(off, count);
                leaf(items, quads, active, closest)
            })
    }

    /// Checks the tree against `boxes`: every usable box in exactly one
    /// leaf, every child box around its contents, quads holding the
    /// leaves' boxes.
    ///
    /// # Errors
    /// [`AccelError::Invalid`] naming the first broken rule.
    pub fn validate(&self, boxes: &[Aabb]) -> Result<(), AccelError> {
        let err = |m: String| Err(AccelError::Invalid(format!("instance BVH: {m}")));
        let mut seen = vec![0u32; boxes.len()];
        let mut stack = if self.nodes.is_empty() {
            vec![]
        } else {
            vec![(0u32, self.bounds)]
        };
        while let Some((k, outer)) = stack.pop() {
            let Some(node) = self.nodes.get(k as usize) else {
                return err(format!("node {k} out of range"));
            };
            for i in 0..node.child.len() {
                let c = node.child[i];
                if c == EMPTY_SLOT {
                    continue;
                }
                let b = node.child_box(i);
                if !outer.contains_box(&b) {
                    return err(format!("node {k} child {i}: box outside its parent's"));
                }
                if c & LEAF_BIT == 0 {
                    stack.push((c, b));
                    continue;
                }
                let (off, n) = ((c & !LEAF_BIT) as usize, node.count[i] as usize);
                if off % 4 != 0 || off + n > self.items.len() || n == 0 {
                    return err(format!("node {k} child {i}: leaf range {off}+{n}"));
                }
                let (items, quads) = self.leaf(off as u32, n as u32);
                for (q, four) in quads.iter().zip(items.chunks(4)) {
                    let want: Vec<Aabb> = four
                        .iter()
                        .map(|&j| boxes.get(j as usize).copied().unwrap_or(Aabb::EMPTY))
                        .collect();
                    if !q.same_bits(&BoxQuad::pack(&want)) {
                        return err(format!("node {k} child {i}: quad differs from its boxes"));
                    }
                }
                for &j in items {
                    let Some(bj) = boxes.get(j as usize) else {
                        return err(format!("instance {j} out of range"));
                    };
                    if !b.contains_box(bj) {
                        return err(format!("instance {j} outside its leaf's box"));
                    }
                    seen[j as usize] += 1;
                }
            }
        }
        for (j, (b, &s)) in boxes.iter().zip(&seen).enumerate() {
            let usable = !b.is_empty() && b.is_finite();
            if s != u32::from(usable) {
                return err(format!("instance {j} in {s} leaves"));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    use super::*;
    use crate::packet::boxes::ray_reaches;
    use crate::testing::meshgen;

    /// Boxes of every kind: small and large, overlapping, repeated, flat,
    /// empty, infinite and NaN.
    fn boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = SmallRng::seed_from_u64(seed);
        (0..n)
            .map(|i| {
                let c = Vec3::new(
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-2.0..2.0),
                );
                let h = Vec3::new(
                    rng.random_range(0.0..2.0),
                    rng.random_range(0.0..2.0),
                    rng.random_range(0.0..2.0),
                );
                match i % 23 {
                    0 => Aabb::EMPTY,
                    1 => Aabb::new(c, c + Vec3::new(0.0, 1.0, 1.0)),
                    2 => Aabb::new(Vec3::splat(-1.0), Vec3::new(f32::INFINITY, 1.0, 1.0)),
                    3 => Aabb::new(Vec3::splat(f32::NAN), Vec3::ONE),
                    4 => Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0)),
                    _ => Aabb::new(c - h, c + h),
                }
            })
            .collect()
    }

    /// The instances whose box a ray may reach, as the caller tests them
    /// (with their slack).
    fn reached(all: &[Aabb], ray: &Ray) -> Vec<u32> {
        (0..all.len() as u32)
            .filter(|&i| {
                let b = &all[i as usize];
                !b.is_empty() && b.is_finite() && ray_reaches(b, ray, ray.t_max)
            })
            .collect()
    }

    /// The instances whose box the ray meets (the exact clip).
    fn met(all: &[Aabb], ray: &Ray) -> Vec<u32> {
        (0..all.len() as u32)
            .filter(|&i| {
                let b = &all[i as usize];
                b.is_finite() && b.clip(ray).is_some()
            })
            .collect()
    }

    /// `got` (sorted) holds every instance of `must` and none beyond `may`.
    fn between(got: &[u32], must: &[u32], may: &[u32]) -> bool {
        must.iter().all(|i| got.binary_search(i).is_ok()) && got.iter().all(|i| may.binary_search(i).is_ok())
    }

    #[test]
    fn builds_valid_trees_of_any_count_leaving_unusable_boxes_out() {
        for n in [0, 1, 2, 3, 5, 17, 64, 700] {
            let all = boxes(n, n as u64);
            let t = InstanceBvh::build(&all).unwrap();
            t.validate(&all).unwrap();
            assert_eq!(t.node_count() == 0, all.iter().all(|b| b.is_empty() || !b.is_finite()));
            // A tree checked against other boxes fails.
            if n > 5 {
                let mut moved = all.clone();
                moved[5] = Aabb::new(Vec3::splat(50.0), Vec3::splat(51.0));
                assert!(t.validate(&moved).is_err(), "{n} boxes");
            }
        }
    }

    #[test]
    fn large_trees_built_on_a_pool_are_the_same_on_any_thread_count() {
        let all = boxes(3 * INSTANCE_BVH_POOL_MIN, 17);
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let t = pool.install(|| InstanceBvh::build(&all)).unwrap();
            t.validate(&all).unwrap();
            t
        };
        let layout = |t: &InstanceBvh| format!("{:?} {:?}", t.nodes, t.items);
        let one = on(1);
        // Subtrees appended in child order: the depth-first layout of the
        // build off the pool, on any number of threads.
        let serial = layout(&InstanceBvh::build(&all).unwrap());
        assert!(layout(&one) == serial, "one thread: another tree");
        for threads in [2, 3] {
            assert!(layout(&on(threads)) == serial, "{threads} threads: another tree");
        }
    }

    /// Each packet lane is handed the instances its own ray would be.
    fn packets<const N: usize>(t: &InstanceBvh, all: &[Aabb], rays: &[Ray]) {
        for (p, chunk) in rays.chunks_exact(N).enumerate() {
            let pk: [Ray; N] = std::array::from_fn(|l| chunk[l]);
            let lanes = if p % 2 == 0 { u32::MAX >> (32 - N) } else { 0x5 };
            let frustum = if p % 3 == 0 { Frustum::new(&pk, lanes) } else { None };
            let boxes = PacketBoxes::new(&pk, lanes);
            let mut closest: [f32; N] = std::array::from_fn(|l| pk[l].t_max);
            let mut seen = vec![Vec::new(); N];
            t.walk_packet(
                &pk,
                lanes,
                &mut closest,
                frustum.as_ref(),
                &boxes,
                |items, _, active, c| {
                    for &i in items {
                        let b = &all[i as usize];
                        for l in lanes_of(boxes.reaching(b, active, c)) {
                            seen[l].push(i);
                        }
                    }
                    0
                },
            );
            for l in 0..N {
                let mut got = seen[l].clone();
                got.sort_unstable();
                let mut dedup = got.clone();
                dedup.dedup();
                assert_eq!(dedup.len(), got.len(), "packet {p} lane {l}: an instance twice");
                let (must, may) = if lanes & (1 << l) != 0 {
                    (met(all, &pk[l]), reached(all, &pk[l]))
                } else {
                    (Vec::new(), Vec::new())
                };
                assert!(between(&got, &must, &may), "packet {p} lane {l} of {N}: {got:?}");
            }
        }
    }
    /// A single ray's walk hands over every instance whose box it meets,
    /// at most once, and none the caller's own test would refuse; so do
    /// packets (4, 8, 16, 32 lanes, with and without a frustum, lanes with
    /// zero direction components among them) for each lane.
    #[test]
    fn walks_reach_every_instance_a_ray_reaches_once() {
        let all = boxes(400, 9);
        let t = InstanceBvh::build(&all).unwrap();
        let bounds = Aabb::new(Vec3::new(-12.0, -12.0, -4.0), Vec3::new(12.0, 12.0, 4.0));
        let mut rays = meshgen::random_rays(600, 3, bounds);
        rays.extend(meshgen::camera_rays(
            Vec3::new(0.0, -25.0, 3.0),
            Vec3::ZERO,
            16,
            16,
            50.0,
        ));
        for k in 0..32 {
            let o = Vec3::new(k as f32 * 0.7 - 11.0, -15.0, (k % 4) as f32 - 1.5);
            rays.push(Ray::new(o, Vec3::Y, 0.0, f32::INFINITY));
        }
        let mut handed = 0;
        for ray in &rays {
            let mut seen = Vec::new();
            let mut closest = ray.t_max;
            t.walk(ray, &mut closest, |items, quads, c| {
                for (four, q) in items.chunks(4).zip(quads) {
                    let reach = crate::packet::boxes::ray_reaches_quad(q, ray, *c);
                    seen.extend(
                        four.iter()
                            .enumerate()
                            .filter(|(j, _)| reach & (1 << j) != 0)
                            .map(|(_, &i)| i),
                    );
                }
                false
            });
            let mut sorted = seen.clone();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), seen.len(), "an instance handed over twice");
            assert!(between(&sorted, &met(&all, ray), &reached(&all, ray)), "{sorted:?}");
            handed += seen.len();
        }
        assert!(handed > 1000, "{handed} instances handed over");
        packets::<4>(&t, &all, &rays);
        packets::<8>(&t, &all, &rays);
        packets::<16>(&t, &all, &rays);
        packets::<32>(&t, &all, &rays);
    }

    #[test]
    fn refuses_more_instances_than_its_limit() {
        // NOTE: the count alone (a slice of 2^26 boxes is 1.5 GB).
        assert!(check_count(INSTANCE_BVH_MAX).is_ok());
        let e = check_count(INSTANCE_BVH_MAX + 1).unwrap_err();
        assert!(matches!(
            e,
            AccelError::TooManyPrimitives {
                limit: INSTANCE_BVH_MAX,
                ..
            }
        ));
        assert!(e.to_string().contains(&INSTANCE_BVH_MAX.to_string()), "{e}");
    }
}
