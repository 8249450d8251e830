//! The `rttest` command line tool and the shared harness of the criterion benches.
//!
//! The tool re-creates the "RTTest" application of Tsakok's thesis (2008): it loads a scene,
//! builds its kd-tree, renders it with a chosen traversal method and reports build time, tree
//! statistics and ray throughput, for people (a table) or for scripts (`--json`).
//!
//! ```text
//! rttest                                   # atrium, 512x512, hard shadows -> atrium.png + report
//! rttest build  --scene NAME|FILE.obj[.gz] [--intersector wald|watertight] [--repeat N]
//! rttest render --scene NAME|FILE.obj[.gz] [--view NAME | --camera ex,ey,ez,tx,ty,tz,fovy]
//!               [--size WxH] [--shadows none|hard] [--aov color|depth|prim] [--out FILE]
//!               [--frames N] [--method mono|packet|samesign|frustum|mft] [--tile N]
//!               [--no-culling] [--intersector wald|watertight] [--counters]
//! rttest tables [--scene NAME|FILE ...] [--size WxH] [--frames N] [--csv]
//! rttest raycast --scene NAME|FILE.obj[.gz] --rays FILE|- [--format text|binary]
//!               [--out FILE|-] [--out-format text|binary] [--method mono] [--any-hit]
//!               [--intersector wald|watertight]
//! rttest leaks  [--rays N] [--meshes NAME,...]
//! rttest compare [--scene NAME|FILE] [--view NAME] [--size WxH] [--rounds N] [--methods LIST]
//!               [--tiles LIST] [--light-radius R] [--no-soft] [--build-rounds N]
//! global flags: --threads N (rayon pool size, default all cores), --json (one object per line)
//! ```
//!
//! `build --json` keys: `scene, build_ms, load_ms, threads, intersector, triangles,
//! triangles_in_tree, nodes, inner_nodes, leaves, empty_leaves, depth, refs,
//! refs_per_triangle, avg_tris_per_leaf, sah_cost, bytes, bytes_per_triangle,
//! build_peak_bytes, peak_rss_bytes` (the last `null` where `/proc/self/status` is missing).
//!
//! `render --json` keys: `scene, method, view, width, height, threads, intersector, shadows,
//! aov, triangles, build_ms, frames, rays, primary_rays, shadow_rays, hits, occluded,
//! trace_secs, primary_secs, shadow_secs, mrays_per_s, primary_mrays_per_s,
//! shadow_mrays_per_s, shade_secs, write_secs, out, tile, culling` and, with `--counters`,
//! `{primary,shadow}_{nodes,leaves,isects}_per_ray` (for packet methods also
//! `primary_steps_per_packet`, `primary_tests_per_packet` and, for frusta, `culled_percent`). `trace_secs` is the best frame's ray
//! generation + traversal + intersection (primary and shadow passes), never shading or I/O.
//!
//! `compare --json` keys (one object per method): `scene, method, family, build_ms,
//! primary_mrays_per_s, shadow_mrays_per_s, soft16_mrays_per_s, prim_mismatch, prim_ties,
//! prim_edge_ties, prim_coincident, prim_hit_vs_miss, pixels, primary_ms, shadow_ms,
//! soft16_ms, shadow_kernel, soft16_kernel, threads, rounds` (see [`compare`]).
//!
//! `raycast` traces the rays of a file and writes one result per ray, in input order:
//! - rays in **text**: one ray per line, `ox oy oz dx dy dz tmin tmax` (whitespace separated;
//!   blank lines and `#` comments skipped; `inf` allowed), or **binary** (`--format binary`
//!   or a `.bin` / `.f32` file): 8 little-endian `f32` per ray, 32 bytes, no header;
//! - results in **text**: `prim t u v` per line, `prim` being the scene file's primitive id
//!   and a miss `-1 inf 0 0`, or with `--any-hit` `1` / `0`; in **binary**
//!   (`--out-format binary` or a `.bin` / `.f32` `--out`): `i32 prim, f32 t, u, v` (16
//!   bytes, a miss `-1, inf, 0, 0`), or with `--any-hit` one byte `1` / `0` per ray;
//! - a bad ray rejects the whole file: `rttest: error: rays.txt:17: <reason>`, exit status 1;
//! - `--json` (needs `--out FILE`) keys: `scene, method, any_hit, intersector, threads,
//!   triangles, build_ms, rays, hits, trace_secs, mrays_per_s, read_secs, write_secs,
//!   rays_file, out`.
//!
//! See [`raycast`] for the details.
//!
//! Modules, one concept each:
//! - [`cli`]: the command line (clap) and the driver that runs one command;
//! - [`raycast`]: ray files in, one result per ray out (`rttest raycast`);
//! - [`render`]: the tile renderer; tracing is a separate, timed pass over preallocated
//!   per-pixel buffers, shading and image output come after and are timed apart;
//! - [`tables`]: the thesis's Tables 4.1-4.6 and 6.2 (`rttest tables`);
//! - [`scaling`]: Table 6.2, frame rate against threads (rayon pool sizes);
//! - [`compare`]: our methods against Embree and the `bvh` / `obvhs` crates on the same
//!   rays (`rttest compare`); [`baselines`]: those tracers and the passes that run them;
//! - [`soft`]: 16-sample soft shadows to a spherical light, cone vs pyramid vs single rays;
//! - [`shade`]: shadow-ray construction and the diffuse point-light shading of the thesis;
//! - [`report`]: tree statistics and the text / JSON reports;
//! - [`progress`]: progress bars that only appear for work taking more than a second;
//! - [`harness`]: scene, tree and ray setup shared by the benches (and the tests);
//! - [`shadows`]: edge-width against sampled soft shadows (`rttest shadows`), plotted by
//!   [`shadow_plot`]; [`table51`]: the thesis's Table 5.1 in `rttest tables`;
//! - [`leaks`]: watertightness measured, rays at shared edges and vertices (`rttest leaks`);
//! - [`error`]: the one error type, printed as a single line by the binary.

pub mod baselines;
pub mod cli;
pub mod compare;
pub mod error;
pub mod harness;
pub mod leaks;
pub mod progress;
pub mod raycast;
pub mod render;
pub mod report;
pub mod scaling;
pub mod shade;
pub mod shadow_plot;
pub mod shadows;
pub mod soft;
pub mod table51;
pub mod tables;

pub use error::Error;
