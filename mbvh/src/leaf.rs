//! Leaf blocks: up to four triangles of a leaf, stored SoA and tested against one ray at once
//! (Wald, Benthin & Boulos 2008, section 5.6: the leaf's triangles "pre-gathered during
//! building" in SoA form, then an N-wide test and a reduction to the closest hit).
//!
//! A block is one group of `kdtree::leaf` (the kd-tree's SIMD leaves: [`Wald4`] for Wald's
//! projected-barycentric test, thesis 4.2, and [`Watertight4`] for Woop, Benthin & Wald 2013)
//! with the triangle ids of its lanes. The groups compute, lane for lane, the operations of
//! the scalar tests of `kdtree::triangle`, so a lane's `(t, u, v)` is the scalar test's bit for
//! bit (tested there, and here against the scalar records and through the traversal in
//! `tests/oracle.rs`); unused lanes hold NaN records, which never hit. The BVH's own rule for
//! ties is the lowest lane at equal `t`, in both the SIMD block and its scalar twin.

use std::any::Any;

use glam::{BVec4A, Vec4};
use kdtree::Ray;
use kdtree::leaf::{GroupHits, LeafGroup, Wald4, Watertight4};
use kdtree::triangle::TriangleTest;

pub use kdtree::leaf::LANES;

/// A 4-wide leaf test: the block of one intersector.
pub trait LeafBlock: Copy + Send + Sync + 'static {
    /// The scalar record it packs (`kdtree::triangle`).
    type Record: TriangleTest + Copy;
    /// What the test precomputes once per ray.
    type RayData: Copy;
    /// The per-ray precomputation.
    fn prepare(ray: &Ray) -> Self::RayData;
    /// The block of up to four records with their triangle ids (unused lanes never hit).
    ///
    /// # Panics
    /// With more than [`LANES`] records (the build makes leaves of at most four).
    fn pack(records: &[(Self::Record, u32)]) -> Self;
    /// The record of `lane` and its triangle id (`u32::MAX` for an unused lane).
    fn record(&self, lane: usize) -> (Self::Record, u32);
    /// The triangle id of `lane` (`u32::MAX` for an unused lane).
    fn record_prim(&self, lane: usize) -> u32;
    /// The closest hit in `[ray.t_min, t_max]` among the lanes, as `(lane, t, u, v)`; at
    /// equal `t` the lowest lane.
    fn closest(&self, ray: &Ray, data: &Self::RayData, t_max: f32) -> Option<(usize, f32, f32, f32)>;
    /// Whether any lane is hit in `[ray.t_min, t_max]`.
    fn any(&self, ray: &Ray, data: &Self::RayData, t_max: f32) -> bool;
    /// The block's Wald group if it holds Wald records (for the packets' 16-lane leaf test,
    /// [`crate::packet`]), else `None`.
    #[inline(always)]
    fn wald_group(&self) -> Option<&Wald4> {
        None
    }
    /// The scalar twin of [`LeafBlock::closest`]: the records one by one.
    fn closest_scalar(&self, ray: &Ray, t_max: f32) -> Option<(usize, f32, f32, f32)> {
        let data = Self::Record::prepare(ray);
        let mut best: Option<(usize, f32, f32, f32)> = None;
        for lane in 0..LANES {
            let (rec, _) = self.record(lane);
            let limit = best.map_or(t_max, |b| b.1);
            if let Some((t, u, v)) = rec.intersect(ray, &data, limit)
                && best.is_none_or(|b| t < b.1)
            {
                best = Some((lane, t, u, v));
            }
        }
        best
    }
}

/// The closest valid lane of `t` (lowest lane at equal `t`).
#[inline(always)]
fn reduce(valid: BVec4A, t: Vec4) -> Option<usize> {
    if !valid.any() {
        return None;
    }
    let ts = Vec4::select(valid, t, Vec4::INFINITY);
    let m = ts.min_element();
    let at = ts.cmpeq(Vec4::splat(m)) & valid;
    Some(at.bitmask().trailing_zeros() as usize)
}

/// A group of `kdtree::leaf` and the triangle ids of its lanes (`u32::MAX`: unused).
#[derive(Clone, Copy, Debug)]
pub struct Block<G> {
    group: G,
    prim: [u32; LANES],
}

/// A block of Wald records (thesis 4.2).
pub type WaldBlock = Block<Wald4>;

/// A block of watertight records (Woop, Benthin & Wald 2013).
pub type WatertightBlock = Block<Watertight4>;

impl<G: LeafGroup + 'static> LeafBlock for Block<G>
where
    G::Record: Copy,
{
    type Record = G::Record;
    type RayData = G::RayData;

    #[inline(always)]
    fn prepare(ray: &Ray) -> G::RayData {
        G::prepare(ray)
    }

    fn pack(records: &[(G::Record, u32)]) -> Block<G> {
        assert!(records.len() <= LANES, "a block holds at most {LANES} triangles");
        let recs: Vec<G::Record> = records.iter().map(|r| r.0).collect();
        Block { group: G::new(&recs), prim: std::array::from_fn(|i| records.get(i).map_or(u32::MAX, |r| r.1)) }
    }

    fn record(&self, lane: usize) -> (G::Record, u32) {
        (self.group.lane(lane), self.prim[lane])
    }

    #[inline(always)]
    fn record_prim(&self, lane: usize) -> u32 {
        self.prim[lane]
    }

    #[inline(always)]
    fn closest(&self, ray: &Ray, data: &G::RayData, t_max: f32) -> Option<(usize, f32, f32, f32)> {
        let GroupHits { mask, t, u, v } = self.group.intersect(ray, data, t_max);
        let lane = reduce(mask, t)?;
        Some((lane, t.to_array()[lane], u.to_array()[lane], v.to_array()[lane]))
    }

    #[inline(always)]
    fn any(&self, ray: &Ray, data: &G::RayData, t_max: f32) -> bool {
        self.group.intersect(ray, data, t_max).mask.any()
    }

    #[inline(always)]
    fn wald_group(&self) -> Option<&Wald4> {
        // A type comparison, decided at compile time.
        (&self.group as &dyn Any).downcast_ref::<Wald4>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use kdtree::triangle::{WaldTriangle, WatertightTriangle};
    use proptest::prelude::*;

    fn tri(c: &[f32; 9]) -> [Vec3; 3] {
        [Vec3::new(c[0], c[1], c[2]), Vec3::new(c[3], c[4], c[5]), Vec3::new(c[6], c[7], c[8])]
    }

    /// Every lane of the block against the scalar record: the same hit, bit for bit.
    fn lanes_equal_scalar<B: LeafBlock>(tris: &[[Vec3; 3]], ray: &Ray, new: fn(&[Vec3; 3]) -> B::Record) {
        let recs: Vec<(B::Record, u32)> = tris.iter().enumerate().map(|(i, t)| (new(t), i as u32)).collect();
        let block = B::pack(&recs);
        let data = B::prepare(ray);
        let got = block.closest(ray, &data, ray.t_max);
        let want = block.closest_scalar(ray, ray.t_max);
        let bits = |h: Option<(usize, f32, f32, f32)>| h.map(|(l, t, u, v)| (l, t.to_bits(), u.to_bits(), v.to_bits()));
        assert_eq!(bits(got), bits(want), "{ray:?}");
        assert_eq!(block.any(ray, &data, ray.t_max), want.is_some());
        // Each lane alone equals the scalar test.
        let sdata = B::Record::prepare(ray);
        for (lane, (rec, prim)) in recs.iter().enumerate() {
            assert_eq!(block.record(lane).1, *prim);
            let s = rec.intersect(ray, &sdata, ray.t_max);
            let alone = B::pack(&recs[lane..=lane]).closest(ray, &B::prepare(ray), ray.t_max);
            assert_eq!(
                alone.map(|h| (h.1.to_bits(), h.2.to_bits(), h.3.to_bits())),
                s.map(|(t, u, v)| (t.to_bits(), u.to_bits(), v.to_bits()))
            );
        }
    }

    fn coord() -> impl Strategy<Value = f32> {
        prop_oneof![(-4i32..5).prop_map(|i| i as f32 * 0.5), -2.0f32..2.0]
    }

    proptest! {
        #[test]
        fn blocks_equal_the_scalar_tests(
            tris in prop::collection::vec(prop::array::uniform9(coord()), 1..5),
            o in prop::array::uniform3(coord()), d in prop::array::uniform3(coord()),
        ) {
            let tris: Vec<[Vec3; 3]> = tris.iter().map(tri).collect();
            let d = Vec3::new(d[0], d[1], d[2]);
            prop_assume!(d != Vec3::ZERO);
            let ray = Ray::new(Vec3::new(o[0], o[1], o[2]) * 3.0, d, 0.0, f32::INFINITY);
            lanes_equal_scalar::<WaldBlock>(&tris, &ray, WaldTriangle::new);
            lanes_equal_scalar::<WatertightBlock>(&tris, &ray, WatertightTriangle::new);
        }
    }

    #[test]
    fn shared_edges_use_the_scalar_fallback_and_agree() {
        // Rays exactly through the shared diagonal: edge functions exactly zero.
        let t0 = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)];
        let t1 = [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        for i in 0..=8 {
            let s = i as f32 / 8.0;
            let ray = Ray::new(Vec3::new(s, s, 2.0), -Vec3::Z, 0.0, f32::INFINITY);
            lanes_equal_scalar::<WatertightBlock>(&[t0, t1], &ray, WatertightTriangle::new);
            lanes_equal_scalar::<WaldBlock>(&[t0, t1], &ray, WaldTriangle::new);
            let block = WatertightBlock::pack(&[(WatertightTriangle::new(&t0), 0), (WatertightTriangle::new(&t1), 1)]);
            assert!(block.closest(&ray, &WatertightBlock::prepare(&ray), f32::INFINITY).is_some(), "leak at {s}");
        }
    }

    #[test]
    fn unused_lanes_and_degenerate_triangles_never_hit() {
        let flat = [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X];
        let ray = Ray::new(Vec3::new(0.5, 0.0, -1.0), Vec3::Z, f32::NEG_INFINITY, f32::INFINITY);
        let w = WaldBlock::pack(&[(WaldTriangle::new(&flat), 7)]);
        assert!(w.closest(&ray, &WaldBlock::prepare(&ray), f32::INFINITY).is_none());
        let wt = WatertightBlock::pack(&[(WatertightTriangle::new(&flat), 7)]);
        assert!(!wt.any(&ray, &WatertightBlock::prepare(&ray), f32::INFINITY));
        assert_eq!(wt.record(1).1, u32::MAX);
    }
}
