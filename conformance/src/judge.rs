//! The comparisons: whether a method's answer stands for its reference's under a [`Rule`]
//! (the same hit, a tie, a rounding artefact the oracle accepts, a loose difference).

use std::cell::OnceCell;

use glam::Vec3;
use kdtree::{BruteForce, Hit, KdTree, Ray};
use trace::ties::{coplanar, near_shared};

use crate::plan::Rule;
use crate::report::Outcome;

/// Whether `hit` lies on an edge of its triangle: a barycentric within 1e-6 of 0 (a ray
/// grazing the edge; which side it falls on is the triangle test's rounding).
pub(crate) fn on_edge(hit: Hit) -> bool {
    hit.u.min(hit.v).min(1.0 - hit.u - hit.v) <= 1e-6
}

/// Whether the point `p` lies within `tol` of an edge of `tri`.
fn near_edge(tri: &[Vec3; 3], p: Vec3, tol: f32) -> bool {
    (0..3).any(|k| {
        let (v, w) = (tri[k], tri[(k + 1) % 3]);
        let e = w - v;
        let s = ((p - v).dot(e) / e.length_squared().max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
        (p - (v + s * e)).length() <= tol
    })
}

/// The oracle of one tree, built on first use.
pub(crate) struct Judge<'a> {
    pub(crate) tree: &'a KdTree,
    pub(crate) oracle: OnceCell<BruteForce>,
}

impl Judge<'_> {
    fn oracle(&self) -> &BruteForce {
        self.oracle.get_or_init(|| BruteForce::for_tree(self.tree))
    }

    pub(crate) fn hit(&self, rule: Rule, ray: &Ray, got: Option<Hit>, want: Option<Hit>) -> Outcome {
        if got == want {
            return Outcome::Same;
        }
        if rule == Rule::Ties {
            // A grazing ray: the reference's hit on an edge of its triangle (a barycentric
            // within 1e-6 of 0), which the other kernel rounds out, seeing what lies behind.
            let grazing = |h: Hit| on_edge(h) || self.grazes(ray, h);
            // A hit at the origin's rounding (within 64 ulps of its coordinates, the oracle's
            // window): a ray starting on a surface may or may not see it.
            let window = 64.0 * f32::EPSILON * ray.origin.abs().max_element() / ray.dir.length();
            let at_origin = |h: Hit| h.t.abs() <= window;
            return match (got, want) {
                (g, Some(w)) if at_origin(w) && g.is_none_or(|g| g.t > w.t) => Outcome::Tie,
                (Some(g), w) if at_origin(g) && w.is_none_or(|w| w.t > g.t) => Outcome::Tie,
                (Some(g), Some(w)) if self.edge_tie(ray, g, w) => Outcome::Tie,
                (g, Some(w)) if grazing(w) && g.is_none_or(|g| g.t > w.t) => Outcome::Tie,
                (Some(g), w) if grazing(g) && w.is_none_or(|w| w.t > g.t) => Outcome::Tie,
                _ => Outcome::Refused,
            };
        }
        if rule == Rule::Loose {
            return match (got, want) {
                // The same triangle: its distance rounded another way (far from the origin an
                // ulp of the coordinates is more than 1e-4 of the distance).
                (Some(g), Some(w)) if g.prim == w.prim || (g.t - w.t).abs() <= 1e-4 * g.t.abs().max(w.t.abs()) => {
                    Outcome::Tie
                }
                // A ray lying in the plane of a hit triangle: a measure-zero case each
                // triangle test answers its own way (ARCHITECTURE: rays in a face plane).
                (g, w) if g.is_some_and(|g| self.in_plane(ray, g)) || w.is_some_and(|w| self.in_plane(ray, w)) => {
                    Outcome::Tie
                }
                // Everything a tie of the same tracer's kernels is: edge neighbours,
                // coincident faces, and grazing rays (a hit exactly on an edge).
                (g, w) if self.hit(Rule::Ties, ray, g, w) == Outcome::Tie => Outcome::Tie,
                _ => Outcome::Loose,
            };
        }
        if let (Some(g), Some(w)) = (got, want)
            && g.t == w.t
            && self.tests_hit(ray, g)
        {
            return Outcome::Tie;
        }
        if rule == Rule::Equivalent && self.oracle().equivalent_hits(ray, got, want) {
            return Outcome::Artefact;
        }
        Outcome::Refused
    }

    /// Whether `got` and `want` are a tie of [`Rule::Ties`]: within 1e-4 of the distance, on
    /// triangles sharing a vertex or an edge with `want`'s point within 1e-4 of the
    /// triangles' size from it, or on coplanar triangles that both hold both points.
    fn edge_tie(&self, ray: &Ray, got: Hit, want: Hit) -> bool {
        let n = self.tree.triangle_count();
        if got.prim as usize >= n
            || want.prim as usize >= n
            || (got.t - want.t).abs() > 1e-4 * got.t.abs().max(want.t.abs())
        {
            return false;
        }
        let (a, b) = (self.tree.triangle(want.prim), self.tree.triangle(got.prim));
        let p = ray.at(want.t);
        let shared: Vec<Vec3> = a.iter().copied().filter(|v| b.contains(v)).collect();
        let size = a.iter().chain(&b).fold(0.0f32, |m, v| m.max((*v - a[0]).length()));
        // 1e-4 of the size, plus a few ulps of the coordinates (far from the origin an ulp
        // of the positions is more than 1e-4 of a triangle).
        let far = a.iter().chain(&b).fold(p.abs().max_element(), |m, v| m.max(v.abs().max_element()));
        let tol = 1e-4 * size.max(f32::MIN_POSITIVE) + 8.0 * f32::EPSILON * far;
        let at_edge = near_shared(&shared, p, tol);
        // Coincident faces: coplanar, and the point lies in both (within 1e-4).
        let slack = (tol / size.max(f32::MIN_POSITIVE)) as f64;
        at_edge || coplanar(&a, &b) && contains(&b, p, slack) && contains(&a, ray.at(got.t), slack)
    }

    /// Whether `hit`'s point lies within a few ulps of the coordinates of an edge of its
    /// triangle: grazing at the precision of the scene (far from the origin an ulp of the
    /// positions is a sizeable barycentric).
    fn grazes(&self, ray: &Ray, hit: Hit) -> bool {
        if hit.prim as usize >= self.tree.triangle_count() {
            return false;
        }
        let tri = self.tree.triangle(hit.prim);
        let p = ray.at(hit.t);
        let far = tri.iter().fold(p.abs().max_element(), |m, v| m.max(v.abs().max_element()));
        near_edge(&tri, p, 8.0 * f32::EPSILON * far)
    }

    /// Whether `ray` lies in the plane of `hit`'s triangle: its origin within a few ulps of
    /// the coordinates from the plane and its direction parallel to it within 1e-5 rad.
    fn in_plane(&self, ray: &Ray, hit: Hit) -> bool {
        if hit.prim as usize >= self.tree.triangle_count() {
            return false;
        }
        let [a, b, c] = self.tree.triangle(hit.prim).map(|v| v.as_dvec3());
        let Some(n) = (b - a).cross(c - a).try_normalize() else { return false };
        let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
        let far = [a, b, c, o].iter().fold(0.0f64, |m, v| m.max(v.abs().max_element()));
        let d_len = d.length();
        d_len > 0.0 && n.dot(o - a).abs() <= 16.0 * f64::from(f32::EPSILON) * far && n.dot(d).abs() <= 1e-5 * d_len
    }

    /// Whether the tree's triangle test hits `hit.prim` at exactly `hit.t` (a one-triangle
    /// oracle: a tie must be a hit of the test, not any triangle at that distance).
    fn tests_hit(&self, ray: &Ray, hit: Hit) -> bool {
        if hit.prim as usize >= self.tree.triangle_count() {
            return false;
        }
        BruteForce::new(&[self.tree.triangle(hit.prim)], self.tree.intersector())
            .all_hits(ray)
            .first()
            .is_some_and(|h| h.0 == hit.t)
    }

    pub(crate) fn occlusion(&self, rule: Rule, ray: &Ray, got: bool, want: bool) -> Outcome {
        match rule {
            _ if got == want => Outcome::Same,
            // Grazing rays (see `Rule::Ties`) flip any-hit answers too: counted, capped.
            Rule::Loose | Rule::Ties => Outcome::Loose,
            Rule::Equivalent if self.oracle().equivalent_occlusion(ray, got, want) => Outcome::Artefact,
            _ => Outcome::Refused,
        }
    }

    /// Blocked counts of one point's 16 rays: the same, or (equivalent) no further apart
    /// than the rays whose occlusion is a rounding artefact.
    pub(crate) fn soft(&self, rule: Rule, rays: &[Ray], got: u32, want: u32) -> Outcome {
        match rule {
            _ if got == want => Outcome::Same,
            Rule::Loose | Rule::Ties => Outcome::Loose,
            Rule::Equivalent => {
                let ambiguous = rays.iter().filter(|r| self.oracle().equivalent_occlusion(r, true, false)).count();
                if got.abs_diff(want) as usize <= ambiguous { Outcome::Artefact } else { Outcome::Refused }
            }
            Rule::Exact => Outcome::Refused,
        }
    }
}

/// Whether `p` (near the triangle's plane) lies in triangle `t`, barycentrics within `eps`
/// of `[0, 1]` (in `f64`).
fn contains(t: &[Vec3; 3], p: Vec3, eps: f64) -> bool {
    let [a, b, c] = t.map(|v| v.as_dvec3());
    let (e1, e2, q) = (b - a, c - a, p.as_dvec3() - a);
    let (d11, d12, d22, q1, q2) = (e1.dot(e1), e1.dot(e2), e2.dot(e2), q.dot(e1), q.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if det <= 0.0 {
        return false;
    }
    let (u, v) = ((d22 * q1 - d12 * q2) / det, (d11 * q2 - d12 * q1) / det);
    u >= -eps && v >= -eps && u + v <= 1.0 + eps
}

#[cfg(test)]
mod tests {
    use kdtree::{BuildConfig, NoCounters};

    use super::*;
    use crate::cases::soup_scene;

    #[test]
    fn ties_are_told_from_other_hits() {
        // Two coincident triangles (a tie) and one behind them.
        let z = |z: f32| [Vec3::new(0.0, 0.0, z), Vec3::new(1.0, 0.0, z), Vec3::new(0.0, 1.0, z)];
        let scene = soup_scene("ties", &[z(1.0), z(1.0), z(2.0)]);
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let judge = Judge { tree: &tree, oracle: OnceCell::new() };
        let ray = Ray::new(Vec3::new(0.2, 0.2, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        let first = tree.intersect(&ray).unwrap();
        let twin = Hit { prim: 1 - first.prim, ..first };
        let far = Hit { t: 2.0, prim: 2, ..first };
        assert_eq!(judge.hit(Rule::Exact, &ray, Some(first), Some(first)), Outcome::Same);
        assert_eq!(judge.hit(Rule::Exact, &ray, Some(twin), Some(first)), Outcome::Tie);
        assert_eq!(judge.hit(Rule::Exact, &ray, Some(far), Some(first)), Outcome::Refused);
        assert_eq!(judge.hit(Rule::Equivalent, &ray, None, Some(first)), Outcome::Refused);
        assert_eq!(judge.hit(Rule::Loose, &ray, Some(far), Some(first)), Outcome::Loose);
        // A tie must be a hit of the test at that distance, not any triangle.
        assert_eq!(judge.hit(Rule::Exact, &ray, Some(Hit { prim: 2, ..first }), Some(first)), Outcome::Refused);
        assert_eq!(judge.occlusion(Rule::Exact, &ray, false, true), Outcome::Refused);
        assert_eq!(judge.occlusion(Rule::Ties, &ray, false, true), Outcome::Loose);
        let _ = NoCounters;
    }

    #[test]
    fn edge_ties_are_told_from_other_hits() {
        // A unit quad of two triangles sharing the edge (1, 0, 1)-(0, 1, 1), and a far one.
        let (a, b, c, d) = (Vec3::new(0.0, 0.0, 1.0), Vec3::X + Vec3::Z, Vec3::Y + Vec3::Z, Vec3::ONE);
        let far = [Vec3::new(0.0, 0.0, 3.0), Vec3::new(1.0, 0.0, 3.0), Vec3::new(0.0, 1.0, 3.0)];
        let scene = soup_scene("edge", &[[a, b, c], [b, d, c], far]);
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let judge = Judge { tree: &tree, oracle: OnceCell::new() };
        let hit = |t: f32, prim: u32| Hit { t, u: 0.25, v: 0.25, prim };
        let on_edge = Ray::new(Vec3::new(0.5, 0.5, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        let inside = Ray::new(Vec3::new(0.2, 0.2, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        let ulp = f32::from_bits(1.0f32.to_bits() + 1);
        let (w, g) = (hit(1.0, 0), hit(ulp, 1));
        assert_eq!(judge.hit(Rule::Ties, &on_edge, Some(g), Some(w)), Outcome::Tie);
        assert_eq!(judge.hit(Rule::Ties, &on_edge, Some(w), Some(w)), Outcome::Same);
        // Off the shared edge, at another distance, a triangle sharing nothing, or a miss.
        assert_eq!(judge.hit(Rule::Ties, &inside, Some(g), Some(w)), Outcome::Refused);
        // 7e-5 off the edge: an edge tie still (1e-4 of the size), no longer grazing (a few
        // ulps), so a farther hit or a miss is refused.
        let near_edge = Ray::new(Vec3::new(0.49995, 0.49995, 0.0), Vec3::Z, 0.0, f32::INFINITY);
        assert_eq!(judge.hit(Rule::Ties, &near_edge, Some(g), Some(w)), Outcome::Tie);
        assert_eq!(judge.hit(Rule::Ties, &near_edge, Some(hit(1.01, 1)), Some(w)), Outcome::Refused);
        assert_eq!(judge.hit(Rule::Ties, &near_edge, Some(hit(1.0, 2)), Some(w)), Outcome::Refused);
        assert_eq!(judge.hit(Rule::Ties, &near_edge, None, Some(w)), Outcome::Refused);
        // Within the origin's rounding (a ray starting on a surface): a farther hit or a miss
        // ties; just outside the window it does not.
        let at_origin = Hit { t: 1e-7, ..w };
        assert_eq!(judge.hit(Rule::Ties, &inside, Some(hit(1.0, 1)), Some(at_origin)), Outcome::Tie);
        assert_eq!(judge.hit(Rule::Ties, &inside, None, Some(at_origin)), Outcome::Tie);
        assert_eq!(judge.hit(Rule::Ties, &inside, None, Some(Hit { t: 1e-4, ..w })), Outcome::Refused);
        // Exactly through the edge: a farther hit or a miss is the other side of the edge.
        assert_eq!(judge.hit(Rule::Ties, &on_edge, Some(hit(1.01, 1)), Some(w)), Outcome::Tie);
        assert_eq!(judge.hit(Rule::Ties, &on_edge, None, Some(w)), Outcome::Tie);
        // A hit on an edge of its triangle may be rounded out: a miss or a farther hit.
        let graze = Hit { u: 0.5, v: 0.5, ..w };
        assert_eq!(judge.hit(Rule::Ties, &on_edge, None, Some(graze)), Outcome::Tie);
        assert_eq!(judge.hit(Rule::Ties, &on_edge, Some(hit(3.0, 2)), Some(graze)), Outcome::Tie);
        assert_eq!(judge.hit(Rule::Ties, &on_edge, Some(hit(0.5, 2)), Some(graze)), Outcome::Refused);
        assert_eq!(judge.hit(Rule::Ties, &on_edge, Some(graze), None), Outcome::Tie);
        assert_eq!(judge.hit(Rule::Ties, &on_edge, Some(graze), Some(hit(0.5, 2))), Outcome::Refused);
        // Coincident faces tie anywhere (the first test's pair).
        let z = |z: f32| [Vec3::new(0.0, 0.0, z), Vec3::new(1.0, 0.0, z), Vec3::new(0.0, 1.0, z)];
        let scene = soup_scene("ties", &[z(1.0), z(1.0), z(2.0)]);
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let judge = Judge { tree: &tree, oracle: OnceCell::new() };
        assert_eq!(judge.hit(Rule::Ties, &inside, Some(hit(1.0, 1)), Some(hit(1.0, 0))), Outcome::Tie);
        assert_eq!(judge.hit(Rule::Ties, &inside, Some(hit(1.0, 2)), Some(hit(1.0, 0))), Outcome::Refused);
    }
}
