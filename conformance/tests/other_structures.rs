//! Our methods on structures other than the kd-tree (the 4-, 8- and 16-wide BVHs `mbvh-4`,
//! `mbvh-8` and `mbvh-16`, and the 8-wide tree's 16-ray packets `mbvh-8-p16`; on a CPU with
//! AVX2 `mbvh-8` runs its AVX2 node test, with AVX-512 `mbvh-16` its AVX-512 one and
//! `mbvh-8-p16` its AVX-512 packets, and their scalar twins `NAME@sse` (scalar node tests,
//! portable packet lanes) are checked against the oracle too) through the
//! conformance harness (this crate): every query (primary tiles at tiles 4, 8 and
//! 16, hard and soft shadows, streams closest and any hit) against `mono` on the kd-tree
//! built with the same triangle test, under `Rule::Equivalent` (the hit `mono` reports, a tie
//! at the same distance, or a difference the oracle accepts: a rounding artefact on a
//! triangle the ray cannot reach exactly: the two structures test different triangles, so
//! they need not meet the same artefacts), and each method's single rays against the
//! brute-force oracle of the same test exactly. Both intersectors; built-in scenes at every
//! view, soups, the hard cases, the shared scenes when present. `Plan::ours` covers the
//! kd-tree methods only; a new method of ours on another structure is picked up here.

use conformance::{Check, OracleCheck, OracleTest, Plan, Rule};
use kdtree::isa::SimdLevel;
use trace::Registry;
use trace::registry::{KDTREE, Options};

fn plan(registry: &Registry) -> Plan {
    let (mut checks, mut oracles) = (Vec::new(), Vec::new());
    for e in registry.entries().iter().filter(|e| e.family == "ours" && e.structure != KDTREE) {
        for tile in conformance::TILES {
            let options = Options { tile, ..Options::default() };
            checks.push(Check { method: e.name.into(), options, reference: "mono".into(), rule: Rule::Equivalent });
        }
        oracles.push(OracleCheck { method: e.name.into(), test: OracleTest::Tree, rule: Rule::Exact });
        // The scalar twins of the SIMD node tests, where the CPU runs those (`mbvh-8@sse`,
        // `mbvh-16@sse`: the scalar node test), against the oracle too.
        if SimdLevel::detect() >= SimdLevel::Avx2 {
            let twin = format!("{}@sse", e.name);
            oracles.push(OracleCheck { method: twin, test: OracleTest::Tree, rule: Rule::Exact });
        }
    }
    for name in ["mbvh-4", "mbvh-8", "mbvh-16", "mbvh-8-p16"] {
        assert!(oracles.iter().any(|o| o.method == name), "{name} is not checked");
    }
    Plan { checks, oracles, ..Plan::ours(registry) }
}

#[test]
fn other_structures_on_the_builtin_scenes() {
    let registry = Registry::ours();
    let cases = conformance::builtin_cases(31, 23, scenes::builtin::MATERIAL_VARIANTS, &["grove", "garage"]);
    conformance::assert_conforms(&registry, &plan(&registry), &cases);
}

#[test]
fn other_structures_on_soups_and_hard_cases() {
    let registry = Registry::ours();
    let mut cases = conformance::soup_cases(4);
    cases.extend(conformance::hard_cases());
    conformance::assert_conforms(&registry, &plan(&registry), &cases);
}

#[test]
fn other_structures_on_the_shared_scenes() {
    let Some(cases) = conformance::shared_cases_or_skip(17, 11) else { return };
    let registry = Registry::ours();
    let plan = Plan { intersectors: vec![kdtree::Intersector::Wald], ..plan(&registry) };
    conformance::assert_conforms(&registry, &plan, &cases);
}
