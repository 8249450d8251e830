//! The ray-box test of a multi-node (Wald, Benthin & Boulos 2008, section 5.2): one ray
//! against the `W` child boxes of a [`Node<W>`] at once. This module holds what every
//! implementation shares: the [`BoxTest`] trait, the conservative arithmetic ([`WIDEN`],
//! [`TINY`]) and the portable scalar test written once for every width ([`Scalar<W>`],
//! [`hit_scalar`]), which is also the scalar twin of each SIMD test ([`crate::simd4`]:
//! SSE, 4 wide; [`crate::simd8`]: AVX2, 8 wide; [`crate::simd16`]: AVX-512, 16 wide).
//!
//! The boxes are SoA (one lane array per box coordinate), so one slab test of a ray against
//! `W` boxes is six subtractions, six multiplications and the min/max reductions, `W` lanes
//! at a time. Unused slots hold the empty box (`min = +inf`, `max = -inf`), which no ray
//! enters.
//!
//! The slab test is conservative in exact arithmetic: a box the exact ray segment meets is
//! never culled. Each plane distance `(p - o) * (1 / d)` carries at most three roundings
//! (the subtraction, the reciprocal, the product), a relative error below `gamma_3 = 3 eps /
//! (1 - 3 eps)`; the entry distance is lowered and the exit distance raised by twice that
//! (Ize 2013, "Robust BVH ray traversal", uses the same bound on the exit distance), plus
//! the smallest normal float for products that underflow ([`TINY`]), so a grazing ray keeps
//! the box. Planes are picked by the direction's sign bit (near plane `min` for `+d`, `max`
//! for `-d`, `-0.0` counting as negative), which also makes the empty box a miss for every
//! ray.
//!
//! The one undefined product is `0 * inf`: a direction component is zero (`1 / d = ±inf`)
//! and the origin lies exactly on the box's plane, so the ray runs inside that face's plane
//! and the axis bounds nothing. The product is NaN; it is dropped in the reductions: each
//! SIMD step is `max(candidate, accumulator)` (SSE `maxps` and AVX / AVX-512 `vmaxps`
//! return their second operand when either is NaN, and the accumulator, starting at the
//! ray's non-NaN `t_min` / `t_max`, never is), and the scalar test says the same with an
//! explicit test.
//! Every SIMD test does the same operations in the same order as the scalar test, so it
//! gives the scalar test's masks and entry distances bit for bit (`tests/twins.rs`).
//!
//! **The widening, fused where the instruction set has it.** The 8- and 16-wide tests (AVX2
//! with FMA, AVX-512) widen with one fused multiply-add and one addition ([`lowered`],
//! [`raised`]: `fma(-|t|, WIDEN, t) - TINY`); their twins are [`FusedScalar8`] and
//! [`FusedScalar16`] (`f32::mul_add`, correctly rounded on every CPU, a software routine
//! where the CPU has no FMA). Everything else widens unfused, a product and two additions
//! ([`lowered_unfused`], [`raised_unfused`], lane for lane): the 4-wide SSE test, the
//! 16-ray packet test, and the portable tests a tree falls back to without its SIMD test
//! ([`Scalar8`], [`Scalar16`]), where a software `fmaf` per lane would cost more than the
//! operation it saves (`docs/results/incoherent-mbvh.md#fused-widening`). The two forms can
//! differ in the last bit of an entry distance, and so order two equally near children
//! differently; both are conservative. The fused form rounds twice instead of three times,
//! so it lowers and raises by at least what the unfused form's bound asks (`WIDEN` is twice
//! `gamma_3`, the error of the distance itself); it takes one operation off the node step's
//! critical path, where the single-ray traversal spends its time waiting.
//!
//! **The forward test: the widening in the reciprocals.** For a ray whose interval starts at
//! or after its origin (`t_min >= 0`, every ray a renderer makes) every test has a second
//! form ([`BoxTest::hit_forward`], [`hit_scalar_forward`]). In the fused tests nothing
//! follows the reductions: each entry-plane distance is `fma(p - o, inv_entry, -TINY)` and each
//! exit-plane distance `fma(p - o, inv_exit, TINY)`, where `inv_entry` and `inv_exit` are `1 /
//! d` scaled once per ray by `1 -+ 2^-20` ([`ENTRY_EXIT_SCALE`], [`RayBoxes`]). A distance
//! `t >= 0` so computed carries the scale and four roundings (the subtraction, the
//! reciprocal, the scaling, the fused product), each a factor within `1 +- 2^-24`, so the
//! entry comes out at most `t` and the exit at least `t`; a product that underflows has an
//! absolute error below `2^-150`, which the `-+ TINY` inside the one rounding covers. For a
//! negative distance the scale points the wrong way, and harmlessly: a negative entry comes
//! out negative (the products keep their signs, `-TINY` only lowers), below `t_min >= 0`,
//! where it does not count; a negative exit belongs to a box that ends before the interval
//! starts, which a conservative test may keep or cull. So the test stays conservative, and
//! its entries remain lower bounds for the traversal's front-to-back order and culling. It
//! costs one multiply-add per plane where the fused test has a product, and takes the lowering and
//! raising (a fused multiply-add and an addition, eight cycles of latency) off the node
//! step's critical path. Without fused multiply-add (the SSE test, the portable tests, the
//! 16-ray packets' lanes) each product is rounded on its own, one more factor within `1 +-
//! 2^-24`, and `-+ TINY` comes once after the reductions, where it covers an underflowed
//! product's error: two additions per box after the reductions, where the unfused widening
//! has two absolute values, two products and four additions. Rays reaching behind their
//! origin keep the widened test.

use std::fmt::Debug;
use std::ops::Index;

use kdtree::{Counters, Hit, Ray};

use crate::node::{MultiNode, Node, NodeWidth, Width};

/// Twice `gamma_3` (`3 eps / (1 - 3 eps)`, eps = 2^-24): the relative widening of the entry
/// and exit distances that keeps the box test conservative (module docs).
pub const WIDEN: f32 = 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Whether `ray` takes the forward test ([`BoxTest::hit_forward`]): its interval starts at
/// or after its origin (`t_min >= 0`, `-0.0` included).
#[inline(always)]
pub fn forward(ray: &Ray) -> bool {
    ray.t_min >= 0.0
}

/// The absolute part of the widening: a product that underflows to a subnormal or zero has
/// an absolute, not a relative, error (below `2^-149`); the smallest normal float covers it.
pub const TINY: f32 = f32::MIN_POSITIVE;

/// The forward test's scale of a ray's reciprocals ([`RayBoxes::inv_entry`],
/// [`RayBoxes::inv_exit`]): `1 / d` times `1 - ENTRY_EXIT_SCALE` for the entry planes and
/// `1 + ENTRY_EXIT_SCALE` for the exit planes. `2^-20` is sixteen times the unit roundoff,
/// above the three roundings of a plane distance (the subtraction, the reciprocal, the
/// scaling) and the fused product's own (module docs, **The forward test**).
pub const ENTRY_EXIT_SCALE: f32 = 1.0 / (1u32 << 20) as f32;

/// The entry distance `near` lowered by [`WIDEN`] and [`TINY`] with one fused multiply-add
/// (`near - |near| WIDEN`, rounded once, then `- TINY`): the 8- and 16-wide tests' widening
/// (module docs).
#[inline(always)]
pub fn lowered(near: f32) -> f32 {
    near.abs().mul_add(-WIDEN, near) - TINY
}

/// The exit distance `far` raised by [`WIDEN`] and [`TINY`] with one fused multiply-add: the
/// 8- and 16-wide tests' widening (module docs).
#[inline(always)]
pub fn raised(far: f32) -> f32 {
    far.abs().mul_add(WIDEN, far) + TINY
}

/// The entry distance `near` lowered by [`WIDEN`] and [`TINY`], each operation rounded: the
/// unfused widening (module docs), which the SSE, portable and packet tests do lane for lane.
#[inline(always)]
pub fn lowered_unfused(near: f32) -> f32 {
    near - (near.abs() * WIDEN + TINY)
}

/// The exit distance `far` raised by [`WIDEN`] and [`TINY`], each operation rounded: the
/// unfused widening (module docs).
#[inline(always)]
pub fn raised_unfused(far: f32) -> f32 {
    far + (far.abs() * WIDEN + TINY)
}

/// The traversal loops of one tree, leaf test and node test, as a node test's entry points
/// ([`BoxTest::closest`], [`BoxTest::any`]) run them: `crate::Traversal` implements it.
pub trait TraversalLoop {
    /// The closest hit of `ray` (SIMD node and leaf tests).
    fn closest<C: Counters>(&self, ray: &Ray, counters: &mut C) -> Option<Hit>;
    /// Whether `ray` hits anything (SIMD node and leaf tests).
    fn any<C: Counters>(&self, ray: &Ray, counters: &mut C) -> bool;
}

/// One ray against every child box of a node (section 5.2): the mask of the slots whose box
/// the ray's interval enters (bit `i` for slot `i`) and their widened entry distances, every
/// implementation for one node type giving the same bits (the module docs' conservative
/// test).
///
/// A test is a value: [`crate::Avx2`] can only be made after the CPU was found to have
/// AVX2, so holding one proves its instructions may run. [`BoxTest::closest`] and
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
    /// [`BoxTest::hit`] for an interval that starts at or after the origin (`t_min >= 0`),
    /// where a test may widen more cheaply (module docs, **The forward test**): as
    /// conservative, its entry distances lower bounds too, but the mask and distances may
    /// differ from [`BoxTest::hit`]'s (never from its twin's). The traversal calls it for
    /// every ray with `t_min >= 0`; a test without a cheaper form answers with
    /// [`BoxTest::hit`].
    #[inline(always)]
    fn hit_forward(self, node: &Self::Node, r: &Self::RayData, t_min: f32, t_max: f32) -> (u32, Self::Nears) {
        self.hit(node, r, t_min, t_max)
    }
    /// The closest hit of `ray` through `l` (`Traversal::intersect_counted`); a test with
    /// target features runs `l` in a function compiled with them.
    #[inline(always)]
    fn closest<L: TraversalLoop, C: Counters>(self, l: &L, ray: &Ray, counters: &mut C) -> Option<Hit> {
        l.closest(ray, counters)
    }
    /// Whether `ray` hits anything through `l` (`Traversal::occluded_counted`).
    #[inline(always)]
    fn any<L: TraversalLoop, C: Counters>(self, l: &L, ray: &Ray, counters: &mut C) -> bool {
        l.any(ray, counters)
    }
}

/// What the box test needs of a ray, computed once per ray: origin, `1 / d` (plain, and
/// scaled for the forward test's entry and exit planes) and per axis the near plane (`0`:
/// `min` for a positive direction, `1`: `max` for a negative one, `-0.0` included; the far
/// plane is the other). Kept scalar; a SIMD test broadcasts them (hoisted out of the
/// traversal loop).
#[derive(Clone, Copy, Debug)]
pub struct RayBoxes {
    /// The origin.
    pub o: [f32; 3],
    /// `1 / d`.
    pub inv: [f32; 3],
    /// `1 / d` scaled towards zero, `(1 / d) (1 - 2^-20)`: the forward test's entry planes
    /// ([`ENTRY_EXIT_SCALE`]).
    pub inv_entry: [f32; 3],
    /// `1 / d` scaled away from zero, `(1 / d) (1 + 2^-20)`: the forward test's exit planes.
    pub inv_exit: [f32; 3],
    /// Per axis, the near plane's index in `Node::bounds[axis]`.
    pub near: [usize; 3],
}

impl RayBoxes {
    /// The box-test data of `ray`.
    #[inline(always)]
    pub fn new(ray: &Ray) -> RayBoxes {
        let inv = ray.inv_dir.to_array();
        RayBoxes {
            o: ray.origin.to_array(),
            inv,
            inv_entry: inv.map(|i| i * (1.0 - ENTRY_EXIT_SCALE)),
            inv_exit: inv.map(|i| i * (1.0 + ENTRY_EXIT_SCALE)),
            near: [0, 1, 2].map(|axis| usize::from(ray.dir[axis].is_sign_negative())),
        }
    }
}

/// The `W` children's box test, scalar: lane by lane the arithmetic of every SIMD test,
/// NaN dropped by an explicit test, widened with a fused multiply-add (`FUSED`, as the 8- and
/// 16-wide SIMD tests do) or without (module docs).
#[inline(always)]
pub fn hit_scalar<const W: usize, const FUSED: bool>(
    node: &Node<W>,
    r: &RayBoxes,
    t_min: f32,
    t_max: f32,
) -> (u32, [f32; W])
where
    Width<W>: NodeWidth,
{
    slab_scalar::<W, FUSED, false>(node, r, t_min, t_max)
}

/// The forward test ([`BoxTest::hit_forward`], valid for `t_min >= 0`), scalar: per lane and
/// axis the entry and exit planes' offsets `p - o` times the ray's scaled reciprocals
/// ([`RayBoxes::inv_entry`], [`RayBoxes::inv_exit`]), NaN dropped by an explicit test. With
/// `FUSED` each product is `fma(p - o, inv_entry, -TINY)` / `fma(p - o, inv_exit, TINY)`
/// (`f32::mul_add`, correctly rounded on every CPU) and nothing follows the reductions: the
/// twin of the AVX2 and AVX-512 forward tests. Without, each product is rounded on its own
/// and `-+ TINY` is applied once after the reductions: the portable tests' form and the twin
/// of the SSE one (module docs, **The forward test**).
#[inline(always)]
pub fn hit_scalar_forward<const W: usize, const FUSED: bool>(
    node: &Node<W>,
    r: &RayBoxes,
    t_min: f32,
    t_max: f32,
) -> (u32, [f32; W])
where
    Width<W>: NodeWidth,
{
    slab_scalar::<W, FUSED, true>(node, r, t_min, t_max)
}

/// The scalar slab test behind [`hit_scalar`] (`FORWARD = false`: plain products, the
/// widening after the reductions) and [`hit_scalar_forward`] (the scaled reciprocals).
#[inline(always)]
fn slab_scalar<const W: usize, const FUSED: bool, const FORWARD: bool>(
    node: &Node<W>,
    r: &RayBoxes,
    t_min: f32,
    t_max: f32,
) -> (u32, [f32; W])
where
    Width<W>: NodeWidth,
{
    let (inv_n, inv_f) = if FORWARD { (&r.inv_entry, &r.inv_exit) } else { (&r.inv, &r.inv) };
    let mut mask = 0;
    let mut nears = [0.0; W];
    for (i, slot) in nears.iter_mut().enumerate() {
        let (mut near, mut far) = (t_min, t_max);
        for axis in 0..3 {
            // `& 1`: the index is 0 or 1 by construction; the mask spares the bounds check.
            let planes = &node.bounds[axis];
            let entry = planes[r.near[axis] & 1][i] - r.o[axis];
            let exit = planes[(r.near[axis] ^ 1) & 1][i] - r.o[axis];
            let (n, f) = if FORWARD && FUSED {
                (entry.mul_add(inv_n[axis], -TINY), exit.mul_add(inv_f[axis], TINY))
            } else {
                (entry * inv_n[axis], exit * inv_f[axis])
            };
            if !n.is_nan() {
                near = if n > near { n } else { near };
            }
            if !f.is_nan() {
                far = if f < far { f } else { far };
            }
        }
        let (near, far) = match (FORWARD, FUSED) {
            (true, true) => (near, far),
            (true, false) => (near - TINY, far + TINY),
            (false, true) => (lowered(near), raised(far)),
            (false, false) => (lowered_unfused(near), raised_unfused(far)),
        };
        if near <= far {
            mask |= 1 << i;
        }
        *slot = near;
    }
    (mask, nears)
}

/// [`hit_scalar`] as a [`BoxTest`]: with `FUSED = false` the portable test of every width (on
/// every CPU) and the twin of [`crate::Simd4`]; with `FUSED = true` the twin of the fused
/// SIMD tests ([`crate::Avx2`], [`crate::Avx512`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct Scalar<const W: usize, const FUSED: bool = false>;

/// The 4-wide tree's portable test and the scalar twin of [`crate::Simd4`].
pub type Scalar4 = Scalar<4>;

/// The 8-wide tree's portable test (unfused widening).
pub type Scalar8 = Scalar<8>;

/// The 16-wide tree's portable test (unfused widening).
pub type Scalar16 = Scalar<16>;

/// The scalar twin of [`crate::Avx2`] (fused widening).
pub type FusedScalar8 = Scalar<8, true>;

/// The scalar twin of [`crate::Avx512`] (fused widening).
pub type FusedScalar16 = Scalar<16, true>;

impl<const W: usize, const FUSED: bool> BoxTest for Scalar<W, FUSED>
where
    Width<W>: NodeWidth,
{
    type Node = Node<W>;
    type RayData = RayBoxes;
    type Nears = [f32; W];
    type Twin = Scalar<W, FUSED>;

    fn twin(self) -> Scalar<W, FUSED> {
        self
    }

    #[inline(always)]
    fn prepare(ray: &Ray) -> RayBoxes {
        RayBoxes::new(ray)
    }

    #[inline(always)]
    fn hit(self, node: &Node<W>, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; W]) {
        hit_scalar::<W, FUSED>(node, r, t_min, t_max)
    }

    #[inline(always)]
    fn hit_forward(self, node: &Node<W>, r: &RayBoxes, t_min: f32, t_max: f32) -> (u32, [f32; W]) {
        hit_scalar_forward::<W, FUSED>(node, r, t_min, t_max)
    }
}

/// Named hard cases for a node test of any width, shared by the SIMD modules' tests.
#[cfg(test)]
pub(crate) mod cases {
    use glam::Vec3;
    use kdtree::{Aabb, Ray};

    use super::*;

    /// A node with `boxes` in its first slots.
    pub(crate) fn node<const W: usize>(boxes: &[Aabb]) -> Node<W>
    where
        Width<W>: NodeWidth,
    {
        let mut n = Node::empty();
        for (i, b) in boxes.iter().enumerate() {
            n.set(i, i as u32, b);
        }
        n
    }

    /// The unit box at `offset`.
    pub(crate) fn unit(offset: Vec3) -> Aabb {
        Aabb { min: offset, max: offset + Vec3::ONE }
    }

    /// `test`'s mask, after checking it against its scalar twin bit for bit: the mask and
    /// every lane's entry distance (used or not).
    pub(crate) fn check<K: BoxTest>(test: K, n: &K::Node, ray: &Ray) -> u32 {
        let (m, near) = test.hit(n, &K::prepare(ray), ray.t_min, ray.t_max);
        let twin = test.twin();
        let (ms, nears) = twin.hit(n, &K::Twin::prepare(ray), ray.t_min, ray.t_max);
        assert_eq!(m, ms, "{ray:?}: mask differs from the scalar twin's");
        for i in 0..K::Node::WIDTH {
            assert_eq!(near[i].to_bits(), nears[i].to_bits(), "{ray:?} lane {i}: entry differs from the twin's");
        }
        m
    }

    /// `test`'s forward mask ([`BoxTest::hit_forward`]) for a ray with `t_min >= 0`, after
    /// checking it against its scalar twin's bit for bit as [`check`] does; [`check`] itself
    /// for a ray reaching behind its origin (which the traversal gives the fused test).
    pub(crate) fn check_forward<K: BoxTest>(test: K, n: &K::Node, ray: &Ray) -> u32 {
        if !forward(ray) {
            return check(test, n, ray);
        }
        let (m, near) = test.hit_forward(n, &K::prepare(ray), ray.t_min, ray.t_max);
        let twin = test.twin();
        let (ms, nears) = twin.hit_forward(n, &K::Twin::prepare(ray), ray.t_min, ray.t_max);
        assert_eq!(m, ms, "{ray:?}: forward mask differs from the scalar twin's");
        for i in 0..K::Node::WIDTH {
            assert_eq!(
                near[i].to_bits(),
                nears[i].to_bits(),
                "{ray:?} lane {i}: forward entry differs from the twin's"
            );
        }
        m
    }

    /// The named cases through `hit` (a node's mask for a ray), with their expected masks:
    /// plain rays, empty slots, rays in face planes (`0 * inf`) in every slot, a grazing ray.
    pub(crate) fn hard_cases<const W: usize>(mut hit: impl FnMut(&Node<W>, &Ray) -> u32)
    where
        Width<W>: NodeWidth,
    {
        let all = |n: usize| if n >= 32 { u32::MAX } else { (1u32 << n) - 1 };
        let row: Vec<Aabb> = (0..W).map(|i| unit(Vec3::new(2.0 * i as f32, 0.0, 0.0))).collect();
        let n = node::<W>(&row);
        let inf = f32::INFINITY;
        assert_eq!(hit(&n, &Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 0.0, inf)), all(W));
        assert_eq!(hit(&n, &Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 0.0, 6.5)), 0b111);
        assert_eq!(hit(&n, &Ray::new(Vec3::new(9.5, 0.5, 0.5), -Vec3::X, 0.0, inf)), all(W.min(5)));
        assert_eq!(hit(&n, &Ray::new(Vec3::new(-1.0, 5.0, 0.5), Vec3::X, 0.0, inf)), 0);
        // Three boxes and empty slots.
        let n = node::<W>(&[unit(Vec3::ZERO), unit(Vec3::new(2.0, 0.0, 0.0)), unit(Vec3::new(0.0, 5.0, 0.0))]);
        assert_eq!(hit(&n, &Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 0.0, inf)), 0b011);
        assert_eq!(hit(&n, &Ray::new(Vec3::new(9.0, 0.5, 0.5), -Vec3::X, 0.0, inf)), 0b011);
        assert_eq!(hit(&n, &Ray::new(Vec3::new(-1.0, 0.5, 0.5), Vec3::X, 0.0, 1.5)), 0b001);
        assert_eq!(hit(&n, &Ray::new(Vec3::new(9.0, 0.5, 0.5), Vec3::X, 0.0, inf)), 0);
        // Empty slots are never entered.
        let empty = Node::<W>::empty();
        for d in [Vec3::X, -Vec3::X, Vec3::new(0.0, 0.0, 1.0), Vec3::new(-0.0, 1.0, -0.0), Vec3::ONE] {
            for o in [Vec3::ZERO, Vec3::splat(1e30), Vec3::splat(-1e30)] {
                assert_eq!(hit(&empty, &Ray::new(o, d, f32::NEG_INFINITY, inf)), 0);
            }
        }
        // Zero direction components with the origin exactly on a face plane (0 * inf), the
        // box in every slot: entered; beside the box in that plane: missed.
        for slot in 0..W {
            let mut boxes = vec![unit(Vec3::splat(50.0)); W];
            boxes[slot] = unit(Vec3::ZERO);
            let n = node::<W>(&boxes);
            for (o, d) in [
                (Vec3::new(-1.0, 0.0, 0.5), Vec3::X),
                (Vec3::new(-1.0, 1.0, 0.5), Vec3::X),
                (Vec3::new(-1.0, 1.0, 1.0), Vec3::X),
                (Vec3::new(2.0, 0.0, 0.0), -Vec3::X),
                (Vec3::new(0.5, 0.0, -3.0), Vec3::new(-0.0, -0.0, 1.0)),
                (Vec3::new(0.0, 0.5, 3.0), Vec3::new(0.0, 0.0, -1.0)),
            ] {
                assert_eq!(hit(&n, &Ray::new(o, d, 0.0, inf)), 1 << slot, "{o} {d} slot {slot}");
            }
            assert_eq!(hit(&n, &Ray::new(Vec3::new(-1.0, 1.5, 0.5), Vec3::X, 0.0, inf)), 0);
        }
        // Grazing: the exact segment touches the box at one corner point.
        let n = node::<W>(&[unit(Vec3::ZERO)]);
        let d = Vec3::new(1.0, 1.0, 1.0) / 3.0f32.sqrt();
        assert_eq!(hit(&n, &Ray::new(Vec3::new(1.0, 1.0, 1.0) + d * 0.3, d, -1.0, inf)), 1);
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use kdtree::Aabb;
    use proptest::prelude::*;

    use super::cases::{check, check_forward, hard_cases, node};
    use super::*;

    #[test]
    fn every_width_passes_the_hard_cases() {
        hard_cases::<4>(|n, ray| check(Scalar::<4>, n, ray));
        hard_cases::<8>(|n, ray| check(Scalar::<8>, n, ray));
        hard_cases::<16>(|n, ray| check(Scalar::<16>, n, ray));
        hard_cases::<4>(|n, ray| check_forward(Scalar::<4, true>, n, ray));
        hard_cases::<8>(|n, ray| check_forward(Scalar::<8, true>, n, ray));
        hard_cases::<16>(|n, ray| check_forward(Scalar::<16, true>, n, ray));
        hard_cases::<4>(|n, ray| check_forward(Scalar::<4>, n, ray));
        hard_cases::<8>(|n, ray| check_forward(Scalar::<8>, n, ray));
        hard_cases::<16>(|n, ray| check_forward(Scalar::<16>, n, ray));
    }

    /// The mask of `boxes` at width `W` (the forward test's with `FORWARD`, for a ray with
    /// `t_min >= 0`), after checking it (at every width) against an exact-enough reference: a
    /// box the segment enters, sampled densely in f64, is never culled.
    fn conservative<const W: usize, const FUSED: bool, const FORWARD: bool>(
        boxes: &[Aabb],
        ray: &Ray,
    ) -> Result<u32, TestCaseError>
    where
        Width<W>: NodeWidth,
    {
        let n = node::<W>(boxes);
        let m = if FORWARD { check_forward(Scalar::<W, FUSED>, &n, ray) } else { check(Scalar::<W, FUSED>, &n, ray) };
        let (o, d) = (ray.origin, ray.dir);
        for (i, b) in boxes.iter().enumerate() {
            let inside =
                (0..=4000).map(|k| ray.t_min as f64 + k as f64 * 0.005).filter(|&t| t <= ray.t_max as f64).any(|t| {
                    (0..3).all(|a| (b.min[a] as f64..=b.max[a] as f64).contains(&(o[a] as f64 + t * d[a] as f64)))
                });
            if inside {
                prop_assert!(m & (1 << i) != 0, "box {i} {b:?} missed by {ray:?}");
            }
        }
        Ok(m)
    }

    proptest! {
        /// Every width is conservative, and a box gives the same bit and entry distance in
        /// every slot of every width: the lanes are independent and the test is one.
        #[test]
        fn the_scalar_test_is_conservative_at_every_width(
            boxes in prop::collection::vec((prop::array::uniform3(-4i32..4), prop::array::uniform3(0i32..4)), 1..17),
            o in prop::array::uniform3(-6i32..6), d in prop::array::uniform3(-2i32..3), t_min in -2.0f32..1.0,
            t_max in prop_oneof![Just(f32::INFINITY), 0.0f32..8.0],
        ) {
            let boxes: Vec<Aabb> = boxes.iter().map(|(lo, ext)| {
                let lo = Vec3::new(lo[0] as f32, lo[1] as f32, lo[2] as f32);
                Aabb { min: lo, max: lo + Vec3::new(ext[0] as f32, ext[1] as f32, ext[2] as f32) }
            }).collect();
            let d = Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32);
            prop_assume!(d != Vec3::ZERO);
            let o = Vec3::new(o[0] as f32, o[1] as f32, o[2] as f32) * 0.5;
            let ray = Ray::new(o, d, t_min, t_max);
            every_width::<false, false>(&boxes, &ray)?;
            every_width::<true, false>(&boxes, &ray)?;
            // The forward test, on the same ray from its origin on.
            let forward = Ray::new(o, d, t_min.max(0.0), t_max.max(0.0));
            every_width::<false, true>(&boxes, &forward)?;
            every_width::<true, true>(&boxes, &forward)?;
        }
    }

    /// The body of the property above for one widening form (fused or not, forward or not).
    fn every_width<const FUSED: bool, const FORWARD: bool>(boxes: &[Aabb], ray: &Ray) -> Result<(), TestCaseError> {
        let (t_min, t_max) = (ray.t_min, ray.t_max);
        let r = RayBoxes::new(ray);
        let m16 = conservative::<16, FUSED, FORWARD>(boxes, ray)?;
        let n16 = if FORWARD {
            Scalar::<16, FUSED>.hit_forward(&node::<16>(boxes), &r, t_min, t_max).1
        } else {
            hit_scalar::<16, FUSED>(&node::<16>(boxes), &r, t_min, t_max).1
        };
        for chunk in 0..boxes.len().div_ceil(8) {
            let part = &boxes[8 * chunk..boxes.len().min(8 * chunk + 8)];
            let m8 = conservative::<8, FUSED, FORWARD>(part, ray)?;
            let n8 = if FORWARD {
                Scalar::<8, FUSED>.hit_forward(&node::<8>(part), &r, t_min, t_max).1
            } else {
                hit_scalar::<8, FUSED>(&node::<8>(part), &r, t_min, t_max).1
            };
            prop_assert_eq!(m8, (m16 >> (8 * chunk)) & ((1 << part.len()) - 1));
            for (i, near) in n8.iter().enumerate().take(part.len()) {
                prop_assert_eq!(near.to_bits(), n16[8 * chunk + i].to_bits());
            }
            let part = &part[..part.len().min(4)];
            let m4 = conservative::<4, FUSED, FORWARD>(part, ray)?;
            prop_assert_eq!(m4, m8 & ((1 << part.len()) - 1));
        }
        Ok(())
    }

    /// The slab interval of `ray` against `b` in f64 (each distance within `2^-52` of the
    /// exact one, far inside the tests' `2^-20`); empty when `near > far`.
    fn exact_interval(b: &Aabb, ray: &Ray) -> (f64, f64) {
        let (mut near, mut far) = (f64::from(ray.t_min), f64::from(ray.t_max));
        for a in 0..3 {
            let (o, d) = (f64::from(ray.origin[a]), f64::from(ray.dir[a]));
            let (lo, hi) = (f64::from(b.min[a]), f64::from(b.max[a]));
            if d == 0.0 {
                if o < lo || o > hi {
                    return (1.0, 0.0);
                }
                continue;
            }
            let (t0, t1) = ((lo - o) / d, (hi - o) / d);
            near = near.max(t0.min(t1));
            far = far.min(t0.max(t1));
        }
        (near, far)
    }

    proptest! {
        /// The forward test against the exact interval, at scales from `1e-30` to `1e30` and
        /// `1e5` to `3e7` from the origin, with zero direction components and rays aimed at a
        /// box's corner or a point of its face (grazing, or ending on the box with `t_max =
        /// 1`): a box the exact segment meets is entered, at an entry no later than the exact
        /// one, and every width says so in its slot.
        #[test]
        fn the_forward_test_keeps_every_box_the_exact_segment_meets(
            lo in prop::array::uniform3(-4.0f32..4.0), ext in prop::array::uniform3(prop_oneof![Just(0.0f32), 0.0f32..3.0]),
            o in prop::array::uniform3(-6.0f32..6.0), scale in -30i32..=30, offset in prop_oneof![Just(0.0f32), Just(1e5f32), Just(-3e7f32)],
            aim in prop_oneof![Just(None), prop::array::uniform3(0u8..3).prop_map(Some)],
            d in prop::array::uniform3(prop_oneof![Just(0.0f32), -2.0f32..2.0]),
            t_min in prop_oneof![Just(0.0f32), Just(-0.0f32), 0.0f32..0.5], segment in any::<bool>(),
        ) {
            let s = 10f32.powi(scale);
            let at = |v: [f32; 3]| Vec3::from(v) * s + Vec3::splat(offset);
            let b = Aabb { min: at(lo), max: at(lo) + Vec3::from(ext) * s };
            let o = at(o);
            // Aimed: at a corner (0: min, 1: max per axis) or the middle of a face (2).
            let d = match aim {
                Some(pick) => {
                    let p = Vec3::from(std::array::from_fn::<f32, 3, _>(|a| match pick[a] {
                        0 => b.min[a],
                        1 => b.max[a],
                        _ => 0.5 * (b.min[a] + b.max[a]),
                    }));
                    p - o
                }
                None => Vec3::from(d),
            };
            prop_assume!(d != Vec3::ZERO && d.is_finite());
            let ray = Ray::new(o, d, t_min, if segment { 1.0 } else { f32::INFINITY });
            let (near, far) = exact_interval(&b, &ray);
            forward_keeps::<true>(&b, &ray, near, far)?;
            forward_keeps::<false>(&b, &ray, near, far)?;
        }
    }

    /// The forward test (fused or not) of `b` at every width against the exact interval
    /// `[near, far]`: the same bit and entry in every width, the bit set and the entry at most
    /// `near` where the interval is not empty.
    fn forward_keeps<const FUSED: bool>(b: &Aabb, ray: &Ray, near: f64, far: f64) -> Result<(), TestCaseError> {
        let r = RayBoxes::new(ray);
        let (m16, n16) = Scalar::<16, FUSED>.hit_forward(&node::<16>(&[*b]), &r, ray.t_min, ray.t_max);
        let (m8, n8) = Scalar::<8, FUSED>.hit_forward(&node::<8>(&[*b]), &r, ray.t_min, ray.t_max);
        let (m4, n4) = Scalar::<4, FUSED>.hit_forward(&node::<4>(&[*b]), &r, ray.t_min, ray.t_max);
        prop_assert_eq!((m16, m8), (m4, m4));
        prop_assert_eq!((n16[0].to_bits(), n8[0].to_bits()), (n4[0].to_bits(), n4[0].to_bits()));
        if near <= far {
            prop_assert_eq!(m4, 1, "{:?} misses {:?}, exact interval [{}, {}] (fused: {})", ray, b, near, far, FUSED);
            prop_assert!(f64::from(n4[0]) <= near, "{:?}: entry {} after the exact {}", ray, n4[0], near);
        }
        Ok(())
    }
}
