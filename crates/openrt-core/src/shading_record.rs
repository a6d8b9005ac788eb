//! One triangle's shading attributes packed in one cache line.
//!
//! [`ShadingData`] keeps a triangle's vertex normals, texture coordinates,
//! normal flag and material in four arrays: a hit on it reads four to seven
//! cache lines (36- and 24-byte records straddle lines). Bounce and shadow
//! hits of a Whitted frame land on scattered triangles, so the shading of
//! a packet waits on those misses one lane after another. A
//! [`ShadingRecord`] holds the same values in one aligned 64-byte line,
//! which the renderer reads instead; [`ObjectGeometry`](crate::ObjectGeometry)
//! keeps only the records and rebuilds the arrays, the API's form, on request.

use std::sync::{Arc, Mutex};

use glam::{Vec2, Vec3};
use openrt_accel::Triangle;
use rayon::prelude::*;

use crate::{MaterialId, ShadingData};

/// A triangle's vertex normals, texture coordinates and material, in one
/// cache line.
///
/// A triangle without vertex normals stores zero normals: its
/// interpolated normal is then zero, which the surface reconstruction
/// replaces with the geometric normal, exactly as it does for a triangle
/// whose given normals interpolate to zero; so the record needs no flag
/// (and fits 64 bytes).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub(crate) struct ShadingRecord {
    /// Object-space vertex normals; zero where the triangle has none.
    pub normals: [Vec3; 3],
    /// Texture coordinates of the three vertices.
    pub uvs: [Vec2; 3],
    /// The triangle's material.
    pub material: MaterialId,
}

impl ShadingRecord {
    /// Triangle `p`'s record of `data` (the index-by-index twin of
    /// [`ShadingRecord::all`]).
    #[cfg(test)]
    fn of(data: &ShadingData, p: usize) -> Self {
        Self {
            normals: if data.has_normals[p] {
                data.normals[p]
            } else {
                [Vec3::ZERO; 3]
            },
            uvs: data.uvs[p],
            material: data.materials[p],
        }
    }

    /// Every triangle's record of `data`, in triangle order (the API
    /// keeps the four arrays one entry per triangle; a shorter one ends
    /// the records, whose missing hits then have no surface): from
    /// [`PARALLEL_SHADING_RECORDS`] triangles on the threads of the pool it
    /// is called on, into a buffer of `bin` when it holds one large enough.
    pub(crate) fn all(data: &ShadingData, bin: &Arc<RecordBin>) -> Records {
        // PERF: zipped slices, without an index or its bounds checks: the
        // records are written once, straight into the vector.
        let make = |(((n, &given), uv), &material): Attributes<'_>| Self {
            normals: if given { *n } else { [Vec3::ZERO; 3] },
            uvs: *uv,
            material,
        };
        let n = data.materials.len();
        let list = if n >= PARALLEL_SHADING_RECORDS {
            let mut list = bin.take(n);
            list.par_extend(
                data.normals
                    .par_iter()
                    .zip(&data.has_normals)
                    .zip(&data.uvs)
                    .zip(&data.materials)
                    .with_min_len(PARALLEL_SHADING_RECORDS / 4)
                    .map(make),
            );
            list
        } else {
            data.normals
                .iter()
                .zip(&data.has_normals)
                .zip(&data.uvs)
                .zip(&data.materials)
                .map(make)
                .collect()
        };
        Records {
            list,
            bin: (n >= PARALLEL_SHADING_RECORDS).then(|| Arc::clone(bin)),
        }
    }

    /// The attributes of `records` in [`ShadingData`]'s form: triangle
    /// `p` without vertex normals (`has_normals[p]` false) lists the
    /// geometric normal of `triangles[p]`, `(b - a) x (c - a)`, as
    /// [`crate::Context`] fills it in.
    pub(crate) fn data(records: &[Self], has_normals: &[bool], triangles: &[Triangle]) -> ShadingData {
        let mut d = ShadingData::default();
        for ((r, &given), t) in records.iter().zip(has_normals).zip(triangles) {
            d.normals.push(if given {
                r.normals
            } else {
                [(t[1] - t[0]).cross(t[2] - t[0]); 3]
            });
            d.has_normals.push(given);
            d.uvs.push(r.uvs);
            d.materials.push(r.material);
        }
        d
    }
}

/// One triangle's entries of [`ShadingData`]'s four arrays, zipped.
type Attributes<'a> = (((&'a [Vec3; 3], &'a bool), &'a [Vec2; 3]), &'a MaterialId);

/// Objects of at least this many triangles have their records made on
/// the pool's threads, in a buffer recycled from dropped geometry
/// ([`RecordBin`]): a 100k-triangle figure redefined every frame.
pub(crate) const PARALLEL_SHADING_RECORDS: usize = 16_384;

/// The most record buffers a [`RecordBin`] keeps.
pub(crate) const RECORD_BIN_BUFFERS: usize = 4;

/// The record buffers of dropped large geometry, kept for the next
/// commits of the same context.
///
/// PERF: an object redefined every frame needs a new buffer each commit
/// (the last frame's scene still reads the old one); fresh memory costs a
/// page fault per 4 KB on first touch: making 100k records took 4-6 ms
/// in a fresh buffer against 1 ms in one already touched. The buffers of
/// the frames before come back here when their scenes are dropped.
#[derive(Debug, Default)]
pub(crate) struct RecordBin(Mutex<Vec<Vec<ShadingRecord>>>);

impl RecordBin {
    /// An empty buffer with room for `n` records: a kept one if one is
    /// large enough, else a new one.
    fn take(&self, n: usize) -> Vec<ShadingRecord> {
        let kept = self.0.lock().ok().and_then(|mut bin| {
            let i = bin.iter().position(|b| b.capacity() >= n)?;
            Some(bin.swap_remove(i))
        });
        kept.map_or_else(
            || Vec::with_capacity(n),
            |mut b| {
                b.clear();
                b
            },
        )
    }

    /// Keeps `buffer` for a later [`RecordBin::take`], unless
    /// [`RECORD_BIN_BUFFERS`] are kept already.
    fn give(&self, buffer: Vec<ShadingRecord>) {
        if let Ok(mut bin) = self.0.lock()
            && bin.len() < RECORD_BIN_BUFFERS
        {
            bin.push(buffer);
        }
    }

    /// How many buffers are kept.
    #[cfg(test)]
    fn len(&self) -> usize {
        self.0.lock().map_or(0, |b| b.len())
    }
}

/// An object's records; a large object's buffer goes back to its
/// context's [`RecordBin`] when the last geometry sharing it is dropped.
#[derive(Debug, Default)]
pub(crate) struct Records {
    list: Vec<ShadingRecord>,
    bin: Option<Arc<RecordBin>>,
}

impl std::ops::Deref for Records {
    type Target = [ShadingRecord];
    fn deref(&self) -> &[ShadingRecord] {
        &self.list
    }
}

impl Drop for Records {
    fn drop(&mut self) {
        if let Some(bin) = &self.bin {
            bin.give(std::mem::take(&mut self.list));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_is_one_cache_line() {
        assert_eq!(size_of::<ShadingRecord>(), 64);
        assert_eq!(align_of::<ShadingRecord>(), 64);
    }

    #[test]
    fn records_hold_the_arrays_values_and_zero_normals_where_none_were_given() {
        let n = |x: f32| [Vec3::new(x, 0.0, 1.0), Vec3::Y, Vec3::Z];
        let data = ShadingData {
            normals: vec![n(1.0), n(2.0)],
            has_normals: vec![true, false],
            uvs: vec![
                [Vec2::X, Vec2::Y, Vec2::ONE],
                [Vec2::ZERO, Vec2::X, Vec2::new(0.5, 2.0)],
            ],
            materials: vec![MaterialId(3), MaterialId(7)],
        };
        let r = ShadingRecord::all(&data, &Arc::default());
        assert_eq!(r.len(), 2);
        assert_eq!(r[0].normals, n(1.0));
        assert_eq!(r[1].normals, [Vec3::ZERO; 3]);
        assert_eq!(r[0].uvs, data.uvs[0]);
        assert_eq!(r[1].uvs, data.uvs[1]);
        assert_eq!(r[0].material, MaterialId(3));
        assert_eq!(r[1].material, MaterialId(7));
        assert_eq!(r.as_ptr() as usize % 64, 0, "records start on a line");
    }

    #[test]
    fn large_objects_get_the_same_records_on_the_pool() {
        let n = PARALLEL_SHADING_RECORDS + 3;
        let data = ShadingData {
            normals: (0..n).map(|i| [Vec3::splat(i as f32), Vec3::X, Vec3::Y]).collect(),
            has_normals: (0..n).map(|i| i % 3 != 0).collect(),
            uvs: (0..n).map(|i| [Vec2::splat(i as f32 * 0.5); 3]).collect(),
            materials: (0..n).map(|i| MaterialId(i as u32 % 5)).collect(),
        };
        let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
        let bin = Arc::default();
        let parallel = pool.install(|| ShadingRecord::all(&data, &bin));
        let serial: Vec<ShadingRecord> = (0..n).map(|p| ShadingRecord::of(&data, p)).collect();
        assert_eq!(*parallel, serial[..]);
        // Its buffer goes back to the bin when dropped, and the next object's
        // records of no more triangles are made in it, also on one thread.
        let at = parallel.as_ptr();
        drop(parallel);
        assert_eq!(bin.len(), 1);
        let again = ShadingRecord::all(&data, &bin);
        assert_eq!(again.as_ptr(), at);
        assert_eq!(*again, serial[..]);
        assert_eq!(bin.len(), 0);
        // Small objects neither take nor give buffers.
        let small = ShadingRecord::all(&ShadingData::default(), &bin);
        drop(small);
        assert_eq!(bin.len(), 0);
        assert_eq!(again[0].normals, [Vec3::ZERO; 3]);
        assert_eq!(again[n - 2].normals[0], Vec3::splat((n - 2) as f32));
    }

    #[test]
    fn the_bin_keeps_at_most_its_limit_and_hands_out_buffers_large_enough() {
        let bin = RecordBin::default();
        for k in 0..RECORD_BIN_BUFFERS + 3 {
            bin.give(Vec::with_capacity(10 + k));
        }
        assert_eq!(bin.len(), RECORD_BIN_BUFFERS);
        let big = bin.take(12);
        assert!(big.capacity() >= 12 && big.is_empty());
        assert_eq!(bin.len(), RECORD_BIN_BUFFERS - 1);
        // None large enough: a new buffer, the bin untouched.
        let new = bin.take(1_000);
        assert!(new.capacity() >= 1_000);
        assert_eq!(bin.len(), RECORD_BIN_BUFFERS - 1);
    }

    /// A context redefining a large object every frame makes each frame's
    /// records in the buffer of the frame before last, once that frame's
    /// scene is dropped.
    #[test]
    fn redefined_large_objects_reuse_the_buffers_of_dropped_frames() {
        use crate::{Context, PrimitiveKind};
        let mut ctx = Context::new();
        let obj = ctx.gen_object();
        let n = PARALLEL_SHADING_RECORDS + 10;
        let define = |ctx: &mut Context, dz: f32| {
            ctx.begin_object(obj).unwrap();
            ctx.begin(PrimitiveKind::Triangles).unwrap();
            for i in 0..n {
                let x = i as f32;
                for v in [
                    Vec3::new(x, 0.0, dz),
                    Vec3::new(x + 1.0, 0.0, dz),
                    Vec3::new(x, 1.0, dz),
                ] {
                    ctx.vertex(v).unwrap();
                }
            }
            ctx.end().unwrap();
            ctx.end_object().unwrap();
        };
        define(&mut ctx, 0.0);
        ctx.instantiate(obj).unwrap();
        ctx.commit().unwrap();
        let first = ctx.scene().instances()[0].geometry.records.as_ptr();
        let mut seen = vec![first];
        for frame in 1..6 {
            define(&mut ctx, frame as f32);
            ctx.commit().unwrap();
            seen.push(ctx.scene().instances()[0].geometry.records.as_ptr());
        }
        // Two buffers take turns: each frame's scene holds one while the
        // next commit fills the other.
        for w in seen.windows(3) {
            assert_eq!(w[0], w[2], "{seen:?}");
            assert_ne!(w[0], w[1], "{seen:?}");
        }
    }

    /// The surfaces read from the records against the rule they stand
    /// for: a triangle with vertex normals is shaded with them (moved by
    /// the instance's normal matrix), one without with its geometric
    /// normal; through the scalar surface and four lanes alike.
    #[test]
    fn surfaces_take_given_normals_and_the_geometric_normal_where_none_were_given() {
        use crate::{Context, PrimitiveKind};
        use glam::{Mat4, Quat};
        use openrt_accel::Ray;
        let mut ctx = Context::new();
        let obj = ctx.gen_object();
        ctx.begin_object(obj).unwrap();
        ctx.begin(PrimitiveKind::Triangles).unwrap();
        let tilted = Vec3::new(0.3, 0.2, 1.0).normalize();
        ctx.normal(tilted).unwrap();
        for v in [
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(0.0, -1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ] {
            ctx.vertex(v).unwrap();
        }
        ctx.clear_normal().unwrap();
        for v in [
            Vec3::new(0.5, -1.0, 0.0),
            Vec3::new(1.5, -1.0, 0.0),
            Vec3::new(0.5, 1.0, 0.0),
        ] {
            ctx.vertex(v).unwrap();
        }
        ctx.end().unwrap();
        ctx.end_object().unwrap();
        let rotation = Quat::from_rotation_y(0.6) * Quat::from_rotation_x(-0.4);
        ctx.load_matrix(Mat4::from_rotation_translation(rotation, Vec3::new(2.0, 0.0, -3.0)))
            .unwrap();
        ctx.instantiate(obj).unwrap();
        ctx.commit().unwrap();
        let scene = ctx.scene();
        // The API's form comes back from the records: the given normals, and
        // the geometric normal (unnormalised) where none were given.
        let back = scene.instances()[0].geometry.shading();
        assert_eq!(back.has_normals, vec![true, false]);
        assert_eq!(back.normals[0], [tilted; 3]);
        assert_eq!(back.normals[1], [Vec3::new(0.0, 0.0, 2.0); 3]);
        assert_eq!(back.uvs, vec![[Vec2::ZERO; 3]; 2]);
        assert_eq!(back.materials, vec![ctx.current_material(); 2]);
        let world = |p: Vec3| rotation * p + Vec3::new(2.0, 0.0, -3.0);
        let rays = [Vec3::new(-0.7, -0.5, 0.0), Vec3::new(0.7, -0.5, 0.0)].map(|p| {
            let target = world(p);
            let o = target + rotation * Vec3::new(0.1, 0.0, 4.0);
            Ray::new(o, target - o, 0.0, f32::INFINITY)
        });
        let hits = rays
            .each_ref()
            .map(|r| scene.intersect(r).expect("each ray hits its triangle"));
        let geometric = (rotation * Vec3::Z).normalize();
        let want = [(rotation * tilted).normalize(), geometric];
        for (i, (ray, hit)) in rays.iter().zip(&hits).enumerate() {
            let s = scene.surface(ray, hit).unwrap();
            assert_eq!(hit.prim as usize, i);
            assert!(
                s.geometric_normal.abs_diff_eq(geometric, 1e-5),
                "{i}: {:?}",
                s.geometric_normal
            );
            assert!(
                s.shading_normal.abs_diff_eq(want[i], 1e-5),
                "{i}: {:?}",
                s.shading_normal
            );
        }
        assert_eq!(
            scene.surface(&rays[1], &hits[1]).unwrap().shading_normal,
            scene.surface(&rays[1], &hits[1]).unwrap().geometric_normal
        );
        let (ray_refs, hit_refs) = (
            [&rays[0], &rays[1], &rays[0], &rays[1]],
            [Some(&hits[0]), Some(&hits[1]), None, None],
        );
        let mut seen = 0;
        scene.own_surfaces::<wide::f32x4>(&ray_refs, &hit_refs, |i, s, _| {
            seen |= 1 << i;
            assert!(
                s.shading_normal.abs_diff_eq(want[i], 1e-5),
                "lane {i}: {:?}",
                s.shading_normal
            );
        });
        assert_eq!(seen, 0b11);
    }
}
