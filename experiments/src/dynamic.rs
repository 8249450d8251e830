//! The dynamic case of pre-BVH culling (Selgrad, Müller & Stamminger, "Faster Ray-Traced
//! Shadows via Pre-BVH Culling"): an animated scene whose structures are rebuilt every frame.
//!
//! Frame `k` is `scenes::builtin::animated(base, k)` (the base scene with moving closed
//! objects) seen from the base scene's default view. Per frame: the frame's full kd-tree is
//! built and the primary rays are traced on it (single rays, rayon over rows), giving one hard
//! shadow ray per lit hit; then [`culling::measure`] builds the shadow structure (our kd-tree
//! and the 4-wide BVH) over (a) every triangle and (b) the triangles in the region the frame's
//! shadow rays sweep ([`culling::shadow_region`], [`culling::cull`]), traces the shadow rays
//! on each, and checks that every answer is the same. A frame's cost is build plus shadow
//! trace, as in the paper, where primary visibility comes from rasterization and the shadow
//! structure is the only one built per frame; the primary build and pass are timed apart and
//! not counted in it.

use std::fmt::Write as _;

use kdtree::{BuildConfig, KdTree};
use scenes::builtin::animated;
use serde::Serialize;
use trace::Error;
use trace::progress::Progress;
use trace::setup::view_camera;
use trace::timing::timed;

use crate::culling::{self, CullingRow};

/// What `dynamic` measures.
#[derive(Clone, Debug, PartialEq)]
pub struct DynamicConfig {
    /// The base scene: a built-in name or a path to an .obj / .obj.gz file.
    pub scene: String,
    /// Frames 0 .. frames of the animation.
    pub frames: u32,
    /// Image size.
    pub size: (u32, u32),
    /// Interleaved timed rounds per frame; medians are reported.
    pub rounds: u32,
}

impl Default for DynamicConfig {
    fn default() -> Self {
        DynamicConfig { scene: "arena".into(), frames: 8, size: (512, 512), rounds: 1 }
    }
}

/// One frame (one JSON object per frame with `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct DynamicRow {
    /// Frame number.
    pub frame: u32,
    /// Ms to build the frame's full kd-tree for the primary rays (not in the frame totals).
    pub primary_build_ms: f64,
    /// Ms to trace the primary rays and make the shadow rays (not in the frame totals).
    pub primary_ms: f64,
    /// The culling measurement of the frame's shadow rays.
    #[serde(flatten)]
    pub culling: CullingRow,
}

/// The report: one row per frame and the totals.
#[derive(Clone, Debug)]
pub struct DynamicReport {
    /// One row per frame.
    pub rows: Vec<DynamicRow>,
    /// The configuration measured.
    pub config: DynamicConfig,
}

impl DynamicReport {
    /// Per structure (`kdtree`, `mbvh`): the sums over frames of frame ms without and with
    /// culling.
    pub fn totals(&self) -> [(f64, f64); 2] {
        let sum = |i: usize, culled: bool| {
            self.rows.iter().map(|r| if culled { r.culling.frame_culled_ms[i] } else { r.culling.frame_ms[i] }).sum()
        };
        [(sum(0, false), sum(0, true)), (sum(1, false), sum(1, true))]
    }

    /// The frames whose culled shadow answers differ from the unculled ones (none, or the
    /// culling is wrong).
    pub fn differing_frames(&self) -> Vec<u32> {
        self.rows.iter().filter(|r| !r.culling.identical).map(|r| r.frame).collect()
    }
}

/// Measures frames `0 .. config.frames` of the animated variant of `config.scene` (module
/// docs).
pub fn run(config: &DynamicConfig, progress: &dyn Progress) -> Result<DynamicReport, Error> {
    let base = scenes::load_scene(&config.scene)?;
    let (w, h) = config.size;
    let build_config = BuildConfig::default();
    let bar = progress.task(&format!("dynamic: {}", base.name), Some(u64::from(config.frames)));
    let mut rows = Vec::new();
    for frame in 0..config.frames {
        let scene = animated(&base, frame);
        scene.mesh.check().map_err(|e| Error::Usage(format!("{} frame {frame}: {e}", scene.name)))?;
        let (camera, view) = view_camera(&scene, None, w, h)?;
        let mesh = &scene.mesh;
        let (primary_build_s, tree) = timed(|| KdTree::build(&mesh.positions, &mesh.triangles, &build_config));
        let tree = tree?;
        let (primary_s, rays) = timed(|| culling::shadow_rays(&scene, &tree, &camera));
        drop(tree);
        let culling = culling::measure(&scene, &view, &rays, config.rounds, &build_config, || {})?;
        rows.push(DynamicRow { frame, primary_build_ms: primary_build_s * 1e3, primary_ms: primary_s * 1e3, culling });
        bar.inc();
    }
    bar.finish();
    Ok(DynamicReport { rows, config: config.clone() })
}

impl std::fmt::Display for DynamicReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (w, h) = self.config.size;
        let threads = self.rows.first().map_or(0, |r| r.culling.threads);
        let name = self.rows.first().map_or("", |r| r.culling.scene.as_str());
        let mut out = String::new();
        let _ = writeln!(
            out,
            "rttest dynamic: {name}, frames 0..{}, {w}x{h}, {threads} threads, default view, every structure rebuilt every frame; {} round(s) per frame (medians). Build with culling includes the cull; frame = build + shadow trace (the primary tree's build and pass are not counted).\n",
            self.config.frames, self.config.rounds
        );
        let _ = writeln!(
            out,
            "| frame | structure | triangles | kept | culled % | shadow rays | build ms | build ms culled | trace ms | trace ms culled | frame ms | frame ms culled | speed-up | identical |"
        );
        let _ = writeln!(out, "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|");
        for r in &self.rows {
            let c = &r.culling;
            for (i, s) in ["kdtree", "mbvh"].iter().enumerate() {
                let (t, k, p, rays, cells) = (c.triangles, c.kept, c.culled_percent, c.shadow_rays, c.timing_cells(i));
                let _ = writeln!(out, "| {} | {s} | {t} | {k} | {p:.1} | {rays} | {cells} |", r.frame);
            }
        }
        let n = self.rows.len().max(1) as f64;
        let culled = self.rows.iter().map(|r| r.culling.culled_percent).sum::<f64>() / n;
        let _ = writeln!(out, "\nTotal over {} frames (mean culled {culled:.1}%):\n", self.rows.len());
        let _ = writeln!(out, "| structure | frame ms | frame ms culled | speed-up |");
        let _ = writeln!(out, "|---|---:|---:|---:|");
        for (s, (full, cut)) in ["kdtree", "mbvh"].iter().zip(self.totals()) {
            let _ = writeln!(out, "| {s} | {full:.1} | {cut:.1} | {:.2} |", full / cut);
        }
        f.write_str(&out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Culled and unculled shadow answers of both structures, both triangle tests, on a few
    /// frames of the animated arena and one of the animated atrium (the larger scene).
    #[test]
    fn culled_shadows_equal_unculled_on_animated_frames() {
        for (name, frames) in [("arena", &[0, 5, 40, 123][..]), ("atrium", &[17][..])] {
            let base = scenes::load_scene(name).unwrap();
            let mut culled_somewhere = false;
            for &frame in frames {
                let scene = animated(&base, frame);
                let mesh = &scene.mesh;
                let camera = scene.default_view().camera(40, 30).unwrap();
                let tree = KdTree::build(&mesh.positions, &mesh.triangles, &BuildConfig::default()).unwrap();
                let rays = culling::shadow_rays(&scene, &tree, &camera);
                assert!(!rays.is_empty());
                let (triangles, kept) = culling::cull(mesh, &culling::shadow_region(&rays));
                culled_somewhere |= kept.len() < mesh.triangles.len();
                for intersector in [kdtree::Intersector::Wald, kdtree::Intersector::Watertight] {
                    let config = BuildConfig { intersector, ..BuildConfig::default() };
                    let full = culling::answers(mesh, &mesh.triangles, &config, &rays);
                    let cut = culling::answers(mesh, &triangles, &config, &rays);
                    for s in 0..2 {
                        if let Some(i) = (0..rays.len()).find(|&i| full[s][i] != cut[s][i]) {
                            panic!("{name} frame {frame} {intersector:?} structure {s}: ray {i} differs");
                        }
                    }
                }
            }
            assert!(culled_somewhere, "{name}: nothing culled, the test would not test culling");
        }
    }

    #[test]
    fn a_run_reports_every_frame_identical_and_totals() {
        let config = DynamicConfig { scene: "arena".into(), frames: 3, size: (32, 24), rounds: 1 };
        let report = run(&config, &trace::progress::Quiet).unwrap();
        assert_eq!(report.rows.iter().map(|r| r.frame).collect::<Vec<_>>(), [0, 1, 2]);
        assert!(report.differing_frames().is_empty());
        let first = &report.rows[0].culling;
        assert_eq!(first.scene, "arena-animated");
        assert!(report.rows.iter().all(|r| r.culling.kept < r.culling.triangles && r.culling.shadow_rays > 0));
        let [(full, cut), _] = report.totals();
        let sum: f64 = report.rows.iter().map(|r| r.culling.frame_ms[0]).sum();
        assert!(full == sum && cut > 0.0);
        let text = report.to_string();
        assert!(text.contains("| 2 | mbvh |") && text.contains("Total over 3 frames"), "{text}");
    }
}
