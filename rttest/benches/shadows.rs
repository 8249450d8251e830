//! Shadow rays at 1024x1024 (the shadow issue's kernels): hard shadows and 16-sample soft
//! shadows from the same primary hits, as single rays, as 2x2 packets of neighbouring
//! pixels' rays (`packet`, `mft-16`: per light stratum for soft shadows), under the thesis's
//! pyramid and cone (`packet per-point`, `cone-16 per-point`, soft), and as Benthin & Wald's
//! shadow frusta (`multi-frusta-16`) and multi-frusta in SIMD lanes (`lane-frusta-16`), on
//! the atrium and Sponza; and the rays alone, made and not traced (`rays-only`).

use criterion::{Criterion, criterion_group, criterion_main};

mod common;

fn shadows(c: &mut Criterion) {
    use trace::SoftGrouping::{PerPoint, Strata};
    let methods = [
        ("packet", Strata),
        ("packet", PerPoint),
        ("mft-16", Strata),
        ("cone-16", PerPoint),
        ("multi-frusta-16", Strata),
        ("lane-frusta-16", Strata),
    ];
    common::bench_shadow_methods(c, "shadows", &methods);
}

/// The bench group (`criterion_group!` makes an undocumented public function).
#[allow(missing_docs)]
mod group {
    use super::*;
    criterion_group!(benches, shadows);
}
criterion_main!(group::benches);
