//! The shared scene and image crate of the workspace.
//!
//! Everything that touches files lives here: meshes and their OBJ loader (with MTL material
//! libraries), materials (the thesis's shader parameters), the built-in procedural scenes that
//! mirror the thesis's benchmark scenes (Tsakok 2008, Figure 4.1 and Table 6.2), pinhole
//! cameras, lights, floating-point images with PNG/PFM output, heat maps with a legend
//! (`colormap`, `font`), error metrics and tile iteration. The kd-tree and traversal
//! crates never read files; they take the positions and triangles of a [`Mesh`].
//!
//! One camera convention serves every tracer (see [`Camera`]), so that other tracers can
//! reproduce our rays exactly.

pub mod builtin;
pub mod camera;
pub mod colormap;
pub mod error;
pub mod files;
pub mod font;
pub mod image;
pub mod light;
pub mod load;
pub mod material;
pub mod mesh;
pub mod metrics;
pub mod mtl;
pub mod obj;
pub mod scene;
pub mod scratch;
pub mod tile;

pub use camera::Camera;
pub use colormap::{Panel, heatmap, strip, viridis};
pub use error::SceneError;
pub use image::{Image, Rgb8Image, ScalarImage};
pub use light::{PointLight, RectLight, SphereLight};
pub use load::load_scene;
pub use material::{Material, Shader};
pub use mesh::Mesh;
pub use obj::{LoadReport, load_obj};
pub use scene::{Scene, View, shared_scene_files, shared_scenes_dir};
pub use scratch::ScratchDir;
pub use tile::{Tile, morton_order, tiles};
