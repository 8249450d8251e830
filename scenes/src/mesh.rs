//! Triangle meshes: positions, u32 triangle indices, optional vertex normals and per-triangle
//! materials.

use glam::Vec3;

/// A surface material: only what the scenes use.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name (from the OBJ `usemtl` or the built-in scene).
    pub name: String,
    /// Diffuse reflectance (linear RGB, each in [0, 1]).
    pub diffuse: Vec3,
}

impl Default for Material {
    fn default() -> Self {
        Material { name: "default".into(), diffuse: Vec3::splat(0.75) }
    }
}

/// An indexed triangle mesh in world space.
///
/// Invariants (checked by [`Mesh::check`]): every index is below `positions.len()`, every
/// position is finite, `material_ids` and `prim_ids` have one entry per triangle, every
/// material id is below `materials.len()`, and `normals`, when present, has one entry per
/// position.
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

    /// Checks the invariants listed on [`Mesh`], naming the first violation.
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
        if let Some(normals) = &self.normals {
            if normals.len() != self.positions.len() {
                return Err(format!("{} normals for {} positions", normals.len(), self.positions.len()));
            }
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&i) = tri.iter().find(|&&i| i as usize >= self.positions.len()) {
                return Err(format!("triangle {t} uses vertex {i} of {}", self.positions.len()));
            }
        }
        if let Some(t) = self.material_ids.iter().position(|&m| m as usize >= self.materials.len()) {
            return Err(format!("triangle {t} uses material {} of {}", self.material_ids[t], self.materials.len()));
        }
        Ok(())
    }

    /// The unit geometric normal of triangle `i` (`(b - a) x (c - a)`, normalised), or zero
    /// for a degenerate triangle.
    pub fn geometric_normal(&self, i: usize) -> Vec3 {
        let [a, b, c] = self.triangle(i);
        (b - a).cross(c - a).normalize_or_zero()
    }
}
