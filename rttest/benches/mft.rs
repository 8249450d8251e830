//! Multiple Frustum Traversal (thesis 4.1.5): primary rays at 1024x1024 per tile size (4 to
//! 32), beside single rays and the single frustum at 8x8 and 16x16, on the atrium and Sponza.

use bench::render::Method;
use criterion::{Criterion, criterion_group, criterion_main};

mod common;

fn mft(c: &mut Criterion) {
    let mut configs: Vec<(Method, u32)> = vec![(Method::Frustum, 8), (Method::Frustum, 16)];
    configs.extend([4, 8, 16, 32].map(|t| (Method::Mft, t)));
    common::bench_primary_methods(c, "mft", &configs);
}

/// The bench group (`criterion_group!` makes an undocumented public function).
#[allow(missing_docs)]
mod group {
    use super::*;
    criterion_group!(benches, mft);
}
criterion_main!(group::benches);
