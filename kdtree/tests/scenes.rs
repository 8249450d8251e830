//! Traversal on the built-in scenes and on the shared OBJ scenes (when present) against the
//! brute-force oracle: camera rays over every view, and shadow rays from the hits to the
//! point light. Each tree is validated after its build.

mod common;

use common::check_rays;
use glam::Vec3;
use kdtree::{BuildConfig, BuildStrategy, Intersector, KdTree, Ray, ray::offset_origin};
use scenes::Scene;

/// Camera rays on a sparse pixel grid of every view, plus the shadow rays of their hits.
fn scene_rays(scene: &Scene, tree: &KdTree, grid: u32) -> Vec<Ray> {
    let mut rays = Vec::new();
    for view in &scene.views {
        let cam = view.camera(grid, grid).expect("valid view");
        for y in 0..grid {
            for x in 0..grid {
                let (o, d) = cam.pixel_ray(x, y);
                let ray = Ray::new(o, d, 0.0, f32::INFINITY);
                rays.push(ray);
                if let Some(hit) = tree.intersect(&ray) {
                    let tri = scene.mesh.triangle(hit.prim as usize);
                    let to_light = scene.point_light.position - ray.at(hit.t);
                    let origin = offset_origin(&tri, &hit, to_light);
                    rays.push(Ray::new(origin, scene.point_light.position - origin, 0.0, 1.0));
                }
            }
        }
    }
    rays
}

/// The default (binned) build with both intersectors, and the exact build with Wald's test.
/// Scenes below the default's size threshold are binned down to 32 triangles instead, so
/// that their trees have binned nodes.
fn check_scene(scene: &Scene, grid: u32) {
    let binned = match BuildStrategy::default() {
        BuildStrategy::Binned { min_tris, .. } if (min_tris as usize) < scene.mesh.triangle_count() => {
            BuildStrategy::default()
        }
        _ => BuildStrategy::Binned { bins: 16, min_tris: 32 },
    };
    for (intersector, strategy) in
        [(Intersector::Wald, binned), (Intersector::Watertight, binned), (Intersector::Wald, BuildStrategy::Exact)]
    {
        let config = BuildConfig { intersector, strategy, ..BuildConfig::default() };
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &config).expect("build");
        tree.validate().unwrap_or_else(|e| panic!("{}: {e}", scene.name));
        let rays = scene_rays(scene, &tree, grid);
        check_rays(&tree, &rays).unwrap_or_else(|e| panic!("{} ({intersector:?}, {strategy:?}): {e}", scene.name));
    }
}

#[test]
fn small_builtin_scenes_match_the_oracle() {
    for name in ["triangle", "cube", "sphere", "touching-boxes", "axis-plane-triangle"] {
        check_scene(&scenes::builtin::by_name(name).unwrap(), 48);
    }
}

/// One test per large built-in scene (so they run in parallel): `test: "scene" at grid`.
macro_rules! builtin_scene_tests {
    ($($test:ident: $name:literal at $grid:literal;)*) => {$(
        #[test]
        fn $test() {
            check_scene(&scenes::builtin::by_name($name).unwrap(), $grid);
        }
    )*};
}

builtin_scene_tests! {
    arena_matches_the_oracle: "arena" at 24;
    atrium_matches_the_oracle: "atrium" at 16;
    atrium_rotated_matches_the_oracle: "atrium-rotated" at 16;
    grove_matches_the_oracle: "grove" at 10;
}

#[test]
fn shared_scenes_match_the_oracle() {
    let Some(dir) = scenes::shared_scenes_dir() else {
        eprintln!("skipped: no shared scenes folder (set RTTEST_SCENES)");
        return;
    };
    for file in ["sponza-dabrovic.obj.gz", "stanford-bunny.obj.gz"] {
        let path = dir.join(file);
        if !path.exists() {
            eprintln!("skipped: {} is absent", path.display());
            continue;
        }
        let scene = scenes::load_scene(path.to_str().unwrap()).expect("load");
        check_scene(&scene, 12);
    }
}

#[test]
fn rays_grazing_the_cube_edges_and_through_its_corners() {
    let scene = scenes::builtin::by_name("cube").unwrap();
    let (lo, hi) = scene.mesh.bounds().unwrap();
    let mut rays = Vec::new();
    for &x in &[lo.x, hi.x, 0.5 * (lo.x + hi.x)] {
        for &y in &[lo.y, hi.y, 0.5 * (lo.y + hi.y)] {
            for &z in &[lo.z, hi.z, 0.5 * (lo.z + hi.z)] {
                let target = Vec3::new(x, y, z);
                for d in [
                    Vec3::X,
                    Vec3::Y,
                    Vec3::Z,
                    Vec3::new(1.0, 1.0, 1.0),
                    Vec3::new(1.0, -1.0, 0.0),
                    Vec3::new(-0.0, 0.3, -1.0),
                ] {
                    rays.push(Ray::new(target - 5.0 * d, d, 0.0, f32::INFINITY));
                    rays.push(Ray::new(target + 5.0 * d, -d, 0.0, f32::INFINITY));
                }
            }
        }
    }
    for intersector in [Intersector::Wald, Intersector::Watertight] {
        let config = BuildConfig { intersector, ..BuildConfig::default() };
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &config).unwrap();
        check_rays(&tree, &rays).unwrap();
    }
}
