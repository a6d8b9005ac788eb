//! Hello, ray tracer: define an object once, instance it twice, animate one
//! instance (affine motion: only its transform changes), and render a few
//! frames to PNG files.
//!
//! ```sh
//! cargo run --release -p openrt-core --example hello -- [OUT_DIR]   # default: target/hello
//! ```

use std::path::{Path, PathBuf};

use openrt_core::prelude::*;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "target/hello".into());
    run(Path::new(&out))?;
    Ok(())
}

/// Renders the frames into `out`; returns the files written.
pub fn run(out: &Path) -> Result<Vec<PathBuf>, Box<dyn std::error::Error>> {
    std::fs::create_dir_all(out)?;

    let mut ctx = Context::new();

    // A red material; vertices take the current material.
    let red = ctx.create_material(Material {
        diffuse: Vec3::new(0.8, 0.1, 0.1),
        ..Material::default()
    })?;

    // An object, defined like an OpenGL display list: a cube from six quads.
    let cube = ctx.gen_object();
    ctx.define_object(cube, |ctx| {
        ctx.material(red)?;
        ctx.begin(PrimitiveKind::Quads)?;
        for axis in 0..3 {
            for side in [-0.5f32, 0.5] {
                // The four corners of the face at `side` on `axis`.
                for (u, v) in [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)] {
                    let mut p = [0.0f32; 3];
                    p[axis] = side;
                    p[(axis + 1) % 3] = u;
                    p[(axis + 2) % 3] = v;
                    ctx.vertex(Vec3::from_array(p))?;
                }
            }
        }
        ctx.end()
    })?;

    // A floor, under the default (white) material.
    let floor = ctx.gen_object();
    ctx.define_object(floor, |ctx| {
        ctx.begin(PrimitiveKind::Quads)?;
        for (x, z) in [(-5.0, -5.0), (-5.0, 5.0), (5.0, 5.0), (5.0, -5.0)] {
            ctx.vertex(Vec3::new(x, -0.5, z))?;
        }
        ctx.end()
    })?;
    ctx.instantiate(floor)?;

    // Two instances of the cube: one still, one that will spin.
    ctx.push_matrix()?;
    ctx.translate(Vec3::new(-1.0, 0.0, 0.0))?;
    ctx.instantiate(cube)?;
    ctx.pop_matrix()?;
    let spinning = ctx.instantiate(cube)?;

    let camera = Camera {
        from: Vec3::new(0.0, 2.0, 5.0),
        at: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 45.0,
        near: 0.01,
    };
    let env = Environment {
        lights: vec![PointLight {
            position: Vec3::new(3.0, 5.0, 4.0),
            color: Vec3::ONE,
        }],
        ambient: Vec3::splat(0.1),
        background: Vec3::new(0.2, 0.3, 0.5),
    };
    let settings = RenderSettings {
        width: 320,
        height: 240,
        ..RenderSettings::default()
    };
    // The renderer shares the context's thread pool.
    let renderer = Renderer::with_pool(ctx.pool()?);

    let mut written = Vec::new();
    for frame in 0..4 {
        let angle = frame as f32 * 0.4;
        ctx.set_instance_transform(
            spinning,
            Mat4::from_translation(Vec3::new(1.0, 0.0, 0.0)) * Mat4::from_rotation_y(angle),
        )?;
        // Commit: the top level is rebuilt from the instances' boxes; the
        // cube's own tree is built once and kept.
        let stats = ctx.commit()?;
        let (image, frame_stats) = renderer.render(&ctx.scene(), &env, &camera, &settings)?;
        let path = out.join(format!("hello_{frame}.png"));
        image.save_png(&path)?;
        println!(
            "{}: {} instances, commit {:.2} ms, render {:.1} ms",
            path.display(),
            stats.instances,
            stats.total_ms,
            frame_stats.render_ms
        );
        written.push(path);
    }
    Ok(written)
}
