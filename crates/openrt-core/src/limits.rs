//! The renderer's limits. Each is checked where the value enters (the
//! settings of a frame, the size of the render pool), and breaking one gives
//! [`CoreError::Limit`](crate::CoreError::Limit), which states it.

use crate::CoreError;

/// Longest image side, in pixels, for a frame or a scene's resolution.
pub const MAX_IMAGE_SIDE: u32 = 16_384;

/// Most pixels in one image: 2^25, a little more than 8K UHD (7680 x 4320).
/// The frame buffer of such an image takes 400 MB.
pub const MAX_IMAGE_PIXELS: u64 = 1 << 25;

/// Deepest reflection/refraction recursion. Each level can double the rays
/// of a pixel (a reflection and a refraction per hit), so this also bounds
/// the work of one pixel.
pub const MAX_SHADE_DEPTH: u32 = 16;

/// Most samples per pixel in one frame.
pub const MAX_SPP: u32 = 4096;

/// Most render threads in one pool.
pub const MAX_THREADS: usize = 256;

/// Stack of each render thread: [`MAX_SHADE_DEPTH`] levels of packet
/// shading need about 1 MiB (measured by the `deepest_recursion_fits` test), so
/// this leaves a wide margin.
pub const RENDER_STACK_BYTES: usize = 8 << 20;

/// Largest |coordinate| of a vertex in its object, and of an instance's
/// world box. The watertight triangle test multiplies three coordinates
/// (relative to the ray origin); below this bound the products stay far
/// from f32 overflow (2^128 ~ 3.4e38), and boxes stay finite after
/// transforms.
pub const MAX_COORDINATE: f32 = 1e12;

/// `true` when every component of `p` lies within [`MAX_COORDINATE`].
#[must_use]
pub fn within_coordinate_limit(p: glam::Vec3) -> bool {
    p.abs().max_element() <= MAX_COORDINATE
}

/// Checks an image size against [`MAX_IMAGE_SIDE`] and [`MAX_IMAGE_PIXELS`];
/// `call` names the caller in the error.
pub fn check_image_size(call: &'static str, width: u32, height: u32) -> Result<(), CoreError> {
    let limit = |what: &str, value: u64, limit: u64| {
        Err(CoreError::Limit {
            call,
            what: what.into(),
            value,
            limit,
        })
    };
    if width == 0 || height == 0 {
        return Err(CoreError::Limit {
            call,
            what: format!("image size {width}x{height}: the smallest side"),
            value: 0,
            limit: 1,
        });
    }
    let side = width.max(height);
    if side > MAX_IMAGE_SIDE {
        return limit("image side in pixels", u64::from(side), u64::from(MAX_IMAGE_SIDE));
    }
    let pixels = u64::from(width) * u64::from(height);
    if pixels > MAX_IMAGE_PIXELS {
        return limit("image pixel count", pixels, MAX_IMAGE_PIXELS);
    }
    Ok(())
}

/// Checks a shading depth against [`MAX_SHADE_DEPTH`].
pub fn check_depth(call: &'static str, depth: u32) -> Result<(), CoreError> {
    if depth > MAX_SHADE_DEPTH {
        return Err(CoreError::Limit {
            call,
            what: "reflection/refraction depth".into(),
            value: u64::from(depth),
            limit: u64::from(MAX_SHADE_DEPTH),
        });
    }
    Ok(())
}

/// Checks a sample count against 1 and [`MAX_SPP`].
pub fn check_spp(call: &'static str, spp: u32) -> Result<(), CoreError> {
    if spp == 0 || spp > MAX_SPP {
        return Err(CoreError::Limit {
            call,
            what: "samples per pixel (at least 1)".into(),
            value: u64::from(spp),
            limit: u64::from(MAX_SPP),
        });
    }
    Ok(())
}

/// Checks a thread count against 1 and [`MAX_THREADS`].
pub fn check_threads(call: &'static str, threads: usize) -> Result<(), CoreError> {
    if threads == 0 || threads > MAX_THREADS {
        return Err(CoreError::Limit {
            call,
            what: "thread count (at least 1)".into(),
            value: threads as u64,
            limit: MAX_THREADS as u64,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_limits_hold_at_the_edges() {
        assert!(check_image_size("t", 1, 1).is_ok());
        assert!(check_image_size("t", MAX_IMAGE_SIDE, 2048).is_ok());
        assert!(check_image_size("t", 0, 5).is_err());
        assert!(check_image_size("t", 5, 0).is_err());
        let e = check_image_size("render", MAX_IMAGE_SIDE + 1, 1).unwrap_err();
        assert!(e.to_string().contains(&MAX_IMAGE_SIDE.to_string()), "{e}");
        assert!(e.to_string().starts_with("render:"), "{e}");
        // Sides within the limit, pixels over the budget.
        let e = check_image_size("t", MAX_IMAGE_SIDE, MAX_IMAGE_SIDE).unwrap_err();
        assert!(e.to_string().contains(&MAX_IMAGE_PIXELS.to_string()), "{e}");
        assert!(check_image_size("t", u32::MAX, u32::MAX).is_err());
    }

    #[test]
    fn depth_and_thread_limits() {
        assert!(check_depth("t", MAX_SHADE_DEPTH).is_ok());
        assert!(check_depth("t", MAX_SHADE_DEPTH + 1).is_err());
        assert!(check_depth("t", u32::MAX).is_err());
        assert!(check_threads("t", 1).is_ok());
        assert!(check_threads("t", MAX_THREADS).is_ok());
        assert!(check_threads("t", 0).is_err());
        assert!(check_threads("t", MAX_THREADS + 1).is_err());
        assert!(check_threads("t", usize::MAX).is_err());
        assert!(check_spp("t", 1).is_ok() && check_spp("t", MAX_SPP).is_ok());
        assert!(check_spp("t", 0).is_err() && check_spp("t", MAX_SPP + 1).is_err());
    }
}
