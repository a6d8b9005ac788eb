//! The watertight ray/triangle test across a packet's lanes: one triangle
//! against `N` rays per pass, the lane-parallel twin of
//! [`crate::geom::triangle::intersect_triangle`].
//!
//! Woop, Benthin & Wald, "Watertight Ray/Triangle Intersection", JCGT 2(1),
//! 2013, for the test; Wald, Benthin, Wagner & Slusallek 2001 for testing a
//! packet's rays against one triangle at a time. Lanes that share the test's
//! axis permutation (nearly every coherent packet) share the triangle's
//! permuted coordinates; everything else is per lane, four lanes to an SSE
//! register (`wide::f32x4`), a chunk at a time.
//!
//! NOTE: each lane repeats the scalar kernel's operations one for one (same
//! subtractions and products in the same order, no fused multiply-add, the
//! same comparisons written so that NaN goes the same way), so a lane's hit,
//! `t` and barycentrics are bit-identical to [`crate::geom::triangle::intersect_triangle`]'s.
//! The one case it does not decide is an edge function that is exactly zero
//! (a ray through an edge or a vertex): the scalar kernel recomputes those in
//! f64 and applies its tie rule, so such lanes are handed back to it
//! ([`LaneHits::edge`], [`LaneHits::settle_edges`]). Tested against the
//! scalar kernel in this module. On CPUs with AVX2 the leaf loop runs the
//! same test eight lanes to a register (`avx2.rs`, bit for bit this one's).

use wide::f32x4;

use crate::geom::ray::Ray;
use crate::geom::tri_block::TriBlock;
use crate::geom::triangle::Triangle;
use crate::geom::triangle::intersect_triangle;
use crate::geom::watertight4::Edges4;
use crate::packet::boxes::PacketBoxes;
use crate::packet::width::MAX_LANES;
use crate::packet::width::by_axis;

#[cfg(target_arch = "x86_64")]
mod avx2;

/// Lanes per SIMD chunk (one SSE register of `f32`).
const CHUNK: usize = 4;

/// The lanes of one chunk.
const CHUNK_MASK: u32 = (1 << CHUNK) - 1;

/// Chunks in the widest packet.
const MAX_CHUNKS: usize = MAX_LANES / CHUNK;

/// The watertight test's per-ray constants for a packet whose lanes share
/// its axis permutation, four lanes to a SIMD chunk (the packet form of the
/// leaf blocks' per-ray constants).
pub(crate) struct PacketBlockRay<const N: usize> {
    ox: [f32x4; MAX_CHUNKS],
    oy: [f32x4; MAX_CHUNKS],
    oz: [f32x4; MAX_CHUNKS],
    sx: [f32x4; MAX_CHUNKS],
    sy: [f32x4; MAX_CHUNKS],
    sz: [f32x4; MAX_CHUNKS],
    t_min: [f32x4; MAX_CHUNKS],
    kx: usize,
    ky: usize,
    kz: usize,
}

/// What [`PacketBlockRay::intersect_block`] decided for one triangle.
pub(crate) struct LaneHits {
    /// Lanes that hit the triangle inside their interval; their `t`, `b1`
    /// and `b2` hold the hit.
    pub(crate) hit: u32,
    /// Lanes with an edge function exactly zero, which only the scalar
    /// kernel decides (never in `hit`).
    pub(crate) edge: u32,
    t: [f32x4; MAX_CHUNKS],
    b1: [f32x4; MAX_CHUNKS],
    b2: [f32x4; MAX_CHUNKS],
}

impl LaneHits {
    /// No lane hit, no lane on an edge: what a kernel starts from.
    #[inline]
    fn none() -> Self {
        let zero = f32x4::ZERO;
        Self {
            hit: 0,
            edge: 0,
            t: [zero; MAX_CHUNKS],
            b1: [zero; MAX_CHUNKS],
            b2: [zero; MAX_CHUNKS],
        }
    }

    /// Lane `l`'s `(t, b1, b2)`, meaningful for the lanes of `hit`.
    #[inline]
    pub(crate) fn lane(&self, l: usize) -> (f32, f32, f32) {
        let (k, i) = (l / CHUNK, l % CHUNK);
        (
            self.t[k].to_array()[i],
            self.b1[k].to_array()[i],
            self.b2[k].to_array()[i],
        )
    }

    /// Decides the [`LaneHits::edge`] lanes with the scalar kernel (a ray
    /// exactly through an edge or a vertex: its exact recomputation and tie
    /// rule), adding their hits to `hit`; `edge` is then empty.
    #[inline]
    pub(crate) fn settle_edges<const N: usize>(&mut self, rays: &[Ray; N], tri: &Triangle, t_max: &[f32; N]) {
        for l in crate::packet::width::lanes_of(self.edge) {
            if let Some((t, b1, b2)) = intersect_triangle(&rays[l], tri, t_max[l]) {
                let (k, i) = (l / CHUNK, l % CHUNK);
                let set = |v: &mut f32x4, x: f32| {
                    let mut a = v.to_array();
                    a[i] = x;
                    *v = f32x4::new(a);
                };
                set(&mut self.t[k], t);
                set(&mut self.b1[k], b1);
                set(&mut self.b2[k], b2);
                self.hit |= 1 << l;
            }
        }
        self.edge = 0;
    }
}

/// A triangle's vertices in the lanes' shared permutation, splatted.
#[derive(Clone, Copy)]
struct Permuted {
    a: [f32x4; 3],
    b: [f32x4; 3],
    c: [f32x4; 3],
}

impl<const N: usize> PacketBlockRay<N> {
    /// The constants of the `lanes` of `rays`, `None` when their axis
    /// permutations differ (then each lane takes the scalar kernel).
    pub(crate) fn new(rays: &[Ray; N], lanes: u32) -> Option<Self> {
        Self::new_in(rays, None, lanes)
    }

    /// [`PacketBlockRay::new`], with the origins and near bounds read from
    /// `laid` when given (the same rays laid out lane by lane): the same
    /// constants.
    pub(crate) fn new_in(rays: &[Ray; N], laid: Option<&PacketBoxes<N>>, lanes: u32) -> Option<Self> {
        const { assert!(N.is_multiple_of(CHUNK) && N <= MAX_LANES) };
        let first = &rays[lanes.trailing_zeros() as usize];
        let (kx, ky, kz) = (first.kx, first.ky, first.kz);
        // PERF: every lane compared without a branch, then the mask (a lane
        // loop with an early exit mispredicted: a third of this function).
        let mut other = 0u32;
        for (l, r) in rays.iter().enumerate() {
            other |= u32::from((r.kx ^ kx) | (r.ky ^ ky) | (r.kz ^ kz) != 0) << l;
        }
        let [kx, ky, kz] = first.axes();
        if other & lanes != 0 {
            return None;
        }
        // PERF: each ray's three values of four lanes transposed at once
        // (`by_axis`), then rows loaded four lanes at a time: gathered value
        // by value through closures, this was a fifth of the robots' shadow
        // queries (their last occluders' leaves).
        let own;
        let (o, t_min) = if let Some(b) = laid {
            (&b.o, &b.t_min)
        } else {
            own = (by_axis(rays, |r| r.origin), std::array::from_fn(|l| rays[l].t_min));
            (&own.0, &own.1)
        };
        let shear = by_axis(rays, |r| r.shear);
        let rows = |v: &[f32; N]| -> [f32x4; MAX_CHUNKS] {
            std::array::from_fn(|k| f32x4::new(std::array::from_fn(|i| v.get(k * CHUNK + i).copied().unwrap_or(0.0))))
        };
        Some(Self {
            ox: rows(&o[kx]),
            oy: rows(&o[ky]),
            oz: rows(&o[kz]),
            sx: rows(&shear[0]),
            sy: rows(&shear[1]),
            sz: rows(&shear[2]),
            t_min: rows(t_min),
            kx,
            ky,
            kz,
        })
    }

    /// Triangle `j` of `block` in the lanes' permutation, read from the
    /// block's lanes directly (no triangle put together first).
    #[inline]
    fn permute_block(&self, block: &TriBlock, j: usize) -> Permuted {
        // NOTE: no `[_; 3].map` here: it was left as a call in the shadow
        // rays' leaf loop (4% of their queries).
        let p = |vert: usize| {
            let splat = |axis: usize| f32x4::splat(block.coord(vert, axis).as_array()[j]);
            [splat(self.kx), splat(self.ky), splat(self.kz)]
        };
        Permuted {
            a: p(0),
            b: p(1),
            c: p(2),
        }
    }

    #[cfg(test)]
    fn permute(&self, tri: &Triangle) -> Permuted {
        let p = |v: glam::Vec3| {
            [
                f32x4::splat(v[self.kx]),
                f32x4::splat(v[self.ky]),
                f32x4::splat(v[self.kz]),
            ]
        };
        Permuted {
            a: p(tri[0]),
            b: p(tri[1]),
            c: p(tri[2]),
        }
    }

    /// Chunk `k`'s edge functions: `intersect_triangle`'s first operations.
    #[inline]
    fn edges(&self, t: &Permuted, k: usize) -> Edges4 {
        Edges4::new(
            &t.a,
            &t.b,
            &t.c,
            &[self.ox[k], self.oy[k], self.oz[k]],
            self.sx[k],
            self.sy[k],
        )
    }

    /// [`PacketBlockRay::intersect_block`] of a triangle given whole (the
    /// tests' entry).
    #[cfg(test)]
    pub(crate) fn intersect(&self, tri: &Triangle, lanes: u32, t_max: &[f32; N]) -> LaneHits {
        self.intersect_permuted(&self.permute(tri), lanes, t_max)
    }

    /// The whole watertight test of triangle `j` of `block` for the
    /// `lanes`, lane `l` over `(t_min, t_max[l])`: lane by lane the answer
    /// of `intersect_triangle(&rays[l], tri, t_max[l])`, except for the
    /// lanes returned in [`LaneHits::edge`], which the caller decides with
    /// it. Chunks without a lane of `lanes` are not computed.
    // PERF: the triangle's coordinates go from the block's lanes to the
    // splats without being put together as a `Triangle` first (kitchen
    // primary queries 2% faster).
    #[inline]
    pub(crate) fn intersect_block(&self, block: &TriBlock, j: usize, lanes: u32, t_max: &[f32; N]) -> LaneHits {
        self.intersect_permuted(&self.permute_block(block, j), lanes, t_max)
    }

    /// The test on a triangle already permuted and splatted.
    // PERF: forced inline into the leaf loop; a chunk whose lanes all have
    // edge functions of mixed signs stops after them (the pre-test), and
    // one pass per chunk replaces a scalar test (with its division) per
    // lane that passes it.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    fn intersect_permuted(&self, tr: &Permuted, lanes: u32, t_max: &[f32; N]) -> LaneHits {
        let mut out = LaneHits::none();
        for k in 0..N / CHUNK {
            let chunk_lanes = (lanes >> (k * CHUNK)) & CHUNK_MASK;
            if chunk_lanes == 0 {
                continue;
            }
            let e = self.edges(tr, k);
            let mixed = e.mixed();
            // PERF: the pre-test: most chunks stop here (certain misses).
            if (!mixed).to_bitmask() & chunk_lanes == 0 {
                continue;
            }
            let hi = f32x4::new(std::array::from_fn(|i| t_max[k * CHUNK + i]));
            let d = e.decide(mixed, self.sz[k], self.t_min[k], hi);
            out.hit |= d.hit << (k * CHUNK);
            out.edge |= d.edge << (k * CHUNK);
            out.t[k] = d.t;
            out.b1[k] = d.b1;
            out.b2[k] = d.b2;
        }
        out.hit &= lanes;
        out.edge &= lanes;
        out
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use rand::{Rng, SeedableRng};

    use super::*;

    const N: usize = 16;

    fn bits(x: Option<(f32, f32, f32)>) -> Option<(u32, u32, u32)> {
        x.map(|(a, b, c)| (a.to_bits(), b.to_bits(), c.to_bits()))
    }

    /// Every constant of a packet's rays, as bits.
    fn constants(p: &PacketBlockRay<N>) -> Vec<u32> {
        let mut v = vec![p.kx as u32, p.ky as u32, p.kz as u32];
        for rows in [&p.ox, &p.oy, &p.oz, &p.sx, &p.sy, &p.sz, &p.t_min] {
            v.extend(rows.iter().flat_map(|x| x.to_array().map(f32::to_bits)));
        }
        v
    }

    /// The AVX2 kernel's answer, `None` on a CPU without AVX2.
    #[allow(clippy::unnecessary_wraps)]
    fn intersect_block8(
        p: &PacketBlockRay<N>,
        block: &TriBlock,
        j: usize,
        lanes: u32,
        t_max: &[f32; N],
    ) -> Option<LaneHits> {
        #[cfg(target_arch = "x86_64")]
        if crate::packet::width::avx2() {
            // SAFETY: the CPU has AVX2 and `N` is sixteen.
            return Some(unsafe { p.intersect_block8(block, j, lanes, t_max) });
        }
        let _ = (p, block, j, lanes, t_max);
        None
    }

    /// Checks every lane of `rays` against `tri` with the scalar kernel,
    /// and the AVX2 kernel against the four-lane one.
    fn check(rays: &[Ray; N], tri: &Triangle, t_max: &[f32; N]) -> (u32, u32) {
        let p = PacketBlockRay::new(rays, u32::MAX >> (32 - N)).expect("one permutation");
        let all = u32::MAX >> (32 - N);
        // The constants from the lanes laid out are the rays', bit for bit.
        let laid = PacketBlockRay::new_in(rays, Some(&PacketBoxes::new(rays, all)), all).expect("one permutation");
        assert_eq!(constants(&laid), constants(&p));
        let h = p.intersect(tri, all, t_max);
        assert_eq!(h.hit & h.edge, 0);
        // Read from any lane of a leaf block, the triangle gives the same
        // answers, bit for bit.
        let other = [tri[1], tri[2], tri[0]];
        for j in 0..4 {
            let tris: Vec<Triangle> = (0..4).map(|i| if i == j { *tri } else { other }).collect();
            let block = TriBlock::pack(&[0, 1, 2, 3], &tris);
            let b = p.intersect_block(&block, j, all, t_max);
            assert_eq!((b.hit, b.edge), (h.hit, h.edge), "block lane {j}");
            for l in crate::packet::width::lanes_of(h.hit) {
                assert_eq!(bits(Some(b.lane(l))), bits(Some(h.lane(l))), "block lane {j}, lane {l}");
            }
            // The AVX2 copy: the four-lane kernel's answer, whole and on
            // parts of the lanes (whole registers skipped, others masked).
            for part in [all, 0x00F0, 0x0F0F & !0x0102, 0x8001, 0xFF00] {
                let want = p.intersect_block(&block, j, part, t_max);
                let Some(got) = intersect_block8(&p, &block, j, part, t_max) else {
                    break;
                };
                assert_eq!(
                    (got.hit, got.edge),
                    (want.hit, want.edge),
                    "AVX2, block lane {j}, lanes {part:#x}"
                );
                for l in crate::packet::width::lanes_of(want.hit) {
                    assert_eq!(bits(Some(got.lane(l))), bits(Some(want.lane(l))), "AVX2, lane {l}");
                }
            }
        }
        // A part of the lanes (whole chunks skipped, others partly
        // masked) answers for those lanes alone, the same way.
        for part in [0x00F0, 0x0F0F & !0x0102, 0x8001] {
            let q = p.intersect(tri, part, t_max);
            assert_eq!((q.hit, q.edge), (h.hit & part, h.edge & part), "lanes {part:#x}");
        }
        for l in 0..N {
            let want = intersect_triangle(&rays[l], tri, t_max[l]);
            if h.edge & (1 << l) != 0 {
                continue;
            }
            let got = (h.hit & (1 << l) != 0).then(|| h.lane(l));
            assert_eq!(bits(got), bits(want), "lane {l}: {:?} against {tri:?}", rays[l]);
        }
        // With the edge lanes settled by the scalar kernel, every lane.
        let mut settled = p.intersect(tri, all, t_max);
        settled.settle_edges(rays, tri, t_max);
        assert_eq!(settled.edge, 0);
        for l in 0..N {
            let want = intersect_triangle(&rays[l], tri, t_max[l]);
            let got = (settled.hit & (1 << l) != 0).then(|| settled.lane(l));
            assert_eq!(bits(got), bits(want), "settled lane {l}: {:?} against {tri:?}", rays[l]);
        }
        (h.hit, h.edge)
    }

    #[test]
    fn lanes_match_the_scalar_kernel_bit_for_bit_on_a_seeded_sweep() {
        let mut rng = rand::rngs::SmallRng::seed_from_u64(0x7A11);
        let (mut hits, mut edges) = (0u32, 0u32);
        for _ in 0..3000 {
            let v = |rng: &mut rand::rngs::SmallRng| {
                Vec3::new(
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-1.0..1.0),
                )
            };
            let tri = [v(&mut rng), v(&mut rng), v(&mut rng)];
            // A packet from one origin (primary rays) into a cone around -z,
            // with some lanes aimed exactly at vertices and edge midpoints.
            let o = Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 4.0);
            let rays: [Ray; N] = std::array::from_fn(|l| {
                let target = match l % 8 {
                    0 => tri[l / 8 % 3],
                    1 => (tri[0] + tri[1]) * 0.5,
                    _ => Vec3::new(rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0), 0.0),
                };
                let t_min = if l == 5 { 3.9 } else { 0.0 };
                Ray::new(o, target - o, t_min, f32::INFINITY)
            });
            if rays
                .iter()
                .any(|r| (r.kx, r.ky, r.kz) != (rays[0].kx, rays[0].ky, rays[0].kz))
            {
                continue;
            }
            let t_max: [f32; N] = std::array::from_fn(|l| if l % 3 == 0 { 1.0 } else { f32::INFINITY });
            let (h, e) = check(&rays, &tri, &t_max);
            hits += h.count_ones();
            edges += e.count_ones();
        }
        assert!(hits > 2_000, "the sweep hits: {hits}");
        assert!(edges > 0, "the sweep meets exact edges: {edges}");
    }

    #[test]
    fn hard_lanes_match_the_scalar_kernel() {
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let degenerate = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        let far = [
            Vec3::splat(1e30),
            Vec3::new(-1e30, 1e30, 1e30),
            Vec3::new(1e30, -1e30, 1e30),
        ];
        let rays: [Ray; N] = std::array::from_fn(|l| {
            let d = Vec3::new(0.01 * l as f32, 0.02, -1.0);
            match l {
                // Through a vertex, along an edge, behind the origin.
                0 => Ray::infinite(Vec3::new(0.0, 0.0, 1.0), -Vec3::Z),
                1 => Ray::infinite(Vec3::new(0.5, 0.0, 1.0), -Vec3::Z),
                2 => Ray::infinite(Vec3::new(0.2, 0.2, -1.0), -Vec3::Z),
                // NaN origin, empty interval, a hit at the interval's end.
                3 => Ray::new(Vec3::new(f32::NAN, 0.2, 1.0), -Vec3::Z, 0.0, f32::INFINITY),
                4 => Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z, 2.0, 1.0),
                5 => Ray::new(Vec3::new(0.2, 0.2, 1.0), -Vec3::Z, 0.0, 1.0),
                // Origin on the plane.
                6 => Ray::infinite(Vec3::new(0.2, 0.2, 0.0), -Vec3::Z),
                // The same below a negative t_min: `t` is exactly its error
                // bound, zero, and the conservative test rejects it.
                8 => Ray::new(Vec3::new(0.2, 0.2, 0.0), -Vec3::Z, -1.0, 1.0),
                _ => Ray::infinite(Vec3::new(0.1, 0.1, 1.0), d),
            }
        });
        let t_max: [f32; N] = std::array::from_fn(|l| if l == 5 { 1.0 } else { rays[l].t_max });
        for t in [tri, degenerate, far, [tri[0], tri[2], tri[1]]] {
            check(&rays, &t, &t_max);
        }
    }

    #[test]
    fn mixed_permutations_are_refused() {
        let rays: [Ray; N] = std::array::from_fn(|l| {
            let d = if l == 3 { Vec3::X } else { -Vec3::Z };
            Ray::infinite(Vec3::ZERO, d)
        });
        assert!(PacketBlockRay::new(&rays, u32::MAX >> (32 - N)).is_none());
        assert!(PacketBlockRay::new(&rays, 0b0111).is_some());
        let laid = PacketBoxes::new(&rays, u32::MAX >> (32 - N));
        assert!(PacketBlockRay::new_in(&rays, Some(&laid), u32::MAX >> (32 - N)).is_none());
        assert!(PacketBlockRay::new_in(&rays, Some(&laid), 0b0111).is_some());
    }
}
