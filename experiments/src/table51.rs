//! Table 5.1 of the thesis (chapter 5, "Performance"): frame rates of single-sample hard
//! shadows, edge widths (the thesis's, and our silhouette and convolved widths), 4 and 32
//! samples (and 32 samples as shadow packets), on Sponza (when the shared scenes are
//! present) and on `atrium`, beside the thesis's Sponza figures (15.0, 12.0, 4.26, 1.42 fps).
//!
//! A frame is primary rays, visibility and shading ([`crate::shadows::ShadowSetup::frame`]),
//! lit by the scene's rectangular area light; the four methods' frames are interleaved and
//! each row gives the median. The thesis's 32-sample row used cone frusta; ours traces single
//! rays, and its machine, resolution handling and SIMD width differ: compare ratios, not fps.

use std::fmt::Write as _;

use edgewidth::AreaLight;
use kdtree::{BuildConfig, KdTree};

use crate::Error;
use crate::shadows::{ShadowMethod, ShadowSetup, median};

/// The rows of Table 5.1 with the thesis's Sponza frame rates: its four, our two variants of
/// the edge widths after the thesis's (silhouette widths, `edgewidth::silhouette`, and
/// convolved widths, `edgewidth::convolution`: both halves of the penumbra, no leaks), and
/// the 32 samples traced per stratum as packets of neighbouring pixels' rays at the SIMD
/// level's width (16 rays on AVX-512; the same image; the thesis's own 32-sample row used cone
/// frusta); the thesis has no figure for our three.
pub const ROWS: [(ShadowMethod, &str, Option<f64>); 7] = [
    (ShadowMethod::Hard, "Single Sample", Some(15.0)),
    (ShadowMethod::EdgeWidth, "Edge Width", Some(12.0)),
    (ShadowMethod::Silhouette, "Edge Width, silhouettes (ours)", None),
    (ShadowMethod::Convolution, "Edge Width, convolved (ours)", None),
    (ShadowMethod::Sampled(4), "4 Sample", Some(4.26)),
    (ShadowMethod::Sampled(32), "32 Sample", Some(1.42)),
    (ShadowMethod::SampledPackets(32), "32 Sample, packets", None),
];

/// Measures Table 5.1 on `atrium` and Sponza (if present) at `size`, `frames` frames per row
/// (median), with the ray-triangle test of `config`. Returns markdown, or CSV rows.
///
/// `frames` must be at least 1 (0 is a usage error).
pub fn table51(size: (u32, u32), frames: u32, config: &BuildConfig, csv: bool) -> Result<String, Error> {
    if frames == 0 {
        return Err(Error::Usage("Table 5.1 needs at least one frame".into()));
    }
    let mut specs = vec!["atrium".to_string()];
    if let Some(p) = trace::setup::sponza_path() {
        specs.push(p.display().to_string());
    }
    let mut out = String::new();
    if csv {
        out += "table,scene,shadows,fps,ms_per_frame,ratio_to_hard,thesis_fps\n";
    } else {
        let _ = writeln!(
            out,
            "\n### Table 5.1: soft shadow performance ({}x{}, median of {frames} frames)\n",
            size.0, size.1
        );
    }
    for spec in specs {
        let scene = scenes::load_scene(&spec)?;
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, config)?;
        let camera = scene
            .default_view()
            .camera(size.0, size.1)
            .ok_or_else(|| Error::Usage(format!("{}: degenerate default view", scene.name)))?;
        let setup = ShadowSetup::new(&scene, &tree, camera, AreaLight::Rect(scene.area_light))?;
        let mut times = vec![Vec::new(); ROWS.len()];
        for _ in 0..frames {
            for (i, (m, _, _)) in ROWS.iter().enumerate() {
                times[i].push(setup.frame(*m).secs);
            }
        }
        let medians: Vec<f64> = times.iter().map(|t| median(t)).collect();
        let sponza = scene.name.starts_with("sponza");
        if !csv {
            let _ = writeln!(out, "**{}** ({} triangles)\n", scene.name, scene.mesh.triangle_count());
            let _ =
                writeln!(out, "| Shadow type | ours fps | ms/frame | / hard | thesis fps (Sponza) | thesis / hard |");
            let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|");
        }
        for ((_, label, thesis), &secs) in ROWS.iter().zip(&medians) {
            let ratio = secs / medians[0];
            let thesis_fps = thesis.map_or(String::new(), |t| t.to_string());
            let thesis_ratio = match (ROWS[0].2, thesis) {
                (Some(hard), Some(t)) => format!("{:.2}x", hard / t),
                _ => String::new(),
            };
            if csv {
                let _ = writeln!(
                    out,
                    "5.1,{},{label},{:.3},{:.3},{ratio:.3},{}",
                    scene.name,
                    1.0 / secs,
                    secs * 1e3,
                    if sponza { thesis_fps } else { String::new() }
                );
            } else {
                let _ = writeln!(
                    out,
                    "| {label} | {:.2} | {:.1} | {ratio:.2}x | {thesis_fps} | {thesis_ratio} |",
                    1.0 / secs,
                    secs * 1e3
                );
            }
        }
        if !csv {
            out += "\n";
        }
    }
    Ok(out)
}
