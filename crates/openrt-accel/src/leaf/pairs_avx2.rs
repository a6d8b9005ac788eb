//! One ray against a leaf's blocks two at a time, eight triangles to an
//! AVX2 register: the single-ray leaf loop of `blocks.rs` for leaves of two
//! blocks or more on CPUs with AVX2 (the BVH's leaves of five to eight
//! triangles, most kd leaves). The same visits with the same hits, bit for
//! bit: the arithmetic is `geom/watertight8.rs`, the four-lane test's
//! operations, and the lanes are visited in leaf order through the same
//! [`Found::visit`].

use core::arch::x86_64::{__m256, _mm256_loadu2_m128, _mm256_movemask_ps, _mm256_set1_ps, _mm256_storeu_ps};

use super::blocks::{BlockRay, Found, leaf_range, padding};
use crate::geom::ray::Ray;
use crate::geom::tri_block::{LANES, TriBlock};
use crate::geom::triangle::TriHit;
use crate::geom::watertight8::Edges8;
use crate::kd::node::KdNode;

/// Blocks per register.
const PAIR: usize = 2;

/// The eight lanes of an AVX2 register as an array.
#[target_feature(enable = "avx2")]
#[inline]
fn lanes8(v: __m256) -> [f32; 8] {
    let mut out = [0.0f32; 8];
    // SAFETY: `out` is eight contiguous f32; the unaligned store writes
    // exactly those 32 bytes.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), v) };
    out
}

/// `for_each_hit` (`blocks.rs`) of a leaf of at least two blocks, blocks
/// `2 p` and `2 p + 1` tested together (a last odd block with itself, its
/// copy's lanes taken as padding).
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn for_each_hit_avx2(
    ray: &Ray,
    br: &BlockRay,
    leaf: KdNode,
    ids: &[u32],
    blocks: &[TriBlock],
    mut bound: f32,
    mut visit: impl FnMut(u32, TriHit, &mut f32) -> bool,
) -> bool {
    let (off, first, n, count) = leaf_range(leaf);
    let leaf_blocks = &blocks[first..first + count];
    let splat = |v: wide::f32x4| _mm256_set1_ps(v.as_array()[0]);
    let o = [splat(br.o[0]), splat(br.o[1]), splat(br.o[2])];
    let (sx, sy, sz, t_min) = (splat(br.sx), splat(br.sy), splat(br.sz), splat(br.t_min));
    let [kx, ky, kz] = [br.kx, br.ky, br.kz];
    // PERF: one pass per pair, its edge functions computed once. Gathering
    // the masks first, as the four-lane loop does, needed the edge functions
    // from a helper, which was called out of line with its registers
    // spilled (helpers and closures are not inlined across the AVX2 target
    // feature): robots shadow rays took 1.4x the four-lane loop's time.
    for p in (0..count).step_by(PAIR) {
        let q = (p + 1).min(count - 1);
        let (lo, hi) = (&leaf_blocks[p], &leaf_blocks[q]);
        // SAFETY: each coordinate row is four contiguous f32 of a block; the
        // two unaligned loads read exactly those 16 bytes each.
        let pair = |vert: usize, axis: usize| unsafe {
            _mm256_loadu2_m128(
                hi.v[vert][axis].as_array().as_ptr(),
                lo.v[vert][axis].as_array().as_ptr(),
            )
        };
        let a = [pair(0, kx), pair(0, ky), pair(0, kz)];
        let b = [pair(1, kx), pair(1, ky), pair(1, kz)];
        let c = [pair(2, kx), pair(2, ky), pair(2, kz)];
        let e = Edges8::new(&a, &b, &c, &o, sx, sy);
        let mixed = e.mixed();
        let pad = padding(n, p) | (padding(n, p + 1) << LANES);
        let lanes = !_mm256_movemask_ps(mixed).cast_unsigned() & 0xFF & !pad;
        if lanes == 0 {
            continue;
        }
        let start = bound;
        let d = e.decide(mixed, sz, t_min, _mm256_set1_ps(start));
        let found = Found {
            hit: d.hit,
            edge: d.edge,
            t: lanes8(d.t),
            b1: lanes8(d.b1),
            b2: lanes8(d.b2),
            ts: lanes8(d.ts),
            abs_det: lanes8(d.abs_det),
        };
        let base = off + p * LANES;
        let tri = |lane: usize| leaf_blocks[p + lane / LANES].triangle(lane % LANES);
        if found.visit(ray, lanes, start, &mut bound, tri, |lane| ids[base + lane], &mut visit) {
            return true;
        }
    }
    false
}
