//! The perfect-split SAH build (thesis 2.2.1, 3.2.1) in O(N log N) (Wald & Havran 2006).
//!
//! - Cost model (thesis 2.2.1): a split of a node with box `V` into `V_l`, `V_r` costs
//!   `C_trav + C_isect * (G(N_l) SA(V_l) + G(N_r) SA(V_r)) / SA(V)`, times `1 - empty_bonus`
//!   when a side holds no triangle; a leaf costs `C_isect * G(N)`, where `G(n) = ceil(n / W)`
//!   counts the SIMD groups of [`BuildConfig::leaf_width`] `W` (`n` itself for the default
//!   `W = 1`), the same in every search ([`sah`], [`small`], [`binned`]) and in the
//!   leaf-or-split rule (`Ctx::accept`). A node becomes a leaf when no plane is cheaper, when
//!   it is empty or at the depth limit; with [`BuildConfig::max_bad_refines`] a costlier plane
//!   may still split it (Mitsuba's bad refines), and [`BuildConfig::collapse`] retracts the
//!   subtrees that cost more than their leaf after the build ([`collapse`]).
//! - Perfect splits (thesis 3.2.1): the candidate planes of a triangle are the faces of the
//!   box of the triangle clipped to the node ([`clip`]).
//! - O(N log N) (Wald & Havran 2006, section 4): the candidate events of all triangles are
//!   sorted once at the root ([`events`]); each node finds its plane by a linear sweep
//!   ([`sah`]) and hands its children their event lists still sorted ([`split`]); only the
//!   few straddling triangles are clipped again and their new events sorted and merged.
//! - Small nodes (at most [`small::SMALL`] triangles) drop the event lists and keep the
//!   triangles' clipped boxes, sorting their ends per axis and sweeping them ([`small`]);
//!   they choose the same planes, so the tree is the same.
//! - Parallel (rayon) over subtrees above [`PAR_MIN_TRIS`] triangles, sequential with reused
//!   buffers below. Which nodes run in parallel depends only on their triangle counts, and
//!   the subtrees are assembled in a fixed depth-first order, so the tree is bit-identical
//!   whatever the number of threads.
//! - Binned top ([`BuildStrategy::Binned`], the default): nodes with at least `min_tris`
//!   triangles choose their plane by min-max binning ([`binned`]: Shevtsov et al. 2007),
//!   parallel over the triangles, and still clip their straddling triangles; their subtrees
//!   below the size get their own sorted events and the sweep above. [`BuildStrategy::Exact`]
//!   sweeps from the root.
//! - Memory ([`BuildConfig::memory_budget`]): a [`Meter`] counts the bytes of the build's
//!   large buffers (the triangles, event lists and their sort, per-thread scratch, subtree
//!   arrays, the final arrays and the intersection records) and stops the build with
//!   [`BuildError::OverBudget`] before a buffer would take it over the budget. The first
//!   phase's needs are computed before anything is allocated ([`first_phase_bytes`]).

mod binned;
mod clip;
mod collapse;
mod events;
mod sah;
mod small;
mod split;

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;

use crate::node::MAX_NODE_FIELD;
use crate::{Aabb, KdNode, triangle::Intersector};

pub use clip::split_reference;
pub(crate) use clip::{Polygon, clip_triangle};
use events::{Lists, PLANAR, PRIM_MASK, START, ev_prim, ev_type, push_box_events, radix_sort_events};
pub use sah::surface_area64;
use sah::{Costs, Split, find_split};
use small::{Item, SMALL, items_from_lists, small_partition, small_split};
use split::{SplitScratch, child_boxes, split_lists};

/// Build parameters: the SAH terms (by default [`CostModel::WaldHavran`], chosen by
/// measurement: `docs/results/sah-terms.md`; [`BuildConfig::thesis`] for the thesis's).
#[derive(Clone, Debug, PartialEq)]
pub struct BuildConfig {
    /// Cost of one traversal step, `C_trav`.
    pub c_trav: f32,
    /// Cost of one ray-triangle test, `C_isect` (thesis: 5 x `C_trav`; default 20/15).
    pub c_isect: f32,
    /// Fraction of the cost taken off a split that leaves one side empty (0 = off; default
    /// 0.2).
    pub empty_bonus: f32,
    /// Maximum depth; `None` means `8 + log2 N` (see [`BuildConfig::depth_limit`]). Capped at [`crate::MAX_DEPTH`].
    pub max_depth: Option<u32>,
    /// The ray-triangle test the tree's traversal uses.
    pub intersector: Intersector,
    /// The most bytes the build may hold in its large buffers, tree included (`None`: no
    /// limit). Checked before the build ([`first_phase_bytes`]) and during it (see the module
    /// docs); passing it stops the build with [`BuildError::OverBudget`]. The scene's own
    /// mesh is not counted, nor small buffers (a sequential subtree's reused event lists, a
    /// few MiB per thread).
    pub memory_budget: Option<u64>,
    /// How the planes of the large nodes are found: the exact event sweep everywhere, or
    /// min-max binning above a size ([`BuildStrategy`]).
    pub strategy: BuildStrategy,
    /// The leaf's SIMD group width `W` (1 to [`BuildConfig::MAX_LEAF_WIDTH`]): a leaf of `n`
    /// triangles costs `C_isect * ceil(n / W)`, the triangle tests of one ray against its
    /// groups of `W` (`kdtree::leaf`'s `Wald4`: `W = 4`), and every split is priced the same
    /// way, `C_trav + C_isect * (ceil(n_l / W) SA_l + ceil(n_r / W) SA_r) / SA`. 1 is the
    /// thesis's per-triangle cost (2.2.1).
    pub leaf_width: u32,
    /// Mitsuba's bad refines (Wald & Havran 2006, section 4.4's termination; Mitsuba's
    /// `gkdtree` `maxBadRefines`): a split that costs at least the leaf is still made, and
    /// counted along the path, until this many were made above the node; a node of fewer
    /// than [`BAD_REFINE_FEW`] triangles whose best split costs over 4 leaves is a leaf
    /// anyway. 0: off (a node splits only when a plane is cheaper than its leaf).
    pub max_bad_refines: u32,
    /// Retract (Mitsuba's `gkdtree` retraction of bad splits): after the build, every subtree
    /// whose SAH cost (with the leaf cost above and the empty bonus) is at least the cost of
    /// one leaf of its distinct triangles becomes that leaf, bottom up ([`collapse`]).
    pub collapse: bool,
}

/// Nodes with fewer triangles than this are leaves when their best split costs more than 4
/// times their leaf, whatever [`BuildConfig::max_bad_refines`] allows (Mitsuba's rule).
pub const BAD_REFINE_FEW: usize = 16;

/// How the builder finds the planes of large nodes. Both make perfect-split trees (every
/// straddling triangle clipped to the children, thesis 3.2.1); they differ in where the
/// planes of the top nodes may lie.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BuildStrategy {
    /// The exact SAH event sweep (Wald & Havran 2006) at every node: each plane is the
    /// cheapest among all the faces of the triangles' clipped boxes.
    Exact,
    /// Min-max binning (Shevtsov et al. 2007, section 3) for the nodes with at least
    /// `min_tris` triangles, `bins` bins per axis, the plane on a bin boundary; the exact
    /// sweep below, its events made for each subtree only (`binned`).
    Binned {
        /// Bins per axis, 2 to [`BuildStrategy::MAX_BINS`].
        bins: u32,
        /// Nodes with at least this many triangles are binned (at least 1).
        min_tris: u32,
    },
}

impl Default for BuildStrategy {
    /// [`BuildStrategy::BINNED`]: on Sponza, the kitchen and the atrium its trees have SAH
    /// costs from 5% below to 0.2% above the exact build's, fewer traversal steps per ray
    /// and Mrays/s within the measurement's spread or above, and it takes 7-15% less CPU
    /// time (`docs/results/build-and-large-scenes.md`).
    fn default() -> Self {
        BuildStrategy::BINNED
    }
}

impl BuildStrategy {
    /// The most bins per axis.
    pub const MAX_BINS: u32 = 1 << 16;

    /// [`BuildStrategy::Binned`] with the measured default bins and size threshold
    /// (`docs/results/build-and-large-scenes.md`).
    pub const BINNED: BuildStrategy = BuildStrategy::Binned { bins: 256, min_tris: 1024 };

    /// The name used on the command line and in reports: `exact` or `binned`.
    pub fn name(self) -> &'static str {
        match self {
            BuildStrategy::Exact => "exact",
            BuildStrategy::Binned { .. } => "binned",
        }
    }

    /// An error naming the field when the parameters are out of range.
    pub fn check(self) -> Result<(), BuildError> {
        if let BuildStrategy::Binned { bins, min_tris } = self {
            if !(2..=Self::MAX_BINS).contains(&bins) {
                return Err(BuildError::BadConfig(format!("bins = {bins} must be in 2..={}", Self::MAX_BINS)));
            }
            if min_tris == 0 {
                return Err(BuildError::BadConfig("min_tris = 0 must be at least 1".into()));
            }
        }
        Ok(())
    }
}

impl Default for BuildConfig {
    fn default() -> Self {
        CostModel::default().config()
    }
}

/// A named SAH cost model (thesis 2.2.1: `C_trav` per traversal step, `C_isect` per
/// triangle test, and the empty-space bonus).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CostModel {
    /// The thesis's terms (3.2.1): `C_trav = 1`, `C_isect = 5`, no empty-space bonus. Its
    /// trees are the deepest: 3.7-6.5 references per triangle and 2-4 triangles per leaf.
    Thesis,
    /// Wald & Havran 2006 (section 4): `C_trav = 15`, `C_isect = 20` (kept here as the
    /// ratio `1 : 4/3`, so SAH costs stay in traversal steps) and `lambda = 0.8` on a split
    /// with an empty side (an empty bonus of 0.2). The default: `rttest sah-sweep` measures
    /// it at 1.0-1.5x the thesis's single-ray and 1.15-1.65x its MFT speed with 30% fewer
    /// references and 25% shorter builds (`docs/results/sah-terms.md`). Its leaves are priced
    /// per triangle ([`BuildConfig::leaf_width`] 1), without bad refines or collapse: the
    /// SIMD-group leaf cost (`leaf_width` 4) wins 2-5% on Sponza and the atrium but loses
    /// 5-9% on the kitchen, and bad refines with their collapse end within 3% (same page).
    #[default]
    WaldHavran,
}

impl CostModel {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            CostModel::Thesis => "thesis",
            CostModel::WaldHavran => "wald-havran",
        }
    }

    /// The default build configuration with this model's terms.
    pub fn config(self) -> BuildConfig {
        let (c_trav, c_isect, empty_bonus) = match self {
            CostModel::Thesis => (1.0, 5.0, 0.0),
            CostModel::WaldHavran => (1.0, 20.0 / 15.0, 0.2),
        };
        BuildConfig {
            c_trav,
            c_isect,
            empty_bonus,
            max_depth: None,
            intersector: Intersector::Wald,
            memory_budget: None,
            strategy: BuildStrategy::default(),
            leaf_width: 1,
            max_bad_refines: 0,
            collapse: false,
        }
    }
}

impl BuildConfig {
    /// The widest leaf group [`BuildConfig::leaf_width`] may name.
    pub const MAX_LEAF_WIDTH: u32 = 64;

    /// The most bad refines [`BuildConfig::max_bad_refines`] may allow (each may double a
    /// subtree's references).
    pub const MAX_BAD_REFINES: u32 = 16;

    /// An error naming the field when the leaf and termination terms are out of range
    /// (`leaf_width` in 1..=[`Self::MAX_LEAF_WIDTH`], `max_bad_refines` at most
    /// [`Self::MAX_BAD_REFINES`]).
    pub fn check_termination(&self) -> Result<(), BuildError> {
        if !(1..=Self::MAX_LEAF_WIDTH).contains(&self.leaf_width) {
            return Err(BuildError::BadConfig(format!(
                "leaf_width = {} must be in 1..={}",
                self.leaf_width,
                Self::MAX_LEAF_WIDTH
            )));
        }
        if self.max_bad_refines > Self::MAX_BAD_REFINES {
            return Err(BuildError::BadConfig(format!(
                "max_bad_refines = {} must be at most {}",
                self.max_bad_refines,
                Self::MAX_BAD_REFINES
            )));
        }
        Ok(())
    }

    /// The thesis's terms ([`CostModel::Thesis`]), for its tables.
    pub fn thesis() -> BuildConfig {
        CostModel::Thesis.config()
    }

    /// The maximum depth for `n` triangles: `max_depth`, or by default `8 + log2 N`.
    ///
    /// pbrt's `8 + 1.3 log2 N` was measured here and found too deep for perfect splits with
    /// `C_isect = 5 C_trav`. On Sponza (66k triangles), `rttest build --max-depth 29` (pbrt's
    /// depth) against 24 (ours) gives 856k against 503k nodes, 7.65 against 5.27 references per
    /// triangle and 136.76 against 137.22 SAH cost (0.3%), builds 30-50% slower, and
    /// `rttest render --counters` shows the same 51.3 against 51.2 traversal steps and 2.99
    /// against 3.04 intersection tests per primary ray; the atrium behaves the same way.
    pub fn depth_limit(&self, n: usize) -> u32 {
        let d = self.max_depth.unwrap_or_else(|| (8.0 + (n.max(1) as f64).log2()).round() as u32);
        d.min(crate::MAX_DEPTH)
    }
}

/// Why a build was refused. Builds never panic on user input.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BuildError {
    /// A vertex position has a NaN or infinite component.
    #[error("vertex {index} is not finite: {position}")]
    NonFiniteVertex {
        /// Index into the positions.
        index: usize,
        /// The position.
        position: Vec3,
    },
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} uses vertex {vertex} but there are {vertices} vertices")]
    IndexOutOfRange {
        /// The triangle.
        triangle: usize,
        /// The vertex index it uses.
        vertex: u32,
        /// The number of vertices.
        vertices: usize,
    },
    /// The tree would need more nodes, references or triangles than its 32-bit (30-bit for
    /// node fields) indices can address.
    #[error("the tree is too large for its index widths: {0}")]
    TooLarge(String),
    /// A configuration value is out of range.
    #[error("bad build configuration: {0}")]
    BadConfig(String),
    /// The build would pass [`BuildConfig::memory_budget`]: refused before it started (the
    /// estimate of its first phase is over the budget) or stopped during it.
    #[error("the build would need {} ({stage}), over the memory budget of {}", human_bytes(*estimate), human_bytes(*budget))]
    OverBudget {
        /// Bytes the build would hold: the estimate, or what it holds plus the next buffer.
        estimate: u64,
        /// The budget.
        budget: u64,
        /// Where: the estimate before the build, or the buffer that would pass the budget.
        stage: String,
    },
}

/// `bytes` with a binary unit and the exact count: `1.5 GiB (1610612736 bytes)`.
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 4] = ["KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = "bytes";
    for u in UNITS {
        if value < 1024.0 {
            break;
        }
        value /= 1024.0;
        unit = u;
    }
    if unit == "bytes" { format!("{bytes} bytes") } else { format!("{value:.1} {unit} ({bytes} bytes)") }
}

/// The bytes the build of triangles `triangles` (indices into `positions`) with `strategy`
/// holds in its first phase, before any node is split: the triangles' vertices (36 bytes
/// each, kept by the tree), the list of non-degenerate triangles (4 each), and then
/// - exact (or binned with fewer non-degenerate triangles than `min_tris`): the root's event
///   lists (48 per non-degenerate triangle: two events of 8 bytes per axis reserved) and the
///   radix sort's second buffer (8 per event: a triangle flat on an axis has one event
///   there, else two);
/// - binned: the root's items (a triangle and its box, 28 bytes per non-degenerate
///   triangle).
///
/// This is exactly what the build's meter holds when the root's events are sorted (the
/// root's items made), and a lower bound of the build's peak: on the built-in scenes the
/// exact build's peak (`build_peak_bytes` of `rttest build`) is 1.3 to 2 times this. A build
/// whose first phase is over [`BuildConfig::memory_budget`] is refused with this figure
/// before anything is allocated. One pass over the triangles, no allocation; `u64`
/// arithmetic, so no count overflows (an index out of range is skipped here and reported by
/// the build).
pub fn first_phase_bytes(positions: &[Vec3], triangles: &[[u32; 3]], strategy: BuildStrategy) -> u64 {
    let (mut in_tree, mut events) = (0u64, 0u64);
    for tri in triangles {
        let [Some(a), Some(b), Some(c)] = tri.map(|i| positions.get(i as usize).copied()) else { continue };
        let v = [a, b, c];
        if crate::triangle::is_degenerate(&v) {
            continue;
        }
        in_tree += 1;
        let (lo, hi) = (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]));
        events += (0..3).map(|k| if lo[k] == hi[k] { 1 } else { 2 }).sum::<u64>();
    }
    let root = match strategy {
        BuildStrategy::Binned { min_tris, .. } if in_tree >= u64::from(min_tris) => binned::ITEM_BYTES * in_tree,
        _ => 48 * in_tree + 8 * events,
    };
    36 * triangles.len() as u64 + 4 * in_tree + root
}

/// Counts the bytes of the build's large buffers against the budget (see the module docs).
/// Shared by the build's threads; the counts are `u64` with saturating arithmetic.
#[derive(Debug)]
pub(crate) struct Meter {
    budget: Option<u64>,
    used: AtomicU64,
    peak: AtomicU64,
}

impl Meter {
    /// A meter with nothing taken.
    pub fn new(budget: Option<u64>) -> Meter {
        Meter { budget, used: AtomicU64::new(0), peak: AtomicU64::new(0) }
    }

    /// Takes `bytes` for the buffer `what`, before it is allocated; an error (and nothing
    /// taken) when that would pass the budget.
    pub fn take(&self, bytes: u64, what: &str) -> Result<(), BuildError> {
        let before = self.used.fetch_add(bytes, Ordering::Relaxed);
        let now = before.saturating_add(bytes);
        if let Some(budget) = self.budget
            && now > budget
        {
            self.used.fetch_sub(bytes, Ordering::Relaxed);
            return Err(BuildError::OverBudget {
                estimate: now,
                budget,
                stage: format!("{} in use, then {} for {what}", human_bytes(before), human_bytes(bytes)),
            });
        }
        self.peak.fetch_max(now, Ordering::Relaxed);
        Ok(())
    }

    /// Gives back `bytes` taken earlier (a buffer freed).
    pub fn give(&self, bytes: u64) {
        self.used.fetch_sub(bytes, Ordering::Relaxed);
    }

    /// The most bytes taken at once.
    pub fn peak(&self) -> u64 {
        self.peak.load(Ordering::Relaxed)
    }
}

/// What the builder hands to [`crate::KdTree`]: the node array (root at 0) and the
/// triangle-reference array the leaves point into.
pub(crate) struct BuiltNodes {
    /// Nodes, root first, children adjacent.
    pub nodes: Vec<KdNode>,
    /// Leaf triangle references (indices into the triangle array).
    pub prim_refs: Vec<u32>,
}

/// Nodes with at least this many triangles build their two subtrees with `rayon::join`;
/// smaller subtrees are built sequentially. Fixed, so the tree does not depend on threads.
pub const PAR_MIN_TRIS: usize = 1024;

/// `i` as a node child index, or [`BuildError::TooLarge`] if it (or its sibling `i + 1`)
/// does not fit the node's 30-bit field ([`MAX_NODE_FIELD`]).
pub(crate) fn node_index(i: usize) -> Result<u32, BuildError> {
    match u32::try_from(i) {
        Ok(v) if v < MAX_NODE_FIELD => Ok(v),
        _ => Err(BuildError::TooLarge(format!("node index {i} exceeds {MAX_NODE_FIELD}"))),
    }
}

/// A leaf's `(first, count)` checked against the reference (`u32`) and count (30-bit) widths.
pub(crate) fn leaf_fields(first: usize, count: usize) -> Result<(u32, u32), BuildError> {
    let end = first.checked_add(count);
    match (u32::try_from(first), u32::try_from(count), end.map(u32::try_from)) {
        (Ok(f), Ok(c), Some(Ok(_))) if c <= MAX_NODE_FIELD => Ok((f, c)),
        _ => Err(BuildError::TooLarge(format!("leaf references {first}..+{count} exceed the index widths"))),
    }
}

fn inner_node(axis: usize, pos: f32, left: usize) -> Result<KdNode, BuildError> {
    Ok(KdNode::inner(axis as u32, pos, node_index(left)?))
}

fn leaf_node(first: usize, count: usize) -> Result<KdNode, BuildError> {
    let (f, c) = leaf_fields(first, count)?;
    Ok(KdNode::leaf(f, c))
}

/// Reusable per-task buffers: the per-triangle classification array (indexed by triangle,
/// so as large as the input) and the split step's buffers and per-depth event lists. Pooled,
/// so a build allocates about one per thread rather than one per subtree. Their contents
/// never carry over: every entry is written before it is read.
#[derive(Default)]
struct Scratch {
    class: Vec<u8>,
    split: SplitScratch,
    levels: Vec<[Lists; 2]>,
    /// Triangle to item index of a small node (indexed by triangle, like `class`).
    slot: Vec<u32>,
    /// The items of the small nodes being built, a stack.
    items: Vec<Item>,
    /// Scratch items: a small node's own while it is split, and its left child's.
    tmp: [Vec<Item>; 2],
}

/// Shared build state.
struct Ctx<'a> {
    tris: &'a [[Vec3; 3]],
    costs: Costs,
    depth_limit: u32,
    max_bad_refines: u32,
    pool: Mutex<Vec<Scratch>>,
    meter: &'a Meter,
}

impl Ctx<'_> {
    /// A scratch from the pool, or a new one (its per-triangle arrays metered).
    fn take(&self) -> Result<Scratch, BuildError> {
        let mut s = self.pool.lock().unwrap_or_else(|e| e.into_inner()).pop().unwrap_or_default();
        if s.class.len() < self.tris.len() {
            self.meter.take(5 * self.tris.len() as u64, "a thread's per-triangle scratch")?;
            s.class = vec![0; self.tris.len()];
            s.slot = vec![0; self.tris.len()];
        }
        Ok(s)
    }

    /// Returns a scratch to the pool.
    fn give(&self, s: Scratch) {
        self.pool.lock().unwrap_or_else(|e| e.into_inner()).push(s);
    }

    /// The split of a node and the bad refines on its children's path, or `None` for a leaf
    /// (empty, too deep, or no plane accepted by [`Ctx::accept`]). `par`: sweep the axes in
    /// parallel.
    fn decide(&self, lists: &Lists, n: usize, b: &Aabb, at: At, par: bool) -> Option<(Split, At)> {
        self.accept(n, at, |limit| find_split(lists.axes(), n, b, &self.costs, par, limit))
    }

    /// The leaf-or-split rule of every node (thesis 2.2.1 with the SIMD leaf cost of
    /// [`Costs::leaf`]): a node with triangles above the depth limit splits at the plane
    /// `search(limit)` finds (the cheapest, or `None` or one costing at least `limit` when none
    /// is cheaper than `limit`) when it costs less than the node's leaf; with bad refines left
    /// on its path ([`BuildConfig::max_bad_refines`]) also when it costs less than `limit`,
    /// 4 leaves for a node of fewer than [`BAD_REFINE_FEW`] triangles and unbounded above,
    /// and that split is counted as a bad refine on its children's path.
    fn accept(&self, n: usize, at: At, search: impl FnOnce(f64) -> Option<Split>) -> Option<(Split, At)> {
        if n == 0 || at.depth >= self.depth_limit {
            return None;
        }
        let leaf = self.costs.leaf(n);
        let limit = if at.bad >= self.max_bad_refines {
            leaf
        } else if n < BAD_REFINE_FEW {
            4.0 * leaf
        } else {
            f64::INFINITY
        };
        let s = search(limit)?;
        let next = At { depth: at.depth + 1, bad: at.bad };
        if s.cost < leaf {
            Some((s, next))
        } else if s.cost < limit {
            Some((s, At { bad: at.bad + 1, ..next }))
        } else {
            None
        }
    }
}

/// Where a node is: its depth and the bad refines made on its path from the root
/// ([`BuildConfig::max_bad_refines`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct At {
    /// Depth, the root at 0.
    pub depth: u32,
    /// Splits costlier than their node's leaf above this node.
    pub bad: u32,
}

/// Appends a leaf's triangles (ascending) to `refs` and returns its node.
fn make_leaf(lists: &Lists, refs: &mut Vec<u32>) -> Result<KdNode, BuildError> {
    let first = refs.len();
    refs.extend(lists.axis(0).iter().filter(|&&e| matches!(ev_type(e), START | PLANAR)).map(|&e| ev_prim(e)));
    refs[first..].sort_unstable();
    leaf_node(first, refs.len() - first)
}

/// A subtree built by one task: nodes in the final layout relative to the chunk (root at 0,
/// children adjacent) and its references relative to the chunk.
struct Chunk {
    nodes: Vec<KdNode>,
    refs: Vec<u32>,
}

/// The result of the parallel top of the tree: inner nodes over sequentially built chunks.
enum Sub {
    Chunk(Chunk),
    Inner { axis: usize, pos: f32, kids: Box<(Sub, Sub)> },
}

/// Sequential builder of one subtree: event lists per depth (two slots, left and right
/// child), reused down the recursion so deep nodes allocate nothing.
struct Seq<'c, 'a> {
    ctx: &'c Ctx<'a>,
    scratch: Scratch,
    nodes: Vec<KdNode>,
    refs: Vec<u32>,
}

impl Seq<'_, '_> {
    fn node(&mut self, d: usize, side: usize, n: usize, b: Aabb, at: At, idx: usize) -> Result<(), BuildError> {
        if n <= SMALL {
            let Scratch { slot, items, levels, .. } = &mut self.scratch;
            items.clear();
            items_from_lists(&levels[d][side], n, slot, items);
            return self.small(0, n, b, at, idx);
        }
        let Scratch { class, split, levels, .. } = &mut self.scratch;
        let Some((s, kid)) = self.ctx.decide(&levels[d][side], n, &b, at, false) else {
            self.nodes[idx] = make_leaf(&levels[d][side], &mut self.refs)?;
            return Ok(());
        };
        if levels.len() < d + 2 {
            levels.push(Default::default());
        }
        let (cur, next) = levels.split_at_mut(d + 1);
        let [l, r] = &mut next[0];
        // Sequential nodes reuse their scratch's buffers: small, not metered.
        let (nl, nr) = split_lists(self.ctx.tris, &cur[d][side], &b, &s, class, split, l, r, false, &mut |_| Ok(()))?;
        let c = self.nodes.len();
        self.nodes[idx] = inner_node(s.axis, s.pos, c)?;
        self.nodes.extend([KdNode::leaf(0, 0); 2]);
        let (bl, br) = child_boxes(&b, &s);
        self.node(d + 1, 0, nl, bl, kid, c)?;
        self.node(d + 1, 1, nr, br, kid, c + 1)
    }
}

impl Seq<'_, '_> {
    /// Builds the subtree of a small node whose `n` items are the top of the item stack, from
    /// `start`.
    fn small(&mut self, start: usize, n: usize, b: Aabb, at: At, idx: usize) -> Result<(), BuildError> {
        let Scratch { split, items, tmp: [own, left], .. } = &mut self.scratch;
        let ctx = self.ctx;
        debug_assert_eq!(items.len(), start + n);
        let Some((s, next)) = ctx.accept(n, at, |limit| small_split(&items[start..], &b, &ctx.costs, limit)) else {
            let first = self.refs.len();
            self.refs.extend(items[start..].iter().map(|it| it.prim));
            self.refs[first..].sort_unstable();
            items.truncate(start);
            self.nodes[idx] = leaf_node(first, n)?;
            return Ok(());
        };
        own.clear();
        own.extend_from_slice(&items[start..]);
        items.truncate(start);
        let (nl, nr) = small_partition(ctx.tris, own, &b, &s, &mut split.polys, left, items);
        let c = self.nodes.len();
        self.nodes[idx] = inner_node(s.axis, s.pos, c)?;
        self.nodes.extend([KdNode::leaf(0, 0); 2]);
        let (bl, br) = child_boxes(&b, &s);
        // The right child's items lie below the left's: the left subtree is built first.
        self.small(start + nr, nl, bl, next, c)?;
        self.scratch.items.truncate(start + nr);
        self.small(start, nr, br, next, c + 1)
    }
}

/// Builds the subtree of a node with `n` triangles whose sorted events are `lists` (their
/// bytes taken from the meter, and given back here when they are freed).
fn build_par(ctx: &Ctx, lists: Lists, n: usize, b: Aabb, at: At) -> Result<Sub, BuildError> {
    let list_bytes = lists.heap_bytes();
    if n < PAR_MIN_TRIS {
        let mut scratch = match ctx.take() {
            Ok(s) => s,
            Err(e) => {
                ctx.meter.give(list_bytes);
                return Err(e);
            }
        };
        if scratch.levels.is_empty() {
            scratch.levels.push(Default::default());
        }
        scratch.levels[0][0] = lists;
        let mut seq = Seq { ctx, scratch, nodes: vec![KdNode::leaf(0, 0)], refs: Vec::new() };
        let done = seq.node(0, 0, n, b, at, 0);
        // The lists are freed now rather than kept in the pooled scratch.
        seq.scratch.levels[0][0] = Lists::default();
        ctx.meter.give(list_bytes);
        ctx.give(seq.scratch);
        done?;
        let chunk = Chunk { nodes: seq.nodes, refs: seq.refs };
        ctx.meter.take(chunk.heap_bytes(), "a subtree's nodes and references")?;
        return Ok(Sub::Chunk(chunk));
    }
    let Some((s, next)) = ctx.decide(&lists, n, &b, at, true) else {
        let mut refs = Vec::with_capacity(n);
        let leaf = make_leaf(&lists, &mut refs)?;
        drop(lists);
        ctx.meter.give(list_bytes);
        let chunk = Chunk { nodes: vec![leaf], refs };
        ctx.meter.take(chunk.heap_bytes(), "a leaf's references")?;
        return Ok(Sub::Chunk(chunk));
    };
    // The children's lists are taken from the meter by `split_lists` before they grow (the
    // parent's events plus the straddlers' new ones), and settled to their capacity after.
    let (mut left, mut right) = (Lists::default(), Lists::default());
    let mut reserved = 0u64;
    let split = match ctx.take() {
        Ok(mut scratch) => {
            let mut reserve = |bytes: u64| {
                ctx.meter.take(bytes, "a node's children's event lists")?;
                reserved = bytes;
                Ok(())
            };
            let r = split_lists(
                ctx.tris,
                &lists,
                &b,
                &s,
                &mut scratch.class,
                &mut scratch.split,
                &mut left,
                &mut right,
                true,
                &mut reserve,
            );
            ctx.give(scratch);
            r
        }
        Err(e) => Err(e),
    };
    drop(lists);
    ctx.meter.give(list_bytes);
    let (nl, nr) = match split {
        Ok(counts) => counts,
        Err(e) => {
            ctx.meter.give(reserved);
            return Err(e);
        }
    };
    let children = left.heap_bytes() + right.heap_bytes();
    ctx.meter.give(reserved);
    ctx.meter.take(children, "a node's children's event lists")?;
    let (bl, br) = child_boxes(&b, &s);
    let (l, r) = rayon::join(|| build_par(ctx, left, nl, bl, next), || build_par(ctx, right, nr, br, next));
    Ok(Sub::Inner { axis: s.axis, pos: s.pos, kids: Box::new((l?, r?)) })
}

impl Chunk {
    /// Bytes of its arrays (their capacity), for the meter.
    fn heap_bytes(&self) -> u64 {
        8 * self.nodes.capacity() as u64 + 4 * self.refs.capacity() as u64
    }
}

impl Sub {
    /// Bytes of the chunks of the subtree, as taken from the meter.
    fn heap_bytes(&self) -> u64 {
        match self {
            Sub::Chunk(c) => c.heap_bytes(),
            Sub::Inner { kids, .. } => kids.0.heap_bytes() + kids.1.heap_bytes(),
        }
    }

    /// Node and reference counts of the subtree.
    fn size(&self) -> (usize, usize) {
        match self {
            Sub::Chunk(c) => (c.nodes.len(), c.refs.len()),
            Sub::Inner { kids, .. } => {
                let ((ln, lr), (rn, rr)) = (kids.0.size(), kids.1.size());
                (1 + ln + rn, lr + rr)
            }
        }
    }
}

/// Writes `sub` depth first: its root to `root`, its other nodes to `rest` (whose first entry
/// is node `g` of the tree) and its references to `refs` (starting at reference `rb`). The
/// layout is that of appending the nodes in order: an inner node's two children, then the
/// rest of the left subtree, then the rest of the right one. Subtrees are written in
/// parallel into their disjoint parts of the arrays.
fn flatten(
    sub: Sub,
    root: &mut KdNode,
    rest: &mut [KdNode],
    g: usize,
    refs: &mut [u32],
    rb: usize,
) -> Result<(), BuildError> {
    match sub {
        Sub::Chunk(c) => {
            // Chunk node i >= 1 goes to g + i - 1; its references move up by `rb`.
            let relocate = |n: KdNode| -> Result<KdNode, BuildError> {
                if n.is_leaf() {
                    leaf_node(n.first_ref() + rb, n.prim_count())
                } else {
                    inner_node(n.axis(), n.split(), n.left_child() + g - 1)
                }
            };
            *root = relocate(c.nodes[0])?;
            for (d, &n) in rest.iter_mut().zip(&c.nodes[1..]) {
                *d = relocate(n)?;
            }
            refs.copy_from_slice(&c.refs);
            Ok(())
        }
        Sub::Inner { axis, pos, kids } => {
            *root = inner_node(axis, pos, g)?;
            let (l, r) = *kids;
            let ((ln, lr), rn) = (l.size(), r.size().0);
            let (pair, rest) = rest.split_at_mut(2);
            let [kl, kr] = pair else { unreachable!("two children") };
            let (rest_l, rest_r) = rest.split_at_mut(ln - 1);
            debug_assert_eq!(rest_r.len(), rn - 1);
            let (refs_l, refs_r) = refs.split_at_mut(lr);
            let (a, b) = rayon::join(
                || flatten(l, kl, rest_l, g + 2, refs_l, rb),
                || flatten(r, kr, rest_r, g + 1 + ln, refs_r, rb + lr),
            );
            a.and(b)
        }
    }
}

/// Builds the node and reference arrays for the triangles `prims` (indices into `tris`;
/// degenerate triangles already removed) inside `bounds`, taking its buffers from `meter`.
pub(crate) fn build_nodes(
    tris: &[[Vec3; 3]],
    prims: &[u32],
    bounds: Aabb,
    config: &BuildConfig,
    meter: &Meter,
) -> Result<BuiltNodes, BuildError> {
    build_nodes_from(tris, prims, bounds, config, meter, (1, 0))
}

/// [`build_nodes`] with the node and reference counters of the final arrays starting at
/// `start = (node, reference)` instead of `(1, 0)`, as if the tree were appended to arrays that
/// already held that many: a synthetic counter, so that tests can run the index checks near
/// their limits (2^30 nodes, 2^32 references) without allocating billions of entries. Only
/// the tests use another start; the arrays returned hold this tree alone.
fn build_nodes_from(
    tris: &[[Vec3; 3]],
    prims: &[u32],
    bounds: Aabb,
    config: &BuildConfig,
    meter: &Meter,
    start: (usize, usize),
) -> Result<BuiltNodes, BuildError> {
    if tris.len() > PRIM_MASK as usize + 1 {
        return Err(BuildError::TooLarge(format!("{} triangles exceed the builder's 2^30", tris.len())));
    }
    let n = prims.len();
    if n == 0 {
        return Ok(BuiltNodes { nodes: vec![KdNode::leaf(0, 0)], prim_refs: Vec::new() });
    }
    let ctx = Ctx {
        tris,
        costs: Costs::of(config),
        depth_limit: config.depth_limit(n),
        max_bad_refines: config.max_bad_refines,
        pool: Mutex::new(Vec::new()),
        meter,
    };
    let sub = match config.strategy {
        BuildStrategy::Binned { bins, min_tris } if n >= min_tris as usize => {
            let items_bytes = binned::ITEM_BYTES * n as u64;
            meter.take(items_bytes, "the root's items")?;
            let items = binned::root_items(tris, prims);
            let binning = binned::Binning { bins: bins as usize, min_tris: min_tris as usize };
            binned::build_binned(&ctx, items, bounds, At::default(), &binning)
        }
        _ => exact_root(&ctx, prims, bounds),
    };
    let scratch_bytes: u64 =
        ctx.pool.lock().unwrap_or_else(|e| e.into_inner()).drain(..).map(|s| 5 * s.class.len() as u64).sum();
    meter.give(scratch_bytes);
    let sub = sub?;
    let (n_nodes, n_refs) = sub.size();
    let chunk_bytes = sub.heap_bytes();
    let final_bytes = (n_nodes as u64).saturating_mul(8).saturating_add((n_refs as u64).saturating_mul(4));
    meter.take(final_bytes, "the tree's node and reference arrays")?;
    let mut nodes = vec![KdNode::leaf(0, 0); n_nodes];
    let mut prim_refs = vec![0; n_refs];
    let (root, rest) = nodes.split_at_mut(1);
    let done = flatten(sub, &mut root[0], rest, start.0, &mut prim_refs, start.1);
    meter.give(chunk_bytes);
    done?;
    let built = BuiltNodes { nodes, prim_refs };
    if config.collapse { collapse::collapse(built, bounds, &ctx.costs, meter) } else { Ok(built) }
}

/// The exact build's root: the events of all triangles, sorted once, then [`build_par`].
fn exact_root(ctx: &Ctx, prims: &[u32], bounds: Aabb) -> Result<Sub, BuildError> {
    let (tris, meter, n) = (ctx.tris, ctx.meter, prims.len());
    let root_bytes = 3 * 2 * 8 * n as u64;
    meter.take(root_bytes, "the root's event lists")?;
    let mut lists: [Vec<u64>; 3] = Default::default();
    for l in &mut lists {
        l.reserve_exact(2 * n);
    }
    for &p in prims {
        let [a, b, c] = tris[p as usize];
        let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
        push_box_events(&mut lists, p, lo.to_array(), hi.to_array());
    }
    // Sorted once (Wald & Havran 2006, section 4.2), the three axes in parallel. The events
    // are pushed in ascending triangle order, which the radix sort needs.
    let sorted = prims.is_sorted();
    let sort_bytes = if sorted { lists.iter().map(|l| 8 * l.len() as u64).sum() } else { 0 };
    if let Err(e) = meter.take(sort_bytes, "the root sort's second buffer") {
        meter.give(root_bytes);
        return Err(e);
    }
    let sort = |l: &mut Vec<u64>| {
        if sorted {
            radix_sort_events(l, &mut Vec::new());
        } else {
            l.sort_unstable();
        }
    };
    let [l0, l1, l2] = &mut lists;
    rayon::join(|| sort(l0), || rayon::join(|| sort(l1), || sort(l2)));
    meter.give(sort_bytes);
    // The radix sort swaps buffers: the lists' capacities are now the second buffers'.
    let lists = Lists::from_vecs(lists);
    meter.give(root_bytes);
    meter.take(lists.heap_bytes(), "the root's event lists")?;
    build_par(ctx, lists, n, bounds, At::default())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The soup of `tris` as the build sees it: non-degenerate triangles and their bounds.
    fn prims_and_bounds(tris: &[[Vec3; 3]]) -> (Vec<u32>, Aabb) {
        let prims: Vec<u32> = (0..tris.len() as u32).collect();
        let bounds = tris.iter().flatten().fold(Aabb::EMPTY, |b, &p| b.grow(p));
        (prims, bounds)
    }

    /// A synthetic counter: the tree is laid out as if appended to arrays that already hold
    /// nearly 2^30 nodes or 2^32 references, so the index checks run at their limits without
    /// allocating billions of entries. Just below the limit the build succeeds, past it the
    /// build reports `TooLarge` instead of wrapping.
    #[test]
    fn index_checks_fire_at_the_limits_with_a_synthetic_counter() {
        let mut tris = Vec::new();
        for i in 0..40 {
            let o = Vec3::new(i as f32 * 1.5, (i % 7) as f32, (i % 3) as f32);
            tris.push([o, o + Vec3::X, o + Vec3::Y + 0.5 * Vec3::Z]);
        }
        let (prims, bounds) = prims_and_bounds(&tris);
        let config = BuildConfig::default();
        let meter = Meter::new(None);
        let plain = build_nodes(&tris, &prims, bounds, &config, &meter).unwrap();
        let (nodes, refs) = (plain.nodes.len(), plain.prim_refs.len());
        assert!(nodes > 10 && refs >= 40, "a tree with some depth: {nodes} nodes, {refs} refs");
        let build = |start| build_nodes_from(&tris, &prims, bounds, &config, &meter, start);
        // Node indices: a stored child index (the last pair's left child, node `nodes - 2`
        // counted from the start at `start - 1`) must stay below 2^30 - 1.
        let max_node = MAX_NODE_FIELD as usize;
        assert!(build((max_node - nodes + 2, 0)).is_ok());
        assert!(matches!(build((max_node - nodes + 3, 0)), Err(BuildError::TooLarge(_))));
        // References: the last leaf must end within u32.
        let max_ref = u32::MAX as usize;
        assert!(build((1, max_ref - refs)).is_ok());
        assert!(matches!(build((1, max_ref - refs + 1)), Err(BuildError::TooLarge(_))));
        assert!(matches!(build((1, usize::MAX - 10)), Err(BuildError::TooLarge(_))));
    }

    /// The leaf-or-split rule: a split cheaper than the leaf (`C_isect * ceil(n / W)`) is
    /// made; a costlier one only with bad refines left on the path, counted, searched without
    /// a limit for 16 triangles and more and below 4 leaves for fewer; never at the depth
    /// limit or for an empty node.
    #[test]
    fn the_leaf_or_split_rule_counts_bad_refines() {
        let meter = Meter::new(None);
        let costs = Costs { c_trav: 1.0, c_isect: 2.0, empty_factor: 1.0, width: 4.0 };
        let ctx = |max_bad_refines| Ctx {
            tris: &[],
            costs,
            depth_limit: 10,
            max_bad_refines,
            pool: Mutex::new(Vec::new()),
            meter: &meter,
        };
        let split = |cost| Split { axis: 0, pos: 0.5, planar_left: true, cost };
        let at = |depth, bad| At { depth, bad };
        // 100 triangles: a leaf of 25 groups costs 50.
        let off = ctx(0);
        let seen = std::cell::Cell::new(0.0);
        let run = |c: &Ctx, n, a, cost| {
            c.accept(n, a, |limit| {
                seen.set(limit);
                Some(split(cost))
            })
        };
        assert_eq!(run(&off, 100, at(3, 0), 49.0), Some((split(49.0), at(4, 0))));
        assert_eq!(seen.get(), 50.0);
        assert_eq!(run(&off, 100, at(3, 0), 50.0), None);
        let bad = ctx(2);
        assert_eq!(run(&bad, 100, at(3, 0), 49.0), Some((split(49.0), at(4, 0))));
        assert_eq!(seen.get(), f64::INFINITY);
        assert_eq!(run(&bad, 100, at(3, 0), 500.0), Some((split(500.0), at(4, 1))));
        assert_eq!(run(&bad, 100, at(4, 1), 60.0), Some((split(60.0), at(5, 2))));
        assert_eq!(run(&bad, 100, at(5, 2), 60.0), None, "no bad refine left");
        assert_eq!(seen.get(), 50.0);
        // 10 triangles: a leaf of 3 groups costs 6; a split over 4 leaves (24) is refused.
        assert_eq!(run(&bad, 10, at(3, 0), 23.0), Some((split(23.0), at(4, 1))));
        assert_eq!(seen.get(), 24.0);
        assert_eq!(run(&bad, 10, at(3, 0), 24.0), None);
        // No search at the depth limit or for an empty node.
        let never = |_| -> Option<Split> { panic!("searched") };
        assert_eq!(bad.accept(100, at(10, 0), never), None);
        assert_eq!(bad.accept(0, at(0, 0), never), None);
    }

    #[test]
    fn the_meter_refuses_what_would_pass_the_budget() {
        let meter = Meter::new(Some(1000));
        meter.take(600, "a").unwrap();
        let e = meter.take(401, "b").unwrap_err();
        assert!(matches!(e, BuildError::OverBudget { estimate: 1001, budget: 1000, .. }), "{e:?}");
        assert!(e.to_string().contains("1000 bytes") && e.to_string().contains("b"), "{e}");
        meter.take(400, "c").unwrap();
        meter.give(1000);
        meter.take(1000, "d").unwrap();
        assert_eq!(meter.peak(), 1000);
        assert_eq!(human_bytes(1536), "1.5 KiB (1536 bytes)");
        assert_eq!(human_bytes(3 << 30), "3.0 GiB (3221225472 bytes)");
        assert_eq!(human_bytes(12), "12 bytes");
    }

    #[test]
    fn index_checks_report_too_large() {
        assert_eq!(node_index(5), Ok(5));
        assert_eq!(node_index(MAX_NODE_FIELD as usize - 1), Ok(MAX_NODE_FIELD - 1));
        assert!(matches!(node_index(MAX_NODE_FIELD as usize), Err(BuildError::TooLarge(_))));
        assert!(matches!(node_index(usize::MAX), Err(BuildError::TooLarge(_))));
        assert_eq!(leaf_fields(7, 3), Ok((7, 3)));
        assert!(matches!(leaf_fields(0, MAX_NODE_FIELD as usize + 1), Err(BuildError::TooLarge(_))));
        assert!(matches!(leaf_fields(u32::MAX as usize, 2), Err(BuildError::TooLarge(_))));
        assert!(matches!(leaf_fields(usize::MAX, 1), Err(BuildError::TooLarge(_))));
        assert!(matches!(inner_node(0, 0.5, 1 << 30), Err(BuildError::TooLarge(_))));
        assert!(matches!(leaf_node(1 << 33, 1), Err(BuildError::TooLarge(_))));
    }
}
