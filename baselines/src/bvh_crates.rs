//! The two most used pure-Rust BVH crates as single-ray [`Tracer`]s (feature `bvh-crates`):
//!
//! - `bvh` (0.13): binary SAH BVH (`Bvh::build_par`), traversed with its allocation-free
//!   `traverse_iterator` (every leaf whose box the ray crosses, no near-to-far pruning: the
//!   crate has no closest-hit traversal); its own triangle test culls back faces, so the
//!   leaves run our Wald test (`kdtree::triangle::WaldTriangle`, the one our tree uses);
//!
//!   The crate misses boxes for rays with a zero direction component: `Ray::new` caches
//!   `inv_direction = 1 / d` (`±inf` for `±0`), and its slab test
//!   (`ray/intersect_default.rs` and the `simd` kernel of `ray/intersect_simd.rs`) computes
//!   `(aabb - origin) * inv_direction`, which is `0 * inf = NaN` when the origin's coordinate
//!   lies exactly on a face of the box, and then returns `false` ("the ray is in the plane
//!   of an AABB face ... consider this a non-intersection"). A ray in the plane `z = c` of
//!   a box face at `z = c` therefore never enters that box or its subtree, although the box
//!   is closed and its triangles (a floor at `z = c`, a wall standing on it) may be hit: 6
//!   of 935 sibenik pixels and 91 of 14,732 soup and hard-case rays were lost to it (rays
//!   along a floor meeting the foot of a wall, axis-parallel stream rays).
//!
//!   Our adapter builds the crate's `Ray` itself: `inv_direction` is `1 / d` for a non-zero
//!   component (our `Ray::new` keeps none whose reciprocal overflows) and `+f32::MAX` or
//!   `-f32::MAX` for a zero one, so that `0 * MAX = 0`. On an axis with a zero component a
//!   box then gives the interval `[-(o - lo) MAX, (hi - o) MAX]` when the origin is strictly
//!   inside its slab (all of `t` but beyond `t = gap * MAX`: only a gap below about `1e-31`
//!   can matter), one beyond `gap * MAX` when outside (a box at most visited in vain), and,
//!   with the origin on a face, `[0, (hi - o) MAX]` for a box above it with `+MAX` but
//!   `[-(hi - o) MAX, 0]` with `-MAX` (and the mirror image below). So each sign is right
//!   for boxes on one side of the plane only, and the adapter traverses once per choice of
//!   signs (two rays for one zero component, four for two) and keeps the union of the
//!   leaves. That misses nothing the exact slab test keeps: a box touching the plane from
//!   above has only descendants touching it from above or lying in it, and a box lying in
//!   the plane (flat in that axis) holds only triangles coplanar with the ray, which the
//!   Wald test never hits. The leaves run our triangle test on our ray, so the hits are
//!   those of the ray we were given (closest hit and the lower index at equal `t`,
//!   whatever the traversal order); rays without a zero component trace once, as before;
//! - `obvhs` (0.4): PLOC build collapsed to a compressed 8-wide BVH (CWBVH,
//!   `build_cwbvh_from_tris` with `BvhBuildParams::medium_build`, which its authors tune to
//!   Embree's build time), traversed with `ray_traverse` (closest hit) and `ray_traverse_miss`
//!   (any hit) and its own Möller-Trumbore test (`Triangle::intersect`).
//!
//!   The crate's `build_cwbvh_from_tris` ends, in builds with debug assertions (the crate
//!   compiled with `debug-assertions`: our test and dev profiles, not `--release`), with
//!   `CwBvh::validate`, which asserts that every primitive's box lies within its parent's
//!   decoded (quantised) box up to an absolute `1e-5` (`cwbvh/mod.rs`). At coordinates of
//!   4e4 (the arena scaled by 1e3) an `f32` ulp is 0.004, so the decoded box may miss the
//!   exact one by more than `1e-5` and the assertion panics ("Primitive 1309 does not fit
//!   in parent 24"); a debug build of `rttest compare` would abort on such a user scene.
//!   [`Obvhs::build`] therefore runs the same steps itself (PLOC, reinsertion, conversion
//!   to CWBVH with the preset's parameters) without that check, in every build.
//!   Two limits of the crate remain and show in the conformance test's reported streams:
//!   `safe_inverse` turns a direction component with `|d| <= f32::EPSILON` (zero included)
//!   into `±1 / EPSILON` (8.4e6) for the box tests, so an axis-parallel ray treats boxes
//!   whose face lies within `t * 1.2e-7` of its origin's coordinate as missed beyond that
//!   `t`; and its box tests start at `t = EPSILON`, not `tmin`, so a negative `tmin` finds
//!   no box behind the origin. A third shows on the conformance test's soup scaled by 1e-6
//!   (coordinates and hit distances of a few 1e-6): obvhs finds none of its hits, which the
//!   cause has not been traced (an absolute tolerance of its traversal, `EPSILON`-sized, is
//!   the likely one); that case runs without obvhs.
//!
//! Their hits carry the triangle and distance only: `u` and `v` are 0.

use bvh::aabb::{Aabb, Bounded};
use bvh::bounding_hierarchy::{BHShape, BoundingHierarchy};
use glam_obvhs::Vec3A;
use kdtree::triangle::{TriangleTest, WaldTriangle};
use kdtree::{Hit, Ray};
use nalgebra::{Point3, Vector3};
use obvhs::BvhBuildParams;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::ploc::PlocBuilder;
use obvhs::triangle::Triangle;
use scenes::Scene;
use trace::registry::{Binding, Entry, StructureEntry};
use trace::{Registry, SingleRays, TileCounters, Tracer};

/// Registers the two crates' structures and their single-ray methods `bvh` and `obvhs`.
pub fn register(r: &mut Registry) {
    r.add_structure(StructureEntry { name: "bvh", build: |scene| Ok(Box::new(BvhCrate::build(scene))) });
    r.add_structure(StructureEntry { name: "obvhs", build: |scene| Ok(Box::new(Obvhs::build(scene))) });
    r.add(entry("bvh", "the bvh crate (0.13): binary SAH BVH, single rays", |s, _| {
        Ok(Binding::method(SingleRays(s.get::<BvhCrate>("bvh")?)))
    }));
    r.add(entry("obvhs", "the obvhs crate (0.4): CWBVH, single rays", |s, _| {
        Ok(Binding::method(SingleRays(s.get::<Obvhs>("obvhs")?)))
    }));
}

/// A crate's entry, on its own structure of the same name: one kernel for every pass, named
/// by the entry.
fn entry(name: &'static str, summary: &'static str, bind: trace::registry::Bind) -> Entry {
    Entry::whole(name, name, summary, name, bind)
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

    /// The crate's rays for ours (it has no interval: ours is checked at the leaves): one
    /// per choice of sign of `±f32::MAX` as the reciprocal of each zero direction component
    /// (one ray when there is none, two or four otherwise; see the module documentation).
    #[inline]
    fn rays(ray: &Ray) -> impl Iterator<Item = bvh::ray::Ray<f32, 3>> {
        let (o, d) = (ray.origin, ray.dir);
        let zero = [d.x == 0.0, d.y == 0.0, d.z == 0.0];
        let k = zero.iter().filter(|&&z| z).count();
        (0..1u32 << k).map(move |signs| {
            let mut bit = 0;
            let mut inv = |c: f32, zero: bool| {
                if !zero {
                    return 1.0 / c;
                }
                let negative = signs >> bit & 1 == 1;
                bit += 1;
                if negative { -f32::MAX } else { f32::MAX }
            };
            let inv_direction = Vector3::new(inv(d.x, zero[0]), inv(d.y, zero[1]), inv(d.z, zero[2]));
            bvh::ray::Ray { origin: Point3::new(o.x, o.y, o.z), direction: Vector3::new(d.x, d.y, d.z), inv_direction }
        })
    }
}

impl Tracer for BvhCrate {
    fn intersect_counted<C: TileCounters>(&self, ray: &Ray, _: &mut C) -> Option<Hit> {
        let data = WaldTriangle::prepare(ray);
        let mut best = None;
        let mut t_max = ray.t_max;
        for query in Self::rays(ray) {
            for shape in self.bvh.traverse_iterator(&query, &self.shapes) {
                if let Some((t, u, v)) = self.records[shape.prim as usize].intersect(ray, &data, t_max)
                    && best.is_none_or(|b: Hit| t < b.t || (t == b.t && shape.prim < b.prim))
                {
                    best = Some(Hit { t, u, v, prim: shape.prim });
                    t_max = t;
                }
            }
        }
        best
    }

    fn occluded_counted<C: TileCounters>(&self, ray: &Ray, _: &mut C) -> bool {
        let data = WaldTriangle::prepare(ray);
        Self::rays(ray).any(|query| {
            self.bvh
                .traverse_iterator(&query, &self.shapes)
                .any(|shape| self.records[shape.prim as usize].intersect(ray, &data, ray.t_max).is_some())
        })
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
        // `build_cwbvh_from_tris`'s steps for a build without pre-splits (the medium preset
        // has none), but without its `#[cfg(debug_assertions)]` `CwBvh::validate`, which
        // panics in debug builds on scenes at large coordinates (see the module docs).
        let config = BvhBuildParams::medium_build();
        debug_assert!(!config.pre_split);
        let mut bvh2 = PlocBuilder::with_capacity(tris.len()).build(
            config.ploc_search_distance,
            &tris,
            (0..tris.len() as u32).collect(),
            config.sort_precision,
            config.search_depth_threshold,
        );
        ReinsertionOptimizer::default().run(&mut bvh2, config.reinsertion_batch_ratio, None);
        let bvh = bvh2_to_cwbvh(&bvh2, config.max_prims_per_leaf.clamp(1, 3), true, false);
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

    /// A ray in the plane of a box face (`z = 0`, direction `z` zero) hits the foot of a wall
    /// standing on that plane: the crate's own `Ray::new` loses the box (`0 * inf = NaN`),
    /// our adapter's ray does not, and gives our tree's hit.
    #[test]
    fn zero_direction_components_in_a_box_face() {
        let wall = [glam::Vec3::new(1.0, -1.0, 0.0), glam::Vec3::new(1.0, 1.0, 0.0), glam::Vec3::new(1.0, 0.0, 1.0)];
        let floor = [glam::Vec3::new(2.0, -1.0, 0.0), glam::Vec3::new(3.0, -1.0, 0.0), glam::Vec3::new(2.0, 1.0, 0.0)];
        let scene = conformance::soup_scene("wall", &[wall, floor]);
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let b = BvhCrate::build(&scene);
        for dir in [glam::Vec3::new(1.0, 0.0, 0.0), glam::Vec3::new(1.0, 0.0, -0.0), glam::Vec3::new(1.0, 0.25, 0.0)] {
            let ray = Ray::new(glam::Vec3::new(-1.0, 0.2, 0.0), dir, 0.0, f32::INFINITY);
            let want = tree.intersect(&ray).expect("the wall's foot");
            assert_eq!(want.prim, 0);
            assert_eq!(b.intersect(&ray).map(|h| (h.prim, h.t)), Some((0, want.t)), "{dir}");
            assert!(b.occluded(&ray));
            let theirs = bvh::ray::Ray::new(Point3::new(-1.0, 0.2, 0.0), Vector3::new(dir.x, dir.y, dir.z));
            assert_eq!(b.bvh.traverse_iterator(&theirs, &b.shapes).count(), 0, "the crate's bug is gone: {dir}");
        }
    }

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
