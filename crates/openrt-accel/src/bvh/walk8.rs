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

use super::node::LEAF_BIT;
use super::node8::{BVH8_WIDTH, Node8, STACK8};
use super::walk::{FAR_WIDEN, NEAR_SLACK};
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
    let (o, inv, d) = (ray.origin.to_array(), ray.inv_dir.to_array(), ray.dir.to_array());
    let mut mask = 0;
    let mut nears = [0.0; BVH8_WIDTH];
    for (i, slot_near) in nears.iter_mut().enumerate() {
        let b = node.child_box(i);
        let (lo, hi) = (b.min.to_array(), b.max.to_array());
        let (mut near, mut far, mut inside) = (ray.t_min, f32::INFINITY, true);
        for a in 0..3 {
            let (n, f) = if inv[a].is_sign_negative() {
                (hi[a], lo[a])
            } else {
                (lo[a], hi[a])
            };
            if d[a] == 0.0 {
                inside &= lo[a] <= o[a] && o[a] <= hi[a];
                continue;
            }
            // maxps / minps: the second operand unless the first is greater / less.
            let tn = (n - o[a]) * inv[a];
            let tf = (f - o[a]) * inv[a];
            near = if near > tn { near } else { tn };
            far = if far < tf { far } else { tf };
        }
        let far = far * FAR_WIDEN;
        let far = if far < closest { far } else { closest };
        let near = near - near.abs() * NEAR_SLACK;
        *slot_near = near;
        if inside && near <= far {
            mask |= 1 << i;
        }
    }
    (mask, nears)
}

/// The AVX2 node test, for the twin's test.
#[cfg(test)]
pub(crate) fn node8_test_avx2(ray: &Ray, node: &Node8, closest: f32) -> Option<(u32, [f32; BVH8_WIDTH])> {
    // SAFETY: called only where the CPU has AVX2.
    crate::packet::width::avx2().then(|| unsafe { NodeRay8::new(ray).test(node, closest) })
}

/// A deferred child: its slot value, triangle count and entry distance.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    count: u32,
    near: f32,
}

/// [`super::walk::walk`] over the eight-wide tree `nodes` (root 0): the
/// children that `ray` meets, nearest first; `leaf(offset, count, closest)`
/// lowers `closest` on a hit and returns `true` to stop (any hit).
///
/// # Safety
/// The CPU must have AVX2 (`crate::packet::width::avx2()`).
#[target_feature(enable = "avx2")]
#[inline]
pub(crate) unsafe fn walk8<L>(nodes: &[Node8], ray: &Ray, closest: &mut f32, mut leaf: L) -> bool
where
    L: FnMut(u32, u32, &mut f32) -> bool,
{
    if nodes.is_empty() {
        return false;
    }
    let nr = NodeRay8::new(ray);
    // PERF: not zeroed (a 7 kB memset per ray); written before read.
    let mut stack = [std::mem::MaybeUninit::<Entry>::uninit(); STACK8];
    let mut sp = 0usize;
    let mut cur = Entry {
        child: 0,
        count: 0,
        near: f32::NEG_INFINITY,
    };
    loop {
        if cur.child & LEAF_BIT != 0 {
            if leaf(cur.child & !LEAF_BIT, cur.count, closest) {
                return true;
            }
        } else {
            let node = &nodes[cur.child as usize];
            let (mut mask, near) = nr.test(node, *closest);
            if mask != 0 {
                if mask.is_power_of_two() {
                    let i = mask.trailing_zeros() as usize;
                    cur = Entry {
                        child: node.child[i],
                        count: node.count[i],
                        near: near[i],
                    };
                    continue;
                }
                // Insertion by entry distance, farthest first; the nearest
                // goes on at once.
                let mut order = [0usize; BVH8_WIDTH];
                let mut n = 0;
                while mask != 0 {
                    let i = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    let mut j = n;
                    while j > 0 && near[order[j - 1]] < near[i] {
                        order[j] = order[j - 1];
                        j -= 1;
                    }
                    order[j] = i;
                    n += 1;
                }
                for &i in &order[..n - 1] {
                    stack[sp].write(Entry {
                        child: node.child[i],
                        count: node.count[i],
                        near: near[i],
                    });
                    sp += 1;
                }
                let i = order[n - 1];
                cur = Entry {
                    child: node.child[i],
                    count: node.count[i],
                    near: near[i],
                };
                continue;
            }
        }
        loop {
            if sp == 0 {
                return false;
            }
            sp -= 1;
            // SAFETY: entries below `sp` were written by the pushes above.
            cur = unsafe { stack[sp].assume_init() };
            if cur.near <= *closest {
                break;
            }
        }
    }
}
