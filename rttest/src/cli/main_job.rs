//! `rttest` without a command: the thesis at its best on the default scene.
//!
//! Builds the atrium, renders its default view at 512x512 with the fastest exact method of
//! the thesis (MFT on 8x8 tiles, 4.1.5) and 16-sample soft shadows (Table 4.6) into
//! `atrium.png`, traces the same frame with single rays for comparison, and prints a short
//! side-by-side (Mrays/s, N and I per 2x2 packet), the file written and the commands to try
//! next. With `--json`: the two render reports, one JSON object each.

use std::fmt::Write as _;

use trace::Error;
use trace::report::RenderReport;

use super::{GlobalArgs, SceneArgs, emit, load_and_build, print_text, render, render_args};

/// The method the main job shows off.
pub const BEST: &str = "mft-8";

/// `rttest` alone.
pub fn run(global: &GlobalArgs) -> Result<(), Error> {
    let best_args = render_args(&["--method", BEST, "--shadows", "soft16", "--counters"])?;
    let built = load_and_build(global, &best_args.scene, 1)?;
    let best = render(global, &built, &best_args, true)?;
    // Single rays on the same frame, for the side-by-side; traced only, no image.
    let mono_args = render_args(&["--method", "mono", "--shadows", "soft16", "--counters"])?;
    let mono = render(global, &built, &mono_args, false)?;
    if global.json {
        emit(global, &mono)?;
        return emit(global, &best);
    }
    print_text(&summary(&built.report, &best_args.scene, &mono, &best))
}

/// The side-by-side of single rays and the best method, and what to try next.
fn summary(build: &trace::report::BuildReport, scene: &SceneArgs, mono: &RenderReport, best: &RenderReport) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "rttest: {} ({} triangles), kd-tree built in {:.0} ms on {} threads; {}x{}, 16-sample soft shadows (light radius 1 Sponza unit).\n",
        scene.scene, build.tree.triangles, build.build_ms, best.threads, best.width, best.height
    );
    let _ = writeln!(out, "| method | primary Mrays/s | soft16 Mrays/s | N | I |");
    let _ = writeln!(out, "|---|---:|---:|---:|---:|");
    for (label, r) in [("single rays (mono)", mono), ("MFT 8x8 (mft-8)", best)] {
        let (n, i) = r.traversal.as_ref().map_or((f64::NAN, f64::NAN), |t| t.per_packet());
        let _ =
            writeln!(out, "| {label} | {:.2} | {:.2} | {n:.2} | {i:.2} |", r.primary_mrays_per_s, r.shadow_mrays_per_s);
    }
    let _ = writeln!(
        out,
        "\nN = traversal steps, I = ray-triangle tests, per 2x2 packet of primary rays (single rays: per 4 rays)."
    );
    let _ = writeln!(out, "Wrote {}.\n", best.out.as_deref().unwrap_or("nothing"));
    let _ = writeln!(out, "Next:");
    for (what, cmd) in [
        (
            "another method, tile and view",
            "cargo run --release -- render --method mft-cone-16 --view gallery --counters",
        ),
        ("the thesis's Tables 4.1-4.6, 5.1, 6.2", "cargo run --release -- tables --scene atrium"),
        ("ours against Embree", "cargo run --release -p rttest --features embree -- compare"),
        ("edge-width soft shadows", "cargo run --release -- shadows --scene atrium"),
    ] {
        let _ = writeln!(out, "  {cmd:<90} # {what}");
    }
    out
}
