//! One interface over every scene kind: static RON, animated RON, AFF and glTF.

use std::path::Path;
use std::sync::Arc;

use openrt_core::{Camera, CommitStats, Context, Environment, RenderSettings};

use crate::aff::AffPlayer;
use crate::gltf_scene::{GltfOptions, GltfPlayer, MotionClasses};
use crate::{LoadedScene, RonScene, SceneError, SceneWarning, default_scene, load_ron_any};

/// A scene that can be stepped through time.
pub enum ScenePlayer {
    /// A RON scene (static or animated).
    Ron(Box<LoadedScene>),
    /// A BART AFF scene.
    Aff(Box<AffPlayer>),
    /// A glTF 2.0 scene (`.gltf` or `.glb`).
    Gltf(Box<GltfPlayer>),
}

impl ScenePlayer {
    /// Opens a scene by extension (`.aff`, `.ron`, `.gltf` or `.glb`); `None`
    /// opens the built-in default scene.
    pub fn open(path: Option<&Path>) -> Result<Self, SceneError> {
        Self::open_with(path, &GltfOptions::default())
    }

    /// [`ScenePlayer::open`] with the scene, animation and camera a glTF
    /// file plays; choosing them for another kind of scene is an error.
    pub fn open_with(path: Option<&Path>, gltf: &GltfOptions) -> Result<Self, SceneError> {
        let Some(path) = path else {
            if *gltf != GltfOptions::default() {
                return Err(SceneError::Invalid {
                    path: "<built-in scene>".into(),
                    what: "--scene, --animation and --camera choose within glTF files only".into(),
                });
            }
            return Ok(Self::Ron(Box::new(default_scene()?)));
        };
        let is_gltf = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"));
        if is_gltf {
            return Ok(Self::Gltf(Box::new(GltfPlayer::load_with(path, gltf)?)));
        }
        if *gltf != GltfOptions::default() {
            return Err(SceneError::Invalid {
                path: path.to_path_buf(),
                what: "--scene, --animation and --camera choose within glTF files only".into(),
            });
        }
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("aff") => Ok(Self::Aff(Box::new(AffPlayer::load(path)?))),
            Some("gltf" | "glb") => Ok(Self::Gltf(Box::new(GltfPlayer::load(path)?))),
            Some("ron") => Ok(match load_ron_any(path)? {
                RonScene::Scene(s) => Self::Ron(s),
                RonScene::Bart(a) => Self::Aff(a),
                RonScene::Gltf(g) => Self::Gltf(g),
            }),
            _ => Err(SceneError::Invalid {
                path: path.to_path_buf(),
                what: "unknown scene type: expected a .ron, .aff, .gltf or .glb file".into(),
            }),
        }
    }

    /// [`ScenePlayer::open`], with every warning an error: the first one
    /// (such as an AFF key that goes back in time) fails the load.
    pub fn open_strict(path: Option<&Path>) -> Result<Self, SceneError> {
        Self::open_strict_with(path, &GltfOptions::default())
    }

    /// [`ScenePlayer::open_with`], with every warning an error.
    pub fn open_strict_with(path: Option<&Path>, gltf: &GltfOptions) -> Result<Self, SceneError> {
        let p = Self::open_with(path, gltf)?;
        match p.warnings().first() {
            Some(w) => Err(w.clone().into_error()),
            None => Ok(p),
        }
    }

    /// What the load accepted leniently, with file and line (for RON
    /// scenes, which are read strictly, those of the glTF files they use).
    #[must_use]
    pub fn warnings(&self) -> &[SceneWarning] {
        match self {
            Self::Ron(s) => s.warnings(),
            Self::Aff(a) => &a.scene().warnings,
            Self::Gltf(g) => g.warnings(),
        }
    }

    /// The scene's instances and objects by the paper's motion classes.
    #[must_use]
    pub fn motion_classes(&self) -> MotionClasses {
        match self {
            Self::Ron(s) => s.motion_classes(),
            Self::Aff(a) => a.motion_classes(),
            Self::Gltf(g) => g.motion_classes(),
        }
    }

    /// The names of a glTF file's animations, by index (empty for other scenes).
    #[must_use]
    pub fn animation_names(&self) -> Vec<String> {
        match self {
            Self::Gltf(g) => g.animation_names().to_vec(),
            _ => Vec::new(),
        }
    }

    /// Number of frames.
    #[must_use]
    pub fn frames(&self) -> u32 {
        match self {
            Self::Ron(s) => s.animation.map_or(1, |a| a.frames),
            Self::Aff(a) => a.frames(),
            Self::Gltf(g) => g.frames(),
        }
    }

    /// Scene time of a frame.
    #[must_use]
    pub fn time_of(&self, frame: u32) -> f32 {
        match self {
            Self::Ron(s) => s.animation.map_or(0.0, |a| a.time(frame)),
            Self::Aff(a) => a.time_of(frame),
            Self::Gltf(g) => g.time_of(frame),
        }
    }

    /// First and last time of the animation.
    #[must_use]
    pub fn time_range(&self) -> (f32, f32) {
        (self.time_of(0), self.time_of(self.frames().saturating_sub(1)))
    }

    /// Moves the scene to `time` and commits.
    pub fn set_time(&mut self, time: f32) -> Result<CommitStats, SceneError> {
        match self {
            Self::Ron(s) => s.set_time(time),
            Self::Aff(a) => a.set_time(time),
            Self::Gltf(g) => g.set_time(time),
        }
    }

    /// The scene's camera at `time`.
    #[must_use]
    pub fn camera(&self, time: f32) -> Camera {
        match self {
            Self::Ron(s) => s.camera_at(time),
            Self::Aff(a) => a.camera(time),
            Self::Gltf(g) => g.camera(time),
        }
    }

    /// Lights, ambient light and background.
    #[must_use]
    pub fn env(&self) -> Arc<Environment> {
        match self {
            Self::Ron(s) => Arc::clone(&s.env),
            Self::Aff(a) => Arc::clone(&a.env),
            Self::Gltf(g) => Arc::clone(&g.env),
        }
    }

    /// The context holding the scene.
    #[must_use]
    pub fn ctx(&self) -> &Context {
        match self {
            Self::Ron(s) => &s.ctx,
            Self::Aff(a) => &a.ctx,
            Self::Gltf(g) => &g.ctx,
        }
    }

    /// The context, mutably (to change the scene interactively).
    pub fn ctx_mut(&mut self) -> &mut Context {
        match self {
            Self::Ron(s) => &mut s.ctx,
            Self::Aff(a) => &mut a.ctx,
            Self::Gltf(g) => &mut g.ctx,
        }
    }

    /// The structure of every object, deforming glTF objects included
    /// (which otherwise keep [`GLTF_DEFORMING_ACCEL`](crate::GLTF_DEFORMING_ACCEL)).
    pub fn set_accel(&mut self, accel: openrt_core::Accel) -> Result<(), SceneError> {
        self.ctx_mut().set_accel(accel);
        if let Self::Gltf(g) = self {
            g.set_deforming_accel(None).map_err(|source| SceneError::Core {
                path: "<glTF scene>".into(),
                source,
            })?;
        }
        Ok(())
    }

    /// The resolution the scene asks for, default mode and depth.
    #[must_use]
    pub fn settings(&self) -> RenderSettings {
        match self {
            Self::Ron(s) => s.settings,
            Self::Aff(a) => a.settings(),
            Self::Gltf(g) => g.settings(),
        }
    }
}
