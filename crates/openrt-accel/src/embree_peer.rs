//! Embree 3 as a side-by-side peer for benchmarks (feature `embree`).
//!
//! Only used to measure: the same triangles and rays go through Embree's
//! BVH so throughput ratios come from one run on one machine.

use embree3::{BufferUsage, BuildQuality, Device, Format, GeometryKind, IntersectContext, RayHit, Scene, SceneFlags};

use crate::{Ray, Triangle};

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
    pub fn intersect_hit(&self, ray: &Ray) -> Option<crate::Hit> {
        let mut ctx = IntersectContext::incoherent();
        let mut rh = RayHit::from(embree3::Ray::segment(
            ray.origin.to_array(),
            ray.dir.to_array(),
            ray.t_min,
            ray.t_max,
        ));
        self.scene.intersect(&mut ctx, &mut rh);
        rh.hit.is_valid().then_some(crate::Hit {
            t: rh.ray.tfar,
            prim: rh.hit.primID,
            b1: rh.hit.u,
            b2: rh.hit.v,
        })
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
    device: Device,
}

fn mesh_scene(
    device: &Device,
    tris: &[Triangle],
    high_quality: bool,
    flags: SceneFlags,
) -> Result<Scene<'static>, String> {
    let mut scene = device.create_scene().map_err(|e| format!("embree scene: {e:?}"))?;
    scene.set_flags(flags);
    let quality = if high_quality {
        BuildQuality::HIGH
    } else {
        BuildQuality::LOW
    };
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
        Ok(Self {
            top,
            objects: objs,
            instances: inst,
            device,
        })
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
