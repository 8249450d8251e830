//! Every method of `Registry::ours()` gives the single-ray answer (`mono` on the same tree,
//! ties aside) on every built-in scene and view, the shared scenes when present, random
//! soups and the hard cases, with both triangle tests and at tiles 4, 8 and 16: primary
//! tiles, hard and soft shadows, ray streams closest and any hit; and `mono` agrees with the
//! brute-force oracle on the soups and hard cases. A newly registered method is picked up
//! without editing this file (see `trace::conformance`).

use trace::Registry;
use trace::conformance::{self, Plan};

/// The built-in scenes at every view (grove, 60k triangles, at the default view only).
#[test]
fn every_method_on_the_builtin_scenes() {
    let registry = Registry::ours();
    let cases = conformance::builtin_cases(31, 23, &[], &["grove"]);
    let report = conformance::run(&registry, &Plan::ours(&registry), &cases);
    eprintln!("{}", report.summary());
    report.assert_ok();
}

#[test]
fn every_method_on_soups_and_hard_cases() {
    let registry = Registry::ours();
    let mut cases = conformance::soup_cases(4);
    cases.extend(conformance::hard_cases());
    let report = conformance::run(&registry, &Plan::ours(&registry), &cases);
    eprintln!("{}", report.summary());
    report.assert_ok();
}

/// The shared OBJ scenes at their default view, tiny, with Wald's test (the default) only:
/// their trees take a second each to build (skipped without the shared folder).
#[test]
fn every_method_on_the_shared_scenes() {
    let cases = conformance::shared_cases(17, 11);
    if cases.is_empty() {
        eprintln!("no shared scenes folder: skipped");
        return;
    }
    let registry = Registry::ours();
    let plan = Plan { intersectors: vec![kdtree::Intersector::Wald], ..Plan::ours(&registry) };
    let report = conformance::run(&registry, &plan, &cases);
    eprintln!("{}", report.summary());
    report.assert_ok();
}
