//! Procedural content: the museum's flying "animart" at any size, and the
//! terrain scene's heightfield and trees.

use glam::{Quat, Vec3};
use openrt_accel::Triangle;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use crate::aff::AnimatedTriangle;

/// `n` triangles that fly in from random positions in the museum room and
/// assemble into a sphere in front of the pillar, like museum5's animart:
/// 5 samples at times 0..4, scattered at 0 and 1, converging at 2 and 3,
/// assembled at 4.
#[must_use]
pub fn animart(n: usize, seed: u64, material: usize) -> Vec<AnimatedTriangle> {
    let mut rng = SmallRng::seed_from_u64(seed);
    let centre = Vec3::new(0.0, 1.9, 0.0);
    let radius = 0.6;
    // Target: a tessellated sphere with about n triangles.
    let stacks = ((n as f32 / 2.0).sqrt().round() as usize).max(2);
    let slices = n.div_ceil(stacks).max(3);
    let dir = |i: f32, j: f32| {
        let th = std::f32::consts::PI * i / stacks as f32;
        let ph = std::f32::consts::TAU * j / slices as f32;
        Vec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin())
    };
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let (i, j) = ((k / slices) % stacks, k % slices);
        let (i, j) = (i as f32, j as f32);
        let target = [dir(i, j), dir(i + 1.0, j), dir(i + 1.0, j + 1.0)];
        // Triangles at the poles collapse; give them the next ring's corner.
        let target = if (target[1] - target[2]).length() < 1e-4 {
            [target[0], target[1], dir(i, j + 1.0)]
        } else {
            target
        };
        let normals = target;
        let final_pos = target.map(|d| centre + d * radius);
        let random_pos = |rng: &mut SmallRng| {
            Vec3::new(
                rng.random_range(-4.0..4.0),
                rng.random_range(0.3..4.5),
                rng.random_range(-4.0..4.0),
            )
        };
        let mut samples = Vec::with_capacity(5);
        let mut sample_normals = Vec::with_capacity(5);
        for s in 0..5 {
            let pull = [0.0f32, 0.0, 0.5, 0.9, 1.0][s];
            let c = random_pos(&mut rng).lerp(centre + (final_pos[0] - centre) * 1.5, pull);
            let spin = Quat::from_axis_angle(
                Vec3::new(rng.random_range(-1.0..1.0), 1.0, rng.random_range(-1.0..1.0)).normalize(),
                rng.random_range(0.0..6.3) * (1.0 - pull),
            );
            let shape = final_pos.map(|p| p - final_pos[0]);
            let scatter = 1.0 + (1.0 - pull) * 2.0;
            let v = shape.map(|d| spin * d * scatter);
            let base = if s == 4 { final_pos[0] } else { c };
            samples.push([base + v[0], base + v[1], base + v[2]]);
            sample_normals.push(normals.map(|nrm| spin * nrm));
        }
        out.push(AnimatedTriangle {
            times: vec![0.0, 1.0, 2.0, 3.0, 4.0],
            vertices: samples,
            normals: sample_normals,
            material,
        });
    }
    out
}

/// Seeded fractal value noise of the terrain (five octaves of sine waves).
struct TerrainNoise {
    octaves: Vec<(f32, f32, f32, f32)>,
    size: f32,
    height: f32,
}

impl TerrainNoise {
    fn new(size: f32, height: f32, seed: u64) -> Self {
        let mut rng = SmallRng::seed_from_u64(seed);
        let octaves = (0..5)
            .map(|o| {
                let f = 2f32.powi(o) * 1.5;
                (
                    f,
                    0.5f32.powi(o),
                    rng.random_range(0.0..6.3),
                    rng.random_range(0.0..6.3),
                )
            })
            .collect();
        Self { octaves, size, height }
    }

    fn at(&self, x: f32, z: f32) -> f32 {
        let (u, v) = (x / self.size, z / self.size);
        self.octaves
            .iter()
            .map(|&(f, a, p, q)| a * ((u * f * 6.3 + p).sin() * (v * f * 5.1 + q).cos()))
            .sum::<f32>()
            * self.height
    }
}

/// A heightfield of `grid` x `grid` cells over `[-size/2, size/2]^2`
/// (fractal value noise, seeded), two triangles per cell.
#[must_use]
pub fn heightfield(grid: usize, size: f32, height: f32, seed: u64) -> Vec<Triangle> {
    let noise = TerrainNoise::new(size, height, seed);
    let p = |i: usize, j: usize| {
        let x = -size / 2.0 + size * i as f32 / grid as f32;
        let z = -size / 2.0 + size * j as f32 / grid as f32;
        Vec3::new(x, noise.at(x, z), z)
    };
    let mut tris = Vec::with_capacity(2 * grid * grid);
    for i in 0..grid {
        for j in 0..grid {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            tris.push([a, c, b]);
            tris.push([a, d, c]);
        }
    }
    tris
}

/// Height of the heightfield under `(x, z)` (same surface as [`heightfield`]).
#[must_use]
pub fn terrain_height(x: f32, z: f32, size: f32, height: f32, seed: u64) -> f32 {
    TerrainNoise::new(size, height, seed).at(x, z)
}

/// A tree of about `target` triangles with its base at the origin, height
/// about 1: a trunk, recursive branches (tapered prisms) and leaf triangles.
/// Returns `(bark, leaves)`.
#[must_use]
pub fn tree(target: usize, seed: u64) -> (Vec<Triangle>, Vec<Triangle>) {
    let mut rng = SmallRng::seed_from_u64(seed);
    let mut bark = Vec::new();
    let mut leaves = Vec::new();
    let sides = 6;
    let prism = |bark: &mut Vec<Triangle>, a: Vec3, b: Vec3, ra: f32, rb: f32| {
        let d = (b - a).normalize_or(Vec3::Y);
        let (u, w) = d.any_orthonormal_pair();
        for k in 0..sides {
            let ang = |k: usize| std::f32::consts::TAU * k as f32 / sides as f32;
            let (c0, c1) = (
                u * ang(k).cos() + w * ang(k).sin(),
                u * ang(k + 1).cos() + w * ang(k + 1).sin(),
            );
            let (p0, p1, q0, q1) = (a + c0 * ra, a + c1 * ra, b + c0 * rb, b + c1 * rb);
            bark.push([p0, p1, q1]);
            bark.push([p0, q1, q0]);
        }
    };
    // Branches: breadth-first until the bark budget (a third) is spent.
    let mut stack = vec![(Vec3::ZERO, Vec3::Y * 0.45, 0.04f32, 0usize)];
    let bark_budget = target / 3;
    while let Some((a, b, r, depth)) = stack.pop() {
        if bark.len() >= bark_budget {
            break;
        }
        prism(&mut bark, a, b, r, r * 0.7);
        if depth > 12 {
            continue;
        }
        let dir = (b - a).normalize();
        let len = (b - a).length();
        for _ in 0..rng.random_range(2..4) {
            let axis = dir.any_orthonormal_vector();
            let q = Quat::from_axis_angle(
                Quat::from_axis_angle(dir, rng.random_range(0.0..6.3)) * axis,
                rng.random_range(0.3..0.8),
            );
            let nd = (q * dir).normalize();
            stack.insert(0, (b, b + nd * len * rng.random_range(0.6..0.85), r * 0.7, depth + 1));
        }
    }
    // Leaves: small triangles scattered in the crown.
    let crown = Vec3::new(0.0, 0.75, 0.0);
    while bark.len() + leaves.len() < target {
        let c = crown
            + Vec3::new(
                rng.random_range(-0.35..0.35),
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.35..0.35),
            );
        let s = 0.03;
        let e1 = Vec3::new(
            rng.random_range(-s..s),
            rng.random_range(-s..s),
            rng.random_range(-s..s),
        );
        let e2 = Vec3::new(
            rng.random_range(-s..s),
            rng.random_range(-s..s),
            rng.random_range(-s..s),
        );
        leaves.push([c, c + e1, c + e2]);
    }
    (bark, leaves)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generators_make_what_they_promise() {
        let a = animart(4096, 1, 0);
        assert_eq!(a.len(), 4096);
        assert!(
            a.iter()
                .all(|t| t.times.len() == 5 && t.vertices.iter().all(|v| v.iter().all(|p| p.is_finite())))
        );
        let hf = heightfield(16, 100.0, 5.0, 2);
        assert_eq!(hf.len(), 2 * 16 * 16);
        let (b, l) = tree(5000, 3);
        assert!((b.len() + l.len()) >= 5000 && b.len() > 500 && l.len() > 1000);
        let y = terrain_height(10.0, -20.0, 100.0, 5.0, 2);
        assert!(y.is_finite() && y.abs() <= 10.0);
    }
}
