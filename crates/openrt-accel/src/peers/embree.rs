//! Embree 3 as a side-by-side peer for benchmarks (feature `embree`).
//!
//! Only used to measure: the same triangles and rays go through Embree's
//! BVH so throughput ratios come from one run on one machine.

use embree3::{
    BufferUsage, BuildQuality, Device, Format, GeometryKind, Hit4, Hit8, Hit16, INVALID_ID, IntersectContext, Ray4,
    Ray8, Ray16, RayHit, RayHit4, RayHit8, RayHit16, Scene, SceneFlags, ValidMask, ValidMaskN,
};

use crate::geom::ray::Ray;
use crate::geom::triangle::Triangle;

/// A triangle mesh in an Embree scene.
pub struct EmbreeMesh {
    // NOTE: field order matters: the scene is released before the device.
    scene: Scene<'static>,
    _device: Device,
}

impl EmbreeMesh {
    /// Builds an Embree scene over `tris` with the given build quality
    /// (`high` for static objects, `false` for Embree's LOW quality used for moving ones).
    pub fn new(tris: &[Triangle], high_quality: bool) -> Result<Self, String> {
        Self::with_flags(tris, high_quality, false)
    }

    /// As [`EmbreeMesh::new`], with Embree's `ROBUST` scene flag when
    /// `robust`: conservative traversal and a watertight triangle test, the
    /// guarantees the kd-tree gives, for a like-for-like comparison.
    pub fn with_flags(tris: &[Triangle], high_quality: bool, robust: bool) -> Result<Self, String> {
        let device = Device::new().map_err(|e| format!("embree device: {e:?}"))?;
        let flags = if robust { SceneFlags::ROBUST } else { SceneFlags::NONE };
        let scene = mesh_scene(&device, tris, high_quality, flags)?;
        Ok(Self { scene, _device: device })
    }

    /// Closest hit: `(t, prim)`; see [`EmbreeMesh::intersect_hit`] for the barycentrics.
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<(f32, u32)> {
        self.intersect_hit(ray).map(|h| (h.t, h.prim))
    }

    /// Closest hit with Embree's barycentrics.
    #[must_use]
    pub fn intersect_hit(&self, ray: &Ray) -> Option<crate::geom::hit::Hit> {
        closest1(&self.scene, ray).map(|(_, h)| h)
    }

    /// Any hit.
    #[must_use]
    pub fn occluded(&self, ray: &Ray) -> bool {
        let mut ctx = IntersectContext::incoherent();
        let mut r = embree3::Ray::segment(ray.origin.to_array(), ray.dir.to_array(), ray.t_min, ray.t_max);
        self.scene.occluded(&mut ctx, &mut r)
    }
}

/// A two-level Embree scene: one Embree scene per object, instanced in a
/// top-level scene (HIGH build quality for static objects, LOW for objects
/// rebuilt every frame), for side-by-side frame benchmarks.
pub struct EmbreeTwoLevel {
    // NOTE: field order matters: scenes are released before the device.
    top: Scene<'static>,
    objects: Vec<Scene<'static>>,
    /// Per instance: its object and its geometry id in `top`.
    instances: Vec<(usize, u32)>,
    /// Instance index by Embree geometry id (`u32::MAX` for none).
    by_id: Vec<u32>,
    device: Device,
}

fn mesh_scene(
    device: &Device,
    tris: &[Triangle],
    high_quality: bool,
    flags: SceneFlags,
) -> Result<Scene<'static>, String> {
    let quality = if high_quality {
        BuildQuality::HIGH
    } else {
        BuildQuality::LOW
    };
    mesh_scene_with(device, tris, quality, flags)
}

/// Seconds Embree takes to build a scene over `tris` at its MEDIUM (default)
/// quality with one build thread: copying the triangles into its buffers
/// and committing the scene; the device is made before the clock starts.
pub fn embree_medium_build_secs(tris: &[Triangle]) -> Result<f64, String> {
    let config = embree3::Config {
        threads: 1,
        ..embree3::Config::default()
    };
    let device = Device::with_config(config).map_err(|e| format!("embree device: {e:?}"))?;
    let start = std::time::Instant::now();
    let scene = mesh_scene_with(&device, tris, BuildQuality::MEDIUM, SceneFlags::NONE)?;
    let secs = start.elapsed().as_secs_f64();
    drop(scene);
    Ok(secs)
}

/// Embree's LOW builds timed on one device made once (its worker threads
/// started before the first clock), as a renderer keeps its device from
/// frame to frame.
pub struct EmbreeLowBuilds {
    device: Device,
}

impl EmbreeLowBuilds {
    /// A device of `threads` build threads.
    pub fn new(threads: usize) -> Result<Self, String> {
        let config = embree3::Config {
            threads: u32::try_from(threads).unwrap_or(u32::MAX),
            ..embree3::Config::default()
        };
        let device = Device::with_config(config).map_err(|e| format!("embree device: {e:?}"))?;
        Ok(Self { device })
    }

    /// Seconds a LOW-quality scene over `tris` takes: copying the triangles
    /// into Embree's buffers and committing the scene.
    pub fn secs(&self, tris: &[Triangle]) -> Result<f64, String> {
        let start = std::time::Instant::now();
        let scene = mesh_scene_with(&self.device, tris, BuildQuality::LOW, SceneFlags::NONE)?;
        let secs = start.elapsed().as_secs_f64();
        drop(scene);
        Ok(secs)
    }
}

/// Embree's REFIT builds (`RTC_BUILD_QUALITY_REFIT`): one scene over a
/// vertex buffer of the application's, whose triangles are rewritten and
/// refitted frame by frame, as Embree's own refit of deforming geometry.
pub struct EmbreeRefits {
    // NOTE: field order matters: the scene and buffer are released before
    // the device.
    scene: Scene<'static>,
    vertices: embree3::Buffer,
    id: u32,
    count: usize,
    _device: Device,
}

impl EmbreeRefits {
    /// A scene of `tris` (at least one) on a device of `threads` threads,
    /// built once.
    pub fn new(tris: &[Triangle], threads: usize) -> Result<Self, String> {
        if tris.is_empty() {
            return Err("embree refit: no triangles".into());
        }
        let config = embree3::Config {
            threads: u32::try_from(threads).unwrap_or(u32::MAX),
            ..embree3::Config::default()
        };
        let device = Device::with_config(config).map_err(|e| format!("embree device: {e:?}"))?;
        let n = 3 * tris.len();
        // 16 bytes of padding: Embree reads the last vertex with one SSE load.
        let bytes = 12 * n + 16;
        let mut vertices = device
            .create_buffer(bytes)
            .map_err(|e| format!("embree vertex buffer: {e:?}"))?;
        write_vertices(&mut vertices, tris);
        let mut scene = device.create_scene().map_err(|e| format!("embree scene: {e:?}"))?;
        // NOTE: REFIT is a geometry's build quality only (a scene refuses
        // it: "invalid build quality").
        scene.set_flags(SceneFlags::DYNAMIC);
        let mut geom = device
            .create_geometry(GeometryKind::TRIANGLE)
            .map_err(|e| format!("embree geometry: {e:?}"))?;
        geom.set_managed_buffer(BufferUsage::VERTEX, 0, Format::FLOAT3, &vertices, .., 12, n)
            .map_err(|e| format!("embree vertex buffer: {e:?}"))?;
        let idx: Vec<[u32; 3]> = (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        geom.set_new_buffer::<[u32; 3]>(BufferUsage::INDEX, 0, Format::UINT3, 12, idx.len())
            .map_err(|e| format!("embree index buffer: {e:?}"))?
            .copy_from_slice(&idx);
        geom.set_build_quality(BuildQuality::REFIT);
        let geom = geom.commit();
        let id = scene.attach_geometry(&geom);
        scene.commit();
        Ok(Self {
            scene,
            vertices,
            id,
            count: tris.len(),
            _device: device,
        })
    }

    /// Seconds to refit the scene to `tris` (as many as it was made with):
    /// writing them into the vertex buffer and committing.
    pub fn secs(&mut self, tris: &[Triangle]) -> Result<f64, String> {
        if tris.len() != self.count {
            return Err(format!(
                "embree refit: {} triangles, made with {}",
                tris.len(),
                self.count
            ));
        }
        let start = std::time::Instant::now();
        write_vertices(&mut self.vertices, tris);
        self.scene.update_geometry_buffer(self.id, BufferUsage::VERTEX, 0);
        self.scene.commit_geometry(self.id);
        self.scene.commit();
        Ok(start.elapsed().as_secs_f64())
    }
}

/// The triangles' vertices into an Embree buffer of at least `36 n` bytes.
fn write_vertices(buf: &mut embree3::Buffer, tris: &[Triangle]) {
    let mut view = buf.mapped_range_mut::<_, f32>(..36 * tris.len());
    for (dst, t) in view.chunks_exact_mut(9).zip(tris) {
        for (k, v) in t.iter().enumerate() {
            dst[3 * k..3 * k + 3].copy_from_slice(&v.to_array());
        }
    }
}

fn mesh_scene_with(
    device: &Device,
    tris: &[Triangle],
    quality: BuildQuality,
    flags: SceneFlags,
) -> Result<Scene<'static>, String> {
    let mut scene = device.create_scene().map_err(|e| format!("embree scene: {e:?}"))?;
    scene.set_flags(flags);
    scene.set_build_quality(quality);
    if !tris.is_empty() {
        let mut geom = device
            .create_geometry(GeometryKind::TRIANGLE)
            .map_err(|e| format!("embree geometry: {e:?}"))?;
        let verts: Vec<[f32; 3]> = tris.iter().flat_map(|t| t.map(|v| v.to_array())).collect();
        let idx: Vec<[u32; 3]> = (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        geom.set_new_buffer::<[f32; 3]>(BufferUsage::VERTEX, 0, Format::FLOAT3, 12, verts.len())
            .map_err(|e| format!("embree vertex buffer: {e:?}"))?
            .copy_from_slice(&verts);
        geom.set_new_buffer::<[u32; 3]>(BufferUsage::INDEX, 0, Format::UINT3, 12, idx.len())
            .map_err(|e| format!("embree index buffer: {e:?}"))?
            .copy_from_slice(&idx);
        geom.set_build_quality(quality);
        let geom = geom.commit();
        scene.attach_geometry(&geom);
    }
    scene.commit();
    Ok(scene)
}

impl EmbreeTwoLevel {
    /// `objects`: triangles and whether the object moves (LOW quality);
    /// `instances`: object index and column-major object-to-world matrix.
    pub fn new(objects: &[(&[Triangle], bool)], instances: &[(usize, [f32; 16])]) -> Result<Self, String> {
        let device = Device::new().map_err(|e| format!("embree device: {e:?}"))?;
        let objs = objects
            .iter()
            .map(|(t, moving)| mesh_scene(&device, t, !moving, SceneFlags::NONE))
            .collect::<Result<Vec<_>, _>>()?;
        let mut top = device.create_scene().map_err(|e| format!("embree scene: {e:?}"))?;
        top.set_build_quality(BuildQuality::LOW);
        let mut inst = Vec::with_capacity(instances.len());
        for &(o, m) in instances {
            let id = Self::attach(&device, &mut top, &objs[o], &m)?;
            inst.push((o, id));
        }
        top.commit();
        let mut s = Self {
            top,
            objects: objs,
            instances: inst,
            by_id: Vec::new(),
            device,
        };
        s.reindex();
        Ok(s)
    }

    fn attach(device: &Device, top: &mut Scene<'static>, obj: &Scene<'static>, m: &[f32; 16]) -> Result<u32, String> {
        let mut g = device
            .create_geometry(GeometryKind::INSTANCE)
            .map_err(|e| format!("embree instance: {e:?}"))?;
        g.set_instanced_scene(obj);
        g.set_transform(0, m);
        let g = g.commit();
        Ok(top.attach_geometry(&g))
    }

    /// One frame's changes: new transforms for every instance, new
    /// triangles for redefined objects (rebuilt with LOW quality); then the
    /// top level is committed.
    pub fn update(&mut self, transforms: &[[f32; 16]], redefined: &[(usize, &[Triangle])]) -> Result<(), String> {
        for &(o, tris) in redefined {
            self.objects[o] = mesh_scene(&self.device, tris, false, SceneFlags::NONE)?;
            for (inst, m) in self.instances.iter_mut().zip(transforms) {
                if inst.0 == o {
                    self.top.detach_geometry(inst.1);
                    inst.1 = Self::attach(&self.device, &mut self.top, &self.objects[o], m)?;
                }
            }
        }
        for (k, m) in transforms.iter().enumerate() {
            let id = self.instances[k].1;
            self.top.set_geometry_transform(id, 0, m);
            self.top.commit_geometry(id);
        }
        self.top.commit();
        self.reindex();
        Ok(())
    }

    /// Closest hit `t`.
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let mut ctx = IntersectContext::coherent();
        let mut rh = RayHit::from(embree3::Ray::segment(
            ray.origin.to_array(),
            ray.dir.to_array(),
            ray.t_min,
            ray.t_max,
        ));
        self.top.intersect(&mut ctx, &mut rh);
        rh.hit.is_valid().then_some(rh.ray.tfar)
    }
}

/// The closest hit of one ray (rtcIntersect1) with the Embree id of the
/// instance hit (`INVALID_ID` in a scene without instances).
fn closest1(scene: &Scene<'static>, ray: &Ray) -> Option<(u32, crate::geom::hit::Hit)> {
    let mut ctx = IntersectContext::incoherent();
    let mut rh = RayHit::from(embree3::Ray::segment(
        ray.origin.to_array(),
        ray.dir.to_array(),
        ray.t_min,
        ray.t_max,
    ));
    scene.intersect(&mut ctx, &mut rh);
    rh.hit.is_valid().then_some((
        rh.hit.instID[0],
        crate::geom::hit::Hit {
            t: rh.ray.tfar,
            prim: rh.hit.primID,
            b1: rh.hit.u,
            b2: rh.hit.v,
        },
    ))
}

/// A value at a 64-byte boundary (Embree's packet masks, see `fill_packet`).
#[repr(C, align(64))]
struct Aligned64<T>(T);

/// Fills an Embree SoA ray packet from `rays` (lanes outside `lanes`, and
/// rays that hit nothing by construction, are left inactive).
macro_rules! fill_packet {
    ($packet:ty, $n:literal, $rays:expr, $lanes:expr) => {{
        let mut p = <$packet>::default();
        // NOTE: Embree loads the mask as one SIMD register of the packet's
        // width (64 bytes for 16 lanes); `ValidMaskN` is only 16-byte
        // aligned, and a misaligned 16-lane mask hung rtcOccluded16 here.
        let mut valid = Aligned64(ValidMaskN::<$n>::new([ValidMask::Invalid; $n]));
        let mut bits = 0u32;
        for (l, r) in $rays.iter().enumerate().take($n) {
            p.org_x[l] = r.origin.x;
            p.org_y[l] = r.origin.y;
            p.org_z[l] = r.origin.z;
            p.dir_x[l] = r.dir.x;
            p.dir_y[l] = r.dir.y;
            p.dir_z[l] = r.dir.z;
            p.tnear[l] = r.t_min;
            p.tfar[l] = r.t_max;
            p.time[l] = 0.0;
            p.mask[l] = u32::MAX;
            p.id[l] = l as u32;
            p.flags[l] = 0;
            if $lanes & (1 << l) != 0 && r.is_valid() && r.t_min <= r.t_max {
                valid.0.lanes_mut()[l] = ValidMask::Valid;
                bits |= 1 << l;
            } else {
                // NOTE: an inactive lane still gets finite data and an
                // empty interval: Embree's SIMD code computes on every lane.
                p.org_x[l] = 0.0;
                p.org_y[l] = 0.0;
                p.org_z[l] = 0.0;
                p.dir_x[l] = 1.0;
                p.dir_y[l] = 1.0;
                p.dir_z[l] = 1.0;
                p.tnear[l] = 1.0;
                p.tfar[l] = 0.0;
            }
        }
        (p, valid, bits)
    }};
}

/// The packet queries of one width (rtcIntersect4/8/16, rtcOccluded4/8/16).
macro_rules! packet_queries {
    ($closest:ident, $any:ident, $n:literal, $ray:ty, $hit:ty, $rayhit:ident, $isect:ident, $occl:ident) => {
        fn $closest(&self, rays: &[Ray], lanes: u32, out: &mut [Option<(u32, crate::geom::hit::Hit)>]) {
            let (ray, valid, bits) = fill_packet!($ray, $n, rays, lanes);
            let mut rh = $rayhit {
                ray,
                hit: <$hit>::default(),
            };
            let mut ctx = IntersectContext::coherent();
            self.top.$isect(&mut ctx, &mut rh, &valid.0);
            for l in crate::packet::width::lanes_of(bits) {
                if rh.hit.geomID[l] != INVALID_ID {
                    out[l] = Some((
                        self.index_of(rh.hit.instID[0][l]),
                        crate::geom::hit::Hit {
                            t: rh.ray.tfar[l],
                            prim: rh.hit.primID[l],
                            b1: rh.hit.u[l],
                            b2: rh.hit.v[l],
                        },
                    ));
                }
            }
        }

        fn $any(&self, rays: &[Ray], lanes: u32) -> u32 {
            let (mut ray, valid, bits) = fill_packet!($ray, $n, rays, lanes);
            // NOTE: with the coherent flag, rtcOccluded16 on some packets
            // of secondary shadow rays never returned (Embree 3.13.5,
            // AVX-512, instanced scenes); the incoherent flag answers them.
            let mut ctx = IntersectContext::incoherent();
            self.top.$occl(&mut ctx, &mut ray, &valid.0);
            let mut hit = 0;
            for l in crate::packet::width::lanes_of(bits) {
                if ray.tfar[l] == f32::NEG_INFINITY {
                    hit |= 1 << l;
                }
            }
            hit
        }
    };
}

impl EmbreeTwoLevel {
    /// Index (in the `instances` order given to [`EmbreeTwoLevel::new`]) of
    /// the instance with Embree geometry id `id`.
    fn index_of(&self, id: u32) -> u32 {
        self.by_id.get(id as usize).copied().unwrap_or(u32::MAX)
    }

    /// Rebuilds the map from Embree geometry ids to instance indices.
    fn reindex(&mut self) {
        let len = self.instances.iter().map(|i| i.1 as usize + 1).max().unwrap_or(0);
        self.by_id = vec![u32::MAX; len];
        for (k, i) in self.instances.iter().enumerate() {
            self.by_id[i.1 as usize] = k as u32;
        }
    }

    /// Closest hit with the index of the instance hit (rtcIntersect1).
    #[must_use]
    pub fn intersect_instance(&self, ray: &Ray) -> Option<(u32, crate::geom::hit::Hit)> {
        if !ray.is_valid() || ray.t_min > ray.t_max {
            return None;
        }
        closest1(&self.top, ray).map(|(inst, h)| (self.index_of(inst), h))
    }

    /// `true` when anything is hit (rtcOccluded1).
    #[must_use]
    pub fn occluded(&self, ray: &Ray) -> bool {
        if !ray.is_valid() || ray.t_min > ray.t_max {
            return false;
        }
        let mut ctx = IntersectContext::incoherent();
        let mut r = embree3::Ray::segment(ray.origin.to_array(), ray.dir.to_array(), ray.t_min, ray.t_max);
        self.top.occluded(&mut ctx, &mut r)
    }

    packet_queries!(closest4, any4, 4, Ray4, Hit4, RayHit4, intersect4, occluded4);
    packet_queries!(closest8, any8, 8, Ray8, Hit8, RayHit8, intersect8, occluded8);
    packet_queries!(closest16, any16, 16, Ray16, Hit16, RayHit16, intersect16, occluded16);

    /// Closest hits of the `lanes` of a packet through Embree's packet
    /// kernels of the same width (rtcIntersect4/8/16; packets of 32 lanes as
    /// two of 16, Embree's widest; other widths go ray by ray), with the
    /// index of the instance hit.
    #[must_use]
    pub fn intersect_packet<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
    ) -> [Option<(u32, crate::geom::hit::Hit)>; N] {
        let mut out = [None; N];
        match N {
            4 => self.closest4(rays, lanes, &mut out),
            8 => self.closest8(rays, lanes, &mut out),
            16 => self.closest16(rays, lanes, &mut out),
            32 => {
                for half in [0, 16] {
                    self.closest16(&rays[half..], (lanes >> half) & 0xFFFF, &mut out[half..]);
                }
            }
            _ => {
                for l in crate::packet::width::lanes_of(lanes) {
                    out[l] = self.intersect_instance(&rays[l]);
                }
            }
        }
        out
    }

    /// The lanes of a packet that hit anything (rtcOccluded4/8/16; 32 lanes
    /// as two packets of 16).
    #[must_use]
    pub fn occluded_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> u32 {
        match N {
            4 => self.any4(rays, lanes),
            8 => self.any8(rays, lanes),
            16 => self.any16(rays, lanes),
            32 => [0, 16].into_iter().fold(0, |m, half| {
                m | (self.any16(&rays[half..], (lanes >> half) & 0xFFFF) << half)
            }),
            _ => crate::packet::width::lanes_of(lanes)
                .filter(|&l| self.occluded(&rays[l]))
                .fold(0, |m, l| m | (1 << l)),
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::{EmbreeMesh, EmbreeRefits};
    use crate::geom::triangle::Triangle;
    use crate::testing::meshgen;

    /// A refitted scene answers as a scene built afresh over the moved
    /// triangles, and refuses a different count.
    #[test]
    fn refits_answer_as_fresh_scenes() {
        let tris = meshgen::bumpy_sphere(3000, 4, 0.3);
        let mut refits = EmbreeRefits::new(&tris, 1).unwrap();
        let rays = meshgen::camera_rays(Vec3::new(0.5, 0.8, -3.5), Vec3::ZERO, 48, 48, 50.0);
        for step in 1..4 {
            let s = step as f32;
            let moved: Vec<Triangle> = tris
                .iter()
                .map(|t| t.map(|v| v * (1.0 + 0.2 * (v.y * s).sin()) + Vec3::X * 0.1 * s))
                .collect();
            assert!(refits.secs(&moved).unwrap() >= 0.0);
            let fresh = EmbreeMesh::new(&moved, true).unwrap();
            let mut hits = 0;
            for ray in &rays {
                let (a, b) = (
                    super::closest1(&refits.scene, ray).map(|(_, h)| (h.t, h.prim)),
                    fresh.intersect(ray),
                );
                assert_eq!(a, b, "step {step}");
                hits += usize::from(a.is_some());
            }
            assert!(hits > 1000, "{hits} hits: the rays test too little");
        }
        assert!(refits.secs(&tris[1..]).is_err());
    }
}
