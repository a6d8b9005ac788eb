//! Whole-packet box culling by interval arithmetic, for packets without a
//! frustum (reflection and refraction rays, whose origins differ).
//!
//! The lanes' origins and reciprocal directions are bounded, axis by axis,
//! by intervals; a box's slab distances over all lanes are then bounded by
//! the products of those intervals (Boulos et al., "Geometric and
//! Arithmetic Culling Methods for Entire Ray Packets", 2006). When the
//! lower bound of every lane's entry lies beyond the upper bound of every
//! lane's exit, no lane reaches the box, and the packet skips it without a
//! lane test.
//!
//! NOTE: the bounds are those of [`PacketBoxes::reaching`]'s own rounded
//! values: rounded subtraction and multiplication are monotone in each
//! operand (for a fixed sign of the other), so over an interval of origins
//! and one of reciprocals the least and largest rounded products lie at the
//! corners. A box rejected here is one that `reaching` rejects for every
//! lane (tested against it), so the answers do not change.

use wide::f32x4;

use crate::geom::box_quad::BoxQuad;
use crate::packet::boxes::{BOX_SLACK, PacketBoxes};
use crate::packet::width::lanes_of;

/// Intervals holding the lanes of a packet, for [`PacketInterval::rejects_box_quad`].
#[derive(Clone, Copy, Debug)]
pub struct PacketInterval {
    /// Least and largest origin coordinate per axis.
    o_lo: [f32; 3],
    o_hi: [f32; 3],
    /// Least and largest reciprocal direction component per axis.
    inv_lo: [f32; 3],
    inv_hi: [f32; 3],
    /// The least near bound of the lanes.
    t_min: f32,
    /// The largest coordinate of the lanes' origins (the slack's scale).
    scale: f32,
}

impl PacketInterval {
    /// The intervals of the `lanes` of `boxes`; `None` when there is no
    /// lane or a lane cannot be tested ([`PacketBoxes::reaching`] passes
    /// such lanes untested, so no interval may stand for them).
    #[must_use]
    pub fn new<const N: usize>(boxes: &PacketBoxes<N>, lanes: u32) -> Option<Self> {
        if lanes == 0 || lanes & !boxes.testable != 0 {
            return None;
        }
        let (mut o_lo, mut o_hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        let (mut inv_lo, mut inv_hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        let mut t_min = f32::INFINITY;
        for l in lanes_of(lanes) {
            for a in 0..3 {
                o_lo[a] = o_lo[a].min(boxes.o[a][l]);
                o_hi[a] = o_hi[a].max(boxes.o[a][l]);
                inv_lo[a] = inv_lo[a].min(boxes.inv[a][l]);
                inv_hi[a] = inv_hi[a].max(boxes.inv[a][l]);
            }
            // NOTE: a NaN near bound, which `reaching` lets the slab bounds
            // replace, bounds nothing.
            let t = boxes.t_min[l];
            t_min = if t.is_nan() { f32::NEG_INFINITY } else { t_min.min(t) };
        }
        Some(Self {
            o_lo,
            o_hi,
            inv_lo,
            inv_hi,
            t_min,
            scale: boxes.scale,
        })
    }

    /// Bit `i` set: no lane can reach box `i` of `quad` before `t_max`, the
    /// largest far bound of the lanes tested (a NaN rejects nothing).
    #[must_use]
    #[inline]
    pub fn rejects_box_quad(&self, quad: &BoxQuad, t_max: f32) -> u32 {
        if t_max.is_nan() {
            return 0;
        }
        let (lo, hi) = (quad.min, quad.max);
        // The slack of `reaching`, box by box.
        let scale = quad.largest_coordinate().fast_max(f32x4::splat(self.scale));
        let slack = f32x4::splat(BOX_SLACK) * scale;
        let finite = slack.is_finite();
        let mut near = f32x4::splat(self.t_min);
        let mut far = f32x4::splat(t_max * (1.0 + 1e-5));
        for a in 0..3 {
            let (o_lo, o_hi) = (f32x4::splat(self.o_lo[a]), f32x4::splat(self.o_hi[a]));
            let (i_lo, i_hi) = (f32x4::splat(self.inv_lo[a]), f32x4::splat(self.inv_hi[a]));
            let (l, h) = (lo[a] - slack, hi[a] + slack);
            // Every lane's `l - o` and `h - o` lie between these two; the
            // slab distances are their products with the reciprocals, whose
            // extremes lie at the corners.
            let (d_lo, d_hi) = (l - o_hi, h - o_lo);
            let (p0, p1, p2, p3) = (d_lo * i_lo, d_lo * i_hi, d_hi * i_lo, d_hi * i_hi);
            let least = p0.fast_min(p1).fast_min(p2.fast_min(p3));
            let most = p0.fast_max(p1).fast_max(p2.fast_max(p3));
            near = near.fast_max(least);
            far = far.fast_min(most);
        }
        (finite & near.simd_gt(far)).to_bitmask()
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    use super::*;
    use crate::geom::aabb::Aabb;
    use crate::geom::ray::Ray;

    /// A vector with coordinates in `[-r, r)`.
    fn jitter(rng: &mut SmallRng, r: f32) -> Vec3 {
        Vec3::new(
            rng.random_range(-r..r),
            rng.random_range(-r..r),
            rng.random_range(-r..r),
        )
    }

    /// Reflection-like packets: origins spread over a patch, directions in
    /// a cone; boxes near and far, around the origins, flat and huge.
    #[test]
    fn rejected_boxes_are_rejected_by_every_lane_test() {
        let mut rng = SmallRng::seed_from_u64(41);
        let (mut rejected, mut n, mut reached) = (0, 0, 0);
        for k in 0..400 {
            let spread = [0.01, 0.3, 3.0][k % 3];
            let base = jitter(&mut rng, 5.0);
            let axis = jitter(&mut rng, 1.0);
            let rays: [Ray; 16] = std::array::from_fn(|_| {
                let o = base + jitter(&mut rng, 1.0) * spread;
                let d = axis + jitter(&mut rng, 0.2) * spread;
                Ray::new(
                    o,
                    d,
                    1e-4,
                    if k % 4 == 0 {
                        rng.random_range(0.5..20.0)
                    } else {
                        f32::INFINITY
                    },
                )
            });
            let lanes = if k % 5 == 0 {
                rng.random::<u32>() & 0xffff | 1
            } else {
                0xffff
            };
            let pb = PacketBoxes::new(&rays, lanes);
            let Some(iv) = PacketInterval::new(&pb, lanes & pb.testable) else {
                continue;
            };
            let t_max: [f32; 16] = std::array::from_fn(|l| rays[l].t_max);
            let far = lanes_of(lanes & pb.testable)
                .map(|l| t_max[l])
                .fold(f32::NEG_INFINITY, f32::max);
            let boxes: Vec<Aabb> = (0..8)
                .map(|i| {
                    // Half of them along the packet, the others anywhere.
                    let off = jitter(&mut rng, 1.0);
                    let c = if i % 2 == 0 {
                        base + axis.normalize() * rng.random_range(-2.0..12.0) + off * rng.random_range(0.0..3.0)
                    } else {
                        base + off * 12.0
                    };
                    let mut h = Vec3::new(
                        rng.random_range(0.0..2.0),
                        rng.random_range(0.0..2.0),
                        rng.random_range(0.0..2.0),
                    );
                    if i == 0 {
                        h.x = 0.0;
                    }
                    if i == 7 {
                        return Aabb::new(c * 1e5, c * 1e5 + Vec3::splat(1e4));
                    }
                    Aabb::new(c - h, c + h)
                })
                .collect();
            for chunk in boxes.chunks(4) {
                let mask = iv.rejects_box_quad(&BoxQuad::pack(chunk), far);
                for (j, b) in chunk.iter().enumerate() {
                    n += 1;
                    let lanes_reaching = pb.reaching(b, lanes & pb.testable, &t_max);
                    reached += usize::from(lanes_reaching != 0);
                    if mask & (1 << j) != 0 {
                        rejected += 1;
                        assert_eq!(lanes_reaching, 0, "box {b:?} rejected, but lanes reach it");
                    }
                }
            }
        }
        assert!(
            rejected * 3 > n && reached * 5 > n,
            "{rejected} of {n} rejected, {reached} reached"
        );
    }

    #[test]
    fn no_interval_for_untestable_lanes_and_nan_bounds_reject_nothing() {
        let mut rays = [Ray::infinite(Vec3::ZERO, Vec3::new(1.0, 0.5, 0.25)); 16];
        // An origin at infinity: `reaching` passes the lane untested.
        rays[3] = Ray::infinite(Vec3::new(f32::INFINITY, 0.0, 0.0), Vec3::new(1.0, 0.5, 0.25));
        let pb = PacketBoxes::new(&rays, 0xffff);
        assert!(PacketInterval::new(&pb, 0xffff).is_none());
        assert!(PacketInterval::new(&pb, 0).is_none());
        let iv = PacketInterval::new(&pb, 0xffff & !(1 << 3)).expect("testable lanes");
        let behind = BoxQuad::pack(&[Aabb::new(Vec3::splat(-3.0), Vec3::splat(-2.0))]);
        assert_eq!(iv.rejects_box_quad(&behind, f32::INFINITY), 0xf);
        assert_eq!(iv.rejects_box_quad(&behind, f32::NAN), 0);
        let c = Vec3::new(4.0, 2.0, 1.0);
        let ahead = BoxQuad::pack(&[Aabb::new(c - 0.5, c + 0.5)]);
        assert_eq!(iv.rejects_box_quad(&ahead, f32::INFINITY), 0);
        // Beyond every lane's far bound.
        assert_eq!(iv.rejects_box_quad(&ahead, 1.0), 0xf);
    }
}
