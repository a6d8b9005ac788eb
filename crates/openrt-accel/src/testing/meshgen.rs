//! Deterministic meshes and ray sets for tests and benchmarks.

use glam::Vec3;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use crate::geom::aabb::Aabb;
use crate::geom::ray::Ray;
use crate::geom::triangle::Triangle;

/// A UV sphere of about `n` triangles, radially displaced by a smooth seeded
/// pattern of amplitude `bump` (a closed mesh, consistently wound, with shared
/// edges and poles).
#[must_use]
pub fn bumpy_sphere(n: usize, seed: u64, bump: f32) -> Vec<Triangle> {
    let stacks = ((n as f32 / 4.0).sqrt().round() as usize).max(2);
    let slices = 2 * stacks;
    let mut rng = SmallRng::seed_from_u64(seed);
    // A few low-frequency waves with random phases and frequencies.
    let waves: Vec<(f32, f32, f32, f32)> = (0..4)
        .map(|_| {
            (
                rng.random_range(2.0..7.0f32).round(),
                rng.random_range(2.0..7.0f32).round(),
                rng.random_range(0.0..std::f32::consts::TAU),
                rng.random_range(0.0..std::f32::consts::TAU),
            )
        })
        .collect();
    let radius = |th: f32, ph: f32| -> f32 {
        let s: f32 = waves
            .iter()
            .map(|&(a, b, p, q)| (a * th + p).sin() * (b * ph + q).cos())
            .sum();
        1.0 + bump * (0.5 + 0.125 * s)
    };
    let vertex = |i: usize, j: usize| -> Vec3 {
        if i == 0 {
            return Vec3::Y;
        }
        if i == stacks {
            return -Vec3::Y;
        }
        let th = std::f32::consts::PI * i as f32 / stacks as f32;
        let ph = std::f32::consts::TAU * (j % slices) as f32 / slices as f32;
        let r = radius(th, ph);
        Vec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()) * r
    };
    let mut tris = Vec::with_capacity(2 * stacks * slices);
    for i in 0..stacks {
        for j in 0..slices {
            let (a, b, c, d) = (vertex(i, j), vertex(i + 1, j), vertex(i + 1, j + 1), vertex(i, j + 1));
            if i != 0 {
                tris.push([a, b, d]);
            }
            if i + 1 != stacks {
                tris.push([b, c, d]);
            }
        }
    }
    tris
}

/// A flat `nx` by `ny` grid in the z = 0 plane over `[0, nx] x [0, ny]`, two
/// triangles per cell, consistently wound.
#[must_use]
pub fn grid(nx: usize, ny: usize) -> Vec<Triangle> {
    let mut tris = Vec::with_capacity(2 * nx * ny);
    for i in 0..nx {
        for j in 0..ny {
            let p = |a: usize, b: usize| Vec3::new(a as f32, b as f32, 0.0);
            tris.push([p(i, j), p(i + 1, j), p(i + 1, j + 1)]);
            tris.push([p(i, j), p(i + 1, j + 1), p(i, j + 1)]);
        }
    }
    tris
}

/// A closed axis-aligned cube `[lo, hi]` of 12 consistently wound triangles.
#[must_use]
pub fn cube(lo: Vec3, hi: Vec3) -> Vec<Triangle> {
    let b = Aabb::new(lo, hi);
    let c = |i: usize| b.corner(i);
    // Faces as outward-wound quads of corner indices.
    let faces = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    faces
        .iter()
        .flat_map(|f| [[c(f[0]), c(f[1]), c(f[2])], [c(f[0]), c(f[2]), c(f[3])]])
        .collect()
}

/// A fan of `n` triangles around `center` in the z = 0 plane, closing the full circle.
#[must_use]
pub fn fan(center: Vec3, n: usize, radius: f32) -> Vec<Triangle> {
    let p = |k: usize| {
        let a = std::f32::consts::TAU * (k % n) as f32 / n as f32;
        center + Vec3::new(a.cos(), a.sin(), 0.0) * radius
    };
    (0..n).map(|k| [center, p(k), p(k + 1)]).collect()
}

/// `n` random triangles with vertices in `bounds`, each within `size` of its first vertex.
#[must_use]
pub fn random_soup(n: usize, seed: u64, bounds: Aabb, size: f32) -> Vec<Triangle> {
    let mut rng = SmallRng::seed_from_u64(seed);
    let point = |rng: &mut SmallRng| bounds.min + bounds.extent() * Vec3::new(rng.random(), rng.random(), rng.random());
    (0..n)
        .map(|_| {
            let a = point(&mut rng);
            let mut off = || {
                Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ) * size
            };
            let (b, c) = (a + off(), a + off());
            [a, b, c]
        })
        .collect()
}

/// `n` instance boxes spread like a forest or a museum crowd: 2x4x2 boxes
/// over a square of side `4 sqrt(n)`, every 97th one a large box (5% of the
/// side). The layout of the top-level benchmarks.
#[must_use]
pub fn instance_crowd(n: usize, seed: u64) -> Vec<Aabb> {
    let mut rng = SmallRng::seed_from_u64(seed);
    let side = (n as f32).sqrt() * 4.0;
    (0..n)
        .map(|i| {
            let c = Vec3::new(
                rng.random_range(0.0..side),
                rng.random_range(0.0..4.0),
                rng.random_range(0.0..side),
            );
            let h = if i % 97 == 0 {
                Vec3::splat(side * 0.05)
            } else {
                Vec3::new(1.0, 2.0, 1.0)
            };
            Aabb::new(c - h, c + h)
        })
        .collect()
}

/// Pinhole camera rays, `w` by `h`, from `eye` towards `at` (y up) with
/// vertical field of view `fov_deg`, row by row.
#[must_use]
pub fn camera_rays(eye: Vec3, at: Vec3, w: usize, h: usize, fov_deg: f32) -> Vec<Ray> {
    let fwd = (at - eye).normalize();
    let right = fwd.cross(Vec3::Y).normalize();
    let up = right.cross(fwd);
    let tan = (fov_deg.to_radians() * 0.5).tan();
    let aspect = w as f32 / h as f32;
    let mut rays = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let u = ((x as f32 + 0.5) / w as f32 * 2.0 - 1.0) * tan * aspect;
            let v = (1.0 - (y as f32 + 0.5) / h as f32 * 2.0) * tan;
            rays.push(Ray::infinite(eye, fwd + right * u + up * v));
        }
    }
    rays
}

/// `rays` reflected where they meet the plane through `point` with unit
/// normal `normal` (a plane mirror), as a renderer's bounces: from the
/// hit over `[0, inf)`; rays that miss the plane (or run along it) are
/// left out. The reflections of a camera's rays pass near one point, the
/// eye's mirror image.
#[must_use]
pub fn mirrored_rays(rays: &[Ray], point: Vec3, normal: Vec3) -> Vec<Ray> {
    rays.iter()
        .filter_map(|r| {
            let t = (point - r.origin).dot(normal) / r.dir.dot(normal);
            (t > 0.0 && t.is_finite()).then(|| {
                let q = r.origin + r.dir * t;
                Ray::infinite(q, r.dir - 2.0 * r.dir.dot(normal) * normal)
            })
        })
        .collect()
}

/// `rays` reflected off the outside of the sphere at `centre` of `radius`
/// (a curved mirror), from the hit over `[0, inf)`; rays that miss it are
/// left out.
#[must_use]
pub fn sphere_mirrored_rays(rays: &[Ray], centre: Vec3, radius: f32) -> Vec<Ray> {
    rays.iter()
        .filter_map(|r| {
            let d = r.dir.normalize();
            let oc = r.origin - centre;
            let b = oc.dot(d);
            let disc = b * b - (oc.length_squared() - radius * radius);
            let t = -b - disc.max(0.0).sqrt();
            (disc >= 0.0 && t > 0.0).then(|| {
                let q = r.origin + d * t;
                let n = (q - centre).normalize();
                Ray::infinite(q, d - 2.0 * d.dot(n) * n)
            })
        })
        .collect()
}

/// `n` points of random triangles of `tris`, each a vertex, an edge
/// midpoint or a centroid: where a triangle test that is not watertight
/// lets rays through the shared edges and vertices of a closed mesh.
#[must_use]
pub fn hard_points(tris: &[Triangle], n: usize, seed: u64) -> Vec<Vec3> {
    if tris.is_empty() {
        return Vec::new();
    }
    let mut rng = SmallRng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let t = &tris[rng.random_range(0..tris.len())];
            match rng.random_range(0..3) {
                0 => t[rng.random_range(0..3)],
                1 => (t[0] + t[1]) * 0.5,
                _ => (t[0] + t[1] + t[2]) / 3.0,
            }
        })
        .collect()
}

/// `n` rays aimed at [`hard_points`] from random origins in a cube of
/// side 6 about the origin.
#[must_use]
pub fn hard_rays(tris: &[Triangle], n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = SmallRng::seed_from_u64(seed ^ 0x9e37_79b9);
    hard_points(tris, n, seed)
        .into_iter()
        .map(|target| {
            let from = Vec3::new(rng.random(), rng.random(), rng.random()) * 6.0 - 3.0;
            Ray::new(from, target - from, 0.0, f32::INFINITY)
        })
        .collect()
}

/// `n` incoherent rays: origins uniform in `bounds` grown by half its
/// extent, directions uniform on the sphere.
#[must_use]
pub fn random_rays(n: usize, seed: u64, bounds: Aabb) -> Vec<Ray> {
    let mut rng = SmallRng::seed_from_u64(seed);
    let grow = bounds.extent() * 0.5;
    let (lo, ext) = (bounds.min - grow, bounds.extent() + 2.0 * grow);
    (0..n)
        .map(|_| {
            let o = lo + ext * Vec3::new(rng.random(), rng.random(), rng.random());
            let z: f32 = rng.random_range(-1.0..1.0);
            let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let r = (1.0 - z * z).max(0.0).sqrt();
            Ray::infinite(o, Vec3::new(r * phi.cos(), r * phi.sin(), z))
        })
        .collect()
}
