//! `rttest leaks`: the options of the leak test and the command that prints its table or
//! JSON lines (the test itself is [`experiments::leaks`]).

use clap::Args;
use experiments::leaks::{self, LeaksConfig};
use trace::Error;

use super::{GlobalArgs, emit, print_text};
use crate::progress::{self, Bars};

/// `rttest leaks` options.
#[derive(Debug, Clone, Args)]
pub struct LeaksArgs {
    /// Rays per intersector, over all meshes (split evenly between them).
    #[arg(long, value_name = "N", default_value_t = 10_000_000,
          value_parser = clap::value_parser!(u64).range(1..=10_000_000_000))]
    pub rays: u64,
    /// Only these meshes (fan, sphere, the built-in closed scenes, bunny); default all.
    #[arg(long, value_name = "NAME", value_delimiter = ',')]
    pub meshes: Vec<String>,
}

impl From<&LeaksArgs> for LeaksConfig {
    fn from(args: &LeaksArgs) -> LeaksConfig {
        LeaksConfig { rays: args.rays, meshes: args.meshes.clone() }
    }
}

/// `rttest leaks`: every mesh (or those of `--meshes`), `--rays` rays per intersector split
/// evenly between them, a markdown table (or one JSON object per row), the totals last.
/// Notes (a missing bunny) go to stderr, except with `--json`.
pub fn run(global: &GlobalArgs, args: &LeaksArgs) -> Result<(), Error> {
    let report = leaks::run(&args.into(), &Bars { enabled: progress::enabled(global.json) })?;
    if global.json {
        return report.rows().try_for_each(|r| emit(global, r));
    }
    for note in &report.notes {
        eprintln!("rttest: note: {note}");
    }
    print_text(&report)?;
    Ok(())
}
