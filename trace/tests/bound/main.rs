//! The tests that bind the registry's methods or call its kernels: the renderer, the registry,
//! the multi-BVH bindings and the soft-shadow kernels.
//!
//! They are an integration test, not unit tests beside their modules, so that the crate's
//! unit-test build does not monomorphise every kernel of the registry a second time: here
//! they link the instantiations the library already compiled. Beside the code, they made
//! `cargo test --workspace` compile `trace` twice: its build took 25 minutes on a 2-core
//! machine like CI's, 16 without.

mod multibvh;
mod registry;
mod render;
mod soft_kernels;
