//! Whole-packet triangle culling for rays that share an origin.
//!
//! A packet of primary rays leaves the eye as a thin pyramid. Seen from the
//! shared origin, each lane's ray is one point of the projection onto a
//! plane across the dominant axis; the lanes' points fit in a rectangle.
//! A triangle lying wholly in front of the origin projects to the convex
//! hull of its vertices' projections, so when all three vertices project
//! beyond the same side of the rectangle, no lane can hit it, and the leaf
//! loop skips it for the whole packet (Reshetov, Soupikov & Hurley 2005 and
//! Wald, Boulos & Shirley 2007 cull with the packet's frustum or interval
//! the same way).
//!
//! NOTE: the answers do not change. A triangle is skipped only when its
//! projection lies beyond the rectangle by a margin of
//! [`FRUSTUM_MARGIN`] of the rectangle's coordinates, a hundred times the
//! largest rounding error of the projections and of the lanes' own
//! watertight tests, so that no lane's exact test could have hit it
//! (tested against the per-lane loop on camera, hard and random packets).

use wide::f32x4;

use crate::geom::box_quad::BoxQuad;
use crate::geom::ray::Ray;
use crate::geom::tri_block::TriBlock;
use crate::packet::boxes::PacketBoxes;
use crate::packet::width::by_axis;
use crate::packet::width::lanes_of;

/// Relative margin by which a triangle's projection must clear the lanes'
/// rectangle before the whole packet skips it.
pub const FRUSTUM_MARGIN: f32 = 1e-4;

/// A lane mask with every lane set.
const ALL: f32x4 = f32x4::new([f32::from_bits(u32::MAX); 4]);

/// Whether packets make frusta (see [`set_frustum_culling`]).
static CULLING: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(true);

/// Turns frustum culling on or off for every packet walk of the process (on
/// by default). The answers are the same bits either way, only the speed
/// changes: this is the switch of A/B measurements (the CLI sets it from
/// `OPENRT_NO_FRUSTUM`). It is process-wide because frusta are made deep
/// inside both levels' packet walks of both object structures.
pub fn set_frustum_culling(on: bool) {
    CULLING.store(on, std::sync::atomic::Ordering::Relaxed);
}

/// Whether frustum culling is on ([`set_frustum_culling`]).
#[must_use]
pub fn frustum_culling() -> bool {
    CULLING.load(std::sync::atomic::Ordering::Relaxed)
}

#[inline]
fn off() -> bool {
    !frustum_culling()
}

/// The rectangle of a packet's rays seen from their shared origin. Made
/// for packets of whole SSE registers (`N` a multiple of four, as every
/// [`crate::packet::width::PacketWidth`]).
pub struct Frustum {
    /// The origin.
    origin: glam::Vec3,
    /// The rectangle, widened: low and high `u`, low and high `v`.
    rect: [f32; 4],
    /// Built by [`Frustum::new`] (lanes leaving one origin).
    shared_origin: bool,
    /// The origin, on the dominant axis `k` and the two others `a`, `b`.
    o: [f32x4; 3],
    /// `k`, `a`, `b`.
    axes: [usize; 3],
    /// Sign of the lanes' direction along `k`.
    sign: f32x4,
    /// The rectangle, widened by the margin: low and high `a / k` and `b / k`.
    lo_u: f32x4,
    hi_u: f32x4,
    lo_v: f32x4,
    hi_v: f32x4,
    /// [`FRUSTUM_MARGIN`] times the largest coordinate of the apex and the
    /// lanes' origins, plus `radius`: the positional slack of a frustum
    /// whose lanes do not share their origin bit for bit.
    slack: f32x4,
    /// How far the lanes' lines may pass from the apex ([`Frustum::through`];
    /// 0 for the others).
    radius: f32,
    /// The least scale of a box's slack ([`Frustum::rejects_box`]): the
    /// apex's largest coordinate, or twice `radius` over [`FRUSTUM_MARGIN`]
    /// where that is more (so that every box is widened by twice the
    /// radius), in every lane.
    box_scale: f32x4,
    /// [`FRUSTUM_MARGIN`] times the square of `1 + |u| + |v|` at the
    /// rectangle's farthest: the edge test's margin per unit of the
    /// products' magnitude ([`Frustum::edges_apart`]).
    edge_margin: f32x4,
}

impl Frustum {
    /// How far the lanes spread: the rectangle's larger side, in units of
    /// the dominant axis (1 is about 53 degrees).
    #[must_use]
    pub(crate) fn spread(&self) -> f32 {
        (self.rect[1] - self.rect[0]).max(self.rect[3] - self.rect[2])
    }

    /// The frustum of the `lanes` of `rays`: `None` unless they share their
    /// origin bit for bit and point the same way along one axis, where
    /// every direction component is finite; `None` too when culling is off
    /// ([`set_frustum_culling`]; the answers are the same either way).
    #[must_use]
    pub fn new<const N: usize>(rays: &[Ray; N], lanes: u32) -> Option<Self> {
        if off() || lanes == 0 {
            return None;
        }
        Self::new_in(&Rows::of(rays).laid(), lanes)
    }

    /// [`Frustum::new`] of the rays `laid` was made from: the same frustum.
    #[must_use]
    pub fn new_laid<const N: usize>(laid: &PacketBoxes<N>, lanes: u32) -> Option<Self> {
        if off() || lanes == 0 {
            return None;
        }
        Self::new_in(&Laid::from(laid), lanes)
    }

    fn new_in<const N: usize>(rays: &Laid<'_, N>, lanes: u32) -> Option<Self> {
        let f = lanes.trailing_zeros() as usize;
        let o = [rays.o[0][f], rays.o[1][f], rays.o[2][f]].map(f32::to_bits);
        if lanes_of(lanes).any(|l| [rays.o[0][l], rays.o[1][l], rays.o[2][l]].map(f32::to_bits) != o) {
            return None;
        }
        Self::from_apex(
            glam::Vec3::from_array(o.map(f32::from_bits)),
            rays.d,
            lanes,
            false,
            true,
            0.0,
            0.0,
        )
    }

    /// [`Frustum::toward`] with the target the lanes end at: the first
    /// lane's `origin + dir`, which every other lane must reach within the
    /// same tolerance. For packets moved into an object's space, where the
    /// light has no name.
    #[must_use]
    pub fn ending<const N: usize>(rays: &[Ray; N], lanes: u32) -> Option<Self> {
        if lanes == 0 {
            return None;
        }
        let r = &rays[lanes.trailing_zeros() as usize];
        Self::toward(rays, lanes, r.origin + r.dir)
    }

    /// The frustum of the `lanes` of `rays` that all end at `target`: rays
    /// `Ray::new(p, target - p, t_min, t_max)` with `t_max <= 1`, such as
    /// shadow rays towards one point light. Seen from `target`, each lane
    /// is a segment towards its origin. `None` when a lane does not end
    /// within 1e-6 of the coordinates' scale of `target` (far inside the
    /// positional slack of [`Frustum::rejects_box`] and of the triangle
    /// test, which for this frustum is a half-space test with that slack).
    #[must_use]
    pub fn toward<const N: usize>(rays: &[Ray; N], lanes: u32, target: glam::Vec3) -> Option<Self> {
        if off() || lanes == 0 || !target.is_finite() {
            return None;
        }
        Self::toward_in(&Rows::of(rays).laid(), lanes, target)
    }

    /// [`Frustum::toward`] of the rays `laid` was made from: the same frustum.
    #[must_use]
    pub fn toward_laid<const N: usize>(laid: &PacketBoxes<N>, lanes: u32, target: glam::Vec3) -> Option<Self> {
        if off() || lanes == 0 || !target.is_finite() {
            return None;
        }
        Self::toward_in(&Laid::from(laid), lanes, target)
    }

    fn toward_in<const N: usize>(rays: &Laid<'_, N>, lanes: u32, target: glam::Vec3) -> Option<Self> {
        // PERF: four lanes at a time on the rays laid out by axis (a lane
        // loop was 5% of a shadow-query profile).
        let (o, d) = (rays.o, rays.d);
        let quad = |v: &[f32; N], c: usize| f32x4::new([v[c], v[c + 1], v[c + 2], v[c + 3]]);
        let on = |c: usize| lane_mask(lanes >> c);
        let max3 = |v: [f32x4; 3]| v[0].abs().fast_max(v[1].abs()).fast_max(v[2].abs());
        // The largest coordinate of the apex and the lanes' origins (a NaN
        // origin ends the lane off target below).
        const { assert!(N.is_multiple_of(4), "packets are whole registers of four lanes") };
        let mut scale4 = f32x4::ZERO;
        for c in (0..N).step_by(4) {
            let origins = [quad(&o[0], c), quad(&o[1], c), quad(&o[2], c)];
            scale4 = on(c).bitselect(scale4.fast_max(max3(origins)), scale4);
        }
        let scale = scale4.to_array().into_iter().fold(target.abs().max_element(), f32::max);
        // Each lane must end at the target, within 1e-6 of the scale of the
        // coordinates involved, over an interval ending by 1.
        let (tx, ty, tz) = (f32x4::splat(target.x), f32x4::splat(target.y), f32x4::splat(target.z));
        let (tiny, ppm) = (f32x4::splat(1e-30), f32x4::splat(1e-6));
        for c in (0..N).step_by(4) {
            // NOTE: no `[_; 3].map`: it can be left as calls (this function
            // took 8% of the shadow queries instead of 3% in one build).
            let e = [
                quad(&o[0], c) + quad(&d[0], c),
                quad(&o[1], c) + quad(&d[1], c),
                quad(&o[2], c) + quad(&d[2], c),
            ];
            let tolerance = ppm * f32x4::splat(scale).fast_max(max3(e)).fast_max(tiny);
            let off_target = max3([e[0] - tx, e[1] - ty, e[2] - tz]);
            let t_max = quad(rays.t_max, c);
            // NOTE: a NaN or infinite end fails the lane (`fast_max` may
            // drop a NaN); a NaN `t_max` fails the compare.
            let finite = e[0].is_finite() & e[1].is_finite() & e[2].is_finite();
            let fine = t_max.simd_le(f32x4::ONE) & off_target.simd_le(tolerance) & finite;
            if (on(c) & !fine).to_bitmask() != 0 {
                return None;
            }
        }
        Self::from_apex(target, rays.d, lanes, true, false, scale, 0.0)
    }

    /// The frustum of a packet's closest-hit query: lanes sharing an origin
    /// ([`Frustum::new`]) or a virtual apex ([`Frustum::through`]).
    #[must_use]
    pub fn for_intersect<const N: usize>(rays: &[Ray; N], lanes: u32) -> Option<Self> {
        if off() || lanes == 0 {
            return None;
        }
        // The lanes gathered once for both kinds.
        Self::for_intersect_in(rays, &Rows::of(rays).laid(), lanes)
    }

    /// [`Frustum::for_intersect`] of the rays `laid` was made from: the same frustum.
    #[must_use]
    pub fn for_intersect_laid<const N: usize>(rays: &[Ray; N], laid: &PacketBoxes<N>, lanes: u32) -> Option<Self> {
        if off() || lanes == 0 {
            return None;
        }
        Self::for_intersect_in(rays, &Laid::from(laid), lanes)
    }

    fn for_intersect_in<const N: usize>(rays: &[Ray; N], laid: &Laid<'_, N>, lanes: u32) -> Option<Self> {
        Self::new_in(laid, lanes).or_else(|| Self::through_in(rays, laid, lanes))
    }

    /// The frustum of a packet's any-hit query: lanes sharing an origin
    /// ([`Frustum::new`]) or an end point ([`Frustum::ending`]: shadow rays
    /// towards one light).
    #[must_use]
    pub fn for_occluded<const N: usize>(rays: &[Ray; N], lanes: u32) -> Option<Self> {
        if off() || lanes == 0 {
            return None;
        }
        // The lanes gathered once for both kinds.
        Self::for_occluded_in(rays, &Rows::of(rays).laid(), lanes)
    }

    /// [`Frustum::for_occluded`] of the rays `laid` was made from: the same frustum.
    #[must_use]
    pub fn for_occluded_laid<const N: usize>(rays: &[Ray; N], laid: &PacketBoxes<N>, lanes: u32) -> Option<Self> {
        if off() || lanes == 0 {
            return None;
        }
        Self::for_occluded_in(rays, &Laid::from(laid), lanes)
    }

    fn for_occluded_in<const N: usize>(rays: &[Ray; N], laid: &Laid<'_, N>, lanes: u32) -> Option<Self> {
        Self::new_in(laid, lanes).or_else(|| {
            // `Frustum::ending`: the first lane's end is the target.
            let r = &rays[lanes.trailing_zeros() as usize];
            let target = r.origin + r.dir;
            target
                .is_finite()
                .then(|| Self::toward_in(laid, lanes, target))
                .flatten()
        })
    }

    /// The frustum of the `lanes` of `rays` whose lines all pass near one
    /// point behind their origins, the apex: the mirror image of the eye
    /// for the rays a plane mirror reflects from a camera packet (and of
    /// that image for their reflections in turn), or a small region for
    /// rays that a gently curved mirror reflects. The apex is where the
    /// lines of the first and last lane pass closest (in `f64`); the
    /// frustum's `radius` bounds every line's distance from it. `None` when
    /// a lane's origin does not lie ahead of the apex by more than the
    /// radius, a `t_min` is below 0 or NaN, a value is not finite, or the
    /// radius exceeds [`THROUGH_RADIUS`] of the coordinates' scale.
    ///
    /// NOTE: the answers do not change. Each point a lane reaches is a
    /// point of the line from the apex along the lane's direction, in
    /// front of the apex, moved by less than the radius (its bound is
    /// widened by 1e-5 of the scale, beyond this test's rounding). Boxes
    /// are widened by at least twice the radius ([`Frustum::rejects_box`])
    /// and triangles must clear it (the half-space test of shadow rays),
    /// on top of the usual margins.
    #[must_use]
    pub fn through<const N: usize>(rays: &[Ray; N], lanes: u32) -> Option<Self> {
        Self::through_in(rays, &Rows::of(rays).laid(), lanes)
    }

    fn through_in<const N: usize>(rays: &[Ray; N], laid: &Laid<'_, N>, lanes: u32) -> Option<Self> {
        if off() || lanes.count_ones() < 2 {
            return None;
        }
        let (i, j) = (lanes.trailing_zeros() as usize, 31 - lanes.leading_zeros() as usize);
        let apex = closest_point(&rays[i], &rays[j])?;
        if !apex.is_finite() {
            return None;
        }
        let (o, d) = (laid.o, laid.d);
        let quad = |v: &[f32; N], c: usize| f32x4::new([v[c], v[c + 1], v[c + 2], v[c + 3]]);
        let max3 = |v: [f32x4; 3]| v[0].abs().fast_max(v[1].abs()).fast_max(v[2].abs());
        const { assert!(N.is_multiple_of(4), "packets are whole registers of four lanes") };
        let (px, py, pz) = (f32x4::splat(apex.x), f32x4::splat(apex.y), f32x4::splat(apex.z));
        // Per lane: the origin's largest coordinate, the line's distance
        // from the apex (|v x d| / |d|, v from the apex to the origin) and
        // how far the origin lies ahead of the apex (v . d / |d|).
        let (mut scale4, mut far4, mut near4) = (f32x4::ZERO, f32x4::ZERO, f32x4::splat(f32::INFINITY));
        let mut bad = false;
        for c in (0..N).step_by(4) {
            let on = lane_mask(lanes >> c);
            let origin = [quad(&o[0], c), quad(&o[1], c), quad(&o[2], c)];
            let (dx, dy, dz) = (quad(&d[0], c), quad(&d[1], c), quad(&d[2], c));
            let (vx, vy, vz) = (origin[0] - px, origin[1] - py, origin[2] - pz);
            let (cx, cy, cz) = (vy * dz - vz * dy, vz * dx - vx * dz, vx * dy - vy * dx);
            let len = (dx * dx + dy * dy + dz * dz).sqrt();
            let off_line = (cx * cx + cy * cy + cz * cz).sqrt() / len;
            let ahead = (vx * dx + vy * dy + vz * dz) / len;
            let t_min = quad(laid.t_min, c);
            // NOTE: NaN fails every compare; `fine` is false for it.
            let fine = off_line.is_finite() & ahead.is_finite() & max3(origin).is_finite() & t_min.simd_ge(f32x4::ZERO);
            bad |= (on & !fine).to_bitmask() != 0;
            scale4 = on.bitselect(scale4.fast_max(max3(origin)), scale4);
            far4 = on.bitselect(far4.fast_max(off_line), far4);
            near4 = on.bitselect(near4.fast_min(ahead), near4);
        }
        if bad {
            return None;
        }
        let scale = scale4.to_array().into_iter().fold(apex.abs().max_element(), f32::max);
        let far = far4.to_array().into_iter().fold(0.0, f32::max);
        let near = near4.to_array().into_iter().fold(f32::INFINITY, f32::min);
        let radius = far * 1.001 + 1e-5 * scale;
        // NOTE: a NaN fails both compares.
        let fits = radius <= THROUGH_RADIUS * scale && near > radius;
        if !fits {
            return None;
        }
        Self::from_apex(apex, laid.d, lanes, false, false, scale, radius)
    }

    /// How far the lanes' lines may pass from the apex: 0 except for a
    /// frustum of [`Frustum::through`].
    #[must_use]
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// `true` for the frustum of rays leaving one origin (primary rays),
    /// whose triangle test (`Frustum::rejects`) is exact.
    #[must_use]
    pub fn is_shared_origin(&self) -> bool {
        self.shared_origin
    }

    /// The frustum with apex `o` around the directions of the `lanes` of
    /// `rays` (negated with `negate`: seen from `o`), which must point the
    /// same way along one axis.
    // PERF: one pass over all lanes with selects (no early exit, no branch
    // per lane): 3.5% of a kitchen primary-query profile as a lane iterator.
    fn from_apex<const N: usize>(
        o: glam::Vec3,
        dirs: &[[f32; N]; 3],
        lanes: u32,
        negate: bool,
        shared_origin: bool,
        scale: f32,
        radius: f32,
    ) -> Option<Self> {
        if lanes == 0 {
            return None;
        }
        let sg = if negate { -1.0 } else { 1.0 };
        let f = lanes.trailing_zeros() as usize;
        let first = glam::Vec3::new(dirs[0][f], dirs[1][f], dirs[2][f]) * sg;
        let k = first.abs().max_position();
        let (a, b) = ((k + 1) % 3, (k + 2) % 3);
        let s = first[k].signum();
        let (inf, zero) = (f32x4::splat(f32::INFINITY), f32x4::ZERO);
        let (mut lo_u4, mut hi_u4, mut lo_v4, mut hi_v4) = (inf, -inf, inf, -inf);
        let mut bad = false;
        // PERF: four lanes at a time (their two divisions in one `divps`
        // each); a lane loop was 3% of a primary-query profile. The same
        // quotients, and the same bounds up to the sign of a zero, which
        // the margin below removes.
        const { assert!(N.is_multiple_of(4), "packets are whole registers of four lanes") };
        let (sgv, sv) = (f32x4::splat(sg), f32x4::splat(s));
        for c in (0..N).step_by(4) {
            let on_bits = (lanes >> c) & 0xf;
            if on_bits == 0 {
                continue;
            }
            let on = lane_mask(on_bits);
            let axis = |x: usize| f32x4::new(std::array::from_fn(|i| dirs[x][c + i])) * sgv;
            let (dk, da, db) = (axis(k), axis(a), axis(b));
            // NOTE: a zero or NaN component along `k` fails the test.
            let ok = (dk * sv).simd_gt(zero) & dk.is_finite() & da.is_finite() & db.is_finite();
            bad |= (!ok).to_bitmask() & on_bits != 0;
            let (u, v) = (da / dk, db / dk);
            lo_u4 = (on & u.simd_lt(lo_u4)).bitselect(u, lo_u4);
            hi_u4 = (on & u.simd_gt(hi_u4)).bitselect(u, hi_u4);
            lo_v4 = (on & v.simd_lt(lo_v4)).bitselect(v, lo_v4);
            hi_v4 = (on & v.simd_gt(hi_v4)).bitselect(v, hi_v4);
        }
        let low = |x: f32x4| {
            x.to_array()
                .into_iter()
                .fold(f32::INFINITY, |m, y| if y < m { y } else { m })
        };
        let high = |x: f32x4| {
            x.to_array()
                .into_iter()
                .fold(f32::NEG_INFINITY, |m, y| if y > m { y } else { m })
        };
        let (lo_u, hi_u, lo_v, hi_v) = (low(lo_u4), high(hi_u4), low(lo_v4), high(hi_v4));
        if bad {
            return None;
        }
        if !(lo_u.is_finite() && hi_u.is_finite() && lo_v.is_finite() && hi_v.is_finite() && o.is_finite()) {
            return None;
        }
        let m = FRUSTUM_MARGIN * (1.0 + lo_u.abs().max(hi_u.abs()).max(lo_v.abs()).max(hi_v.abs()));
        Some(Self {
            origin: o,
            rect: [lo_u - m, hi_u + m, lo_v - m, hi_v + m],
            shared_origin,
            o: [o[k], o[a], o[b]].map(f32x4::splat),
            axes: [k, a, b],
            sign: f32x4::splat(s),
            lo_u: f32x4::splat(lo_u - m),
            hi_u: f32x4::splat(hi_u + m),
            lo_v: f32x4::splat(lo_v - m),
            hi_v: f32x4::splat(hi_v + m),
            slack: f32x4::splat(FRUSTUM_MARGIN * scale + radius),
            radius,
            box_scale: f32x4::splat(o.abs().max_element().max(2.0 * radius / FRUSTUM_MARGIN)),
            edge_margin: {
                let reach = 1.0 + (lo_u.abs().max(hi_u.abs()) + m) + (lo_v.abs().max(hi_v.abs()) + m);
                f32x4::splat(FRUSTUM_MARGIN * reach * reach)
            },
        })
    }

    /// `true` when no lane can reach any point of `bounds` (an instance's
    /// world box): the box, widened by [`FRUSTUM_MARGIN`] of its largest
    /// coordinate or the apex's (far more than the rounding of the
    /// transforms that take rays to object space), and by at least twice
    /// the [`Frustum::radius`], lies wholly behind the apex, or its part in
    /// front of the apex lies beyond one side of the rectangle.
    #[must_use]
    pub fn rejects_box(&self, bounds: &crate::geom::aabb::Aabb) -> bool {
        let [k, a, b] = self.axes;
        let s = self.sign.to_array()[0];
        let o = self.origin;
        let scale = bounds
            .min
            .abs()
            .max(bounds.max.abs())
            .max_element()
            .max(self.box_scale.to_array()[0]);
        let slack = FRUSTUM_MARGIN * scale;
        // The widened box's range along an axis, relative to the origin,
        // the dominant axis pointing forward.
        let range = |axis: usize| {
            let (lo, hi) = (bounds.min[axis] - slack - o[axis], bounds.max[axis] + slack - o[axis]);
            if s > 0.0 { (lo, hi) } else { (-hi, -lo) }
        };
        let (zlo, zhi) = range(k);
        if zlo.is_nan() || !zhi.is_finite() {
            return false;
        }
        // Every lane's reachable points lie in front of the apex (hits have
        // `t > 0`; a shadow lane's segment ends at the apex): a box wholly
        // behind it is out of reach, and one around it is reached, if at
        // all, by its part in front.
        if zhi <= 0.0 {
            return true;
        }
        let zlo = if zlo > 0.0 { zlo } else { 0.0 };
        let [lu, hu, lv, hv] = self.rect;
        let beyond = |(lo, hi): (f32, f32), low: f32, high: f32| {
            lo > (high * zlo).max(high * zhi) || hi < (low * zlo).min(low * zhi)
        };
        beyond(range(a), lu, hu) || beyond(range(b), lv, hv)
    }

    /// [`Frustum::rejects_box`] for the four boxes of `quad` at once (bit
    /// `i` set: no lane reaches box `i`), with its operations lane by lane,
    /// so the same answers.
    #[must_use]
    #[inline]
    pub fn rejects_box_quad(&self, quad: &BoxQuad) -> u32 {
        let [k, a, b] = self.axes;
        let o = self.origin;
        let (lo, hi) = (quad.min, quad.max);
        // `max` over the box's corners and the origin, as the scalar
        // `max_element` (finite boxes: no NaN to order).
        let scale = quad.largest_coordinate().fast_max(self.box_scale);
        let slack = f32x4::splat(FRUSTUM_MARGIN) * scale;
        let forward = self.sign.to_array()[0] > 0.0;
        let range = |axis: usize| {
            let oa = f32x4::splat(o[axis]);
            let (l, h) = (lo[axis] - slack - oa, hi[axis] + slack - oa);
            if forward { (l, h) } else { (-h, -l) }
        };
        let (zlo, zhi) = range(k);
        // The scalar test's refusals: a NaN near depth, an infinite or NaN
        // far one; then boxes wholly behind the apex, and the near depth of
        // a box around it moved up to the apex.
        let zero = f32x4::ZERO;
        let ok = zlo.simd_eq(zlo) & zhi.is_finite();
        let behind = zhi.simd_le(zero);
        let zlo = zlo.simd_gt(zero).bitselect(zlo, zero);
        let [lu, hu, lv, hv] = self.rect.map(f32x4::splat);
        let beyond = |(l, h): (f32x4, f32x4), low: f32x4, high: f32x4| {
            l.simd_gt((high * zlo).fast_max(high * zhi)) | h.simd_lt((low * zlo).fast_min(low * zhi))
        };
        (ok & (behind | beyond(range(a), lu, hu) | beyond(range(b), lv, hv))).to_bitmask()
    }

    /// Bit `j` set: no lane can hit triangle `j` of `block`. For a frustum of
    /// [`Frustum::new`] a projection test (the object-space rays share the
    /// origin the watertight test subtracts, so it sees what the lanes'
    /// tests see); for a shared target, [`Frustum::rejects_beyond`].
    #[inline]
    pub(crate) fn rejects(&self, block: &TriBlock) -> u32 {
        if !self.shared_origin {
            return self.rejects_beyond(block);
        }
        let [k, a, b] = self.axes;
        let zero = f32x4::ZERO;
        let (mut front, mut hi_u, mut lo_u, mut hi_v, mut lo_v) = (ALL, ALL, ALL, ALL, ALL);
        let mut p = [[zero; 3]; 3];
        for (vert, p) in p.iter_mut().enumerate() {
            // Relative to the origin, the dominant axis pointing forward:
            // the vertex projects to (x / z, y / z).
            let z = (block.coord(vert, k) - self.o[0]) * self.sign;
            let x = (block.coord(vert, a) - self.o[1]) * self.sign;
            let y = (block.coord(vert, b) - self.o[2]) * self.sign;
            front &= z.simd_gt(zero);
            hi_u &= x.simd_gt(self.hi_u * z);
            lo_u &= x.simd_lt(self.lo_u * z);
            hi_v &= y.simd_gt(self.hi_v * z);
            lo_v &= y.simd_lt(self.lo_v * z);
            *p = [z, x, y];
        }
        let beyond = (front & (hi_u | lo_u | hi_v | lo_v)).to_bitmask();
        // PERF: a triangle reaching behind the origin has no projection to
        // test; the edge test decides it (large walls and floors around the
        // eye: most of a museum packet's leaf tests). Others skip it: where
        // the projection test could decide, the edge test did not pay.
        if front.to_bitmask() | beyond == 0xf {
            return beyond;
        }
        beyond | self.edges_apart(&p).to_bitmask()
    }

    /// The triangles (vertices relative to the origin, `[z, x, y]`) whose
    /// edges leave the rectangle on two sides: the plane through the
    /// origin and one edge has the whole rectangle strictly on one side,
    /// and the plane through another edge has it on the other. A line
    /// through the origin meets a triangle only where its three edge
    /// functions (Plücker products, linear in the direction) share a sign,
    /// so no lane's ray meets these, whichever side of the origin the
    /// triangle lies on. The edge function at a direction `(1, u, v)` is
    /// `n_z + u n_x + v n_y`, `n` the cross product of the edge's end
    /// points, so its least and largest values over the rectangle come
    /// from the rectangle's bounds.
    /// NOTE: a side counts only when it clears a margin of
    /// [`FRUSTUM_MARGIN`] of the products' magnitude (the end points'
    /// largest coordinates multiplied, times the square of the rectangle's
    /// reach `1 + |u| + |v|`), far more than the rounding of these products
    /// and of the lanes' own edge functions; an infinite or NaN value
    /// decides nothing.
    #[inline]
    fn edges_apart(&self, p: &[[f32x4; 3]; 3]) -> f32x4 {
        let none = f32x4::ZERO;
        let (mut pos, mut neg) = (none, none);
        let mag = p.map(|[z, x, y]| z.abs().fast_max(x.abs()).fast_max(y.abs()));
        for i in 0..3 {
            let j = (i + 1) % 3;
            let ([pz, px, py], [qz, qx, qy]) = (p[i], p[j]);
            let nz = px * qy - py * qx;
            let nx = py * qz - pz * qy;
            let ny = pz * qx - px * qz;
            let (u0, u1) = (self.lo_u * nx, self.hi_u * nx);
            let (v0, v1) = (self.lo_v * ny, self.hi_v * ny);
            let most = nz + u0.fast_max(u1) + v0.fast_max(v1);
            let least = nz + u0.fast_min(u1) + v0.fast_min(v1);
            let margin = self.edge_margin * mag[i] * mag[j];
            let sure = margin.is_finite() & most.is_finite() & least.is_finite();
            pos |= sure & least.simd_gt(margin);
            neg |= sure & most.simd_lt(-margin);
        }
        pos & neg
    }

    /// [`Frustum::rejects`] for a shared-target frustum (shadow rays): the
    /// lanes' segments lie within the tolerance of [`Frustum::toward`] of
    /// the lines from the apex through the rectangle, on the inner side of
    /// each of its four planes. A triangle whose three vertices lie beyond
    /// one plane by more than the slack (the frustum's, plus
    /// [`FRUSTUM_MARGIN`] of the vertex's own largest coordinate, for the
    /// rounding of the test) lies beyond it wholly, out of every segment's
    /// reach.
    #[inline]
    fn rejects_beyond(&self, block: &TriBlock) -> u32 {
        let [k, a, b] = self.axes;
        let one = f32x4::splat(1.0);
        let margin = f32x4::splat(FRUSTUM_MARGIN);
        let (mut hi_u, mut lo_u, mut hi_v, mut lo_v) = (ALL, ALL, ALL, ALL);
        let (wu_hi, wu_lo) = (one + self.hi_u.abs(), one + self.lo_u.abs());
        let (wv_hi, wv_lo) = (one + self.hi_v.abs(), one + self.lo_v.abs());
        for vert in 0..3 {
            let (pk, pa, pb) = (block.coord(vert, k), block.coord(vert, a), block.coord(vert, b));
            let slack = self.slack + margin * pk.abs().max(pa.abs()).max(pb.abs());
            let z = (pk - self.o[0]) * self.sign;
            let x = (pa - self.o[1]) * self.sign;
            let y = (pb - self.o[2]) * self.sign;
            hi_u &= (x - self.hi_u * z).simd_gt(slack * wu_hi);
            lo_u &= (self.lo_u * z - x).simd_gt(slack * wu_lo);
            hi_v &= (y - self.hi_v * z).simd_gt(slack * wv_hi);
            lo_v &= (self.lo_v * z - y).simd_gt(slack * wv_lo);
        }
        (hi_u | lo_u | hi_v | lo_v).to_bitmask()
    }
}

/// A packet's rays laid out axis by axis, as the frusta read them: gathered
/// from the rays ([`Rows`]) or borrowed from a [`PacketBoxes`] made from
/// them (the same values).
struct Laid<'a, const N: usize> {
    o: &'a [[f32; N]; 3],
    d: &'a [[f32; N]; 3],
    t_min: &'a [f32; N],
    t_max: &'a [f32; N],
}

impl<'a, const N: usize> From<&'a PacketBoxes<N>> for Laid<'a, N> {
    fn from(b: &'a PacketBoxes<N>) -> Self {
        let (o, d, t_min, t_max) = b.rows();
        Self { o, d, t_min, t_max }
    }
}

/// A packet's rays gathered into rows, axis by axis ([`Laid`] borrows them).
struct Rows<const N: usize> {
    o: [[f32; N]; 3],
    d: [[f32; N]; 3],
    t_min: [f32; N],
    t_max: [f32; N],
}

impl<const N: usize> Rows<N> {
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn of(rays: &[Ray; N]) -> Self {
        Self {
            o: by_axis(rays, |r| r.origin),
            d: by_axis(rays, |r| r.dir),
            t_min: std::array::from_fn(|l| rays[l].t_min),
            t_max: std::array::from_fn(|l| rays[l].t_max),
        }
    }

    fn laid(&self) -> Laid<'_, N> {
        Laid {
            o: &self.o,
            d: &self.d,
            t_min: &self.t_min,
            t_max: &self.t_max,
        }
    }
}

/// The largest radius of a [`Frustum::through`], relative to the largest
/// coordinate of its apex and its lanes' origins: packets whose lines pass
/// farther from one point get no frustum.
pub const THROUGH_RADIUS: f32 = 1e-2;

/// Four lanes of a mask as `f32x4` lane masks: lane `i` set when bit `i` is.
// PERF: forced inline, as the closures it replaces in the hot frusta were.
#[allow(clippy::inline_always)]
#[inline(always)]
fn lane_mask(bits: u32) -> f32x4 {
    f32x4::new(std::array::from_fn(|i| {
        f32::from_bits(if bits & (1 << i) != 0 { u32::MAX } else { 0 })
    }))
}

/// The point of `a`'s line nearest to `b`'s line, computed in `f64`;
/// `None` when the lines are parallel to within rounding.
fn closest_point(a: &Ray, b: &Ray) -> Option<glam::Vec3> {
    let (oa, da) = (a.origin.as_dvec3(), a.dir.as_dvec3());
    let (ob, db) = (b.origin.as_dvec3(), b.dir.as_dvec3());
    let w = oa - ob;
    let (aa, ab, bb) = (da.dot(da), da.dot(db), db.dot(db));
    let (aw, bw) = (da.dot(w), db.dot(w));
    let den = aa * bb - ab * ab;
    // NOTE: a NaN fails the compare.
    let apart = den > 1e-12 * aa * bb;
    if !apart {
        return None;
    }
    let s = (ab * bw - bb * aw) / den;
    Some((oa + da * s).as_vec3())
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    use super::*;
    use crate::geom::aabb::Aabb;
    use crate::geom::triangle::Triangle;
    use crate::geom::triangle::intersect_triangle;
    use crate::testing::meshgen;

    /// The rectangle and the refusals of the four-lane pass are a lane
    /// loop's, for camera packets, packets with a lane pointing back, along
    /// an axis or with NaN, partial masks, widths of 16, 8 and 4.
    #[test]
    fn rectangles_four_lanes_at_a_time_are_the_lane_loops() {
        fn lane_loop<const N: usize>(rays: &[Ray; N], lanes: u32) -> Option<[u32; 4]> {
            let first = rays[lanes.trailing_zeros() as usize].dir;
            let k = first.abs().max_position();
            let (a, b) = ((k + 1) % 3, (k + 2) % 3);
            let s = first[k].signum();
            let (mut lo_u, mut hi_u, mut lo_v, mut hi_v) =
                (f32::INFINITY, -f32::INFINITY, f32::INFINITY, -f32::INFINITY);
            for l in lanes_of(lanes) {
                let d = rays[l].dir;
                if !(d[k] * s > 0.0 && d.is_finite()) {
                    return None;
                }
                let (u, v) = (d[a] / d[k], d[b] / d[k]);
                (lo_u, hi_u, lo_v, hi_v) = (lo_u.min(u), hi_u.max(u), lo_v.min(v), hi_v.max(v));
            }
            if !(lo_u.is_finite() && hi_u.is_finite() && lo_v.is_finite() && hi_v.is_finite()) {
                return None;
            }
            let m = FRUSTUM_MARGIN * (1.0 + lo_u.abs().max(hi_u.abs()).max(lo_v.abs()).max(hi_v.abs()));
            Some([lo_u - m, hi_u + m, lo_v - m, hi_v + m].map(f32::to_bits))
        }
        fn check<const N: usize>(rng: &mut SmallRng, rays: [Ray; N]) {
            let mut rays = rays;
            let o = rays[0].origin;
            match rng.random_range(0..6) {
                0 => {
                    let l = rng.random_range(0..N);
                    rays[l] = Ray::infinite(o, -rays[l].dir);
                }
                1 => rays[rng.random_range(0..N)] = Ray::infinite(o, Vec3::new(0.0, -0.0, -1.0)),
                2 => rays[rng.random_range(0..N)] = Ray::infinite(o, Vec3::new(f32::NAN, 0.1, -1.0)),
                _ => {}
            }
            let lanes = rng.random::<u32>() & (u32::MAX >> (32 - N)) | 1 << rng.random_range(0..N);
            let got = Frustum::new(&rays, lanes).map(|f| f.rect.map(f32::to_bits));
            assert_eq!(got, lane_loop(&rays, lanes), "{N} lanes {lanes:#x}");
        }
        let mut rng = SmallRng::seed_from_u64(31);
        let eye = Vec3::new(0.5, -0.25, 2.0);
        for p in blocks(eye, Vec3::new(0.0, 0.0, -10.0))
            .iter()
            .chain(&blocks(eye, Vec3::new(9.0, 1.0, 2.5)))
        {
            for _ in 0..20 {
                check::<16>(&mut rng, *p);
                check::<8>(&mut rng, std::array::from_fn(|l| p[l]));
                check::<4>(&mut rng, std::array::from_fn(|l| p[l + 3]));
            }
        }
    }

    /// Four lanes at a time, a shared-target frustum is made for the same
    /// packets as the lane loop makes it, with the same slack: shadow
    /// packets, a lane off target, past the target, with a NaN or huge
    /// origin, partial masks, widths of 16, 8 and 4.
    #[test]
    fn shared_targets_four_lanes_at_a_time_are_the_lane_loops() {
        fn lane_loop<const N: usize>(rays: &[Ray; N], lanes: u32, target: Vec3) -> Option<f32> {
            let scale = lanes_of(lanes).fold(target.abs().max_element(), |s, l| {
                s.max(rays[l].origin.abs().max_element())
            });
            for l in lanes_of(lanes) {
                let r = &rays[l];
                let end = r.origin + r.dir;
                let tolerance = 1e-6 * scale.max(end.abs().max_element()).max(1e-30);
                let off_target = (end - target).abs().max_element();
                if !(r.t_max <= 1.0 && off_target <= tolerance && end.is_finite()) {
                    return None;
                }
            }
            Some(scale)
        }
        fn check<const N: usize>(rng: &mut SmallRng) {
            let target = Vec3::new(rng.random_range(-5.0..5.0), 4.0, rng.random_range(-5.0..5.0));
            let mut rays: [Ray; N] = std::array::from_fn(|_| {
                let p = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..0.0),
                    rng.random_range(-1.0..1.0),
                );
                Ray::new(p, target - p, 0.0, 1.0 - 1e-4)
            });
            let l = rng.random_range(0..N);
            let r = rays[l];
            match rng.random_range(0..8) {
                0 => rays[l] = Ray::new(r.origin, r.dir * 1.001, 0.0, 1.0 - 1e-4),
                1 => rays[l] = Ray::new(r.origin, r.dir, 0.0, 1.5),
                2 => {
                    let mut o = r.origin;
                    o[rng.random_range(0..3)] = f32::NAN;
                    rays[l] = Ray::new(o, r.dir, 0.0, 1.0);
                }
                3 => {
                    let p = Vec3::new(3e4, -2.0, 1.0);
                    rays[l] = Ray::new(p, target - p, 0.0, 1.0);
                }
                4 => rays[l] = Ray::new(r.origin, r.dir * (1.0 + 1e-7), 0.0, f32::NAN),
                _ => {}
            }
            let lanes = rng.random::<u32>() & (u32::MAX >> (32 - N)) | 1 << rng.random_range(0..N);
            // The rectangle's own refusals (lanes pointing both ways along
            // its axis) are the other test's.
            let want = lane_loop(&rays, lanes, target).filter(|&s| {
                Frustum::from_apex(target, &by_axis(&rays, |r| r.dir), lanes, true, false, s, 0.0).is_some()
            });
            let got = Frustum::toward(&rays, lanes, target).map(|f| f.slack.to_array()[0].to_bits());
            assert_eq!(
                got,
                want.map(|s| (FRUSTUM_MARGIN * s).to_bits()),
                "{N} lanes {lanes:#x}"
            );
        }
        let mut rng = SmallRng::seed_from_u64(44);
        for _ in 0..4000 {
            check::<32>(&mut rng);
            check::<16>(&mut rng);
            check::<8>(&mut rng);
            check::<4>(&mut rng);
        }
    }

    /// 4x4 pixel blocks of a camera, as the renderer's primary packets.
    /// Every field of a frustum, as bits.
    fn frustum_bits(f: &Frustum) -> Vec<u32> {
        let mut v: Vec<u32> = f.origin.to_array().map(f32::to_bits).to_vec();
        v.extend(f.rect.map(f32::to_bits));
        v.push(u32::from(f.shared_origin));
        v.extend(f.axes.map(|a| a as u32));
        for x in f.o.iter().chain([
            &f.sign,
            &f.lo_u,
            &f.hi_u,
            &f.lo_v,
            &f.hi_v,
            &f.slack,
            &f.box_scale,
            &f.edge_margin,
        ]) {
            v.extend(x.to_array().map(f32::to_bits));
        }
        v.push(f.radius.to_bits());
        v
    }

    /// Frusta made from a packet's lanes laid out ([`PacketBoxes`]) are the
    /// frusta made from its rays, field for field, bit for bit: camera,
    /// shadow and mirrored packets, with lanes pointing back, along an axis,
    /// with NaN or past the target, and partial masks.
    #[test]
    fn frusta_from_laid_out_lanes_are_the_rays_frusta() {
        let mut rng = SmallRng::seed_from_u64(77);
        let eye = Vec3::new(0.5, -0.25, 2.0);
        let light = Vec3::new(-3.0, 6.0, 1.0);
        let camera = blocks(eye, Vec3::new(0.0, 0.0, -10.0));
        let mirror = mirrored(&camera, -4.0);
        let sphere = curved(&camera, Vec3::new(0.0, 0.0, -6.0), 3.0);
        assert!(!mirror.is_empty() && !sphere.is_empty());
        let (mut made, mut none) = (0, 0);
        let all = camera.iter().chain(&mirror).chain(&sphere).collect::<Vec<_>>();
        for (k, p) in all.into_iter().enumerate() {
            for round in 0..6 {
                let mut rays = if k % 2 == 1 {
                    shadow_packet(p, light, &mut rng)
                } else {
                    *p
                };
                let l = rng.random_range(0..16);
                match round {
                    1 => rays[l] = Ray::infinite(rays[l].origin, -rays[l].dir),
                    2 => rays[l] = Ray::infinite(rays[l].origin, Vec3::new(0.0, -0.0, -1.0)),
                    3 => rays[l] = Ray::infinite(rays[l].origin, Vec3::new(f32::NAN, 0.1, -1.0)),
                    4 => rays[l] = Ray::new(rays[l].origin, rays[l].dir * 1.5, 0.0, 1.0),
                    _ => {}
                }
                let lanes = if round == 5 {
                    rng.random::<u32>() & 0xffff | 1
                } else {
                    0xffff
                };
                let laid = PacketBoxes::new(&rays, lanes);
                let pairs = [
                    (Frustum::new(&rays, lanes), Frustum::new_laid(&laid, lanes)),
                    (
                        Frustum::toward(&rays, lanes, light),
                        Frustum::toward_laid(&laid, lanes, light),
                    ),
                    (
                        Frustum::for_intersect(&rays, lanes),
                        Frustum::for_intersect_laid(&rays, &laid, lanes),
                    ),
                    (
                        Frustum::for_occluded(&rays, lanes),
                        Frustum::for_occluded_laid(&rays, &laid, lanes),
                    ),
                    // The kinds in each query's order, made one by one.
                    (
                        Frustum::new(&rays, lanes).or_else(|| Frustum::through(&rays, lanes)),
                        Frustum::for_intersect(&rays, lanes),
                    ),
                    (
                        Frustum::new(&rays, lanes).or_else(|| Frustum::ending(&rays, lanes)),
                        Frustum::for_occluded(&rays, lanes),
                    ),
                ];
                for (i, (want, got)) in pairs.iter().enumerate() {
                    assert_eq!(
                        got.as_ref().map(frustum_bits),
                        want.as_ref().map(frustum_bits),
                        "packet {k}, round {round}, kind {i}"
                    );
                    if want.is_some() { made += 1 } else { none += 1 }
                }
            }
        }
        assert!(made > 500 && none > 500, "frusta made {made}, refused {none}");
    }

    fn blocks(eye: Vec3, at: Vec3) -> Vec<[Ray; 16]> {
        let (w, h) = (32, 24);
        let rays = meshgen::camera_rays(eye, at, w, h, 50.0);
        let mut out = Vec::new();
        for by in (0..h).step_by(4) {
            for bx in (0..w).step_by(4) {
                out.push(std::array::from_fn(|l| rays[(by + l / 4) * w + bx + l % 4]));
            }
        }
        out
    }

    /// Triangles near and across the packets' edges: a soup, and small
    /// triangles with a vertex exactly on a lane's ray.
    fn triangles(eye: Vec3, packets: &[[Ray; 16]], seed: u64) -> Vec<Triangle> {
        let mut rng = SmallRng::seed_from_u64(seed);
        let b = Aabb::new(eye + Vec3::new(-4.0, -3.0, -12.0), eye + Vec3::new(4.0, 3.0, -1.0));
        let mut tris = meshgen::random_soup(600, seed, b, 0.4);
        for p in packets.iter().step_by(3) {
            let r = &p[rng.random_range(0..16)];
            let v = r.origin + r.dir * rng.random_range(1.0..10.0);
            let mut e = || Vec3::new(rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05), 0.0);
            let (e1, e2) = (e(), e());
            tris.push([v, v + e1, v + e2]);
        }
        tris
    }

    /// Shadow rays from points in front of the eye (along the camera
    /// packet's rays) to the light, as the renderer makes them.
    fn shadow_packet(p: &[Ray; 16], light: Vec3, rng: &mut SmallRng) -> [Ray; 16] {
        std::array::from_fn(|l| {
            let q = p[l].origin + p[l].dir * rng.random_range(2.0..8.0);
            Ray::new(q, light - q, 0.0, 1.0 - 1e-4)
        })
    }

    /// Every triangle the frustum rejects is missed by every lane's exact
    /// test, and most far-off triangles are rejected.
    fn check_triangles(eye: Vec3, at: Vec3, seed: u64) -> (usize, usize) {
        let packets = blocks(eye, at);
        let tris = triangles(eye, &packets, seed);
        let (mut rejected, mut total) = (0, 0);
        for p in &packets {
            let f = Frustum::new(p, u32::from(u16::MAX)).expect("camera lanes share an origin");
            assert!(f.is_shared_origin());
            for chunk in (0..tris.len() as u32).collect::<Vec<_>>().chunks(4) {
                let block = TriBlock::pack(chunk, &tris);
                let mask = f.rejects(&block);
                for (j, &id) in chunk.iter().enumerate() {
                    total += 1;
                    if mask & (1 << j) == 0 {
                        continue;
                    }
                    rejected += 1;
                    for r in p {
                        assert!(
                            intersect_triangle(r, &tris[id as usize], f32::INFINITY).is_none(),
                            "triangle {id} rejected but hit"
                        );
                    }
                }
            }
        }
        (rejected, total)
    }

    #[test]
    fn rejected_triangles_are_missed_by_every_lane() {
        for (k, (eye, at)) in [
            (Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0)),
            (Vec3::new(0.3, 0.2, 0.1), Vec3::new(0.5, -0.2, -1.0)),
            // Far from the world's origin: the rounding of the subtraction.
            (Vec3::splat(3.0e4), Vec3::splat(3.0e4) + Vec3::new(0.1, 0.0, -1.0)),
        ]
        .into_iter()
        .enumerate()
        {
            let (rejected, total) = check_triangles(eye, at, k as u64);
            assert!(rejected * 2 > total, "only {rejected} of {total} culled");
        }
    }

    /// Triangles reaching behind the eye, which the projection test cannot
    /// decide: the edge test rejects only triangles every lane misses,
    /// including those with an edge along a lane's own ray (zero edge
    /// function) or a vertex on it, and rejects most of the far-off ones.
    #[test]
    fn triangles_around_the_eye_are_rejected_only_when_missed() {
        let mut rng = SmallRng::seed_from_u64(17);
        let mut n_behind = 0;
        for (eye, at) in [
            (Vec3::new(0.2, 1.0, 0.5), Vec3::new(0.0, 0.8, -5.0)),
            (Vec3::splat(2.0e4), Vec3::splat(2.0e4) + Vec3::new(0.3, -0.1, -1.0)),
        ] {
            let packets = blocks(eye, at);
            let (mut rejected, mut total) = (0, 0);
            for p in &packets {
                let f = Frustum::new(p, u32::from(u16::MAX)).expect("camera lanes share an origin");
                let mut tris: Vec<Triangle> = (0..40)
                    .map(|_| {
                        let mut v = || {
                            eye + Vec3::new(
                                rng.random_range(-6.0..6.0),
                                rng.random_range(-3.0..3.0),
                                rng.random_range(-8.0..4.0),
                            )
                        };
                        [v(), v(), v()]
                    })
                    .collect();
                // An edge along a lane's ray, through the eye; a vertex on
                // a lane's ray with the others behind the eye.
                let r = &p[rng.random_range(0..16)];
                tris.push([eye + r.dir * 3.0, eye - r.dir * 2.0, eye + Vec3::new(4.0, 0.0, 1.0)]);
                tris.push([
                    eye + r.dir * 5.0,
                    eye + Vec3::new(-1.0, 2.0, 3.0),
                    eye + Vec3::new(1.0, -2.0, 2.0),
                ]);
                for chunk in (0..tris.len() as u32).collect::<Vec<_>>().chunks(4) {
                    let mask = f.rejects(&TriBlock::pack(chunk, &tris));
                    for (j, &id) in chunk.iter().enumerate() {
                        let t = &tris[id as usize];
                        let reaches_back = t.iter().any(|v| (*v - eye).dot(at - eye) < 0.0);
                        total += 1;
                        n_behind += usize::from(reaches_back);
                        if mask & (1 << j) == 0 {
                            continue;
                        }
                        rejected += 1;
                        for r in p {
                            assert!(
                                intersect_triangle(r, t, f32::INFINITY).is_none(),
                                "triangle {t:?} rejected but hit"
                            );
                        }
                    }
                }
            }
            assert!(rejected * 2 > total, "only {rejected} of {total} rejected");
        }
        assert!(n_behind > 1000, "{n_behind} triangles reach behind the eye");
    }

    /// Four boxes at a time, the frustum answers as it does box by box:
    /// camera and shadow frusta, boxes in front, behind, around the apex,
    /// flat, far off and huge, partial quads.
    #[test]
    fn box_quads_answer_as_single_boxes() {
        let mut rng = SmallRng::seed_from_u64(23);
        let eye = Vec3::new(0.1, 0.5, 2.0);
        let light = Vec3::new(2.0, 4.0, 1.0);
        let (mut rejected, mut n) = (0, 0);
        for p in blocks(eye, Vec3::new(0.3, -0.2, -5.0)).iter().step_by(3) {
            let shadow = shadow_packet(p, light, &mut rng);
            let frusta = [
                Frustum::new(p, u32::from(u16::MAX)).unwrap(),
                Frustum::toward(&shadow, u32::from(u16::MAX), light).unwrap(),
            ];
            for f in &frusta {
                let boxes: Vec<Aabb> = (0..22)
                    .map(|i| {
                        let c = eye
                            + Vec3::new(
                                rng.random_range(-8.0..8.0),
                                rng.random_range(-6.0..6.0),
                                rng.random_range(-12.0..6.0),
                            );
                        let mut h = Vec3::new(
                            rng.random_range(0.0..2.0),
                            rng.random_range(0.0..2.0),
                            rng.random_range(0.0..2.0),
                        );
                        match i % 7 {
                            0 => h.y = 0.0,
                            1 => return Aabb::new(eye - Vec3::splat(0.5), eye + Vec3::splat(0.5)),
                            2 => return Aabb::new(c * 1e4, c * 1e4 + Vec3::splat(3e3)),
                            _ => {}
                        }
                        Aabb::new(c - h, c + h)
                    })
                    .collect();
                for chunk in boxes.chunks(4) {
                    let mask = f.rejects_box_quad(&BoxQuad::pack(chunk));
                    for (j, b) in chunk.iter().enumerate() {
                        let want = f.rejects_box(b);
                        assert_eq!(mask & (1 << j) != 0, want, "box {b:?}");
                        rejected += usize::from(want);
                        n += 1;
                    }
                    // Padding lanes repeat the last box's answer.
                    let last = chunk.len() - 1;
                    for j in chunk.len()..4 {
                        assert_eq!(mask >> j & 1, mask >> last & 1);
                    }
                }
            }
        }
        assert!(rejected * 4 > n && rejected < n, "{rejected} of {n} rejected");
    }

    #[test]
    fn rejected_boxes_are_missed_by_every_lane() {
        let mut rng = SmallRng::seed_from_u64(7);
        let eye = Vec3::new(0.1, 0.5, 2.0);
        let light = Vec3::new(2.0, 4.0, 1.0);
        let packets = blocks(eye, Vec3::new(0.0, 0.0, -5.0));
        let b = Aabb::new(Vec3::new(-5.0, -3.0, -10.0), Vec3::new(5.0, 5.0, 2.0));
        let tris = meshgen::random_soup(400, 3, b, 0.6);
        let (mut culled, mut n) = (0, 0);
        for p in &packets {
            let shadow = shadow_packet(p, light, &mut rng);
            let frusta = [
                Frustum::new(p, u32::from(u16::MAX)).unwrap(),
                Frustum::toward(&shadow, u32::from(u16::MAX), light).expect("shadow rays end at the light"),
            ];
            for (f, rays) in frusta.iter().zip([p, &shadow]) {
                for t in &tris {
                    n += 1;
                    if f.rejects_box(&Aabb::from_points(t)) {
                        culled += 1;
                        for r in rays {
                            assert!(intersect_triangle(r, t, r.t_max).is_none());
                        }
                    }
                }
            }
        }
        assert!(culled * 2 > n, "only {culled} of {n} boxes culled");
    }

    /// Boxes behind the apex (the eye, or the light seen from the lanes'
    /// origins) and around it: rejected when wholly behind, or when their
    /// part in front lies beyond a side; never when a lane hits a triangle
    /// in them. Counts each kind, so the test sees both.
    #[test]
    fn boxes_behind_and_around_the_apex() {
        let mut rng = SmallRng::seed_from_u64(31);
        let eye = Vec3::new(0.1, 0.5, 2.0);
        let light = Vec3::new(2.0, 4.0, 1.0);
        let packets = blocks(eye, Vec3::new(0.3, -0.2, -5.0));
        let (mut behind, mut around, mut hit_around) = (0, 0, 0);
        for p in packets.iter().step_by(2) {
            let shadow = shadow_packet(p, light, &mut rng);
            let frusta = [
                (Frustum::new(p, u32::from(u16::MAX)).unwrap(), p, eye, Vec3::Z),
                // Seen from the origins, the light's far side is behind it.
                (
                    Frustum::toward(&shadow, u32::from(u16::MAX), light).unwrap(),
                    &shadow,
                    light,
                    (light - eye).normalize(),
                ),
            ];
            for (f, rays, apex, back) in &frusta {
                let centre = |rng: &mut SmallRng, depth: f32| {
                    *apex
                        + *back * depth
                        + Vec3::new(
                            rng.random_range(-3.0..3.0),
                            rng.random_range(-3.0..3.0),
                            rng.random_range(-3.0..3.0),
                        )
                };
                for i in 0..60 {
                    // Wholly behind, around the apex (some holding it), or
                    // in front along the lanes (reached: the control).
                    let far = rng.random_range(2.0..8.0);
                    let c = match i % 3 {
                        0 => centre(&mut rng, far),
                        1 => centre(&mut rng, 0.0),
                        _ => rays[rng.random_range(0..16)].origin + rays[rng.random_range(0..16)].dir * 0.5,
                    };
                    let b = Aabb::new(c - Vec3::splat(1.0), c + Vec3::splat(1.0));
                    let tris = meshgen::random_soup(40, rng.random(), b, 0.8);
                    let hit = rays
                        .iter()
                        .any(|r| tris.iter().any(|t| intersect_triangle(r, t, r.t_max).is_some()));
                    let bounds = tris.iter().fold(Aabb::EMPTY, |b, t| b.union(Aabb::from_points(t)));
                    let rejected = f.rejects_box(&bounds);
                    assert_eq!(f.rejects_box_quad(&BoxQuad::pack(&[bounds])) & 1 != 0, rejected);
                    assert!(!(rejected && hit), "box {bounds:?} rejected but hit");
                    let depth = |v: Vec3| (v - *apex).dot(f.sign.to_array()[0] * unit(f.axes[0]));
                    let (lo, hi) = (depth(bounds.min), depth(bounds.max));
                    if lo.max(hi) < 0.0 {
                        behind += usize::from(rejected);
                    } else if lo.min(hi) < 0.0 {
                        around += usize::from(rejected);
                        hit_around += usize::from(hit);
                    }
                }
            }
        }
        assert!(
            behind > 100 && around > 20 && hit_around > 5,
            "{behind} behind, {around} around ({hit_around} hit)"
        );
    }

    fn unit(axis: usize) -> Vec3 {
        Vec3::AXES[axis]
    }

    #[test]
    fn shadow_packets_cull_only_triangles_no_segment_reaches() {
        let mut rng = SmallRng::seed_from_u64(9);
        let eye = Vec3::new(0.1, 0.5, 2.0);
        let light = Vec3::new(2.0, 4.0, 1.0);
        let packets = blocks(eye, Vec3::new(0.0, 0.0, -5.0));
        let b = Aabb::new(Vec3::new(-5.0, -3.0, -10.0), Vec3::new(5.0, 5.0, 2.0));
        let mut tris = meshgen::random_soup(400, 5, b, 0.6);
        let (mut culled, mut n) = (0, 0);
        for p in &packets {
            let shadow = shadow_packet(p, light, &mut rng);
            // Small triangles touching segments, one of them at the light.
            tris.truncate(400);
            for r in shadow.iter().step_by(4) {
                let v = r.origin + r.dir * rng.random_range(0.05..0.9999);
                tris.push([v, v + Vec3::new(0.01, 0.0, 0.0), v + Vec3::new(0.0, 0.01, 0.002)]);
            }
            tris.push([light, light + Vec3::X * 0.01, light + Vec3::Y * 0.01]);
            let f = Frustum::ending(&shadow, u32::from(u16::MAX)).expect("shadow rays share their end");
            assert!(!f.is_shared_origin());
            for chunk in (0..tris.len() as u32).collect::<Vec<_>>().chunks(4) {
                let mask = f.rejects(&TriBlock::pack(chunk, &tris));
                for (j, &id) in chunk.iter().enumerate() {
                    n += 1;
                    if mask & (1 << j) != 0 {
                        culled += 1;
                        for r in &shadow {
                            assert!(
                                intersect_triangle(r, &tris[id as usize], r.t_max).is_none(),
                                "triangle {id} culled but hit"
                            );
                        }
                    }
                }
            }
        }
        assert!(culled * 2 > n, "only {culled} of {n} triangles culled");
    }

    #[test]
    fn packets_without_a_shared_apex_get_no_frustum() {
        let eye = Vec3::ZERO;
        let p = blocks(eye, Vec3::new(0.0, 0.0, -1.0))[0];
        let mut moved = p;
        moved[3] = Ray::infinite(Vec3::new(0.0, 0.0, 1e-6), p[3].dir);
        assert!(Frustum::new(&moved, u32::from(u16::MAX)).is_none());
        // The moved lane left out of the mask: a frustum again.
        assert!(Frustum::new(&moved, u32::from(u16::MAX) & !(1 << 3)).is_some());
        // Opposite signs along the dominant axis, a zero component there.
        let mut back = p;
        back[0] = Ray::infinite(eye, Vec3::new(0.0, 0.0, 1.0));
        assert!(Frustum::new(&back, u32::from(u16::MAX)).is_none());
        let mut flat = p;
        flat[0] = Ray::infinite(eye, Vec3::new(1.0, 0.0, 0.0));
        assert!(Frustum::new(&flat, u32::from(u16::MAX)).is_none());
        assert!(Frustum::new(&p, 0).is_none());
        // Rays that do not end at the target.
        assert!(Frustum::toward(&p, u32::from(u16::MAX), Vec3::new(0.0, 0.0, -1.0)).is_none());
    }

    /// The camera packets' rays reflected by the plane `z = plane_z`
    /// ([`meshgen::mirrored_rays`]), packet by packet.
    fn mirrored(packets: &[[Ray; 16]], plane_z: f32) -> Vec<[Ray; 16]> {
        let at = Vec3::new(0.0, 0.0, plane_z);
        packets
            .iter()
            .filter_map(|p| meshgen::mirrored_rays(p, at, Vec3::Z).try_into().ok())
            .collect()
    }

    /// The same off a sphere ([`meshgen::sphere_mirrored_rays`]): packets
    /// whose every lane meets it.
    fn curved(packets: &[[Ray; 16]], centre: Vec3, radius: f32) -> Vec<[Ray; 16]> {
        packets
            .iter()
            .filter_map(|p| meshgen::sphere_mirrored_rays(p, centre, radius).try_into().ok())
            .collect()
    }

    #[test]
    fn mirrored_packets_pass_through_the_eyes_image() {
        for eye in [Vec3::new(0.1, 0.5, 2.0), Vec3::new(3.0e3, -2.0e3, 2.5e3)] {
            let packets = blocks(eye, eye + Vec3::new(0.05, -0.1, -1.0));
            let image = Vec3::new(eye.x, eye.y, 2.0 * (eye.z - 3.0) - eye.z);
            for p in mirrored(&packets, eye.z - 3.0) {
                let f = Frustum::through(&p, u32::from(u16::MAX)).expect("a plane mirror's rays share a virtual eye");
                assert!(!f.is_shared_origin());
                let scale = image.abs().max_element().max(eye.abs().max_element());
                assert!(f.radius() < 1e-4 * scale, "radius {} at scale {scale}", f.radius());
                assert!(
                    (f.origin - image).length() < 1e-3 * scale,
                    "apex {} against {image}",
                    f.origin
                );
            }
        }
    }

    /// Mirrored and curved-mirror packets: every triangle and box their
    /// frustum culls is missed by every lane's exact test (triangles near
    /// the mirror, touching lanes, behind it, and a soup ahead), and most
    /// of the soup is culled.
    #[test]
    fn virtual_apex_frusta_cull_only_what_no_lane_reaches() {
        let mut rng = SmallRng::seed_from_u64(23);
        let eye = Vec3::new(0.1, 0.5, 2.0);
        let packets = blocks(eye, Vec3::new(0.0, -0.5, -5.0));
        let bounces: Vec<[Ray; 16]> = mirrored(&packets, -3.0)
            .into_iter()
            .chain(curved(&packets, Vec3::new(0.0, -0.5, -23.0), 20.0))
            .collect();
        let b = Aabb::new(Vec3::new(-6.0, -6.0, -8.0), Vec3::new(6.0, 6.0, 8.0));
        let soup = meshgen::random_soup(400, 41, b, 0.6);
        let (mut made, mut culled, mut n, mut boxes_culled) = (0, 0, 0, 0);
        for p in &bounces {
            let Some(f) = Frustum::through(p, u32::from(u16::MAX)) else {
                continue;
            };
            made += 1;
            let mut tris = soup.clone();
            for r in p {
                // Small triangles touching a lane's ray, turned every way,
                // just off the mirror and farther on.
                for t in [1e-3, rng.random_range(0.1..1.0), rng.random_range(1.0..8.0)] {
                    let v = r.origin + r.dir * t;
                    let mut e = || {
                        Vec3::new(
                            rng.random_range(-1.0..1.0),
                            rng.random_range(-1.0..1.0),
                            rng.random_range(-1.0..1.0),
                        ) * 1e-3
                    };
                    let (e1, e2) = (e(), e());
                    tris.push([v, v + e1, v + e2]);
                }
                // Behind the mirror, on the lane's line.
                let v = r.origin - r.dir * rng.random_range(0.01..2.0);
                tris.push([v, v + Vec3::new(0.02, 0.0, 0.0), v + Vec3::new(0.0, 0.02, 0.0)]);
            }
            for chunk in (0..tris.len() as u32).collect::<Vec<_>>().chunks(4) {
                let block = TriBlock::pack(chunk, &tris);
                let mask = f.rejects(&block);
                let quad = BoxQuad::pack(&std::array::from_fn::<Aabb, 4, _>(|j| {
                    Aabb::from_points(&tris[chunk[j.min(chunk.len() - 1)] as usize])
                }));
                let box_mask = f.rejects_box_quad(&quad);
                for (j, &id) in chunk.iter().enumerate() {
                    let t = &tris[id as usize];
                    let culled_box = f.rejects_box(&Aabb::from_points(t));
                    assert_eq!(
                        culled_box,
                        box_mask & (1 << j) != 0,
                        "box {id}: quad and single tests differ"
                    );
                    n += 1;
                    culled += usize::from(mask & (1 << j) != 0);
                    boxes_culled += usize::from(culled_box);
                    if mask & (1 << j) != 0 || culled_box {
                        for r in p {
                            assert!(
                                intersect_triangle(r, t, r.t_max).is_none(),
                                "triangle {id} culled but hit"
                            );
                        }
                    }
                }
            }
        }
        assert!(
            made * 2 > bounces.len(),
            "only {made} of {} packets got a frustum",
            bounces.len()
        );
        assert!(
            culled * 2 > n && boxes_culled * 2 > n,
            "{culled} triangles, {boxes_culled} boxes of {n} culled"
        );
    }

    #[test]
    fn packets_without_a_virtual_apex_get_no_frustum() {
        let eye = Vec3::new(0.1, 0.5, 2.0);
        let p = mirrored(&blocks(eye, Vec3::new(0.0, 0.0, -5.0)), -3.0)[5];
        let all = u32::from(u16::MAX);
        assert!(Frustum::through(&p, all).is_some());
        // One lane, or none.
        assert!(Frustum::through(&p, 1 << 4).is_none());
        assert!(Frustum::through(&p, 0).is_none());
        // A lane reaching behind its origin, or with a NaN interval.
        let mut back = p;
        back[7] = p[7].with_interval(-1.0, f32::INFINITY);
        assert!(Frustum::through(&back, all).is_none());
        back[7] = p[7];
        back[7].t_min = f32::NAN;
        assert!(Frustum::through(&back, all).is_none());
        // A NaN origin.
        let mut nan = p;
        nan[2] = Ray::infinite(Vec3::new(f32::NAN, 0.0, 0.0), p[2].dir);
        assert!(Frustum::through(&nan, all).is_none());
        // Lines that meet ahead of their origins (converging rays).
        let focus = Vec3::new(0.0, 0.0, 10.0);
        let converging: [Ray; 16] = std::array::from_fn(|l| {
            let o = Vec3::new((l % 4) as f32 - 1.5, (l / 4) as f32 - 1.5, 0.0);
            Ray::infinite(o, focus - o)
        });
        assert!(Frustum::through(&converging, all).is_none());
        // Scattered lines: farther from any point than `THROUGH_RADIUS`.
        let mut rng = SmallRng::seed_from_u64(3);
        let scattered: [Ray; 16] = std::array::from_fn(|_| {
            let o = Vec3::new(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0), 0.0);
            Ray::infinite(
                o,
                Vec3::new(rng.random_range(-0.3..0.3), rng.random_range(-0.3..0.3), 1.0),
            )
        });
        assert!(Frustum::through(&scattered, all).is_none());
        // Lines passing their offset from one point (whose largest
        // coordinate, 100, is the scale): twice `THROUGH_RADIUS` of the
        // scale away, refused; a fifth of it, kept.
        let apex = Vec3::new(0.0, 0.0, -100.0);
        let fan = |offset: f32| -> [Ray; 16] {
            std::array::from_fn(|l| {
                let d = Vec3::new((l % 4) as f32 * 0.01 - 0.015, (l / 4) as f32 * 0.01 - 0.015, 1.0);
                let side = d.cross(Vec3::Y).normalize() * if l % 2 == 0 { offset } else { -offset };
                Ray::infinite(apex + side + d * 100.0, d)
            })
        };
        assert!(Frustum::through(&fan(THROUGH_RADIUS * 200.0), all).is_none());
        assert!(
            Frustum::through(&fan(THROUGH_RADIUS * 20.0), all).is_some_and(|f| f.radius() <= THROUGH_RADIUS * 100.0)
        );
    }
}
