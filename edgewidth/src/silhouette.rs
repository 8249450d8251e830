//! Silhouette widths: single-ray soft shadows that draw both halves of the penumbra and do not
//! leak, a variant of the thesis's Edge Width Soft Shadows (Tsakok 2008, chapter 5, Eq. 5.1)
//! in the manner of Parker, Shirley & Smits 1998 ("Single Sample Soft Shadows").
//!
//! ## What it changes against Eq. 5.1, and why
//! Eq. 5.1 softens a shadow by the *chord* an occluder cuts from the shadow ray (its edge
//! width along the ray) against a fixed width `R`. That has two faults
//! (`docs/results/soft-shadows-quality.md`): a ray that misses every occluder reports nothing,
//! so only the inner half of the penumbra is drawn; and an occluder thinner along the ray than
//! the light is wide lets light through (thesis Figure 5.8). Here the width is measured
//! *across* the ray instead of along it, and in the light's own units:
//!
//! - Every silhouette edge of the occluders near the ray (an edge between a triangle facing
//!   the point and one facing away, or an edge of an open surface) is projected from the
//!   shading point onto the plane through the light's centre perpendicular to the ray. Its
//!   distance `m` from the centre there is where, on the light, the edge's shadow boundary
//!   falls, so the penumbra's width follows the blocker's distance (`m` is the edge's
//!   lateral distance times `d_light / d_blocker`, as in PCSS) with no fixed `R`.
//! - The edge is taken as a straight boundary, the occluder on one side: the light's blocked
//!   fraction is the share of its area beyond the line (a disc's circular segment for a
//!   spherical light, the sum of two uniform distributions for a rectangle, see
//!   [`Profile::tail`]). At the hard shadow's edge (`m = 0`) that is one half, so the lit half
//!   of the penumbra is drawn (the ray misses: the nearest edge blocks less than half) as
//!   well as the dark half (the ray hits: the nearest edge it could leave by lets less than
//!   half through).
//! - Nothing leaks through a closed occluder: the light passes only around a silhouette, never
//!   through a hit, however thin the object is along the ray. Only an open surface seen nearly
//!   edge-on is thin *across* the ray; from a point whose centre is visible its boundary
//!   edges block the strip its projection covers (foreshortened by the angle it is seen at,
//!   and assumed to reach a cone's width beyond its own triangle), not a half-plane, so a
//!   plane edge-on to the light barely shadows, as in the reference.
//!
//! ## Cost
//! The search visits every kd-tree leaf in the light's cone (shrunk as better edges are
//! found) and looks at each triangle there once (a 64-slot mailbox): per triangle a cull by
//! its bounding sphere and by how steeply it is seen against how far its neighbours' normals
//! turn, then its silhouette edges. That costs far more than the rays: on `atrium` about 700
//! nodes and 500 triangle references per point, 25 us against 0.16 us for the hard ray.
//!
//! So a frame runs it only where a penumbra can be: [`hard_probe`] traces every pixel's hard
//! ray first (with the nearest blocker's distance, which gives PCSS's penumbra width in
//! pixels), and [`penumbra_mask`] marks the pixels within that reach (at most [`MAX_REACH`])
//! of a blocked pixel with a lit neighbour; only those get the search
//! ([`silhouette_search`], reusing the probe's answer), the rest keep the hard answer (the
//! horizon's share when lit). A frame that searches every masked pixel costs 3.5x to 19x hard
//! shadows over the scenes of `docs/results/soft-shadows-quality.md` (7x to 41x searching
//! every pixel), at nearly the same error; [`silhouette_visibility`] is the ungated answer for
//! one point.
//!
//! Inside the mask, the frame ([`crate::sparse`]) searches only a coarse lattice (every 4th
//! pixel in x and y, then every 2nd where blending is not safe) and blends the pixels between
//! from their corners where the corners hold the frame's answers, lie on the pixel's surface,
//! not all across the hard shadow's edge from it, and close in visibility; the others are
//! searched themselves. On those scenes that searches 11% to 41% of the masked pixels, for an
//! error within 0.0015 RMSE of searching them all, and a frame costs 2.3x to 12x hard shadows
//! (3x to 18x searching every masked pixel, in the same runs): the pixels still searched are
//! mostly at the occluders' own geometric edges, where the search is also dearest.
//!
//! ## One ray, and what finds the near misses
//! A hard shadow ray to the light's centre says whether the point is in the hard shadow. The
//! silhouette edges are then gathered from the kd-tree leaves within the light's cone (apex at
//! the point, the light's bounding disc at its end: the single-ray descent with an interval
//! per child widened by the cone's radius at each depth, [`cone_step`]): misses keep the edge
//! that blocks most, hits the edge that lets most through. A hit's exit is checked by one
//! more any-hit ray towards the middle of the light part it claims (an edge of a second
//! occluder behind, or of a box touching the hit one, is not an exit); if the best
//! [`EXITS`] exits are all blocked (layers of one occluder, each a little wider than the
//! last, give several) the point is in the umbra. The receiver's own horizon counts as one
//! more edge (a light partly below it is partly blocked); a light centre below the horizon
//! gets one ray towards the part above it.

use glam::Vec3;
use kdtree::{KdTree, Ray};
use std::collections::HashMap;

use crate::sampling::{AreaLight, ShadingPoint};

/// Neighbour marker: an edge of one triangle only (the boundary of an open surface).
const BOUNDARY: u32 = u32::MAX;
/// Neighbour marker: an edge shared by three or more triangles (always a silhouette, taken as
/// closed).
const NON_MANIFOLD: u32 = u32::MAX - 1;
/// Neighbour flag: the neighbour is wound the other way (its normal points to the other side
/// of the surface), so the edge is a silhouette when both face the same way.
const FLIPPED: u32 = 1 << 31;

/// Each triangle's unit geometric normal and its neighbour across each edge, made once per
/// scene: what tells a silhouette edge from an inner one for any ray direction.
///
/// Edges are matched by the exact positions of their ends, so meshes that repeat vertices per
/// face are joined as if indexed; neighbours wound against each other are flagged, so that a
/// mesh need not be consistently oriented. Edge `i` of a triangle runs from its vertex `i` to vertex
/// `(i + 1) % 3`.
#[derive(Clone, Debug, Default)]
pub struct Silhouettes {
    normals: Vec<Vec3>,
    neighbours: Vec<[u32; 3]>,
    culls: Vec<Cull>,
}

/// What lets the cone search skip a triangle without reading its vertices or neighbours: its
/// bounding sphere, its plane, and how far its neighbours' normals turn from its own.
#[derive(Clone, Copy, Debug, Default)]
struct Cull {
    center: Vec3,
    radius: f32,
    normal: Vec3,
    /// `normal . vertex`: the plane's offset.
    offset: f32,
    /// The sine of the largest angle between the normal and a neighbour's (facing the same
    /// side), or 2 when an edge is open, non-manifold or folds by more than a right angle: a
    /// triangle seen at an angle whose cosine exceeds this from every point of it faces the
    /// same way as all its neighbours, so none of its edges is a silhouette.
    sin_fold: f32,
}

impl Silhouettes {
    /// No triangles.
    pub const EMPTY: Silhouettes = Silhouettes { normals: Vec::new(), neighbours: Vec::new(), culls: Vec::new() };

    /// The adjacency of `tree`'s triangles (indexed as the tree's). `O(N)` with a hash map;
    /// degenerate triangles get a zero normal and are never silhouettes.
    pub fn new(tree: &KdTree) -> Silhouettes {
        let n = tree.triangle_count();
        let mut normals = Vec::with_capacity(n);
        let mut neighbours = vec![[BOUNDARY; 3]; n];
        type Key = ([u32; 3], [u32; 3]);
        let key = |a: Vec3, b: Vec3| -> Key {
            let (a, b) = (a.to_array().map(f32::to_bits), b.to_array().map(f32::to_bits));
            if a <= b { (a, b) } else { (b, a) }
        };
        // The first triangle and edge seen for each key, and how many share it.
        let mut first: HashMap<Key, (u32, u8, u32)> = HashMap::with_capacity(n * 2);
        for prim in 0..n as u32 {
            let t = tree.triangle(prim);
            normals.push((t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero());
            for i in 0..3 {
                let entry = first.entry(key(t[i], t[(i + 1) % 3])).or_insert((prim, i as u8, 0));
                entry.2 += 1;
                if entry.2 == 2 {
                    let (other, edge) = (entry.0, entry.1 as usize);
                    // Consistent winding runs the shared edge the other way in the neighbour.
                    let theirs = tree.triangle(other)[edge];
                    let flip = if theirs == t[i] { FLIPPED } else { 0 };
                    neighbours[prim as usize][i] = other | flip;
                    neighbours[other as usize][edge] = prim | flip;
                }
            }
        }
        // A third triangle on an edge: every triangle on it is non-manifold there.
        for (prim, nb) in neighbours.iter_mut().enumerate() {
            let t = tree.triangle(prim as u32);
            for (i, slot) in nb.iter_mut().enumerate() {
                if first.get(&key(t[i], t[(i + 1) % 3])).is_some_and(|e| e.2 > 2) {
                    *slot = NON_MANIFOLD;
                }
            }
        }
        let culls = (0..n)
            .map(|prim| {
                let t = tree.triangle(prim as u32);
                let normal = normals[prim];
                let center = (t[0] + t[1] + t[2]) / 3.0;
                let radius = t.iter().map(|v| v.distance(center)).fold(0.0f32, f32::max) * 1.0001;
                let mut sin_fold = 0.0f32;
                for &other in &neighbours[prim] {
                    let cos = match other {
                        BOUNDARY | NON_MANIFOLD => -1.0,
                        _ if other & FLIPPED != 0 => -normal.dot(normals[(other & !FLIPPED) as usize]),
                        _ => normal.dot(normals[other as usize]),
                    };
                    let sin = if cos > 0.0 { (1.0 - cos * cos).max(0.0).sqrt() + 1e-4 } else { 2.0 };
                    sin_fold = sin_fold.max(sin);
                }
                Cull { center, radius, normal, offset: normal.dot(t[0]), sin_fold }
            })
            .collect();
        Silhouettes { normals, neighbours, culls }
    }

    /// The number of triangles.
    pub fn len(&self) -> usize {
        self.normals.len()
    }

    /// True when there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.normals.is_empty()
    }
}

/// The light seen from one point, projected onto the plane through its centre perpendicular
/// to the shadow ray: where a light point at offset `e` from the centre in that plane lies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Profile {
    /// A parallelogram (a rectangular light) with half edges `u` and `v`, uniform in area.
    Rect {
        /// Half the first edge.
        u: Vec3,
        /// Half the second edge.
        v: Vec3,
    },
    /// A disc of this radius, uniform in area (a spherical light's cone cut at its centre's
    /// distance: `D tan(asin(r / D))`).
    Disc(f32),
}

impl Profile {
    /// The profile of `light` seen from `p` (`None` when `p` is inside a spherical light or the
    /// input is not finite).
    pub fn of(light: &AreaLight, p: Vec3) -> Option<Profile> {
        match light {
            AreaLight::Rect(l) => {
                let (u, v) = (0.5 * l.edge_u, 0.5 * l.edge_v);
                (u.is_finite() && v.is_finite()).then_some(Profile::Rect { u, v })
            }
            AreaLight::Sphere(l) => {
                let d = (l.center - p).length();
                let s = l.radius / d;
                let rho = l.radius / (1.0 - s * s).sqrt();
                (rho.is_finite() && s < 1.0 && rho >= 0.0).then_some(Profile::Disc(rho))
            }
        }
    }

    /// How far the light reaches from its centre along the unit direction `n`.
    #[inline]
    pub fn support(&self, n: Vec3) -> f32 {
        match *self {
            Profile::Rect { u, v } => u.dot(n).abs() + v.dot(n).abs(),
            Profile::Disc(r) => r,
        }
    }

    /// The largest [`Profile::support`] over all directions: the radius of the light's cone at
    /// its centre.
    #[inline]
    pub fn max_support(&self) -> f32 {
        match *self {
            Profile::Rect { u, v } => (u + v).length().max((u - v).length()),
            Profile::Disc(r) => r,
        }
    }

    /// Whether the whole light lies above the plane through the point with normal `normal`
    /// (any length), its centre at `to` from the point: a quick test before the horizon's
    /// share (a sphere's profile radius is at least its radius, so a true answer is always
    /// right). Homogeneous in the normal's length, and false for NaN input.
    #[inline]
    pub fn above(&self, normal: Vec3, to: Vec3) -> bool {
        let height = normal.dot(to);
        match *self {
            Profile::Rect { u, v } => height > normal.dot(u).abs() + normal.dot(v).abs(),
            Profile::Disc(r) => height > r * normal.length(),
        }
    }

    /// Whether the whole light lies below the plane through the point with normal `normal`
    /// (any length), its centre at `to` from the point: the light is hidden by the receiver
    /// itself. Homogeneous in the normal's length, and false for NaN input.
    #[inline]
    pub fn below(&self, normal: Vec3, to: Vec3) -> bool {
        let depth = -normal.dot(to);
        match *self {
            Profile::Rect { u, v } => depth > normal.dot(u).abs() + normal.dot(v).abs(),
            Profile::Disc(r) => depth > r * normal.length(),
        }
    }

    /// The share of the light beyond the line `e . n = m` (`n` a unit vector perpendicular to
    /// the ray): `1/2` at `m = 0`, `0` from the support on, `1` below minus the support. For
    /// a rectangle `e . n` is the sum of two uniform variables (a trapezoid density), for a
    /// disc the circular segment. `m = +inf` gives `0`, `-inf` gives `1`; NaN gives NaN.
    #[inline]
    pub fn tail(&self, n: Vec3, m: f32) -> f32 {
        match *self {
            Profile::Rect { u, v } => trapezoid_tail(u.dot(n).abs(), v.dot(n).abs(), m),
            Profile::Disc(r) => disc_tail(r, m),
        }
    }
}

/// `P(X + Y >= m)` for `X` uniform on `[-a, a]`, `Y` on `[-b, b]`.
#[inline]
fn trapezoid_tail(a: f32, b: f32, m: f32) -> f32 {
    let (a, b) = (a.max(b), a.min(b));
    let upper = |m: f32| {
        if m >= a + b {
            0.0
        } else if m >= a - b {
            let e = a + b - m;
            e * e / (8.0 * a * b)
        } else {
            (a - m) / (2.0 * a)
        }
    };
    if m < 0.0 { 1.0 - upper(-m) } else { upper(m) }
}

/// The share of a disc of radius `r` beyond a chord at distance `m` from its centre.
#[inline]
fn disc_tail(r: f32, m: f32) -> f32 {
    if m >= r {
        return 0.0;
    }
    if m <= -r {
        return 1.0;
    }
    let s = m / r;
    (s.acos() - s * (1.0 - s * s).max(0.0).sqrt()) * std::f32::consts::FRAC_1_PI
}

/// Per-thread scratch: the cone descent's stack. Reused from ray to ray, so tracing allocates
/// nothing once it has grown to the tree's depth.
#[derive(Clone, Debug, Default)]
pub struct SilhouetteScratch {
    stack: Vec<(u32, f32, f32)>,
    mailbox: Mailbox,
}

/// The triangles met last, by the low bits of their index: a triangle held by several leaves
/// (a kd-tree repeats it in every leaf it overlaps) is mostly looked at once.
#[derive(Clone, Debug)]
struct Mailbox([u32; MAILBOX]);

/// Slots of the [`Mailbox`] (a power of two).
const MAILBOX: usize = 64;

impl Default for Mailbox {
    fn default() -> Self {
        Mailbox([u32::MAX; MAILBOX])
    }
}

impl Mailbox {
    /// True when `prim` was met already (since it last lost its slot); marks it met.
    #[inline(always)]
    fn seen(&mut self, prim: u32) -> bool {
        let slot = &mut self.0[prim as usize & (MAILBOX - 1)];
        let seen = *slot == prim;
        *slot = prim;
        seen
    }
}

/// One point's answer: the visible fraction and the rays it traced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SilhouetteVisibility {
    /// The visible fraction of the light, in `[0, 1]`.
    pub fraction: f32,
    /// Rays traced: the shadow ray, and a check ray for each exit tried (at most
    /// `1 + EXITS` in all).
    pub rays: u32,
}

/// How many exits a blocked point keeps and checks, best first.
pub const EXITS: usize = 4;

/// The nearest parameter the cone descent looks at, as a fraction of the ray: edges nearer
/// the shading point than this are its own surface's, which the horizon stands for.
pub const T_NEAR: f32 = 1e-4;

/// The visible fraction of `light` from `p` with silhouette widths (see the module's text):
/// one hard shadow ray to the light's centre, the silhouette edges within the light's cone,
/// and a check ray per claimed exit when the centre is blocked. Never allocates once
/// `scratch` has grown; NaN or infinite input gives `0` (no ray), never a panic.
pub fn silhouette_visibility(
    tree: &KdTree,
    silhouettes: &Silhouettes,
    light: &AreaLight,
    p: &ShadingPoint,
    scratch: &mut SilhouetteScratch,
) -> SilhouetteVisibility {
    visibility(tree, silhouettes, light, p, scratch, None)
}

/// [`silhouette_visibility`] of a point whose hard shadow ray to the light's centre has been
/// traced already (by [`hard_probe`]): `blocked` is its answer. The rays returned are the
/// check rays only. Gives what [`silhouette_visibility`] gives, with one ray fewer.
pub fn silhouette_search(
    tree: &KdTree,
    silhouettes: &Silhouettes,
    light: &AreaLight,
    p: &ShadingPoint,
    blocked: bool,
    scratch: &mut SilhouetteScratch,
) -> SilhouetteVisibility {
    visibility(tree, silhouettes, light, p, scratch, Some(blocked))
}

/// The unit `normal` and the unit direction of `to` (the light's centre from the point), or
/// `None` where either is zero after normalising or not finite: no horizon to measure.
#[inline(always)]
fn unit_frame(normal: Vec3, to: Vec3) -> Option<(Vec3, Vec3)> {
    let (normal, dir) = (normal.normalize_or_zero(), to.normalize_or_zero());
    let usable = to.is_finite() && normal.is_finite() && dir != Vec3::ZERO && normal != Vec3::ZERO;
    usable.then_some((normal, dir))
}

/// The visible fraction of `p` whose light's centre is below its horizon (the line `e . h =
/// m_h` on the light's plane, [`horizon_line`]) but not all of the light: one ray towards the
/// middle of the part above it, answered by `occluded` (called at most once), whose answer
/// counts for that whole part. No ray (and no light) where no part of the light is above.
#[inline(always)]
fn above_horizon(
    light: &AreaLight,
    p: &ShadingPoint,
    profile: Profile,
    (h, m_h): (Vec3, f32),
    occluded: impl FnOnce(&Ray) -> bool,
) -> SilhouetteVisibility {
    let none = SilhouetteVisibility { fraction: 0.0, rays: 0 };
    if h == Vec3::ZERO {
        return none;
    }
    let up = -h;
    let above = profile.tail(up, -m_h);
    if above.is_nan() || above <= 0.0 {
        return none;
    }
    let target = on_light(light, p.point, light.center() + up * 0.5 * (-m_h + profile.support(up)));
    match p.shadow_ray(target) {
        Some(ray) => SilhouetteVisibility { fraction: if occluded(&ray) { 0.0 } else { above }, rays: 1 },
        None => none,
    }
}

/// [`silhouette_visibility`], its centre ray's answer given (`known`) or traced here.
fn visibility(
    tree: &KdTree,
    silhouettes: &Silhouettes,
    light: &AreaLight,
    p: &ShadingPoint,
    scratch: &mut SilhouetteScratch,
    known: Option<bool>,
) -> SilhouetteVisibility {
    let none = SilhouetteVisibility { fraction: 0.0, rays: 0 };
    let center = light.center();
    let Some(profile) = Profile::of(light, p.point) else {
        // Inside a spherical light (or non-finite input): as hard shadows.
        return match p.shadow_ray(center) {
            Some(ray) => SilhouetteVisibility { fraction: f32::from(u8::from(!tree.occluded(&ray))), rays: 1 },
            None => none,
        };
    };
    let to = center - p.point;
    if profile.below(p.normal, to) {
        // The receiver hides the whole light.
        return none;
    }
    let Some((normal, dir)) = unit_frame(p.normal, to) else { return none };
    // The horizon: the receiver's tangent plane seen on the light plane is the line
    // `e . h = m_h` with `h` the normal's part across the ray, pointing down.
    let (h, m_h) = horizon_line(normal, to, dir);
    let Some(ray) = p.shadow_ray(center) else {
        return above_horizon(light, p, profile, (h, m_h), |ray| tree.occluded(ray));
    };
    let horizon = if h == Vec3::ZERO { 1.0 } else { 1.0 - profile.tail(h, m_h) };
    let blocked = known.unwrap_or_else(|| tree.occluded(&ray));
    let mut search = Search {
        origin: ray.origin,
        dir: ray.dir,
        inv_len2: ray.dir.length_squared().recip(),
        profile,
        reach: profile.max_support(),
        free: horizon,
        exits: [Exit::NONE; EXITS],
        blocked,
        limit: profile.max_support(),
    };
    if !(search.inv_len2.is_finite() && search.reach.is_finite()) {
        return none;
    }
    scratch.mailbox = Mailbox::default();
    search.walk(tree, silhouettes, &mut scratch.stack, &mut scratch.mailbox);
    let mut rays = u32::from(known.is_none());
    let fraction = if !blocked {
        search.free
    } else {
        // The best exit whose light is not blocked by something else.
        let mut found = 0.0;
        for exit in search.exits {
            if exit.visible <= 0.0 {
                break;
            }
            let target = on_light(light, p.point, center + exit.n * 0.5 * (exit.m + profile.support(exit.n)));
            let Some(check) = p.shadow_ray(target) else { continue };
            rays += 1;
            if !tree.occluded(&check) {
                found = exit.visible.min(search.free);
                break;
            }
        }
        found
    };
    let fraction = if fraction.is_nan() { f32::from(u8::from(!blocked)) } else { fraction.clamp(0.0, 1.0) };
    SilhouetteVisibility { fraction, rays }
}

/// The receiver's tangent plane (unit `normal`) seen on the light plane from a point `to` away
/// from the light's centre (`dir` its unit direction): the line `e . h = m_h`, `h` pointing
/// below the horizon; `(0, inf)` when the normal is along the ray.
fn horizon_line(normal: Vec3, to: Vec3, dir: Vec3) -> (Vec3, f32) {
    let across = normal - dir * dir.dot(normal);
    if across.length_squared() > 1e-12 {
        let len = across.length();
        (-across / len, to.dot(normal) / len)
    } else {
        (Vec3::ZERO, f32::INFINITY)
    }
}

/// A pixel's hard shadow ray, as the gated frame pass ([`penumbra_mask`]) sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Probe {
    /// Answered in full without a search (the light's centre below the horizon, the point
    /// inside a spherical light, degenerate input): the visibility is final.
    Done(SilhouetteVisibility),
    /// The centre is visible; the visible fraction if no edge is near is the horizon's.
    Lit(f32),
    /// The centre is blocked; how far (in pixels) the penumbra may reach from the hard
    /// shadow's edge there.
    Blocked(f32),
}

impl Probe {
    /// The answer when no search follows: the final visibility, the horizon's share, or 0.
    pub fn fraction(self) -> f32 {
        match self {
            Probe::Done(v) => v.fraction,
            Probe::Lit(f) => f,
            Probe::Blocked(_) => 0.0,
        }
    }
}

/// The farthest a penumbra is taken to reach from a hard shadow's edge, in pixels. Wider
/// penumbrae keep the hard answer beyond it: on the scenes of
/// `docs/results/soft-shadows-quality.md` 6 pixels (at 256x256) costs little error against
/// 24 (kitchen's even falls: the search is wrong under its layered table) at about half the
/// time, where 3 pixels doubles the error on arena and the analytic sphere.
pub const MAX_REACH: f32 = 6.0;

/// The hard shadow ray of [`silhouette_visibility`] alone, for a point whose pixel covers
/// `pixel` world units across (at its distance from the camera): whether the light's centre
/// is visible and, when it is blocked, how many pixels the penumbra may reach from there
/// (PCSS's width: the light's extent on its plane times `t / (1 - t)` for the nearest
/// blocker at `t` of the ray, stretched by the receiver's slant to the light, plus a pixel,
/// at most [`MAX_REACH`]). One ray (a nearest-hit one), none for a `Done` without rays.
pub fn hard_probe(tree: &KdTree, light: &AreaLight, p: &ShadingPoint, pixel: f32) -> Probe {
    hard_probe_and_blocker(tree, light, p, pixel).0
}

/// [`hard_probe`] and, for a blocked probe, its nearest blocker's distance as the fraction
/// of the way to the light's centre (`None` for any other probe): the same ray, traced once.
/// A nearest-hit ray to a blocker costs about what an any-hit one does in a kd-tree, whose
/// front-to-back descent meets the nearest blocker's leaf first.
///
/// Nothing is normalised before the ray: the tests of the common cases (the whole light
/// above the horizon, or below it) are homogeneous in the normal's length, and the unit
/// vectors are made only for a horizon's share or a blocker's reach. Always inlined: the
/// shading point its caller has just made is read from registers, not from the stores that
/// made it (a stalled load on every probe, `perf annotate` of the convolved edge widths).
#[inline(always)]
pub fn hard_probe_and_blocker(tree: &KdTree, light: &AreaLight, p: &ShadingPoint, pixel: f32) -> (Probe, Option<f32>) {
    hard_probe_with(tree, light, p, pixel, |ray| tree.intersect(ray).map(|hit| hit.t))
}

/// [`hard_probe_and_blocker`] with its one ray answered by `blocker`: the nearest blocker's
/// distance along the ray (the fraction of the way to its end), or `None` where nothing
/// blocks it. The ray is the light centre's, or, for a final probe whose light's centre is
/// below the horizon, the one towards the part of the light above it. `blocker` is called at
/// most once, and only where the answer takes a ray; a point inside a spherical light traces
/// its own in `tree`. With a `blocker` that traces nothing, the probe of a point whose ray is
/// known from its neighbours (the sparse probes of [`crate::convolution`]): a NaN distance
/// then stands for a blocker not measured.
#[inline(always)]
pub fn hard_probe_with(
    tree: &KdTree,
    light: &AreaLight,
    p: &ShadingPoint,
    pixel: f32,
    blocker: impl FnOnce(&Ray) -> Option<f32>,
) -> (Probe, Option<f32>) {
    let probe = |probe: Probe| (probe, None);
    let center = light.center();
    let Some(profile) = Profile::of(light, p.point) else {
        return probe(Probe::Done(silhouette_visibility(
            tree,
            &Silhouettes::EMPTY,
            light,
            p,
            &mut SilhouetteScratch::default(),
        )));
    };
    let to = center - p.point;
    let Some(ray) = p.shadow_ray(center) else {
        // What `silhouette_visibility` answers there, without its set-up, its one ray
        // answered by `blocker`.
        let none = Probe::Done(SilhouetteVisibility { fraction: 0.0, rays: 0 });
        if profile.below(p.normal, to) {
            return probe(none);
        }
        let Some((normal, dir)) = unit_frame(p.normal, to) else { return probe(none) };
        let horizon = horizon_line(normal, to, dir);
        return probe(Probe::Done(above_horizon(light, p, profile, horizon, |ray| blocker(ray).is_some())));
    };
    // A vector that normalises to zero (its squared length 0 or past f32) has no direction.
    let usable = |v: Vec3| {
        let l2 = v.length_squared();
        l2 > 0.0 && l2.is_finite()
    };
    if !(to.is_finite() && p.normal.is_finite() && usable(to) && usable(p.normal)) {
        return probe(Probe::Done(SilhouetteVisibility { fraction: 0.0, rays: 0 }));
    }
    let blocker = blocker(&ray);
    let unit = || (p.normal.normalize_or_zero(), to.normalize_or_zero());
    match blocker {
        None if profile.above(p.normal, to) => probe(Probe::Lit(1.0)),
        None => {
            let (normal, dir) = unit();
            let (h, m_h) = horizon_line(normal, to, dir);
            let horizon = if h == Vec3::ZERO { 1.0 } else { 1.0 - profile.tail(h, m_h) };
            probe(Probe::Lit(if horizon.is_nan() { 1.0 } else { horizon.clamp(0.0, 1.0) }))
        }
        Some(t) => {
            let (normal, dir) = unit();
            let t = t.clamp(0.0, 1.0);
            let width = profile.max_support() * t / (1.0 - t).max(1e-3);
            let slant = normal.dot(dir).max(0.1);
            let reach = width / (slant * pixel) + 1.0;
            (Probe::Blocked(if reach.is_nan() { MAX_REACH } else { reach.min(MAX_REACH) }), blocker)
        }
    }
}

/// Which pixels of a `width` x `height` frame (row-major `probes`, `None` where no surface
/// was hit) need the cone search: every pixel within a blocked pixel's reach of it, for each
/// blocked pixel with a lit 8-neighbour (the hard shadow's edge, on its dark side). The
/// rest keep [`Probe::fraction`]: far from a hard shadow's edge a point is taken to be in the
/// umbra or fully lit. A penumbra whose hard shadow falls between pixel centres (an occluder
/// thinner than a pixel's footprint) is missed, as hard shadows miss it.
pub fn penumbra_mask(width: u32, height: u32, probes: &[Option<Probe>]) -> Vec<bool> {
    let (w, h) = (width as usize, height as usize);
    let mut mask = vec![false; probes.len()];
    if probes.len() != w * h {
        return mask;
    }
    let lit = |x: usize, y: usize| matches!(probes[y * w + x], Some(Probe::Lit(_)));
    for y in 0..h {
        for x in 0..w {
            let Some(Probe::Blocked(reach)) = probes[y * w + x] else { continue };
            let (x0, x1, y0, y1) = (x.saturating_sub(1), (x + 2).min(w), y.saturating_sub(1), (y + 2).min(h));
            if !(y0..y1).any(|ny| (x0..x1).any(|nx| lit(nx, ny))) {
                continue;
            }
            let r = reach.ceil() as usize;
            for row in mask[y.saturating_sub(r) * w..(y + r + 1).min(h) * w].chunks_mut(w) {
                row[x.saturating_sub(r)..(x + r + 1).min(w)].fill(true);
            }
        }
    }
    mask
}

/// The point of `light` seen from `p` in the direction of `q`, a point of the plane through
/// the light's centre perpendicular to the shadow ray: on a rectangle's own plane (which is
/// tilted against that plane, so that `q` may lie behind a ceiling the light hangs under), or
/// `q` itself for a sphere (inside it) or a ray parallel to the rectangle.
fn on_light(light: &AreaLight, p: Vec3, q: Vec3) -> Vec3 {
    match light {
        AreaLight::Rect(l) => {
            let normal = l.edge_u.cross(l.edge_v);
            let s = (l.center() - p).dot(normal) / (q - p).dot(normal);
            if s.is_finite() && s > 0.0 { p + (q - p) * s } else { q }
        }
        AreaLight::Sphere(_) => q,
    }
}

/// A silhouette edge the shading point may see the light past while its centre is blocked:
/// the light share `visible` beyond it, its direction `n` and distance `m` on the light plane.
#[derive(Clone, Copy, Debug)]
struct Exit {
    visible: f32,
    n: Vec3,
    m: f32,
}

impl Exit {
    const NONE: Exit = Exit { visible: 0.0, n: Vec3::ZERO, m: 0.0 };
}

/// The cone search of one shading point: the ray `origin + t dir`, `t` in `[T_NEAR, 1]`, and
/// the light's cone around it (radius `reach * t`).
struct Search {
    origin: Vec3,
    dir: Vec3,
    inv_len2: f32,
    profile: Profile,
    reach: f32,
    /// The smallest visible fraction any edge leaves while the centre is visible (the
    /// horizon's to start with).
    free: f32,
    /// The best exits, best first.
    exits: [Exit; EXITS],
    /// Whether the centre is blocked (then exits count, else blockers).
    blocked: bool,
    /// How far from the centre on the light plane an edge can still matter: `reach`, shrunk
    /// as better edges are found (an edge at `m` along `n` acts as one at `m / support(n)` of
    /// the light's extent that way).
    limit: f32,
}

/// An interval of the ray's parameter, or none.
pub type Span = Option<(f32, f32)>;

/// The part of `[t0, t1]` where the cone `origin + t dir +- t k` (along one axis) reaches
/// below (`lower`) and above (`upper`) the plane `split`: the single-ray step widened by the
/// cone's radius. `None` for a side the cone does not reach.
#[inline(always)]
pub fn cone_step(o: f32, d: f32, k: f32, split: f32, t0: f32, t1: f32) -> (Span, Span) {
    // Below: o + t (d - k) <= split. Above: o + t (d + k) >= split.
    let rhs = split - o;
    let side = |c: f32, below: bool| -> Option<(f32, f32)> {
        // `t c <= rhs` (below) or `t c >= rhs` (above).
        let (lo, hi) = if c == 0.0 {
            let inside = if below { rhs >= 0.0 } else { rhs <= 0.0 };
            if inside { (t0, t1) } else { return None }
        } else {
            let x = rhs / c;
            if (c > 0.0) == below { (t0, t1.min(x)) } else { (t0.max(x), t1) }
        };
        (lo <= hi).then_some((lo, hi))
    };
    (side(d - k, true), side(d + k, false))
}

impl Search {
    /// Visits every leaf the cone reaches and every silhouette edge in them.
    fn walk(
        &mut self,
        tree: &KdTree,
        silhouettes: &Silhouettes,
        stack: &mut Vec<(u32, f32, f32)>,
        mailbox: &mut Mailbox,
    ) {
        let nodes = tree.nodes();
        if nodes.is_empty() {
            return;
        }
        let (o, d) = (self.origin.to_array(), self.dir.to_array());
        let margin = 1e-6 * self.dir.abs().max_element();
        stack.clear();
        stack.push((0, T_NEAR, 1.0));
        while let Some((index, t0, t1)) = stack.pop() {
            let node = nodes[index as usize];
            if node.is_leaf() {
                for &prim in tree.leaf_prims(node) {
                    if !mailbox.seen(prim) {
                        self.triangle(tree, silhouettes, prim);
                    }
                }
                continue;
            }
            let a = node.axis();
            // The cone's radius per unit `t` along an axis, with a margin for rounding.
            let k = self.limit * 1.001 + margin;
            let (below, above) = cone_step(o[a], d[a], k, node.split(), t0, t1);
            let left = node.left_child() as u32;
            // The side the ray itself starts on first: the edges nearest the axis are found
            // early, which shrinks the search for the rest.
            let (first, second) = if o[a] + t0 * d[a] < node.split() {
                (below.map(|s| (left, s)), above.map(|s| (left + 1, s)))
            } else {
                (above.map(|s| (left + 1, s)), below.map(|s| (left, s)))
            };
            for (child, (s0, s1)) in [second, first].into_iter().flatten() {
                stack.push((child, s0, s1));
            }
        }
    }

    /// The silhouette edges of triangle `prim` for this ray's direction. An edge between two
    /// triangles is taken from the one facing the shading point (so once); an open or
    /// non-manifold edge from each of its triangles.
    #[inline]
    fn triangle(&mut self, tree: &KdTree, silhouettes: &Silhouettes, prim: u32) {
        let (Some(&normal), Some(&nb), Some(cull)) = (
            silhouettes.normals.get(prim as usize),
            silhouettes.neighbours.get(prim as usize),
            silhouettes.culls.get(prim as usize),
        ) else {
            return;
        };
        if normal == Vec3::ZERO {
            return;
        }
        // Outside the cone (its bounding sphere), or seen too steeply to hold a silhouette.
        let to = cull.center - self.origin;
        let distance = to.length() + cull.radius;
        if (cull.normal.dot(self.origin) - cull.offset).abs() > cull.sin_fold * distance {
            return;
        }
        let tc = to.dot(self.dir) * self.inv_len2;
        let dt = cull.radius * self.inv_len2.sqrt();
        let lateral = (to - self.dir * tc).length() - cull.radius;
        if tc + dt < T_NEAR || tc - dt > 1.0 || lateral > self.limit * (tc + dt) * 1.001 {
            return;
        }
        // Facing is seen from the origin (the silhouette of a central projection), with each
        // edge's own vertex for the neighbour, which shares it.
        let t = tree.triangle(prim);
        let rel = t.map(|v| v - self.origin);
        let front = normal.dot(rel[0]) < 0.0;
        for (i, &other) in nb.iter().enumerate() {
            let closure = match other {
                BOUNDARY => Closure::Open,
                NON_MANIFOLD => Closure::Closed,
                _ => {
                    let index = other & !FLIPPED;
                    let theirs = silhouettes.normals.get(index as usize).is_some_and(|n| n.dot(rel[i]) < 0.0);
                    // A fold seen from the origin: taken once, from the triangle facing it
                    // (or, wound against its neighbour, from the lower index).
                    let once = if other & FLIPPED == 0 { front && !theirs } else { front == theirs && prim < index };
                    if !once {
                        continue;
                    }
                    Closure::Closed
                }
            };
            self.edge(t[i], t[(i + 1) % 3], t[(i + 2) % 3], normal, closure);
        }
    }

    /// One silhouette edge `a b` of a triangle whose third vertex is `c`.
    #[inline]
    fn edge(&mut self, a: Vec3, b: Vec3, c: Vec3, normal: Vec3, closure: Closure) {
        let (o, d) = (self.origin, self.dir);
        let (mut a, mut b) = (a, b);
        let (mut ta, mut tb) = ((a - o).dot(d) * self.inv_len2, (b - o).dot(d) * self.inv_len2);
        // Clip to `t` in [T_NEAR, 1].
        if (ta < T_NEAR && tb < T_NEAR) || (ta > 1.0 && tb > 1.0) || ta.is_nan() || tb.is_nan() {
            return;
        }
        for bound in [T_NEAR, 1.0] {
            let outside = |t: f32| if bound == T_NEAR { t < T_NEAR } else { t > 1.0 };
            if outside(ta) {
                a += (b - a) * ((bound - ta) / (tb - ta));
                ta = bound;
            } else if outside(tb) {
                b += (a - b) * ((bound - tb) / (ta - tb));
                tb = bound;
            }
        }
        // Projected from the origin onto the light plane, relative to the light's centre.
        let pa = (a - o) / ta - d;
        let pb = (b - o) / tb - d;
        let ab = pb - pa;
        let len2 = ab.length_squared();
        let s = if len2 > 0.0 { (-pa.dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
        let q = pa + ab * s;
        let m = q.length();
        if m.is_nan() || m >= self.limit {
            return;
        }
        // Which side of the edge (seen from the origin) the occluder lies on.
        let plane = (a - o).cross(b - o);
        let (side_c, side_d) = ((c - o).dot(plane), d.dot(plane));
        if side_c == 0.0 || side_c.is_nan() {
            return;
        }
        let on_line = side_d == 0.0;
        // The centre on the edge itself (its distance is rounding): the hard shadow's edge.
        let m = if on_line && s > 0.0 && s < 1.0 { 0.0 } else { m };
        let inside = !on_line && (side_c > 0.0) == (side_d > 0.0);
        let n = if m > 1e-6 * self.reach {
            q / m
        } else {
            // On the edge's line: its normal on the light plane, away from the occluder.
            let across = plane - d * (d.dot(plane) * self.inv_len2);
            -across.normalize_or_zero() * side_c.signum()
        };
        // The occluder's extent across the edge on the light plane: unbounded for a closed
        // silhouette, and for any edge on whose occluder's side a blocked centre lies (the
        // light passes a hit only at its exits); the foreshortened strip of an open surface's boundary seen
        // from outside.
        let width = match closure {
            Closure::Closed => f32::INFINITY,
            Closure::Open if inside && self.blocked => f32::INFINITY,
            Closure::Open => {
                let e = (b - a).normalize_or_zero();
                let dn = d * self.inv_len2.sqrt();
                let cos_e = e.dot(dn);
                let f = (normal.dot(dn).abs() / (1.0 - cos_e * cos_e).max(1e-12).sqrt()).min(1.0);
                let height = (c - a).reject_from_normalized(e).length();
                let t = 1.0 / ((1.0 - s) / ta + s / tb);
                f * (height / t).max(2.0 * self.reach)
            }
        };
        let (lo, hi) = if inside { (m - width, m) } else { (m, m + width) };
        let blocked = self.profile.tail(n, lo) - self.profile.tail(n, hi);
        let visible = 1.0 - blocked;
        // The search shrinks to edges that can beat the ones kept (closed edges only: an open
        // one's strip is not a half-plane).
        let closed = width == f32::INFINITY;
        let reach_of = |m: f32| m * self.reach / self.profile.support(n).max(1e-30);
        if (lo > 0.0 || !inside) && visible < self.free {
            self.free = visible;
            if !self.blocked && closed {
                self.limit = self.limit.min(reach_of(m));
            }
        }
        if (inside || on_line) && lo <= 0.0 {
            let exit = Exit { visible, n, m };
            // An edge met again (its triangle is in several leaves) is kept once.
            let known = self.exits.iter().any(|e| e.m == m && e.n == n);
            if let (false, Some(at)) = (known, self.exits.iter().position(|e| visible > e.visible)) {
                self.exits.copy_within(at..EXITS - 1, at + 1);
                self.exits[at] = exit;
            }
            let second = self.exits[EXITS - 1];
            if self.blocked && closed && second.visible > 0.0 {
                let scaled = second.m * self.reach / self.profile.support(second.n).max(1e-30);
                self.limit = self.limit.min(scaled);
            }
        }
    }
}

/// Whether the occluder goes on past a silhouette edge (closed) or stops at it (the boundary
/// of an open surface).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Closure {
    Closed,
    Open,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analytic::sphere_visible_fraction;
    use crate::sampling::{Rng, visible_fraction};
    use crate::test_scenes::{floor, rect_light, trees};
    use kdtree::{BuildConfig, Ray};
    use scenes::builtin::shapes::Part;
    use scenes::{RectLight, SphereLight};

    /// A one-sided quad (two triangles) with corners `a`, `a + u`, `a + u + v`, `a + v`.
    fn quad(a: Vec3, u: Vec3, v: Vec3) -> [[Vec3; 3]; 2] {
        [[a, a + u, a + u + v], [a, a + u + v, a + v]]
    }

    /// The shading point on the floor (or whatever is first) straight below `(x, 0.01, z)`.
    fn floor_point(tree: &KdTree, x: f32, z: f32) -> ShadingPoint {
        let ray = Ray::new(Vec3::new(x, 0.01, z), Vec3::NEG_Y, 0.0, 1.0);
        let hit = tree.intersect(&ray).expect("the floor");
        ShadingPoint::new(tree.triangle(hit.prim), hit, Vec3::NEG_Y)
    }

    /// Ours, hard and a 1024-sample reference at each point.
    fn measure(tree: &KdTree, light: &AreaLight, points: &[ShadingPoint]) -> Vec<(f32, f32, f32)> {
        let sil = Silhouettes::new(tree);
        let mut scratch = SilhouetteScratch::default();
        points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let ours = silhouette_visibility(tree, &sil, light, p, &mut scratch);
                assert!((0.0..=1.0).contains(&ours.fraction) && ours.rays <= 1 + EXITS as u32, "{ours:?}");
                let hard = visible_fraction(tree, light, p, 1, &mut Rng::new(0));
                let reference = visible_fraction(tree, light, p, 1024, &mut Rng::new(i as u64));
                (ours.fraction, hard, reference)
            })
            .collect()
    }

    fn rmse(v: &[(f32, f32, f32)], pick: impl Fn(&(f32, f32, f32)) -> f32) -> f32 {
        (v.iter().map(|x| (pick(x) - x.2).powi(2)).sum::<f32>() / v.len() as f32).sqrt()
    }

    /// Points on the floor along `x` in `[x0, x1]` at `z`.
    fn line(tree: &KdTree, x0: f32, x1: f32, z: f32, n: usize) -> Vec<ShadingPoint> {
        (0..n).map(|i| floor_point(tree, x0 + (x1 - x0) * i as f32 / (n - 1) as f32, z)).collect()
    }

    #[test]
    fn the_gated_pass_matches_the_full_search_along_a_penumbra() {
        let light = rect_light(Vec3::new(0.0, 6.0, 0.0), 1.0);
        let slab = Part::cuboid(Vec3::new(-8.0, 2.0, -8.0), Vec3::new(0.0, 2.2, 8.0));
        let sheet = quad(Vec3::new(-8.0, 2.0, -8.0), Vec3::new(8.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 16.0));
        for tree in trees(&[floor(), slab], &[]).iter().chain(&trees(&[floor()], &sheet)) {
            // A one-row image of the floor across the hard shadow's edge, 0.2 a pixel.
            let points = line(tree, -4.0, 4.0, 0.3, 41);
            let probes: Vec<Option<Probe>> = points.iter().map(|p| Some(hard_probe(tree, &light, p, 0.2))).collect();
            let mask = penumbra_mask(41, 1, &probes);
            let (sil, mut scratch) = (Silhouettes::new(tree), SilhouetteScratch::default());
            for ((p, probe), &masked) in points.iter().zip(&probes).zip(&mask) {
                let full = silhouette_visibility(tree, &sil, &light, p, &mut scratch);
                let probe = probe.unwrap();
                let gated = if masked {
                    let v = silhouette_search(tree, &sil, &light, p, matches!(probe, Probe::Blocked(_)), &mut scratch);
                    assert_eq!(v.rays + 1, full.rays);
                    v.fraction
                } else {
                    probe.fraction()
                };
                assert_eq!(gated, full.fraction, "{probe:?} at {}", p.point);
            }
            // The penumbra (half a unit each side of x = 0) is searched, the far ends are not.
            assert!(mask[18..=22].iter().all(|&m| m) && !mask[0] && !mask[40], "{mask:?}");
        }
    }

    #[test]
    fn the_mask_dilates_the_dark_side_of_every_hard_edge_by_its_reach() {
        // 12 x 5: a one-pixel blocked column (a thin occluder's hard shadow) at x = 1 reaching
        // 1.5 pixels; a 3 x 3 blocked block at x = 9..=11 whose ring reaches 1 pixel and whose
        // centre, with no lit neighbour, would reach 20; no hit at (0, 0).
        let mut probes = vec![Some(Probe::Lit(1.0)); 60];
        for y in 0..5 {
            probes[y * 12 + 1] = Some(Probe::Blocked(1.5));
        }
        for y in 1..4 {
            for x in 9..12 {
                probes[y * 12 + x] = Some(Probe::Blocked(if (x, y) == (10, 2) { 20.0 } else { 1.0 }));
            }
        }
        probes[0] = None;
        let mask = penumbra_mask(12, 5, &probes);
        let rows: Vec<String> =
            mask.chunks(12).map(|r| r.iter().map(|&m| if m { '#' } else { '.' }).collect()).collect();
        assert!(rows.iter().all(|r| r == "####....####"), "{rows:?}");
        // A size mismatch masks nothing, and a frame with no lit pixel has no edge.
        assert!(!penumbra_mask(11, 5, &probes).contains(&true));
        assert!(!penumbra_mask(1, 2, &[Some(Probe::Blocked(5.0)), None]).contains(&true));
    }

    #[test]
    fn adjacency_finds_closed_open_flipped_and_non_manifold_edges() {
        let tree = &trees(&[Part::cuboid(Vec3::ZERO, Vec3::ONE)], &[])[0];
        let s = Silhouettes::new(tree);
        assert_eq!(s.len(), 12);
        assert!(s.neighbours.iter().flatten().all(|&n| n < FLIPPED), "a box is closed and consistently wound");
        let [a, b] = quad(Vec3::ZERO, Vec3::X, Vec3::Z);
        let flipped = [b[0], b[2], b[1]];
        let tree = KdTree::build_soup(&[a, flipped], &BuildConfig::default()).unwrap();
        let s = Silhouettes::new(&tree);
        assert_eq!(s.neighbours.iter().flatten().filter(|&&n| n == BOUNDARY).count(), 4);
        assert_eq!(s.neighbours.iter().flatten().filter(|&&n| n != BOUNDARY && n & FLIPPED != 0).count(), 2);
        let fin = [Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0), Vec3::Y];
        let tree = KdTree::build_soup(&[a, b, fin], &BuildConfig::default()).unwrap();
        let s = Silhouettes::new(&tree);
        assert_eq!(s.neighbours.iter().flatten().filter(|&&n| n == NON_MANIFOLD).count(), 3);
    }

    #[test]
    fn profiles_split_the_light_at_half_and_saturate_at_the_support() {
        let rect = Profile::Rect { u: Vec3::new(2.0, 0.0, 0.0), v: Vec3::new(0.0, 0.0, 0.5) };
        let disc = Profile::Disc(1.5);
        for p in [rect, disc] {
            for n in [Vec3::X, Vec3::Z, Vec3::new(0.6, 0.0, 0.8)] {
                assert!((p.tail(n, 0.0) - 0.5).abs() < 1e-6);
                let s = p.support(n);
                assert_eq!((p.tail(n, s), p.tail(n, -s)), (0.0, 1.0));
                assert_eq!((p.tail(n, f32::INFINITY), p.tail(n, f32::NEG_INFINITY)), (0.0, 1.0));
                let mut last = 1.0;
                for i in -20..=20 {
                    let t = p.tail(n, s * i as f32 / 20.0);
                    assert!(t <= last + 1e-6 && (t - (1.0 - p.tail(n, -s * i as f32 / 20.0))).abs() < 1e-5);
                    last = t;
                }
            }
            assert!(p.max_support() >= p.support(Vec3::new(0.6, 0.0, 0.8)));
        }
        // A uniform rectangle cut along one edge: linear.
        assert!((rect.tail(Vec3::X, 1.0) - 0.25).abs() < 1e-6);
        // Above the plane: the rectangle's corners reach 2 along x and 0.5 along z; the disc
        // 1.5 every way.
        let up = Vec3::Y;
        assert!(rect.above(up, Vec3::new(0.0, 0.1, 0.0)) && disc.above(up, Vec3::new(0.0, 1.6, 0.0)));
        assert!(!disc.above(up, Vec3::new(0.0, 1.4, 0.0)));
        let tilted = Vec3::new(0.6, 0.8, 0.0);
        assert!(!rect.above(tilted, Vec3::new(0.0, 1.0, 0.0)) && rect.above(tilted, Vec3::new(0.0, 1.6, 0.0)));
        assert!(!rect.above(up, Vec3::new(0.0, f32::NAN, 0.0)));
        // Below the plane, the mirror image; neither test cares for the normal's length.
        assert!(rect.below(up, Vec3::new(0.0, -0.1, 0.0)) && disc.below(up, Vec3::new(0.0, -1.6, 0.0)));
        assert!(!disc.below(up, Vec3::new(0.0, -1.4, 0.0)) && !rect.below(up, Vec3::ZERO));
        assert!(!rect.below(tilted, Vec3::new(0.0, -1.0, 0.0)) && rect.below(tilted, Vec3::new(0.0, -1.6, 0.0)));
        assert!(!rect.below(up, Vec3::new(0.0, f32::NAN, 0.0)) && !disc.below(Vec3::NAN, -Vec3::Y));
        for scale in [1e-20f32, 3.0, 1e15] {
            assert!(
                disc.above(up * scale, Vec3::new(0.0, 1.6, 0.0)) && !disc.above(up * scale, Vec3::new(0.0, 1.4, 0.0))
            );
            assert!(
                disc.below(up * scale, Vec3::new(0.0, -1.6, 0.0)) && !disc.below(up * scale, Vec3::new(0.0, -1.4, 0.0))
            );
            assert!(rect.below(tilted * scale, Vec3::new(0.0, -1.6, 0.0)));
        }
        // A point light: a step.
        let point = Profile::Rect { u: Vec3::ZERO, v: Vec3::ZERO };
        assert_eq!((point.tail(Vec3::X, -1e-3), point.tail(Vec3::X, 1e-3)), (1.0, 0.0));
    }

    #[test]
    fn cone_step_widens_the_single_ray_step() {
        // A ray along +x from 0 with a cone of slope 0.5 and a split at 1: below up to t = 2,
        // above from t = 2/3.
        let (below, above) = cone_step(0.0, 1.0, 0.5, 1.0, 0.0, 4.0);
        assert_eq!(below, Some((0.0, 2.0)));
        assert!((above.unwrap().0 - 2.0 / 3.0).abs() < 1e-6 && above.unwrap().1 == 4.0);
        // An origin on the split plane: both sides over the whole interval, for any direction.
        for d in [-0.5, -0.3, 0.0, 0.3, 0.5] {
            assert_eq!(cone_step(1.0, d, 0.5, 1.0, 0.0, 4.0), (Some((0.0, 4.0)), Some((0.0, 4.0))), "{d}");
        }
        // Steeper than the cone: only the side it goes to (and the origin itself).
        assert_eq!(cone_step(1.0, 1.0, 0.5, 1.0, 0.0, 4.0), (Some((0.0, 0.0)), Some((0.0, 4.0))));
        // Zero radius: the ray's own step.
        assert_eq!(cone_step(0.0, 1.0, 0.0, 1.0, 0.0, 4.0), (Some((0.0, 1.0)), Some((1.0, 4.0))));
    }

    /// A slab over half the floor, closed (a box) or one triangle thick (a quad), and a
    /// square light above: both halves of the penumbra, closer than hard shadows.
    #[test]
    fn thick_and_one_triangle_thin_walls_draw_both_halves_of_the_penumbra() {
        let light = rect_light(Vec3::new(0.0, 6.0, 0.0), 1.0);
        let slab = Part::cuboid(Vec3::new(-8.0, 2.0, -8.0), Vec3::new(0.0, 2.2, 8.0));
        let sheet = quad(Vec3::new(-8.0, 2.0, -8.0), Vec3::new(8.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 16.0));
        for tree in trees(&[floor(), slab], &[]).iter().chain(&trees(&[floor()], &sheet)) {
            let v = measure(tree, &light, &line(tree, -1.5, 1.5, 0.3, 61));
            let (ours, hard) = (rmse(&v, |x| x.0), rmse(&v, |x| x.1));
            assert!(ours < 0.3 * hard, "ours {ours} hard {hard}");
            assert!(v.iter().any(|x| x.0 > 0.05 && x.0 < 0.45) && v.iter().any(|x| x.0 > 0.55 && x.0 < 0.95));
            // Deep in the umbra and far out in the light: exact.
            assert_eq!((v[0].0, v[60].0), (0.0, 1.0));
        }
    }

    /// A one-sided vertical plane containing the light's centre: from points a little off
    /// its plane it is seen nearly edge-on and blocks a sliver of the light, not half.
    #[test]
    fn a_plane_edge_on_to_the_light_blocks_a_sliver() {
        let light = rect_light(Vec3::new(0.0, 6.0, 0.0), 1.0);
        let plane = quad(Vec3::new(-2.0, 1.0, 0.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 3.0, 0.0));
        for tree in trees(&[floor()], &plane) {
            let points: Vec<_> = [0.01, 0.03, -0.03, 0.1, 0.0].iter().map(|&z| floor_point(&tree, 0.3, z)).collect();
            let v = measure(&tree, &light, &points);
            for &(ours, _, reference) in &v[..4] {
                assert!((ours - reference).abs() < 0.1 && ours > 0.8, "{v:?}");
            }
        }
    }

    /// A box standing on the floor: points touching its foot, on its lit and its dark side.
    #[test]
    fn an_occluder_touching_the_receiver() {
        let light = rect_light(Vec3::new(3.0, 5.0, 0.0), 1.0);
        let foot = Part::cuboid(Vec3::new(-0.5, 0.0, -0.5), Vec3::new(0.5, 1.0, 0.5));
        for tree in trees(&[floor(), foot], &[]) {
            let dark = measure(&tree, &light, &line(&tree, -2.5, -0.5001, 0.2, 41));
            let lit = measure(&tree, &light, &line(&tree, 0.5001, 1.5, 0.2, 11));
            assert!(rmse(&dark, |x| x.0) < 0.5 * rmse(&dark, |x| x.1), "{dark:?}");
            assert!(rmse(&lit, |x| x.0) < 0.1, "{lit:?}");
            // Right at the foot on the dark side: the umbra.
            assert!(dark[40].0 < 0.05 && dark[40].2 < 0.05, "{:?}", dark[40]);
        }
    }

    /// A spherical light low over the floor, its centre above and then below the horizon.
    #[test]
    fn a_light_partly_below_the_horizon() {
        for tree in trees(&[floor()], &[]) {
            for height in [0.5, 0.2, -0.2, -0.6, -1.2] {
                let light = AreaLight::Sphere(SphereLight {
                    center: Vec3::new(5.0, height, 0.0),
                    radius: 1.0,
                    intensity: Vec3::ONE,
                });
                let v = measure(&tree, &light, &[floor_point(&tree, 0.0, 0.0)]);
                let (ours, _, reference) = v[0];
                assert!((ours - reference).abs() < 0.06, "height {height}: {v:?}");
                assert!(height <= -1.0 || ours > 0.0, "part of it is above");
            }
        }
    }

    /// A light wholly below the receiver's tangent plane is hidden by the receiver: nothing is
    /// traced. One whose centre only is below traces one ray towards the part above.
    #[test]
    fn a_light_wholly_below_the_horizon_traces_nothing() {
        let below = rect_light(Vec3::new(3.0, -0.5, 0.0), 1.0);
        let upright = AreaLight::Rect(RectLight {
            corner: Vec3::new(3.0, -1.5, -1.0),
            edge_u: Vec3::new(0.0, 2.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, 2.0),
            intensity: Vec3::ONE,
        });
        for tree in trees(&[floor()], &[]) {
            let p = floor_point(&tree, 0.0, 0.0);
            let none = SilhouetteVisibility { fraction: 0.0, rays: 0 };
            let mut scratch = SilhouetteScratch::default();
            assert_eq!(silhouette_visibility(&tree, &Silhouettes::EMPTY, &below, &p, &mut scratch), none);
            assert_eq!(hard_probe_and_blocker(&tree, &below, &p, 0.01), (Probe::Done(none), None));
            let Probe::Done(v) = hard_probe(&tree, &upright, &p, 0.01) else { panic!("its centre is below") };
            assert!(v.rays == 1 && v.fraction > 0.0 && v.fraction < 0.5, "{v:?}");
        }
    }

    /// Points whose shadow rays lie in kd-tree split planes (the faces of boxes, where the
    /// builder splits): the cone descent visits both sides.
    #[test]
    fn points_on_split_planes() {
        let light = rect_light(Vec3::new(0.0, 6.0, 0.0), 1.0);
        let slab = Part::cuboid(Vec3::new(-8.0, 2.0, -8.0), Vec3::new(0.0, 2.2, 8.0));
        for tree in trees(&[floor(), slab], &[]) {
            let v = measure(&tree, &light, &[floor_point(&tree, 0.0, 0.3), floor_point(&tree, 0.0, 0.0)]);
            for (ours, _, reference) in v {
                assert!((ours - reference).abs() < 0.12, "{ours} vs {reference}");
            }
        }
    }

    /// A box inside a larger box: the inner one's silhouette is no exit, and the outer one's
    /// penumbra is still drawn.
    #[test]
    fn nested_occluders() {
        let light = rect_light(Vec3::new(0.0, 7.0, 0.0), 1.0);
        let outer = Part::cuboid(Vec3::new(-2.0, 2.0, -2.0), Vec3::new(2.0, 3.0, 2.0));
        let inner = Part::cuboid(Vec3::new(-1.0, 2.3, -1.0), Vec3::new(1.0, 2.7, 1.0));
        for tree in trees(&[floor(), outer, inner], &[]) {
            // Under the inner box's edge: deep in the outer one's umbra.
            let deep = measure(&tree, &light, &line(&tree, -1.5, 1.5, 0.0, 31));
            assert!(deep.iter().all(|x| x.0 == 0.0 && x.2 == 0.0), "{deep:?}");
            let edge = measure(&tree, &light, &line(&tree, 1.5, 3.5, 0.0, 41));
            assert!(rmse(&edge, |x| x.0) < 0.5 * rmse(&edge, |x| x.1), "{edge:?}");
        }
    }

    /// The closed form: a sphere over a plane under a spherical light (`crate::analytic`), on
    /// a grid of floor points across the whole shadow.
    #[test]
    fn the_sphere_over_a_plane_against_the_closed_form() {
        let (center, radius) = (Vec3::new(0.0, 2.0, 0.0), 1.0);
        let sphere = Part::icosphere(radius, 4).translated(center);
        let l = SphereLight { center: Vec3::new(1.2, 8.0, 0.0), radius: 1.0, intensity: Vec3::ONE };
        let light = AreaLight::Sphere(l);
        for tree in trees(&[floor(), sphere], &[]) {
            let sil = Silhouettes::new(&tree);
            let mut scratch = SilhouetteScratch::default();
            let (mut ours, mut hard, mut n) = (0.0f64, 0.0f64, 0);
            for i in 0..40 {
                for j in 0..40 {
                    let p = floor_point(&tree, -2.5 + 3.0 * i as f32 / 39.0, -1.5 + 3.0 * j as f32 / 39.0);
                    let exact = sphere_visible_fraction(p.point, l.center, l.radius, center, radius);
                    let v = silhouette_visibility(&tree, &sil, &light, &p, &mut scratch).fraction;
                    let h = visible_fraction(&tree, &light, &p, 1, &mut Rng::new(0));
                    ours += (f64::from(v) - exact).powi(2);
                    hard += (f64::from(h) - exact).powi(2);
                    n += 1;
                }
            }
            let (ours, hard) = ((ours / n as f64).sqrt(), (hard / n as f64).sqrt());
            assert!(ours < 0.03 && ours < 0.25 * hard, "ours {ours} hard {hard}");
        }
    }

    #[test]
    fn degenerate_input_gives_a_fraction_never_a_panic() {
        let slab = Part::cuboid(Vec3::new(-8.0, 2.0, -8.0), Vec3::new(0.0, 2.2, 8.0));
        let sliver = [Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, 1.0, 0.0)];
        let tree = &trees(&[floor(), slab], &[sliver])[0];
        let sil = Silhouettes::new(tree);
        let mut scratch = SilhouetteScratch::default();
        let p = floor_point(tree, 0.2, 0.1);
        let (nan, inf) = (f32::NAN, f32::INFINITY);
        let lights = [
            rect_light(Vec3::new(0.0, 6.0, 0.0), 0.0),
            rect_light(Vec3::new(0.0, 6.0, 0.0), nan),
            rect_light(Vec3::new(nan, 6.0, 0.0), 1.0),
            rect_light(Vec3::new(0.0, inf, 0.0), 1.0),
            AreaLight::Sphere(SphereLight { center: Vec3::new(0.2, 0.5, 0.1), radius: 1.0, intensity: Vec3::ONE }),
            AreaLight::Sphere(SphereLight { center: Vec3::new(0.0, 6.0, 0.0), radius: nan, intensity: Vec3::ONE }),
            AreaLight::Sphere(SphereLight { center: Vec3::new(0.0, 6.0, 0.0), radius: 0.0, intensity: Vec3::ONE }),
            // The light's centre at the shading point.
            rect_light(p.point, 1.0),
        ];
        let mut bad_point = p;
        bad_point.point = Vec3::NAN;
        let mut flat = p;
        flat.normal = Vec3::ZERO;
        for light in lights {
            for point in [p, bad_point, flat] {
                for s in [&sil, &Silhouettes::EMPTY] {
                    let v = silhouette_visibility(tree, s, &light, &point, &mut scratch);
                    assert!((0.0..=1.0).contains(&v.fraction), "{light:?} {point:?}: {v:?}");
                }
            }
        }
        // A point light is hard shadows.
        let point_light = lights[0];
        for x in [-0.5, -0.01, 0.01, 0.5] {
            let p = floor_point(tree, x, 0.0);
            let ours = silhouette_visibility(tree, &sil, &point_light, &p, &mut scratch).fraction;
            assert_eq!(ours, visible_fraction(tree, &point_light, &p, 1, &mut Rng::new(0)), "{x}");
        }
        // An empty tree.
        let empty = KdTree::build_soup(&[], &BuildConfig::default()).unwrap();
        let v = silhouette_visibility(&empty, &Silhouettes::new(&empty), &lights[0], &p, &mut scratch);
        assert_eq!(v.fraction, 1.0);
    }
}
