//! Watertightness (issue 7): about 10^5 rays at shared edges and vertices of closed meshes.
//! The watertight test must let none through; Wald's test must be caught leaking on the
//! hard meshes, so that the harness is shown to find leaks.

use experiments::leaks::{self, LeakResult};

mod common;

use common::{rttest, scratch};

#[test]
fn the_watertight_test_never_leaks_and_walds_is_caught() {
    let mut results: Vec<LeakResult> = Vec::new();
    for (i, name) in ["fan", "sphere-20k", "cube", "touching-boxes"].into_iter().enumerate() {
        let mesh = leaks::mesh_by_name(name).unwrap().expect("a generated mesh");
        results.extend(leaks::measure(&mesh, 25_000, 99 + i as u64).unwrap());
    }
    print!("{}", leaks::markdown_table(&results));
    for r in &results {
        assert_eq!(r.rays, 25_000, "{r:?}");
        if r.intersector == "watertight" {
            assert_eq!(r.leaks, 0, "the watertight test leaked: {r:?}");
        }
    }
    let wald = |mesh: &str| results.iter().find(|r| r.mesh == mesh && r.intersector == "wald").unwrap().leaks;
    assert!(wald("fan") > 0 && wald("sphere-20k") > 0, "Wald's test leaks at vertices of thin fans and spheres");
    let totals = leaks::totals(&results);
    assert_eq!(totals.len(), 2);
    assert_eq!(totals[0].rays, 100_000);
    assert_eq!(totals[0].leaks, results.iter().filter(|r| r.intersector == "wald").map(|r| r.leaks).sum::<u64>());
}

#[test]
fn rttest_leaks_prints_a_table_or_json_lines() {
    let dir = scratch("leaks", "cli");
    let out = rttest(&dir, &["leaks", "--rays", "4000", "--meshes", "cube,fan", "--threads", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    // The machine line first (`rttest::cli::header`), then the table.
    let (machine, text) = stdout.split_once('\n').expect("the machine line, then the table");
    assert!(machine.starts_with("cpu: "), "{stdout}");
    assert!(
        text.starts_with("| mesh | triangles | intersector | rays | Mrays/s | leaks | leaks per million |"),
        "{text}"
    );
    assert_eq!(text.lines().count(), 2 + 4 + 2, "{text}");
    assert!(text.contains("| all |"));

    let out = rttest(&dir, &["leaks", "--rays", "4000", "--meshes", "cube,fan", "--json"]);
    assert!(out.status.success());
    let lines: Vec<serde_json::Value> =
        String::from_utf8_lossy(&out.stdout).lines().map(|l| serde_json::from_str(l).expect("JSON")).collect();
    assert_eq!(lines.len(), 6);
    for v in &lines {
        for key in
            ["mesh", "triangles", "intersector", "rays", "trace_secs", "mrays_per_s", "leaks", "leaks_per_million"]
        {
            assert!(v.get(key).is_some(), "{key} missing from {v}");
        }
    }
    assert_eq!(lines[0]["rays"], 2000);
    let watertight_total = &lines[5];
    assert_eq!((watertight_total["mesh"].as_str(), watertight_total["leaks"].as_u64()), (Some("all"), Some(0)));

    let out = rttest(&dir, &["leaks", "--meshes", "teapot"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.lines().count() == 1 && stderr.contains("teapot"), "{stderr}");
}
