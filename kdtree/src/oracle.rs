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
