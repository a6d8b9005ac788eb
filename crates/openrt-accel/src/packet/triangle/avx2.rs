//! The packet triangle test eight lanes to an AVX2 register: the four-lane
//! kernel ([`PacketBlockRay::intersect_block`]) with the same operations in
//! the same order, for CPUs with AVX2 (chosen at run time by the leaf loop,
//! `leaf/blocks.rs`).
//!
//! NOTE: bit for bit the four-lane kernel's answer: the arithmetic is
//! `geom/watertight8.rs`, the four-lane test's operations eight lanes to a
//! register. Tested against the four-lane kernel (and through it the scalar
//! one) in `super::tests`.

use core::arch::x86_64::{__m256, _mm256_loadu_ps, _mm256_movemask_ps, _mm256_set1_ps, _mm256_storeu_ps};

use wide::f32x4;

use super::{LaneHits, PacketBlockRay};
use crate::geom::tri_block::TriBlock;
use crate::geom::watertight8::Edges8;

/// Lanes per AVX2 register.
const WIDE: usize = 8;

/// Eight lanes of a chunk array, from lane `8 k` on.
///
/// # Safety
/// `8 k + 8` lanes must lie within `a` (`[f32x4]` is contiguous `f32`).
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn load(a: &[f32x4], k: usize) -> __m256 {
    debug_assert!((k + 1) * WIDE <= a.len() * 4);
    // SAFETY: `f32x4` is sixteen bytes of four `f32` without padding, so
    // the array is contiguous `f32`; the caller keeps the eight lanes read
    // inside it.
    unsafe { _mm256_loadu_ps(a.as_ptr().cast::<f32>().add(k * WIDE)) }
}

/// Writes eight lanes of a chunk array from lane `8 k` on.
///
/// # Safety
/// As [`load`].
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn store(a: &mut [f32x4], k: usize, v: __m256) {
    debug_assert!((k + 1) * WIDE <= a.len() * 4);
    // SAFETY: as in `load`, for writing.
    unsafe { _mm256_storeu_ps(a.as_mut_ptr().cast::<f32>().add(k * WIDE), v) };
}

impl<const N: usize> PacketBlockRay<N> {
    /// [`PacketBlockRay::intersect_block`] eight lanes at a time: the same
    /// [`LaneHits`] (`hit`, `edge`, and every hit lane's `t`, `b1`, `b2`,
    /// bit for bit). Lanes outside `lanes` may hold other values than the
    /// four-lane kernel leaves there; nothing reads them.
    ///
    /// # Safety
    /// The CPU must have AVX2, and `N` must be a multiple of eight.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(crate) unsafe fn intersect_block8(&self, block: &TriBlock, j: usize, lanes: u32, t_max: &[f32; N]) -> LaneHits {
        debug_assert!(N.is_multiple_of(WIDE));
        let mut out = LaneHits::none();
        let splat = |vert: usize, axis: usize| _mm256_set1_ps(block.coord(vert, axis).as_array()[j]);
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let (a, b, c) = (
            [splat(0, kx), splat(0, ky), splat(0, kz)],
            [splat(1, kx), splat(1, ky), splat(1, kz)],
            [splat(2, kx), splat(2, ky), splat(2, kz)],
        );
        for k in 0..N / WIDE {
            let part = (lanes >> (k * WIDE)) & 0xFF;
            if part == 0 {
                continue;
            }
            // SAFETY (every `load` and `store` below): `k < N / 8` and the
            // arrays hold `MAX_LANES >= N` lanes.
            let o = unsafe { [load(&self.ox, k), load(&self.oy, k), load(&self.oz, k)] };
            let (sx, sy) = unsafe { (load(&self.sx, k), load(&self.sy, k)) };
            let e = Edges8::new(&a, &b, &c, &o, sx, sy);
            let mixed = e.mixed();
            // The pre-test: lanes with mixed signs are certain misses.
            if !(_mm256_movemask_ps(mixed).cast_unsigned()) & part == 0 {
                continue;
            }
            // SAFETY: lanes `8 k..8 k + 8` of the `N` bounds.
            let hi = unsafe { _mm256_loadu_ps(t_max.as_ptr().add(k * WIDE)) };
            let (sz, t_min) = unsafe { (load(&self.sz, k), load(&self.t_min, k)) };
            let d = e.decide(mixed, sz, t_min, hi);
            out.hit |= d.hit << (k * WIDE);
            out.edge |= d.edge << (k * WIDE);
            unsafe {
                store(&mut out.t, k, d.t);
                store(&mut out.b1, k, d.b1);
                store(&mut out.b2, k, d.b2);
            }
        }
        out.hit &= lanes;
        out.edge &= lanes;
        out
    }
}
