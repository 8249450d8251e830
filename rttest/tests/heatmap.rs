//! End-to-end tests of the cost images: `rttest render --aov nodes|leaves|isects|culled` and
//! `--compare-methods`.

use std::path::Path;

mod common;

use common::rttest;

/// Width and height from a PNG's IHDR chunk.
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).expect("PNG written");
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "{} is not a PNG", path.display());
    let be = |i: usize| u32::from_be_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    (be(16), be(20))
}

/// A cost image is written as PFM (exact per-ray values) and as a heat-map PNG with a legend.
#[test]
fn a_cost_aov_writes_pfm_and_png() {
    let dir = common::scratch("heatmap", "one");
    let out = rttest(&dir, &["render", "--scene", "cube", "--size", "40x24", "--aov", "isects", "--method", "mft-8"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let image = scenes::ScalarImage::load_pfm(&dir.join("cube-mft-8-isects.pfm")).expect("PFM");
    assert_eq!((image.width, image.height), (40, 24));
    assert!(image.values.iter().any(|&v| v > 0.0) && image.values.iter().all(|v| v.is_finite() && *v >= 0.0));
    let (w, h) = png_size(&dir.join("cube-mft-8-isects.png"));
    assert!(w > 40 && h > 24, "the PNG has room for the label and the legend: {w}x{h}");
}

/// `--compare-methods`: one PFM per method whose pixels sum to the reported (exact) total, and
/// one strip.
#[test]
fn compare_methods_sums_match_the_totals() {
    let dir = common::scratch("heatmap", "compare");
    let out = rttest(
        &dir,
        &[
            "render",
            "--scene",
            "atrium",
            "--size",
            "128x96",
            "--aov",
            "nodes",
            "--compare-methods",
            "mono,packet,mft-16",
            "--out",
            "strip",
            "--json",
        ],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    let rows = v["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 3);
    let mut totals = Vec::new();
    for row in rows {
        let image = scenes::ScalarImage::load_pfm(&dir.join(row["pfm"].as_str().unwrap())).expect("PFM");
        let sum: f64 = image.values.iter().map(|&v| f64::from(v)).sum();
        let total = row["total"].as_f64().unwrap();
        assert!(total > 0.0 && (sum - total).abs() <= 1e-5 * total, "{row}: pixels sum to {sum}");
        totals.push(total);
    }
    assert!(totals[2] < totals[0], "MFT takes fewer steps per ray than single rays: {totals:?}");
    assert_eq!(v["strip"], "strip.png");
    let (w, _) = png_size(&dir.join("strip.png"));
    assert!(w > 3 * 128, "three panels side by side: {w}");
}

#[test]
fn bad_cost_options_are_errors() {
    let dir = common::scratch("heatmap", "bad");
    for (args, needle) in [
        (&["render", "--scene", "cube", "--compare-methods", "mono"][..], "--compare-methods"),
        (&["render", "--scene", "cube", "--aov", "nodes", "--cost-max", "nan"], "--cost-max"),
        (&["render", "--scene", "cube", "--aov", "nodes", "--cost-max", "0"], "--cost-max"),
        (&["render", "--scene", "cube", "--aov", "nodes", "--compare-methods", "mono,nope"], "nope"),
    ] {
        let out = rttest(&dir, args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(needle), "{args:?}: {err}");
    }
}
