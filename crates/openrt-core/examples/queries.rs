//! Ray queries alone, with no shading and no image: the API as a collision
//! or visibility library uses it. Boxes are instanced and moved; each step
//! asks which box a probe ray meets first, where, and whether two points
//! see each other.
//!
//! ```sh
//! cargo run --release -p openrt-core --example queries
//! ```

use openrt_core::prelude::*;

/// Defines `id` as an axis-aligned box from `lo` to `hi` (12 triangles).
fn define_box(ctx: &mut Context, id: ObjectId, lo: Vec3, hi: Vec3) -> Result<usize, CoreError> {
    ctx.define_object(id, |ctx| {
        ctx.begin(PrimitiveKind::Quads)?;
        let c = |x: bool, y: bool, z: bool| {
            Vec3::new(
                if x { hi.x } else { lo.x },
                if y { hi.y } else { lo.y },
                if z { hi.z } else { lo.z },
            )
        };
        let faces = [
            [
                c(false, false, false),
                c(false, true, false),
                c(true, true, false),
                c(true, false, false),
            ],
            [
                c(false, false, true),
                c(true, false, true),
                c(true, true, true),
                c(false, true, true),
            ],
            [
                c(false, false, false),
                c(false, false, true),
                c(false, true, true),
                c(false, true, false),
            ],
            [
                c(true, false, false),
                c(true, true, false),
                c(true, true, true),
                c(true, false, true),
            ],
            [
                c(false, false, false),
                c(true, false, false),
                c(true, false, true),
                c(false, false, true),
            ],
            [
                c(false, true, false),
                c(false, true, true),
                c(true, true, true),
                c(true, true, false),
            ],
        ];
        for face in faces {
            for v in face {
                ctx.vertex(v)?;
            }
        }
        ctx.end()
    })
}

fn main() -> Result<(), CoreError> {
    for line in run()? {
        println!("{line}");
    }
    Ok(())
}

/// Runs the queries; returns what they found, one line per answer.
pub fn run() -> Result<Vec<String>, CoreError> {
    let mut lines = Vec::new();
    let mut ctx = Context::new();
    let crate_box = ctx.gen_object();
    define_box(&mut ctx, crate_box, Vec3::splat(-0.5), Vec3::splat(0.5))?;

    // A row of crates along x; the middle one will slide up and away.
    let mut crates = Vec::new();
    for i in 0..5 {
        ctx.load_matrix(Mat4::from_translation(Vec3::new(2.0 * i as f32, 0.0, 0.0)))?;
        crates.push(ctx.instantiate(crate_box)?);
    }
    ctx.load_identity();

    for step in 0..3 {
        let lift = step as f32;
        ctx.set_instance_transform(crates[2], Mat4::from_translation(Vec3::new(4.0, lift, 0.0)))?;
        ctx.commit()?;
        let scene = ctx.scene();

        // Closest hit: a probe along +x from between the second and third
        // crates: it meets the middle crate until that one has moved away.
        let probe = Ray::infinite(Vec3::new(3.0, 0.0, 0.0), Vec3::X);
        if let Some(hit) = scene.intersect(&probe) {
            let id = scene.instances()[hit.instance as usize].id;
            let surface = scene.surface(&probe, &hit)?;
            lines.push(format!(
                "step {step}: the probe meets {id} at t = {:.3}, point {:.3}, normal {:.3}",
                hit.t, surface.point, surface.geometric_normal
            ));
        }

        // Visibility: do two points see each other? The segment is the ray
        // from one to the other with t in (0, 1).
        let (a, b) = (Vec3::new(4.0, 0.0, -3.0), Vec3::new(4.0, 0.0, 3.0));
        let blocked = scene.occluded(&Ray::new(a, b - a, 1e-4, 1.0 - 1e-4));
        let seen = if blocked {
            "are hidden from each other"
        } else {
            "see each other"
        };
        lines.push(format!("step {step}: {a} and {b} {seen}"));

        // Sixteen rays at once (a packet): every lane gets the single ray's answer.
        let rays: [Ray; 16] = std::array::from_fn(|i| {
            Ray::infinite(Vec3::new(2.0 * (i % 5) as f32, 5.0, 0.1 * i as f32 - 0.4), -Vec3::Y)
        });
        let hits = scene.intersect_packet(&rays, u32::from(u16::MAX));
        let down = hits.iter().filter(|h| h.is_some()).count();
        for (ray, hit) in rays.iter().zip(&hits) {
            assert_eq!(
                hit.map(|h| h.t),
                scene.intersect(ray).map(|h| h.t),
                "a packet lane is its single ray"
            );
        }
        lines.push(format!(
            "step {step}: {down} of 16 rays dropped from above land on a crate"
        ));
    }
    Ok(lines)
}
