//! Built-in procedural scenes (generated in code, deterministic, made of closed meshes).

use crate::Scene;

pub mod shapes;

/// Names of the built-in scenes, the default first.
pub const NAMES: &[&str] = &["atrium"];

/// The built-in scene called `name`.
pub fn by_name(name: &str) -> Option<Scene> {
    let _ = name;
    None
}
