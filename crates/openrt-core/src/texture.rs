//! Textures: RGB images sampled with repeat addressing and bilinear filtering.

use glam::{Vec2, Vec3};

/// An RGB texture in linear `[0, 1]` values, row 0 at the top (v = 0 at the top row,
/// as NFF/AFF texture coordinates use it).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: usize,
    height: usize,
    texels: Vec<Vec3>,
}

impl Texture {
    /// A texture from `width * height` texels, row by row; `None` if the
    /// sizes do not match, a size is zero, or a texel is not finite.
    #[must_use]
    pub fn new(width: usize, height: usize, texels: Vec<Vec3>) -> Option<Self> {
        (width > 0 && height > 0 && texels.len() == width * height && texels.iter().all(|t| t.is_finite()))
            .then_some(Self { width, height, texels })
    }

    /// Width in texels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in texels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    fn texel(&self, x: usize, y: usize) -> Vec3 {
        self.texels[y * self.width + x]
    }

    /// Bilinear sample at `uv` with repeat addressing (any `uv`, also far
    /// outside `[0, 1]`; non-finite coordinates sample texel (0, 0)).
    #[must_use]
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        if !uv.is_finite() {
            return self.texels[0];
        }
        // Texel centres at half-integers; wrap before scaling to keep precision.
        let u = uv.x - uv.x.floor();
        let v = uv.y - uv.y.floor();
        let x = u * self.width as f32 - 0.5;
        let y = v * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (xi, yi) = (x0 as i64, y0 as i64);
        let (w, h) = (self.width as i64, self.height as i64);
        let (xa, xb) = (wrap(xi, w), wrap(xi + 1, w));
        let (ya, yb) = (wrap(yi, h), wrap(yi + 1, h));
        let top = self.texel(xa, ya).lerp(self.texel(xb, ya), fx);
        let bottom = self.texel(xa, yb).lerp(self.texel(xb, yb), fx);
        top.lerp(bottom, fy)
    }
}

/// `i` wrapped into `[0, n)` (repeat addressing).
///
/// PERF: a texel index is at most one period outside (the coordinate was
/// wrapped into `[0, 1]` first), so one comparison replaces the integer
/// division of `rem_euclid` (four per bilinear sample were 10% of a textured
/// frame); anything farther still takes `rem_euclid`.
#[inline]
fn wrap(i: i64, n: i64) -> usize {
    let r = if i < 0 {
        i + n
    } else if i >= n {
        i - n
    } else {
        i
    };
    if (0..n).contains(&r) {
        r as usize
    } else {
        i.rem_euclid(n) as usize
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn wrapping_equals_the_euclidean_remainder() {
        for n in 1..6i64 {
            for i in -3 * n..3 * n {
                assert_eq!(super::wrap(i, n), i.rem_euclid(n) as usize, "{i} mod {n}");
            }
        }
    }

    use super::*;

    fn checker() -> Texture {
        Texture::new(2, 2, vec![Vec3::ZERO, Vec3::ONE, Vec3::ONE, Vec3::ZERO]).unwrap()
    }

    #[test]
    fn texel_centres_are_exact_and_between_is_bilinear() {
        let t = checker();
        assert_eq!(t.sample(Vec2::new(0.25, 0.25)), Vec3::ZERO);
        assert_eq!(t.sample(Vec2::new(0.75, 0.25)), Vec3::ONE);
        assert_eq!(t.sample(Vec2::new(0.5, 0.25)), Vec3::splat(0.5));
        // Half-way between all four: the average.
        assert_eq!(t.sample(Vec2::new(0.5, 0.5)), Vec3::splat(0.5));
    }

    #[test]
    fn repeats_far_outside_the_unit_square() {
        let t = checker();
        for k in [-15.0f32, -1.0, 3.0, 39.0] {
            assert_eq!(
                t.sample(Vec2::new(0.25 + k, 0.75 + k)),
                t.sample(Vec2::new(0.25, 0.75)),
                "{k}"
            );
        }
        assert_eq!(t.sample(Vec2::splat(f32::NAN)), Vec3::ZERO);
    }

    #[test]
    fn rejects_bad_sizes_and_values() {
        assert!(Texture::new(0, 1, vec![]).is_none());
        assert!(Texture::new(2, 1, vec![Vec3::ZERO]).is_none());
        assert!(Texture::new(1, 1, vec![Vec3::NAN]).is_none());
    }
}
