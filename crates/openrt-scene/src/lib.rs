//! # openrt-scene
//!
//! Scene formats for OpenRT-rs, all driving the `openrt-core` API:
//! - a versioned RON format ([`load_ron`], reference in `docs/SCENE-FORMAT.md`);
//! - BART's AFF format ([`aff`]): reader, keyframe animation, player;
//! - texture files (PPM and PNG) through the `image` crate;
//! - the built-in default scene ([`default_scene`]).
//!
//! ```
//! let scene = openrt_scene::default_scene().unwrap();
//! assert!(scene.ctx.scene().instances().len() > 3);
//! ```

pub mod aff;
mod builtin;
mod error;
pub mod generate;
mod loader;
mod player;
mod ron_format;
mod shapes;
mod texture_io;

pub use builtin::{DEFAULT_SCENE_RON, default_scene};
pub use error::SceneError;
pub use loader::{LoadedScene, RonScene, load_ron, load_ron_any, load_ron_str};
pub use player::ScenePlayer;
pub use ron_format::{
    AnimationDesc, BartDesc, CameraDesc, CameraKeys, GeneratorDesc, InstanceDesc, InstanceKeys, LightDesc,
    MaterialDesc, ObjectDesc, SUPPORTED_VERSIONS, SceneFile, TransformOp,
};
pub use shapes::{emit_box, emit_sphere};
pub use texture_io::load_texture;
