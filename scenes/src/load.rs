//! Loading a scene by name: a built-in generator's name or the path of an OBJ file.
//!
//! Kept apart from `scene` (what a scene is) because it calls the built-in generators, which
//! build `Scene`s: so `scene` imports nothing that imports it.

use std::path::Path;

use crate::{Scene, SceneError, builtin, obj};

/// Loads a scene given as a built-in name (see [`builtin::NAMES`]) or a path to an
/// `.obj` / `.obj.gz` file.
pub fn load_scene(spec: &str) -> Result<Scene, SceneError> {
    if let Some(scene) = builtin::by_name(spec) {
        return Ok(scene);
    }
    let path = Path::new(spec);
    if !path.exists() {
        return Err(SceneError::UnknownScene(spec.to_string(), builtin::NAMES.join(", ")));
    }
    let (mesh, _report) = obj::load_obj(path)?;
    let stem = path.file_name().and_then(|s| s.to_str()).unwrap_or("scene");
    let stem = stem.trim_end_matches(".gz").trim_end_matches(".obj");
    Ok(Scene::from_mesh(stem, mesh))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn built_in_names_load_and_unknown_names_fail_clearly() {
        let scene = load_scene("cube").unwrap();
        assert_eq!(scene.mesh.triangle_count(), 12);
        assert!(scene.view("default").is_ok());
        let err = scene.view("nope").unwrap_err().to_string();
        assert!(err.contains("nope") && err.contains("default"), "{err}");
        let err = load_scene("/no/such/scene.obj").unwrap_err().to_string();
        assert!(err.contains("/no/such/scene.obj") && err.contains("atrium"), "{err}");
    }

    #[test]
    fn subdivided_atrium_loads_by_name() {
        let scene = load_scene("atrium-x2").unwrap();
        assert_eq!(scene.mesh.triangle_count(), 2 * load_scene("atrium").unwrap().mesh.triangle_count());
    }
}
