//! 16-sample soft shadows to a spherical light (thesis Table 4.6): the primary hits of a view,
//! then for each hit facing the light its 16 shadow rays traced with a
//! [`cones::ShadowMethod`] (one cone, one pyramid, or single rays), in parallel over rows.

use glam::Vec3;
use kdtree::{Hit, KdTree};
use rayon::prelude::*;
use scenes::{Camera, Scene, SphereLight};

use cones::shadows::{SAMPLES, light_samples, sample_cone, shadow_rays};
use cones::{Cone, ShadowMethod, SoftShadowTracer};

use crate::render::{Method, Renderer, Shadows, TileCounters};

/// The diagonal of the Sponza atrium's bounding box, 41.59 units (the vertex bounds of the Dabrovic
/// model of `../shared/scenes/sponza-dabrovic.obj.gz`, whose units the thesis's light radii 1
/// and 2 are given in). A light radius `r` on another scene is `r * diagonal / SPONZA_DIAGONAL`.
pub const SPONZA_DIAGONAL: f32 = 41.59;

/// Light radius `r` in Sponza units scaled to a scene whose bounding box diagonal is `diag`.
pub fn scaled_radius(r: f32, diag: f32) -> f32 {
    r * diag / SPONZA_DIAGONAL
}

/// The primary hits of `camera`'s image, row by row: the renderer's single-ray pass (all
/// cores), reordered from its tile layout.
pub fn primary_hits(scene: &Scene, tree: &KdTree, camera: &Camera) -> Vec<Option<Hit>> {
    let renderer = Renderer::new(scene, tree, *camera, Method::Mono, Shadows::None);
    let mut buffers = renderer.buffers();
    renderer.trace(&mut buffers);
    renderer.layout().to_row_major(&buffers.hits)
}

/// The shadow rays' origin and cone of the primary hit `hit`: the point moved off its
/// surface towards the light's centre. `None` when the light's centre is behind the surface
/// or the point is inside the light. Public so that other tracers (`rttest compare`) trace
/// exactly these rays.
pub fn shadow_start(scene: &Scene, light: &SphereLight, hit: &Hit, dir: Vec3) -> Option<(Vec3, Cone)> {
    let tri = scene.mesh.triangle(hit.prim as usize);
    let p = kdtree::ray::surface_point(&tri, hit);
    let n = crate::shade::facing_normal(&scene.mesh, hit, dir);
    let to_light = light.center - p;
    if n.dot(to_light) <= 0.0 {
        return None;
    }
    let start = kdtree::ray::offset_origin(&tri, hit, to_light);
    Some((start, sample_cone(start, light)?))
}

/// The result of one soft-shadow pass.
#[derive(Clone, Debug, Default)]
pub struct SoftPass<C> {
    /// Visible fraction of the light per pixel (0 for pixels without a lit hit).
    pub visible: Vec<f32>,
    /// Points that traced shadow rays.
    pub points: u64,
    /// Shadow rays traced (16 per point).
    pub rays: u64,
    /// Shadow rays blocked.
    pub blocked: u64,
    /// Traversal counters summed over the pass.
    pub counts: C,
}

/// Traces the 16 shadow rays of every hit in `hits` (row-major, `camera`'s image) to
/// `light` with `method`.
pub fn soft_shadow_pass<C: TileCounters>(
    scene: &Scene,
    tree: &KdTree,
    camera: &Camera,
    hits: &[Option<Hit>],
    light: &SphereLight,
    method: ShadowMethod,
) -> SoftPass<C> {
    let w = camera.width as usize;
    let mut visible = vec![0.0f32; hits.len()];
    let (points, rays, blocked, counts) = visible
        .par_chunks_mut(w)
        .zip(hits.par_chunks(w))
        .enumerate()
        .map_init(SoftShadowTracer::new, |tracer, (y, (out, row))| {
            let mut counts = C::default();
            let (mut points, mut blocked) = (0u64, 0u64);
            for (x, (slot, hit)) in out.iter_mut().zip(row).enumerate() {
                let Some(hit) = hit else { continue };
                let dir = camera.pixel_ray(x as u32, y as u32).1;
                let Some((start, cone)) = shadow_start(scene, light, hit, dir) else { continue };
                let Some(samples) = light_samples(start, light) else { continue };
                let rays = shadow_rays(start, &samples);
                let mask = tracer.occluded(tree, &rays, &cone, method, &mut counts);
                let n = u64::from(mask.count_ones());
                blocked += n;
                points += 1;
                *slot = 1.0 - n as f32 / SAMPLES as f32;
            }
            (points, points * SAMPLES as u64, blocked, counts)
        })
        .reduce(|| (0, 0, 0, C::default()), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2, a.3.merge(b.3)));
    SoftPass { visible, points, rays, blocked, counts }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kdtree::{BuildConfig, NoCounters};
    use packets::PacketCounts;

    #[test]
    fn every_method_sees_the_same_soft_shadows() {
        let scene = scenes::load_scene("atrium").unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let camera = scene.default_view().camera(48, 32).unwrap();
        let hits = primary_hits(&scene, &tree, &camera);
        let diag = (tree.bounds().max - tree.bounds().min).length();
        let light =
            SphereLight { center: scene.point_light.position, radius: scaled_radius(2.0, diag), intensity: Vec3::ONE };
        let single: SoftPass<NoCounters> =
            soft_shadow_pass(&scene, &tree, &camera, &hits, &light, ShadowMethod::Single);
        assert!(single.blocked > 0 && single.blocked < single.rays);
        assert!(single.visible.iter().any(|&v| v > 0.0 && v < 1.0), "no penumbra");
        for m in [ShadowMethod::Pyramid, ShadowMethod::Cone] {
            let got: SoftPass<PacketCounts> = soft_shadow_pass(&scene, &tree, &camera, &hits, &light, m);
            assert_eq!(got.visible, single.visible, "{m:?}");
            assert!(got.counts.nodes > 0);
        }
    }
}
