//! `rttest shadows`: the options of the soft-shadow comparison and the command that prints
//! its rows (the comparison itself is [`experiments::shadows`]).

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use experiments::shadows::{self, LightKind, ShadowsConfig};
use trace::Error;

use super::{GlobalArgs, IntersectorArg, emit, parse_size};
use crate::progress::{self, Bars};

/// `rttest shadows` options.
#[derive(Debug, Clone, Args)]
pub struct ShadowsArgs {
    /// Scenes (built-in names, `analytic`, or OBJ paths; repeatable). Default: atrium, arena,
    /// atrium-rotated, grove, analytic and every .obj / .obj.gz in the shared scenes folder.
    #[arg(long, value_name = "NAME|PATH")]
    pub scene: Vec<String>,
    /// The view (default: each scene's default view).
    #[arg(long)]
    pub view: Option<String>,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "256x256", value_parser = parse_size)]
    pub size: (u32, u32),
    /// The area light: the scene's rectangle, or a sphere at its centre with the same area.
    #[arg(long, value_enum, default_value_t = LightArg::Rect)]
    pub light: LightArg,
    /// Scale of the light about its centre (1 = the scene's light).
    #[arg(long, value_name = "X", default_value_t = 1.0)]
    pub light_size: f32,
    /// Scale of the edge width `R` (Eq. 5.1): `R = scale * light diameter / distance`.
    #[arg(long, value_name = "X", default_value_t = 1.0)]
    pub edge_scale: f32,
    /// Light-leak remedy: entry/exit pairs count only if their triangles share a vertex.
    #[arg(long)]
    pub shared_vertex: bool,
    /// Light-leak remedy: scale edge widths through materials whose name contains NAME
    /// (repeatable), e.g. `--thickness banner=8`.
    #[arg(long, value_name = "NAME=SCALE")]
    pub thickness: Vec<String>,
    /// Samples per pixel of the reference.
    #[arg(long, value_name = "N", default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub ref_samples: u32,
    /// Where references are cached (default: `target/shadow-cache` of the workspace).
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
    /// Where images, CSV and plots go (one folder per scene).
    #[arg(long, value_name = "DIR", default_value = "shadows-out")]
    pub out_dir: PathBuf,
    /// Frames timed per method, interleaved across methods; the median is reported.
    #[arg(long, value_name = "N", default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub frames: u32,
    /// The ray-triangle test.
    #[arg(long, value_enum, default_value_t = IntersectorArg::Wald)]
    pub intersector: IntersectorArg,
    /// Only these rows, by name, comma-separated (e.g. `hard,edge-width-convolution`; default:
    /// every method). Each frame is still timed against a hard-shadow frame of its own.
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    pub methods: Vec<String>,
}

/// `--light` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LightArg {
    /// The scene's rectangular area light.
    Rect,
    /// A sphere at the rectangle's centre with the rectangle's area as its disc.
    Sphere,
}

impl From<LightArg> for LightKind {
    fn from(a: LightArg) -> LightKind {
        match a {
            LightArg::Rect => LightKind::Rect,
            LightArg::Sphere => LightKind::Sphere,
        }
    }
}

impl From<&ShadowsArgs> for ShadowsConfig {
    fn from(args: &ShadowsArgs) -> ShadowsConfig {
        ShadowsConfig {
            scenes: args.scene.clone(),
            view: args.view.clone(),
            size: args.size,
            light: args.light.into(),
            light_size: args.light_size,
            edge_scale: args.edge_scale,
            shared_vertex: args.shared_vertex,
            thickness: args.thickness.clone(),
            ref_samples: args.ref_samples,
            cache_dir: args.cache_dir.clone(),
            out_dir: args.out_dir.clone(),
            frames: args.frames,
            intersector: args.intersector.into(),
            methods: args.methods.clone(),
        }
    }
}

/// `rttest shadows`: per scene, its rows (one line of text, or one JSON object, per method)
/// as soon as its images, CSV and plot are written.
pub fn run(global: &GlobalArgs, args: &ShadowsArgs) -> Result<(), Error> {
    let config = ShadowsConfig::from(args);
    config.validate()?;
    let bars = Bars { enabled: progress::enabled(global.json) };
    // Scene by scene, so that a long run prints each scene's rows when they are ready.
    for spec in config.scene_list() {
        let scene = shadows::run_scene(&config, &spec, &bars)?;
        for row in &scene.rows {
            emit(global, row)?;
        }
    }
    Ok(())
}
