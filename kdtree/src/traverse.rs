//! Single-ray traversal.
use crate::{Hit, KdTree, Ray};
impl KdTree {
    /// Closest hit.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let _ = ray;
        todo!()
    }
    /// Any hit.
    pub fn occluded(&self, ray: &Ray) -> bool {
        let _ = ray;
        todo!()
    }
}
