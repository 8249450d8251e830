//! Triangle meshes: positions, u32 triangle indices, optional vertex normals and per-triangle
//! materials.

use glam::Vec3;

pub use crate::material::Material;

/// An indexed triangle mesh in world space.
///
/// Invariants (checked by [`Mesh::check`]): every index is below `positions.len()`, every
/// position is finite, `material_ids` and `prim_ids` have one entry per triangle, every
/// material id is below `materials.len()`, every material passes [`Material::check`], and `normals`, when present, has one entry per
/// position. The other methods assume them: on a mesh with a NaN or infinite position they
/// return non-finite values (bounds, normals) but never panic.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as three indices into `positions`, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
    /// Optional per-vertex shading normals (one per position).
    pub normals: Option<Vec<Vec3>>,
    /// Per-triangle index into `materials`.
    pub material_ids: Vec<u32>,
    /// The materials.
    pub materials: Vec<Material>,
    /// Per-triangle primitive id: the triangle's number in the source file's face order after
    /// fan triangulation, counting the degenerate triangles that the loader dropped, so that
    /// any other tracer loading the same file numbers the triangles the same way. For built-in
    /// scenes it is the triangle's index.
    pub prim_ids: Vec<u32>,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The three vertex positions of triangle `i`.
    #[inline]
    pub fn triangle(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[i];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    /// The axis-aligned bounds `(min, max)` of all positions referenced by triangles, or
    /// `None` for a mesh without triangles.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.triangles.iter().flatten().map(|&i| self.positions[i as usize]);
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    /// Checks the invariants listed on [`Mesh`], naming the first violation: a NaN or
    /// infinite position is an error naming the vertex (`vertex 7 is not finite: ...`).
    pub fn check(&self) -> Result<(), String> {
        let n = self.triangles.len();
        if self.material_ids.len() != n || self.prim_ids.len() != n {
            return Err(format!(
                "{} triangles but {} material ids and {} primitive ids",
                n,
                self.material_ids.len(),
                self.prim_ids.len()
            ));
        }
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(format!("vertex {i} is not finite: {}", self.positions[i]));
        }
        if let Some(normals) = &self.normals
            && normals.len() != self.positions.len()
        {
            return Err(format!("{} normals for {} positions", normals.len(), self.positions.len()));
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&i) = tri.iter().find(|&&i| i as usize >= self.positions.len()) {
                return Err(format!("triangle {t} uses vertex {i} of {}", self.positions.len()));
            }
        }
        if let Some(t) = self.material_ids.iter().position(|&m| m as usize >= self.materials.len()) {
            return Err(format!("triangle {t} uses material {} of {}", self.material_ids[t], self.materials.len()));
        }
        for m in &self.materials {
            m.check()?;
        }
        Ok(())
    }

    /// The unit geometric normal of triangle `i` (`(b - a) x (c - a)`, normalised), or zero
    /// for a degenerate triangle or one with a NaN or infinite vertex.
    pub fn geometric_normal(&self, i: usize) -> Vec3 {
        let [a, b, c] = self.triangle(i);
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// A mesh with exactly twice the triangles: each triangle is split at the midpoint of its
    /// longest edge into two, in the same winding, with the same material; triangle `i`
    /// becomes triangles `2i` and `2i + 1`, and `prim_ids` are renumbered `0..2n`.
    ///
    /// Used to make a scene at 2, 4, 8, ... times its triangle count with the same shape, to
    /// measure how build time scales with the number of triangles (thesis 3.3). Two triangles
    /// that split the same edge share its midpoint; a neighbour that splits another edge is
    /// left with a T-junction, so the result need not be closed. Shading normals, when present,
    /// are carried (the midpoint's normal is the normalised mean of the edge's two).
    pub fn split_longest_edges(&self) -> Mesh {
        let mut positions = self.positions.clone();
        let mut normals = self.normals.clone();
        let mut midpoints: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
        let mut triangles = Vec::with_capacity(2 * self.triangles.len());
        for &[a, b, c] in &self.triangles {
            let (pa, pb, pc) = (self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]);
            let lengths = [pa.distance_squared(pb), pb.distance_squared(pc), pc.distance_squared(pa)];
            // Rotate the corners so that the longest edge is (p, q), with r opposite it.
            let [p, q, r] = if lengths[0] >= lengths[1] && lengths[0] >= lengths[2] {
                [a, b, c]
            } else if lengths[1] >= lengths[2] {
                [b, c, a]
            } else {
                [c, a, b]
            };
            let m = *midpoints.entry((p.min(q), p.max(q))).or_insert_with(|| {
                positions.push(0.5 * (self.positions[p as usize] + self.positions[q as usize]));
                if let Some(n) = normals.as_mut() {
                    let mid = (n[p as usize] + n[q as usize]).normalize_or_zero();
                    n.push(mid);
                }
                positions.len() as u32 - 1
            });
            triangles.push([p, m, r]);
            triangles.push([m, q, r]);
        }
        Mesh {
            positions,
            triangles,
            normals,
            material_ids: self.material_ids.iter().flat_map(|&m| [m, m]).collect(),
            materials: self.materials.clone(),
            prim_ids: (0..2 * self.triangles.len() as u32).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_triangles() -> Mesh {
        Mesh {
            positions: vec![Vec3::ZERO, Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(4.0, 1.0, 0.0)],
            triangles: vec![[0, 1, 2], [1, 3, 2]],
            normals: Some(vec![Vec3::Z; 4]),
            material_ids: vec![0, 1],
            materials: vec![Material::default(), Material::diffuse("b", Vec3::X)],
            prim_ids: vec![7, 9],
        }
    }

    #[test]
    fn split_doubles_triangles_and_keeps_area_winding_and_materials() {
        let mesh = two_triangles();
        let split = mesh.split_longest_edges();
        split.check().unwrap();
        assert_eq!(split.triangle_count(), 4);
        assert_eq!(split.prim_ids, vec![0, 1, 2, 3]);
        assert_eq!(split.material_ids, vec![0, 0, 1, 1]);
        // Both triangles split their shared diagonal (1, 2), so they share its midpoint.
        assert_eq!(split.positions.len(), 5);
        assert_eq!(split.positions[4], Vec3::new(2.0, 0.5, 0.0));
        let area = |m: &Mesh, i: usize| {
            let [a, b, c] = m.triangle(i);
            0.5 * (b - a).cross(c - a)
        };
        for t in 0..2 {
            assert_eq!(area(&split, 2 * t) + area(&split, 2 * t + 1), area(&mesh, t));
            assert_eq!(split.geometric_normal(2 * t), mesh.geometric_normal(t));
        }
        assert_eq!(split.normals.as_ref().map(Vec::len), Some(5));
    }

    #[test]
    fn check_names_non_finite_vertices() {
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let mut mesh = two_triangles();
            mesh.positions[3].y = bad;
            let e = mesh.check().unwrap_err();
            assert!(e.contains("vertex 3 is not finite"), "{e}");
            // Other methods do not panic; the normal of a non-finite triangle is zero.
            assert_eq!(mesh.geometric_normal(1), Vec3::ZERO);
            assert_eq!(mesh.geometric_normal(0), Vec3::Z);
            assert!(mesh.bounds().is_some());
            assert_eq!(mesh.split_longest_edges().triangle_count(), 4);
        }
    }

    #[test]
    fn repeated_splits_scale_exactly() {
        let mut mesh = two_triangles();
        for k in 1..=4 {
            mesh = mesh.split_longest_edges();
            assert_eq!(mesh.triangle_count(), 2 << k);
            mesh.check().unwrap();
        }
    }
}
