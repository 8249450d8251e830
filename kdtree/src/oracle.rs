//! The brute-force oracle: every triangle, closest hit.
//!
//! It runs the same triangle test as the tree it checks, so any disagreement is a traversal
//! error, never a difference in intersection arithmetic: a tree hit has exactly the oracle's
//! distance (bit for bit), and may name another triangle only when both lie at that distance.

use glam::Vec3;

use crate::triangle::{Intersector, TriangleTest, WaldTriangle, WatertightTriangle};
use crate::{Hit, KdTree, Ray};

/// A brute-force intersector over all triangles.
#[derive(Clone, Debug)]
pub struct BruteForce {
    intersector: Intersector,
    wald: Vec<WaldTriangle>,
    watertight: Vec<WatertightTriangle>,
}

impl BruteForce {
    /// The oracle for a triangle soup with the given test.
    pub fn new(tris: &[[Vec3; 3]], intersector: Intersector) -> BruteForce {
        BruteForce {
            intersector,
            wald: tris.iter().map(WaldTriangle::new).collect(),
            watertight: tris.iter().map(WatertightTriangle::new).collect(),
        }
    }

    /// The oracle for the triangles of `tree`, with the tree's test.
    pub fn for_tree(tree: &KdTree) -> BruteForce {
        BruteForce::new(&tree.tris, tree.intersector)
    }

    /// The closest hit over all triangles; ties go to the lowest triangle index.
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

    /// Checks the answers of a traversal method for `ray` (its closest hit `got` and its
    /// any-hit answer `occluded`) against this oracle, naming the first disagreement.
    ///
    /// The method must report the oracle's closest distance bit for bit (both run the same
    /// triangle test), the same triangle or another at exactly that distance (a tie), and the
    /// same any-hit answer. One ambiguity is allowed, and only one: a hit so close to the
    /// origin that it lies within the rounding error of the origin's own position
    /// (`t |d| <= 64 ulp(max |o|)`). Such a hit is an artefact of an origin on (or one ulp
    /// off) a surface: the triangle test may round the distance to 0 for a point the ray never
    /// reaches in exact arithmetic, while traversal follows exact arithmetic. The method may
    /// report it or not; past it, it must agree.
    pub fn check(&self, ray: &Ray, got: Option<Hit>, occluded: bool) -> Result<(), String> {
        let want = self.intersect(ray);
        let is_hit = |g: &Hit| self.all_hits(ray).iter().any(|&(t, p)| p == g.prim && t == g.t);
        let near = ray.origin.abs().max_element() * (64.0 * f32::EPSILON) / ray.dir.length();
        if let Some(w) = want.filter(|w| w.t <= near && w.t >= ray.t_min) {
            let beyond = self.intersect(&Ray::new(ray.origin, ray.dir, near.next_up(), ray.t_max));
            let ok = match got {
                None => beyond.is_none(),
                Some(g) if g.t <= near => is_hit(&g),
                Some(g) => beyond.is_some_and(|b| b.t == g.t),
            };
            if !ok || (beyond.is_some() && !occluded) {
                return Err(format!("ray {ray:?}: got {got:?} (occluded {occluded}), oracle {w:?} then {beyond:?}"));
            }
            return Ok(());
        }
        match (got, want) {
            (None, None) => {}
            (Some(g), Some(w)) => {
                if g.t != w.t {
                    return Err(format!("ray {ray:?}: got {g:?}, oracle {w:?}"));
                }
                if g.prim != w.prim && !is_hit(&g) {
                    return Err(format!("ray {ray:?}: got {g:?}, not an oracle hit (oracle {w:?})"));
                }
            }
            (g, w) => return Err(format!("ray {ray:?}: got {g:?}, oracle {w:?}")),
        }
        if occluded != want.is_some() {
            return Err(format!("ray {ray:?}: occluded {occluded}, oracle hit {want:?}"));
        }
        Ok(())
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
}
