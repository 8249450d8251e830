//! Entry and exit hits paired in ray order (Tsakok 2008, chapter 5, Listing 5.1), with the
//! two light-leak remedies of "Light Leaks" (Figures 5.8-5.10).
//!
//! A shadow ray starts outside every object and toggles between outside and inside at each
//! hit. An *entry* hit opens a pair, the next hit (its *exit*) closes it, and the distance
//! between them is an *edge width*; the largest is the ray's edge width. Listing 5.1 keeps
//! the open entry in `distances[0]` across leaves; with the thesis's two slips corrected
//! (`width`, not `difference`, is the maximised value, and the entry carried to the next leaf
//! is the last sorted distance `distances[distCount]`, not `distances[distCount - 1]`) it is
//! exactly [`Pairing::push`] fed the hits in ray order. An entry still open at the end means
//! the geometry is not closed: the width is infinite and the point fully occluded (the thesis:
//! "malformed geometry will still be hard shadowed").
//!
//! The hits of one surface crossing are counted once (see [`HitList::insert`]): a triangle
//! referenced by several leaves, and a ray through the edge or vertex shared by triangles of
//! one surface (the triangle tests may report both triangles at the same distance).
//!
//! ## Which hits count
//! A ray's edge width is a function of the hits the tree's triangle test reports on its
//! segment, one per triangle, and nothing else: [`crate::brute`] tests every triangle,
//! [`crate::traverse`] and [`crate::packet`] the triangles of the leaves they visit, and all
//! three sort the hits by `(t, triangle)` into a [`HitList`] and pair them with [`Pairing`].
//! The test is deterministic, so a triangle reports the same `t` to every leaf that holds it,
//! and the kernels agree with the brute force as long as they find the same triangles and
//! pair them in the same order (see [`HitList::insert`] for how the list guarantees both).
//!
//! Degenerate rays are not special-cased. A ray lying in the plane of a face (a shadow ray
//! along a floor, or between two boxes that touch face to face) gets no hit from that face
//! (both tests reject a ray in a triangle's plane), and whatever the test reports on the edges
//! of the faces around it: a graze can read as an entry never closed (a hard shadow) or as a
//! thin width where a ray a hair to either side would cross nothing. Such rays are a set of
//! measure zero; the kernels and the brute force give them the same answer, which is all the
//! crate promises for them.

use glam::Vec3;
use kdtree::KdTree;

/// The light-leak remedies of the thesis (chapter 5, "Light Leaks"); both off by default.
#[derive(Clone, Copy, Debug, Default)]
pub struct LeakRemedies<'a> {
    /// Per-triangle thickness scale (indexed like the tree's triangles; `1` = as measured):
    /// an edge width is multiplied by the larger scale of its entry and exit triangles, so
    /// that thin occluders marked by the artist cast an umbra. Missing and NaN entries count
    /// as `1` (an infinite one makes every pair through it an umbra).
    pub thickness: Option<&'a [f32]>,
    /// The shared-vertex rule (Figure 5.10): an entry/exit pair whose triangles share no
    /// vertex has an infinite width.
    pub shared_vertex: bool,
}

/// True when triangles `a` and `b` have a vertex in common (equal positions, so meshes that
/// duplicate vertices per face still qualify).
#[inline]
pub fn share_vertex(a: &[Vec3; 3], b: &[Vec3; 3]) -> bool {
    a.iter().any(|p| b.contains(p))
}

/// The pairing state carried along one shadow ray: the open entry, if any, and the largest
/// edge width so far.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pairing {
    open: Option<(f32, u32)>,
    max_width: f32,
}

impl Default for Pairing {
    fn default() -> Self {
        Pairing::new()
    }
}

impl Pairing {
    /// Outside every object, no width yet.
    #[inline]
    pub fn new() -> Pairing {
        Pairing { open: None, max_width: 0.0 }
    }

    /// The next hit along the ray, at `t` on triangle `prim` of `tree`: an entry when the ray
    /// is outside, else the exit that closes the open entry and gives an edge width.
    #[inline]
    pub fn push(&mut self, t: f32, prim: u32, tree: &KdTree, remedies: &LeakRemedies) {
        match self.open.take() {
            None => self.open = Some((t, prim)),
            Some((t_entry, entry)) => {
                let mut width = t - t_entry;
                if let Some(scale) = remedies.thickness {
                    let s = |p: u32| scale.get(p as usize).copied().filter(|s| !s.is_nan()).unwrap_or(1.0);
                    width *= s(entry).max(s(prim));
                }
                if remedies.shared_vertex && !share_vertex(&tree.triangle(entry), &tree.triangle(prim)) {
                    width = f32::INFINITY;
                }
                self.max_width = self.max_width.max(width);
            }
        }
    }

    /// The largest edge width of the closed pairs so far.
    #[inline]
    pub fn max_width(&self) -> f32 {
        self.max_width
    }

    /// True while an entry is open (the ray is inside an object).
    #[inline]
    pub fn is_inside(&self) -> bool {
        self.open.is_some()
    }

    /// The ray's edge width once every hit is pushed: infinite if an entry is still open.
    #[inline]
    pub fn finish(&self) -> f32 {
        if self.open.is_some() { f32::INFINITY } else { self.max_width }
    }
}

/// Hits closer than this relative difference in `t` are one crossing when their triangles
/// share a vertex and face the ray the same way (a ray through a shared edge: the Wald test
/// computes each triangle's own plane distance, a few ulps apart).
pub const TIE: f32 = 64.0 * f32::EPSILON;

/// One hit waiting to be paired.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PendingHit {
    /// Distance along the ray.
    pub t: f32,
    /// The triangle.
    pub prim: u32,
}

/// The hits found but not yet paired, sorted by `(t, prim)`, each surface crossing once.
///
/// Hits are paired in bulk by [`HitList::flush_below`] up to a threshold that the caller
/// guarantees no later hit will precede; the list then refuses every hit before the largest
/// threshold flushed so far (its *floor*). A triangle's hit is therefore counted once however
/// many leaves report it: a report at or above the floor finds the earlier report still
/// pending (same triangle), one below it was paired already.
#[derive(Clone, Debug)]
pub struct HitList {
    hits: Vec<PendingHit>,
    /// The last hit handed to the pairing (for crossings split across a flush).
    last: Option<PendingHit>,
    /// Every hit before this has been paired: later reports of them are repeats.
    floor: f32,
}

impl Default for HitList {
    fn default() -> Self {
        HitList { hits: Vec::new(), last: None, floor: f32::NEG_INFINITY }
    }
}

/// True when the triangles of hits `a` and `b` share a vertex and face the ray `dir` the
/// same way: two reports of one crossing through their shared edge or vertex.
#[inline]
fn same_crossing(tree: &KdTree, a: u32, b: u32, dir: Vec3) -> bool {
    let (ta, tb) = (tree.triangle(a), tree.triangle(b));
    let facing = |t: &[Vec3; 3]| (t[1] - t[0]).cross(t[2] - t[0]).dot(dir) > 0.0;
    share_vertex(&ta, &tb) && facing(&ta) == facing(&tb)
}

#[inline]
fn tied(a: f32, b: f32) -> bool {
    (a - b).abs() <= TIE * a.abs().max(b.abs())
}

impl HitList {
    /// Empties the list for a new ray (keeps its capacity).
    #[inline]
    pub fn clear(&mut self) {
        self.hits.clear();
        self.last = None;
        self.floor = f32::NEG_INFINITY;
    }

    /// The pending hits, sorted.
    pub fn hits(&self) -> &[PendingHit] {
        &self.hits
    }

    /// Adds the hit of `prim` at `t` on the ray with direction `dir`, unless it is already
    /// counted: below the floor (paired already, see [`HitList`]), the same triangle still
    /// pending (found again in another leaf), or a tie (see [`TIE`]) with a pending or the
    /// last paired hit on a triangle sharing a vertex and facing the same way. Of tied
    /// triangles the smaller id stays, so the result does not depend on the order in which
    /// leaves report them.
    #[inline]
    pub fn insert(&mut self, t: f32, prim: u32, tree: &KdTree, dir: Vec3) {
        if t < self.floor || self.hits.iter().any(|h| h.prim == prim) {
            return;
        }
        if let Some(last) = self.last
            && (last.prim == prim || (tied(last.t, t) && same_crossing(tree, last.prim, prim, dir)))
        {
            return;
        }
        if let Some(i) = self.hits.iter().position(|h| tied(h.t, t) && same_crossing(tree, h.prim, prim, dir)) {
            if prim < self.hits[i].prim {
                self.hits.remove(i);
            } else {
                return;
            }
        }
        let at = self.hits.partition_point(|h| h.t < t || (h.t == t && h.prim < prim));
        self.hits.insert(at, PendingHit { t, prim });
    }

    /// Pairs, in order, every pending hit with `t < bound` (the caller guarantees that no
    /// hit not yet reported lies before `bound`), removes them and raises the floor to
    /// `bound`. Returns `true` as soon as the width passes `r` (the early exit of
    /// Listing 5.1).
    #[inline]
    pub fn flush_below(
        &mut self,
        bound: f32,
        r: f32,
        pairing: &mut Pairing,
        tree: &KdTree,
        remedies: &LeakRemedies,
    ) -> bool {
        let k = self.hits.partition_point(|h| h.t < bound);
        for h in &self.hits[..k] {
            pairing.push(h.t, h.prim, tree, remedies);
            self.last = Some(*h);
            if pairing.max_width() > r {
                return true;
            }
        }
        self.hits.drain(..k);
        self.floor = self.floor.max(bound);
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kdtree::BuildConfig;

    fn two_quads() -> KdTree {
        // Triangles 0, 1 share vertices; triangle 2 shares none with them.
        let a = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let b = [Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        let c = [Vec3::new(5.0, 0.0, 1.0), Vec3::new(6.0, 0.0, 1.0), Vec3::new(5.0, 1.0, 1.0)];
        KdTree::build_soup(&[a, b, c], &BuildConfig::default()).unwrap()
    }

    #[test]
    fn pairs_entries_with_exits_and_keeps_the_largest_width() {
        let tree = two_quads();
        let off = LeakRemedies::default();
        let mut p = Pairing::new();
        p.push(0.1, 0, &tree, &off);
        assert!(p.is_inside());
        p.push(0.15, 2, &tree, &off);
        p.push(0.5, 0, &tree, &off);
        p.push(0.8, 1, &tree, &off);
        assert!(!p.is_inside());
        assert!((p.finish() - 0.3).abs() < 1e-6);
        p.push(0.9, 0, &tree, &off);
        assert_eq!(p.finish(), f32::INFINITY, "an entry never closed is full occlusion");
    }

    #[test]
    fn nan_thickness_scales_count_as_one() {
        let tree = two_quads();
        for (scale, want) in [
            ([f32::NAN, 1.0, f32::NAN], 0.1),
            ([f32::NAN, 1.0, 3.0], 0.3),
            ([f32::INFINITY, 1.0, f32::NAN], f32::INFINITY),
        ] {
            let thick = LeakRemedies { thickness: Some(&scale), shared_vertex: false };
            let mut p = Pairing::new();
            p.push(0.1, 0, &tree, &thick);
            p.push(0.2, 2, &tree, &thick);
            let w = p.finish();
            assert!((w - want).abs() < 1e-6 || w == want, "{scale:?}: {w}");
        }
    }

    #[test]
    fn remedies_scale_widths_and_reject_pairs_without_a_shared_vertex() {
        let tree = two_quads();
        let scale = [1.0, 1.0, 4.0];
        let thick = LeakRemedies { thickness: Some(&scale), shared_vertex: false };
        let mut p = Pairing::new();
        p.push(0.1, 0, &tree, &thick);
        p.push(0.2, 2, &tree, &thick);
        assert!((p.finish() - 0.4).abs() < 1e-6);
        let shared = LeakRemedies { thickness: None, shared_vertex: true };
        let mut p = Pairing::new();
        p.push(0.1, 0, &tree, &shared);
        p.push(0.2, 1, &tree, &shared);
        assert!((p.finish() - 0.1).abs() < 1e-6);
        p.push(0.3, 0, &tree, &shared);
        p.push(0.35, 2, &tree, &shared);
        assert_eq!(p.finish(), f32::INFINITY);
    }

    #[test]
    fn one_crossing_through_a_shared_edge_counts_once() {
        let tree = two_quads();
        let dir = Vec3::Z;
        let mut list = HitList::default();
        list.insert(0.5, 1, &tree, dir);
        list.insert(0.5 + 1e-7, 0, &tree, dir);
        list.insert(0.5, 1, &tree, dir);
        assert_eq!(list.hits(), &[PendingHit { t: 0.5 + 1e-7, prim: 0 }]);
        // Triangle 2 shares no vertex: a separate crossing even at the same distance.
        list.insert(0.5, 2, &tree, dir);
        assert_eq!(list.hits().len(), 2);
    }

    #[test]
    fn hits_below_the_paired_floor_are_repeats_and_above_it_count() {
        let tree = two_quads();
        let (dir, off) = (Vec3::Z, LeakRemedies::default());
        let mut list = HitList::default();
        let mut p = Pairing::new();
        list.insert(0.2, 2, &tree, dir);
        list.insert(0.4, 0, &tree, dir);
        assert!(!list.flush_below(0.3, f32::INFINITY, &mut p, &tree, &off));
        assert!(p.is_inside());
        // Triangle 2 reported again by a later leaf: below the floor, already paired.
        list.insert(0.2, 2, &tree, dir);
        // A hit between the floor and the pending one, found late: it counts, in order.
        list.insert(0.3, 1, &tree, dir);
        assert_eq!(list.hits(), &[PendingHit { t: 0.3, prim: 1 }, PendingHit { t: 0.4, prim: 0 }]);
        // A lower flush threshold does not lower the floor.
        assert!(!list.flush_below(0.1, f32::INFINITY, &mut p, &tree, &off));
        list.insert(0.25, 2, &tree, dir);
        assert_eq!(list.hits().len(), 2);
        assert!(!list.flush_below(f32::INFINITY, f32::INFINITY, &mut p, &tree, &off));
        // In at 0.2, out at 0.3, in again at 0.4: triangle 2 counted once.
        assert!((p.max_width() - 0.1).abs() < 1e-6);
        assert!(p.is_inside());
        list.clear();
        list.insert(0.2, 2, &tree, dir);
        assert_eq!(list.hits().len(), 1, "clear resets the floor");
    }
}
