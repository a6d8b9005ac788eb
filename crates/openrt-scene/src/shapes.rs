//! Procedural shapes emitted through the OpenRT-style API.

use glam::{Vec2, Vec3};
use openrt_core::{Context, CoreError, PrimitiveKind};

/// An axis-aligned box as 6 outward-facing quads with per-face texture coordinates.
pub fn emit_box(ctx: &mut Context, lo: Vec3, hi: Vec3) -> Result<(), CoreError> {
    let b = openrt_accel::Aabb::new(lo, hi);
    let c = |i: usize| b.corner(i);
    let faces = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let uv = [
        Vec2::new(0.0, 0.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(0.0, 1.0),
    ];
    ctx.begin(PrimitiveKind::Quads)?;
    for f in faces {
        for (k, &i) in f.iter().enumerate() {
            ctx.tex_coord(uv[k])?;
            ctx.vertex(c(i))?;
        }
    }
    ctx.end()
}

/// A UV sphere with smooth vertex normals.
pub fn emit_sphere(ctx: &mut Context, center: Vec3, radius: f32, segments: u32) -> Result<(), CoreError> {
    let stacks = segments.max(3);
    let slices = 2 * stacks;
    let point = |i: u32, j: u32| {
        let th = std::f32::consts::PI * i as f32 / stacks as f32;
        let ph = std::f32::consts::TAU * j as f32 / slices as f32;
        Vec3::new(th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin())
    };
    ctx.begin(PrimitiveKind::Triangles)?;
    for i in 0..stacks {
        for j in 0..slices {
            let quad = [(i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j)];
            for tri in [[0, 1, 2], [0, 2, 3]] {
                for k in tri {
                    let (a, b) = quad[k];
                    let n = point(a, b);
                    ctx.normal(n)?;
                    ctx.tex_coord(Vec2::new(b as f32 / slices as f32, a as f32 / stacks as f32))?;
                    ctx.vertex(center + n * radius)?;
                }
            }
        }
    }
    // Triangles at the poles have two equal vertices: they are dropped and counted.
    ctx.end()
}
