//! Embree 3 as a side-by-side peer for benchmarks (feature `embree`).
//!
//! Only used to measure: the same triangles and rays go through Embree's
//! BVH so throughput ratios come from one run on one machine.

use embree3::{BufferUsage, BuildQuality, Device, Format, GeometryKind, IntersectContext, RayHit, Scene};

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
        let device = Device::new().map_err(|e| format!("embree device: {e:?}"))?;
        let mut scene = device.create_scene().map_err(|e| format!("embree scene: {e:?}"))?;
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
        geom.set_build_quality(if high_quality {
            BuildQuality::HIGH
        } else {
            BuildQuality::LOW
        });
        let geom = geom.commit();
        scene.set_build_quality(if high_quality {
            BuildQuality::HIGH
        } else {
            BuildQuality::LOW
        });
        scene.attach_geometry(&geom);
        scene.commit();
        Ok(Self { scene, _device: device })
    }

    /// Closest hit: `(t, prim)`.
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<(f32, u32)> {
        let mut ctx = IntersectContext::incoherent();
        let mut rh = RayHit::from(embree3::Ray::segment(
            ray.origin.to_array(),
            ray.dir.to_array(),
            ray.t_min,
            ray.t_max,
        ));
        self.scene.intersect(&mut ctx, &mut rh);
        rh.hit.is_valid().then_some((rh.ray.tfar, rh.hit.primID))
    }

    /// Any hit.
    #[must_use]
    pub fn occluded(&self, ray: &Ray) -> bool {
        let mut ctx = IntersectContext::incoherent();
        let mut r = embree3::Ray::segment(ray.origin.to_array(), ray.dir.to_array(), ray.t_min, ray.t_max);
        self.scene.occluded(&mut ctx, &mut r)
    }
}
