//! Packets of up to 16 incoherent rays through the 8-wide tree, with a switch to single rays
//! where few of them remain (the hybrid traversal of Benthin, Wald, Woop, Ernst & Mark 2012,
//! "Combining Single and Packet-Ray Tracing for Arbitrary Ray Distributions on the Intel MIC
//! Architecture", which Embree's `embree-16` incoherent rows run: 8-wide nodes, 16-ray
//! packets). Issue 28 asks whether that beats one ray against 16 children per step (the
//! multi-BVH of Wald, Benthin & Boulos 2008, [`crate::traverse`]) on AO and diffuse rays.
//!
//! - **The packet** ([`PacketTraversal::intersect_stream`], [`PacketTraversal::occluded_stream`]):
//!   the rays SoA in 16 lanes (origin, `1 / d`, `t_min`, per-lane `t_far`, the direction's
//!   sign bits per axis), one lane per ray; a chunk shorter than 16 leaves the other lanes
//!   inactive, and so does a ray that cannot hit anything (non-finite, NaN interval).
//! - **A node**: for each of the 8 children, the slab test of every lane at once
//!   ([`Lanes`]: one AVX-512 register per ray coordinate), a conservative single-ray test's
//!   arithmetic per lane: planes by the lane's direction sign, NaN dropped by operand order,
//!   and for a packet whose lanes all start at or after their origins the forward test
//!   (`(p - o)` times the lane's reciprocal scaled by `1 -+ 2^-20`, `-+ TINY` after the
//!   reductions; `crate::boxtest`'s **The forward test**), else the unfused
//!   [`crate::boxtest::hit_scalar`] (`(p - o) * (1 / d)` widened by `WIDEN` and `TINY`). The
//!   children some lane enters are pushed with their per-lane entry distances (NaN where a
//!   lane does not enter), ordered by the entry distance of the packet's first active lane
//!   (farthest pushed first), and the nearest is taken at once.
//! - **Popping** an entry recomputes its lanes as those whose entry distance is at most their
//!   current `t_far` (entries beyond a lane's closest hit drop that lane, as a single ray
//!   drops the entry).
//! - **A leaf**: a Wald block (thesis 4.2) that at least [`LEAF_LANES`] lanes reach is
//!   tested triangle by triangle over the 16 lanes, the scalar test's operations lane for
//!   lane (as `kdtree::leaf::Wald4` does them over four triangles) with the block's rule
//!   (closest hit at most `t_far`, the lowest triangle at equal distance); otherwise, and
//!   for watertight blocks, each active lane runs the single ray's 4-wide block test
//!   ([`LeafBlock::closest`] / [`LeafBlock::any`]) with its own ray and `t_far`. Either way
//!   a lane's answer is its single ray's block test's.
//! - **The hybrid switch**: an entry with at most `threshold` active lanes (default
//!   [`HYBRID_THRESHOLD`] for closest hits, [`HYBRID_THRESHOLD_ANY`] for any hit, or
//!   [`HYBRID_THRESHOLD_ANY_AVX2`] in two AVX2 halves) is
//!   finished lane by lane with the single-ray traversal ([`Traversal`]) from that node, with
//!   the lane's current `t_far`.
//!
//! Measured on this project's AVX-512 CPU (Intel Xeon, family 6 model 167; `rttest compare`,
//! atrium 512x512): the packets trace AO rays (any hit) about 1.5x as fast as `mbvh-8`'s
//! single rays and diffuse rays (closest hit) at about 0.85-1.0x: AO rays are short and
//! share nodes; diffuse bounces leave the packet after a few nodes, where a packet node
//! test (8 children x 16 lanes, about 33 vector operations per child with the per-lane
//! plane blends that keep it bit-identical to the single-ray test) costs several single-ray
//! node tests.
//! - **Any hit**: the same descent without ordering and without entry distances (entries
//!   carry their lane mask); a lane leaves the packet at its first hit and the packet ends
//!   when every lane is blocked.
//!
//! Every lane's answer is its single ray's: the same closest distance bit for bit, and the
//! same triangle but where two triangles are hit at exactly that distance (the traversal
//! visits leaves in another order, and a later leaf's hit at an equal distance replaces the
//! earlier one, in both; the oracle's rule for ties). Tested below against single rays and
//! between the two lane types.
//!
//! **Lane types.** [`Lanes`] is implemented by [`Row`] (portable, a loop over 16 `f32`) and,
//! on x86-64, by an AVX-512 register (`__m512`, 16-bit `k` masks) and by two AVX registers
//! (`__m256` halves, masks from their sign bits); [`PacketLanes`] picks one: [`Portable16`]
//! anywhere, the [`Avx512`] token, or the [`Avx2`] token on a CPU without AVX-512 (Embree's
//! 16-ray packets run as two 8-wide halves there too). Each token runs the whole stream in
//! one function compiled for its instructions (the loop, the lane operations and the
//! single-ray node test inline into it). All give the same answers bit for bit. Masks are kept in general
//! registers and children are taken from them with `tzcnt` / `blsr`; nothing is compressed
//! to memory (`vcompressps` to memory is microcoded on AMD Zen 4).

use std::fmt::Debug;
use std::mem::MaybeUninit;

use glam::Vec3;
use kdtree::leaf::Wald4;
use kdtree::{Counters, Hit, Ray};

use crate::boxtest::{BoxTest, RayBoxes, TINY, WIDEN};
use crate::leaf::{LANES, LeafBlock};
use crate::node::{EMPTY, LEAF, Node8, stack_capacity};
use crate::simd8::Avx2;
use crate::simd16::Avx512;
use crate::traverse::{Traversal, block_count, traceable};

/// Rays per packet: the lanes of one AVX-512 register.
pub const PACKET: usize = 16;

/// The default hybrid switch of closest-hit packets: an entry with at most this many active
/// lanes is finished with single rays (measured with `rttest compare` on diffuse rays, atrium,
/// thresholds 2 to 16: 6 was the fastest, and packets stayed within about 0.85-1.0x of
/// `mbvh-8`'s single rays at every threshold).
pub const HYBRID_THRESHOLD: u32 = 6;

/// The default hybrid switch of any-hit packets in AVX-512 and portable lanes (measured on
/// AO rays in AVX-512, atrium, thresholds 2 to 16: 2 to 4 were the fastest, about 1.5x
/// `mbvh-8`'s single rays).
pub const HYBRID_THRESHOLD_ANY: u32 = 3;

/// The default hybrid switch of any-hit packets in two AVX2 halves ([`Avx2`]), where a packet
/// node test costs twice the instructions of one AVX-512 register, so single rays pay from
/// more lanes on. Measured on AO rays (four per primary hit, 1024x1024, one thread, on the
/// machine that printed `cpu: AMD EPYC (family 25 model 1), simd: avx2`): thresholds 2, 3, 4,
/// 5, 6 and 8 gave 13.80, 14.30, 14.53, 14.62, 14.64 and 14.52 Mrays/s on the atrium, 12.04,
/// 12.52, 12.83, 12.91, 12.99 and 12.89 on Sponza
/// (`docs/results/incoherent-mbvh.md#the-avx2-packets-any-hit-threshold`).
pub const HYBRID_THRESHOLD_ANY_AVX2: u32 = 6;

/// The default of [`PacketTraversal::with_leaf_lanes`]: Wald leaves are tested over the 16
/// lanes at once where at least this many lanes reach them.
pub const LEAF_LANES: u32 = 6;

/// The traversal stack's capacity: as for single rays, a node pops one entry and pushes at
/// most seven.
const STACK: usize = stack_capacity(8);

/// Sixteen `f32` aligned for one 512-bit load: the portable lane type and the storage of
/// every lane vector.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Row(pub [f32; PACKET]);

/// The operations of the packet's box test on 16 lanes, each rounding once as the scalar
/// test does (no fused multiply-add). Implemented by [`Row`] and, on x86-64, by an AVX-512
/// register; both give the same bits.
pub trait Lanes: Copy {
    /// `x` in every lane.
    fn splat(x: f32) -> Self;
    /// The lanes of `row`.
    fn load(row: &Row) -> Self;
    /// The lanes as a [`Row`].
    fn store(self) -> Row;
    /// `self - b`.
    fn sub(self, b: Self) -> Self;
    /// `self + b`.
    fn add(self, b: Self) -> Self;
    /// `self * b`.
    fn mul(self, b: Self) -> Self;
    /// `self > b ? self : b` per lane (`vmaxps`: `b` where either is NaN).
    fn max(self, b: Self) -> Self;
    /// `self < b ? self : b` per lane (`vminps`: `b` where either is NaN).
    fn min(self, b: Self) -> Self;
    /// `|self|` (the sign bit cleared).
    fn abs(self) -> Self;
    /// Lane `i`: `b` where bit `i` of `mask` is set, else `self`.
    fn select(self, mask: u16, b: Self) -> Self;
    /// `self / b`.
    fn div(self, b: Self) -> Self;
    /// The lanes where `self <= b` (ordered: false where either is NaN).
    fn le(self, b: Self) -> u16;
    /// The lanes where `self < b` (ordered).
    fn lt(self, b: Self) -> u16;
    /// The lanes where `self >= b` (ordered).
    fn ge(self, b: Self) -> u16;
}

impl Lanes for Row {
    #[inline(always)]
    fn splat(x: f32) -> Row {
        Row([x; PACKET])
    }

    #[inline(always)]
    fn load(row: &Row) -> Row {
        *row
    }

    #[inline(always)]
    fn store(self) -> Row {
        self
    }

    #[inline(always)]
    fn sub(self, b: Row) -> Row {
        Row(std::array::from_fn(|i| self.0[i] - b.0[i]))
    }

    #[inline(always)]
    fn add(self, b: Row) -> Row {
        Row(std::array::from_fn(|i| self.0[i] + b.0[i]))
    }

    #[inline(always)]
    fn mul(self, b: Row) -> Row {
        Row(std::array::from_fn(|i| self.0[i] * b.0[i]))
    }

    #[inline(always)]
    fn max(self, b: Row) -> Row {
        Row(std::array::from_fn(|i| if self.0[i] > b.0[i] { self.0[i] } else { b.0[i] }))
    }

    #[inline(always)]
    fn min(self, b: Row) -> Row {
        Row(std::array::from_fn(|i| if self.0[i] < b.0[i] { self.0[i] } else { b.0[i] }))
    }

    #[inline(always)]
    fn abs(self) -> Row {
        Row(self.0.map(f32::abs))
    }

    #[inline(always)]
    fn select(self, mask: u16, b: Row) -> Row {
        Row(std::array::from_fn(|i| if mask >> i & 1 != 0 { b.0[i] } else { self.0[i] }))
    }

    #[inline(always)]
    fn div(self, b: Row) -> Row {
        Row(std::array::from_fn(|i| self.0[i] / b.0[i]))
    }

    #[inline(always)]
    fn le(self, b: Row) -> u16 {
        (0..PACKET).fold(0, |m, i| m | u16::from(self.0[i] <= b.0[i]) << i)
    }

    #[inline(always)]
    fn lt(self, b: Row) -> u16 {
        (0..PACKET).fold(0, |m, i| m | u16::from(self.0[i] < b.0[i]) << i)
    }

    #[inline(always)]
    fn ge(self, b: Row) -> u16 {
        (0..PACKET).fold(0, |m, i| m | u16::from(self.0[i] >= b.0[i]) << i)
    }
}

/// A lane type for the packets, as a value: [`Portable16`] (any CPU) or the [`Avx512`]
/// token (made only where the CPU has AVX-512 and the SIMD cap allows it), whose entry points
/// run the stream in one function compiled for AVX-512.
pub trait PacketLanes: Copy + Debug + Send + Sync + 'static {
    /// The lanes' default hybrid switch of any-hit packets ([`PacketTraversal::thresholds`]).
    const ANY_THRESHOLD: u32 = HYBRID_THRESHOLD_ANY;

    /// The closest hits of `rays` (any number, traced 16 at a time) into `out`.
    fn closest<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
        self,
        p: &PacketTraversal<'_, B, K, Self>,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    );
    /// Whether each of `rays` is blocked, into `out`.
    fn any<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
        self,
        p: &PacketTraversal<'_, B, K, Self>,
        rays: &[Ray],
        out: &mut [bool],
        counters: &mut C,
    );
}

/// The portable lanes ([`Row`]): the twin of the AVX-512 packets, on every CPU.
#[derive(Clone, Copy, Debug, Default)]
pub struct Portable16;

impl PacketLanes for Portable16 {
    fn closest<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
        self,
        p: &PacketTraversal<'_, B, K, Self>,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        closest_stream::<Row, B, K, C>(&p.single, p.threshold, p.leaf_lanes, rays, out, counters);
    }

    fn any<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
        self,
        p: &PacketTraversal<'_, B, K, Self>,
        rays: &[Ray],
        out: &mut [bool],
        counters: &mut C,
    ) {
        any_stream::<Row, B, K, C>(&p.single, p.any_threshold, p.leaf_lanes, rays, out, counters);
    }
}

impl PacketLanes for Avx512 {
    fn closest<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
        self,
        p: &PacketTraversal<'_, B, K, Self>,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        zmm::closest(self, p, rays, out, counters);
    }

    fn any<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
        self,
        p: &PacketTraversal<'_, B, K, Self>,
        rays: &[Ray],
        out: &mut [bool],
        counters: &mut C,
    ) {
        zmm::any(self, p, rays, out, counters);
    }
}

impl PacketLanes for Avx2 {
    const ANY_THRESHOLD: u32 = HYBRID_THRESHOLD_ANY_AVX2;

    fn closest<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
        self,
        p: &PacketTraversal<'_, B, K, Self>,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        ymm::closest(self, p, rays, out, counters);
    }

    fn any<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
        self,
        p: &PacketTraversal<'_, B, K, Self>,
        rays: &[Ray],
        out: &mut [bool],
        counters: &mut C,
    ) {
        ymm::any(self, p, rays, out, counters);
    }
}

/// The 8-wide tree traced by packets of 16 rays ([`PacketLanes`] `L`), lanes finished by the
/// single-ray traversal `single` (its node test `K`) below the hybrid threshold.
#[derive(Clone, Copy, Debug)]
pub struct PacketTraversal<'a, B, K: BoxTest<Node = Node8>, L> {
    single: Traversal<'a, B, K>,
    lanes: L,
    threshold: u32,
    any_threshold: u32,
    leaf_lanes: u32,
}

impl<'a, B: LeafBlock, K: BoxTest<Node = Node8>> Traversal<'a, B, K> {
    /// This tree traced by packets of 16 rays in the lanes `lanes`, with the single-ray
    /// traversal `self` below the default thresholds ([`HYBRID_THRESHOLD`] for closest
    /// hits, the lanes' [`PacketLanes::ANY_THRESHOLD`] for any hit: [`HYBRID_THRESHOLD_ANY`],
    /// or [`HYBRID_THRESHOLD_ANY_AVX2`] in AVX2 halves) and Wald leaves over the 16 lanes
    /// from [`LEAF_LANES`] lanes on.
    pub fn packets<L: PacketLanes>(self, lanes: L) -> PacketTraversal<'a, B, K, L> {
        PacketTraversal {
            single: self,
            lanes,
            threshold: HYBRID_THRESHOLD,
            any_threshold: L::ANY_THRESHOLD,
            leaf_lanes: LEAF_LANES,
        }
    }
}

impl<'a, B: LeafBlock, K: BoxTest<Node = Node8>, L: PacketLanes> PacketTraversal<'a, B, K, L> {
    /// The same packets switching to single rays at `threshold` active lanes or fewer, for
    /// closest and any hit (0: never; 16: always, from the root).
    pub fn with_threshold(self, threshold: u32) -> Self {
        PacketTraversal { threshold, any_threshold: threshold, ..self }
    }

    /// The same packets testing Wald leaves over all 16 lanes at once where at least
    /// `lanes` lanes reach the leaf (fewer: lane by lane, each its single ray's block test;
    /// 17: never). Watertight leaves are always tested lane by lane.
    pub fn with_leaf_lanes(self, lanes: u32) -> Self {
        PacketTraversal { leaf_lanes: lanes, ..self }
    }

    /// The hybrid thresholds: closest hit, any hit.
    pub fn thresholds(&self) -> (u32, u32) {
        (self.threshold, self.any_threshold)
    }

    /// The single-ray traversal of the same tree.
    pub fn single(&self) -> Traversal<'a, B, K> {
        self.single
    }

    /// The lane type.
    pub fn lanes(&self) -> L {
        self.lanes
    }

    /// The closest hit of each of `rays` into `out` (same length), 16 rays per packet.
    ///
    /// # Panics
    /// If `out` and `rays` differ in length.
    pub fn intersect_stream<C: Counters>(&self, rays: &[Ray], out: &mut [Option<Hit>], counters: &mut C) {
        assert_eq!(rays.len(), out.len(), "one answer per ray");
        self.lanes.closest(self, rays, out, counters);
    }

    /// Whether each of `rays` is blocked, into `out` (same length), 16 rays per packet.
    ///
    /// # Panics
    /// If `out` and `rays` differ in length.
    pub fn occluded_stream<C: Counters>(&self, rays: &[Ray], out: &mut [bool], counters: &mut C) {
        assert_eq!(rays.len(), out.len(), "one answer per ray");
        self.lanes.any(self, rays, out, counters);
    }
}

/// The packet of up to 16 rays as the box test reads it.
#[derive(Clone, Copy)]
struct Packet<V> {
    o: [V; 3],
    /// The directions (the Wald leaf test's).
    d: [V; 3],
    /// The reciprocals of the entry and exit planes' products: for a forward packet `1 / d`
    /// scaled by `1 - 2^-20` and `1 + 2^-20` (`crate::boxtest::RayBoxes::inv_entry`,
    /// `inv_exit`), else `1 / d` in both.
    inv_entry: [V; 3],
    inv_exit: [V; 3],
    /// Per axis, the lanes whose direction is negative (`-0.0` included): their near plane
    /// is the box's `max`.
    neg: [u16; 3],
    t_min: V,
    /// The lanes that can hit anything.
    active: u16,
    /// Whether every active lane starts at or after its origin (`t_min >= 0`): the packet
    /// then takes the forward test ([`child_test`]).
    forward: bool,
}

/// The packet of `rays` (at most 16) and its rays' `t_max` as the lanes' first `t_far`.
#[inline(always)]
fn packet<V: Lanes>(rays: &[Ray]) -> (Packet<V>, Row) {
    let zero = [Row([0.0; PACKET]); 3];
    let (mut o, mut d, mut inv, mut inv_entry, mut inv_exit) = (zero, zero, zero, zero, zero);
    let (mut t_min, mut t_far) = (Row([0.0; PACKET]), Row([f32::NAN; PACKET]));
    let (mut neg, mut active, mut forward) = ([0u16; 3], 0u16, true);
    for (l, ray) in rays.iter().enumerate() {
        if !traceable(ray) {
            continue;
        }
        active |= 1 << l;
        let boxes = RayBoxes::new(ray);
        for axis in 0..3 {
            o[axis].0[l] = ray.origin[axis];
            d[axis].0[l] = ray.dir[axis];
            inv[axis].0[l] = boxes.inv[axis];
            inv_entry[axis].0[l] = boxes.inv_entry[axis];
            inv_exit[axis].0[l] = boxes.inv_exit[axis];
            neg[axis] |= u16::from(ray.dir[axis].is_sign_negative()) << l;
        }
        t_min.0[l] = ray.t_min;
        t_far.0[l] = ray.t_max;
        forward &= crate::boxtest::forward(ray);
    }
    let p = Packet {
        o: o.map(|r| V::load(&r)),
        d: d.map(|r| V::load(&r)),
        inv_entry: if forward { inv_entry } else { inv }.map(|r| V::load(&r)),
        inv_exit: if forward { inv_exit } else { inv }.map(|r| V::load(&r)),
        neg,
        t_min: V::load(&t_min),
        active,
        forward,
    };
    (p, t_far)
}

/// The leaf data of each lane's ray (an inactive lane's: a harmless ray's).
#[inline(always)]
fn leaf_data<B: LeafBlock>(rays: &[Ray], active: u16) -> [B::RayData; PACKET] {
    let idle = Ray::new(Vec3::ZERO, Vec3::X, 0.0, 0.0);
    std::array::from_fn(|l| B::prepare(if active >> l & 1 != 0 { &rays[l] } else { &idle }))
}

/// Slot `i` of `node` against every lane: the lanes whose `[t_min, t_far]` enters the box and
/// the widened entry distances. A packet whose lanes all start at or after their origins
/// ([`Packet::forward`]) takes the unfused forward test lane for lane
/// ([`crate::boxtest::hit_scalar_forward`] without `FUSED`: each plane's product with the
/// lane's scaled reciprocal, the reductions, then `-+ TINY`; `crate::boxtest`'s **The forward
/// test**), other packets [`crate::boxtest::hit_scalar`]'s unfused arithmetic (as
/// [`crate::Scalar8`]). Both are conservative, so the lanes' answers are their single rays'
/// (module docs).
#[inline(always)]
fn child_test<V: Lanes>(node: &Node8, i: usize, p: &Packet<V>, t_far: V) -> (u16, V) {
    let mut near = p.t_min;
    let mut far = t_far;
    for axis in 0..3 {
        let planes = &node.bounds[axis];
        let (lo, hi) = (V::splat(planes[0][i]), V::splat(planes[1][i]));
        let near_plane = lo.select(p.neg[axis], hi);
        let far_plane = hi.select(p.neg[axis], lo);
        let n = near_plane.sub(p.o[axis]).mul(p.inv_entry[axis]);
        let f = far_plane.sub(p.o[axis]).mul(p.inv_exit[axis]);
        // Candidate first: a NaN candidate (0 * inf) leaves the accumulator.
        near = n.max(near);
        far = f.min(far);
    }
    let tiny = V::splat(TINY);
    if p.forward {
        let (near, far) = (near.sub(tiny), far.add(tiny));
        return (near.le(far), near);
    }
    let widen = V::splat(WIDEN);
    let near = near.sub(near.abs().mul(widen).add(tiny));
    let far = far.add(far.abs().mul(widen).add(tiny));
    (near.le(far), near)
}

/// Wald triangle `j` of `g` (thesis 4.2) against every lane with `[t_min, t_max]`: the lanes
/// it hits, `t`, `beta` and `gamma`, lane for lane the operations of the scalar test
/// (`kdtree::triangle::WaldTriangle::intersect`, as `kdtree::leaf::Wald4` does them).
#[inline(always)]
fn wald_lanes<V: Lanes>(g: &Wald4, j: usize, p: &Packet<V>, t_max: V) -> (u16, V, V, V) {
    let k = match g.k[j] {
        0.0 => 0,
        1.0 => 1,
        _ => 2,
    };
    let (u, v) = ([1, 2, 0][k], [2, 0, 1][k]);
    let s = V::splat;
    let (n_u, n_v) = (s(g.n_u[j]), s(g.n_v[j]));
    let denom = p.d[k].add(n_u.mul(p.d[u])).add(n_v.mul(p.d[v]));
    // Vertex `a` relative to the origin: nearby numbers, subtracted first.
    let (ak, au, av) = (s(g.a_k[j]).sub(p.o[k]), s(g.a_u[j]).sub(p.o[u]), s(g.a_v[j]).sub(p.o[v]));
    let t = ak.add(n_u.mul(au)).add(n_v.mul(av)).div(denom);
    let in_range = t.ge(p.t_min) & t.le(t_max) & t.lt(s(f32::INFINITY));
    let hu = t.mul(p.d[u]).sub(au);
    let hv = t.mul(p.d[v]).sub(av);
    let beta = s(g.b_nu[j]).mul(hu).add(s(g.b_nv[j]).mul(hv));
    let gamma = s(g.c_nu[j]).mul(hu).add(s(g.c_nv[j]).mul(hv));
    let zero = s(0.0);
    let inside = beta.ge(zero) & gamma.ge(zero) & beta.add(gamma).le(s(1.0));
    (in_range & inside, t, beta, gamma)
}

/// The closest hits of the lanes `mask` in a Wald block, triangle by triangle over the 16
/// lanes: per lane the block's rule (the closest hit at most the lane's `t_far`, the lowest
/// triangle at equal distance), as [`LeafBlock::closest`] gives it for the lane's ray.
#[inline(always)]
fn wald_closest<V: Lanes, B: LeafBlock>(
    g: &Wald4,
    block: &B,
    p: &Packet<V>,
    mask: u16,
    t_far: &mut Row,
    out: &mut [Option<Hit>],
) {
    let entry = V::load(t_far);
    let (mut best, mut bu, mut bv) = (entry, entry, entry);
    let mut hit = 0u16;
    let mut tri = [0u8; PACKET];
    for j in 0..LANES {
        if block.record_prim(j) == u32::MAX {
            break;
        }
        let (m, t, beta, gamma) = wald_lanes(g, j, p, entry);
        let better = m & mask & (t.lt(best) | !hit);
        if better == 0 {
            continue;
        }
        best = best.select(better, t);
        bu = bu.select(better, beta);
        bv = bv.select(better, gamma);
        hit |= better;
        let mut b = better;
        while b != 0 {
            tri[b.trailing_zeros() as usize] = j as u8;
            b &= b - 1;
        }
    }
    if hit == 0 {
        return;
    }
    let (t, u, v) = (best.store(), bu.store(), bv.store());
    let mut b = hit;
    while b != 0 {
        let l = b.trailing_zeros() as usize;
        b &= b - 1;
        t_far.0[l] = t.0[l];
        out[l] = Some(Hit { t: t.0[l], u: u.0[l], v: v.0[l], prim: block.record_prim(usize::from(tri[l])) });
    }
}

/// The lanes of `mask` that some triangle of a Wald block blocks in `[t_min, t_max]`.
#[inline(always)]
fn wald_any<V: Lanes, B: LeafBlock>(g: &Wald4, block: &B, p: &Packet<V>, mask: u16, t_max: V) -> u16 {
    let mut blocked = 0;
    for j in 0..LANES {
        if block.record_prim(j) == u32::MAX {
            break;
        }
        blocked |= wald_lanes(g, j, p, t_max).0 & mask;
        if blocked == mask {
            break;
        }
    }
    blocked
}

/// Closest hits of any number of rays, 16 at a time.
#[inline(always)]
fn closest_stream<V: Lanes, B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
    tr: &Traversal<'_, B, K>,
    threshold: u32,
    leaf_lanes: u32,
    rays: &[Ray],
    out: &mut [Option<Hit>],
    counters: &mut C,
) {
    for (rays, out) in rays.chunks(PACKET).zip(out.chunks_mut(PACKET)) {
        closest_packet::<V, B, K, C>(tr, threshold, leaf_lanes, rays, out, counters);
    }
}

/// Any-hit answers of any number of rays, 16 at a time.
#[inline(always)]
fn any_stream<V: Lanes, B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
    tr: &Traversal<'_, B, K>,
    threshold: u32,
    leaf_lanes: u32,
    rays: &[Ray],
    out: &mut [bool],
    counters: &mut C,
) {
    for (rays, out) in rays.chunks(PACKET).zip(out.chunks_mut(PACKET)) {
        any_packet::<V, B, K, C>(tr, threshold, leaf_lanes, rays, out, counters);
    }
}

/// The closest hits of one packet of at most 16 rays (module docs).
#[inline(always)]
fn closest_packet<V: Lanes, B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
    tr: &Traversal<'_, B, K>,
    threshold: u32,
    leaf_lanes: u32,
    rays: &[Ray],
    out: &mut [Option<Hit>],
    counters: &mut C,
) {
    out.fill(None);
    let (p, mut t_far) = packet::<V>(rays);
    if p.active == 0 {
        return;
    }
    let data = leaf_data::<B>(rays, p.active);
    // Invariant: `nodes[..sp]` and `nears[..sp]` are initialised.
    let mut nodes = [const { MaybeUninit::<u32>::uninit() }; STACK];
    let mut nears = [const { MaybeUninit::<Row>::uninit() }; STACK];
    let mut sp = 0;
    let (mut cur, mut mask) = (0u32, p.active);
    let nan = V::splat(f32::NAN);
    loop {
        // Descend from `cur` with the lanes `mask` until a leaf, a switch to single rays or
        // a node no lane enters.
        loop {
            if cur & LEAF != 0 {
                let block = &tr.blocks[(cur & !LEAF) as usize];
                counters.leaf();
                if let Some(g) = block.wald_group()
                    && mask.count_ones() >= leaf_lanes
                {
                    if C::ENABLED {
                        counters.tests(block_count(block) * u64::from(mask.count_ones()));
                    }
                    wald_closest(g, block, &p, mask, &mut t_far, out);
                    break;
                }
                let mut m = mask;
                while m != 0 {
                    let l = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if C::ENABLED {
                        counters.tests(block_count(block));
                    }
                    if let Some((lane, t, u, v)) = block.closest(&rays[l], &data[l], t_far.0[l]) {
                        t_far.0[l] = t;
                        out[l] = Some(Hit { t, u, v, prim: block.record_prim(lane) });
                    }
                }
                break;
            }
            if mask.count_ones() <= threshold {
                let mut m = mask;
                while m != 0 {
                    let l = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if let Some(hit) = tr.closest_from::<true, C>(cur, &rays[l], &data[l], t_far.0[l], counters) {
                        t_far.0[l] = hit.t;
                        out[l] = Some(hit);
                    }
                }
                break;
            }
            counters.node();
            let node = &tr.nodes[cur as usize];
            let far = V::load(&t_far);
            let leader = mask.trailing_zeros() as usize;
            let mut kids = [0u32; 8];
            let mut masks = [0u16; 8];
            let mut keys = [0.0f32; 8];
            let mut entries = [MaybeUninit::<Row>::uninit(); 8];
            let mut k = 0;
            for (i, &child) in node.child.iter().enumerate() {
                if child == EMPTY {
                    continue;
                }
                let (hit, near) = child_test(node, i, &p, far);
                let hit = hit & mask;
                if hit == 0 {
                    continue;
                }
                // Lanes that do not enter get NaN: never at most their `t_far`.
                let row = nan.select(hit, near).store();
                keys[k] = if hit >> leader & 1 != 0 { row.0[leader] } else { f32::INFINITY };
                kids[k] = child;
                masks[k] = hit;
                entries[k].write(row);
                k += 1;
            }
            if k == 0 {
                break;
            }
            // The order: by the first lane's entry distance, farthest pushed first, the
            // nearest taken at once (equal keys: the higher slot first).
            let mut order = [0usize; 8];
            for j in 0..k {
                let mut at = j;
                while at > 0 && keys[order[at - 1]] < keys[j] {
                    order[at] = order[at - 1];
                    at -= 1;
                }
                order[at] = j;
            }
            for &j in &order[..k - 1] {
                nodes[sp].write(kids[j]);
                // SAFETY: written for every `j < k`.
                nears[sp].write(unsafe { entries[j].assume_init() });
                sp += 1;
            }
            let nearest = order[k - 1];
            (cur, mask) = (kids[nearest], masks[nearest]);
        }
        // Pop the next entry some lane still needs.
        loop {
            if sp == 0 {
                return;
            }
            sp -= 1;
            // SAFETY: below the stack pointer (invariant).
            let near = V::load(unsafe { nears[sp].assume_init_ref() });
            let m = near.le(V::load(&t_far));
            if m != 0 {
                // SAFETY: below the stack pointer (invariant).
                (cur, mask) = (unsafe { nodes[sp].assume_init() }, m);
                break;
            }
        }
    }
}

/// Whether each ray of one packet of at most 16 rays is blocked (module docs).
#[inline(always)]
fn any_packet<V: Lanes, B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
    tr: &Traversal<'_, B, K>,
    threshold: u32,
    leaf_lanes: u32,
    rays: &[Ray],
    out: &mut [bool],
    counters: &mut C,
) {
    out.fill(false);
    let (p, t_far) = packet::<V>(rays);
    let mut active = p.active;
    if active == 0 {
        return;
    }
    let data = leaf_data::<B>(rays, active);
    let far = V::load(&t_far);
    // Invariant: `stack[..sp]` is initialised.
    let mut stack = [const { MaybeUninit::<(u32, u16)>::uninit() }; STACK];
    let mut sp = 0;
    let (mut cur, mut mask) = (0u32, active);
    loop {
        loop {
            if cur & LEAF != 0 {
                let block = &tr.blocks[(cur & !LEAF) as usize];
                counters.leaf();
                if let Some(g) = block.wald_group()
                    && mask.count_ones() >= leaf_lanes
                {
                    if C::ENABLED {
                        counters.tests(block_count(block) * u64::from(mask.count_ones()));
                    }
                    let blocked = wald_any(g, block, &p, mask, far);
                    for (l, o) in out.iter_mut().enumerate() {
                        *o |= blocked >> l & 1 != 0;
                    }
                    active &= !blocked;
                    break;
                }
                let mut m = mask;
                while m != 0 {
                    let l = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if C::ENABLED {
                        counters.tests(block_count(block));
                    }
                    if block.any(&rays[l], &data[l], rays[l].t_max) {
                        out[l] = true;
                        active &= !(1 << l);
                    }
                }
                break;
            }
            if mask.count_ones() <= threshold {
                let mut m = mask;
                while m != 0 {
                    let l = m.trailing_zeros() as usize;
                    m &= m - 1;
                    if tr.any_from::<true, C>(cur, &rays[l], &data[l], counters) {
                        out[l] = true;
                        active &= !(1 << l);
                    }
                }
                break;
            }
            counters.node();
            let node = &tr.nodes[cur as usize];
            let mut first = None;
            for (i, &child) in node.child.iter().enumerate() {
                if child == EMPTY {
                    continue;
                }
                let hit = child_test(node, i, &p, far).0 & mask;
                if hit == 0 {
                    continue;
                }
                if first.is_none() {
                    first = Some((child, hit));
                } else {
                    stack[sp].write((child, hit));
                    sp += 1;
                }
            }
            let Some(next) = first else { break };
            (cur, mask) = next;
        }
        if active == 0 {
            return;
        }
        loop {
            if sp == 0 {
                return;
            }
            sp -= 1;
            // SAFETY: below the stack pointer (invariant).
            let (node, m) = unsafe { stack[sp].assume_init() };
            if m & active != 0 {
                (cur, mask) = (node, m & active);
                break;
            }
        }
    }
}

/// The packet loops' entry points for the lanes `$lanes` of token `$token`: `closest` and
/// `any` call the runners `$closest` / `$any`, which compile the loops for `$features` (the
/// features `$token`'s `detect` checks).
#[cfg(target_arch = "x86_64")]
macro_rules! runners {
    ($token:ident, $lanes:ident, $features:literal, $closest:ident, $any:ident) => {
        #[inline(always)]
        pub(super) fn closest<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
            _: $token,
            p: &PacketTraversal<'_, B, K, $token>,
            rays: &[Ray],
            out: &mut [Option<Hit>],
            counters: &mut C,
        ) {
            // SAFETY: the token exists, so its `detect` found every feature enabled there.
            unsafe { $closest(&p.single, p.threshold, p.leaf_lanes, rays, out, counters) }
        }

        #[inline(always)]
        pub(super) fn any<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
            _: $token,
            p: &PacketTraversal<'_, B, K, $token>,
            rays: &[Ray],
            out: &mut [bool],
            counters: &mut C,
        ) {
            // SAFETY: the token exists, so its `detect` found every feature enabled there.
            unsafe { $any(&p.single, p.any_threshold, p.leaf_lanes, rays, out, counters) }
        }

        #[target_feature(enable = $features)]
        fn $closest<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
            tr: &Traversal<'_, B, K>,
            threshold: u32,
            leaf_lanes: u32,
            rays: &[Ray],
            out: &mut [Option<Hit>],
            counters: &mut C,
        ) {
            closest_stream::<$lanes, B, K, C>(tr, threshold, leaf_lanes, rays, out, counters);
        }

        #[target_feature(enable = $features)]
        fn $any<B: LeafBlock, K: BoxTest<Node = Node8>, C: Counters>(
            tr: &Traversal<'_, B, K>,
            threshold: u32,
            leaf_lanes: u32,
            rays: &[Ray],
            out: &mut [bool],
            counters: &mut C,
        ) {
            any_stream::<$lanes, B, K, C>(tr, threshold, leaf_lanes, rays, out, counters);
        }
    };
}

/// The AVX-512 lanes: one `__m512` per lane vector, `k` masks as `u16`, and the runners that
/// compile the packet loops for AVX-512.
#[cfg(target_arch = "x86_64")]
mod zmm {
    use std::arch::x86_64::*;

    use super::*;

    /// Sixteen lanes in one AVX-512 register.
    ///
    /// # Safety
    /// Its operations are AVX-512 F instructions: used only inside [`closest_avx512`] and
    /// [`any_avx512`], which run only where an [`Avx512`] token exists.
    #[derive(Clone, Copy)]
    pub(super) struct Zmm(__m512);

    // SAFETY (every operation below): a `Zmm` is only used inside the runners, which an
    // `Avx512` token proves may run AVX-512 F (see the type).
    impl Lanes for Zmm {
        #[inline(always)]
        fn splat(x: f32) -> Zmm {
            Zmm(unsafe { _mm512_set1_ps(x) })
        }

        #[inline(always)]
        fn load(row: &Row) -> Zmm {
            // SAFETY: a `Row` is sixteen `f32` aligned to 64 bytes.
            Zmm(unsafe { _mm512_load_ps(row.0.as_ptr()) })
        }

        #[inline(always)]
        fn store(self) -> Row {
            let mut row = Row([0.0; PACKET]);
            // SAFETY: a `Row` is sixteen `f32` aligned to 64 bytes.
            unsafe { _mm512_store_ps(row.0.as_mut_ptr(), self.0) };
            row
        }

        #[inline(always)]
        fn sub(self, b: Zmm) -> Zmm {
            Zmm(unsafe { _mm512_sub_ps(self.0, b.0) })
        }

        #[inline(always)]
        fn add(self, b: Zmm) -> Zmm {
            Zmm(unsafe { _mm512_add_ps(self.0, b.0) })
        }

        #[inline(always)]
        fn mul(self, b: Zmm) -> Zmm {
            Zmm(unsafe { _mm512_mul_ps(self.0, b.0) })
        }

        #[inline(always)]
        fn max(self, b: Zmm) -> Zmm {
            Zmm(unsafe { _mm512_max_ps(self.0, b.0) })
        }

        #[inline(always)]
        fn min(self, b: Zmm) -> Zmm {
            Zmm(unsafe { _mm512_min_ps(self.0, b.0) })
        }

        #[inline(always)]
        fn abs(self) -> Zmm {
            Zmm(unsafe { _mm512_abs_ps(self.0) })
        }

        #[inline(always)]
        fn select(self, mask: u16, b: Zmm) -> Zmm {
            Zmm(unsafe { _mm512_mask_blend_ps(mask, self.0, b.0) })
        }

        #[inline(always)]
        fn div(self, b: Zmm) -> Zmm {
            Zmm(unsafe { _mm512_div_ps(self.0, b.0) })
        }

        #[inline(always)]
        fn le(self, b: Zmm) -> u16 {
            unsafe { _mm512_cmp_ps_mask::<_CMP_LE_OQ>(self.0, b.0) }
        }

        #[inline(always)]
        fn lt(self, b: Zmm) -> u16 {
            unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(self.0, b.0) }
        }

        #[inline(always)]
        fn ge(self, b: Zmm) -> u16 {
            unsafe { _mm512_cmp_ps_mask::<_CMP_GE_OQ>(self.0, b.0) }
        }
    }

    runners!(Avx512, Zmm, "avx512f,avx512vl,avx2,fma,bmi1,bmi2,popcnt,lzcnt", closest_avx512, any_avx512);
}

/// The AVX2 lanes: the 16 lanes as two `__m256` halves (lanes 0-7 and 8-15), masks as `u16`
/// built from the halves' sign bits, and the runners that compile the packet loops for AVX2:
/// the 16-ray packets on a CPU without AVX-512, as Embree runs its 16-ray packets there (two
/// 8-wide halves per operation).
#[cfg(target_arch = "x86_64")]
mod ymm {
    use std::arch::x86_64::*;

    use super::*;

    /// Sixteen lanes in two AVX registers.
    ///
    /// # Safety
    /// Its operations are AVX and AVX2 instructions: used only inside [`closest_avx2`] and
    /// [`any_avx2`], which run only where an [`Avx2`] token exists.
    #[derive(Clone, Copy)]
    pub(super) struct Ymm2(__m256, __m256);

    impl Ymm2 {
        /// `f` on both halves.
        #[inline(always)]
        fn each(self, b: Ymm2, f: impl Fn(__m256, __m256) -> __m256) -> Ymm2 {
            Ymm2(f(self.0, b.0), f(self.1, b.1))
        }

        /// The 16-bit mask of a per-half comparison `f` (a lane's bit where its result is all
        /// ones).
        #[inline(always)]
        fn mask(self, b: Ymm2, f: impl Fn(__m256, __m256) -> __m256) -> u16 {
            // SAFETY: AVX, inside the runners (see the type).
            let (lo, hi) = unsafe { (_mm256_movemask_ps(f(self.0, b.0)), _mm256_movemask_ps(f(self.1, b.1))) };
            (lo | hi << 8) as u16
        }
    }

    /// The halves' blend masks of `mask` (lane `i` all ones where bit `i` is set): each lane
    /// keeps its own bit of the broadcast mask and compares it with that bit.
    #[inline(always)]
    fn expand(mask: u16) -> (__m256, __m256) {
        // SAFETY: AVX2, inside the runners (see `Ymm2`).
        unsafe {
            let m = _mm256_set1_epi32(i32::from(mask));
            let lo = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
            let hi = _mm256_slli_epi32::<8>(lo);
            let on = |bit: __m256i| _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(m, bit), bit));
            (on(lo), on(hi))
        }
    }

    // SAFETY (every operation below): a `Ymm2` is only used inside the runners, which an
    // `Avx2` token proves may run AVX2 (see the type).
    impl Lanes for Ymm2 {
        #[inline(always)]
        fn splat(x: f32) -> Ymm2 {
            let v = unsafe { _mm256_set1_ps(x) };
            Ymm2(v, v)
        }

        #[inline(always)]
        fn load(row: &Row) -> Ymm2 {
            // SAFETY: a `Row` is sixteen `f32` aligned to 64 bytes, so both halves are
            // aligned to 32.
            unsafe { Ymm2(_mm256_load_ps(row.0.as_ptr()), _mm256_load_ps(row.0.as_ptr().add(8))) }
        }

        #[inline(always)]
        fn store(self) -> Row {
            let mut row = Row([0.0; PACKET]);
            // SAFETY: as in `load`.
            unsafe {
                _mm256_store_ps(row.0.as_mut_ptr(), self.0);
                _mm256_store_ps(row.0.as_mut_ptr().add(8), self.1);
            }
            row
        }

        #[inline(always)]
        fn sub(self, b: Ymm2) -> Ymm2 {
            self.each(b, |x, y| unsafe { _mm256_sub_ps(x, y) })
        }

        #[inline(always)]
        fn add(self, b: Ymm2) -> Ymm2 {
            self.each(b, |x, y| unsafe { _mm256_add_ps(x, y) })
        }

        #[inline(always)]
        fn mul(self, b: Ymm2) -> Ymm2 {
            self.each(b, |x, y| unsafe { _mm256_mul_ps(x, y) })
        }

        #[inline(always)]
        fn max(self, b: Ymm2) -> Ymm2 {
            // `vmaxps`: the second operand where either is NaN, as `Row::max`.
            self.each(b, |x, y| unsafe { _mm256_max_ps(x, y) })
        }

        #[inline(always)]
        fn min(self, b: Ymm2) -> Ymm2 {
            self.each(b, |x, y| unsafe { _mm256_min_ps(x, y) })
        }

        #[inline(always)]
        fn abs(self) -> Ymm2 {
            let magnitude = unsafe { _mm256_castsi256_ps(_mm256_set1_epi32(i32::MAX)) };
            self.each(Ymm2(magnitude, magnitude), |x, m| unsafe { _mm256_and_ps(x, m) })
        }

        #[inline(always)]
        fn select(self, mask: u16, b: Ymm2) -> Ymm2 {
            let (lo, hi) = expand(mask);
            unsafe { Ymm2(_mm256_blendv_ps(self.0, b.0, lo), _mm256_blendv_ps(self.1, b.1, hi)) }
        }

        #[inline(always)]
        fn div(self, b: Ymm2) -> Ymm2 {
            self.each(b, |x, y| unsafe { _mm256_div_ps(x, y) })
        }

        #[inline(always)]
        fn le(self, b: Ymm2) -> u16 {
            self.mask(b, |x, y| unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(x, y) })
        }

        #[inline(always)]
        fn lt(self, b: Ymm2) -> u16 {
            self.mask(b, |x, y| unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(x, y) })
        }

        #[inline(always)]
        fn ge(self, b: Ymm2) -> u16 {
            self.mask(b, |x, y| unsafe { _mm256_cmp_ps::<_CMP_GE_OQ>(x, y) })
        }
    }

    runners!(Avx2, Ymm2, "avx2,fma,bmi1,bmi2,popcnt,lzcnt", closest_avx2, any_avx2);
}

/// Elsewhere no [`Avx2`] or [`Avx512`] token is ever made; these keep the types usable with
/// the portable lanes (as `ymm` and `zmm`).
#[cfg(not(target_arch = "x86_64"))]
mod portable {
    use super::*;

    pub(super) fn closest<B: LeafBlock, K: BoxTest<Node = Node8>, L, C: Counters>(
        _: L,
        p: &PacketTraversal<'_, B, K, L>,
        rays: &[Ray],
        out: &mut [Option<Hit>],
        counters: &mut C,
    ) {
        closest_stream::<Row, B, K, C>(&p.single, p.threshold, p.leaf_lanes, rays, out, counters);
    }

    pub(super) fn any<B: LeafBlock, K: BoxTest<Node = Node8>, L, C: Counters>(
        _: L,
        p: &PacketTraversal<'_, B, K, L>,
        rays: &[Ray],
        out: &mut [bool],
        counters: &mut C,
    ) {
        any_stream::<Row, B, K, C>(&p.single, p.any_threshold, p.leaf_lanes, rays, out, counters);
    }
}

#[cfg(not(target_arch = "x86_64"))]
use portable as ymm;
#[cfg(not(target_arch = "x86_64"))]
use portable as zmm;
