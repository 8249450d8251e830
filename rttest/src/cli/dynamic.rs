//! `rttest dynamic`: pre-BVH culling on an animated scene rebuilt every frame (the dynamic case
//! of Selgrad et al.), the options of [`experiments::dynamic`] and its table or JSON lines.

use clap::Args;
use experiments::dynamic::{self, DynamicConfig};
use trace::Error;

use super::{GlobalArgs, parse_size, print_json, print_text};
use crate::progress::{self, Bars};

/// `rttest dynamic` options.
#[derive(Debug, Clone, Args)]
pub struct DynamicArgs {
    /// The base scene (built-in name or path to an .obj / .obj.gz file); moving objects are
    /// added to it (`scenes::builtin::animated`).
    #[arg(long, default_value = "arena", value_name = "NAME")]
    pub scene: String,
    /// Frames 0 .. N of the animation.
    #[arg(long, default_value_t = 8, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100000))]
    pub frames: u32,
    /// Image size (the primary hits the shadow rays start from).
    #[arg(long, value_name = "WxH", default_value = "512x512", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Interleaved timed rounds per frame; medians are reported.
    #[arg(long, default_value_t = 1, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub rounds: u32,
}

impl From<&DynamicArgs> for DynamicConfig {
    fn from(a: &DynamicArgs) -> DynamicConfig {
        DynamicConfig { scene: a.scene.clone(), frames: a.frames, size: a.size, rounds: a.rounds }
    }
}

/// `rttest dynamic`: markdown tables (per frame, then totals), or one JSON object per frame;
/// an error naming the frames whose culled shadow answers differ from the unculled ones.
pub fn run(global: &GlobalArgs, args: &DynamicArgs) -> Result<(), Error> {
    let report = dynamic::run(&args.into(), &Bars { enabled: progress::enabled(global.json) })?;
    if global.json {
        for row in &report.rows {
            print_json(row)?;
        }
    } else {
        print_text(&report)?;
    }
    let differing = report.differing_frames();
    if !differing.is_empty() {
        return Err(Error::Usage(format!("culled shadow answers differ from unculled ones in frames {differing:?}")));
    }
    Ok(())
}
