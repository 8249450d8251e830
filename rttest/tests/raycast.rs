//! End-to-end tests of `rttest raycast` on the built-in `cube` scene, checked against known
//! geometry and against the brute-force oracle of the kd-tree crate.

use std::path::Path;
use std::process::{Command, Stdio};

use glam::Vec3;
use kdtree::{BruteForce, Intersector, Ray};

mod common;

use common::rttest;

/// A fresh, empty scratch folder for one test.
fn scratch(name: &str) -> scenes::ScratchDir {
    common::scratch("raycast", name)
}

/// Runs `rttest args` in `dir` and returns its stdout, failing the test on a non-zero exit.
fn rttest_ok(dir: &Path, args: &[&str]) -> Vec<u8> {
    let out = rttest(dir, args);
    assert!(out.status.success(), "rttest {args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
    out.stdout
}

/// One ray as in the files: origin, direction, tmin, tmax.
#[derive(Clone, Copy, Debug)]
struct R([f32; 8]);

impl R {
    fn new(o: [f32; 3], d: [f32; 3], tmin: f32, tmax: f32) -> R {
        R([o[0], o[1], o[2], d[0], d[1], d[2], tmin, tmax])
    }

    fn ray(&self) -> Ray {
        let v = self.0;
        Ray::try_new(Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]), v[6], v[7]).expect("valid test ray")
    }
}

/// The text form of `rays`, with `{}` (round-tripping) numbers.
fn text_rays(rays: &[R]) -> String {
    let mut s = String::from("# ox oy oz dx dy dz tmin tmax\n");
    for r in rays {
        let v = r.0;
        s.push_str(&format!("{} {} {} {} {} {} {} {}\n", v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]));
    }
    s
}

/// The binary form of `rays`: 8 little-endian f32 each.
fn binary_rays(rays: &[R]) -> Vec<u8> {
    rays.iter().flat_map(|r| r.0).flat_map(f32::to_le_bytes).collect()
}

/// A closest-hit result as written: prim (-1 for a miss), t, u, v.
type Res = (i32, f32, f32, f32);

fn parse_text_results(bytes: &[u8]) -> Vec<Res> {
    let text = String::from_utf8(bytes.to_vec()).expect("UTF-8 results");
    text.lines()
        .map(|line| {
            let f: Vec<&str> = line.split(' ').collect();
            assert_eq!(f.len(), 4, "bad result line '{line}'");
            (f[0].parse().unwrap(), f[1].parse().unwrap(), f[2].parse().unwrap(), f[3].parse().unwrap())
        })
        .collect()
}

fn parse_binary_results(bytes: &[u8]) -> Vec<Res> {
    assert_eq!(bytes.len() % 16, 0);
    let word = |b: &[u8]| [b[0], b[1], b[2], b[3]];
    bytes
        .chunks_exact(16)
        .map(|r| {
            (
                i32::from_le_bytes(word(&r[0..4])),
                f32::from_le_bytes(word(&r[4..8])),
                f32::from_le_bytes(word(&r[8..12])),
                f32::from_le_bytes(word(&r[12..16])),
            )
        })
        .collect()
}

/// The cube's triangles, in the scene's (and the tree's) numbering.
fn cube_triangles() -> Vec<[Vec3; 3]> {
    let scene = scenes::load_scene("cube").expect("cube");
    assert_eq!(scene.mesh.prim_ids, (0..12).collect::<Vec<u32>>(), "built-in scenes number triangles in order");
    (0..scene.mesh.triangle_count()).map(|i| scene.mesh.triangle(i)).collect()
}

/// A small deterministic generator (xorshift64*), so the tests need no extra crate.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// Uniform in `[lo, hi)`.
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// `n` random rays around the cube: origins in [-3, 3]^3 (inside and outside), random
/// directions (half of them aimed near the cube), some with a positive tmin or a finite
/// tmax, some along the axes.
fn random_rays(n: usize, seed: u64) -> Vec<R> {
    let mut rng = Rng(seed);
    (0..n)
        .map(|i| {
            let o = [rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), rng.range(-3.0, 3.0)];
            let mut d = [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)];
            if i % 2 == 1 {
                // Aimed at a point near the cube, so that about half the rays hit it.
                let p = [rng.range(-1.2, 1.2), rng.range(-1.2, 1.2), rng.range(-1.2, 1.2)];
                d = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
            }
            if i % 10 == 0 {
                // Axis-parallel: the zero-component cases of the traversal.
                let keep = (i / 10) % 3;
                for (k, x) in d.iter_mut().enumerate() {
                    if k != keep {
                        *x = 0.0;
                    }
                }
            }
            if d == [0.0; 3] {
                d = [1.0, 0.0, 0.0];
            }
            let tmin = if i % 3 == 0 { rng.range(0.0, 2.0) } else { 0.0 };
            let tmax = if i % 4 == 0 { tmin + rng.range(0.0, 6.0) } else { f32::INFINITY };
            R::new(o, d, tmin, tmax)
        })
        .collect()
}

/// Checks one tool result against the oracle: same distance bit for bit, and the same
/// triangle, or another one the oracle also hits at exactly that distance (a shared edge).
fn check_against_oracle(oracle: &BruteForce, ray: &R, got: Res, what: &str) {
    let ray_ = ray.ray();
    match oracle.intersect(&ray_) {
        None => assert_eq!(got, (-1, f32::INFINITY, 0.0, 0.0), "{what}: {ray:?} should miss"),
        Some(want) => {
            assert!(got.0 >= 0, "{what}: {ray:?} should hit {want:?}, got a miss");
            assert_eq!(got.1.to_bits(), want.t.to_bits(), "{what}: {ray:?}: t {} vs oracle {}", got.1, want.t);
            if got.0 as u32 == want.prim {
                assert_eq!((got.2, got.3), (want.u, want.v), "{what}: {ray:?}: barycentrics");
            } else {
                let all = oracle.all_hits(&ray_);
                assert!(
                    all.contains(&(want.t, got.0 as u32)),
                    "{what}: {ray:?}: prim {} not hit at t {}",
                    got.0,
                    want.t
                );
            }
        }
    }
}

#[test]
fn rays_hitting_known_faces_give_their_prim_and_t() {
    let dir = scratch("faces");
    let tris = cube_triangles();
    // From 5 units outside each face, off the faces' diagonals, straight in: t = 4. A
    // non-unit direction scales t; tmin and tmax bound it.
    let rays = [
        (R::new([0.5, 0.3, -5.0], [0.0, 0.0, 1.0], 0.0, f32::INFINITY), 2, -1.0, 4.0),
        (R::new([0.5, 0.3, 5.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY), 2, 1.0, 4.0),
        (R::new([-5.0, -0.2, 0.7], [1.0, 0.0, 0.0], 0.0, f32::INFINITY), 0, -1.0, 4.0),
        (R::new([5.0, -0.2, 0.7], [-2.0, 0.0, 0.0], 0.0, f32::INFINITY), 0, 1.0, 2.0),
        (R::new([0.1, 5.0, -0.6], [0.0, -0.5, 0.0], 0.0, 100.0), 1, 1.0, 8.0),
        (R::new([0.1, -5.0, -0.6], [0.0, 1.0, 0.0], 0.0, f32::INFINITY), 1, -1.0, 4.0),
        // From inside, the far face: t = 1.
        (R::new([0.2, 0.1, 0.0], [0.0, 0.0, 1.0], 0.0, f32::INFINITY), 2, 1.0, 1.0),
        // tmin past the near face: the far face at t = 6.
        (R::new([0.5, 0.3, -5.0], [0.0, 0.0, 1.0], 4.5, f32::INFINITY), 2, 1.0, 6.0),
    ];
    let list: Vec<R> = rays.iter().map(|r| r.0).collect();
    std::fs::write(dir.join("rays.txt"), text_rays(&list)).unwrap();
    let results = parse_text_results(&rttest_ok(&dir, &["raycast", "--scene", "cube", "--rays", "rays.txt"]));
    assert_eq!(results.len(), rays.len());
    let oracle = BruteForce::new(&tris, Intersector::Wald);
    for ((ray, axis, side, t), got) in rays.iter().zip(&results) {
        assert_eq!(got.1, *t, "{ray:?}: distance");
        let tri = tris[got.0 as usize];
        assert!(tri.iter().all(|p| p[*axis] == *side), "{ray:?}: prim {} is not on the face {axis} = {side}", got.0);
        let (u, v) = (got.2, got.3);
        assert!((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v) && u + v <= 1.0, "{ray:?}: barycentrics");
        check_against_oracle(&oracle, ray, *got, "face");
    }
}

#[test]
fn misses_give_minus_one_inf_zero_zero() {
    let dir = scratch("miss");
    let rays = [
        R::new([5.0, 5.0, 5.0], [0.0, 0.0, 1.0], 0.0, f32::INFINITY), // beside the cube
        R::new([0.5, 0.3, -5.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY), // pointing away
        R::new([0.5, 0.3, -5.0], [0.0, 0.0, 1.0], 0.0, 3.5),          // stops short
        R::new([0.5, 0.3, -5.0], [0.0, 0.0, 1.0], 6.5, f32::INFINITY), // starts past it
    ];
    std::fs::write(dir.join("rays.txt"), text_rays(&rays)).unwrap();
    let stdout = rttest_ok(&dir, &["raycast", "--scene", "cube", "--rays", "rays.txt"]);
    assert_eq!(String::from_utf8(stdout).unwrap(), "-1 inf 0 0\n".repeat(4));
    let stdout = rttest_ok(&dir, &["raycast", "--scene", "cube", "--rays", "rays.txt", "--any-hit"]);
    assert_eq!(String::from_utf8(stdout).unwrap(), "0\n".repeat(4));
}

#[test]
fn binary_input_and_output_match_text() {
    let dir = scratch("binary");
    let rays = random_rays(2000, 7);
    std::fs::write(dir.join("rays.txt"), text_rays(&rays)).unwrap();
    std::fs::write(dir.join("rays.bin"), binary_rays(&rays)).unwrap();
    std::fs::write(dir.join("rays.dat"), binary_rays(&rays)).unwrap();
    let text = parse_text_results(&rttest_ok(&dir, &["raycast", "--scene", "cube", "--rays", "rays.txt"]));
    assert_eq!(text.len(), rays.len());
    assert!(text.iter().any(|r| r.0 >= 0) && text.iter().any(|r| r.0 < 0), "both hits and misses");

    // Binary in (by extension), text out.
    let from_bin = parse_text_results(&rttest_ok(&dir, &["raycast", "--scene", "cube", "--rays", "rays.bin"]));
    // Binary in (by --format), binary out (by extension).
    rttest_ok(
        &dir,
        &[
            "raycast",
            "--scene",
            "cube",
            "--rays",
            "rays.dat",
            "--format",
            "binary",
            "--out",
            "out.bin",
            "--threads",
            "3",
        ],
    );
    let bin_bin = parse_binary_results(&std::fs::read(dir.join("out.bin")).unwrap());
    // Text in, binary out on stdout (by --out-format).
    let text_bin = parse_binary_results(&rttest_ok(
        &dir,
        &["raycast", "--scene", "cube", "--rays", "rays.txt", "--out-format", "binary"],
    ));
    let bits = |v: &[Res]| v.iter().map(|r| (r.0, r.1.to_bits(), r.2.to_bits(), r.3.to_bits())).collect::<Vec<_>>();
    assert_eq!(bits(&from_bin), bits(&text));
    assert_eq!(bits(&bin_bin), bits(&text));
    assert_eq!(bits(&text_bin), bits(&text));

    // Any hit: one line 0/1 in text, one byte 0/1 in binary, the same answers.
    let any_text = rttest_ok(&dir, &["raycast", "--scene", "cube", "--rays", "rays.txt", "--any-hit"]);
    let any_bin =
        rttest_ok(&dir, &["raycast", "--scene", "cube", "--rays", "rays.bin", "--any-hit", "--out-format", "binary"]);
    let any_text: Vec<u8> = String::from_utf8(any_text).unwrap().lines().map(|l| l.parse().unwrap()).collect();
    assert_eq!(any_bin, any_text);
    let closest: Vec<u8> = text.iter().map(|r| u8::from(r.0 >= 0)).collect();
    assert_eq!(any_text, closest);
}

#[test]
fn stdin_rays_and_comments() {
    let dir = scratch("stdin");
    let mut child = Command::new(env!("CARGO_BIN_EXE_rttest"))
        .args(["raycast", "--scene", "cube", "--rays", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .current_dir(&dir)
        .spawn()
        .expect("run rttest");
    {
        use std::io::Write;
        let mut stdin = child.stdin.take().unwrap();
        stdin.write_all(b"\n  # comment\n0.5 0.3 -5 0 0 1 0 inf\r\n\n5 5 5 0 0 1 0 INF").unwrap();
    }
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success());
    let results = parse_text_results(&out.stdout);
    assert_eq!(results.len(), 2);
    assert_eq!(results[0].1, 4.0);
    assert_eq!(results[1], (-1, f32::INFINITY, 0.0, 0.0));
}

#[test]
fn a_bad_line_is_a_one_line_error_with_its_number() {
    let dir = scratch("bad");
    let good = "0.5 0.3 -5 0 0 1 0 inf";
    let cases = [
        ("0 0 0 1 0 0 0", "expected 8 numbers"),
        ("0 0 0 1 0 0 0 1 1", "found 9"),
        ("0 0 zero 1 0 0 0 1", "field 3 'zero' is not a number"),
        ("nan 0 0 1 0 0 0 1", "origin"),
        ("0 inf 0 1 0 0 0 1", "origin"),
        ("0 0 0 0 0 0 0 1", "direction"),
        ("0 0 0 1 nan 0 0 1", "direction"),
        ("0 0 0 1 0 0 2 1", "interval"),
        ("0 0 0 1 0 0 nan 1", "interval"),
    ];
    for (bad, reason) in cases {
        let text = format!("# header\n{good}\n\n{good}\n{bad}\n{good}\n");
        std::fs::write(dir.join("rays.txt"), text).unwrap();
        for extra in [&[][..], &["--any-hit"][..], &["--json", "--out", "out.txt"][..]] {
            let mut args = vec!["raycast", "--scene", "cube", "--rays", "rays.txt"];
            args.extend_from_slice(extra);
            let out = rttest(&dir, &args);
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(1), "'{bad}': {stderr}");
            assert!(out.stdout.is_empty(), "'{bad}': nothing on stdout");
            assert_eq!(stderr.lines().count(), 1, "'{bad}': one line: {stderr}");
            assert!(stderr.starts_with("rttest: error: rays.txt:5: "), "'{bad}': {stderr}");
            assert!(stderr.contains(reason), "'{bad}' should say '{reason}': {stderr}");
            assert!(!dir.join("out.txt").exists(), "no results file for a rejected ray list");
        }
    }
}

#[test]
fn bad_binary_files_and_arguments_are_one_line_errors() {
    let dir = scratch("badbin");
    let mut bytes = binary_rays(&[R::new([0.5, 0.3, -5.0], [0.0, 0.0, 1.0], 0.0, f32::INFINITY)]);
    std::fs::write(dir.join("rays.bin"), &bytes[..31]).unwrap();
    let check = |args: &[&str], want: &str| {
        let out = rttest(&dir, args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: one line: {stderr}");
        assert!(stderr.starts_with("rttest: error: ") && stderr.contains(want), "{args:?}: {stderr}");
    };
    check(&["raycast", "--scene", "cube", "--rays", "rays.bin"], "rays.bin: size 31 bytes is not a multiple of 32");
    bytes.extend(binary_rays(&[R::new([0.0; 3], [1.0, 0.0, 0.0], 0.0, 1.0)]));
    bytes[32 + 12..32 + 16].copy_from_slice(&0.0f32.to_le_bytes()); // zero direction in ray 1
    std::fs::write(dir.join("rays.bin"), &bytes).unwrap();
    check(&["raycast", "--scene", "cube", "--rays", "rays.bin"], "rays.bin: ray 1 at byte 32: ray direction");
    check(&["raycast", "--scene", "cube", "--rays", "missing.txt"], "missing.txt: cannot open");
    std::fs::write(dir.join("rays.txt"), "0.5 0.3 -5 0 0 1 0 inf\n").unwrap();
    check(&["raycast", "--scene", "cube", "--rays", "rays.txt", "--json"], "--out");
    check(&["raycast", "--scene", "no-such-scene", "--rays", "rays.txt"], "no-such-scene");
    check(&["raycast", "--scene", "cube", "--rays", "rays.txt", "--format", "csv"], "csv");
}

#[test]
fn json_summary_goes_to_stdout_and_results_to_out() {
    let dir = scratch("json");
    let rays = random_rays(500, 3);
    std::fs::write(dir.join("rays.txt"), text_rays(&rays)).unwrap();
    let stdout = rttest_ok(&dir, &["raycast", "--scene", "cube", "--rays", "rays.txt", "--out", "res.txt", "--json"]);
    let stdout = String::from_utf8(stdout).unwrap();
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    for k in ["scene", "rays", "hits", "trace_secs", "mrays_per_s", "method", "any_hit", "intersector", "threads"] {
        assert!(v.get(k).is_some(), "key {k} missing from {v}");
    }
    assert_eq!(v["scene"], "cube");
    assert_eq!(v["rays"], 500);
    assert_eq!(v["method"], "mono");
    assert_eq!(v["any_hit"], false);
    let results = parse_text_results(&std::fs::read(dir.join("res.txt")).unwrap());
    assert_eq!(v["hits"], results.iter().filter(|r| r.0 >= 0).count() as u64);
    let stdout = rttest_ok(
        &dir,
        &["raycast", "--scene", "cube", "--rays", "rays.txt", "--out", "any.txt", "--json", "--any-hit"],
    );
    let w: serde_json::Value = serde_json::from_str(String::from_utf8(stdout).unwrap().trim()).unwrap();
    assert_eq!(w["any_hit"], true);
    assert_eq!(w["hits"], v["hits"]);
}

/// 10k random rays, closest and any hit, both intersectors: the tool agrees with the
/// brute-force oracle over the cube's triangles, distances compared exactly.
#[test]
fn random_rays_agree_with_the_brute_force_oracle() {
    let dir = scratch("oracle");
    let tris = cube_triangles();
    let rays = random_rays(10_000, 0x9e37_79b9_7f4a_7c15);
    std::fs::write(dir.join("rays.txt"), text_rays(&rays)).unwrap();
    for (name, intersector) in [("wald", Intersector::Wald), ("watertight", Intersector::Watertight)] {
        let oracle = BruteForce::new(&tris, intersector);
        let args = ["raycast", "--scene", "cube", "--rays", "rays.txt", "--intersector", name];
        let results = parse_text_results(&rttest_ok(&dir, &args));
        assert_eq!(results.len(), rays.len());
        let mut hits = 0;
        for (ray, got) in rays.iter().zip(&results) {
            check_against_oracle(&oracle, ray, *got, name);
            hits += usize::from(got.0 >= 0);
        }
        assert!(hits > 1000 && hits < 9000, "{name}: a mix of hits and misses ({hits})");

        let mut any_args = args.to_vec();
        any_args.push("--any-hit");
        let any = String::from_utf8(rttest_ok(&dir, &any_args)).unwrap();
        let any: Vec<bool> = any.lines().map(|l| l == "1").collect();
        let want: Vec<bool> = rays.iter().map(|r| oracle.intersect(&r.ray()).is_some()).collect();
        assert_eq!(any, want, "{name}: any hit is closest.is_some()");
    }
}
