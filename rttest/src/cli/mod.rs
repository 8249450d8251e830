//! The command line: `rttest [render|build|raycast] ...`, and the driver that runs one command.
//!
//! Every command runs inside one rayon pool of `--threads` threads (all cores by default),
//! so the build, the trace passes and the shading all use the same threads. With `--json`
//! each result is one JSON object on its own line of stdout and nothing else goes to stdout;
//! every object names the machine (`cpu`, `simd`). Text results start with the machine line
//! ([`header`]).

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use clap::{Args, Parser, Subcommand, ValueEnum};
use glam::Vec3;
use kdtree::treefile::Checks;
use kdtree::{BuildConfig, BuildStrategy, CostModel, Intersector, KdTree};
use packets::LaneWidth;
use scenes::{Camera, Scene};
use serde::Serialize;
use trace::registry::{KDTREE, Selected, TILE_SIZE};
use trace::report::{BuildReport, RenderReport, TraversalReport, TreeSummary, WorkloadReport};
use trace::timing::mrays_per_s;
use trace::workload::{self, Incoherent};
use trace::{
    Error, FrameBuffers, FrameStats, Machine, Options, Registry, Renderer, Shadows, SimdLevel, SoftGrouping, Structures,
};

use crate::progress::{self, Bar};

pub mod compare;
pub mod culling;
pub mod dynamic;
pub mod heatmap;
pub mod leaks;
pub mod main_job;
pub mod raycast;
pub mod sah_sweep;
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
    /// The widest SIMD instruction set the kernels may use: `auto` (the CPU's widest), or
    /// `sse` (4 lanes), `avx2` (8) or `avx512` (16) to measure a narrower width on this CPU
    /// (the width ladder). A level the CPU lacks is an error.
    #[arg(long, global = true, value_enum, default_value_t = SimdArg::Auto)]
    pub simd: SimdArg,
}

/// `--simd` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SimdArg {
    /// The widest level this CPU runs.
    Auto,
    /// SSE 4.1: 4-wide packets.
    Sse,
    /// AVX2 and FMA: 8-wide packets and nodes.
    Avx2,
    /// AVX-512 F and VL: 16-wide packets.
    Avx512,
}

impl SimdArg {
    /// The cap this value sets (`None` for `auto`).
    pub fn level(self) -> Option<SimdLevel> {
        match self {
            SimdArg::Auto => None,
            SimdArg::Sse => Some(SimdLevel::Sse41),
            SimdArg::Avx2 => Some(SimdLevel::Avx2),
            SimdArg::Avx512 => Some(SimdLevel::Avx512),
        }
    }
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
    /// Sweep the SAH cost model (C_trav:C_isect, empty bonus, depth limit): tree shape, N, I,
    /// build time and single-ray / MFT Mrays/s in one table per scene.
    SahSweep(sah_sweep::SahSweepArgs),
    /// Pre-BVH culling for shadow rays: culled fraction, build and trace with and without.
    Culling(culling::CullingArgs),
    /// Pre-BVH culling on an animated scene rebuilt every frame: per frame and in total.
    Dynamic(dynamic::DynamicArgs),
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
    /// The SAH cost model: Wald & Havran's 15:20 with an empty bonus of 0.2 (the default,
    /// chosen by `rttest sah-sweep`), or the thesis's 1:5 without one (for its tables).
    #[arg(long, value_enum, default_value_t = CostModelArg::WaldHavran)]
    pub cost_model: CostModelArg,
    /// SAH cost of a ray-triangle test, with a traversal step costing 1 (overrides the cost
    /// model's: 4/3 for wald-havran, 5 for thesis).
    #[arg(long, value_name = "X")]
    pub c_isect: Option<f32>,
    /// SAH empty-space bonus in [0, 1): the fraction taken off a split with an empty side
    /// (overrides the cost model's: 0.2 for wald-havran, 0 for thesis).
    #[arg(long, value_name = "X")]
    pub empty_bonus: Option<f32>,
    /// Stop the build with an error before its buffers (tree included, the scene not) would
    /// pass this many bytes: a number, or with KiB, MiB, GiB or TiB (e.g. 512MiB, 2GiB).
    #[arg(long, value_name = "BYTES", value_parser = trace::report::parse_bytes)]
    pub memory_budget: Option<u64>,
    /// How the planes of large nodes are found: `exact` (the SAH event sweep at every node)
    /// or `binned` (min-max binning of the nodes with at least --bin-min-tris triangles,
    /// --bins bins per axis, the exact sweep below them). Both clip straddling triangles
    /// (perfect splits).
    #[arg(long = "build", value_enum, default_value_t = BuildStrategyArg::default(), value_name = "STRATEGY")]
    pub strategy: BuildStrategyArg,
    /// Bins per axis of `--build binned` (2 to 65536; default 256).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(2..=65536))]
    pub bins: Option<u32>,
    /// Nodes with at least this many triangles are binned by `--build binned` (default 1024).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub bin_min_tris: Option<u32>,
    /// The SAH prices a leaf of n triangles as ceil(n / W) tests of W-wide SIMD groups (1:
    /// per triangle, the thesis's; 4: the leaves' groups of 4). Overrides the cost model's.
    #[arg(long, value_name = "W", value_parser = clap::value_parser!(u32).range(1..=64))]
    pub leaf_width: Option<u32>,
    /// Mitsuba's bad refines: splits costlier than the leaf still allowed on a path (0: off;
    /// at most 16). Overrides the cost model's.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=16))]
    pub bad_refines: Option<u32>,
    /// After the build, collapse every subtree whose SAH cost is at least its leaf's
    /// (Mitsuba's retraction of bad splits): `on` or `off` (default: the cost model's).
    #[arg(long, value_name = "on|off", value_parser = parse_on_off)]
    pub collapse: Option<bool>,
    /// Load the tree from this file (written by `rttest build --save`) instead of building
    /// it. The file must have been built for this scene with the same --intersector,
    /// --c-isect, --empty-bonus, --max-depth, --leaf-width, --bad-refines, --collapse and
    /// --build (with its --bins, --bin-min-tris);
    /// it is checked in full before use.
    #[arg(long, value_name = "FILE")]
    pub tree: Option<PathBuf>,
    /// How a tree file is checked when loaded: `full` (every check of the file, then the
    /// tree's validate(), which costs about a build) or `file` (every check of the file:
    /// lengths, header against scene and options, ranges, NaN, checksum, records; not
    /// validate()).
    #[arg(long, value_enum, default_value_t = TreeChecksArg::Full, value_name = "CHECKS")]
    pub tree_checks: TreeChecksArg,
}

/// `--tree-checks` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TreeChecksArg {
    /// Every check of the file, then `KdTree::validate()`.
    Full,
    /// Every check of the file, without `KdTree::validate()`.
    File,
}

impl From<TreeChecksArg> for Checks {
    fn from(a: TreeChecksArg) -> Checks {
        match a {
            TreeChecksArg::Full => Checks::Full,
            TreeChecksArg::File => Checks::File,
        }
    }
}

/// `--build` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum BuildStrategyArg {
    /// The exact SAH event sweep at every node (Wald & Havran 2006).
    Exact,
    /// Min-max binning above a size, the exact sweep below (Shevtsov et al. 2007).
    Binned,
}

impl BuildStrategyArg {
    /// The strategy with its default parameters ([`BuildStrategy::BINNED`] for `binned`).
    pub fn strategy(self) -> BuildStrategy {
        match self {
            BuildStrategyArg::Exact => BuildStrategy::Exact,
            BuildStrategyArg::Binned => BuildStrategy::BINNED,
        }
    }
}

impl Default for BuildStrategyArg {
    /// The library's default strategy.
    fn default() -> Self {
        match BuildConfig::default().strategy {
            BuildStrategy::Exact => BuildStrategyArg::Exact,
            BuildStrategy::Binned { .. } => BuildStrategyArg::Binned,
        }
    }
}

/// `--cost-model` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CostModelArg {
    /// Wald & Havran 2006: C_trav:C_isect = 15:20, empty bonus 0.2.
    WaldHavran,
    /// The thesis (3.2.1): C_trav:C_isect = 1:5, no empty bonus.
    Thesis,
}

impl From<CostModelArg> for CostModel {
    fn from(a: CostModelArg) -> CostModel {
        match a {
            CostModelArg::WaldHavran => CostModel::WaldHavran,
            CostModelArg::Thesis => CostModel::Thesis,
        }
    }
}

impl SceneArgs {
    /// The build configuration these options ask for: the cost model's terms, overridden by
    /// `--c-isect` and `--empty-bonus`. A NaN, infinite or out-of-range term is a usage
    /// error naming its option (before the scene is loaded).
    pub fn build_config(&self) -> Result<BuildConfig, Error> {
        let model = CostModel::from(self.cost_model).config();
        let c_isect = self.c_isect.unwrap_or(model.c_isect);
        let empty_bonus = self.empty_bonus.unwrap_or(model.empty_bonus);
        if !(c_isect.is_finite() && c_isect > 0.0) {
            return Err(Error::Usage(format!("--c-isect {c_isect} must be a finite number > 0")));
        }
        if !(0.0..1.0).contains(&empty_bonus) {
            return Err(Error::Usage(format!("--empty-bonus {empty_bonus} must be in [0, 1)")));
        }
        let strategy = match self.strategy {
            BuildStrategyArg::Exact => {
                if self.bins.is_some() || self.bin_min_tris.is_some() {
                    return Err(Error::Usage("--bins and --bin-min-tris need --build binned".into()));
                }
                BuildStrategy::Exact
            }
            BuildStrategyArg::Binned => {
                let BuildStrategy::Binned { bins, min_tris } = BuildStrategy::BINNED else {
                    unreachable!("BuildStrategy::BINNED is binned")
                };
                BuildStrategy::Binned {
                    bins: self.bins.unwrap_or(bins),
                    min_tris: self.bin_min_tris.unwrap_or(min_tris),
                }
            }
        };
        Ok(BuildConfig {
            strategy,
            intersector: self.intersector.into(),
            max_depth: self.max_depth,
            c_isect,
            empty_bonus,
            memory_budget: self.memory_budget,
            leaf_width: self.leaf_width.unwrap_or(model.leaf_width),
            max_bad_refines: self.bad_refines.unwrap_or(model.max_bad_refines),
            collapse: self.collapse.unwrap_or(model.collapse),
            ..model
        })
    }
}

/// `on` / `off` (also `true` / `false`, `1` / `0`).
fn parse_on_off(s: &str) -> Result<bool, String> {
    match s {
        "on" | "true" | "1" => Ok(true),
        "off" | "false" | "0" => Ok(false),
        _ => Err(format!("'{s}' is neither on nor off")),
    }
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
    /// Build (or with --tree, load) this many times and report the fastest.
    #[arg(long, default_value_t = 1, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub repeat: u32,
    /// Save the tree to this file (for --tree), then read it back, timed (load_tree_ms).
    #[arg(long, value_name = "FILE")]
    pub save: Option<PathBuf>,
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
    /// Shadow rays: none, one per hit to the point light, 16 per hit to a spherical light at
    /// the point light (traced with the method's soft-shadow kernel), or one edge-width ray
    /// per hit to that light's centre (thesis chapter 5).
    #[arg(long, value_enum, default_value_t = ShadowsArg::Hard)]
    pub shadows: ShadowsArg,
    /// Radius of the soft shadows' spherical light, in Sponza units (scaled by the scene's
    /// diagonal, as Table 4.6): a finite number >= 0.
    #[arg(long, value_name = "R", default_value_t = 1.0)]
    pub light_radius: f32,
    /// What to write: the shaded image (PNG), the hit distance or primitive id (PFM), or a
    /// cost image (traversal steps, leaves, triangle tests or culled packets per primary
    /// ray: PFM and a heat-map PNG with a legend).
    #[arg(long, value_enum, default_value_t = Aov::Color)]
    pub aov: Aov,
    /// Output file (default: SCENE.png, SCENE-depth.pfm, SCENE-prim.pfm, SCENE-METHOD-COST
    /// for a cost image, SCENE-COST for a strip). A .pfm colour image or a .png depth/prim
    /// image is written in that format; a cost image is written as both FILE.pfm and
    /// FILE.png.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// With a cost --aov: the cost images of these methods (registry names) on one colour
    /// scale, side by side in one PNG (FILE.png), each also as FILE-METHOD.pfm. Nothing is
    /// timed.
    #[arg(long, value_name = "A,B,...", value_delimiter = ',')]
    pub compare_methods: Option<Vec<String>>,
    /// Top of the cost images' colour scale (default: the largest pixel value): a finite
    /// number > 0, to put several runs on one scale.
    #[arg(long, value_name = "X")]
    pub cost_max: Option<f32>,
    /// Frames traced; the reported trace time is the fastest.
    #[arg(long, default_value_t = 5, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=10000))]
    pub frames: u32,
    /// The method: a registry name, or NAME-TILE for a tiled one (its help lists the methods
    /// of this build, from the registry: [`method_help`], [`method_long_help`]).
    #[arg(long, default_value = "mono", value_name = "METHOD", help = method_help(), long_help = method_long_help())]
    pub method: String,
    /// Tile side: the work unit of a thread, and the frustum of `frustum` and `mft` (a
    /// multiple of 4 from 4 to 64 for the packet methods).
    #[arg(long, value_name = "N", default_value_t = TILE_SIZE,
          value_parser = clap::value_parser!(u32).range(1..=64))]
    pub tile: u32,
    /// Turn packet/leaf culling off (frustum methods; thesis Table 4.2).
    #[arg(long)]
    pub no_culling: bool,
    /// How the tiled methods of ours trace 16-sample soft shadows: each tile's rays to each
    /// light stratum together, or each point's 16 rays under their pyramid or cone (the
    /// thesis's, Table 4.6; packet, samesign, frustum, mft, cone and mft-cone).
    #[arg(long, value_enum, default_value_t = SoftGroupingArg::Strata)]
    pub soft_grouping: SoftGroupingArg,
    /// How many shadow frusta `lane-frusta` traces at once: the widest this CPU runs (16
    /// with AVX-512, 8 with AVX2, else 4), or 1 (the scalar twin), 4, 8 or 16.
    #[arg(long, value_enum, default_value_t = LanesArg::Auto)]
    pub lanes: LanesArg,
    /// Also trace one untimed frame counting nodes, leaves and intersection tests per ray
    /// (and, for packet methods, per 2x2 packet).
    #[arg(long)]
    pub counters: bool,
    /// Also time the incoherent workload's streams through the method (`ao`: --ao-rays
    /// any-hit rays per primary hit, a tenth of the scene's diagonal long; `diffuse`: one
    /// closest-hit bounce per hit), the same rays as `compare`'s columns, best of --frames.
    #[arg(long, value_enum, value_delimiter = ',', value_name = "ao,diffuse")]
    pub workload: Vec<WorkloadArg>,
    /// Ambient-occlusion rays per primary hit for `--workload ao` (1 to 64).
    #[arg(long, default_value_t = 4, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=64))]
    pub ao_rays: u32,
    /// Generations of secondary rays (the thesis's shader proxy, 3.3): reflection and
    /// refraction rays from hits on materials that reflect or refract, traced by the
    /// method's stream kernel, shaded with the same --shadows. 0 for none; the thesis
    /// renders with 1.
    #[arg(long, default_value_t = 0, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=8))]
    pub secondary: u32,
    /// Reflections off a flat mirror, in runs of neighbouring pixels, leave from the virtual
    /// eye (the eye mirrored in the mirror's plane), so that a run shares one origin: one
    /// frustum for the frustum methods, one omni-directional packet for `packet`. Off, every
    /// reflection starts at its hit point.
    #[arg(long)]
    pub virtual_eye: bool,
}

/// The short help of a `--method` option: the names of the registry every command uses, so
/// that it lists every method of this build.
pub fn method_help() -> String {
    format!("The method: {} (NAME-N: the tiled ones on N x N tiles, e.g. mft-16)", baselines::registry().help())
}

/// The long help of a `--method` option: each method of the registry with its summary.
pub fn method_long_help() -> String {
    format!(
        "The method: a registry name, or NAME-N for a tiled one (mft-16: MFT on 16x16 tiles, the same as mft with --tile 16). The methods of this build:\n\n{}",
        baselines::registry().summaries()
    )
}

/// `--workload` values: the incoherent streams of `trace::workload`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum WorkloadArg {
    /// Ambient-occlusion rays (any hit).
    Ao,
    /// One diffuse bounce per hit (closest hit).
    Diffuse,
}

/// `--soft-grouping` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SoftGroupingArg {
    /// Each tile's rays to each light stratum together, as 2x2 packets (Benthin & Wald 2009).
    Strata,
    /// Each point's 16 rays under their pyramid or cone (thesis 4.1.9, Table 4.6).
    PerPoint,
}

impl From<SoftGroupingArg> for SoftGrouping {
    fn from(arg: SoftGroupingArg) -> SoftGrouping {
        match arg {
            SoftGroupingArg::Strata => SoftGrouping::Strata,
            SoftGroupingArg::PerPoint => SoftGrouping::PerPoint,
        }
    }
}

/// `--lanes` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LanesArg {
    /// The widest this CPU runs natively.
    Auto,
    /// One frustum at a time (the scalar twin).
    #[value(name = "1")]
    One,
    /// Four frusta (SSE).
    #[value(name = "4")]
    Four,
    /// Eight frusta (AVX2; four without it).
    #[value(name = "8")]
    Eight,
    /// Sixteen frusta (AVX-512, the paper's width; eight or four without it).
    #[value(name = "16")]
    Sixteen,
}

impl From<LanesArg> for LaneWidth {
    fn from(arg: LanesArg) -> LaneWidth {
        match arg {
            LanesArg::Auto => LaneWidth::widest(),
            LanesArg::One => LaneWidth::Scalar,
            LanesArg::Four => LaneWidth::Four,
            LanesArg::Eight => LaneWidth::Eight,
            LanesArg::Sixteen => LaneWidth::Sixteen,
        }
    }
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
    /// Edge Width Soft Shadows (thesis chapter 5): one edge-width ray per hit to the centre
    /// of the same spherical light, traced over our kd-tree whatever the method; not counted
    /// by --counters.
    EdgeWidth,
}

impl From<ShadowsArg> for Shadows {
    fn from(a: ShadowsArg) -> Shadows {
        match a {
            ShadowsArg::None => Shadows::None,
            ShadowsArg::Hard => Shadows::Hard,
            ShadowsArg::Soft16 => Shadows::Soft16,
            ShadowsArg::EdgeWidth => Shadows::EdgeWidth,
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
    /// Traversal steps per primary ray: the thesis's N (PFM and heat-map PNG).
    Nodes,
    /// Leaves visited per primary ray (PFM and heat-map PNG).
    Leaves,
    /// Triangle tests per primary ray (packet-triangle tests for packets): the thesis's I.
    Isects,
    /// 2x2 packets culled at leaves per primary ray (thesis 4.1.4).
    Culled,
}

impl Aov {
    fn name(self) -> &'static str {
        match self {
            Aov::Color => "color",
            Aov::Depth => "depth",
            Aov::Prim => "prim",
            Aov::Nodes => "nodes",
            Aov::Leaves => "leaves",
            Aov::Isects => "isects",
            Aov::Culled => "culled",
        }
    }

    /// The traversal cost a cost image shows, `None` for the other outputs.
    pub fn cost(self) -> Option<trace::aov::Cost> {
        use trace::aov::Cost;
        match self {
            Aov::Color | Aov::Depth | Aov::Prim => None,
            Aov::Nodes => Some(Cost::Nodes),
            Aov::Leaves => Some(Cost::Leaves),
            Aov::Isects => Some(Cost::Isects),
            Aov::Culled => Some(Cost::Culled),
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
    SimdLevel::limit(cli.global.simd.level()).map_err(|e| Error::Usage(format!("--simd: {e}")))?;
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
        Some(Command::SahSweep(args)) => sah_sweep::run(&global, &args),
        Some(Command::Culling(args)) => culling::run(&global, &args),
        Some(Command::Dynamic(args)) => dynamic::run(&global, &args),
        None => main_job::run(&global),
    })
}

/// Prints a result: its JSON object on one line ([`json_line`]), or its text table under
/// the machine line ([`header`]).
pub fn emit<R: Serialize + std::fmt::Display>(global: &GlobalArgs, report: &R) -> Result<(), Error> {
    let mut out = std::io::stdout().lock();
    if global.json {
        writeln!(out, "{}", json_line(report)?)?;
    } else {
        header(&mut out)?;
        writeln!(out, "{report}")?;
    }
    Ok(())
}

/// Prints a command's text results (a table, a summary) on stdout under the machine line.
pub fn print_text(text: &dyn std::fmt::Display) -> Result<(), Error> {
    let mut out = std::io::stdout().lock();
    header(&mut out)?;
    write!(out, "{text}")?;
    Ok(())
}

/// Prints one JSON result ([`json_line`]) on its own line of stdout.
pub fn print_json<R: Serialize>(report: &R) -> Result<(), Error> {
    writeln!(std::io::stdout().lock(), "{}", json_line(report)?)?;
    Ok(())
}

/// The first line of every command's text results: the machine the run measured on,
/// `cpu: NAME (family F model M), simd: LEVEL, N threads` ([`trace::Machine`]), `N` the
/// threads of the pool the run is in (`--threads`), written to `out` once per process
/// (later calls write nothing).
pub fn header(out: &mut dyn Write) -> std::io::Result<()> {
    static PRINTED: AtomicBool = AtomicBool::new(false);
    if !PRINTED.swap(true, Ordering::Relaxed) {
        writeln!(out, "{}", run_machine())?;
    }
    Ok(())
}

/// The machine as this run uses it: [`Machine::detect`] with its threads the current rayon
/// pool's.
fn run_machine() -> Machine {
    Machine { threads: rayon::current_num_threads(), ..Machine::detect() }
}

/// `report` as one line of JSON, with the machine added after its own fields: `cpu` (the
/// model string with its family and model, as the machine line shows it), `simd` (the
/// level's name) and, where the report has none, `threads` (the pool's threads).
pub fn json_line<R: Serialize>(report: &R) -> Result<String, Error> {
    #[derive(Serialize)]
    struct WithMachine<'a, R> {
        #[serde(flatten)]
        report: &'a R,
        cpu: String,
        simd: &'static str,
        #[serde(skip_serializing_if = "Option::is_none")]
        threads: Option<usize>,
    }
    let has_threads = serde_json::to_value(report).map_err(std::io::Error::other)?.get("threads").is_some();
    let machine = Machine::detect();
    let line = WithMachine {
        report,
        cpu: machine.cpu.to_string(),
        simd: machine.simd.name(),
        threads: (!has_threads).then(rayon::current_num_threads),
    };
    Ok(serde_json::to_string(&line).map_err(std::io::Error::other)?)
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
    // The builder checks the terms too; here they fail before the scene is loaded, naming
    // the option.
    let config = args.build_config()?;
    let show = progress::enabled(global.json);
    let start = Instant::now();
    let loading = Bar::spinner(&format!("loading {}", args.scene), show);
    let scene = scenes::load_scene(&args.scene)?;
    loading.finish();
    let load_ms = start.elapsed().as_secs_f64() * 1e3;

    if let Some(path) = &args.tree {
        let loading = Bar::spinner(&format!("loading the tree {}", path.display()), show);
        let mut best: Option<(KdTree, f64)> = None;
        for _ in 0..repeat {
            let start = Instant::now();
            let tree = trace::setup::load_tree(path, &scene, &config, args.tree_checks.into())?;
            let ms = start.elapsed().as_secs_f64() * 1e3;
            if best.as_ref().is_none_or(|(_, b)| ms < *b) {
                best = Some((tree, ms));
            }
        }
        loading.finish();
        let (tree, load_tree_ms) = best.ok_or_else(|| Error::Usage("no load was run".into()))?;
        let mut report = build_report(&scene, &tree, 0.0, load_ms);
        report.load_tree_ms = Some(load_tree_ms);
        report.tree_file = Some(path.display().to_string());
        return Ok(Built { scene, tree, report });
    }
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
    let report = build_report(&scene, &tree, build_ms, load_ms);
    Ok(Built { scene, tree, report })
}

/// The build report of `tree`, built in `build_ms` (0 when loaded) over `scene`, loaded in
/// `load_ms`; no tree file.
fn build_report(scene: &Scene, tree: &KdTree, build_ms: f64, load_ms: f64) -> BuildReport {
    BuildReport {
        scene: scene.name.clone(),
        build_ms,
        load_tree_ms: None,
        validate_ms: None,
        tree_file: None,
        load_ms,
        threads: rayon::current_num_threads(),
        intersector: tree.intersector().name().to_string(),
        c_trav: tree.config().c_trav,
        c_isect: tree.config().c_isect,
        empty_bonus: tree.config().empty_bonus,
        build_strategy: tree.config().strategy.name().to_string(),
        bins: match tree.config().strategy {
            BuildStrategy::Binned { bins, .. } => Some(bins),
            BuildStrategy::Exact => None,
        },
        bin_min_tris: match tree.config().strategy {
            BuildStrategy::Binned { min_tris, .. } => Some(min_tris),
            BuildStrategy::Exact => None,
        },
        leaf_width: tree.config().leaf_width,
        max_bad_refines: tree.config().max_bad_refines,
        collapse: tree.config().collapse,
        tree: TreeSummary::of(tree),
    }
}

/// `rttest build`.
///
/// With `--save FILE`, the tree is written to FILE and read back from it, timed: that load
/// (file read, every check, `validate()` included unless `--tree-checks file`) is
/// `load_tree_ms`, and `validate_ms` is one more `validate()` of the loaded tree timed alone. The loaded tree must give the same
/// bytes as the built one, or the command fails.
fn build_command(global: &GlobalArgs, args: &BuildArgs) -> Result<(), Error> {
    let mut built = load_and_build(global, &args.scene, args.repeat)?;
    if let Some(path) = &args.save {
        trace::setup::save_tree(path, &built.tree, &built.scene)?;
        let start = Instant::now();
        let loaded = trace::setup::load_tree(path, &built.scene, built.tree.config(), args.scene.tree_checks.into())?;
        let load_tree_ms = start.elapsed().as_secs_f64() * 1e3;
        let start = Instant::now();
        loaded.validate().map_err(|e| Error::Usage(format!("the loaded tree does not validate: {e}")))?;
        let validate_ms = start.elapsed().as_secs_f64() * 1e3;
        let same = |t: &KdTree| kdtree::treefile::to_bytes(t, &built.scene.mesh.positions, &built.scene.mesh.triangles);
        if same(&loaded).ok() != same(&built.tree).ok() {
            return Err(Error::File {
                path: path.clone(),
                message: "the tree read back differs from the tree saved".into(),
            });
        }
        built.report.load_tree_ms = Some(load_tree_ms);
        built.report.validate_ms = Some(validate_ms);
        built.report.tree_file = Some(path.display().to_string());
    }
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
            cost => format!("{}-{}-{}.pfm", scene.name, args.method, cost.name()),
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
        Aov::Nodes | Aov::Leaves | Aov::Isects | Aov::Culled => {
            return Err(Error::Usage(format!("--aov {}: a cost image is written by heatmap", aov.name())));
        }
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
    if args.counters && args.shadows == ShadowsArg::EdgeWidth {
        return Err(Error::Usage("--counters: edge-width shadow rays are not counted; use other --shadows".into()));
    }
    check_cost_args(args)?;
    let registry = baselines::registry();
    let options = Options {
        tile: args.tile,
        culling: !args.no_culling,
        soft: args.soft_grouping.into(),
        lanes: args.lanes.into(),
        ..Options::default()
    };
    // A method that exists but has no per-point kernel: name the option that asked for one.
    let strata = Options { soft: SoftGrouping::Strata, ..options };
    let selected = registry.select(&args.method, options).map_err(|e| match e {
        Error::Usage(m) if options != strata && registry.select(&args.method, strata).is_ok() => {
            Error::Usage(format!("--soft-grouping per-point: {m}"))
        }
        e => e,
    })?;
    let (camera, view) = camera_for(&built.scene, args)?;
    let out = out_path(&built.scene, args);
    let structures = structures_for(&registry, &selected, built)?;
    let method = registry.bind(&selected, &structures).map_err(|e| match e {
        Error::Usage(m) => Error::Usage(format!("--method {m}")),
        e => e,
    })?;
    let shadows = Shadows::from(args.shadows);
    let light = trace::soft::scene_light(&built.scene, &built.tree, args.light_radius);
    let renderer = Renderer::new(&built.scene, &method, camera, shadows)
        .with_light(light)
        .with_tree(&built.tree)
        .with_secondary(args.secondary)
        .with_virtual_eyes(args.virtual_eye);
    let mut buffers = renderer.buffers();
    let timing = time_frames(&renderer, &mut buffers, args.frames, progress::enabled(global.json));
    let stats = timing.best;
    let traversal = args.counters.then(|| {
        let (_, primary, shadow) = renderer.trace_counted(&mut buffers);
        let packets = method.entry.packets.then(|| renderer.packet_count());
        TraversalReport::new(stats.primary_rays, primary, stats.shadow_rays, shadow, packets)
    });
    let workload = time_workload(built, &method, &camera, args);
    let (shade_secs, write_secs) = match (write, args.aov.cost()) {
        (false, _) => (0.0, 0.0),
        (true, None) => write_image(&renderer, &buffers, args.aov, &out)?,
        (true, Some(cost)) => heatmap::write_one(&renderer, &mut buffers, cost, &method.name, args, &out)?,
    };

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
        shadow_kernel: match shadows {
            Shadows::None => String::new(),
            Shadows::Hard => method.kernels.shadow.clone(),
            Shadows::Soft16 => method.kernels.soft.clone(),
            Shadows::EdgeWidth => "edge-width".to_string(),
        },
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
        secondary_depth: args.secondary,
        secondary_rays: stats.secondary_rays,
        secondary_hits: stats.secondary_hits,
        secondary_shadow_rays: stats.secondary_shadow_rays,
        spawn_secs: stats.spawn_secs,
        secondary_secs: stats.secondary_secs,
        secondary_shadow_secs: stats.secondary_shadow_secs,
        secondary_mrays_per_s: if stats.secondary_rays == 0 {
            0.0
        } else {
            mrays_per_s(stats.secondary_rays, stats.secondary_secs)
        },
        shade_secs,
        write_secs,
        out: write.then(|| out.display().to_string()),
        traversal,
        workload,
    })
}

/// `--workload`: the incoherent rays of the frame (`Incoherent::of_frame`, as `compare`
/// makes them) traced by `method`'s stream queries `args.frames` times; the best times.
fn time_workload(built: &Built, method: &trace::Bound<'_>, camera: &Camera, args: &RenderArgs) -> WorkloadReport {
    let mut report = WorkloadReport::default();
    if args.workload.is_empty() {
        return report;
    }
    let rays = Incoherent::of_frame(&built.scene, &built.tree, camera, args.ao_rays, workload::SEED);
    let best =
        |f: &mut dyn FnMut()| (0..args.frames).map(|_| trace::timing::timed(&mut *f).0).fold(f64::INFINITY, f64::min);
    if args.workload.contains(&WorkloadArg::Ao) {
        let mut out = vec![false; rays.ao.len()];
        let secs = best(&mut || method.tracer.stream_occluded(&rays.ao, &mut out));
        report.ao_rays = Some(rays.ao.len() as u64);
        report.ao_ms = Some(secs * 1e3);
        report.ao_mrays_per_s = Some(mrays_per_s(rays.ao.len() as u64, secs));
    }
    if args.workload.contains(&WorkloadArg::Diffuse) {
        let mut out = vec![None; rays.diffuse.len()];
        let secs = best(&mut || method.tracer.stream(&rays.diffuse, &mut out));
        report.diffuse_rays = Some(rays.diffuse.len() as u64);
        report.diffuse_ms = Some(secs * 1e3);
        report.diffuse_mrays_per_s = Some(mrays_per_s(rays.diffuse.len() as u64, secs));
    }
    report
}

/// Rejects a bad `--cost-max`, and `--compare-methods` without a cost `--aov`, before any
/// work.
fn check_cost_args(args: &RenderArgs) -> Result<(), Error> {
    if let Some(m) = args.cost_max
        && !(m.is_finite() && m > 0.0)
    {
        return Err(Error::Usage(format!("--cost-max {m} must be a finite number > 0")));
    }
    if args.compare_methods.is_some() && args.aov.cost().is_none() {
        return Err(Error::Usage("--compare-methods needs a cost --aov: nodes, leaves, isects or culled".into()));
    }
    Ok(())
}

/// `rttest render`. The text output starts with the build report; the JSON object has the
/// build time and triangle count only (`rttest build` has the rest). With
/// `--compare-methods`, the cost images of several methods instead ([`heatmap::compare`]).
fn render_command(global: &GlobalArgs, args: &RenderArgs) -> Result<(), Error> {
    check_cost_args(args)?;
    let built = load_and_build(global, &args.scene, 1)?;
    if let Some(methods) = &args.compare_methods {
        if !global.json {
            emit(global, &built.report)?;
        }
        return heatmap::compare(global, &built, args, methods);
    }
    let report = render(global, &built, args, true)?;
    // Nothing goes to stdout before everything has succeeded.
    if !global.json {
        emit(global, &built.report)?;
    }
    emit(global, &report)
}
