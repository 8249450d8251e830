//! Progressive soft shadows: while the camera rests, each frame adds 16 more shadow rays per
//! lit pixel to the visible fraction of the spherical light.
//!
//! The first frame is the method's own soft-shadow pass (`FrameTracer::soft`, the 16
//! stratified samples of `cones::shadows::light_samples` under the method's kernel). Pass
//! `k >= 1` takes the same 4x4 strata of the disk facing the point, jittered inside each
//! stratum by an offset that depends on `k` only (a Cranley-Patterson rotation of the
//! stratum centres), and traces the rays with the method's stream kernel
//! (`FrameTracer::stream_occluded`); the running mean converges to the light's visible
//! fraction.

use cones::shadows::{SAMPLES, shadow_rays};
use glam::Vec3;
use kdtree::Ray;
use scenes::SphereLight;

/// The offset of refinement pass `k` inside each stratum, in `[-0.5, 0.5)^2` of a stratum
/// (0 for pass 0: the stratum centres of `light_samples`). A 2-D Halton point.
pub fn jitter(k: u32) -> (f64, f64) {
    if k == 0 {
        return (0.0, 0.0);
    }
    fn radical_inverse(mut i: u32, base: u32) -> f64 {
        let (mut f, mut r) = (1.0, 0.0);
        while i > 0 {
            f /= f64::from(base);
            r += f * f64::from(i % base);
            i /= base;
        }
        r
    }
    (radical_inverse(k, 2) - 0.5, radical_inverse(k, 3) - 0.5)
}

/// The 16 points on the disk of `light` facing `p` for pass `k`: the 4x4 strata of
/// `cones::shadows::light_samples` (concentric map of the square to the disk), each moved by
/// [`jitter`]`(k)` inside its stratum. `None` where `light_samples` has none (`p` inside the
/// light, or not finite).
pub fn samples(p: Vec3, light: &SphereLight, k: u32) -> Option<[Vec3; SAMPLES]> {
    cones::shadows::jittered_light_samples(p, light, jitter(k))
}

/// The 16 shadow rays of pass `k` from `start` (a point already moved off its surface by
/// `trace::soft::shadow_start`).
pub fn rays(start: Vec3, light: &SphereLight, k: u32) -> Option<[Ray; SAMPLES]> {
    Some(shadow_rays(start, &samples(start, light, k)?))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pass 0 is exactly the driver's samples; later passes stay on the light's disk, in their
    /// strata, and differ from pass 0.
    #[test]
    fn passes_jitter_inside_the_strata() {
        let light = SphereLight { center: Vec3::new(1.0, 5.0, -2.0), radius: 0.5, intensity: Vec3::ONE };
        let p = Vec3::new(0.3, 0.1, 0.2);
        assert_eq!(samples(p, &light, 0), cones::shadows::light_samples(p, &light));
        let base = samples(p, &light, 0).unwrap();
        for k in 1..20 {
            let (ja, jb) = jitter(k);
            assert!((-0.5..0.5).contains(&ja) && (-0.5..0.5).contains(&jb), "{k}");
            let s = samples(p, &light, k).unwrap();
            assert_ne!(s, base, "{k}");
            for (q, b) in s.iter().zip(&base) {
                let off = *q - light.center;
                assert!(off.length() <= light.radius * 1.0001, "on the disk");
                assert!(off.dot(light.center - p).abs() < 1e-4, "facing p");
                assert!((*q - *b).length() <= light.radius * 0.6, "near its stratum");
            }
        }
        assert!(samples(light.center, &light, 3).is_none());
        assert!(rays(p, &light, 2).unwrap().iter().all(|r| r.t_max > 0.0));
    }
}
