//! `rttest raycast`: trace a list of rays given in a file and write one result per ray.
//!
//! ```text
//! rttest raycast --scene NAME|FILE.obj[.gz] --rays FILE|- [--format text|binary]
//!                [--out FILE|-] [--out-format text|binary]
//!                [--method mono|packet|samesign|frustum|mft|cone|mft-cone] [--any-hit]
//!                [--intersector wald|watertight]          (global: --threads N, --json)
//! ```
//!
//! ## Input: the rays
//! - **text** (default, and for files ending in `.txt` or anything but `.bin` / `.f32`):
//!   one ray per line, eight whitespace-separated numbers `ox oy oz dx dy dz tmin tmax`.
//!   Blank lines and lines whose first non-blank character is `#` are skipped. Numbers are
//!   anything Rust's `f32` parser takes, including `inf` (for `tmax`) and exponents.
//! - **binary** (`--format binary`, or files ending in `.bin` or `.f32`): the same eight
//!   values as little-endian `f32`, 32 bytes per ray, no header. A file whose size is not a
//!   multiple of 32 is an error naming the size.
//!
//! `--rays -` reads stdin (text unless `--format binary`). The whole list is read and checked
//! before anything is traced or written: the first bad ray rejects the file with one line,
//! `rttest: error: rays.txt:17: <what is wrong>` for text (1-based line numbers) or
//! `rttest: error: rays.bin: ray 16 at byte 512: <what is wrong>` for binary (0-based ray
//! index, the row of its result). Bad rays are: a wrong number of fields, a field that is
//! not a number, a NaN or infinite origin, a zero, NaN or infinite direction, and a NaN or
//! empty interval (`tmin > tmax`), as [`kdtree::Ray::try_new`] decides. The direction need
//! not be normalised; `t` is in units of it.
//!
//! ## Output: one result per ray, in input order
//! - **text** (default; `--out-format text`, or an `--out` file not ending in `.bin`/`.f32`):
//!   closest hit: one line `prim t u v` per ray, where `prim` is the hit triangle's primitive
//!   id in the *scene file's* face numbering (`Mesh::prim_ids`; for built-in scenes the
//!   triangle index), `t` the hit distance and `u v` the barycentric weights of the
//!   triangle's second and third vertex. A miss is the line `-1 inf 0 0`. Numbers are
//!   written with Rust's shortest round-tripping `f32` format, so parsing `t` gives back the
//!   exact value. With `--any-hit`: one line `1` (something is hit in `[tmin, tmax]`) or `0`.
//! - **binary** (`--out-format binary`, or an `--out` file ending in `.bin`/`.f32`): closest
//!   hit: 16 bytes per ray, little-endian `i32 prim, f32 t, f32 u, f32 v`; a miss is
//!   `-1, +inf, 0, 0`. With `--any-hit`: one byte per ray, `1` or `0`.
//!
//! Without `--out` (or with `--out -`) the results go to stdout. With `--json` the results
//! must go to a file, and stdout gets one summary object with the keys `scene, method,
//! any_hit, intersector, threads, triangles, build_ms, rays, hits, trace_secs, mrays_per_s,
//! read_secs, write_secs, rays_file, out`. Without `--json` and with `--out FILE`, a short
//! text summary is printed instead; with results on stdout nothing else is printed there.
//! `hits` counts rays that hit (or, with `--any-hit`, rays that are occluded). `trace_secs`
//! is traversal and intersection only: reading, parsing and writing are timed apart.
//!
//! ## How
//! Input is read in blocks of a few MiB and each block parsed in parallel; the rays are kept
//! (44 bytes each) and traced in one timed pass, the stream query of the registered method
//! ([`trace::Method::stream`]) in parallel over chunks of rays, each chunk writing its own
//! slice of a preallocated result buffer, so the output is in input order. Packet methods
//! group consecutive rays: 4 to a packet, and for the frusta runs of up to 64 rays that share
//! an origin; every method must give the single-ray answers (the conformance test checks it
//! on ray lists of this kind), which makes a ray file a test of all of them on arbitrary rays.
//! Results are formatted in parallel and written through one buffered writer.

use std::io::{self, Read, Write};
use std::path::Path;

use clap::ValueEnum;
use glam::Vec3;
use kdtree::{Hit, Ray};
use rayon::prelude::*;
use serde::Serialize;

use crate::Error;
use trace::FrameTracer;

/// Rays per parallel task when tracing (and per formatting task when writing).
pub const CHUNK: usize = 4096;

/// Bytes read from the ray file at a time; each block is parsed in parallel.
const BLOCK: usize = 8 << 20;

/// Bytes of text handed to one parsing task.
const PARSE_PIECE: usize = 256 << 10;

/// Bytes per ray in the binary input: eight little-endian `f32`.
pub const RAY_BYTES: usize = 32;

/// Bytes per closest-hit result in the binary output: `i32` prim and three `f32`.
pub const HIT_BYTES: usize = 16;

/// The formats, as `rttest raycast --help` shows them.
pub const FORMATS_HELP: &str = "\
Rays, text: one per line, 'ox oy oz dx dy dz tmin tmax'; blank lines and # comments skipped; inf allowed.
Rays, binary (.bin, .f32): 8 little-endian f32 per ray, 32 bytes, no header.
Results, text: 'prim t u v' per line (prim: the scene file's primitive id); a miss is '-1 inf 0 0';
  with --any-hit '1' or '0'.
Results, binary (.bin, .f32): little-endian i32 prim, f32 t, u, v (16 bytes; a miss is -1, inf, 0, 0);
  with --any-hit one byte 1 or 0 per ray.
The first bad ray rejects the file: 'rttest: error: FILE:LINE: reason'. With --json, --out is required.";

/// `--format` / `--out-format` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Whitespace-separated numbers, one ray (or result) per line.
    Text,
    /// Little-endian binary records, no header.
    Binary,
}

impl Format {
    /// The format of a file by its extension: binary for `.bin` and `.f32`, else text.
    pub fn of_path(path: &Path) -> Format {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("bin") || e.eq_ignore_ascii_case("f32") => Format::Binary,
            _ => Format::Text,
        }
    }

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Format::Text => "text",
            Format::Binary => "binary",
        }
    }
}

/// True for the path `-` (stdin or stdout).
pub fn is_dash(path: &Path) -> bool {
    path.as_os_str() == "-"
}

// ---------------------------------------------------------------------------------------
// Reading

/// A bad ray in the input: where, and what is wrong. Becomes [`Error::Rays`].
#[derive(Clone, Debug, PartialEq)]
pub struct RayFileError {
    /// `17` (a text line, 1-based) or ` ray 16 at byte 512` (binary, 0-based ray index; the
    /// leading space makes the message read `rays.bin: ray 16 ...`).
    pub place: String,
    /// What is wrong with it.
    pub message: String,
}

/// Parses one text line into a ray: `None` for blank and comment lines.
pub fn parse_line(line: &str) -> Result<Option<Ray>, String> {
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return Ok(None);
    }
    let mut v = [0.0f32; 8];
    let mut n = 0;
    for field in line.split_ascii_whitespace() {
        if n < 8 {
            v[n] = field.parse::<f32>().map_err(|_| format!("field {} '{field}' is not a number", n + 1))?;
        }
        n += 1;
    }
    if n != 8 {
        return Err(format!("expected 8 numbers 'ox oy oz dx dy dz tmin tmax', found {n}"));
    }
    ray_from(&v).map(Some)
}

/// The checked ray of eight values `ox oy oz dx dy dz tmin tmax`.
fn ray_from(v: &[f32; 8]) -> Result<Ray, String> {
    Ray::try_new(Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]), v[6], v[7]).map_err(|e| e.to_string())
}

/// Parses a piece of text made of whole lines, appending its rays to `out`. Returns the
/// number of lines (newlines, plus one for a last line without one), or the first bad line
/// as (1-based line number within the piece, message).
fn parse_text_piece(piece: &[u8], out: &mut Vec<Ray>) -> Result<usize, (usize, String)> {
    let mut lines = 0;
    for bytes in piece.split_inclusive(|&b| b == b'\n') {
        lines += 1;
        let line = std::str::from_utf8(bytes).map_err(|_| (lines, "not UTF-8 text".to_string()))?;
        if let Some(ray) = parse_line(line).map_err(|m| (lines, m))? {
            out.push(ray);
        }
    }
    Ok(lines)
}

/// Parses a block of whole text lines in parallel, appending its rays to `out` in order.
/// `line_base` is the number of lines before the block; returns the block's line count.
fn parse_text_block(block: &[u8], line_base: usize, out: &mut Vec<Ray>) -> Result<usize, RayFileError> {
    // Cut the block into pieces of about PARSE_PIECE bytes at line ends.
    let mut pieces = Vec::with_capacity(block.len() / PARSE_PIECE + 1);
    let mut rest = block;
    while !rest.is_empty() {
        let cut = if rest.len() <= PARSE_PIECE {
            rest.len()
        } else {
            rest[PARSE_PIECE..].iter().position(|&b| b == b'\n').map_or(rest.len(), |p| PARSE_PIECE + p + 1)
        };
        let (head, tail) = rest.split_at(cut);
        pieces.push(head);
        rest = tail;
    }
    let parsed: Vec<_> = pieces
        .par_iter()
        .map(|piece| {
            let mut rays = Vec::with_capacity(piece.len() / 48 + 1);
            parse_text_piece(piece, &mut rays).map(|lines| (rays, lines))
        })
        .collect();
    let mut lines = line_base;
    for piece in parsed {
        match piece {
            Ok((rays, n)) => {
                out.extend_from_slice(&rays);
                lines += n;
            }
            Err((line, message)) => return Err(RayFileError { place: (lines + line).to_string(), message }),
        }
    }
    Ok(lines - line_base)
}

/// Parses whole 32-byte binary records in parallel, appending their rays to `out`.
/// `ray_base` is the number of rays before the block.
fn parse_binary_block(block: &[u8], ray_base: usize, out: &mut Vec<Ray>) -> Result<(), RayFileError> {
    let start = out.len();
    out.resize(start + block.len() / RAY_BYTES, Ray::new(Vec3::ZERO, Vec3::X, 0.0, 0.0));
    out[start..].par_chunks_mut(CHUNK).zip(block.par_chunks(CHUNK * RAY_BYTES)).enumerate().try_for_each(
        |(c, (rays, bytes))| {
            for (i, (slot, record)) in rays.iter_mut().zip(bytes.chunks_exact(RAY_BYTES)).enumerate() {
                let mut v = [0.0f32; 8];
                for (x, b) in v.iter_mut().zip(record.chunks_exact(4)) {
                    *x = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
                }
                *slot = ray_from(&v).map_err(|message| {
                    let index = ray_base + c * CHUNK + i;
                    RayFileError { place: format!(" ray {index} at byte {}", index * RAY_BYTES), message }
                })?;
            }
            Ok(())
        },
    )
}

/// Reads up to `BLOCK` more bytes onto `buf`; true at the end of the input.
fn fill(reader: &mut dyn Read, buf: &mut Vec<u8>) -> io::Result<bool> {
    let n = reader.take(BLOCK as u64).read_to_end(buf)?;
    Ok(n < BLOCK)
}

/// Reads and checks every ray of `reader` in `format`. `name` is the file as shown in
/// messages. The whole input is rejected at its first bad ray.
pub fn read_rays(reader: &mut dyn Read, format: Format, name: &str) -> Result<Vec<Ray>, Error> {
    let wrap = |e: RayFileError| Error::Rays { file: name.to_string(), place: e.place, message: e.message };
    let io_err = |e: io::Error| Error::File { path: name.into(), message: format!("cannot read: {e}") };
    let mut rays = Vec::new();
    let mut buf: Vec<u8> = Vec::with_capacity(BLOCK + (1 << 16));
    match format {
        Format::Text => {
            let mut lines = 0;
            loop {
                let eof = fill(reader, &mut buf).map_err(io_err)?;
                let end = if eof { Some(buf.len()) } else { buf.iter().rposition(|&b| b == b'\n').map(|p| p + 1) };
                // A line longer than a block: read on until it ends.
                let Some(end) = end else { continue };
                lines += parse_text_block(&buf[..end], lines, &mut rays).map_err(wrap)?;
                buf.drain(..end);
                if eof {
                    return Ok(rays);
                }
            }
        }
        Format::Binary => {
            let mut total = 0u64;
            loop {
                let before = buf.len();
                let eof = fill(reader, &mut buf).map_err(io_err)?;
                total += (buf.len() - before) as u64;
                let end = buf.len() / RAY_BYTES * RAY_BYTES;
                if eof && end != buf.len() {
                    return Err(Error::File {
                        path: name.into(),
                        message: format!(
                            "size {total} bytes is not a multiple of {RAY_BYTES} (8 little-endian f32 per ray)"
                        ),
                    });
                }
                parse_binary_block(&buf[..end], rays.len(), &mut rays).map_err(wrap)?;
                buf.drain(..end);
                if eof {
                    return Ok(rays);
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Tracing

/// The results of tracing a ray list, one per ray in input order.
#[derive(Clone, Debug, PartialEq)]
pub enum Results {
    /// The closest hit of each ray (`prim` is the tree's triangle index).
    Closest(Vec<Option<Hit>>),
    /// Whether anything is hit in each ray's interval.
    AnyHit(Vec<bool>),
}

impl Results {
    /// Rays that hit something.
    pub fn hits(&self) -> u64 {
        match self {
            Results::Closest(h) => h.iter().filter(|h| h.is_some()).count() as u64,
            Results::AnyHit(h) => h.iter().filter(|&&h| h).count() as u64,
        }
    }

    /// Number of results.
    pub fn len(&self) -> usize {
        match self {
            Results::Closest(h) => h.len(),
            Results::AnyHit(h) => h.len(),
        }
    }

    /// True if there are no results.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Traces `rays` with `method` on the current rayon pool ([`trace::frame::stream_pass`]):
/// closest hits, or only whether anything is hit with `any_hit`.
pub fn trace(method: &dyn FrameTracer, rays: &[Ray], any_hit: bool) -> Results {
    if any_hit {
        let mut out = vec![false; rays.len()];
        method.stream_occluded(rays, &mut out);
        Results::AnyHit(out)
    } else {
        let mut out = vec![None; rays.len()];
        method.stream(rays, &mut out);
        Results::Closest(out)
    }
}

// ---------------------------------------------------------------------------------------
// Writing

/// The primitive id written for a hit: the file's face id of the tree's triangle `prim`.
#[inline]
fn file_prim(prim_ids: &[u32], prim: u32) -> u32 {
    prim_ids.get(prim as usize).copied().unwrap_or(prim)
}

/// Formats one chunk of results into bytes.
fn format_chunk(results: ResultsSlice<'_>, prim_ids: &[u32], format: Format) -> io::Result<Vec<u8>> {
    let mut buf = Vec::new();
    match (results, format) {
        (ResultsSlice::Closest(hits), Format::Text) => {
            buf.reserve(hits.len() * 32);
            for hit in hits {
                match hit {
                    Some(h) => writeln!(buf, "{} {} {} {}", file_prim(prim_ids, h.prim), h.t, h.u, h.v)?,
                    None => buf.extend_from_slice(b"-1 inf 0 0\n"),
                }
            }
        }
        (ResultsSlice::Closest(hits), Format::Binary) => {
            buf.reserve(hits.len() * HIT_BYTES);
            for hit in hits {
                let (prim, t, u, v) = match hit {
                    // Ids above i32::MAX are refused before tracing (see `check_prim_ids`).
                    Some(h) => (file_prim(prim_ids, h.prim) as i32, h.t, h.u, h.v),
                    None => (-1, f32::INFINITY, 0.0, 0.0),
                };
                buf.extend_from_slice(&prim.to_le_bytes());
                for x in [t, u, v] {
                    buf.extend_from_slice(&x.to_le_bytes());
                }
            }
        }
        (ResultsSlice::AnyHit(hits), Format::Text) => {
            buf.reserve(hits.len() * 2);
            for &h in hits {
                buf.extend_from_slice(if h { b"1\n" } else { b"0\n" });
            }
        }
        (ResultsSlice::AnyHit(hits), Format::Binary) => buf.extend(hits.iter().map(|&h| u8::from(h))),
    }
    Ok(buf)
}

/// A borrowed chunk of [`Results`].
#[derive(Clone, Copy)]
enum ResultsSlice<'a> {
    Closest(&'a [Option<Hit>]),
    AnyHit(&'a [bool]),
}

/// Writes `results` to `out` in `format`, mapping tree triangle indices to the file's
/// primitive ids with `prim_ids` (see the module documentation for the layouts). Chunks are
/// formatted in parallel, a group at a time, and written in order.
pub fn write_results(results: &Results, prim_ids: &[u32], format: Format, out: &mut dyn Write) -> io::Result<()> {
    const GROUP: usize = 256 * CHUNK;
    let len = results.len();
    for start in (0..len).step_by(GROUP) {
        let end = (start + GROUP).min(len);
        let chunks: Vec<_> = (start..end)
            .step_by(CHUNK)
            .collect::<Vec<_>>()
            .into_par_iter()
            .map(|s| {
                let e = (s + CHUNK).min(end);
                let slice = match results {
                    Results::Closest(h) => ResultsSlice::Closest(&h[s..e]),
                    Results::AnyHit(h) => ResultsSlice::AnyHit(&h[s..e]),
                };
                format_chunk(slice, prim_ids, format)
            })
            .collect();
        for chunk in chunks {
            out.write_all(&chunk?)?;
        }
    }
    out.flush()
}

/// Fails if a primitive id does not fit the binary output's `i32`.
/// Refuses binary output of primitive ids that do not fit an `i32`.
pub fn check_prim_ids(prim_ids: &[u32], format: Format, any_hit: bool) -> Result<(), Error> {
    if format == Format::Binary && !any_hit && prim_ids.iter().any(|&id| id > i32::MAX as u32) {
        return Err(Error::Usage("primitive ids above 2^31 - 1 do not fit the binary output; use text".into()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_line_accepts_rays_comments_and_blanks() {
        assert_eq!(parse_line("   "), Ok(None));
        assert_eq!(parse_line("  # a comment"), Ok(None));
        let ray = parse_line("0 0 -5\t0 0 1 0 inf\r\n").unwrap().unwrap();
        assert_eq!(ray.origin, Vec3::new(0.0, 0.0, -5.0));
        assert_eq!(ray.dir, Vec3::Z);
        assert_eq!(ray.t_max, f32::INFINITY);
        assert_eq!(parse_line("1e-3 2 3 1 0 0 -inf 1e30").unwrap().unwrap().t_min, f32::NEG_INFINITY);
    }

    #[test]
    fn parse_line_rejects_bad_rays() {
        assert!(parse_line("0 0 0 1 0 0 0").unwrap_err().contains("found 7"));
        assert!(parse_line("0 0 0 1 0 0 0 1 2").unwrap_err().contains("found 9"));
        assert!(parse_line("0 0 x 1 0 0 0 1").unwrap_err().contains("field 3 'x'"));
        assert!(parse_line("nan 0 0 1 0 0 0 1").unwrap_err().contains("origin"));
        assert!(parse_line("0 0 0 0 0 0 0 1").unwrap_err().contains("direction"));
        assert!(parse_line("0 0 0 inf 0 0 0 1").unwrap_err().contains("direction"));
        assert!(parse_line("0 0 0 1 0 0 2 1").unwrap_err().contains("interval"));
        assert!(parse_line("0 0 0 1 0 0 nan 1").unwrap_err().contains("interval"));
    }

    /// Line numbers stay right across parallel pieces and blocks.
    #[test]
    fn text_errors_name_the_line_across_pieces() {
        let mut text = String::new();
        for i in 0..500_000 {
            text.push_str(if i % 7 == 0 { "# comment\n" } else { "0 0 0 1 0 0 0 inf\n" });
        }
        let rays = read_rays(&mut text.as_bytes(), Format::Text, "r.txt").unwrap();
        assert_eq!(rays.len(), 500_000 - 500_000usize.div_ceil(7));
        text.push_str("0 0 0 1 0 0 0\n");
        let err = read_rays(&mut text.as_bytes(), Format::Text, "r.txt").unwrap_err().to_string();
        assert_eq!(err, "r.txt:500001: expected 8 numbers 'ox oy oz dx dy dz tmin tmax', found 7");
        // A last line without a newline counts too.
        let err = read_rays(&mut "\n\n1 2".as_bytes(), Format::Text, "r.txt").unwrap_err().to_string();
        assert!(err.starts_with("r.txt:3: "), "{err}");
    }

    #[test]
    fn binary_input_is_checked() {
        let mut bytes = Vec::new();
        for v in [[0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, f32::INFINITY], [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]] {
            bytes.extend(v.iter().flat_map(|x| x.to_le_bytes()));
        }
        let err = read_rays(&mut &bytes[..], Format::Binary, "r.bin").unwrap_err().to_string();
        assert!(err.starts_with("r.bin: ray 1 at byte 32: ray direction"), "{err}");
        assert_eq!(read_rays(&mut &bytes[..32], Format::Binary, "r.bin").unwrap().len(), 1);
        let err = read_rays(&mut &bytes[..40], Format::Binary, "r.bin").unwrap_err().to_string();
        assert!(err.contains("size 40 bytes"), "{err}");
    }

    #[test]
    fn formats_by_extension() {
        assert_eq!(Format::of_path(Path::new("a.bin")), Format::Binary);
        assert_eq!(Format::of_path(Path::new("a.F32")), Format::Binary);
        assert_eq!(Format::of_path(Path::new("a.txt")), Format::Text);
        assert_eq!(Format::of_path(Path::new("rays")), Format::Text);
    }
}
