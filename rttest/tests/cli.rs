//! End-to-end tests of the `rttest` binary on tiny scenes.

use std::process::Output;

mod common;

use common::rttest;

/// A fresh, empty scratch folder for one test.
fn scratch(name: &str) -> scenes::ScratchDir {
    common::scratch("cli", name)
}

/// The single JSON object that a successful `--json` run prints.
fn json(out: &Output) -> serde_json::Value {
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "failed: {}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(stdout.lines().count(), 1, "stdout is not one line: {stdout}");
    serde_json::from_str(&stdout).expect("stdout is JSON")
}

fn assert_keys(v: &serde_json::Value, keys: &[&str]) {
    for k in keys {
        assert!(v.get(k).is_some(), "key {k} missing from {v}");
    }
}

#[test]
fn build_json_has_the_tree_statistics() {
    let dir = scratch("build");
    let v = json(&rttest(&dir, &["build", "--scene", "cube", "--json", "--threads", "2"]));
    assert_keys(
        &v,
        &[
            "scene",
            "triangles",
            "build_ms",
            "nodes",
            "leaves",
            "empty_leaves",
            "depth",
            "refs_per_triangle",
            "sah_cost",
            "bytes",
            "threads",
            "intersector",
        ],
    );
    assert_eq!(v["scene"], "cube");
    assert_eq!(v["threads"], 2);
    assert_eq!(v["triangles"], 12);
    assert_eq!(v["intersector"], "wald");
    let v = json(&rttest(&dir, &["build", "--scene", "cube", "--intersector", "watertight", "--json"]));
    assert_eq!(v["intersector"], "watertight");
    // Global flags may also come before the command.
    let v = json(&rttest(&dir, &["--threads", "1", "--json", "build", "--scene", "triangle"]));
    assert_eq!(v["threads"], 1);
    assert_eq!(v["triangles"], 1);
}

#[test]
fn sah_options_reach_the_builder() {
    let dir = scratch("sah-options");
    let deep = json(&rttest(&dir, &["build", "--scene", "sphere", "--json"]));
    let shallow = json(&rttest(&dir, &["build", "--scene", "sphere", "--max-depth", "3", "--json"]));
    assert!(shallow["depth"].as_u64().unwrap() <= 3);
    assert!(shallow["nodes"].as_u64() < deep["nodes"].as_u64());
    // Cheaper intersections make leaves hold more triangles.
    let cheap = json(&rttest(&dir, &["build", "--scene", "sphere", "--c-isect", "0.5", "--json"]));
    assert!(cheap["nodes"].as_u64() < deep["nodes"].as_u64());
    let out = rttest(&dir, &["build", "--scene", "sphere", "--empty-bonus", "1.5"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--empty-bonus 1.5"));
}

/// `--leaf-width`, `--bad-refines` and `--collapse` reach the builder and the report: leaves
/// priced by groups of 4 make a smaller tree of the sphere; out-of-range values and a
/// `--collapse` that is neither on nor off are usage errors.
#[test]
fn leaf_width_and_termination_options_reach_the_builder() {
    let dir = scratch("leaf-width");
    let build = |extra: &[&str]| {
        let mut args = vec!["build", "--scene", "sphere", "--json"];
        args.extend_from_slice(extra);
        json(&rttest(&dir, &args))
    };
    let plain = build(&[]);
    assert_eq!((plain["leaf_width"].as_u64(), plain["max_bad_refines"].as_u64()), (Some(1), Some(0)));
    let grouped = build(&["--leaf-width", "4", "--bad-refines", "2", "--collapse", "on"]);
    assert_eq!((grouped["leaf_width"].as_u64(), grouped["max_bad_refines"].as_u64()), (Some(4), Some(2)));
    assert_eq!(grouped["collapse"].as_bool(), Some(true));
    assert!(grouped["nodes"].as_u64() < plain["nodes"].as_u64(), "{grouped} {plain}");
    for args in [&["--leaf-width", "0"][..], &["--bad-refines", "17"], &["--collapse", "maybe"]] {
        let mut all = vec!["build", "--scene", "sphere"];
        all.extend_from_slice(args);
        let out = rttest(&dir, &all);
        assert!(!out.status.success(), "{args:?}");
        assert!(String::from_utf8_lossy(&out.stderr).contains(args[0]), "{args:?}");
    }
}

/// `--build`, `--bins` and `--bin-min-tris` reach the builder and the report: the sphere
/// (1280 triangles) binned from 64 triangles is another tree than the exact one, and the
/// binned default (from 1024 triangles) bins its root.
#[test]
fn build_strategy_options_reach_the_builder() {
    let dir = scratch("build-strategy");
    let build = |extra: &[&str]| {
        let mut args = vec!["build", "--scene", "sphere", "--json"];
        args.extend_from_slice(extra);
        json(&rttest(&dir, &args))
    };
    let exact = build(&["--build", "exact"]);
    assert_eq!(exact["build_strategy"], "exact");
    assert!(exact["bins"].is_null() && exact["bin_min_tris"].is_null());
    let binned = build(&["--build", "binned", "--bins", "16", "--bin-min-tris", "64"]);
    assert_eq!((binned["build_strategy"].as_str(), binned["bins"].as_u64()), (Some("binned"), Some(16)));
    assert_eq!(binned["bin_min_tris"].as_u64(), Some(64));
    assert_ne!(binned["sah_cost"], exact["sah_cost"], "binned from 64 triangles changes the tree");
    let default = build(&[]);
    assert_eq!((default["build_strategy"].as_str(), default["bins"].as_u64()), (Some("binned"), Some(256)));
    assert_eq!(default["bin_min_tris"].as_u64(), Some(1024));
    // Bins without binning, and out-of-range bins, are usage errors.
    for (args, says) in [(&["--build", "exact", "--bins", "8"][..], "--bins"), (&["--bins", "1"][..], "--bins")] {
        let mut all = vec!["build", "--scene", "sphere"];
        all.extend_from_slice(args);
        let out = rttest(&dir, &all);
        assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains(says), "{args:?}");
    }
}

#[test]
fn render_json_reports_rays_and_writes_the_png() {
    let dir = scratch("render");
    let out = rttest(&dir, &["render", "--scene", "cube", "--size", "32x24", "--frames", "2", "--json"]);
    let v = json(&out);
    assert_keys(
        &v,
        &[
            "scene",
            "method",
            "width",
            "height",
            "threads",
            "rays",
            "primary_rays",
            "shadow_rays",
            "hits",
            "trace_secs",
            "mrays_per_s",
            "shade_secs",
            "write_secs",
        ],
    );
    assert_eq!(v["method"], "mono");
    assert_eq!(v["primary_rays"], 32 * 24);
    let rays = v["rays"].as_u64().unwrap();
    assert_eq!(rays, v["primary_rays"].as_u64().unwrap() + v["shadow_rays"].as_u64().unwrap());
    assert!(v["hits"].as_u64().unwrap() > 0, "the default view sees the cube");
    assert!(dir.join("cube.png").is_file());
}

#[test]
fn prim_and_depth_aovs_write_pfm() {
    let dir = scratch("aov");
    for (aov, file) in [("prim", "triangle-prim.pfm"), ("depth", "triangle-depth.pfm")] {
        let out =
            rttest(&dir, &["render", "--scene", "triangle", "--size", "32x32", "--aov", aov, "--shadows", "none"]);
        assert!(out.status.success(), "{aov}: {}", String::from_utf8_lossy(&out.stderr));
        let bytes = std::fs::read(dir.join(file)).expect("PFM written");
        assert!(bytes.starts_with(b"Pf\n32 32\n"), "{aov}: not a 32x32 greyscale PFM");
        // Header "Pf\n32 32\n-1.0\n" (scale line may vary) then 32 * 32 floats.
        assert!(bytes.len() >= 32 * 32 * 4);
        let values: Vec<f32> = bytes[bytes.len() - 32 * 32 * 4..]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if aov == "prim" {
            assert!(values.iter().all(|&v| v == -1.0 || v == 0.0), "one triangle: ids are 0 or -1");
            assert!(values.contains(&0.0) && values.contains(&-1.0));
        } else {
            assert!(values.iter().any(|v| v.is_finite() && *v > 0.0));
            assert!(values.contains(&f32::INFINITY));
        }
    }
}

#[test]
fn custom_camera_and_named_out_file() {
    let dir = scratch("camera");
    let v = json(&rttest(
        &dir,
        &["render", "--scene", "cube", "--size", "16x16", "--camera", "-3,2,4,0,0,0,45", "--out", "x.pfm", "--json"],
    ));
    assert_eq!(v["view"], "custom");
    assert!(dir.join("x.pfm").is_file());
}

#[test]
fn render_workload_times_the_incoherent_streams() {
    let dir = scratch("workload");
    let args = ["render", "--scene", "cube", "--size", "24x16", "--frames", "1", "--json", "--method", "mbvh-4"];
    let v = json(&rttest(&dir, &[&args[..], &["--workload", "ao,diffuse", "--ao-rays", "3"]].concat()));
    let (ao, diffuse) = (v["ao_rays"].as_u64().unwrap(), v["diffuse_rays"].as_u64().unwrap());
    assert!(diffuse > 0 && diffuse <= v["hits"].as_u64().unwrap() && ao == 3 * diffuse, "{v}");
    assert!(v["ao_mrays_per_s"].as_f64().unwrap() > 0.0 && v["diffuse_mrays_per_s"].as_f64().unwrap() > 0.0);
    let only_ao = json(&rttest(&dir, &[&args[..], &["--workload", "ao"]].concat()));
    assert!(only_ao["ao_rays"].as_u64().unwrap() == 4 * diffuse && only_ao.get("diffuse_rays").is_none());
    let none = json(&rttest(&dir, &args));
    assert!(none.get("ao_rays").is_none() && none.get("diffuse_mrays_per_s").is_none());
}

#[test]
fn dynamic_reports_every_frame_with_identical_shadows() {
    let dir = scratch("dynamic");
    let out = rttest(&dir, &["dynamic", "--scene", "arena", "--frames", "2", "--size", "24x16", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let rows: Vec<serde_json::Value> =
        String::from_utf8_lossy(&out.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(rows.len(), 2);
    for (k, r) in rows.iter().enumerate() {
        assert_eq!(r["frame"], k as u64);
        assert_eq!(r["scene"], "arena-animated");
        assert_eq!(r["identical"], true);
        assert!(r["kept"].as_u64() < r["triangles"].as_u64() && r["frame_culled_ms"].as_array().unwrap().len() == 2);
    }
}

/// Every run names its machine: text results start with the one machine line
/// (`cpu: ..., simd: ..., N threads`, the run's threads), printed once, and every JSON object
/// has `cpu`, `simd` and `threads` (the pool's where the report had none).
#[test]
fn every_result_names_the_machine() {
    let dir = scratch("machine");
    let simd_levels = ["scalar", "sse2", "sse4.1", "avx2", "avx512"];
    let is_machine_line = |line: &str| {
        line.starts_with("cpu: ")
            && line.split_once(", simd: ").is_some_and(|(_, rest)| {
                rest.split_once(", ").is_some_and(|(simd, threads)| {
                    simd_levels.contains(&simd) && threads.trim_end_matches('s').ends_with(" thread")
                })
            })
    };
    // Text: the first line, once, also above a render's two reports (build, then render).
    for args in [&["build", "--scene", "cube"][..], &["render", "--scene", "cube", "--size", "16x16", "--frames", "1"]]
    {
        let out = rttest(&dir, args);
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        let stdout = String::from_utf8_lossy(&out.stdout);
        let first = stdout.lines().next().unwrap_or_default();
        assert!(is_machine_line(first), "{args:?}: first line {first:?}");
        assert_eq!(stdout.lines().filter(|l| l.starts_with("cpu: ")).count(), 1, "{args:?}: {stdout}");
    }
    // The line's threads are the run's (`--threads`), not the machine's CPUs.
    let out = rttest(&dir, &["build", "--scene", "cube", "--threads", "1"]);
    let first = String::from_utf8_lossy(&out.stdout).lines().next().unwrap_or_default().to_string();
    assert!(first.ends_with(", 1 thread"), "--threads 1: first line {first:?}");
    // JSON: the machine's fields, the same as the text line says.
    let out = rttest(&dir, &["build", "--scene", "cube"]);
    let line = String::from_utf8_lossy(&out.stdout).lines().next().unwrap_or_default().to_string();
    let v = json(&rttest(&dir, &["build", "--scene", "cube", "--json", "--threads", "2"]));
    let (cpu, simd) = (v["cpu"].as_str().expect("cpu"), v["simd"].as_str().expect("simd"));
    assert!(line.starts_with(&format!("cpu: {cpu}, simd: {simd}, ")), "{line} against {v}");
    assert_eq!(v["threads"], 2);
    // A report without its own `threads` gets the pool's, and stdout stays JSON lines.
    let out =
        rttest(&dir, &["dynamic", "--scene", "arena", "--frames", "1", "--size", "16x16", "--json", "--threads", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    let row: serde_json::Value = serde_json::from_str(&stdout).expect("one JSON object");
    assert_eq!((row["cpu"].as_str(), row["simd"].as_str(), &row["threads"]), (Some(cpu), Some(simd), &2.into()));
}

#[test]
fn bad_input_gives_one_line_and_non_zero_exit() {
    let dir = scratch("errors");
    let cases: &[&[&str]] = &[
        &["render", "--scene", "no-such-scene"],
        &["render", "--scene", "cube", "--size", "0x5"],
        &["render", "--scene", "cube", "--size", "big"],
        &["render", "--scene", "cube", "--size", "16384x16384"],
        &["render", "--scene", "cube", "--camera", "1,2,3"],
        &["render", "--scene", "cube", "--camera", "0,0,0,0,0,0,45"],
        &["render", "--scene", "cube", "--view", "no-such-view"],
        &["render", "--scene", "cube", "--frames", "0"],
        &["render", "--scene", "cube", "--method", "no-such-method"],
        &["render", "--scene", "cube", "--method", "mft-6"],
        &["render", "--scene", "cube", "--method", "mft", "--tile", "6"],
        &["render", "--scene", "cube", "--size", "8x8", "--out", "no/such/dir/x.png"],
        &["build", "--scene", "missing.obj"],
        &["build", "--threads", "0"],
        &["--bogus"],
        &["frobnicate"],
    ];
    for args in cases {
        let out = rttest(&dir, args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: stderr is not one line: {stderr}");
        assert!(stderr.starts_with("rttest: error: "), "{args:?}: {stderr}");
        assert!(out.stdout.is_empty(), "{args:?}: wrote to stdout");
    }
}

/// NaN and infinite numbers in any option are one-line usage errors naming the option,
/// before any expensive work.
#[test]
fn non_finite_numbers_are_errors_naming_the_option() {
    let dir = scratch("non-finite");
    let cases: &[(&[&str], &str)] = &[
        (&["build", "--c-isect", "nan"], "--c-isect NaN"),
        (&["build", "--c-isect", "inf"], "--c-isect inf"),
        (&["render", "--c-isect=-inf"], "--c-isect -inf"),
        (&["build", "--empty-bonus", "NaN"], "--empty-bonus NaN"),
        (&["build", "--scene", "cube", "--memory-budget", "nanGiB"], "nanGiB"),
        (&["build", "--scene", "cube", "--memory-budget", "inf"], "inf"),
        (&["render", "--scene", "cube", "--camera", "nan,0,5,0,0,0,45"], "--camera"),
        (&["render", "--scene", "cube", "--camera", "0,0,5,0,0,0,inf"], "--camera"),
        (&["render", "--scene", "cube", "--camera", "1e39,0,5,0,0,0,45"], "finite"),
        (&["render", "--scene", "cube", "--camera=0,0,5,0,-inf,0,45"], "finite"),
        (&["shadows", "--scene", "cube", "--edge-scale", "nan"], "--edge-scale"),
        (&["shadows", "--scene", "cube", "--edge-scale", "inf"], "--edge-scale"),
        (&["shadows", "--scene", "cube", "--light-size", "NaN"], "--light-size"),
        (&["shadows", "--scene", "cube", "--light-size", "inf"], "--light-size"),
        (&["shadows", "--scene", "atrium", "--thickness", "floor=nan"], "--thickness 'floor=nan'"),
        (&["shadows", "--scene", "atrium", "--thickness", "floor=inf"], "--thickness 'floor=inf'"),
        (&["shadows", "--scene", "cube", "--methods", "hard,nan"], "--methods: no method 'nan'"),
        (&["compare", "--light-radius", "nan"], "--light-radius"),
        (&["compare", "--light-radius=-inf"], "--light-radius"),
        (&["render", "--scene", "cube", "--shadows", "soft16", "--light-radius", "nan"], "--light-radius"),
    ];
    for (args, name) in cases {
        let start = std::time::Instant::now();
        let out = rttest(&dir, args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: stderr is not one line: {stderr}");
        assert!(stderr.starts_with("rttest: error: ") && !stderr.contains("internal error"), "{args:?}: {stderr}");
        assert!(stderr.contains(name), "{args:?} should name '{name}': {stderr}");
        assert!(out.stdout.is_empty(), "{args:?}: wrote to stdout");
        assert!(start.elapsed().as_secs() < 20, "{args:?}: the error came late");
    }
}

/// The main job: atrium with MFT and 16-sample soft shadows, single rays beside it.
#[test]
fn no_arguments_renders_the_atrium() {
    let dir = scratch("default");
    let out = rttest(&dir, &["--json", "--threads", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object per line"))
        .collect();
    assert_eq!(lines.len(), 2, "single rays, then the best method");
    let (mono, best) = (&lines[0], &lines[1]);
    assert_eq!((&mono["method"], &best["method"]), (&"mono".into(), &"mft".into()));
    for v in &lines {
        assert_eq!(v["scene"], "atrium");
        assert_eq!(v["width"], 512);
        assert_eq!(v["shadows"], "soft16");
        assert_eq!(v["shadow_rays"].as_u64().unwrap() % 16, 0);
        assert!(v["shadow_rays"].as_u64().unwrap() > 0);
        assert!(v["primary_steps_per_packet"].is_number() || v["primary_nodes_per_ray"].is_number());
    }
    // The same rays: the same hits and the same blocked soft-shadow rays.
    assert_eq!((&mono["hits"], &mono["occluded"]), (&best["hits"], &best["occluded"]));
    assert!(dir.join("atrium.png").is_file());
    let text = rttest(&dir, &["--threads", "2"]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.starts_with("cpu: "), "the machine line first: {text}");
    assert!(
        text.contains("| MFT 8x8 (mft-8) |") && text.contains("Wrote atrium.png") && text.contains("Next:"),
        "{text}"
    );
}

#[test]
fn images_are_identical_across_runs_and_thread_counts() {
    let dir = scratch("determinism");
    let mut files = Vec::new();
    for (run, threads) in [(0, "1"), (1, "2"), (2, "2"), (3, "3")] {
        let mut run_files = Vec::new();
        for aov in ["color", "depth", "prim"] {
            let out = format!("{aov}-{run}.pfm");
            let o = rttest(
                &dir,
                &["render", "--scene", "arena", "--size", "48x40", "--threads", threads, "--aov", aov, "--out", &out],
            );
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            run_files.push(std::fs::read(dir.join(&out)).expect("image written"));
        }
        files.push(run_files);
    }
    for run in &files[1..] {
        assert!(run == &files[0], "an image differs between runs or thread counts");
    }
}

/// `--soft-grouping`: the packet and cone methods' soft shadows per light stratum by
/// default, per point (the thesis's pyramid and cone) on request, the same answers; a
/// method without a per-point kernel is a usage error naming the option.
#[test]
fn soft_grouping_picks_the_kernel_and_keeps_the_answers() {
    let dir = scratch("soft-grouping");
    let render = |method: &str, grouping: &str| {
        let args = [
            "render",
            "--scene",
            "atrium",
            "--size",
            "48x32",
            "--frames",
            "1",
            "--shadows",
            "soft16",
            "--method",
            method,
            "--soft-grouping",
            grouping,
            "--json",
        ];
        json(&rttest(&dir, &args))
    };
    let mono = render("mono", "strata");
    assert_eq!(mono["shadow_kernel"], "kd-single");
    // The stratum packets are as wide as the run's SIMD level: 16 lanes from avx2 on (two
    // registers at avx2), else 2x2.
    let wide = match mono["simd"].as_str() {
        Some("avx512" | "avx2") => "-w16",
        _ => "",
    };
    for (method, thesis) in [("packet", "kd-pyramid"), ("cone-8", "kd-cone")] {
        let strata = render(method, "strata");
        let per_point = render(method, "per-point");
        assert_eq!(
            (&strata["shadow_kernel"], &per_point["shadow_kernel"]),
            (&format!("kd-stratum-packets{wide}").into(), &thesis.into())
        );
        for v in [&strata, &per_point] {
            assert_eq!((&v["shadow_rays"], &v["occluded"]), (&mono["shadow_rays"], &mono["occluded"]), "{method}");
        }
    }
    let out = rttest(&dir, &["render", "--scene", "cube", "--method", "mono", "--soft-grouping", "per-point"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("--soft-grouping per-point") && stderr.contains("packet"),
        "{stderr}"
    );
}

/// `--simd` caps the level every kernel binds to, and the machine line reports the level
/// the run used; a level this CPU lacks is a usage error naming both levels. The images of
/// every level are identical (every width gives the single rays' answers).
#[test]
fn simd_caps_the_level_and_keeps_the_image() {
    let dir = scratch("simd");
    let widest =
        json(&rttest(&dir, &["build", "--scene", "cube", "--json"]))["simd"].as_str().expect("simd").to_string();
    let order = ["sse2", "sse4.1", "avx2", "avx512"];
    let rank = |s: &str| order.iter().position(|l| *l == s);
    let mut images = Vec::new();
    for (arg, level) in [("sse", "sse4.1"), ("avx2", "avx2"), ("avx512", "avx512")] {
        let out_png = dir.join(format!("mft-{arg}.png"));
        let args = [
            "--simd",
            arg,
            "--json",
            "render",
            "--scene",
            "arena",
            "--method",
            "mft-16",
            "--size",
            "64x48",
            "--frames",
            "1",
            "--shadows",
            "hard",
            "--out",
            out_png.to_str().unwrap(),
        ];
        let out = rttest(&dir, &args);
        if rank(level) > rank(&widest) {
            assert!(!out.status.success(), "{arg} on a {widest} CPU");
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(err.contains("--simd") && err.contains(&widest) && err.contains(level), "{err}");
            continue;
        }
        assert!(out.status.success(), "{arg}: {}", String::from_utf8_lossy(&out.stderr));
        let stdout = String::from_utf8_lossy(&out.stdout);
        for line in stdout.lines() {
            let v: serde_json::Value = serde_json::from_str(line).expect("JSON lines");
            assert_eq!(v["simd"], level, "{line}");
        }
        images.push((arg, std::fs::read(&out_png).expect("the image")));
    }
    for (arg, image) in &images[1..] {
        assert!(image == &images[0].1, "--simd {arg} changed the image");
    }
}
