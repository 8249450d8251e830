//! Thesis Table 6.2: frame rate against the number of threads, for the best method of a scene.
//!
//! One rayon pool per size, 1, 2, ... up to the machine's cores, each made once; then
//! `rounds` rounds, each tracing and shading one frame on every pool in turn (1, 2, ..., 1,
//! 2, ...), so that a slow phase of a noisy machine hits every size alike; the median frame
//! time of each size gives its frames per second and its speedup over one thread.
//!
//! A frame is what Tables 4.1-4.5 time: the primary pass (no shadow rays) and the shading
//! pass. Both hand out the image's tiles to the pool's threads through rayon's work stealing:
//! the tiles are split in halves down to single tiles, an idle thread steals the largest half
//! left, so no thread waits while another still has more than one tile of work (at 512x512
//! and 16x16 tiles a frame has 1024 tiles).

use std::fmt::Write as _;

use scenes::{Camera, Scene};
use trace::timing::{interleaved, median, timed};
use trace::{Bound, Error, Renderer, Shadows};

/// One pool size of one scene.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ScalingRow {
    /// Scene name.
    pub scene: String,
    /// The method (`mft`, `frustum`, ...).
    pub method: String,
    /// Its tile side.
    pub tile: u32,
    /// Threads in the pool.
    pub threads: usize,
    /// Median milliseconds of a frame (trace + shading).
    pub frame_ms: f64,
    /// `1000 / frame_ms`.
    pub fps: f64,
    /// Frame rate over the one-thread frame rate.
    pub speedup: f64,
}

/// The machine's cores as the OS reports them (1 if unknown).
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Measures `method` (with its tile) on `scene` seen by `camera` with pools of 1 to
/// `max_threads` threads, `rounds` interleaved rounds (see the module documentation).
pub fn measure(
    scene: &Scene,
    method: &Bound<'_>,
    camera: Camera,
    max_threads: usize,
    rounds: u32,
) -> Result<Vec<ScalingRow>, Error> {
    let tile = method.options.tile;
    let renderer = Renderer::new(scene, method, camera, Shadows::None);
    let mut pools = (1..=max_threads.max(1))
        .map(|n| rayon::ThreadPoolBuilder::new().num_threads(n).build())
        .collect::<Result<Vec<_>, _>>()?;
    let mut buffers = renderer.buffers();
    // One untimed frame per pool: its threads started, the caches warm.
    for pool in &pools {
        pool.install(|| {
            renderer.trace(&mut buffers);
            renderer.color(&buffers)
        });
    }
    let times: Vec<Vec<f64>> = interleaved(
        rounds.max(1),
        &mut pools,
        |pool| {
            timed(|| {
                pool.install(|| {
                    renderer.trace(&mut buffers);
                    std::hint::black_box(renderer.color(&buffers));
                })
            })
            .0 * 1e3
        },
        || {},
    );
    let one = median(&times[0]);
    Ok(times
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let ms = median(t);
            ScalingRow {
                scene: scene.name.clone(),
                method: method.entry.name.to_string(),
                tile,
                threads: i + 1,
                frame_ms: ms,
                fps: 1e3 / ms,
                speedup: one / ms,
            }
        })
        .collect())
}

/// The markdown of Table 6.2 for `rows` (all scenes), with a note on the machine.
pub fn markdown(rows: &[ScalingRow], size: (u32, u32), rounds: u32) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "\n### Table 6.2: threads (rayon pool sizes), best method per scene\n");
    let _ = writeln!(
        out,
        "Default views, {}x{}, primary rays and shading as in Tables 4.1-4.5; medians of {rounds} rounds, pool sizes interleaved; this machine has {} cores. Thesis: 2.0x from 1 to 2 cores (Core 2 Duo).\n",
        size.0,
        size.1,
        cores()
    );
    let _ = writeln!(out, "| scene | method | tile | threads | frame ms | fps | speedup |");
    let _ = writeln!(out, "|---|---|---:|---:|---:|---:|---:|");
    for r in rows {
        let _ = writeln!(
            out,
            "| {} | {} | {}x{} | {} | {:.2} | {:.1} | {:.2}x |",
            r.scene, r.method, r.tile, r.tile, r.threads, r.frame_ms, r.fps, r.speedup
        );
    }
    out
}

/// The CSV of Table 6.2.
pub fn csv(rows: &[ScalingRow]) -> String {
    let mut out = String::from("scene,method,tile,threads,frame_ms,fps,speedup\n");
    for r in rows {
        let _ = writeln!(
            out,
            "{},{},{},{},{:.3},{:.3},{:.3}",
            r.scene, r.method, r.tile, r.threads, r.frame_ms, r.fps, r.speedup
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use kdtree::BuildConfig;
    use trace::setup::load_and_build;
    use trace::{Options, Registry, Structures};

    #[test]
    fn one_row_per_pool_size_and_unit_speedup_at_one() {
        let (scene, tree, _) = load_and_build("touching-boxes", &BuildConfig::default()).unwrap();
        let camera = scene.default_view().camera(32, 32).unwrap();
        let (registry, structures) = (Registry::ours(), Structures::new(&tree));
        let mft = registry.bind(&registry.select("mft-8", Options::default()).unwrap(), &structures).unwrap();
        let rows = measure(&scene, &mft, camera, 2, 2).unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[0].speedup, 1.0);
        assert!(rows.iter().all(|r| r.fps > 0.0 && r.threads >= 1));
        let text = markdown(&rows, (32, 32), 2);
        assert!(text.contains("Table 6.2") && text.contains("| touching-boxes | mft | 8x8 | 2 |"));
        assert_eq!(csv(&rows).lines().count(), 3);
    }
}
