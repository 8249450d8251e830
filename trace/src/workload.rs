//! The incoherent workload: ambient-occlusion rays and one diffuse bounce from a frame's
//! primary hits, generated once and traced by every method (Wald, Benthin & Boulos 2008,
//! section 6: the rays where packets "fall apart").
//!
//! For each primary hit, at the hit point moved off its surface by the workspace's one scheme
//! (`kdtree::ray::offset_origin`) to the side the camera sees (the geometric normal turned to
//! face the primary ray, [`crate::shade::facing_normal`]):
//! - `ao_per_hit` ambient-occlusion rays, cosine-distributed about that normal (Malley's
//!   method: a uniform point of the unit disk lifted onto the hemisphere), of length a tenth
//!   of the scene's bounding-box diagonal (`t` in `[0, 1]` with the direction scaled to that
//!   length): any-hit queries;
//! - one diffuse-bounce ray, cosine-distributed the same way, unbounded: a closest-hit query;
//! - one mirror-reflection ray, every surface taken as a perfect mirror
//!   ([`crate::secondary::spawn`], the renderer's spawn rule), unbounded: a closest-hit query,
//!   the `reflect` column of `rttest compare` (the secondary rays of the thesis's shader
//!   proxy, 3.3, which the omni-directional packets of 4.1.2 were made for).
//!
//! The random numbers come from the workspace's seeded `Rng` (SplitMix64), drawn in the order
//! of the hits given, so the rays depend only on the scene, the camera, the hits and the seed:
//! every tracer (Embree included) traces exactly the same rays through its stream queries
//! ([`crate::FrameTracer::stream`], [`crate::FrameTracer::stream_occluded`]).

use glam::Vec3;
use kdtree::surface::Surface;
use kdtree::{Hit, Ray};
use scenes::builtin::shapes::Rng;
use scenes::{Camera, Scene};

use crate::secondary::ReflectFrom;
use crate::shade::facing_normal;

/// The default seed of [`Incoherent::generate`].
pub const SEED: u64 = 0x5eed_00a0;

/// The ambient-occlusion rays' length as a fraction of the scene's bounding-box diagonal.
pub const AO_LENGTH: f32 = 0.1;

/// A frame's incoherent rays.
#[derive(Clone, Debug, Default)]
pub struct Incoherent {
    /// Ambient-occlusion rays, `ao_per_hit` per primary hit in the order of the hits
    /// (any hit, `t` in `[0, 1]`, the direction a tenth of the scene's diagonal long).
    pub ao: Vec<Ray>,
    /// Diffuse-bounce rays, one per primary hit (closest hit, unbounded, unit direction).
    pub diffuse: Vec<Ray>,
    /// Mirror-reflection rays, one per primary hit whose triangle is not degenerate (closest
    /// hit, unbounded, unit direction).
    pub reflect: Vec<Ray>,
}

/// A cosine-distributed unit direction about the unit normal `n` (Malley's method) from two
/// uniform numbers in `[0, 1)`.
pub fn cosine_direction(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let (t, b) = n.any_orthonormal_pair();
    let r = u1.sqrt();
    let phi = std::f32::consts::TAU * u2;
    let z = (1.0 - u1).max(0.0).sqrt();
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * z).normalize()
}

impl Incoherent {
    /// The incoherent rays of a frame exactly as `rttest compare` makes them: the primary
    /// hits of single rays on `tree` (the reference every method is checked against), taken
    /// in the order of the frame's tiles of side [`crate::frame::TILE_SIZE`], then
    /// [`Incoherent::generate`] with the tree's bounding-box diagonal. `rttest render
    /// --workload` traces these, so its figures and `compare`'s columns measure the same rays.
    pub fn of_frame(scene: &Scene, tree: &kdtree::KdTree, camera: &Camera, ao_per_hit: u32, seed: u64) -> Incoherent {
        let layout = crate::frame::TileLayout::new(camera.width, camera.height, crate::frame::TILE_SIZE);
        let mut hits = vec![None; layout.pixel_count()];
        let (_, kdtree::NoCounters) =
            crate::frame::primary_pass(&crate::method::SingleRays(tree), &layout, camera, &mut hits);
        let pixels = layout.tiles().iter().flat_map(|t| t.pixels());
        let diagonal = (tree.bounds().max - tree.bounds().min).length();
        Incoherent::generate(scene, camera, pixels, &hits, diagonal, ao_per_hit, seed)
    }

    /// The incoherent rays of the primary `hits` (any order; `pixels[i]` is the pixel of
    /// `hits[i]`) of `camera` on `scene`: `ao_per_hit` AO rays and one diffuse ray per hit
    /// whose origin and normal are finite. `diagonal` is the scene's bounding-box diagonal.
    pub fn generate(
        scene: &Scene,
        camera: &Camera,
        pixels: impl Iterator<Item = (u32, u32)>,
        hits: &[Option<Hit>],
        diagonal: f32,
        ao_per_hit: u32,
        seed: u64,
    ) -> Incoherent {
        let mut rng = Rng::new(seed);
        let mut out = Incoherent::default();
        let length = AO_LENGTH * diagonal;
        // Every surface a perfect mirror (the reflect rays).
        let mirror = scenes::Material { reflectivity: 1.0, ..scenes::Material::default() };
        for ((x, y), hit) in pixels.zip(hits) {
            let Some(hit) = hit else { continue };
            let (eye, dir) = camera.pixel_ray(x, y);
            let n = facing_normal(&scene.mesh, hit, dir);
            let tri = scene.mesh.triangle(hit.prim as usize);
            let origin = kdtree::ray::offset_origin(&tri, hit, n);
            if !(origin.is_finite() && n.is_finite() && n != Vec3::ZERO) {
                continue;
            }
            for _ in 0..ao_per_hit {
                let d = cosine_direction(n, rng.range(0.0, 1.0), rng.range(0.0, 1.0));
                out.ao.push(Ray::new(origin, d * length, 0.0, 1.0));
            }
            let d = cosine_direction(n, rng.range(0.0, 1.0), rng.range(0.0, 1.0));
            out.diffuse.push(Ray::new(origin, d, 0.0, f32::INFINITY));
            if let Some((ray, _)) =
                crate::secondary::spawn(&Surface::new(&tri), &mirror, eye, dir, hit, ReflectFrom::Surface).reflection
            {
                out.reflect.push(ray);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_directions_lie_in_the_hemisphere_with_cosine_density() {
        let mut rng = Rng::new(3);
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let k = 20000;
        let mut mean_cos = 0.0;
        for _ in 0..k {
            let d = cosine_direction(n, rng.range(0.0, 1.0), rng.range(0.0, 1.0));
            assert!((d.length() - 1.0).abs() < 1e-5);
            assert!(d.dot(n) >= 0.0);
            mean_cos += d.dot(n) as f64 / k as f64;
        }
        // E[cos] = 2/3 under the cosine density (1/2 if uniform over the hemisphere).
        assert!((mean_cos - 2.0 / 3.0).abs() < 0.01, "{mean_cos}");
    }

    #[test]
    fn a_frames_rays_are_those_of_its_single_ray_hits_in_tile_order() {
        let scene = scenes::load_scene("touching-boxes").unwrap();
        let camera = scene.default_view().camera(40, 24).unwrap();
        let tree = kdtree::KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &Default::default()).unwrap();
        let rays = Incoherent::of_frame(&scene, &tree, &camera, 3, SEED);
        // The same hits, gathered pixel by pixel in the layout's tile order.
        let layout = crate::frame::TileLayout::new(40, 24, crate::frame::TILE_SIZE);
        let pixels: Vec<(u32, u32)> = layout.tiles().iter().flat_map(|t| t.pixels()).collect();
        let hits: Vec<Option<Hit>> =
            pixels.iter().map(|&(x, y)| tree.intersect(&crate::method::primary_ray(&camera, x, y))).collect();
        let diag = (tree.bounds().max - tree.bounds().min).length();
        let expected = Incoherent::generate(&scene, &camera, pixels.iter().copied(), &hits, diag, 3, SEED);
        assert!(!expected.diffuse.is_empty() && expected.ao.len() == 3 * expected.diffuse.len());
        let key = |r: &Ray| (r.origin.to_array(), r.dir.to_array(), r.t_min, r.t_max);
        assert_eq!(rays.ao.iter().map(key).collect::<Vec<_>>(), expected.ao.iter().map(key).collect::<Vec<_>>());
        assert_eq!(
            rays.diffuse.iter().map(key).collect::<Vec<_>>(),
            expected.diffuse.iter().map(key).collect::<Vec<_>>()
        );
        assert!(!expected.reflect.is_empty());
        assert_eq!(
            rays.reflect.iter().map(key).collect::<Vec<_>>(),
            expected.reflect.iter().map(key).collect::<Vec<_>>()
        );
    }

    #[test]
    fn rays_start_on_the_seen_side_and_are_reproducible() {
        let scene = scenes::load_scene("cube").unwrap();
        let camera = scene.default_view().camera(16, 12).unwrap();
        let tree = kdtree::KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &Default::default()).unwrap();
        let pixels: Vec<(u32, u32)> = (0..12).flat_map(|y| (0..16).map(move |x| (x, y))).collect();
        let hits: Vec<Option<Hit>> =
            pixels.iter().map(|&(x, y)| tree.intersect(&crate::method::primary_ray(&camera, x, y))).collect();
        let n_hits = hits.iter().flatten().count();
        assert!(n_hits > 0);
        let diag = (tree.bounds().max - tree.bounds().min).length();
        let a = Incoherent::generate(&scene, &camera, pixels.iter().copied(), &hits, diag, 4, SEED);
        let b = Incoherent::generate(&scene, &camera, pixels.iter().copied(), &hits, diag, 4, SEED);
        assert_eq!(a.ao.len(), 4 * n_hits);
        assert_eq!(a.diffuse.len(), n_hits);
        assert_eq!(a.reflect.len(), n_hits);
        assert!(a.ao.iter().zip(&b.ao).all(|(p, q)| p.origin == q.origin && p.dir == q.dir));
        for r in &a.ao {
            assert!((r.dir.length() - 0.1 * diag).abs() < 1e-3 * diag);
            assert_eq!((r.t_min, r.t_max), (0.0, 1.0));
        }
        // Seen from outside, a closed cube: the rays leave it, so nothing blocks a diffuse or
        // reflected ray at its own surface (no self-hit at t ~ 0).
        for r in a.diffuse.iter().chain(&a.reflect) {
            assert!(tree.intersect(r).is_none_or(|h| h.t > 1e-3), "{r:?}");
        }
    }
}
