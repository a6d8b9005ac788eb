//! Camera controls: orbit, pan, zoom and fly.

use glam::{Quat, Vec3};
use openrt_core::Camera;

/// Moves `cam` by mouse and keyboard input; all amounts are relative to the
/// distance from the eye to the look-at point, so controls feel the same at
/// any scene scale.
pub fn orbit(cam: &mut Camera, dx: f32, dy: f32) {
    let offset = cam.from - cam.at;
    let up = cam.up.try_normalize().unwrap_or(Vec3::Y);
    let yaw = Quat::from_axis_angle(up, -dx * 0.01);
    let right = offset.cross(up).try_normalize().unwrap_or(Vec3::X);
    let pitch = Quat::from_axis_angle(right, -dy * 0.01);
    let new = pitch * (yaw * offset);
    // Keep away from the poles.
    if new.normalize().dot(up).abs() < 0.98 {
        cam.from = cam.at + new;
    } else {
        cam.from = cam.at + yaw * offset;
    }
}

pub fn pan(cam: &mut Camera, dx: f32, dy: f32, viewport_height: f32) {
    let dist = (cam.from - cam.at).length();
    let fwd = (cam.at - cam.from).normalize_or(Vec3::NEG_Z);
    let right = fwd.cross(cam.up).normalize_or(Vec3::X);
    let up = right.cross(fwd);
    let scale = 2.0 * dist * (cam.fov_y_deg.to_radians() * 0.5).tan() / viewport_height.max(1.0);
    let d = (-right * dx + up * dy) * scale;
    cam.from += d;
    cam.at += d;
}

pub fn zoom(cam: &mut Camera, scroll: f32) {
    let offset = cam.from - cam.at;
    let f = (-scroll * 0.002).exp();
    let new = offset * f;
    if new.length() > 1e-4 * offset.length().max(1e-6) {
        cam.from = cam.at + new;
    }
}

/// Flies along the view (`forward`), sideways (`right`) and up, in units of
/// the eye-to-target distance per second.
pub fn fly(cam: &mut Camera, forward: f32, right: f32, up: f32, dt: f32) {
    let dist = (cam.from - cam.at).length().max(1e-3);
    let fwd = (cam.at - cam.from).normalize_or(Vec3::NEG_Z);
    let r = fwd.cross(cam.up).normalize_or(Vec3::X);
    let d = (fwd * forward + r * right + cam.up.normalize_or(Vec3::Y) * up) * dist * dt;
    cam.from += d;
    cam.at += d;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orbit_keeps_the_distance_and_zoom_changes_it() {
        let mut c = Camera {
            from: Vec3::new(0.0, 1.0, 5.0),
            ..Camera::default()
        };
        let d0 = (c.from - c.at).length();
        orbit(&mut c, 40.0, 10.0);
        assert!(((c.from - c.at).length() - d0).abs() < 1e-4);
        zoom(&mut c, 100.0);
        assert!((c.from - c.at).length() < d0);
        let at = c.at;
        pan(&mut c, 10.0, 0.0, 400.0);
        assert_ne!(c.at, at);
        fly(&mut c, 1.0, 0.0, 0.0, 0.1);
        assert!(c.from.is_finite() && c.at.is_finite());
    }
}
