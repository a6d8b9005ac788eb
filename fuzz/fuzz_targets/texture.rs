//! PPM and PNG textures through the `image` crate and the texture limits;
//! a texture that loads samples to finite colours.

#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(t) = openrt_scene::decode_texture(data, Path::new("fuzz.ppm"), Path::new("fuzz.aff")) {
        for uv in [(0.0, 0.0), (0.5, 0.5), (-3.25, 7.5), (1e7, -1e7)] {
            assert!(t.sample(glam::Vec2::new(uv.0, uv.1)).is_finite());
        }
    }
});
