//! The registry: names, tiles, per-point soft shadows and kernel names of bound methods
//! ([`trace::registry`]).

use packets::LaneWidth;
use trace::setup::load_and_build;
use trace::{Options, Registry, SimdLevel, SoftGrouping, Structures};

#[test]
fn names_resolve_with_and_without_tiles() {
    let r = Registry::ours();
    let o = Options::default();
    assert_eq!(r.select("mft-8", o).unwrap().options.tile, 8);
    assert_eq!(r.select("mft-8", o).unwrap().name, "mft-8");
    assert_eq!(r.select("mft", o).unwrap().name, "mft-16");
    assert_eq!(r.select("mft-cone-16", o).unwrap().name, "mft-cone-16");
    assert_eq!(r.entry(r.select("mft-cone-16", o).unwrap().entry).name, "mft-cone");
    assert_eq!(r.select("mono", o).unwrap().name, "mono");
    assert!(r.select("mono-8", o).is_err());
    let e = r.select("nonsense", o).unwrap_err().to_string();
    assert!(e.contains("mft[-N]") && e.contains("mono"), "{e}");
    let names = r.names(&[8, 16]);
    assert_eq!(names[..3], ["mono", "packet", "samesign"]);
    // Only the tiles a method takes: 16 regions of whole 2x2 packets need a multiple of 8.
    let names = r.names(&[4, 8]);
    assert!(names.iter().any(|n| n == "mft-4") && names.iter().any(|n| n == "mft-x16-8"));
    assert!(!names.iter().any(|n| n == "mft-x16-4"));
    assert!(names.contains(&"mft-cone-8".to_string()));
}

#[test]
fn a_bad_tile_is_an_error_naming_the_method() {
    let (_, tree, _) = load_and_build("cube", &Default::default()).unwrap();
    let s = Structures::new(&tree);
    let r = Registry::ours();
    let bad = r.select("mft-6", Options::default()).unwrap();
    assert!(r.bind(&bad, &s).unwrap_err().to_string().starts_with("mft-6:"));
    let good = r.select("mono", Options { tile: 7, ..Options::default() }).unwrap();
    assert!(r.bind(&good, &s).is_ok());
}

#[test]
fn per_point_soft_shadows_name_their_kernel_or_are_refused() {
    let (_, tree, _) = load_and_build("cube", &Default::default()).unwrap();
    let s = Structures::new(&tree);
    let r = Registry::ours();
    let per_point = Options { soft: SoftGrouping::PerPoint, ..Options::default() };
    let soft = |method: &str, o: Options| r.bind(&r.select(method, o).unwrap(), &s).unwrap().kernels.soft;
    // The stratum packets are as wide as the method's SIMD level: 2x2 at `sse4.1`.
    let wide = packets::Width::for_level(Options::default().simd).suffix();
    let sse = Options { simd: SimdLevel::Sse41, ..Options::default() };
    for (method, strata, thesis) in [
        ("packet", "kd-stratum-packets", "kd-pyramid"),
        ("mft-8", "kd-stratum-packets", "kd-pyramid"),
        ("cone-16", "kd-stratum-packets", "kd-cone"),
    ] {
        assert_eq!(soft(method, sse), strata);
        assert_eq!(soft(method, Options::default()), format!("{strata}{wide}"));
        assert_eq!(soft(method, per_point), thesis);
    }
    for method in ["mono", "multi-frusta-16", "mbvh-8"] {
        let e = r.select(method, per_point).unwrap_err().to_string();
        assert!(e.contains("no per-point") && e.contains("packet, samesign"), "{e}");
    }
}

/// Each bound method names its kernels from the kernels themselves: the tile of a
/// frustum kernel is its own field.
#[test]
fn kernels_are_named_by_their_identity() {
    let (_, tree, _) = load_and_build("cube", &Default::default()).unwrap();
    let s = Structures::new(&tree);
    let r = Registry::ours();
    let kernels = |method: &str| r.bind(&r.select(method, Options::default()).unwrap(), &s).unwrap().kernels;
    let k = kernels("multi-frusta-8@sse");
    assert_eq!(
        (k.primary.as_str(), k.shadow.as_str(), k.soft.as_str()),
        ("kd-mft-8", "kd-frusta-8", "kd-multi-frusta-8")
    );
    // The primary packets are as wide as the SIMD level (4x4 pixels at avx512), but a
    // 4-pixel tile keeps 2x2 packets.
    let wide = packets::Width::for_level(SimdLevel::active()).suffix();
    assert_eq!(kernels("multi-frusta-8").primary, format!("kd-mft-8{wide}"));
    assert_eq!(kernels("mft-4").primary, "kd-mft-4");
    assert_eq!(k.stream, "kd-mft-runs");
    let k = kernels("mono");
    assert_eq!([k.primary, k.shadow, k.soft, k.stream], ["kd-single"; 4]);
    let k = kernels("lane-frusta-16");
    let lanes = match LaneWidth::widest() {
        LaneWidth::Eight => "kd-lane-frusta".to_string(),
        w => format!("kd-lane-frusta-x{}", w.lanes()),
    };
    assert_eq!((k.shadow.as_str(), k.soft.as_str()), (lanes.as_str(), lanes.as_str()));
    if LaneWidth::widest() == LaneWidth::Sixteen {
        assert_eq!(kernels("lane-frusta-16@avx2").shadow, "kd-lane-frusta");
    }
    let k = kernels("packet@sse");
    assert_eq!(
        (k.primary.as_str(), k.shadow.as_str(), k.stream.as_str()),
        ("kd-omni-packets", "kd-packets", "kd-omni-packets")
    );
    // At a wider level the shadow packets widen and say so; the lane frusta narrow.
    let k = kernels("packet");
    let wide = packets::Width::for_level(SimdLevel::active()).suffix();
    assert_eq!(k.shadow, format!("kd-packets{wide}"));
    if SimdLevel::active() >= SimdLevel::Avx2 {
        // 16 lanes at `avx2` (two registers), 8 where the method asks for them.
        assert_eq!(kernels("packet@avx2").shadow, "kd-packets-w16");
        assert_eq!(kernels("packet@w8").shadow, "kd-packets-w8");
        assert_eq!(kernels("packet@avx2@w8").shadow, "kd-packets-w8");
        assert_eq!(kernels("mft-16@w8").primary, "kd-mft-16-w8");
        assert_eq!(kernels("packet@w4").shadow, "kd-packets");
        assert_eq!(kernels("lane-frusta-16@sse").shadow, "kd-lane-frusta-x4");
    }
    // Wider packets than the level runs are an error naming the width.
    let sse_w8 = r.select("packet@sse@w8", Options::default()).unwrap();
    let e = r.bind(&sse_w8, &s).unwrap_err().to_string();
    assert!(e.contains("w8") && e.contains("avx2"), "{e}");
    for bad in ["packet@w12", "packet@w", "packet@fast"] {
        let e = r.select(bad, Options::default()).unwrap_err().to_string();
        assert!(e.contains(bad), "{e}");
    }
    let k = kernels("cone-4");
    assert_eq!((k.primary.as_str(), k.stream.as_str()), ("kd-cone-4", "kd-cone-runs"));
}

/// The long help lists every entry with its summary, one line each.
#[test]
fn summaries_list_every_entry() {
    let r = Registry::ours();
    let help = r.summaries();
    assert_eq!(help.lines().count(), r.entries().len());
    for name in ["mono", "multi-frusta[-N]", "lane-frusta[-N]", "mbvh-4", "mbvh-8", "mft-cone[-N]"] {
        assert!(help.lines().any(|l| l.starts_with(name)), "{name}: {help}");
    }
}
