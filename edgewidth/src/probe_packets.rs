//! The convolution's hard probes ([`crate::convolution::probe`]) traced a SIMD register's
//! width at a time: the centre rays of a tile's shading points as nearest-hit packets of 4,
//! 8 or 16 rays ([`packets::samesign`], the thesis's packet traversal of 2.3.1 at the
//! register's width), each probe then made from its lane's answer as the single ray's is.
//!
//! A probe is one nearest-hit ray to the light's centre; neighbouring pixels' rays to one
//! point of the light are the most coherent rays a frame has (the hard shadow rays that
//! `kd-packets-w16` traces the same way, `docs/results/targets.md`). The
//! packet walk gives each lane the single ray's hit bit for bit (`packets`' conformance
//! tests), so a probe here is the single-ray [`crate::convolution::probe`]'s, bit for bit, at
//! every width (tested). What stays single: a final probe's ray (the light's centre below
//! the horizon, the ray towards the part of the light above it), which only
//! [`crate::silhouette::hard_probe_with`] knows how to make.

use glam::Vec3;
use kdtree::{Hit, KdTree, NoCounters};
use packets::{Width, samesign};

use crate::sampling::{AreaLight, ShadingPoint};
use crate::silhouette::{Probe, hard_probe_with};
use crate::sparse::Pixel;

/// Shading points waiting for their probes, traced together by [`ProbePackets::trace`]; kept
/// from one batch to the next so that a frame allocates only while its buffers grow.
#[derive(Debug, Default)]
pub struct ProbePackets {
    /// Each point's slot (the caller's), shading point and footprint, in the order pushed.
    pending: Vec<(usize, ShadingPoint, f32)>,
    /// The centre rays as segments, of the points that cast one (`traced[i]` is the pending
    /// point of segment `i`).
    starts: Vec<Vec3>,
    ends: Vec<Vec3>,
    traced: Vec<u32>,
    /// Per segment: its nearest hit, its distance the fraction of the way to the light's
    /// centre (`None`: nothing blocks it).
    nearest: Vec<Option<Hit>>,
    /// Per pending point: its centre ray's answer, `None` where it casts none.
    answers: Vec<Option<Option<f32>>>,
}

impl ProbePackets {
    /// Queues the probe of `p`, whose pixel covers `footprint` world units across, for
    /// `slot`. Points pushed one after the other share packets: push neighbours together
    /// (a tile in Morton order, [`scenes::morton_order`]).
    #[inline]
    pub fn push(&mut self, slot: usize, p: ShadingPoint, footprint: f32) {
        self.pending.push((slot, p, footprint));
    }

    /// Traces the queued probes, their centre rays `lanes` at a time, and hands each to
    /// `write(slot, pixel, blocker)` in the order pushed, with the blocker as
    /// [`crate::convolution::probe`] gives it (NaN: none). Empties the queue; returns the
    /// rays the probes count ([`rays_of`]).
    pub fn trace(
        &mut self,
        tree: &KdTree,
        light: &AreaLight,
        lanes: Width,
        mut write: impl FnMut(usize, Pixel, f32),
    ) -> u64 {
        let center = light.center();
        let ProbePackets { pending, starts, ends, traced, nearest, answers } = self;
        starts.clear();
        ends.clear();
        traced.clear();
        for (k, (_, p, _)) in pending.iter().enumerate() {
            if let Some((start, end)) = p.shadow_segment(center) {
                starts.push(start);
                ends.push(end);
                traced.push(k as u32);
            }
        }
        nearest.clear();
        packets::at_width!(lanes, V => samesign::intersect_segments::<V, _>(tree, starts, ends, nearest, &mut NoCounters));
        answers.clear();
        answers.resize(pending.len(), None);
        for (&k, hit) in traced.iter().zip(nearest.iter()) {
            answers[k as usize] = Some(hit.map(|h| h.t));
        }
        let mut rays = 0;
        for (&(slot, p, footprint), &answer) in pending.iter().zip(answers.iter()) {
            // `hard_probe_with` asks for the centre ray exactly where `shadow_segment` gave
            // one; any other ray it asks for is a final probe's, traced here alone.
            let (probe, blocker) = hard_probe_with(tree, light, &p, footprint, |ray| {
                answer.unwrap_or_else(|| tree.intersect(ray).map(|hit| hit.t))
            });
            rays += u64::from(rays_of(probe));
            write(slot, Pixel::new(&p, footprint, probe), blocker.unwrap_or(f32::NAN));
        }
        pending.clear();
        rays
    }
}

/// The rays a hard probe traced: one, or a final probe's own count (none, or one towards the
/// part of the light above the horizon).
pub(crate) fn rays_of(probe: Probe) -> u32 {
    match probe {
        Probe::Done(v) => v.rays,
        Probe::Lit(_) | Probe::Blocked(_) => 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::convolution::probe;
    use crate::test_scenes::{floor, rect_light, trees};
    use glam::Vec3;
    use scenes::SphereLight;
    use scenes::builtin::shapes::Part;

    /// Shading points on the floor `y = 0` in an `n` x `n` grid from `(x0, z0)`, `step` apart,
    /// as the camera above would see them.
    fn grid(n: u32, (x0, z0): (f32, f32), step: f32) -> Vec<ShadingPoint> {
        let tri = [Vec3::new(-50.0, 0.0, -50.0), Vec3::new(50.0, 0.0, -50.0), Vec3::new(0.0, 0.0, 50.0)];
        (0..n * n)
            .map(|i| {
                let q = Vec3::new(x0 + (i % n) as f32 * step, 0.0, z0 + (i / n) as f32 * step);
                // The barycentrics of `q` in `tri`, so the point is the hit's own.
                let (e1, e2, r) = (tri[1] - tri[0], tri[2] - tri[0], q - tri[0]);
                let det = e1.x * e2.z - e1.z * e2.x;
                let (u, v) = ((r.x * e2.z - r.z * e2.x) / det, (e1.x * r.z - e1.z * r.x) / det);
                ShadingPoint::new(tri, Hit { t: 1.0, u, v, prim: 0 }, Vec3::new(0.1, -1.0, 0.2))
            })
            .collect()
    }

    /// At every width, with both triangle tests, the batched probes are the single-ray
    /// probes bit for bit (probe, pixel and blocker): a slab's straight edge and a sphere
    /// under a rectangle and a disc, points whose light centre is below their horizon (final
    /// probes, traced alone), and a batch length that is no multiple of a packet's.
    #[test]
    fn every_width_gives_the_single_rays_probes() {
        let rect = rect_light(Vec3::new(0.3, 6.0, 0.2), 1.0);
        // Its centre below the floor's plane, its top above: every probe is a final one.
        let low =
            AreaLight::Sphere(SphereLight { center: Vec3::new(9.0, -0.3, 0.0), radius: 1.0, intensity: Vec3::ONE });
        let slab = Part::cuboid(Vec3::new(-8.0, 2.0, -8.0), Vec3::new(0.0, 2.2, 8.0));
        let ball = Part::icosphere(1.0, 3).translated(Vec3::new(0.5, 2.0, 0.0));
        let points = grid(37, (-3.0, -2.5), 0.15);
        let mut compared = [0usize; 3];
        for light in [rect, low] {
            for part in [slab.clone(), ball.clone()] {
                for tree in trees(&[floor(), part], &[]) {
                    let want: Vec<_> = points
                        .iter()
                        .map(|p| {
                            let (pixel, t) = probe(&tree, &light, p, 0.1);
                            (pixel, t.unwrap_or(f32::NAN).to_bits())
                        })
                        .collect();
                    for lanes in Width::ALL {
                        let mut batch = ProbePackets::default();
                        for (i, p) in points.iter().enumerate() {
                            batch.push(i, *p, 0.1);
                        }
                        let mut have = vec![None; points.len()];
                        let rays =
                            batch.trace(&tree, &light, lanes, |i, pixel, t| have[i] = Some((pixel, t.to_bits())));
                        let have: Vec<_> = have.into_iter().map(Option::unwrap).collect();
                        assert_eq!(have, want, "{lanes:?} {:?}", tree.intersector());
                        let counted: u64 = want.iter().map(|(p, _)| u64::from(rays_of(p.probe))).sum();
                        assert_eq!(rays, counted);
                    }
                    for (pixel, t) in &want {
                        let kind = match pixel.probe {
                            Probe::Lit(_) => 0,
                            Probe::Blocked(_) => {
                                assert!(!f32::from_bits(*t).is_nan());
                                1
                            }
                            Probe::Done(_) => 2,
                        };
                        compared[kind] += 1;
                    }
                }
            }
        }
        assert!(compared.iter().all(|&c| c > 100), "lit, blocked and final probes compared: {compared:?}");
    }
}
