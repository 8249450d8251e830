//! Multiple Frustum Traversal (thesis 4.1.5): primary rays at 1024x1024 per tile size (4 to
//! 32), beside single rays and the single frustum at 8x8 and 16x16, on the atrium and Sponza.

use criterion::{Criterion, criterion_group, criterion_main};

mod common;

fn mft(c: &mut Criterion) {
    let configs = ["frustum-8", "frustum-16", "mft-4", "mft-8", "mft-16", "mft-32"];
    common::bench_primary_methods(c, "mft", &configs);
}

/// The bench group (`criterion_group!` makes an undocumented public function).
#[allow(missing_docs)]
mod group {
    use super::*;
    criterion_group!(benches, mft);
}
criterion_main!(group::benches);
