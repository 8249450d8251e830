//! The brute-force oracle: every triangle, closest hit.
//!
//! It runs the same triangle test as the tree it checks, so any disagreement is a traversal
//! error, never a difference in intersection arithmetic: a tree hit has exactly the oracle's
//! distance (bit for bit), and may name another triangle only when both lie at that distance.

use glam::Vec3;

use crate::triangle::{Intersector, TriangleTest, WaldTriangle, WatertightTriangle};
use crate::{Hit, KdTree, Ray};

mod exact;

pub use exact::segment_meets_triangle;

/// A brute-force intersector over all triangles.
#[derive(Clone, Debug)]
pub struct BruteForce {
    intersector: Intersector,
    wald: Vec<WaldTriangle>,
    watertight: Vec<WatertightTriangle>,
    /// The triangles, for [`BruteForce::unreachable`].
    tris: Vec<[Vec3; 3]>,
}

impl BruteForce {
    /// The oracle for a triangle soup with the given test. Triangles with a NaN or infinite
    /// vertex are never hit, like degenerate ones (their records are NaN).
    pub fn new(tris: &[[Vec3; 3]], intersector: Intersector) -> BruteForce {
        BruteForce {
            intersector,
            wald: tris.iter().map(WaldTriangle::new).collect(),
            watertight: tris.iter().map(WatertightTriangle::new).collect(),
            tris: tris.to_vec(),
        }
    }

    /// The oracle for the triangles of `tree`, with the tree's test.
    pub fn for_tree(tree: &KdTree) -> BruteForce {
        BruteForce::new(&tree.tris, tree.intersector)
    }

    /// The closest hit over all triangles; ties go to the lowest triangle index. A ray with
    /// NaN components gets `None`, as from [`KdTree::intersect`].
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        match self.intersector {
            Intersector::Wald => closest(&self.wald, ray),
            Intersector::Watertight => closest(&self.watertight, ray),
        }
    }

    /// True if any triangle is hit in the ray's interval.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.intersect(ray).is_some()
    }

    /// True if, in exact arithmetic, `ray` cannot meet triangle `prim`: its segment
    /// `origin + t dir`, `t` in `[t_min, t_max]`, misses the closed triangle
    /// ([`segment_meets_triangle`], decided exactly with big integers; edges and vertices
    /// count as reached). Then a hit that the triangle test reports on the triangle is a
    /// rounding artefact of the test, and a traversal may report it (its leaf may be on the
    /// ray's path) or not. Wald's test reports such hits (its barycentrics come from
    /// coefficients rounded to `f32`, and products that underflow to zero count as "on the
    /// edge"); the watertight test can too (its shear is rounded).
    ///
    /// The ray is taken as it is, `dir` after [`Ray::new`] flushed its tiny components to
    /// zero, as traversal sees it. A triangle with an exactly zero normal is the segment
    /// between its extreme vertices (the tree leaves out the triangles whose `f64` normal is
    /// zero, and the tests never hit them). Input that cannot be decided (NaN, which
    /// [`Ray::try_new`] rejects) is never excused.
    pub fn unreachable(&self, ray: &Ray, prim: u32) -> bool {
        let Some(tri) = self.tris.get(prim as usize) else { return false };
        !segment_meets_triangle(tri, ray.origin, ray.dir, ray.t_min, ray.t_max)
    }

    /// Checks the answers of a traversal method for `ray` (its closest hit `got` and its
    /// any-hit answer `occluded`) against this oracle, naming the first disagreement.
    ///
    /// The method must report the oracle's closest distance bit for bit (both run the same
    /// triangle test), the same triangle or another at exactly that distance (a tie), and the
    /// same any-hit answer. Two ambiguities are allowed, and only these:
    ///
    /// - A hit so close to the origin that it lies within the rounding error of the origin's
    ///   own position (`|t| |d| <= 64 ulp(max |o|)`). Such a hit is an artefact of an origin on
    ///   (or one ulp off) a surface: the triangle test may round the distance to 0 for a point
    ///   the ray never reaches in exact arithmetic, while traversal follows exact arithmetic.
    ///   The method may report it or not; past it, it must agree.
    /// - A hit on a triangle the ray cannot reach in exact arithmetic (its segment misses the
    ///   closed triangle, [`BruteForce::unreachable`]). The method may report it
    ///   (its leaf may be on the ray's path) or not, but a reported one must be a hit of the
    ///   test, and no triangle the ray meets before it may be hit before it.
    /// - A hit of the test at `t` after another hit at `t' < t` whose triangle the ray meets,
    ///   in exact arithmetic, only after `t`: its distance was rounded below `t`, and the
    ///   method may skip its leaves, which lie beyond `t`. (In well-scaled scenes the test's
    ///   distances are accurate to a few ulps and this never happens; a 1e31-wide triangle
    ///   through the ray's origin is reported at `t = -3.6e-8` instead of 0.)
    ///
    /// The exact reachability test runs only when the answers are not the oracle's own
    /// closest hit (ties to the lowest index) and any-hit answer, which every rule accepts.
    pub fn check(&self, ray: &Ray, got: Option<Hit>, occluded: bool) -> Result<(), String> {
        let hits = self.all_hits(ray);
        let first = hits.iter().fold(None, |best: Option<(f32, u32)>, &h| match best {
            Some(b) if b.0 <= h.0 => Some(b),
            _ => Some(h),
        });
        if got.map(|g| (g.t, g.prim)) == first && occluded == first.is_some() {
            return Ok(());
        }
        let (real, artefacts): (Vec<_>, Vec<_>) = hits.iter().partition(|&&(_, p)| !self.unreachable(ray, p));
        if let Some(g) = got
            && artefacts.contains(&(g.t, g.prim))
        {
            if occluded && let Some(&(t, p)) = self.reachable_before(ray, &real, g.t) {
                return Err(format!(
                    "ray {ray:?}: got the unreachable hit {g:?} but triangle {p}, reachable before it, is hit at t = {t}"
                ));
            }
            if occluded {
                return Ok(());
            }
            return Err(format!("ray {ray:?}: got the unreachable hit {g:?} but occluded false"));
        }
        self.check_hits(ray, &real, got, occluded, !artefacts.is_empty())
    }

    /// [`BruteForce::check`] against the hits `real` (`(t, prim)`, in index order); with
    /// `may_occlude`, an any-hit answer of true is accepted without a hit in `real`.
    fn check_hits(
        &self,
        ray: &Ray,
        real: &[(f32, u32)],
        got: Option<Hit>,
        occluded: bool,
        may_occlude: bool,
    ) -> Result<(), String> {
        // The closest of `real` from `t0` on, ties to the lowest index (as `intersect`).
        let closest_from = |t0: f32| {
            real.iter().filter(|h| h.0 >= t0).fold(None, |best: Option<(f32, u32)>, &h| match best {
                Some(b) if b.0 <= h.0 => Some(b),
                _ => Some(h),
            })
        };
        let want = closest_from(ray.t_min);
        let is_hit = |g: &Hit| real.iter().any(|&(t, p)| p == g.prim && t == g.t);
        let near = ray.origin.abs().max_element() * (64.0 * f32::EPSILON) / ray.dir.length();
        if let Some(w) = want.filter(|w| w.0.abs() <= near) {
            let beyond = closest_from(near.next_up());
            let ok = match got {
                None => beyond.is_none(),
                Some(g) if g.t <= near => is_hit(&g),
                Some(g) => beyond.is_some_and(|b| b.0 == g.t) && is_hit(&g),
            };
            if !ok || (beyond.is_some() && !occluded) {
                return Err(format!(
                    "ray {ray:?}: got {got:?} (occluded {occluded}), oracle (t, prim) {w:?} then {beyond:?}"
                ));
            }
            return Ok(());
        }
        match (got, want) {
            (None, None) => {}
            (Some(g), Some(w)) => {
                if g.t != w.0 && !(is_hit(&g) && self.reachable_before(ray, real, g.t).is_none()) {
                    return Err(format!("ray {ray:?}: got {g:?}, oracle (t, prim) {w:?}"));
                }
                if g.prim != w.1 && !is_hit(&g) {
                    return Err(format!("ray {ray:?}: got {g:?}, not an oracle hit (oracle (t, prim) {w:?})"));
                }
            }
            (g, w) => return Err(format!("ray {ray:?}: got {g:?}, oracle (t, prim) {w:?}")),
        }
        if occluded != want.is_some() && !(occluded && may_occlude) {
            return Err(format!("ray {ray:?}: occluded {occluded}, oracle hit (t, prim) {want:?}"));
        }
        Ok(())
    }

    /// The first of the hits `real` (`(t, prim)`) that the test reports before `t` on a
    /// triangle that the ray meets, in exact arithmetic, in `[t_min, t]`; `None` when every
    /// hit reported before `t` is one whose exact crossing comes after `t`, its distance
    /// rounded below it (for example a 1e31-wide triangle through the ray's origin, exactly
    /// at `t = 0`, reported at `t = -3.6e-8` for a direction of length 4e31). A traversal
    /// that found a hit at `t` may skip the leaves of such a triangle, which lie beyond `t`.
    fn reachable_before<'h>(&self, ray: &Ray, real: &'h [(f32, u32)], t: f32) -> Option<&'h (f32, u32)> {
        real.iter().filter(|h| h.0 < t).find(|&&(_, p)| {
            self.tris.get(p as usize).is_none_or(|tri| segment_meets_triangle(tri, ray.origin, ray.dir, ray.t_min, t))
        })
    }

    /// Whether `got`, one traversal method's closest hit for `ray`, may stand for `want`,
    /// another's (e.g. a packet lane against the single-ray kernel): the same hit; or a tie,
    /// another triangle that the test hits at exactly the same distance (which of two
    /// triangles at one distance is reported depends on the order leaves are visited in); or
    /// two answers each of which [`BruteForce::check`] accepts.
    ///
    /// The last case covers the rounding artefacts of the triangle test that a method reports
    /// or not depending on which leaves it visits, and methods legitimately visit different
    /// leaves: the single-ray kernel's plane distance `(split - o) / d` can underflow to 0 and
    /// visit both children, where a cone, measuring distances along its axis, culls exactly.
    pub fn equivalent_hits(&self, ray: &Ray, got: Option<Hit>, want: Option<Hit>) -> bool {
        if got == want {
            return true;
        }
        // Each answer must be the test's own hit on its triangle, barycentrics included.
        let genuine = |h: Option<Hit>| h.is_none_or(|h| self.test_hit(ray, h.prim) == Some(h));
        if !(genuine(got) && genuine(want)) {
            return false;
        }
        if let (Some(g), Some(w)) = (got, want)
            && g.t == w.t
        {
            return true;
        }
        self.check(ray, got, got.is_some()).is_ok() && self.check(ray, want, want.is_some()).is_ok()
    }

    /// The test's hit on triangle `prim` in the ray's interval, as a traversal reports it.
    fn test_hit(&self, ray: &Ray, prim: u32) -> Option<Hit> {
        fn one<T: TriangleTest>(records: &[T], ray: &Ray, prim: u32) -> Option<Hit> {
            let (t, u, v) = records.get(prim as usize)?.intersect(ray, &T::prepare(ray), ray.t_max)?;
            Some(Hit { t, u, v, prim })
        }
        match self.intersector {
            Intersector::Wald => one(&self.wald, ray, prim),
            Intersector::Watertight => one(&self.watertight, ray, prim),
        }
    }

    /// Whether `got`, one traversal method's any-hit answer for `ray`, may stand for `want`,
    /// another's: the same answer, or different answers when the test's only hits in the
    /// ray's interval are on triangles it cannot reach in exact arithmetic (rounding
    /// artefacts, see [`BruteForce::equivalent_hits`]).
    pub fn equivalent_occlusion(&self, ray: &Ray, got: bool, want: bool) -> bool {
        if got == want {
            return true;
        }
        let hits = self.all_hits(ray);
        !hits.is_empty() && hits.iter().all(|&(_, p)| self.unreachable(ray, p))
    }

    /// Every triangle hit by the ray, as `(t, prim)`, in index order.
    pub fn all_hits(&self, ray: &Ray) -> Vec<(f32, u32)> {
        match self.intersector {
            Intersector::Wald => all(&self.wald, ray),
            Intersector::Watertight => all(&self.watertight, ray),
        }
    }
}

fn closest<T: TriangleTest>(records: &[T], ray: &Ray) -> Option<Hit> {
    let data = T::prepare(ray);
    let mut best: Option<Hit> = None;
    let mut t_max = ray.t_max;
    for (prim, rec) in records.iter().enumerate() {
        if let Some((t, u, v)) = rec.intersect(ray, &data, t_max)
            && best.is_none_or(|b| t < b.t)
        {
            best = Some(Hit { t, u, v, prim: prim as u32 });
            t_max = t;
        }
    }
    best
}

fn all<T: TriangleTest>(records: &[T], ray: &Ray) -> Vec<(f32, u32)> {
    let data = T::prepare(ray);
    records
        .iter()
        .enumerate()
        .filter_map(|(prim, rec)| rec.intersect(ray, &data, ray.t_max).map(|(t, _, _)| (t, prim as u32)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_catches_misses_wrong_distances_and_wrong_any_hit_answers() {
        let tris = [
            [Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)],
            [Vec3::new(0.0, 0.0, 2.0), Vec3::new(1.0, 0.0, 2.0), Vec3::new(0.0, 1.0, 2.0)],
        ];
        let oracle = BruteForce::new(&tris, Intersector::Wald);
        let ray = Ray::new(Vec3::new(0.2, 0.2, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        let right = oracle.intersect(&ray);
        assert_eq!(right.map(|h| h.prim), Some(0));
        assert!(oracle.check(&ray, right, true).is_ok());
        assert!(oracle.check(&ray, None, true).is_err());
        assert!(oracle.check(&ray, right, false).is_err());
        let far = Hit { t: 2.0, u: 0.2, v: 0.2, prim: 1 };
        assert!(oracle.check(&ray, Some(far), true).is_err());
        let miss = Ray::new(Vec3::new(2.0, 2.0, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        assert!(oracle.check(&miss, None, false).is_ok());
        assert!(oracle.check(&miss, None, true).is_err());
    }

    #[test]
    fn non_finite_triangles_and_rays() {
        let good = [Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)];
        let mut bad = good.map(|p| p + Vec3::Z);
        bad[1].x = f32::INFINITY;
        let mut nan = good.map(|p| p - 0.5 * Vec3::Z);
        nan[0].y = f32::NAN;
        for intersector in [Intersector::Wald, Intersector::Watertight] {
            let oracle = BruteForce::new(&[nan, good, bad], intersector);
            let ray = Ray::new(Vec3::new(0.2, 0.2, 0.0), Vec3::Z, 0.0, f32::INFINITY);
            assert_eq!(oracle.all_hits(&ray).iter().map(|h| h.1).collect::<Vec<_>>(), [1]);
            for nan_ray in [
                Ray::new(Vec3::new(0.2, f32::NAN, 0.0), Vec3::Z, 0.0, f32::INFINITY),
                Ray::new(Vec3::new(0.2, 0.2, 0.0), Vec3::NAN, 0.0, f32::INFINITY),
                Ray::new(Vec3::new(0.2, 0.2, 0.0), Vec3::Z, 0.0, f32::NAN),
            ] {
                assert_eq!(oracle.intersect(&nan_ray), None);
                assert!(!oracle.occluded(&nan_ray) && oracle.all_hits(&nan_ray).is_empty());
                // "No hit" is the right answer for a NaN ray; a hit is never excused.
                assert!(oracle.check(&nan_ray, None, false).is_ok());
                let h = oracle.intersect(&ray);
                assert!(oracle.check(&nan_ray, h, true).is_err());
                assert!(oracle.check(&nan_ray, None, true).is_err());
                assert!(!oracle.unreachable(&nan_ray, 1));
                assert!(oracle.equivalent_hits(&nan_ray, None, None) && !oracle.equivalent_hits(&nan_ray, h, None));
                assert!(!oracle.equivalent_occlusion(&nan_ray, true, false));
            }
        }
    }

    #[test]
    fn unreachable_hits_may_be_reported_or_not_but_never_before_a_reachable_one() {
        // Triangle 0 lies in z in [1, 1.5]; the rays run along +x at z = 2, above it.
        let tris = [
            [Vec3::new(1.0, -1.0, 1.0), Vec3::new(1.0, 1.0, 1.0), Vec3::new(1.0, 0.0, 1.5)],
            [Vec3::new(3.0, -1.0, 0.0), Vec3::new(3.0, 1.0, 0.0), Vec3::new(3.0, 0.0, 3.0)],
        ];
        let oracle = BruteForce::new(&tris, Intersector::Wald);
        let ray = Ray::new(Vec3::new(0.0, 0.0, 2.0), Vec3::X, 0.0, f32::INFINITY);
        assert!(oracle.unreachable(&ray, 0) && !oracle.unreachable(&ray, 1));
        let real = oracle.intersect(&ray).expect("triangle 1 is hit");
        assert_eq!(real.prim, 1);
        // A pretend artefact: triangle 0 reported at t = 1 (the test does not report it, so
        // it is no hit of the test and is refused).
        let fake = Hit { t: 1.0, u: 0.0, v: 0.0, prim: 0 };
        assert!(oracle.check(&ray, Some(fake), true).is_err());
        assert!(oracle.check(&ray, Some(real), true).is_ok());
        assert!(oracle.check(&ray, None, false).is_err());
        assert!(oracle.check(&ray, Some(real), false).is_err());
        // A ray with a zero component inside the triangle's range is reachable.
        let through = Ray::new(Vec3::new(0.0, 0.0, 1.2), Vec3::X, 0.0, f32::INFINITY);
        assert!(!oracle.unreachable(&through, 0));
        assert!(!oracle.unreachable(&Ray::new(Vec3::new(0.0, 0.0, 2.0), Vec3::new(1.0, 0.0, -0.5), 0.0, 1.0), 0));
    }

    #[test]
    fn rays_whose_segment_misses_the_triangle_exactly_are_unreachable() {
        // Triangle 0 spans x, y in [1, 2] at z = 0.
        let tris = [[Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, 1.0, 0.0), Vec3::new(1.0, 2.0, 0.0)]];
        let oracle = BruteForce::new(&tris, Intersector::Wald);
        let ray = |o: Vec3, d: Vec3, t_max: f32| Ray::new(o, d, 0.0, t_max);
        // A tiny non-zero x component (its reciprocal, 1e38, is finite, so it is kept): x
        // stays below 1e-8 for t in [0, 1e30], left of the triangle.
        let tiny = Vec3::new(1e-38, 0.0, -1.0);
        assert_ne!(Ray::new(Vec3::ZERO, tiny, 0.0, 1.0).dir.x, 0.0);
        assert!(oracle.unreachable(&ray(Vec3::new(0.0, 1.5, 1.0), tiny, 1e30), 0));
        // A ray in the triangle's plane with that x component reaches x = 1 at t = 1e38:
        // excused up to t = 1e30, not with an infinite interval.
        let in_plane = Vec3::new(1e-38, 0.0, 0.0);
        assert!(oracle.unreachable(&ray(Vec3::new(0.0, 1.5, 0.0), in_plane, 1e30), 0));
        assert!(!oracle.unreachable(&ray(Vec3::new(0.0, 1.5, 0.0), in_plane, f32::INFINITY), 0));
        // Every axis overlaps the box over the segment, but not at one time: it passes the
        // box's corner (x + y = 4.5 at z = 0, the corner has x + y = 4).
        let corner = ray(Vec3::new(2.5, 2.0, 1.0), Vec3::new(0.0, 0.0, -1.0) + Vec3::new(-1.0, 1.0, 0.0) * 0.5, 4.0);
        assert!(oracle.unreachable(&corner, 0));
        // Through the box's corner (2, 2, 0), outside the triangle; through its vertex (2, 1, 0)
        // exactly (touching counts as reaching), and through the middle.
        let box_corner = ray(Vec3::new(2.5, 1.5, 1.0), Vec3::new(-0.5, 0.5, -1.0), 4.0);
        assert!(oracle.unreachable(&box_corner, 0));
        let touch = ray(Vec3::new(2.5, 0.5, 1.0), Vec3::new(-0.5, 0.5, -1.0), 4.0);
        assert!(!oracle.unreachable(&touch, 0));
        assert!(!oracle.unreachable(&ray(Vec3::new(1.2, 1.2, 1.0), Vec3::new(0.0, 0.0, -1.0), 4.0), 0));
        // The segment ends just before the plane z = 0: one ulp short of t = 1.
        assert!(oracle.unreachable(&ray(Vec3::new(1.2, 1.2, 1.0), Vec3::new(0.0, 0.0, -1.0), 0.99999994), 0));
        assert!(!oracle.unreachable(&ray(Vec3::new(1.2, 1.2, 1.0), Vec3::new(0.0, 0.0, -1.0), 1.0), 0));
    }

    #[test]
    fn answers_may_differ_only_by_ties_and_unreachable_hits() {
        // Triangle 0 at z = 1 and its twin 1 (a tie); triangle 2 at z = 2, behind them.
        let tris = [
            [Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)],
            [Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)],
            [Vec3::new(0.0, 0.0, 2.0), Vec3::new(1.0, 0.0, 2.0), Vec3::new(0.0, 1.0, 2.0)],
        ];
        let oracle = BruteForce::new(&tris, Intersector::Wald);
        let ray = Ray::new(Vec3::new(0.2, 0.2, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        let first = oracle.intersect(&ray).expect("triangle 0 is hit");
        let twin = Hit { prim: 1, ..first };
        let far = Hit { t: 2.0, prim: 2, ..first };
        assert!(oracle.equivalent_hits(&ray, Some(first), Some(first)));
        assert!(oracle.equivalent_hits(&ray, Some(twin), Some(first)), "a tie");
        assert!(!oracle.equivalent_hits(&ray, Some(far), Some(first)), "a later hit");
        assert!(!oracle.equivalent_hits(&ray, None, Some(first)), "a miss");
        assert!(!oracle.equivalent_hits(&ray, Some(Hit { u: 0.3, ..first }), Some(first)), "other barycentrics");
        assert!(oracle.equivalent_occlusion(&ray, true, true));
        assert!(!oracle.equivalent_occlusion(&ray, false, true));
        let miss = Ray::new(Vec3::new(2.0, 2.0, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        assert!(!oracle.equivalent_occlusion(&miss, true, false), "no hit at all");

        // A sliver whose Wald record reports a hit for a ray that misses its box (the
        // `traversal` fuzz finding in `tests/fuzz_findings.rs`): either answer goes, for the
        // closest hit and the any-hit query.
        let sliver = [
            Vec3::new(2.3691403e-38, 2.3418052e-38, 1.01376515e-25),
            Vec3::new(2.3510604e-38, 9.19e-41, -1.5028658e-36),
            Vec3::new(2.1851257e37, -7.729682e-37, -7.065031e24),
        ];
        let oracle = BruteForce::new(&[sliver], Intersector::Wald);
        let ray = Ray::new(
            Vec3::new(-7.729682e-37, 2.3944935e-10, 1.7578e-41),
            Vec3::new(2.3476166e-38, -4.0658027e31, -2.9818803e-8),
            -2.729787e24,
            4.725e-41,
        );
        let artefact = oracle.intersect(&ray).expect("Wald's test reports it");
        assert!(oracle.unreachable(&ray, 0));
        assert!(oracle.equivalent_hits(&ray, None, Some(artefact)));
        assert!(oracle.equivalent_hits(&ray, Some(artefact), None));
        assert!(!oracle.equivalent_hits(&ray, Some(Hit { t: 1e-42, ..artefact }), None), "not a hit of the test");
        assert!(oracle.equivalent_occlusion(&ray, false, true));
        assert!(oracle.equivalent_occlusion(&ray, true, false));
    }
}
