//! The command line: `rttest [render|build|raycast] ...`, and the driver that runs one command.
//!
//! Every command runs inside one rayon pool of `--threads` threads (all cores by default),
//! so the build, the trace passes and the shading all use the same threads. With `--json`
//! each result is one JSON object on its own line of stdout and nothing else goes to stdout.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::{Args, Parser, Subcommand, ValueEnum};
use glam::Vec3;
use kdtree::{BuildConfig, Intersector, KdTree};
use scenes::{Camera, Scene};
use serde::Serialize;
use trace::registry::{KDTREE, Selected, TILE_SIZE};
use trace::report::{BuildReport, RenderReport, TraversalReport, TreeSummary};
use trace::timing::mrays_per_s;
use trace::{Error, FrameBuffers, FrameStats, Options, Registry, Renderer, Shadows, Structures};

use crate::progress::{self, Bar};

pub mod compare;
pub mod culling;
pub mod leaks;
pub mod main_job;
pub mod raycast;
pub mod shadows;
pub mod tables;

/// Largest accepted image side, so a typo cannot ask for terabytes of buffers.
pub const MAX_SIDE: u32 = 16384;

/// Largest accepted pixel count (about 50 bytes of buffers each: 1.6 GB at the limit).
pub const MAX_PIXELS: u64 = 1 << 25;

/// Fast kd-tree ray tracing: build trees, render scenes and trace ray files (after Tsakok 2008, "RTTest").
///
/// Without a command, builds the atrium scene, renders its default view at 512x512 with hard
/// shadows into atrium.png and prints the build time, tree statistics and ray throughput.
/// --threads and --json go before or after the command.
#[derive(Debug, Parser)]
#[command(name = "rttest", version)]
pub struct Cli {
    /// Options of every command.
    #[command(flatten)]
    pub global: GlobalArgs,
    /// The command (default: render atrium).
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// Options accepted by every command.
#[derive(Debug, Clone, Args)]
pub struct GlobalArgs {
    /// Worker threads (default: all cores).
    #[arg(long, global = true, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
    /// Print one JSON object per result on stdout, and nothing else there.
    #[arg(long, global = true)]
    pub json: bool,
}

/// The commands.
#[derive(Debug, Clone, Subcommand)]
pub enum Command {
    /// Build a scene's tree, render it and report ray throughput.
    Render(RenderArgs),
    /// Build a scene's tree and report build time and tree statistics.
    Build(BuildArgs),
    /// Shoot rays exactly at shared edges and vertices of closed meshes and count the leaks.
    Leaks(leaks::LeaksArgs),
    /// Trace the rays of a file (text or binary) and write one result per ray.
    #[command(after_long_help = crate::raycast::FORMATS_HELP)]
    Raycast(raycast::RaycastArgs),
    /// Print the thesis's Tables 4.1-4.6 (packets, frusta, culling, MFT, cones, soft shadows),
    /// 5.1 and 6.2 for our scenes.
    Tables(tables::TablesArgs),
    /// Edge-width soft shadows against sampled ones: images, errors, CSV and a plot.
    Shadows(shadows::ShadowsArgs),
    /// Every registered method, ours and the baselines, on the same rays (build, primary,
    /// shadow and soft-shadow Mrays/s, primitive mismatches).
    Compare(compare::CompareArgs),
    /// Pre-BVH culling for shadow rays: culled fraction, build and trace with and without.
    Culling(culling::CullingArgs),
}

/// Which scene and how its tree is built.
#[derive(Debug, Clone, Args)]
pub struct SceneArgs {
    /// A built-in scene (atrium, arena, atrium-rotated, grove, triangle, cube, sphere,
    /// touching-boxes, axis-plane-triangle) or a path to an .obj or .obj.gz file.
    #[arg(long, default_value = "atrium", value_name = "NAME|PATH")]
    pub scene: String,
    /// The ray-triangle test the tree is built for.
    #[arg(long, value_enum, default_value_t = IntersectorArg::Wald)]
    pub intersector: IntersectorArg,
    /// Maximum tree depth (default: 8 + log2 N; at most 60).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=60))]
    pub max_depth: Option<u32>,
    /// SAH cost of a ray-triangle test, with a traversal step costing 1 (thesis: 5).
    #[arg(long, value_name = "X", default_value_t = 5.0)]
    pub c_isect: f32,
    /// SAH empty-space bonus in [0, 1): the fraction taken off a split with an empty side.
    #[arg(long, value_name = "X", default_value_t = 0.0)]
    pub empty_bonus: f32,
    /// Stop the build with an error before its buffers (tree included, the scene not) would
    /// pass this many bytes: a number, or with KiB, MiB, GiB or TiB (e.g. 512MiB, 2GiB).
    #[arg(long, value_name = "BYTES", value_parser = trace::report::parse_bytes)]
    pub memory_budget: Option<u64>,
}

/// `--intersector` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum IntersectorArg {
    /// Wald's projected-barycentric test (thesis 4.2).
    Wald,
    /// The watertight test of Woop, Benthin and Wald (2013).
    Watertight,
}

impl From<IntersectorArg> for Intersector {
    fn from(a: IntersectorArg) -> Intersector {
        match a {
            IntersectorArg::Wald => Intersector::Wald,
            IntersectorArg::Watertight => Intersector::Watertight,
        }
    }
}

/// `rttest build` options.
#[derive(Debug, Clone, Args)]
pub struct BuildArgs {
    /// The scene.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Build this many times and report the fastest.
    #[arg(long, default_value_t = 1, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub repeat: u32,
}

/// `rttest render` options.
#[derive(Debug, Clone, Args)]
pub struct RenderArgs {
    /// The scene.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// A named view of the scene (default: its first view).
    #[arg(long, value_name = "NAME", conflicts_with = "camera")]
    pub view: Option<String>,
    /// A custom camera: eye, target and vertical field of view in degrees.
    #[arg(long, value_name = "EX,EY,EZ,TX,TY,TZ,FOVY", value_parser = parse_camera, allow_hyphen_values = true)]
    pub camera: Option<CameraSpec>,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "512x512", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Shadow rays: none, one per hit to the point light, or 16 per hit to a spherical light
    /// at the point light (traced with the method's soft-shadow kernel).
    #[arg(long, value_enum, default_value_t = ShadowsArg::Hard)]
    pub shadows: ShadowsArg,
    /// Radius of the soft shadows' spherical light, in Sponza units (scaled by the scene's
    /// diagonal, as Table 4.6): a finite number >= 0.
    #[arg(long, value_name = "R", default_value_t = 1.0)]
    pub light_radius: f32,
    /// What to write: the shaded image (PNG), or the hit distance or primitive id (PFM).
    #[arg(long, value_enum, default_value_t = Aov::Color)]
    pub aov: Aov,
    /// Output file (default: SCENE.png, SCENE-depth.pfm or SCENE-prim.pfm). A .pfm
    /// colour image or a .png depth/prim image is written in that format.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Frames traced; the reported trace time is the fastest.
    #[arg(long, default_value_t = 5, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=10000))]
    pub frames: u32,
    /// The method (a registry name: mono, packet, samesign, frustum, mft, cone, mft-cone,
    /// NAME-TILE such as mft-16, or a baseline such as embree-8 in a build with it).
    #[arg(long, default_value = "mono", value_name = "METHOD")]
    pub method: String,
    /// Tile side: the work unit of a thread, and the frustum of `frustum` and `mft` (a
    /// multiple of 4 from 4 to 64 for the packet methods).
    #[arg(long, value_name = "N", default_value_t = TILE_SIZE,
          value_parser = clap::value_parser!(u32).range(1..=64))]
    pub tile: u32,
    /// Turn packet/leaf culling off (frustum methods; thesis Table 4.2).
    #[arg(long)]
    pub no_culling: bool,
    /// Also trace one untimed frame counting nodes, leaves and intersection tests per ray
    /// (and, for packet methods, per 2x2 packet).
    #[arg(long)]
    pub counters: bool,
}

/// `--shadows` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ShadowsArg {
    /// No shadow rays: every surface facing the light is lit.
    None,
    /// One shadow ray per hit towards the point light.
    Hard,
    /// 16 rays per hit to a spherical light at the point light (thesis Table 4.6).
    Soft16,
}

impl From<ShadowsArg> for Shadows {
    fn from(a: ShadowsArg) -> Shadows {
        match a {
            ShadowsArg::None => Shadows::None,
            ShadowsArg::Hard => Shadows::Hard,
            ShadowsArg::Soft16 => Shadows::Soft16,
        }
    }
}

/// `--aov` values: what the image file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Aov {
    /// Diffuse shading with the point light (PNG).
    Color,
    /// Distance of the primary hit, `+inf` for misses (PFM).
    Depth,
    /// Primitive id of the primary hit in the file's face numbering, `-1` for misses (PFM).
    Prim,
}

impl Aov {
    fn name(self) -> &'static str {
        match self {
            Aov::Color => "color",
            Aov::Depth => "depth",
            Aov::Prim => "prim",
        }
    }
}

/// A camera given on the command line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraSpec {
    /// Eye position.
    pub eye: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Vertical field of view in degrees.
    pub fovy_deg: f32,
}

/// Parses `WxH` (e.g. `1024x768`), each side in `1..=MAX_SIDE`, at most [`MAX_PIXELS`] pixels.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("expected WxH such as 512x512, got '{s}'"))?;
    let side = |v: &str| -> Result<u32, String> {
        match v.trim().parse::<u32>() {
            Ok(n) if (1..=MAX_SIDE).contains(&n) => Ok(n),
            _ => Err(format!("'{v}' is not an image side in 1..={MAX_SIDE}")),
        }
    };
    let (w, h) = (side(w)?, side(h)?);
    if u64::from(w) * u64::from(h) > MAX_PIXELS {
        return Err(format!("{w}x{h} has more than {MAX_PIXELS} pixels"));
    }
    Ok((w, h))
}

/// Parses `ex,ey,ez,tx,ty,tz,fovy` into a camera spec (seven finite numbers).
pub fn parse_camera(s: &str) -> Result<CameraSpec, String> {
    let values: Vec<f32> = s
        .split(',')
        .map(|v| v.trim().parse::<f32>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("'{s}' is not a list of finite numbers"))?;
    let [ex, ey, ez, tx, ty, tz, fovy] = values[..] else {
        return Err(format!("expected 7 numbers ex,ey,ez,tx,ty,tz,fovy, got {}", values.len()));
    };
    Ok(CameraSpec { eye: Vec3::new(ex, ey, ez), target: Vec3::new(tx, ty, tz), fovy_deg: fovy })
}

/// The render options with clap's defaults, and `args` after the command (e.g.
/// `["--method", "mft-8"]`).
pub fn render_args(args: &[&str]) -> Result<RenderArgs, Error> {
    #[derive(Parser)]
    struct Defaults {
        #[command(flatten)]
        args: RenderArgs,
    }
    let argv = std::iter::once("render").chain(args.iter().copied());
    Defaults::try_parse_from(argv).map(|d| d.args).map_err(|e| Error::Usage(e.to_string()))
}

/// Runs the command line `cli`, writing reports to stdout.
pub fn run(cli: Cli) -> Result<(), Error> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(cli.global.threads.unwrap_or(0) as usize).build()?;
    let global = cli.global;
    pool.install(|| match cli.command {
        Some(Command::Build(args)) => build_command(&global, &args),
        Some(Command::Leaks(args)) => leaks::run(&global, &args),
        Some(Command::Render(args)) => render_command(&global, &args),
        Some(Command::Raycast(args)) => raycast::run(&global, &args, || load_and_build(&global, &args.scene, 1)),
        Some(Command::Tables(args)) => tables::run(&global, &args),
        Some(Command::Shadows(args)) => shadows::run(&global, &args),
        Some(Command::Compare(args)) => compare::run(&global, &args),
        Some(Command::Culling(args)) => culling::run(&global, &args),
        None => main_job::run(&global),
    })
}

/// Prints a result: its JSON object on one line, or its text table.
pub fn emit<R: Serialize + std::fmt::Display>(global: &GlobalArgs, report: &R) -> Result<(), Error> {
    let mut out = std::io::stdout().lock();
    if global.json {
        let line = serde_json::to_string(report).map_err(std::io::Error::other)?;
        writeln!(out, "{line}")?;
    } else {
        writeln!(out, "{report}")?;
    }
    Ok(())
}

/// A loaded scene with its tree, as every command starts.
pub struct Built {
    /// The scene.
    pub scene: Scene,
    /// Its kd-tree.
    pub tree: KdTree,
    /// The build's report.
    pub report: BuildReport,
}

/// The structures `selected` traces: our kd-tree, and its own structure if it is a baseline
/// (built here, untimed).
pub fn structures_for<'a>(registry: &Registry, selected: &Selected, built: &'a Built) -> Result<Structures<'a>, Error> {
    let mut structures = Structures::new(&built.tree);
    let name = registry.entry(selected.entry).structure;
    if name != KDTREE {
        let entry =
            registry.structure(name).ok_or_else(|| Error::Usage(format!("no structure '{name}' in this build")))?;
        structures.insert(name, (entry.build)(&built.scene)?);
    }
    Ok(structures)
}

/// Loads the scene and builds its tree `repeat` times, keeping the fastest build.
pub fn load_and_build(global: &GlobalArgs, args: &SceneArgs, repeat: u32) -> Result<Built, Error> {
    // The builder checks these too; here they fail before the scene is loaded, naming the option.
    if !(args.c_isect.is_finite() && args.c_isect > 0.0) {
        return Err(Error::Usage(format!("--c-isect {} must be a finite number > 0", args.c_isect)));
    }
    if !(0.0..1.0).contains(&args.empty_bonus) {
        return Err(Error::Usage(format!("--empty-bonus {} must be in [0, 1)", args.empty_bonus)));
    }
    let show = progress::enabled(global.json);
    let start = Instant::now();
    let loading = Bar::spinner(&format!("loading {}", args.scene), show);
    let scene = scenes::load_scene(&args.scene)?;
    loading.finish();
    let load_ms = start.elapsed().as_secs_f64() * 1e3;

    let config = BuildConfig {
        intersector: args.intersector.into(),
        max_depth: args.max_depth,
        c_isect: args.c_isect,
        empty_bonus: args.empty_bonus,
        memory_budget: args.memory_budget,
        ..BuildConfig::default()
    };
    let message = format!("building {}", scene.name);
    let building =
        if repeat > 1 { Bar::steps(u64::from(repeat), &message, show) } else { Bar::spinner(&message, show) };
    let mut best: Option<(KdTree, f64)> = None;
    for _ in 0..repeat {
        let start = Instant::now();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &config)?;
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if best.as_ref().is_none_or(|(_, b)| ms < *b) {
            best = Some((tree, ms));
        }
        building.inc();
    }
    building.finish();
    let (tree, build_ms) = best.ok_or_else(|| Error::Usage("no build was run".into()))?;
    let report = BuildReport {
        scene: scene.name.clone(),
        build_ms,
        load_ms,
        threads: rayon::current_num_threads(),
        intersector: tree.intersector().name().to_string(),
        tree: TreeSummary::of(&tree),
    };
    Ok(Built { scene, tree, report })
}

/// `rttest build`.
fn build_command(global: &GlobalArgs, args: &BuildArgs) -> Result<(), Error> {
    let built = load_and_build(global, &args.scene, args.repeat)?;
    emit(global, &built.report)
}

/// The camera of `args`: `--camera`, `--view` or the scene's default view.
fn camera_for(scene: &Scene, args: &RenderArgs) -> Result<(Camera, String), Error> {
    let (w, h) = args.size;
    if let Some(c) = args.camera {
        let camera = Camera::look_at(c.eye, c.target, c.fovy_deg, w, h).ok_or_else(|| {
            Error::Usage(
                "--camera is degenerate: eye equals target, the view is vertical, or fovy is not in (0, 180)".into(),
            )
        })?;
        return Ok((camera, "custom".into()));
    }
    trace::setup::view_camera(scene, args.view.as_deref(), w, h)
}

/// The output file: `--out`, or `<scene>.png` / `<scene>-depth.pfm` / `<scene>-prim.pfm`.
fn out_path(scene: &Scene, args: &RenderArgs) -> PathBuf {
    args.out.clone().unwrap_or_else(|| {
        PathBuf::from(match args.aov {
            Aov::Color => format!("{}.png", scene.name),
            Aov::Depth => format!("{}-depth.pfm", scene.name),
            Aov::Prim => format!("{}-prim.pfm", scene.name),
        })
    })
}

/// True if `path` ends in `.ext` (any case).
fn has_extension(path: &Path, ext: &str) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case(ext))
}

/// The best times over several traced frames.
struct Timing {
    /// The frame with the smallest total trace time.
    best: FrameStats,
    /// The smallest primary-pass time of any frame.
    primary_secs: f64,
    /// The smallest shadow-pass time of any frame (0 without shadow rays).
    shadow_secs: f64,
}

/// Traces `frames` frames into `buffers` and keeps the best times.
fn time_frames(renderer: &Renderer<'_>, buffers: &mut FrameBuffers, frames: u32, show: bool) -> Timing {
    let bar = Bar::steps(u64::from(frames), "tracing frames", show);
    let mut timing = Timing { best: FrameStats::default(), primary_secs: f64::INFINITY, shadow_secs: f64::INFINITY };
    for frame in 0..frames {
        let stats = renderer.trace(buffers);
        timing.primary_secs = timing.primary_secs.min(stats.primary_secs);
        timing.shadow_secs = timing.shadow_secs.min(stats.shadow_secs);
        if frame == 0 || stats.trace_secs() < timing.best.trace_secs() {
            timing.best = stats;
        }
        bar.inc();
    }
    bar.finish();
    if timing.best.shadow_rays == 0 {
        timing.shadow_secs = 0.0;
    }
    timing
}

/// Pass 3 and the file: shades (or extracts the AOV of) `buffers` and writes it to `out`,
/// in PNG or PFM by the file's extension. Returns (shade seconds, write seconds).
fn write_image(renderer: &Renderer<'_>, buffers: &FrameBuffers, aov: Aov, out: &Path) -> Result<(f64, f64), Error> {
    enum Output {
        Color(scenes::Image),
        Scalar(scenes::ScalarImage),
    }
    let start = Instant::now();
    let image = match aov {
        Aov::Color => Output::Color(renderer.color(buffers)),
        Aov::Depth => Output::Scalar(renderer.depth(buffers)),
        Aov::Prim => Output::Scalar(renderer.prim(buffers)),
    };
    let shade_secs = start.elapsed().as_secs_f64();
    let start = Instant::now();
    match &image {
        Output::Color(img) if has_extension(out, "pfm") => img.save_pfm(out)?,
        Output::Color(img) => img.save_png(out)?,
        Output::Scalar(img) if has_extension(out, "png") => img.save_png(out)?,
        Output::Scalar(img) => img.save_pfm(out)?,
    }
    Ok((shade_secs, start.elapsed().as_secs_f64()))
}

/// Renders `built` with `args` (method, view, size, shadows, frames, counters) and, with
/// `write`, shades and writes the image; returns the report.
pub fn render(global: &GlobalArgs, built: &Built, args: &RenderArgs, write: bool) -> Result<RenderReport, Error> {
    if !(args.light_radius.is_finite() && args.light_radius >= 0.0) {
        return Err(Error::Usage(format!("--light-radius {} must be a finite number >= 0", args.light_radius)));
    }
    let registry = baselines::registry();
    let selected = registry.select(&args.method, Options { tile: args.tile, culling: !args.no_culling })?;
    let (camera, view) = camera_for(&built.scene, args)?;
    let out = out_path(&built.scene, args);
    let structures = structures_for(&registry, &selected, built)?;
    let method = registry.bind(&selected, &structures).map_err(|e| match e {
        Error::Usage(m) => Error::Usage(format!("--method {m}")),
        e => e,
    })?;
    let shadows = Shadows::from(args.shadows);
    let light = trace::soft::scene_light(&built.scene, &built.tree, args.light_radius);
    let renderer = Renderer::new(&built.scene, &method, camera, shadows).with_light(light);
    let mut buffers = renderer.buffers();
    let timing = time_frames(&renderer, &mut buffers, args.frames, progress::enabled(global.json));
    let stats = timing.best;
    let traversal = args.counters.then(|| {
        let (_, primary, shadow) = renderer.trace_counted(&mut buffers);
        let packets = method.entry.packets.then(|| renderer.packet_count());
        TraversalReport::new(stats.primary_rays, primary, stats.shadow_rays, shadow, packets)
    });
    let (shade_secs, write_secs) = if write { write_image(&renderer, &buffers, args.aov, &out)? } else { (0.0, 0.0) };

    Ok(RenderReport {
        scene: built.scene.name.clone(),
        method: method.entry.name.to_string(),
        tile: method.options.tile,
        culling: !args.no_culling,
        view,
        width: camera.width,
        height: camera.height,
        threads: rayon::current_num_threads(),
        intersector: built.report.intersector.clone(),
        shadows: shadows.name().to_string(),
        aov: args.aov.name().to_string(),
        triangles: built.report.tree.triangles,
        build_ms: built.report.build_ms,
        frames: args.frames,
        rays: stats.rays(),
        primary_rays: stats.primary_rays,
        shadow_rays: stats.shadow_rays,
        hits: stats.hits,
        occluded: stats.occluded,
        trace_secs: stats.trace_secs(),
        primary_secs: timing.primary_secs,
        shadow_secs: timing.shadow_secs,
        mrays_per_s: mrays_per_s(stats.rays(), stats.trace_secs()),
        primary_mrays_per_s: mrays_per_s(stats.primary_rays, timing.primary_secs),
        shadow_mrays_per_s: mrays_per_s(stats.shadow_rays, timing.shadow_secs),
        shade_secs,
        write_secs,
        out: write.then(|| out.display().to_string()),
        traversal,
    })
}

/// `rttest render`. The text output starts with the build report; the JSON object has the
/// build time and triangle count only (`rttest build` has the rest).
fn render_command(global: &GlobalArgs, args: &RenderArgs) -> Result<(), Error> {
    let built = load_and_build(global, &args.scene, 1)?;
    let report = render(global, &built, args, true)?;
    // Nothing goes to stdout before everything has succeeded.
    if !global.json {
        emit(global, &built.report)?;
    }
    emit(global, &report)
}
