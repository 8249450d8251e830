//! Secondary rays: the reflection and refraction rays of the thesis's shader proxy (Tsakok
//! 2008, 3.3 and Figure 3.2; the material types of 4.2.1, Listing 4.7).
//!
//! A hit on a material that reflects or refracts ([`scenes::Material`]) splits its colour
//! three ways ([`Spawn`]): its own shading (diffuse, Phong specular, shadow), a reflection
//! ray and a refraction ray. With `t` the transparency, `r` the reflectivity and `F` the
//! Fresnel reflectance:
//! - `local = (1 - t) (1 - r)`;
//! - `reflection = (1 - t) r + t F`;
//! - `refraction = t (1 - F)`.
//!
//! The three weights sum to 1. `F` is Schlick's approximation (1994) for the
//! transparent-reflective `M_TR`. For the transparent `M_T`, which the thesis gives no
//! reflection ray, `F` is 0, except under total internal reflection, where `F` is 1 for both
//! types (no light is transmitted).
//!
//! The geometry ([`reflect`], [`refract`], [`schlick`]):
//! - The normal is the triangle's geometric normal, turned to face the incoming ray. Built-in
//!   objects are closed and consistently wound, so the ray enters a material where it meets a
//!   triangle's front (counter-clockwise) side.
//! - Snell's law gives the refracted direction, with index `1 -> ior` entering and
//!   `ior -> 1` leaving. An index of exactly 1 continues the ray unbent, bit for bit, and
//!   reflects nothing (`F = 0`).
//! - Where the frame asks (`Renderer::with_virtual_eyes`, `rttest render --virtual-eye`), a
//!   reflection in a run off one plane leaves from the *virtual eye* ([`ReflectFrom`]):
//!   the origin of the ray that reached the hit, mirrored in the triangle's plane
//!   ([`packets::mirror::Mirror::reflected_ray`]), its interval starting just past the
//!   mirror. It is the same line as a ray started at the hit point, but the reflections of
//!   one eye's rays off one plane share their origin bit for bit, so a run of them is one
//!   frustum for the frustum, MFT and cone kernels and one omni-directional packet for the
//!   thesis's packets (4.1.2). A point is in such a run when the point spawned just before or
//!   after it saw the same plane from the same eye ([`in_plane_run`]): a flat mirror's
//!   pixels. The others start on the surface: the virtual eyes of a curved mirror's
//!   triangles lie scattered far apart, and packets of rays from them traversed 1.3x slower
//!   than from their hit points on the garage's cars. So does a reflection flatter than
//!   [`packets::mirror::MIN_COS`]. It is off by default: on the garage the runs traced as
//!   frusta were slower than the same rays from their hit points as omni-directional packets
//!   at the machine's width (`docs/results/secondary-rays.md`).
//! - Refractions (and those flat reflections) start on the surface they leave by the
//!   workspace's one spawn rule ([`kdtree::ray::offset_origin`], through the triangle's
//!   [`Surface`] record): a reflection on the side the ray came from, a refraction on the
//!   other side. So neither can hit its own triangle at `t = 0`.
//! - A degenerate triangle (zero normal), a NaN or infinite normal, direction or point spawns
//!   no ray. Its hit keeps its own shading with weight 1: never a NaN, never a panic.
//!
//! Secondary hits are shaded without spawning further rays at the thesis's depth of 1
//! ([`DEFAULT_DEPTH`]). A greater depth lets each generation's hits spawn the next.

use glam::Vec3;
use kdtree::surface::{Surface, Surfaces};
use kdtree::{Hit, Ray};
use packets::mirror::Mirror;
use rayon::prelude::*;
use scenes::{Material, Mesh, Shader};

/// The thesis's recursion depth: primary hits spawn secondary rays, whose hits are shaded
/// without spawning more (3.3: "secondary traces ... which do not further spawn additional
/// rays").
pub const DEFAULT_DEPTH: u32 = 1;

/// The deepest recursion a frame accepts.
pub const MAX_DEPTH: u32 = 8;

/// The mirror direction of `d` about the unit normal `n`: `d - 2 (d . n) n`.
#[inline]
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

/// The direction of the unit `d` refracted through a surface whose unit normal `n` faces
/// the incoming ray (`d . n <= 0`), with `eta = n1 / n2` (Snell's law), or `None` under
/// total internal reflection. With `eta == 1` the ray continues unbent: `d` itself.
#[inline]
pub fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    if eta == 1.0 {
        return Some(d);
    }
    let cos_i = (-d.dot(n)).clamp(0.0, 1.0);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
    if sin2_t > 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(eta * d + (eta * cos_i - cos_t) * n)
}

/// Schlick's (1994) approximation of the Fresnel reflectance at a boundary from index `n1`
/// (the incoming side) to `n2`, for the cosine `cos_i` of the angle of incidence:
/// `F0 + (1 - F0) (1 - cos)^5` with `F0 = ((n1 - n2) / (n1 + n2))^2`. Leaving a denser
/// medium (`n1 > n2`) the cosine is the transmitted ray's, and total internal reflection
/// gives 1. Equal indices reflect nothing.
#[inline]
pub fn schlick(cos_i: f32, n1: f32, n2: f32) -> f32 {
    if n1 == n2 {
        return 0.0;
    }
    let mut cos = cos_i.clamp(0.0, 1.0);
    if n1 > n2 {
        let sin2_t = (n1 / n2) * (n1 / n2) * (1.0 - cos * cos);
        if sin2_t > 1.0 {
            return 1.0;
        }
        cos = (1.0 - sin2_t).sqrt();
    }
    let f0 = ((n1 - n2) / (n1 + n2)).powi(2);
    f0 + (1.0 - f0) * (1.0 - cos).powi(5)
}

/// How a hit's colour splits between its own shading and its secondary rays, and those rays
/// (see the module documentation for the weights).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spawn {
    /// The weight of the hit's own shading (diffuse, specular, shadow).
    pub local: f32,
    /// The reflection ray and its weight.
    pub reflection: Option<(Ray, f32)>,
    /// The refraction ray and its weight.
    pub refraction: Option<(Ray, f32)>,
}

impl Spawn {
    /// No secondary ray: the hit's own shading alone.
    pub const LOCAL: Spawn = Spawn { local: 1.0, reflection: None, refraction: None };
}

/// Where a reflection ray starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReflectFrom {
    /// From the virtual eye, the parent ray's origin mirrored in the triangle's plane, its
    /// interval starting past the mirror (unless flatter than `MIN_COS`).
    VirtualEye,
    /// From the hit point, lifted off the surface by the spawn offset.
    Surface,
}

/// What makes two reflections share a virtual eye: the mirror plane and the eye, bit for bit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeKey {
    plane: Mirror,
    eye: [u32; 3],
}

impl EyeKey {
    /// The key of a reflection off the triangle `surface` of a ray from `from` (`None` for a
    /// degenerate or non-finite triangle).
    pub fn new(surface: &Surface, from: Vec3) -> Option<EyeKey> {
        Some(EyeKey { plane: Mirror::of_surface(surface)?, eye: from.to_array().map(f32::to_bits) })
    }
}

/// Where the reflection of point `k` of a sequence starts, `keys` being each point's
/// [`EyeKey`] (`None` for points that reflect nothing): from the virtual eye when the point
/// just before or after it has the same key (a run of one flat mirror seen from one eye),
/// otherwise from the surface.
pub fn in_plane_run(keys: &[Option<EyeKey>], k: usize) -> ReflectFrom {
    let Some(key) = keys.get(k).copied().flatten() else { return ReflectFrom::Surface };
    let same = |j: Option<usize>| j.and_then(|j| keys.get(j).copied().flatten()) == Some(key);
    if same(k.checked_sub(1)) || same(k.checked_add(1)) { ReflectFrom::VirtualEye } else { ReflectFrom::Surface }
}

/// The secondary rays of the hit `hit` on triangle record `surface` with `material`, reached
/// by the ray from `from` along `dir` (any length; `hit.t` in its units), the reflection
/// started as `reflect_from` says: the shader proxy's spawning step.
///
/// A weight whose ray cannot be made (a non-finite origin or direction) goes back to the
/// local shading, so the weights always sum to 1.
pub fn spawn(
    surface: &Surface,
    material: &Material,
    from: Vec3,
    dir: Vec3,
    hit: &Hit,
    reflect_from: ReflectFrom,
) -> Spawn {
    let shader = material.shader();
    if !matches!(shader, Shader::Reflective | Shader::Transparent | Shader::TransparentReflective) {
        return Spawn::LOCAL;
    }
    let normal = surface.normal;
    let d = dir.normalize_or_zero();
    if !(normal.is_finite() && normal != Vec3::ZERO && d.is_finite() && d != Vec3::ZERO) {
        return Spawn::LOCAL;
    }
    let p = surface.point(hit);
    if !p.is_finite() {
        return Spawn::LOCAL;
    }
    let entering = normal.dot(d) < 0.0;
    let n = if entering { normal } else { -normal };
    let cos_i = (-d.dot(n)).clamp(0.0, 1.0);
    let (t, r) = (material.transparency, material.reflectivity);
    let (mut fresnel, mut transmitted) = (0.0, None);
    if material.refracts() {
        let (n1, n2) = if entering { (1.0, material.ior) } else { (material.ior, 1.0) };
        transmitted = refract(d, n, n1 / n2);
        fresnel = match (transmitted, shader) {
            (None, _) => 1.0,
            (Some(_), Shader::TransparentReflective) => schlick(cos_i, n1, n2),
            (Some(_), _) => 0.0,
        };
    }
    let mut out = Spawn { local: (1.0 - t) * (1.0 - r), reflection: None, refraction: None };
    let mut ray = |direction: Vec3, side: Vec3, weight: f32| -> Option<(Ray, f32)> {
        if weight <= 0.0 {
            return None;
        }
        let origin = surface.offset_origin(p, side);
        match Ray::try_new(origin, direction, 0.0, f32::INFINITY) {
            Ok(ray) => Some((ray, weight)),
            Err(_) => {
                out.local += weight;
                None
            }
        }
    };
    let weight = (1.0 - t) * r + t * fresnel;
    let from_virtual_eye = (weight > 0.0 && reflect_from == ReflectFrom::VirtualEye)
        .then(|| Mirror::of_surface(surface)?.reflected_ray(from, dir, hit.t, surface.offset))
        .flatten();
    let reflection = match from_virtual_eye {
        Some(reflected) => Some((reflected, weight)),
        None => ray(reflect(d, n), n, weight),
    };
    let refraction = transmitted.and_then(|dt| ray(dt, -n, t * (1.0 - fresnel)));
    out.reflection = reflection;
    out.refraction = refraction;
    out
}

/// Points per parallel chunk of [`spawn_generation`].
const SPAWN_CHUNK: usize = 4096;

/// One generation of a frame's secondary rays, the rays of the points of the generation
/// before (the pixels' primary hits for the first): what the frame traces and shades.
#[derive(Clone, Debug, Default)]
pub struct Generation {
    /// The rays, in the order they are traced. Each chunk of [`SPAWN_CHUNK`] points of the
    /// generation before gives its reflections first, then its refractions, each in the
    /// points' order. The first generation visits each tile's pixels in Morton order, so
    /// four consecutive rays come from a 2x2 block when all four pixels spawn one.
    pub rays: Vec<Ray>,
    /// The point of the generation before each ray belongs to: a pixel in tile order for
    /// the first generation, an index into the generation before's `rays` after it.
    pub parent: Vec<u32>,
    /// The weight of each ray's colour in its parent's ([`Spawn`]).
    pub weight: Vec<f32>,
    /// Each ray's closest hit.
    pub hits: Vec<Option<Hit>>,
    /// The visible fraction of the light at each hit (1 without shadows, 0 for misses).
    pub visible: Vec<f32>,
    /// The weight of each hit's own shading: 1, unless the next generation's rays take a
    /// share.
    pub local: Vec<f32>,
}

impl Generation {
    /// The number of rays.
    pub fn len(&self) -> usize {
        self.rays.len()
    }

    /// Whether it has no ray.
    pub fn is_empty(&self) -> bool {
        self.rays.is_empty()
    }
}

/// The secondary rays spawned from the shading points `order[..]` of one generation
/// (`point(i)`: the hit of point `i` and the origin and direction of the ray that reached it,
/// `None` for misses), in parallel over chunks of `order`; with `virtual_eyes`, reflections
/// in runs off one plane leave from the virtual eye ([`in_plane_run`]). Writes each point's local weight into
/// `local` (indexed by point; points that spawn nothing keep theirs). The rays' `hits`,
/// `visible` and `local` are left empty for the caller to fill.
pub fn spawn_generation(
    surfaces: &Surfaces,
    mesh: &Mesh,
    order: &[u32],
    point: impl Fn(u32) -> Option<(Hit, Vec3, Vec3)> + Sync,
    virtual_eyes: bool,
    local: &mut [f32],
) -> Generation {
    let parts: Vec<(Generation, Vec<(u32, f32)>)> = order
        .par_chunks(SPAWN_CHUNK)
        .map(|chunk| {
            let (mut reflections, mut refractions) = (Generation::default(), Generation::default());
            let mut locals = Vec::new();
            let points: Vec<(u32, Hit, Vec3, Vec3, &Material)> = chunk
                .iter()
                .filter_map(|&i| {
                    let (hit, from, dir) = point(i)?;
                    let material =
                        mesh.material_ids.get(hit.prim as usize).and_then(|&m| mesh.materials.get(m as usize))?;
                    (material.reflects() || material.refracts()).then_some((i, hit, from, dir, material))
                })
                .collect();
            let keys: Vec<Option<EyeKey>> = match virtual_eyes {
                true => points.iter().map(|&(_, hit, from, _, _)| EyeKey::new(surfaces.get(hit.prim), from)).collect(),
                false => Vec::new(),
            };
            for (k, &(i, hit, from, dir, material)) in points.iter().enumerate() {
                let s = spawn(surfaces.get(hit.prim), material, from, dir, &hit, in_plane_run(&keys, k));
                locals.push((i, s.local));
                for (out, ray) in [(&mut reflections, s.reflection), (&mut refractions, s.refraction)] {
                    if let Some((ray, weight)) = ray {
                        out.rays.push(ray);
                        out.parent.push(i);
                        out.weight.push(weight);
                    }
                }
            }
            reflections.rays.append(&mut refractions.rays);
            reflections.parent.append(&mut refractions.parent);
            reflections.weight.append(&mut refractions.weight);
            (reflections, locals)
        })
        .collect();
    let out = Generation {
        rays: concat(&parts.iter().map(|p| &p.0.rays[..]).collect::<Vec<_>>()),
        parent: concat(&parts.iter().map(|p| &p.0.parent[..]).collect::<Vec<_>>()),
        weight: concat(&parts.iter().map(|p| &p.0.weight[..]).collect::<Vec<_>>()),
        ..Generation::default()
    };
    for (_, locals) in &parts {
        for &(i, w) in locals {
            if let Some(slot) = local.get_mut(i as usize) {
                *slot = w;
            }
        }
    }
    out
}

/// The slices `parts` one after the other, gathered in parallel straight into the new vector
/// (rayon's indexed collect: no fill first).
fn concat<T: Copy + Send + Sync>(parts: &[&[T]]) -> Vec<T> {
    let mut offsets = Vec::with_capacity(parts.len() + 1);
    offsets.push(0);
    for p in parts {
        offsets.push(offsets[offsets.len() - 1] + p.len());
    }
    let total = offsets[parts.len()];
    (0..total)
        .into_par_iter()
        .map(|j| {
            // The last part starting at or before `j` (empty parts share the next one's start).
            let k = offsets.partition_point(|&o| o <= j) - 1;
            parts[k][j - offsets[k]]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mirror() -> Material {
        Material { reflectivity: 1.0, ..Material::diffuse("mirror", Vec3::ONE) }
    }

    fn glass(ior: f32, reflectivity: f32) -> Material {
        Material { transparency: 1.0, reflectivity, ior, ..Material::diffuse("glass", Vec3::ONE) }
    }

    /// The floor triangle of the plane y = 0, its front (counter-clockwise) side up.
    fn floor() -> Surface {
        Surface::new(&[Vec3::new(-10.0, 0.0, 10.0), Vec3::new(10.0, 0.0, 10.0), Vec3::new(0.0, 0.0, -10.0)])
    }

    fn hit_at_centre() -> Hit {
        Hit { t: 1.0, u: 0.25, v: 0.25, prim: 0 }
    }

    /// [`spawn`] for a ray along `d` that reached the hit at its distance `hit.t`: from
    /// `p - t d`.
    fn spawn_along(surface: &Surface, material: &Material, d: Vec3, hit: &Hit) -> Spawn {
        spawn(surface, material, surface.point(hit) - hit.t * d, d, hit, ReflectFrom::VirtualEye)
    }

    /// Where a ray's interval starts.
    fn start(ray: &Ray) -> Vec3 {
        ray.at(ray.t_min)
    }

    fn weights(s: &Spawn) -> f32 {
        s.local + s.reflection.map_or(0.0, |r| r.1) + s.refraction.map_or(0.0, |r| r.1)
    }

    #[test]
    fn reflection_mirrors_the_direction_and_starts_above_the_surface() {
        let d = Vec3::new(1.0, -1.0, 0.5);
        let s = spawn_along(&floor(), &mirror(), d, &hit_at_centre());
        let (ray, w) = s.reflection.unwrap();
        assert_eq!((s.local, w), (0.0, 1.0));
        assert_eq!(ray.dir, Vec3::new(d.x, -d.y, d.z));
        // From the virtual eye: the ray's origin `p - d` mirrored in y = 0, its interval
        // starting past the hit distance, on the incoming side.
        let p = floor().point(&hit_at_centre());
        assert_eq!(ray.origin, Vec3::new(p.x - d.x, d.y, p.z - d.z));
        assert!(ray.t_min > 1.0 && start(&ray).y > 0.0, "starts on the incoming side: {ray:?}");
        assert!((start(&ray) - p).length() < 1e-4);
        assert!(s.refraction.is_none());
    }

    #[test]
    fn runs_off_one_plane_from_one_eye_leave_from_the_virtual_eye() {
        let floor_key = EyeKey::new(&floor(), Vec3::Y);
        let tilted = Surface::new(&[Vec3::ZERO, Vec3::new(1.0, 0.1, 0.0), Vec3::Z]);
        let keys = [
            floor_key,
            floor_key,
            EyeKey::new(&tilted, Vec3::Y),
            floor_key,
            None,
            floor_key,
            EyeKey::new(&floor(), Vec3::X),
        ];
        let got: Vec<ReflectFrom> = (0..keys.len() + 1).map(|k| in_plane_run(&keys, k)).collect();
        use ReflectFrom::{Surface as S, VirtualEye as V};
        assert_eq!(got, [V, V, S, S, S, S, S, S], "alone, another plane, another eye, none, past the end");
        // From the surface: the hit point lifted by the spawn offset, the same direction.
        let d = Vec3::new(1.0, -1.0, 0.5);
        let hit = hit_at_centre();
        let p = floor().point(&hit);
        let (ray, _) = spawn(&floor(), &mirror(), p - d, d, &hit, ReflectFrom::Surface).reflection.unwrap();
        let (eye_ray, _) = spawn_along(&floor(), &mirror(), d, &hit).reflection.unwrap();
        assert!(ray.t_min == 0.0 && ray.origin.y > 0.0 && (ray.origin - p).length() < 1e-4, "{ray:?}");
        assert!((ray.dir - eye_ray.dir.normalize()).length() < 1e-6);
    }

    #[test]
    fn a_ray_from_below_reflects_below() {
        let s = spawn_along(&floor(), &mirror(), Vec3::new(0.3, 1.0, 0.0), &hit_at_centre());
        let (ray, _) = s.reflection.unwrap();
        assert!(ray.dir.y < 0.0 && start(&ray).y < 0.0 && ray.origin.y > 0.0, "{ray:?}");
    }

    #[test]
    fn grazing_reflection_stays_on_the_incoming_side() {
        // A ray almost in the plane: its reflection leaves at the same tiny angle, from an
        // origin on the incoming side, never under the surface: from the surface, not the
        // virtual eye (flatter than MIN_COS).
        let d = Vec3::new(1.0, -1e-7, 0.0);
        let (ray, _) = spawn_along(&floor(), &mirror(), d, &hit_at_centre()).reflection.unwrap();
        assert!(ray.dir.y >= 0.0 && ray.origin.y > 0.0 && ray.t_min == 0.0, "{ray:?}");
        // Just steeper than MIN_COS: from the virtual eye, still starting above the surface.
        let cos = packets::mirror::MIN_COS as f32 * 1.01;
        let d = Vec3::new((1.0 - cos * cos).sqrt(), -cos, 0.0);
        let (ray, _) = spawn_along(&floor(), &mirror(), d, &hit_at_centre()).reflection.unwrap();
        assert!(ray.origin.y < 0.0 && ray.t_min > 1.0 && start(&ray).y > 0.0, "{ray:?}");
        // Exactly in the plane (no incoming side): the direction is unchanged, the origin
        // moved off the plane to one side.
        let (ray, _) = spawn_along(&floor(), &mirror(), Vec3::X, &hit_at_centre()).reflection.unwrap();
        assert_eq!(ray.dir, Vec3::X);
        assert!(ray.origin.y != 0.0);
    }

    #[test]
    fn snell_refraction_entering_and_leaving() {
        let d = Vec3::new(1.0, -1.0, 0.0).normalize();
        let s = spawn_along(&floor(), &glass(1.5, 0.0), d, &hit_at_centre());
        let (ray, w) = s.refraction.unwrap();
        assert_eq!(w, 1.0);
        assert!(s.reflection.is_none(), "M_T reflects nothing without total internal reflection");
        // sin(t) = sin(45 deg) / 1.5.
        let sin_t = ray.dir.x / ray.dir.length();
        assert!((sin_t - std::f32::consts::FRAC_1_SQRT_2 / 1.5).abs() < 1e-6, "{sin_t}");
        assert!(ray.dir.y < 0.0 && ray.origin.y < 0.0, "goes on below, from below: {ray:?}");
        // Leaving the glass upwards at that angle inside bends back to 45 degrees.
        let up = Vec3::new(sin_t, (1.0 - sin_t * sin_t).sqrt(), 0.0);
        let (ray, _) = spawn_along(&floor(), &glass(1.5, 0.0), up, &hit_at_centre()).refraction.unwrap();
        let sin_out = ray.dir.x / ray.dir.length();
        assert!((sin_out - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-5, "{sin_out}");
        assert!(ray.dir.y > 0.0 && ray.origin.y > 0.0, "goes on above, from above: {ray:?}");
    }

    #[test]
    fn total_internal_reflection_sends_everything_back_inside() {
        // From inside glass of index 1.5 (a ray hitting the back side, going up), at 60
        // degrees: beyond the critical angle of 41.8 degrees.
        let d = Vec3::new(60f32.to_radians().sin(), 60f32.to_radians().cos(), 0.0);
        for m in [glass(1.5, 0.0), glass(1.5, 0.2)] {
            let s = spawn_along(&floor(), &m, d, &hit_at_centre());
            assert!(s.refraction.is_none(), "{:?}", m.shader());
            let (ray, w) = s.reflection.unwrap();
            assert!((w - 1.0).abs() < 1e-6 && s.local.abs() < 1e-6, "{s:?}");
            assert!(ray.dir.y < 0.0 && start(&ray).y < 0.0, "reflected back inside: {ray:?}");
        }
        assert_eq!(refract(d, -Vec3::Y, 1.5), None);
        assert_eq!(schlick(d.y, 1.5, 1.0), 1.0);
    }

    #[test]
    fn index_of_exactly_one_continues_unbent_and_reflects_nothing() {
        let d = Vec3::new(0.3, -0.8, 0.1);
        let s = spawn_along(&floor(), &glass(1.0, 0.5), d, &hit_at_centre());
        let (ray, w) = s.refraction.unwrap();
        assert_eq!(ray.dir, d.normalize());
        assert!(ray.origin.y < 0.0);
        // M_TR with F = 0: only the opaque part's reflectivity, here none (transparency 1).
        assert_eq!(w, 1.0);
        assert!(s.reflection.is_none());
        assert_eq!(schlick(0.1, 1.0, 1.0), 0.0);
    }

    #[test]
    fn schlick_matches_the_known_values() {
        // Normal incidence on glass: ((1 - 1.5) / 2.5)^2 = 0.04.
        assert!((schlick(1.0, 1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing: 1.
        assert!((schlick(0.0, 1.0, 1.5) - 1.0).abs() < 1e-6);
        // Monotone in the angle.
        let mut last = 0.0;
        for k in (0..=10).rev() {
            let f = schlick(k as f32 / 10.0, 1.0, 1.5);
            assert!(f >= last);
            last = f;
        }
    }

    #[test]
    fn weights_sum_to_one_for_every_shader_and_angle() {
        let m = [
            Material::default(),
            Material { specular_blend: 0.5, specular_exponent: 10.0, ..Material::default() },
            Material { reflectivity: 0.4, ..Material::default() },
            Material { transparency: 0.7, ior: 1.33, ..Material::default() },
            Material { transparency: 0.7, reflectivity: 0.3, ior: 1.5, ..Material::default() },
        ];
        for material in &m {
            for k in 0..32 {
                let a = k as f32 / 31.0 * std::f32::consts::PI;
                for d in [Vec3::new(a.cos(), -a.sin() - 0.01, 0.2), Vec3::new(a.cos(), a.sin() + 0.01, -0.1)] {
                    let s = spawn_along(&floor(), material, d, &hit_at_centre());
                    assert!((weights(&s) - 1.0).abs() < 1e-5, "{:?} {d}: {s:?}", material.shader());
                    if matches!(material.shader(), Shader::Diffuse | Shader::Specular) {
                        assert_eq!(s, Spawn::LOCAL);
                    }
                }
            }
        }
    }

    #[test]
    fn concat_keeps_the_order_across_empty_parts() {
        let parts: [&[u32]; 5] = [&[], &[1, 2], &[], &[], &[3, 4, 5]];
        assert_eq!(concat(&parts), vec![1, 2, 3, 4, 5]);
        assert!(concat::<u32>(&[&[], &[]]).is_empty());
        let long: Vec<u32> = (0..10_000).collect();
        assert_eq!(concat(&[&long[..3000], &[], &long[3000..]]), long);
    }

    #[test]
    fn degenerate_and_nan_input_spawn_nothing() {
        let degenerate = Surface::new(&[Vec3::ZERO, Vec3::X, Vec3::X * 2.0]);
        assert_eq!(spawn_along(&degenerate, &mirror(), -Vec3::Y, &hit_at_centre()), Spawn::LOCAL);
        let nan = Surface::new(&[Vec3::NAN, Vec3::X, Vec3::Z]);
        assert_eq!(spawn_along(&nan, &mirror(), -Vec3::Y, &hit_at_centre()), Spawn::LOCAL);
        assert_eq!(spawn_along(&floor(), &mirror(), Vec3::NAN, &hit_at_centre()), Spawn::LOCAL);
        assert_eq!(spawn_along(&floor(), &mirror(), Vec3::ZERO, &hit_at_centre()), Spawn::LOCAL);
        let far = Hit { u: f32::INFINITY, ..hit_at_centre() };
        assert_eq!(spawn_along(&floor(), &glass(1.5, 0.5), -Vec3::Y, &far), Spawn::LOCAL);
    }
}
