//! The kd-tree: nodes, references and precomputed intersection records in contiguous arrays.

use glam::Vec3;

use crate::build::{self, BuildConfig, BuildError, Meter};
use crate::leaf::{GAP, LANES, LeafGroup, Wald4, Watertight4};
use crate::triangle::{Intersector, WaldTriangle, WatertightTriangle, is_degenerate};
use crate::{Aabb, KdNode};

/// A perfect-split SAH kd-tree over a triangle soup (thesis 3.2.1).
///
/// Memory layout: `nodes` (8 bytes each, root at 0, children adjacent), `prim_refs` (one
/// `u32` triangle index per leaf reference, each leaf's references contiguous and starting at
/// a multiple of 4, in node order, the gaps holding [`GAP`]), one precomputed intersection
/// record per triangle for the tree's [`Intersector`] (the packet, frustum, cone and
/// edge-width kernels read them through `prim_refs`), and the SIMD leaves: group `g` of
/// [`crate::leaf`] holds the records of references `4g .. 4g + 4` (what single rays read).
///
/// Invariant (checked when the tree is made, relied on by the single-ray kernel's unchecked
/// node reads): `nodes` is not empty and every inner node's children are in it.
#[derive(Clone, Debug)]
pub struct KdTree {
    pub(crate) nodes: Vec<KdNode>,
    pub(crate) prim_refs: Vec<u32>,
    /// Wald groups of [`crate::leaf`] (empty unless the tree is built for Wald's test).
    pub(crate) wald4: Vec<Wald4>,
    /// Watertight groups of [`crate::leaf`] (empty unless built for the watertight test).
    pub(crate) watertight4: Vec<Watertight4>,
    pub(crate) bounds: Aabb,
    pub(crate) intersector: Intersector,
    pub(crate) wald: Vec<WaldTriangle>,
    pub(crate) watertight: Vec<WatertightTriangle>,
    /// Triangle vertices, kept for validation, statistics and the oracle twin.
    pub(crate) tris: Vec<[Vec3; 3]>,
    pub(crate) config: BuildConfig,
    /// The most bytes the build held at once in its metered buffers (`None` for a tree made
    /// by [`KdTree::from_parts`]).
    pub(crate) build_peak_bytes: Option<u64>,
}

impl KdTree {
    /// Builds the tree over the triangles `triangles` (indices into `positions`).
    ///
    /// Degenerate (zero-area) triangles are kept in the numbering but left out of the tree:
    /// no ray can hit them. Non-finite positions and out-of-range indices are rejected with
    /// an error naming the vertex or triangle; nothing here panics on user input. With a
    /// [`BuildConfig::memory_budget`], a build whose first phase alone is estimated over it
    /// ([`build::first_phase_bytes`]) is refused before anything is allocated, and a build that
    /// would pass it stops; both with [`BuildError::OverBudget`].
    pub fn build(positions: &[Vec3], triangles: &[[u32; 3]], config: &BuildConfig) -> Result<KdTree, BuildError> {
        if let Some(index) = positions.iter().position(|p| !p.is_finite()) {
            return Err(BuildError::NonFiniteVertex { index, position: positions[index] });
        }
        if !(config.c_trav.is_finite() && config.c_trav >= 0.0) {
            return Err(BuildError::BadConfig(format!("c_trav = {} must be finite and >= 0", config.c_trav)));
        }
        if !(config.c_isect.is_finite() && config.c_isect > 0.0) {
            return Err(BuildError::BadConfig(format!("c_isect = {} must be finite and > 0", config.c_isect)));
        }
        if !(0.0..1.0).contains(&config.empty_bonus) {
            return Err(BuildError::BadConfig(format!("empty_bonus = {} must be in [0, 1)", config.empty_bonus)));
        }
        config.strategy.check()?;
        config.check_termination()?;
        if u32::try_from(triangles.len()).is_err() {
            return Err(BuildError::TooLarge(format!("{} triangles do not fit 32-bit ids", triangles.len())));
        }
        if let Some(budget) = config.memory_budget {
            let estimate = build::first_phase_bytes(positions, triangles, config.strategy);
            if estimate > budget {
                return Err(BuildError::OverBudget {
                    estimate,
                    budget,
                    stage: format!(
                        "estimate before the {} build: {} triangles' vertices, the root's events and their sort, or its items",
                        config.strategy.name(),
                        triangles.len()
                    ),
                });
            }
        }
        let meter = Meter::new(config.memory_budget);
        meter.take(36 * triangles.len() as u64, "the triangles' vertices")?;
        let mut tris = Vec::with_capacity(triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            let mut v = [Vec3::ZERO; 3];
            for (k, &i) in tri.iter().enumerate() {
                v[k] = *positions.get(i as usize).ok_or(BuildError::IndexOutOfRange {
                    triangle: t,
                    vertex: i,
                    vertices: positions.len(),
                })?;
            }
            tris.push(v);
        }
        Self::build_from_triangles(tris, config, &meter)
    }

    /// Builds the tree over a triangle soup given as vertex triples. A NaN or infinite
    /// coordinate is [`BuildError::NonFiniteVertex`] with index `3 * triangle + corner`.
    pub fn build_soup(tris: &[[Vec3; 3]], config: &BuildConfig) -> Result<KdTree, BuildError> {
        if let Some((t, v)) = tris.iter().enumerate().find(|(_, v)| !v.iter().all(|p| p.is_finite())) {
            let k = v.iter().position(|p| !p.is_finite()).unwrap_or(0);
            return Err(BuildError::NonFiniteVertex { index: 3 * t + k, position: v[k] });
        }
        // Vertex indices 3t, 3t + 1, 3t + 2 must fit u32: checked, not wrapped.
        if tris.len() > (u32::MAX as usize).div_ceil(3) {
            return Err(BuildError::TooLarge(format!("{} triangles' vertices do not fit 32-bit indices", tris.len())));
        }
        let positions: Vec<Vec3> = tris.iter().flatten().copied().collect();
        let indices: Vec<[u32; 3]> = (0..tris.len() as u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        Self::build(&positions, &indices, config)
    }

    fn build_from_triangles(tris: Vec<[Vec3; 3]>, config: &BuildConfig, meter: &Meter) -> Result<KdTree, BuildError> {
        let n_prims = tris.iter().filter(|t| !is_degenerate(t)).count();
        meter.take(4 * n_prims as u64, "the list of non-degenerate triangles")?;
        let prims: Vec<u32> = (0..tris.len() as u32).filter(|&t| !is_degenerate(&tris[t as usize])).collect();
        let bounds = prims.iter().fold(Aabb::EMPTY, |b, &t| {
            let [a, bb, c] = tris[t as usize];
            b.grow(a).grow(bb).grow(c)
        });
        let built = build::build_nodes(&tris, &prims, bounds, config, meter)?;
        drop(prims);
        meter.give(4 * n_prims as u64);
        let record = match config.intersector {
            Intersector::Wald => std::mem::size_of::<WaldTriangle>(),
            Intersector::Watertight => std::mem::size_of::<WatertightTriangle>(),
        };
        meter.take(record as u64 * tris.len() as u64, "the intersection records")?;
        let refs = built.prim_refs.len() as u64;
        let mut tree =
            KdTree::assemble(tris, built.nodes, built.prim_refs, bounds, config).map_err(BuildError::TooLarge)?;
        // The aligned references and the SIMD groups replace the builder's references.
        let group = match config.intersector {
            Intersector::Wald => std::mem::size_of::<Wald4>(),
            Intersector::Watertight => std::mem::size_of::<Watertight4>(),
        } as u64;
        let slots = tree.prim_refs.len() as u64;
        meter.take((4 * slots + group * slots / LANES as u64).saturating_sub(4 * refs), "the SIMD leaf groups")?;
        tree.build_peak_bytes = Some(meter.peak());
        Ok(tree)
    }

    /// A tree from node and reference arrays made elsewhere (another builder, a file), over
    /// the triangle soup `tris`, with the root box `bounds`.
    ///
    /// The arrays are checked structurally (indices in range, depth within the stack); use
    /// [`KdTree::validate`] for the full check that every triangle is reachable. A NaN or
    /// infinite vertex, a NaN in `bounds` or a NaN or infinite split plane is an error naming
    /// it (the empty box [`Aabb::EMPTY`], whose corners are infinite, is allowed).
    pub fn from_parts(
        tris: Vec<[Vec3; 3]>,
        nodes: Vec<KdNode>,
        prim_refs: Vec<u32>,
        bounds: Aabb,
        config: &BuildConfig,
    ) -> Result<KdTree, String> {
        if nodes.is_empty() {
            return Err("no nodes".into());
        }
        if let Some((t, v)) = tris.iter().enumerate().find(|(_, v)| !v.iter().all(|p| p.is_finite())) {
            return Err(format!("triangle {t} has a vertex that is not finite: {v:?}"));
        }
        if bounds.min.is_nan() || bounds.max.is_nan() {
            return Err(format!("the bounds {bounds:?} have a NaN corner"));
        }
        if let Some(i) = nodes.iter().position(|n| !n.is_leaf() && !n.split().is_finite()) {
            return Err(format!("node {i} has the split plane {}, which is not finite", nodes[i].split()));
        }
        // Every leaf, reachable or not (all are laid out again): references in range. Outside
        // the leaves' ranges the array may hold anything (the gaps of an aligned tree).
        for (i, n) in nodes.iter().enumerate().filter(|(_, n)| n.is_leaf()) {
            let refs = prim_refs.get(n.prim_range()).ok_or_else(|| {
                format!("leaf {i} references {:?}, past the end ({})", n.prim_range(), prim_refs.len())
            })?;
            if let Some(r) = refs.iter().find(|&&r| r as usize >= tris.len()) {
                return Err(format!("leaf {i} references triangle {r} of {}", tris.len()));
            }
        }
        // Depth-first walk with depths: children in range, depth within the stack.
        let mut todo = vec![(0usize, 0usize)];
        let mut seen = 0usize;
        while let Some((i, depth)) = todo.pop() {
            seen += 1;
            if seen > nodes.len() || depth > crate::MAX_DEPTH as usize {
                return Err(format!("node {i} is at depth {depth}: a cycle or a tree too deep"));
            }
            let n = nodes[i];
            if !n.is_leaf() {
                if n.left_child() + 1 >= nodes.len() {
                    return Err(format!("node {i} has child {} of {}", n.left_child(), nodes.len()));
                }
                todo.push((n.left_child(), depth + 1));
                todo.push((n.left_child() + 1, depth + 1));
            }
        }
        KdTree::assemble(tris, nodes, prim_refs, bounds, config)
    }

    /// The tree from its arrays, with the intersection records of `config.intersector`: the
    /// references are laid out again in node order, each non-empty leaf's starting at a
    /// multiple of 4 (so that its SIMD groups are `first / 4 ..`), and the groups are made.
    /// Laying out an already laid-out tree again changes nothing.
    ///
    /// Every tree passes through here, which checks the invariant the single-ray kernel reads
    /// nodes by without bounds checks: there is a root, and each inner node's two children
    /// are in the node array.
    fn assemble(
        tris: Vec<[Vec3; 3]>,
        mut nodes: Vec<KdNode>,
        prim_refs: Vec<u32>,
        bounds: Aabb,
        config: &BuildConfig,
    ) -> Result<KdTree, String> {
        if nodes.is_empty() {
            return Err("no nodes".into());
        }
        if let Some((i, n)) = nodes.iter().enumerate().find(|(_, n)| !n.is_leaf() && n.left_child() + 1 >= nodes.len())
        {
            return Err(format!(
                "node {i} has children {} and {} of {} nodes",
                n.left_child(),
                n.left_child() + 1,
                nodes.len()
            ));
        }
        let prim_refs = align_leaves(&mut nodes, &prim_refs)?;
        let (mut wald, mut watertight, mut wald4, mut watertight4) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        match config.intersector {
            Intersector::Wald => {
                wald = tris.iter().map(WaldTriangle::new).collect();
                wald4 = groups(&prim_refs, &wald);
            }
            Intersector::Watertight => {
                watertight = tris.iter().map(WatertightTriangle::new).collect();
                watertight4 = groups(&prim_refs, &watertight);
            }
        }
        Ok(KdTree {
            nodes,
            prim_refs,
            wald4,
            watertight4,
            bounds,
            intersector: config.intersector,
            wald,
            watertight,
            tris,
            config: config.clone(),
            build_peak_bytes: None,
        })
    }

    /// The nodes, root at index 0.
    pub fn nodes(&self) -> &[KdNode] {
        &self.nodes
    }

    /// The triangle references of a leaf node.
    pub fn leaf_prims(&self, leaf: KdNode) -> &[u32] {
        &self.prim_refs[leaf.prim_range()]
    }

    /// The whole triangle-reference array (leaves index into it; between leaves, padding to a
    /// multiple of 4 holds [`GAP`]).
    pub fn prim_refs(&self) -> &[u32] {
        &self.prim_refs
    }

    /// The Wald intersection records, one per triangle (empty unless the tree was built for
    /// [`Intersector::Wald`]).
    pub fn wald_records(&self) -> &[WaldTriangle] {
        &self.wald
    }

    /// The watertight intersection records, one per triangle (empty unless the tree was built
    /// for [`Intersector::Watertight`]).
    pub fn watertight_records(&self) -> &[WatertightTriangle] {
        &self.watertight
    }

    /// The SIMD leaf groups of a Wald tree ([`crate::leaf`]; empty for a watertight tree).
    pub fn wald_groups(&self) -> &[Wald4] {
        &self.wald4
    }

    /// The SIMD leaf groups of a watertight tree ([`crate::leaf`]; empty for a Wald tree).
    pub fn watertight_groups(&self) -> &[Watertight4] {
        &self.watertight4
    }

    /// The bounds of all non-degenerate triangles (the root's box).
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The intersection test this tree was built for.
    pub fn intersector(&self) -> Intersector {
        self.intersector
    }

    /// The configuration the tree was built with.
    pub fn config(&self) -> &BuildConfig {
        &self.config
    }

    /// The most bytes the build held at once in its large buffers (the triangles, event
    /// lists, scratch, subtree arrays, final arrays and records; what
    /// [`BuildConfig::memory_budget`] limits). `None` for a tree from [`KdTree::from_parts`].
    pub fn build_peak_bytes(&self) -> Option<u64> {
        self.build_peak_bytes
    }

    /// Number of triangles given to the build (including degenerate ones).
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// The vertices of triangle `prim`.
    pub fn triangle(&self, prim: u32) -> [Vec3; 3] {
        self.tris[prim as usize]
    }

    /// The whole tree as bytes (nodes then references), for determinism checks.
    pub fn layout_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(8 * self.nodes.len() + 4 * self.prim_refs.len());
        for n in &self.nodes {
            let (a, b) = n.raw();
            out.extend_from_slice(&a.to_le_bytes());
            out.extend_from_slice(&b.to_le_bytes());
        }
        for r in &self.prim_refs {
            out.extend_from_slice(&r.to_le_bytes());
        }
        out
    }
}

/// The references of `nodes`' leaves laid out in node order, each non-empty leaf's starting
/// at a multiple of [`LANES`] (gaps hold [`GAP`]); the leaves are rewritten to point there.
/// A layout whose first references do not fit a node's 32 bits is an error (the caller has
/// checked every leaf's range).
fn align_leaves(nodes: &mut [KdNode], prim_refs: &[u32]) -> Result<Vec<u32>, String> {
    let slots: usize = nodes.iter().filter(|n| n.is_leaf()).map(|n| n.prim_count().next_multiple_of(LANES)).sum();
    let mut out = Vec::with_capacity(slots);
    for node in nodes.iter_mut().filter(|n| n.is_leaf()) {
        let first = u32::try_from(out.len())
            .map_err(|_| format!("{} references with leaf padding do not fit 32-bit indices", out.len()))?;
        out.extend_from_slice(&prim_refs[node.prim_range()]);
        out.resize(out.len().next_multiple_of(LANES), GAP);
        *node = KdNode::leaf(first, node.prim_count() as u32);
    }
    Ok(out)
}

/// The SIMD groups of an aligned reference array: group `g` holds the records of references
/// `4g .. 4g + 4` (padding lanes for the gaps).
fn groups<G: LeafGroup>(prim_refs: &[u32], records: &[G::Record]) -> Vec<G>
where
    G::Record: Copy,
{
    prim_refs
        .chunks(LANES)
        .map(|refs| {
            let lanes: Vec<G::Record> = refs.iter().take_while(|&&r| r != GAP).map(|&r| records[r as usize]).collect();
            G::new(&lanes)
        })
        .collect()
}
