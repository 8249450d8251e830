//! End-to-end tests of tree files: `rttest build --save FILE`, then `--tree FILE` on build,
//! render and raycast gives the same tree and the same images and hits; a damaged, truncated
//! or mismatched file stops the command with an error naming the file.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;

use common::rttest;

fn scratch(name: &str) -> scenes::ScratchDir {
    common::scratch("tree-files", name)
}

fn ok(out: Output) -> Output {
    assert!(out.status.success(), "failed: {}", String::from_utf8_lossy(&out.stderr));
    out
}

fn json(out: Output) -> serde_json::Value {
    let out = ok(out);
    serde_json::from_slice(&out.stdout).expect("stdout is one JSON object")
}

/// Runs `rttest args`, expects a failure and returns its stderr.
fn fails(dir: &Path, args: &[&str]) -> String {
    let out = rttest(dir, args);
    assert!(!out.status.success(), "rttest {args:?} succeeded");
    assert!(out.stdout.is_empty(), "rttest {args:?} wrote to stdout");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// `rttest build --save` on the sphere; returns the file's path.
fn saved_sphere(dir: &Path, intersector: &str) -> PathBuf {
    let v = json(rttest(
        dir,
        &["build", "--scene", "sphere", "--intersector", intersector, "--save", "sphere.tree", "--json"],
    ));
    assert_eq!(v["tree_file"], "sphere.tree");
    assert!(v["build_ms"].as_f64().unwrap() > 0.0);
    assert!(v["load_tree_ms"].as_f64().unwrap() > 0.0, "{v}");
    assert!(v["validate_ms"].as_f64().unwrap() > 0.0, "{v}");
    dir.join("sphere.tree")
}

#[test]
fn a_saved_tree_loads_as_the_same_tree_and_renders_the_same_image() {
    let dir = scratch("same");
    saved_sphere(&dir, "watertight");
    let built = json(rttest(&dir, &["build", "--scene", "sphere", "--intersector", "watertight", "--json"]));
    let loaded = json(rttest(
        &dir,
        &["build", "--scene", "sphere", "--intersector", "watertight", "--tree", "sphere.tree", "--json"],
    ));
    assert_eq!(loaded["build_ms"], 0.0);
    let file_checks = json(rttest(
        &dir,
        &[
            "build",
            "--scene",
            "sphere",
            "--intersector",
            "watertight",
            "--tree",
            "sphere.tree",
            "--tree-checks",
            "file",
            "--json",
        ],
    ));
    assert!(loaded["load_tree_ms"].as_f64().unwrap() > 0.0);
    for key in ["nodes", "leaves", "empty_leaves", "depth", "refs", "sah_cost", "bytes", "triangles_in_tree"] {
        assert_eq!(built[key], loaded[key], "{key}");
        assert_eq!(built[key], file_checks[key], "{key}");
    }
    // The same images, colour and primitive ids, from the built and the loaded tree.
    for (aov, ext) in [("color", "png"), ("prim", "pfm")] {
        let common = ["render", "--scene", "sphere", "--intersector", "watertight", "--size", "48x32", "--frames", "1"];
        let (a, b) = (format!("built.{ext}"), format!("loaded.{ext}"));
        ok(rttest(&dir, &[&common[..], &["--aov", aov, "--out", &a]].concat()));
        ok(rttest(&dir, &[&common[..], &["--aov", aov, "--out", &b, "--tree", "sphere.tree"]].concat()));
        assert_eq!(std::fs::read(dir.join(a)).unwrap(), std::fs::read(dir.join(b)).unwrap(), "{aov}");
    }
    // And the same hits from raycast.
    std::fs::write(dir.join("rays.txt"), "0 0 -5 0 0 1 0 inf\n0.3 0.2 5 0 0 -1 0 inf\n9 9 9 1 0 0 0 inf\n").unwrap();
    let raycast = ["raycast", "--scene", "sphere", "--intersector", "watertight", "--rays", "rays.txt"];
    ok(rttest(&dir, &[&raycast[..], &["--out", "built.txt"]].concat()));
    ok(rttest(&dir, &[&raycast[..], &["--out", "loaded.txt", "--tree", "sphere.tree"]].concat()));
    let hits = std::fs::read_to_string(dir.join("built.txt")).unwrap();
    assert_eq!(hits, std::fs::read_to_string(dir.join("loaded.txt")).unwrap());
    assert_eq!(hits.lines().filter(|l| !l.starts_with("-1")).count(), 2, "{hits}");
}

#[test]
fn damaged_and_mismatched_tree_files_are_refused_naming_the_file() {
    let dir = scratch("damaged");
    let path = saved_sphere(&dir, "wald");
    let bytes = std::fs::read(&path).unwrap();
    let load = |file: &str, extra: &[&str]| {
        let args = [&["build", "--scene", "sphere", "--tree", file][..], extra].concat();
        fails(&dir, &args)
    };

    let mut flipped = bytes.clone();
    let middle = flipped.len() / 2;
    flipped[middle] ^= 0x10;
    std::fs::write(dir.join("flipped.tree"), &flipped).unwrap();
    for checks in ["full", "file"] {
        let e = load("flipped.tree", &["--tree-checks", checks]);
        assert!(e.contains("flipped.tree") && e.contains("cannot load the tree"), "{e}");
    }

    std::fs::write(dir.join("short.tree"), &bytes[..bytes.len() - 3]).unwrap();
    let e = load("short.tree", &[]);
    assert!(e.contains("short.tree") && e.contains("truncated"), "{e}");

    std::fs::write(dir.join("image.tree"), b"\x89PNG\r\n\x1a\n not a tree").unwrap();
    let e = load("image.tree", &[]);
    assert!(e.contains("image.tree") && e.contains("not a tree file"), "{e}");

    let e = fails(&dir, &["build", "--scene", "cube", "--tree", "sphere.tree"]);
    assert!(e.contains("sphere.tree") && e.contains("another scene"), "{e}");
    let e = load("sphere.tree", &["--intersector", "watertight"]);
    assert!(e.contains("sphere.tree") && e.contains("wald intersector"), "{e}");
    let e = load("sphere.tree", &["--c-isect", "3"]);
    assert!(e.contains("sphere.tree") && e.contains("c_isect"), "{e}");
    let e = load("missing.tree", &[]);
    assert!(e.contains("missing.tree") && e.contains("cannot read"), "{e}");
    // Render stops the same way, before writing anything.
    let e = fails(&dir, &["render", "--scene", "sphere", "--tree", "short.tree", "--size", "8x8", "--out", "x.png"]);
    assert!(e.contains("short.tree"), "{e}");
    assert!(!dir.join("x.png").exists());
}
