//! `rttest tables`: the thesis's Tables 4.1-4.6 (Tsakok 2008, 4.1.3-4.1.9) on our scenes.
//!
//! For each scene: primary rays of the default view at 512x512 (by default) with the thesis's
//! simple shading (one point light with attenuation, no shadow rays), traced with single
//! rays, omni-directional 2x2 packets, the single frustum at tiles 4 to 32 (and 8x8 without
//! packet/leaf culling), MFT, one cone and MFT cones at tiles 4 to 32. Each row has the best
//! frame time of
//! `--frames` frames (trace, and trace + shading as the frame rate), Mrays/s, N (traversal
//! steps per 2x2 packet), I (packet-triangle tests per 2x2 packet) and the share of packets
//! culled at leaves, from one extra counted frame. Markdown to stdout, or CSV with `--csv`.
//! Where the scene is Sponza the thesis's own Sponza rows are printed beside ours.
//!
//! Table 4.6 (unless `--no-soft-shadows`): 16 shadow rays per primary hit to a spherical light
//! at the scene's point light, radius 1 and 2 in Sponza units scaled to the scene, traced
//! under one cone, under one pyramid and one by one ([`crate::soft`]).

use std::fmt::Write as _;
use std::time::Instant;

use kdtree::isa::SimdLevel;
use kdtree::{BuildConfig, BuildStrategy, CostModel, Intersector, KdTree};
use scenes::Scene;
use trace::progress::Progress;
use trace::setup::view_camera;
use trace::timing::mrays_per_s;
use trace::{Error, FrameTracer, Options, Renderer, Shadows, SoftGrouping, Structures, TileLayout, soft};

/// What `tables` measures.
#[derive(Clone, Debug, PartialEq)]
pub struct TablesConfig {
    /// Scenes (built-in names or OBJ paths); empty: [`trace::setup::default_scenes`].
    pub scene: Vec<String>,
    /// Image size.
    pub size: (u32, u32),
    /// Frames timed per configuration; the best is kept.
    pub frames: u32,
    /// The ray-triangle test of the trees.
    pub intersector: Intersector,
    /// The SAH cost model of the trees (`CostModel::Thesis` for the thesis's own trees).
    pub cost_model: CostModel,
    /// How the trees' planes are found (`BuildStrategy::Exact` for the thesis's build).
    pub strategy: BuildStrategy,
    /// CSV instead of markdown: one table of the primary-ray rows, then (after a blank line)
    /// one of the soft-shadow rows of Table 4.6.
    pub csv: bool,
    /// Leave out Table 4.6 (16-sample soft shadows, the slowest part).
    pub no_soft_shadows: bool,
    /// Leave out Table 6.2 (frame rate against threads, the best method of each scene).
    pub no_scaling: bool,
    /// Leave out the width ladder ([`crate::ladder`]).
    pub no_ladder: bool,
    /// Only the width ladder: none of the thesis's tables.
    pub only_ladder: bool,
    /// Leave out Table 3.1 and the garage's Table 6.2 ([`crate::pipeline`]).
    pub no_pipeline: bool,
    /// Only Table 3.1 and the garage's Table 6.2.
    pub only_pipeline: bool,
    /// The scene of [`crate::pipeline`] (the thesis's garage).
    pub pipeline_scene: String,
}

impl Default for TablesConfig {
    fn default() -> Self {
        TablesConfig {
            scene: Vec::new(),
            size: (512, 512),
            frames: 5,
            intersector: Intersector::Wald,
            cost_model: CostModel::default(),
            strategy: BuildStrategy::default(),
            csv: false,
            no_soft_shadows: false,
            no_scaling: false,
            no_ladder: false,
            only_ladder: false,
            no_pipeline: false,
            only_pipeline: false,
            pipeline_scene: "garage".into(),
        }
    }
}

/// One measured soft-shadow configuration of one scene (Table 4.6).
#[derive(Clone, Debug)]
struct SoftRow {
    scene: String,
    /// Light radius in Sponza units (scaled to the scene).
    radius: f32,
    /// The row's name (`single`, `pyramid`, `cone`, `stratum packets`, `multi-frusta`,
    /// `lane frusta`).
    label: &'static str,
    /// The soft-shadow kernel that traced it (`kd-single`, `kd-pyramid`, `kd-cone`, ...): the
    /// thesis's rows are found by it.
    kernel: String,
    /// Best shadow-pass time.
    ms: f64,
    mrays: f64,
    /// Traversal steps per shaded point (16 rays).
    n: f64,
    /// Ray-triangle tests per shaded point, counted per 2x2 packet test for the frusta and
    /// per ray / 4 for single rays (the unit of I in Tables 4.1-4.5).
    i: f64,
    /// Mean visible fraction of the light over the shaded points (the same for every method).
    visible: f64,
}

/// One measured configuration of one scene.
#[derive(Clone, Debug)]
struct Row {
    scene: String,
    /// The registry name of the method (`mono`, `mft`, ...).
    method: &'static str,
    tile: u32,
    culling: bool,
    trace_ms: f64,
    fps: f64,
    mrays: f64,
    n: f64,
    i: f64,
    culled: f64,
}

/// The thesis's Sponza figures: (method, tile, fps, N, I) from Tables 4.1, 4.3 and 4.5.
const THESIS_SPONZA: &[(&str, u32, f64, f64, f64)] = &[
    ("packet", 2, 13.60, 33.81, 3.83),
    ("frustum", 4, 17.50, 11.05, 9.86),
    ("frustum", 8, 24.00, 4.17, 22.20),
    ("frustum", 16, 20.60, 2.14, 63.71),
    ("frustum", 32, 9.90, 1.52, 226.81),
    ("mft", 4, 18.80, 10.74, 5.74),
    ("mft", 8, 26.00, 3.92, 9.96),
    ("mft", 16, 27.50, 1.93, 22.86),
    ("mft", 32, 19.50, 1.31, 68.98),
    ("cone", 4, 20.00, 12.10, 13.32),
    ("cone", 8, 22.20, 5.03, 33.40),
    ("cone", 16, 15.50, 2.95, 106.08),
    ("cone", 32, 6.40, 2.30, 382.47),
    ("mft-cone", 4, 18.80, 11.23, 6.93),
    ("mft-cone", 8, 25.00, 4.28, 13.32),
    ("mft-cone", 16, 25.10, 2.27, 33.40),
    ("mft-cone", 32, 15.50, 1.62, 106.08),
];

/// The kernels of the thesis's per-point soft shadows under one cone and one pyramid.
const CONE: &str = "kd-cone";
/// See [`CONE`].
const PYRAMID: &str = "kd-pyramid";

/// The thesis's Table 4.6 (Sponza, 16-sample soft shadows): (radius, soft-shadow kernel, fps,
/// N, I).
const THESIS_SOFT: &[(f32, &str, f64, f64, f64)] = &[
    (1.0, CONE, 2.72, 118.28, 116.10),
    (1.0, PYRAMID, 2.00, 120.72, 129.31),
    (2.0, CONE, 1.97, 164.30, 378.91),
    (2.0, PYRAMID, 1.36, 174.23, 449.69),
];

/// The configurations of every scene: (method, tile, culling).
const CONFIGS: &[(&str, u32, bool)] = &[
    ("mono", 16, true),
    ("packet", 16, true),
    ("frustum", 4, true),
    ("frustum", 8, true),
    ("frustum", 16, true),
    ("frustum", 32, true),
    ("frustum", 8, false),
    ("mft", 4, true),
    ("mft", 8, true),
    ("mft", 16, true),
    ("mft", 32, true),
    ("cone", 4, true),
    ("cone", 8, true),
    ("cone", 16, true),
    ("cone", 32, true),
    ("mft-cone", 4, true),
    ("mft-cone", 8, true),
    ("mft-cone", 16, true),
    ("mft-cone", 32, true),
];

/// The scenes to run: the config's, or the default list.
fn scene_list(config: &TablesConfig) -> Vec<String> {
    if config.scene.is_empty() { trace::setup::default_scenes() } else { config.scene.clone() }
}

/// The options of the thesis's chapter-4 tables: its 2x2 packets (4 lanes, `sse4.1`, or
/// less where the CPU has less), so that N and I count per 2x2 packet as the thesis's do
/// and the rows measure the thesis's kernels. The wider packets of this CPU are the width
/// ladder's (`docs/results/width-ladder.md`); Table 6.2 runs the best method at the
/// default, widest level.
fn thesis_options() -> Options {
    Options { simd: SimdLevel::Sse41.min(SimdLevel::active()), ..Options::default() }
}

/// Measures every configuration on one scene.
fn measure(
    scene: &Scene,
    structures: &Structures<'_>,
    config: &TablesConfig,
    progress: &dyn Progress,
) -> Result<Vec<Row>, Error> {
    let registry = baselines::registry();
    let (w, h) = config.size;
    let (camera, _) = view_camera(scene, None, w, h)?;
    let bar = progress.task(&format!("tables: {}", scene.name), Some(CONFIGS.len() as u64));
    let mut rows = Vec::new();
    let mut shade_secs = f64::INFINITY;
    for &(method, tile, culling) in CONFIGS {
        let selected = registry.select(method, Options { tile, culling, ..thesis_options() })?;
        let bound = registry.bind(&selected, structures)?;
        let renderer = Renderer::new(scene, &bound, camera, Shadows::None);
        let mut buffers = renderer.buffers();
        let mut best = f64::INFINITY;
        for _ in 0..config.frames {
            best = best.min(renderer.trace(&mut buffers).primary_secs);
        }
        let start = Instant::now();
        let _image = renderer.color(&buffers);
        shade_secs = shade_secs.min(start.elapsed().as_secs_f64());
        let (stats, counts, _) = renderer.trace_counted(&mut buffers);
        // Single rays: a 2x2 packet's worth is four rays.
        let packets =
            if bound.entry.packets { renderer.packet_count() as f64 } else { stats.primary_rays as f64 / 4.0 };
        let (n, i) = (counts.nodes as f64 / packets, counts.tests as f64 / packets);
        rows.push(Row {
            scene: scene.name.clone(),
            method: bound.entry.name,
            tile,
            culling,
            trace_ms: best * 1e3,
            fps: 0.0,
            mrays: mrays_per_s(stats.primary_rays, best),
            n,
            i,
            culled: counts.culled_percent().unwrap_or(0.0),
        });
        bar.inc();
    }
    bar.finish();
    // The frame rate counts the trace and the (same for every method) shading pass.
    for row in &mut rows {
        row.fps = 1.0 / (row.trace_ms * 1e-3 + shade_secs);
    }
    Ok(rows)
}

/// The rows of Table 4.6: (name, the registered method and soft-shadow grouping whose kernel
/// it is). The thesis's three per point (single rays, the pyramid of the
/// 16 rays, their cone), then each tile's rays to each light stratum as 2x2 packets (`mft`,
/// the default of every packet and cone method), as Benthin & Wald's shadow frusta
/// (`multi-frusta`), and each point's 16 rays as one of their multi-frusta in SIMD lanes
/// (`lane-frusta`).
const SOFT_ROWS: [(&str, &str, SoftGrouping); 6] = [
    ("single", "mono", SoftGrouping::Strata),
    ("pyramid", "packet", SoftGrouping::PerPoint),
    ("cone", "cone", SoftGrouping::PerPoint),
    ("stratum packets", "mft", SoftGrouping::Strata),
    ("multi-frusta", "multi-frusta", SoftGrouping::Strata),
    ("lane frusta", "lane-frusta", SoftGrouping::Strata),
];

/// Times the 16-sample soft shadows of every hit of the default view to a spherical light at
/// the scene's point light, radius 1 and 2 in Sponza units scaled to the scene, for each row
/// of [`SOFT_ROWS`], and checks that they agree.
fn measure_soft(
    scene: &Scene,
    structures: &Structures<'_>,
    config: &TablesConfig,
    progress: &dyn Progress,
) -> Result<Vec<SoftRow>, Error> {
    let registry = baselines::registry();
    let (w, h) = config.size;
    let (camera, _) = view_camera(scene, None, w, h)?;
    let layout = TileLayout::new(w, h, trace::registry::TILE_SIZE);
    let surfaces = trace::shade::surfaces(&scene.mesh);
    let view = trace::frame::View { layout: &layout, scene, surfaces: &surfaces, camera: &camera };
    let mono = registry.bind(&registry.select("mono", Options::default())?, structures)?;
    let mut hits = vec![None; layout.pixel_count()];
    mono.tracer.primary(&layout, &camera, &mut hits, None);
    let frames = config.frames.min(3);
    let bar = progress.task(&format!("table 4.6: {}", scene.name), Some(2 * SOFT_ROWS.len() as u64));
    let mut rows = Vec::new();
    let mut visible = vec![0.0f32; layout.pixel_count()];
    for radius in [1.0f32, 2.0] {
        let light = soft::scene_light(scene, structures.kdtree(), radius);
        let mut reference: Option<Vec<f32>> = None;
        for (label, method, soft) in SOFT_ROWS {
            let bound = registry.bind(&registry.select(method, Options { soft, ..thesis_options() })?, structures)?;
            let tracer: &dyn FrameTracer = &*bound.tracer;
            let mut best = f64::INFINITY;
            let mut stats = Default::default();
            for _ in 0..frames {
                let start = Instant::now();
                stats = tracer.soft(&view, &hits, &light, &mut visible, None);
                best = best.min(start.elapsed().as_secs_f64());
            }
            match &reference {
                None => reference = Some(visible.clone()),
                Some(r) if *r != visible => {
                    return Err(Error::Usage(format!(
                        "{}: {} soft shadows differ from single rays (a bug: please report it)",
                        scene.name, label
                    )));
                }
                Some(_) => {}
            }
            let mut counts = kdtree::Counts::default();
            let counted = tracer.soft(&view, &hits, &light, &mut visible, Some(&mut counts));
            let points = counted.points.max(1) as f64;
            let tests = if method == "mono" { counts.tests as f64 / 4.0 } else { counts.tests as f64 };
            rows.push(SoftRow {
                scene: scene.name.clone(),
                radius,
                label,
                kernel: bound.kernels.soft.clone(),
                ms: best * 1e3,
                mrays: mrays_per_s(stats.rays, best),
                n: counts.nodes as f64 / points,
                i: tests / points,
                visible: visible.iter().map(|&v| f64::from(v)).sum::<f64>() / points,
            });
            bar.inc();
        }
    }
    bar.finish();
    Ok(rows)
}

/// The measured tables, printed by `Display` (markdown, or CSV with `config.csv`).
#[derive(Clone, Debug)]
pub struct TablesReport {
    config: TablesConfig,
    rows: Vec<Row>,
    soft_rows: Vec<SoftRow>,
    scaling_rows: Vec<crate::scaling::ScalingRow>,
    threads: usize,
    table51: String,
    ladder: Option<crate::ladder::LadderReport>,
    pipeline: Option<crate::pipeline::PipelineReport>,
}

/// Measures Tables 4.1-4.6, 6.2 and 5.1 (see the module documentation) on the current rayon
/// pool.
pub fn run(config: &TablesConfig, progress: &dyn Progress) -> Result<TablesReport, Error> {
    let pipeline = ((!config.no_pipeline && !config.only_ladder) || config.only_pipeline)
        .then(|| {
            let rounds = config.frames.max(3);
            let pipeline = crate::pipeline::PipelineConfig::thesis(
                &config.pipeline_scene,
                config.size,
                rounds,
                crate::scaling::cores(),
            );
            crate::pipeline::run(&pipeline, progress)
        })
        .transpose()?;
    let ladder = (!config.only_pipeline && (!config.no_ladder || config.only_ladder))
        .then(|| {
            let scenes = scene_list(config);
            crate::ladder::run(
                &crate::ladder::LadderConfig { scenes, size: config.size, rounds: config.frames },
                progress,
            )
        })
        .transpose()?;
    if config.only_ladder || config.only_pipeline {
        return Ok(TablesReport {
            config: config.clone(),
            rows: Vec::new(),
            soft_rows: Vec::new(),
            scaling_rows: Vec::new(),
            threads: rayon::current_num_threads(),
            table51: String::new(),
            ladder,
            pipeline,
        });
    }
    let registry = baselines::registry();
    let mut all = Vec::new();
    let mut soft_rows = Vec::new();
    let mut scaling_rows = Vec::new();
    let build =
        BuildConfig { intersector: config.intersector, strategy: config.strategy, ..config.cost_model.config() };
    for spec in scene_list(config) {
        let scene = scenes::load_scene(&spec)?;
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &build)?;
        let structures = Structures::new(&tree);
        let rows = measure(&scene, &structures, config, progress)?;
        if !config.no_scaling
            && let Some(best) = rows.iter().filter(|r| r.culling).max_by(|a, b| a.fps.total_cmp(&b.fps))
            && let Some(camera) = scene.default_view().camera(config.size.0, config.size.1)
        {
            let bound = registry
                .bind(&registry.select(best.method, Options { tile: best.tile, ..Options::default() })?, &structures)?;
            let cores = crate::scaling::cores();
            let rounds = config.frames.max(5);
            scaling_rows.extend(crate::scaling::measure(&scene, &bound, camera, cores, rounds)?);
        }
        all.extend(rows);
        if !config.no_soft_shadows {
            soft_rows.extend(measure_soft(&scene, &structures, config, progress)?);
        }
    }
    let table51 = crate::table51::table51(config.size, config.frames, &build, config.csv)?;
    Ok(TablesReport {
        config: config.clone(),
        rows: all,
        soft_rows,
        scaling_rows,
        threads: rayon::current_num_threads(),
        table51,
        ladder,
        pipeline,
    })
}

impl std::fmt::Display for TablesReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let config = &self.config;
        let ladder = self.ladder.as_ref();
        let text = if config.csv {
            let only = config.only_ladder || config.only_pipeline;
            let mut text = if only { String::new() } else { csv(&self.rows) };
            if !self.soft_rows.is_empty() {
                text.push('\n');
                text.push_str(&soft_csv(&self.soft_rows));
            }
            if !self.scaling_rows.is_empty() {
                text.push('\n');
                text.push_str(&crate::scaling::csv(&self.scaling_rows));
            }
            if let Some(ladder) = ladder {
                if !text.is_empty() {
                    text.push('\n');
                }
                text.push_str(&ladder.csv());
            }
            text
        } else {
            let only = config.only_ladder || config.only_pipeline;
            let mut text = if only { String::new() } else { markdown(&self.rows, config, self.threads) };
            if !self.soft_rows.is_empty() {
                text.push_str(&soft_markdown(&self.soft_rows, config, self.threads));
            }
            if !self.scaling_rows.is_empty() {
                text.push_str(&crate::scaling::markdown(&self.scaling_rows, config.size, config.frames.max(5)));
            }
            if let Some(ladder) = ladder {
                text.push_str(&ladder.to_string());
            }
            if let Some(pipeline) = &self.pipeline {
                text.push_str(&pipeline.to_string());
            }
            text
        };
        write!(f, "{text}{}", self.table51)
    }
}

fn label(r: &Row) -> String {
    match r.method {
        "mono" => "single rays".into(),
        "packet" => "packet 2x2".into(),
        m => format!("{} {}x{}{}", m, r.tile, r.tile, if r.culling { "" } else { " (no culling)" }),
    }
}

fn csv(rows: &[Row]) -> String {
    let mut out = String::from("scene,method,tile,culling,trace_ms,fps,mrays_per_s,n,i,culled_percent\n");
    for r in rows {
        let _ = writeln!(
            out,
            "{},{},{},{},{:.3},{:.2},{:.3},{:.3},{:.3},{:.2}",
            r.scene, r.method, r.tile, r.culling, r.trace_ms, r.fps, r.mrays, r.n, r.i, r.culled
        );
    }
    out
}

fn find<'a>(rows: &'a [Row], scene: &str, method: &str, tile: u32, culling: bool) -> Option<&'a Row> {
    rows.iter().find(|r| {
        r.scene == scene && r.method == method && (r.tile == tile || method == "packet") && r.culling == culling
    })
}

fn thesis(scene: &str, method: &str, tile: u32) -> Option<(f64, f64, f64)> {
    if !scene.to_lowercase().starts_with("sponza") {
        return None;
    }
    THESIS_SPONZA.iter().find(|t| t.0 == method && (t.1 == tile || method == "packet")).map(|t| (t.2, t.3, t.4))
}

/// The fastest row of `method` on `scene` (culling on).
fn best_of<'a>(rows: &'a [Row], scene: &str, method: &str) -> Option<&'a Row> {
    rows.iter().filter(|r| r.scene == scene && r.method == method && r.culling).max_by(|a, b| a.fps.total_cmp(&b.fps))
}

fn pct(new: f64, old: f64) -> f64 {
    100.0 * (new - old) / old
}

/// The columns of a Table 4.3 or 4.5 row from the tile on: `r` (MFT, a cone or MFT cones)
/// against the single frustum of the same tile, then the thesis's figures for the same
/// comparison; `None` where that frustum was not measured.
fn against_frustum(rows: &[Row], r: &Row) -> Option<String> {
    let f = find(rows, &r.scene, "frustum", r.tile, true)?;
    let th = match (thesis(&r.scene, r.method, r.tile), thesis(&r.scene, "frustum", r.tile)) {
        (Some(m), Some(f)) => format!("{:+.1}% | {:+.1}% | {:+.1}%", pct(m.0, f.0), pct(m.1, f.1), pct(m.2, f.2)),
        _ => " | | ".into(),
    };
    Some(format!(
        "{}x{} | {:.1} | {:.2} | {:.2} | {:.2} | {:+.1}% | {:+.1}% | {:+.1}% | {th} |",
        r.tile,
        r.tile,
        r.fps,
        r.mrays,
        r.n,
        r.i,
        pct(r.fps, f.fps),
        pct(r.n, f.n),
        pct(r.i, f.i)
    ))
}

fn markdown(rows: &[Row], config: &TablesConfig, threads: usize) -> String {
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    let mut out = String::new();
    let (w, h) = config.size;
    let _ = writeln!(
        out,
        "Primary rays, default views, {w}x{h}, {} threads, best of {} frames. fps = 1 / (trace + shading); N = traversal steps and I = packet-triangle tests per 2x2 packet (single rays: per ray x 4).\n",
        threads, config.frames
    );

    let _ = writeln!(out, "### Table 4.1: packets and frusta\n");
    let _ = writeln!(out, "| scene | method | trace ms | fps | Mrays/s | N | I | thesis fps | thesis N | thesis I |");
    let _ = writeln!(out, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows.iter().filter(|r| matches!(r.method, "mono" | "packet" | "frustum") && r.culling) {
        let t = thesis(&r.scene, r.method, r.tile);
        let th = |f: fn((f64, f64, f64)) -> f64| t.map_or("".into(), |t| format!("{:.2}", f(t)));
        let _ = writeln!(
            out,
            "| {} | {} | {:.2} | {:.1} | {:.2} | {:.2} | {:.2} | {} | {} | {} |",
            r.scene,
            label(r),
            r.trace_ms,
            r.fps,
            r.mrays,
            r.n,
            r.i,
            th(|t| t.0),
            th(|t| t.1),
            th(|t| t.2)
        );
    }

    let _ = writeln!(out, "\n### Table 4.2: packet/leaf culling, frustum 8x8\n");
    let _ = writeln!(
        out,
        "| scene | fps with culling | fps without | change from culling | packets culled | I with | I without |"
    );
    let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|---:|");
    for s in &scenes {
        if let (Some(on), Some(off)) = (find(rows, s, "frustum", 8, true), find(rows, s, "frustum", 8, false)) {
            let _ = writeln!(
                out,
                "| {s} | {:.1} | {:.1} | {:+.1}% | {:.1}% | {:.2} | {:.2} |",
                on.fps,
                off.fps,
                pct(on.fps, off.fps),
                on.culled,
                on.i,
                off.i
            );
        }
    }

    let _ = writeln!(out, "\n### Table 4.3: MFT against the single frustum of the same tile\n");
    let _ = writeln!(
        out,
        "| scene | tile | fps | Mrays/s | N | I | % fps | % N | % I | thesis % fps | thesis % N | thesis % I |"
    );
    let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows.iter().filter(|r| r.method == "mft") {
        if let Some(columns) = against_frustum(rows, r) {
            let _ = writeln!(out, "| {} | {columns}", r.scene);
        }
    }

    let _ = writeln!(out, "\n### Table 4.4: peak MFT against the peak single frustum\n");
    let _ = writeln!(out, "| scene | MFT fps | MFT tile | frustum fps | frustum tile | MFT gain | thesis gain |");
    let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|---:|");
    for s in &scenes {
        let best = |m: &str| best_of(rows, s, m);
        if let (Some(m), Some(f)) = (best("mft"), best("frustum")) {
            let th = if s.to_lowercase().starts_with("sponza") {
                format!("{:+.1}%", pct(27.5, 24.0))
            } else {
                String::new()
            };
            let _ = writeln!(
                out,
                "| {s} | {:.1} | {}x{} | {:.1} | {}x{} | {:+.1}% | {th} |",
                m.fps,
                m.tile,
                m.tile,
                f.fps,
                f.tile,
                f.tile,
                pct(m.fps, f.fps)
            );
        }
    }

    let _ = writeln!(
        out,
        "\n### Table 4.5: single cone and MFT cones against the single pyramid frustum of the same tile\n"
    );
    let _ = writeln!(
        out,
        "| scene | method | tile | fps | Mrays/s | N | I | % fps | % N | % I | thesis % fps | thesis % N | thesis % I |"
    );
    let _ = writeln!(out, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows.iter().filter(|r| matches!(r.method, "cone" | "mft-cone")) {
        if let Some(columns) = against_frustum(rows, r) {
            let _ = writeln!(out, "| {} | {} | {columns}", r.scene, r.method);
        }
    }
    out
}

fn soft_csv(rows: &[SoftRow]) -> String {
    let mut out = String::from("scene,radius,method,shadow_ms,fps,mrays_per_s,n,i,visible\n");
    for r in rows {
        let _ = writeln!(
            out,
            "{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.4}",
            r.scene,
            r.radius,
            r.label,
            r.ms,
            1e3 / r.ms,
            r.mrays,
            r.n,
            r.i,
            r.visible
        );
    }
    out
}

fn soft_markdown(rows: &[SoftRow], config: &TablesConfig, threads: usize) -> String {
    let mut out = String::new();
    let (w, h) = config.size;
    let _ = writeln!(
        out,
        "\n### Table 4.6: 16-sample soft shadows to a spherical light, cone against pyramid, and per light stratum\n"
    );
    let _ = writeln!(
        out,
        "Default views, {w}x{h}, {} threads, best of {} frames of the shadow pass alone (primary hits made once by single rays). Light at the scene's point light, radius 1 and 2 in Sponza units scaled by the scene's diagonal / {:.2}. fps = 1 / shadow pass; N = traversal steps and I = packet-triangle tests (single rays: tests / 4) per shaded point of 16 rays (multi-frusta: ray-triangle tests at frustum leaves plus packet-triangle tests of the 2x2 packets it hands over; lane frusta: steps of 8 or 4 frusta together, and 4-ray packet-triangle tests); every row agrees with single rays ray by ray (checked). `stratum packets` (`mft`) and `multi-frusta` trace each tile's rays to each of the 16 light strata together (Benthin & Wald 2009), as 2x2 packets or as shadow frusta; `lane frusta` (`lane-frusta`) each point's 16 rays as one frustum, several points in SIMD lanes.\n",
        threads,
        config.frames.min(3),
        soft::SPONZA_DIAGONAL
    );
    let _ = writeln!(
        out,
        "| scene | radius | method | shadow ms | fps | Mrays/s | N | I | visible | cone / pyramid time | thesis fps | thesis N | thesis I |"
    );
    let _ = writeln!(out, "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        let pyramid = rows.iter().find(|p| p.scene == r.scene && p.radius == r.radius && p.kernel == PYRAMID);
        let ratio = match pyramid {
            Some(p) if r.kernel == CONE => format!("{:.2}", r.ms / p.ms),
            _ => String::new(),
        };
        let th = THESIS_SOFT
            .iter()
            .find(|t| r.scene.to_lowercase().starts_with("sponza") && t.0 == r.radius && t.1 == r.kernel)
            .map_or(" | | ".to_string(), |t| format!("{:.2} | {:.2} | {:.2}", t.2, t.3, t.4));
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:.1} | {:.2} | {:.2} | {:.1} | {:.1} | {:.3} | {ratio} | {th} |",
            r.scene,
            r.radius,
            r.label,
            r.ms,
            1e3 / r.ms,
            r.mrays,
            r.n,
            r.i,
            r.visible
        );
    }
    out
}
