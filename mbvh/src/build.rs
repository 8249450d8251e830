//! The build: a binary BVH by binned SAH, collapsed top-down into multi-nodes of any width (Wald,
//! Benthin & Boulos 2008, section 4: "build a binary BVH \[with\] SAH-based binning, ... copy
//! \[it\] into our multi-node layout ..., which we can then collapse").
//!
//! - **Binned SAH** (Wald 2007, "On fast construction of SAH-based bounding volume
//!   hierarchies"): per node, the triangles' centroids are put into [`BINS`] bins along each
//!   axis of the centroid box and the best of the `3 (BINS - 1)` planes is taken. The cost
//!   is the paper's SIMD-aware SAH (section 4): a leaf of `n` triangles costs `ceil(n / 4)`
//!   4-wide tests, so splits are weighed by `SA(child) ceil(n_child / 4)`. Binning rather than
//!   the kd-tree's exact sweep: a BVH split only partitions triangles (no clipping), binned
//!   SAH finds trees of nearly the quality of the full sweep (Wald 2007) in `O(N)` per level
//!   without the sort, and the paper itself collapses a binned build. Nodes of more than
//!   [`LEAF_SIZE`] triangles are always split (a leaf is one 4-wide block); at most 4 are a
//!   leaf, which the SIMD cost always prefers (one chunk). Large nodes are split in parallel
//!   (`rayon::join`); the result does not depend on the thread count. The build's boxes are
//!   SIMD registers ([`Bounds`]: a union is one `minps` and one `maxps`), one pass over a
//!   node's references bins them on all three axes, and the sweep skips the planes after
//!   empty bins (they split as the plane before); the same tree as binning each axis in its
//!   own pass with `Aabb`'s scalar boxes (tested against that), built 1.26-1.43x as fast
//!   (`docs/results/incoherent-mbvh.md#the-builds-binning-in-simd-registers`).
//! - **Spatial splits** (Stich, Friedrich & Dietrich 2009, "Spatial splits in bounding volume
//!   hierarchies", the SBVH): where the best object split's two boxes overlap by more than
//!   [`SPATIAL_ALPHA`] of the root's area, the node's box is also cut into [`BINS`] slabs
//!   along its widest axis, each reference's part in every slab it crosses priced, and the
//!   cheaper of the two splits is taken. The references a spatial split cuts are clipped
//!   by `kdtree`'s conservative clip (`kdtree::build::split_reference`): each side gets a
//!   reference with the box of its part of the triangle, so that the traversal's
//!   conservative box test never misses the triangle (tested down to 1e-30 and up to 1e18,
//!   and 1e6 from the origin). Long or large triangles (Sponza's walls and floors) then stop
//!   widening boxes across the scene. Spatial splits may add at most [`SPLIT_BUDGET`]
//!   references per triangle over the whole tree: each node's budget is shared between its
//!   children by their counts, so the tree does not depend on the thread count. Costs are
//!   summed in `f64` (`kdtree::build::surface_area64`), so that neither tiny nor huge scenes
//!   round every area to 0 or infinity.
//!   [`SpatialSplits`] sets the threshold and the budget (`MultiBvh::build_with`), or turns
//!   spatial splits off.
//! - **Depth.** Beyond binary depth [`MEDIAN_DEPTH`] nodes are split at the object median,
//!   so the binary depth stays below `MEDIAN_DEPTH + 33` and the multi-node tree's (each
//!   multi-node takes at least one binary level) within [`MAX_DEPTH`]: the traversal's
//!   fixed stacks ([`crate::node::stack_capacity`]) cannot overflow.
//! - **Collapse** (section 4.2, "merging a child node into its parent", top-down): starting
//!   at the root, the inner child of largest surface area is replaced by its two children
//!   while the node has fewer than its width (`MultiNode::WIDTH`: 4, 8 or 16); then each
//!   inner child is collapsed the same way. The trees of every width are collapsed from the
//!   same binary BVH (the build is deterministic) and have the same leaves. The paper's other two
//!   moves (merging two leaves, two inner nodes) serve 16-wide leaves; with leaves of one
//!   4-wide block they do not apply.

use glam::{Vec3, Vec3A};
use kdtree::Aabb;
use kdtree::build::{split_reference, surface_area64};
use kdtree::triangle::is_degenerate;

use crate::node::{LEAF, MAX_DEPTH, MultiNode};

/// Bins per axis of the binned SAH.
pub const BINS: usize = 32;

/// The most triangles in a leaf: one 4-wide block.
pub const LEAF_SIZE: usize = 4;

/// Binary depth beyond which nodes are split at the object median (48): the binary depth
/// then stays below `MEDIAN_DEPTH + 33` and the multi-node tree's within [`MAX_DEPTH`].
pub const MEDIAN_DEPTH: u32 = MAX_DEPTH - 37;

/// Spatial splits are tried where the best object split's two boxes overlap by more than
/// this share of the root's surface area (Stich et al. 2009's `alpha`). Their 1e-5 gave the
/// same rays per second on Sponza, the kitchen and the atrium for 1.5-2x the build time.
pub const SPATIAL_ALPHA: f64 = 1e-3;

/// The most references spatial splits may add, per triangle of the mesh. They add 0.02
/// (the kitchen) to 0.18 (Sponza); of budgets 0.25, 0.5 and 1, 1 gave Sponza's fastest
/// primary rays.
pub const SPLIT_BUDGET: f64 = 1.0;

/// Where and how much the build splits triangles (module docs): [`SpatialSplits::DEFAULT`], or
/// [`SpatialSplits::OFF`] for the plain binned SAH (the kitchen's view was faster without
/// them: `docs/results/incoherent-mbvh.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpatialSplits {
    /// Spatial splits are tried where the best object split's boxes overlap by more than this
    /// share of the root's surface area: at least 0 (`f64::INFINITY`: never).
    pub alpha: f64,
    /// The most extra references per triangle over the whole tree: finite, at least 0.
    pub budget: f64,
}

impl SpatialSplits {
    /// [`SPATIAL_ALPHA`] and [`SPLIT_BUDGET`].
    pub const DEFAULT: SpatialSplits = SpatialSplits { alpha: SPATIAL_ALPHA, budget: SPLIT_BUDGET };
    /// No spatial splits: every triangle in exactly one leaf.
    pub const OFF: SpatialSplits = SpatialSplits { alpha: f64::INFINITY, budget: 0.0 };

    /// An error naming the field that is NaN, negative or (for the budget) infinite.
    pub fn check(&self) -> Result<(), BuildError> {
        if self.alpha.is_nan() || self.alpha < 0.0 {
            return Err(BuildError::BadConfig(format!("spatial split alpha = {} must be at least 0", self.alpha)));
        }
        if !(self.budget.is_finite() && self.budget >= 0.0) {
            return Err(BuildError::BadConfig(format!(
                "spatial split budget = {} must be finite and at least 0",
                self.budget
            )));
        }
        Ok(())
    }
}

impl Default for SpatialSplits {
    fn default() -> Self {
        SpatialSplits::DEFAULT
    }
}

/// Binary nodes with more triangles than this are split in parallel.
const PARALLEL: usize = 4096;

/// Why a build failed: the kd-tree's errors (a non-finite vertex, an index out of range,
/// more than the index widths hold), so that both structures refuse the same input alike.
pub use kdtree::BuildError;

/// A box in SIMD registers: the build's boxes, which it unions once per reference and bin
/// (`Vec3A`, one 128-bit register per corner: a union is one `minps` and one `maxps`, where
/// `Aabb`'s `Vec3` takes three scalar operations per corner). The same values as [`Aabb`]'s
/// operations bit for bit: both take `if a < b { a } else { b }` per coordinate.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Bounds {
    pub min: Vec3A,
    pub max: Vec3A,
}

impl Bounds {
    /// Contains nothing; the identity of [`Bounds::union`].
    pub const EMPTY: Bounds = Bounds { min: Vec3A::INFINITY, max: Vec3A::NEG_INFINITY };

    /// The smallest box containing both.
    #[inline(always)]
    pub fn union(self, other: Bounds) -> Bounds {
        Bounds { min: self.min.min(other.min), max: self.max.max(other.max) }
    }

    /// The smallest box containing `self` and `p`.
    #[inline(always)]
    fn grow(self, p: Vec3A) -> Bounds {
        Bounds { min: self.min.min(p), max: self.max.max(p) }
    }

    /// The same box as an [`Aabb`].
    #[inline(always)]
    pub fn aabb(&self) -> Aabb {
        Aabb { min: self.min.into(), max: self.max.into() }
    }
}

impl From<Aabb> for Bounds {
    #[inline(always)]
    fn from(b: Aabb) -> Bounds {
        Bounds { min: b.min.into(), max: b.max.into() }
    }
}

/// The box of `prims`.
pub(crate) fn bounds_of(prims: &[Prim]) -> Aabb {
    prims.iter().fold(Bounds::EMPTY, |b, p| b.union(p.bounds)).aabb()
}

/// One reference in the build: a triangle, or the part of it a spatial split left on one
/// side, with its (clipped) box and the triangle's id.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Prim {
    pub bounds: Bounds,
    pub id: u32,
}

impl Prim {
    fn new(bounds: Aabb, id: u32) -> Prim {
        Prim { bounds: bounds.into(), id }
    }

    /// The centre of its box, by which it is binned.
    #[inline(always)]
    fn centroid(&self) -> Vec3A {
        (self.bounds.min + self.bounds.max) * 0.5
    }
}

/// A node of the binary BVH.
#[derive(Debug)]
pub(crate) enum Binary {
    /// The ids of the leaf's triangles.
    Leaf { bounds: Aabb, ids: Box<[u32]> },
    /// Two children.
    Inner { bounds: Aabb, kids: Box<[Binary; 2]> },
}

impl Binary {
    fn bounds(&self) -> &Aabb {
        match self {
            Binary::Leaf { bounds, .. } | Binary::Inner { bounds, .. } => bounds,
        }
    }
}

/// The build's primitives: the non-degenerate triangles with their boxes, after checking the
/// input.
pub(crate) fn prims(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Vec<Prim>, BuildError> {
    if let Some(index) = positions.iter().position(|p| !p.is_finite()) {
        return Err(BuildError::NonFiniteVertex { index, position: positions[index] });
    }
    if triangles.len() >= LEAF as usize {
        return Err(BuildError::TooLarge(format!("{} triangles", triangles.len())));
    }
    let mut out = Vec::with_capacity(triangles.len());
    for (i, t) in triangles.iter().enumerate() {
        if let Some(&vertex) = t.iter().find(|&&v| v as usize >= positions.len()) {
            return Err(BuildError::IndexOutOfRange { triangle: i, vertex, vertices: positions.len() });
        }
        let tri = t.map(|v| positions[v as usize]);
        if is_degenerate(&tri) {
            continue;
        }
        out.push(Prim::new(Aabb::from_points(&tri), i as u32));
    }
    Ok(out)
}

/// The binary build over one mesh (checked by [`prims`]): its triangles for the spatial
/// splits, and the root's surface area that their threshold is relative to.
pub(crate) struct Builder<'a> {
    positions: &'a [Vec3],
    triangles: &'a [[u32; 3]],
    /// The overlap above which spatial splits are tried: alpha times the root's area.
    min_overlap: f64,
}

/// A node's partition: the two sides' references and each side's share of the split budget.
type Sides = ([Vec<Prim>; 2], [usize; 2]);

impl<'a> Builder<'a> {
    /// The build over `triangles`, whose references (from [`prims`]) have the box `bounds`,
    /// trying spatial splits above `alpha` (checked by [`SpatialSplits::check`]).
    pub(crate) fn new(positions: &'a [Vec3], triangles: &'a [[u32; 3]], bounds: &Aabb, alpha: f64) -> Builder<'a> {
        Builder { positions, triangles, min_overlap: alpha * surface_area64(bounds) }
    }

    fn triangle(&self, id: u32) -> [Vec3; 3] {
        self.triangles[id as usize].map(|v| self.positions[v as usize])
    }

    /// The binary BVH over `prims`, which may make up to `budget` more references by spatial
    /// splits (the whole tree's is [`split_budget`]'s).
    pub(crate) fn binary(&self, prims: Vec<Prim>, depth: u32, budget: usize) -> Binary {
        let bounds = bounds_of(&prims);
        if prims.len() <= LEAF_SIZE {
            return Binary::Leaf { bounds, ids: prims.iter().map(|p| p.id).collect() };
        }
        let parallel = prims.len() > PARALLEL;
        let ([left, right], [bl, br]) = self.split(prims, &bounds, depth, budget);
        let (l, r) = if parallel {
            rayon::join(|| self.binary(left, depth + 1, bl), || self.binary(right, depth + 1, br))
        } else {
            (self.binary(left, depth + 1, bl), self.binary(right, depth + 1, br))
        };
        Binary::Inner { bounds, kids: Box::new([l, r]) }
    }

    /// Partitions `prims` (box `bounds`) by the cheaper of the best binned object split and,
    /// where the object split's sides overlap, the best spatial split (module docs).
    fn split(&self, mut prims: Vec<Prim>, bounds: &Aabb, depth: u32, budget: usize) -> Sides {
        let n = prims.len();
        let object = if depth >= MEDIAN_DEPTH { None } else { object_split(&prims) };
        let overlap = object.as_ref().map_or(f64::INFINITY, |o| surface_area64(&o.boxes[0].intersection(o.boxes[1])));
        if depth < MEDIAN_DEPTH && budget > 0 && overlap > self.min_overlap {
            let limit = object.as_ref().map_or(f64::INFINITY, |o| o.cost);
            if let Some(sides) = self.spatial_split(&prims, bounds, limit, budget) {
                return sides;
            }
        }
        let mid = match object {
            Some(o) => o.partition(&mut prims),
            None => {
                let axis = widest(&centroid_box(&prims));
                median(&mut prims, axis)
            }
        };
        let right = prims.split_off(mid);
        let bl = budget * mid / n;
        ([prims, right], [bl, budget - bl])
    }

    /// The best spatial split of `prims` if it costs less than `limit`, makes at most `budget`
    /// more references and leaves fewer references than `prims` on each side: [`BINS`]
    /// equal slabs of `bounds` along its widest axis, each reference's part in every slab it
    /// crosses added to that slab's box (Stich et al. 2009, section 4.2); the side counts
    /// are the references entering and leaving each slab. The parts are estimates for the
    /// costs ([`slab_part`]); the references of the split taken are clipped conservatively.
    /// Only the widest axis is binned: on Sponza, the kitchen and the atrium all three gave
    /// the same rays per second (within the noise) for about twice the build time.
    fn spatial_split(&self, prims: &[Prim], bounds: &Aabb, limit: f64, budget: usize) -> Option<Sides> {
        let n = prims.len();
        let a = widest(bounds);
        let (lo, extent) = (bounds.min[a], bounds.max[a] - bounds.min[a]);
        if extent <= 0.0 {
            return None;
        }
        let plane = |b: usize| lo + extent * (b as f32 / BINS as f32);
        let scale = BINS as f32 / extent;
        let slab_of = |x: f32| bin((x - lo) * scale);
        let mut enter = [0usize; BINS];
        let mut leave = [0usize; BINS];
        let mut boxes = [Bounds::EMPTY; BINS];
        for p in prims {
            let (b0, b1) = (slab_of(p.bounds.min[a]), slab_of(p.bounds.max[a]));
            enter[b0] += 1;
            leave[b1] += 1;
            if b0 == b1 {
                boxes[b0] = boxes[b0].union(p.bounds);
                continue;
            }
            let tri = self.triangle(p.id);
            let own = p.bounds.aabb();
            for (b, slab) in boxes.iter_mut().enumerate().take(b1 + 1).skip(b0) {
                let part = slab_part(&tri, a, plane(b), plane(b + 1)).intersection(own);
                if !part.is_empty() {
                    *slab = slab.union(part.into());
                }
            }
        }
        let (mut acc, mut count) = (Bounds::EMPTY, 0);
        let mut right = [(Bounds::EMPTY, 0usize); BINS];
        for b in (1..BINS).rev() {
            acc = acc.union(boxes[b]);
            count += leave[b];
            right[b] = (acc, count);
        }
        let mut best: Option<(f64, f32)> = None; // (cost, plane)
        let (mut acc, mut count) = (Bounds::EMPTY, 0);
        for b in 0..BINS - 1 {
            acc = acc.union(boxes[b]);
            count += enter[b];
            let (right_box, rc) = right[b + 1];
            if count == 0 || rc == 0 || count >= n || rc >= n {
                continue;
            }
            let cost = surface_area64(&acc.aabb()) * chunks(count) + surface_area64(&right_box.aabb()) * chunks(rc);
            if cost < limit && best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, plane(b + 1)));
            }
        }
        let (_, pos) = best?;
        let (mut left, mut right) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for p in prims {
            if p.bounds.max[a] <= pos {
                left.push(*p);
            } else if p.bounds.min[a] >= pos {
                right.push(*p);
            } else {
                let [below, above] = split_reference(&self.triangle(p.id), &p.bounds.aabb(), a, pos);
                // The box holds a part of the triangle, which the conservative clip keeps.
                debug_assert!(below.is_some() || above.is_some(), "triangle {} lost at {pos}", p.id);
                left.extend(below.map(|b| Prim::new(b, p.id)));
                right.extend(above.map(|b| Prim::new(b, p.id)));
            }
        }
        let (nl, nr) = (left.len(), right.len());
        let made = (nl + nr).saturating_sub(n);
        if nl == 0 || nr == 0 || nl >= n || nr >= n || made > budget {
            return None;
        }
        let rest = budget - made;
        let bl = rest * nl / (nl + nr);
        Some(([left, right], [bl, rest - bl]))
    }
}

/// The box of the part of `tri` between the planes `x_a = lo` and `x_a = hi` (its vertices
/// there and its edges' crossings of both planes), for the spatial split's costs: plain `f32`
/// arithmetic, not the conservative clip, since only the chosen split's references are kept.
fn slab_part(tri: &[Vec3; 3], a: usize, lo: f32, hi: f32) -> Aabb {
    let mut part = Aabb::EMPTY;
    for (i, v) in tri.iter().enumerate() {
        if v[a] >= lo && v[a] <= hi {
            part = part.grow(*v);
        }
        let w = tri[(i + 1) % 3];
        for c in [lo, hi] {
            if (v[a] < c && w[a] > c) || (v[a] > c && w[a] < c) {
                let mut x = *v + (w - *v) * ((c - v[a]) / (w[a] - v[a]));
                x[a] = c;
                part = part.grow(x);
            }
        }
    }
    part
}

/// The spatial splits' budget for `n` triangles: `per_triangle` more references per triangle.
pub(crate) fn split_budget(n: usize, per_triangle: f64) -> usize {
    (n as f64 * per_triangle) as usize
}

/// `ceil(n / 4)`: 4-wide tests for `n` triangles.
fn chunks(n: usize) -> f64 {
    n.div_ceil(LEAF_SIZE) as f64
}

/// The box of the references' centres.
fn centroid_box(prims: &[Prim]) -> Aabb {
    prims.iter().fold(Bounds::EMPTY, |b, p| b.grow(p.centroid())).aabb()
}

/// The axis of the box's largest extent (the first of equal ones).
fn widest(b: &Aabb) -> usize {
    let e = b.max - b.min;
    if e.x >= e.y && e.x >= e.z {
        0
    } else if e.y >= e.z {
        1
    } else {
        2
    }
}

/// The best binned-SAH object split of a node: references go left when their centre's bin
/// is at most `last` on `axis`.
struct ObjectSplit {
    cost: f64,
    axis: usize,
    last: usize,
    /// The centre box's lower corner on `axis` and bins per unit there.
    origin: f32,
    scale: f32,
    /// The two sides' boxes.
    boxes: [Aabb; 2],
}

/// The best binned-SAH object split of `prims` ([`BINS`] bins of the centre box per axis), or
/// `None` when every centre is in one bin.
fn object_split(prims: &[Prim]) -> Option<ObjectSplit> {
    let cb = centroid_box(prims);
    let (origin, extent) = (Vec3A::from(cb.min), Vec3A::from(cb.max - cb.min));
    // Bins per unit; infinite on an axis where every centre is equal (not swept below).
    let scale = Vec3A::splat(BINS as f32) / extent;
    // One pass bins every reference on all three axes.
    let mut counts = [[0usize; BINS]; 3];
    let mut boxes = [[Bounds::EMPTY; BINS]; 3];
    for p in prims {
        let bins = bins((p.centroid() - origin) * scale);
        for (a, &b) in bins.iter().enumerate() {
            counts[a][b] += 1;
            boxes[a][b] = boxes[a][b].union(p.bounds);
        }
    }
    let mut best: Option<ObjectSplit> = None;
    for a in 0..3 {
        if extent[a] <= 0.0 {
            continue;
        }
        let (counts, boxes) = (&counts[a], &boxes[a]);
        let mut right = [(Bounds::EMPTY, 0usize); BINS];
        let (mut acc, mut count) = (Bounds::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc = acc.union(boxes[b]);
            count += counts[b];
            right[b] = (acc, count);
        }
        let (mut acc, mut count) = (Bounds::EMPTY, 0);
        for b in 0..BINS - 1 {
            // The plane after an empty bin splits as the plane before it (the same sides), which
            // was priced first and wins a tie: small nodes have mostly empty bins.
            if counts[b] == 0 {
                continue;
            }
            acc = acc.union(boxes[b]);
            count += counts[b];
            let (rbox, rc) = right[b + 1];
            if rc == 0 {
                continue;
            }
            let (left, rbox) = (acc.aabb(), rbox.aabb());
            let cost = surface_area64(&left) * chunks(count) + surface_area64(&rbox) * chunks(rc);
            if best.as_ref().is_none_or(|o| cost < o.cost) {
                best = Some(ObjectSplit {
                    cost,
                    axis: a,
                    last: b,
                    origin: origin[a],
                    scale: scale[a],
                    boxes: [left, rbox],
                });
            }
        }
    }
    best
}

/// The bin of a scaled offset `x` from the binned range's start (at least 0, or NaN on an
/// axis of no extent): `x` truncated, at most `BINS - 1`, NaN in bin 0. The one rule of the
/// build's bins: [`bins`] is its SIMD form, and the partitions use it.
#[inline(always)]
fn bin(x: f32) -> usize {
    (x as usize).min(BINS - 1)
}

/// [`bin`] on each axis of `x` (in SSE2 on x86-64: a clamp and one conversion for all three
/// axes; elsewhere `bin` per axis).
#[inline(always)]
fn bins(x: Vec3A) -> [usize; 3] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__m128, _mm_cvttps_epi32, _mm_max_ps, _mm_min_ps, _mm_set1_ps, _mm_setzero_ps};
        let v: __m128 = x.into();
        // SAFETY: SSE2 is part of every x86-64 CPU. `maxps` takes its second operand where
        // the first is NaN, so NaN becomes 0; then every lane is in [0, BINS - 1] and
        // converts exactly.
        let i = unsafe {
            let clamped = _mm_min_ps(_mm_max_ps(v, _mm_setzero_ps()), _mm_set1_ps((BINS - 1) as f32));
            std::mem::transmute::<std::arch::x86_64::__m128i, [i32; 4]>(_mm_cvttps_epi32(clamped))
        };
        [i[0] as usize, i[1] as usize, i[2] as usize]
    }
    #[cfg(not(target_arch = "x86_64"))]
    x.to_array().map(bin)
}

impl ObjectSplit {
    /// Partitions `prims` and returns the size of the first part, in `1..prims.len()`.
    fn partition(&self, prims: &mut [Prim]) -> usize {
        let (a, n) = (self.axis, prims.len());
        let left = |p: &Prim| bin((p.centroid()[a] - self.origin) * self.scale) <= self.last;
        // Two-pointer partition (deterministic).
        let (mut i, mut j) = (0, n);
        while i < j {
            if left(&prims[i]) {
                i += 1;
            } else {
                j -= 1;
                prims.swap(i, j);
            }
        }
        if i == 0 || i == n {
            let axis = widest(&centroid_box(prims));
            median(prims, axis)
        } else {
            i
        }
    }
}

/// The object median along `axis` (centroid order, then id, so the order is total).
fn median(prims: &mut [Prim], axis: usize) -> usize {
    let mid = prims.len() / 2;
    prims.select_nth_unstable_by(mid, |p, q| p.centroid()[axis].total_cmp(&q.centroid()[axis]).then(p.id.cmp(&q.id)));
    mid
}

/// The collapsed tree: multi-nodes (root at 0) and, per leaf, the ids of its triangles.
pub(crate) struct Collapsed<N> {
    pub nodes: Vec<N>,
    pub leaves: Vec<Vec<u32>>,
    pub depth: u32,
}

/// Collapses `root` into multi-nodes.
pub(crate) fn collapse<N: MultiNode>(root: &Binary) -> Result<Collapsed<N>, BuildError> {
    let mut out = Collapsed { nodes: Vec::new(), leaves: Vec::new(), depth: 0 };
    match root {
        Binary::Leaf { .. } => {
            let mut node = N::empty();
            if let Some(child) = leaf(root, &mut out)? {
                node.set(0, child, root.bounds());
            }
            out.nodes.push(node);
            out.depth = 1;
        }
        Binary::Inner { .. } => {
            multi(root, &mut out, 1)?;
        }
    }
    Ok(out)
}

/// A leaf child word (`LEAF | block`), or `None` for an empty leaf.
fn leaf<N>(b: &Binary, out: &mut Collapsed<N>) -> Result<Option<u32>, BuildError> {
    let Binary::Leaf { ids, .. } = b else { unreachable!("leaf() takes leaves") };
    if ids.is_empty() {
        return Ok(None);
    }
    let index = out.leaves.len();
    if index >= LEAF as usize - 1 {
        return Err(BuildError::TooLarge(format!("{index} leaves")));
    }
    out.leaves.push(ids.to_vec());
    Ok(Some(LEAF | index as u32))
}

/// The multi-node of inner binary node `b` (section 4.2: pull up the largest inner child
/// while there is room), then its inner children recursively. Returns its index.
fn multi<N: MultiNode>(b: &Binary, out: &mut Collapsed<N>, depth: u32) -> Result<u32, BuildError> {
    let Binary::Inner { kids, .. } = b else { unreachable!("multi() takes inner nodes") };
    let mut slots: Vec<&Binary> = kids.iter().collect();
    while slots.len() < N::WIDTH {
        let largest = slots
            .iter()
            .enumerate()
            .filter(|(_, s)| matches!(s, Binary::Inner { .. }))
            .max_by(|(_, a), (_, b)| a.bounds().surface_area().total_cmp(&b.bounds().surface_area()))
            .map(|(i, _)| i);
        let Some(i) = largest else { break };
        let Binary::Inner { kids, .. } = slots[i] else { unreachable!() };
        slots.splice(i..=i, kids.iter());
    }
    let index = out.nodes.len();
    if index >= LEAF as usize - 1 {
        return Err(BuildError::TooLarge(format!("{index} nodes")));
    }
    out.nodes.push(N::empty());
    out.depth = out.depth.max(depth);
    for (i, s) in slots.iter().enumerate() {
        let child = match s {
            Binary::Leaf { .. } => leaf(s, out)?,
            Binary::Inner { .. } => Some(multi(s, out, depth + 1)?),
        };
        if let Some(child) = child {
            let bounds = *s.bounds();
            out.nodes[index].set(i, child, &bounds);
        }
    }
    Ok(index as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::Node8;

    /// Small triangles and, every sixth, a long sliver across the whole box: spatial splits cut
    /// the slivers.
    fn slivers(n: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 40) as f32 / (1u64 << 24) as f32 * 8.0 - 4.0
        };
        let mut positions = Vec::new();
        for i in 0..n {
            let a = Vec3::new(rnd(), rnd(), rnd());
            let c = if i % 6 == 0 { -a } else { a + Vec3::new(rnd(), rnd(), rnd()) * 0.05 };
            positions.extend([a, c, c + Vec3::new(0.01, 0.02, 0.03)]);
        }
        (positions, (0..n).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect())
    }

    fn leaves(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec<u32>> {
        let prims = prims(positions, triangles).unwrap();
        let bounds = bounds_of(&prims);
        let budget = split_budget(prims.len(), SPLIT_BUDGET);
        let root = Builder::new(positions, triangles, &bounds, SPATIAL_ALPHA).binary(prims, 1, budget);
        collapse::<Node8>(&root).unwrap().leaves
    }

    #[test]
    fn spatial_splits_stay_in_budget_and_do_not_depend_on_the_threads() {
        let (p, t) = slivers(6000);
        let on =
            |threads| rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| leaves(&p, &t));
        let one = on(1);
        assert_eq!(one, on(2), "the tree changed with the thread count");
        let refs: usize = one.iter().map(Vec::len).sum();
        assert!(refs > t.len() * 21 / 20 && refs <= t.len() + split_budget(t.len(), SPLIT_BUDGET), "{refs} references");
    }

    #[test]
    fn a_slab_part_is_the_box_of_the_triangle_between_the_planes() {
        let tri = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 2.0)];
        let part = slab_part(&tri, 0, 1.0, 2.0);
        assert_eq!((part.min, part.max), (Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.0, 3.0, 1.5)));
        // Planes outside the triangle: the whole triangle, or nothing.
        let all = slab_part(&tri, 1, -1.0, 5.0);
        assert_eq!((all.min, all.max), (Vec3::ZERO, Vec3::new(4.0, 4.0, 2.0)));
        assert!(slab_part(&tri, 2, 3.0, 4.0).is_empty());
    }

    /// The binned object split as first written: each axis binned in a pass of its own with
    /// `Aabb`'s scalar boxes, every plane priced.
    fn object_split_reference(prims: &[Prim]) -> Option<(f64, usize, usize)> {
        let cb = centroid_box(prims);
        let extent = cb.max - cb.min;
        let mut best: Option<(f64, usize, usize)> = None;
        for a in 0..3 {
            if extent[a] <= 0.0 {
                continue;
            }
            let scale = BINS as f32 / extent[a];
            let mut counts = [0usize; BINS];
            let mut boxes = [Aabb::EMPTY; BINS];
            for p in prims {
                let c = (p.bounds.aabb().min + p.bounds.aabb().max) * 0.5;
                let b = (((c[a] - cb.min[a]) * scale) as usize).min(BINS - 1);
                counts[b] += 1;
                boxes[b] = boxes[b].union(p.bounds.aabb());
            }
            for plane in 0..BINS - 1 {
                let side = |bins: std::ops::Range<usize>| {
                    bins.fold((Aabb::EMPTY, 0), |(b, n), i| (b.union(boxes[i]), n + counts[i]))
                };
                let ((lb, lc), (rb, rc)) = (side(0..plane + 1), side(plane + 1..BINS));
                if lc == 0 || rc == 0 {
                    continue;
                }
                let cost = surface_area64(&lb) * chunks(lc) + surface_area64(&rb) * chunks(rc);
                if best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, a, plane));
                }
            }
        }
        best
    }

    #[test]
    fn the_object_split_is_the_reference_split() {
        let (p, t) = slivers(3000);
        let all = prims(&p, &t).unwrap();
        // Nodes of 5 to 3000 references (small ones leave most bins empty), and some far
        // from the origin and tiny.
        for (shift, scale) in [(Vec3::ZERO, 1.0), (Vec3::splat(1e5), 1.0), (Vec3::ZERO, 1e-30)] {
            let moved: Vec<Prim> = all
                .iter()
                .map(|q| {
                    let b = q.bounds.aabb();
                    Prim::new(Aabb { min: b.min * scale + shift, max: b.max * scale + shift }, q.id)
                })
                .collect();
            for n in [5, 6, 9, 17, 40, 300, 3000] {
                for chunk in moved.chunks(n).take(20) {
                    let got = object_split(chunk).map(|o| (o.cost, o.axis, o.last));
                    assert_eq!(got, object_split_reference(chunk), "{n} references, shift {shift}, scale {scale}");
                }
            }
        }
    }

    #[test]
    fn the_simd_boxes_are_the_scalar_boxes() {
        let (p, t) = slivers(500);
        let all = prims(&p, &t).unwrap();
        let scalar = all.iter().fold(Aabb::EMPTY, |b, q| b.union(q.bounds.aabb()));
        let simd = bounds_of(&all);
        assert_eq!(simd.min.to_array().map(f32::to_bits), scalar.min.to_array().map(f32::to_bits));
        assert_eq!(simd.max.to_array().map(f32::to_bits), scalar.max.to_array().map(f32::to_bits));
        let centres = all.iter().fold(Aabb::EMPTY, |b, q| b.grow((q.bounds.aabb().min + q.bounds.aabb().max) * 0.5));
        let cb = centroid_box(&all);
        assert_eq!(cb.min.to_array().map(f32::to_bits), centres.min.to_array().map(f32::to_bits));
        assert_eq!(cb.max.to_array().map(f32::to_bits), centres.max.to_array().map(f32::to_bits));
    }

    #[test]
    fn bins_are_the_truncated_offsets_at_most_the_last_bin() {
        assert_eq!([0.0, 0.99, 1.0, 31.0, 1e30, f32::INFINITY, f32::NAN].map(bin), [0, 0, 1, 31, 31, 31, 0]);
        let xs = [0.0, -0.0, 1e-40, 0.5, 1.0, 30.99, 31.0, 31.5, 32.0, 1e9, 1e30, f32::INFINITY, f32::NAN];
        for &x in &xs {
            for &y in &xs {
                let v = Vec3A::new(x, y, 7.25);
                assert_eq!(bins(v), v.to_array().map(bin), "{v}");
            }
        }
    }
}
