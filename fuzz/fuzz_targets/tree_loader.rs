//! Arbitrary bytes, and mutations of valid tree files, -> `kdtree::treefile::from_bytes`:
//! never panics, never reads out of bounds, never allocates from an unchecked length; a file
//! it accepts is a valid tree (`validate()` ran) that saves back to exactly the same bytes.
#![no_main]

use std::sync::OnceLock;

use kdtree::treefile::{self, Checks};
use kdtree::{BuildConfig, Intersector, KdTree};
use libfuzzer_sys::fuzz_target;
use scenes::Mesh;

/// The touching boxes (small, several levels) and their valid tree files, one per
/// intersector.
struct Fixture {
    mesh: Mesh,
    files: [(BuildConfig, Vec<u8>); 2],
}

fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let mesh = scenes::builtin::by_name("touching-boxes").expect("built-in scene").mesh;
        let file = |intersector| {
            let config = BuildConfig { intersector, ..BuildConfig::default() };
            let tree = KdTree::build(&mesh.positions, &mesh.triangles, &config).expect("build");
            let bytes = treefile::to_bytes(&tree, &mesh.positions, &mesh.triangles).expect("save");
            (config, bytes)
        };
        let files = [file(Intersector::Wald), file(Intersector::Watertight)];
        Fixture { mesh, files }
    })
}

fuzz_target!(|data: &[u8]| {
    let fx = fixture();
    let Some((&mode, rest)) = data.split_first() else { return };
    let (config, valid) = &fx.files[usize::from(mode & 1)];
    let bytes: Vec<u8> = if mode & 2 == 0 {
        // Arbitrary bytes, half of the time behind a valid header's first 84 bytes so that
        // the arrays' checks are reached.
        if mode & 4 == 0 { rest.to_vec() } else { valid[..84].iter().chain(rest).copied().collect() }
    } else {
        // A valid file with edits: (offset u16, xor byte) triples, then an optional cut and,
        // with bit 3, the checksum recomputed so that the checks behind it are reached.
        let mut b = valid.clone();
        let mut edits = rest.chunks_exact(3);
        for e in &mut edits {
            let at = usize::from(u16::from_le_bytes([e[0], e[1]])) % b.len();
            b[at] ^= e[2];
        }
        if let [cut, ..] = edits.remainder() {
            let keep = b.len() - usize::from(*cut) % b.len();
            b.truncate(keep);
        }
        if mode & 8 != 0 {
            treefile::reseal(&mut b);
        }
        b
    };
    // Bit 4: the file checks only (Checks::File); the tree must then be safe to use (no
    // panic in validate, traversal or saving) even when validate refuses it.
    let checks = if mode & 16 == 0 { Checks::Full } else { Checks::File };
    if let Ok(tree) = treefile::from_bytes(&bytes, &fx.mesh.positions, &fx.mesh.triangles, config, checks) {
        let valid = tree.validate();
        assert!(checks == Checks::File || valid.is_ok(), "an accepted tree validates");
        let ray =
            kdtree::Ray::try_new(glam::Vec3::new(-3.0, 0.5, 0.1), glam::Vec3::new(1.0, 0.01, 0.02), 0.0, f32::INFINITY)
                .expect("ray");
        let _ = (tree.intersect(&ray), tree.occluded(&ray));
        let again = treefile::to_bytes(&tree, &fx.mesh.positions, &fx.mesh.triangles).expect("save again");
        assert_eq!(again, bytes, "an accepted file saves back to the same bytes");
    }
});
