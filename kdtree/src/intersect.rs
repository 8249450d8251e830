//! The triangle test as a type: [`TreeTest`], implemented by the zero-sized [`WaldTest`] and
//! [`WatertightTest`], names a tree's [`Intersector`] at compile time, with its per-triangle
//! records and SIMD leaf groups. A kernel generic over `I: TreeTest` reads `I::records(tree)`
//! and `I::groups(tree)` and never matches on the intersector; the choice is made once, where
//! a method is bound to a tree (a `match tree.intersector()` that picks `I`).

use crate::KdTree;
use crate::leaf::{LeafGroup, ShearedSplat, SplatRay, Wald4, Watertight4};
use crate::triangle::{Intersector, TriangleTest, WaldTriangle, WatertightTriangle};

/// A tree's ray-triangle test as a type parameter: the [`Intersector`] it stands for, its
/// per-triangle record and its SIMD leaf group, and the tree's arrays of them.
///
/// A tree holds the records and groups of its own intersector only. Binding must pick the
/// `I` whose [`TreeTest::INTERSECTOR`] is `tree.intersector()` (as [`KdTree::intersect`] and
/// every kernel's convenience entry point do); the accessors check that in debug builds, and
/// in release a wrong `I` reads the other test's arrays, which are empty: no UB, a kernel
/// indexing them panics on the bounds check (and a tree without triangles reports no hit).
pub trait TreeTest: Copy + Send + Sync + 'static {
    /// The intersector this type names.
    const INTERSECTOR: Intersector;
    /// The per-triangle record (packet, frustum, cone and edge-width kernels, scalar leaves).
    type Record: TriangleTest;
    /// The 4-triangle SIMD leaf group of [`crate::leaf`] (single rays).
    type Group: LeafGroup<Record = Self::Record>;
    /// The tree's records of this test, one per triangle (empty if the tree was built for
    /// the other test).
    fn records(tree: &KdTree) -> &[Self::Record];
    /// The tree's SIMD leaf groups of this test (empty if the tree was built for the other).
    fn groups(tree: &KdTree) -> &[Self::Group];
    /// This test's buffer of rays prepared for the SIMD leaf groups, in `buffers`.
    fn prepared(buffers: &mut PreparedRays) -> &mut Vec<<Self::Group as LeafGroup>::RayData>;
}

/// Reusable buffers of rays prepared for each test's SIMD leaf groups
/// ([`LeafGroup::prepare`]), for a kernel that prepares many rays at once and keeps the
/// buffer between calls (a shadow frustum's rays); [`TreeTest::prepared`] picks the test's.
#[derive(Clone, Debug, Default)]
pub struct PreparedRays {
    wald: Vec<SplatRay>,
    watertight: Vec<ShearedSplat>,
}

/// Wald's projected-barycentric test (thesis 4.2) as a type: [`Intersector::Wald`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct WaldTest;

/// The watertight test of Woop, Benthin & Wald (JCGT 2013) as a type:
/// [`Intersector::Watertight`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct WatertightTest;

impl TreeTest for WaldTest {
    const INTERSECTOR: Intersector = Intersector::Wald;
    type Record = WaldTriangle;
    type Group = Wald4;

    #[inline(always)]
    fn records(tree: &KdTree) -> &[WaldTriangle] {
        debug_assert_eq!(tree.intersector(), Self::INTERSECTOR, "a Wald kernel bound to a watertight tree");
        tree.wald_records()
    }

    #[inline(always)]
    fn groups(tree: &KdTree) -> &[Wald4] {
        debug_assert_eq!(tree.intersector(), Self::INTERSECTOR, "a Wald kernel bound to a watertight tree");
        tree.wald_groups()
    }

    #[inline(always)]
    fn prepared(buffers: &mut PreparedRays) -> &mut Vec<SplatRay> {
        &mut buffers.wald
    }
}

impl TreeTest for WatertightTest {
    const INTERSECTOR: Intersector = Intersector::Watertight;
    type Record = WatertightTriangle;
    type Group = Watertight4;

    #[inline(always)]
    fn records(tree: &KdTree) -> &[WatertightTriangle] {
        debug_assert_eq!(tree.intersector(), Self::INTERSECTOR, "a watertight kernel bound to a Wald tree");
        tree.watertight_records()
    }

    #[inline(always)]
    fn groups(tree: &KdTree) -> &[Watertight4] {
        debug_assert_eq!(tree.intersector(), Self::INTERSECTOR, "a watertight kernel bound to a Wald tree");
        tree.watertight_groups()
    }

    #[inline(always)]
    fn prepared(buffers: &mut PreparedRays) -> &mut Vec<ShearedSplat> {
        &mut buffers.watertight
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::{BuildConfig, Ray};

    fn tree(intersector: Intersector) -> KdTree {
        let tris = [[Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)]];
        KdTree::build_soup(&tris, &BuildConfig { intersector, ..Default::default() }).expect("one triangle builds")
    }

    /// Each type names its intersector, and on a tree of that intersector reads the tree's
    /// own arrays (one record per triangle, one group per 4 references).
    #[test]
    fn each_test_reads_its_own_arrays() {
        assert_eq!(WaldTest::INTERSECTOR, Intersector::Wald);
        assert_eq!(WatertightTest::INTERSECTOR, Intersector::Watertight);
        let wald = tree(Intersector::Wald);
        assert_eq!(WaldTest::records(&wald), wald.wald_records());
        assert_eq!(WaldTest::records(&wald).len(), 1);
        assert_eq!(WaldTest::groups(&wald).len(), wald.prim_refs().len() / 4);
        assert!(!WaldTest::groups(&wald).is_empty());
        let watertight = tree(Intersector::Watertight);
        assert_eq!(WatertightTest::records(&watertight), watertight.watertight_records());
        assert_eq!(WatertightTest::records(&watertight).len(), 1);
        assert!(!WatertightTest::groups(&watertight).is_empty());
    }

    /// The generic single-ray kernel with the tree's own test is the convenience entry point,
    /// for both intersectors; a tree holds only its own test's arrays (so binding the other
    /// test would find nothing to read: `bind` always picks the tree's own).
    #[test]
    fn the_tree_holds_only_its_own_test() {
        let ray = Ray::new(Vec3::new(0.2, 0.2, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        let wald = tree(Intersector::Wald);
        assert!(wald.watertight_records().is_empty() && wald.watertight_groups().is_empty());
        assert_eq!(wald.intersect_with::<WaldTest>(&ray), wald.intersect(&ray));
        assert!(wald.intersect(&ray).is_some());
        let watertight = tree(Intersector::Watertight);
        assert!(watertight.wald_records().is_empty() && watertight.wald_groups().is_empty());
        assert_eq!(watertight.intersect_with::<WatertightTest>(&ray), watertight.intersect(&ray));
        assert!(watertight.occluded_with::<WatertightTest>(&ray));
    }
}
