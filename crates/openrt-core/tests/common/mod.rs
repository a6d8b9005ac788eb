//! Helpers shared by the core's test binaries.

// NOTE: each test binary uses its own subset of these helpers.
#![allow(dead_code)]

use openrt_accel::Triangle;
use openrt_core::{Context, MaterialId, ObjectId, PrimitiveKind};

/// Defines `id` as the triangles `tris` (unwrapping every call).
pub fn define(ctx: &mut Context, id: ObjectId, tris: &[Triangle]) {
    define_with(ctx, id, tris, None);
}

/// [`define`] with `material` set inside the definition.
pub fn define_with(ctx: &mut Context, id: ObjectId, tris: &[Triangle], material: Option<MaterialId>) {
    ctx.begin_object(id).unwrap();
    if let Some(m) = material {
        ctx.material(m).unwrap();
    }
    ctx.begin(PrimitiveKind::Triangles).unwrap();
    for t in tris {
        for &v in t {
            ctx.vertex(v).unwrap();
        }
    }
    ctx.end().unwrap();
    ctx.end_object().unwrap();
}

/// A new object defined as `tris`.
pub fn new_object(ctx: &mut Context, tris: &[Triangle]) -> ObjectId {
    let id = ctx.gen_object();
    define(ctx, id, tris);
    id
}
