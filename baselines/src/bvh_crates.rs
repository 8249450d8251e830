//! The two most used pure-Rust BVH crates as single-ray [`Tracer`]s (feature `bvh-crates`):
//!
//! - `bvh` (0.13): binary SAH BVH (`Bvh::build_par`), traversed with its allocation-free
//!   `traverse_iterator` (every leaf whose box the ray crosses, no near-to-far pruning: the
//!   crate has no closest-hit traversal); its own triangle test culls back faces, so the
//!   leaves run our Wald test (`kdtree::triangle::WaldTriangle`, the one our tree uses);
//! - `obvhs` (0.4): PLOC build collapsed to a compressed 8-wide BVH (CWBVH,
//!   `build_cwbvh_from_tris` with `BvhBuildParams::medium_build`, which its authors tune to
//!   Embree's build time), traversed with `ray_traverse` (closest hit) and `ray_traverse_miss`
//!   (any hit) and its own Möller-Trumbore test (`Triangle::intersect`).
//!
//! Their hits carry the triangle and distance only: `u` and `v` are 0.

use std::time::Duration;

use bvh::aabb::{Aabb, Bounded};
use bvh::bounding_hierarchy::{BHShape, BoundingHierarchy};
use glam_obvhs::Vec3A;
use kdtree::triangle::{TriangleTest, WaldTriangle};
use kdtree::{Hit, Ray};
use nalgebra::{Point3, Vector3};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::CwBvh;
use obvhs::triangle::Triangle;
use scenes::Scene;
use trace::frame::Driven;
use trace::registry::{Entry, StructureEntry};
use trace::{Registry, SingleRays, TileCounters, Tracer};

/// Registers the two crates' structures and their single-ray methods `bvh` and `obvhs`.
pub fn register(r: &mut Registry) {
    r.add_structure(StructureEntry { name: "bvh", build: |scene| Ok(Box::new(BvhCrate::build(scene))) });
    r.add_structure(StructureEntry { name: "obvhs", build: |scene| Ok(Box::new(Obvhs::build(scene))) });
    r.add(entry("bvh", "the bvh crate (0.13): binary SAH BVH, single rays", |s, _| {
        Ok(Box::new(Driven(SingleRays(s.get::<BvhCrate>("bvh")?))))
    }));
    r.add(entry("obvhs", "the obvhs crate (0.4): CWBVH, single rays", |s, _| {
        Ok(Box::new(Driven(SingleRays(s.get::<Obvhs>("obvhs")?))))
    }));
}

/// A crate's entry, on its own structure of the same name.
fn entry(name: &'static str, summary: &'static str, bind: trace::registry::Bind) -> Entry {
    Entry {
        name,
        family: name,
        summary,
        tiled: false,
        packets: false,
        structure: name,
        shadow_kernel: name,
        soft_kernel: name,
        bind,
    }
}

/// One triangle as a `bvh` shape: its box, our index and its node in the hierarchy.
#[derive(Clone, Copy, Debug)]
struct Shape {
    aabb: Aabb<f32, 3>,
    prim: u32,
    node: usize,
}

impl Bounded<f32, 3> for Shape {
    fn aabb(&self) -> Aabb<f32, 3> {
        self.aabb
    }
}

impl BHShape<f32, 3> for Shape {
    fn set_bh_node_index(&mut self, index: usize) {
        self.node = index;
    }

    fn bh_node_index(&self) -> usize {
        self.node
    }
}

/// The `bvh` crate's BVH over a mesh, with our Wald records for the leaves.
pub struct BvhCrate {
    bvh: bvh::bvh::Bvh<f32, 3>,
    shapes: Vec<Shape>,
    records: Vec<WaldTriangle>,
}

impl std::fmt::Debug for BvhCrate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BvhCrate").field("shapes", &self.shapes.len()).finish_non_exhaustive()
    }
}

impl BvhCrate {
    /// Builds the BVH of `scene`'s triangles (on the current rayon pool); degenerate
    /// triangles are kept (they are never hit), so indices are ours.
    pub fn build(scene: &Scene) -> BvhCrate {
        let mesh = &scene.mesh;
        let tris: Vec<[glam::Vec3; 3]> = (0..mesh.triangles.len()).map(|i| mesh.triangle(i)).collect();
        let mut shapes: Vec<Shape> = tris
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
                Shape {
                    aabb: Aabb::with_bounds(Point3::new(lo.x, lo.y, lo.z), Point3::new(hi.x, hi.y, hi.z)),
                    prim: i as u32,
                    node: 0,
                }
            })
            .collect();
        let bvh = bvh::bvh::Bvh::build_par(&mut shapes);
        BvhCrate { bvh, shapes, records: tris.iter().map(WaldTriangle::new).collect() }
    }

    /// The crate's ray for ours (it has no interval: ours is checked at the leaves).
    #[inline]
    fn ray(ray: &Ray) -> bvh::ray::Ray<f32, 3> {
        let (o, d) = (ray.origin, ray.dir);
        bvh::ray::Ray::new(Point3::new(o.x, o.y, o.z), Vector3::new(d.x, d.y, d.z))
    }
}

impl Tracer for BvhCrate {
    fn intersect_counted<C: TileCounters>(&self, ray: &Ray, _: &mut C) -> Option<Hit> {
        let query = Self::ray(ray);
        let data = WaldTriangle::prepare(ray);
        let mut best = None;
        let mut t_max = ray.t_max;
        for shape in self.bvh.traverse_iterator(&query, &self.shapes) {
            if let Some((t, u, v)) = self.records[shape.prim as usize].intersect(ray, &data, t_max)
                && best.is_none_or(|b: Hit| t < b.t || (t == b.t && shape.prim < b.prim))
            {
                best = Some(Hit { t, u, v, prim: shape.prim });
                t_max = t;
            }
        }
        best
    }

    fn occluded_counted<C: TileCounters>(&self, ray: &Ray, _: &mut C) -> bool {
        let query = Self::ray(ray);
        let data = WaldTriangle::prepare(ray);
        self.bvh
            .traverse_iterator(&query, &self.shapes)
            .any(|shape| self.records[shape.prim as usize].intersect(ray, &data, ray.t_max).is_some())
    }
}

/// The `obvhs` crate's CWBVH over a mesh, with its triangles.
pub struct Obvhs {
    bvh: CwBvh,
    tris: Vec<Triangle>,
}

impl std::fmt::Debug for Obvhs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Obvhs").field("tris", &self.tris.len()).finish_non_exhaustive()
    }
}

impl Obvhs {
    /// Builds the CWBVH of `scene`'s triangles (medium build preset; on the current rayon
    /// pool). Degenerate triangles are kept, so indices are ours.
    pub fn build(scene: &Scene) -> Obvhs {
        let mesh = &scene.mesh;
        let v = |p: glam::Vec3| Vec3A::new(p.x, p.y, p.z);
        let tris: Vec<Triangle> = (0..mesh.triangles.len())
            .map(|i| {
                let [a, b, c] = mesh.triangle(i);
                Triangle { v0: v(a), v1: v(b), v2: v(c) }
            })
            .collect();
        let bvh = obvhs::cwbvh::builder::build_cwbvh_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        Obvhs { bvh, tris }
    }

    #[inline]
    fn ray(ray: &Ray) -> obvhs::ray::Ray {
        let (o, d) = (ray.origin, ray.dir);
        obvhs::ray::Ray::new(Vec3A::new(o.x, o.y, o.z), Vec3A::new(d.x, d.y, d.z), ray.t_min, ray.t_max)
    }
}

impl Tracer for Obvhs {
    fn intersect_counted<C: TileCounters>(&self, ray: &Ray, _: &mut C) -> Option<Hit> {
        let mut hit = obvhs::ray::RayHit::none();
        let indices = &self.bvh.primitive_indices;
        let found =
            self.bvh.ray_traverse(Self::ray(ray), &mut hit, |r, id| self.tris[indices[id] as usize].intersect(r));
        found.then(|| Hit { t: hit.t, u: 0.0, v: 0.0, prim: indices[hit.primitive_id as usize] })
    }

    fn occluded_counted<C: TileCounters>(&self, ray: &Ray, _: &mut C) -> bool {
        let indices = &self.bvh.primitive_indices;
        !self.bvh.ray_traverse_miss(Self::ray(ray), |r, id| self.tris[indices[id] as usize].intersect(r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kdtree::{BuildConfig, KdTree};

    /// Both crates find our single-ray hits (same triangle, or a tie at the same distance) on
    /// the atrium, and the same occlusion for its shadow rays.
    #[test]
    fn crates_agree_with_our_tree() {
        let scene = scenes::load_scene("atrium").unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let camera = scene.default_view().camera(48, 32).unwrap();
        let rays = trace::setup::primary_rays(&camera);
        let shadows = trace::setup::shadow_rays(&scene, &tree, &rays);
        let b = BvhCrate::build(&scene);
        let o = Obvhs::build(&scene);
        fn agree<T: Tracer>(name: &str, t: &T, tree: &KdTree, rays: &[Ray], shadows: &[Ray]) {
            let (mut same, mut occl_same) = (0, 0);
            for ray in rays {
                let (want, got) = (tree.intersect(ray), t.intersect(ray));
                match (want, got) {
                    (None, None) => same += 1,
                    (Some(w), Some(g)) if w.prim == g.prim || (w.t - g.t).abs() <= 1e-4 * w.t => same += 1,
                    _ => {}
                }
            }
            for ray in shadows {
                occl_same += usize::from(tree.occluded(ray) == t.occluded(ray));
            }
            assert!(same * 1000 >= rays.len() * 999, "{name}: {same} of {}", rays.len());
            assert!(occl_same * 1000 >= shadows.len() * 999, "{name}: {occl_same} of {}", shadows.len());
        }
        agree("bvh", &b, &tree, &rays, &shadows);
        agree("obvhs", &o, &tree, &rays, &shadows);
    }
}
