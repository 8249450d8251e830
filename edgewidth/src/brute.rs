//! The brute-force twin of the edge-width traversal: every triangle along the segment,
//! sorted and paired the same way ([`crate::pairing`]). The reference the kernels are tested
//! against; `O(N)` per ray.

use kdtree::triangle::TriangleTest;
use kdtree::{Intersector, KdTree, Ray};

use crate::pairing::{HitList, LeakRemedies, Pairing};

/// The edge width of `ray` from all of `tree`'s triangles (same contract as
/// [`crate::edge_width`]: infinite past `r` or with an entry never closed, `0` for a NaN
/// ray).
pub fn edge_width_brute(tree: &KdTree, ray: &Ray, r: f32, remedies: &LeakRemedies) -> f32 {
    match tree.intersector() {
        Intersector::Wald => brute(tree, tree.wald_records(), ray, r, remedies),
        Intersector::Watertight => brute(tree, tree.watertight_records(), ray, r, remedies),
    }
}

fn brute<T: TriangleTest>(tree: &KdTree, records: &[T], ray: &Ray, r: f32, remedies: &LeakRemedies) -> f32 {
    let prepared = T::prepare(ray);
    let mut list = HitList::default();
    for (prim, record) in records.iter().enumerate() {
        if let Some((t, _, _)) = record.intersect(ray, &prepared, ray.t_max) {
            list.insert(t, prim as u32, tree, ray.dir);
        }
    }
    let mut pairing = Pairing::new();
    if list.flush_below(f32::INFINITY, r, &mut pairing, tree, remedies) {
        return f32::INFINITY;
    }
    let width = pairing.finish();
    if width > r { f32::INFINITY } else { width }
}
