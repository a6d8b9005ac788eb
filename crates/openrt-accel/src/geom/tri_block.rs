//! Four triangles coordinate by coordinate: the SIMD block that leaves of
//! both structures test at once (`leaf/blocks.rs`), that frustums cull
//! (`packet/frustum.rs`) and that packets test lane by lane
//! (`packet/triangle.rs`).

use wide::f32x4;

use crate::geom::triangle::Triangle;

/// Triangles per block (one SSE register per coordinate).
pub(crate) const LANES: usize = 4;

/// `LANES` triangles, coordinate by coordinate: `v[vertex][axis]` holds that
/// coordinate of each lane's triangle.
///
/// PERF: 144 bytes, read front to back; a leaf's blocks are contiguous.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TriBlock {
    pub(crate) v: [[f32x4; 3]; 3],
}

impl TriBlock {
    /// The block holding the triangles `ids` of `tris`; a short list is
    /// padded by repeating its last triangle (a repeated lane finds the same
    /// hit, which the closest-hit bound then rejects).
    pub(crate) fn pack(ids: &[u32], tris: &[Triangle]) -> Self {
        debug_assert!(!ids.is_empty() && ids.len() <= LANES);
        let last = ids.len() - 1;
        let lanes: [&Triangle; LANES] = std::array::from_fn(|i| &tris[ids[i.min(last)] as usize]);
        // PERF: plain loops over the nine coordinates (nested `from_fn`
        // closures were not inlined: 4% of a 16k-triangle refit).
        let mut v = [[f32x4::ZERO; 3]; 3];
        for (vert, row) in v.iter_mut().enumerate() {
            for (axis, c) in row.iter_mut().enumerate() {
                *c = f32x4::from(lanes.map(|t| t[vert][axis]));
            }
        }
        Self { v }
    }

    /// Whether every lane's triangle is valid ([`crate::geom::triangle::is_valid_triangle`]).
    #[inline]
    pub(crate) fn all_valid(&self) -> bool {
        crate::geom::triangle::valid_lanes(&self.v) == (1 << LANES) - 1
    }

    /// The lanes' boxes, lane by lane: `(lo, hi)` by axis, for finite
    /// coordinates exactly [`crate::geom::aabb::Aabb::from_points`] of each
    /// lane's triangle (`min` and `max` round nothing; NaN is not handled).
    #[inline]
    pub(crate) fn lane_bounds(&self) -> ([f32x4; 3], [f32x4; 3]) {
        let [a, b, c] = &self.v;
        (
            std::array::from_fn(|k| a[k].fast_min(b[k]).fast_min(c[k])),
            std::array::from_fn(|k| a[k].fast_max(b[k]).fast_max(c[k])),
        )
    }

    /// Coordinate `axis` of vertex `vert` of the four triangles.
    #[inline]
    pub(crate) fn coord(&self, vert: usize, axis: usize) -> f32x4 {
        self.v[vert][axis]
    }

    /// Lane `i`'s triangle as stored.
    #[inline]
    pub(crate) fn triangle(&self, i: usize) -> Triangle {
        let c = |vert: usize, axis: usize| self.v[vert][axis].to_array()[i];
        std::array::from_fn(|vert| glam::Vec3::new(c(vert, 0), c(vert, 1), c(vert, 2)))
    }
}
