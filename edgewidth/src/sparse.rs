//! Sparse silhouette search: inside the penumbra mask ([`penumbra_mask`]), the cone search
//! of silhouette widths ([`silhouette_search`], about 25 us a point against 0.16 us for a hard
//! ray) runs on a coarse lattice of pixels, and the pixels between take the bilinear blend of
//! their lattice corners' visibilities where that is safe; elsewhere they are searched
//! themselves. The idea is adaptive subsampling with a discontinuity test (the G-buffer test of
//! Benthin & Wald 2009's filter, [`crate::filter`]), applied to the search instead of to
//! samples.
//!
//! ## Passes, coarse to fine
//! A frame is answered in [`PASSES`] passes over its pixels ([`pass_of`]):
//! 0. every pixel outside the mask keeps its hard answer ([`Probe::fraction`]) and the masked
//!    pixels at multiples of 4 in x and y are searched;
//! 1. the masked pixels at multiples of 2 (not both of 4) blend their corners on the 4-lattice;
//! 2. the other masked pixels blend their corners on the 2-lattice.
//!
//! A pixel on a line of the coarser lattice (its x or y a multiple of the corners' step) blends
//! its two corners on that line, any other its four. Every corner of a pass's pixel lies on a
//! coarser lattice, so it was answered by an earlier pass and no pixel of a pass reads another
//! of the same pass: a pass runs over its pixels in parallel, in any order, with the same
//! result. A wide, smooth penumbra is searched at one pixel in 16; a narrow one, whose corners
//! fall outside the mask or disagree, is refined to every second pixel or to every pixel.
//!
//! ## When the blend is safe ([`SparseFrame::interpolate`])
//! A pixel blends its corners only when every corner
//! - is inside the frame and holds the frame's answer there from an earlier pass: searched or
//!   blended inside the mask, or the hard answer outside it (what the frame keeps there,
//!   which the spread test below still weighs; this spares the search at the mask's rim);
//! - has a hard probe that is not final ([`Probe::Done`]: the light's centre below its
//!   horizon, another surface's answer), and at least one corner has the pixel's own (the
//!   light's centre lit at both, or blocked at both). A pixel whose corners all differ lies
//!   in a hard shadow (or a gap in one) narrower than the lattice, a thin occluder's. Corners
//!   on both sides of the hard shadow's edge are blended when the rest holds (the
//!   visibility is continuous across that edge, one half there), and the pixel's own hard
//!   answer decides the half: a search gives a lit centre at least half the light (each
//!   edge that leaves the centre visible blocks less than half of a centrally symmetric
//!   light) and a blocked one at most half, so the blend is held to that half
//!   ([`Tolerances::across_edges`] turns this off: then every corner must agree);
//! - lies on a surface continuous with the pixel's: their normals within [`Tolerances::cos_normal`]
//!   and each point within [`Tolerances::plane`] pixel footprints per pixel of distance of the
//!   other's tangent plane (a floor and the table top above it are not blended);
//! - and the corners' visibilities spread by at most [`Tolerances::spread`].
//!
//! A corner blended in pass 1 passed the same tests against its own corners 4 pixels apart,
//! so pass 2 takes it as a lattice value. A lit pixel's blend is also capped at its horizon's
//! share ([`Probe::Lit`]), which its own search could not exceed. Otherwise the pixel is
//! searched.
//!
//! ## Cost
//! Over the scenes of `docs/results/soft-shadows-quality.md` (256 x 256, each scene's light,
//! 2 threads) the passes search 11% (the analytic sphere) to 41% (atrium) of the masked
//! pixels and blend the rest, at an error within 0.0015 RMSE of searching them all; a frame
//! then costs 2.3x to 12x hard shadows, against 3x to 18x. The masked pixels still searched
//! are mostly at the occluders' own geometric edges (corners on other surfaces, or facing
//! away from the light), which no lattice spares; the time falls less than the count of
//! searches does, so the searches left seem dearer than the average one.

use crate::sampling::ShadingPoint;
use crate::silhouette::Probe;
#[cfg(doc)]
use crate::silhouette::{penumbra_mask, silhouette_search};
use glam::Vec3;

/// How many passes a frame takes: the 4-lattice searched, then the 2-lattice and the rest
/// blended or searched.
pub const PASSES: u32 = 3;

/// The pass that answers pixel `(x, y)` ([`SparseFrame::resolve`]): 0 for the pixels outside
/// the mask (`masked` false) and the 4-lattice, 1 for the rest of the 2-lattice, 2 for the
/// others.
pub fn pass_of(x: u32, y: u32, masked: bool) -> u32 {
    if !masked || (x.is_multiple_of(4) && y.is_multiple_of(4)) {
        0
    } else if x.is_multiple_of(2) && y.is_multiple_of(2) {
        1
    } else {
        2
    }
}

/// A hit pixel as the sparse passes see it: what the tests of its corners read, 40 bytes
/// (a frame's buffer of them stays small; its shading point is made again for a search).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pixel {
    /// Its shading point's position.
    pub point: Vec3,
    /// Its shading point's geometric normal, facing the viewer.
    pub normal: Vec3,
    /// How many world units it covers across at its distance from the camera.
    pub footprint: f32,
    /// Its hard shadow ray ([`crate::silhouette::hard_probe`]).
    pub probe: Probe,
}

impl Pixel {
    /// The pixel of the shading point `p`, `footprint` world units across, and its `probe`.
    pub fn new(p: &ShadingPoint, footprint: f32, probe: Probe) -> Pixel {
        Pixel { point: p.point, normal: p.normal, footprint, probe }
    }
}

/// A pixel's answer after the passes so far.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Answer {
    /// Not answered yet (a masked pixel of a later pass), or no surface hit.
    #[default]
    Pending,
    /// The hard answer ([`Probe::fraction`]): outside the mask, or a final probe.
    Hard(f32),
    /// The cone search's visible fraction.
    Searched(f32),
    /// The blend of its corners' visible fractions.
    Interpolated(f32),
}

impl Answer {
    /// The visible fraction (`0` while pending).
    pub fn fraction(self) -> f32 {
        match self {
            Answer::Pending => 0.0,
            Answer::Hard(v) | Answer::Searched(v) | Answer::Interpolated(v) => v,
        }
    }
}

/// When a pixel may blend its corners instead of being searched (see the module's text).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerances {
    /// The largest spread (highest minus lowest) of the corners' visible fractions.
    pub spread: f32,
    /// The smallest cosine between the pixel's normal and a corner's.
    pub cos_normal: f32,
    /// How far a corner's point may lie from the pixel's tangent plane (and the pixel's from
    /// the corner's), in pixel footprints (the larger of the two) per pixel between them.
    pub plane: f32,
    /// Whether a pixel may blend corners across the hard shadow's edge (some corners' light
    /// centre lit, others' blocked; at least one as the pixel's), its blend then held to its
    /// own half of the penumbra. When not, every corner must have the pixel's hard answer.
    pub across_edges: bool,
}

impl Tolerances {
    /// The defaults: a spread of 0.3, normals within 25 degrees, one footprint per pixel,
    /// blending across the hard shadow's edge. On the scenes of
    /// `docs/results/soft-shadows-quality.md` a spread of 0.2 searched up to 10% more of the
    /// masked pixels for at most 0.0013 less RMSE.
    pub const DEFAULT: Tolerances = Tolerances { spread: 0.3, cos_normal: 0.906, plane: 1.0, across_edges: true };

    /// Whether `a` and `b`, `apart` pixels from each other, lie on one smooth surface: normals
    /// within [`Tolerances::cos_normal`], and each point within [`Tolerances::plane`] of the
    /// other's tangent plane. Non-finite input is not.
    #[inline]
    pub fn on_one_surface(&self, a: &Pixel, b: &Pixel, apart: f32) -> bool {
        let (na, nb) = (a.normal, b.normal);
        let d = b.point - a.point;
        let reach = self.plane * a.footprint.max(b.footprint) * apart;
        na.dot(nb) >= self.cos_normal && na.dot(d).abs() <= reach && nb.dot(d).abs() <= reach
    }
}

impl Default for Tolerances {
    fn default() -> Tolerances {
        Tolerances::DEFAULT
    }
}

/// One frame's pixels (row-major, `None` where nothing was hit) and penumbra mask, ready for
/// the passes.
#[derive(Clone, Copy, Debug)]
pub struct SparseFrame<'a> {
    width: u32,
    height: u32,
    pixels: &'a [Option<Pixel>],
    mask: &'a [bool],
    tolerances: Tolerances,
}

impl<'a> SparseFrame<'a> {
    /// A `width` x `height` frame. Buffers of the wrong length are read as far as they go:
    /// a pixel past one is taken as not hit, not masked.
    pub fn new(
        width: u32,
        height: u32,
        pixels: &'a [Option<Pixel>],
        mask: &'a [bool],
        tolerances: Tolerances,
    ) -> SparseFrame<'a> {
        SparseFrame { width, height, pixels, mask, tolerances }
    }

    fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }

    fn pixel(&self, x: u32, y: u32) -> Option<&Pixel> {
        self.pixels.get(self.index(x, y)).and_then(Option::as_ref)
    }

    fn masked(&self, x: u32, y: u32) -> bool {
        self.mask.get(self.index(x, y)).copied().unwrap_or(false)
    }

    /// Pixel `(x, y)`'s answer in pass `pass`, given the answers of the earlier passes
    /// (`known`, row-major; only the pixel's corners are read), or `None` when another pass
    /// answers it. A masked pixel whose probe is not final is blended
    /// ([`SparseFrame::interpolate`]) or else searched: `search` gives its visible fraction.
    pub fn resolve(
        &self,
        known: &[Answer],
        x: u32,
        y: u32,
        pass: u32,
        search: impl FnOnce(&Pixel) -> f32,
    ) -> Option<Answer> {
        let masked = self.masked(x, y);
        if pass_of(x, y, masked) != pass {
            return None;
        }
        let Some(pixel) = self.pixel(x, y) else { return Some(Answer::Pending) };
        Some(match pixel.probe {
            Probe::Lit(_) | Probe::Blocked(_) if masked => match self.interpolate(known, x, y) {
                Some(v) => Answer::Interpolated(v),
                None => Answer::Searched(search(pixel)),
            },
            probe => Answer::Hard(probe.fraction()),
        })
    }

    /// The bilinear blend of pixel `(x, y)`'s lattice corners in `known` (see the module's
    /// text), or `None` when it is not safe (or the pixel is on the 4-lattice, or not hit):
    /// then the pixel is to be searched.
    pub fn interpolate(&self, known: &[Answer], x: u32, y: u32) -> Option<f32> {
        let step = match pass_of(x, y, true) {
            1 => 4,
            2 => 2,
            _ => return None,
        };
        let pixel = self.pixel(x, y)?;
        let lit = match pixel.probe {
            Probe::Lit(_) => true,
            Probe::Blocked(_) => false,
            Probe::Done(_) => return None,
        };
        let (x0, y0) = (x - x % step, y - y % step);
        let (fx, fy) = ((x - x0) as f32 / step as f32, (y - y0) as f32 / step as f32);
        // On a lattice line only the two corners on it count.
        let xs: &[(u32, f32)] = if x == x0 { &[(x0, 1.0)] } else { &[(x0, 1.0 - fx), (x0 + step, fx)] };
        let ys: &[(u32, f32)] = if y == y0 { &[(y0, 1.0)] } else { &[(y0, 1.0 - fy), (y0 + step, fy)] };
        let (mut blend, mut lo, mut hi, mut same) = (0.0f32, f32::INFINITY, f32::NEG_INFINITY, 0);
        for &(cy, wy) in ys {
            for &(cx, wx) in xs {
                if cx >= self.width || cy >= self.height {
                    return None;
                }
                let v = match known.get(self.index(cx, cy))? {
                    Answer::Searched(v) | Answer::Interpolated(v) => *v,
                    Answer::Hard(v) if !self.masked(cx, cy) => *v,
                    Answer::Hard(_) | Answer::Pending => return None,
                };
                let corner = self.pixel(cx, cy)?;
                match corner.probe {
                    Probe::Lit(_) if lit => same += 1,
                    Probe::Blocked(_) if !lit => same += 1,
                    Probe::Lit(_) | Probe::Blocked(_) if self.tolerances.across_edges => {}
                    _ => return None,
                }
                let apart = ((cx.abs_diff(x).pow(2) + cy.abs_diff(y).pow(2)) as f32).sqrt();
                if !self.tolerances.on_one_surface(pixel, corner, apart) {
                    return None;
                }
                blend += wx * wy * v;
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        let agree = hi - lo <= self.tolerances.spread;
        if !agree || same == 0 || !blend.is_finite() {
            return None;
        }
        // The pixel's own hard answer decides the half of the penumbra.
        Some(match pixel.probe {
            Probe::Lit(horizon) => blend.max(0.5).min(horizon),
            _ => blend.min(0.5),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analytic::sphere_visible_fraction;
    use crate::sampling::AreaLight;
    use crate::silhouette::{
        SilhouetteScratch, SilhouetteVisibility, Silhouettes, hard_probe, penumbra_mask, silhouette_search,
    };
    use glam::Vec3;
    use kdtree::{BuildConfig, KdTree, Ray};
    use scenes::SphereLight;
    use scenes::builtin::shapes::{MeshBuilder, Part};

    fn tree(parts: &[Part]) -> KdTree {
        let mut b = MeshBuilder::new();
        let m = b.material("m", Vec3::ONE);
        for p in parts {
            b.add(p, m);
        }
        let mesh = b.finish();
        let soup: Vec<[Vec3; 3]> = mesh.triangles.iter().map(|t| t.map(|i| mesh.positions[i as usize])).collect();
        KdTree::build_soup(&soup, &BuildConfig::default()).unwrap()
    }

    fn floor() -> Part {
        Part::cuboid(Vec3::new(-10.0, -1.0, -10.0), Vec3::new(10.0, 0.0, 10.0))
    }

    /// The shading point on whatever is first straight below `(x, 0.01, z)`.
    fn floor_point(tree: &KdTree, x: f32, z: f32) -> ShadingPoint {
        let ray = Ray::new(Vec3::new(x, 0.01, z), Vec3::NEG_Y, 0.0, 1.0);
        let hit = tree.intersect(&ray).expect("the floor");
        ShadingPoint::new(tree.triangle(hit.prim), hit, Vec3::NEG_Y)
    }

    /// A 5 x 5 frame of floor pixels 0.1 apart, all masked and lit (horizon 1), its
    /// 4-lattice corners searched with `corners` (row-major: (0,0), (4,0), (0,4), (4,4)).
    fn lattice(corners: [f32; 4]) -> (Vec<Option<Pixel>>, Vec<bool>, Vec<Answer>) {
        let tree = tree(&[floor()]);
        let pixels = (0..25)
            .map(|i| {
                let point = floor_point(&tree, 0.1 * (i % 5) as f32, 0.1 * (i / 5) as f32);
                Some(Pixel::new(&point, 0.1, Probe::Lit(1.0)))
            })
            .collect();
        let mut known = vec![Answer::Pending; 25];
        for (c, v) in [0, 4, 20, 24].into_iter().zip(corners) {
            known[c] = Answer::Searched(v);
        }
        (pixels, vec![true; 25], known)
    }

    #[test]
    fn passes_go_coarse_to_fine() {
        assert_eq!(pass_of(0, 0, true), 0);
        assert_eq!(pass_of(8, 4, true), 0);
        assert_eq!(pass_of(3, 5, false), 0);
        assert_eq!(pass_of(2, 0, true), 1);
        assert_eq!(pass_of(6, 2, true), 1);
        assert_eq!(pass_of(1, 0, true), 2);
        assert_eq!(pass_of(4, 3, true), 2);
    }

    /// Agreeing corners are blended (bilinearly, two corners on a lattice line), and the
    /// pixel is not searched.
    #[test]
    fn agreeing_corners_are_blended() {
        let (pixels, mask, known) = lattice([0.6, 0.8, 0.7, 0.75]);
        let frame = SparseFrame::new(5, 5, &pixels, &mask, Tolerances::DEFAULT);
        let centre = frame.resolve(&known, 2, 2, 1, |_| panic!("searched")).unwrap();
        let Answer::Interpolated(v) = centre else { panic!("{centre:?}") };
        assert!((v - 0.7125).abs() < 1e-6, "{v}");
        let Some(edge) = frame.interpolate(&known, 2, 0) else { panic!("not blended") };
        assert!((edge - 0.7).abs() < 1e-6, "{edge}");
        // The other passes' pixels are not answered in pass 1.
        assert_eq!(frame.resolve(&known, 1, 1, 1, |_| 0.0), None);
        assert_eq!(frame.resolve(&known, 4, 4, 1, |_| 0.0), None);
        // A lit pixel's blend is capped at its horizon's share.
        let mut pixels = pixels;
        pixels[12].as_mut().unwrap().probe = Probe::Lit(0.5);
        let frame = SparseFrame::new(5, 5, &pixels, &mask, Tolerances::DEFAULT);
        assert_eq!(frame.interpolate(&known, 2, 2), Some(0.5));
    }

    /// Each unsafe case searches the pixel: corners spread too far, corners whose hard answers
    /// all differ from the pixel's (or any, when not blending across the hard edge), a corner
    /// outside the mask or not searched, a corner on another surface, a corner outside the
    /// frame.
    #[test]
    fn corners_that_disagree_search_the_pixel() {
        let searched = |pixels: &[Option<Pixel>], mask: &[bool], known: &[Answer], x: u32, y: u32| {
            let frame = SparseFrame::new(5, 5, pixels, mask, Tolerances::DEFAULT);
            let mut called = false;
            let a = frame.resolve(known, x, y, pass_of(x, y, true), |_| {
                called = true;
                0.25
            });
            called && a == Some(Answer::Searched(0.25))
        };
        // Visibilities apart by more than the spread.
        let (pixels, mask, known) = lattice([0.9, 0.55, 0.9, 0.9]);
        assert!(searched(&pixels, &mask, &known, 2, 2));
        // ...but only the corners that count: (2, 4) blends (0, 4) and (4, 4).
        assert!(!searched(&pixels, &mask, &known, 2, 4));
        // A corner in the hard shadow: searched unless blending across the hard edge, which
        // holds a lit pixel's blend to the lit half.
        let (mut pixels, mask, mut known) = lattice([0.6; 4]);
        pixels[24].as_mut().unwrap().probe = Probe::Blocked(3.0);
        known[24] = Answer::Searched(0.45);
        let same_only = Tolerances { across_edges: false, ..Tolerances::DEFAULT };
        assert_eq!(SparseFrame::new(5, 5, &pixels, &mask, same_only).interpolate(&known, 2, 2), None);
        assert!(!searched(&pixels, &mask, &known, 2, 0));
        let across = SparseFrame::new(5, 5, &pixels, &mask, Tolerances::DEFAULT);
        assert_eq!(across.interpolate(&known, 2, 2), Some(0.5625));
        assert_eq!(across.interpolate(&known, 3, 3), None, "(2, 2) is not answered yet");
        // ...and a blocked pixel there to the dark half.
        pixels[12].as_mut().unwrap().probe = Probe::Blocked(3.0);
        let across = SparseFrame::new(5, 5, &pixels, &mask, Tolerances::DEFAULT);
        assert_eq!(across.interpolate(&known, 2, 2), Some(0.5));
        // A blocked pixel among lit corners (a thin occluder's hard shadow), either way.
        pixels[24].as_mut().unwrap().probe = Probe::Lit(1.0);
        pixels[12].as_mut().unwrap().probe = Probe::Blocked(3.0);
        known[24] = Answer::Searched(0.6);
        assert!(searched(&pixels, &mask, &known, 2, 2));
        assert_eq!(SparseFrame::new(5, 5, &pixels, &mask, same_only).interpolate(&known, 2, 2), None);
        // A corner outside the mask gives its hard answer, weighed by the spread test...
        let (mut pixels, mut mask, mut known) = lattice([0.6; 4]);
        mask[20] = false;
        known[20] = Answer::Hard(1.0);
        assert!(searched(&pixels, &mask, &known, 2, 2));
        known[20] = Answer::Hard(0.8);
        assert!(!searched(&pixels, &mask, &known, 2, 2));
        // ...but not a masked corner holding a final probe's answer, or one not answered.
        mask[20] = true;
        pixels[20].as_mut().unwrap().probe = Probe::Done(SilhouetteVisibility { fraction: 0.8, rays: 1 });
        assert!(searched(&pixels, &mask, &known, 2, 2));
        pixels[20].as_mut().unwrap().probe = Probe::Lit(1.0);
        known[20] = Answer::Pending;
        assert!(searched(&pixels, &mask, &known, 2, 2));
        // A corner on a table top above the floor, and one on a wall.
        let (mut pixels, mask, known) = lattice([0.6; 4]);
        pixels[0].as_mut().unwrap().point.y += 0.5;
        assert!(searched(&pixels, &mask, &known, 2, 2));
        let (mut pixels, mask, known) = lattice([0.6; 4]);
        pixels[0].as_mut().unwrap().normal = Vec3::X;
        assert!(searched(&pixels, &mask, &known, 2, 2));
        // Pass 2 reads the 2-lattice: (3, 3) has the unanswered (2, 2) as a corner.
        let (pixels, mask, known) = lattice([0.6; 4]);
        assert!(searched(&pixels, &mask, &known, 3, 3));
        // Corners past the frame's edge: a 3 x 3 frame's (2, 2) has none.
        let frame = SparseFrame::new(3, 3, &pixels[..9], &mask[..9], Tolerances::DEFAULT);
        assert_eq!(frame.interpolate(&known[..9], 2, 2), None);
    }

    /// The closed form (`crate::analytic`): a sphere over a floor under a spherical light, seen
    /// straight down as a 64 x 64 frame. The sparse passes stay within a small bound of the
    /// gated frame that searches every masked pixel, searching a fraction of them.
    #[test]
    fn the_sparse_frame_keeps_the_gated_frames_error_on_the_sphere() {
        let (center, radius) = (Vec3::new(0.0, 2.0, 0.0), 1.0);
        let tree = tree(&[floor(), Part::icosphere(radius, 4).translated(center)]);
        let sil = Silhouettes::new(&tree);
        let l = SphereLight { center: Vec3::new(1.2, 8.0, 0.0), radius: 1.0, intensity: Vec3::ONE };
        let light = AreaLight::Sphere(l);
        let (n, span) = (64u32, 3.0f32);
        let footprint = span / (n - 1) as f32;
        let points: Vec<ShadingPoint> = (0..n * n)
            .map(|i| floor_point(&tree, -2.5 + footprint * (i % n) as f32, -1.5 + footprint * (i / n) as f32))
            .collect();
        let pixels: Vec<Option<Pixel>> = points
            .iter()
            .map(|point| Some(Pixel::new(point, footprint, hard_probe(&tree, &light, point, footprint))))
            .collect();
        let probes: Vec<Option<Probe>> = pixels.iter().map(|p| p.map(|p| p.probe)).collect();
        let mask = penumbra_mask(n, n, &probes);
        let mut scratch = SilhouetteScratch::default();
        let mut search = |i: usize| {
            let blocked = matches!(probes[i], Some(Probe::Blocked(_)));
            silhouette_search(&tree, &sil, &light, &points[i], blocked, &mut scratch).fraction
        };
        // The gated frame: every masked pixel searched.
        let dense: Vec<f32> = (0..points.len())
            .map(|i| match probes[i].unwrap() {
                Probe::Lit(_) | Probe::Blocked(_) if mask[i] => search(i),
                probe => probe.fraction(),
            })
            .collect();
        // The sparse passes, in place (no pixel of a pass reads another of the same pass).
        let frame = SparseFrame::new(n, n, &pixels, &mask, Tolerances::DEFAULT);
        let mut known = vec![Answer::Pending; (n * n) as usize];
        for pass in 0..PASSES {
            for i in 0..n * n {
                if let Some(a) = frame.resolve(&known, i % n, i / n, pass, |_| search(i as usize)) {
                    known[i as usize] = a;
                }
            }
        }
        let rmse = |v: &mut dyn Iterator<Item = f32>| {
            let e: f64 = v
                .zip(&points)
                .map(|(v, p)| {
                    (f64::from(v) - sphere_visible_fraction(p.point, l.center, l.radius, center, radius)).powi(2)
                })
                .sum();
            (e / points.len() as f64).sqrt()
        };
        let (dense_err, sparse_err) = (rmse(&mut dense.iter().copied()), rmse(&mut known.iter().map(|a| a.fraction())));
        let masked = mask.iter().filter(|&&m| m).count();
        let searched = known.iter().filter(|a| matches!(a, Answer::Searched(_))).count();
        let blended = known.iter().filter(|a| matches!(a, Answer::Interpolated(_))).count();
        assert_eq!(searched + blended, masked);
        assert!(sparse_err < dense_err + 0.003, "sparse {sparse_err} gated {dense_err}");
        assert!(searched * 3 < masked, "searched {searched} of {masked}");
    }
}
