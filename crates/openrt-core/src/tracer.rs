//! What shading asks of a traversal backend: closest hits, for single rays
//! and for packets, and whether shadow rays are blocked, one by one or as a
//! packet towards one light. The kd-trees of a committed [`Scene`] answer
//! it, and so does the Embree peer (feature `embree`).

use openrt_accel::Ray;

use crate::occluder_hint::OccluderHint;
use crate::{Scene, SceneHit};

/// A traversal backend for the shader.
pub(crate) trait Tracer: Sync {
    /// Closest hit of `ray`.
    fn intersect(&self, ray: &Ray) -> Option<SceneHit>;
    /// Closest hits of the `lanes` of a packet.
    fn intersect_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> [Option<SceneHit>; N];
    /// `true` when anything blocks the shadow ray `ray`. `hint` is the last
    /// occluder of its light, which a backend may try first and update
    /// ([`OccluderHint`]); the answer is the same either way. Embree's
    /// backends ignore it (their any-hit query names no blocker).
    fn occluded_hinted(&self, ray: &Ray, hint: &mut OccluderHint) -> bool;
    /// The blocked lanes of a packet of shadow rays that all end at
    /// `target` (one light), which a backend may cull with; `hint` as in
    /// [`Tracer::occluded_hinted`].
    fn occluded_packet_toward_hinted<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        target: glam::Vec3,
        hint: &mut OccluderHint,
    ) -> u32;
}

impl Tracer for Scene {
    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<SceneHit> {
        Scene::intersect(self, ray)
    }

    #[inline]
    fn intersect_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> [Option<SceneHit>; N] {
        Scene::intersect_packet(self, rays, lanes)
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
