//! The 4-wide node test in SSE (through glam's `Vec4`; NEON or scalar code on other
//! architectures): [`crate::boxtest`]'s slab test, one 128-bit register per box coordinate
//! of a [`Node4`]'s four children. It is the 4-wide tree's portable test and its scalar twin
//! is [`Scalar4`]: `maxps` / `minps` with the candidate first drop a `0 * inf` NaN as the
//! twin's explicit test does, and without fused multiply-add every lane rounds as the twin's
//! (`tests/twins.rs`).

use glam::{BVec4A, Vec4};
use kdtree::Ray;

use crate::boxtest::{BoxTest, RayBoxes, Scalar4, TINY, WIDEN};
use crate::node::{Lanes, Node4};

// A `Lanes<4>` is read as a `Vec4` in place (`load`): four `f32`, the `Vec4` no more aligned.
const _: () = assert!(size_of::<Vec4>() == size_of::<Lanes<4>>() && align_of::<Vec4>() <= align_of::<Lanes<4>>());

/// [`hit4`] as a [`BoxTest`]: the default test of [`Node4`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Simd4;

impl BoxTest for Simd4 {
    type Node = Node4;
    type RayData = RayBoxes4;
    type Nears = [f32; 4];
    type Twin = Scalar4;

    fn twin(self) -> Scalar4 {
        Scalar4::default()
    }

    #[inline(always)]
    fn prepare(ray: &Ray) -> RayBoxes4 {
        RayBoxes4::new(ray)
    }

    #[inline(always)]
    fn hit(self, node: &Node4, r: &RayBoxes4, t_min: f32, t_max: f32) -> (u32, [f32; 4]) {
        let (mask, near) = hit4(node, r, t_min, t_max);
        (mask, near.to_array())
    }

    #[inline(always)]
    fn hit_forward(self, node: &Node4, r: &RayBoxes4, t_min: f32, t_max: f32) -> (u32, [f32; 4]) {
        let (mask, near) = hit4_forward(node, r, t_min, t_max);
        (mask, near.to_array())
    }
}

/// [`RayBoxes`] splatted over four lanes, computed once per ray.
#[derive(Clone, Copy, Debug)]
pub struct RayBoxes4 {
    /// The origin's coordinates, each splatted.
    pub o: [Vec4; 3],
    /// `1 / d`, each splatted.
    pub inv: [Vec4; 3],
    /// [`RayBoxes::inv_entry`], each splatted.
    pub inv_entry: [Vec4; 3],
    /// [`RayBoxes::inv_exit`], each splatted.
    pub inv_exit: [Vec4; 3],
    /// Per axis, the near plane ([`RayBoxes::near`]).
    pub near: [usize; 3],
}

impl RayBoxes4 {
    /// The box-test data of `ray`.
    #[inline(always)]
    pub fn new(ray: &Ray) -> RayBoxes4 {
        let r = RayBoxes::new(ray);
        RayBoxes4 {
            o: r.o.map(Vec4::splat),
            inv: r.inv.map(Vec4::splat),
            inv_entry: r.inv_entry.map(Vec4::splat),
            inv_exit: r.inv_exit.map(Vec4::splat),
            near: r.near,
        }
    }
}

/// One box coordinate of the four children, read in place (one aligned 128-bit load).
#[inline(always)]
fn load(lanes: &Lanes<4>) -> Vec4 {
    // SAFETY: a `Lanes<4>` is four `f32` (16 bytes, 16-byte aligned) and a `Vec4` four `f32`
    // of the same size and no stricter alignment (asserted above), valid for any bits.
    unsafe { *(lanes as *const Lanes<4>).cast::<Vec4>() }
}

/// The four children's box test (SIMD): the mask of the slots whose box the ray's interval
/// `[t_min, t_max]` enters, bit `i` for slot `i`, and the (widened) entry distances.
#[inline(always)]
pub fn hit4(node: &Node4, r: &RayBoxes4, t_min: f32, t_max: f32) -> (u32, Vec4) {
    let mut near = Vec4::splat(t_min);
    let mut far = Vec4::splat(t_max);
    for axis in 0..3 {
        // `& 1`: the index is 0 or 1 by construction; the mask spares the bounds check.
        let planes = &node.bounds[axis];
        let n = (load(&planes[r.near[axis] & 1]) - r.o[axis]) * r.inv[axis];
        let f = (load(&planes[(r.near[axis] ^ 1) & 1]) - r.o[axis]) * r.inv[axis];
        // Candidate first: a NaN candidate (0 * inf) leaves the accumulator (module docs).
        near = n.max(near);
        far = f.min(far);
    }
    let near = near - (near.abs() * WIDEN + TINY);
    let far = far + (far.abs() * WIDEN + TINY);
    let mask: BVec4A = near.cmple(far);
    (mask.bitmask(), near)
}

/// The four children's forward test (SIMD), for `t_min >= 0` (`crate::boxtest`'s **The
/// forward test**, without fused multiply-add): each plane's offset times the ray's scaled
/// reciprocal, the reductions, then `-+ TINY`, as its twin
/// [`crate::boxtest::hit_scalar_forward`] does lane for lane.
#[inline(always)]
pub fn hit4_forward(node: &Node4, r: &RayBoxes4, t_min: f32, t_max: f32) -> (u32, Vec4) {
    let mut near = Vec4::splat(t_min);
    let mut far = Vec4::splat(t_max);
    for axis in 0..3 {
        let planes = &node.bounds[axis];
        let n = (load(&planes[r.near[axis] & 1]) - r.o[axis]) * r.inv_entry[axis];
        let f = (load(&planes[(r.near[axis] ^ 1) & 1]) - r.o[axis]) * r.inv_exit[axis];
        // Candidate first: a NaN candidate (0 * inf) leaves the accumulator (module docs).
        near = n.max(near);
        far = f.min(far);
    }
    let (near, far) = (near - Vec4::splat(TINY), far + Vec4::splat(TINY));
    let mask: BVec4A = near.cmple(far);
    (mask.bitmask(), near)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boxtest::cases::{check, check_forward, hard_cases};

    #[test]
    fn the_hard_cases_equal_the_scalar_twin() {
        hard_cases::<4>(|n, ray| check(Simd4, n, ray));
        hard_cases::<4>(|n, ray| check_forward(Simd4, n, ray));
    }
}
