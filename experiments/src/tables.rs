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

use clap::Args;
use cones::ShadowMethod;
use kdtree::{BuildConfig, KdTree, NoCounters};
use packets::PacketCounts;
use scenes::{Scene, SphereLight};

use crate::Error;
use crate::cli::{GlobalArgs, IntersectorArg, parse_size};
use crate::progress::{self, Progress};
use crate::render::{Method, Renderer, Shadows};
use crate::report::mrays_per_s;
use crate::soft;

/// `rttest tables` options.
#[derive(Debug, Clone, Args)]
pub struct TablesArgs {
    /// Scenes (built-in names or OBJ paths; repeatable). Default: atrium, arena,
    /// atrium-rotated, grove and every .obj / .obj.gz in the shared scenes folder.
    #[arg(long, value_name = "NAME|PATH")]
    pub scene: Vec<String>,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "512x512", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Frames timed per configuration; the best is kept.
    #[arg(long, default_value_t = 5, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub frames: u32,
    /// The ray-triangle test.
    #[arg(long, value_enum, default_value_t = IntersectorArg::Wald)]
    pub intersector: IntersectorArg,
    /// Print the rows as CSV instead of the markdown tables: one table of the primary-ray
    /// rows, then (after a blank line) one of the soft-shadow rows of Table 4.6.
    #[arg(long)]
    pub csv: bool,
    /// Leave out Table 4.6 (16-sample soft shadows, the slowest part).
    #[arg(long)]
    pub no_soft_shadows: bool,
    /// Leave out Table 6.2 (frame rate against threads, the best method of each scene).
    #[arg(long)]
    pub no_scaling: bool,
}

/// One measured soft-shadow configuration of one scene (Table 4.6).
#[derive(Clone, Debug)]
struct SoftRow {
    scene: String,
    /// Light radius in Sponza units (scaled to the scene).
    radius: f32,
    method: ShadowMethod,
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
    method: Method,
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
const THESIS_SPONZA: &[(Method, u32, f64, f64, f64)] = &[
    (Method::Packet, 2, 13.60, 33.81, 3.83),
    (Method::Frustum, 4, 17.50, 11.05, 9.86),
    (Method::Frustum, 8, 24.00, 4.17, 22.20),
    (Method::Frustum, 16, 20.60, 2.14, 63.71),
    (Method::Frustum, 32, 9.90, 1.52, 226.81),
    (Method::Mft, 4, 18.80, 10.74, 5.74),
    (Method::Mft, 8, 26.00, 3.92, 9.96),
    (Method::Mft, 16, 27.50, 1.93, 22.86),
    (Method::Mft, 32, 19.50, 1.31, 68.98),
    (Method::Cone, 4, 20.00, 12.10, 13.32),
    (Method::Cone, 8, 22.20, 5.03, 33.40),
    (Method::Cone, 16, 15.50, 2.95, 106.08),
    (Method::Cone, 32, 6.40, 2.30, 382.47),
    (Method::MftCone, 4, 18.80, 11.23, 6.93),
    (Method::MftCone, 8, 25.00, 4.28, 13.32),
    (Method::MftCone, 16, 25.10, 2.27, 33.40),
    (Method::MftCone, 32, 15.50, 1.62, 106.08),
];

/// The thesis's Table 4.6 (Sponza, 16-sample soft shadows): (radius, method, fps, N, I).
const THESIS_SOFT: &[(f32, ShadowMethod, f64, f64, f64)] = &[
    (1.0, ShadowMethod::Cone, 2.72, 118.28, 116.10),
    (1.0, ShadowMethod::Pyramid, 2.00, 120.72, 129.31),
    (2.0, ShadowMethod::Cone, 1.97, 164.30, 378.91),
    (2.0, ShadowMethod::Pyramid, 1.36, 174.23, 449.69),
];

/// The configurations of every scene: (method, tile, culling).
const CONFIGS: &[(Method, u32, bool)] = &[
    (Method::Mono, 16, true),
    (Method::Packet, 16, true),
    (Method::Frustum, 4, true),
    (Method::Frustum, 8, true),
    (Method::Frustum, 16, true),
    (Method::Frustum, 32, true),
    (Method::Frustum, 8, false),
    (Method::Mft, 4, true),
    (Method::Mft, 8, true),
    (Method::Mft, 16, true),
    (Method::Mft, 32, true),
    (Method::Cone, 4, true),
    (Method::Cone, 8, true),
    (Method::Cone, 16, true),
    (Method::Cone, 32, true),
    (Method::MftCone, 4, true),
    (Method::MftCone, 8, true),
    (Method::MftCone, 16, true),
    (Method::MftCone, 32, true),
];

/// The scenes to run: the arguments, or the four built-in stand-ins and the shared OBJs.
fn scene_list(args: &TablesArgs) -> Vec<String> {
    if !args.scene.is_empty() {
        return args.scene.clone();
    }
    let mut list: Vec<String> = ["atrium", "arena", "atrium-rotated", "grove"].map(String::from).to_vec();
    if let Some(dir) = scenes::shared_scenes_dir()
        && let Ok(entries) = std::fs::read_dir(dir)
    {
        let mut files: Vec<String> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                let name = p.file_name().map(|n| n.to_string_lossy().to_lowercase()).unwrap_or_default();
                name.ends_with(".obj") || name.ends_with(".obj.gz")
            })
            .map(|p| p.display().to_string())
            .collect();
        files.sort();
        list.extend(files);
    }
    list
}

/// Measures every configuration on one scene.
fn measure(scene: &Scene, tree: &KdTree, args: &TablesArgs, show: bool) -> Result<Vec<Row>, Error> {
    let (w, h) = args.size;
    let (camera, _) = crate::cli::view_camera(scene, None, w, h)?;
    let bar = Progress::bar(CONFIGS.len() as u64, &format!("tables: {}", scene.name), show);
    let mut rows = Vec::new();
    let mut shade_secs = f64::INFINITY;
    for &(method, tile, culling) in CONFIGS {
        let renderer = Renderer::new(scene, tree, camera, method, Shadows::None)
            .with_tile(tile)
            .map_err(|e| Error::Usage(e.to_string()))?
            .with_culling(culling);
        let mut buffers = renderer.buffers();
        let mut best = f64::INFINITY;
        for _ in 0..args.frames {
            best = best.min(renderer.trace(&mut buffers).primary_secs);
        }
        let start = Instant::now();
        let _image = renderer.color(&buffers);
        shade_secs = shade_secs.min(start.elapsed().as_secs_f64());
        let (stats, counts, _) = renderer.trace_counted(&mut buffers);
        // Single rays: a 2x2 packet's worth is four rays.
        let packets = match method {
            Method::Mono => stats.primary_rays as f64 / 4.0,
            _ => renderer.packet_count() as f64,
        };
        let (n, i) = (counts.nodes as f64 / packets, counts.tests as f64 / packets);
        rows.push(Row {
            scene: scene.name.clone(),
            method,
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

/// Times the 16-sample soft shadows of every hit of the default view to a spherical light at
/// the scene's point light, radius 1 and 2 in Sponza units scaled to the scene, for each
/// [`ShadowMethod`], and checks that they agree.
fn measure_soft(scene: &Scene, tree: &KdTree, args: &TablesArgs, show: bool) -> Result<Vec<SoftRow>, Error> {
    let (w, h) = args.size;
    let (camera, _) = crate::cli::view_camera(scene, None, w, h)?;
    let hits = soft::primary_hits(scene, tree, &camera);
    let diag = (tree.bounds().max - tree.bounds().min).length();
    let frames = args.frames.min(3);
    let bar = Progress::bar(2 * ShadowMethod::ALL.len() as u64, &format!("table 4.6: {}", scene.name), show);
    let mut rows = Vec::new();
    for radius in [1.0f32, 2.0] {
        let light = SphereLight {
            center: scene.point_light.position,
            radius: soft::scaled_radius(radius, diag),
            intensity: scene.point_light.intensity,
        };
        let mut reference: Option<Vec<f32>> = None;
        for method in ShadowMethod::ALL {
            let mut best = f64::INFINITY;
            let mut pass = None;
            for _ in 0..frames {
                let start = Instant::now();
                let p = soft::soft_shadow_pass::<NoCounters>(scene, tree, &camera, &hits, &light, method);
                best = best.min(start.elapsed().as_secs_f64());
                pass = Some(p);
            }
            let pass = pass.expect("at least one frame");
            match &reference {
                None => reference = Some(pass.visible.clone()),
                Some(r) if *r != pass.visible => {
                    return Err(Error::Usage(format!(
                        "{}: {} soft shadows differ from single rays (a bug: please report it)",
                        scene.name,
                        method.name()
                    )));
                }
                Some(_) => {}
            }
            let counted = soft::soft_shadow_pass::<PacketCounts>(scene, tree, &camera, &hits, &light, method);
            let points = counted.points.max(1) as f64;
            let tests = if method == ShadowMethod::Single {
                counted.counts.tests as f64 / 4.0
            } else {
                counted.counts.tests as f64
            };
            rows.push(SoftRow {
                scene: scene.name.clone(),
                radius,
                method,
                ms: best * 1e3,
                mrays: mrays_per_s(pass.rays, best),
                n: counted.counts.nodes as f64 / points,
                i: tests / points,
                visible: pass.visible.iter().map(|&v| f64::from(v)).sum::<f64>() / points,
            });
            bar.inc();
        }
    }
    bar.finish();
    Ok(rows)
}

/// `rttest tables`.
pub fn tables_command(global: &GlobalArgs, args: &TablesArgs) -> Result<(), Error> {
    let show = progress::enabled(global.json);
    let mut all = Vec::new();
    let mut soft_rows = Vec::new();
    let mut scaling_rows = Vec::new();
    for spec in scene_list(args) {
        let scene = scenes::load_scene(&spec)?;
        let config = BuildConfig { intersector: args.intersector.into(), ..BuildConfig::default() };
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &config)?;
        let rows = measure(&scene, &tree, args, show)?;
        if !args.no_scaling
            && let Some(best) = rows.iter().filter(|r| r.culling).max_by(|a, b| a.fps.total_cmp(&b.fps))
            && let Some(camera) = scene.default_view().camera(args.size.0, args.size.1)
        {
            let cores = crate::scaling::cores();
            let rounds = args.frames.max(5);
            scaling_rows.extend(crate::scaling::measure(&scene, &tree, camera, best.method, best.tile, cores, rounds)?);
        }
        all.extend(rows);
        if !args.no_soft_shadows {
            soft_rows.extend(measure_soft(&scene, &tree, args, show)?);
        }
    }
    let text = if args.csv {
        let mut text = csv(&all);
        if !soft_rows.is_empty() {
            text.push('\n');
            text.push_str(&soft_csv(&soft_rows));
        }
        if !scaling_rows.is_empty() {
            text.push('\n');
            text.push_str(&crate::scaling::csv(&scaling_rows));
        }
        text
    } else {
        let mut text = markdown(&all, args);
        if !soft_rows.is_empty() {
            text.push_str(&soft_markdown(&soft_rows, args));
        }
        if !scaling_rows.is_empty() {
            text.push_str(&crate::scaling::markdown(&scaling_rows, args.size, args.frames.max(5)));
        }
        text
    };
    print!("{text}");
    let config = BuildConfig { intersector: args.intersector.into(), ..BuildConfig::default() };
    print!("{}", crate::table51::table51(args.size, args.frames, &config, args.csv)?);
    Ok(())
}

fn label(r: &Row) -> String {
    match r.method {
        Method::Mono => "single rays".into(),
        Method::Packet => "packet 2x2".into(),
        m => format!("{} {}x{}{}", m.name(), r.tile, r.tile, if r.culling { "" } else { " (no culling)" }),
    }
}

fn csv(rows: &[Row]) -> String {
    let mut out = String::from("scene,method,tile,culling,trace_ms,fps,mrays_per_s,n,i,culled_percent\n");
    for r in rows {
        let _ = writeln!(
            out,
            "{},{},{},{},{:.3},{:.2},{:.3},{:.3},{:.3},{:.2}",
            r.scene,
            r.method.name(),
            r.tile,
            r.culling,
            r.trace_ms,
            r.fps,
            r.mrays,
            r.n,
            r.i,
            r.culled
        );
    }
    out
}

fn find<'a>(rows: &'a [Row], scene: &str, method: Method, tile: u32, culling: bool) -> Option<&'a Row> {
    rows.iter().find(|r| {
        r.scene == scene && r.method == method && (r.tile == tile || method == Method::Packet) && r.culling == culling
    })
}

fn thesis(scene: &str, method: Method, tile: u32) -> Option<(f64, f64, f64)> {
    if !scene.to_lowercase().starts_with("sponza") {
        return None;
    }
    THESIS_SPONZA.iter().find(|t| t.0 == method && (t.1 == tile || method == Method::Packet)).map(|t| (t.2, t.3, t.4))
}

/// The fastest row of `method` on `scene` (culling on).
fn best_of<'a>(rows: &'a [Row], scene: &str, method: Method) -> Option<&'a Row> {
    rows.iter().filter(|r| r.scene == scene && r.method == method && r.culling).max_by(|a, b| a.fps.total_cmp(&b.fps))
}

fn pct(new: f64, old: f64) -> f64 {
    100.0 * (new - old) / old
}

fn markdown(rows: &[Row], args: &TablesArgs) -> String {
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    let mut out = String::new();
    let (w, h) = args.size;
    let _ = writeln!(
        out,
        "Primary rays, default views, {w}x{h}, {} threads, best of {} frames. fps = 1 / (trace + shading); N = traversal steps and I = packet-triangle tests per 2x2 packet (single rays: per ray x 4).\n",
        rayon::current_num_threads(),
        args.frames
    );

    let _ = writeln!(out, "### Table 4.1: packets and frusta\n");
    let _ = writeln!(out, "| scene | method | trace ms | fps | Mrays/s | N | I | thesis fps | thesis N | thesis I |");
    let _ = writeln!(out, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows.iter().filter(|r| matches!(r.method, Method::Mono | Method::Packet | Method::Frustum) && r.culling) {
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
        if let (Some(on), Some(off)) =
            (find(rows, s, Method::Frustum, 8, true), find(rows, s, Method::Frustum, 8, false))
        {
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
    for r in rows.iter().filter(|r| r.method == Method::Mft) {
        let Some(f) = find(rows, &r.scene, Method::Frustum, r.tile, true) else { continue };
        let th = match (thesis(&r.scene, Method::Mft, r.tile), thesis(&r.scene, Method::Frustum, r.tile)) {
            (Some(m), Some(f)) => format!("{:+.1}% | {:+.1}% | {:+.1}%", pct(m.0, f.0), pct(m.1, f.1), pct(m.2, f.2)),
            _ => " | | ".into(),
        };
        let _ = writeln!(
            out,
            "| {} | {}x{} | {:.1} | {:.2} | {:.2} | {:.2} | {:+.1}% | {:+.1}% | {:+.1}% | {th} |",
            r.scene,
            r.tile,
            r.tile,
            r.fps,
            r.mrays,
            r.n,
            r.i,
            pct(r.fps, f.fps),
            pct(r.n, f.n),
            pct(r.i, f.i)
        );
    }

    let _ = writeln!(out, "\n### Table 4.4: peak MFT against the peak single frustum\n");
    let _ = writeln!(out, "| scene | MFT fps | MFT tile | frustum fps | frustum tile | MFT gain | thesis gain |");
    let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|---:|");
    for s in &scenes {
        let best = |m: Method| best_of(rows, s, m);
        if let (Some(m), Some(f)) = (best(Method::Mft), best(Method::Frustum)) {
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
    for r in rows.iter().filter(|r| matches!(r.method, Method::Cone | Method::MftCone)) {
        let Some(f) = find(rows, &r.scene, Method::Frustum, r.tile, true) else { continue };
        let th = match (thesis(&r.scene, r.method, r.tile), thesis(&r.scene, Method::Frustum, r.tile)) {
            (Some(m), Some(f)) => format!("{:+.1}% | {:+.1}% | {:+.1}%", pct(m.0, f.0), pct(m.1, f.1), pct(m.2, f.2)),
            _ => " | | ".into(),
        };
        let _ = writeln!(
            out,
            "| {} | {} | {}x{} | {:.1} | {:.2} | {:.2} | {:.2} | {:+.1}% | {:+.1}% | {:+.1}% | {th} |",
            r.scene,
            r.method.name(),
            r.tile,
            r.tile,
            r.fps,
            r.mrays,
            r.n,
            r.i,
            pct(r.fps, f.fps),
            pct(r.n, f.n),
            pct(r.i, f.i)
        );
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
            r.method.name(),
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

fn soft_markdown(rows: &[SoftRow], args: &TablesArgs) -> String {
    let mut out = String::new();
    let (w, h) = args.size;
    let _ = writeln!(out, "\n### Table 4.6: 16-sample soft shadows to a spherical light, cone against pyramid\n");
    let _ = writeln!(
        out,
        "Default views, {w}x{h}, {} threads, best of {} frames of the shadow pass alone (primary hits made once by single rays). Light at the scene's point light, radius 1 and 2 in Sponza units scaled by the scene's diagonal / {:.2}. fps = 1 / shadow pass; N = traversal steps and I = packet-triangle tests (single rays: tests / 4) per shaded point of 16 rays; the three methods agree ray by ray (checked).\n",
        rayon::current_num_threads(),
        args.frames.min(3),
        soft::SPONZA_DIAGONAL
    );
    let _ = writeln!(
        out,
        "| scene | radius | method | shadow ms | fps | Mrays/s | N | I | visible | cone / pyramid time | thesis fps | thesis N | thesis I |"
    );
    let _ = writeln!(out, "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in rows {
        let pyramid =
            rows.iter().find(|p| p.scene == r.scene && p.radius == r.radius && p.method == ShadowMethod::Pyramid);
        let ratio = match (r.method, pyramid) {
            (ShadowMethod::Cone, Some(p)) => format!("{:.2}", r.ms / p.ms),
            _ => String::new(),
        };
        let th = THESIS_SOFT
            .iter()
            .find(|t| r.scene.to_lowercase().starts_with("sponza") && t.0 == r.radius && t.1 == r.method)
            .map_or(" | | ".to_string(), |t| format!("{:.2} | {:.2} | {:.2}", t.2, t.3, t.4));
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:.1} | {:.2} | {:.2} | {:.1} | {:.1} | {:.3} | {ratio} | {th} |",
            r.scene,
            r.radius,
            r.method.name(),
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
