//! Convolved edge widths: the hard shadow of one ray per pixel, blurred on the receiver by the
//! light's image through the nearest blocker. Both halves of the penumbra, no leaks, and no
//! search: at most one shadow ray per pixel and a gather over neighbouring pixels.
//!
//! ## What it changes against Eq. 5.1, and why
//! The thesis's Edge Width Soft Shadows (Tsakok 2008, chapter 5, Eq. 5.1) measure an edge
//! width *along* the shadow ray, which draws only the inner half of the penumbra and leaks
//! through thin occluders (`docs/results/soft-shadows-quality.md`). [`crate::silhouette`]
//! measures it *across* the ray instead, by searching the silhouette edges in the light's
//! cone: exact in both respects, but each search costs about 150 hard rays. Here the width
//! across the ray is read off the frame's own hard shadow: how far a pixel lies from the hard
//! shadow's edge, on its own surface, against the penumbra's width there.
//!
//! Precisely, for a planar occluder parallel to a planar receiver the visible fraction is the
//! hard shadow (the light's centre seen or not) convolved with the light's shape, scaled by
//! `t / (1 - t)` for a blocker at the fraction `t` of the way to the light and projected onto
//! the receiver along the ray (Soler & Sillion 1998, "Fast calculation of soft shadow
//! textures using convolution"): a receiver point `p + d` whose centre ray crosses the
//! blocker's plane inside the light's cone from `p` has its hard answer weighed in `p`'s.
//! PCSS (Fernando 2005) uses the same width from the blocker's distance, over a shadow map;
//! here the hard shadow is exact per pixel, traced by rays, so nothing leaks, and the kernel
//! is tested in world space ([`Kernel`]), so it keeps the light's shape and the receiver's
//! slant.
//!
//! ## A frame
//! 1. Every hit pixel has its hard shadow ray, nearest hit ([`probe`]): traced on the
//!    2-lattice (every other pixel of every other row), then, for each pixel between, taken
//!    from its lattice corners where they agree and lie on its surface, else traced
//!    ([`Params::sparse_probes`]). On the scenes of `docs/results/soft-shadows-quality.md`
//!    that traces 29% to 46% of the rays of a probe per pixel. A tile's rays go together,
//!    in Morton order, as packets of the SIMD level's width ([`crate::probe_packets`]; the
//!    single rays' probes bit for bit).
//! 2. The blocked pixels with a lit 8-neighbour are the hard shadow's edge ([`hard_edges`],
//!    read off a byte a pixel that the probes write); their probes found their nearest
//!    blockers.
//! 3. [`ConvolutionFrame::new`] finds the pixels a penumbra can reach: around each edge
//!    pixel, as far as its blocker's penumbra reaches in pixels (at most
//!    [`Params::max_reach`] of the frame's height). Each takes the blocker of the nearest
//!    edge pixel reaching it.
//! 4. [`ConvolutionFrame::visibility`] averages the hard answers of the pixels inside the
//!    pixel's kernel that lie on its surface (normals and tangent planes close), reading at
//!    most `(2 taps + 1)^2` of them ([`Params::taps`]; wider kernels are read on a coarser
//!    grid). Pixels outside the reach keep their hard answer. A row of the kernel is read
//!    in SIMD lanes, 16 on AVX-512 (one vector for the default 13 columns), 8 on AVX2, 4
//!    otherwise, from the pixels' fields stored one array each (structure of arrays): the
//!    same bits at every width ([`ConvolutionFrame::with_lanes`]).
//! 5. [`convolved_frame`] runs steps 1 to 4 over a frame, convolving inside the reach only on
//!    the lattice of the sparse passes ([`crate::sparse`]): every fourth pixel, then the
//!    others only where blending their corners is not safe ([`TOLERANCES`]).
//!
//! ## What it gets wrong
//! The convolution is exact only for parallel planes. Where the occluder is not flat across
//! the penumbra, the one blocker distance is a guess (the nearest edge pixel's); where the
//! receiver's continuation is hidden from the camera (behind the occluder itself), the
//! kernel averages the part it sees; an occluder thinner than a pixel casts no hard shadow
//! to blur. Those are the errors `rttest shadows` measures against its reference.

use glam::Vec3;
use kdtree::KdTree;
use kdtree::isa::SimdLevel;
use packets::Width;
use packets::simd::{SimdF32, SimdMask, array_fn};

use crate::probe_packets::ProbePackets;
use crate::sampling::{AreaLight, ShadingPoint};
use crate::silhouette::{Probe, Profile, hard_probe_and_blocker, hard_probe_with};
use crate::sparse::{self, Answer, Pixel, SparseFrame, Tolerances};
use rayon::prelude::*;

/// Traces the hard shadow ray of `p` (nearest hit), whose pixel covers `footprint` world units
/// across: the pixel as the convolution (and the sparse passes) read it, and, where the
/// light's centre is blocked, the blocker's distance as the fraction of the way (the
/// kernel's scale at the hard shadow's edge).
#[inline(always)]
pub fn probe(tree: &KdTree, light: &AreaLight, p: &ShadingPoint, footprint: f32) -> (Pixel, Option<f32>) {
    let (probe, blocker) = hard_probe_and_blocker(tree, light, p, footprint);
    (Pixel::new(p, footprint, probe), blocker)
}

/// The hard shadow's edge in a `width` x `height` frame of `receivers` (row-major): the
/// blocked pixels with a lit 8-neighbour, as ascending row-major indices (found in parallel).
/// Empty for a buffer of the wrong length.
pub fn hard_edges(width: u32, height: u32, receivers: &[Option<Pixel>]) -> Vec<usize> {
    let sides: Vec<Side> = receivers.par_iter().map(|r| Side::of(r.as_ref())).collect();
    edges_of(width, height, &sides)
}

/// A pixel's hard answer as the edge test reads it, in a byte: a fortieth of its record's
/// bytes, so the test's nine reads a pixel stay in cache.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Side {
    /// No hit, or a final probe (its answer is not an occluder's).
    #[default]
    Neither,
    /// The light's centre is visible.
    Lit,
    /// The light's centre is blocked.
    Blocked,
}

impl Side {
    /// The side of `pixel`'s probe (`Neither` for no pixel).
    fn of(pixel: Option<&Pixel>) -> Side {
        match pixel.map(|p| p.probe) {
            Some(Probe::Lit(_)) => Side::Lit,
            Some(Probe::Blocked(_)) => Side::Blocked,
            _ => Side::Neither,
        }
    }
}

/// [`hard_edges`] of the frame's sides (row-major), rows in parallel.
fn edges_of(width: u32, height: u32, sides: &[Side]) -> Vec<usize> {
    let (w, h) = (width as usize, height as usize);
    if sides.len() != w * h {
        return Vec::new();
    }
    (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            let rows = y.saturating_sub(1)..(y + 2).min(h);
            let lit_near = move |x: usize| {
                rows.clone().any(|ny| sides[ny * w + x.saturating_sub(1)..ny * w + (x + 2).min(w)].contains(&Side::Lit))
            };
            (0..w).filter(move |&x| sides[y * w + x] == Side::Blocked && lit_near(x)).map(move |x| y * w + x)
        })
        .collect()
}

/// One frame's convolved visible fractions, row-major, and the shadow rays traced: every
/// step of the module's text, each pass over the rows (the probes' over bands of tiles) in
/// parallel. `point(x, y)` gives pixel `(x, y)`'s shading point and footprint (world units
/// across), `None` where nothing was hit (visibility 0). Inside the penumbrae's reach the
/// convolution runs on the sparse passes' lattice ([`crate::sparse`], with `tolerances`): on
/// every fourth pixel, then on the others only where blending their corners is not safe.
pub fn convolved_frame(
    tree: &KdTree,
    light: &AreaLight,
    (width, height): (u32, u32),
    params: Params,
    tolerances: Tolerances,
    buffers: &mut ConvolutionBuffers,
    point: impl Fn(u32, u32) -> Option<(ShadingPoint, f32)> + Sync,
) -> (Vec<f32>, u64) {
    let w = width.max(1) as usize;
    let n = width as usize * height as usize;
    let xy = |i: usize| ((i % w) as u32, (i / w) as u32);
    let ConvolutionBuffers { pixels, near, sides, lattice, blockers, taps, known } = buffers;
    // The probes in bands of `TILE` rows, each band tile by tile: neighbouring rays, one after
    // the other, visit the same nodes (5% to 15% faster than row by row). Every slot is
    // written, so the buffers are only resized, never cleared first (a frame's worth of
    // memory written by one thread). With `params.sparse_probes`, the 2-lattice's probes
    // first, in a buffer of their own, then every pixel from them (`Lattice::probe`).
    pixels.resize(n, None);
    near.resize(n, f32::NAN);
    sides.resize(n, Side::Neither);
    let lanes = Width::for_level(SimdLevel::active());
    let mut probed = 0;
    if n > 0 {
        let lattice = if params.sparse_probes {
            let (lw, lh) = (width.div_ceil(2), height.div_ceil(2));
            lattice.resize(lw as usize * lh as usize, (None, f32::NAN));
            let chunks = lattice.par_chunks_mut(lw as usize * (TILE / 2) as usize);
            probed += in_bands((lw, lh), TILE / 2, chunks, |out, batch, tile| {
                for &(at, x, y) in tile {
                    match point(2 * x, 2 * y) {
                        Some((p, footprint)) => batch.push(at, p, footprint),
                        None => out[at] = (None, f32::NAN),
                    }
                }
                batch.trace(tree, light, lanes, |at, pixel, t| out[at] = (Some(pixel), t))
            });
            Some(Lattice { width: lw, height: lh, probes: &lattice[..] })
        } else {
            None
        };
        let band = w * TILE as usize;
        let bands = pixels.par_chunks_mut(band).zip(near.par_chunks_mut(band)).zip(sides.par_chunks_mut(band));
        probed += in_bands((width, height), TILE, bands, |((out, near), sides), batch, tile| {
            let mut rays = 0;
            for &(at, x, y) in tile {
                let known = match &lattice {
                    Some(lattice) => lattice.probe(tree, light, (x, y), &point, &mut rays),
                    None => point(x, y).map_or(Lookup::Known(None), |(p, footprint)| Lookup::Trace(p, footprint)),
                };
                let known = match known {
                    Lookup::Known(known) => known,
                    Lookup::Trace(p, footprint) => {
                        batch.push(at, p, footprint);
                        continue;
                    }
                };
                (out[at], near[at]) = known.map_or((None, f32::NAN), |(p, t)| (Some(p), t));
                sides[at] = Side::of(out[at].as_ref());
            }
            rays + batch.trace(tree, light, lanes, |at, pixel, t| {
                (out[at], near[at]) = (Some(pixel), t);
                sides[at] = Side::of(out[at].as_ref());
            })
        });
    }
    let (pixels, near, sides) = (&pixels[..], &near[..], &sides[..]);
    // The edge's blockers, from its probes (in `(0, 1)`: a blocker at either end has no
    // kernel).
    let edges: Vec<(usize, f32)> = edges_of(width, height, sides)
        .into_iter()
        .filter_map(|i| (near[i] > 0.0 && near[i] < 1.0).then_some((i, near[i])))
        .collect();
    let reused = (std::mem::take(blockers), std::mem::take(taps));
    let convolved = ConvolutionFrame::in_buffers(width, height, pixels, &edges, light, params, reused);
    let mask = convolved.mask();
    let sparse = SparseFrame::new(width, height, pixels, &mask, tolerances);
    // Every pixel starts at its hard answer, the final one outside the mask. The masked ones
    // are answered pass by pass, each pass reading only the earlier passes' answers (pass 0,
    // the mask's 4-lattice, none).
    pixels
        .par_iter()
        .map(|p| p.as_ref().map_or(Answer::Pending, |p| Answer::Hard(p.probe.fraction())))
        .collect_into_vec(known);
    for pass in 0..sparse::PASSES {
        // The masked pixels of the pass, found by the pass itself (`resolve` answers only its
        // own): one parallel region a pass, no list made between them.
        let answers: Vec<(usize, Answer)> = (0..n)
            .into_par_iter()
            .with_min_len(w)
            .filter(|&i| mask[i])
            .filter_map(|i| {
                let (x, y) = xy(i);
                Some((i, sparse.resolve(known, x, y, pass, |_| convolved.visibility(x, y))?))
            })
            .collect();
        for (i, answer) in answers {
            known[i] = answer;
        }
    }
    let visible = known.par_iter().map(|a| a.fraction()).collect();
    (*blockers, *taps) = convolved.into_buffers();
    (visible, probed)
}

/// The side of the square tiles [`convolved_frame`] traces its probes in (even: a tile of
/// the 2-lattice is half as wide).
const TILE: u32 = 16;

/// Runs `f` on every tile of a `width` x `height` frame, in bands of `tile` rows, the bands
/// in parallel, each band tile by tile. `bands` gives each band's output, row-major (`width *
/// tile` entries); `f(out, batch, pixels)` gets the tile's pixels as `(at, x, y)`, pixel `(x,
/// y)` at `at` of its band's `out`, in Morton order (neighbouring rays one after the other, so
/// that the probes it queues in `batch`, one per thread, share packets), and returns the rays
/// it traced. Returns their sum.
fn in_bands<B: Send>(
    (width, height): (u32, u32),
    tile: u32,
    bands: impl IndexedParallelIterator<Item = B>,
    f: impl Fn(&mut B, &mut ProbePackets, &[(usize, u32, u32)]) -> u64 + Sync,
) -> u64 {
    let tiles = scenes::tiles(width, height, tile);
    let order = scenes::morton_order(tile, tile);
    bands
        .zip(tiles.par_chunks(width.div_ceil(tile) as usize))
        .map_init(
            || (ProbePackets::default(), Vec::new()),
            |(batch, pixels), (mut out, band)| {
                let mut rays = 0;
                for t in band {
                    pixels.clear();
                    // The full tile's order, less the pixels a clipped tile lacks.
                    let inside = order.iter().map(|&i| (t.x0 + i % tile, t.y0 + i / tile));
                    pixels.extend(
                        inside
                            .filter(|&(x, y)| x < t.x1 && y < t.y1)
                            .map(|(x, y)| ((y - band[0].y0) as usize * width as usize + x as usize, x, y)),
                    );
                    rays += f(&mut out, batch, pixels);
                }
                rays
            },
        )
        .sum()
}

/// A pixel's probe as [`Lattice::probe`] finds it.
enum Lookup {
    /// Known without a ray of its own: the lattice's, or inferred from its corners (`None`:
    /// nothing hit).
    Known(Option<(Pixel, f32)>),
    /// To be traced: the pixel's shading point and footprint.
    Trace(ShadingPoint, f32),
}

/// The probes of a frame's 2-lattice (the pixels of even `x` and `y`), row-major, each with
/// its blocker (NaN: none), as [`convolved_frame`] traces them before the other pixels.
struct Lattice<'a> {
    width: u32,
    height: u32,
    probes: &'a [(Option<Pixel>, f32)],
}

impl Lattice<'_> {
    /// Pixel `(x, y)`'s probe and blocker (NaN: none), `Known(None)` where nothing was hit,
    /// or, where it must be traced, its shading point.
    ///
    /// A lattice pixel has its own. Another one takes the answer of its nearest lattice
    /// pixels (its corners: two on a lattice line, else four) where each was hit, traced a
    /// ray that saw the light, or did not, alike (the centre ray, or for a final probe the ray
    /// to the part of the light above its horizon) and lies on its surface
    /// ([`Tolerances::on_one_surface`] with [`TOLERANCES`]): its own ray, whichever it needs,
    /// is taken to answer as theirs, and is not traced. Elsewhere (a corner past the frame,
    /// without a hit or a ray, on another surface, or the corners apart) it is to trace its
    /// probe ([`Lookup::Trace`]). What an inferred pixel misses is a hard shadow, or a gap of
    /// light, thinner than the two pixels between its corners; it measures no blocker (NaN),
    /// so the hard shadow's edge takes its blockers from the traced pixels. Adds the rays an
    /// inferred pixel traced (a final probe's own) to `rays`.
    #[inline(always)]
    fn probe(
        &self,
        tree: &KdTree,
        light: &AreaLight,
        (x, y): (u32, u32),
        point: impl Fn(u32, u32) -> Option<(ShadingPoint, f32)>,
        rays: &mut u64,
    ) -> Lookup {
        let entry = |cx: u32, cy: u32| {
            let (lx, ly) = (cx / 2, cy / 2);
            let inside = lx < self.width && ly < self.height;
            inside.then(|| self.probes.get(ly as usize * self.width as usize + lx as usize)).flatten()
        };
        if x.is_multiple_of(2) && y.is_multiple_of(2) {
            return Lookup::Known(entry(x, y).and_then(|&(pixel, t)| pixel.map(|p| (p, t))));
        }
        let Some((p, footprint)) = point(x, y) else { return Lookup::Known(None) };
        let own = Pixel::new(&p, footprint, Probe::Lit(1.0));
        // The corners' columns and rows: one on a lattice line, else the two either side.
        let near = |c: u32| if c.is_multiple_of(2) { (c, None) } else { (c - 1, Some(c + 1)) };
        let ((x0, x1), (y0, y1)) = (near(x), near(y));
        let (x1, y1) = (x1.unwrap_or(x0), y1.unwrap_or(y0));
        let mut seen = None;
        // On a lattice line the corners repeat: each is tested twice, and agrees with itself.
        let agree = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)].into_iter().all(|(cx, cy)| {
            let Some((Some(corner), _)) = entry(cx, cy) else { return false };
            let blocked = match corner.probe {
                Probe::Lit(_) => false,
                Probe::Blocked(_) => true,
                Probe::Done(v) if v.rays == 1 => v.fraction <= 0.0,
                Probe::Done(_) => return false,
            };
            let apart = ((cx.abs_diff(x).pow(2) + cy.abs_diff(y).pow(2)) as f32).sqrt();
            let same = *seen.get_or_insert(blocked) == blocked;
            same && TOLERANCES.on_one_surface(&own, corner, apart)
        });
        let Some(blocked) = seen.filter(|_| agree) else { return Lookup::Trace(p, footprint) };
        let mut inferred = false;
        let (probe, _) = hard_probe_with(tree, light, &p, footprint, |_| {
            inferred = true;
            blocked.then_some(f32::NAN)
        });
        // A final probe whose ray was not inferred traced its own, if any.
        *rays += u64::from(match probe {
            Probe::Done(v) if !inferred => v.rays,
            _ => 0,
        });
        Lookup::Known(Some((Pixel { probe, ..own }, f32::NAN)))
    }
}

/// The buffers of [`convolved_frame`], kept from one frame to the next so that a frame
/// writes to memory it wrote before. Fresh buffers, about 100 bytes a pixel, cost a page
/// fault per 4 KiB: 6,000 faults and about a tenth of the time of a 512 x 512 frame, on the
/// machine of `docs/results/soft-shadows-quality.md`. Any frame size may follow any other.
#[derive(Debug, Default)]
pub struct ConvolutionBuffers {
    pixels: Vec<Option<Pixel>>,
    near: Vec<f32>,
    sides: Vec<Side>,
    lattice: Vec<(Option<Pixel>, f32)>,
    blockers: Vec<f32>,
    taps: Vec<f32>,
    known: Vec<Answer>,
}

/// When the sparse passes ([`crate::sparse`]) blend a pixel's lattice corners instead of
/// convolving it: [`Tolerances::DEFAULT`] with a spread of 0.5. On the scenes of
/// `docs/results/soft-shadows-quality.md` that convolves 10% to 15% fewer pixels than a spread
/// of 0.3, and its error is lower on three of the four real scenes and the same on the
/// kitchen (blending smooths the kernel's coarse grid).
pub const TOLERANCES: Tolerances = Tolerances { spread: 0.5, ..Tolerances::DEFAULT };

/// How far the convolution reaches and what it counts as one surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    /// A kernel is read on a grid of at most `2 taps + 1` pixels across: every pixel while
    /// its radius is at most `taps` pixels, every `ceil(radius / taps)`-th beyond (1 to 15;
    /// others are taken as the nearest).
    pub taps: u32,
    /// The widest penumbra, from the hard shadow's edge, as a share of the frame's height
    /// (at least a pixel); wider ones are cut there.
    pub max_reach: f32,
    /// The smallest cosine between the normals of a pixel and a pixel it reads.
    pub cos_normal: f32,
    /// How far the pixel read may lie from the pixel's tangent plane, in footprints (the
    /// larger of the two pixels'), plus [`Params::bend`] per pixel between them.
    pub plane: f32,
    /// The tangent plane's allowance per pixel between the two, in footprints (a gently
    /// curved receiver).
    pub bend: f32,
    /// Whether the probes are traced on the 2-lattice first, a pixel between then taking its
    /// lattice corners' answer where they agree and lie on its surface, with no ray of its
    /// own; otherwise every pixel traces its probe. What the sparse probes miss is a hard
    /// shadow, or a gap of light, thinner than two pixels that passes between its corners:
    /// on the scenes of `docs/results/soft-shadows-quality.md` they cut the convolution's
    /// time by 2% to 16% for up to 11% more RMSE (the kitchen at 256 x 256).
    pub sparse_probes: bool,
}

impl Params {
    /// The defaults: kernels read on at most 13 x 13 pixels, penumbrae up to 1/32 of the
    /// frame's height (8 pixels at 256 x 256), normals within 25 degrees, two footprints and a
    /// quarter per pixel off the plane, sparse probes.
    ///
    /// On the scenes of `docs/results/soft-shadows-quality.md` a reach of 1/16 of the height
    /// (16 pixels at 256 x 256) had more error on all four real scenes (atrium 0.068 against
    /// 0.064, before the cells' weights): a wide kernel reads more of what a screen does not show (the receiver hidden
    /// behind the occluder, surfaces that end inside it). Only the analytic sphere, which
    /// fits the model, gained (0.0055 against 0.0065).
    pub const DEFAULT: Params =
        Params { taps: 6, max_reach: 1.0 / 32.0, cos_normal: 0.906, plane: 2.0, bend: 0.25, sparse_probes: true };

    /// [`Params::taps`] as the kernel reads it: from 1 to 15 (at most 31 pixels across).
    fn grid_taps(&self) -> u32 {
        self.taps.clamp(1, 15)
    }
}

impl Default for Params {
    fn default() -> Params {
        Params::DEFAULT
    }
}

/// The light's image through a blocker, as a test on offsets `d` from the receiver point: the
/// point `p + d`'s centre ray crosses the blocker's plane inside the light's cone from `p`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kernel {
    /// A parallelogram light: `|d . a| <= 1` and `|d . b| <= 1` (the offset projected along
    /// the ray onto the light's plane, in the light's half edges, over `t / (1 - t)`).
    Rect {
        /// The first half edge's dual, projected and scaled.
        a: Vec3,
        /// The second half edge's dual, projected and scaled.
        b: Vec3,
    },
    /// A disc (a spherical light's cone): the offset across the unit ray direction `dir`
    /// within `sqrt(r2)`.
    Disc {
        /// The unit direction to the light's centre.
        dir: Vec3,
        /// The squared radius of the light's image on the receiver side.
        r2: f32,
    },
}

impl Kernel {
    /// The kernel of a receiver at `p` whose ray to the light's centre is blocked at the
    /// fraction `t` of the way; `None` for a degenerate one (`t` not in `(0, 1)`, the point
    /// inside a spherical light, a ray along a rectangle's plane, non-finite input).
    pub fn new(light: &AreaLight, p: Vec3, t: f32) -> Option<Kernel> {
        if !(t > 0.0 && t < 1.0) {
            return None;
        }
        let k = t / (1.0 - t);
        let dir = (light.center() - p).normalize_or_zero();
        let kernel = match (light, Profile::of(light, p)?) {
            (AreaLight::Rect(l), Profile::Rect { u, v }) => {
                let n = l.edge_u.cross(l.edge_v);
                let dn = dir.dot(n);
                if dn.abs() <= 1e-3 * n.length() {
                    return None;
                }
                // Duals of the half edges in the light's plane: e = alpha u + beta v has
                // alpha = e . du and beta = e . dv.
                let (du, dv) = (v.cross(n) / u.dot(v.cross(n)), n.cross(u) / v.dot(n.cross(u)));
                // Projected along the ray onto the light's plane: e = d - dir (d . n) / (dir . n).
                let along = |dual: Vec3| (dual - n * (dir.dot(dual) / dn)) / k;
                Kernel::Rect { a: along(du), b: along(dv) }
            }
            (_, profile) => {
                let r = profile.max_support() * k;
                Kernel::Disc { dir, r2: r * r }
            }
        };
        let finite = match kernel {
            Kernel::Rect { a, b } => a.is_finite() && b.is_finite(),
            Kernel::Disc { dir, r2 } => dir != Vec3::ZERO && r2.is_finite(),
        };
        finite.then_some(kernel)
    }

    /// Whether the offset `d` from the receiver point lies inside.
    #[inline]
    pub fn contains(&self, d: Vec3) -> bool {
        match *self {
            Kernel::Rect { a, b } => d.dot(a).abs() <= 1.0 && d.dot(b).abs() <= 1.0,
            Kernel::Disc { dir, r2 } => {
                let along = d.dot(dir);
                d.length_squared() - along * along <= r2
            }
        }
    }
}

/// One frame's receivers (row-major, `None` where nothing was hit), with each pixel's
/// blocker for the kernel: ready to answer any pixel ([`ConvolutionFrame::visibility`]).
#[derive(Clone, Debug)]
pub struct ConvolutionFrame<'a> {
    width: u32,
    height: u32,
    receivers: &'a [Option<Pixel>],
    light: &'a AreaLight,
    params: Params,
    /// The widest reach in pixels ([`Params::max_reach`] of the height).
    widest: f32,
    /// Per pixel, the blocker fraction its kernel takes (NaN: keep the hard answer).
    blockers: Vec<f32>,
    /// What a kernel reads of each pixel, one array per field.
    taps: Taps,
    /// The lanes the kernel reads a row with, chosen once for the frame.
    lanes: Width,
}

/// The pixels a kernel reads: every `step`-th one from `(x, y)`, `taps` steps each way.
#[derive(Clone, Copy, Debug)]
struct Grid {
    x: i64,
    y: i64,
    step: i64,
    taps: i64,
}

/// The pixels as a kernel reads them, structure of arrays: each one's point, normal and
/// footprint, the footprint's sign its hard ray's answer (`+` lit, `-` blocked). A pixel
/// without a hit, or whose light centre is below its horizon (its answer is the horizon's,
/// not an occluder's), is NaN in every field and is never read. Each field's row has `pad`
/// NaN pixels on both sides, as many as a kernel's lanes reach past the frame, so a row's
/// lanes are read with no test of their own; a field's right padding is the next one's left.
#[derive(Clone, Debug)]
struct Taps {
    /// The entries of one image row: its 7 fields' rows, each `width + pad` entries, and a
    /// final `pad`.
    row: usize,
    /// The entries from one field's row to the next.
    field: usize,
    pad: usize,
    /// Row after row, each its 7 fields' rows: `x`, `y`, `z`, normal `x`, `y`, `z`, signed
    /// footprint.
    values: Vec<f32>,
}

impl Taps {
    const FIELDS: usize = 7;
    const X: usize = 0;
    const NORMAL: usize = 3;
    const FOOTPRINT: usize = 6;

    /// The taps of `receivers` (`width` per row), rows in parallel, in `values` (overwritten).
    fn new(width: usize, receivers: &[Option<Pixel>], pad: usize, mut values: Vec<f32>) -> Taps {
        let (w, field) = (width.max(1), width + pad);
        let row = Taps::FIELDS * field + pad;
        // Every row is written (NaN first), so the buffer is resized, never cleared first.
        values.resize(row * (receivers.len() / w), f32::NAN);
        if values.is_empty() {
            return Taps { row, field, pad, values };
        }
        values.par_chunks_mut(row).zip(receivers.par_chunks(w)).for_each(|(out, pixels)| {
            out.fill(f32::NAN);
            for (x, pixel) in pixels.iter().enumerate() {
                let Some(p) = pixel else { continue };
                let footprint = match p.probe {
                    Probe::Lit(_) => p.footprint.abs(),
                    Probe::Blocked(_) => -p.footprint.abs(),
                    Probe::Done(_) => continue,
                };
                let fields = [p.point.x, p.point.y, p.point.z, p.normal.x, p.normal.y, p.normal.z, footprint];
                for (k, v) in fields.into_iter().enumerate() {
                    out[k * field + pad + x] = v;
                }
            }
        });
        Taps { row, field, pad, values }
    }

    /// Row `y`'s fields, each `width + 2 pad` entries with the pixel `x` at `pad + x`.
    #[inline(always)]
    fn row(&self, y: i64) -> [&[f32]; Taps::FIELDS] {
        let start = y as usize * self.row;
        std::array::from_fn(|k| &self.values[start + k * self.field..start + (k + 1) * self.field + self.pad])
    }
}

/// One row's nearest edge pixels, as [`ConvolutionFrame::new`] finds them: per pixel the
/// squared distance in pixels to the nearest edge pixel reaching it so far, and that edge
/// pixel's blocker (NaN: none yet). Both are padded by a vector's lanes past the row, so
/// that a span of the row is read and written in whole vectors.
#[derive(Debug, Default)]
struct Nearest {
    distances: Vec<f32>,
    blockers: Vec<f32>,
}

impl Nearest {
    /// A row of `width` pixels with no edge pixel yet (the buffers kept).
    fn clear(&mut self, width: usize) {
        let padded = width + MAX_LANES;
        self.distances.clear();
        self.distances.resize(padded, f32::INFINITY);
        self.blockers.clear();
        self.blockers.resize(padded, f32::NAN);
    }

    /// Adds the edge pixels `edges` (column, row, reach in pixels, blocker) to row `y`: each
    /// pixel of the row within an edge pixel's reach takes its blocker where it is the nearest
    /// so far (the earlier one on a tie). Lane `l` of a span's `j`-th vector is its pixel
    /// `j W + l`, and pixels past the span keep what they hold. Each lane does the scalar
    /// loop's operations on its pixel (the offsets are whole numbers, exact in `f32`), so
    /// every width gives the same bits.
    #[inline(always)]
    fn add<'e, V: SimdF32>(&mut self, edges: impl Iterator<Item = &'e (usize, usize, f32, f32)>, y: usize) {
        const { assert!(V::LANES <= MAX_LANES, "the rows are padded by MAX_LANES") };
        let width = self.distances.len() - MAX_LANES;
        let lane = V::strided(&LANE, 0, 1);
        for edge in edges {
            let Some((lo, hi, dy2)) = span(edge, y, width) else { continue };
            // The offsets count in `i32`, whose conversion to `f32` is one instruction (a
            // `usize`'s is a dozen).
            let dx0 = -((edge.0 - lo) as i32);
            let (blocker, dy2) = (V::splat(edge.3), V::splat(dy2));
            for start in (lo..hi).step_by(V::LANES) {
                let dx = lane + V::splat((dx0 + (start - lo) as i32) as f32);
                let d2 = dx * dx + dy2;
                let near = V::strided(&self.distances, start, 1);
                let closer = d2.cmplt(near) & lane.cmplt(V::splat((hi - start) as f32));
                let slots = start..start + V::LANES;
                self.distances[slots.clone()].copy_from_slice(V::select(closer, d2, near).to_array().as_ref());
                let old = V::strided(&self.blockers, start, 1);
                self.blockers[slots].copy_from_slice(V::select(closer, blocker, old).to_array().as_ref());
            }
        }
    }
}

/// The pixels of row `y` (of `width`) that the edge pixel `(column, row, reach, blocker)`
/// reaches, `lo..hi`, and the squared rows between them; `None` when the reach's disc misses
/// the row.
#[inline(always)]
fn span(&(ex, ey, reach, _): &(usize, usize, f32, f32), y: usize, width: usize) -> Option<(usize, usize, f32)> {
    let dy2 = (ey.abs_diff(y) as f32).powi(2);
    let half = reach * reach - dy2;
    if half < 0.0 {
        return None;
    }
    let half = half.sqrt() as usize;
    Some((ex.saturating_sub(half), (ex + half + 1).min(width), dy2))
}

/// The most lanes a [`SimdF32`] of the kernels has (AVX-512's 16): how far the rows of
/// [`Nearest`] and [`Taps`] are padded for whole vectors.
const MAX_LANES: usize = 16;

impl<'a> ConvolutionFrame<'a> {
    /// A `width` x `height` frame of `receivers` (row-major) under `light`, with the blockers
    /// of its hard shadow's edge (`edges`: row-major index and the blocker [`probe`] found,
    /// ascending by index, as [`hard_edges`] lists them). Each pixel within an edge pixel's
    /// penumbra reach (a disc of [`Params::max_reach`] of the height at most) takes the
    /// blocker of the nearest such edge pixel; rows in parallel. A buffer of the wrong length
    /// gives a frame of hard answers. Kernels are read at the widest lanes the SIMD level
    /// allows ([`ConvolutionFrame::with_lanes`]).
    pub fn new(
        width: u32,
        height: u32,
        receivers: &'a [Option<Pixel>],
        edges: &[(usize, f32)],
        light: &'a AreaLight,
        params: Params,
    ) -> ConvolutionFrame<'a> {
        ConvolutionFrame::in_buffers(width, height, receivers, edges, light, params, Default::default())
    }

    /// [`ConvolutionFrame::new`] in the buffers of an earlier frame (its blockers and taps,
    /// [`ConvolutionFrame::into_buffers`]), overwritten.
    fn in_buffers(
        width: u32,
        height: u32,
        receivers: &'a [Option<Pixel>],
        edges: &[(usize, f32)],
        light: &'a AreaLight,
        params: Params,
        (mut blockers, taps_buffer): (Vec<f32>, Vec<f32>),
    ) -> ConvolutionFrame<'a> {
        let w = width as usize;
        let widest = (params.max_reach * height as f32).max(1.0);
        // Each edge pixel's position, reach (pixels) and blocker: none for a buffer of the
        // wrong length.
        let fits = receivers.len() == w * height as usize && w > 0;
        let reached: Vec<(usize, usize, f32, f32)> = edges
            .par_iter()
            .filter(|_| fits)
            .filter_map(|&(i, t)| {
                let r = receivers.get(i)?.as_ref()?;
                Some((i % w, i / w, reach_pixels(light, r, t, widest), t))
            })
            .collect();
        // Every row is written (NaN first), so the buffer is resized, never cleared first.
        blockers.resize(receivers.len(), f32::NAN);
        let reach = widest.ceil() as usize;
        let lanes = Width::for_level(SimdLevel::active());
        blockers.par_chunks_mut(w.max(1)).enumerate().for_each_init(Nearest::default, |nearest, (y, row)| {
            row.fill(f32::NAN);
            let first = reached.partition_point(|e| e.1 + reach < y);
            let near = reached[first..].iter().take_while(|e| e.1 <= y + reach);
            if near.clone().next().is_none() {
                return;
            }
            nearest.clear(row.len());
            packets::at_width!(lanes, V => nearest.add::<V>(near, y));
            row.copy_from_slice(&nearest.blockers[..row.len()]);
        });
        // Each edge pixel takes its own blocker (its reach is at least 0), so no edge within
        // the frame means no kernel.
        let taps = if reached.is_empty() {
            Taps::new(0, &[], 0, taps_buffer)
        } else {
            // A kernel's lanes reach `taps` steps left of the pixel and, rounded up to whole
            // vectors of at most `MAX_LANES`, `taps + MAX_LANES - 1` steps right; a step is
            // at most the widest reach over `taps`, rounded up.
            let taps = params.grid_taps() as usize;
            let step = (widest.ceil() as usize).div_ceil(taps);
            Taps::new(w, receivers, (taps + MAX_LANES) * step, taps_buffer)
        };
        ConvolutionFrame { width, height, receivers, light, params, widest, blockers, taps, lanes }
    }

    /// The frame's buffers, for the next frame's [`ConvolutionFrame::in_buffers`].
    fn into_buffers(self) -> (Vec<f32>, Vec<f32>) {
        (self.blockers, self.taps.values)
    }

    /// The same frame with its kernels read `lanes` pixels at a time: the answers are the
    /// same bit for bit at every width (each lane sums one column of the kernel, and the
    /// columns are summed in one order), only the speed differs.
    pub fn with_lanes(self, lanes: Width) -> ConvolutionFrame<'a> {
        ConvolutionFrame { lanes, ..self }
    }

    /// How many pixels are within a penumbra's reach (answered by the convolution).
    pub fn reached(&self) -> usize {
        self.blockers.iter().filter(|b| !b.is_nan()).count()
    }

    /// Per pixel (row-major), whether it is within a penumbra's reach: the mask of the sparse
    /// passes ([`crate::sparse`]), which convolve on a coarse lattice of these pixels and
    /// blend the pixels between where that is safe.
    pub fn mask(&self) -> Vec<bool> {
        self.blockers.par_iter().map(|b| !b.is_nan()).collect()
    }

    /// The visible fraction at pixel `(x, y)`: its hard answer out of the penumbrae's reach,
    /// else the mean hard answer of the pixels of its kernel on its surface (at most its
    /// horizon's share when its centre is lit). `0` where nothing was hit.
    pub fn visibility(&self, x: u32, y: u32) -> f32 {
        packets::at_width!(self.lanes, V => self.visibility_in::<V>(x, y))
    }

    /// [`ConvolutionFrame::visibility`] with the kernel's rows read in lanes of `V`: any
    /// [`SimdF32`], the portable ones of any width included (the twins of the tests).
    #[inline(always)]
    fn visibility_in<V: SimdF32>(&self, x: u32, y: u32) -> f32 {
        let i = y as usize * self.width as usize + x as usize;
        let Some(Some(r)) = self.receivers.get(i) else { return 0.0 };
        let hard = r.probe.fraction();
        let t = self.blockers[i];
        let (Probe::Lit(_) | Probe::Blocked(_), false) = (r.probe, t.is_nan()) else { return hard };
        let Some(kernel) = Kernel::new(self.light, r.point, t) else { return hard };
        let p = &self.params;
        // Every `step`-th pixel, at most `2 taps + 1` across: each stands for a `step`-wide
        // cell, and the cells cover the reach.
        let reach = reach_pixels(self.light, r, t, self.widest).ceil() as i64;
        let step = (reach + i64::from(p.grid_taps()) - 1) / i64::from(p.grid_taps());
        let step = step.max(1);
        let taps = reach / step;
        let grid = Grid { x: i64::from(x), y: i64::from(y), step, taps };
        // Each tap weighs the share of its cell (`step` pixels across, taken as `step`
        // footprints on the receiver) inside the kernel, from its distance to the kernel's
        // boundary: a smooth edge instead of a kernel that grows by whole cells.
        let cell = (step as f32 * r.footprint).max(f32::MIN_POSITIVE);
        let (sum, weight) = match kernel {
            Kernel::Rect { a, b } => {
                let (ca, cb) = (V::splat((a.length() * cell).recip()), V::splat((b.length() * cell).recip()));
                let (a, b) = (splat3::<V>(a), splat3::<V>(b));
                let half = V::splat(0.5);
                self.gather::<V>(
                    r,
                    grid,
                    #[inline(always)]
                    |d: [V; 3]| {
                        let wa = ((V::ONE - dot(d, a).abs()) * ca + half).max(V::ZERO).min(V::ONE);
                        let wb = ((V::ONE - dot(d, b).abs()) * cb + half).max(V::ZERO).min(V::ONE);
                        wa * wb
                    },
                )
            }
            Kernel::Disc { dir, r2 } => {
                let (radius, inv) = (V::splat(r2.sqrt()), V::splat(cell.recip()));
                let (dir, half) = (splat3::<V>(dir), V::splat(0.5));
                self.gather::<V>(
                    r,
                    grid,
                    #[inline(always)]
                    |d: [V; 3]| {
                        let along = dot(d, dir);
                        let across = (dot(d, d) - along * along).max(V::ZERO).sqrt();
                        ((radius - across) * inv + half).max(V::ZERO).min(V::ONE)
                    },
                )
            }
        };
        // The pixel itself always weighs at least a half (d = 0), unless its own input is not
        // finite.
        let v = if weight > 0.0 { sum / weight } else { hard };
        match r.probe {
            Probe::Lit(horizon) => v.min(horizon),
            _ => v,
        }
    }

    /// The weighted sum of the hard answers of the pixels of `grid` around `r` that lie on
    /// `r`'s surface, and the sum of their weights (`weight` of the offsets: the share of
    /// each pixel's cell inside the kernel, [`Kernel::contains`] made smooth).
    ///
    /// The rows are read from the pixel's outwards, down then up, each direction up to the
    /// first row none of whose pixels lies inside the kernel (`weight` positive): on a plane
    /// the kernel's image is convex and holds the pixel, so the rows it meets are one run
    /// through the pixel's. A receiver seen at a slant shows the kernel shorter across the
    /// rows than its reach: on atrium, arena, Sponza and the kitchen (256 x 256) a kernel
    /// reads 5.2 to 6.7 of its 7.7 to 8.9 rows so, and of the rows that added to a kernel
    /// when all were read, at most 0.3% to 3% lay past its run (an occluder's image across
    /// the kernel, or a surface that bends away).
    ///
    /// A row is read in vectors of `V::LANES` columns. Lane `l` of a row's `j`-th vector is
    /// column `j W + l` (`kx = j W + l - taps`), and it adds to that column's sums only: every
    /// column is summed over the rows in the same order at every width, the stop is the
    /// whole row's, and the columns are summed left to right at the end, so every width gives
    /// the same bits. Columns past the frame read the taps' NaN padding and weigh nothing.
    #[inline(always)]
    fn gather<V: SimdF32>(&self, r: &Pixel, grid: Grid, weight: impl Fn([V; 3]) -> V) -> (f32, f32) {
        // The vectors of a row: at most 31 columns.
        match (2 * grid.taps + 1) as usize / V::LANES {
            0 => self.gather_in::<V, 1>(r, grid, weight),
            1 => self.gather_in::<V, 2>(r, grid, weight),
            2..=3 => self.gather_in::<V, 4>(r, grid, weight),
            4..=7 => self.gather_in::<V, 8>(r, grid, weight),
            _ => self.gather_in::<V, 32>(r, grid, weight),
        }
    }

    /// [`ConvolutionFrame::gather`] with each row in at most `N` vectors.
    #[inline(always)]
    fn gather_in<V: SimdF32, const N: usize>(&self, r: &Pixel, grid: Grid, weight: impl Fn([V; 3]) -> V) -> (f32, f32) {
        const { assert!(V::LANES <= MAX_LANES, "the taps are padded by MAX_LANES") };
        let h = i64::from(self.height);
        let Grid { x, y, step, taps } = grid;
        let columns = 2 * taps + 1;
        let vectors = (columns as usize).div_ceil(V::LANES).min(N);
        let p = &self.params;
        let point = splat3::<V>(r.point);
        let normal = splat3::<V>(r.normal);
        let footprint = V::splat(r.footprint);
        let (cos_normal, plane, bend) = (V::splat(p.cos_normal), V::splat(p.plane), V::splat(p.bend));
        // The lanes' columns `j W + l`: which are the grid's, and how far across.
        let valid: [V::Mask; N] = array_fn(|j| V::strided(&LANE, j * V::LANES, 1).cmplt(V::splat(columns as f32)));
        let across: [V; N] =
            array_fn(|j| V::strided(&ACROSS, j * V::LANES + (MAX_TAPS - taps) as usize, 1) * V::splat(step as f32));
        let (mut sums, mut weights) = ([V::ZERO; N], [V::ZERO; N]);
        let stride = step as usize;
        let (below, above) = (taps.min((h - 1 - y) / step), taps.min(y / step));
        for (sign, first, last) in [(1, 0, below), (-1, 1, above)] {
            for k in first..=last {
                let dy = sign * k * step;
                let row = self.taps.row(y + dy);
                let dy_abs = V::splat(dy.abs() as f32);
                let mut inside = false;
                for j in 0..vectors {
                    let at = (self.taps.pad as i64 + x + (j * V::LANES) as i64 * step - taps * step) as usize;
                    let read = |field: usize| V::strided(row[field], at, stride);
                    let d = [read(Taps::X) - point[0], read(Taps::X + 1) - point[1], read(Taps::X + 2) - point[2]];
                    // A pixel without a hit has NaN in every field: its weight is NaN, and fails.
                    let wq = weight(d);
                    let within = wq.cmpgt(V::ZERO) & valid[j];
                    inside |= within.any();
                    let q = [read(Taps::NORMAL), read(Taps::NORMAL + 1), read(Taps::NORMAL + 2)];
                    let apart = across[j].max(dy_abs);
                    let signed = read(Taps::FOOTPRINT);
                    let off = footprint.max(signed.abs()) * (plane + bend * apart);
                    let on_surface = dot(normal, q).cmpge(cos_normal)
                        & dot(normal, d).abs().cmple(off)
                        & dot(q, d).abs().cmple(off)
                        & within;
                    // The hard answer, 1 lit or 0 blocked, from the footprint's sign.
                    let value = V::ONE.copysign(signed).max(V::ZERO);
                    sums[j] = sums[j] + V::select(on_surface, wq * value, V::ZERO);
                    weights[j] = weights[j] + V::select(on_surface, wq, V::ZERO);
                }
                if !inside {
                    break;
                }
            }
        }
        let (mut sum, mut total) = (0.0f32, 0.0f32);
        for j in 0..vectors {
            let (s, w) = (sums[j].to_array(), weights[j].to_array());
            for l in 0..V::LANES {
                sum += s[l];
                total += w[l];
            }
        }
        (sum, total)
    }
}

/// The most [`Params::taps`] a kernel reads: 31 columns.
const MAX_TAPS: i64 = 15;

/// Lane tables, read as vectors: `LANE[i] = i`, a column's index; `ACROSS[i] = |i - 15|`,
/// its distance from the centre column in steps (from `15 - taps` on, and 16 lanes past the
/// last column).
const LANE: [f32; 48] = {
    let mut t = [0.0; 48];
    let mut i = 0;
    while i < 48 {
        t[i] = i as f32;
        i += 1;
    }
    t
};
const ACROSS: [f32; 64] = {
    let mut t = [0.0; 64];
    let mut i = 0;
    while i < 64 {
        t[i] = (i as i64 - MAX_TAPS).abs() as f32;
        i += 1;
    }
    t
};

/// `v` in every lane, one lane vector per axis.
#[inline(always)]
fn splat3<V: SimdF32>(v: Vec3) -> [V; 3] {
    [V::splat(v.x), V::splat(v.y), V::splat(v.z)]
}

/// The dot product of two vectors held as one lane vector per axis.
#[inline(always)]
fn dot<V: SimdF32>(a: [V; 3], b: [V; 3]) -> V {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// How many pixels from `r` its kernel for a blocker at `t` reaches: the light's image
/// radius, stretched by the receiver's slant to the light, over the pixel's footprint, plus
/// one; at most `widest`, and at most that for non-finite input.
fn reach_pixels(light: &AreaLight, r: &Pixel, t: f32, widest: f32) -> f32 {
    let Some(profile) = Profile::of(light, r.point) else { return 0.0 };
    let dir = (light.center() - r.point).normalize_or_zero();
    let width = profile.max_support() * t / (1.0 - t).max(1e-3);
    let slant = r.normal.dot(dir).max(0.1);
    let reach = width / (slant * r.footprint) + 1.0;
    if reach.is_nan() { widest } else { reach.clamp(0.0, widest) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analytic::sphere_visible_fraction;
    use crate::sampling::{Rng, visible_fraction};
    use crate::test_scenes::{floor, rect_light, trees};
    use kdtree::Ray;
    use scenes::builtin::shapes::Part;
    use scenes::{RectLight, SphereLight};

    /// The test frames are small (20 to 64 pixels): penumbrae up to a quarter of their height.
    const WIDE: Params = Params { max_reach: 0.25, ..Params::DEFAULT };

    /// The floor seen straight down as an `n` x `n` frame from `(x0, z0)`, `step` apart (the
    /// footprint), each pixel the first surface below `(x, 0.01, z)`.
    struct Floor {
        n: u32,
        points: Vec<ShadingPoint>,
        pixels: Vec<Option<Pixel>>,
        edges: Vec<(usize, f32)>,
    }

    impl Floor {
        fn new(tree: &KdTree, light: &AreaLight, n: u32, (x0, z0): (f32, f32), step: f32) -> Floor {
            let points: Vec<ShadingPoint> = (0..n * n)
                .map(|i| {
                    let (x, z) = (x0 + step * (i % n) as f32, z0 + step * (i / n) as f32);
                    let ray = Ray::new(Vec3::new(x, 0.01, z), Vec3::NEG_Y, 0.0, 1.0);
                    let hit = tree.intersect(&ray).expect("the floor");
                    ShadingPoint::new(tree.triangle(hit.prim), hit, Vec3::NEG_Y)
                })
                .collect();
            let (pixels, near): (Vec<Option<Pixel>>, Vec<Option<f32>>) =
                points.iter().map(|p| probe(tree, light, p, step)).map(|(p, t)| (Some(p), t)).unzip();
            let edges = hard_edges(n, n, &pixels)
                .into_iter()
                .filter_map(|i| Some((i, near[i].filter(|&t| t > 0.0 && t < 1.0)?)))
                .collect();
            Floor { n, points, pixels, edges }
        }

        fn frame<'a>(&'a self, light: &'a AreaLight) -> ConvolutionFrame<'a> {
            ConvolutionFrame::new(self.n, self.n, &self.pixels, &self.edges, light, WIDE)
        }

        /// Every pixel convolved.
        fn dense(&self, light: &AreaLight) -> Vec<f32> {
            let frame = self.frame(light);
            (0..self.n * self.n).map(|i| frame.visibility(i % self.n, i / self.n)).collect()
        }

        /// The whole frame ([`convolved_frame`]): the sparse passes over the convolution, as
        /// `rttest shadows` runs them. Its rays: at most a probe per pixel, at least the
        /// edge's.
        fn sparse(&self, tree: &KdTree, light: &AreaLight) -> Vec<f32> {
            let n = self.n;
            let step = self.pixels[0].unwrap().footprint;
            let point = |x: u32, y: u32| Some((self.points[(y * n + x) as usize], step));
            let mut buffers = ConvolutionBuffers::default();
            let (v, rays) = convolved_frame(tree, light, (n, n), WIDE, TOLERANCES, &mut buffers, point);
            // Buffers reused by a smaller frame, then by this one again: the same answer.
            let half = convolved_frame(tree, light, (n / 2, n / 3), WIDE, TOLERANCES, &mut buffers, point).0;
            assert_eq!(half.len(), (n / 2 * (n / 3)) as usize);
            assert!(convolved_frame(tree, light, (n, n), WIDE, TOLERANCES, &mut buffers, point).0 == v);
            // The frame's edge test read the sides its probes wrote: the records' edge.
            assert_eq!(edges_of(n, n, &buffers.sides), hard_edges(n, n, &buffers.pixels));
            // At most a probe per pixel (a final one may trace none, a sparse one is inferred),
            // and at least the edge's, which find its blockers.
            assert!(rays <= u64::from(n * n) && rays >= self.edges.len() as u64);
            v
        }

        fn hard(&self) -> Vec<f32> {
            self.pixels.iter().map(|p| p.unwrap().probe.fraction()).collect()
        }

        /// A 256-sample reference per pixel.
        fn reference(&self, tree: &KdTree, light: &AreaLight) -> Vec<f32> {
            let points = self.points.iter().enumerate();
            points.map(|(i, p)| visible_fraction(tree, light, p, 256, &mut Rng::new(i as u64))).collect()
        }
    }

    fn rmse(a: &[f32], b: &[f32]) -> f32 {
        (a.iter().zip(b).map(|(a, b)| (a - b).powi(2)).sum::<f32>() / a.len() as f32).sqrt()
    }

    /// A slab over half the floor, closed (a box) or one triangle thick (a quad), under a
    /// square light: both halves of the penumbra drawn, far closer to the reference than hard
    /// shadows, densely and sparsely; the umbra stays dark (no leak through the sheet). The
    /// pixel column at `x = 0` lies in the slab's face plane, a split plane of the tree: its
    /// shadow rays run inside it.
    #[test]
    fn a_straight_edge_gets_both_halves_of_its_penumbra() {
        let light = rect_light(Vec3::new(0.0, 6.0, 0.0), 1.0);
        let slab = Part::cuboid(Vec3::new(-8.0, 2.0, -8.0), Vec3::new(0.0, 2.2, 8.0));
        let a = Vec3::new(-8.0, 2.0, -8.0);
        let sheet = [
            [a, a + Vec3::new(8.0, 0.0, 0.0), a + Vec3::new(8.0, 0.0, 16.0)],
            [a, a + Vec3::new(8.0, 0.0, 16.0), a + Vec3::new(0.0, 0.0, 16.0)],
        ];
        for tree in trees(&[floor(), slab], &[]).iter().chain(&trees(&[floor()], &sheet)) {
            // 40 x 40 pixels 0.125 apart from x = -2.5 (column 20 at x = 0 exactly): the
            // penumbra is x in [-0.5, 0.5].
            let f = Floor::new(tree, &light, 40, (-2.5, -2.5), 0.125);
            let (dense, sparse, hard) = (f.dense(&light), f.sparse(tree, &light), f.hard());
            let reference = f.reference(tree, &light);
            let (e_dense, e_sparse, e_hard) =
                (rmse(&dense, &reference), rmse(&sparse, &reference), rmse(&hard, &reference));
            assert!(e_dense < 0.35 * e_hard && e_sparse < 0.45 * e_hard, "{e_dense} {e_sparse} {e_hard}");
            let row = |v: &[f32], x: usize| v[20 * 40 + x];
            // Lit half (x = 0.25, pixel 22): partly shadowed; dark half (x = -0.25): partly lit.
            assert!(row(&dense, 22) < 0.95 && row(&dense, 22) > 0.5, "{}", row(&dense, 22));
            assert!(row(&dense, 18) > 0.05 && row(&dense, 18) < 0.5, "{}", row(&dense, 18));
            // Deep in the umbra and in full light: exact.
            assert_eq!((row(&dense, 2), row(&dense, 38)), (0.0, 1.0));
            assert!(dense.iter().chain(&sparse).all(|v| (0.0..=1.0).contains(v)));
        }
    }

    /// The sparse probes (the 2-lattice traced, the pixels between taking their corners'
    /// answer where those agree) give the hard shadow of a probe per pixel, bit for bit, on
    /// occluders wider than two pixels (a straight edge, a box's foot in contact with the
    /// floor, nested boxes), for under half the rays, and the frame stays as close to the
    /// reference.
    #[test]
    fn sparse_probes_give_the_same_hard_shadow_for_fewer_rays() {
        // No edge of the hard shadow along a line of pixel centres (there a probe per pixel
        // is ragged: lit and blocked by turns, features thinner than the lattice).
        let light = rect_light(Vec3::new(0.37, 6.0, 0.29), 1.0);
        let slab = Part::cuboid(Vec3::new(-8.0, 2.0, -8.0), Vec3::new(0.0, 2.2, 8.0));
        let foot = Part::cuboid(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(0.0, 1.0, 1.0));
        let inner = Part::cuboid(Vec3::new(-1.6, 0.0, -0.5), Vec3::new(-1.1, 0.3, 0.5));
        for parts in [vec![floor(), slab], vec![floor(), foot, inner]] {
            for tree in trees(&parts, &[]) {
                let (n, step) = (40, 0.125);
                let f = Floor::new(&tree, &light, n, (-3.0, -2.5), step);
                let point = |x: u32, y: u32| Some((f.points[(y * n + x) as usize], step));
                let reference = f.reference(&tree, &light);
                let run = |sparse_probes: bool| {
                    let mut buffers = ConvolutionBuffers::default();
                    let params = Params { sparse_probes, ..WIDE };
                    let (v, rays) = convolved_frame(&tree, &light, (n, n), params, TOLERANCES, &mut buffers, point);
                    let hard: Vec<f32> = buffers.pixels.iter().map(|p| p.unwrap().probe.fraction()).collect();
                    (rmse(&v, &reference), rays, hard, buffers.sides)
                };
                let (e_dense, rays_dense, hard_dense, sides_dense) = run(false);
                let (e_sparse, rays_sparse, hard_sparse, sides_sparse) = run(true);
                assert_eq!(rays_dense, u64::from(n * n));
                assert!(rays_sparse < rays_dense / 2, "{rays_sparse} rays of {rays_dense}");
                // Each pixel whose hard answer or side differs: (x, y, dense, sparse).
                let apart: Vec<_> = (0..hard_dense.len())
                    .filter(|&i| hard_sparse[i] != hard_dense[i] || sides_sparse[i] != sides_dense[i])
                    .map(|i| (i % n as usize, i / n as usize, hard_dense[i], hard_sparse[i]))
                    .collect();
                assert!(apart.is_empty(), "{apart:?}");
                assert!(e_sparse <= 1.05 * e_dense + 1e-3, "{e_sparse} against {e_dense}");
            }
        }
    }

    /// The kernel read in lanes of 4, 8 and 16 (native where this CPU has them, the portable
    /// twins where not) and in the portable lanes of 1, 4 and 16 gives the same bits on every
    /// pixel: a rectangle and a disc, grids of 13 and 31 columns, steps of 1 to 3.
    #[test]
    fn every_width_gives_the_same_bits() {
        use packets::simd::PortableF32;
        let rect = rect_light(Vec3::new(0.0, 6.0, 0.0), 1.0);
        let disc =
            AreaLight::Sphere(SphereLight { center: Vec3::new(1.2, 8.0, 0.0), radius: 1.0, intensity: Vec3::ONE });
        let slab = Part::cuboid(Vec3::new(-8.0, 2.0, -8.0), Vec3::new(0.0, 2.2, 8.0));
        let ball = Part::icosphere(1.0, 3).translated(Vec3::new(0.0, 2.0, 0.0));
        let mut convolved = 0;
        for (light, part) in [(rect, slab), (disc, ball)] {
            for tree in trees(&[floor(), part], &[]) {
                let f = Floor::new(&tree, &light, 48, (-2.6, -2.2), 0.1);
                for params in [WIDE, Params { taps: 15, ..WIDE }, Params { taps: 2, max_reach: 0.1, ..WIDE }] {
                    let frame = ConvolutionFrame::new(f.n, f.n, &f.pixels, &f.edges, &light, params);
                    let pixels = || (0..f.n * f.n).map(|i| (i % f.n, i / f.n));
                    let bits =
                        |v: &dyn Fn(u32, u32) -> f32| pixels().map(|(x, y)| v(x, y).to_bits()).collect::<Vec<_>>();
                    let one = bits(&|x, y| frame.visibility_in::<PortableF32<1>>(x, y));
                    for lanes in Width::ALL {
                        let frame = frame.clone().with_lanes(lanes);
                        assert_eq!(bits(&|x, y| frame.visibility(x, y)), one, "{lanes:?} {params:?}");
                    }
                    assert_eq!(bits(&|x, y| frame.visibility_in::<PortableF32<4>>(x, y)), one);
                    assert_eq!(bits(&|x, y| frame.visibility_in::<PortableF32<16>>(x, y)), one);
                    let hard = f.hard();
                    convolved +=
                        pixels().filter(|&(x, y)| frame.visibility(x, y) != hard[(y * f.n + x) as usize]).count();
                }
            }
        }
        assert!(convolved > 1000, "the kernels ran: {convolved} pixels differ from the hard answer");
    }

    /// A row's nearest edge pixels found in lanes of 1, 4, 8 and 16 (native where this CPU has
    /// them, the portable twins where not) are the scalar loop's, bit for bit: edge pixels
    /// with reaches of 0 to 20 pixels over 30 rows, spans cut by both ends of the row, and
    /// ties between edge pixels at the same distance.
    #[test]
    fn the_nearest_edges_are_the_same_at_every_width() {
        use packets::simd::PortableF32;
        let (w, rows) = (61usize, 30usize);
        let mut rng = Rng::new(11);
        let mut random: Vec<(usize, usize, f32, f32)> = (0..120)
            .map(|_| {
                let x = (rng.next_f32() * w as f32) as usize % w;
                let y = (rng.next_f32() * rows as f32) as usize % rows;
                (x, y, rng.next_f32() * 20.0, rng.next_f32())
            })
            .collect();
        random.sort_by_key(|e| (e.1, e.0));
        // Two edge pixels mirrored about column 25: every pixel of that column is a tie.
        let pair = vec![(20, 10, 9.0, 0.25), (30, 10, 9.0, 0.75)];
        // The loop the lanes replace: one pixel of each span at a time.
        let scalar = |edges: &[(usize, usize, f32, f32)], y: usize| {
            let (mut near, mut slots) = (vec![f32::INFINITY; w], vec![f32::NAN; w]);
            for edge in edges {
                let Some((lo, hi, dy2)) = span(edge, y, w) else { continue };
                for x in lo..hi {
                    let d2 = (x as f32 - edge.0 as f32).powi(2) + dy2;
                    if d2 < near[x] {
                        (near[x], slots[x]) = (d2, edge.3);
                    }
                }
            }
            slots.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        };
        let mut nearest = Nearest::default();
        let mut lanes = |add: &dyn Fn(&mut Nearest)| {
            nearest.clear(w);
            add(&mut nearest);
            nearest.blockers[..w].iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        };
        let mut reached = 0;
        for edges in [&random, &pair] {
            for y in 0..rows {
                let expected = scalar(edges, y);
                reached += expected.iter().filter(|v| !f32::from_bits(**v).is_nan()).count();
                assert_eq!(lanes(&|n| n.add::<PortableF32<1>>(edges.iter(), y)), expected, "row {y}, 1 lane");
                for width in Width::ALL {
                    let found = lanes(&|n| packets::at_width!(width, V => n.add::<V>(edges.iter(), y)));
                    assert_eq!(found, expected, "row {y}, {width:?}");
                }
            }
        }
        assert!(reached > rows * w / 2, "most pixels are within reach: {reached}");
        assert_eq!(scalar(&pair, 12)[25], 0.25f32.to_bits(), "a tie goes to the earlier edge pixel");
    }

    /// The closed form: a sphere over the floor under a spherical light. The convolution
    /// comes within a small RMSE of it, well under hard shadows'.
    #[test]
    fn the_sphere_matches_the_closed_form() {
        let (center, radius) = (Vec3::new(0.0, 2.0, 0.0), 1.0);
        let l = SphereLight { center: Vec3::new(1.2, 8.0, 0.0), radius: 1.0, intensity: Vec3::ONE };
        let light = AreaLight::Sphere(l);
        for tree in trees(&[floor(), Part::icosphere(radius, 4).translated(center)], &[]) {
            // The whole shadow and penumbra, x in [-2.1, 1.3], z in [-1.7, 1.7].
            let f = Floor::new(&tree, &light, 64, (-2.6, -2.2), 4.4 / 63.0);
            let exact: Vec<f32> = f
                .points
                .iter()
                .map(|p| sphere_visible_fraction(p.point, l.center, l.radius, center, radius) as f32)
                .collect();
            let (dense, sparse) = (f.dense(&light), f.sparse(&tree, &light));
            let (e_dense, e_sparse, e_hard) = (rmse(&dense, &exact), rmse(&sparse, &exact), rmse(&f.hard(), &exact));
            assert!(e_dense < 0.3 * e_hard && e_sparse < 0.3 * e_hard, "{e_dense} {e_sparse} {e_hard}");
        }
    }

    /// A box standing on the floor: next to its foot the blocker is close, the kernel small,
    /// and the contact shadow stays dark; a second, smaller box in the first one's shadow
    /// (nested occluders) changes nothing there.
    #[test]
    fn contact_and_nested_occluders_keep_the_umbra() {
        let light = rect_light(Vec3::new(3.0, 5.0, 0.0), 1.0);
        let foot = Part::cuboid(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(0.0, 1.0, 1.0));
        let inner = Part::cuboid(Vec3::new(-1.6, 0.0, -0.5), Vec3::new(-1.1, 0.3, 0.5));
        for parts in [vec![floor(), foot.clone()], vec![floor(), foot, inner]] {
            for tree in trees(&parts, &[]) {
                // The shadow and its penumbra: x in [-2.3, -1], z in [-1.3, 1.3].
                let f = Floor::new(&tree, &light, 32, (-3.0, -1.6), 0.1);
                let (dense, reference) = (f.dense(&light), f.reference(&tree, &light));
                // Right behind the box's foot (x = -1.1, z = 0): dark in both.
                let i = 16 * 32 + 19;
                assert!(reference[i] < 0.05 && dense[i] < 0.05, "{} {}", reference[i], dense[i]);
                let (e_dense, e_hard) = (rmse(&dense, &reference), rmse(&f.hard(), &reference));
                assert!(e_dense < 0.6 * e_hard, "{e_dense} {e_hard}");
            }
        }
    }

    /// A one-sided vertical plane containing the light's centre: its hard shadow is at most
    /// the line of pixels whose centre rays lie in its plane, and the convolution stays as
    /// close to the reference as hard shadows (from points a little off its plane it blocks
    /// a sliver of the light); a light partly below the horizon keeps each pixel at most its
    /// horizon's share.
    #[test]
    fn an_edge_on_plane_and_a_light_below_the_horizon() {
        let light = rect_light(Vec3::new(0.0, 6.0, 0.0), 1.0);
        let (a, u, v) = (Vec3::new(-2.0, 1.0, 0.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 3.0, 0.0));
        let plane = [[a, a + u, a + u + v], [a, a + u + v, a + v]];
        for tree in trees(&[floor()], &plane) {
            let f = Floor::new(&tree, &light, 21, (-1.0, -1.0), 0.1);
            let (dense, sparse, hard) = (f.dense(&light), f.sparse(&tree, &light), f.hard());
            let reference = f.reference(&tree, &light);
            let (e_dense, e_sparse, e_hard) =
                (rmse(&dense, &reference), rmse(&sparse, &reference), rmse(&hard, &reference));
            assert!(e_dense <= e_hard + 0.01 && e_sparse <= e_hard + 0.01, "{e_dense} {e_sparse} {e_hard}");
        }
        // A light level with the floor, half below it, and a wall casting a shadow.
        let low = rect_light(Vec3::new(6.0, 0.0, 0.0), 1.0);
        let wall = Part::cuboid(Vec3::new(2.0, 0.0, -8.0), Vec3::new(2.2, 2.0, 0.0));
        for tree in trees(&[floor(), wall], &[]) {
            let f = Floor::new(&tree, &low, 24, (-1.0, -1.2), 0.1);
            let (dense, sparse) = (f.dense(&low), f.sparse(&tree, &low));
            for ((d, s), p) in dense.iter().zip(&sparse).zip(&f.pixels) {
                let limit = match p.unwrap().probe {
                    Probe::Lit(horizon) => horizon,
                    Probe::Done(v) => v.fraction,
                    Probe::Blocked(_) => 0.5,
                };
                assert!(*d <= limit + 1e-6 && *s <= limit + 1e-6 && (0.0..=1.0).contains(d), "{d} {s} {limit}");
            }
        }
    }

    /// The kernel as the offsets whose centre rays cross the blocker's plane inside the
    /// light's cone from the point: checked against that construction on a tilted
    /// rectangle and a sphere, away from the boundary (where the linearised kernel and the
    /// construction may differ by the offset's share of the ray's length).
    #[test]
    fn the_kernel_is_the_light_seen_through_the_blocker() {
        let tilted = AreaLight::Rect(RectLight {
            corner: Vec3::new(-1.0, 6.0, -0.5),
            edge_u: Vec3::new(2.0, 0.6, 0.0),
            edge_v: Vec3::new(0.3, 0.0, 1.2),
            intensity: Vec3::ONE,
        });
        let sphere =
            AreaLight::Sphere(SphereLight { center: Vec3::new(1.0, 5.0, 0.5), radius: 0.8, intensity: Vec3::ONE });
        let p = Vec3::new(0.3, 0.0, -0.2);
        let mut rng = Rng::new(3);
        for light in [tilted, sphere] {
            let c = light.center();
            for t in [0.1f32, 0.3, 0.6] {
                let kernel = Kernel::new(&light, p, t).unwrap();
                // The exact test: where on the light, seen from `p`, the centre ray of `p + d`
                // crosses the plane at `t` parallel to the light (perpendicular to the ray for
                // the sphere), and how far inside the light that is (1 on its boundary).
                let normal = match light {
                    AreaLight::Rect(l) => l.edge_u.cross(l.edge_v).normalize(),
                    AreaLight::Sphere(_) => (c - p).normalize(),
                };
                let b = p + t * (c - p);
                let inside = |d: Vec3| {
                    let q = p + d;
                    let s = (b - q).dot(normal) / (c - q).dot(normal);
                    let on_light = p + (q + s * (c - q) - p) / t;
                    match light {
                        AreaLight::Rect(l) => {
                            let (u, v) = (0.5 * l.edge_u, 0.5 * l.edge_v);
                            let n = u.cross(v);
                            let e = on_light - c;
                            let (a, bb) =
                                (e.dot(v.cross(n)) / u.dot(v.cross(n)), e.dot(n.cross(u)) / v.dot(n.cross(u)));
                            a.abs().max(bb.abs())
                        }
                        AreaLight::Sphere(_) => {
                            let Some(Profile::Disc(rho)) = Profile::of(&light, p) else { unreachable!() };
                            (on_light - c).length() / rho
                        }
                    }
                };
                let reach = 3.0 * t / (1.0 - t);
                for _ in 0..400 {
                    let d = Vec3::new(rng.next_f32() - 0.5, 0.0, rng.next_f32() - 0.5) * 2.0 * reach;
                    let exact = inside(d);
                    if (exact - 1.0).abs() > 0.1 {
                        assert_eq!(kernel.contains(d), exact < 1.0, "{d} at t = {t}: {exact}");
                    }
                }
                assert!(kernel.contains(Vec3::ZERO));
            }
            // Degenerate blockers have no kernel.
            for t in [0.0, 1.0, -0.5, f32::NAN, f32::INFINITY] {
                assert_eq!(Kernel::new(&light, p, t), None, "{t}");
            }
        }
        // A ray along a rectangle's plane, and a point inside a sphere.
        let flat = rect_light(Vec3::new(0.0, 6.0, 0.0), 1.0);
        assert_eq!(Kernel::new(&flat, Vec3::new(10.0, 6.0, 0.0), 0.5), None);
        assert_eq!(Kernel::new(&sphere, Vec3::new(1.0, 5.2, 0.5), 0.5), None);
    }

    /// The edge is the blocked pixels with a lit 8-neighbour, diagonals and the frame's border
    /// included; a final probe or a pixel without a hit is neither side.
    #[test]
    fn the_edge_is_the_blocked_pixels_beside_lit_ones() {
        let lit = Pixel { point: Vec3::ZERO, normal: Vec3::Y, footprint: 0.1, probe: Probe::Lit(1.0) };
        let blocked = Pixel { probe: Probe::Blocked(3.0), ..lit };
        let done =
            Pixel { probe: Probe::Done(crate::silhouette::SilhouetteVisibility { fraction: 1.0, rays: 1 }), ..lit };
        // 5 x 4, row by row: L lit, B blocked, D a final probe, - no hit.
        let frame = ["BBBDB", "BBB-B", "BBBBB", "LBBBB"];
        let pixels: Vec<Option<Pixel>> = frame
            .iter()
            .flat_map(|row| row.chars())
            .map(|c| match c {
                'L' => Some(lit),
                'B' => Some(blocked),
                'D' => Some(done),
                _ => None,
            })
            .collect();
        // Only the lit corner's neighbours: (0, 2), (1, 2) and (1, 3).
        assert_eq!(hard_edges(5, 4, &pixels), vec![10, 11, 16]);
        let sides: Vec<Side> = pixels.iter().map(|p| Side::of(p.as_ref())).collect();
        assert_eq!(edges_of(5, 4, &sides), vec![10, 11, 16]);
        assert_eq!(edges_of(4, 4, &sides), Vec::<usize>::new());
        // A lit pixel in the middle: all eight neighbours, none of the final or missing ones.
        let mut pixels = vec![Some(blocked); 9];
        pixels[4] = Some(lit);
        pixels[0] = Some(done);
        pixels[8] = None;
        assert_eq!(hard_edges(3, 3, &pixels), vec![1, 2, 3, 5, 6, 7]);
    }

    /// Damaged input answers, never panics: buffers of the wrong length, non-finite points,
    /// edges out of range; a frame without hits is dark.
    #[test]
    fn damaged_frames_give_hard_answers() {
        let light = rect_light(Vec3::new(0.0, 6.0, 0.0), 1.0);
        let lit = Pixel { point: Vec3::ZERO, normal: Vec3::Y, footprint: 0.1, probe: Probe::Lit(1.0) };
        let blocked = Pixel { probe: Probe::Blocked(3.0), ..lit };
        let nan = Pixel { point: Vec3::NAN, ..blocked };
        let pixels = vec![Some(lit), Some(blocked), Some(nan), None];
        assert_eq!(hard_edges(3, 2, &pixels), Vec::<usize>::new());
        let edges = [(1, 0.5), (2, 0.5), (99, 0.5)];
        let frame = ConvolutionFrame::new(3, 2, &pixels, &edges, &light, Params::DEFAULT);
        assert_eq!(frame.reached(), 0);
        let frame = ConvolutionFrame::new(2, 2, &pixels, &edges, &light, Params::DEFAULT);
        assert_eq!(hard_edges(2, 2, &pixels), vec![1, 2]);
        for (x, y) in [(0, 0), (1, 0), (0, 1), (1, 1), (5, 5)] {
            let v = frame.visibility(x, y);
            assert!((0.0..=1.0).contains(&v), "{v} at ({x}, {y})");
        }
        assert_eq!(frame.visibility(1, 1), 0.0);
    }
}
