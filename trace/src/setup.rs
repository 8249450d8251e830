//! Scene, tree, camera and ray setup shared by the experiments, the command line, the tests
//! and the criterion benches.
//!
//! Everything here runs *outside* the timed loops: a bench loads a [`Workload`] once, then
//! times only [`trace_closest`] or [`trace_any`] over its precomputed rays.

use std::path::{Path, PathBuf};
use std::time::Instant;

use kdtree::treefile::Checks;
use kdtree::{BuildConfig, KdTree, Ray};
use rayon::prelude::*;
use scenes::{Camera, Mesh, Scene};

use crate::error::Error;
use crate::{method, shade};

/// The Sponza file in the shared scenes folder, if it is there.
pub fn sponza_path() -> Option<PathBuf> {
    shared_scene("sponza-dabrovic.obj.gz")
}

/// A file in the shared scenes folder ([`scenes::shared_scenes_dir`]), if it is there.
pub fn shared_scene(file: &str) -> Option<PathBuf> {
    let path = scenes::shared_scenes_dir()?.join(file);
    path.is_file().then_some(path)
}

/// The camera of the scene's view `name` (its default view when `None`) at `w x h`, and the
/// view's name; a degenerate view is a usage error naming it.
pub fn view_camera(scene: &Scene, name: Option<&str>, w: u32, h: u32) -> Result<(Camera, String), Error> {
    let view = match name {
        Some(name) => scene.view(name)?,
        None => scene.default_view(),
    };
    let camera = view
        .camera(w, h)
        .ok_or_else(|| Error::Usage(format!("view '{}' of scene '{}' is degenerate", view.name, scene.name)))?;
    Ok((camera, view.name.clone()))
}

/// The scenes of the experiments when none is named: the four built-in stand-ins of the
/// thesis's scenes and every `.obj` / `.obj.gz` in the shared scenes folder, sorted.
pub fn default_scenes() -> Vec<String> {
    let mut list: Vec<String> = ["atrium", "arena", "atrium-rotated", "grove"].map(String::from).to_vec();
    list.extend(scenes::shared_scene_files().iter().map(|p| p.display().to_string()));
    list
}

/// Loads `spec` (a built-in name or a path) and builds its tree with `config`.
/// Returns the scene, the tree and the build time in milliseconds.
pub fn load_and_build(spec: &str, config: &BuildConfig) -> Result<(Scene, KdTree, f64), Error> {
    let scene = scenes::load_scene(spec)?;
    let start = Instant::now();
    let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, config)?;
    Ok((scene, tree, start.elapsed().as_secs_f64() * 1e3))
}

/// Writes `tree`, built over `scene`'s mesh, to the tree file `path`
/// ([`kdtree::treefile`]). Errors name the file.
pub fn save_tree(path: &Path, tree: &KdTree, scene: &Scene) -> Result<(), Error> {
    let file_error = |message: String| Error::File { path: path.to_path_buf(), message };
    let bytes = kdtree::treefile::to_bytes(tree, &scene.mesh.positions, &scene.mesh.triangles)
        .map_err(|e| file_error(format!("cannot save the tree of scene '{}': {e}", scene.name)))?;
    scenes::files::write_bytes(path, &bytes).map_err(|e| file_error(format!("cannot write the tree file: {e}")))
}

/// Reads the tree file `path` (one read) and loads its tree for `scene`, asking for the
/// intersector and SAH terms of `config`: every check of [`kdtree::treefile::from_bytes`]
/// runs, [`KdTree::validate`] last with [`Checks::Full`]. Errors name the file and the
/// problem.
pub fn load_tree(path: &Path, scene: &Scene, config: &BuildConfig, checks: Checks) -> Result<KdTree, Error> {
    let file_error = |message: String| Error::File { path: path.to_path_buf(), message };
    let bytes = scenes::files::read_bytes(path).map_err(|e| file_error(format!("cannot read the tree file: {e}")))?;
    kdtree::treefile::from_bytes(&bytes, &scene.mesh.positions, &scene.mesh.triangles, config, checks)
        .map_err(|e| file_error(format!("cannot load the tree for scene '{}': {e}", scene.name)))
}

/// A scene with its tree and the rays of one frame: the primary rays of a camera and the
/// shadow rays from their hits towards the scene's point light.
#[derive(Debug)]
pub struct Workload {
    /// The scene.
    pub scene: Scene,
    /// Its tree (default build configuration).
    pub tree: KdTree,
    /// The camera the rays come from.
    pub camera: Camera,
    /// One primary ray per pixel, row-major.
    pub primary: Vec<Ray>,
    /// One shadow ray per primary hit facing the light.
    pub shadow: Vec<Ray>,
}

impl Workload {
    /// The workload of `spec` seen from its view `view` (its default view when `None`) at
    /// `width` x `height`.
    pub fn new(spec: &str, view: Option<&str>, width: u32, height: u32) -> Result<Workload, Error> {
        let (scene, tree, _) = load_and_build(spec, &BuildConfig::default())?;
        let (camera, _) = view_camera(&scene, view, width, height)?;
        Ok(Self::with_camera(scene, tree, camera))
    }

    /// The workload of a loaded scene and tree seen by `camera`.
    pub fn with_camera(scene: Scene, tree: KdTree, camera: Camera) -> Workload {
        let primary = primary_rays(&camera);
        let shadow = shadow_rays(&scene, &tree, &primary);
        Workload { scene, tree, camera, primary, shadow }
    }
}

/// The primary rays of every pixel of `camera`, row-major.
pub fn primary_rays(camera: &Camera) -> Vec<Ray> {
    (0..camera.height).flat_map(|y| (0..camera.width).map(move |x| method::primary_ray(camera, x, y))).collect()
}

/// The shadow rays of the hits of `primary` towards the scene's point light (one per hit
/// facing the light), in the order of `primary`.
pub fn shadow_rays(scene: &Scene, tree: &KdTree, primary: &[Ray]) -> Vec<Ray> {
    let surfaces = shade::surfaces(&scene.mesh);
    primary
        .par_iter()
        .filter_map(|ray| {
            let hit = tree.intersect(ray)?;
            shade::shadow_ray(&surfaces, &scene.point_light, ray.dir, &hit)
        })
        .collect()
}

/// Closest-hit queries for all `rays` on the current rayon pool; returns the number of hits.
pub fn trace_closest(tree: &KdTree, rays: &[Ray]) -> usize {
    rays.par_chunks(256).map(|chunk| chunk.iter().filter(|r| tree.intersect(r).is_some()).count()).sum()
}

/// Any-hit queries for all `rays` on the current rayon pool; returns the number occluded.
pub fn trace_any(tree: &KdTree, rays: &[Ray]) -> usize {
    rays.par_chunks(256).map(|chunk| chunk.iter().filter(|r| tree.occluded(r)).count()).sum()
}

/// `mesh` with its triangle count multiplied by `2^doublings`, for build-scaling benches
/// (each doubling is [`Mesh::split_longest_edges`]).
pub fn refined(mesh: &Mesh, doublings: u32) -> Mesh {
    let mut mesh = mesh.clone();
    for _ in 0..doublings {
        mesh = mesh.split_longest_edges();
    }
    mesh
}

/// The workloads of the packet benches: the atrium's default view and, when the shared
/// scenes are there, Sponza from the Embree comparison view (eye (-10, 3, 0), target
/// (0, 4, 0), fovy 70), both at `size` x `size`.
pub fn packet_workloads(size: u32) -> Vec<(&'static str, Scene, KdTree, Camera)> {
    let mut out = Vec::new();
    if let Ok((scene, tree, _)) = load_and_build("atrium", &BuildConfig::default())
        && let Some(camera) = scene.default_view().camera(size, size)
    {
        out.push(("atrium", scene, tree, camera));
    }
    match sponza_path() {
        Some(path) => {
            if let Ok((scene, tree, _)) = load_and_build(&path.to_string_lossy(), &BuildConfig::default())
                && let Some(camera) =
                    Camera::look_at(glam::Vec3::new(-10.0, 3.0, 0.0), glam::Vec3::new(0.0, 4.0, 0.0), 70.0, size, size)
            {
                out.push(("sponza", scene, tree, camera));
            }
        }
        None => eprintln!("packet benches: Sponza skipped, no shared scenes folder"),
    }
    out
}
