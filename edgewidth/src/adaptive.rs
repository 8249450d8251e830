//! Adaptive stratified soft shadows: four probe samples per pixel, and the pixel's other 12
//! of 16 stratified samples only where probes disagree.
//!
//! A pixel's 16 samples are exactly those of 16 stratified samples ([`visible_fraction`]
//! with `n = 16` and the same generator), so a refined pixel gets that method's answer bit
//! for bit. The probes are the four corner strata of the 4x4 grid ([`PROBES`]): the light's
//! extremes, so that an occluder edge crossing the light separates two of them unless it only
//! clips a corner stratum's inner part. A pixel is refined when its own probes are not all
//! visible or all blocked, or when any of its eight neighbours' probes differ from its own
//! ([`needs_refining`]): the penumbra and a band of one pixel around it. Elsewhere (umbra and
//! fully lit surfaces) the pixel keeps its probes' 0 or 1.
//!
//! It therefore differs from 16 stratified samples only on pixels whose 16 samples would not
//! all agree while the probes of the pixel and of all its neighbours do: occluders thinner
//! than the gap between corner samples, or a penumbra narrower than a pixel that no
//! neighbour's probes see. That is its error, reported against the reference like every
//! method's (`rttest shadows`). Its cost is 4 rays per pixel plus 12 per refined pixel,
//! against 16. The idea is the classic one of adaptive supersampling (Whitted 1980): sample
//! sparsely and refine where neighbouring samples disagree.
//!
//! [`visible_fraction`]: crate::sampling::visible_fraction

use glam::Vec2;

use crate::sampling::{Rng, strata, stratified};

/// Samples per refined pixel.
pub const SAMPLES: u32 = 16;

/// The probes: the indices of the 4x4 grid's corner strata among the 16 samples.
pub const PROBES: [usize; 4] = [0, 3, 12, 15];

/// The samples traced only when a pixel is refined: all but the [`PROBES`], in order.
pub const REST: [usize; 12] = [1, 2, 4, 5, 6, 7, 8, 9, 10, 11, 13, 14];

/// Sample `k` of a pixel's [`SAMPLES`] on the unit square, for the pixel's generator `rng`
/// before any draw: the point [`visible_fraction`](crate::sampling::visible_fraction) with
/// `n = 16` and that generator draws `k`-th, reached without drawing the `2k` numbers before
/// it ([`Rng::skipped`]).
#[inline]
pub fn sample_position(rng: Rng, k: usize) -> Vec2 {
    stratified(k as u32, strata(SAMPLES), &mut rng.skipped(2 * k as u64))
}

/// Whether a pixel whose probes found `own` of 4 visible needs its other 12 samples: when
/// `own` is neither 0 nor 4, or when a neighbour's count (pixels without a hit left out)
/// differs from it.
#[inline]
pub fn needs_refining(own: u8, neighbours: impl IntoIterator<Item = u8>) -> bool {
    !(own == 0 || own == 4) || neighbours.into_iter().any(|n| n != own)
}

/// The visible fraction of a pixel: `(probes + rest) / 16` when refined, else the probes'
/// 0 or 1.
#[inline]
pub fn fraction(probes: u8, rest: Option<u8>) -> f32 {
    match rest {
        Some(rest) => f32::from(probes + rest) / SAMPLES as f32,
        None => f32::from(probes) / PROBES.len() as f32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::visible_fraction;
    use crate::sampling::{AreaLight, ShadingPoint};
    use glam::Vec3;
    use kdtree::{BuildConfig, Hit, KdTree};
    use scenes::{RectLight, SphereLight};

    /// A floor triangle under a light, a blocker half covering the light, as seen from
    /// points `x` along the floor.
    fn scene() -> (KdTree, [Vec3; 3]) {
        let floor = [Vec3::new(-50.0, 0.0, -50.0), Vec3::new(0.0, 0.0, 50.0), Vec3::new(50.0, 0.0, -50.0)];
        let blocker = [Vec3::new(-20.0, 2.0, -20.0), Vec3::new(0.05, 2.0, 20.0), Vec3::new(0.0, 2.0, -20.0)];
        (KdTree::build_soup(&[floor, blocker], &BuildConfig::default()).unwrap(), floor)
    }

    #[test]
    fn probes_and_rest_are_the_sixteen_samples_of_visible_fraction() {
        let (tree, floor) = scene();
        let rect =
            RectLight { corner: Vec3::new(-0.5, 4.0, -0.5), edge_u: Vec3::X, edge_v: Vec3::Z, intensity: Vec3::ONE };
        let sphere = SphereLight { center: Vec3::new(0.0, 4.0, 0.0), radius: 0.6, intensity: Vec3::ONE };
        let mut partial = 0;
        for light in [AreaLight::Rect(rect), AreaLight::Sphere(sphere)] {
            for i in 0..200 {
                // Points across the blocker's edge, from umbra to fully lit.
                let u = 0.2 + 0.6 * i as f32 / 200.0;
                let hit = Hit { t: 1.0, u, v: 0.5 * (1.0 - u), prim: 0 };
                let p = ShadingPoint::new(floor, hit, Vec3::NEG_Y);
                let seed = 1000 + i as u64;
                let all = visible_fraction(&tree, &light, &p, 16, &mut Rng::new(seed));
                // The samples `which`, traced one by one as `visible_fraction` traces them.
                let seen = |which: &[usize]| {
                    let target = |k: usize| light.sample(p.point, sample_position(Rng::new(seed), k));
                    which.iter().filter_map(|&k| p.shadow_ray(target(k))).filter(|r| !tree.occluded(r)).count() as u8
                };
                let (probes, rest) = (seen(&PROBES), seen(&REST));
                assert_eq!(fraction(probes, Some(rest)), all, "point {i}");
                partial += usize::from(all > 0.0 && all < 1.0);
                // Unrefined, a pixel keeps its probes' answer: exact wherever all 16 agree.
                if all == 0.0 || all == 1.0 {
                    assert_eq!(fraction(probes, None), all);
                }
            }
        }
        assert!(partial > 10, "the points cross a penumbra: {partial}");
    }

    #[test]
    fn the_probes_are_the_corner_strata() {
        for (&k, corner) in PROBES.iter().zip([(0, 0), (3, 0), (0, 3), (3, 3)]) {
            let s = sample_position(Rng::new(5), k);
            assert_eq!(((s.x * 4.0) as u32, (s.y * 4.0) as u32), corner);
        }
        // Random access gives the sequential draws.
        let mut rng = Rng::new(5);
        for k in 0..SAMPLES as usize {
            assert_eq!(sample_position(Rng::new(5), k), stratified(k as u32, strata(SAMPLES), &mut rng));
        }
        let mut all: Vec<usize> = PROBES.iter().chain(&REST).copied().collect();
        all.sort_unstable();
        assert_eq!(all, (0..16).collect::<Vec<_>>());
    }

    #[test]
    fn only_agreeing_neighbourhoods_are_left_unrefined() {
        assert!(!needs_refining(0, [0, 0, 0]));
        assert!(!needs_refining(4, [4; 8]));
        assert!(!needs_refining(4, []));
        for own in 1..4 {
            assert!(needs_refining(own, [own; 8]), "mixed probes");
        }
        assert!(needs_refining(4, [4, 4, 3]));
        assert!(needs_refining(0, [4]));
        assert_eq!(fraction(4, None), 1.0);
        assert_eq!(fraction(0, None), 0.0);
        assert_eq!(fraction(2, Some(7)), 9.0 / 16.0);
    }
}
