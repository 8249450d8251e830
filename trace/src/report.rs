//! The reports: tree statistics, build and render results, as a text table or one JSON object.
//!
//! The JSON field names are the interface to scripts (the README tables are made from them);
//! keep them stable. Times are in the unit their name says (`_ms`, `_secs`).

use std::fmt;

use kdtree::KdTree;

use kdtree::Counts;
use serde::Serialize;

/// The statistics of a built kd-tree, as reported by `rttest build`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct TreeSummary {
    /// Triangles given to the build (including degenerate ones).
    pub triangles: u64,
    /// Non-degenerate triangles, the ones the tree holds.
    pub triangles_in_tree: u64,
    /// Nodes, inner and leaf.
    pub nodes: u64,
    /// Inner nodes.
    pub inner_nodes: u64,
    /// Leaves, empty or not.
    pub leaves: u64,
    /// Leaves without triangles.
    pub empty_leaves: u64,
    /// Depth of the deepest leaf (the root alone has depth 0).
    pub depth: u64,
    /// Triangle references in leaves.
    pub refs: u64,
    /// `refs / triangles_in_tree`: how often perfect splits duplicate a triangle.
    pub refs_per_triangle: f64,
    /// Mean triangles per non-empty leaf.
    pub avg_tris_per_leaf: f64,
    /// The SAH cost of the tree relative to its root box (thesis 2.2.1).
    pub sah_cost: f64,
    /// Memory of the tree: nodes, references and per-triangle intersection records.
    pub bytes: u64,
    /// `bytes / triangles` (0 without triangles).
    pub bytes_per_triangle: f64,
    /// The most bytes the build held at once in its large buffers (event lists, scratch,
    /// subtree arrays, the tree and its triangles): what `--memory-budget` limits.
    pub build_peak_bytes: Option<u64>,
    /// The process's peak resident memory so far (`VmHWM` of `/proc/self/status`: scene, build
    /// and tree), read when the summary is made; `None` where there is no such file.
    pub peak_rss_bytes: Option<u64>,
}

impl TreeSummary {
    /// The statistics of `tree`, as [`KdTree::stats`] computes them.
    pub fn of(tree: &KdTree) -> TreeSummary {
        let s = tree.stats();
        TreeSummary {
            triangles: s.triangles as u64,
            triangles_in_tree: s.triangles_in_tree as u64,
            nodes: s.nodes as u64,
            inner_nodes: s.inner_nodes as u64,
            leaves: s.leaves as u64,
            empty_leaves: s.empty_leaves as u64,
            depth: s.depth as u64,
            refs: s.refs as u64,
            refs_per_triangle: s.refs_per_triangle,
            avg_tris_per_leaf: s.avg_tris_per_nonempty_leaf,
            sah_cost: s.sah_cost,
            bytes: s.bytes as u64,
            bytes_per_triangle: if s.triangles > 0 { s.bytes as f64 / s.triangles as f64 } else { 0.0 },
            build_peak_bytes: tree.build_peak_bytes(),
            peak_rss_bytes: peak_rss_bytes(),
        }
    }
}

/// The process's peak resident set size in bytes: `VmHWM` of `/proc/self/status` (Linux);
/// `None` elsewhere or if the line cannot be read.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    parse_vm_hwm(&status)
}

/// The `VmHWM:   1234 kB` line of a `/proc/self/status` text, in bytes.
pub fn parse_vm_hwm(status: &str) -> Option<u64> {
    let line = status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?;
    let kb: u64 = line.trim().strip_suffix("kB")?.trim().parse().ok()?;
    kb.checked_mul(1024)
}

/// Parses a byte count: a whole number of bytes (`1500000000`), or a number with a binary
/// unit `KiB`, `MiB`, `GiB` or `TiB` (`512MiB`, `1.5GiB`, case-insensitive, a space allowed),
/// for `--memory-budget`. Errors name the input; `nan`, `inf` and the like are errors (the
/// number is digits and one dot).
pub fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (number, unit) = (&t[..split], t[split..].trim());
    let scale: u64 = match unit.to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "kib" => 1 << 10,
        "mib" => 1 << 20,
        "gib" => 1 << 30,
        "tib" => 1 << 40,
        _ => return Err(format!("'{s}': expected bytes, or a number with KiB, MiB, GiB or TiB")),
    };
    let bad = || format!("'{s}' is not a byte count (such as 1500000000, 512MiB or 1.5GiB)");
    if number.is_empty() || number.starts_with('.') || number.matches('.').count() > 1 {
        return Err(bad());
    }
    if scale == 1 {
        return number.parse::<u64>().map_err(|_| bad());
    }
    let value: f64 = number.parse().map_err(|_| bad())?;
    let bytes = (value * scale as f64).floor();
    if !(bytes.is_finite() && bytes < u64::MAX as f64) {
        return Err(format!("'{s}' is too large"));
    }
    Ok(bytes as u64)
}

/// The result of building one scene's tree (`rttest build`, and the head of `rttest render`).
#[derive(Clone, Debug, Serialize)]
pub struct BuildReport {
    /// Scene name.
    pub scene: String,
    /// Milliseconds to build the tree (the best of `--repeat` builds); 0 when the tree was
    /// loaded from a file (`--tree`) instead.
    pub build_ms: f64,
    /// Milliseconds to load the tree file and check it ([`kdtree::KdTree::validate`] included
    /// unless `--tree-checks file`): the `--tree` file (the best of `--repeat` loads), or the
    /// file `rttest build --save` just wrote, read back; `None` when no tree file was read.
    pub load_tree_ms: Option<f64>,
    /// Of `load_tree_ms`, the part [`kdtree::KdTree::validate`] takes, timed alone on the
    /// loaded tree (`rttest build` only).
    pub validate_ms: Option<f64>,
    /// The tree file loaded (`--tree`) or saved (`--save`).
    pub tree_file: Option<String>,
    /// Milliseconds to load or generate the scene.
    pub load_ms: f64,
    /// Threads in the pool the build ran on.
    pub threads: usize,
    /// The ray-triangle test the tree was built for (`wald` or `watertight`).
    pub intersector: String,
    /// The SAH terms: `C_trav`, `C_isect` and the empty bonus.
    pub c_trav: f32,
    /// See `c_trav`.
    pub c_isect: f32,
    /// See `c_trav`.
    pub empty_bonus: f32,
    /// How the planes of large nodes were found (`exact` or `binned`,
    /// [`kdtree::BuildStrategy`]).
    pub build_strategy: String,
    /// Bins per axis of a binned build (`None` for exact).
    pub bins: Option<u32>,
    /// The smallest node a binned build bins (`None` for exact).
    pub bin_min_tris: Option<u32>,
    /// The leaf's SIMD group width in the SAH ([`kdtree::BuildConfig::leaf_width`]).
    pub leaf_width: u32,
    /// Bad refines allowed on a path ([`kdtree::BuildConfig::max_bad_refines`]).
    pub max_bad_refines: u32,
    /// Whether costlier subtrees were collapsed ([`kdtree::BuildConfig::collapse`]).
    pub collapse: bool,
    /// The tree's statistics (flattened into the JSON object).
    #[serde(flatten)]
    pub tree: TreeSummary,
}

/// The result of rendering one scene (`rttest render`).
#[derive(Clone, Debug, Serialize)]
pub struct RenderReport {
    /// Scene name.
    pub scene: String,
    /// The traversal method of the primary rays (`mono`, `packet`, `samesign`, `frustum`,
    /// `mft`).
    pub method: String,
    /// Tile side (the frustum of `frustum` and `mft`).
    pub tile: u32,
    /// Packet/leaf culling on (frustum methods).
    pub culling: bool,
    /// The view rendered (`custom` for `--camera`).
    pub view: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Threads in the pool.
    pub threads: usize,
    /// The ray-triangle test (`wald` or `watertight`).
    pub intersector: String,
    /// `none`, `hard`, `soft16` or `edge-width`.
    pub shadows: String,
    /// The kernel tracing the shadow rays (the registry's kernel name: `kd-packets`,
    /// `kd-stratum-packets`, ...; `edge-width`; empty without shadows).
    pub shadow_kernel: String,
    /// `color`, `depth` or `prim`.
    pub aov: String,
    /// Triangles in the scene.
    pub triangles: u64,
    /// Milliseconds to build the tree.
    pub build_ms: f64,
    /// Frames traced; the times are the best (minimum) over them.
    pub frames: u32,
    /// Rays traced in one frame: `primary_rays + shadow_rays`.
    pub rays: u64,
    /// Primary rays in one frame (one per pixel).
    pub primary_rays: u64,
    /// Shadow rays in one frame (one per primary hit facing the light, with shadows on).
    pub shadow_rays: u64,
    /// Primary rays that hit.
    pub hits: u64,
    /// Shadow rays that found a blocker.
    pub occluded: u64,
    /// Best frame's seconds for ray generation, traversal and intersection (both passes).
    pub trace_secs: f64,
    /// Best seconds of the primary pass alone.
    pub primary_secs: f64,
    /// Best seconds of the shadow pass alone (0 without shadows).
    pub shadow_secs: f64,
    /// `rays / trace_secs / 1e6`.
    pub mrays_per_s: f64,
    /// `primary_rays / primary_secs / 1e6`.
    pub primary_mrays_per_s: f64,
    /// `shadow_rays / shadow_secs / 1e6` (0 without shadows).
    pub shadow_mrays_per_s: f64,
    /// Generations of secondary rays (`--secondary`; 0: none).
    pub secondary_depth: u32,
    /// Secondary (reflection and refraction) rays in the best frame, every generation.
    pub secondary_rays: u64,
    /// Secondary rays that hit.
    pub secondary_hits: u64,
    /// Shadow rays from the secondary hits.
    pub secondary_shadow_rays: u64,
    /// The best frame's seconds spawning the secondary rays (the shader proxy).
    pub spawn_secs: f64,
    /// The best frame's seconds tracing the secondary rays.
    pub secondary_secs: f64,
    /// The best frame's seconds tracing the secondary hits' shadows.
    pub secondary_shadow_secs: f64,
    /// `secondary_rays / secondary_secs / 1e6` (0 without secondary rays).
    pub secondary_mrays_per_s: f64,
    /// Seconds to shade (or extract the AOV) into the image, once.
    pub shade_secs: f64,
    /// Seconds to write the image file.
    pub write_secs: f64,
    /// The image file written (`None`: traced only, nothing written).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub out: Option<String>,
    /// Traversal work per ray, with `--counters` (flattened into the JSON object).
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub traversal: Option<TraversalReport>,
    /// The incoherent workload's streams, with `--workload` (flattened into the JSON object).
    #[serde(flatten)]
    pub workload: WorkloadReport,
}

/// The incoherent workload of a frame (`crate::workload`: ambient-occlusion rays, any hit;
/// one diffuse bounce, closest hit) traced by the method's stream queries, the best of the
/// frames; each field present only for the streams asked for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct WorkloadReport {
    /// Ambient-occlusion rays traced per frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ao_rays: Option<u64>,
    /// Best milliseconds of the AO stream.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ao_ms: Option<f64>,
    /// `ao_rays / ao_ms / 1e3`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ao_mrays_per_s: Option<f64>,
    /// Diffuse-bounce rays traced per frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diffuse_rays: Option<u64>,
    /// Best milliseconds of the diffuse stream.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diffuse_ms: Option<f64>,
    /// `diffuse_rays / diffuse_ms / 1e3`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diffuse_mrays_per_s: Option<f64>,
}

/// Mean traversal work per ray, from one counted frame (`--counters`), and for the packet
/// methods the thesis's per-packet figures (Tables 4.1-4.3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct TraversalReport {
    /// N: traversal steps per 2x2 packet of the primary pass (packet methods; a frustum's
    /// steps are shared by its packets).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub primary_steps_per_packet: Option<f64>,
    /// I: packet-triangle tests per 2x2 packet of the primary pass (packet methods): per 4
    /// rays, so a 16-ray packet's one test counts a quarter (the thesis's unit at every
    /// width; the chapter-4 tables run 2x2 packets).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub primary_tests_per_packet: Option<f64>,
    /// Percentage of the packets considered at leaves that packet/leaf culling skipped
    /// (frustum methods).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub culled_percent: Option<f64>,
    /// Nodes fetched per primary ray (inner and leaf).
    pub primary_nodes_per_ray: f64,
    /// Leaves visited per primary ray.
    pub primary_leaves_per_ray: f64,
    /// Ray-triangle tests per primary ray.
    pub primary_isects_per_ray: f64,
    /// Nodes fetched per shadow ray.
    pub shadow_nodes_per_ray: f64,
    /// Leaves visited per shadow ray.
    pub shadow_leaves_per_ray: f64,
    /// Ray-triangle tests per shadow ray.
    pub shadow_isects_per_ray: f64,
    /// Percentage of what the shadow kernel considered at leaves that it culled before any
    /// ray test (packets for the frustum kernels, frustum-triangle pairs for `lane-frusta`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shadow_culled_percent: Option<f64>,
}

impl TraversalReport {
    /// The thesis's N and I of the primary pass: per 2x2 packet for packet methods, per 4
    /// single rays otherwise (Tables 4.1-4.5).
    pub fn per_packet(&self) -> (f64, f64) {
        match (self.primary_steps_per_packet, self.primary_tests_per_packet) {
            (Some(n), Some(i)) => (n, i),
            _ => (4.0 * self.primary_nodes_per_ray, 4.0 * self.primary_isects_per_ray),
        }
    }

    /// Per-ray means of the counts of `primary_rays` primary and `shadow_rays` shadow rays;
    /// with `packets` (the primary pass's 2x2 packets, for packet methods) the per-packet
    /// figures too.
    pub fn new(primary_rays: u64, primary: Counts, shadow_rays: u64, shadow: Counts, packets: Option<u64>) -> Self {
        let per = |n: u64, rays: u64| if rays > 0 { n as f64 / rays as f64 } else { 0.0 };
        TraversalReport {
            primary_steps_per_packet: packets.map(|p| primary.steps_per_packet(p)),
            primary_tests_per_packet: packets.map(|p| primary.tests_per_packet(p)),
            culled_percent: primary.culled_percent(),
            primary_nodes_per_ray: per(primary.nodes, primary_rays),
            primary_leaves_per_ray: per(primary.leaves, primary_rays),
            primary_isects_per_ray: per(primary.tests, primary_rays),
            shadow_nodes_per_ray: per(shadow.nodes, shadow_rays),
            shadow_leaves_per_ray: per(shadow.leaves, shadow_rays),
            shadow_isects_per_ray: per(shadow.tests, shadow_rays),
            shadow_culled_percent: shadow.culled_percent(),
        }
    }
}

/// Bytes in a human unit.
fn human_bytes(bytes: u64) -> String {
    const MIB: f64 = 1024.0 * 1024.0;
    const GIB: f64 = 1024.0 * MIB;
    if bytes as f64 >= GIB {
        format!("{:.2} GiB", bytes as f64 / GIB)
    } else if bytes as f64 >= MIB {
        format!("{:.1} MiB", bytes as f64 / MIB)
    } else {
        format!("{:.1} KiB", bytes as f64 / 1024.0)
    }
}

impl fmt::Display for BuildReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let t = &self.tree;
        writeln!(f, "scene        {} ({} triangles, {} in tree)", self.scene, t.triangles, t.triangles_in_tree)?;
        writeln!(f, "load         {:.1} ms", self.load_ms)?;
        match &self.tree_file {
            Some(file) if self.build_ms == 0.0 => {
                writeln!(f, "tree         loaded from {file}, not built ({} intersector)", self.intersector)?
            }
            _ => writeln!(
                f,
                "build        {:.1} ms ({} threads, {} intersector, C_trav:C_isect {}:{}, empty bonus {}, leaf width {}{}, {} build{})",
                self.build_ms,
                self.threads,
                self.intersector,
                self.c_trav,
                self.c_isect,
                self.empty_bonus,
                self.leaf_width,
                match (self.max_bad_refines, self.collapse) {
                    (0, false) => String::new(),
                    (b, c) => format!(", {b} bad refines{}", if c { ", collapse" } else { "" }),
                },
                self.build_strategy,
                match (self.bins, self.bin_min_tris) {
                    (Some(b), Some(m)) => format!(" with {b} bins from {m} triangles"),
                    _ => String::new(),
                }
            )?,
        }
        if let Some(ms) = self.load_tree_ms {
            let file = self.tree_file.as_deref().unwrap_or("?");
            match self.validate_ms {
                Some(v) => writeln!(f, "load tree    {ms:.1} ms ({file}; of which validate {v:.1} ms)")?,
                None => writeln!(f, "load tree    {ms:.1} ms ({file})")?,
            }
        }
        writeln!(
            f,
            "nodes        {} ({} inner, {} leaves of which {} empty)",
            t.nodes, t.inner_nodes, t.leaves, t.empty_leaves
        )?;
        writeln!(f, "depth        {}", t.depth)?;
        writeln!(
            f,
            "refs         {} ({:.2} per triangle, {:.2} per non-empty leaf)",
            t.refs, t.refs_per_triangle, t.avg_tris_per_leaf
        )?;
        writeln!(f, "SAH cost     {:.2}", t.sah_cost)?;
        writeln!(f, "memory       {} ({:.1} bytes per triangle)", human_bytes(t.bytes), t.bytes_per_triangle)?;
        let peak = |b: Option<u64>| b.map_or("unknown".to_string(), human_bytes);
        write!(f, "peak memory  build {}, process {}", peak(t.build_peak_bytes), peak(t.peak_rss_bytes))
    }
}

impl fmt::Display for RenderReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "render       {}x{}, view {}, method {} (tile {}{}), shadows {}{}, {} threads",
            self.width,
            self.height,
            self.view,
            self.method,
            self.tile,
            if self.culling { "" } else { ", no culling" },
            self.shadows,
            if self.shadow_kernel.is_empty() { String::new() } else { format!(" ({})", self.shadow_kernel) },
            self.threads
        )?;
        writeln!(
            f,
            "rays         {} = {} primary ({} hits) + {} shadow ({} blocked)",
            self.rays, self.primary_rays, self.hits, self.shadow_rays, self.occluded
        )?;
        writeln!(
            f,
            "trace        {:.4} s (best of {} frame{}): {:.2} Mrays/s (primary {:.2}, shadow {:.2})",
            self.trace_secs,
            self.frames,
            if self.frames == 1 { "" } else { "s" },
            self.mrays_per_s,
            self.primary_mrays_per_s,
            self.shadow_mrays_per_s
        )?;
        if self.secondary_depth > 0 {
            writeln!(
                f,
                "secondary    depth {}: {} rays ({} hits), {:.4} s: {:.2} Mrays/s; spawning {:.4} s; {} shadow rays, {:.4} s",
                self.secondary_depth,
                self.secondary_rays,
                self.secondary_hits,
                self.secondary_secs,
                self.secondary_mrays_per_s,
                self.spawn_secs,
                self.secondary_shadow_rays,
                self.secondary_shadow_secs
            )?;
        }
        let w = &self.workload;
        if let (Some(rays), Some(ms), Some(m)) = (w.ao_rays, w.ao_ms, w.ao_mrays_per_s) {
            writeln!(f, "ao           {rays} rays, {ms:.2} ms (best of {} frames): {m:.2} Mrays/s", self.frames)?;
        }
        if let (Some(rays), Some(ms), Some(m)) = (w.diffuse_rays, w.diffuse_ms, w.diffuse_mrays_per_s) {
            writeln!(f, "diffuse      {rays} rays, {ms:.2} ms (best of {} frames): {m:.2} Mrays/s", self.frames)?;
        }
        if let Some(t) = &self.traversal {
            writeln!(
                f,
                "per ray      primary {:.2} nodes, {:.2} leaves, {:.2} tests; shadow {:.2} nodes, {:.2} leaves, {:.2} tests",
                t.primary_nodes_per_ray,
                t.primary_leaves_per_ray,
                t.primary_isects_per_ray,
                t.shadow_nodes_per_ray,
                t.shadow_leaves_per_ray,
                t.shadow_isects_per_ray
            )?;
            if let (Some(n), Some(i)) = (t.primary_steps_per_packet, t.primary_tests_per_packet) {
                write!(f, "per packet   N = {n:.2} steps, I = {i:.2} tests (per 4 rays, the thesis's 2x2 packet)")?;
                match t.culled_percent {
                    Some(c) => writeln!(f, ", {c:.1}% of packets culled at leaves")?,
                    None => writeln!(f)?,
                }
            }
            if let Some(c) = t.shadow_culled_percent {
                writeln!(f, "shadow       {c:.1}% culled at leaves before any ray test")?;
            }
        }
        match &self.out {
            Some(out) => write!(
                f,
                "output       {out} ({}: shade {:.4} s, write {:.4} s)",
                self.aov, self.shade_secs, self.write_secs
            ),
            None => write!(f, "output       none (traced only)"),
        }
    }
}
