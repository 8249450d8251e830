//! The tree file: a built [`KdTree`] as bytes, so a scene's tree is built once and loaded
//! after (issue 16). This module works on bytes only; opening files is the caller's
//! (`trace::setup`), which names the file in its errors.
//!
//! Layout, version [`VERSION`], every number little-endian:
//!
//! ```text
//! header   magic "RTKDTREE" (8 bytes)  version u32  intersector u32 (0 wald, 1 watertight)
//!          c_trav f32  c_isect f32  empty_bonus f32  max_depth u32 (0: the default 8 + log2 N)
//!          strategy u32 (0 exact, 1 binned)  bins u32  min_tris u32 (both 0 for exact)
//!          leaf_width u32  max_bad_refines u32  collapse u32 (0 or 1)
//!          triangle count u64  scene hash u64 (scene_hash: FNV-1a 64 over words of positions and indices)
//!          bounds: min x y z, max x y z (6 f32)
//! arrays   one section each: tag (4 bytes)  element size u32  count u64  count * size bytes
//!          "NODE" the nodes (8 bytes: word0 u32, word1 u32; see [`crate::node`])
//!          "PREF" the leaves' triangle references (u32)
//!          "WALD" or "WTRI" the intersection records of the header's intersector
//!                 (Wald: kuv u32 then 9 f32, 40 bytes; watertight: 9 f32, 36 bytes)
//! footer   checksum u64 (checksum: word-wise FNV-1a 64 of every byte before it)
//! ```
//!
//! Each array is one contiguous run of fixed-size elements, so a reader needs one read per
//! array (or a memory map). Each array is written by one `write_*` and read by one `read_*`
//! function; a new array is a new section and a new [`VERSION`].
//!
//! Loading ([`from_bytes`]) trusts nothing: every length is checked against the bytes left
//! before anything is allocated, the header must match the scene (hash and triangle count),
//! the intersector and the SAH terms asked for, every child index and reference must be in
//! range, every split plane and the bounds finite, the records and bounds equal to those
//! recomputed from the scene, the checksum right, and then [`KdTree::validate`] runs (unless
//! [`Checks::File`] is asked for: the same checks without the validate walk). Each
//! refusal is a [`TreeFileError`] saying what is wrong; nothing here panics on any input.

use glam::Vec3;

use crate::triangle::{Intersector, WaldTriangle, WatertightTriangle, is_degenerate};
use crate::{Aabb, BuildConfig, BuildStrategy, KdNode, KdTree};

/// The first 8 bytes of every tree file.
pub const MAGIC: [u8; 8] = *b"RTKDTREE";

/// The layout version this code writes and reads. Bump it when the layout changes.
pub const VERSION: u32 = 3;

/// Section tag of the node array.
const NODES: [u8; 4] = *b"NODE";
/// Section tag of the reference array.
const PRIM_REFS: [u8; 4] = *b"PREF";
/// Section tag of the Wald records.
const WALD: [u8; 4] = *b"WALD";
/// Section tag of the watertight records.
const WATERTIGHT: [u8; 4] = *b"WTRI";

/// Why a tree file was refused (or could not be written). The caller adds the file's name.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TreeFileError {
    /// The bytes end before a field or an array does.
    #[error("truncated: {what} needs {needed} bytes at offset {offset}, but only {left} are left")]
    Truncated {
        /// The field or array being read.
        what: String,
        /// Its offset in the file.
        offset: u64,
        /// Bytes it needs (saturated at `u64::MAX` for absurd counts).
        needed: u64,
        /// Bytes left in the file.
        left: u64,
    },
    /// The file does not start with [`MAGIC`].
    #[error("not a tree file: the magic is {found:?}, expected \"RTKDTREE\"")]
    BadMagic {
        /// The first bytes found (up to 8).
        found: String,
    },
    /// The file's layout version is not [`VERSION`].
    #[error("tree file version {found}, but this program reads version {VERSION}: build and save the tree again")]
    BadVersion {
        /// The version in the file.
        found: u32,
    },
    /// The header names an intersector this program does not know.
    #[error("unknown intersector code {0} in the header")]
    UnknownIntersector(u32),
    /// The tree was built for another intersector than the one asked for.
    #[error("the tree was built for the {file} intersector, but {expected} is asked for")]
    IntersectorMismatch {
        /// The file's intersector name.
        file: &'static str,
        /// The asked-for intersector name.
        expected: &'static str,
    },
    /// The tree was built with other SAH terms than the ones asked for.
    #[error("the tree was built with {field} = {file}, but {expected} is asked for")]
    ConfigMismatch {
        /// The configuration field (`c_trav`, `c_isect`, `empty_bonus`, `max_depth`, `strategy`,
        /// `leaf_width`, `max_bad_refines`, `collapse`).
        field: &'static str,
        /// The file's value.
        file: String,
        /// The asked-for value.
        expected: String,
    },
    /// The tree was built for another scene.
    #[error(
        "the tree was built for another scene: file has {file_triangles} triangles and scene hash {file_hash:016x}, \
         the scene has {scene_triangles} triangles and hash {scene_hash:016x}"
    )]
    SceneMismatch {
        /// Triangle count in the file.
        file_triangles: u64,
        /// Scene hash in the file.
        file_hash: u64,
        /// Triangle count of the scene.
        scene_triangles: u64,
        /// Hash of the scene.
        scene_hash: u64,
    },
    /// A section tag or element size is not the one expected at this place.
    #[error(
        "bad section at offset {offset}: expected {expected} (element size {expected_size}), found tag {found:?} with element size {found_size}"
    )]
    BadSection {
        /// Offset of the section.
        offset: u64,
        /// The expected tag.
        expected: String,
        /// The expected element size.
        expected_size: u32,
        /// The tag found.
        found: String,
        /// The element size found.
        found_size: u32,
    },
    /// An array is longer than the tree's index widths allow.
    #[error("{what} has {count} elements, more than the index width allows ({max})")]
    TooMany {
        /// The array.
        what: &'static str,
        /// Its count.
        count: u64,
        /// The largest count allowed.
        max: u64,
    },
    /// A NaN or infinite number where a finite one must be.
    #[error("{0} is not finite")]
    NonFinite(String),
    /// An index out of range.
    #[error("out of range: {0}")]
    OutOfRange(String),
    /// A configuration value in the header is out of its range.
    #[error("bad configuration in the header: {0}")]
    BadConfig(String),
    /// The node arrays do not form a tree (a cycle, a tree too deep, no nodes).
    #[error("bad tree structure: {0}")]
    Structure(String),
    /// An array or the bounds differ from what the scene's triangles give.
    #[error("{0} does not match the scene's triangles")]
    Mismatch(String),
    /// The checksum in the footer is not that of the bytes before it.
    #[error("checksum mismatch: stored {stored:016x}, computed {computed:016x} (the file is damaged)")]
    Checksum {
        /// The footer's checksum.
        stored: u64,
        /// The checksum of the bytes.
        computed: u64,
    },
    /// Bytes after the footer.
    #[error("{0} bytes after the end of the tree")]
    TrailingBytes(u64),
    /// The scene given is unusable (an index out of range, a non-finite vertex).
    #[error("the scene cannot carry a tree: {0}")]
    BadScene(String),
    /// [`KdTree::validate`] refused the loaded tree.
    #[error("the tree does not validate: {0}")]
    Invalid(String),
}

/// FNV-1a 64 offset basis.
const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
/// FNV-1a 64 prime.
const FNV_PRIME: u64 = 0x0100_0000_01b3;

/// One FNV-1a step over a 64-bit word: `(hash ^ word) * prime`. Both operations are
/// bijections of the hash, so changing any one word always changes the result.
#[inline(always)]
fn mix(hash: u64, word: u64) -> u64 {
    (hash ^ word).wrapping_mul(FNV_PRIME)
}

/// FNV-1a 64 taken over 64-bit words instead of bytes (8 times fewer multiplications: the
/// 8 MB of Sponza's tree in a few milliseconds): the little-endian words of `bytes`, the
/// last one zero-padded, then the byte length.
pub fn checksum(bytes: &[u8]) -> u64 {
    let mut chunks = bytes.chunks_exact(8);
    let mut h = FNV_OFFSET;
    for c in &mut chunks {
        let mut w = [0u8; 8];
        w.copy_from_slice(c);
        h = mix(h, u64::from_le_bytes(w));
    }
    let rest = chunks.remainder();
    if !rest.is_empty() {
        let mut w = [0u8; 8];
        w[..rest.len()].copy_from_slice(rest);
        h = mix(h, u64::from_le_bytes(w));
    }
    mix(h, bytes.len() as u64)
}

/// The 32-bit values of `values` hashed in pairs as 64-bit words (`first | second << 32`,
/// the last one alone when the count is odd), from `hash`.
fn mix_u32s(mut hash: u64, values: impl Iterator<Item = u32>) -> u64 {
    let mut pending: Option<u32> = None;
    for v in values {
        match pending.take() {
            Some(lo) => hash = mix(hash, u64::from(lo) | u64::from(v) << 32),
            None => pending = Some(v),
        }
    }
    if let Some(lo) = pending {
        hash = mix(hash, u64::from(lo));
    }
    hash
}

/// The scene hash of the header, word-wise FNV-1a 64 as [`checksum`]: the vertex count, the
/// positions' coordinate bits (x, y, z per vertex, in pairs of 32-bit values), the triangle
/// count, then the indices (three per triangle, in pairs). Stable across platforms and runs;
/// changing any coordinate bit or index changes it.
pub fn scene_hash(positions: &[Vec3], triangles: &[[u32; 3]]) -> u64 {
    let mut h = mix(FNV_OFFSET, positions.len() as u64);
    h = mix_u32s(h, positions.iter().flat_map(|p| p.to_array().map(f32::to_bits)));
    h = mix(h, triangles.len() as u64);
    mix_u32s(h, triangles.iter().flatten().copied())
}

/// Recomputes the footer checksum of a tree file in place (no-op on fewer than 8 bytes), so
/// that a deliberately changed file reaches the checks behind the checksum: for tests and
/// the fuzz target.
pub fn reseal(bytes: &mut [u8]) {
    if bytes.len() >= 8 {
        let end = bytes.len() - 8;
        let sum = checksum(&bytes[..end]);
        bytes[end..].copy_from_slice(&sum.to_le_bytes());
    }
}

fn intersector_code(i: Intersector) -> u32 {
    match i {
        Intersector::Wald => 0,
        Intersector::Watertight => 1,
    }
}

/// The vertices of each triangle of the scene; an index out of range is an error.
fn scene_triangles(positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Vec<[Vec3; 3]>, TreeFileError> {
    triangles
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            let mut v = [Vec3::ZERO; 3];
            for (k, &i) in tri.iter().enumerate() {
                v[k] = *positions.get(i as usize).ok_or_else(|| {
                    TreeFileError::BadScene(format!("triangle {t} uses vertex {i} of {}", positions.len()))
                })?;
            }
            Ok(v)
        })
        .collect()
}

/// True if the two triangles have the same bits.
fn same_triangle(a: &[Vec3; 3], b: &[Vec3; 3]) -> bool {
    a.iter().zip(b).all(|(p, q)| p.to_array().map(f32::to_bits) == q.to_array().map(f32::to_bits))
}

// ---------------------------------------------------------------------------------------
// Writing

/// Appends a section header: tag, element size, count.
fn write_section(out: &mut Vec<u8>, tag: [u8; 4], elem_size: u32, count: usize) {
    out.extend_from_slice(&tag);
    out.extend_from_slice(&elem_size.to_le_bytes());
    out.extend_from_slice(&(count as u64).to_le_bytes());
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_f32(out: &mut Vec<u8>, v: f32) {
    out.extend_from_slice(&v.to_bits().to_le_bytes());
}

/// The "NODE" section.
fn write_nodes(out: &mut Vec<u8>, nodes: &[KdNode]) {
    write_section(out, NODES, 8, nodes.len());
    for n in nodes {
        let (a, b) = n.raw();
        put_u32(out, a);
        put_u32(out, b);
    }
}

/// The "PREF" section.
fn write_prim_refs(out: &mut Vec<u8>, refs: &[u32]) {
    write_section(out, PRIM_REFS, 4, refs.len());
    for &r in refs {
        put_u32(out, r);
    }
}

/// The "WALD" section.
fn write_wald(out: &mut Vec<u8>, records: &[WaldTriangle]) {
    write_section(out, WALD, 40, records.len());
    for r in records {
        put_u32(out, r.kuv);
        for v in [r.n_u, r.n_v, r.a_k, r.a_u, r.a_v, r.b_nu, r.b_nv, r.c_nu, r.c_nv] {
            put_f32(out, v);
        }
    }
}

/// The "WTRI" section.
fn write_watertight(out: &mut Vec<u8>, records: &[WatertightTriangle]) {
    write_section(out, WATERTIGHT, 36, records.len());
    for r in records {
        for p in r.v {
            for c in p.to_array() {
                put_f32(out, c);
            }
        }
    }
}

/// The tree file of `tree`, built over the triangles `triangles` (indices into `positions`),
/// the scene whose hash goes into the header. Refuses a tree that was not built over these
/// triangles ([`TreeFileError::Mismatch`]), so a file never claims a scene it does not fit.
pub fn to_bytes(tree: &KdTree, positions: &[Vec3], triangles: &[[u32; 3]]) -> Result<Vec<u8>, TreeFileError> {
    let tris = scene_triangles(positions, triangles)?;
    if tris.len() != tree.tris.len() {
        return Err(TreeFileError::Mismatch(format!(
            "the tree's {} triangles (the scene has {})",
            tree.tris.len(),
            tris.len()
        )));
    }
    if let Some(t) = (0..tris.len()).find(|&t| !same_triangle(&tris[t], &tree.tris[t])) {
        return Err(TreeFileError::Mismatch(format!("the tree's triangle {t}")));
    }
    let config = tree.config();
    let record_bytes = match tree.intersector {
        Intersector::Wald => 40 * tree.wald.len(),
        Intersector::Watertight => 36 * tree.watertight.len(),
    };
    let mut out = Vec::with_capacity(128 + 8 * tree.nodes.len() + 4 * tree.prim_refs.len() + record_bytes);
    out.extend_from_slice(&MAGIC);
    put_u32(&mut out, VERSION);
    put_u32(&mut out, intersector_code(tree.intersector));
    put_f32(&mut out, config.c_trav);
    put_f32(&mut out, config.c_isect);
    put_f32(&mut out, config.empty_bonus);
    put_u32(&mut out, config.max_depth.unwrap_or(0));
    let (code, bins, min_tris) = strategy_fields(config.strategy);
    put_u32(&mut out, code);
    put_u32(&mut out, bins);
    put_u32(&mut out, min_tris);
    put_u32(&mut out, config.leaf_width);
    put_u32(&mut out, config.max_bad_refines);
    put_u32(&mut out, u32::from(config.collapse));
    out.extend_from_slice(&(triangles.len() as u64).to_le_bytes());
    out.extend_from_slice(&scene_hash(positions, triangles).to_le_bytes());
    for v in tree.bounds.min.to_array().into_iter().chain(tree.bounds.max.to_array()) {
        put_f32(&mut out, v);
    }
    write_nodes(&mut out, &tree.nodes);
    write_prim_refs(&mut out, &tree.prim_refs);
    match tree.intersector {
        Intersector::Wald => write_wald(&mut out, &tree.wald),
        Intersector::Watertight => write_watertight(&mut out, &tree.watertight),
    }
    let sum = checksum(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    Ok(out)
}

// ---------------------------------------------------------------------------------------
// Reading

/// A cursor over the file's bytes; every read is checked against the bytes left.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn left(&self) -> usize {
        self.bytes.len() - self.pos
    }

    /// The next `n` bytes, or [`TreeFileError::Truncated`] naming `what`.
    fn take(&mut self, n: u64, what: &str) -> Result<&'a [u8], TreeFileError> {
        let left = self.left();
        if n > left as u64 {
            return Err(TreeFileError::Truncated {
                what: what.to_string(),
                offset: self.pos as u64,
                needed: n,
                left: left as u64,
            });
        }
        let n = n as usize;
        let out = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(out)
    }

    fn u32(&mut self, what: &str) -> Result<u32, TreeFileError> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u64(&mut self, what: &str) -> Result<u64, TreeFileError> {
        let b = self.take(8, what)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }

    fn f32(&mut self, what: &str) -> Result<f32, TreeFileError> {
        self.u32(what).map(f32::from_bits)
    }

    /// A section header with tag `tag` and element size `elem_size`; returns its elements'
    /// bytes (count checked against the bytes left before anything is used).
    fn section(&mut self, tag: [u8; 4], elem_size: u32, what: &'static str) -> Result<(u64, &'a [u8]), TreeFileError> {
        let offset = self.pos as u64;
        let found = self.take(4, &format!("the {what} section's tag"))?;
        let found_tag = String::from_utf8_lossy(found).into_owned();
        let found_size = self.u32(&format!("the {what} section's element size"))?;
        if found != tag || found_size != elem_size {
            return Err(TreeFileError::BadSection {
                offset,
                expected: String::from_utf8_lossy(&tag).into_owned(),
                expected_size: elem_size,
                found: found_tag,
                found_size,
            });
        }
        let count = self.u64(&format!("the {what} section's count"))?;
        let bytes = self.take(count.saturating_mul(u64::from(elem_size)), &format!("{count} {what}"))?;
        Ok((count, bytes))
    }
}

/// The little-endian `u32` words of `bytes` (a multiple of 4 long).
fn words(bytes: &[u8]) -> impl Iterator<Item = u32> + '_ {
    bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
}

/// The "NODE" section. Each inner node's split must be finite and its children in range;
/// each leaf's reference range is checked against the references in [`read_prim_refs`].
fn read_nodes(r: &mut Reader<'_>) -> Result<Vec<KdNode>, TreeFileError> {
    let (count, bytes) = r.section(NODES, 8, "nodes")?;
    let max = u64::from(crate::node::MAX_NODE_FIELD) + 1;
    if count > max {
        return Err(TreeFileError::TooMany { what: "the node array", count, max });
    }
    if count == 0 {
        return Err(TreeFileError::Structure("no nodes".into()));
    }
    let mut nodes = Vec::with_capacity(count as usize);
    let mut w = words(bytes);
    while let (Some(word0), Some(word1)) = (w.next(), w.next()) {
        let i = nodes.len();
        let axis = word1 & 3;
        let node = if axis == 3 {
            KdNode::leaf(word0, word1 >> 2)
        } else {
            let split = f32::from_bits(word0);
            if !split.is_finite() {
                return Err(TreeFileError::NonFinite(format!("the split plane {split} of node {i}")));
            }
            let child = word1 >> 2;
            if u64::from(child) + 1 >= count {
                return Err(TreeFileError::OutOfRange(format!(
                    "node {i} has children {child} and {} of {count} nodes",
                    u64::from(child) + 1
                )));
            }
            KdNode::inner(axis, split, child)
        };
        nodes.push(node);
    }
    Ok(nodes)
}

/// The "PREF" section: each reference below `triangles`, or [`crate::leaf::GAP`] (the
/// padding that aligns each leaf's references to the SIMD groups; a gap inside a leaf's
/// range is refused by `KdTree::from_parts`).
fn read_prim_refs(r: &mut Reader<'_>, triangles: u64) -> Result<Vec<u32>, TreeFileError> {
    let (count, bytes) = r.section(PRIM_REFS, 4, "triangle references")?;
    let max = u64::from(u32::MAX);
    if count > max {
        return Err(TreeFileError::TooMany { what: "the reference array", count, max });
    }
    let refs: Vec<u32> = words(bytes).collect();
    if let Some(i) = refs.iter().position(|&t| t != crate::leaf::GAP && u64::from(t) >= triangles) {
        return Err(TreeFileError::OutOfRange(format!("reference {i} names triangle {} of {triangles}", refs[i])));
    }
    Ok(refs)
}

/// The "WALD" section.
fn read_wald(r: &mut Reader<'_>) -> Result<Vec<WaldTriangle>, TreeFileError> {
    let (_, bytes) = r.section(WALD, 40, "Wald records")?;
    Ok(bytes
        .chunks_exact(40)
        .map(|c| {
            let w: Vec<u32> = words(c).collect();
            let f = |k: usize| f32::from_bits(w[k]);
            WaldTriangle {
                kuv: w[0],
                n_u: f(1),
                n_v: f(2),
                a_k: f(3),
                a_u: f(4),
                a_v: f(5),
                b_nu: f(6),
                b_nv: f(7),
                c_nu: f(8),
                c_nv: f(9),
            }
        })
        .collect())
}

/// The "WTRI" section.
fn read_watertight(r: &mut Reader<'_>) -> Result<Vec<WatertightTriangle>, TreeFileError> {
    let (_, bytes) = r.section(WATERTIGHT, 36, "watertight records")?;
    Ok(bytes
        .chunks_exact(36)
        .map(|c| {
            let f: Vec<f32> = words(c).map(f32::from_bits).collect();
            WatertightTriangle {
                v: [Vec3::new(f[0], f[1], f[2]), Vec3::new(f[3], f[4], f[5]), Vec3::new(f[6], f[7], f[8])],
            }
        })
        .collect())
}

/// True if the two Wald records have the same bits.
fn same_wald(a: &WaldTriangle, b: &WaldTriangle) -> bool {
    let bits = |r: &WaldTriangle| {
        let f = [r.n_u, r.n_v, r.a_k, r.a_u, r.a_v, r.b_nu, r.b_nv, r.c_nu, r.c_nv].map(f32::to_bits);
        (r.kuv, f)
    };
    bits(a) == bits(b)
}

/// The header's strategy fields: code (0 exact, 1 binned), bins, min_tris.
fn strategy_fields(s: BuildStrategy) -> (u32, u32, u32) {
    match s {
        BuildStrategy::Exact => (0, 0, 0),
        BuildStrategy::Binned { bins, min_tris } => (1, bins, min_tris),
    }
}

/// Compares a header value with the asked-for one (floats by their bits).
fn expect_same(field: &'static str, file: f32, expected: f32) -> Result<(), TreeFileError> {
    if file.to_bits() != expected.to_bits() {
        return Err(TreeFileError::ConfigMismatch { field, file: file.to_string(), expected: expected.to_string() });
    }
    Ok(())
}

/// The records a file carries, by intersector.
enum Records {
    Wald(Vec<WaldTriangle>),
    Watertight(Vec<WatertightTriangle>),
}

/// How much [`from_bytes`] checks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Checks {
    /// Every check of the file, then [`KdTree::validate`] (which costs about as much as the
    /// build: it clips every triangle down the tree).
    #[default]
    Full,
    /// Every check of the file (lengths, header against the scene and configuration, ranges,
    /// finiteness, checksum, records and bounds against the scene, tree structure), not
    /// [`KdTree::validate`]'s completeness walk. What the file cannot then guarantee is only
    /// that a deliberately altered file, with its checksum recomputed, still references every
    /// triangle in every leaf it enters: a wrong image, never a panic or an out-of-bounds read.
    File,
}

/// Loads the tree of a tree file for the scene `positions` / `triangles`, asking for the
/// intersector and SAH terms of `expected` (its `memory_budget` is kept in the loaded tree's
/// configuration, not compared). Every check of the module docs runs, [`KdTree::validate`]
/// last with [`Checks::Full`]; the first that fails is the error. The loaded tree equals the
/// saved one in every array, bit for bit; its [`KdTree::build_peak_bytes`] is `None`
/// (nothing was built).
pub fn from_bytes(
    bytes: &[u8],
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    expected: &BuildConfig,
    checks: Checks,
) -> Result<KdTree, TreeFileError> {
    let mut r = Reader { bytes, pos: 0 };
    let magic = r.take(8, "the magic").map_err(|e| match e {
        TreeFileError::Truncated { .. } if bytes.len() < 8 && !MAGIC.starts_with(bytes) => {
            TreeFileError::BadMagic { found: String::from_utf8_lossy(bytes).into_owned() }
        }
        e => e,
    })?;
    if magic != MAGIC {
        return Err(TreeFileError::BadMagic { found: String::from_utf8_lossy(magic).into_owned() });
    }
    let version = r.u32("the version")?;
    if version != VERSION {
        return Err(TreeFileError::BadVersion { found: version });
    }
    let intersector = match r.u32("the intersector")? {
        0 => Intersector::Wald,
        1 => Intersector::Watertight,
        code => return Err(TreeFileError::UnknownIntersector(code)),
    };
    if intersector != expected.intersector {
        return Err(TreeFileError::IntersectorMismatch {
            file: intersector.name(),
            expected: expected.intersector.name(),
        });
    }
    let c_trav = r.f32("c_trav")?;
    let c_isect = r.f32("c_isect")?;
    let empty_bonus = r.f32("empty_bonus")?;
    let max_depth = r.u32("max_depth")?;
    if !(c_trav.is_finite() && c_trav >= 0.0) {
        return Err(TreeFileError::BadConfig(format!("c_trav = {c_trav}")));
    }
    if !(c_isect.is_finite() && c_isect > 0.0) {
        return Err(TreeFileError::BadConfig(format!("c_isect = {c_isect}")));
    }
    if !(0.0..1.0).contains(&empty_bonus) {
        return Err(TreeFileError::BadConfig(format!("empty_bonus = {empty_bonus}")));
    }
    if max_depth > crate::MAX_DEPTH {
        return Err(TreeFileError::BadConfig(format!("max_depth = {max_depth} (at most {})", crate::MAX_DEPTH)));
    }
    expect_same("c_trav", c_trav, expected.c_trav)?;
    expect_same("c_isect", c_isect, expected.c_isect)?;
    expect_same("empty_bonus", empty_bonus, expected.empty_bonus)?;
    let max_depth = (max_depth > 0).then_some(max_depth);
    if max_depth != expected.max_depth {
        let show = |d: Option<u32>| d.map_or("the default (8 + log2 N)".to_string(), |d| d.to_string());
        return Err(TreeFileError::ConfigMismatch {
            field: "max_depth",
            file: show(max_depth),
            expected: show(expected.max_depth),
        });
    }
    let strategy = match (r.u32("the strategy")?, r.u32("bins")?, r.u32("min_tris")?) {
        (0, 0, 0) => BuildStrategy::Exact,
        (1, bins, min_tris) => BuildStrategy::Binned { bins, min_tris },
        (code, bins, min_tris) => {
            return Err(TreeFileError::BadConfig(format!("strategy {code} with bins = {bins}, min_tris = {min_tris}")));
        }
    };
    strategy.check().map_err(|e| TreeFileError::BadConfig(e.to_string()))?;
    if strategy != expected.strategy {
        return Err(TreeFileError::ConfigMismatch {
            field: "strategy",
            file: format!("{strategy:?}"),
            expected: format!("{:?}", expected.strategy),
        });
    }
    let leaf_width = r.u32("leaf_width")?;
    let max_bad_refines = r.u32("max_bad_refines")?;
    let collapse = match r.u32("collapse")? {
        0 => false,
        1 => true,
        code => return Err(TreeFileError::BadConfig(format!("collapse = {code} (0 or 1)"))),
    };
    let terms = BuildConfig { leaf_width, max_bad_refines, collapse, ..expected.clone() };
    terms.check_termination().map_err(|e| TreeFileError::BadConfig(e.to_string()))?;
    for (field, file, want) in [
        ("leaf_width", leaf_width, expected.leaf_width),
        ("max_bad_refines", max_bad_refines, expected.max_bad_refines),
        ("collapse", u32::from(collapse), u32::from(expected.collapse)),
    ] {
        if file != want {
            return Err(TreeFileError::ConfigMismatch { field, file: file.to_string(), expected: want.to_string() });
        }
    }
    let file_triangles = r.u64("the triangle count")?;
    let file_hash = r.u64("the scene hash")?;
    let hash = scene_hash(positions, triangles);
    if file_triangles != triangles.len() as u64 || file_hash != hash {
        return Err(TreeFileError::SceneMismatch {
            file_triangles,
            file_hash,
            scene_triangles: triangles.len() as u64,
            scene_hash: hash,
        });
    }
    let mut corner = [0f32; 6];
    for (k, c) in corner.iter_mut().enumerate() {
        *c = r.f32(&format!("bound {k}"))?;
    }
    let bounds =
        Aabb { min: Vec3::new(corner[0], corner[1], corner[2]), max: Vec3::new(corner[3], corner[4], corner[5]) };
    if bounds != Aabb::EMPTY && !(bounds.min.is_finite() && bounds.max.is_finite()) {
        return Err(TreeFileError::NonFinite(format!("the bounds {bounds:?}")));
    }

    let nodes = read_nodes(&mut r)?;
    let prim_refs = read_prim_refs(&mut r, file_triangles)?;
    for (i, n) in nodes.iter().enumerate().filter(|(_, n)| n.is_leaf()) {
        if n.first_ref() as u64 + n.prim_count() as u64 > prim_refs.len() as u64 {
            return Err(TreeFileError::OutOfRange(format!(
                "leaf {i} references {}..{} of {} references",
                n.first_ref(),
                n.first_ref() as u64 + n.prim_count() as u64,
                prim_refs.len()
            )));
        }
    }
    let records = match intersector {
        Intersector::Wald => Records::Wald(read_wald(&mut r)?),
        Intersector::Watertight => Records::Watertight(read_watertight(&mut r)?),
    };
    let body_end = r.pos;
    let stored = r.u64("the checksum")?;
    if r.left() > 0 {
        return Err(TreeFileError::TrailingBytes(r.left() as u64));
    }
    let computed = checksum(&bytes[..body_end]);
    if stored != computed {
        return Err(TreeFileError::Checksum { stored, computed });
    }

    // Against the scene: its triangles, their bounds and records.
    let tris = scene_triangles(positions, triangles)?;
    if let Some(t) = tris.iter().position(|v| !v.iter().all(|p| p.is_finite())) {
        return Err(TreeFileError::BadScene(format!("triangle {t} has a vertex that is not finite")));
    }
    let scene_bounds =
        tris.iter().filter(|t| !is_degenerate(t)).fold(Aabb::EMPTY, |b, &[a, bb, c]| b.grow(a).grow(bb).grow(c));
    let bits =
        |b: &Aabb| [b.min.to_array(), b.max.to_array()].concat().into_iter().map(f32::to_bits).collect::<Vec<_>>();
    if bits(&scene_bounds) != bits(&bounds) {
        return Err(TreeFileError::Mismatch(format!("the bounds {bounds:?} (the scene's are {scene_bounds:?})")));
    }
    let config = BuildConfig {
        c_trav,
        c_isect,
        empty_bonus,
        max_depth,
        intersector,
        memory_budget: expected.memory_budget,
        strategy,
        leaf_width,
        max_bad_refines,
        collapse,
    };
    let (file_nodes, file_refs) = (nodes.clone(), prim_refs.clone());
    let tree = KdTree::from_parts(tris, nodes, prim_refs, bounds, &config).map_err(TreeFileError::Structure)?;
    // `from_parts` lays the references out in node order, aligned to the SIMD groups; a file
    // whose layout is another (not written by `to_bytes`) would load as a tree that saves
    // to different bytes, so it is refused.
    if tree.nodes != file_nodes || tree.prim_refs != file_refs {
        return Err(TreeFileError::Structure(
            "the leaves' references are not laid out as this version writes them (node order, each leaf's first at a multiple of 4)".into(),
        ));
    }
    match &records {
        Records::Wald(stored) => {
            if stored.len() != tree.wald.len() {
                return Err(TreeFileError::Mismatch(format!("the {} Wald records", stored.len())));
            }
            if let Some(i) = (0..stored.len()).find(|&i| !same_wald(&stored[i], &tree.wald[i])) {
                return Err(TreeFileError::Mismatch(format!("Wald record {i}")));
            }
        }
        Records::Watertight(stored) => {
            if stored.len() != tree.watertight.len() {
                return Err(TreeFileError::Mismatch(format!("the {} watertight records", stored.len())));
            }
            if let Some(i) = (0..stored.len()).find(|&i| !same_triangle(&stored[i].v, &tree.watertight[i].v)) {
                return Err(TreeFileError::Mismatch(format!("watertight record {i}")));
            }
        }
    }
    if checks == Checks::Full {
        tree.validate().map_err(TreeFileError::Invalid)?;
    }
    Ok(tree)
}
