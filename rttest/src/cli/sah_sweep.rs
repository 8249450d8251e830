//! `rttest sah-sweep`: the arguments of [`experiments::sah_sweep`] and its output.

use clap::Args;
use experiments::sah_sweep::{self, SweepConfig};
use trace::Error;

use super::{GlobalArgs, print_json, print_text};
use crate::progress::{self, Bars};

/// `rttest sah-sweep` options.
#[derive(Debug, Clone, Args)]
pub struct SahSweepArgs {
    /// Scenes (built-in names or OBJ paths; repeatable). Default: atrium, arena,
    /// atrium-rotated, grove and every .obj / .obj.gz in the shared scenes folder.
    #[arg(long, value_name = "NAME|PATH")]
    pub scene: Vec<String>,
    /// Only these cost models (names separated by ';'; default all): thesis, wald-havran,
    /// pbrt, isect-2, isect-3, isect-10, isect-20, bonus-0.2, bonus-0.5, depth-4, depth+4,
    /// bonus-0.2,depth+4, bonus-0.5,depth+4, wh-leaf4, wh-leaf8, wh-bad3, wh-bad3-collapse,
    /// wh-leaf4-bad3, wh-leaf4-bad3-collapse, wh-leaf4-isect2, wh-leaf8-bad3-collapse,
    /// wh-leaf4-isect3, wh-leaf4-isect2-bad3-collapse.
    #[arg(long, value_name = "NAME", value_delimiter = ';')]
    pub candidates: Vec<String>,
    /// Image side: `N x N` primary rays from each scene's default view.
    #[arg(long, value_name = "N", default_value_t = 512, value_parser = clap::value_parser!(u32).range(8..=4096))]
    pub size: u32,
    /// Interleaved timing rounds; medians are reported.
    #[arg(long, value_name = "N", default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub rounds: u32,
}

/// `rttest sah-sweep`: one markdown table per scene (or one JSON object per row).
pub fn run(global: &GlobalArgs, args: &SahSweepArgs) -> Result<(), Error> {
    let all = sah_sweep::default_candidates();
    let candidates = if args.candidates.is_empty() {
        all
    } else {
        let mut picked = Vec::new();
        for name in &args.candidates {
            let Some(c) = all.iter().find(|c| &c.name == name) else {
                let names: Vec<&str> = all.iter().map(|c| c.name.as_str()).collect();
                return Err(Error::Usage(format!("unknown cost model '{name}'; known: {}", names.join(", "))));
            };
            picked.push(c.clone());
        }
        picked
    };
    let scenes = if args.scene.is_empty() { trace::setup::default_scenes() } else { args.scene.clone() };
    let config = SweepConfig { scenes, candidates, size: args.size, rounds: args.rounds };
    let report = sah_sweep::run(&config, &Bars { enabled: progress::enabled(global.json) })?;
    if global.json {
        for row in &report.rows {
            print_json(row)?;
        }
        return Ok(());
    }
    print_text(&report)?;
    Ok(())
}
