//! Textures: RGB images with a mipmap chain, sampled with repeat,
//! clamp-to-edge or mirrored-repeat addressing and nearest, bilinear or
//! trilinear filtering.

use glam::{Vec2, Vec3, Vec3A};
use serde::{Deserialize, Serialize};

mod byte_texels;
mod lanes;

pub(crate) use lanes::{takes_lanes, trilinear_lanes};

/// How a texture coordinate outside `[0, 1]` is addressed, per axis (the
/// wrap modes of OpenGL and of glTF samplers).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub enum TextureWrap {
    /// The image tiles the plane.
    #[default]
    Repeat,
    /// The edge texels extend outward.
    ClampToEdge,
    /// The image tiles the plane, every other tile mirrored.
    MirroredRepeat,
}

/// Texel indices of the two bilinear taps on one axis and the weight of
/// the second, for a coordinate `c` on an axis of `n` texels addressed by
/// `mode`; `c` is finite.
#[inline]
fn taps(c: f32, n: usize, mode: TextureWrap) -> (usize, usize, f32) {
    let ni = n as i64;
    let clamp = |i: i64| i.clamp(0, ni - 1) as usize;
    match mode {
        TextureWrap::Repeat => {
            // The arithmetic of `Level::bilinear`, bit for bit.
            let c = c - floor(c);
            let x = c * n as f32 - 0.5;
            let x0 = floor(x);
            (wrap(x0 as i64, ni), wrap(x0 as i64 + 1, ni), x - x0)
        }
        TextureWrap::ClampToEdge | TextureWrap::MirroredRepeat => {
            let c = folded(c, mode);
            let x = c * n as f32 - 0.5;
            let x0 = floor(x);
            (clamp(x0 as i64), clamp(x0 as i64 + 1), x - x0)
        }
    }
}

/// The texel index holding coordinate `c` on an axis of `n` texels; `c` is finite.
#[inline]
fn nearest_tap(c: f32, n: usize, mode: TextureWrap) -> usize {
    match mode {
        TextureWrap::Repeat => {
            // The arithmetic of `Level::nearest`, bit for bit.
            let c = c - floor(c);
            wrap(floor(c * n as f32) as i64, n as i64)
        }
        TextureWrap::ClampToEdge | TextureWrap::MirroredRepeat => {
            (floor(folded(c, mode) * n as f32) as i64).clamp(0, n as i64 - 1) as usize
        }
    }
}

/// `c` for clamped addressing: mirrored into `[0, 1]` (period 2) for
/// [`TextureWrap::MirroredRepeat`], else limited to `[-1, 2]` (beyond which
/// every tap is an edge texel anyway) so the texel arithmetic stays exact.
#[inline]
fn folded(c: f32, mode: TextureWrap) -> f32 {
    if mode == TextureWrap::MirroredRepeat {
        let m = c - 2.0 * floor(c * 0.5);
        if m > 1.0 { 2.0 - m } else { m }
    } else {
        c.clamp(-1.0, 2.0)
    }
}

/// How a texture is filtered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum TextureFilter {
    /// The nearest texel of the full-size image.
    Nearest,
    /// Bilinear interpolation of the full-size image.
    Bilinear,
    /// Bilinear in the two mipmap levels around the ray cone's level of
    /// detail, blended (Williams 1983; the level from ray cones after
    /// Akenine-Möller et al., "Texture Level of Detail Strategies for
    /// Real-Time Ray Tracing", Ray Tracing Gems, 2019).
    #[default]
    Trilinear,
}

impl TextureFilter {
    /// Every filter, in order of cost.
    pub const ALL: [Self; 3] = [Self::Nearest, Self::Bilinear, Self::Trilinear];

    /// The name used on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Nearest => "nearest",
            Self::Bilinear => "bilinear",
            Self::Trilinear => "trilinear",
        }
    }
}

impl std::str::FromStr for TextureFilter {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|f| f.name() == s)
            .ok_or_else(|| format!("unknown texture filter '{s}' (nearest, bilinear or trilinear)"))
    }
}

/// The texels of four bilinear lookups, one lane each, and the weights of
/// the second column and row.
#[derive(Clone, Copy, Debug)]
struct Taps {
    xa: [u32; 4],
    xb: [u32; 4],
    ya: [u32; 4],
    yb: [u32; 4],
    fx: [f32; 4],
    fy: [f32; 4],
}

/// One level of the mipmap chain.
#[derive(Clone, Debug, PartialEq)]
struct Level {
    width: usize,
    height: usize,
    /// PERF: in `Vec3A`, each texel one 16-byte load straight into the
    /// blend's register (robots GL-like textures phase 0.93x the time of
    /// 12-byte texels, 1.33x the memory).
    texels: Vec<Vec3A>,
    /// The same texels as bytes where every one is `byte / 255`
    /// (`byte_texels.rs`), else empty; the lookups read these.
    bytes: Vec<[u8; 4]>,
}

impl Level {
    /// A level of `width * height` texels, kept as bytes too where they are.
    fn new(width: usize, height: usize, texels: Vec<Vec3A>) -> Self {
        Self {
            width,
            height,
            bytes: byte_texels::encode_all(&texels),
            texels,
        }
    }

    fn texel(&self, x: usize, y: usize) -> Vec3 {
        self.texel_a(x, y).into()
    }

    /// The texel at `(x, y)` as stored.
    #[inline]
    fn texel_a(&self, x: usize, y: usize) -> Vec3A {
        let i = y * self.width + x;
        if self.bytes.is_empty() {
            self.texels[i]
        } else {
            byte_texels::decode(self.bytes[i])
        }
    }

    /// The next level: half the size (rounded up), each texel the box
    /// average of the 2x2 texels above it (an odd last row or column is
    /// averaged with itself).
    fn halve(&self) -> Self {
        let (w, h) = (self.width.div_ceil(2), self.height.div_ceil(2));
        let mut texels = Vec::with_capacity(w * h);
        for y in 0..h {
            let (y0, y1) = (2 * y, (2 * y + 1).min(self.height - 1));
            for x in 0..w {
                let (x0, x1) = (2 * x, (2 * x + 1).min(self.width - 1));
                let sum = self.texel_a(x0, y0) + self.texel_a(x1, y0) + self.texel_a(x0, y1) + self.texel_a(x1, y1);
                texels.push(sum * 0.25);
            }
        }
        Self::new(w, h, texels)
    }

    /// Bilinear sample with repeat addressing; `uv` is finite.
    fn bilinear(&self, uv: Vec2) -> Vec3 {
        // Texel centres at half-integers; wrap before scaling to keep precision.
        let u = uv.x - floor(uv.x);
        let v = uv.y - floor(uv.y);
        let x = u * self.width as f32 - 0.5;
        let y = v * self.height as f32 - 0.5;
        let (x0, y0) = (floor(x), floor(y));
        let (fx, fy) = (x - x0, y - y0);
        let (xi, yi) = (x0 as i64, y0 as i64);
        let (w, h) = (self.width as i64, self.height as i64);
        let (xa, xb) = (wrap(xi, w), wrap(xi + 1, w));
        let (ya, yb) = (wrap(yi, h), wrap(yi + 1, h));
        let top = self.texel(xa, ya).lerp(self.texel(xb, ya), fx);
        let bottom = self.texel(xa, yb).lerp(self.texel(xb, yb), fx);
        top.lerp(bottom, fy)
    }

    /// The bilinear blend of lane `l`'s four texels in `t`: the products
    /// of [`Level::bilinear`] (the lane-parallel lookup's last step).
    #[allow(clippy::inline_always)]
    #[inline(always)]
    ///
    /// PERF: in `Vec3A`, three coordinates to a register: `lerp` is
    /// `a * (1 - s) + b * s` in both, coordinate by coordinate, so the bits
    /// are those of `Vec3`.
    fn blend(&self, t: &Taps, l: usize) -> Vec3A {
        let (xa, xb, ya, yb) = (t.xa[l] as usize, t.xb[l] as usize, t.ya[l] as usize, t.yb[l] as usize);
        let texel = |x: usize, y: usize| self.texel_a(x, y);
        let top = texel(xa, ya).lerp(texel(xb, ya), t.fx[l]);
        let bottom = texel(xa, yb).lerp(texel(xb, yb), t.fx[l]);
        top.lerp(bottom, t.fy[l])
    }

    /// Bilinear sample with each axis addressed by its mode; `uv` is finite.
    fn bilinear_addressed(&self, uv: Vec2, wrap: [TextureWrap; 2]) -> Vec3 {
        let (xa, xb, fx) = taps(uv.x, self.width, wrap[0]);
        let (ya, yb, fy) = taps(uv.y, self.height, wrap[1]);
        let top = self.texel(xa, ya).lerp(self.texel(xb, ya), fx);
        let bottom = self.texel(xa, yb).lerp(self.texel(xb, yb), fx);
        top.lerp(bottom, fy)
    }

    /// The texel holding `uv`, each axis addressed by its mode; `uv` is finite.
    fn nearest_addressed(&self, uv: Vec2, wrap: [TextureWrap; 2]) -> Vec3 {
        self.texel(
            nearest_tap(uv.x, self.width, wrap[0]),
            nearest_tap(uv.y, self.height, wrap[1]),
        )
    }

    /// The texel holding `uv`; `uv` is finite.
    fn nearest(&self, uv: Vec2) -> Vec3 {
        let u = uv.x - floor(uv.x);
        let v = uv.y - floor(uv.y);
        let x = wrap(floor(u * self.width as f32) as i64, self.width as i64);
        let y = wrap(floor(v * self.height as f32) as i64, self.height as i64);
        self.texel(x, y)
    }
}

/// An RGB texture in linear `[0, 1]` values, row 0 at the top (v = 0 at the
/// top row, as NFF/AFF texture coordinates use it), with its mipmap chain
/// down to 1x1, built once when the texture is made.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    levels: Vec<Level>,
    /// Addressing along u and v.
    wrap: [TextureWrap; 2],
}

impl Texture {
    /// A texture from `width * height` texels, row by row; `None` if the
    /// sizes do not match, a size is zero, or a texel is not finite.
    #[must_use]
    pub fn new(width: usize, height: usize, texels: Vec<Vec3>) -> Option<Self> {
        if !(width > 0 && height > 0 && texels.len() == width * height && texels.iter().all(|t| t.is_finite())) {
            return None;
        }
        let texels = texels.into_iter().map(Vec3A::from).collect();
        let mut levels = vec![Level::new(width, height, texels)];
        while let Some(last) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
            let next = last.halve();
            levels.push(next);
        }
        Some(Self {
            levels,
            wrap: [TextureWrap::Repeat; 2],
        })
    }

    /// The texture addressed by `u` along u and `v` along v (new textures repeat).
    #[must_use]
    pub fn with_wrap(mut self, u: TextureWrap, v: TextureWrap) -> Self {
        self.wrap = [u, v];
        self
    }

    /// The addressing along u and v.
    #[must_use]
    pub fn wrap(&self) -> [TextureWrap; 2] {
        self.wrap
    }

    /// Bilinear sample of level `i`, addressed by the texture's modes.
    #[inline]
    fn bilinear(&self, i: usize, uv: Vec2) -> Vec3 {
        if self.wrap == [TextureWrap::Repeat; 2] {
            self.levels[i].bilinear(uv)
        } else {
            self.levels[i].bilinear_addressed(uv, self.wrap)
        }
    }

    /// Width in texels.
    #[must_use]
    pub fn width(&self) -> usize {
        self.levels[0].width
    }

    /// Height in texels.
    #[must_use]
    pub fn height(&self) -> usize {
        self.levels[0].height
    }

    /// The full-size texels, row by row (as the lookups store them: 16
    /// bytes each).
    #[must_use]
    pub fn texels(&self) -> &[Vec3A] {
        &self.levels[0].texels
    }

    /// Number of mipmap levels (1 for a 1x1 texture).
    #[must_use]
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// Bilinear sample of the full-size image at `uv`, addressed by the
    /// texture's wrap modes (any `uv`, also far outside `[0, 1]`; non-finite
    /// coordinates sample texel (0, 0)).
    #[must_use]
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        if !uv.is_finite() {
            return self.levels[0].texel(0, 0);
        }
        self.bilinear(0, uv)
    }

    /// A filtered sample at `uv` for a footprint of level of detail `lod`
    /// (log2 of the footprint's width in full-size texels; 0 or less is
    /// magnification). Nearest and bilinear ignore `lod`; a NaN `lod` means 0.
    #[must_use]
    pub fn sample_filtered(&self, uv: Vec2, lod: f32, filter: TextureFilter) -> Vec3 {
        if !uv.is_finite() {
            return self.levels[0].texel(0, 0);
        }
        match filter {
            TextureFilter::Nearest if self.wrap == [TextureWrap::Repeat; 2] => self.levels[0].nearest(uv),
            TextureFilter::Nearest => self.levels[0].nearest_addressed(uv, self.wrap),
            TextureFilter::Bilinear => self.bilinear(0, uv),
            TextureFilter::Trilinear => {
                let top = (self.levels.len() - 1) as f32;
                // NOTE: max/min, not clamp: a NaN lod becomes 0.
                let lod = lod.max(0.0).min(top);
                let base = floor(lod);
                let f = lod - base;
                let i = base as usize;
                let a = self.bilinear(i, uv);
                if f == 0.0 || i + 1 >= self.levels.len() {
                    a
                } else {
                    a.lerp(self.bilinear(i + 1, uv), f)
                }
            }
        }
    }
}

/// `x.floor()`, bit for bit (signed zeros, NaN and infinities included),
/// without a call.
///
/// PERF: the portable x86-64 build has no rounding instruction (SSE4.1), so
/// `f32::floor` is a call to `floorf`: nine per trilinear sample, 4% of a
/// robots GL-like frame and 2% of a kitchen one in the calls alone
/// (docs/PERFORMANCE.md).
#[inline]
fn floor(x: f32) -> f32 {
    // Every float of magnitude 2^23 or more is an integer; NaN and the
    // infinities come back as they are, as from `floor`.
    if x.is_nan() || x.abs() >= 8_388_608.0 {
        return x;
    }
    // Exact: |x| < 2^23 fits an i32, and so does its truncation.
    let t = x as i32 as f32;
    if t == x {
        // An integer already, -0.0 kept.
        x
    } else if t > x {
        t - 1.0
    } else {
        t
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
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    #[test]
    fn the_inline_floor_is_floor_bit_for_bit() {
        let mut specials = vec![
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            2_147_483_648.0,
            -2_147_483_904.0,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        // Both sides of integers up to 2^23 (every 4093rd), and seeded
        // random bit patterns (every exponent, NaN payloads included).
        for k in (0..8_388_608i32).step_by(4093) {
            let f = k as f32;
            specials.extend([f, -f, f.next_up(), f.next_down(), -f.next_up(), -f.next_down()]);
        }
        let mut rng = SmallRng::seed_from_u64(23);
        specials.extend((0..200_000).map(|_| f32::from_bits(rng.random())));
        for x in specials {
            let (got, want) = (floor(x), x.floor());
            assert!(
                got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "floor({x:e}) = {got:e}, want {want:e}"
            );
        }
    }

    fn checker() -> Texture {
        Texture::new(2, 2, vec![Vec3::ZERO, Vec3::ONE, Vec3::ONE, Vec3::ZERO]).unwrap()
    }

    #[test]
    fn mipmaps_average_and_trilinear_blends_between_levels() {
        // A 4x2 stripe texture: columns alternate black and white.
        let texels = (0..8)
            .map(|i| if i % 2 == 0 { Vec3::ZERO } else { Vec3::ONE })
            .collect();
        let t = super::Texture::new(4, 2, texels).unwrap();
        assert_eq!(t.levels(), 3, "4x2, 2x1, 1x1");
        let uv = Vec2::new(0.125, 0.25);
        assert_eq!(
            t.sample_filtered(uv, -3.0, super::TextureFilter::Trilinear),
            t.sample(uv)
        );
        // Level 1 and below: the stripes averaged to grey.
        assert_eq!(
            t.sample_filtered(uv, 1.0, super::TextureFilter::Trilinear),
            Vec3::splat(0.5)
        );
        assert_eq!(
            t.sample_filtered(uv, 9.0, super::TextureFilter::Trilinear),
            Vec3::splat(0.5)
        );
        let half = t.sample_filtered(uv, 0.5, super::TextureFilter::Trilinear);
        assert_eq!(half, t.sample(uv).lerp(Vec3::splat(0.5), 0.5));
        assert_eq!(
            t.sample_filtered(uv, f32::NAN, super::TextureFilter::Trilinear),
            t.sample(uv)
        );
        assert_eq!(t.sample_filtered(uv, 5.0, super::TextureFilter::Nearest), Vec3::ZERO);
        assert_eq!(
            t.sample_filtered(Vec2::new(0.3, 0.9), 0.0, super::TextureFilter::Nearest),
            Vec3::ONE
        );
        // Odd sizes: 3x1 halves to 2x1 (the last column averaged with itself), then 1x1.
        let t = super::Texture::new(3, 1, vec![Vec3::ZERO, Vec3::ONE, Vec3::splat(0.25)]).unwrap();
        assert_eq!(t.levels(), 3);
        assert_eq!(
            t.sample_filtered(Vec2::new(0.75, 0.5), 1.0, super::TextureFilter::Trilinear),
            Vec3::splat(0.25)
        );
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

    /// A 5 x 3 texture of distinct texels (odd sizes: the mipmaps' edges too).
    fn ramp() -> Texture {
        let texels = (0..15)
            .map(|i| Vec3::new(i as f32 / 15.0, (i % 5) as f32 / 5.0, (i / 5) as f32 / 3.0))
            .collect();
        Texture::new(5, 3, texels).unwrap()
    }

    #[test]
    fn addressed_repeat_is_the_repeat_kernel_bit_for_bit() {
        // The per-axis taps of the other modes, given Repeat, against the
        // repeat-only kernel they stand beside.
        let t = ramp();
        let mut rng = SmallRng::seed_from_u64(41);
        for _ in 0..20_000 {
            let uv = Vec2::new(rng.random_range(-40.0..40.0), rng.random_range(-3.0..3.0));
            for level in &t.levels {
                let a = level.bilinear(uv);
                let b = level.bilinear_addressed(uv, [TextureWrap::Repeat; 2]);
                assert_eq!(a.to_array().map(f32::to_bits), b.to_array().map(f32::to_bits), "{uv}");
                assert_eq!(
                    level.nearest(uv),
                    level.nearest_addressed(uv, [TextureWrap::Repeat; 2]),
                    "{uv}"
                );
            }
        }
    }

    #[test]
    fn clamp_to_edge_extends_the_edge_texels() {
        let t = ramp().with_wrap(TextureWrap::ClampToEdge, TextureWrap::ClampToEdge);
        let texel = |x: usize, y: usize| Vec3::from(t.texels()[y * 5 + x]);
        // Inside the texel centres: as repeating.
        let inside = Vec2::new(0.5, 0.5);
        assert_eq!(t.sample(inside), ramp().sample(inside));
        // Outside: the nearest edge texel, however far.
        for (uv, want) in [
            (Vec2::new(-3.0, 0.5), texel(0, 1)),
            (Vec2::new(1e9, 0.5), texel(4, 1)),
            (Vec2::new(0.5, -0.01), texel(2, 0)),
            (Vec2::new(2.0, 7.0), texel(4, 2)),
        ] {
            assert_eq!(t.sample(uv), want, "{uv}");
            for filter in TextureFilter::ALL {
                assert_eq!(t.sample_filtered(uv, 0.0, filter), want, "{uv} {filter:?}");
            }
        }
        // Every mipmap level is clamped: a coarse sample far outside is that
        // level's edge, not a blend with the other side.
        let coarse = t.sample_filtered(Vec2::new(-5.0, 0.5), 1.0, TextureFilter::Trilinear);
        let l1 = &t.levels[1];
        assert_eq!((l1.width, l1.height), (3, 2));
        assert_eq!(
            coarse,
            l1.texel(0, 0).lerp(l1.texel(0, 1), 0.5),
            "level 1: v = 0.5 is between its rows"
        );
    }

    #[test]
    fn mirrored_repeat_reflects_every_other_tile() {
        let t = ramp().with_wrap(TextureWrap::MirroredRepeat, TextureWrap::Repeat);
        let mut rng = SmallRng::seed_from_u64(7);
        for _ in 0..2_000 {
            // Dyadic coordinates: the mirrored ones are exact.
            let u = f32::from(rng.random_range(0u16..1024)) / 1024.0;
            let v = f32::from(rng.random_range(0u16..1024)) / 1024.0;
            let at = t.sample(Vec2::new(u, v));
            assert_eq!(t.sample(Vec2::new(2.0 - u, v)), at, "mirrored in [1, 2]: {u}");
            assert_eq!(t.sample(Vec2::new(-u, v)), at, "mirrored in [-1, 0]: {u}");
            assert_eq!(t.sample(Vec2::new(u + 4.0, v)), at, "period 2: {u}");
            assert_eq!(
                t.sample_filtered(Vec2::new(-u, v), 0.0, TextureFilter::Nearest),
                t.sample_filtered(Vec2::new(u, v), 0.0, TextureFilter::Nearest),
                "{u}"
            );
        }
        // v still repeats.
        assert_eq!(t.sample(Vec2::new(0.3, 0.25 + 3.0)), t.sample(Vec2::new(0.3, 0.25)));
    }

    #[test]
    fn rejects_bad_sizes_and_values() {
        assert!(Texture::new(0, 1, vec![]).is_none());
        assert!(Texture::new(2, 1, vec![Vec3::ZERO]).is_none());
        assert!(Texture::new(1, 1, vec![Vec3::NAN]).is_none());
    }
}
