//! The thesis's renderer as a whole: Table 3.1 (the share of frame time per pipeline stage)
//! and Table 6.2's real workload (Tsakok 2008, 3.3 and chapter 6), on the built-in garage.
//!
//! Table 6.2's benchmark is two cars in a garage. It uses MFT 16x16 primaries, perfect
//! reflections, glass and edge-width shadows. A frame here is that workload:
//! - the primary pass;
//! - the shadows of the primary hits;
//! - one generation of secondary rays ([`trace::secondary`]: reflections and refractions,
//!   traced by the method's stream kernel);
//! - the shadows at the secondary hits;
//! - the shading of every hit.
//!
//! Each configuration is a method and a kind of shadows. By default these are the thesis's
//! frame (`mft-16`, edge widths) and the same frame with hard shadows, traced by ours and by
//! Embree's 16-ray packets where the build has Embree (`embree-16` traces every pass: its
//! packets for the primary and shadow passes, its stream for the secondary rays).
//!
//! The configurations and pool sizes are timed in interleaved rounds; each stage's time is
//! the median over the rounds. The stages are those a frame times apart: primary rays,
//! primary shadows, spawning the secondary rays (the shader proxy), secondary rays,
//! secondary shadows and shading. Table 3.1 splits traversal from intersection with a
//! profiler; here one more frame per configuration clocks the leaf visits of the primary and
//! secondary passes and the primary kernels' ray generation
//! ([`trace::Renderer::intersection_shares`], `kdtree::clock`), and each timed stage is split
//! by those shares. Embree's kernels are not clocked: their rows keep ray generation,
//! traversal and intersection together.

use std::fmt::Write as _;

use serde::Serialize;
use trace::progress::Progress;
use trace::timing::{median, timed};
use trace::{Error, Options, Renderer, Shadows, Structures};

/// What the pipeline tables measure.
#[derive(Clone, Debug, PartialEq)]
pub struct PipelineConfig {
    /// The scene (a built-in name or an OBJ path; the thesis's is `garage`).
    pub scene: String,
    /// Image size.
    pub size: (u32, u32),
    /// Interleaved rounds; each stage's time is the median.
    pub rounds: u32,
    /// The configurations: (method, shadows).
    pub configs: Vec<(String, Shadows)>,
    /// Pool sizes of Table 6.2 (threads), for the first configuration.
    pub threads: Vec<usize>,
    /// Generations of secondary rays (the thesis's 1).
    pub depth: u32,
}

impl PipelineConfig {
    /// The thesis's frame and its hard-shadow twins, ours and (where built) Embree's, on
    /// `scene` at `size`, with Table 6.2 over pools of 1 to `cores` threads.
    pub fn thesis(scene: &str, size: (u32, u32), rounds: u32, cores: usize) -> PipelineConfig {
        let mut configs = vec![("mft-16".to_string(), Shadows::EdgeWidth), ("mft-16".to_string(), Shadows::Hard)];
        if cfg!(feature = "embree") {
            configs.push(("embree-16".to_string(), Shadows::Hard));
        }
        PipelineConfig {
            scene: scene.to_string(),
            size,
            rounds,
            configs,
            threads: (1..=cores.max(1)).collect(),
            depth: trace::secondary::DEFAULT_DEPTH,
        }
    }
}

/// One configuration on one pool: medians of each stage.
#[derive(Clone, Debug, Serialize)]
pub struct StageRow {
    /// Scene name.
    pub scene: String,
    /// The method (registry name).
    pub method: String,
    /// `hard`, `edge-width`, ...
    pub shadows: String,
    /// Threads of the pool.
    pub threads: usize,
    /// Median milliseconds of a whole frame (trace and shading).
    pub frame_ms: f64,
    /// `1000 / frame_ms`.
    pub fps: f64,
    /// Frame rate over the one-thread frame rate of the same configuration (1 where only one
    /// pool was measured).
    pub speedup: f64,
    /// Median milliseconds of the primary pass (ray generation, traversal, intersection).
    pub primary_ms: f64,
    /// The share of the primary pass in leaf visits (intersection), where clocked.
    pub primary_intersection: Option<f64>,
    /// The share of the primary pass making its rays, where clocked.
    pub ray_generation: Option<f64>,
    /// Median milliseconds of the primary hits' shadows.
    pub shadow_ms: f64,
    /// Median milliseconds spawning the secondary rays.
    pub spawn_ms: f64,
    /// Median milliseconds tracing the secondary rays.
    pub secondary_ms: f64,
    /// The share of the secondary rays' time in leaf visits (intersection), where clocked.
    pub secondary_intersection: Option<f64>,
    /// Median milliseconds of the secondary hits' shadows.
    pub secondary_shadow_ms: f64,
    /// Median milliseconds of the shading (every hit, the secondary colours summed in).
    pub shade_ms: f64,
    /// Primary rays per frame.
    pub primary_rays: u64,
    /// Secondary rays per frame.
    pub secondary_rays: u64,
    /// Shadow rays per frame (primary and secondary hits).
    pub shadow_rays: u64,
}

impl StageRow {
    /// The stages as (name, milliseconds), in pipeline order. Traversal and intersection are
    /// the pass split by its clocked share; without one (Embree), the traversal row holds the
    /// whole pass and the intersection row is `None`.
    pub fn stages(&self) -> [(&'static str, Option<f64>); 9] {
        let part = |ms: f64, share: Option<f64>| share.map(|s| ms * s);
        let (generation, primary_intersection) =
            (part(self.primary_ms, self.ray_generation), part(self.primary_ms, self.primary_intersection));
        let primary_traversal = self.primary_ms - generation.unwrap_or(0.0) - primary_intersection.unwrap_or(0.0);
        let secondary_intersection = part(self.secondary_ms, self.secondary_intersection);
        let secondary_traversal = self.secondary_ms - secondary_intersection.unwrap_or(0.0);
        [
            ("ray generation", generation),
            ("primary traversal", Some(primary_traversal)),
            ("primary intersection", primary_intersection),
            ("primary shadows", Some(self.shadow_ms)),
            ("spawning secondary rays", Some(self.spawn_ms)),
            ("secondary traversal", Some(secondary_traversal)),
            ("secondary intersection", secondary_intersection),
            ("secondary shadows", Some(self.secondary_shadow_ms)),
            ("shading", Some(self.shade_ms)),
        ]
    }
}

/// The measured rows: each configuration on the current pool, then the first configuration
/// on every pool size of `config.threads` (Table 6.2).
#[derive(Clone, Debug, Serialize)]
pub struct PipelineReport {
    /// Scene, size and rounds.
    pub scene: String,
    /// Image size.
    pub size: (u32, u32),
    /// Rounds.
    pub rounds: u32,
    /// Generations of secondary rays.
    pub depth: u32,
    /// Every configuration on the current pool (Table 3.1 and the frame-rate comparison).
    pub stages: Vec<StageRow>,
    /// The first configuration on each pool size (Table 6.2).
    pub scaling: Vec<StageRow>,
}

/// Runs the pipeline tables (see the module documentation).
pub fn run(config: &PipelineConfig, progress: &dyn Progress) -> Result<PipelineReport, Error> {
    let registry = baselines::registry();
    let (scene, tree, _) = trace::setup::load_and_build(&config.scene, &kdtree::BuildConfig::default())?;
    let (scene, tree) = (&scene, &tree);
    let camera = scene
        .default_view()
        .camera(config.size.0, config.size.1)
        .ok_or_else(|| Error::Usage(format!("{}: no camera at {}x{}", scene.name, config.size.0, config.size.1)))?;
    let mut structures = Structures::new(tree);
    let mut selected = Vec::new();
    for (name, _) in &config.configs {
        let s = registry.select(name, Options::default())?;
        selected.push(s);
    }
    for s in &selected {
        let entry = registry.entry(s.entry);
        if !structures.has(entry.structure) {
            let Some(structure) = registry.structure(entry.structure) else {
                return Err(Error::Usage(format!("no structure '{}' in this build", entry.structure)));
            };
            structures.insert(entry.structure, (structure.build)(scene)?);
        }
    }
    let methods = selected.iter().map(|s| registry.bind(s, &structures)).collect::<Result<Vec<_>, _>>()?;
    let light = trace::soft::scene_light(scene, tree, 1.0);
    let renderers: Vec<Renderer<'_>> = methods
        .iter()
        .zip(&config.configs)
        .map(|(m, &(_, shadows))| {
            Renderer::new(scene, m, camera, shadows).with_light(light).with_tree(tree).with_secondary(config.depth)
        })
        .collect();
    let rounds = config.rounds.max(1);
    let bar = progress.task(
        &format!("pipeline: {}", scene.name),
        Some(u64::from(rounds) * (renderers.len() + config.threads.len()) as u64),
    );
    let frame = |r: &Renderer<'_>, buf: &mut trace::FrameBuffers| {
        let (secs, stats) = timed(|| r.trace(buf));
        let (shade, _) = timed(|| std::hint::black_box(r.color(buf)));
        (secs + shade, stats, shade)
    };
    // Every configuration on the current pool.
    let mut buffers: Vec<_> = renderers.iter().map(|r| r.buffers()).collect();
    for (r, b) in renderers.iter().zip(&mut buffers) {
        frame(r, b);
    }
    let mut samples: Vec<Vec<(f64, trace::FrameStats, f64)>> = vec![Vec::new(); renderers.len()];
    for _ in 0..rounds {
        for ((r, b), s) in renderers.iter().zip(&mut buffers).zip(&mut samples) {
            s.push(frame(r, b));
            bar.inc();
        }
    }
    let threads = rayon::current_num_threads();
    let mut stages: Vec<StageRow> =
        samples.iter().zip(&renderers).zip(&config.configs).map(|((s, _), c)| row(scene, c, threads, s)).collect();
    // One more frame each, its leaf visits clocked: the split of Table 3.1.
    for ((r, b), row) in renderers.iter().zip(&buffers).zip(&mut stages) {
        let shares = r.intersection_shares(b);
        (row.ray_generation, row.primary_intersection, row.secondary_intersection) =
            (shares.generation, shares.primary, shares.secondary);
    }
    // Table 6.2: the first configuration on every pool size, interleaved.
    let mut scaling = Vec::new();
    if let (Some(first), Some(c)) = (renderers.first(), config.configs.first()) {
        let pools = config
            .threads
            .iter()
            .map(|&n| rayon::ThreadPoolBuilder::new().num_threads(n).build())
            .collect::<Result<Vec<_>, _>>()?;
        let mut buf = first.buffers();
        for pool in &pools {
            pool.install(|| frame(first, &mut buf));
        }
        let mut per_pool: Vec<Vec<(f64, trace::FrameStats, f64)>> = vec![Vec::new(); pools.len()];
        for _ in 0..rounds {
            for (pool, s) in pools.iter().zip(&mut per_pool) {
                s.push(pool.install(|| frame(first, &mut buf)));
                bar.inc();
            }
        }
        scaling = per_pool.iter().zip(&config.threads).map(|(s, &n)| row(scene, c, n, s)).collect();
        let one = scaling.first().map_or(0.0, |r: &StageRow| r.fps);
        for r in &mut scaling {
            r.speedup = if one > 0.0 { r.fps / one } else { 0.0 };
        }
    }
    bar.finish();
    Ok(PipelineReport { scene: scene.name.clone(), size: config.size, rounds, depth: config.depth, stages, scaling })
}

/// The medians of one configuration's rounds.
fn row(
    scene: &scenes::Scene,
    (method, shadows): &(String, Shadows),
    threads: usize,
    samples: &[(f64, trace::FrameStats, f64)],
) -> StageRow {
    let ms = |f: &dyn Fn(&(f64, trace::FrameStats, f64)) -> f64| {
        median(&samples.iter().map(|s| f(s) * 1e3).collect::<Vec<_>>())
    };
    let frame_ms = ms(&|s| s.0);
    let last = samples.last().map(|s| s.1).unwrap_or_default();
    StageRow {
        scene: scene.name.clone(),
        method: method.clone(),
        shadows: shadows.name().to_string(),
        threads,
        frame_ms,
        fps: if frame_ms > 0.0 { 1e3 / frame_ms } else { 0.0 },
        speedup: 1.0,
        primary_ms: ms(&|s| s.1.primary_secs),
        primary_intersection: None,
        ray_generation: None,
        shadow_ms: ms(&|s| s.1.shadow_secs),
        spawn_ms: ms(&|s| s.1.spawn_secs),
        secondary_ms: ms(&|s| s.1.secondary_secs),
        secondary_intersection: None,
        secondary_shadow_ms: ms(&|s| s.1.secondary_shadow_secs),
        shade_ms: ms(&|s| s.2),
        primary_rays: last.primary_rays,
        secondary_rays: last.secondary_rays,
        shadow_rays: last.shadow_rays + last.secondary_shadow_rays,
    }
}

impl std::fmt::Display for PipelineReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut out = String::new();
        let (w, h) = self.size;
        let _ = writeln!(out, "\n### Table 3.1: share of frame time per pipeline stage\n");
        let _ = writeln!(
            out,
            "{}, default view, {w}x{h}, {} threads, {} generation(s) of secondary rays; medians of {} interleaved rounds. Thesis (cover scene): primary traversal 21.0%, primary intersection 13.0%, primary shading 12.9%, secondary traversal 34.3%, secondary intersection 12.0%, secondary shading 5.7%.\n",
            self.scene,
            self.stages.first().map_or(0, |r| r.threads),
            self.depth,
            self.rounds
        );
        let mut header = String::from("| stage |");
        let mut rule = String::from("|---|");
        for r in &self.stages {
            let _ = write!(header, " {}, {} shadows |", r.method, r.shadows);
            rule.push_str("---:|");
        }
        let _ = writeln!(out, "{header}\n{rule}");
        for (i, (name, _)) in StageRow::stages(&self.stages[0]).iter().enumerate() {
            let mut line = format!("| {name} |");
            for r in &self.stages {
                match r.stages()[i].1 {
                    Some(ms) => {
                        let _ = write!(line, " {ms:.2} ms ({:.1}%) |", 100.0 * ms / r.frame_ms.max(1e-12));
                    }
                    None => line.push_str(" (with traversal) |"),
                }
            }
            let _ = writeln!(out, "{line}");
        }
        let mut line = String::from("| **frame** |");
        for r in &self.stages {
            let _ = write!(line, " **{:.2} ms, {:.2} fps** |", r.frame_ms, r.fps);
        }
        let _ = writeln!(out, "{line}");
        let mut line = String::from("| rays: primary / secondary / shadow |");
        for r in &self.stages {
            let _ = write!(line, " {} / {} / {} |", r.primary_rays, r.secondary_rays, r.shadow_rays);
        }
        let _ = writeln!(out, "{line}");
        let hard = |fam: &str| self.stages.iter().find(|r| r.shadows == "hard" && r.method.starts_with(fam));
        if let (Some(ours), Some(embree)) = (hard("mft"), hard("embree")) {
            let _ = writeln!(
                out,
                "\nHard shadows in every pass: ours ({}) {:.2} fps, Embree ({}) {:.2} fps: ours / Embree = {:.2}.",
                ours.method,
                ours.fps,
                embree.method,
                embree.fps,
                ours.fps / embree.fps
            );
        }
        if !self.scaling.is_empty() {
            let first = &self.scaling[0];
            let _ = writeln!(out, "\n### Table 6.2: the garage frame against the number of threads\n");
            let _ = writeln!(
                out,
                "{}, {} shadows, {w}x{h}, medians of {} rounds, pool sizes interleaved. Thesis: 4.5 / 9.0 / 17.4 fps on 1 / 2 / 4 cores of a Core 2 Quad at 512x512.\n",
                first.method, first.shadows, self.rounds
            );
            let _ = writeln!(out, "| threads | frame ms | fps | speedup |");
            let _ = writeln!(out, "|---:|---:|---:|---:|");
            for r in &self.scaling {
                let _ = writeln!(out, "| {} | {:.2} | {:.2} | {:.2}x |", r.threads, r.frame_ms, r.fps, r.speedup);
            }
        }
        f.write_str(&out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_add_up_to_the_frame_and_scaling_covers_every_pool() {
        let config = PipelineConfig {
            scene: "touching-boxes".into(),
            size: (32, 24),
            rounds: 2,
            configs: vec![("mft-8".into(), Shadows::EdgeWidth), ("mono".into(), Shadows::Hard)],
            threads: vec![1, 2],
            depth: 1,
        };
        let report = run(&config, &trace::progress::Quiet).unwrap();
        assert_eq!(report.stages.len(), 2);
        assert_eq!(report.scaling.iter().map(|r| r.threads).collect::<Vec<_>>(), vec![1, 2]);
        for r in report.stages.iter().chain(&report.scaling) {
            let sum: f64 = r.stages().iter().filter_map(|s| s.1).sum();
            assert!(r.frame_ms > 0.0 && sum > 0.0, "{r:?}");
            assert_eq!(r.primary_rays, 32 * 24);
        }
        // Both are kd kernels: the primary pass is split, the secondary where rays were traced.
        for r in &report.stages {
            let share = r.primary_intersection.unwrap();
            assert!(share > 0.0 && share < 1.0, "{r:?}");
            let [generation, traversal, intersection] = [0, 1, 2].map(|i| r.stages()[i].1.unwrap());
            assert!(generation > 0.0 && traversal > 0.0, "{r:?}");
            assert!((generation + traversal + intersection - r.primary_ms).abs() < 1e-9);
            assert_eq!(r.secondary_intersection.is_some(), r.secondary_rays > 0, "{r:?}");
        }
        let text = report.to_string();
        assert!(text.contains("Table 3.1") && text.contains("Table 6.2") && text.contains("spawning secondary rays"));
        assert!(text.contains("primary intersection") && text.contains("secondary traversal"));
    }
}
