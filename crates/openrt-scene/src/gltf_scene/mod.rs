//! glTF 2.0 scenes (`.gltf` with external or embedded buffers, `.glb`) on
//! the `gltf` crate, played through the paper's motion classes: every mesh
//! is one object, instanced once per node that uses it; nodes that no
//! animation moves keep their instances' transforms (static objects, SAH
//! trees built once); nodes moved by translation, rotation or scale
//! channels, or under such a node, get a new instance transform every frame
//! (affine motion: only the top level is rebuilt); skinned meshes and
//! meshes with animated morph weights get an object of their own per node,
//! deformed on the pool and redefined every frame (unstructured motion).
//!
//! The mapping onto the Whitted model, and what is not played yet, is in
//! docs/SCENE-FORMAT.md ("glTF 2.0"); each thing left out is a warning
//! (`openrt --strict` makes it an error), never a silent change.

mod animation;
mod convert;
mod deform;
mod figure;
mod options;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat4, Vec3};
use openrt_core::{
    Accel, Camera, CommitStats, Context, CoreError, Environment, InstanceId, PointLight, RenderSettings,
};

use crate::{SceneError, SceneWarning};
use animation::{Channel, Trs, WeightChannel};
use deform::Deformer;
pub use deform::GLTF_MAX_INFLUENCES;
pub use figure::{MAX_FIGURE_TRIANGLES, skinned_figure_glb};
pub use options::{GltfAnimation, GltfOptions, MotionClasses};

/// glTF extensions this loader reads (a file may require them); an
/// extension a file uses without requiring it that is not listed here is
/// a warning (the scene renders without it).
pub const GLTF_SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_emissive_strength",
    "KHR_texture_transform",
    "KHR_materials_unlit",
];

/// The structure a deforming (skinned or morphed) object gets unless
/// [`GltfPlayer::set_deforming_accel`] says otherwise: BVHs, whose refit the
/// bench's deforming table measures several times faster than the kd-tree's
/// (the images are the same bytes with either).
pub const GLTF_DEFORMING_ACCEL: Accel = Accel::Bvh;

/// Frames per second of a glTF animation played frame by frame.
pub const GLTF_FRAME_RATE: f32 = 30.0;

/// A glTF scene ready to play.
pub struct GltfPlayer {
    /// The context holding the scene (committed once by the load).
    pub ctx: Context,
    /// Lights, ambient light and background.
    pub env: Arc<Environment>,
    settings: RenderSettings,
    path: PathBuf,
    warnings: Vec<SceneWarning>,
    /// Per node: its parent and its local transform at rest.
    parents: Vec<Option<usize>>,
    rest: Vec<Trs>,
    /// The scene's nodes, parents before children.
    order: Vec<usize>,
    /// Every node, parents before children (world transforms of joints
    /// outside the scene too).
    world_order: Vec<usize>,
    /// Instances of the nodes that animation moves (directly or through an ancestor).
    moving: Vec<(usize, InstanceId)>,
    /// The played animation's channels and its length in seconds.
    channels: Vec<Channel>,
    weight_channels: Vec<WeightChannel>,
    /// Per node: its morph weights at rest (one per morph target).
    rest_weights: Vec<Vec<f32>>,
    /// Nodes whose meshes are skinned or morphed.
    deformers: Vec<Deformer>,
    duration: f32,
    /// The camera: its node, vertical field of view (radians) and near plane;
    /// `None` frames the scene.
    camera: Option<(usize, f32, f32)>,
    framing: Camera,
    /// How many objects are static, and how many instances move.
    static_instances: usize,
    /// The last [`GltfPlayer::set_time`]'s deformation cost.
    deform_times: DeformTimes,
    /// The file's animations by index: their names (empty when unnamed).
    animation_names: Vec<String>,
    /// Punctual lights at their nodes; the scene's bounds at time 0 place
    /// directional ones.
    lights: Vec<SceneLight>,
    light_bounds: openrt_accel::Aabb,
    /// Per node: moved by the animation (itself or an ancestor).
    node_animated: Vec<bool>,
}

/// A KHR_lights_punctual light as a point light at its node (a
/// directional one far back along its node's -z axis).
#[derive(Clone, Copy, Debug)]
pub(crate) struct SceneLight {
    pub node: usize,
    pub directional: bool,
    pub color: Vec3,
}

/// What deforming meshes cost in one [`GltfPlayer::set_time`], before its commit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeformTimes {
    /// Morphing and skinning the vertices (in parallel on the pool), ms.
    pub skin_ms: f64,
    /// Redefining the deformed objects through the API, ms.
    pub define_ms: f64,
}

impl GltfPlayer {
    /// Loads `path` (`.gltf` or `.glb`), its default scene (else its first)
    /// and its first animation, and commits the scene at time 0.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        convert::load(path, &GltfOptions::default())
    }

    /// Loads `path` with the scene, animation and camera of `options`.
    pub fn load_with(path: &Path, options: &GltfOptions) -> Result<Self, SceneError> {
        convert::load(path, options)
    }

    /// A glTF or GLB file held in memory (buffers and images embedded:
    /// external files are refused); errors name `<memory>`.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, SceneError> {
        Self::from_slice_with(bytes, &GltfOptions::default())
    }

    /// [`GltfPlayer::from_slice`] with the scene, animation and camera of `options`.
    pub fn from_slice_with(bytes: &[u8], options: &GltfOptions) -> Result<Self, SceneError> {
        convert::load_slice(Path::new("<memory>"), bytes, None, options)
    }

    /// The file played.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What the load accepted leniently (skins, morph targets, spot lights...).
    #[must_use]
    pub fn warnings(&self) -> &[SceneWarning] {
        &self.warnings
    }

    /// Frames of the animation at [`GLTF_FRAME_RATE`] (1 without one).
    #[must_use]
    pub fn frames(&self) -> u32 {
        if self.channels.is_empty() && self.weight_channels.is_empty() {
            1
        } else {
            (self.duration * GLTF_FRAME_RATE).ceil() as u32 + 1
        }
    }

    /// Scene time of `frame`.
    #[must_use]
    pub fn time_of(&self, frame: u32) -> f32 {
        frame as f32 / GLTF_FRAME_RATE
    }

    /// The resolution and default mode.
    #[must_use]
    pub fn settings(&self) -> RenderSettings {
        self.settings
    }

    /// The names of the file's animations, by index (empty when unnamed),
    /// for choosing one with [`GltfOptions::animation`].
    #[must_use]
    pub fn animation_names(&self) -> &[String] {
        &self.animation_names
    }

    /// The structure of the objects redefined every frame (`None`: the
    /// context's); [`GLTF_DEFORMING_ACCEL`] after loading.
    pub fn set_deforming_accel(&mut self, accel: Option<Accel>) -> Result<(), CoreError> {
        for d in self.deformers.iter().filter(|d| d.animated) {
            self.ctx.set_object_accel(d.object, accel)?;
        }
        Ok(())
    }

    /// What the last [`GltfPlayer::set_time`] spent deforming meshes before
    /// its commit (the commit's own figures are in its [`CommitStats`]).
    #[must_use]
    pub fn deform_times(&self) -> DeformTimes {
        self.deform_times
    }

    /// The scene's instances and objects by motion class.
    #[must_use]
    pub fn motion_classes(&self) -> MotionClasses {
        let deforming: Vec<&Deformer> = self.deformers.iter().filter(|d| d.animated).collect();
        MotionClasses {
            static_instances: self.static_instances,
            affine_instances: self.moving.len(),
            deforming_objects: deforming.len(),
            deforming_triangles: deforming
                .iter()
                .flat_map(|d| d.prims.iter())
                .map(deform::Prim::triangles)
                .sum(),
        }
    }

    /// `time` on the animation's loop: times past the end start again (the
    /// end itself is the last key).
    fn looped(&self, time: f32) -> f32 {
        if self.duration <= 0.0 {
            0.0
        } else if (0.0..=self.duration).contains(&time) {
            time
        } else {
            time.rem_euclid(self.duration)
        }
    }

    /// Every node's morph weights at `time`.
    fn weights(&self, time: f32) -> Vec<Vec<f32>> {
        let t = self.looped(time);
        let mut w = self.rest_weights.clone();
        for c in &self.weight_channels {
            w[c.node] = c.sample(t);
        }
        w
    }

    /// Every node's world transform at `time` (looping over the animation).
    fn world(&self, time: f32) -> Vec<Mat4> {
        let t = self.looped(time);
        let mut local = self.rest.clone();
        for c in &self.channels {
            local[c.node] = local[c.node].with(c, t);
        }
        let mut world = vec![Mat4::IDENTITY; local.len()];
        for &n in &self.world_order {
            let m = local[n].matrix();
            world[n] = self.parents[n].map_or(m, |p| world[p] * m);
        }
        world
    }

    /// Lights where their nodes are in `world` (the default light, when the
    /// file has none, at the camera at `time`).
    fn env_at(&self, world: &[Mat4], time: f32) -> Environment {
        let b = self.light_bounds;
        let lights = if self.lights.is_empty() {
            vec![PointLight {
                position: self.camera(time).from,
                color: Vec3::ONE,
            }]
        } else {
            self.lights
                .iter()
                .map(|l| {
                    let m = world[l.node];
                    let position = if l.directional {
                        let dir = m.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Y);
                        let r = if b.is_empty() { 100.0 } else { (b.max - b.min).length() };
                        let c = if b.is_empty() { Vec3::ZERO } else { b.center() };
                        c - dir * 100.0 * r
                    } else {
                        m.transform_point3(Vec3::ZERO)
                    };
                    PointLight {
                        position,
                        color: l.color,
                    }
                })
                .collect()
        };
        Environment {
            lights,
            ambient: Vec3::splat(0.1),
            background: Vec3::splat(0.2),
        }
    }

    /// Whether a light sits on an animated node (or, without lights, the
    /// default light on an animated camera's).
    fn lights_move(&self) -> bool {
        let moves = |n: usize| self.node_animated.get(n).copied().unwrap_or(false);
        if self.lights.is_empty() {
            self.camera.is_some_and(|(n, _, _)| moves(n))
        } else {
            self.lights.iter().any(|l| moves(l.node))
        }
    }

    /// Moves the animated instances to `time`, deforms the skinned and
    /// morphed meshes (in parallel on the context's pool) and commits.
    /// Lights on animated nodes move with them (the default light follows
    /// an animated camera).
    pub fn set_time(&mut self, time: f32) -> Result<CommitStats, SceneError> {
        let world = self.world(time);
        let core = |source| SceneError::Core {
            path: self.path.clone(),
            source,
        };
        for &(node, id) in &self.moving {
            self.ctx.set_instance_transform(id, world[node]).map_err(core)?;
        }
        if self.lights_move() {
            self.env = Arc::new(self.env_at(&world, time));
        }
        self.deform_times = DeformTimes::default();
        if self.deformers.iter().any(|d| d.animated) {
            let weights = self.weights(time);
            let pool = self.ctx.pool().map_err(core)?;
            for d in self.deformers.iter().filter(|d| d.animated) {
                let t0 = std::time::Instant::now();
                let shapes = pool.install(|| d.shapes(&world, &weights[d.node]));
                let t1 = std::time::Instant::now();
                self.deform_times.skin_ms += (t1 - t0).as_secs_f64() * 1e3;
                let defined = deform::define(&mut self.ctx, d.object, &d.prims, &shapes);
                self.deform_times.define_ms += t1.elapsed().as_secs_f64() * 1e3;
                defined.map_err(|(at, e)| SceneError::Invalid {
                    path: self.path.clone(),
                    what: format!("glTF {at}: {e}"),
                })?;
            }
        }
        self.ctx.commit().map_err(core)
    }

    /// The file's camera at `time` (its node's world transform looks down
    /// its -z axis), else a camera framing the scene's bounds.
    #[must_use]
    pub fn camera(&self, time: f32) -> Camera {
        let Some((node, yfov, znear)) = self.camera else {
            return self.framing;
        };
        let m = self.world(time)[node];
        let from = m.transform_point3(Vec3::ZERO);
        let ahead = m.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Z);
        let up = m.transform_vector3(Vec3::Y).normalize_or(Vec3::Y);
        Camera {
            from,
            at: from + ahead,
            up,
            fov_y_deg: yfov.to_degrees(),
            near: znear,
        }
    }
}
