//! The SAH terms chosen by measurement: one table of tree shape against single-ray and MFT
//! speed for a set of cost models (thesis 2.2.1 and 3.2.1).
//!
//! Each [`Candidate`] is a cost model from the literature or a step away from the thesis's:
//!
//! - `thesis`: `C_trav = 1`, `C_isect = 5`, no empty-space bonus (thesis 3.2.1);
//! - `wald-havran`: `C_trav = 15`, `C_isect = 20` and `lambda = 0.8` for a split with an
//!   empty side (Wald & Havran 2006, section 4), i.e. an empty bonus of 0.2;
//! - `pbrt`: `C_trav = 1`, `C_isect = 80`, empty bonus 0.5 (pbrt-v3 `KdTreeAccel` defaults);
//! - the thesis's model with `C_isect` moved to 2, 3, 10 and 20, with empty bonuses of 0.2
//!   and 0.5, with the depth limit moved 4 levels either way, and with both bonuses and 4
//!   more levels (empty-space cuts spend depth: with a bonus, leaves reach the depth limit
//!   sooner);
//! - `wald-havran` with the SIMD leaf cost (`leaf4`, `leaf8`: a leaf and each side of a
//!   split priced as `ceil(n / W)` group tests, [`BuildConfig::leaf_width`]), with Mitsuba's
//!   bad refines (`bad3`: 3 per path, [`BuildConfig::max_bad_refines`]) and their collapse
//!   (`collapse`, [`BuildConfig::collapse`]), and combinations (`wh-leaf4-isect2`,
//!   `wh-leaf4-isect3`: the group test priced at 2 and 3 traversal steps instead of 4/3).
//!
//! Every candidate's tree is built over the same scene; then, in interleaved rounds (every
//! candidate once per round, medians reported), its primary rays are traced as single rays
//! (`mono`) and by MFT (`mft-16`), and its hard-shadow rays as single rays. One extra counted
//! pass gives N (traversal steps per ray) and I (triangle tests per ray). The table reports
//! them beside the tree's shape (references and bytes per triangle, SAH cost, depth) and its
//! build time, so the default can be picked from one table (`docs/results/sah-terms.md`).

use std::fmt;

use kdtree::{BuildConfig, Counts, Hit, KdTree};
use scenes::Scene;
use serde::Serialize;
use trace::frame::{TileLayout, View};
use trace::progress::Progress;
use trace::registry::{Options, Structures};
use trace::report::TreeSummary;
use trace::setup::view_camera;
use trace::timing::{median, mrays_per_s, timed};

use crate::Error;

/// One SAH cost model.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Candidate {
    /// A short name for the table.
    pub name: String,
    /// `C_trav`.
    pub c_trav: f32,
    /// `C_isect`.
    pub c_isect: f32,
    /// Fraction taken off a split with an empty side.
    pub empty_bonus: f32,
    /// Levels added to the default depth limit `8 + log2 N` (negative: fewer).
    pub depth_offset: i32,
    /// The leaf's SIMD group width in the SAH ([`BuildConfig::leaf_width`]; 1: per triangle).
    pub leaf_width: u32,
    /// Bad refines per path ([`BuildConfig::max_bad_refines`]; 0: off).
    pub bad_refines: u32,
    /// Collapse the costlier subtrees ([`BuildConfig::collapse`]).
    pub collapse: bool,
}

impl Candidate {
    fn new(name: &str, c_trav: f32, c_isect: f32, empty_bonus: f32, depth_offset: i32) -> Candidate {
        Candidate {
            name: name.to_string(),
            c_trav,
            c_isect,
            empty_bonus,
            depth_offset,
            leaf_width: 1,
            bad_refines: 0,
            collapse: false,
        }
    }

    /// This candidate with the leaf width `w`, `bad` bad refines and `collapse`.
    fn leaf(self, w: u32, bad: u32, collapse: bool) -> Candidate {
        Candidate { leaf_width: w, bad_refines: bad, collapse, ..self }
    }

    /// The build configuration of this candidate for a scene of `triangles` triangles.
    pub fn config(&self, triangles: usize) -> BuildConfig {
        let base = BuildConfig {
            c_trav: self.c_trav,
            c_isect: self.c_isect,
            empty_bonus: self.empty_bonus,
            leaf_width: self.leaf_width,
            max_bad_refines: self.bad_refines,
            collapse: self.collapse,
            ..BuildConfig::default()
        };
        let depth = base.depth_limit(triangles) as i64 + i64::from(self.depth_offset);
        BuildConfig {
            max_depth: (self.depth_offset != 0).then_some(depth.clamp(1, kdtree::MAX_DEPTH as i64) as u32),
            ..base
        }
    }
}

/// The candidates of the default sweep (see the module documentation).
pub fn default_candidates() -> Vec<Candidate> {
    vec![
        Candidate::new("thesis", 1.0, 5.0, 0.0, 0),
        Candidate::new("wald-havran", 15.0, 20.0, 0.2, 0),
        Candidate::new("pbrt", 1.0, 80.0, 0.5, 0),
        Candidate::new("isect-2", 1.0, 2.0, 0.0, 0),
        Candidate::new("isect-3", 1.0, 3.0, 0.0, 0),
        Candidate::new("isect-10", 1.0, 10.0, 0.0, 0),
        Candidate::new("isect-20", 1.0, 20.0, 0.0, 0),
        Candidate::new("bonus-0.2", 1.0, 5.0, 0.2, 0),
        Candidate::new("bonus-0.5", 1.0, 5.0, 0.5, 0),
        Candidate::new("depth-4", 1.0, 5.0, 0.0, -4),
        Candidate::new("depth+4", 1.0, 5.0, 0.0, 4),
        Candidate::new("bonus-0.2,depth+4", 1.0, 5.0, 0.2, 4),
        Candidate::new("bonus-0.5,depth+4", 1.0, 5.0, 0.5, 4),
        Candidate::new("wh-leaf4", 15.0, 20.0, 0.2, 0).leaf(4, 0, false),
        Candidate::new("wh-leaf8", 15.0, 20.0, 0.2, 0).leaf(8, 0, false),
        Candidate::new("wh-bad3", 15.0, 20.0, 0.2, 0).leaf(1, 3, false),
        Candidate::new("wh-bad3-collapse", 15.0, 20.0, 0.2, 0).leaf(1, 3, true),
        Candidate::new("wh-leaf4-bad3", 15.0, 20.0, 0.2, 0).leaf(4, 3, false),
        Candidate::new("wh-leaf4-bad3-collapse", 15.0, 20.0, 0.2, 0).leaf(4, 3, true),
        Candidate::new("wh-leaf4-isect2", 15.0, 30.0, 0.2, 0).leaf(4, 0, false),
        Candidate::new("wh-leaf8-bad3-collapse", 15.0, 20.0, 0.2, 0).leaf(8, 3, true),
        Candidate::new("wh-leaf4-isect3", 15.0, 45.0, 0.2, 0).leaf(4, 0, false),
        Candidate::new("wh-leaf4-isect2-bad3-collapse", 15.0, 30.0, 0.2, 0).leaf(4, 3, true),
    ]
}

/// What to sweep.
#[derive(Clone, Debug)]
pub struct SweepConfig {
    /// Scenes (built-in names or paths).
    pub scenes: Vec<String>,
    /// The cost models.
    pub candidates: Vec<Candidate>,
    /// Image side: `size x size` primary rays from each scene's default view.
    pub size: u32,
    /// Interleaved timing rounds (medians reported).
    pub rounds: u32,
}

/// One candidate on one scene.
#[derive(Clone, Debug, Serialize)]
pub struct SweepRow {
    /// The scene's name.
    pub scene: String,
    /// The cost model.
    pub candidate: Candidate,
    /// The depth limit used.
    pub max_depth: u32,
    /// Build time in milliseconds (one build, the thread pool's threads).
    pub build_ms: f64,
    /// The tree's statistics (references and bytes per triangle, depth, ...; its `sah_cost`
    /// is under the candidate's own model).
    pub tree: TreeSummary,
    /// The tree's SAH cost under the thesis's model (`C_trav = 1`, `C_isect = 5`), the same
    /// for every candidate.
    pub sah_thesis: f64,
    /// Traversal steps per primary ray (single rays).
    pub steps_per_ray: f64,
    /// Triangle tests per primary ray (single rays).
    pub tests_per_ray: f64,
    /// Single-ray primary Mrays/s (median of the rounds).
    pub mono_mrays_per_s: f64,
    /// Single-ray hard-shadow Mrays/s (median of the rounds).
    pub shadow_mrays_per_s: f64,
    /// MFT (16 x 16 tiles) primary Mrays/s (median of the rounds).
    pub mft_mrays_per_s: f64,
}

/// The sweep's rows, scene by scene in candidate order.
#[derive(Clone, Debug, Serialize)]
pub struct SweepReport {
    /// Image side.
    pub size: u32,
    /// Worker threads.
    pub threads: usize,
    /// Rounds.
    pub rounds: u32,
    /// The rows.
    pub rows: Vec<SweepRow>,
}

/// One candidate's tree and buffers during the rounds.
struct Built {
    tree: KdTree,
    build_ms: f64,
    hits: Vec<Option<Hit>>,
    occluded: Vec<bool>,
    mono: Vec<f64>,
    shadow: Vec<f64>,
    mft: Vec<f64>,
    shadow_rays: u64,
    counts: Counts,
}

/// Runs the sweep: every candidate on every scene.
pub fn run(config: &SweepConfig, progress: &dyn Progress) -> Result<SweepReport, Error> {
    if config.candidates.is_empty() {
        return Err(Error::Usage("the SAH sweep needs at least one candidate".into()));
    }
    let mut rows = Vec::new();
    for spec in &config.scenes {
        let scene = scenes::load_scene(spec)?;
        rows.extend(sweep_scene(&scene, config, progress)?);
    }
    Ok(SweepReport { size: config.size, threads: rayon::current_num_threads(), rounds: config.rounds, rows })
}

fn sweep_scene(scene: &Scene, config: &SweepConfig, progress: &dyn Progress) -> Result<Vec<SweepRow>, Error> {
    let (camera, _) = view_camera(scene, None, config.size, config.size)?;
    let n = scene.mesh.triangles.len();
    let registry = baselines::registry();
    let mono = registry.select("mono", Options::default())?;
    let mft = registry.select("mft-16", Options::default())?;
    let layout = TileLayout::new(camera.width, camera.height, Options::default().tile);
    let surfaces = trace::shade::surfaces(&scene.mesh);
    let view = View { layout: &layout, scene, surfaces: &surfaces, camera: &camera };

    let builds = progress.task(&format!("sah sweep: {} builds", scene.name), Some(config.candidates.len() as u64));
    let mut built = Vec::new();
    // A warm-up build, so that the first candidate's time does not include the page faults
    // of the process's first large allocations.
    KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &config.candidates[0].config(n))?;
    for candidate in &config.candidates {
        let build_config = candidate.config(n);
        let (secs, tree) = timed(|| KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &build_config));
        let tree = tree?;
        let pixels = layout.pixel_count();
        built.push(Built {
            tree,
            build_ms: secs * 1e3,
            hits: vec![None; pixels],
            occluded: vec![false; pixels],
            mono: Vec::new(),
            shadow: Vec::new(),
            mft: Vec::new(),
            shadow_rays: 0,
            counts: Counts::default(),
        });
        builds.inc();
    }
    builds.finish();

    // One counted single-ray pass per tree: N and I, and the hits the shadow rays start from.
    for b in &mut built {
        let structures = Structures::new(&b.tree);
        let bound = registry.bind(&mono, &structures)?;
        bound.tracer.primary(&layout, &camera, &mut b.hits, Some(&mut b.counts));
    }

    let bar = progress.task(&format!("sah sweep: {}", scene.name), Some(u64::from(config.rounds) * built.len() as u64));
    let mut scratch_hits = vec![None; layout.pixel_count()];
    for _ in 0..config.rounds {
        for b in &mut built {
            let structures = Structures::new(&b.tree);
            let single = registry.bind(&mono, &structures)?;
            let frusta = registry.bind(&mft, &structures)?;
            b.mono.push(timed(|| single.tracer.primary(&layout, &camera, &mut scratch_hits, None)).0);
            let (secs, (rays, _)) = timed(|| single.tracer.shadow(&view, &b.hits, &mut b.occluded, None));
            b.shadow.push(secs);
            b.shadow_rays = rays;
            b.mft.push(timed(|| frusta.tracer.primary(&layout, &camera, &mut scratch_hits, None)).0);
            bar.inc();
        }
    }
    bar.finish();

    let rays = layout.pixel_count() as u64;
    Ok(config
        .candidates
        .iter()
        .zip(built)
        .map(|(candidate, b)| SweepRow {
            scene: scene.name.clone(),
            candidate: candidate.clone(),
            max_depth: b.tree.config().depth_limit(n),
            build_ms: b.build_ms,
            tree: TreeSummary::of(&b.tree),
            sah_thesis: b.tree.sah_cost(1.0, 5.0),
            steps_per_ray: b.counts.nodes as f64 / rays as f64,
            tests_per_ray: b.counts.tests as f64 / rays as f64,
            mono_mrays_per_s: mrays_per_s(rays, median(&b.mono)),
            shadow_mrays_per_s: mrays_per_s(b.shadow_rays, median(&b.shadow)),
            mft_mrays_per_s: mrays_per_s(rays, median(&b.mft)),
        })
        .collect())
}

impl fmt::Display for SweepReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "SAH terms: {0}x{0} primary rays, {1} threads, medians of {2} interleaved rounds",
            self.size, self.threads, self.rounds
        )?;
        let mut scene = None;
        for r in &self.rows {
            if scene != Some(&r.scene) {
                scene = Some(&r.scene);
                let baseline = self.rows.iter().find(|b| b.scene == r.scene).expect("the row itself");
                writeln!(f)?;
                writeln!(f, "### {} (ratios against `{}`)", r.scene, baseline.candidate.name)?;
                writeln!(f)?;
                writeln!(
                    f,
                    "| candidate | C_trav:C_isect | bonus | W, bad, collapse | depth | build ms | refs/tri | bytes/tri | SAH (1:5) | N | I | mono Mrays/s | shadow Mrays/s | MFT Mrays/s |"
                )?;
                writeln!(f, "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")?;
            }
            let base = self.rows.iter().find(|b| b.scene == r.scene).expect("the row itself");
            let ratio = |x: f64, b: f64| if b > 0.0 { x / b } else { 0.0 };
            writeln!(
                f,
                "| {} | {}:{} | {} | {}, {}, {} | {} | {:.0} | {:.2} | {:.0} | {:.1} | {:.1} | {:.2} | {:.2} ({:.2}) | {:.2} ({:.2}) | {:.2} ({:.2}) |",
                r.candidate.name,
                r.candidate.c_trav,
                r.candidate.c_isect,
                r.candidate.empty_bonus,
                r.candidate.leaf_width,
                r.candidate.bad_refines,
                if r.candidate.collapse { "on" } else { "off" },
                r.max_depth,
                r.build_ms,
                r.tree.refs_per_triangle,
                r.tree.bytes_per_triangle,
                r.sah_thesis,
                r.steps_per_ray,
                r.tests_per_ray,
                r.mono_mrays_per_s,
                ratio(r.mono_mrays_per_s, base.mono_mrays_per_s),
                r.shadow_mrays_per_s,
                ratio(r.shadow_mrays_per_s, base.shadow_mrays_per_s),
                r.mft_mrays_per_s,
                ratio(r.mft_mrays_per_s, base.mft_mrays_per_s),
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use trace::progress::Quiet;

    #[test]
    fn candidates_build_different_trees_and_report_their_counts() {
        let candidates = vec![
            Candidate::new("thesis", 1.0, 5.0, 0.0, 0),
            Candidate::new("isect-20", 1.0, 20.0, 0.0, 0),
            Candidate::new("pbrt", 1.0, 80.0, 0.5, 0),
            Candidate::new("shallow", 1.0, 5.0, 0.0, -6),
            Candidate::new("wald-havran", 15.0, 20.0, 0.2, 0),
            Candidate::new("wh-leaf4", 15.0, 20.0, 0.2, 0).leaf(4, 0, false),
        ];
        let config = SweepConfig { scenes: vec!["atrium".into()], candidates, size: 32, rounds: 1 };
        let report = run(&config, &Quiet).unwrap();
        assert_eq!(report.rows.len(), 6);
        // Leaves priced by groups of 4 hold more triangles: fewer references, fewer steps.
        let (wh, leaf4) = (&report.rows[4], &report.rows[5]);
        assert!(leaf4.tree.refs_per_triangle < wh.tree.refs_per_triangle, "{leaf4:?} {wh:?}");
        assert!(leaf4.steps_per_ray < wh.steps_per_ray, "{leaf4:?} {wh:?}");
        let [thesis, isect20, pbrt, shallow] = [&report.rows[0], &report.rows[1], &report.rows[2], &report.rows[3]];
        // A costlier triangle test splits more: more references per triangle.
        assert!(isect20.tree.refs_per_triangle > thesis.tree.refs_per_triangle);
        assert_ne!(pbrt.tree.nodes, thesis.tree.nodes);
        // The SAH column is the thesis's model for every row, which the thesis's own tree
        // was built to minimise: another candidate's tree does not beat it by much.
        assert!(thesis.sah_thesis <= isect20.sah_thesis * 1.05, "{} {}", thesis.sah_thesis, isect20.sah_thesis);
        // The depth offset is applied.
        assert_eq!(shallow.max_depth + 6, thesis.max_depth);
        assert!(shallow.tree.depth <= u64::from(shallow.max_depth));
        for r in &report.rows {
            assert!(r.steps_per_ray > 1.0 && r.tests_per_ray > 0.0, "{r:?}");
            assert!(r.mono_mrays_per_s > 0.0 && r.shadow_mrays_per_s > 0.0 && r.mft_mrays_per_s > 0.0, "{r:?}");
        }
        let text = report.to_string();
        assert!(text.contains("| pbrt | 1:80 | 0.5 | 1, 0, off |"), "{text}");
        assert!(text.contains("| wh-leaf4 | 15:20 | 0.2 | 4, 0, off |"), "{text}");
    }

    #[test]
    fn an_empty_sweep_is_a_usage_error() {
        let config = SweepConfig { scenes: vec!["atrium".into()], candidates: Vec::new(), size: 8, rounds: 1 };
        assert!(matches!(run(&config, &Quiet), Err(Error::Usage(_))));
    }
}
