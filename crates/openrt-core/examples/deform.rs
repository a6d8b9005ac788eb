//! Unstructured motion: an object whose geometry changes every frame (a
//! rippling sheet) is redefined before each commit. The commit rebuilds only
//! that object, with the cheap builder or a refit of last frame's tree, while
//! the static ball beside it keeps its SAH tree.
//!
//! ```sh
//! cargo run --release -p openrt-core --example deform -- [OUT_DIR]   # default: target/deform
//! ```

use std::path::Path;

use openrt_core::prelude::*;

/// Grid cells per side of the sheet.
const CELLS: usize = 48;

/// Defines `sheet` as a grid of triangles rippling at time `t`.
fn define_sheet(ctx: &mut Context, sheet: ObjectId, t: f32) -> Result<usize, CoreError> {
    let height = |x: f32, z: f32| 0.15 * (3.0 * (x * x + z * z).sqrt() - 4.0 * t).sin();
    ctx.define_object(sheet, |ctx| {
        ctx.begin(PrimitiveKind::Triangles)?;
        let step = 4.0 / CELLS as f32;
        for i in 0..CELLS {
            for j in 0..CELLS {
                let (x0, z0) = (-2.0 + i as f32 * step, -2.0 + j as f32 * step);
                let (x1, z1) = (x0 + step, z0 + step);
                let p = |x: f32, z: f32| Vec3::new(x, height(x, z), z);
                for v in [p(x0, z0), p(x0, z1), p(x1, z0), p(x1, z0), p(x0, z1), p(x1, z1)] {
                    ctx.vertex(v)?;
                }
            }
        }
        ctx.end()
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "target/deform".into());
    run(Path::new(&out))?;
    Ok(())
}

/// Renders the frames into `out`; returns each frame's commit statistics.
pub fn run(out: &Path) -> Result<Vec<openrt_core::CommitStats>, Box<dyn std::error::Error>> {
    std::fs::create_dir_all(out)?;
    let mut ctx = Context::new();

    // A static object: defined once, its SAH tree built once.
    let ball = ctx.gen_object();
    let gold = ctx.create_material(Material {
        diffuse: Vec3::new(0.7, 0.5, 0.1),
        specular: Vec3::splat(0.4),
        shininess: 40.0,
        ..Material::default()
    })?;
    ctx.define_object(ball, |ctx| {
        ctx.material(gold)?;
        // Vertices go through the matrix stack, as in OpenGL.
        ctx.translate(Vec3::new(0.0, 0.6, 0.0))?;
        ctx.scale(Vec3::splat(0.4))?;
        ctx.begin(PrimitiveKind::Triangles)?;
        for tri in openrt_accel::meshgen::bumpy_sphere(2000, 1, 0.0) {
            for v in tri {
                ctx.vertex(v)?;
            }
        }
        ctx.end()
    })?;
    ctx.instantiate(ball)?;

    // The deforming object: instanced once, redefined every frame.
    let sheet = ctx.gen_object();
    define_sheet(&mut ctx, sheet, 0.0)?;
    ctx.instantiate(sheet)?;

    let camera = Camera {
        from: Vec3::new(0.0, 2.5, 4.0),
        at: Vec3::ZERO,
        up: Vec3::Y,
        fov_y_deg: 45.0,
        near: 0.01,
    };
    let env = Environment {
        lights: vec![PointLight {
            position: Vec3::new(2.0, 4.0, 3.0),
            color: Vec3::ONE,
        }],
        ambient: Vec3::splat(0.1),
        background: Vec3::new(0.1, 0.1, 0.15),
    };
    let settings = RenderSettings {
        width: 320,
        height: 240,
        ..RenderSettings::default()
    };
    let renderer = Renderer::with_pool(ctx.pool()?);

    let mut commits = Vec::new();
    for frame in 0..4 {
        if frame > 0 {
            define_sheet(&mut ctx, sheet, frame as f32 * 0.25)?;
        }
        let stats = ctx.commit()?;
        let (image, _) = renderer.render(&ctx.scene(), &env, &camera, &settings)?;
        let path = out.join(format!("deform_{frame}.png"));
        image.save_png(&path)?;
        // Frame 0 builds both objects with the SAH; later frames rebuild the
        // sheet alone, with the fast builder (refitted from its last tree).
        let built: Vec<String> = stats
            .builds
            .iter()
            .map(|b| {
                let how = if b.refitted { "refitted" } else { "built" };
                format!("{} {how} ({:?}) in {:.2} ms", b.object, b.builder, b.ms)
            })
            .collect();
        println!("{}: {}", path.display(), built.join(", "));
        commits.push(stats);
    }
    Ok(commits)
}
