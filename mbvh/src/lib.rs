//! A multi-branching BVH for single rays: Wald, Benthin & Boulos 2008, "Getting Rid of
//! Packets — Efficient SIMD Single-Ray Traversal using Multi-branching BVHs"
//! (`../shared/seeds/wald-benthin-boulos-2008-getting-rid-of-packets.txt`).
//!
//! Instead of tracing four rays through a binary structure (the thesis's packets), one ray is
//! traced through a BVH whose nodes have `W` children, and the SIMD lanes test the child
//! boxes of a node ([`boxtest`]) or the four triangles of a leaf ([`leaf`]) at once. It needs
//! no coherence between rays, so it is the structure for incoherent rays (ambient
//! occlusion, diffuse bounces), where packets and frusta fall apart.
//!
//! The width is a parameter, written once: the node [`Node<W>`], the scalar node test
//! [`Scalar<W>`], the collapse and the traversal serve every width with a [`NodeWidth`]
//! (4, 8 and 16); only the SIMD node tests are per width and instruction set.
//!
//! - [`node`]: [`Node<W>`], the SoA multi-node (per axis `[min, max]`, each `W` lanes
//!   aligned for one register; [`Node4`], [`Node8`], [`Node16`]), what each width fixes ([`NodeWidth`]:
//!   lane alignment, stack capacity) and [`MultiNode`], the node as the build and the
//!   traversal see it.
//! - [`boxtest`]: the conservative slab test (section 5.2): [`BoxTest`] (a node test as a
//!   value, with its scalar twin and the traversal's entry points) and the portable scalar
//!   test of every width, [`Scalar<W>`], the twin of every SIMD test (with fused widening,
//!   [`FusedScalar8`] and [`FusedScalar16`], for the AVX2 and AVX-512 tests).
//! - [`simd4`]: [`Simd4`], the 4-wide test in SSE (glam's `Vec4`).
//! - [`simd8`]: [`Avx2`], the 8-wide test in AVX2, a token chosen at run time.
//! - [`simd16`]: [`Avx512`], the paper's 16-wide test in AVX-512 (one 512-bit register per
//!   box coordinate, the hit mask a k-mask), a token chosen at run time like [`Avx2`];
//!   without it 16-wide trees use [`Scalar16`].
//! - [`build`]: binned SAH binary BVH with spatial splits (Stich et al. 2009) collapsed
//!   top-down into `W`-wide multi-nodes (section 4).
//! - [`leaf`]: leaf blocks of up to four triangles SoA for both of `kdtree`'s intersectors,
//!   each lane bit-identical to the scalar test.
//! - [`traverse`]: closest hit (children nearest first) and any hit (early exit), one loop
//!   for every width and node test, with a scalar twin.
//! - [`packet`]: the 8-wide tree traced by packets of 16 rays (one AVX-512 register per ray
//!   coordinate, [`Avx512`]; two AVX registers per coordinate on a CPU without AVX-512,
//!   [`Avx2`]; or the portable twin [`Portable16`]), lanes finished by single
//!   rays below a threshold (the hybrid traversal of Benthin et al. 2012, Embree's
//!   incoherent `embree-16`).
//!
//! Modules import only downwards: `node` imports nothing of the crate; `boxtest` and
//! `build` import `node`; `simd4`, `simd8` and `simd16` import `node` and `boxtest`; `traverse`
//! imports `node`, `boxtest` and `leaf`; `packet` imports `node`, `boxtest`, `leaf`,
//! `simd8`, `simd16` and `traverse`; this root imports them all.
//!
//! **Where the CPU makes us differ from the paper.** The paper targets 16-wide SIMD (Larrabee)
//! and builds 16-wide nodes and leaves. The project's first machine (AMD Zen 1) has SSE4.2 and
//! AVX2, no 16-wide SIMD, and executes every 256-bit operation as two 128-bit halves: an
//! 8-wide node test costs about two 4-wide ones, so 8 wide buys no arithmetic throughput, only
//! fewer, fatter nodes (fewer traversal steps and stack operations). We build every width over
//! the same binary BVH: [`Mbvh`], 4 wide (one SSE register per coordinate, glam's `Vec4`),
//! [`Mbvh8`], 8 wide (AVX2 where the CPU has it, checked once when the traversal is made),
//! and [`Mbvh16`], the paper's 16 wide (AVX-512 where the CPU has it, [`Avx512`], checked
//! the same way; the scalar test elsewhere).
//! Measured here (`docs/results/incoherent-mbvh.md`), 8 wide is the faster, 1.1-1.6x on
//! primary, shadow, AO and diffuse rays: a ray visits about a third fewer nodes, and a single
//! ray's node step costs its latency more than its arithmetic (16 wide is not measured there:
//! that CPU has no AVX-512). Leaves stay one 4-wide block of triangles in every width. With
//! at most 16 children the paper's unsorted active list (section 5.3) is replaced by an
//! insertion sort of the entered children onto the stack.
//!
//! The tree is independent of the triangle test; its leaves are stored once per intersector
//! ([`MultiBvh::wald`], [`MultiBvh::watertight`]) so that a method can answer with the test of the
//! kd-tree it is compared with. Kernels never allocate, lock or dispatch dynamically.

pub mod boxtest;
pub mod build;
pub mod leaf;
pub mod node;
pub mod packet;
pub mod simd16;
pub mod simd4;
pub mod simd8;
pub mod traverse;

use glam::Vec3;
use kdtree::Aabb;
use kdtree::triangle::{WaldTriangle, WatertightTriangle, is_degenerate};
use rayon::prelude::*;

pub use boxtest::{BoxTest, FusedScalar8, FusedScalar16, Scalar, Scalar4, Scalar8, Scalar16};
pub use build::{BuildError, SpatialSplits};
pub use leaf::{LeafBlock, WaldBlock, WatertightBlock};
pub use node::{MAX_DEPTH, MultiNode, Node, Node4, Node8, Node16, NodeWidth, Width};
pub use packet::{
    HYBRID_THRESHOLD, HYBRID_THRESHOLD_ANY, HYBRID_THRESHOLD_ANY_AVX2, LEAF_LANES, PacketLanes, PacketTraversal,
    Portable16,
};
pub use simd4::Simd4;
pub use simd8::Avx2;
pub use simd16::Avx512;
pub use traverse::Traversal;

/// The 4-wide BVH ([`Node4`]).
pub type Mbvh = MultiBvh<Node4>;

/// The 8-wide BVH ([`Node8`]), collapsed from the same binary BVH as [`Mbvh`].
pub type Mbvh8 = MultiBvh<Node8>;

/// The 16-wide BVH ([`Node16`], the paper's width), collapsed from the same binary BVH as
/// [`Mbvh`] and [`Mbvh8`].
pub type Mbvh16 = MultiBvh<Node16>;

/// A node width's default test: the one [`MultiBvh::wald`] and [`MultiBvh::watertight`]
/// traverse with, portable (it runs on every CPU of the architecture); a faster one that
/// needs a CPU feature is asked for with `Traversal::with_test`.
pub trait DefaultTest: MultiNode {
    /// The test.
    type Test: BoxTest<Node = Self> + Default;
}

/// SSE on x86-64 (glam's `Vec4`; NEON or scalar elsewhere).
impl DefaultTest for Node4 {
    type Test = Simd4;
}

/// Scalar; [`Avx2`] where [`Avx2::detect`] finds it.
impl DefaultTest for Node8 {
    type Test = Scalar8;
}

/// Scalar; [`Avx512`] where [`Avx512::detect`] finds it (`Traversal::with_test`).
impl DefaultTest for Node16 {
    type Test = Scalar16;
}

/// A multi-branching BVH over a triangle mesh, nodes of type `N` ([`Node<W>`]), with leaf
/// blocks for both intersectors.
#[derive(Clone, Debug)]
pub struct MultiBvh<N: MultiNode> {
    nodes: Vec<N>,
    wald: Vec<WaldBlock>,
    watertight: Vec<WatertightBlock>,
    bounds: Aabb,
    depth: u32,
    triangles: usize,
}

/// Sizes of a built tree, for reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MbvhStats {
    /// Multi-nodes.
    pub nodes: usize,
    /// Leaves (blocks).
    pub leaves: usize,
    /// References in the leaves: every non-degenerate triangle, some in several leaves by
    /// spatial splits (`build`).
    pub leaf_triangles: usize,
    /// The multi-node tree's depth (the root alone is 1).
    pub depth: u32,
    /// Mean used child slots per multi-node.
    pub branching: f64,
    /// Bytes of nodes and of one intersector's blocks.
    pub bytes: usize,
}

impl<N: MultiNode> MultiBvh<N> {
    /// Builds the tree over `triangles` (indices into `positions`). Degenerate triangles
    /// (zero area) are left out, as from the kd-tree; `Hit::prim` is the index into
    /// `triangles`. A non-finite vertex or an index out of range is an error naming it.
    pub fn build(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<MultiBvh<N>, BuildError> {
        Self::build_with(positions, triangles, SpatialSplits::DEFAULT)
    }

    /// [`MultiBvh::build`] with the given spatial splits ([`SpatialSplits::OFF`]: none); a
    /// NaN or negative setting, or an infinite budget, is an error naming the field.
    pub fn build_with(
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        splits: SpatialSplits,
    ) -> Result<MultiBvh<N>, BuildError> {
        splits.check()?;
        let prims = build::prims(positions, triangles)?;
        let bounds = build::bounds_of(&prims);
        let budget = build::split_budget(prims.len(), splits.budget);
        let binary = build::Builder::new(positions, triangles, &bounds, splits.alpha).binary(prims, 1, budget);
        let collapsed = build::collapse::<N>(&binary)?;
        let tri = |id: u32| triangles[id as usize].map(|v| positions[v as usize]);
        // Packed in parallel (in order: the same blocks on any thread count).
        let wald = collapsed
            .leaves
            .par_iter()
            .map(|ids| WaldBlock::pack(&ids.iter().map(|&id| (WaldTriangle::new(&tri(id)), id)).collect::<Vec<_>>()))
            .collect();
        let watertight = collapsed
            .leaves
            .par_iter()
            .map(|ids| {
                WatertightBlock::pack(
                    &ids.iter().map(|&id| (WatertightTriangle::new(&tri(id)), id)).collect::<Vec<_>>(),
                )
            })
            .collect();
        Ok(MultiBvh {
            nodes: collapsed.nodes,
            wald,
            watertight,
            bounds,
            depth: collapsed.depth,
            triangles: triangles.len(),
        })
    }

    /// The multi-nodes; the root is the first.
    pub fn nodes(&self) -> &[N] {
        &self.nodes
    }

    /// The box of every non-degenerate triangle.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Sizes and shape.
    pub fn stats(&self) -> MbvhStats {
        let used: usize = self.nodes.iter().map(|n| n.children().iter().filter(|&&c| c != node::EMPTY).count()).sum();
        let leaf_triangles =
            self.wald.iter().map(|b| (0..leaf::LANES).filter(|&l| b.record_prim(l) != u32::MAX).count()).sum();
        MbvhStats {
            nodes: self.nodes.len(),
            leaves: self.wald.len(),
            leaf_triangles,
            depth: self.depth,
            branching: used as f64 / self.nodes.len().max(1) as f64,
            bytes: self.nodes.len() * size_of::<N>() + self.wald.len() * size_of::<WaldBlock>(),
        }
    }

    /// Checks the tree against the mesh it was built from: every node and leaf reached
    /// exactly once from the root, every child box inside its parent's slot box, every
    /// non-degenerate triangle in at least one leaf (degenerate ones in none, none twice in
    /// one leaf), each leaf's box meeting its triangles' boxes, each triangle covered by its
    /// leaves' boxes (spatial splits put parts of it in several: its vertices exactly, and a
    /// lattice of 45 inner points within `2^-20` of its largest coordinate), both
    /// intersectors' records equal to the scalar records bit for bit, and the depth within
    /// [`MAX_DEPTH`]. Returns the first violation.
    pub fn validate(&self, positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<(), String> {
        if triangles.len() != self.triangles {
            return Err(format!("built over {} triangles, given {}", self.triangles, triangles.len()));
        }
        let mut node_seen = vec![false; self.nodes.len()];
        let mut leaf_seen = vec![false; self.wald.len()];
        let mut tri_boxes: Vec<Vec<Aabb>> = vec![Vec::new(); triangles.len()];
        let mut stack = vec![(0u32, Aabb { min: Vec3::NEG_INFINITY, max: Vec3::INFINITY }, 1u32)];
        let inside = |a: &Aabb, b: &Aabb| a.min.cmpge(b.min).all() && a.max.cmple(b.max).all();
        while let Some((index, parent, depth)) = stack.pop() {
            if depth > MAX_DEPTH {
                return Err(format!("node {index} at depth {depth} > {MAX_DEPTH}"));
            }
            let seen = node_seen.get_mut(index as usize).ok_or(format!("node {index} does not exist"))?;
            if std::mem::replace(seen, true) {
                return Err(format!("node {index} reached twice"));
            }
            let node = &self.nodes[index as usize];
            for (slot, &child) in node.children().iter().enumerate() {
                let b = node.child_box(slot);
                if child == node::EMPTY {
                    if !b.is_empty() {
                        return Err(format!("node {index} slot {slot}: empty slot with box {b:?}"));
                    }
                    continue;
                }
                if !inside(&b, &parent) {
                    return Err(format!("node {index} slot {slot}: box {b:?} outside its parent's {parent:?}"));
                }
                if child & node::LEAF == 0 {
                    stack.push((child, b, depth + 1));
                    continue;
                }
                let leaf = (child & !node::LEAF) as usize;
                let seen = leaf_seen.get_mut(leaf).ok_or(format!("leaf {leaf} does not exist"))?;
                if std::mem::replace(seen, true) {
                    return Err(format!("leaf {leaf} reached twice"));
                }
                for lane in 0..leaf::LANES {
                    let (w, id) = self.wald[leaf].record(lane);
                    let (wt, id2) = self.watertight[leaf].record(lane);
                    if id != id2 {
                        return Err(format!("leaf {leaf} lane {lane}: ids {id} and {id2} differ"));
                    }
                    if id == u32::MAX {
                        continue;
                    }
                    let t = triangles
                        .get(id as usize)
                        .ok_or(format!("leaf {leaf}: triangle {id} does not exist"))?
                        .map(|v| positions[v as usize]);
                    let boxes = &mut tri_boxes[id as usize];
                    if (0..lane).any(|l| self.wald[leaf].record_prim(l) == id) {
                        return Err(format!("triangle {id} twice in leaf {leaf}"));
                    }
                    if Aabb::from_points(&t).intersection(b).is_empty() {
                        return Err(format!("triangle {id} outside its leaf box {b:?}"));
                    }
                    boxes.push(b);
                    let (rw, rwt) = (WaldTriangle::new(&t), WatertightTriangle::new(&t));
                    let same_wald = format!("{rw:?}") == format!("{w:?}");
                    if !same_wald
                        || rwt.v.map(|v| v.to_array().map(f32::to_bits)) != wt.v.map(|v| v.to_array().map(f32::to_bits))
                    {
                        return Err(format!("triangle {id}: leaf records differ from the scalar records"));
                    }
                }
            }
        }
        if let Some(i) = node_seen.iter().position(|s| !s) {
            return Err(format!("node {i} unreachable"));
        }
        if let Some(i) = leaf_seen.iter().position(|s| !s) {
            return Err(format!("leaf {i} unreachable"));
        }
        for (id, t) in triangles.iter().enumerate() {
            let t = t.map(|v| positions[v as usize]);
            let (degenerate, boxes) = (is_degenerate(&t), &tri_boxes[id]);
            if boxes.is_empty() != degenerate {
                return Err(format!(
                    "triangle {id} (degenerate: {degenerate}) in {} leaf",
                    if boxes.is_empty() { "no" } else { "a" }
                ));
            }
            if !degenerate {
                covered(&t, boxes).map_err(|p| format!("triangle {id}: point {p} in none of its leaves' boxes"))?;
            }
        }
        Ok(())
    }
}

impl<N: DefaultTest> MultiBvh<N> {
    /// The tree with Wald's test in the leaves (thesis 4.2) and the width's default node
    /// test ([`DefaultTest`]; `Traversal::with_test` picks another, e.g. [`Avx2`] or
    /// [`Avx512`]).
    pub fn wald(&self) -> Traversal<'_, WaldBlock, N::Test> {
        Traversal::new(&self.nodes, &self.wald, N::Test::default())
    }

    /// The tree with the watertight test in the leaves (Woop et al. 2013) and the width's
    /// default node test.
    pub fn watertight(&self) -> Traversal<'_, WatertightBlock, N::Test> {
        Traversal::new(&self.nodes, &self.watertight, N::Test::default())
    }
}

/// Whether the boxes cover triangle `t`: each vertex inside one exactly, and the inner points
/// of barycentric coordinates `(i + 1/3, j + 1/3, k + 1/3) / 9` (`i + j + k = 8`) inside one
/// grown by `2^-20` of the triangle's largest coordinate magnitude (their rounding). The first
/// point outside every box is the error.
fn covered(t: &[Vec3; 3], boxes: &[Aabb]) -> Result<(), Vec3> {
    let inside = |p: Vec3, grow: f32| boxes.iter().any(|b| p.cmpge(b.min - grow).all() && p.cmple(b.max + grow).all());
    if let Some(&v) = t.iter().find(|&&v| !inside(v, 0.0)) {
        return Err(v);
    }
    let grow = t.iter().map(|v| v.abs().max_element()).fold(0.0, f32::max) * (1.0 / (1u32 << 20) as f32);
    for i in 0..9 {
        for j in 0..9 - i {
            let w = [i as f32 + 1.0 / 3.0, j as f32 + 1.0 / 3.0, (8 - i - j) as f32 + 1.0 / 3.0].map(|w| w / 9.0);
            let p = t[0] * w[0] + t[1] * w[1] + t[2] * w[2];
            if !inside(p, grow) {
                return Err(p);
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use kdtree::{NoCounters, Ray};

    fn quad_mesh(n: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for i in 0..n {
            let x = i as f32;
            let base = positions.len() as u32;
            positions.extend([Vec3::new(x, 0.0, 0.0), Vec3::new(x + 0.9, 0.0, 0.0), Vec3::new(x, 1.0, 0.0)]);
            triangles.push([base, base + 1, base + 2]);
        }
        (positions, triangles)
    }

    #[test]
    fn builds_validate_and_shape() {
        for n in [0, 1, 3, 4, 5, 17, 1000] {
            let (p, t) = quad_mesh(n);
            let bvh = Mbvh::build(&p, &t).unwrap();
            bvh.validate(&p, &t).unwrap();
            let s = bvh.stats();
            assert_eq!(s.leaf_triangles, n);
            let bvh8 = Mbvh8::build(&p, &t).unwrap();
            bvh8.validate(&p, &t).unwrap();
            let s8 = bvh8.stats();
            // The same binary BVH collapsed: the same leaves, fewer and wider nodes.
            assert_eq!((s8.leaves, s8.leaf_triangles), (s.leaves, s.leaf_triangles));
            assert!(s8.nodes <= s.nodes && s8.depth <= s.depth, "{s:?} {s8:?}");
            if n >= 1000 {
                assert!(s.branching > 3.5, "{s:?}");
                // 250 leaves in a balanced binary tree: 8-wide nodes take three binary levels,
                // so the last ones hold four leaves.
                assert!(s8.branching > 4.0 && s8.nodes < s.nodes, "{s:?} {s8:?}");
            }
        }
    }

    #[test]
    fn the_widths_give_the_same_hits() {
        let (p, t) = quad_mesh(300);
        let (b4, b8) = (Mbvh::build(&p, &t).unwrap(), Mbvh8::build(&p, &t).unwrap());
        let b16 = Mbvh16::build(&p, &t).unwrap();
        let (avx, avx512) = (Avx2::detect(), Avx512::detect());
        for i in 0..600 {
            let x = i as f32 * 0.5 + 0.13;
            let ray = Ray::new(Vec3::new(x, 0.2, -1.0), Vec3::new(0.01 * (i % 7) as f32, 0.0, 1.0), 0.0, f32::INFINITY);
            let want = b4.wald().intersect_counted(&ray, &mut NoCounters);
            assert_eq!(b8.wald().intersect_counted(&ray, &mut NoCounters), want, "{ray:?}");
            assert_eq!(b8.wald().occluded_counted(&ray, &mut NoCounters), want.is_some());
            if let Some(avx) = avx {
                let tr = b8.watertight().with_test(avx);
                assert_eq!(tr.intersect_counted(&ray, &mut NoCounters), tr.intersect_scalar(&ray, &mut NoCounters));
                assert_eq!(tr.occluded_counted(&ray, &mut NoCounters), want.is_some());
            }
            assert_eq!(b16.wald().intersect_counted(&ray, &mut NoCounters), want, "{ray:?}");
            if let Some(avx512) = avx512 {
                let tr = b16.wald().with_test(avx512);
                assert_eq!(tr.intersect_counted(&ray, &mut NoCounters), want, "{ray:?}");
                assert_eq!(tr.occluded_counted(&ray, &mut NoCounters), want.is_some());
            }
        }
    }

    /// Width 16 with the scalar test and, where the CPU has it, the AVX-512 test: the tree
    /// collapsed from the same binary BVH, traced against `BruteForce` and its scalar twin.
    #[test]
    fn a_16_wide_tree_traces_like_brute_force() {
        use kdtree::{BruteForce, Hit, Intersector};
        use scenes::builtin::shapes::Rng;

        /// `tr`'s closest hit of `ray`, checked against the oracle (closest and any hit) and
        /// against its scalar twin bit for bit.
        fn traced<B: LeafBlock, K: BoxTest>(tr: Traversal<'_, B, K>, oracle: &BruteForce, ray: &Ray) -> Option<Hit> {
            let got = tr.intersect_counted(ray, &mut NoCounters);
            let occluded = tr.occluded_counted(ray, &mut NoCounters);
            oracle.check(ray, got, occluded).unwrap();
            let bits = |h: Option<Hit>| h.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.prim));
            assert_eq!(bits(got), bits(tr.intersect_scalar(ray, &mut NoCounters)), "{ray:?}");
            assert_eq!(occluded, tr.occluded_scalar(ray, &mut NoCounters), "{ray:?}");
            got
        }

        let mut rng = Rng::new(16);
        let mut point = |s: f32| Vec3::new(rng.range(-s, s), rng.range(-s, s), rng.range(-s, s));
        let mut positions = Vec::new();
        for _ in 0..400 {
            let c = point(4.0);
            positions.extend([c + point(0.6), c + point(0.6), c + point(0.6)]);
        }
        let triangles: Vec<[u32; 3]> = (0..400).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let bvh = Mbvh16::build(&positions, &triangles).unwrap();
        bvh.validate(&positions, &triangles).unwrap();
        let (s, s8) = (bvh.stats(), Mbvh8::build(&positions, &triangles).unwrap().stats());
        assert_eq!((s.leaves, s.leaf_triangles), (s8.leaves, s8.leaf_triangles));
        assert!(s.nodes < s8.nodes && s.depth <= s8.depth && s.branching > s8.branching, "{s:?} {s8:?}");
        let tris: Vec<[Vec3; 3]> = triangles.iter().map(|t| t.map(|v| positions[v as usize])).collect();
        let (w, wt) = (BruteForce::new(&tris, Intersector::Wald), BruteForce::new(&tris, Intersector::Watertight));
        let avx512 = Avx512::detect();
        if avx512.is_none() {
            eprintln!(
                "note: no AVX-512 on this CPU (or the SIMD cap): the 16-wide tree is traced with the scalar test only"
            );
        }
        let mut hits = 0;
        for i in 0..600 {
            let (o, to) = (point(6.0), point(3.0));
            // Every third ray axis-parallel: zero direction components.
            let d = if i % 3 == 0 { Vec3::new(0.0, 0.0, (to - o).z) } else { to - o };
            if d == Vec3::ZERO {
                continue;
            }
            let ray = Ray::new(o, d, 0.0, if i % 2 == 0 { f32::INFINITY } else { 1.0 });
            let got = traced(bvh.wald(), &w, &ray);
            traced(bvh.watertight(), &wt, &ray);
            if let Some(avx) = avx512 {
                assert_eq!(traced(bvh.wald().with_test(avx), &w, &ray), got, "{ray:?}");
                traced(bvh.watertight().with_test(avx), &wt, &ray);
            }
            hits += usize::from(got.is_some());
        }
        assert!(hits > 50, "{hits} hits");
    }

    #[test]
    fn degenerate_triangles_are_left_out_and_never_hit() {
        let (mut p, mut t) = quad_mesh(3);
        p.extend([Vec3::new(0.2, 0.2, -1.0), Vec3::new(0.3, 0.3, -1.0), Vec3::new(0.4, 0.4, -1.0)]);
        t.push([9, 10, 11]);
        let bvh = Mbvh::build(&p, &t).unwrap();
        bvh.validate(&p, &t).unwrap();
        let ray = Ray::new(Vec3::new(0.25, 0.25, -2.0), Vec3::Z, 0.0, f32::INFINITY);
        assert_eq!(bvh.wald().intersect_counted(&ray, &mut NoCounters).unwrap().prim, 0);
    }

    #[test]
    fn bad_input_is_an_error_naming_it() {
        let (mut p, t) = quad_mesh(2);
        p[4].y = f32::NAN;
        assert!(matches!(Mbvh::build(&p, &t), Err(BuildError::NonFiniteVertex { index: 4, .. })));
        let (p, mut t) = quad_mesh(2);
        t[1][2] = 99;
        let e = Mbvh::build(&p, &t).unwrap_err().to_string();
        assert!(e.contains("triangle 1") && e.contains("99"), "{e}");
    }

    #[test]
    fn spatial_splits_can_be_turned_off_and_bad_settings_are_errors() {
        // Long slivers through a cloud of small triangles: their boxes overlap everywhere.
        let mut p = Vec::new();
        for i in 0..600 {
            let f = i as f32;
            let a = Vec3::new((f * 0.37).sin() * 4.0, (f * 0.73).cos() * 4.0, (f * 1.31).sin() * 4.0);
            let c = if i % 6 == 0 { -a } else { a + Vec3::new(0.1, 0.05, 0.02) };
            p.extend([a, c, c + Vec3::new(0.02, 0.03, 0.05)]);
        }
        let t: Vec<[u32; 3]> = (0..600).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let (on, off) = (Mbvh::build(&p, &t).unwrap(), Mbvh::build_with(&p, &t, SpatialSplits::OFF).unwrap());
        off.validate(&p, &t).unwrap();
        assert_eq!(off.stats().leaf_triangles, 600);
        assert!(on.stats().leaf_triangles > 630, "{:?}", on.stats());
        for i in 0..500 {
            let f = i as f32;
            let o = Vec3::new((f * 0.11).sin() * 6.0, (f * 0.29).cos() * 6.0, 7.0);
            let ray = Ray::new(o, -o + Vec3::new(0.3, -0.2, (f * 0.05).sin()), 0.0, f32::INFINITY);
            let hit = |b: &Mbvh| b.wald().intersect_counted(&ray, &mut NoCounters).map(|h| (h.t.to_bits(), h.prim));
            assert_eq!(hit(&on), hit(&off), "{ray:?}");
        }
        for (alpha, budget, field) in [
            (f64::NAN, 1.0, "alpha"),
            (-1.0, 1.0, "alpha"),
            (1e-3, f64::INFINITY, "budget"),
            (1e-3, f64::NAN, "budget"),
        ] {
            let e = Mbvh::build_with(&p, &t, SpatialSplits { alpha, budget }).unwrap_err();
            assert!(matches!(&e, BuildError::BadConfig(m) if m.contains(field)), "{e}");
        }
    }

    #[test]
    fn validate_catches_a_damaged_tree() {
        let (p, t) = quad_mesh(40);
        let bvh = Mbvh::build(&p, &t).unwrap();
        let mut shrunk = bvh.clone();
        shrunk.nodes[0].bounds[0][1][0] = -100.0;
        assert!(shrunk.validate(&p, &t).is_err());
        let mut lost = bvh.clone();
        let slot = lost.nodes[0].child.iter().position(|&c| c != node::EMPTY).unwrap();
        lost.nodes[0].child[slot] = node::EMPTY;
        assert!(lost.validate(&p, &t).is_err());

        let bvh8 = Mbvh8::build(&p, &t).unwrap();
        bvh8.validate(&p, &t).unwrap();
        let mut shrunk = bvh8.clone();
        shrunk.nodes[0].bounds[1][1][0] = -100.0;
        assert!(shrunk.validate(&p, &t).unwrap_err().contains("outside"));
        let mut twice = bvh8.clone();
        let used: Vec<usize> = (0..Node8::WIDTH).filter(|&i| twice.nodes[0].child[i] != node::EMPTY).collect();
        twice.nodes[0].child[used[0]] = twice.nodes[0].child[used[1]];
        assert!(twice.validate(&p, &t).is_err());
    }

    #[test]
    fn non_finite_rays_hit_nothing() {
        let (p, t) = quad_mesh(8);
        let bvh = Mbvh::build(&p, &t).unwrap();
        for ray in [
            Ray::new(Vec3::new(0.25, f32::NAN, -1.0), Vec3::Z, 0.0, f32::INFINITY),
            Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::new(0.0, f32::INFINITY, 1.0), 0.0, f32::INFINITY),
            Ray::new(Vec3::new(0.25, 0.25, -1.0), Vec3::Z, f32::NAN, f32::INFINITY),
        ] {
            assert!(bvh.wald().intersect_counted(&ray, &mut NoCounters).is_none());
            assert!(!bvh.watertight().occluded_counted(&ray, &mut NoCounters));
            let bvh8 = Mbvh8::build(&p, &t).unwrap();
            assert!(bvh8.wald().intersect_counted(&ray, &mut NoCounters).is_none());
            if let Some(avx) = Avx2::detect() {
                assert!(bvh8.wald().with_test(avx).intersect_counted(&ray, &mut NoCounters).is_none());
                assert!(!bvh8.watertight().with_test(avx).occluded_counted(&ray, &mut NoCounters));
            }
            let bvh16 = Mbvh16::build(&p, &t).unwrap();
            assert!(bvh16.wald().intersect_counted(&ray, &mut NoCounters).is_none());
            if let Some(avx) = Avx512::detect() {
                assert!(bvh16.wald().with_test(avx).intersect_counted(&ray, &mut NoCounters).is_none());
                assert!(!bvh16.watertight().with_test(avx).occluded_counted(&ray, &mut NoCounters));
            }
        }
    }
}
