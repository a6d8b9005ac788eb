//! Axis-aligned bounding boxes and the robust slab test.

use glam::{Vec3, Vec3A};

use crate::geom::numeric::{gamma, step_ulps};
use crate::geom::ray::Ray;

/// An axis-aligned box `[min, max]`; the empty box has `min > max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box (identity of [`Aabb::union`]).
    pub const EMPTY: Self = Self {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// A box from two corners (in any order).
    #[must_use]
    pub fn new(a: Vec3, b: Vec3) -> Self {
        Self {
            min: a.min(b),
            max: a.max(b),
        }
    }

    /// The smallest box holding every point.
    #[must_use]
    pub fn from_points(points: &[Vec3]) -> Self {
        points.iter().fold(Self::EMPTY, |b, &p| b.grow(p))
    }

    /// `true` when the box holds no point.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    /// `true` when both corners are finite.
    #[must_use]
    pub fn is_finite(&self) -> bool {
        self.min.is_finite() && self.max.is_finite()
    }

    /// The box grown to hold `p`.
    #[must_use]
    pub fn grow(self, p: Vec3) -> Self {
        Self {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// The smallest box holding both boxes.
    #[must_use]
    pub fn union(self, o: Self) -> Self {
        Self {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// The common part of both boxes (possibly empty).
    #[must_use]
    pub fn intersection(self, o: Self) -> Self {
        Self {
            min: self.min.max(o.min),
            max: self.max.min(o.max),
        }
    }

    /// `max - min` (negative for the empty box).
    #[must_use]
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }

    /// The centre point.
    #[must_use]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Corner `i` of the box (bit 0 selects max x, bit 1 max y, bit 2 max z).
    #[must_use]
    pub fn corner(&self, i: usize) -> Vec3 {
        Vec3::new(
            if i & 1 == 0 { self.min.x } else { self.max.x },
            if i & 2 == 0 { self.min.y } else { self.max.y },
            if i & 4 == 0 { self.min.z } else { self.max.z },
        )
    }

    /// The axis of largest extent (0, 1 or 2).
    #[must_use]
    pub fn longest_axis(&self) -> usize {
        let e = self.extent();
        if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        }
    }

    /// Surface area; 0 for the empty box. A flat box has the area of its two faces.
    #[must_use]
    pub fn surface_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// `true` when `p` lies in the closed box.
    #[must_use]
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// `true` when `o` lies in the closed box.
    #[must_use]
    pub fn contains_box(&self, o: &Self) -> bool {
        o.is_empty() || (self.contains(o.min) && self.contains(o.max))
    }

    /// The box grown by `ulps` units in the last place on every side, so that
    /// a box computed with rounding error still holds what it should.
    #[must_use]
    pub fn enlarged_ulps(&self, ulps: u32) -> Self {
        let k = i32::try_from(ulps).unwrap_or(i32::MAX);
        Self {
            min: self.min.map(|x| step_ulps(x, -k)),
            max: self.max.map(|x| step_ulps(x, k)),
        }
    }

    /// [`Aabb::clip`] for the `lanes` of a packet, lane `l` over
    /// `(t_min, t_max[l])`: each lane's entry and exit, and the lanes whose
    /// ray meets the box (the others hold zeros).
    ///
    /// NOTE: lane by lane the operations of [`Aabb::clip`] on
    /// `rays[l].with_interval(rays[l].t_min, t_max[l])`, in its order, with
    /// selects for its branches: the same bits (tested against it).
    // PERF: one straight pass over all lanes instead of a clip per lane
    // (6.7% of a kitchen primary-ray profile as a loop of clips).
    #[must_use]
    #[inline]
    pub fn clip_lanes<const N: usize>(
        &self,
        rays: &[Ray; N],
        lanes: u32,
        t_max: &[f32; N],
    ) -> ([f32; N], [f32; N], u32) {
        let mut t0 = [0.0f32; N];
        let mut t1 = [0.0f32; N];
        if lanes == 0 || self.is_empty() {
            return (t0, t1, 0);
        }
        let (lo, hi) = (self.min.to_array(), self.max.to_array());
        let widen = 1.0 + 2.0 * gamma(3);
        let mut live = 0u32;
        for l in 0..N {
            let r = &rays[l];
            let asked = lanes & (1 << l) != 0;
            let (o, d, inv) = (r.origin.to_array(), r.dir.to_array(), r.inv_dir.to_array());
            // `with_interval` keeps an invalid ray's own interval.
            let mut near = r.t_min;
            let mut far = if r.is_valid() { t_max[l] } else { r.t_max };
            let mut outside = false;
            for a in 0..3 {
                let x = (lo[a] - o[a]) * inv[a];
                let y = (hi[a] - o[a]) * inv[a];
                let swap = x > y;
                let n = if swap { y } else { x };
                let f = (if swap { x } else { y }) * widen;
                let parallel = d[a] == 0.0;
                // Bitwise on purpose: no branch in the lane loop.
                #[allow(clippy::needless_bitwise_bool)]
                let off = parallel & ((o[a] < lo[a]) | (o[a] > hi[a]));
                outside |= off;
                let n = if parallel { f32::NEG_INFINITY } else { n };
                let f = if parallel { f32::INFINITY } else { f };
                near = if n > near { n } else { near };
                far = if f < far { f } else { far };
            }
            // `clip`'s `t0 > t1` rejection (a NaN bound does not reject).
            #[allow(clippy::neg_cmp_op_on_partial_ord)]
            let hit = asked && !outside && !(near > far);
            t0[l] = if hit { near } else { 0.0 };
            t1[l] = if hit { far } else { 0.0 };
            live |= u32::from(hit) << l;
        }
        (t0, t1, live)
    }

    /// Clips `ray` to the closed box: returns the parameter interval inside it
    /// (intersected with the ray's own interval), or `None`.
    ///
    /// Robust slab test after Ize, "Robust BVH Ray Traversal" (JCGT 2013) and
    /// Woop et al. (JCGT 2013): the far distance is scaled by `1 + 2*gamma(3)`
    /// so rounding never shrinks the interval. A zero direction component
    /// (of either sign) is decided by the origin alone, so a ray running
    /// along a face is inside the box.
    // PERF: inlined and read through arrays: as a call with `Vec3` indexing
    // it was 7% of a closest-hit profile (one clip per ray and per instance).
    #[must_use]
    #[inline]
    pub fn clip(&self, ray: &Ray) -> Option<(f32, f32)> {
        if self.is_empty() {
            return None;
        }
        // PERF: the three slabs at once in SIMD lanes, with selects instead
        // of a branch per axis (the per-axis swap and early exit were
        // unpredictable for incoherent rays, most of which miss).
        let (o, d) = (Vec3A::from(ray.origin), Vec3A::from(ray.dir));
        let (lo, hi) = (Vec3A::from(self.min), Vec3A::from(self.max));
        let inv = Vec3A::from(ray.inv_dir);
        let (a, b) = ((lo - o) * inv, (hi - o) * inv);
        let swap = a.cmpgt(b);
        let near = Vec3A::select(swap, b, a);
        let far = Vec3A::select(swap, a, b) * (1.0 + 2.0 * gamma(3));
        // NOTE: exact comparison: only a true zero (of either sign) makes the
        // ray parallel to a slab; then the origin alone decides.
        let parallel = d.cmpeq(Vec3A::ZERO);
        if (parallel & (o.cmplt(lo) | o.cmpgt(hi))).any() {
            return None;
        }
        let near = Vec3A::select(parallel, Vec3A::NEG_INFINITY, near).to_array();
        let far = Vec3A::select(parallel, Vec3A::INFINITY, far).to_array();
        // Written so that a NaN never widens the interval.
        let t0 = near.into_iter().fold(ray.t_min, |t, n| if n > t { n } else { t });
        let t1 = far.into_iter().fold(ray.t_max, |t, f| if f < t { f } else { t });
        if t0 > t1 { None } else { Some((t0, t1)) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The slab test one axis at a time with a branch per decision (the
    /// form `clip` had before it went to SIMD lanes): the reference. One
    /// difference, on purpose: the old form returned an empty interval
    /// (`t_min > t_max`) as a hit when every direction component was zero,
    /// as no axis checked it; the final check here (and in `clip`) does.
    fn clip_by_axis(b: &Aabb, ray: &Ray) -> Option<(f32, f32)> {
        if b.is_empty() {
            return None;
        }
        let (mut t0, mut t1) = (ray.t_min, ray.t_max);
        for a in 0..3 {
            let o = ray.origin[a];
            if ray.dir[a] == 0.0 {
                if o < b.min[a] || o > b.max[a] {
                    return None;
                }
                continue;
            }
            let mut tn = (b.min[a] - o) * ray.inv_dir[a];
            let mut tf = (b.max[a] - o) * ray.inv_dir[a];
            if tn > tf {
                std::mem::swap(&mut tn, &mut tf);
            }
            tf *= 1.0 + 2.0 * gamma(3);
            t0 = if tn > t0 { tn } else { t0 };
            t1 = if tf < t1 { tf } else { t1 };
            if t0 > t1 {
                return None;
            }
        }
        if t0 > t1 { None } else { Some((t0, t1)) }
    }

    #[test]
    fn the_simd_slab_test_gives_the_per_axis_answer_bit_for_bit() {
        use rand::{Rng, SeedableRng, rngs::SmallRng};
        let mut rng = SmallRng::seed_from_u64(5);
        // Coordinates from a small grid so that origins on faces, rays in
        // slab planes and zero components of both signs are frequent.
        let mut pick = |rng: &mut SmallRng| -> f32 {
            match rng.random_range(0..6) {
                0 => 0.0,
                1 => -0.0,
                2 => f32::from_bits(1),
                3 => rng.random_range(-2..=2) as f32,
                _ => rng.random_range(-3.0..3.0),
            }
        };
        let mut tested = 0;
        let mut packet = Vec::new();
        for _ in 0..200_000 {
            let v = |rng: &mut SmallRng, p: &mut dyn FnMut(&mut SmallRng) -> f32| Vec3::new(p(rng), p(rng), p(rng));
            let (c1, c2) = (v(&mut rng, &mut pick), v(&mut rng, &mut pick));
            let b = if rng.random_bool(0.05) {
                Aabb::EMPTY
            } else {
                Aabb::new(c1.min(c2), c1.max(c2))
            };
            let (o, d) = (v(&mut rng, &mut pick), v(&mut rng, &mut pick));
            let (t_min, t_max) = match rng.random_range(0..4) {
                0 => (0.0, f32::INFINITY),
                1 => (rng.random_range(-1.0..1.0), rng.random_range(0.0..4.0)),
                2 => (f32::NAN, 1.0),
                _ => (0.5, 0.25),
            };
            let ray = Ray::new(o, d, t_min, t_max);
            let bits = |r: Option<(f32, f32)>| r.map(|(a, b)| (a.to_bits(), b.to_bits()));
            assert_eq!(bits(b.clip(&ray)), bits(clip_by_axis(&b, &ray)), "{b:?} {ray:?}");
            tested += usize::from(clip_by_axis(&b, &ray).is_some());
            // Every 16 rays, the same box against them as a packet, each
            // lane over its own bound, some lanes masked off.
            packet.push((
                ray,
                if rng.random_bool(0.2) {
                    rng.random_range(-1.0..4.0)
                } else {
                    ray.t_max
                },
            ));
            if packet.len() == 16 {
                let rays: [Ray; 16] = std::array::from_fn(|l| packet[l].0);
                let t_max: [f32; 16] = std::array::from_fn(|l| packet[l].1);
                let lanes = rng.random_range(0..=0xFFFF);
                let (t0, t1, live) = b.clip_lanes(&rays, lanes, &t_max);
                for l in 0..16 {
                    let want = (lanes & (1 << l) != 0)
                        .then(|| b.clip(&rays[l].with_interval(rays[l].t_min, t_max[l])))
                        .flatten();
                    let got = (live & (1 << l) != 0).then_some((t0[l], t1[l]));
                    assert_eq!(bits(got), bits(want), "lane {l}: {b:?} {:?} to {}", rays[l], t_max[l]);
                    if want.is_none() {
                        assert_eq!((t0[l], t1[l]), (0.0, 0.0));
                    }
                }
                packet.clear();
            }
        }
        assert!(tested > 10_000, "too few hits to mean anything: {tested}");
    }

    #[test]
    fn empty_box_is_missed_and_has_no_area() {
        let r = Ray::infinite(Vec3::ZERO, Vec3::ONE);
        assert!(Aabb::EMPTY.clip(&r).is_none());
        assert_eq!(Aabb::EMPTY.surface_area(), 0.0);
        assert!(Aabb::EMPTY.is_empty());
    }

    #[test]
    fn rays_along_faces_with_signed_zero_directions_are_inside() {
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        for (o, d) in [
            (Vec3::new(0.0, 0.5, -1.0), Vec3::new(0.0, 0.0, 1.0)),
            (Vec3::new(0.0, 0.5, -1.0), Vec3::new(-0.0, 0.0, 1.0)),
            (Vec3::new(1.0, 1.0, -1.0), Vec3::new(-0.0, -0.0, 1.0)),
            (Vec3::new(1.0, 0.0, 2.0), Vec3::new(0.0, -0.0, -1.0)),
        ] {
            let (t0, t1) = b.clip(&Ray::infinite(o, d)).expect("ray on a face hits the box");
            assert!(t0 <= 1.0 + 1e-6 && t1 >= 2.0 - 1e-6, "{o} {d}: {t0} {t1}");
        }
        // Just outside the face: a miss.
        let o = Vec3::new(-f32::MIN_POSITIVE, 0.5, -1.0);
        assert!(b.clip(&Ray::infinite(o, Vec3::Z)).is_none());
    }

    #[test]
    fn flat_box_is_hit_by_a_crossing_ray() {
        let b = Aabb::new(Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 1.0, 1.0));
        let (t0, t1) = b.clip(&Ray::infinite(Vec3::new(0.5, 0.5, 0.0), Vec3::Z)).unwrap();
        assert!(t0 <= 1.0 && t1 >= 1.0);
        assert!(b.surface_area() > 0.0);
    }

    #[test]
    fn enlarged_box_contains_original() {
        let b = Aabb::new(Vec3::splat(1e6), Vec3::splat(1e6 + 1.0));
        let e = b.enlarged_ulps(2);
        assert!(e.contains_box(&b));
        assert!(e.min.x < b.min.x);
    }
}
