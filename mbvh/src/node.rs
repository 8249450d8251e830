//! The 4-wide multi-node (Wald, Benthin & Boulos 2008, section 3: the "multi-node" SoA
//! layout) and its ray-box test (section 5.2), SIMD and scalar; and the two traits every
//! width implements ([`MultiNode`], [`BoxTest`]; the 8-wide node is in [`crate::node8`]).
//!
//! A [`Node4`] holds the boxes of its four children structure-of-arrays: one `Vec4` per box
//! coordinate (`min.x` of the four children, then `min.y`, ...), so one SSE register holds one
//! coordinate of all four children and one slab test of a ray against the four boxes is six
//! subtractions, six multiplications and the min/max reductions. Unused slots hold the empty
//! box (`min = +inf`, `max = -inf`), which no ray enters.
//!
//! The slab test is conservative in exact arithmetic: a box the exact ray segment meets is
//! never culled. Each plane distance `(p - o) * (1 / d)` carries at most three roundings
//! (the subtraction, the reciprocal, the product), a relative error below `gamma_3 = 3 eps /
//! (1 - 3 eps)`; the entry distance is lowered and the exit distance raised by twice that
//! (Ize 2013, "Robust BVH ray traversal", uses the same bound on the exit distance), plus
//! the smallest normal float for products that underflow ([`TINY`]), so a grazing ray keeps
//! the box. Planes are picked by the direction's sign bit (near plane
//! `min` for `+d`, `max` for `-d`, `-0.0` counting as negative), which also makes the empty
//! box a miss for every ray.
//!
//! The one undefined product is `0 * inf`: a direction component is zero (`1 / d = ±inf`)
//! and the origin lies exactly on the box's plane, so the ray runs inside that face's plane
//! and the axis bounds nothing. The product is NaN; it is dropped in the reductions: each
//! step is `candidate.max(accumulator)` (SSE `maxps` returns its second operand when either
//! is NaN, and the accumulator, starting at the ray's finite `t_min` / `t_max`, never is),
//! and the scalar twin says the same with an explicit test. `node_test_matches_scalar_twin`
//! and `rays_in_face_planes_enter_the_box` check both.

use std::fmt::Debug;
use std::ops::Index;

use glam::{BVec4A, Vec3, Vec4};
use kdtree::{Aabb, Counters, Hit, Ray};

use crate::leaf::LeafBlock;
use crate::traverse::Traversal;

/// The branching factor of [`Node4`].
pub const WIDTH: usize = 4;

/// A child slot with no child.
pub const EMPTY: u32 = u32::MAX;

/// The flag of a leaf child: the rest of the word is its block index.
pub const LEAF: u32 = 1 << 31;

/// Twice `gamma_3` (`3 eps / (1 - 3 eps)`, eps = 2^-24): the relative widening of the entry
/// and exit distances that keeps the box test conservative (module docs).
pub const WIDEN: f32 = 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// The absolute part of the widening: a product that underflows to a subnormal or zero has
/// an absolute, not a relative, error (below `2^-149`); the smallest normal float covers it.
pub const TINY: f32 = f32::MIN_POSITIVE;

/// A multi-node: the boxes of up to four children, SoA, and what each child is.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Node4 {
    /// Per axis `[min, max]`, each a `Vec4` over the four children.
    pub bounds: [[Vec4; 2]; 3],
    /// Per slot: [`EMPTY`], a leaf (`LEAF | block`) or the index of an inner [`Node4`].
    pub child: [u32; WIDTH],
}

impl Node4 {
    /// A node with four empty slots.
    pub fn empty() -> Node4 {
        let (inf, ninf) = (Vec4::splat(f32::INFINITY), Vec4::splat(f32::NEG_INFINITY));
        Node4 { bounds: [[inf, ninf]; 3], child: [EMPTY; WIDTH] }
    }

    /// Sets slot `i` to `child` with box `b`.
    pub fn set(&mut self, i: usize, child: u32, b: &Aabb) {
        for axis in 0..3 {
            self.bounds[axis][0][i] = b.min[axis];
            self.bounds[axis][1][i] = b.max[axis];
        }
        self.child[i] = child;
    }

    /// The box of slot `i` (empty for an empty slot).
    pub fn child_box(&self, i: usize) -> Aabb {
        let c = |k: usize| Vec3::new(self.bounds[0][k][i], self.bounds[1][k][i], self.bounds[2][k][i]);
        Aabb { min: c(0), max: c(1) }
    }
}

/// A multi-node of some width (section 3): what the build, `validate` and the traversal need.
pub trait MultiNode: Copy + Debug + Send + Sync + 'static {
    /// Child slots per node.
    const WIDTH: usize;
    /// The box test used when no wider instruction set is asked for: portable, on every CPU.
    type Test: BoxTest<Node = Self> + Default;
    /// A node with every slot empty.
    fn empty() -> Self;
    /// Sets slot `i` to `child` with box `b`.
    fn set(&mut self, i: usize, child: u32, b: &Aabb);
    /// The box of slot `i` (empty for an empty slot).
    fn child_box(&self, i: usize) -> Aabb;
    /// Per slot: [`EMPTY`], a leaf (`LEAF | block`) or the index of an inner node.
    fn children(&self) -> &[u32];
}

impl MultiNode for Node4 {
    const WIDTH: usize = WIDTH;
    type Test = Simd4;

    fn empty() -> Node4 {
        Node4::empty()
    }

    fn set(&mut self, i: usize, child: u32, b: &Aabb) {
        Node4::set(self, i, child, b);
    }

    fn child_box(&self, i: usize) -> Aabb {
        Node4::child_box(self, i)
    }

    #[inline(always)]
    fn children(&self) -> &[u32] {
        &self.child
    }
}

/// One ray against every child box of a node (section 5.2): the mask of the slots whose box
/// the ray's interval enters (bit `i` for slot `i`) and their widened entry distances, every
/// implementation of one node type giving the same bits (the module docs' conservative test).
///
/// A test is a value: [`crate::node8::Avx2`] can only be made after the CPU was found to
/// have AVX2, so holding one proves its instructions may run. [`BoxTest::closest`] and
/// [`BoxTest::any`] are the traversal's entry points, so that a test can run the whole loop
/// under its target features (one check when the traversal is made, none per ray).
pub trait BoxTest: Copy + Debug + Send + Sync + 'static {
    /// The node it tests.
    type Node: MultiNode;
    /// What it precomputes once per ray.
    type RayData: Copy;
    /// Entry distances, one per slot.
    type Nears: Copy + Index<usize, Output = f32>;
    /// The scalar twin: the same arithmetic lane by lane (bit-identical masks and distances).
    type Twin: BoxTest<Node = Self::Node>;
    /// This test's scalar twin.
    fn twin(self) -> Self::Twin;
    /// The per-ray precomputation.
    fn prepare(ray: &Ray) -> Self::RayData;
    /// The slots of `node` whose box `[t_min, t_max]` enters, and the entry distances.
    fn hit(self, node: &Self::Node, r: &Self::RayData, t_min: f32, t_max: f32) -> (u32, Self::Nears);
    /// The closest hit of `ray` through `tr` ([`Traversal::intersect_counted`]).
    #[inline(always)]
    fn closest<B: LeafBlock, C: Counters>(tr: &Traversal<'_, B, Self>, ray: &Ray, counters: &mut C) -> Option<Hit> {
        tr.closest_loop::<true, C>(ray, counters)
    }
    /// Whether `ray` hits anything through `tr` ([`Traversal::occluded_counted`]).
    #[inline(always)]
    fn any<B: LeafBlock, C: Counters>(tr: &Traversal<'_, B, Self>, ray: &Ray, counters: &mut C) -> bool {
        tr.any_loop::<true, C>(ray, counters)
    }
}

/// [`hit4`]: the 4-wide node test in glam's `Vec4` (SSE on x86-64), the default of [`Node4`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Simd4;

/// [`hit4_scalar`]: the scalar twin of [`Simd4`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Scalar4;

impl BoxTest for Simd4 {
    type Node = Node4;
    type RayData = RayBoxes;
    type Nears = [f32; 4];
    type Twin = Scalar4;

    fn twin(self) -> Scalar4 {
        Scalar4
    }

    #[inline(always)]
    fn prepare(ray: &Ray) -> RayBoxes {
        RayBoxes::new(ray)
    }

    #[inline(always)]
    fn hit(self, node: &Node4, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; 4]) {
        let (mask, near) = hit4(node, r, t_min, t_max);
        (mask, near.to_array())
    }
}

impl BoxTest for Scalar4 {
    type Node = Node4;
    type RayData = Ray;
    type Nears = [f32; 4];
    type Twin = Scalar4;

    fn twin(self) -> Scalar4 {
        Scalar4
    }

    #[inline(always)]
    fn prepare(ray: &Ray) -> Ray {
        *ray
    }

    #[inline(always)]
    fn hit(self, node: &Node4, ray: &Ray, t_min: f32, t_max: f32) -> (u32, [f32; 4]) {
        hit4_scalar(node, ray, t_min, t_max)
    }
}

/// What the box test needs of a ray, computed once per ray: origin and reciprocal direction
/// splatted over four lanes, and per axis which plane is the near one (`0`: `min`, `1`:
/// `max`, the direction's sign bit).
#[derive(Clone, Copy, Debug)]
pub struct RayBoxes {
    /// The origin's coordinates, each splatted.
    pub o: [Vec4; 3],
    /// `1 / d`, each splatted.
    pub inv: [Vec4; 3],
    /// Per axis, the near plane: `0` (`min`) for a positive direction, `1` (`max`) for a
    /// negative one (`-0.0` included); the far plane is the other.
    pub near: [usize; 3],
}

impl RayBoxes {
    /// The box-test data of `ray`.
    #[inline(always)]
    pub fn new(ray: &Ray) -> RayBoxes {
        let near = [0, 1, 2].map(|axis| usize::from(ray.dir[axis].is_sign_negative()));
        RayBoxes {
            o: [Vec4::splat(ray.origin.x), Vec4::splat(ray.origin.y), Vec4::splat(ray.origin.z)],
            inv: [Vec4::splat(ray.inv_dir.x), Vec4::splat(ray.inv_dir.y), Vec4::splat(ray.inv_dir.z)],
            near,
        }
    }
}

/// The four children's box test (SIMD): the mask of the slots whose box the ray's interval
/// `[t_min, t_max]` enters, bit `i` for slot `i`, and the (widened) entry distances.
#[inline(always)]
pub fn hit4(node: &Node4, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, Vec4) {
    let mut near = Vec4::splat(t_min);
    let mut far = Vec4::splat(t_max);
    for axis in 0..3 {
        // `& 1`: the index is 0 or 1 by construction; the mask spares the bounds check.
        let planes = &node.bounds[axis];
        let n = (planes[r.near[axis] & 1] - r.o[axis]) * r.inv[axis];
        let f = (planes[(r.near[axis] ^ 1) & 1] - r.o[axis]) * r.inv[axis];
        // Candidate first: a NaN candidate (0 * inf) leaves the accumulator (module docs).
        near = n.max(near);
        far = f.min(far);
    }
    let near = near - (near.abs() * WIDEN + TINY);
    let far = far + (far.abs() * WIDEN + TINY);
    let mask: BVec4A = near.cmple(far);
    (mask.bitmask(), near)
}

/// The scalar twin of [`hit4`]: the same arithmetic lane by lane, with NaN dropped by an
/// explicit test.
pub fn hit4_scalar(node: &Node4, ray: &Ray, t_min: f32, t_max: f32) -> (u32, [f32; 4]) {
    let mut mask = 0;
    let mut nears = [0.0; 4];
    for (i, slot) in nears.iter_mut().enumerate() {
        let (mut near, mut far) = (t_min, t_max);
        for axis in 0..3 {
            let negative = ray.dir[axis].is_sign_negative();
            let (lo, hi) = (node.bounds[axis][0][i], node.bounds[axis][1][i]);
            let (pn, pf) = if negative { (hi, lo) } else { (lo, hi) };
            let n = (pn - ray.origin[axis]) * ray.inv_dir[axis];
            let f = (pf - ray.origin[axis]) * ray.inv_dir[axis];
            if !n.is_nan() {
                near = if n > near { n } else { near };
            }
            if !f.is_nan() {
                far = if f < far { f } else { far };
            }
        }
        let near = near - (near.abs() * WIDEN + TINY);
        let far = far + (far.abs() * WIDEN + TINY);
        if near <= far {
            mask |= 1 << i;
        }
        *slot = near;
    }
    (mask, nears)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn node(boxes: &[Aabb]) -> Node4 {
        let mut n = Node4::empty();
        for (i, b) in boxes.iter().enumerate() {
            n.set(i, i as u32, b);
        }
        n
    }

    fn unit(offset: Vec3) -> Aabb {
        Aabb { min: offset, max: offset + Vec3::ONE }
    }

    fn both(n: &Node4, ray: &Ray) -> u32 {
        let (m, near) = hit4(n, &RayBoxes::new(ray), ray.t_min, ray.t_max);
        let (ms, nears) = hit4_scalar(n, ray, ray.t_min, ray.t_max);
        assert_eq!(m, ms, "{ray:?}");
        for i in 0..4 {
            if m & (1 << i) != 0 {
                assert_eq!(near[i].to_bits(), nears[i].to_bits(), "{ray:?} lane {i}");
            }
        }
        m
    }

    #[test]
    fn plain_rays_enter_the_boxes_they_cross() {
        let n = node(&[unit(Vec3::ZERO), unit(Vec3::new(2.0, 0.0, 0.0)), unit(Vec3::new(0.0, 5.0, 0.0))]);
        let ray = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 0.0, f32::INFINITY);
        assert_eq!(both(&n, &ray), 0b011);
        let back = Ray::new(Vec3::new(9.0, 0.5, 0.5), -Vec3::X, 0.0, f32::INFINITY);
        assert_eq!(both(&n, &back), 0b011);
        let short = Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 0.0, 1.5);
        assert_eq!(both(&n, &short), 0b001);
        let behind = Ray::new(Vec3::new(9.0, 0.5, 0.5), Vec3::X, 0.0, f32::INFINITY);
        assert_eq!(both(&n, &behind), 0);
    }

    #[test]
    fn empty_slots_are_never_entered() {
        let n = Node4::empty();
        for d in [Vec3::X, -Vec3::X, Vec3::new(0.0, 0.0, 1.0), Vec3::new(-0.0, 1.0, -0.0), Vec3::ONE] {
            for o in [Vec3::ZERO, Vec3::splat(1e30), Vec3::splat(-1e30)] {
                assert_eq!(both(&n, &Ray::new(o, d, f32::NEG_INFINITY, f32::INFINITY)), 0);
            }
        }
    }

    #[test]
    fn rays_in_face_planes_enter_the_box() {
        // Zero direction components with the origin exactly on a face plane: 0 * inf.
        let n = node(&[unit(Vec3::ZERO)]);
        for (o, d) in [
            (Vec3::new(-1.0, 0.0, 0.5), Vec3::X),
            (Vec3::new(-1.0, 1.0, 0.5), Vec3::X),
            (Vec3::new(-1.0, 1.0, 1.0), Vec3::X),
            (Vec3::new(2.0, 0.0, 0.0), -Vec3::X),
            (Vec3::new(0.5, 0.0, -3.0), Vec3::new(-0.0, -0.0, 1.0)),
            (Vec3::new(0.0, 0.5, 3.0), Vec3::new(0.0, 0.0, -1.0)),
        ] {
            assert_eq!(both(&n, &Ray::new(o, d, 0.0, f32::INFINITY)), 1, "{o} {d}");
        }
        // Beside the box in that plane: missed.
        assert_eq!(both(&n, &Ray::new(Vec3::new(-1.0, 1.5, 0.5), Vec3::X, 0.0, f32::INFINITY)), 0);
    }

    #[test]
    fn grazing_rays_keep_the_box() {
        // The exact segment touches the box at one corner point.
        let n = node(&[unit(Vec3::ZERO)]);
        let d = Vec3::new(1.0, 1.0, 1.0) / 3.0f32.sqrt();
        let ray = Ray::new(Vec3::new(1.0, 1.0, 1.0) + d * 0.3, d, -1.0, f32::INFINITY);
        assert_eq!(both(&n, &ray), 1);
    }

    proptest! {
        #[test]
        fn node_test_matches_scalar_twin(
            boxes in prop::collection::vec((prop::array::uniform3(-4i32..4), prop::array::uniform3(0i32..4)), 1..5),
            o in prop::array::uniform3(-6i32..6), d in prop::array::uniform3(-2i32..3), t_min in -2.0f32..1.0,
        ) {
            let boxes: Vec<Aabb> = boxes.iter().map(|(lo, ext)| {
                let lo = Vec3::new(lo[0] as f32, lo[1] as f32, lo[2] as f32);
                Aabb { min: lo, max: lo + Vec3::new(ext[0] as f32, ext[1] as f32, ext[2] as f32) }
            }).collect();
            let d = Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32);
            prop_assume!(d != Vec3::ZERO);
            let o = Vec3::new(o[0] as f32, o[1] as f32, o[2] as f32) * 0.5;
            let ray = Ray::new(o, d, t_min, f32::INFINITY);
            let m = both(&node(&boxes), &ray);
            // Against an exact-enough reference: sample the segment densely in f64.
            for (i, b) in boxes.iter().enumerate() {
                let inside = (0..=4000).any(|k| {
                    let t = t_min as f64 + k as f64 * 0.005;
                    (0..3).all(|a| {
                        let p = o[a] as f64 + t * d[a] as f64;
                        p >= b.min[a] as f64 && p <= b.max[a] as f64
                    })
                });
                if inside {
                    prop_assert!(m & (1 << i) != 0, "box {i} {b:?} missed by {ray:?}");
                }
            }
        }
    }
}
