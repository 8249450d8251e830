//! Other tracers on exactly our rays, registered as methods of the one registry
//! ([`trace::Registry`]): Intel Embree 3 (feature `embree`) and the pure-Rust BVH crates
//! `bvh` and `obvhs` (feature `bvh-crates`).
//!
//! Each is a [`trace::Method`] registered whole (one kernel for every pass, named by its
//! entry, `trace::registry::Entry::whole`), so the frame driver runs it over a frame exactly as it runs
//! ours (rayon over the same tiles, per-pixel buffers in tile order, ray generation inside
//! the timed pass), and with exactly our rays: primary rays from `scenes::Camera::pixel_ray`,
//! hard shadow rays from `trace::method::hard_shadow_segment` on *our* single-ray hits,
//! soft-shadow rays from `trace::soft::shadow_start` and `cones::shadows`.
//!
//! - `embree`: our own small FFI to Embree 3 (device, scene, `rtcIntersect1/4/8/16`,
//!   `rtcOccluded1/4/8/16`, layouts checked against the header); `embree_blocks`: single rays
//!   and packets of 4, 8 and 16 over 2x2, 4x2 and 4x4 pixel blocks;
//! - `bvh_crates`: the `bvh` and `obvhs` crates as single-ray tracers.

#[cfg(feature = "bvh-crates")]
pub mod bvh_crates;
#[cfg(feature = "embree")]
pub mod embree;
#[cfg(feature = "embree")]
pub mod embree_blocks;

use trace::Registry;

/// Adds the baselines this build has to `registry`.
pub fn register(registry: &mut Registry) {
    #[cfg(feature = "embree")]
    embree_blocks::register(registry);
    #[cfg(feature = "bvh-crates")]
    bvh_crates::register(registry);
    let _ = registry;
}

/// Our methods and the baselines this build has: the one catalogue, assembled here, that every
/// command, the viewer, the benches and the tables use. Only tests that check our methods
/// alone (those of `trace`, the `traversal` fuzz target) take [`Registry::ours`] instead.
pub fn registry() -> Registry {
    let mut registry = Registry::ours();
    register(&mut registry);
    registry
}

/// What a method name or group needs to exist in this build, when this build lacks it: the
/// feature to turn on, and how.
pub fn feature_hint(name: &str) -> Option<&'static str> {
    if name.starts_with("embree") {
        (!cfg!(feature = "embree")).then_some(
            "Embree baselines need the `embree` feature: `apt-get install -y libembree-dev`, then build with `cargo build --release -p rttest --features embree`",
        )
    } else if matches!(name, "bvh" | "obvhs" | "bvh-crates") {
        (!cfg!(feature = "bvh-crates")).then_some(
            "the bvh and obvhs baselines need the `bvh-crates` feature: build with `cargo build --release -p rttest --features bvh-crates`",
        )
    } else {
        None
    }
}

/// The Embree device line of a report (version, tasking, native packet widths), once a
/// device exists; `None` without the feature or before any Embree build.
pub fn embree_note() -> Option<String> {
    #[cfg(feature = "embree")]
    return embree_blocks::note();
    #[cfg(not(feature = "embree"))]
    None
}
