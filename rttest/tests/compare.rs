//! `rttest compare` end to end, and (with the `embree` feature) Embree against our single-ray
//! traversal on the built-in scenes and the shared scenes: the same primitive, or a tie (the
//! same distance: at a shared edge or vertex, where two surfaces meet, or on coincident
//! coplanar faces), on every pixel but at most 0.01%, and the same primitive on at least
//! 99.99% of the pixels outside coincident faces.
//!
//! At 256x256 three rays disagree at another distance (each counted twice, for Embree's
//! single rays and its 16-packets: 2 of 393,216 pixels on atrium-rotated, 2 of 262,144 on
//! Sponza, 2 of 131,072 on the bunny). Exact arithmetic decides them
//! (`embree_disagreements_at_another_distance_decided_exactly`): each ray passes just inside
//! a triangle by an edge it shares with another, and one side misses both. On atrium-rotated
//! Embree does (6.1e-6 inside triangle 2817; ours names its neighbour 2814, 9 ulp before it,
//! an artefact the oracle accepts); on Sponza (1.4e-6 inside 56080) and the bunny (1.0e-8
//! inside 19252) Wald's `f32` test does, and Embree is right. Our watertight test names the
//! exact first triangle on all three.

mod common;

use common::rttest;

#[test]
fn compare_json_has_one_object_per_method() {
    let dir = common::scratch("compare", "json");
    let out = rttest(
        &dir,
        &[
            "compare",
            "--scene",
            "touching-boxes",
            "--size",
            "24x20",
            "--rounds",
            "2",
            "--build-rounds",
            "1",
            "--methods",
            "mono,packet,mft-8,cone-8",
            "--tiles",
            "8",
            "--json",
            "--threads",
            "2",
        ],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let rows: Vec<serde_json::Value> = stdout.lines().map(|l| serde_json::from_str(l).expect("JSON line")).collect();
    let methods: Vec<&str> = rows.iter().map(|r| r["method"].as_str().unwrap()).collect();
    assert_eq!(methods, ["mono", "packet", "mft-8", "cone-8"]);
    for r in &rows {
        for key in ["build_ms", "primary_mrays_per_s", "shadow_mrays_per_s", "soft16_mrays_per_s", "prim_mismatch"] {
            assert!(r.get(key).is_some(), "{key} missing in {r}");
        }
        assert!(r["primary_mrays_per_s"].as_f64().unwrap() > 0.0);
        // Our packet methods run the single-ray triangle test: ties at most.
        assert_eq!(r["prim_mismatch"], r["prim_ties"], "{r}");
    }
}

#[test]
fn compare_text_and_bad_requests() {
    let dir = common::scratch("compare", "text");
    let out = rttest(
        &dir,
        &["compare", "--scene", "cube", "--size", "16x16", "--rounds", "1", "--methods", "ours", "--no-soft"],
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("| mono |") && text.contains("| mft-cone-16 |"), "{text}");

    let out = rttest(&dir, &["compare", "--scene", "cube", "--methods", "nonsense"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown method"));
    let out = rttest(&dir, &["compare", "--scene", "cube", "--size", "16x16", "--tiles", "6"]);
    assert!(!out.status.success());

    // Embree asked for: a hint how to enable it without the feature, a row with it.
    let out =
        rttest(&dir, &["compare", "--scene", "cube", "--size", "16x16", "--rounds", "1", "--methods", "embree-16"]);
    if cfg!(feature = "embree") {
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        assert!(String::from_utf8_lossy(&out.stdout).contains("| embree-16 |"));
    } else {
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--features embree") && err.contains("libembree-dev"), "{err}");
    }
}

#[cfg(feature = "embree")]
mod embree {
    use baselines::embree::{BuildQuality, Coherence, Device, EmbreeScene, Packet16};
    use baselines::embree_blocks::{EmbreeBlocks, EmbreeSingle};
    use experiments::compare::mismatches;
    use kdtree::NoCounters;
    use trace::method::primary_ray;
    use trace::{SingleRays, TileLayout};

    /// The frame driver's primary pass, uncounted.
    fn primary_pass<M: trace::Method>(
        m: &M,
        camera: &scenes::Camera,
        layout: &TileLayout,
        out: &mut [Option<kdtree::Hit>],
    ) {
        let (_, NoCounters) = trace::frame::primary_pass(m, layout, camera, out);
    }
    use kdtree::oracle::segment_meets_triangle;
    use kdtree::{BruteForce, BuildConfig, Intersector, KdTree};

    /// Embree (single rays and 16-packets, high-quality BVH) against our single rays on the
    /// views of `spec` at 256x256: returns (pixels, mismatches, ties, ties on coincident faces).
    fn agreement(spec: &str) -> (u64, u64, u64, u64) {
        let scene = scenes::load_scene(spec).unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let device = Device::new(None).unwrap();
        let emb =
            EmbreeScene::build(&device, &scene.mesh.positions, &scene.mesh.triangles, BuildQuality::High).unwrap();
        let mut totals = (0, 0, 0, 0);
        for view in &scene.views {
            let camera = view.camera(256, 256).unwrap();
            let layout = TileLayout::new(256, 256, 16);
            let mut ours = vec![None; layout.pixel_count()];
            primary_pass(&SingleRays(&tree), &camera, &layout, &mut ours);
            let ours = layout.to_row_major(&ours);
            let mut single = vec![None; layout.pixel_count()];
            primary_pass(
                &SingleRays(EmbreeSingle { scene: &emb, coherence: Coherence::Coherent }),
                &camera,
                &layout,
                &mut single,
            );
            let mut packets = vec![None; layout.pixel_count()];
            primary_pass(&EmbreeBlocks::<Packet16>::new(&emb, Coherence::Coherent), &camera, &layout, &mut packets);
            for got in [single, packets] {
                let m = mismatches(&scene, &camera, &ours, &layout.to_row_major(&got));
                eprintln!("{spec} {}: {m:?}", view.name);
                totals.0 += ours.len() as u64;
                totals.1 += m.prim_mismatch;
                totals.2 += m.prim_ties;
                totals.3 += m.prim_coincident;
            }
        }
        totals
    }

    fn check(spec: &str) {
        let (pixels, mismatch, ties, coincident) = agreement(spec);
        eprintln!("{spec}: {pixels} pixels, {mismatch} mismatches: {ties} ties, {coincident} on coincident faces");
        assert!((mismatch - ties) * 10_000 <= pixels, "{spec}: {} disagreements are not ties", mismatch - ties);
        let (pixels, mismatch) = (pixels - coincident, mismatch - coincident);
        assert!(mismatch * 10_000 <= pixels, "{spec}: {mismatch} of {pixels} pixels disagree");
    }

    #[test]
    fn embree_agrees_on_the_built_in_scenes() {
        for spec in ["atrium", "arena", "atrium-rotated", "grove", "touching-boxes", "sphere"] {
            check(spec);
        }
    }

    #[test]
    fn embree_agrees_on_the_shared_scenes() {
        let Some(dir) = scenes::shared_scenes_dir() else {
            eprintln!("no shared scenes folder: skipped");
            return;
        };
        let mut files: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.to_string_lossy().ends_with(".obj.gz") || p.to_string_lossy().ends_with(".obj"))
            .collect();
        files.sort();
        assert!(!files.is_empty());
        for f in files {
            check(&f.to_string_lossy());
        }
    }

    /// Which side passes between the two triangles of an edge.
    #[derive(PartialEq)]
    enum Leak {
        Embree,
        /// Our default, Wald's test.
        Wald,
        /// Neither: both name `first` (Wald's test leaked here while its record stored the
        /// plane offset instead of vertex `a`).
        Neither,
    }

    /// One of the three rays on which Embree and our single rays name triangles at different
    /// distances (each counted twice in [`agreement`]: Embree's single rays and 16-packets
    /// answer alike). Each passes, in exact arithmetic, just inside triangle `first`, by the
    /// edge it shares with `neighbour`, and one side misses both. Bit patterns of `f32`s;
    /// hits are `(prim, t)`.
    struct Disagreement {
        /// A built-in scene, or a file of the shared scenes folder.
        scene: &'static str,
        shared: bool,
        /// The pixel of the `default` view at 256x256.
        pixel: (u32, u32),
        origin: [u32; 3],
        dir: [u32; 3],
        /// The triangle the exact ray meets first, and the `f32` just above its exact
        /// distance `t*` (so `t*` lies in `(prev(t_above), t_above]`).
        first: u32,
        t_above: u32,
        /// The triangle across the edge from `first`.
        neighbour: u32,
        /// Our hit (the default, Wald's test), and Embree's (single rays and 16-packets).
        ours: (u32, u32),
        embree: (u32, u32),
        leak: Leak,
    }

    /// Atrium-rotated: the exact ray meets triangle 2817 first, at `t*` = 14.7696287, 6.1e-6
    /// inside the edge it shares with 2814 (a fold), and crosses 2814's plane 4.3e-7 outside
    /// 2814. Ours names 2817 at 14.769629, one ulp after `t*` (until Wald's record stored
    /// vertex `a` instead of the plane offset, it named 2814 at 14.76962, rounding the point
    /// into the other triangle of the edge); Embree misses both and reports 2808 at
    /// 14.921841, behind them.
    const ATRIUM: Disagreement = Disagreement {
        scene: "atrium-rotated",
        shared: false,
        pixel: (128, 203),
        origin: [0xc127_a37d, 0xbfda_9f06, 0x40c4_c235],
        dir: [0x3f67_e39b, 0x3e13_64e8, 0xbecc_041f],
        first: 2817,
        t_above: 0x416c_5067,
        neighbour: 2814,
        ours: (2817, 0x416c_5068),
        embree: (2808, 0x416e_bfdc),
        leak: Leak::Embree,
    };

    /// Sponza: the exact ray meets triangle 56080 first, at `t*` = 11.7408734, 1.41e-6 inside
    /// the edge it shares with 56079 (barycentric 7.6e-5). Embree is right, and so is ours
    /// since Wald's record stores vertex `a`: with the plane offset stored, Wald's test put
    /// the hit point about 1e-6 (one ulp of the origin's 10) off, just outside (beta =
    /// -1.13e-6), missed 56079 too, and reported 54951 behind, at 11.822466.
    const SPONZA: Disagreement = Disagreement {
        scene: "sponza-dabrovic.obj.gz",
        shared: true,
        pixel: (84, 47),
        origin: [0xc120_0000, 0x4040_0000, 0x0000_0000],
        dir: [0x3f59_c19a, 0x3ef6_2d2b, 0xbe59_e640],
        first: 56080,
        t_above: 0x413b_da9f,
        neighbour: 56079,
        ours: (56080, 0x413b_da9e),
        embree: (56080, 0x413b_da9e),
        leak: Leak::Neither,
    };

    /// The bunny: the exact ray meets triangle 19252 first, at `t*` = 0.216668254, 1.0e-8
    /// inside the edge it shares with 19072 (barycentric 1.0e-5). Embree is right, and so is
    /// ours since Wald's record stores vertex `a`: with the plane offset stored, Wald's test
    /// put the hit point about 1e-8 (under one ulp of the coordinates, 0.2) off, just outside
    /// (beta + gamma = 1 + 1.3e-6), missed 19072 too, and reported 57194 behind, at
    /// 0.22956938.
    const BUNNY: Disagreement = Disagreement {
        scene: "stanford-bunny.obj.gz",
        shared: true,
        pixel: (86, 79),
        origin: [0x3d36_5aee, 0x3e3a_1a7a, 0x3e4f_defb],
        dir: [0xbed8_2171, 0xbe15_efe6, 0xbf65_069b],
        first: 19252,
        t_above: 0x3e5d_de49,
        neighbour: 19072,
        ours: (19252, 0x3e5d_de49),
        embree: (19252, 0x3e5d_de47),
        leak: Leak::Neither,
    };

    /// The hit as `(prim, t bits)`.
    fn bits(h: Option<kdtree::Hit>) -> Option<(u32, u32)> {
        h.map(|h| (h.prim, h.t.to_bits()))
    }

    /// Whether the exact ray `ray` meets triangle `prim` of `scene` in `[0, t_max]`.
    fn meets(scene: &scenes::Scene, ray: &kdtree::Ray, prim: u32, t_max: f32) -> bool {
        segment_meets_triangle(&scene.mesh.triangle(prim as usize), ray.origin, ray.dir, 0.0, t_max)
    }

    /// Checks `case`: its ray, what exact arithmetic says, and the answers of our Wald and
    /// watertight tests and of Embree (skipped without the shared scenes).
    fn decide(case: &Disagreement) {
        let spec = if case.shared {
            let Some(dir) = scenes::shared_scenes_dir() else {
                eprintln!("no shared scenes folder: {} skipped", case.scene);
                return;
            };
            dir.join(case.scene).to_string_lossy().into_owned()
        } else {
            case.scene.to_string()
        };
        let name = case.scene;
        let scene = scenes::load_scene(&spec).unwrap();
        let camera = scene.view("default").unwrap().camera(256, 256).unwrap();
        let ray = primary_ray(&camera, case.pixel.0, case.pixel.1);
        assert_eq!(ray.origin.to_array().map(f32::to_bits), case.origin, "{name}: origin");
        assert_eq!(ray.dir.to_array().map(f32::to_bits), case.dir, "{name}: direction");
        let (first, neighbour) =
            (scene.mesh.triangle(case.first as usize), scene.mesh.triangle(case.neighbour as usize));
        assert_eq!(first.iter().filter(|v| neighbour.contains(v)).count(), 2, "{name}: no shared edge");

        // Exact: `first` is met in `[0, t_above]`, not in `[0, prev(t_above)]`, and no other
        // triangle is met in `[0, t_above]`.
        let t_above = f32::from_bits(case.t_above);
        assert!(meets(&scene, &ray, case.first, t_above), "{name}: t* above t_above");
        assert!(!meets(&scene, &ray, case.first, t_above.next_down()), "{name}: t* below t_above");
        let others: Vec<u32> = (0..scene.mesh.triangle_count() as u32)
            .filter(|&i| i != case.first && meets(&scene, &ray, i, t_above))
            .collect();
        assert!(others.is_empty(), "{name}: met before t*: {others:?}");

        // Our answers, Wald's test (the default) and the watertight test.
        let build = |intersector| {
            let config = BuildConfig { intersector, ..BuildConfig::default() };
            KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &config).unwrap()
        };
        let (wald, watertight) = (build(Intersector::Wald), build(Intersector::Watertight));
        let ours = wald.intersect(&ray);
        assert_eq!(bits(ours), Some(case.ours), "{name}: ours (Wald's test)");
        assert_eq!(watertight.intersect(&ray).map(|h| h.prim), Some(case.first), "{name}: watertight");

        let device = Device::new(None).unwrap();
        let emb =
            EmbreeScene::build(&device, &scene.mesh.positions, &scene.mesh.triangles, BuildQuality::High).unwrap();
        assert_eq!(bits(emb.intersect(&ray, Coherence::Coherent)), Some(case.embree), "{name}: Embree");
        let layout = TileLayout::new(256, 256, 16);
        let mut packets = vec![None; layout.pixel_count()];
        primary_pass(&EmbreeBlocks::<Packet16>::new(&emb, Coherence::Coherent), &camera, &layout, &mut packets);
        let lane = layout.to_row_major(&packets)[(case.pixel.1 * 256 + case.pixel.0) as usize];
        assert_eq!(bits(lane), Some(case.embree), "{name}: Embree's 16-packets");

        // The verdicts: the side that leaks reports a hit past `t*` (so it missed `first`, met
        // in `[0, t]` of its hit) on neither triangle of the edge; the other side is right.
        let (right, wrong) = match case.leak {
            Leak::Embree => (case.ours, case.embree),
            Leak::Wald => (case.embree, case.ours),
            Leak::Neither => {
                assert_eq!((case.ours.0, case.embree.0), (case.first, case.first), "{name}: both right");
                return;
            }
        };
        let t_wrong = f32::from_bits(wrong.1);
        assert!(t_wrong > t_above && meets(&scene, &ray, case.first, t_wrong), "{name}: no leak");
        assert!(wrong.0 != case.first && wrong.0 != case.neighbour, "{name}: hit at the edge");
        assert!(!meets(&scene, &ray, wrong.0, f32::from_bits(right.1)), "{name}: {wrong:?} before {right:?}");
        if case.leak == Leak::Wald {
            // Embree names `first`; Wald's test hits neither triangle of the edge.
            assert_eq!(case.embree.0, case.first);
            let tris: Vec<_> = (0..scene.mesh.triangle_count()).map(|i| scene.mesh.triangle(i)).collect();
            let hits = BruteForce::new(&tris, Intersector::Wald).all_hits(&ray);
            assert!(hits.iter().all(|&(_, p)| p != case.first && p != case.neighbour), "{name}: {hits:?}");
        } else if case.ours.0 != case.first {
            // Ours names the neighbour, which the exact ray misses, no later than `t*`: a
            // rounding artefact of the test that the oracle accepts (the right surface).
            assert_eq!(case.ours.0, case.neighbour);
            assert!(!meets(&scene, &ray, case.neighbour, f32::INFINITY) && f32::from_bits(case.ours.1) <= t_above);
            assert!(BruteForce::for_tree(&wald).check(&ray, ours, true).is_ok());
        }
    }

    /// The three disagreements at another distance of [`agreement`] (as measured while Wald's
    /// record stored the plane offset), decided in exact arithmetic
    /// ([`segment_meets_triangle`]): each ray passes just inside one triangle by an edge it
    /// shares with another; on atrium-rotated Embree passes between them and ours is right, on
    /// Sponza and the bunny Wald's `f32` test did and Embree is right, and now both are. Our
    /// watertight test is right on all three.
    #[test]
    fn embree_disagreements_at_another_distance_decided_exactly() {
        for case in [&ATRIUM, &SPONZA, &BUNNY] {
            decide(case);
        }
    }
}
