//! `rttest build` memory figures and `--memory-budget` (issue 7).

use trace::report::{parse_bytes, parse_vm_hwm};

mod common;

use common::{rttest, scratch};

#[test]
fn byte_counts_parse_with_binary_units() {
    assert_eq!(parse_bytes("1500000000"), Ok(1_500_000_000));
    assert_eq!(parse_bytes("512MiB"), Ok(512 << 20));
    assert_eq!(parse_bytes("2GiB"), Ok(2 << 30));
    assert_eq!(parse_bytes("1.5 gib"), Ok(3 << 29));
    assert_eq!(parse_bytes("64KiB"), Ok(64 << 10));
    assert_eq!(parse_bytes("1TiB"), Ok(1 << 40));
    assert_eq!(parse_bytes(" 7 "), Ok(7));
    for bad in ["", "MiB", "1.5", "-3", "1e9", "12 MB", "1..5GiB", ".5GiB", "99999999999999999999", "3 parsecs"] {
        assert!(parse_bytes(bad).is_err(), "{bad:?} parsed");
    }
    assert!(parse_bytes("99999999999TiB").unwrap_err().contains("too large"));
    // NaN and infinities are not byte counts, with or without a unit.
    for bad in ["nan", "NaN", "inf", "-inf", "infinity", "nanGiB", "inf MiB", "1e400GiB"] {
        let e = parse_bytes(bad).unwrap_err();
        assert!(e.contains(bad), "{bad:?}: {e}");
    }
}

#[test]
fn the_peak_resident_size_is_read_from_proc_status() {
    let status = "Name:\trttest\nVmPeak:\t  100 kB\nVmHWM:\t    2048 kB\nVmRSS:\t 1024 kB\n";
    assert_eq!(parse_vm_hwm(status), Some(2048 * 1024));
    assert_eq!(parse_vm_hwm("VmRSS:\t 1024 kB\n"), None);
    assert_eq!(parse_vm_hwm("VmHWM:\t lots kB\n"), None);
    if cfg!(target_os = "linux") {
        assert!(trace::report::peak_rss_bytes().is_some_and(|b| b > 1 << 20));
    }
}

#[test]
fn build_reports_memory_per_triangle_and_peaks() {
    let dir = scratch("build-memory", "report");
    let out = rttest(&dir, &["build", "--scene", "arena", "--json", "--threads", "1"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let (bytes, tris) = (v["bytes"].as_f64().unwrap(), v["triangles"].as_f64().unwrap());
    assert!((v["bytes_per_triangle"].as_f64().unwrap() - bytes / tris).abs() < 1e-9);
    let build_peak = v["build_peak_bytes"].as_u64().expect("build_peak_bytes");
    assert!(build_peak as f64 > bytes, "the build's peak holds the tree and more");
    if cfg!(target_os = "linux") {
        assert!(v["peak_rss_bytes"].as_u64().expect("VmHWM") > build_peak);
    }
    let text = rttest(&dir, &["build", "--scene", "cube"]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains("bytes per triangle") && text.contains("peak memory"), "{text}");
}

#[test]
fn a_memory_budget_stops_the_build_with_one_clear_line() {
    let dir = scratch("build-memory", "budget");
    // Far too small: refused before the build, naming the estimate and the budget.
    let out = rttest(&dir, &["build", "--scene", "arena", "--memory-budget", "1KiB"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && out.stdout.is_empty());
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("rttest: error: kd-tree build failed: the build would need")
            && stderr.contains("estimate")
            && stderr.contains("over the memory budget of 1.0 KiB (1024 bytes)"),
        "{stderr}"
    );
    // Between the first phase and the peak: stopped during the build.
    let first = kdtree::first_phase_bytes(
        &scenes::builtin::by_name("arena").unwrap().mesh.positions,
        &scenes::builtin::by_name("arena").unwrap().mesh.triangles,
        kdtree::BuildConfig::default().strategy,
    );
    let out =
        rttest(&dir, &["build", "--scene", "arena", "--threads", "1", "--memory-budget", &(first + 100).to_string()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("over the memory budget") && !stderr.contains("estimate"),
        "{stderr}"
    );
    // Enough: the build runs.
    assert!(rttest(&dir, &["build", "--scene", "arena", "--memory-budget", "1GiB"]).status.success());
    let out = rttest(&dir, &["build", "--scene", "arena", "--memory-budget", "lots"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.starts_with("rttest: error: ") && stderr.lines().count() == 1, "{stderr}");
}
