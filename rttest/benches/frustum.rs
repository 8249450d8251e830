//! Frustum interval traversal with packet/leaf culling (thesis 2.3.2, 4.1.3-4.1.4): primary
//! rays at 1024x1024 per tile size (4 to 32, and 8x8 without culling), beside single rays,
//! on the atrium and Sponza.

use criterion::{Criterion, criterion_group, criterion_main};

mod common;

fn frustum(c: &mut Criterion) {
    let configs = ["frustum-4", "frustum-8", "frustum-16", "frustum-32"];
    common::bench_primary_methods(c, "frustum", &configs);
}

/// The bench group (`criterion_group!` makes an undocumented public function).
#[allow(missing_docs)]
mod group {
    use super::*;
    criterion_group!(benches, frustum);
}
criterion_main!(group::benches);
