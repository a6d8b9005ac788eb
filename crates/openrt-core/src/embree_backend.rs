//! The Embree 3 peer as a renderer backend (feature `embree`): the same
//! committed frame as one Embree scene per object (HIGH build quality for
//! objects built with the SAH, LOW for redefined ones) instanced in a
//! top-level scene committed every frame. Only traversal differs from the
//! kd backends; shading, rays and images are the same up to Embree's own
//! hit differences.

use std::sync::Arc;

use openrt_accel::{BuilderKind, EmbreeTwoLevel, Ray, Triangle};

use crate::occluder_hint::OccluderHint;
use crate::tracer::Tracer;
use crate::{CoreError, ObjectGeometry, Scene, SceneHit};

/// The Embree scene kept in step with the committed frames: the renderer's
/// Embree backends, and the bench's ray-kind figures.
#[derive(Default)]
pub struct EmbreeScene {
    two_level: Option<EmbreeTwoLevel>,
    /// Per Embree object, the geometry it was built from.
    geoms: Vec<Arc<ObjectGeometry>>,
    /// Per instance, its Embree object.
    inst_obj: Vec<usize>,
    /// Frame of the synced scene (stamped on the hits).
    frame: u64,
}

impl EmbreeScene {
    /// Brings the Embree scene to `scene`: with the same instances and
    /// objects, the transforms are set and redefined objects rebuilt (LOW);
    /// otherwise everything is built again.
    pub fn sync(&mut self, scene: &Scene) -> Result<(), CoreError> {
        let err = |e: String| CoreError::Backend {
            backend: "embree",
            reason: e,
        };
        let mut geoms: Vec<Arc<ObjectGeometry>> = Vec::new();
        let mut inst_obj = Vec::with_capacity(scene.instances().len());
        let mut transforms = Vec::with_capacity(scene.instances().len());
        for i in scene.instances() {
            let k = geoms
                .iter()
                .position(|g| Arc::ptr_eq(g, &i.geometry))
                .unwrap_or_else(|| {
                    geoms.push(Arc::clone(&i.geometry));
                    geoms.len() - 1
                });
            inst_obj.push(k);
            transforms.push(glam::Mat4::from(i.to_world).to_cols_array());
        }
        match self.two_level.as_mut() {
            Some(tl) if inst_obj == self.inst_obj && geoms.len() == self.geoms.len() => {
                let redefined: Vec<(usize, &[Triangle])> = (0..geoms.len())
                    .filter(|&o| !Arc::ptr_eq(&geoms[o], &self.geoms[o]))
                    .map(|o| (o, geoms[o].tree.triangles()))
                    .collect();
                tl.update(&transforms, &redefined).map_err(err)?;
            }
            _ => {
                let objects: Vec<(&[Triangle], bool)> = geoms
                    .iter()
                    .map(|g| (g.tree.triangles(), g.tree.builder() == BuilderKind::Fast))
                    .collect();
                let instances: Vec<(usize, [f32; 16])> = inst_obj.iter().copied().zip(transforms).collect();
                self.two_level = Some(EmbreeTwoLevel::new(&objects, &instances).map_err(err)?);
            }
        }
        self.geoms = geoms;
        self.inst_obj = inst_obj;
        self.frame = scene.frame();
        Ok(())
    }

    fn tl(&self) -> &EmbreeTwoLevel {
        self.two_level.as_ref().expect("synced before the frame")
    }
}

fn scene_hit(frame: u64, (instance, h): (u32, openrt_accel::Hit)) -> SceneHit {
    SceneHit {
        frame,
        t: h.t,
        instance,
        prim: h.prim,
        b1: h.b1,
        b2: h.b2,
    }
}

impl EmbreeScene {
    /// Closest hit (rtcIntersect1), instance indices as in the synced scene.
    ///
    /// # Panics
    /// Before the first [`EmbreeScene::sync`].
    #[must_use]
    pub fn intersect(&self, ray: &Ray) -> Option<SceneHit> {
        self.tl().intersect_instance(ray).map(|h| scene_hit(self.frame, h))
    }

    /// Any hit (rtcOccluded1).
    #[must_use]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.tl().occluded(ray)
    }

    /// Closest hits of a packet (rtcIntersect4/8/16).
    #[must_use]
    pub fn intersect_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> [Option<SceneHit>; N] {
        self.tl()
            .intersect_packet(rays, lanes)
            .map(|h| h.map(|h| scene_hit(self.frame, h)))
    }

    /// The blocked lanes of a packet (rtcOccluded4/8/16).
    #[must_use]
    pub fn occluded_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> u32 {
        self.tl().occluded_packet(rays, lanes)
    }
}

impl Tracer for EmbreeScene {
    fn intersect(&self, ray: &Ray) -> Option<SceneHit> {
        EmbreeScene::intersect(self, ray)
    }

    fn intersect_packet<const N: usize>(&self, rays: &[Ray; N], lanes: u32) -> [Option<SceneHit>; N] {
        EmbreeScene::intersect_packet(self, rays, lanes)
    }

    fn occluded_hinted(&self, ray: &Ray, _: &mut OccluderHint) -> bool {
        EmbreeScene::occluded(self, ray)
    }

    fn occluded_packet_toward_hinted<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        _: glam::Vec3,
        _: &mut OccluderHint,
    ) -> u32 {
        EmbreeScene::occluded_packet(self, rays, lanes)
    }
}
