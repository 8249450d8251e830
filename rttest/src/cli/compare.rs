//! `rttest compare`: the arguments of [`experiments::compare`] and its output.

use clap::Args;
use experiments::compare::{self, CompareConfig};
use trace::Error;

use super::{GlobalArgs, emit, parse_size, print_text};
use crate::progress::{self, Bars};

/// `rttest compare` options.
#[derive(Debug, Clone, Args)]
pub struct CompareArgs {
    /// A built-in scene or a path to an .obj or .obj.gz file.
    #[arg(long, default_value = "atrium", value_name = "NAME|PATH")]
    pub scene: String,
    /// A named view of the scene (default: its first view).
    #[arg(long, value_name = "NAME")]
    pub view: Option<String>,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "512x512", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Timed rounds; each times every method once, in turn; medians are reported.
    #[arg(long, default_value_t = 5, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub rounds: u32,
    /// Timed builds of each structure, interleaved; the median is reported.
    #[arg(long, default_value_t = 3, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100))]
    pub build_rounds: u32,
    /// Methods, comma-separated: names (`mono`, `mft-16`, `embree-16`, `bvh`, ...), groups
    /// (`all`, `ours`, `embree`, `bvh-crates`), or a method of ours at a capped SIMD level
    /// (`mft-16@sse`, `mft-16@avx2`, `mft-16@avx512`) or packet width (`mft-16@w8`,
    /// `mft-16@w16`: the width ladder). `all` takes the baselines this build has.
    #[arg(long, value_delimiter = ',', default_value = "all", value_name = "LIST")]
    pub methods: Vec<String>,
    /// Tile sizes of our frustum, MFT, cone and MFT-cone methods (multiples of 4, 4 to 64).
    #[arg(long, value_delimiter = ',', default_value = "8,16", value_name = "LIST",
          value_parser = clap::value_parser!(u32).range(4..=64))]
    pub tiles: Vec<u32>,
    /// Radius of the spherical light of the soft shadows, in Sponza units (scaled by the
    /// scene's diagonal, as Table 4.6): a finite number >= 0.
    #[arg(long, default_value_t = 1.0, value_name = "R")]
    pub light_radius: f32,
    /// Leave out the 16-sample soft shadows (the slowest column).
    #[arg(long)]
    pub no_soft: bool,
    /// Ambient-occlusion rays per primary hit (the incoherent `ao` column; 1 to 64).
    #[arg(long, default_value_t = 4, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=64))]
    pub ao_rays: u32,
    /// Leave out the incoherent columns (`ao`, `diffuse`).
    #[arg(long)]
    pub no_incoherent: bool,
}

impl From<&CompareArgs> for CompareConfig {
    fn from(a: &CompareArgs) -> CompareConfig {
        CompareConfig {
            scene: a.scene.clone(),
            view: a.view.clone(),
            size: a.size,
            rounds: a.rounds,
            build_rounds: a.build_rounds,
            methods: a.methods.clone(),
            tiles: a.tiles.clone(),
            light_radius: a.light_radius,
            no_soft: a.no_soft,
            ao_rays: a.ao_rays,
            no_incoherent: a.no_incoherent,
        }
    }
}

/// `rttest compare`: the markdown table, or one JSON object per method.
pub fn run(global: &GlobalArgs, args: &CompareArgs) -> Result<(), Error> {
    let report = compare::run(&args.into(), &Bars { enabled: progress::enabled(global.json) })?;
    if global.json {
        for row in &report.rows {
            emit(global, &Json(row))?;
        }
        return Ok(());
    }
    print_text(&report)?;
    Ok(())
}

/// A row printed as JSON (its `Display` is never used: `--json` only).
struct Json<'a>(&'a compare::CompareRow);

impl serde::Serialize for Json<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.serialize(s)
    }
}

impl std::fmt::Display for Json<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0.method)
    }
}
