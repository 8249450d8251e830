//! Every method of `Registry::ours()` gives the single-ray answer (`mono` on the same tree,
//! ties aside) on every built-in scene and view, the shared scenes when present, random
//! soups and the hard cases, with both triangle tests and at tiles 4, 8 and 16: primary
//! tiles, hard and soft shadows, ray streams closest and any hit; and `mono` agrees with the
//! brute-force oracle on the soups and hard cases. A newly registered method is picked up
//! without editing this file (see the crate's documentation).

use conformance::Plan;
use trace::Registry;

/// The built-in scenes at every view (grove and garage, the largest, at the default view only;
/// not the material variants, whose geometry is another scene's).
#[test]
fn every_method_on_the_builtin_scenes() {
    let registry = Registry::ours();
    let cases = conformance::builtin_cases(31, 23, scenes::builtin::MATERIAL_VARIANTS, &["grove", "garage"]);
    conformance::assert_conforms(&registry, &Plan::ours(&registry), &cases);
}

#[test]
fn every_method_on_soups_and_hard_cases() {
    let registry = Registry::ours();
    let mut cases = conformance::soup_cases(4);
    cases.extend(conformance::hard_cases());
    conformance::assert_conforms(&registry, &Plan::ours(&registry), &cases);
}

/// The shared OBJ scenes at their default view, tiny, with Wald's test (the default) only:
/// their trees take a second each to build (skipped without the shared folder).
#[test]
fn every_method_on_the_shared_scenes() {
    let Some(cases) = conformance::shared_cases_or_skip(17, 11) else { return };
    let registry = Registry::ours();
    let plan = Plan { intersectors: vec![kdtree::Intersector::Wald], ..Plan::ours(&registry) };
    conformance::assert_conforms(&registry, &plan, &cases);
}

#[path = "../../packets/tests/common/mod.rs"]
mod common;

mod random {
    use super::common::vertex;
    use conformance::{Case, Plan};
    use glam::Vec3;
    use proptest::prelude::*;
    use scenes::Camera;
    use trace::Registry;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

        /// Random soups (sharing vertices and axis planes) seen by random cameras inside and
        /// outside them, narrow and wide, lit from random points: every method at every tile
        /// size gives the single ray's answers (primary, hard and soft shadows, streams),
        /// which agree with the brute-force oracle.
        #[test]
        fn every_method_on_random_soups_and_cameras(
            tris in prop::collection::vec((vertex(), vertex(), vertex()), 1..120),
            eye in vertex(), target in vertex(), wide in any::<bool>(), light in vertex(), seed in any::<u64>(),
        ) {
            let tris: Vec<[Vec3; 3]> = tris.into_iter().map(|(a, b, c)| [a, b, c]).collect();
            let eye = eye * 1.5;
            prop_assume!((target - eye).length() > 1e-3 && (target - eye).normalize().y.abs() < 0.999);
            let camera = Camera::look_at(eye, target, if wide { 150.0 } else { 40.0 }, 24, 20).unwrap();
            let mut scene = conformance::soup_scene("random soup", &tris);
            scene.point_light.position = light * 1.2;
            let case = Case::new("random soup", scene, vec![("random".into(), camera)], true, seed);
            let registry = Registry::ours();
            let report = conformance::run(&registry, &Plan::ours(&registry), &[case]);
            prop_assert!(report.failing().is_empty(), "{}", report.summary());
        }
    }
}
