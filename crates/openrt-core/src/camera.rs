//! The pinhole camera of NFF/AFF.

use glam::Vec3;
use openrt_accel::Ray;

use crate::CoreError;

/// A pinhole camera: eye, look-at point, up vector, vertical field of view
/// and near distance (NFF's `hither`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub from: Vec3,
    /// Point looked at.
    pub at: Vec3,
    /// Up direction (need not be orthogonal to the view direction).
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Primary rays start this far (in view-direction units) from the eye.
    pub near: f32,
}

impl Default for Camera {
    fn default() -> Self {
        Self {
            from: Vec3::new(0.0, 0.0, 5.0),
            at: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            near: 0.0,
        }
    }
}

/// A camera prepared for an image size.
#[derive(Clone, Copy, Debug)]
pub struct CameraRays {
    from: Vec3,
    fwd: Vec3,
    right: Vec3,
    up: Vec3,
    width: u32,
    height: u32,
    near: f32,
}

impl Camera {
    /// Checks the camera and prepares ray generation for a `width` x `height` image.
    pub fn rays(&self, width: u32, height: u32) -> Result<CameraRays, CoreError> {
        let bad = |what: String| Err(CoreError::NonFinite { call: "camera", what });
        if !(self.from.is_finite() && self.at.is_finite() && self.up.is_finite() && self.near.is_finite()) {
            return bad(format!("camera {self:?}"));
        }
        if !(self.fov_y_deg > 0.0 && self.fov_y_deg < 180.0) {
            return bad(format!(
                "field of view {} (must be in (0, 180) degrees)",
                self.fov_y_deg
            ));
        }
        if width == 0 || height == 0 {
            return bad(format!("image size {width}x{height}"));
        }
        let Some(fwd) = (self.at - self.from).try_normalize() else {
            return bad("view direction (from == at)".into());
        };
        let Some(right) = fwd.cross(self.up).try_normalize() else {
            return bad("up vector (parallel to the view direction)".into());
        };
        let up = right.cross(fwd);
        let tan = (self.fov_y_deg.to_radians() * 0.5).tan();
        let aspect = width as f32 / height as f32;
        Ok(CameraRays {
            from: self.from,
            fwd,
            right: right * tan * aspect,
            up: up * tan,
            width,
            height,
            near: self.near.max(0.0),
        })
    }
}

impl CameraRays {
    /// The primary ray through the centre of pixel `(x, y)` (y = 0 at the top).
    /// Its direction has unit length along the view axis, so `near` is a
    /// distance along that axis.
    #[must_use]
    pub fn ray(&self, x: u32, y: u32) -> Ray {
        self.ray_at(x, y, 0.5, 0.5)
    }

    /// The primary ray through the point `(ox, oy)` of pixel `(x, y)`
    /// (`(0.5, 0.5)` is its centre: [`CameraRays::ray`]).
    #[must_use]
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub fn ray_at(&self, x: u32, y: u32, ox: f32, oy: f32) -> Ray {
        let u = (x as f32 + ox) / self.width as f32 * 2.0 - 1.0;
        let v = 1.0 - (y as f32 + oy) / self.height as f32 * 2.0;
        Ray::new_inline(
            self.from,
            self.fwd + self.right * u + self.up * v,
            self.near,
            f32::INFINITY,
        )
    }

    /// The angle one pixel spans at the centre of the image (radians, small
    /// angle): the spread of a primary ray cone.
    #[must_use]
    pub fn pixel_spread(&self) -> f32 {
        2.0 * self.up.length() / self.height as f32
    }

    /// Image width.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Image height.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }
}
