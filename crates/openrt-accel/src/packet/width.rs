//! Ray packets: the lane width chosen for the CPU, lane masks, and the
//! grouping of a packet's rays by direction signs.
//!
//! A packet is an array of `N` [`Ray`]s with a `u32` mask of the lanes in
//! use. Packet traversal ([`crate::packet::traverse`]) needs every active
//! lane to share the signs of its direction components (then the near/far
//! order of every split is the same for all lanes) and to have no zero
//! component (whose side of a plane the origin decides); [`sign_groups`]
//! splits a packet into such groups and the lanes that must walk alone.
//! Wald, Benthin, Wagner & Slusallek, "Interactive Rendering with Coherent
//! Ray Tracing", Eurographics 2001, for packets through kd-trees.

use std::sync::OnceLock;

use wide::f32x4;

use crate::geom::ray::Ray;

/// Widest packet any kernel is instantiated for: 32 lanes, as many as a
/// `u32` lane mask holds.
pub const MAX_LANES: usize = 32;

/// The packet widths the kernels are instantiated for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PacketWidth {
    /// 4 lanes: one SSE or NEON register; the width without AVX2.
    W4,
    /// 8 lanes: one AVX2 register.
    W8,
    /// 16 lanes: one AVX-512 register.
    W16,
    /// 32 lanes, 8x4 pixels: large packets, the width on AVX2 and AVX-512
    /// CPUs ([`PacketWidth::cpu`]).
    W32,
}

impl PacketWidth {
    /// Lanes in a packet of this width.
    #[must_use]
    pub const fn lanes(self) -> usize {
        match self {
            Self::W4 => 4,
            Self::W8 => 8,
            Self::W16 => 16,
            Self::W32 => 32,
        }
    }

    /// The width for `lanes` (4, 8, 16 or 32).
    #[must_use]
    pub const fn from_lanes(lanes: usize) -> Option<Self> {
        match lanes {
            4 => Some(Self::W4),
            8 => Some(Self::W8),
            16 => Some(Self::W16),
            32 => Some(Self::W32),
            _ => None,
        }
    }

    /// The width for this CPU, detected once ([`PacketWidth::cpu`]). A
    /// renderer takes another with `set_packet_width`.
    #[must_use]
    pub fn detect() -> Self {
        static WIDTH: OnceLock<PacketWidth> = OnceLock::new();
        *WIDTH.get_or_init(Self::cpu)
    }

    /// The width a setting names: `4`, `8`, `16` or `32` (surrounding blanks
    /// allowed); `None` for any other text.
    #[must_use]
    pub fn parse(value: &str) -> Option<Self> {
        value.trim().parse().ok().and_then(Self::from_lanes)
    }

    /// The packet width for this CPU: large packets of 32 lanes (8x4
    /// pixels) on CPUs with AVX2 (AVX-512 ones included), else 4.
    ///
    /// PERF: 32 lanes share each node fetch, frustum test and first-lane
    /// box test of the walks among twice the rays of 16 (Wald, Boulos &
    /// Shirley 2007 trace 8x8 packets). Measured on an AVX-512 CPU against
    /// 16 lanes, one thread, 640x480: BVH primary queries 0.77-0.85 of the
    /// time (kitchen, robots, museum4k), GL-like frames 0.80-0.88, Whitted
    /// 0.86-0.99; the terrain within 1.06 either way. The leaf and walk
    /// kernels are AVX2 at most, so AVX2 CPUs run the same code.
    #[must_use]
    pub fn cpu() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            if avx2() {
                return Self::W32;
            }
        }
        Self::W4
    }
}

/// Whether the CPU has AVX2 (detected once).
#[cfg(target_arch = "x86_64")]
#[inline]
#[must_use]
pub fn avx2() -> bool {
    static AVX2: OnceLock<bool> = OnceLock::new();
    *AVX2.get_or_init(|| std::arch::is_x86_feature_detected!("avx2"))
}

/// The mask of the first `n` lanes.
#[inline]
#[must_use]
pub const fn lanes_mask(n: usize) -> u32 {
    if n >= 32 { u32::MAX } else { (1u32 << n) - 1 }
}

/// Lane indices of a mask, lowest first.
#[inline]
pub fn lanes_of(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        if mask == 0 {
            return None;
        }
        let l = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        Some(l)
    })
}

/// The lanes of `mask` split by the signs of their direction: `groups[s]`
/// holds the lanes whose negative components are the bits of `s` (x = 1,
/// y = 2, z = 4) and that have no zero component; `alone` the lanes with a
/// zero component (either sign), which walk by themselves.
// PERF: forced inline: called, its groups were written lane word by lane
// word and read back 16 bytes at a time by the walk before the stores had
// landed (failed store forwarding: 12% of a primary walk's samples).
#[allow(clippy::inline_always)]
#[inline(always)]
#[must_use]
pub fn sign_groups<const N: usize>(rays: &[Ray; N], mask: u32) -> ([u32; 8], u32) {
    sign_groups_of::<N>(|a, l| rays[l].dir[a], mask)
}

/// [`sign_groups`] of the directions `dir(axis, lane)`.
// PERF: forced inline, as `sign_groups`.
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn sign_groups_of<const N: usize>(dir: impl Fn(usize, usize) -> f32, mask: u32) -> ([u32; 8], u32) {
    // PERF: a mask per sign and one of zero components, four lanes of one
    // axis to a register (the sign bits straight from `movmskps`, the zeros
    // from one compare), then the groups from the masks. As a lane loop
    // (a chain of shifts and ors per lane) it was 40% of a packet walk.
    let (mut neg, mut zero) = ([0u32; 3], 0u32);
    for c in (0..N - N % 4).step_by(4) {
        for (a, neg) in neg.iter_mut().enumerate() {
            let v = f32x4::new([dir(a, c), dir(a, c + 1), dir(a, c + 2), dir(a, c + 3)]);
            *neg |= v.to_bitmask() << c;
            zero |= v.simd_eq(f32x4::ZERO).to_bitmask() << c;
        }
    }
    for l in N - N % 4..N {
        let d = [dir(0, l), dir(1, l), dir(2, l)];
        for a in 0..3 {
            neg[a] |= u32::from(d[a].is_sign_negative()) << l;
        }
        zero |= u32::from(d[0] == 0.0 || d[1] == 0.0 || d[2] == 0.0) << l;
    }
    groups_of(mask, neg, zero)
}

/// The groups of [`sign_groups`] from the masks of the lanes with a
/// negative component along each axis and of those with a zero component.
#[allow(clippy::inline_always)]
#[inline(always)]
fn groups_of(mask: u32, neg: [u32; 3], zero: u32) -> ([u32; 8], u32) {
    let live = mask & !zero;
    let side = |a: usize, s: usize| if s & (1 << a) != 0 { neg[a] } else { !neg[a] };
    let groups = std::array::from_fn(|s| live & side(0, s) & side(1, s) & side(2, s));
    (groups, mask & zero)
}

/// One vector of each ray (`f`), axis by axis: `out[a][l]` is `f(&rays[l])[a]`.
// PERF: four lanes at a time, each ray's three values loaded as one register
// and transposed (a lane loop of scalar copies was 8% of a packet walk);
// forced inline like the lane loops of the walk that calls it.
#[allow(clippy::inline_always)]
#[inline(always)]
pub(crate) fn by_axis<const N: usize>(rays: &[Ray; N], f: impl Fn(&Ray) -> glam::Vec3) -> [[f32; N]; 3] {
    let mut out = [[0.0f32; N]; 3];
    let mut chunks = rays.chunks_exact(4);
    for (k, c) in chunks.by_ref().enumerate() {
        let t = f32x4::transpose(std::array::from_fn(|i| {
            let v = f(&c[i]);
            f32x4::new([v.x, v.y, v.z, 0.0])
        }));
        for (a, row) in out.iter_mut().enumerate() {
            row[4 * k..4 * k + 4].copy_from_slice(t[a].as_array());
        }
    }
    let done = N - chunks.remainder().len();
    for (l, r) in rays.iter().enumerate().skip(done) {
        let v = f(r);
        for (a, row) in out.iter_mut().enumerate() {
            row[l] = v[a];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    #[test]
    fn widths_round_trip_and_detection_gives_a_known_width() {
        for w in [PacketWidth::W4, PacketWidth::W8, PacketWidth::W16, PacketWidth::W32] {
            assert_eq!(PacketWidth::from_lanes(w.lanes()), Some(w));
            assert!(w.lanes() <= MAX_LANES);
        }
        assert_eq!(PacketWidth::from_lanes(5), None);
        assert_eq!(PacketWidth::parse(" 8 "), Some(PacketWidth::W8));
        assert_eq!(PacketWidth::parse("4"), Some(PacketWidth::W4));
        assert_eq!(PacketWidth::parse("32"), Some(PacketWidth::W32));
        for bad in ["", "12", "64", "avx", "-4"] {
            assert_eq!(PacketWidth::parse(bad), None, "{bad:?}");
        }
        assert_eq!(PacketWidth::detect(), PacketWidth::cpu());
    }

    #[test]
    fn lanes_are_listed_lowest_first() {
        assert_eq!(lanes_of(0b1010_0001).collect::<Vec<_>>(), vec![0, 5, 7]);
        assert_eq!(lanes_of(0).count(), 0);
        assert_eq!(lanes_mask(4), 0xF);
        assert_eq!(lanes_mask(32), u32::MAX);
    }

    /// The transposed layout holds each lane's own values, for whole
    /// registers of lanes and for lanes left over.
    #[test]
    fn laid_out_lanes_are_the_rays_values() {
        fn check<const N: usize>() {
            let rays: [Ray; N] = std::array::from_fn(|l| {
                let f = l as f32;
                Ray::infinite(Vec3::new(f, -2.0 * f, 0.5 + f), Vec3::new(1.0 + f, -0.0, -3.0 - f))
            });
            let (org, inv) = (by_axis(&rays, |r| r.origin), by_axis(&rays, Ray::inv_dir));
            for (l, r) in rays.iter().enumerate() {
                for a in 0..3 {
                    assert_eq!(
                        org[a][l].to_bits(),
                        r.origin[a].to_bits(),
                        "{N} lanes: lane {l}, axis {a}"
                    );
                    assert_eq!(
                        inv[a][l].to_bits(),
                        r.inv_dir()[a].to_bits(),
                        "{N} lanes: lane {l}, axis {a}"
                    );
                }
            }
        }
        check::<32>();
        check::<16>();
        check::<8>();
        check::<6>();
        check::<1>();
    }

    #[test]
    fn signs_group_lanes_and_zero_components_walk_alone() {
        let r = |d: Vec3| Ray::infinite(Vec3::ZERO, d);
        let rays = [
            r(Vec3::new(1.0, 1.0, 1.0)),
            r(Vec3::new(-1.0, 1.0, 1.0)),
            r(Vec3::new(1.0, 2.0, 3.0)),
            r(Vec3::new(1.0, -0.0, 1.0)),
            r(Vec3::new(-1.0, -1.0, -1.0)),
            r(Vec3::new(0.0, 1.0, 1.0)),
            r(Vec3::new(1.0, 1.0, 1.0)),
            r(Vec3::new(1.0, 1.0, 1.0)),
        ];
        let (g, alone) = sign_groups(&rays, 0b0111_1111);
        assert_eq!(g[0], 0b0100_0101);
        assert_eq!(g[1], 0b0000_0010);
        assert_eq!(g[7], 0b0001_0000);
        assert_eq!(alone, 0b0010_1000);
        assert_eq!(g.iter().fold(alone, |a, m| a | m), 0b0111_1111);
    }

    #[test]
    fn sign_groups_match_a_lane_by_lane_grouping() {
        use rand::{Rng, SeedableRng};
        fn check<const N: usize>(rng: &mut rand::rngs::SmallRng, pick: impl Fn(&mut rand::rngs::SmallRng) -> f32) {
            let rays: [Ray; N] = std::array::from_fn(|_| {
                let d = Vec3::new(pick(rng), pick(rng), pick(rng));
                Ray::infinite(Vec3::ZERO, d)
            });
            let mask = rng.random::<u32>() & (u32::MAX >> (32 - N));
            let (mut want, mut want_alone) = ([0u32; 8], 0u32);
            for l in lanes_of(mask) {
                let d = rays[l].dir;
                if d.cmpeq(Vec3::ZERO).any() {
                    want_alone |= 1 << l;
                } else {
                    want[d.is_negative_bitmask() as usize] |= 1 << l;
                }
            }
            assert_eq!(sign_groups(&rays, mask), (want, want_alone), "{N} lanes");
        }
        let mut rng = rand::rngs::SmallRng::seed_from_u64(77);
        let pick = |rng: &mut rand::rngs::SmallRng| match rng.random_range(0..8) {
            0 => 0.0,
            1 => -0.0,
            2 => f32::NAN,
            3 => -f32::NAN,
            _ => rng.random_range(-1.0f32..1.0),
        };
        // Whole registers of four lanes, and widths with lanes left over.
        for _ in 0..500 {
            check::<32>(&mut rng, pick);
            check::<16>(&mut rng, pick);
            check::<8>(&mut rng, pick);
            check::<4>(&mut rng, pick);
            check::<7>(&mut rng, pick);
            check::<2>(&mut rng, pick);
        }
    }
}
