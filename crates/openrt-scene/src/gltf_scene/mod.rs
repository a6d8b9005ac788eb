//! glTF 2.0 scenes (`.gltf` with external or embedded buffers, `.glb`) on
//! the `gltf` crate, played through the paper's motion classes: every mesh
//! is one object, instanced once per node that uses it; nodes that no
//! animation moves keep their instances' transforms (static objects, SAH
//! trees built once); nodes moved by translation, rotation or scale
//! channels, or under such a node, get a new instance transform every frame
//! (affine motion: only the top level is rebuilt).
//!
//! The mapping onto the Whitted model, and what is not played yet, is in
//! docs/SCENE-FORMAT.md ("glTF 2.0"); each thing left out is a warning
//! (`openrt --strict` makes it an error), never a silent change.

mod animation;
mod convert;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat4, Vec3};
use openrt_core::{Camera, CommitStats, Context, Environment, InstanceId, RenderSettings};

use crate::{SceneError, SceneWarning};
use animation::{Channel, Trs};

/// glTF extensions a file may require and this loader reads.
pub const GLTF_SUPPORTED_REQUIRED: &[&str] = &["KHR_lights_punctual"];

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
    /// Instances of the nodes that animation moves (directly or through an ancestor).
    moving: Vec<(usize, InstanceId)>,
    /// The played animation's channels and its length in seconds.
    channels: Vec<Channel>,
    duration: f32,
    /// The camera: its node, vertical field of view (radians) and near plane;
    /// `None` frames the scene.
    camera: Option<(usize, f32, f32)>,
    framing: Camera,
    /// How many objects are static, and how many instances move.
    static_instances: usize,
}

impl GltfPlayer {
    /// Loads `path` (`.gltf` or `.glb`), its default scene (else its first)
    /// and its first animation, and commits the scene at time 0.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        convert::load(path)
    }

    /// A glTF or GLB file held in memory (buffers and images embedded:
    /// external files are refused); errors name `<memory>`.
    pub fn from_slice(bytes: &[u8]) -> Result<Self, SceneError> {
        convert::load_slice(Path::new("<memory>"), bytes, None)
    }

    /// What the load accepted leniently (skins, morph targets, spot lights...).
    #[must_use]
    pub fn warnings(&self) -> &[SceneWarning] {
        &self.warnings
    }

    /// Frames of the animation at [`GLTF_FRAME_RATE`] (1 without one).
    #[must_use]
    pub fn frames(&self) -> u32 {
        if self.channels.is_empty() {
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

    /// Instances by motion class: static, and moved by the animation.
    #[must_use]
    pub fn motion_classes(&self) -> (usize, usize) {
        (self.static_instances, self.moving.len())
    }

    /// Every node's world transform at `time` (looping over the animation).
    fn world(&self, time: f32) -> Vec<Mat4> {
        // Looping: times past the end start again (the end itself is the last key).
        let t = if self.duration <= 0.0 {
            0.0
        } else if (0.0..=self.duration).contains(&time) {
            time
        } else {
            time.rem_euclid(self.duration)
        };
        let mut local = self.rest.clone();
        for c in &self.channels {
            local[c.node] = local[c.node].with(c, t);
        }
        let mut world = vec![Mat4::IDENTITY; local.len()];
        for &n in &self.order {
            let m = local[n].matrix();
            world[n] = self.parents[n].map_or(m, |p| world[p] * m);
        }
        world
    }

    /// Moves the animated instances to `time` and commits.
    pub fn set_time(&mut self, time: f32) -> Result<CommitStats, SceneError> {
        let world = self.world(time);
        let core = |source| SceneError::Core {
            path: self.path.clone(),
            source,
        };
        for &(node, id) in &self.moving {
            self.ctx.set_instance_transform(id, world[node]).map_err(core)?;
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
