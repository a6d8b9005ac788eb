//! Single-ray traversal of the eight-wide tree with AVX2: the four-wide
//! walk's node test ([`super::walk`]: Ize's robust slab test, far distances
//! widened by [`FAR_WIDEN`], near ones lowered by [`NEAR_SLACK`]) on eight
//! boxes in one register per coordinate (Fuetterling et al. 2017,
//! "Accelerated single ray tracing for wide vector units"), chosen at run
//! time. The scalar twin `node8_test_scalar` computes the same bits per
//! lane (tested); the operations and their order are the four-wide test's.

use core::arch::x86_64::{
    __m256, _CMP_LE_OQ, _mm256_and_ps, _mm256_andnot_ps, _mm256_cmp_ps, _mm256_loadu_ps, _mm256_max_ps, _mm256_min_ps,
    _mm256_movemask_ps, _mm256_mul_ps, _mm256_set1_ps, _mm256_storeu_ps, _mm256_sub_ps,
};

use super::node8::{BVH8_WIDTH, Node8};
use super::walk::{FAR_WIDEN, NEAR_SLACK, SlotNode, walk_nodes};
use crate::geom::ray::Ray;

/// A ray's constants for the eight-wide node test.
struct NodeRay8 {
    o: [__m256; 3],
    inv: [__m256; 3],
    neg: [bool; 3],
    parallel: [bool; 3],
    any_parallel: bool,
    t_min: __m256,
}

impl NodeRay8 {
    #[target_feature(enable = "avx2")]
    fn new(ray: &Ray) -> Self {
        let o = ray.origin.to_array();
        let inv = ray.inv_dir.to_array();
        let parallel = ray.dir.to_array().map(|x| x == 0.0);
        Self {
            o: o.map(|v| _mm256_set1_ps(v)),
            inv: inv.map(|v| _mm256_set1_ps(v)),
            neg: inv.map(f32::is_sign_negative),
            parallel,
            any_parallel: parallel.iter().any(|&p| p),
            t_min: _mm256_set1_ps(ray.t_min),
        }
    }

    /// The children of `node` that the ray may meet before `closest`, as a
    /// mask, with their lowered entry distances.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn test(&self, node: &Node8, closest: f32) -> (u32, [f32; BVH8_WIDTH]) {
        let mut near = self.t_min;
        let mut far = _mm256_set1_ps(f32::INFINITY);
        let mut inside = _mm256_set1_ps(f32::from_bits(u32::MAX));
        for a in 0..3 {
            let (lo, hi) = (row(&node.lo[a]), row(&node.hi[a]));
            let (n, f) = if self.neg[a] { (hi, lo) } else { (lo, hi) };
            if self.any_parallel && self.parallel[a] {
                inside = _mm256_and_ps(
                    _mm256_and_ps(inside, _mm256_cmp_ps::<_CMP_LE_OQ>(lo, self.o[a])),
                    _mm256_cmp_ps::<_CMP_LE_OQ>(self.o[a], hi),
                );
                continue;
            }
            near = _mm256_max_ps(near, _mm256_mul_ps(_mm256_sub_ps(n, self.o[a]), self.inv[a]));
            far = _mm256_min_ps(far, _mm256_mul_ps(_mm256_sub_ps(f, self.o[a]), self.inv[a]));
        }
        let far = _mm256_min_ps(_mm256_mul_ps(far, _mm256_set1_ps(FAR_WIDEN)), _mm256_set1_ps(closest));
        let abs = _mm256_andnot_ps(_mm256_set1_ps(-0.0), near);
        let near = _mm256_sub_ps(near, _mm256_mul_ps(abs, _mm256_set1_ps(NEAR_SLACK)));
        let mask = _mm256_movemask_ps(_mm256_and_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far), inside));
        let mut nears = [0.0f32; BVH8_WIDTH];
        // SAFETY: `nears` is eight contiguous f32; the unaligned store
        // writes exactly those 32 bytes.
        unsafe { _mm256_storeu_ps(nears.as_mut_ptr(), near) };
        (mask.cast_unsigned(), nears)
    }
}

/// One box coordinate of eight children.
#[target_feature(enable = "avx2")]
#[inline]
fn row(r: &[f32; BVH8_WIDTH]) -> __m256 {
    // SAFETY: eight contiguous f32; the unaligned load reads exactly those
    // 32 bytes.
    unsafe { _mm256_loadu_ps(r.as_ptr()) }
}

/// The scalar twin of the AVX2 node test: the same operations lane by lane.
#[cfg(test)]
pub(crate) fn node8_test_scalar(ray: &Ray, node: &Node8, closest: f32) -> (u32, [f32; BVH8_WIDTH]) {
    let mut mask = 0;
    let mut nears = [0.0; BVH8_WIDTH];
    for (i, slot_near) in nears.iter_mut().enumerate() {
        let (met, near) = super::walk::box_test_scalar(ray, &node.child_box(i), closest);
        *slot_near = near;
        mask |= u32::from(met) << i;
    }
    (mask, nears)
}

/// The AVX2 node test, for the twin's test.
#[cfg(test)]
pub(crate) fn node8_test_avx2(ray: &Ray, node: &Node8, closest: f32) -> Option<(u32, [f32; BVH8_WIDTH])> {
    // SAFETY: called only where the CPU has AVX2.
    crate::packet::width::avx2().then(|| unsafe { NodeRay8::new(ray).test(node, closest) })
}

impl SlotNode for Node8 {
    #[inline]
    fn slot(&self, i: usize) -> (u32, u32) {
        (self.child[i], self.count[i])
    }
}

/// [`super::walk::walk`] over the eight-wide tree `nodes` (root 0): the
/// children that `ray` meets, nearest first; `leaf(offset, count, closest)`
/// lowers `closest` on a hit and returns `true` to stop (any hit).
///
/// # Safety
/// The CPU must have AVX2 (`crate::packet::width::avx2()`).
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) unsafe fn walk8<L>(nodes: &[Node8], ray: &Ray, closest: &mut f32, leaf: L) -> bool
where
    L: FnMut(u32, u32, &mut f32) -> bool,
{
    if nodes.is_empty() {
        return false;
    }
    let nr = NodeRay8::new(ray);
    walk_nodes(nodes, closest, |node, closest| nr.test(node, closest), leaf)
}
