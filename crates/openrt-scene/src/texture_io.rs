//! Texture files (binary/ASCII PPM and PNG) through the `image` crate.

use std::path::Path;

use glam::Vec3;
use openrt_core::Texture;

use crate::SceneError;
use crate::limits::{MAX_TEXTURE_SIDE, MAX_TEXTURE_TEXELS};

/// Loads an RGB texture; errors name the texture file and the scene using it.
pub fn load_texture(texture: &Path, used_by: &Path) -> Result<Texture, SceneError> {
    let bytes = crate::limits::read_file(texture).map_err(|e| SceneError::Texture {
        texture: texture.to_path_buf(),
        path: used_by.to_path_buf(),
        msg: e.to_string(),
    })?;
    decode_texture(&bytes, texture, used_by)
}

/// Decodes the bytes of a PPM or PNG texture (from `texture`, used by
/// `used_by`: both only name the files in errors), within
/// [`MAX_TEXTURE_SIDE`] and [`MAX_TEXTURE_TEXELS`].
pub fn decode_texture(bytes: &[u8], texture: &Path, used_by: &Path) -> Result<Texture, SceneError> {
    let err = |msg: String| SceneError::Texture {
        texture: texture.to_path_buf(),
        path: used_by.to_path_buf(),
        msg,
    };
    let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| err(format!("cannot read: {e}")))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(MAX_TEXTURE_SIDE);
    limits.max_image_height = Some(MAX_TEXTURE_SIDE);
    limits.max_alloc = Some(MAX_TEXTURE_TEXELS * 4);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| match e {
        image::ImageError::Limits(l) => err(format!(
            "beyond the texture limits ({MAX_TEXTURE_SIDE} texels a side, {MAX_TEXTURE_TEXELS} texels): {l}"
        )),
        e => err(format!("not a PPM or PNG image: {e}")),
    })?;
    let (w, h) = (img.width(), img.height());
    if u64::from(w) * u64::from(h) > MAX_TEXTURE_TEXELS {
        return Err(err(format!(
            "{w}x{h} texels is beyond the limit of {MAX_TEXTURE_TEXELS} texels (MAX_TEXTURE_TEXELS)"
        )));
    }
    let rgb = img.to_rgb8();
    let texels = rgb
        .pixels()
        .map(|p| Vec3::new(f32::from(p[0]), f32::from(p[1]), f32::from(p[2])) / 255.0)
        .collect();
    Texture::new(w as usize, h as usize, texels).ok_or_else(|| err(format!("unusable size {w}x{h}")))
}
