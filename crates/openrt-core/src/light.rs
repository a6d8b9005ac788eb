//! Lights and the environment of a frame.

use glam::Vec3;

/// A point light (NFF `l`): no falloff, as in NFF/AFF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// Position.
    pub position: Vec3,
    /// Colour (intensity per channel).
    pub color: Vec3,
}

/// Lights, ambient light and background colour.
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// Point lights.
    pub lights: Vec<PointLight>,
    /// Ambient light (multiplies each material's ambient colour).
    pub ambient: Vec3,
    /// Colour of rays that hit nothing.
    pub background: Vec3,
}

impl Default for Environment {
    fn default() -> Self {
        Self {
            lights: Vec::new(),
            ambient: Vec3::splat(0.1),
            background: Vec3::ZERO,
        }
    }
}
