//! The pinhole camera of NFF/AFF.

use glam::Vec3;
use openrt_accel::{Ray, rays_from_lanes};
use wide::f32x4;

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

    /// [`CameraRays::ray_at`] of a packet's pixels, four lanes at a time:
    /// `out[l]` becomes the ray through the point `(ox, oy)` of pixel
    /// `pixels[l]` for each lane `l` of `lanes` (the other rays are left as
    /// they are), the same bits ([`openrt_accel::rays_from_lanes`]; tested).
    /// `pixels` and `out` hold a multiple of four lanes.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub fn rays_at(&self, pixels: &[(u32, u32)], lanes: u32, ox: f32, oy: f32, out: &mut [Ray]) {
        let s = f32x4::splat;
        let (width, height) = (s(self.width as f32), s(self.height as f32));
        for (c, (four, rays)) in pixels.chunks_exact(4).zip(out.chunks_exact_mut(4)).enumerate() {
            let bits = (lanes >> (4 * c)) & 0xf;
            if bits == 0 {
                continue;
            }
            let x = f32x4::from(std::array::from_fn::<f32, 4, _>(|i| four[i].0 as f32));
            let y = f32x4::from(std::array::from_fn::<f32, 4, _>(|i| four[i].1 as f32));
            let u = (x + s(ox)) / width * s(2.0) - s(1.0);
            let v = s(1.0) - (y + s(oy)) / height * s(2.0);
            let (f, r, up) = (self.fwd, self.right, self.up);
            let dir = [
                s(f.x) + s(r.x) * u + s(up.x) * v,
                s(f.y) + s(r.y) * u + s(up.y) * v,
                s(f.z) + s(r.z) * u + s(up.z) * v,
            ];
            let from = [s(self.from.x), s(self.from.y), s(self.from.z)];
            rays_from_lanes(rays, bits, from, dir, self.near, f32::INFINITY);
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    fn vec(rng: &mut SmallRng, scale: f32) -> Vec3 {
        Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ) * scale
    }

    /// A packet's camera rays are `ray_at`'s bits lane by lane (every field,
    /// the sign of zeros included: compared through `Debug`), on random
    /// cameras, image sizes from 1x1 up, pixels on the image's edges and
    /// axis-aligned views (zero direction components), with any lanes
    /// masked off (those rays left as they were).
    #[test]
    fn packet_camera_rays_are_the_single_rays() {
        let mut rng = SmallRng::seed_from_u64(0xca_3e7a);
        for round in 0..3_000 {
            let scale = 10f32.powi(rng.random_range(-3..5));
            let from = vec(&mut rng, scale);
            let at = if round % 4 == 0 {
                from + Vec3::Z * scale
            } else {
                from + vec(&mut rng, scale)
            };
            let camera = Camera {
                from,
                at,
                up: if round % 3 == 0 { Vec3::Y } else { vec(&mut rng, 1.0) },
                fov_y_deg: rng.random_range(1.0..170.0),
                near: rng.random_range(0.0..1.0),
            };
            let (w, h) = (rng.random_range(1..2000), rng.random_range(1..2000));
            let Ok(cam) = camera.rays(w, h) else {
                continue;
            };
            let pixel = |rng: &mut SmallRng| match rng.random_range(0..4) {
                0 => (0, h - 1),
                1 => (w - 1, 0),
                2 => (w / 2, h / 2),
                _ => (rng.random_range(0..w), rng.random_range(0..h)),
            };
            let pixels: [(u32, u32); 16] = std::array::from_fn(|_| pixel(&mut rng));
            let (ox, oy) = (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0));
            let lanes = rng.random_range(0..1u32 << 16);
            let keep = cam.ray(0, 0);
            let mut out = [keep; 16];
            cam.rays_at(&pixels, lanes, ox, oy, &mut out);
            for (l, got) in out.iter().enumerate() {
                let want = if lanes & (1 << l) != 0 {
                    cam.ray_at(pixels[l].0, pixels[l].1, ox, oy)
                } else {
                    keep
                };
                assert_eq!(format!("{got:?}"), format!("{want:?}"), "round {round}, lane {l}");
            }
        }
    }
}
