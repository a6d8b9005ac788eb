//! Surface materials as in NFF/AFF.

use glam::Vec3;

use crate::TextureId;

/// A Phong/Whitted material: the NFF/AFF `fm` parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Ambient reflectance.
    pub ambient: Vec3,
    /// Diffuse reflectance.
    pub diffuse: Vec3,
    /// Specular reflectance (also the mirror reflection weight).
    pub specular: Vec3,
    /// Phong exponent.
    pub shininess: f32,
    /// Light the surface gives off itself, added unlit (glTF's
    /// `emissiveFactor`, times `emission_texture` when there is one; zero
    /// for NFF/AFF materials).
    pub emission: Vec3,
    /// Transmission weight (0 = opaque).
    pub transmission: f32,
    /// Index of refraction.
    pub ior: f32,
    /// Texture multiplying the ambient and diffuse colours.
    pub texture: Option<TextureId>,
    /// Texture multiplying the emission (glTF's `emissiveTexture`).
    pub emission_texture: Option<TextureId>,
    /// One-sided surface (NFF polygons): rays reaching its back side pass
    /// through it. Shadow rays treat every surface as opaque.
    pub one_sided: bool,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            ambient: Vec3::splat(0.1),
            diffuse: Vec3::splat(0.8),
            specular: Vec3::ZERO,
            shininess: 0.0,
            emission: Vec3::ZERO,
            transmission: 0.0,
            ior: 1.0,
            texture: None,
            emission_texture: None,
            one_sided: false,
        }
    }
}

impl Material {
    /// `true` when every number is finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.ambient.is_finite()
            && self.diffuse.is_finite()
            && self.specular.is_finite()
            && self.shininess.is_finite()
            && self.emission.is_finite()
            && self.transmission.is_finite()
            && self.ior.is_finite()
    }
}
