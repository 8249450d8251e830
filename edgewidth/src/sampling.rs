//! Sampled soft shadows, the references and competitors of the edge widths: rectangular and
//! spherical area lights, stratified visibility with `N` shadow rays, and the 4x4 interleaved
//! sample sets of Benthin & Wald 2009 (4.5).
//!
//! As both papers do (thesis chapter 5, Benthin & Wald 4.5), shading uses one sample at the
//! light's centre and multiplies it by the visible fraction of the light; these functions
//! compute only that fraction. Every shadow ray starts at `kdtree::ray::offset_origin`.

use glam::{Vec2, Vec3};
use kdtree::surface::Surface;
use kdtree::{Hit, KdTree, Ray};
use scenes::{RectLight, SphereLight};

/// An area light: a rectangle (uniform in area) or a sphere (uniform in the solid angle it
/// subtends, so that the visible fraction is a solid-angle fraction: the closed form of
/// [`crate::analytic`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AreaLight {
    /// A parallelogram light (`scenes::RectLight`).
    Rect(RectLight),
    /// A spherical light (`scenes::SphereLight`).
    Sphere(SphereLight),
}

impl AreaLight {
    /// The centre: where hard shadows, edge widths and the shading aim.
    pub fn center(&self) -> Vec3 {
        match self {
            AreaLight::Rect(l) => l.center(),
            AreaLight::Sphere(l) => l.center,
        }
    }

    /// The radius used for the edge width `R` (Eq. 5.1): the sphere's radius, or the radius
    /// of the disc with the rectangle's area.
    pub fn radius(&self) -> f32 {
        match self {
            AreaLight::Rect(l) => (l.edge_u.cross(l.edge_v).length() / std::f32::consts::PI).sqrt(),
            AreaLight::Sphere(l) => l.radius,
        }
    }

    /// The intensity per colour channel, as if concentrated at the centre.
    pub fn intensity(&self) -> Vec3 {
        match self {
            AreaLight::Rect(l) => l.intensity,
            AreaLight::Sphere(l) => l.intensity,
        }
    }

    /// The light scaled about its centre by `factor` (`--light-size`).
    pub fn scaled(&self, factor: f32) -> AreaLight {
        match *self {
            AreaLight::Rect(l) => {
                let (u, v) = (l.edge_u * factor, l.edge_v * factor);
                AreaLight::Rect(RectLight { corner: l.center() - 0.5 * (u + v), edge_u: u, edge_v: v, ..l })
            }
            AreaLight::Sphere(l) => AreaLight::Sphere(SphereLight { radius: l.radius * factor, ..l }),
        }
    }

    /// The point of the light for the unit-square sample `s`, seen from `p`: on the rectangle
    /// at `s`, or on the near side of the sphere along a direction uniform in the cone it
    /// subtends from `p` (the centre when `p` is inside the sphere). A NaN or infinite `p`,
    /// `s` or light gives a point that is not finite (never a panic), which
    /// [`ShadingPoint::shadow_ray`] turns into no ray.
    #[inline]
    pub fn sample(&self, p: Vec3, s: Vec2) -> Vec3 {
        match self {
            AreaLight::Rect(l) => l.point(s.x, s.y),
            AreaLight::Sphere(l) => sphere_sample(l, p, s),
        }
    }
}

/// A point on the near side of sphere `l` along a direction uniform in the solid angle it
/// subtends from `p`.
///
/// With `sin^2 = (r / d)^2`, `1 - cos(theta_max) = sin^2 / (1 + cos(theta_max))` (no
/// cancellation for small lights), `1 - cos(theta) = s.x (1 - cos(theta_max))`, `phi = 2 pi
/// s.y`; the point is at `d cos(theta) - sqrt(r^2 - d^2 sin^2(theta))` along the direction.
fn sphere_sample(l: &SphereLight, p: Vec3, s: Vec2) -> Vec3 {
    let to = l.center - p;
    let d = to.length();
    if d <= l.radius || d == 0.0 {
        return l.center;
    }
    let w = to / d;
    let sin2_max = (l.radius / d).powi(2);
    let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
    let one_minus_cos = s.x * sin2_max / (1.0 + cos_max);
    let cos = 1.0 - one_minus_cos;
    let sin = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * s.y;
    let (u, v) = w.any_orthonormal_pair();
    let dir = (u * phi.cos() + v * phi.sin()) * sin + w * cos;
    let disc = (l.radius * l.radius - d * d * sin * sin).max(0.0);
    p + dir * (d * cos - disc.sqrt())
}

/// A small deterministic random generator (SplitMix64), seeded per pixel.
#[derive(Clone, Copy, Debug)]
pub struct Rng(u64);

impl Rng {
    /// The generator of `seed` (e.g. a pixel index mixed with a frame seed).
    #[inline]
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }

    /// The generator after `n` more draws, without drawing them: SplitMix64's state moves
    /// by one constant per draw, so any draw can be reached at once.
    #[inline]
    pub fn skipped(self, n: u64) -> Rng {
        Rng(self.0.wrapping_add(n.wrapping_mul(0x9E37_79B9_7F4A_7C15)))
    }

    /// A uniform `f32` in `[0, 1)`.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }
}

/// The grid of `n` strata, `nx` columns by `n / nx` rows with `nx` the largest divisor of
/// `n` not above `sqrt(n)` (4 = 2x2, 8 = 2x4, 32 = 4x8, 1024 = 32x32).
#[inline]
pub fn strata(n: u32) -> (u32, u32) {
    let mut nx = (n as f64).sqrt() as u32;
    while nx > 1 && !n.is_multiple_of(nx) {
        nx -= 1;
    }
    let nx = nx.max(1);
    (nx, n / nx)
}

/// The `k`-th of `n` stratified (jittered) samples of the unit square.
#[inline]
pub fn stratified(k: u32, (nx, ny): (u32, u32), rng: &mut Rng) -> Vec2 {
    let (i, j) = (k % nx, k / nx);
    Vec2::new((i as f32 + rng.next_f32()) / nx as f32, (j as f32 + rng.next_f32()) / ny as f32)
}

/// Where a shadow ray towards the light starts, and the surface side it may leave on: a
/// primary hit on a triangle, with `normal` the triangle's geometric normal facing the
/// viewer. It keeps the triangle's [`Surface`] record, so that each of its shadow rays costs a
/// dot product and a select to start ([`Surface::offset_origin`]) instead of the `f64`
/// normal of [`kdtree::ray::offset_origin`], with the same origin bit for bit.
#[derive(Clone, Copy, Debug)]
pub struct ShadingPoint {
    /// The geometric normal, facing the viewer.
    pub normal: Vec3,
    /// The hit point from its barycentrics (`kdtree::ray::surface_point`).
    pub point: Vec3,
    /// The triangle's surface record.
    pub surface: Surface,
}

impl ShadingPoint {
    /// The shading point of `hit` on `tri` seen along `view_dir`.
    pub fn new(tri: [Vec3; 3], hit: Hit, view_dir: Vec3) -> ShadingPoint {
        ShadingPoint::on(&Surface::new(&tri), &hit, view_dir)
    }

    /// The shading point of `hit` on the triangle of the record `surface` (made once per
    /// scene, `kdtree::surface::Surfaces`) seen along `view_dir`: [`ShadingPoint::new`] of
    /// that triangle, the same point.
    #[inline]
    pub fn on(surface: &Surface, hit: &Hit, view_dir: Vec3) -> ShadingPoint {
        ShadingPoint { normal: surface.facing_normal(view_dir), point: surface.point(hit), surface: *surface }
    }

    /// The shadow ray from this point to `target` (`t` in `[0, 1]`, reaching `target` at 1),
    /// or `None` when `target` lies behind the surface, or when `target`, the point or its
    /// normal is not finite (NaN or infinite input: no ray, never a NaN one). It starts at
    /// `kdtree::ray::offset_origin(tri, hit, target - point)`. Always inlined: returned through
    /// memory, the ray is read back wider than it was written, a stalled load on every shadow
    /// ray (`perf annotate` of the convolved edge widths' probes).
    #[inline(always)]
    pub fn shadow_ray(&self, target: Vec3) -> Option<Ray> {
        let (start, target) = self.shadow_segment(target)?;
        Some(Ray::segment(start, target))
    }

    /// The ends of [`ShadingPoint::shadow_ray`]: its origin and `target` (the ray is
    /// `Ray::segment(start, target)`), for kernels that build their packets
    /// from the ends (`packets::RayPacket::segments`).
    #[inline(always)]
    pub fn shadow_segment(&self, target: Vec3) -> Option<(Vec3, Vec3)> {
        let to = target - self.point;
        // Written so that NaN fails.
        if !(to.is_finite() && self.normal.dot(to) > 0.0) {
            return None;
        }
        Some((self.surface.offset_origin(self.point, to), target))
    }
}

/// The visible fraction of `light` from `p` with `n` stratified samples (`n = 1`: the centre,
/// hard shadows), jittered by `rng`. Samples behind the surface count as blocked, and so do
/// samples that are not finite (from a NaN or infinite light or shading point; with `n = 1`
/// only the centre is sampled, so a NaN radius alone does not matter).
pub fn visible_fraction(tree: &KdTree, light: &AreaLight, p: &ShadingPoint, n: u32, rng: &mut Rng) -> f32 {
    if n <= 1 {
        return p.shadow_ray(light.center()).map_or(0.0, |ray| f32::from(u8::from(!tree.occluded(&ray))));
    }
    let grid = strata(n);
    let mut visible = 0u32;
    for k in 0..n {
        let target = light.sample(p.point, stratified(k, grid, rng));
        if let Some(ray) = p.shadow_ray(target) {
            visible += u32::from(!tree.occluded(&ray));
        }
    }
    visible as f32 / n as f32
}

/// Benthin & Wald's 4x4 interleaved sampling (2009, 4.5): 16 sets of 16 samples whose
/// union is one 16x16 stratified pattern; pixel `(x, y)` uses set `4 (y % 4) + x % 4`.
///
/// The unit square has 4x4 coarse strata of 4x4 fine strata each. In every coarse stratum a
/// random permutation (its own) deals the 16 fine strata to the 16 sets, and each set's sample
/// is jittered inside its fine stratum. So every set is a jittered stratified pattern over the
/// 4x4 coarse strata with its own, random position inside each of them, and the 16 sets of a
/// 4x4 pixel block together cover each of the 256 fine strata exactly once (which the
/// discontinuity filter then averages).
///
/// Dealing fine stratum `(i, j)` to set `4 (j % 4) + i % 4` instead, as a plain modulo split
/// does, also covers every fine stratum once, but then every set takes the same corner of each
/// coarse stratum: each set is one regular 4x4 grid shifted by its own offset, and a pixel
/// sees a shadow edge through a regular grid. On Sponza at 256x256 that raised the unfiltered
/// visibility RMSE of 16 interleaved samples from 0.017 (as 16 stratified samples) to 0.029
/// (`docs/results/soft-shadows-quality.md`).
#[derive(Clone, Debug, PartialEq)]
pub struct InterleavedSets {
    sets: [[Vec2; 16]; 16],
}

impl InterleavedSets {
    /// The sets of one frame, jittered by `seed`.
    pub fn new(seed: u64) -> InterleavedSets {
        let mut rng = Rng::new(seed);
        let mut sets = [[Vec2::ZERO; 16]; 16];
        for coarse in 0..16u32 {
            let (cx, cy) = (coarse % 4, coarse / 4);
            // Fisher-Yates: `deal[set]` is the fine stratum of this coarse one the set gets.
            let mut deal: [u32; 16] = std::array::from_fn(|k| k as u32);
            for k in (1..16usize).rev() {
                let r = ((rng.next_f32() * (k + 1) as f32) as usize).min(k);
                deal.swap(k, r);
            }
            for (set, &fine) in deal.iter().enumerate() {
                let (i, j) = (4 * cx + fine % 4, 4 * cy + fine / 4);
                sets[set][coarse as usize] =
                    Vec2::new((i as f32 + rng.next_f32()) / 16.0, (j as f32 + rng.next_f32()) / 16.0);
            }
        }
        InterleavedSets { sets }
    }

    /// The set of pixel `(x, y)`.
    #[inline]
    pub fn for_pixel(&self, x: u32, y: u32) -> &[Vec2; 16] {
        &self.sets[(4 * (y % 4) + x % 4) as usize]
    }

    /// The visible fraction of `light` from `p` with the set of pixel `(x, y)`; samples are
    /// counted as in [`visible_fraction`] (non-finite ones as blocked).
    pub fn visible_fraction(&self, tree: &KdTree, light: &AreaLight, p: &ShadingPoint, x: u32, y: u32) -> f32 {
        let mut visible = 0u32;
        for s in self.for_pixel(x, y) {
            if let Some(ray) = p.shadow_ray(light.sample(p.point, *s)) {
                visible += u32::from(!tree.occluded(&ray));
            }
        }
        visible as f32 / 16.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shading_points_start_their_rays_where_offset_origin_does() {
        // Small, huge, far-out and nearly degenerate triangles, targets on both sides.
        let mut rng = Rng::new(9);
        let mut r = |s: f32| (rng.next_f32() - 0.5) * s;
        for (scale, shift) in [(1.0, 0.0), (1e-4, 0.0), (1e4, 0.0), (1.0, 1e5), (10.0, -3e6)] {
            for _ in 0..200 {
                let a = Vec3::new(r(scale), r(scale), r(scale)) + Vec3::splat(shift);
                let (e1, e2) = (Vec3::new(r(scale), r(scale), r(scale)), Vec3::new(r(scale), r(scale), r(scale)));
                let tri = [a, a + e1, a + e2 * if r(1.0) > 0.4 { 1e-6 } else { 1.0 }];
                let hit = Hit { t: 1.0, u: r(1.0) + 0.5, v: 0.25, prim: 0 };
                let view = Vec3::new(r(1.0), r(1.0), r(1.0));
                let p = ShadingPoint::new(tri, hit, view);
                let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize_or_zero();
                assert_eq!(p.normal, if n.dot(view) > 0.0 { -n } else { n });
                assert_eq!(p.point, kdtree::ray::surface_point(&tri, &hit));
                let target = p.point + Vec3::new(r(4.0 * scale), r(4.0 * scale), r(4.0 * scale));
                if let Some(ray) = p.shadow_ray(target) {
                    assert_eq!(ray.origin, kdtree::ray::offset_origin(&tri, &hit, target - p.point));
                }
            }
        }
    }

    #[test]
    fn skipping_draws_reaches_the_same_draw() {
        let start = Rng::new(42);
        let mut seq = start;
        for n in 0..50u64 {
            assert_eq!(start.skipped(n).next_f32(), seq.next_f32(), "draw {n}");
        }
    }

    #[test]
    fn strata_are_near_square() {
        assert_eq!(strata(1), (1, 1));
        assert_eq!(strata(4), (2, 2));
        assert_eq!(strata(8), (2, 4));
        assert_eq!(strata(32), (4, 8));
        assert_eq!(strata(256), (16, 16));
        assert_eq!(strata(7), (1, 7));
    }

    #[test]
    fn stratified_samples_fill_each_stratum_once() {
        let mut rng = Rng::new(3);
        let grid = strata(32);
        let mut seen = [false; 32];
        for k in 0..32 {
            let s = stratified(k, grid, &mut rng);
            let cell = (s.y * 8.0) as usize * 4 + (s.x * 4.0) as usize;
            assert!(!seen[cell]);
            seen[cell] = true;
        }
    }

    #[test]
    fn interleaved_sets_are_each_stratified_and_together_cover_all_strata() {
        let sets = InterleavedSets::new(11);
        let mut all = [false; 256];
        for y in 0..4 {
            for x in 0..4 {
                let mut coarse = [false; 16];
                for s in sets.for_pixel(x, y) {
                    let c = (s.y * 4.0) as usize * 4 + (s.x * 4.0) as usize;
                    assert!(!coarse[c], "set of pixel ({x}, {y}) is not stratified");
                    coarse[c] = true;
                    all[(s.y * 16.0) as usize * 16 + (s.x * 16.0) as usize] = true;
                }
            }
        }
        assert!(all.iter().all(|&b| b));
        assert_eq!(sets.for_pixel(1, 2), sets.for_pixel(5, 6));
    }

    /// The fine stratum of `s` inside its coarse stratum, `0..16`.
    fn fine_in_coarse(s: Vec2) -> usize {
        let (i, j) = ((s.x * 16.0) as usize, (s.y * 16.0) as usize);
        4 * (j % 4) + i % 4
    }

    #[test]
    fn interleaved_sets_are_not_shifted_copies_of_one_grid() {
        // A plain modulo split gives every set the same fine stratum in every coarse one (a
        // regular grid, shifted per set): each set must instead take different positions,
        // and no two sets may differ by one shift over all coarse strata.
        for seed in [1, 7, 11] {
            let sets = InterleavedSets::new(seed);
            let positions: Vec<Vec<usize>> = (0..16)
                .map(|k| {
                    let mut set = sets.for_pixel(k % 4, k / 4).to_vec();
                    set.sort_by_key(|s| (s.y * 4.0) as usize * 4 + (s.x * 4.0) as usize);
                    set.into_iter().map(fine_in_coarse).collect()
                })
                .collect();
            for (k, p) in positions.iter().enumerate() {
                let distinct: std::collections::HashSet<_> = p.iter().collect();
                assert!(distinct.len() >= 8, "seed {seed}: set {k} takes only {} positions", distinct.len());
            }
            for a in 0..16 {
                for b in a + 1..16 {
                    let shift = |c: usize| (positions[b][c] + 16 - positions[a][c]) % 16;
                    assert!((1..16).any(|c| shift(c) != shift(0)), "seed {seed}: sets {a} and {b} are one shift apart");
                }
            }
        }
    }

    #[test]
    fn sphere_samples_lie_on_the_near_side_inside_the_cone() {
        let l = SphereLight { center: Vec3::new(0.0, 10.0, 0.0), radius: 2.0, intensity: Vec3::ONE };
        let light = AreaLight::Sphere(l);
        let p = Vec3::new(1.0, 0.0, 0.5);
        let mut rng = Rng::new(1);
        let sin_max = l.radius / (l.center - p).length();
        for _ in 0..200 {
            let q = light.sample(p, Vec2::new(rng.next_f32(), rng.next_f32()));
            assert!(((q - l.center).length() - l.radius).abs() < 1e-4);
            assert!((q - l.center).dot(p - l.center) >= -1e-4, "near side");
            let cos = (q - p).normalize().dot((l.center - p).normalize());
            assert!(cos >= (1.0 - sin_max * sin_max).sqrt() - 1e-5);
        }
    }

    #[test]
    fn non_finite_lights_and_points_count_as_blocked() {
        // A floor triangle under a light, nothing to block it.
        let tri = [Vec3::new(-5.0, 0.0, -5.0), Vec3::new(0.0, 0.0, 5.0), Vec3::new(5.0, 0.0, -5.0)];
        let tree = KdTree::build_soup(&[tri], &kdtree::BuildConfig::default()).unwrap();
        let hit = Hit { t: 1.0, u: 0.3, v: 0.3, prim: 0 };
        let p = ShadingPoint::new(tri, hit, Vec3::NEG_Y);
        let sphere = SphereLight { center: Vec3::new(0.0, 4.0, 0.0), radius: 0.5, intensity: Vec3::ONE };
        let rect =
            RectLight { corner: Vec3::new(-0.5, 4.0, -0.5), edge_u: Vec3::X, edge_v: Vec3::Z, intensity: Vec3::ONE };
        let sets = InterleavedSets::new(3);
        for light in [AreaLight::Sphere(sphere), AreaLight::Rect(rect)] {
            assert_eq!(visible_fraction(&tree, &light, &p, 16, &mut Rng::new(1)), 1.0);
            assert_eq!(sets.visible_fraction(&tree, &light, &p, 1, 2), 1.0);
        }
        let (nan, inf) = (f32::NAN, f32::INFINITY);
        // (light, visible with the centre alone): a NaN radius leaves the centre finite.
        let lights = [
            (AreaLight::Sphere(SphereLight { center: Vec3::new(0.0, nan, 0.0), ..sphere }), 0.0),
            (AreaLight::Sphere(SphereLight { center: Vec3::new(0.0, inf, 0.0), ..sphere }), 0.0),
            (AreaLight::Sphere(SphereLight { radius: nan, ..sphere }), 1.0),
            (AreaLight::Sphere(sphere).scaled(nan), 1.0),
            (AreaLight::Rect(RectLight { corner: Vec3::new(nan, 4.0, 0.0), ..rect }), 0.0),
            (AreaLight::Rect(RectLight { edge_u: Vec3::new(inf, 0.0, 0.0), ..rect }), 0.0),
            (AreaLight::Rect(rect).scaled(inf), 0.0),
        ];
        for (light, centre) in lights {
            assert_eq!(visible_fraction(&tree, &light, &p, 1, &mut Rng::new(1)), centre, "{light:?}");
            assert_eq!(visible_fraction(&tree, &light, &p, 16, &mut Rng::new(1)), 0.0, "{light:?}");
            assert_eq!(sets.visible_fraction(&tree, &light, &p, 1, 2), 0.0, "{light:?}");
        }
        // A shading point from a NaN hit or triangle: no shadow ray at all.
        let good = AreaLight::Sphere(sphere);
        let mut bad_tri = tri;
        bad_tri[1].x = nan;
        for q in
            [ShadingPoint::new(tri, Hit { u: nan, ..hit }, Vec3::NEG_Y), ShadingPoint::new(bad_tri, hit, Vec3::NEG_Y)]
        {
            assert!(q.shadow_ray(sphere.center).is_none());
            assert_eq!(visible_fraction(&tree, &good, &q, 4, &mut Rng::new(1)), 0.0);
        }
        assert!(p.shadow_ray(Vec3::new(0.0, inf, 0.0)).is_none());
        assert!(p.shadow_ray(sphere.center).is_some());
    }

    #[test]
    fn scaling_keeps_the_centre_and_scales_the_radius() {
        let rect = AreaLight::Rect(RectLight {
            corner: Vec3::new(-1.0, 5.0, -2.0),
            edge_u: Vec3::new(2.0, 0.0, 0.0),
            edge_v: Vec3::new(0.0, 0.0, 4.0),
            intensity: Vec3::ONE,
        });
        let big = rect.scaled(2.0);
        assert!((big.center() - rect.center()).length() < 1e-6);
        assert!((big.radius() - 2.0 * rect.radius()).abs() < 1e-5);
    }
}
