//! Closed primitives for the built-in scenes and the builder that assembles them into a mesh.
//!
//! Every [`Part`] is a closed, consistently wound surface with shared vertices: each undirected
//! edge is used by exactly two triangles and the normals `(b - a) x (c - a)` point outwards.
//! The edge-width soft shadows of the later chapters need such closed meshes (silhouette edges
//! are found from the two triangles beside each edge). Parts are added to a [`MeshBuilder`]
//! with their own vertices, so a whole built-in scene passes the same edge check.
//!
//! The constructors do not check their numbers (the built-in scenes pass constants): a NaN or
//! infinite parameter gives non-finite positions, never a panic, and [`Mesh::check`] and
//! `KdTree::build` reject the mesh naming the vertex.

use std::collections::HashMap;

use glam::{Affine3A, Vec2, Vec3};

use crate::{Material, Mesh};

/// One cross-section placement of a [`Part::sweep`]: section point `(s, t)` goes to
/// `origin + s * u + t * v`. The path must advance along `u x v`.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Where the section's origin goes.
    pub origin: Vec3,
    /// Image of the section's first axis (its length scales the section).
    pub u: Vec3,
    /// Image of the section's second axis (its length scales the section).
    pub v: Vec3,
}

impl Frame {
    /// A frame at `origin` whose path direction is `forward`, with `v` the part of `reference`
    /// perpendicular to `forward` (so `reference` must not be parallel to `forward`), scaled by
    /// `scale` along `u` and `v`.
    pub fn oriented(origin: Vec3, forward: Vec3, reference: Vec3, scale: Vec2) -> Frame {
        let f = forward.normalize();
        let v = (reference - f * reference.dot(f)).normalize();
        let u = v.cross(f);
        Frame { origin, u: u * scale.x, v: v * scale.y }
    }
}

/// A closed triangle surface in its own coordinates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Part {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

impl Part {
    /// Sweeps the convex counter-clockwise polygon `section` through `frames` (at least two),
    /// closing both ends with caps: a tube with `section.len() * (frames.len() - 1) * 2` side
    /// triangles. Caps are fans from the first corner for triangles and quads, else fans
    /// around an added centre vertex.
    pub fn sweep(section: &[Vec2], frames: &[Frame]) -> Part {
        let n = section.len() as u32;
        assert!(n >= 3 && frames.len() >= 2, "a sweep needs a polygon and two frames");
        let mut part = Part::default();
        for f in frames {
            part.positions.extend(section.iter().map(|s| f.origin + s.x * f.u + s.y * f.v));
        }
        for k in 0..frames.len() as u32 - 1 {
            for j in 0..n {
                let (a, b) = (k * n + j, k * n + (j + 1) % n);
                let (c, d) = (b + n, a + n);
                part.triangles.push([a, b, c]);
                part.triangles.push([a, c, d]);
            }
        }
        let last = (frames.len() as u32 - 1) * n;
        // The start cap faces backwards (reversed fan), the end cap forwards.
        part.cap(0, n, true);
        part.cap(last, n, false);
        part
    }

    /// Closes the ring of `n` vertices starting at `first`.
    fn cap(&mut self, first: u32, n: u32, reversed: bool) {
        let mut push = |t: [u32; 3]| self.triangles.push(if reversed { [t[0], t[2], t[1]] } else { t });
        if n <= 4 {
            for j in 1..n - 1 {
                push([first, first + j, first + j + 1]);
            }
        } else {
            let ring = &self.positions[first as usize..(first + n) as usize];
            let centre = ring.iter().copied().sum::<Vec3>() / n as f32;
            let c = self.positions.len() as u32;
            self.positions.push(centre);
            for j in 0..n {
                self.triangles.push(if reversed {
                    [c, first + (j + 1) % n, first + j]
                } else {
                    [c, first + j, first + (j + 1) % n]
                });
            }
        }
    }

    /// The axis-aligned box `[min, max]` (12 triangles).
    pub fn cuboid(min: Vec3, max: Vec3) -> Part {
        let h = 0.5 * (max - min);
        let c = 0.5 * (min + max);
        let section = [Vec2::new(-h.x, -h.y), Vec2::new(h.x, -h.y), Vec2::new(h.x, h.y), Vec2::new(-h.x, h.y)];
        let frame = |z: f32| Frame { origin: Vec3::new(c.x, c.y, z), u: Vec3::X, v: Vec3::Y };
        Part::sweep(&section, &[frame(min.z), frame(max.z)])
    }

    /// A regular `segments`-gon of radius 1 (counter-clockwise).
    pub fn circle(segments: u32) -> Vec<Vec2> {
        (0..segments)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / segments as f32;
                Vec2::new(a.cos(), a.sin())
            })
            .collect()
    }

    /// A vertical prism or frustum: a `segments`-gon of radius `r0` at height `y0` to radius
    /// `r1` at `y1 > y0`, centred on the Y axis, with `rings` bands of side triangles and
    /// capped ends: `segments * (2 * rings + 2)` triangles.
    pub fn prism(r0: f32, r1: f32, y0: f32, y1: f32, segments: u32, rings: u32) -> Part {
        let rings = rings.max(1);
        let frames: Vec<Frame> = (0..=rings)
            .map(|k| {
                let t = k as f32 / rings as f32;
                let r = r0 + (r1 - r0) * t;
                Frame::oriented(Vec3::new(0.0, y0 + (y1 - y0) * t, 0.0), Vec3::Y, Vec3::Z, Vec2::splat(r))
            })
            .collect();
        Part::sweep(&Part::circle(segments), &frames)
    }

    /// A wedge (ramp): the right triangle with legs `length` along +X and `height` along +Y,
    /// extruded over `[z0, z1]` (8 triangles).
    pub fn wedge(length: f32, height: f32, z0: f32, z1: f32) -> Part {
        let section = [Vec2::ZERO, Vec2::new(length, 0.0), Vec2::new(0.0, height)];
        let frame = |z: f32| Frame { origin: Vec3::new(0.0, 0.0, z), u: Vec3::X, v: Vec3::Y };
        Part::sweep(&section, &[frame(z0), frame(z1)])
    }

    /// A geodesic sphere of radius `radius` around the origin: an icosahedron whose faces are
    /// split `subdivisions` times (20 * 4^subdivisions triangles, shared vertices).
    pub fn icosphere(radius: f32, subdivisions: u32) -> Part {
        let t = (1.0 + 5.0f32.sqrt()) / 2.0;
        let mut positions: Vec<Vec3> = [
            (-1.0, t, 0.0),
            (1.0, t, 0.0),
            (-1.0, -t, 0.0),
            (1.0, -t, 0.0),
            (0.0, -1.0, t),
            (0.0, 1.0, t),
            (0.0, -1.0, -t),
            (0.0, 1.0, -t),
            (t, 0.0, -1.0),
            (t, 0.0, 1.0),
            (-t, 0.0, -1.0),
            (-t, 0.0, 1.0),
        ]
        .iter()
        .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
        .collect();
        let mut triangles: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..subdivisions {
            let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
            let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
                *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    positions.push((positions[a as usize] + positions[b as usize]).normalize());
                    positions.len() as u32 - 1
                })
            };
            let mut next = Vec::with_capacity(triangles.len() * 4);
            for [a, b, c] in triangles {
                let ab = midpoint(a, b, &mut positions);
                let bc = midpoint(b, c, &mut positions);
                let ca = midpoint(c, a, &mut positions);
                next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
            }
            triangles = next;
        }
        Part { positions: positions.into_iter().map(|p| p * radius).collect(), triangles }
    }

    /// A superellipsoid (Barr 1981) with semi-axes `radii`, centred on the origin, Y up: the
    /// point at latitude `v` and longitude `u` is `(rx C(v, e_v) C(u, e_h), ry S(v, e_v),
    /// rz C(v, e_v) S(u, e_h))` with `C(w, e) = sign(cos w) |cos w|^e` (and `S` with `sin`).
    /// Exponents of 1 give an ellipsoid, smaller ones a rounded box (`e_v` shapes the vertical
    /// profile, `e_h` the plan). `segments` (at least 3) vertices around each of `rings - 1`
    /// rings (`rings` at least 2) between two poles: `2 * segments * (rings - 1)` triangles.
    pub fn superellipsoid(radii: Vec3, e_v: f32, e_h: f32, segments: u32, rings: u32) -> Part {
        let (segments, rings) = (segments.max(3), rings.max(2));
        let power = |c: f32, e: f32| c.signum() * c.abs().powf(e);
        let mut part = Part::default();
        part.positions.push(Vec3::new(0.0, -radii.y, 0.0));
        for k in 1..rings {
            let v = -std::f32::consts::FRAC_PI_2 + std::f32::consts::PI * k as f32 / rings as f32;
            let (cv, sv) = (power(v.cos(), e_v), power(v.sin(), e_v));
            for j in 0..segments {
                let u = std::f32::consts::TAU * j as f32 / segments as f32;
                let (cu, su) = (power(u.cos(), e_h), power(u.sin(), e_h));
                part.positions.push(radii * Vec3::new(cv * cu, sv, cv * su));
            }
        }
        part.positions.push(Vec3::new(0.0, radii.y, 0.0));
        let north = part.positions.len() as u32 - 1;
        let at = |k: u32, j: u32| 1 + (k - 1) * segments + j % segments;
        for j in 0..segments {
            part.triangles.push([0, at(1, j), at(1, j + 1)]);
        }
        for k in 1..rings - 1 {
            for j in 0..segments {
                let (a, b, c, d) = (at(k, j), at(k, j + 1), at(k + 1, j + 1), at(k + 1, j));
                part.triangles.push([a, d, c]);
                part.triangles.push([a, c, b]);
            }
        }
        for j in 0..segments {
            part.triangles.push([at(rings - 1, j), north, at(rings - 1, j + 1)]);
        }
        part
    }

    /// A torus around the Y axis: a tube of radius `minor` whose centre runs on the circle of
    /// radius `major > minor` in the XZ plane; `segments` steps around Y and `sides` around the
    /// tube (each at least 3): `2 * segments * sides` triangles.
    pub fn torus(major: f32, minor: f32, segments: u32, sides: u32) -> Part {
        let (segments, sides) = (segments.max(3), sides.max(3));
        let mut part = Part::default();
        for i in 0..segments {
            let theta = std::f32::consts::TAU * i as f32 / segments as f32;
            for j in 0..sides {
                let phi = std::f32::consts::TAU * j as f32 / sides as f32;
                let r = major + minor * phi.cos();
                part.positions.push(Vec3::new(r * theta.cos(), minor * phi.sin(), r * theta.sin()));
            }
        }
        let at = |i: u32, j: u32| (i % segments) * sides + j % sides;
        for i in 0..segments {
            for j in 0..sides {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                part.triangles.push([a, d, c]);
                part.triangles.push([a, c, b]);
            }
        }
        part
    }

    /// Closes an open surface that is a height field over the XZ plane (such as a terrain
    /// grid, normals up) into a solid: vertical walls down from its boundary to height `floor`
    /// and a flat bottom (a fan around the bottom's centre). `floor` must lie below the surface.
    pub fn close_downwards(surface: &Part, floor: f32) -> Part {
        let mut part = surface.clone();
        let directed: std::collections::HashSet<(u32, u32)> =
            surface.triangles.iter().flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)]).collect();
        // Boundary edges: directed edges whose reverse no triangle uses, in triangle order.
        let boundary: Vec<(u32, u32)> = surface
            .triangles
            .iter()
            .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
            .filter(|&(a, b)| !directed.contains(&(b, a)))
            .collect();
        let mut below: HashMap<u32, u32> = HashMap::new();
        for &(a, _) in &boundary {
            below.entry(a).or_insert_with(|| {
                let p = part.positions[a as usize];
                part.positions.push(Vec3::new(p.x, floor, p.z));
                part.positions.len() as u32 - 1
            });
        }
        let bottom: Vec<Vec3> = below.values().map(|&i| part.positions[i as usize]).collect();
        let centre = bottom.iter().copied().sum::<Vec3>() / bottom.len().max(1) as f32;
        let c = part.positions.len() as u32;
        part.positions.push(centre);
        for &(a, b) in &boundary {
            let (a2, b2) = (below[&a], below[&b]);
            part.triangles.extend([[b, a, a2], [b, a2, b2], [c, b2, a2]]);
        }
        part
    }

    /// This part under the affine map `m` (winding flipped if `m` mirrors, so it stays outward).
    pub fn transformed(&self, m: Affine3A) -> Part {
        let flip = m.matrix3.determinant() < 0.0;
        Part {
            positions: self.positions.iter().map(|&p| m.transform_point3(p)).collect(),
            triangles: self.triangles.iter().map(|&[a, b, c]| if flip { [a, c, b] } else { [a, b, c] }).collect(),
        }
    }

    /// This part moved by `offset`.
    pub fn translated(&self, offset: Vec3) -> Part {
        self.transformed(Affine3A::from_translation(offset))
    }

    /// The enclosed volume (positive for outward winding), by the divergence theorem.
    pub fn signed_volume(&self) -> f32 {
        let p = |i: u32| self.positions[i as usize].as_dvec3();
        let six_v: f64 = self.triangles.iter().map(|&[a, b, c]| p(a).dot(p(b).cross(p(c)))).sum();
        (six_v / 6.0) as f32
    }
}

/// Accumulates parts, each with its own vertices and a material, into a [`Mesh`].
#[derive(Debug, Default)]
pub struct MeshBuilder {
    mesh: Mesh,
}

impl MeshBuilder {
    /// An empty builder.
    pub fn new() -> MeshBuilder {
        MeshBuilder::default()
    }

    /// The id of the material called `name`, created with colour `diffuse` on first use.
    pub fn material(&mut self, name: &str, diffuse: Vec3) -> u32 {
        if let Some(i) = self.mesh.materials.iter().position(|m| m.name == name) {
            return i as u32;
        }
        self.mesh.materials.push(Material::diffuse(name, diffuse));
        self.mesh.materials.len() as u32 - 1
    }

    /// The id of the material called `material.name`, added as given on first use (an
    /// existing material of that name is kept as it is).
    pub fn add_material(&mut self, material: Material) -> u32 {
        if let Some(i) = self.mesh.materials.iter().position(|m| m.name == material.name) {
            return i as u32;
        }
        self.mesh.materials.push(material);
        self.mesh.materials.len() as u32 - 1
    }

    /// Adds `part` with material `material`.
    pub fn add(&mut self, part: &Part, material: u32) {
        let base = self.mesh.positions.len() as u32;
        self.mesh.positions.extend_from_slice(&part.positions);
        for &[a, b, c] in &part.triangles {
            self.mesh.triangles.push([a + base, b + base, c + base]);
            self.mesh.material_ids.push(material);
        }
    }

    /// Adds the box `[min, max]`.
    pub fn add_box(&mut self, min: Vec3, max: Vec3, material: u32) {
        self.add(&Part::cuboid(min, max), material);
    }

    /// Triangles added so far.
    pub fn triangle_count(&self) -> usize {
        self.mesh.triangles.len()
    }

    /// The finished mesh, with `prim_ids[i] = i`.
    pub fn finish(mut self) -> Mesh {
        self.mesh.prim_ids = (0..self.mesh.triangles.len() as u32).collect();
        self.mesh
    }
}

/// Splits the wall rectangle `span` x `height` minus the rectangular `openings`
/// `(u0, u1, y0, y1)` into non-overlapping rectangles: vertical strips between the openings'
/// edges, each cut around the openings that cross it.
pub fn wall_boxes(
    span: (f32, f32),
    height: (f32, f32),
    openings: &[(f32, f32, f32, f32)],
) -> Vec<(f32, f32, f32, f32)> {
    let mut us: Vec<f32> = vec![span.0, span.1];
    us.extend(openings.iter().flat_map(|o| [o.0, o.1]));
    us.sort_by(f32::total_cmp);
    us.dedup();
    let mut out = Vec::new();
    for strip in us.windows(2) {
        let (u0, u1) = (strip[0], strip[1]);
        let mut holes: Vec<(f32, f32)> =
            openings.iter().filter(|o| o.0 <= u0 && o.1 >= u1).map(|o| (o.2, o.3)).collect();
        holes.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut y = height.0;
        for (h0, h1) in holes {
            if h0 > y {
                out.push((u0, u1, y, h0));
            }
            y = y.max(h1);
        }
        if height.1 > y {
            out.push((u0, u1, y, height.1));
        }
    }
    out
}

/// A small deterministic random number generator (SplitMix64), so that scenes are the same on
/// every platform and run.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator with the given seed.
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        let unit = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * unit
    }
}

/// Test helpers shared by the scene tests.
#[cfg(test)]
pub(crate) mod checks {
    use super::*;

    /// The first undirected edge not used by exactly two triangles, if any.
    pub fn open_edge(triangles: &[[u32; 3]]) -> Option<((u32, u32), u32)> {
        let mut uses: HashMap<(u32, u32), u32> = HashMap::new();
        for &[a, b, c] in triangles {
            for (p, q) in [(a, b), (b, c), (c, a)] {
                *uses.entry((p.min(q), p.max(q))).or_default() += 1;
            }
        }
        let mut bad: Vec<_> = uses.into_iter().filter(|&(_, n)| n != 2).collect();
        bad.sort_unstable();
        bad.first().copied()
    }

    /// The first directed edge used twice (two triangles disagreeing on orientation), if any.
    pub fn inconsistent_edge(triangles: &[[u32; 3]]) -> Option<(u32, u32)> {
        let mut seen = std::collections::HashSet::new();
        triangles.iter().flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)]).find(|&e| !seen.insert(e))
    }

    /// The first triangle with zero area in f32, if any.
    pub fn degenerate(positions: &[Vec3], triangles: &[[u32; 3]]) -> Option<usize> {
        triangles.iter().position(|&[a, b, c]| {
            let (pa, pb, pc) = (positions[a as usize], positions[b as usize], positions[c as usize]);
            a == b || b == c || a == c || (pb - pa).cross(pc - pa) == Vec3::ZERO
        })
    }

    /// Asserts that `part` is closed, consistently wound, outward (positive volume) and has no
    /// degenerate triangle.
    pub fn assert_closed_outward(part: &Part, what: &str) {
        assert_eq!(open_edge(&part.triangles), None, "{what}: open edge");
        assert_eq!(inconsistent_edge(&part.triangles), None, "{what}: inconsistent winding");
        assert_eq!(degenerate(&part.positions, &part.triangles), None, "{what}: degenerate triangle");
        assert!(part.signed_volume() > 0.0, "{what}: volume {}", part.signed_volume());
    }
}

#[cfg(test)]
mod tests {
    use super::checks::assert_closed_outward;
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn primitives_are_closed_and_outward() {
        let cube = Part::cuboid(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 3.0, 2.5));
        assert_eq!(cube.triangles.len(), 12);
        assert_relative_eq!(cube.signed_volume(), 3.0, epsilon = 1e-5);
        assert_closed_outward(&cube, "cuboid");

        let prism = Part::prism(1.0, 0.5, 0.0, 2.0, 16, 3);
        assert_eq!(prism.triangles.len(), 16 * (2 * 3 + 2));
        assert_closed_outward(&prism, "frustum");
        assert_closed_outward(&Part::prism(0.1, 0.1, 1.0, 1.5, 5, 1), "pentagonal prism");

        let wedge = Part::wedge(2.0, 1.0, 0.0, 3.0);
        assert_eq!(wedge.triangles.len(), 8);
        assert_relative_eq!(wedge.signed_volume(), 3.0, epsilon = 1e-5);
        assert_closed_outward(&wedge, "wedge");

        for s in 0..4 {
            let sphere = Part::icosphere(2.0, s);
            assert_eq!(sphere.triangles.len(), 20 * 4usize.pow(s));
            assert_closed_outward(&sphere, "icosphere");
        }
        for (e_v, e_h) in [(1.0, 1.0), (0.6, 0.35), (0.3, 0.2), (1.5, 0.8)] {
            let blob = Part::superellipsoid(Vec3::new(2.0, 0.5, 1.0), e_v, e_h, 40, 24);
            assert_eq!(blob.triangles.len(), 2 * 40 * 23);
            assert_closed_outward(&blob, &format!("superellipsoid {e_v} {e_h}"));
        }
        let ellipsoid = Part::superellipsoid(Vec3::new(1.0, 2.0, 3.0), 1.0, 1.0, 128, 64).signed_volume();
        assert!((ellipsoid - 8.0 * std::f32::consts::PI).abs() < 0.05 * ellipsoid, "{ellipsoid}");
        let torus = Part::torus(2.0, 0.5, 48, 16);
        assert_eq!(torus.triangles.len(), 2 * 48 * 16);
        assert_closed_outward(&torus, "torus");
        let ring = std::f32::consts::PI * 0.25 * std::f32::consts::TAU * 2.0;
        assert!((torus.signed_volume() - ring).abs() < 0.05 * ring, "{}", torus.signed_volume());
        assert_closed_outward(&Part::torus(1.0, 0.2, 3, 3), "coarsest torus");
        let v = Part::icosphere(1.0, 4).signed_volume();
        assert!((v - 4.0 / 3.0 * std::f32::consts::PI).abs() < 0.03, "{v}");
    }

    #[test]
    fn non_finite_parameters_give_meshes_that_check_rejects() {
        let (nan, inf) = (f32::NAN, f32::INFINITY);
        let parts = [
            Part::cuboid(Vec3::new(nan, 0.0, 0.0), Vec3::ONE),
            Part::cuboid(Vec3::ZERO, Vec3::new(1.0, inf, 1.0)),
            Part::prism(nan, 1.0, 0.0, 1.0, 8, 2),
            Part::prism(1.0, 1.0, 0.0, inf, 8, 2),
            Part::wedge(1.0, nan, 0.0, 1.0),
            Part::icosphere(nan, 2),
            Part::icosphere(inf, 1),
            Part::close_downwards(
                &Part { positions: vec![Vec3::ZERO, Vec3::Z, Vec3::X], triangles: vec![[0, 1, 2]] },
                nan,
            ),
            Part::cuboid(Vec3::ZERO, Vec3::ONE).translated(Vec3::new(0.0, 0.0, inf)),
        ];
        for (i, part) in parts.iter().enumerate() {
            let mut builder = MeshBuilder::new();
            let m = builder.material("m", Vec3::ONE);
            builder.add_box(Vec3::ZERO, Vec3::ONE, m);
            builder.add(part, m);
            let e = builder.finish().check().unwrap_err();
            assert!(e.contains("is not finite"), "part {i}: {e}");
        }
    }

    #[test]
    fn curved_sweeps_and_mirrored_transforms_stay_outward() {
        let frames: Vec<Frame> = (0..=8)
            .map(|k| {
                let a = std::f32::consts::PI * k as f32 / 8.0;
                let p = Vec3::new(-a.cos(), a.sin(), 0.0) * 3.0;
                let tangent = Vec3::new(a.sin(), a.cos(), 0.0);
                Frame::oriented(p, tangent, Vec3::Z, Vec2::new(0.3, 0.5))
            })
            .collect();
        let square = [Vec2::new(-1.0, -1.0), Vec2::new(1.0, -1.0), Vec2::new(1.0, 1.0), Vec2::new(-1.0, 1.0)];
        let arch = Part::sweep(&square, &frames);
        assert_closed_outward(&arch, "arch");
        let mirror = Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0));
        assert_closed_outward(&arch.transformed(mirror), "mirrored arch");
    }

    #[test]
    fn height_fields_close_into_solids() {
        let n = 6u32;
        let mut grid = Part::default();
        for i in 0..=n {
            for k in 0..=n {
                let (x, z) = (i as f32, k as f32);
                grid.positions.push(Vec3::new(x, 1.0 + 0.3 * (x * z).sin(), z));
            }
        }
        let at = |i: u32, k: u32| i * (n + 1) + k;
        for i in 0..n {
            for k in 0..n {
                grid.triangles.push([at(i, k), at(i + 1, k + 1), at(i + 1, k)]);
                grid.triangles.push([at(i, k), at(i, k + 1), at(i + 1, k + 1)]);
            }
        }
        let solid = Part::close_downwards(&grid, -1.0);
        assert_closed_outward(&solid, "closed height field");
        assert_eq!(solid.triangles.len(), grid.triangles.len() + 3 * 4 * n as usize);
    }

    #[test]
    fn builder_offsets_indices_and_dedupes_materials() {
        let mut b = MeshBuilder::new();
        let red = b.material("red", Vec3::X);
        b.add_box(Vec3::ZERO, Vec3::ONE, red);
        let red_again = b.material("red", Vec3::Y);
        assert_eq!(red, red_again);
        let shiny = Material { reflectivity: 0.5, ..Material::diffuse("red", Vec3::Z) };
        assert_eq!(b.add_material(shiny.clone()), red, "the first definition of a name stays");
        let mirror = b.add_material(Material { name: "mirror".into(), ..shiny });
        let blue = b.material("blue", Vec3::Z);
        b.add(&Part::icosphere(1.0, 1), blue);
        let mesh = b.finish();
        mesh.check().unwrap();
        assert_eq!(mesh.materials[red as usize], Material::diffuse("red", Vec3::X));
        assert_eq!(mesh.materials[mirror as usize].reflectivity, 0.5);
        assert_eq!(mesh.triangle_count(), 12 + 80);
        assert_eq!(mesh.prim_ids, (0..92).collect::<Vec<u32>>());
        assert_eq!(checks::open_edge(&mesh.triangles), None);
    }

    #[test]
    fn wall_boxes_cover_the_wall_minus_the_openings() {
        let openings = [(1.0, 2.0, 0.0, 1.0), (1.5, 3.0, 2.0, 2.5)];
        let boxes = wall_boxes((0.0, 4.0), (0.0, 3.0), &openings);
        let area: f32 = boxes.iter().map(|b| (b.1 - b.0) * (b.3 - b.2)).sum();
        let holes: f32 = 1.0 + 1.5 * 0.5;
        assert!((area - (12.0 - holes)).abs() < 1e-5, "{area}");
        // No box overlaps an opening.
        for b in &boxes {
            for o in &openings {
                let overlap = b.0 < o.1 && o.0 < b.1 && b.2 < o.3 && o.2 < b.3;
                assert!(!overlap, "{b:?} overlaps {o:?}");
            }
        }
    }

    #[test]
    fn rng_is_deterministic_and_in_range() {
        let mut a = Rng::new(7);
        let mut b = Rng::new(7);
        for _ in 0..1000 {
            let x = a.range(-2.0, 3.0);
            assert_eq!(x, b.range(-2.0, 3.0));
            assert!((-2.0..3.0).contains(&x));
        }
    }
}
