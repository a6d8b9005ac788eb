//! Commit: each object pays only for what changed, then the top-level BSP
//! is rebuilt over the instances' world boxes.

use std::sync::Arc;
use std::time::Instant;

use openrt_accel::{BuilderKind, InstanceBsp};

use crate::object::ObjectTree;
use rayon::prelude::*;

use crate::context::{InstanceSlot, Promotion};
use crate::instance::InstanceRecord;
use crate::limits::{MAX_COORDINATE, within_coordinate_limit};
use crate::object::ObjectGeometry;
use crate::{Context, CoreError, InstanceId, ObjectId, Scene};

/// One object tree built during a commit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildRecord {
    /// The object.
    pub object: ObjectId,
    /// The builder used.
    pub builder: BuilderKind,
    /// Triangles in the tree.
    pub triangles: usize,
    /// Degenerate triangles dropped from the definition.
    pub dropped: usize,
    /// Build time in milliseconds.
    pub ms: f64,
    /// The fast tree was refitted on the last tree's planes
    /// ([`Context::set_refit`]) rather than built afresh.
    pub refitted: bool,
}

/// What a commit did and how long each step took.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CommitStats {
    /// Frame number of the new scene.
    pub frame: u64,
    /// Object trees built (new objects: SAH; redefined objects: fast builder).
    pub builds: Vec<BuildRecord>,
    /// Objects whose background SAH build was started.
    pub promotions_started: Vec<ObjectId>,
    /// Objects whose SAH tree from the background replaced the fast tree.
    pub promotions_swapped: Vec<ObjectId>,
    /// Objects whose background SAH build failed, with the reason; the fast
    /// tree stays, and the build is not tried again until the object is
    /// redefined.
    pub promotions_failed: Vec<(ObjectId, String)>,
    /// Top-level rebuild time in milliseconds (or the time to find that
    /// no rebuild was needed).
    pub toplevel_ms: f64,
    /// The previous frame's top level was kept: every instance's world
    /// box was bit-for-bit the same (the tree depends on nothing else).
    pub toplevel_reused: bool,
    /// Nodes of the top level (the BSP's, or the BVH's wide nodes).
    pub toplevel_nodes: usize,
    /// Instances in the scene.
    pub instances: usize,
    /// Whole commit in milliseconds.
    pub total_ms: f64,
}

impl CommitStats {
    /// Total build time of one builder, in milliseconds.
    #[must_use]
    pub fn build_ms(&self, builder: BuilderKind) -> f64 {
        self.builds
            .iter()
            .filter(|b| b.builder == builder)
            .map(|b| b.ms)
            .sum::<f64>()
            + 0.0
    }

    /// Number of trees built with one builder.
    #[must_use]
    pub fn build_count(&self, builder: BuilderKind) -> usize {
        self.builds.iter().filter(|b| b.builder == builder).count()
    }
}

/// Builds an object tree of `accel`; `fail` (tests only) counts down to an
/// injected failure. `refit_from`: the object's last tree, to refit when it
/// came from the fast builder and `builder` is the fast builder.
fn build_tree(
    accel: crate::Accel,
    tris: Vec<openrt_accel::Triangle>,
    builder: BuilderKind,
    refit_from: Option<&ObjectTree>,
    fail: Option<&mut usize>,
) -> Result<ObjectTree, openrt_accel::AccelError> {
    if let Some(n) = fail {
        if *n == 0 {
            return Err(openrt_accel::AccelError::Invalid("injected build failure".into()));
        }
        *n -= 1;
    }
    ObjectTree::build(accel, tris, builder, refit_from)
}

/// Background SAH builds running at once, at most: they share the pool
/// with the commit and the renderer, and a bound keeps them from filling
/// it while a frame is built. A pool of `n` threads runs at most
/// `n / 2` (at least one, at most this many), so a frame keeps at least
/// half the threads while promotions run (one thread: a promotion holds it
/// for one SAH build).
pub const MAX_PROMOTIONS_IN_FLIGHT: usize = 2;

/// Promotions a pool of `threads` threads runs at once.
fn promotion_slots(threads: usize) -> usize {
    (threads / 2).clamp(1, MAX_PROMOTIONS_IN_FLIGHT)
}

/// Commits with at least this many instances make their records in parallel.
const PARALLEL_RECORDS: usize = 2_048;

/// The last frame's records, walked in slot order beside the live
/// instances (both lists are in slot order).
struct KeptRecords<'a>(std::iter::Peekable<std::slice::Iter<'a, InstanceRecord>>);

impl<'a> KeptRecords<'a> {
    /// The last frame's record of instance `id` when it is still valid:
    /// same handle, same object geometry, bit-identical transform.
    fn get(&mut self, id: InstanceId, slot: &InstanceSlot, geom: &Arc<ObjectGeometry>) -> Option<&'a InstanceRecord> {
        while self.0.next_if(|r| r.id.index < id.index).is_some() {}
        self.0.next_if(|r| r.id.index == id.index).filter(|r| {
            r.id == id
                && r.object == slot.object
                && Arc::ptr_eq(&r.geometry, geom)
                && same_bits(r.to_world.to_cols_array(), slot.transform.to_cols_array())
        })
    }
}

/// Bit-for-bit equality (-0.0 differs from 0.0: it changes reciprocals).
fn same_bits<const N: usize>(a: [f32; N], b: [f32; N]) -> bool {
    a.map(f32::to_bits) == b.map(f32::to_bits)
}

impl Context {
    /// Finishes the frame: builds what changed and publishes a new [`Scene`].
    ///
    /// - an object defined for the first time gets a full-SAH tree (static
    ///   and affine objects keep it for as long as they are not redefined);
    /// - a redefined object gets a tree from the fast builder (unstructured
    ///   motion);
    /// - an object built by the fast builder that has not changed for
    ///   `promote_after` commits gets an SAH tree built on a background
    ///   thread, swapped in by the first commit after it is ready (beyond the
    ///   paper);
    /// - the top-level BSP is rebuilt from the instances' world boxes, or
    ///   kept when none of them changed ([`CommitStats::toplevel_reused`]).
    ///
    /// Commit is atomic. On error (an instance of a deleted object, an open
    /// definition, a failed build) nothing changes: every definition is
    /// still pending, and the previous scene stays current. Every tree is
    /// built before anything is installed.
    pub fn commit(&mut self) -> Result<CommitStats, CoreError> {
        let start = Instant::now();
        self.ensure_not_defining("commit")?;
        for (i, inst) in self.instances.iter().enumerate() {
            if !inst.alive {
                continue;
            }
            let ok = self
                .objects
                .get(inst.object.index as usize)
                .is_some_and(|o| o.alive && o.generation == inst.object.generation);
            if !ok {
                return Err(CoreError::InstanceOfDeletedObject {
                    instance: crate::InstanceId {
                        index: i as u32,
                        generation: inst.generation,
                    },
                    object: inst.object,
                });
            }
        }
        let mut stats = CommitStats::default();
        let promote_after = self.promote_after;
        let redefinition_builder = self.redefinition_builder;
        let accel = self.accel;

        // Phase 1 builds everything into `staged` and changes nothing, so
        // that an error leaves the context and the scene as they were.
        // `staged[i]` is object slot i's new geometry: a new definition's
        // tree, or a finished background SAH tree for the current version.
        let mut staged: Vec<Option<Arc<ObjectGeometry>>> = vec![None; self.objects.len()];
        for (index, slot) in self.objects.iter_mut().enumerate() {
            if !slot.alive {
                continue;
            }
            let id = ObjectId {
                index: index as u32,
                generation: slot.generation,
            };
            if let Some(mesh) = &slot.pending {
                let builder = slot.forced_builder.unwrap_or(if slot.geometry.is_some() {
                    redefinition_builder
                } else {
                    BuilderKind::Sah
                });
                let t0 = Instant::now();
                // NOTE: the definition stays pending until phase 2, so the
                // builder gets a copy (a memcpy, ~1% of a fast build).
                let tris = mesh.triangles.clone();
                let n = tris.len();
                #[cfg(test)]
                let fail = self.hooks.fail_builds.as_mut();
                #[cfg(not(test))]
                let fail: Option<&mut usize> = None;
                let prev = slot.geometry.as_ref().filter(|_| self.refit).map(|g| &g.tree);
                // A build that can use the pool's threads runs on them; a
                // smaller one runs here (the same tree, without waking the pool).
                let tree = self
                    .bsp_builder
                    .install_build(builder, n, || {
                        build_tree(slot.accel.unwrap_or(accel), tris, builder, prev, fail)
                    })
                    .map_err(|source| CoreError::Accel { call: "commit", source })?;
                stats.builds.push(BuildRecord {
                    object: id,
                    builder,
                    triangles: mesh.triangles.len(),
                    dropped: mesh.dropped,
                    ms: t0.elapsed().as_secs_f64() * 1e3,
                    refitted: tree.refitted(),
                });
                // PERF: a large object's records are made on the pool's threads.
                let geometry = if n >= crate::shading_record::PARALLEL_SHADING_RECORDS {
                    self.bsp_builder
                        .install(|| ObjectGeometry::new(tree, &mesh.shading, &self.record_bin))
                } else {
                    ObjectGeometry::new(tree, &mesh.shading, &self.record_bin)
                };
                staged[index] = Some(Arc::new(geometry));
                continue;
            }
            // Collect a finished background build; a result for older
            // geometry is dropped.
            if let Some(Promotion::Running { result, .. }) = &slot.promotion
                && !result.is_empty()
            {
                slot.promotion = slot.promotion.take().map(Promotion::finish);
            }
            if let Some(Promotion::Ready { version, result }) = &slot.promotion
                && *version == slot.version
                && let Ok(geometry) = result
            {
                staged[index] = Some(Arc::clone(geometry));
            }
        }

        // Instances, in slot order, then the top-level BSP.        // Instances, in slot order, then the top-level BSP.
        // PERF: an instance whose handle, object geometry and transform are
        // those of the last frame keeps its record (inverses and world box):
        // recomputing 10k records cost 1.5 ms per commit with nothing moved;
        // when every record is kept, the whole list is shared.
        let prev = Arc::clone(&self.scene);
        let live = || {
            self.instances
                .iter()
                .enumerate()
                .filter(|(_, s)| s.alive)
                .filter_map(|(i, s)| {
                    let o = s.object.index as usize;
                    let geom = staged[o].as_ref().or(self.objects[o].geometry.as_ref())?;
                    let id = InstanceId {
                        index: i as u32,
                        generation: s.generation,
                    };
                    Some((id, s, geom))
                })
        };
        // NOTE: this check pass stops at the first changed instance; only a
        // frame that moves nothing walks the whole list, and then clones nothing.
        let mut kept = KeptRecords(prev.instances.iter().peekable());
        let mut count = 0;
        let all_kept = live().all(|(id, s, geom)| {
            count += 1;
            kept.get(id, s, geom).is_some()
        }) && count == prev.instances.len();
        let records = if all_kept {
            Arc::clone(&prev.instances)
        } else {
            let mut kept = KeptRecords(prev.instances.iter().peekable());
            // NOTE: sized up front: collected from the filtering iterator, the
            // list grew by reallocation and copies.
            let mut todo = Vec::with_capacity(self.instances.len());
            todo.extend(live().map(|(id, s, geom)| (id, s, geom, kept.get(id, s, geom))));
            let record =
                |&(id, s, geom, old): &(InstanceId, &InstanceSlot, &Arc<ObjectGeometry>, Option<&InstanceRecord>)| {
                    match old {
                        Some(r) => r.clone(),
                        None => InstanceRecord::new(id, s.object, Arc::clone(geom), s.transform),
                    }
                };
            // PERF: new records (inverse, normal matrix, world box: ~0.1 µs
            // each) are made on the top-level builder's threads, which the
            // build right after then finds awake.
            Arc::new(if todo.len() >= PARALLEL_RECORDS {
                self.bsp_builder.install(|| todo.par_iter().map(record).collect())
            } else {
                todo.iter().map(record).collect()
            })
        };
        // An instance whose world box leaves the coordinate range (a large
        // object under a large scale) could not be hit reliably: refuse it.
        if let Some(r) = records.iter().find(|r| {
            let b = r.world_bounds;
            let inside = within_coordinate_limit(b.min) && within_coordinate_limit(b.max);
            !r.geometry.tree.bounds().is_empty() && !inside
        }) {
            let b = r.world_bounds;
            return Err(CoreError::InstanceOutOfRange {
                instance: r.id,
                object: r.object,
                min: b.min.to_array(),
                max: b.max.to_array(),
                largest: if b.min.is_finite() && b.max.is_finite() {
                    f64::from(b.min.abs().max(b.max.abs()).max_element())
                } else {
                    f64::INFINITY
                },
                limit: f64::from(MAX_COORDINATE),
            });
        }
        let t0 = Instant::now();
        // NOTE: the BSP is a function of the box list alone (leaf items are
        // indices into it), so an unchanged list, compared bit for bit,
        // keeps the last tree even when objects behind the boxes changed.
        stats.toplevel_reused = (!prev.bsp.nodes().is_empty() || prev.tbvh.is_some())
            && (all_kept
                || prev.instances.len() == records.len()
                    && prev.instances.iter().zip(records.iter()).all(|(p, r)| {
                        let (a, b) = (p.world_bounds, r.world_bounds);
                        same_bits(a.min.to_array(), b.min.to_array()) && same_bits(a.max.to_array(), b.max.to_array())
                    }));
        let bvh_top = self.top_level.uses_bvh(records.len());
        // A kept tree must be of the structure chosen now.
        stats.toplevel_reused &= prev.tbvh.is_some() == bvh_top;
        let (bsp, globals, tbvh) = if stats.toplevel_reused {
            (Arc::clone(&prev.bsp), Arc::clone(&prev.globals), prev.tbvh.clone())
        } else {
            // Instances spanning the scene are tested before the walk, not
            // put in the BSP (an empty box is left out of it).
            let (boxes, globals) = crate::scene::top_level_boxes(&records);
            let accel_error = |source| CoreError::Accel { call: "commit", source };
            if bvh_top {
                // On the BSP builder's threads: a large tree's subtrees are
                // tasks of that pool (the same tree on any thread count).
                let tbvh = self
                    .bsp_builder
                    .install(|| openrt_accel::InstanceBvh::build(&boxes))
                    .map_err(accel_error)?;
                (
                    Arc::new(InstanceBsp::default()),
                    Arc::new(globals),
                    Some(Arc::new(tbvh)),
                )
            } else {
                let bsp = self.bsp_builder.build(&boxes).map_err(accel_error)?;
                (Arc::new(bsp), Arc::new(globals), None)
            }
        };
        stats.toplevel_ms = t0.elapsed().as_secs_f64() * 1e3;
        stats.toplevel_nodes = tbvh.as_ref().map_or(bsp.nodes().len(), |t| t.node_count());
        stats.instances = records.len();

        // Phase 2 cannot fail: it installs what phase 1 built (the change
        // log reads the definitions first).
        if self.change_log.is_some() {
            let swapped: Vec<ObjectId> = self
                .objects
                .iter()
                .enumerate()
                .filter(|(i, s)| s.alive && s.pending.is_none() && staged[*i].is_some())
                .map(|(i, s)| ObjectId {
                    index: i as u32,
                    generation: s.generation,
                })
                .collect();
            self.log_commit(self.frame + 1, &swapped);
        }
        self.apply_objects(staged, promote_after, &mut stats);

        let materials = if self.materials_dirty {
            self.materials_dirty = false;
            Arc::new(self.materials.clone())
        } else {
            Arc::clone(&self.scene.materials)
        };
        let textures = if self.textures_dirty {
            self.textures_dirty = false;
            Arc::new(self.textures.clone())
        } else {
            Arc::clone(&self.scene.textures)
        };
        self.frame += 1;
        stats.frame = self.frame;
        self.scene = Arc::new(Scene {
            instances: records,
            bsp,
            globals,
            tbvh,
            materials,
            textures,
            frame: self.frame,
        });
        stats.total_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(stats)
    }

    /// Installs the staged geometry, counts unchanged commits, and starts,
    /// swaps or records the background SAH builds.
    fn apply_objects(
        &mut self,
        staged: Vec<Option<Arc<ObjectGeometry>>>,
        promote_after: Option<u32>,
        stats: &mut CommitStats,
    ) {
        #[cfg(test)]
        let fail = self.hooks.fail_promotions;
        #[cfg(not(test))]
        let fail = false;
        let slots = promotion_slots(self.bsp_builder.threads());
        let mut in_flight = self
            .objects
            .iter()
            .filter(|s| matches!(s.promotion, Some(Promotion::Running { .. })))
            .count();
        for ((index, slot), new) in self.objects.iter_mut().enumerate().zip(staged) {
            if !slot.alive {
                continue;
            }
            let id = ObjectId {
                index: index as u32,
                generation: slot.generation,
            };
            if slot.pending.take().is_some() {
                slot.forced_builder = None;
                slot.geometry = new;
                slot.version += 1;
                slot.unchanged_commits = 0;
                // A running promotion is for older geometry: its result is ignored.
                slot.promotion = None;
                continue;
            }
            let Some(geom) = &slot.geometry else { continue };
            // NOTE: a BVH has one builder: a promotion would build the same tree.
            if geom.builder() != BuilderKind::Fast || geom.tree.accel() != crate::Accel::Kd {
                continue;
            }
            slot.unchanged_commits = slot.unchanged_commits.saturating_add(1);
            match slot.promotion.take() {
                Some(Promotion::Ready { version, result }) if version == slot.version => match result {
                    Ok(_) => {
                        slot.geometry = new;
                        stats.promotions_swapped.push(id);
                    }
                    Err(reason) => {
                        // Recorded once; not retried for this geometry.
                        stats.promotions_failed.push((id, reason.clone()));
                        slot.promotion = Some(Promotion::Failed { version, reason });
                    }
                },
                Some(Promotion::Ready { .. }) => {}
                Some(p @ (Promotion::Running { .. } | Promotion::Failed { .. })) => slot.promotion = Some(p),
                None => {
                    if promote_after.is_some_and(|n| slot.unchanged_commits >= n) && in_flight < slots {
                        in_flight += 1;
                        let tris = geom.tree.triangles().to_vec();
                        let old = Arc::clone(geom);
                        let (tx, rx) = crossbeam::channel::bounded(1);
                        // On the commit's own pool: no thread is spawned.
                        self.bsp_builder.spawn(move || {
                            let tree = if fail {
                                Err(openrt_accel::AccelError::Invalid("injected promotion failure".into()))
                            } else {
                                ObjectTree::build(crate::Accel::Kd, tris, BuilderKind::Sah, None)
                            };
                            let _ = tx.send(
                                tree.map(|tree| Arc::new(old.with_tree(tree)))
                                    .map_err(|e| e.to_string()),
                            );
                        });
                        slot.promotion = Some(Promotion::Running {
                            version: slot.version,
                            result: rx,
                        });
                        stats.promotions_started.push(id);
                    }
                }
            }
        }
    }

    /// Blocks until every background SAH build has finished, so that the
    /// next commit swaps them in (for deterministic playback and tests).
    pub fn wait_for_promotions(&mut self) {
        for slot in &mut self.objects {
            slot.promotion = slot.promotion.take().map(Promotion::finish);
        }
    }

    /// Which builder made the current tree of an object (`None` before its first commit).
    pub fn object_builder(&self, id: ObjectId) -> Result<Option<BuilderKind>, CoreError> {
        Ok(self
            .object_slot("object_builder", id)?
            .geometry
            .as_ref()
            .map(|g| g.builder()))
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::promotion_slots;

    use crate::{Context, CoreError, PrimitiveKind};

    fn tri(ctx: &mut Context, id: crate::ObjectId, z: f32) {
        ctx.begin_object(id).unwrap();
        ctx.begin(PrimitiveKind::Triangles).unwrap();
        for p in [
            Vec3::new(-1.0, -1.0, z),
            Vec3::new(1.0, -1.0, z),
            Vec3::new(0.0, 1.0, z),
        ] {
            ctx.vertex(p).unwrap();
        }
        ctx.end().unwrap();
        ctx.end_object().unwrap();
    }

    fn t_at(ctx: &Context, x: f32) -> Option<f32> {
        let r = openrt_accel::Ray::infinite(Vec3::new(x, 0.0, 10.0), -Vec3::Z);
        ctx.scene().intersect(&r).map(|h| h.t)
    }

    #[test]
    fn promotions_leave_half_the_pool_to_frames() {
        assert_eq!(
            [1, 2, 3, 4, 8, 16].map(promotion_slots),
            [1, 1, 1, 2, 2, 2],
            "at least one, at most MAX_PROMOTIONS_IN_FLIGHT, never more than half"
        );
    }

    #[test]
    fn a_failing_build_leaves_everything_as_it_was() {
        let mut ctx = Context::new();
        let (a, b) = (ctx.gen_object(), ctx.gen_object());
        tri(&mut ctx, a, 0.0);
        tri(&mut ctx, b, 1.0);
        ctx.instantiate(a).unwrap();
        ctx.translate(Vec3::X * 5.0).unwrap();
        ctx.instantiate(b).unwrap();
        ctx.load_identity();
        ctx.commit().unwrap();
        let before = ctx.scene();
        // Redefine both; the second build fails.
        tri(&mut ctx, a, 2.0);
        tri(&mut ctx, b, 3.0);
        ctx.hooks.fail_builds = Some(1);
        let e = ctx.commit().unwrap_err();
        assert!(matches!(e, CoreError::Accel { call: "commit", .. }), "{e}");
        assert!(
            std::sync::Arc::ptr_eq(&before, &ctx.scene()),
            "the old scene stays current"
        );
        assert_eq!(ctx.frame, before.frame());
        assert!(
            ctx.objects.iter().all(|s| s.pending.is_some()),
            "both definitions are still pending"
        );
        assert_eq!(ctx.objects[0].version, 1);
        // Without the failure, the same commit applies both definitions.
        ctx.hooks.fail_builds = None;
        let stats = ctx.commit().unwrap();
        assert_eq!(stats.builds.len(), 2);
        assert_eq!(t_at(&ctx, 0.0), Some(8.0));
        assert_eq!(t_at(&ctx, 5.0), Some(7.0));
    }

    #[test]
    fn a_failed_promotion_is_reported_once_and_not_retried() {
        let mut ctx = Context::new();
        // Promotions replace a kd-tree's fast build (a BVH has one builder).
        ctx.set_accel(crate::Accel::Kd);
        ctx.set_promote_after(Some(1));
        let a = ctx.gen_object();
        tri(&mut ctx, a, 0.0);
        ctx.instantiate(a).unwrap();
        ctx.commit().unwrap();
        tri(&mut ctx, a, 0.5); // redefined: fast tree
        ctx.commit().unwrap();
        ctx.hooks.fail_promotions = true;
        let started = ctx.commit().unwrap();
        assert_eq!(started.promotions_started, vec![a]);
        ctx.wait_for_promotions();
        let failed = ctx.commit().unwrap();
        assert_eq!(failed.promotions_failed.len(), 1);
        assert!(
            failed.promotions_failed[0].1.contains("injected"),
            "{:?}",
            failed.promotions_failed
        );
        assert!(ctx.promotion_failure(a).unwrap().is_some());
        for _ in 0..5 {
            let s = ctx.commit().unwrap();
            assert!(
                s.promotions_started.is_empty() && s.promotions_failed.is_empty(),
                "{s:?}"
            );
        }
        assert_eq!(ctx.object_builder(a).unwrap(), Some(openrt_accel::BuilderKind::Fast));
        assert_eq!(t_at(&ctx, 0.0), Some(9.5), "the fast tree stays in use");
        // A redefinition clears the failure and promotes again.
        ctx.hooks.fail_promotions = false;
        tri(&mut ctx, a, 0.0);
        ctx.commit().unwrap();
        assert!(ctx.promotion_failure(a).unwrap().is_none());
        assert_eq!(ctx.commit().unwrap().promotions_started, vec![a]);
        ctx.wait_for_promotions();
        assert_eq!(ctx.commit().unwrap().promotions_swapped, vec![a]);
    }

    #[test]
    fn handles_are_never_issued_twice_when_a_generation_would_wrap() {
        let mut ctx = Context::new();
        let a = ctx.gen_object();
        tri(&mut ctx, a, 0.0);
        let i = ctx.instantiate(a).unwrap();
        // Fast-forward both slots to the last generation.
        ctx.objects[0].generation = u32::MAX;
        ctx.instances[0].generation = u32::MAX;
        ctx.instances[0].object.generation = u32::MAX;
        let a = crate::ObjectId {
            generation: u32::MAX,
            ..a
        };
        let i = crate::InstanceId {
            generation: u32::MAX,
            ..i
        };
        ctx.remove_instance(i).unwrap();
        ctx.delete_object(a).unwrap();
        // The slots are retired: new handles take new slots.
        let b = ctx.gen_object();
        assert_ne!(b.index(), a.index());
        tri(&mut ctx, b, 0.0);
        let j = ctx.instantiate(b).unwrap();
        assert_ne!(j.index(), i.index());
        assert!(ctx.instance(i).is_err() && ctx.object_builder(a).is_err());
        // Ordinary reuse still works.
        ctx.remove_instance(j).unwrap();
        let k = ctx.instantiate(b).unwrap();
        assert_eq!((k.index(), k.generation()), (j.index(), j.generation() + 1));
        ctx.commit().unwrap();
    }
}
