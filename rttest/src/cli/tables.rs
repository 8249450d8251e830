//! `rttest tables`: the arguments of [`experiments::tables`] and its output.

use clap::Args;
use experiments::tables::{self, TablesConfig};
use trace::Error;

use super::{BuildStrategyArg, CostModelArg, GlobalArgs, IntersectorArg, header, parse_size, print_text};
use crate::progress::{self, Bars};

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
    /// The trees' SAH cost model (`thesis` builds the thesis's own trees).
    #[arg(long, value_enum, default_value_t = CostModelArg::WaldHavran)]
    pub cost_model: CostModelArg,
    /// How the trees' planes are found: `binned` (the default) or `exact` (the SAH event
    /// sweep at every node, the thesis's build).
    #[arg(long = "build", value_enum, default_value_t = BuildStrategyArg::default(), value_name = "STRATEGY")]
    pub strategy: BuildStrategyArg,
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
    /// Leave out the width ladder (each kernel at 1, 4, 8 and 16 rays per instruction beside
    /// Embree's, one `compare` run per scene).
    #[arg(long, conflicts_with = "only_ladder")]
    pub no_ladder: bool,
    /// Only the width ladder, none of the thesis's tables.
    #[arg(long, conflicts_with = "only_pipeline")]
    pub only_ladder: bool,
    /// Leave out Table 3.1 and the garage's Table 6.2 (the thesis's whole renderer: MFT
    /// primaries, reflections and glass, edge-width shadows; beside it hard shadows by ours
    /// and by Embree).
    #[arg(long, conflicts_with = "only_pipeline")]
    pub no_pipeline: bool,
    /// Only Table 3.1 and the garage's Table 6.2.
    #[arg(long)]
    pub only_pipeline: bool,
    /// The scene of Table 3.1 and the garage's Table 6.2.
    #[arg(long, value_name = "NAME|PATH", default_value = "garage")]
    pub pipeline_scene: String,
}

impl From<&TablesArgs> for TablesConfig {
    fn from(a: &TablesArgs) -> TablesConfig {
        TablesConfig {
            scene: a.scene.clone(),
            size: a.size,
            frames: a.frames,
            intersector: a.intersector.into(),
            cost_model: a.cost_model.into(),
            strategy: a.strategy.strategy(),
            csv: a.csv,
            no_soft_shadows: a.no_soft_shadows,
            no_scaling: a.no_scaling,
            no_ladder: a.no_ladder,
            only_ladder: a.only_ladder,
            no_pipeline: a.no_pipeline,
            only_pipeline: a.only_pipeline,
            pipeline_scene: a.pipeline_scene.clone(),
        }
    }
}

/// `rttest tables`: markdown (or CSV) on stdout, under the machine line (on stderr with
/// `--csv`, so that stdout stays one CSV text).
pub fn run(global: &GlobalArgs, args: &TablesArgs) -> Result<(), Error> {
    let report = tables::run(&args.into(), &Bars { enabled: progress::enabled(global.json) })?;
    if args.csv {
        header(&mut std::io::stderr().lock())?;
        print!("{report}");
        return Ok(());
    }
    print_text(&report)
}
