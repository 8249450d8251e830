//! Tree files (`kdtree::treefile`): build -> save -> load gives the same tree bit for bit, and
//! every kind of damage is refused with its own error, without a panic.

use kdtree::treefile::{self, Checks, TreeFileError};
use kdtree::{BuildConfig, BuildStrategy, Intersector, KdTree};
use scenes::Mesh;

/// Header layout (see the module docs): bytes 0..8 magic, 8 version, 12 intersector,
/// 16 c_trav, 20 c_isect, 24 empty_bonus, 28 max_depth, 32 strategy, 36 bins, 40 min_tris,
/// 44 leaf_width, 48 max_bad_refines, 52 collapse, 56 triangle count, 64 scene hash, 72..96
/// bounds; the node section starts at 96 (tag, size, count), nodes at 112.
const HEADER_FIELDS: [(usize, &str); 16] = [
    (0, "magic"),
    (8, "version"),
    (12, "intersector"),
    (16, "c_trav"),
    (20, "c_isect"),
    (24, "empty_bonus"),
    (28, "max_depth"),
    (32, "strategy"),
    (36, "bins"),
    (40, "min_tris"),
    (44, "leaf_width"),
    (48, "max_bad_refines"),
    (52, "collapse"),
    (56, "triangle count"),
    (64, "scene hash"),
    (72, "bounds"),
];
const BOUNDS: usize = 72;
const NODE_SECTION: usize = 96;
const FIRST_NODE: usize = 112;

fn mesh(name: &str) -> Mesh {
    scenes::builtin::by_name(name).unwrap().mesh
}

fn config(intersector: Intersector) -> BuildConfig {
    BuildConfig { intersector, ..BuildConfig::default() }
}

fn build(mesh: &Mesh, config: &BuildConfig) -> KdTree {
    KdTree::build(&mesh.positions, &mesh.triangles, config).unwrap()
}

fn save(mesh: &Mesh, tree: &KdTree) -> Vec<u8> {
    treefile::to_bytes(tree, &mesh.positions, &mesh.triangles).unwrap()
}

fn load(bytes: &[u8], mesh: &Mesh, config: &BuildConfig) -> Result<KdTree, TreeFileError> {
    treefile::from_bytes(bytes, &mesh.positions, &mesh.triangles, config, Checks::Full)
}

fn bits<T: Copy, const N: usize>(v: &[T], f: impl Fn(&T) -> [u32; N]) -> Vec<[u32; N]> {
    v.iter().map(f).collect()
}

/// Every array and value of the two trees, compared by bits.
fn assert_identical(a: &KdTree, b: &KdTree) {
    assert_eq!(a.nodes(), b.nodes());
    assert_eq!(a.prim_refs(), b.prim_refs());
    let boxes = |t: &KdTree| [t.bounds().min.to_array(), t.bounds().max.to_array()].concat().map_bits();
    assert_eq!(boxes(a), boxes(b));
    assert_eq!(a.intersector(), b.intersector());
    let wald = |r: &kdtree::triangle::WaldTriangle| {
        [r.kuv, r.n_u.to_bits(), r.n_v.to_bits(), r.a_k.to_bits(), r.a_u.to_bits(), r.a_v.to_bits()]
    };
    let wald_rest = |r: &kdtree::triangle::WaldTriangle| [r.b_nu, r.b_nv, r.c_nu, r.c_nv].map(f32::to_bits);
    assert_eq!(bits(a.wald_records(), wald), bits(b.wald_records(), wald));
    assert_eq!(bits(a.wald_records(), wald_rest), bits(b.wald_records(), wald_rest));
    let wt = |r: &kdtree::triangle::WatertightTriangle| {
        let [p, q, s] = r.v;
        [p.x, p.y, p.z, q.x, q.y, q.z, s.x, s.y, s.z].map(f32::to_bits)
    };
    assert_eq!(bits(a.watertight_records(), wt), bits(b.watertight_records(), wt));
    assert_eq!(a.triangle_count(), b.triangle_count());
    for t in 0..a.triangle_count() as u32 {
        let v = |tree: &KdTree| tree.triangle(t).map(|p| p.to_array().map(f32::to_bits));
        assert_eq!(v(a), v(b));
    }
    let terms = |t: &KdTree| {
        let c = t.config();
        (
            (c.c_trav.to_bits(), c.c_isect.to_bits(), c.empty_bonus.to_bits(), c.max_depth, c.intersector),
            (c.leaf_width, c.max_bad_refines, c.collapse),
        )
    };
    assert_eq!(terms(a), terms(b));
}

trait MapBits {
    fn map_bits(self) -> Vec<u32>;
}

impl MapBits for Vec<f32> {
    fn map_bits(self) -> Vec<u32> {
        self.into_iter().map(f32::to_bits).collect()
    }
}

#[test]
fn round_trips_are_bit_identical_for_both_intersectors() {
    for name in ["cube", "sphere", "touching-boxes", "axis-plane-triangle", "arena", "atrium-rotated"] {
        let mesh = mesh(name);
        for intersector in [Intersector::Wald, Intersector::Watertight] {
            let config = config(intersector);
            let tree = build(&mesh, &config);
            let bytes = save(&mesh, &tree);
            let loaded = load(&bytes, &mesh, &config).unwrap_or_else(|e| panic!("{name} {intersector:?}: {e}"));
            assert_identical(&tree, &loaded);
            assert_eq!(loaded.build_peak_bytes(), None);
            // Saving the loaded tree gives the same bytes.
            assert_eq!(save(&mesh, &loaded), bytes, "{name} {intersector:?}");
        }
    }
}

#[test]
fn non_default_terms_round_trip_and_must_match() {
    let mesh = mesh("sphere");
    let config = BuildConfig { c_isect: 3.0, empty_bonus: 0.25, max_depth: Some(7), ..BuildConfig::default() };
    let tree = build(&mesh, &config);
    let bytes = save(&mesh, &tree);
    assert_identical(&tree, &load(&bytes, &mesh, &config).unwrap());
    for (other, field) in [
        (BuildConfig { c_isect: 5.0, ..config.clone() }, "c_isect"),
        (BuildConfig { c_trav: 2.0, ..config.clone() }, "c_trav"),
        (BuildConfig { empty_bonus: 0.0, ..config.clone() }, "empty_bonus"),
        (BuildConfig { max_depth: None, ..config.clone() }, "max_depth"),
    ] {
        let e = load(&bytes, &mesh, &other).unwrap_err();
        assert!(matches!(&e, TreeFileError::ConfigMismatch { field: f, .. } if *f == field), "{e}");
    }
    // The memory budget is not part of the tree.
    assert!(load(&bytes, &mesh, &BuildConfig { memory_budget: Some(1), ..config.clone() }).is_ok());
}

/// The leaf width and the termination rules are in the header: a tree built with them
/// round-trips, loads only with the same terms, and damaged fields are refused.
#[test]
fn the_leaf_width_and_termination_round_trip_and_must_match() {
    let mesh = mesh("sphere");
    let config = BuildConfig { leaf_width: 4, max_bad_refines: 2, collapse: true, ..BuildConfig::default() };
    let tree = build(&mesh, &config);
    let bytes = save(&mesh, &tree);
    assert_eq!([word(&bytes, 44), word(&bytes, 48), word(&bytes, 52)], [4, 2, 1]);
    assert_identical(&tree, &load(&bytes, &mesh, &config).unwrap());
    for (other, field) in [
        (BuildConfig { leaf_width: 8, ..config.clone() }, "leaf_width"),
        (BuildConfig { max_bad_refines: 0, ..config.clone() }, "max_bad_refines"),
        (BuildConfig { collapse: false, ..config.clone() }, "collapse"),
    ] {
        let e = load(&bytes, &mesh, &other).unwrap_err();
        assert!(matches!(&e, TreeFileError::ConfigMismatch { field: f, .. } if *f == field), "{e}");
    }
    for (at, v) in [(44, 0), (44, BuildConfig::MAX_LEAF_WIDTH + 1), (48, BuildConfig::MAX_BAD_REFINES + 1), (52, 2)] {
        let mut b = bytes.clone();
        set_word(&mut b, at, v);
        treefile::reseal(&mut b);
        let e = load(&b, &mesh, &config).unwrap_err();
        assert!(matches!(&e, TreeFileError::BadConfig(_)), "{at} = {v}: {e}");
    }
    // The default tree's file records width 1, no bad refines, no collapse.
    let plain = save(&mesh, &build(&mesh, &BuildConfig::default()));
    let d = BuildConfig::default();
    assert_eq!(
        [word(&plain, 44), word(&plain, 48), word(&plain, 52)],
        [d.leaf_width, d.max_bad_refines, u32::from(d.collapse)]
    );
}

/// The build strategy is in the header: a binned tree round-trips, loads only as the same
/// strategy with the same parameters, and a damaged strategy field is refused.
#[test]
fn the_build_strategy_round_trips_and_must_match() {
    let mesh = mesh("sphere");
    let binned = BuildStrategy::Binned { bins: 32, min_tris: 100 };
    let config = BuildConfig { strategy: binned, ..BuildConfig::default() };
    let tree = build(&mesh, &config);
    let bytes = save(&mesh, &tree);
    assert_identical(&tree, &load(&bytes, &mesh, &config).unwrap());
    for other in [
        BuildStrategy::Exact,
        BuildStrategy::Binned { bins: 33, min_tris: 100 },
        BuildStrategy::Binned { bins: 32, min_tris: 99 },
    ] {
        let e = load(&bytes, &mesh, &BuildConfig { strategy: other, ..config.clone() }).unwrap_err();
        assert!(matches!(&e, TreeFileError::ConfigMismatch { field: "strategy", .. }), "{e}");
    }
    // Unknown codes and out-of-range parameters (checksum resealed).
    for (at, v) in [(32, 2), (36, 1), (36, BuildStrategy::MAX_BINS + 1), (40, 0)] {
        let mut b = bytes.clone();
        set_word(&mut b, at, v);
        treefile::reseal(&mut b);
        let e = load(&b, &mesh, &config).unwrap_err();
        assert!(matches!(&e, TreeFileError::BadConfig(_)), "{at} = {v}: {e}");
    }
    // An exact tree's file says so (code 0, bins and min_tris 0).
    let exact = save(&mesh, &build(&mesh, &BuildConfig { strategy: BuildStrategy::Exact, ..config }));
    assert_eq!([word(&exact, 32), word(&exact, 36), word(&exact, 40)], [0, 0, 0]);
}

/// The sphere's tree (several levels, triangles crossing the node boxes) and its file.
fn sphere_file() -> (Mesh, BuildConfig, Vec<u8>) {
    let mesh = mesh("sphere");
    let config = config(Intersector::Wald);
    let tree = build(&mesh, &config);
    let bytes = save(&mesh, &tree);
    (mesh, config, bytes)
}

/// Every prefix of a file, shorter than it, is refused as truncated; a cut inside a header
/// field names that field.
fn check_truncations(mesh: &Mesh, config: &BuildConfig, bytes: &[u8], lengths: impl Iterator<Item = usize>) {
    for len in lengths {
        let e = load(&bytes[..len], mesh, config).unwrap_err();
        let TreeFileError::Truncated { what, offset, left, .. } = &e else { panic!("length {len}: {e:?}") };
        assert_eq!(*offset + *left, len as u64, "length {len}: {e}");
        if let Some(&(_, field)) = HEADER_FIELDS.iter().rev().find(|(at, _)| *at <= len && len < NODE_SECTION) {
            let field = field.split(' ').next().unwrap();
            assert!(what.contains(field) || (field == "bounds" && what.contains("bound")), "length {len}: {e}");
        }
    }
}

#[test]
fn every_truncation_is_refused_naming_what_is_missing() {
    // The cube's file at every length (a few hundred bytes).
    let mesh = mesh("cube");
    let config = config(Intersector::Wald);
    let bytes = save(&mesh, &build(&mesh, &config));
    check_truncations(&mesh, &config, &bytes, 0..bytes.len());
    // The sphere's (watertight): the header at every length, then every array's start and
    // end and lengths spread over the file.
    let (mesh, config) = (self::mesh("sphere"), self::config(Intersector::Watertight));
    let bytes = save(&mesh, &build(&mesh, &config));
    let refs = first_ref_at(&bytes);
    let marks = [node_at(0), refs - 16, refs, bytes.len() - 8];
    let near_marks = marks.into_iter().flat_map(|m| m.saturating_sub(9)..(m + 9).min(bytes.len()));
    let spread = (0..bytes.len()).step_by(bytes.len() / 97 + 1);
    check_truncations(&mesh, &config, &bytes, (0..FIRST_NODE + 1).chain(near_marks).chain(spread));
}

#[test]
fn wrong_magic_version_and_trailing_bytes_are_refused() {
    let (mesh, config, bytes) = sphere_file();
    let mut b = bytes.clone();
    b[0] ^= 0x20;
    assert!(matches!(load(&b, &mesh, &config), Err(TreeFileError::BadMagic { .. })));
    assert!(matches!(load(b"PNG", &mesh, &config), Err(TreeFileError::BadMagic { .. })));
    let mut b = bytes.clone();
    b[8..12].copy_from_slice(&(treefile::VERSION + 1).to_le_bytes());
    assert_eq!(load(&b, &mesh, &config).unwrap_err(), TreeFileError::BadVersion { found: treefile::VERSION + 1 });
    let mut b = bytes.clone();
    b[12..16].copy_from_slice(&7u32.to_le_bytes());
    assert_eq!(load(&b, &mesh, &config).unwrap_err(), TreeFileError::UnknownIntersector(7));
    let mut b = bytes.clone();
    b.push(0);
    assert_eq!(load(&b, &mesh, &config).unwrap_err(), TreeFileError::TrailingBytes(1));
}

#[test]
fn a_tree_for_another_scene_or_intersector_is_refused() {
    let (mesh, config, bytes) = sphere_file();
    let e = load(&bytes, &self::mesh("cube"), &config).unwrap_err();
    assert!(matches!(e, TreeFileError::SceneMismatch { .. }), "{e}");
    // One bit of one coordinate.
    let mut moved = mesh.clone();
    moved.positions[3].y = f32::from_bits(moved.positions[3].y.to_bits() ^ 1);
    let e = load(&bytes, &moved, &config).unwrap_err();
    assert!(matches!(e, TreeFileError::SceneMismatch { .. }), "{e}");
    // Same positions, another index.
    let mut renumbered = mesh.clone();
    renumbered.triangles[0].swap(0, 1);
    assert!(matches!(load(&bytes, &renumbered, &config), Err(TreeFileError::SceneMismatch { .. })));
    let e = load(&bytes, &mesh, &self::config(Intersector::Watertight)).unwrap_err();
    assert_eq!(e, TreeFileError::IntersectorMismatch { file: "wald", expected: "watertight" });
    // Saving refuses a tree with a scene it was not built over.
    let tree = load(&bytes, &mesh, &config).unwrap();
    let e = treefile::to_bytes(&tree, &moved.positions, &moved.triangles).unwrap_err();
    assert!(matches!(e, TreeFileError::Mismatch(_)), "{e}");
}

/// The offset of node `i`, and of the first reference.
fn node_at(i: usize) -> usize {
    FIRST_NODE + 8 * i
}

fn node_count(bytes: &[u8]) -> usize {
    u64::from_le_bytes(bytes[NODE_SECTION + 8..FIRST_NODE].try_into().unwrap()) as usize
}

fn first_ref_at(bytes: &[u8]) -> usize {
    node_at(node_count(bytes)) + 16
}

fn word(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

fn set_word(bytes: &mut [u8], at: usize, v: u32) {
    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

#[test]
fn corrupt_indices_nan_splits_and_boxes_are_refused() {
    let (mesh, config, bytes) = sphere_file();
    let n = node_count(&bytes);
    assert!(n > 1, "the sphere's tree has inner nodes");
    let inner = (0..n).find(|&i| word(&bytes, node_at(i) + 4) & 3 != 3).unwrap();
    let leaf = (0..n).find(|&i| word(&bytes, node_at(i) + 4) & 3 == 3).unwrap();

    // A child index past the end.
    let mut b = bytes.clone();
    let axis = word(&b, node_at(inner) + 4) & 3;
    set_word(&mut b, node_at(inner) + 4, (n as u32) << 2 | axis);
    let e = load(&b, &mesh, &config).unwrap_err();
    assert!(matches!(&e, TreeFileError::OutOfRange(m) if m.contains(&format!("node {inner}"))), "{e}");

    // A child pointing back at the root: a cycle, caught by the structure check.
    let mut b = bytes.clone();
    set_word(&mut b, node_at(inner) + 4, axis);
    treefile::reseal(&mut b);
    assert!(load(&b, &mesh, &config).is_err());

    // NaN and infinite splits.
    for bad in [f32::NAN, f32::INFINITY] {
        let mut b = bytes.clone();
        set_word(&mut b, node_at(inner), bad.to_bits());
        let e = load(&b, &mesh, &config).unwrap_err();
        assert!(matches!(&e, TreeFileError::NonFinite(m) if m.contains(&format!("node {inner}"))), "{e}");
    }

    // A reference to a triangle that does not exist.
    let mut b = bytes.clone();
    set_word(&mut b, first_ref_at(&bytes), mesh.triangles.len() as u32);
    let e = load(&b, &mesh, &config).unwrap_err();
    assert!(matches!(&e, TreeFileError::OutOfRange(m) if m.contains("reference 0")), "{e}");

    // A leaf reaching past the references.
    let mut b = bytes.clone();
    set_word(&mut b, node_at(leaf), u32::MAX);
    let e = load(&b, &mesh, &config).unwrap_err();
    assert!(matches!(&e, TreeFileError::OutOfRange(m) if m.contains(&format!("leaf {leaf}"))), "{e}");

    // A NaN bound.
    let mut b = bytes.clone();
    set_word(&mut b, BOUNDS, f32::NAN.to_bits());
    assert!(matches!(load(&b, &mesh, &config), Err(TreeFileError::NonFinite(_))));
    // A finite bound other than the scene's.
    let mut b = bytes.clone();
    let lower = (f32::from_bits(word(&b, BOUNDS)) - 1.0).to_bits();
    set_word(&mut b, BOUNDS, lower);
    treefile::reseal(&mut b);
    assert!(matches!(load(&b, &mesh, &config), Err(TreeFileError::Mismatch(_))));
}

#[test]
fn absurd_counts_are_refused_before_allocating() {
    let (mesh, config, bytes) = sphere_file();
    for count in [u64::MAX, u64::MAX / 8 + 1, 1 << 40] {
        let mut b = bytes.clone();
        b[NODE_SECTION + 8..FIRST_NODE].copy_from_slice(&count.to_le_bytes());
        let e = load(&b, &mesh, &config).unwrap_err();
        assert!(matches!(e, TreeFileError::Truncated { .. }), "{e}");
    }
    let mut b = bytes.clone();
    b[NODE_SECTION..NODE_SECTION + 4].copy_from_slice(b"EDON");
    assert!(matches!(load(&b, &mesh, &config), Err(TreeFileError::BadSection { .. })));
    let mut b = bytes.clone();
    b[NODE_SECTION + 8..FIRST_NODE].copy_from_slice(&0u64.to_le_bytes());
    assert!(load(&b, &mesh, &config).is_err());
}

#[test]
fn damage_behind_the_structure_checks_is_caught_by_checksum_records_and_validate() {
    let (mesh, config, bytes) = sphere_file();
    // A flipped bit in the last record: the checksum, and once resealed, the record check.
    let mut b = bytes.clone();
    let at = b.len() - 12;
    b[at] ^= 1;
    assert!(matches!(load(&b, &mesh, &config), Err(TreeFileError::Checksum { .. })));
    treefile::reseal(&mut b);
    let e = load(&b, &mesh, &config).unwrap_err();
    assert!(matches!(&e, TreeFileError::Mismatch(m) if m.contains("Wald record")), "{e}");

    // A leaf's reference replaced by a triangle it does not hold: every check passes but
    // validate (a triangle entering the leaf is no longer referenced).
    let n = node_count(&bytes);
    let leaf =
        (0..n).find(|&i| word(&bytes, node_at(i) + 4) & 3 == 3 && word(&bytes, node_at(i) + 4) >> 2 > 0).unwrap();
    let (first, count) = (word(&bytes, node_at(leaf)) as usize, (word(&bytes, node_at(leaf) + 4) >> 2) as usize);
    let held: Vec<u32> = (first..first + count).map(|r| word(&bytes, first_ref_at(&bytes) + 4 * r)).collect();
    let other = (0..mesh.triangles.len() as u32).find(|t| !held.contains(t)).unwrap();
    let mut b = bytes.clone();
    set_word(&mut b, first_ref_at(&bytes) + 4 * first, other);
    treefile::reseal(&mut b);
    let e = load(&b, &mesh, &config).unwrap_err();
    assert!(matches!(e, TreeFileError::Invalid(_)), "{e}");
    // Emptying a leaf changes the references' layout (each leaf's first at a multiple of 4,
    // in node order): refused as a structure this version does not write.
    let mut e = bytes.clone();
    set_word(&mut e, node_at(leaf) + 4, 3);
    treefile::reseal(&mut e);
    let refused = load(&e, &mesh, &config).unwrap_err();
    assert!(matches!(&refused, TreeFileError::Structure(m) if m.contains("laid out")), "{refused}");
    // Checks::File leaves exactly this to validate(): the file loads, and validate refuses it.
    let tree = treefile::from_bytes(&b, &mesh.positions, &mesh.triangles, &config, Checks::File).unwrap();
    assert!(tree.validate().is_err());
    // Everything else is still refused without validate().
    let mut c = bytes.clone();
    c[bytes.len() / 2] ^= 4;
    assert!(treefile::from_bytes(&c, &mesh.positions, &mesh.triangles, &config, Checks::File).is_err());
}

#[test]
fn checksum_and_scene_hash_are_pinned() {
    // Part of the format: values computed independently (Python) from the documented
    // definition (word-wise FNV-1a 64, zero-padded last word, then the length).
    assert_eq!(treefile::checksum(b""), 0xaf63_bd4c_8601_b7df);
    assert_eq!(treefile::checksum(b"a"), 0x089b_e307_b544_f397);
    assert_eq!(treefile::checksum(b"foobarbaz"), 0xa10b_d6e2_6325_70d0);
    // One vertex (1, 2, 3), one triangle [0, 0, 0].
    let h = treefile::scene_hash(&[glam::Vec3::new(1.0, 2.0, 3.0)], &[[0, 0, 0]]);
    assert_eq!(h, 0xe3a5_6f63_46d3_a9af);
}
