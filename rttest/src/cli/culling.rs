//! `rttest culling`: pre-BVH culling for shadow rays (Selgrad et al.), the options of
//! [`experiments::culling`] and its table or JSON lines.

use clap::Args;
use experiments::culling::{self, CullingConfig};
use trace::Error;

use super::{GlobalArgs, parse_size, print_json, print_text};
use crate::progress::{self, Bars};

/// `rttest culling` options.
#[derive(Debug, Clone, Args)]
pub struct CullingArgs {
    /// Scenes, comma-separated: built-in names or paths to .obj / .obj.gz files.
    #[arg(long, value_delimiter = ',', default_value = "atrium", value_name = "LIST")]
    pub scenes: Vec<String>,
    /// Image size (the primary hits the shadow rays start from).
    #[arg(long, value_name = "WxH", default_value = "512x512", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Interleaved timed rounds; medians are reported.
    #[arg(long, default_value_t = 5, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub rounds: u32,
}

impl From<&CullingArgs> for CullingConfig {
    fn from(a: &CullingArgs) -> CullingConfig {
        CullingConfig { scenes: a.scenes.clone(), size: a.size, rounds: a.rounds }
    }
}

/// `rttest culling`: a markdown table, or one JSON object per scene.
pub fn run(global: &GlobalArgs, args: &CullingArgs) -> Result<(), Error> {
    let report = culling::run(&args.into(), &Bars { enabled: progress::enabled(global.json) })?;
    if global.json {
        for row in &report.rows {
            print_json(row)?;
        }
        return Ok(());
    }
    print_text(&report)?;
    if report.rows.iter().any(|r| !r.identical) {
        return Err(Error::Usage("culled shadow answers differ from unculled ones".into()));
    }
    Ok(())
}
