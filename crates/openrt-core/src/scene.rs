//! A committed frame: instances, the top-level BSP and two-level traversal.

use std::sync::Arc;

use glam::{Vec2, Vec3};
use openrt_accel::{
    Aabb, InstanceBsp, PacketBoxes, PacketInterval, Ray, Triangle, lanes_of, ray_reaches_quad, traverse,
    traverse_packet_laid,
};

use crate::instance::InstanceRecord;
use crate::occluder_hint::{HINT_MARGIN, OccluderHint};
use crate::{CoreError, InstanceId, Material, MaterialId, ObjectId, Texture};

/// The most instances tested before the top-level walk ([`Scene::global_instances`]).
pub const MAX_GLOBAL_INSTANCES: usize = 4;

/// An instance whose world box has at least this share of the surface area
/// of the box around all instances is tested before the top-level walk.
pub const GLOBAL_AREA_SHARE: f32 = 0.5;

/// The boxes the top-level BSP is built over (the instances' world boxes,
/// the global ones left out as empty) and the global instances.
pub(crate) fn top_level_boxes(instances: &[InstanceRecord]) -> (Vec<Aabb>, Vec<u32>) {
    let mut boxes: Vec<Aabb> = instances.iter().map(|r| r.world_bounds).collect();
    let globals = global_instances(&boxes);
    for &i in &globals {
        boxes[i as usize] = Aabb::EMPTY;
    }
    (boxes, globals)
}

/// The instances (indices into `boxes`, in order, at most
/// [`MAX_GLOBAL_INSTANCES`]) whose world boxes take at least
/// [`GLOBAL_AREA_SHARE`] of the surface area of the box around all of
/// them, in a scene of more than `MAX_GLOBAL_INSTANCES` instances: the
/// ground or the city that every ray may meet. Such a box is in every cell
/// of the top-level BSP, where it makes cells crowded and a plane rarely
/// valid (Algorithm 1); tested first, it also gives every ray its
/// closest hit so far before the walk.
pub(crate) fn global_instances(boxes: &[Aabb]) -> Vec<u32> {
    if boxes.len() <= MAX_GLOBAL_INSTANCES {
        return Vec::new();
    }
    let usable = |b: &&Aabb| !b.is_empty() && b.is_finite();
    let all = boxes.iter().filter(usable).fold(Aabb::EMPTY, |a, b| a.union(*b));
    let area = all.surface_area();
    if !(area > 0.0 && area.is_finite()) {
        return Vec::new();
    }
    boxes
        .iter()
        .enumerate()
        .filter(|(_, b)| usable(b) && b.surface_area() >= GLOBAL_AREA_SHARE * area)
        .take(MAX_GLOBAL_INSTANCES)
        .map(|(i, _)| i as u32)
        .collect()
}

/// Entries of the mailboxes (one per ray, or one per packet with a lane mask
/// per entry), direct-mapped on the instance index.
///
/// PERF: a terrain ray tests about nine instances of 661; in 32 slots two
/// of them often shared one, and the first, met again in a later cell, was
/// tested again (a whole walk of its tree). 64 slots: terrain primary
/// queries 221 ms against 275 (packets), 421 against 535 (single rays),
/// shadows 165 against 171; kitchen, robots and museum1k within 1%. 128
/// and 256 slots gained 3-5% more on the terrain and cost the others 1-2%.
const MAILBOX: usize = 64;

/// The closest hit in a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneHit {
    /// [`Scene::frame`] of the scene that found the hit; [`Scene::surface`]
    /// takes only its own scene's hits.
    pub frame: u64,
    /// Ray parameter (same in world and object space).
    pub t: f32,
    /// Index into [`Scene::instances`].
    pub instance: u32,
    /// Triangle index in the instance's object.
    pub prim: u32,
    /// Barycentric weight of the second vertex.
    pub b1: f32,
    /// Barycentric weight of the third vertex.
    pub b2: f32,
}

/// Everything shading needs about a hit point, in world space.
// PERF: 16-byte aligned: a packet's surfaces are copied in 16-byte moves,
// and unaligned ones stalled on partly overlapping loads and stores
// (kitchen GL-like frames 0.97-0.98 of the time aligned, with `Facing`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(align(16))]
pub struct Surface {
    /// Hit point.
    pub point: Vec3,
    /// Unit geometric normal, oriented by the triangle's winding as seen in
    /// world space (mirroring transforms keep it consistent).
    pub geometric_normal: Vec3,
    /// Unit shading normal: interpolated vertex normals through the inverse
    /// transpose, or the geometric normal when the triangle has none.
    pub shading_normal: Vec3,
    /// Interpolated texture coordinates.
    pub uv: Vec2,
    /// Largest |coordinate| of the hit triangle's world vertices: the
    /// magnitude that bounds the rounding error of `point` (for ray offsets).
    pub error_scale: f32,
    /// Twice the area of the hit triangle in texture space (`|duv1 x duv2|`).
    pub uv_area: f32,
    /// Twice the area of the hit triangle in world space.
    pub world_area: f32,
    /// Material of the triangle.
    pub material: MaterialId,
    /// The instance hit.
    pub instance: InstanceId,
    /// Its object.
    pub object: ObjectId,
}

/// A committed, immutable frame that any number of threads can trace.
#[derive(Debug, Default)]
pub struct Scene {
    /// Shared with the next frame's scene when no instance changed.
    pub(crate) instances: Arc<Vec<InstanceRecord>>,
    /// Shared with the next frame's scene when no instance box changed.
    pub(crate) bsp: Arc<InstanceBsp>,
    /// Instances whose world box spans most of the scene ([`global_instances`]),
    /// tested before the walk and left out of the BSP.
    pub(crate) globals: Arc<Vec<u32>>,
    /// The top level as a BVH over the same boxes, walked instead of the BSP.
    pub(crate) tbvh: Option<Arc<openrt_accel::InstanceBvh>>,
    pub(crate) materials: Arc<Vec<Material>>,
    pub(crate) textures: Arc<Vec<Arc<Texture>>>,
    pub(crate) frame: u64,
}

impl Scene {
    /// The instances of this frame, in top-level index order.
    #[must_use]
    pub fn instances(&self) -> &[InstanceRecord] {
        &self.instances
    }

    /// The top-level BSP (empty when the top level is a BVH).
    #[must_use]
    pub fn bsp(&self) -> &InstanceBsp {
        &self.bsp
    }

    /// The top-level BVH, when the commit chose one ([`crate::TopLevel`]).
    #[must_use]
    pub fn instance_bvh(&self) -> Option<&openrt_accel::InstanceBvh> {
        self.tbvh.as_deref()
    }

    /// The structure of this frame's top level: [`TopLevel::Bsp`] or
    /// [`TopLevel::Bvh`].
    ///
    /// [`TopLevel::Bsp`]: crate::TopLevel::Bsp
    /// [`TopLevel::Bvh`]: crate::TopLevel::Bvh
    #[must_use]
    pub fn top_level(&self) -> crate::TopLevel {
        if self.tbvh.is_some() {
            crate::TopLevel::Bvh
        } else {
            crate::TopLevel::Bsp
        }
    }

    /// The instances tested before the top-level walk, left out of its BSP
    /// ([`MAX_GLOBAL_INSTANCES`], [`GLOBAL_AREA_SHARE`]).
    #[must_use]
    pub fn global_instances(&self) -> &[u32] {
        &self.globals
    }

    /// Checks the top level: the global instances are those of the
    /// instances' world boxes, and the BSP or the BVH holds every other box
    /// ([`InstanceBsp::validate`], [`InstanceBvh::validate`]).
    ///
    /// # Errors
    /// The first rule broken, as the tree's `validate` states it.
    ///
    /// [`InstanceBvh::validate`]: openrt_accel::InstanceBvh::validate
    pub fn validate_top_level(&self) -> Result<(), openrt_accel::AccelError> {
        let (boxes, globals) = top_level_boxes(&self.instances);
        if *self.globals != globals {
            return Err(openrt_accel::AccelError::Invalid(format!(
                "global instances {:?} are not those of the boxes ({globals:?})",
                self.globals
            )));
        }
        match &self.tbvh {
            Some(t) => t.validate(&boxes),
            None => self.bsp.validate(&boxes),
        }
    }

    /// The material table.
    #[must_use]
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    /// The texture table.
    #[must_use]
    pub fn textures(&self) -> &[Arc<Texture>] {
        &self.textures
    }

    /// Frame number of the commit that made this scene (0 before any commit).
    #[must_use]
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// Triangles in the scene counted per instance.
    #[must_use]
    pub fn instanced_triangles(&self) -> usize {
        self.instances.iter().map(|i| i.geometry.tree.triangles().len()).sum()
    }

    /// Closest hit in `(ray.t_min, ray.t_max)`.
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<SceneHit> {
        let mut tests = 0;
        self.intersect_counted(ray, &mut tests)
    }

    /// [`Scene::intersect`], also counting object-tree traversals (instance tests).
    ///
    /// Two-level traversal (Wald, Benthin & Slusallek 2003): the ray is
    /// clipped to the scene box and walks the top-level BSP front to back; in
    /// a leaf each instance not yet tested by this ray (mailbox) gets the ray
    /// in its object space, clipped to the object's bounds, up to the closest
    /// hit so far. Since an instance's hit may lie beyond the current cell,
    /// the walk continues until the next cell starts beyond the closest hit.
    pub fn intersect_counted(&self, ray: &Ray, tests: &mut u32) -> Option<SceneHit> {
        let mut best = None;
        self.walk(ray, |i, inst, closest| {
            *tests += 1;
            let local = inst.ray_to_object(ray, *closest);
            if let Some(h) = inst.geometry.tree.intersect_within(&local, closest) {
                best = Some(SceneHit {
                    frame: self.frame,
                    t: h.t,
                    instance: i,
                    prim: h.prim,
                    b1: h.b1,
                    b2: h.b2,
                });
            }
            false
        });
        best
    }

    /// `true` when anything is hit in `(ray.t_min, ray.t_max)`.
    #[must_use]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.walk(ray, |_, inst, closest| {
            inst.geometry.tree.occluded(&inst.ray_to_object(ray, *closest))
        })
    }

    /// [`Scene::occluded`], trying the triangles of `hint`'s leaf first
    /// (where an earlier ray towards the same light was blocked) and keeping
    /// where this ray was blocked in it. The same answer whatever the hint
    /// holds (see [`OccluderHint`]).
    #[must_use]
    pub fn occluded_hinted(&self, ray: &Ray, hint: &mut OccluderHint) -> bool {
        if self.hint_blocks(hint, ray) {
            return true;
        }
        let mut found = None;
        let blocked = self.walk(ray, |i, inst, closest| {
            found = inst
                .geometry
                .tree
                .occluder(&inst.ray_to_object(ray, *closest))
                .map(|leaf| (i, leaf));
            found.is_some()
        });
        if found.is_some() {
            hint.leaf = found;
        }
        blocked
    }

    /// `true` when a triangle of the hint's leaf blocks `ray` well inside the
    /// ray's interval and inside the triangle ([`HINT_MARGIN`]): there, the
    /// walk would find a blocker too.
    fn hint_blocks(&self, hint: &OccluderHint, ray: &Ray) -> bool {
        let Some((i, leaf)) = hint.leaf else {
            return false;
        };
        self.instances.get(i as usize).is_some_and(|inst| {
            // NOTE: the ray the walk gives the instance, bit for bit.
            inst.geometry
                .tree
                .leaf_blocks(&inst.ray_to_object(ray, ray.t_max), leaf, HINT_MARGIN)
        })
    }

    /// The two-level walk shared by both queries: clip to the scene box,
    /// traverse the top-level BSP front to back (or walk the instance BVH,
    /// where each instance is met once), and call `test(index,
    /// instance, closest)` once per instance per ray (a direct-mapped
    /// mailbox of tested instances: a test repeated after two tested
    /// instances shared a slot finds nothing closer than before),
    /// for the instances whose world box the ray may reach before
    /// `closest` (`ray_reaches_quad`, four boxes at a time). `test` returns
    /// `true` to stop; the walk returns whether it was stopped.
    #[inline]
    fn walk<F>(&self, ray: &Ray, mut test: F) -> bool
    where
        F: FnMut(u32, &InstanceRecord, &mut f32) -> bool,
    {
        let mut closest = ray.t_max;
        for &i in self.globals.iter() {
            let inst = &self.instances[i as usize];
            if inst.world_bounds.clip(&ray.with_interval(ray.t_min, closest)).is_some() && test(i, inst, &mut closest) {
                return true;
            }
        }
        if let Some(t) = &self.tbvh {
            return t.walk(ray, &mut closest, |items, quads, closest| {
                for (four, quad) in items.chunks(4).zip(quads) {
                    let reach = ray_reaches_quad(quad, ray, *closest);
                    for (j, &i) in four.iter().enumerate() {
                        if reach & (1 << j) != 0 && test(i, &self.instances[i as usize], closest) {
                            return true;
                        }
                    }
                }
                false
            });
        }
        let Some((t0, t1)) = self.bsp.bounds().clip(ray) else {
            return false;
        };
        let mut mailbox = [u32::MAX; MAILBOX];
        traverse(self.bsp.nodes(), ray, t0, t1, &mut closest, |leaf, closest| {
            let quads = self.bsp.leaf_box_quads(leaf);
            for (q, four) in self.bsp.leaf_items(leaf).chunks(4).enumerate() {
                // PERF: the world boxes first, four at a time, from the
                // world ray's own reciprocals, before the ray is moved into
                // object space (a transform and six divisions) to miss the
                // object's box there: a terrain ray met 51 instances, most
                // of them so; one box at a time this was a quarter of robots'
                // single-ray queries.
                // NOTE: a ray that misses a box before `closest` misses the
                // instance anywhere it could still count (`closest` only
                // falls, so the quad's answers, taken before the tests of
                // its instances, only keep too many). Every built tree has
                // its leaves' quads.
                // PERF: only an instance tested takes a mailbox slot: one
                // whose box the ray misses would push out an instance
                // already tested, to be tested again in a later cell (the
                // robots' city, in every cell, shares its slot with four
                // robot parts: robots' single rays took 1.8 times as long).
                let reach = quads.get(q).map_or(0xF, |quad| ray_reaches_quad(quad, ray, *closest));
                for (j, &i) in four.iter().enumerate() {
                    let slot = &mut mailbox[i as usize % MAILBOX];
                    if *slot == i || reach & (1 << j) == 0 {
                        continue;
                    }
                    *slot = i;
                    let inst = &self.instances[i as usize];
                    if test(i, inst, closest) {
                        return true;
                    }
                }
            }
            false
        })
    }

    /// [`Scene::intersect`] for the rays of the `lanes` mask at once: lane
    /// `l` of the answer equals `intersect(&rays[l])` bit for bit (`None`
    /// for lanes outside the mask).
    ///
    /// Two-level packet traversal (Wald, Benthin & Slusallek 2003, with the
    /// packets of Wald et al. 2001): the packet walks the top-level BSP; in a
    /// leaf, the lanes that have not yet tested an instance (a mailbox per
    /// packet, with the lanes per entry) are moved into its object space
    /// once and walk its kd-tree as a packet, each up to its own closest hit.
    #[must_use]
    pub fn intersect_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> [Option<SceneHit>; N] {
        let mut best = [None; N];
        // PERF: the object-space copy of the packet is made when an
        // instance with a transform is first tested (a copy of 1.3 KB per
        // packet was 2% of robots' primary rays, whose city has none).
        let mut local: Option<[Ray; N]> = None;
        let mut hits = [None; N];
        // Primary rays share their origin; rays a mirror reflects from
        // them pass near a virtual one.
        // The lanes laid out once, for the boxes, the frustum and the trees
        // of instances without a transform.
        let boxes = PacketBoxes::new(rays, lanes);
        let frustum = openrt_accel::Frustum::for_intersect_laid(rays, &boxes, lanes);
        self.walk_packet(
            rays,
            &boxes,
            lanes,
            frustum.as_ref(),
            |i, inst, active, closest, laid_out| {
                // An instance without a transform sees the world frustum as it is.
                let f = frustum.as_ref().filter(|_| inst.identity);
                let found = if f.is_some() {
                    // PERF: and the world rays: the tree's packet queries read
                    // each lane's bound from `closest`, not from the ray (see
                    // `with_interval`), so no copy is needed.
                    inst.geometry
                        .tree
                        .intersect_packet_in(rays, active, closest, &mut hits, f, Some(laid_out))
                } else {
                    let local = local.get_or_insert(*rays);
                    for l in lanes_of(active) {
                        local[l] = inst.ray_to_object(&rays[l], closest[l]);
                    }
                    inst.geometry
                        .tree
                        .intersect_packet_in(local, active, closest, &mut hits, f, None)
                };
                for l in lanes_of(found) {
                    if let Some(h) = hits[l] {
                        best[l] = Some(SceneHit {
                            frame: self.frame,
                            t: h.t,
                            instance: i,
                            prim: h.prim,
                            b1: h.b1,
                            b2: h.b2,
                        });
                    }
                }
                0
            },
        );
        best
    }

    /// [`Scene::occluded`] for the rays of the `lanes` mask at once: the
    /// mask of the lanes whose ray is blocked.
    #[must_use]
    pub fn occluded_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> u32 {
        let boxes = PacketBoxes::new(rays, lanes);
        let frustum = openrt_accel::Frustum::new_laid(&boxes, lanes);
        self.occluded_packet_in(rays, &boxes, lanes, frustum.as_ref()).0
    }

    /// [`Scene::occluded_packet`] for rays that all end at `target`
    /// (`Ray::new(p, target - p, t_min, t_max)` with `t_max <= 1`: the
    /// shadow rays towards one point light): instances that no lane's
    /// segment can reach are skipped for the whole packet. Same answers.
    #[must_use]
    pub fn occluded_packet_toward<const N: usize>(&self, rays: &[Ray; N], lanes: u32, target: Vec3) -> u32 {
        let boxes = PacketBoxes::new(rays, lanes);
        let frustum = openrt_accel::Frustum::toward_laid(&boxes, lanes, target);
        self.occluded_packet_in(rays, &boxes, lanes, frustum.as_ref()).0
    }

    /// [`Scene::occluded_packet_toward`], trying the triangles of `hint`'s
    /// leaf first on every lane and keeping where a lane the walk answered
    /// was blocked in it, as [`Scene::occluded_hinted`], except while the
    /// hint rests after tries that settled no lane ([`HINT_MAX_REST`]).
    /// The same answer whatever the hint holds.
    ///
    /// [`HINT_MAX_REST`]: crate::kernels::HINT_MAX_REST
    #[must_use]
    pub fn occluded_packet_toward_hinted<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        target: Vec3,
        hint: &mut OccluderHint,
    ) -> u32 {
        // A hint that keeps settling nothing rests for a few packets.
        // PERF: the hint's leaf is tried without a frustum: its few
        // triangles cost less than making one (robots shadow queries 0.68
        // of the time when the frustum, made for the hint, served the walk
        // too); the lanes it leaves are laid out and get theirs.
        let blocked = if hint.packet_turn() {
            let settled = self.hint_blocks_packet(hint, rays, lanes);
            hint.packet_tried(settled != 0);
            settled
        } else {
            0
        };
        let rest = lanes & !blocked;
        if rest == 0 {
            return blocked;
        }
        let boxes = PacketBoxes::new(rays, rest);
        let frustum = openrt_accel::Frustum::toward_laid(&boxes, rest, target);
        let (more, found) = self.occluded_packet_in(rays, &boxes, rest, frustum.as_ref());
        if found.is_some() {
            hint.leaf = found;
        }
        blocked | more
    }

    /// The lanes of a packet that [`Scene::hint_blocks`] settles.
    fn hint_blocks_packet<const N: usize>(&self, hint: &OccluderHint, rays: &[Ray; N], lanes: u32) -> u32 {
        let Some((i, leaf)) = hint.leaf else {
            return 0;
        };
        let Some(inst) = self.instances.get(i as usize) else {
            return 0;
        };
        let tree = &inst.geometry.tree;
        if inst.identity {
            // The world rays are what the walk gives the instance.
            return tree.leaf_blocks_packet(rays, lanes, leaf, HINT_MARGIN);
        }
        let mut local = *rays;
        for l in lanes_of(lanes) {
            local[l] = inst.ray_to_object(&rays[l], rays[l].t_max);
        }
        tree.leaf_blocks_packet(&local, lanes, leaf, HINT_MARGIN)
    }

    /// The blocked lanes, and where one of them was blocked (instance, leaf).
    fn occluded_packet_in<const N: usize>(
        &self,
        rays: &[Ray; N],
        boxes: &PacketBoxes<N>,
        lanes: u32,
        frustum: Option<&openrt_accel::Frustum>,
    ) -> (u32, Option<(u32, openrt_accel::KdNode)>) {
        let mut local: Option<[Ray; N]> = None;
        let mut found = None;
        let blocked = self.walk_packet(rays, boxes, lanes, frustum, |i, inst, active, closest, laid_out| {
            let (hit, leaf) = if inst.identity {
                // PERF: the world rays as they are: an any-hit walk never
                // lowers a lane's bound, so `ray_to_object` would only copy
                // them.
                inst.geometry
                    .tree
                    .occluder_packet_in(rays, active, frustum, Some(laid_out))
            } else {
                let local = local.get_or_insert(*rays);
                for l in lanes_of(active) {
                    local[l] = inst.ray_to_object(&rays[l], closest[l]);
                }
                inst.geometry.tree.occluder_packet_in(local, active, None, None)
            };
            if let Some(leaf) = leaf {
                found = found.or(Some((i, leaf)));
            }
            hit
        });
        (blocked, found)
    }

    /// The two-level walk of a packet, shared by both packet queries: each
    /// lane clipped to the scene box, the top-level BSP walked by the packet
    /// ([`openrt_accel::traverse_packet`]), and `test(index, instance, lanes, closest)`
    /// called with the lanes meeting that instance for the first time
    /// (a mailbox per packet holding the lanes that met each instance, as
    /// [`Scene::walk`] keeps one per ray). `test`
    /// returns the lanes it finished; the walk returns all finished lanes.
    #[inline]
    fn walk_packet<const N: usize, F>(
        &self,
        rays: &[Ray; N],
        boxes: &PacketBoxes<N>,
        lanes: u32,
        frustum: Option<&openrt_accel::Frustum>,
        mut test: F,
    ) -> u32
    where
        F: FnMut(u32, &InstanceRecord, u32, &mut [f32; N], &PacketBoxes<N>) -> u32,
    {
        let mut closest: [f32; N] = std::array::from_fn(|l| rays[l].t_max);
        // The lanes that can reach an instance's world box are tested for
        // the whole packet before any lane is moved to object space; the
        // same layout (`boxes`, made for `lanes`) clips the lanes to the
        // scene box and to the trees of instances without a transform.
        // Instance `i` tested by those of `lanes` that reach its world box:
        // `None` when none does, else the lanes it finished.
        let mut enter = |i: u32, lanes: u32, closest: &mut [f32; N]| {
            let inst = &self.instances[i as usize];
            let reach = boxes.reaching(&inst.world_bounds, lanes, closest);
            (reach != 0).then(|| test(i, inst, reach, closest, boxes) & reach)
        };
        let mut finished = 0u32;
        for &i in self.globals.iter() {
            finished |= enter(i, lanes & !finished, &mut closest).unwrap_or(0);
        }
        if let Some(t) = &self.tbvh {
            let done = t.walk_packet(
                rays,
                lanes & !finished,
                &mut closest,
                frustum,
                boxes,
                |items, quads, active, closest| {
                    let mut done = 0u32;
                    for (four, quad) in items.chunks(4).zip(quads) {
                        let rejected = frustum.map_or(0, |f| f.rejects_box_quad(quad));
                        for (j, &i) in four.iter().enumerate() {
                            if rejected & (1 << j) != 0 {
                                continue;
                            }
                            done |= enter(i, active & !done, closest).unwrap_or(0);
                            if done == active {
                                return done;
                            }
                        }
                    }
                    done
                },
            );
            return finished | done;
        }
        let (t0, t1, live) = boxes.clip(&self.bsp.bounds(), lanes & !finished, &closest);
        if live == 0 {
            return finished;
        }
        // One mailbox for the packet: per slot an instance and the lanes
        // that have met it. Like the per-ray mailbox it only saves work: a
        // lane that meets an instance again (after its slot was taken)
        // finds the same hits, none of them closer.
        let mut mailbox = [(u32::MAX, 0u32); MAILBOX];
        // Packets without a frustum (bounces without a virtual apex)
        // skip boxes by the intervals of their lanes instead.
        let interval = if frustum.is_none() {
            PacketInterval::new(boxes, live)
        } else {
            None
        };
        let done = traverse_packet_laid(
            self.bsp.nodes(),
            rays,
            Some(boxes),
            live,
            &t0,
            &t1,
            &mut closest,
            |leaf, active, closest| {
                let mut done = 0u32;
                let items = self.bsp.leaf_items(leaf);
                let quads = self.bsp.leaf_box_quads(leaf);
                // The far bound of the lanes here (NaN, if a lane has one,
                // rejects nothing).
                let far = if interval.is_some() {
                    lanes_of(active).fold(f32::NEG_INFINITY, |m, l| {
                        let t = closest[l];
                        if t > m || t.is_nan() { t } else { m }
                    })
                } else {
                    f32::NAN
                };
                for (q, four) in items.chunks(4).enumerate() {
                    // Instances whose world box no lane can reach (the
                    // packet's frustum) are skipped for the whole packet,
                    // four boxes at a time.
                    // NOTE: every built tree has its leaves' quads (its
                    // `validate` checks them); without one nothing is culled.
                    let rejected = match (frustum, &interval, quads.get(q)) {
                        (Some(f), _, Some(quad)) => f.rejects_box_quad(quad),
                        (None, Some(iv), Some(quad)) => iv.rejects_box_quad(quad, far),
                        _ => 0,
                    };
                    for (j, &i) in four.iter().enumerate() {
                        if rejected & (1 << j) != 0 {
                            continue;
                        }
                        let slot = &mut mailbox[i as usize % MAILBOX];
                        let met = if slot.0 == i { slot.1 } else { 0 };
                        let fresh = active & !done & !met;
                        if fresh == 0 {
                            continue;
                        }
                        // NOTE: the slot changes hands only for an instance
                        // tested here; one whose box no lane reaches keeps
                        // out, so that an instance already tested (the
                        // robots' city, met in every cell) is not pushed
                        // out and tested again. A lane that misses the
                        // world box misses the instance anywhere: it is
                        // marked with the lanes tested.
                        if let Some(d) = enter(i, fresh, closest) {
                            *slot = (i, met | fresh);
                            done |= d;
                            if done == active {
                                return done;
                            }
                        }
                    }
                }
                done
            },
        );
        finished | done
    }

    /// World-space shading information for a hit of `ray`.
    ///
    /// # Errors
    /// [`CoreError::ForeignHit`] for a hit found in another frame's scene,
    /// or naming an instance or triangle this scene does not have.
    pub fn surface(&self, ray: &Ray, hit: &SceneHit) -> Result<Surface, CoreError> {
        self.own_surface(ray, hit).ok_or(CoreError::ForeignHit {
            hit_frame: hit.frame,
            scene_frame: self.frame,
            instance: hit.instance,
            prim: hit.prim,
        })
    }

    /// [`Scene::surface`], `None` for a hit that is not this scene's.
    // PERF: forced inline into the shader, whose copy of a returned
    // `Result` (written field by field, read back 16 bytes at a time)
    // waited on failed store forwarding: kitchen GL-like frames 7% faster
    // inlined, more without the `Result`.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub(crate) fn own_surface(&self, ray: &Ray, hit: &SceneHit) -> Option<Surface> {
        if hit.frame != self.frame {
            return None;
        }
        let inst = self.instances.get(hit.instance as usize)?;
        let p = hit.prim as usize;
        let tri = inst.geometry.tree.triangles().get(p)?;
        let rec = inst.geometry.records.get(p)?;
        let b0 = 1.0 - hit.b1 - hit.b2;
        // PERF: an instance without a transform skips the matrix products
        // (the same values; at most the sign of a zero differs, which no
        // later step looks at).
        let to_world_normal = |n: Vec3| if inst.identity { n } else { inst.normal_matrix * n };
        let ng_obj = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        let geometric_normal = if inst.identity {
            ng_obj.normalize_or_zero()
        } else {
            (inst.normal_matrix * ng_obj * inst.det_sign).normalize_or_zero()
        };
        // NOTE: a triangle without vertex normals has zero normals in its
        // record (`ShadingRecord`), so it takes the geometric normal here.
        let n = rec.normals;
        let ns = to_world_normal(n[0] * b0 + n[1] * hit.b1 + n[2] * hit.b2).normalize_or_zero();
        let shading_normal = if ns == Vec3::ZERO { geometric_normal } else { ns };
        let uv = rec.uvs;
        // NOTE: the hit point is interpolated from the world-space vertices
        // (Wächter & Binder, Ray Tracing Gems ch. 6): its error is a few ulps
        // of its magnitude, unlike origin + t * dir.
        let w = if inst.identity {
            *tri
        } else {
            tri.map(|v| inst.to_world.transform_point3(v))
        };
        let point = w[0] * b0 + w[1] * hit.b1 + w[2] * hit.b2;
        let point = if point.is_finite() { point } else { ray.at(hit.t) };
        let error_scale = w.iter().map(|v| v.abs().max_element()).fold(0.0, f32::max);
        let uv_area = (uv[1] - uv[0]).perp_dot(uv[2] - uv[0]).abs();
        let world_area = (w[1] - w[0]).cross(w[2] - w[0]).length();
        Some(Surface {
            point,
            error_scale,
            geometric_normal,
            shading_normal,
            uv: uv[0] * b0 + uv[1] * hit.b1 + uv[2] * hit.b2,
            uv_area,
            world_area,
            material: rec.material,
            instance: inst.id,
            object: inst.object,
        })
    }

    /// Every instanced triangle moved to world space in f32, with its
    /// `(instance index, prim)` origin: the input of the brute-force oracle.
    #[must_use]
    pub fn world_triangles(&self) -> (Vec<Triangle>, Vec<(u32, u32)>) {
        let mut tris = Vec::new();
        let mut origin = Vec::new();
        for (i, inst) in self.instances.iter().enumerate() {
            for (p, t) in inst.geometry.tree.triangles().iter().enumerate() {
                tris.push(t.map(|v| inst.to_world.transform_point3(v)));
                origin.push((i as u32, p as u32));
            }
        }
        (tris, origin)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn cube(at: f32, half: f32) -> Aabb {
        Aabb {
            min: Vec3::splat(at - half),
            max: Vec3::splat(at + half),
        }
    }

    #[test]
    fn boxes_spanning_most_of_the_scene_are_global_up_to_the_limit() {
        // A ground around eight small boxes: the ground alone.
        let mut boxes: Vec<Aabb> = (0..8).map(|i| cube(i as f32 * 10.0, 1.0)).collect();
        boxes.insert(2, cube(35.0, 40.0));
        assert_eq!(global_instances(&boxes), vec![2]);
        // Inside the small boxes' span [-1, 71]^3, just over and just under
        // the share: half sides 26 and 25 (the limit is 25.46).
        boxes[2] = cube(35.0, 26.0);
        assert_eq!(global_instances(&boxes), vec![2]);
        boxes[2] = cube(35.0, 25.0);
        assert!(global_instances(&boxes).is_empty(), "{:?}", global_instances(&boxes));
        // Many spanning boxes: the first MAX_GLOBAL_INSTANCES of them.
        let mut many: Vec<Aabb> = (0..10).map(|_| cube(0.0, 50.0)).collect();
        many.push(cube(0.0, 1.0));
        assert_eq!(
            global_instances(&many),
            (0..MAX_GLOBAL_INSTANCES as u32).collect::<Vec<_>>()
        );
        // Small scenes walk the BSP alone; empty and non-finite boxes are never global.
        assert!(global_instances(&many[..MAX_GLOBAL_INSTANCES]).is_empty());
        let mut odd = vec![Aabb::EMPTY; 6];
        odd[1] = Aabb {
            min: Vec3::splat(f32::NEG_INFINITY),
            max: Vec3::splat(f32::INFINITY),
        };
        odd[3] = cube(0.0, 1.0);
        // The one finite box spans all that counts.
        assert_eq!(global_instances(&odd), vec![3]);
    }
}
