//! The soft-shadow kernels against single rays ([`trace::kernel::soft`]).

use cones::shadows::SAMPLES;
use kdtree::{KdTree, Ray, WaldTest};
use packets::LaneWidth;
use scenes::Tile;
use trace::kernel::soft::{Cone, Frusta, Lanes, OmniPoints, Pyramid, Single, StratumPackets};
use trace::kernel::{SoftShadow, shadow};
use trace::method::{ShadowJob, SoftJob, SoftStats, primary_ray};
use trace::setup::load_and_build;

/// Every soft-shadow kernel answers a point's 16 rays (`Method::soft_point`) as single
/// rays do, and a tile's soft shadows (`Method::soft_tile`) with the same visible
/// fractions, on the atrium's points.
#[test]
fn every_soft_kernel_gives_single_rays_answers() {
    let (scene, tree, _) = load_and_build("atrium", &Default::default()).unwrap();
    // The default build is for Wald's test: the kernels are called with it.
    assert_eq!(tree.intersector(), kdtree::Intersector::Wald);
    let camera = scene.default_view().camera(24, 16).unwrap();
    let tile = Tile { x0: 0, y0: 0, x1: 24, y1: 16 };
    let hits: Vec<_> = tile.pixels().map(|(x, y)| tree.intersect(&primary_ray(&camera, x, y))).collect();
    let surfaces = trace::shade::surfaces(&scene.mesh);
    let light = trace::soft::scene_light(&scene, &tree, 2.0);
    let job = SoftJob {
        hits: ShadowJob { scene: &scene, surfaces: &surfaces, camera: &camera, tile: &tile, hits: &hits },
        light: &light,
    };
    let points: Vec<_> = (0..hits.len()).filter_map(|i| job.point(i)).collect();
    assert!(points.len() > 100);
    let want: Vec<u16> = points
        .iter()
        .map(|(rays, cone)| Single.soft_point::<WaldTest, _>(&tree, &mut (), rays, cone, &mut kdtree::NoCounters))
        .collect();
    assert!(want.iter().any(|&m| m != 0) && want.iter().any(|&m| m != u16::MAX), "some rays blocked, some not");
    let mut visible = vec![0.0; hits.len()];
    let want_stats = Single.soft_tile::<WaldTest, _>(&tree, &mut (), &job, &mut visible, &mut kdtree::NoCounters);
    fn check<S: SoftShadow>(
        kernel: S,
        tree: &KdTree,
        job: &SoftJob<'_>,
        points: &[([Ray; SAMPLES], cones::Cone)],
        want: &[u16],
        tile: (&[f32], SoftStats),
    ) {
        let mut scratch = kernel.scratch();
        for ((rays, cone), &w) in points.iter().zip(want) {
            assert_eq!(
                kernel.soft_point::<WaldTest, _>(tree, &mut scratch, rays, cone, &mut kdtree::NoCounters),
                w,
                "{}",
                kernel.name()
            );
        }
        let mut visible = vec![0.0; tile.0.len()];
        assert_eq!(
            kernel.soft_tile::<WaldTest, _>(tree, &mut scratch, job, &mut visible, &mut kdtree::NoCounters),
            tile.1,
            "{}",
            kernel.name()
        );
        assert_eq!(visible, tile.0, "{}", kernel.name());
    }
    let tile = (&visible[..], want_stats);
    check(Pyramid, &tree, &job, &points, &want, tile);
    check(Cone, &tree, &job, &points, &want, tile);
    check(OmniPoints, &tree, &job, &points, &want, tile);
    for width in packets::Width::ALL {
        check(StratumPackets { packets: shadow::Packets { width } }, &tree, &job, &points, &want, tile);
    }
    check(Frusta { tile: 24 }, &tree, &job, &points, &want, tile);
    for width in [LaneWidth::Scalar, LaneWidth::Four, LaneWidth::widest()] {
        check(Lanes { width }, &tree, &job, &points, &want, tile);
    }
}
