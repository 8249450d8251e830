//! `rttest raycast`: the arguments, and the run: read and check the ray file, build, trace
//! with the method's stream query, write the results ([`crate::raycast`] has the formats).

use std::fs::File;
use std::io::{self, BufWriter};
use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use serde::Serialize;
use trace::Error;

use super::{Built, GlobalArgs, SceneArgs, emit, structures_for};
use crate::raycast::{Format, RAY_BYTES, check_prim_ids, is_dash, read_rays, trace, write_results};

/// `rttest raycast` options.
#[derive(Debug, Clone, Args)]
pub struct RaycastArgs {
    /// The scene.
    #[command(flatten)]
    pub scene: SceneArgs,
    /// The rays: a text or binary file (see --format), or - for stdin.
    #[arg(long, value_name = "FILE")]
    pub rays: PathBuf,
    /// Format of the ray file (default: binary for .bin and .f32 files, else text).
    #[arg(long, value_enum, value_name = "FORMAT")]
    pub format: Option<Format>,
    /// Where the results go (default: stdout; - is stdout too).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Format of the results (default: binary for an --out file ending in .bin or .f32, else text).
    #[arg(long, value_enum, value_name = "FORMAT")]
    pub out_format: Option<Format>,
    /// How rays traverse the tree (a registered method, traced by its stream kernel): one by
    /// one, or grouped (4 consecutive rays to a packet; runs of up to 64 rays sharing an
    /// origin to a frustum or cone).
    #[arg(long, default_value = "mono", value_name = "METHOD", help = super::method_help(), long_help = super::method_long_help())]
    pub method: String,
    /// Ask only whether anything is hit (1 or 0 per ray), not for the closest hit.
    #[arg(long)]
    pub any_hit: bool,
}

/// The summary of one `rttest raycast` run (printed with `--json`, or as text with `--out`).
#[derive(Clone, Debug, Serialize)]
pub struct RaycastReport {
    /// Scene name.
    pub scene: String,
    /// The traversal method (`mono`).
    pub method: String,
    /// True for `--any-hit` (occlusion) queries.
    pub any_hit: bool,
    /// The ray-triangle test (`wald` or `watertight`).
    pub intersector: String,
    /// Threads in the pool.
    pub threads: usize,
    /// Triangles in the scene.
    pub triangles: u64,
    /// Milliseconds to build the tree.
    pub build_ms: f64,
    /// Rays traced.
    pub rays: u64,
    /// Rays that hit (closest hit) or are occluded (`--any-hit`).
    pub hits: u64,
    /// Seconds of traversal and intersection for all rays.
    pub trace_secs: f64,
    /// `rays / trace_secs / 1e6`.
    pub mrays_per_s: f64,
    /// Seconds to read and check the ray file.
    pub read_secs: f64,
    /// Seconds to format and write the results.
    pub write_secs: f64,
    /// The ray file (`-` for stdin).
    pub rays_file: String,
    /// The results file (`-` for stdout).
    pub out: String,
}

impl std::fmt::Display for RaycastReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "raycast      {} rays from {}, method {}, {}, {} threads",
            self.rays,
            self.rays_file,
            self.method,
            if self.any_hit { "any hit" } else { "closest hit" },
            self.threads
        )?;
        writeln!(f, "hits         {}", self.hits)?;
        writeln!(f, "trace        {:.4} s: {:.2} Mrays/s", self.trace_secs, self.mrays_per_s)?;
        write!(f, "io           read {:.4} s, write {:.4} s, results in {}", self.read_secs, self.write_secs, self.out)
    }
}

/// `rttest raycast`: the scene is loaded and built by `load`, after the arguments and the
/// ray file have been checked.
pub fn run(global: &GlobalArgs, args: &RaycastArgs, load: impl FnOnce() -> Result<Built, Error>) -> Result<(), Error> {
    let registry = baselines::registry();
    let selected = registry.select(&args.method, trace::Options::default())?;
    let out_path = args.out.as_ref().filter(|p| !is_dash(p));
    if global.json && out_path.is_none() {
        return Err(Error::Usage("--json prints a summary on stdout, so the results need --out FILE".into()));
    }
    let in_format =
        args.format.unwrap_or_else(|| if is_dash(&args.rays) { Format::Text } else { Format::of_path(&args.rays) });
    let out_format = args.out_format.unwrap_or_else(|| out_path.map_or(Format::Text, |p| Format::of_path(p)));
    let rays_name = args.rays.display().to_string();

    // Read and check every ray before building anything.
    let start = Instant::now();
    let rays = if is_dash(&args.rays) {
        read_rays(&mut io::stdin().lock(), in_format, &rays_name)?
    } else {
        let file = File::open(&args.rays)
            .map_err(|e| Error::File { path: args.rays.clone(), message: format!("cannot open: {e}") })?;
        if in_format == Format::Binary
            && let Ok(meta) = file.metadata()
            && meta.is_file()
            && meta.len() % RAY_BYTES as u64 != 0
        {
            return Err(Error::File {
                path: args.rays.clone(),
                message: format!(
                    "size {} bytes is not a multiple of {RAY_BYTES} (8 little-endian f32 per ray)",
                    meta.len()
                ),
            });
        }
        read_rays(&mut io::BufReader::with_capacity(1 << 16, file), in_format, &rays_name)?
    };
    let read_secs = start.elapsed().as_secs_f64();

    let built = load()?;
    let prim_ids = &built.scene.mesh.prim_ids;
    check_prim_ids(prim_ids, out_format, args.any_hit)?;
    let structures = structures_for(&registry, &selected, &built)?;
    let method = registry.bind(&selected, &structures)?;

    let start = Instant::now();
    let results = trace(&*method.tracer, &rays, args.any_hit);
    let trace_secs = start.elapsed().as_secs_f64();

    let start = Instant::now();
    match out_path {
        Some(path) => {
            let file = File::create(path)
                .map_err(|e| Error::File { path: path.clone(), message: format!("cannot create: {e}") })?;
            let mut w = BufWriter::with_capacity(1 << 20, file);
            write_results(&results, prim_ids, out_format, &mut w)
                .map_err(|e| Error::File { path: path.clone(), message: format!("cannot write: {e}") })?;
        }
        None => write_results(&results, prim_ids, out_format, &mut io::stdout().lock())?,
    }
    let write_secs = start.elapsed().as_secs_f64();

    let Some(path) = out_path else { return Ok(()) };
    let report = RaycastReport {
        scene: built.scene.name.clone(),
        method: method.entry.name.to_string(),
        any_hit: args.any_hit,
        intersector: built.report.intersector.clone(),
        threads: rayon::current_num_threads(),
        triangles: built.report.tree.triangles,
        build_ms: built.report.build_ms,
        rays: rays.len() as u64,
        hits: results.hits(),
        trace_secs,
        mrays_per_s: trace::timing::mrays_per_s(rays.len() as u64, trace_secs),
        read_secs,
        write_secs,
        rays_file: rays_name,
        out: path.display().to_string(),
    };
    emit(global, &report)
}
