//! The shadow-ray copy of the BVH: CWBVH nodes with their child planes already `f32`, tested
//! with obvhs's own node test (see [`ShadowNode`]).

use super::*;

/// A CWBVH node for shadow rays: the fields obvhs's `traverse!` reads, and the child planes
/// converted from bytes to `f32` once instead of at every node test (the conversion was most of
/// a node test). The test is obvhs's `CwBvhNode::intersect_ray_simd` on the converted planes: the
/// same operations on the same values, so the same children are visited.
#[derive(Clone, Copy)]
#[repr(C, align(16))]
pub(super) struct ShadowNode {
    /// Child planes, `[min_x, max_x, min_y, max_y, min_z, max_z]`, 8 children each.
    pub(super) planes: [[f32; 8]; 6],
    pub(super) p: Vec3A,
    pub(super) extent: Vec3A,
    pub(super) child_meta: [u8; 8],
    pub(super) child_base_idx: u32,
    pub(super) primitive_base_idx: u32,
    pub(super) imask: u8,
}

/// The node tests of obvhs's CWBVH clamp the entry distance at this (its `EPSILON`).
pub(super) const NODE_TMIN: f32 = 0.0001;

impl ShadowNode {
    pub(super) fn new(n: &CwBvhNode) -> Self {
        let f = |q: &[u8; 8]| q.map(f32::from);
        Self {
            planes: [
                f(&n.child_min_x),
                f(&n.child_max_x),
                f(&n.child_min_y),
                f(&n.child_max_y),
                f(&n.child_min_z),
                f(&n.child_max_z),
            ],
            p: Vec3A::from(n.p),
            extent: n.compute_extent(),
            child_meta: n.child_meta,
            child_base_idx: n.child_base_idx,
            primitive_base_idx: n.primitive_base_idx,
            imask: n.imask,
        }
    }

    /// The hit mask of the children `ray` enters (obvhs's layout: internal children in the
    /// high byte, leaf primitives in the low 24 bits).
    #[inline(always)]
    pub(super) fn intersect(&self, ray: &Ray, oct_inv4: u32) -> u32 {
        let adj_dir_inv = self.extent * ray.inv_direction;
        let adj_origin = (self.p - ray.origin) * ray.inv_direction;
        let (child_bits8, bit_index8) = CwBvhNode {
            child_meta: self.child_meta,
            ..CwBvhNode::default()
        }
        .get_child_and_index_bits(oct_inv4);
        // The slabs' near side follows the sign of `inv_direction`, which obvhs takes from
        // the direction's sign bit: a -0.0 component (a sun straight down, negated) has a
        // negative inverse although `-0.0 < 0.0` is false.
        let neg = [
            ray.inv_direction.x < 0.0,
            ray.inv_direction.y < 0.0,
            ray.inv_direction.z < 0.0,
        ];
        let mut hit_mask = 0u32;
        for i in 0..2 {
            let mask = self.children4(i, &neg, adj_dir_inv, adj_origin, ray.tmax);
            for j in 0..4 {
                if mask & (1 << j) != 0 {
                    let child_bits = extract_byte64(child_bits8, i * 4 + j);
                    let bit_index = extract_byte64(bit_index8, i * 4 + j);
                    hit_mask |= child_bits << bit_index;
                }
            }
        }
        hit_mask
    }

    /// Which of children `4 i .. 4 i + 4` the ray enters, a 4-bit mask.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(super) fn children4(
        &self,
        i: usize,
        neg: &[bool; 3],
        dir: Vec3A,
        orig: Vec3A,
        tmax: f32,
    ) -> u32 {
        use std::arch::x86_64::*;
        let slab = |axis: usize, d: f32, o: f32| {
            // SAFETY: SSE2 is part of x86_64; each load reads floats 4 i .. 4 i + 4 of 8.
            unsafe {
                let lo = _mm_loadu_ps(self.planes[2 * axis].as_ptr().add(4 * i));
                let hi = _mm_loadu_ps(self.planes[2 * axis + 1].as_ptr().add(4 * i));
                let (near, far) = if neg[axis] { (hi, lo) } else { (lo, hi) };
                let (d, o) = (_mm_set1_ps(d), _mm_set1_ps(o));
                (
                    _mm_add_ps(_mm_mul_ps(near, d), o),
                    _mm_add_ps(_mm_mul_ps(far, d), o),
                )
            }
        };
        let (tmin_x, tmax_x) = slab(0, dir.x, orig.x);
        let (tmin_y, tmax_y) = slab(1, dir.y, orig.y);
        let (tmin_z, tmax_z) = slab(2, dir.z, orig.z);
        // SAFETY: SSE2 is part of x86_64.
        unsafe {
            let t0 = _mm_max_ps(tmin_x, _mm_max_ps(tmin_y, tmin_z));
            let t1 = _mm_min_ps(tmax_x, _mm_min_ps(tmax_y, tmax_z));
            let t0 = _mm_max_ps(t0, _mm_set1_ps(NODE_TMIN));
            let t1 = _mm_min_ps(t1, _mm_set1_ps(tmax));
            _mm_movemask_ps(_mm_cmple_ps(t0, t1)) as u32
        }
    }

    /// Which of children `4 i .. 4 i + 4` the ray enters, a 4-bit mask (scalar fallback, the
    /// same operations lane by lane; `_mm_max_ps(a, b)` is `if a > b { a } else { b }`).
    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    pub(super) fn children4(
        &self,
        i: usize,
        neg: &[bool; 3],
        dir: Vec3A,
        orig: Vec3A,
        tmax: f32,
    ) -> u32 {
        let max = |a: f32, b: f32| if a > b { a } else { b };
        let min = |a: f32, b: f32| if a < b { a } else { b };
        let (d, o) = ([dir.x, dir.y, dir.z], [orig.x, orig.y, orig.z]);
        let mut mask = 0;
        for j in 0..4 {
            let c = 4 * i + j;
            let t = |axis: usize| {
                let (lo, hi) = (self.planes[2 * axis][c], self.planes[2 * axis + 1][c]);
                let (near, far) = if neg[axis] { (hi, lo) } else { (lo, hi) };
                (near * d[axis] + o[axis], far * d[axis] + o[axis])
            };
            let ((x0, x1), (y0, y1), (z0, z1)) = (t(0), t(1), t(2));
            let t0 = max(max(x0, max(y0, z0)), NODE_TMIN);
            let t1 = min(min(x1, min(y1, z1)), tmax);
            mask |= u32::from(t0 <= t1) << j;
        }
        mask
    }
}

/// The shadow-ray copy of the BVH's nodes, indexed like `CwBvh::nodes`.
pub(super) struct ShadowBvh {
    pub(super) nodes: Vec<ShadowNode>,
}

impl ShadowBvh {
    pub(super) fn new(bvh: &CwBvh) -> Self {
        Self {
            nodes: bvh.nodes.iter().map(ShadowNode::new).collect(),
        }
    }
}
