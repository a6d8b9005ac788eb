//! Four boxes laid out across the lanes of SSE registers, for testing a
//! top-level leaf's instances against a packet's frustum four at a time.

use wide::f32x4;

use crate::geom::aabb::Aabb;

/// Four boxes in structure-of-arrays order: `min[axis]` and `max[axis]`
/// hold one box per lane. A leaf's last quad repeats its last box in the
/// lanes past its end (a repeat gets the answer the box itself gets).
#[derive(Clone, Copy, Debug)]
pub struct BoxQuad {
    pub(crate) min: [f32x4; 3],
    pub(crate) max: [f32x4; 3],
}

impl BoxQuad {
    /// The quad of up to four `boxes` (at least one), the last repeated.
    #[must_use]
    pub fn pack(boxes: &[Aabb]) -> Self {
        let last = boxes.len().saturating_sub(1);
        let lane = |i: usize| boxes.get(i.min(last)).copied().unwrap_or(Aabb::EMPTY);
        let axis = |a: usize, max: bool| {
            f32x4::new(std::array::from_fn(|i| {
                let b = lane(i);
                if max { b.max[a] } else { b.min[a] }
            }))
        };
        Self {
            min: [axis(0, false), axis(1, false), axis(2, false)],
            max: [axis(0, true), axis(1, true), axis(2, true)],
        }
    }

    /// Per box, the largest magnitude among its six coordinates (`maxps`
    /// in a fixed order: the scale of the slack every box test of the
    /// packets and single rays adds).
    #[inline]
    pub(crate) fn largest_coordinate(&self) -> f32x4 {
        let m = |a: usize| self.min[a].abs().fast_max(self.max[a].abs());
        m(0).fast_max(m(1)).fast_max(m(2))
    }

    /// `true` when both quads hold the same bits.
    #[must_use]
    pub(crate) fn same_bits(&self, other: &Self) -> bool {
        let bits = |q: &Self| [q.min, q.max].map(|v| v.map(|x| x.to_array().map(f32::to_bits)));
        bits(self) == bits(other)
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    #[test]
    fn a_short_quad_repeats_its_last_box() {
        let boxes = [
            Aabb::new(Vec3::ZERO, Vec3::ONE),
            Aabb::new(Vec3::splat(-2.0), Vec3::new(3.0, -1.0, 0.5)),
        ];
        let q = BoxQuad::pack(&boxes);
        for (i, want) in [0, 1, 1, 1].into_iter().enumerate() {
            for a in 0..3 {
                assert_eq!(q.min[a].to_array()[i], boxes[want].min[a]);
                assert_eq!(q.max[a].to_array()[i], boxes[want].max[a]);
            }
        }
        assert!(q.same_bits(&BoxQuad::pack(&[boxes[0], boxes[1], boxes[1], boxes[1]])));
        assert!(!q.same_bits(&BoxQuad::pack(&[boxes[1], boxes[0]])));
    }
}
