//! The built-in default scene (`builtin/room.ron`; `scenes/room.ron` links to it).

use std::path::Path;

use crate::{LoadedScene, SceneError, load_ron_str};

/// RON text of the default scene: a room with a mirror sphere, a glass
/// sphere and a box, lit by two lights; it needs no texture files.
pub const DEFAULT_SCENE_RON: &str = include_str!("../builtin/room.ron");

/// Builds the default scene.
pub fn default_scene() -> Result<LoadedScene, SceneError> {
    load_ron_str(DEFAULT_SCENE_RON, Path::new("<built-in room.ron>"))
}
