//! Texture files (binary/ASCII PPM and PNG) through the `image` crate.

use std::path::Path;

use glam::Vec3;
use openrt_core::Texture;

use crate::SceneError;

/// Loads an RGB texture; errors name the texture file and the scene using it.
pub fn load_texture(texture: &Path, used_by: &Path) -> Result<Texture, SceneError> {
    let err = |msg: String| SceneError::Texture {
        texture: texture.to_path_buf(),
        path: used_by.to_path_buf(),
        msg,
    };
    let bytes = std::fs::read(texture).map_err(|e| err(format!("cannot read: {e}")))?;
    let img = image::load_from_memory(&bytes).map_err(|e| err(format!("not a PPM or PNG image: {e}")))?;
    let rgb = img.to_rgb8();
    let (w, h) = rgb.dimensions();
    let texels = rgb
        .pixels()
        .map(|p| Vec3::new(f32::from(p[0]), f32::from(p[1]), f32::from(p[2])) / 255.0)
        .collect();
    Texture::new(w as usize, h as usize, texels).ok_or_else(|| err(format!("unusable size {w}x{h}")))
}
