//! A scene: a mesh with named camera views and default lights (loaded by name or path in
//! [`crate::load`]).

use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::{Camera, Mesh, PointLight, RectLight, SceneError};

/// A named camera view: eye, target and vertical field of view (see [`Camera`]).
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    /// Name used on the command line (`--view NAME`).
    pub name: String,
    /// Eye position.
    pub eye: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Vertical field of view in degrees.
    pub fovy_deg: f32,
}

impl View {
    /// The camera of this view for a `width` x `height` image (`None` for a degenerate view,
    /// including a NaN or infinite eye, target or field of view: see [`Camera::look_at`]).
    pub fn camera(&self, width: u32, height: u32) -> Option<Camera> {
        Camera::look_at(self.eye, self.target, self.fovy_deg, width, height)
    }
}

/// A mesh with its named views (the first is the default) and default lights.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Scene name (built-in name or file stem).
    pub name: String,
    /// The geometry.
    pub mesh: Mesh,
    /// Named views; never empty, the first is the default.
    pub views: Vec<View>,
    /// The default point light (hard shadows, thesis benchmark shading).
    pub point_light: PointLight,
    /// The default rectangular area light (soft shadows).
    pub area_light: RectLight,
}

impl Scene {
    /// The view called `name`, or an error listing the views there are.
    pub fn view(&self, name: &str) -> Result<&View, SceneError> {
        self.views.iter().find(|v| v.name == name).ok_or_else(|| SceneError::UnknownView {
            scene: self.name.clone(),
            view: name.to_string(),
            available: self.views.iter().map(|v| v.name.as_str()).collect::<Vec<_>>().join(", "),
        })
    }

    /// The default (first) view.
    pub fn default_view(&self) -> &View {
        &self.views[0]
    }

    /// A scene around a loaded mesh with a view and lights derived from its bounds.
    ///
    /// For the recognised shared scenes (file names starting with `sponza`, `kitchen`,
    /// `sibenik` or `conference`) the first view, `default`, is the scene's known benchmark
    /// or check viewpoint (see `SOURCES.md`) and the bounds-derived one is called `overview`.
    ///
    /// The mesh should pass [`Mesh::check`] (the OBJ loader's meshes do); a mesh with an
    /// infinite position gets views whose [`View::camera`] is `None`, never a panic.
    pub fn from_mesh(name: &str, mesh: Mesh) -> Scene {
        let (lo, hi) = mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
        let center = 0.5 * (lo + hi);
        let extent = (hi - lo).max(Vec3::splat(1e-3));
        let radius = extent.length() * 0.5;
        let mut views: Vec<View> = known_view(name).into_iter().collect();
        views.push(View {
            name: if views.is_empty() { "default".into() } else { "overview".into() },
            eye: center + Vec3::new(0.3, 0.35, 1.0).normalize() * radius * 1.8,
            target: center,
            fovy_deg: 50.0,
        });
        let light_pos = center + Vec3::new(0.1, 0.35, 0.05) * extent;
        let size = 0.05 * extent.max_element();
        Scene {
            name: name.to_string(),
            mesh,
            views,
            point_light: PointLight { position: light_pos, intensity: Vec3::splat(radius * radius * 0.3) },
            area_light: RectLight {
                corner: light_pos - Vec3::new(0.5 * size, 0.0, 0.5 * size),
                edge_u: Vec3::new(size, 0.0, 0.0),
                edge_v: Vec3::new(0.0, 0.0, size),
                intensity: Vec3::splat(radius * radius * 0.3),
            },
        }
    }
}

/// The known viewpoint of a recognised shared scene, named `default`.
fn known_view(name: &str) -> Option<View> {
    let (eye, target, fovy_deg) = if name.starts_with("sponza") {
        // The view used for the Embree figures quoted in the issues.
        ((-10.0, 3.0, 0.0), (0.0, 4.0, 0.0), 70.0)
    } else if name.starts_with("kitchen") {
        // Inside the kitchen: cupboards, sink, table and stools.
        ((3.75, 2.3, 3.6), (2.0, 0.8, 1.5), 60.0)
    } else if name.starts_with("sibenik") {
        // Down the nave towards the altar.
        ((-15.0, -10.0, 0.0), (0.0, -8.0, 0.0), 70.0)
    } else if name.starts_with("conference") {
        // The long table and chairs.
        ((1400.0, 450.0, 500.0), (0.0, 80.0, -300.0), 70.0)
    } else {
        return None;
    };
    Some(View { name: "default".into(), eye: Vec3::from(eye), target: Vec3::from(target), fovy_deg })
}

/// The folder of shared benchmark scenes (Sponza and others), if present: `$RTTEST_SCENES`,
/// else `../shared/scenes` from the workspace root, else `../shared/scenes` from the current
/// directory. Tests and benches that use it skip cleanly when it is `None`.
pub fn shared_scenes_dir() -> Option<PathBuf> {
    let mut candidates = Vec::new();
    if let Some(dir) = std::env::var_os("RTTEST_SCENES") {
        candidates.push(PathBuf::from(dir));
    }
    candidates.push(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes"));
    candidates.push(PathBuf::from("../shared/scenes"));
    candidates.into_iter().find(|p| p.is_dir())
}

/// The `.obj` and `.obj.gz` files of the shared scenes folder ([`shared_scenes_dir`]),
/// sorted; empty when the folder is absent or unreadable.
pub fn shared_scene_files() -> Vec<PathBuf> {
    let Some(dir) = shared_scenes_dir() else { return Vec::new() };
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut files: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            let name = p.file_name().map(|n| n.to_string_lossy().to_lowercase()).unwrap_or_default();
            p.is_file() && (name.ends_with(".obj") || name.ends_with(".obj.gz"))
        })
        .collect();
    files.sort();
    files
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::load_scene;

    #[test]
    fn files_get_bounds_views_and_known_viewpoints() {
        let dir = crate::ScratchDir::new("scenes-scene-tests", "views").unwrap();
        let text = "v 0 0 0\nv 4 0 0\nv 0 2 0\nv 0 0 3\nf 1 2 3\nf 1 4 2\n";
        for (file, first_view) in
            [("plain.obj", "default"), ("kitchen-test.obj", "default"), ("sponza-x.obj", "default")]
        {
            let path = dir.join(file);
            std::fs::write(&path, text).unwrap();
            let scene = load_scene(path.to_str().unwrap()).unwrap();
            assert_eq!(scene.default_view().name, first_view);
            assert_eq!(scene.name, file.trim_end_matches(".obj"));
            for v in &scene.views {
                assert!(v.camera(32, 32).is_some(), "{file}: {}", v.name);
            }
        }
        let sponza = load_scene(dir.join("sponza-x.obj").to_str().unwrap()).unwrap();
        assert_eq!(sponza.default_view().eye, Vec3::new(-10.0, 3.0, 0.0));
        assert_eq!(sponza.views[1].name, "overview");
        let kitchen = load_scene(dir.join("kitchen-test.obj").to_str().unwrap()).unwrap();
        assert_eq!(kitchen.default_view().fovy_deg, 60.0);
    }

    #[test]
    fn non_finite_meshes_and_views_give_no_camera() {
        let mut mesh = load_scene("triangle").unwrap().mesh;
        mesh.positions[1].x = f32::INFINITY;
        let scene = Scene::from_mesh("broken", mesh.clone());
        assert!(scene.views.iter().all(|v| v.camera(8, 8).is_none()));
        // NaN: no panic, whatever views result.
        mesh.positions[1].x = f32::NAN;
        let _ = Scene::from_mesh("broken", mesh).default_view().camera(8, 8);
        let good = View { name: "v".into(), eye: Vec3::Z, target: Vec3::ZERO, fovy_deg: 45.0 };
        assert!(good.camera(8, 8).is_some());
        for bad in [
            View { eye: Vec3::new(0.0, f32::NAN, 1.0), ..good.clone() },
            View { target: Vec3::new(0.0, 0.0, f32::NEG_INFINITY), ..good.clone() },
            View { fovy_deg: f32::NAN, ..good.clone() },
        ] {
            assert!(bad.camera(8, 8).is_none(), "{bad:?}");
        }
    }
}
