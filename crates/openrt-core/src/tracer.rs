//! What shading asks of a traversal backend: closest and any hit, for single
//! rays and for packets. The kd-trees of a committed [`Scene`] answer it,
//! and so does the Embree peer (feature `embree`).

use openrt_accel::Ray;

use crate::{OccluderHint, Scene, SceneHit};

/// A traversal backend for the shader.
pub(crate) trait Tracer: Sync {
    /// Closest hit of `ray`.
    fn intersect(&self, ray: &Ray) -> Option<SceneHit>;
    /// `true` when anything blocks `ray`.
    fn occluded(&self, ray: &Ray) -> bool;
    /// Closest hits of the `lanes` of a packet.
    fn intersect_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> [Option<SceneHit>; N];
    /// The lanes of a packet that are blocked.
    fn occluded_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> u32;
    /// [`Tracer::occluded_packet`] for rays that all end at `target` (shadow
    /// rays towards one light), which a backend may cull with.
    fn occluded_packet_toward<const N: usize>(&self, rays: &[Ray; N], lanes: u32, target: glam::Vec3) -> u32 {
        let _ = target;
        self.occluded_packet(rays, lanes)
    }
    /// [`Tracer::occluded`] for a shadow ray, with the last occluder of its
    /// light, which a backend may try first and update ([`OccluderHint`]);
    /// the same answer either way. Embree's backends ignore it (its any-hit
    /// query names no blocker).
    fn occluded_hinted(&self, ray: &Ray, hint: &mut OccluderHint) -> bool {
        let _ = hint;
        self.occluded(ray)
    }
    /// [`Tracer::occluded_packet_toward`] with the last occluder of the
    /// light at `target`, as [`Tracer::occluded_hinted`].
    fn occluded_packet_toward_hinted<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        target: glam::Vec3,
        hint: &mut OccluderHint,
    ) -> u32 {
        let _ = hint;
        self.occluded_packet_toward(rays, lanes, target)
    }
}

impl Tracer for Scene {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<SceneHit> {
        Scene::intersect(self, ray)
    }

    #[inline]
    fn occluded(&self, ray: &Ray) -> bool {
        Scene::occluded(self, ray)
    }

    #[inline]
    fn intersect_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> [Option<SceneHit>; N] {
        Scene::intersect_packet(self, rays, lanes)
    }

    #[inline]
    fn occluded_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> u32 {
        Scene::occluded_packet(self, rays, lanes)
    }

    #[inline]
    fn occluded_packet_toward<const N: usize>(&self, rays: &[Ray; N], lanes: u32, target: glam::Vec3) -> u32 {
        Scene::occluded_packet_toward(self, rays, lanes, target)
    }

    #[inline]
    fn occluded_hinted(&self, ray: &Ray, hint: &mut OccluderHint) -> bool {
        Scene::occluded_hinted(self, ray, hint)
    }

    #[inline]
    fn occluded_packet_toward_hinted<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        target: glam::Vec3,
        hint: &mut OccluderHint,
    ) -> u32 {
        Scene::occluded_packet_toward_hinted(self, rays, lanes, target, hint)
    }
}
