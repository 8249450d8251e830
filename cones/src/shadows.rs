//! Cone soft shadows (thesis 4.1.9, Figure 4.5, Table 4.6): the 16 shadow rays from a
//! surface point to a spherical light, traced as one group bounded by the cone from the
//! point tangent to the light, by the pyramid of the same 16 rays, or one by one.
//!
//! The rays go from the point (moved off its surface by `kdtree::ray::offset_origin`) to
//! 16 stratified points of the light's disk as seen from the point (centre `c`, radius `r`,
//! facing the point), over `t` in `[0, 1]`. Every such ray lies inside the tangent cone
//! (`sin α = r / |c - p|`), and inside the narrower cone of the sample disk
//! ([`sample_cone`], `tan α = 0.75 r / |c - p|`), which is the one traced: the cone needs
//! nothing from the rays but their lengths, so its cost does not grow with the number of
//! samples, while the pyramid takes the per-axis extremes of all 16 directions. All three give the same occlusion per ray: the cone and
//! the pyramid go through `packets`' frustum traversal in any-hit mode, whose leaves test
//! the rays exactly.

use glam::{DVec3, Vec3};
use kdtree::{Counters, Intersector, KdTree, Ray, WaldTest, WatertightTest};
use packets::{Frusta, OmniPacket, PacketTreeTest, RayPacket, TileTracer};
use scenes::SphereLight;

use crate::cone::Cone;
use crate::traverse::cone_bound;

/// Shadow rays per shaded point.
pub const SAMPLES: usize = 16;

/// How the 16 shadow rays of a point are traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ShadowMethod {
    /// Each ray on its own (`KdTree::occluded`).
    Single,
    /// The 16 rays as four 2x2 packets under one pyramid frustum (their per-axis direction
    /// extremes, `packets::bound`).
    Pyramid,
    /// The 16 rays as four 2x2 packets under the cone tangent to the light.
    Cone,
}

impl ShadowMethod {
    /// Every method, in table order.
    pub const ALL: [ShadowMethod; 3] = [ShadowMethod::Single, ShadowMethod::Pyramid, ShadowMethod::Cone];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            ShadowMethod::Single => "single",
            ShadowMethod::Pyramid => "pyramid",
            ShadowMethod::Cone => "cone",
        }
    }
}

/// The 16 sample points of `light` seen from `p`: the centres of a 4x4 grid of strata of the
/// unit square, mapped to the light's disk facing `p` (Shirley's concentric map keeps the
/// strata of equal area). `None` when `p` is inside the light or the input is not finite.
pub fn light_samples(p: Vec3, light: &SphereLight) -> Option<[Vec3; SAMPLES]> {
    // The stratum centres' polar coordinates do not depend on `p`: computed once, with the
    // very operations of `jittered_light_samples`, so the samples are bit for bit its own
    // with a zero jitter (tested), without 32 `sin`/`cos` per point.
    static CENTRES: std::sync::LazyLock<[(f64, f64, f64); SAMPLES]> =
        std::sync::LazyLock::new(|| std::array::from_fn(|i| concentric(i, (0.0, 0.0))));
    let (c, r, u, v) = disk_frame(p, light)?;
    Some(std::array::from_fn(|i| {
        let (rho, cos, sin) = CENTRES[i];
        (c + r * rho * (cos * u + sin * v)).as_vec3()
    }))
}

/// The light's centre, radius and the two unit axes of its disk facing `p` (all `f64`), or
/// `None` when `p` is inside the light or the input is not finite.
fn disk_frame(p: Vec3, light: &SphereLight) -> Option<(DVec3, f64, DVec3, DVec3)> {
    let axis = (light.center - p).as_dvec3();
    let dist = axis.length();
    if !dist.is_finite() || light.radius.is_nan() || light.radius < 0.0 || dist <= f64::from(light.radius) {
        return None;
    }
    let w = axis / dist;
    let helper = if w.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let u = w.cross(helper).normalize();
    let v = w.cross(u);
    Some((light.center.as_dvec3(), f64::from(light.radius), u, v))
}

/// Sample `i`'s point of the unit square (stratum `(i % 4, i / 4)` of a 4x4 grid, moved by
/// `jitter` strata) on the unit disk by Shirley's concentric map: `(rho, cos phi, sin phi)`.
fn concentric(i: usize, (ja, jb): (f64, f64)) -> (f64, f64, f64) {
    let a = ((i % 4) as f64 + 0.5 + ja) / 2.0 - 1.0;
    let b = ((i / 4) as f64 + 0.5 + jb) / 2.0 - 1.0;
    // The centre of the square, reachable only with a jitter, maps to the disk's centre.
    let (rho, phi) = if a == 0.0 && b == 0.0 {
        (0.0, 0.0)
    } else if a.abs() > b.abs() {
        (a, std::f64::consts::FRAC_PI_4 * (b / a))
    } else {
        (b, std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * (a / b))
    };
    (rho, phi.cos(), phi.sin())
}

/// [`light_samples`] with every sample moved by `jitter` (each component in `[-0.5, 0.5)`,
/// in units of a stratum) inside its stratum of the square before the concentric map: the
/// same strata, another point in each (the viewer's progressive soft shadows). A zero jitter
/// gives exactly [`light_samples`].
pub fn jittered_light_samples(p: Vec3, light: &SphereLight, jitter: (f64, f64)) -> Option<[Vec3; SAMPLES]> {
    let (c, r, u, v) = disk_frame(p, light)?;
    Some(std::array::from_fn(|i| {
        let (rho, cos, sin) = concentric(i, jitter);
        (c + r * rho * (cos * u + sin * v)).as_vec3()
    }))
}

/// How far from the light's centre the samples of [`light_samples`] lie, as a fraction of the
/// radius: the stratum centres `±0.25`, `±0.75` map to rings of radius 0.25 and 0.75.
pub const SAMPLE_RING: f64 = 0.75;

/// The cone from `p` holding the 16 rays from `p` to [`light_samples`]`(p, light)`: axis
/// towards the light's centre, `tan α = 0.75 r / |c - p|` (the samples lie on the disk facing
/// `p` through the centre, at most `0.75 r` from it), opened for the rounding of the `f32`
/// sample points and ray directions (a few ulps of the coordinates, seen from `|c - p|`
/// away). It needs nothing from the rays, and is narrower than the cone tangent to the
/// light ([`Cone::tangent_to_sphere`], `sin α = r / |c - p|`), which also holds them. `None`
/// where [`light_samples`] is.
pub fn sample_cone(p: Vec3, light: &SphereLight) -> Option<Cone> {
    let to = (light.center - p).as_dvec3();
    let dist = to.length();
    let r = f64::from(light.radius);
    if !dist.is_finite() || r.is_nan() || r < 0.0 || dist <= r {
        return None;
    }
    let scale = light.center.as_dvec3().length() + p.as_dvec3().length() + r + dist;
    let margin = 8.0 * f64::from(f32::EPSILON) * scale / dist;
    let alpha = (SAMPLE_RING * r / dist).atan() + margin;
    Cone::from_tan(p.as_dvec3(), to, alpha.tan()).ok()
}

/// The 16 shadow rays from `origin` (already off the surface) to `samples`, over `[0, 1]`.
/// Not checked: a NaN or infinite origin or sample gives a ray that
/// [`SoftShadowTracer::occluded`] reports as not occluded.
pub fn shadow_rays(origin: Vec3, samples: &[Vec3; SAMPLES]) -> [Ray; SAMPLES] {
    samples.map(|s| shadow_ray(origin, s))
}

/// One of [`shadow_rays`]: from `origin` to the light sample `sample`, over `[0, 1]`.
#[inline]
pub fn shadow_ray(origin: Vec3, sample: Vec3) -> Ray {
    Ray::segment(origin, sample)
}

/// Scratch space for tracing groups of 16 shadow rays from one point, one per thread.
#[derive(Clone, Debug)]
pub struct SoftShadowTracer {
    tracer: TileTracer,
    packets: Vec<OmniPacket>,
}

impl Default for SoftShadowTracer {
    fn default() -> Self {
        SoftShadowTracer::new()
    }
}

impl SoftShadowTracer {
    /// A tracer in any-hit mode for four packets.
    pub fn new() -> SoftShadowTracer {
        let mut tracer = TileTracer::new(4).expect("4 is a valid tile size");
        tracer.set_any_hit(true);
        SoftShadowTracer { tracer, packets: Vec::with_capacity(4) }
    }

    /// Which of the 16 `rays` (sharing one origin, `t_min >= 0`; see [`shadow_rays`]) are
    /// occluded, as bit `i` for ray `i`, traced with `method`. `cone` must hold every ray's
    /// direction ([`sample_cone`] does, and the [`Cone::tangent_to_sphere`] of the light);
    /// it is used by [`ShadowMethod::Cone`] only.
    ///
    /// Input that breaks these rules never makes it panic: a ray with a NaN or infinite
    /// origin or direction (or a NaN interval) is not occluded, by every method, as
    /// `KdTree::occluded` answers; rays with different origins are traced one by one; a cone
    /// with a NaN field is replaced by the rays' pyramid (see `TileTracer::trace_frusta`).
    pub fn occluded<C: Counters>(
        &mut self,
        tree: &KdTree,
        rays: &[Ray; SAMPLES],
        cone: &Cone,
        method: ShadowMethod,
        counters: &mut C,
    ) -> u16 {
        match tree.intersector() {
            Intersector::Wald => self.occluded_with::<WaldTest, C>(tree, rays, cone, method, counters),
            Intersector::Watertight => self.occluded_with::<WatertightTest, C>(tree, rays, cone, method, counters),
        }
    }

    /// [`SoftShadowTracer::occluded`] with the tree's triangle test `I`, chosen once by the
    /// caller (see [`kdtree::TreeTest`]).
    pub fn occluded_with<I: PacketTreeTest, C: Counters>(
        &mut self,
        tree: &KdTree,
        rays: &[Ray; SAMPLES],
        cone: &Cone,
        method: ShadowMethod,
        counters: &mut C,
    ) -> u16 {
        if method == ShadowMethod::Single {
            let mut mask = 0u16;
            for (i, ray) in rays.iter().enumerate() {
                mask |= u16::from(tree.occluded_with_counted::<I, C>(ray, counters)) << i;
            }
            return mask;
        }
        self.packets.clear();
        for four in rays.chunks(4) {
            match OmniPacket::new(RayPacket::new(four)) {
                Some(p) => self.packets.push(p),
                // Rays that do not share an origin: one by one.
                None => return self.occluded_with::<I, C>(tree, rays, cone, ShadowMethod::Single, counters),
            }
        }
        if self.tracer.load_packets(&self.packets).is_none() {
            // The packets' origins differ.
            return self.occluded_with::<I, C>(tree, rays, cone, ShadowMethod::Single, counters);
        }
        match method {
            ShadowMethod::Pyramid => self.tracer.trace_frustum_with::<I, C>(tree, counters),
            _ => {
                let intervals = self.tracer.prepare_intervals_with::<I>(tree);
                let near = intervals.iter().map(|i| i.0).fold(f32::INFINITY, f32::min);
                let far = intervals.iter().map(|i| i.1).fold(f32::NEG_INFINITY, f32::max);
                let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
                for r in rays {
                    let l = r.dir.as_dvec3().length();
                    (lo, hi) = (lo.min(l), hi.max(l));
                }
                let pyramid = packets::FrustumBound { k0: [0.0; 4], k1: [0.0; 4], near, far, hit_scale: 1.0 };
                let bound = cone_bound(cone, &pyramid, (lo * (1.0 - 1e-12), hi * (1.0 + 1e-12)));
                self.tracer.trace_frusta_with::<I, C>(tree, &Frusta::One(bound), counters);
            }
        }
        let mut mask = 0u16;
        for (i, hit) in self.tracer.packet_hits().iter().enumerate() {
            mask |= (hit.found.bitmask() as u16 & 0xF) << (4 * i);
        }
        mask
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kdtree::{BuildConfig, NoCounters};

    #[test]
    fn the_tabled_centres_are_the_zero_jitter_samples_bit_for_bit() {
        let lights = [
            SphereLight { center: Vec3::new(1.0, 5.0, -2.0), radius: 0.75, intensity: Vec3::ONE },
            SphereLight { center: Vec3::new(1.0e5, -3.0, 7.0), radius: 40.0, intensity: Vec3::ONE },
            SphereLight { center: Vec3::ZERO, radius: 1e-3, intensity: Vec3::ONE },
        ];
        for light in &lights {
            for p in [Vec3::new(0.2, 0.1, 0.3), Vec3::new(-9.0, 2.0, 1e4), Vec3::new(0.0, 7.0, 0.0)] {
                let direct = jittered_light_samples(p, light, (0.0, 0.0));
                assert_eq!(
                    light_samples(p, light).map(|s| s.map(|q| q.to_array().map(f32::to_bits))),
                    direct.map(|s| s.map(|q| q.to_array().map(f32::to_bits)))
                );
            }
        }
        // Inside the light: none.
        assert!(light_samples(lights[0].center, &lights[0]).is_none());
    }

    #[test]
    fn samples_lie_on_the_light_inside_the_tangent_cone() {
        let light = SphereLight { center: Vec3::new(1.0, 5.0, -2.0), radius: 0.75, intensity: Vec3::ONE };
        let p = Vec3::new(0.2, 0.1, 0.3);
        let s = light_samples(p, &light).unwrap();
        let cone = Cone::tangent_to_sphere(p, light.center, light.radius).unwrap();
        let narrow = sample_cone(p, &light).unwrap();
        assert!(narrow.tan_alpha < cone.tan_alpha);
        for q in s {
            assert!((q - light.center).length() <= light.radius * 1.0001);
            assert!(cone.contains(q - p) && narrow.contains(q - p));
        }
        // The outermost samples lie on the cone's edge, up to the rounding margin (about 2e-6
        // rad here): it is no wider than it must be.
        let widest = s.iter().map(|&q| crate::cone::angle_between(narrow.axis, (q - p).as_dvec3())).fold(0.0, f64::max);
        assert!(narrow.half_angle() - widest < 1e-5, "{} vs {widest}", narrow.half_angle());
        // Distinct strata.
        for i in 0..SAMPLES {
            for j in 0..i {
                assert!((s[i] - s[j]).length() > 0.05);
            }
        }
        assert!(light_samples(light.center, &light).is_none());
    }

    #[test]
    fn non_finite_points_and_lights_give_no_samples_and_no_cone() {
        let light = SphereLight { center: Vec3::new(1.0, 5.0, -2.0), radius: 0.75, intensity: Vec3::ONE };
        let p = Vec3::new(0.2, 0.1, 0.3);
        assert!(light_samples(p, &light).is_some() && sample_cone(p, &light).is_some());
        let (nan, inf) = (f32::NAN, f32::INFINITY);
        for (p, light) in [
            (Vec3::new(nan, 0.1, 0.3), light),
            (Vec3::new(0.2, -inf, 0.3), light),
            (p, SphereLight { center: Vec3::new(1.0, nan, -2.0), ..light }),
            (p, SphereLight { center: Vec3::new(inf, 5.0, -2.0), ..light }),
            (p, SphereLight { radius: nan, ..light }),
            (p, SphereLight { radius: inf, ..light }),
        ] {
            assert!(light_samples(p, &light).is_none(), "{p} {light:?}");
            assert!(sample_cone(p, &light).is_none(), "{p} {light:?}");
        }
    }

    /// A quad at y = 2 covering x < 1.0 between the floor point `p` and a sphere light above
    /// it: half the light is blocked.
    fn half_wall() -> (KdTree, SphereLight, Vec3) {
        let tris = [
            [Vec3::new(-5.0, 2.0, -5.0), Vec3::new(1.0, 2.0, -5.0), Vec3::new(1.0, 2.0, 5.0)],
            [Vec3::new(-5.0, 2.0, -5.0), Vec3::new(1.0, 2.0, 5.0), Vec3::new(-5.0, 2.0, 5.0)],
        ];
        let tree = KdTree::build_soup(&tris, &BuildConfig::default()).unwrap();
        let light = SphereLight { center: Vec3::new(1.0, 4.0, 0.0), radius: 0.8, intensity: Vec3::ONE };
        (tree, light, Vec3::new(1.0, 0.0, 0.0))
    }

    /// Rays that break `occluded`'s rules: NaN or infinite lanes are not occluded and the
    /// others get the single rays' answers, whatever the method; rays from two origins are
    /// traced one by one. Never a panic.
    #[test]
    fn bad_rays_never_panic_and_match_single_rays() {
        let (tree, light, p) = half_wall();
        let good = shadow_rays(p, &light_samples(p, &light).unwrap());
        let cone = sample_cone(p, &light).unwrap();
        let (nan, inf) = (f32::NAN, f32::INFINITY);
        let mut t = SoftShadowTracer::new();
        let mut cases: Vec<([Ray; SAMPLES], u16)> = Vec::new();
        // The first packet's origins NaN: those rays are invalid lanes, the rest is traced.
        let mut rays = good;
        for r in &mut rays[..4] {
            *r = Ray::new(Vec3::new(nan, 0.0, 0.0), r.dir, 0.0, 1.0);
        }
        cases.push((rays, 0xFFF0));
        // Scattered bad directions and intervals.
        let mut rays = good;
        rays[5] = Ray::new(p, Vec3::new(0.0, nan, 0.0), 0.0, 1.0);
        rays[9] = Ray::new(p, Vec3::new(inf, 4.0, 0.0), 0.0, 1.0);
        rays[14] = Ray::new(p, rays[14].dir, 0.0, nan);
        cases.push((rays, !(1 << 5 | 1 << 9 | 1 << 14)));
        // Two origins, one per half: packets cannot be loaded as one tile.
        let mut rays = good;
        let q = Vec3::new(0.5, 0.0, 0.0);
        for r in &mut rays[8..] {
            *r = Ray::segment(q, light.center);
        }
        cases.push((rays, 0xFFFF));
        for (rays, mask) in cases {
            let single = t.occluded(&tree, &rays, &cone, ShadowMethod::Single, &mut NoCounters);
            assert!(single & mask != 0, "something is blocked");
            assert_eq!(single & !mask, 0, "the bad rays are not occluded: {single:016b}");
            for m in [ShadowMethod::Pyramid, ShadowMethod::Cone] {
                assert_eq!(t.occluded(&tree, &rays, &cone, m, &mut NoCounters), single, "{m:?}");
            }
        }
        // A cone with NaN fields (made by hand) is not trusted: the pyramid is used.
        let bad_cone = Cone { tan_alpha: f64::NAN, ..cone };
        let single = t.occluded(&tree, &good, &cone, ShadowMethod::Single, &mut NoCounters);
        assert_eq!(t.occluded(&tree, &good, &bad_cone, ShadowMethod::Cone, &mut NoCounters), single);
    }

    /// A wall half across the light: the three methods agree ray by ray, and some rays are
    /// blocked and some not.
    #[test]
    fn methods_agree_on_a_half_blocked_light() {
        let (tree, light, p) = half_wall();
        let rays = shadow_rays(p, &light_samples(p, &light).unwrap());
        let cone = sample_cone(p, &light).unwrap();
        let mut t = SoftShadowTracer::new();
        let single = t.occluded(&tree, &rays, &cone, ShadowMethod::Single, &mut NoCounters);
        assert!(single != 0 && single != 0xFFFF, "{single:016b}");
        for m in [ShadowMethod::Pyramid, ShadowMethod::Cone] {
            assert_eq!(t.occluded(&tree, &rays, &cone, m, &mut NoCounters), single, "{m:?}");
        }
    }
}
