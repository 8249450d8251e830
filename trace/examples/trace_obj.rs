//! Load a scene, build the kd-tree, trace rays with a method chosen by name, read the hits.
//!
//! ```sh
//! cargo run --release -p trace --example trace_obj -- ../shared/scenes/sponza-dabrovic.obj.gz mft-16
//! cargo run --release -p trace --example trace_obj -- atrium packet
//! ```
//!
//! The first argument is an `.obj` / `.obj.gz` path or a built-in scene name (default
//! `atrium`), the second a method name of the registry (default `mft-16`; `mono` is single
//! rays, the scalar twin every method must agree with). The rays are a camera's, made by the
//! caller as any other rays would be, and traced as a stream (`FrameTracer::stream`): each
//! method groups them as it likes (2x2 packets, frusta where rays share an origin) and gives
//! back one closest hit per ray, in order. The example checks every hit against single rays.

use kdtree::{BuildConfig, Hit, Ray};
use trace::setup::load_and_build;
use trace::{Options, Registry, Structures};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let scene_name = args.next().unwrap_or_else(|| "atrium".to_string());
    let method_name = args.next().unwrap_or_else(|| "mft-16".to_string());

    // The scene and its perfect-split SAH kd-tree (thesis 2.1), with the default build.
    let (scene, tree, build_ms) = load_and_build(&scene_name, &BuildConfig::default())?;
    println!("{}: {} triangles, tree built in {build_ms:.1} ms", scene.name, scene.mesh.triangles.len());

    // Rays: the primary rays of the scene's first view, 256x256, row by row. Any rays work;
    // `Ray::try_new` rejects NaN or infinite input with an error naming the component.
    let (w, h) = (256, 256);
    let (camera, view) = trace::setup::view_camera(&scene, None, w, h)?;
    let mut rays = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let (origin, dir) = camera.pixel_ray(x, y);
            rays.push(Ray::try_new(origin, dir, 0.0, f32::INFINITY)?);
        }
    }

    // The method by name: our methods only here (`Registry::ours`); with the baselines of a
    // build, ask `baselines::registry()` instead. Binding checks the options (a tile size a
    // packet method cannot take is an error naming the method).
    let registry = Registry::ours();
    let selected = registry.select(&method_name, Options::default())?;
    let structures = Structures::new(&tree);
    let bound = registry.bind(&selected, &structures)?;

    let mut hits: Vec<Option<Hit>> = vec![None; rays.len()];
    let start = std::time::Instant::now();
    bound.tracer.stream(&rays, &mut hits);
    let secs = start.elapsed().as_secs_f64();
    let found = hits.iter().flatten().count();
    println!(
        "{} on view '{view}': {} rays, {found} hits, {:.2} Mrays/s",
        bound.name,
        rays.len(),
        rays.len() as f64 / secs / 1e6
    );

    // Reading a hit: the triangle (`prim`, our index; `scene.mesh.prim_ids[prim]` is the
    // file's numbering), the distance `t` along the unit direction and the barycentrics.
    if let Some((i, hit)) = hits.iter().enumerate().find_map(|(i, h)| h.map(|h| (i, h))) {
        let p = rays[i].origin + rays[i].dir * hit.t;
        println!(
            "first hit: ray {i} -> triangle {} (file face {}), t = {:.4}, (u, v) = ({:.3}, {:.3}), point {p}",
            hit.prim, scene.mesh.prim_ids[hit.prim as usize], hit.t, hit.u, hit.v
        );
    }

    // Every method gives single rays' answers; a ray through a shared edge or vertex may name
    // either triangle (a tie), which is why a few may differ here.
    let same = rays.iter().zip(&hits).filter(|(ray, hit)| tree.intersect(ray).map(|h| h.prim) == hit.map(|h| h.prim));
    println!("{} of {} hits name the same triangle as single rays", same.count(), rays.len());
    Ok(())
}
