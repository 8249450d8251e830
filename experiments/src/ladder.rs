//! The width ladder: each kernel at 1, 4, 8 and 16 rays per instruction beside Embree's
//! single rays and 4-, 8- and 16-ray packets, on the same rays (`rttest tables`; issue 28).
//!
//! One [`crate::compare`] run per scene times every rung (interleaved rounds, medians), so a
//! row's widths and Embree's compare within one run. A rung is a registry method capped at a
//! SIMD level (`NAME@LEVEL`, [`trace::Options::simd`]) or a packet width (`NAME@wN`,
//! [`trace::Options::packet_lanes`]): our packet kernels at 4 (SSE 4.1, the thesis's 2x2
//! packets), 8 (AVX2, 4x2 pixels) and 16 lanes (4x4 pixels: one AVX-512 register, or two
//! AVX2 registers on a CPU without AVX-512), MFT with
//! 16 frusta over those packets, Benthin & Wald's lane frusta 4, 8 and 16 frusta per step,
//! the multi-BVHs at node widths 4, 8 and 16 (one ray against W children), and the kd-tree's
//! single rays as every kernel's `W = 1`. Levels above the machine's (or `rttest --simd`'s
//! cap) are not run and show as `-`, as do Embree's rungs in a build without it.

use std::fmt::Write as _;

use kdtree::isa::SimdLevel;
use serde::Serialize;
use trace::progress::Progress;
use trace::{Error, Registry};

use crate::compare::{self, CompareConfig, CompareRow};

/// The widths of the ladder's columns.
pub const WIDTHS: [u32; 4] = [1, 4, 8, 16];

/// A column of `rttest compare` that a ladder row reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Column {
    /// Primary rays.
    Primary,
    /// Hard shadow rays.
    Shadow,
    /// 16-sample soft-shadow rays.
    Soft16,
    /// Ambient-occlusion rays (incoherent, any hit).
    Ao,
    /// Diffuse bounces (incoherent, closest hit).
    Diffuse,
}

impl Column {
    /// The column's name in `rttest compare`.
    pub fn name(self) -> &'static str {
        match self {
            Column::Primary => "primary",
            Column::Shadow => "shadow",
            Column::Soft16 => "soft16",
            Column::Ao => "ao",
            Column::Diffuse => "diffuse",
        }
    }

    fn of(self, row: &CompareRow) -> Option<f64> {
        match self {
            Column::Primary => Some(row.primary_mrays_per_s),
            Column::Shadow => row.shadow_mrays_per_s,
            Column::Soft16 => row.soft16_mrays_per_s,
            Column::Ao => row.ao_mrays_per_s,
            Column::Diffuse => row.diffuse_mrays_per_s,
        }
    }
}

/// One row of the ladder: a technique in one column, and the method traced at each width
/// of [`WIDTHS`] (`None`: no such width).
struct Rungs {
    technique: &'static str,
    column: Column,
    methods: [Option<&'static str>; 4],
}

const fn rungs(technique: &'static str, column: Column, methods: [Option<&'static str>; 4]) -> Rungs {
    Rungs { technique, column, methods }
}

/// The ladder's rows: ours, then Embree's.
const LADDER: &[Rungs] = &[
    rungs(
        "MFT 16x16 (`kd-mft-16`)",
        Column::Primary,
        [Some("mono"), Some("mft-16@sse"), Some("mft-16@w8"), Some("mft-16@w16")],
    ),
    rungs(
        "MFT 16x16, 16 frusta (`kd-mft-x16`)",
        Column::Primary,
        [Some("mono"), Some("mft-x16-16@sse"), Some("mft-x16-16@w8"), Some("mft-x16-16@w16")],
    ),
    rungs(
        "omni-directional packets (`kd-omni-packets`)",
        Column::Primary,
        [Some("mono"), Some("packet@sse"), Some("packet@w8"), Some("packet@w16")],
    ),
    rungs(
        "shadow packets (`kd-packets`)",
        Column::Shadow,
        [Some("mono"), Some("packet@sse"), Some("packet@w8"), Some("packet@w16")],
    ),
    rungs(
        "stratum packets (`kd-stratum-packets`)",
        Column::Soft16,
        [Some("mono"), Some("packet@sse"), Some("packet@w8"), Some("packet@w16")],
    ),
    rungs(
        "lane frusta, W frusta per step (`kd-lane-frusta`)",
        Column::Shadow,
        [Some("mono"), Some("lane-frusta-16@sse"), Some("lane-frusta-16@avx2"), Some("lane-frusta-16@avx512")],
    ),
    rungs(
        "lane frusta, W frusta per step (`kd-lane-frusta`)",
        Column::Soft16,
        [Some("mono"), Some("lane-frusta-16@sse"), Some("lane-frusta-16@avx2"), Some("lane-frusta-16@avx512")],
    ),
    rungs(
        "multi-BVH, W children per ray",
        Column::Primary,
        [Some("mono"), Some("mbvh-4"), Some("mbvh-8"), Some("mbvh-16")],
    ),
    rungs("multi-BVH, W children per ray", Column::Ao, [Some("mono"), Some("mbvh-4"), Some("mbvh-8"), Some("mbvh-16")]),
    rungs(
        "multi-BVH, W children per ray",
        Column::Diffuse,
        [Some("mono"), Some("mbvh-4"), Some("mbvh-8"), Some("mbvh-16")],
    ),
    rungs("8-wide BVH nodes, W-ray packets (hybrid)", Column::Ao, [Some("mbvh-8"), None, None, Some("mbvh-8-p16")]),
    rungs(
        "8-wide BVH nodes, W-ray packets (hybrid)",
        Column::Diffuse,
        [Some("mbvh-8"), None, None, Some("mbvh-8-p16")],
    ),
    rungs("Embree packets", Column::Primary, [Some("embree-1"), Some("embree-4"), Some("embree-8"), Some("embree-16")]),
    rungs("Embree packets", Column::Shadow, [Some("embree-1"), Some("embree-4"), Some("embree-8"), Some("embree-16")]),
    rungs("Embree packets", Column::Soft16, [Some("embree-1"), Some("embree-4"), Some("embree-8"), Some("embree-16")]),
    rungs("Embree packets", Column::Ao, [Some("embree-1"), Some("embree-4"), Some("embree-8"), Some("embree-16")]),
    rungs("Embree packets", Column::Diffuse, [Some("embree-1"), Some("embree-4"), Some("embree-8"), Some("embree-16")]),
    rungs("Embree packets, incoherent flag", Column::Ao, [Some("embree-1"), None, None, Some("embree-16-incoherent")]),
    rungs(
        "Embree packets, incoherent flag",
        Column::Diffuse,
        [Some("embree-1"), None, None, Some("embree-16-incoherent")],
    ),
];

/// Whether `registry` has `method` and this machine may run it: its base name registered
/// (Embree's only in a build with it), its `@LEVEL`, if any, at most `level`, and its
/// packet width `@wN`, if any, one that `level` runs (8 and 16 lanes from `avx2` on).
fn runnable(registry: &Registry, method: &str, level: SimdLevel) -> bool {
    let (base, at) = match method.rsplit_once('@') {
        Some((base, at)) => (base, Some(at)),
        None => (method, None),
    };
    let fits = |at: &str| match at.strip_prefix('w').and_then(|n| n.parse::<usize>().ok()) {
        Some(lanes) => packets::Width::at_level(lanes, level).is_some(),
        None => SimdLevel::from_name(at).is_some_and(|at| at <= level),
    };
    at.is_none_or(fits) && registry.names(&[16]).iter().any(|n| n == base)
}

/// The methods the ladder runs on this machine, each once, `mono` first.
pub fn methods(registry: &Registry, level: SimdLevel) -> Vec<String> {
    let mut out: Vec<String> = vec!["mono".into()];
    for m in LADDER.iter().flat_map(|r| r.methods.iter().flatten()) {
        if runnable(registry, m, level) && !out.iter().any(|o| o == m) {
            out.push((*m).to_string());
        }
    }
    out
}

/// What the ladder measures.
#[derive(Clone, Debug, PartialEq)]
pub struct LadderConfig {
    /// Scenes (built-in names or OBJ paths).
    pub scenes: Vec<String>,
    /// Image size.
    pub size: (u32, u32),
    /// Interleaved rounds per scene (medians reported).
    pub rounds: u32,
}

/// One measured cell: a technique's speed in one column at one width of one scene.
#[derive(Clone, Debug, Serialize)]
pub struct Rung {
    /// Scene name.
    pub scene: String,
    /// The technique (the row's name).
    pub technique: &'static str,
    /// The compare column.
    pub column: Column,
    /// Rays (or, for the multi-BVHs, children) per instruction.
    pub width: u32,
    /// The method traced (`mft-16@avx2`).
    pub method: &'static str,
    /// Mrays/s, median of the rounds.
    pub mrays_per_s: f64,
}

/// The ladder of every scene.
#[derive(Clone, Debug, Serialize)]
pub struct LadderReport {
    /// The measured cells.
    pub rungs: Vec<Rung>,
    /// The SIMD level the run allowed.
    pub level: String,
    /// Rounds per scene.
    pub rounds: u32,
    /// Image size.
    pub size: (u32, u32),
    /// The Embree device line, or why Embree is missing.
    pub embree_note: Option<String>,
}

/// Runs the ladder's methods through one `compare` run per scene (16x16 tiles, every
/// column) and reads each rung from it.
pub fn run(config: &LadderConfig, progress: &dyn Progress) -> Result<LadderReport, Error> {
    let registry = baselines::registry();
    let level = SimdLevel::active();
    let methods = methods(&registry, level);
    let mut cells = Vec::new();
    let mut embree_note = None;
    for scene in &config.scenes {
        let report = compare::run(
            &CompareConfig {
                scene: scene.clone(),
                size: config.size,
                rounds: config.rounds,
                build_rounds: 1,
                methods: methods.clone(),
                tiles: vec![16],
                ..CompareConfig::default()
            },
            progress,
        )?;
        embree_note = embree_note.or(report.embree_note.clone());
        for rungs in LADDER {
            for (&width, method) in WIDTHS.iter().zip(rungs.methods) {
                let Some(method) = method else { continue };
                let Some(row) = report.rows.iter().find(|r| r.method == method) else { continue };
                let Some(mrays_per_s) = rungs.column.of(row) else { continue };
                cells.push(Rung {
                    scene: row.scene.clone(),
                    technique: rungs.technique,
                    column: rungs.column,
                    width,
                    method,
                    mrays_per_s,
                });
            }
        }
    }
    Ok(LadderReport { rungs: cells, level: level.to_string(), rounds: config.rounds, size: config.size, embree_note })
}

impl LadderReport {
    /// The cells as CSV: `scene,technique,column,width,method,mrays_per_s`.
    pub fn csv(&self) -> String {
        let mut out = String::from("scene,technique,column,width,method,mrays_per_s\n");
        for r in &self.rungs {
            let _ = writeln!(
                out,
                "{},\"{}\",{},{},{},{:.3}",
                r.scene,
                r.technique,
                r.column.name(),
                r.width,
                r.method,
                r.mrays_per_s
            );
        }
        out
    }

    fn cell(&self, scene: &str, rungs: &Rungs, width: u32) -> Option<f64> {
        self.rungs
            .iter()
            .find(|r| {
                r.scene == scene && r.technique == rungs.technique && r.column == rungs.column && r.width == width
            })
            .map(|r| r.mrays_per_s)
    }

    fn scenes(&self) -> Vec<&str> {
        let mut out: Vec<&str> = Vec::new();
        for r in &self.rungs {
            if !out.contains(&r.scene.as_str()) {
                out.push(&r.scene);
            }
        }
        out
    }
}

impl std::fmt::Display for LadderReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut text = String::new();
        let _ = writeln!(
            text,
            "\n## The width ladder: Mrays/s at 1, 4, 8 and 16 rays per instruction\n\n{}x{}, 16x16 tiles, \
             medians of {} interleaved rounds (one `rttest compare` run per scene), SIMD levels up to {}. \
             W = 1 is the single-ray kernel (`mono`, `embree-1`); the multi-BVH rows' W is the node's \
             children per ray; `-`: not run on this machine or build. In brackets: the speed-up over W = 4.",
            self.size.0, self.size.1, self.rounds, self.level
        );
        if let Some(note) = &self.embree_note {
            let _ = writeln!(text, "\n{note}");
        }
        for scene in self.scenes() {
            let _ = writeln!(
                text,
                "\n### {scene}\n\n| technique | column | W = 1 | W = 4 | W = 8 | W = 16 |\n|---|---|---:|---:|---:|---:|"
            );
            for rungs in LADDER {
                let cells: Vec<Option<f64>> = WIDTHS.iter().map(|&w| self.cell(scene, rungs, w)).collect();
                if cells.iter().all(Option::is_none) {
                    continue;
                }
                let four = cells[1];
                let shown: Vec<String> = cells
                    .iter()
                    .enumerate()
                    .map(|(i, c)| match (c, four) {
                        (None, _) => "-".into(),
                        (Some(v), Some(f)) if i >= 2 && f > 0.0 => format!("{v:.2} ({:.2})", v / f),
                        (Some(v), _) => format!("{v:.2}"),
                    })
                    .collect();
                let _ = writeln!(text, "| {} | {} | {} |", rungs.technique, rungs.column.name(), shown.join(" | "));
            }
        }
        f.write_str(&text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every rung names a method the registry knows, at a level the registry parses.
    #[test]
    fn every_rung_is_a_registry_method() {
        let registry = baselines::registry();
        let known = registry.names(&[16]);
        for m in LADDER.iter().flat_map(|r| r.methods.iter().flatten()) {
            let base = m.rsplit_once('@').map_or(*m, |(b, _)| b);
            if base.starts_with("embree") {
                continue;
            }
            assert!(known.iter().any(|k| k == base), "{m} is not registered");
            if let Some((_, level)) = m.rsplit_once('@') {
                let width = level.strip_prefix('w').and_then(|n| n.parse::<usize>().ok());
                assert!(SimdLevel::from_name(level).is_some() || width.is_some(), "{m}: unknown level");
                if runnable(&registry, m, SimdLevel::detect()) {
                    registry.select(m, trace::Options::default()).unwrap_or_else(|e| panic!("{m}: {e}"));
                }
            }
        }
    }

    /// Levels above the cap are left out; `mono` comes first, each method once.
    #[test]
    fn methods_follow_the_level() {
        let registry = baselines::registry();
        let sse = methods(&registry, SimdLevel::Sse41);
        assert_eq!(sse[0], "mono");
        assert!(sse.iter().any(|m| m == "mft-16@sse"));
        assert!(!sse.iter().any(|m| ["@avx2", "@avx512", "@w8", "@w16"].iter().any(|s| m.ends_with(s))));
        let avx2 = methods(&registry, SimdLevel::Avx2);
        assert!(avx2.iter().any(|m| m == "packet@w8") && avx2.iter().any(|m| m == "packet@w16"));
        assert!(!avx2.iter().any(|m| m.ends_with("@avx512")));
        let all = methods(&registry, SimdLevel::Avx512);
        assert!(all.iter().any(|m| m == "packet@w16"));
        let mut unique = all.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), all.len());
    }

    /// A small run fills every rung of ours that the machine can run, and prints it.
    #[test]
    fn a_small_ladder_runs() {
        let config = LadderConfig { scenes: vec!["cube".into()], size: (32, 32), rounds: 1 };
        let report = run(&config, &trace::progress::Quiet).unwrap();
        let level = SimdLevel::active();
        let ours = LADDER.iter().filter(|r| !r.technique.starts_with("Embree"));
        for rungs in ours {
            for (&w, m) in WIDTHS.iter().zip(rungs.methods) {
                let Some(m) = m else { continue };
                let want = runnable(&baselines::registry(), m, level);
                let got = report.cell("cube", rungs, w).is_some();
                assert_eq!(got, want, "{} {} W={w}", rungs.technique, rungs.column.name());
            }
        }
        let text = report.to_string();
        assert!(text.contains("### cube") && text.contains("| MFT 16x16"), "{text}");
    }
}
