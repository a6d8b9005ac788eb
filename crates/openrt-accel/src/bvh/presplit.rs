//! Triangle pre-splitting before a BVH's SAH build (Karras & Aila, "Fast
//! parallel construction of high-quality bounding volume hierarchies", HPG
//! 2013; Ernst & Greiner, "Early split clipping for bounding volume
//! hierarchies", IEEE RT 2007).
//!
//! A long diagonal triangle's box is mostly empty space, and a BVH cannot
//! cut it as a kd-tree's clipped splits do: every ray through the box pays
//! for the triangle. Before the build, the triangles whose boxes waste the
//! most area are cut into pieces by the planes of a dyadic grid over the
//! object's bounds (the coarsest plane crossing a piece first: the planes
//! the build's top splits are likely to choose); each piece is a reference
//! to the same triangle with the box of the triangle clipped to it, so the
//! build can put the pieces on both sides of a split. A leaf never names a
//! triangle twice (`pack` drops repeats); a triangle may sit in several
//! leaves, which changes no answer: each leaf finds the same hit, and the
//! tie rule picks one.

use glam::Vec3;

use super::build::Ref;
use crate::geom::aabb::Aabb;
use crate::geom::triangle::Triangle;

/// Extra references the pre-splitting may add, per valid triangle.
pub const BVH_PRESPLIT_BUDGET: f32 = 0.5;

/// Most pieces of one triangle.
pub const BVH_PRESPLIT_MAX_PIECES: usize = 16;

/// Triangles whose box has at most this many times the surface area of
/// their ideal box (the union of infinitely small boxes over the triangle)
/// are not split.
///
/// PERF: a right triangle in an axis plane has twice its ideal area, and
/// splitting every triangle (museum16k's walls among them) made museum16k
/// shadow rays 0.88-0.90 as fast (single rays, BVH); from 3 they were
/// unchanged while robots kept its gains.
pub const BVH_PRESPLIT_MIN_WASTE: f32 = 3.0;

/// Finest level of the dyadic grid searched for a plane (2^20 cells).
const MAX_LEVEL: u32 = 20;

/// Vertices a piece may hold: a triangle cut by the six faces of a box has
/// at most 9; the rest is room for vertices that rounding puts on both
/// sides of a plane (past it, the piece is kept whole).
const MAX_VERTICES: usize = 3 + 8;

/// A piece: a convex polygon (part of one triangle) and its box.
#[derive(Clone, Copy)]
struct Piece {
    verts: [Vec3; MAX_VERTICES],
    n: usize,
    lo: Vec3,
    hi: Vec3,
}

impl Piece {
    fn of(tri: &Triangle) -> Self {
        let mut verts = [Vec3::ZERO; MAX_VERTICES];
        verts[..3].copy_from_slice(tri);
        Self {
            verts,
            n: 3,
            lo: tri[0].min(tri[1]).min(tri[2]),
            hi: tri[0].max(tri[1]).max(tri[2]),
        }
    }

    fn area(&self) -> f32 {
        let e = self.hi - self.lo;
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// The two halves of the polygon on either side of `x` on `axis`, their
    /// boxes grown by `slack` (the rounding of the clipped vertices) and
    /// cut to the parent's box and to their half-spaces; `None` where a
    /// half is empty or the polygon outgrows [`MAX_VERTICES`].
    fn split(&self, axis: usize, x: f32, slack: f32) -> Option<(Self, Self)> {
        let mut left = Self {
            verts: [Vec3::ZERO; MAX_VERTICES],
            n: 0,
            lo: Vec3::INFINITY,
            hi: Vec3::NEG_INFINITY,
        };
        let mut right = left;
        let push = |p: &mut Self, v: Vec3| -> bool {
            if p.n == MAX_VERTICES {
                return false;
            }
            p.verts[p.n] = v;
            p.n += 1;
            p.lo = p.lo.min(v);
            p.hi = p.hi.max(v);
            true
        };
        for k in 0..self.n {
            let (a, b) = (self.verts[k], self.verts[(k + 1) % self.n]);
            let (da, db) = (a[axis] - x, b[axis] - x);
            if da <= 0.0 && !push(&mut left, a) {
                return None;
            }
            if da >= 0.0 && !push(&mut right, a) {
                return None;
            }
            if (da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0) {
                let t = da / (da - db);
                let mut v = a + (b - a) * t;
                v[axis] = x;
                if !push(&mut left, v) || !push(&mut right, v) {
                    return None;
                }
            }
        }
        if left.n < 3 || right.n < 3 {
            return None;
        }
        for (p, side) in [(&mut left, 0), (&mut right, 1)] {
            p.lo = (p.lo - Vec3::splat(slack)).max(self.lo);
            p.hi = (p.hi + Vec3::splat(slack)).min(self.hi);
            if side == 0 {
                p.hi[axis] = p.hi[axis].min(x);
            } else {
                p.lo[axis] = p.lo[axis].max(x);
            }
        }
        Some((left, right))
    }
}

/// The coarsest plane of the dyadic grid over `lo..lo + ext` on one axis
/// strictly inside `a..b`: its level and position.
fn grid_plane(lo: f32, ext: f32, a: f32, b: f32) -> Option<(u32, f32)> {
    if ext <= 0.0 || b <= a {
        return None;
    }
    (1..=MAX_LEVEL).find_map(|level| {
        let cell = ext / (1u32 << level) as f32;
        let x = lo + ((a - lo) / cell).floor().max(0.0) * cell + cell;
        (x > a && x < b).then_some((level, x))
    })
}

/// The plane a piece is cut at: the coarsest grid plane crossing its box
/// on any axis (the longer extent on a tie).
fn plane_of(p: &Piece, bounds: &Aabb) -> Option<(usize, f32)> {
    let ext = bounds.max - bounds.min;
    (0..3)
        .filter_map(|a| {
            grid_plane(bounds.min[a], ext[a], p.lo[a], p.hi[a]).map(|(level, x)| (level, -(p.hi[a] - p.lo[a]), a, x))
        })
        .min_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)))
        .map(|(_, _, a, x)| (a, x))
}

/// Area of the union of infinitely small boxes over the triangle: twice the
/// sum of its projected areas.
fn ideal_area(t: &Triangle) -> f32 {
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    n.x.abs() + n.y.abs() + n.z.abs()
}

/// References of `refs` (one per valid triangle of `tris`, in `bounds`)
/// with the most wasteful triangles cut into pieces: up to `budget` extra
/// references, shared by priority `(box area - ideal area)^(1/3)` (Karras
/// & Aila's, without their grid-level factor) among the triangles past
/// [`BVH_PRESPLIT_MIN_WASTE`].
pub(crate) fn presplit(tris: &[Triangle], refs: Vec<Ref>, bounds: &Aabb, budget: usize) -> Vec<Ref> {
    if budget == 0 || refs.is_empty() {
        return refs;
    }
    let priority: Vec<f64> = refs
        .iter()
        .map(|r| {
            let t = &tris[r.id() as usize];
            let (area, ideal) = (Piece::of(t).area(), ideal_area(t));
            if area <= ideal * BVH_PRESPLIT_MIN_WASTE {
                0.0
            } else {
                f64::from(area - ideal).cbrt()
            }
        })
        .collect();
    let total: f64 = priority.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return refs;
    }
    let scale = budget as f64 / total;
    let mut out = Vec::with_capacity(refs.len() + budget);
    let mut stack: Vec<(Piece, usize)> = Vec::new();
    for (r, p) in refs.into_iter().zip(priority) {
        // Truncated: the pieces stay within the budget.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let pieces = ((p * scale) as usize + 1).min(BVH_PRESPLIT_MAX_PIECES);
        if pieces == 1 {
            out.push(r);
            continue;
        }
        let id = r.id();
        let t = &tris[id as usize];
        let whole = Piece::of(t);
        let slack = whole.lo.abs().max(whole.hi.abs()).max_element() * f32::EPSILON * 8.0;
        // Pieces split in turn, the count shared between the halves.
        stack.clear();
        stack.push((whole, pieces));
        while let Some((piece, want)) = stack.pop() {
            let halves = if want > 1 {
                plane_of(&piece, bounds).and_then(|(axis, x)| piece.split(axis, x, slack))
            } else {
                None
            };
            match halves {
                Some((l, r)) => {
                    let (la, ra) = (l.area(), r.area());
                    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                    let lw =
                        ((want as f32 * la / (la + ra).max(f32::MIN_POSITIVE)).round() as usize).clamp(1, want - 1);
                    stack.push((l, lw));
                    stack.push((r, want - lw));
                }
                None => out.push(Ref::new(piece.lo, piece.hi, id)),
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::{BVH_PRESPLIT_MAX_PIECES, grid_plane, presplit};
    use crate::bvh::build::Ref;
    use crate::geom::aabb::Aabb;

    #[test]
    fn grid_planes_are_the_coarsest_inside() {
        assert_eq!(grid_plane(0.0, 8.0, 1.0, 7.0), Some((1, 4.0)));
        assert_eq!(grid_plane(0.0, 8.0, 4.0, 7.0), Some((2, 6.0)));
        assert_eq!(grid_plane(0.0, 8.0, 4.5, 4.9), Some((5, 4.75)));
        assert_eq!(grid_plane(0.0, 0.0, 1.0, 2.0), None);
        assert_eq!(grid_plane(0.0, 8.0, 2.0, 2.0), None);
    }

    #[test]
    fn pieces_cover_the_triangle() {
        let tris = vec![
            [
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(100.0, 100.0, 100.0),
                Vec3::new(100.0, 100.0, 100.5),
            ],
            [
                Vec3::new(-3.0, 7.0, 1.0),
                Vec3::new(60.0, -20.0, 33.0),
                Vec3::new(61.0, -19.0, 33.5),
            ],
        ];
        let refs = crate::bvh::refs_of(&tris);
        let bounds = Aabb::from_points(&tris.concat());
        let out = presplit(&tris, refs, &bounds, 20);
        assert!(out.len() > 2, "{} references", out.len());
        for (i, t) in tris.iter().enumerate() {
            let whole = Aabb::from_points(t);
            let boxes: Vec<Aabb> = out.iter().filter(|r| r.id() == i as u32).map(Ref::aabb).collect();
            assert!(boxes.len() > 1, "triangle {i} was not split");
            for b in &boxes {
                assert!(whole.contains_box(b), "piece {b:?} outside {whole:?}");
                assert!(
                    b.surface_area() < whole.surface_area(),
                    "piece {b:?} as large as the triangle's box"
                );
            }
            // Every point of the triangle lies in some piece's box.
            for s in 0..=40 {
                for u in 0..=40 - s {
                    let (a, b) = (s as f32 / 40.0, u as f32 / 40.0);
                    let p = t[0] * (1.0 - a - b) + t[1] * a + t[2] * b;
                    assert!(
                        boxes.iter().any(|bx| bx.contains(p)),
                        "triangle {i}: point {p:?} in no piece"
                    );
                }
            }
        }
    }

    #[test]
    fn the_budget_the_piece_limit_and_the_waste_threshold_hold() {
        // Long slivers (all wasteful) and right triangles in axis planes
        // (twice their ideal area: below the threshold, never split).
        let mut tris = Vec::new();
        for i in 0..200 {
            let o = Vec3::splat(i as f32 * 0.01);
            tris.push([o, o + Vec3::new(10.0, 9.0, 8.0), o + Vec3::new(10.0, 9.0, 8.1)]);
            tris.push([o, o + Vec3::X, o + Vec3::Y]);
        }
        let refs = crate::bvh::refs_of(&tris);
        let bounds = Aabb::from_points(&tris.concat());
        for budget in [1, 50, 200, 100_000] {
            let out = presplit(&tris, refs.clone(), &bounds, budget);
            assert!(
                out.len() - refs.len() <= budget,
                "budget {budget}: {} extra",
                out.len() - refs.len()
            );
            let mut per = vec![0usize; tris.len()];
            for r in &out {
                per[r.id() as usize] += 1;
            }
            for (i, &n) in per.iter().enumerate() {
                assert!((1..=BVH_PRESPLIT_MAX_PIECES).contains(&n), "triangle {i}: {n} pieces");
                if i % 2 == 1 {
                    assert_eq!(n, 1, "the right triangle {i} was split");
                }
            }
            if budget == 100_000 {
                assert!(
                    per.iter().step_by(2).all(|&n| n > BVH_PRESPLIT_MAX_PIECES / 2),
                    "{per:?}"
                );
            }
        }
    }
}
