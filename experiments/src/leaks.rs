//! Watertightness, measured (issue 7): rays shot exactly at the shared edges and shared
//! vertices of closed meshes, counting the rays that pass through (`rttest leaks`: [`run`]
//! with a [`LeaksConfig`]).
//!
//! ## The rays
//! A *target* is a point exactly on a shared edge (the `f32` midpoint of its two vertices, or
//! `a + s (b - a)` for a random `s`) or exactly a shared vertex. An edge is shared when two
//! non-degenerate triangles use it, in opposite directions (consistent winding); a vertex is
//! shared when every edge around it is. Boundary edges and their vertices (holes in a scanned
//! mesh, for example) are never targets.
//!
//! Each ray crosses the surface at its target *transversally*: its direction `d` makes
//! `|d . n| >= MIN_COS` with the unit normal `n` of every triangle at the target, with the same
//! sign for all of them (entering the solid through all of them, or leaving through all of
//! them; half the rays each way, around the mean normal). "At the target" is everywhere the
//! ray may cross given its aim's error: an edge target within [`NEAR_VERTEX`] of an end also
//! needs every triangle around that end (a ray aimed next to the tip of a thin fan may cross
//! at the tip, where the surface can be seen edge-on). A target with no such direction (a
//! fold or a saddle), or next to a vertex that is not shared, is skipped. The origin is `x - L d`, at a random distance `L` of 2% to
//! 150% of the mesh's diagonal, so it may be outside or inside the closed mesh or inside
//! another part of it.
//!
//! ## The leak criterion
//! Near its target the surface is closed and the ray crosses it there, from one side to the
//! other, whatever happened before: so it must hit *something* at a distance
//! `t <= t_target + TOLERANCE (t_target + M)`, where `t_target` is the distance from the
//! origin to the target along the ray and `M` the largest coordinate magnitude of the origin
//! and the target. A hit before the target (another part, or the same one entered earlier)
//! also counts. A ray that hits nothing up to there (no hit at all, or a first hit beyond)
//! has passed the surface without a hit: a *leak*.
//!
//! The slack covers the aim: the `f32` origin and direction pass within a few ulps of `M`
//! and of `t_target` of the target (`4 f32::EPSILON (M + t_target)` is generous), and a
//! crossing at no less than about 11.5 degrees (`MIN_COS = 0.2`) moves the crossing by at
//! most five times that along the ray: `2.4e-6 (M + t_target)`; `TOLERANCE = 1e-5` is four
//! times that. It stays far below the thinnest part of the built-in scenes (grove's leaves,
//! 0.01 thick, where `M + t_target < 150`: `1.5e-3`), so a ray through a crack is not excused
//! by the far side of a thin part (except within about `1e-4` of a sharp rim, such as the
//! flat cones' of `fan`).
//!
//! ## The meshes
//! `fan` (double cones of 97 to 4099 thin triangles around each apex, some nearly flat),
//! `sphere` (a geodesic sphere of 20,480 triangles, rotated and moved off the origin), the
//! built-in closed scenes (`cube`, `sphere`, `touching-boxes`, `arena`, `atrium`,
//! `atrium-rotated`, `grove`) and the Stanford bunny from the shared scenes folder when it is
//! there (its shared edges only: the scan has holes). The rays are the same for every
//! intersector (a fixed seed per mesh); a mesh's tree is built for each intersector, and only
//! the tracing (`KdTree::occluded` over `[0, leak_t_max]`, on the rayon pool) is timed.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::time::Instant;

use glam::{DVec3, Quat, Vec3};
use kdtree::{BuildConfig, Intersector, KdTree, Ray};
use rayon::prelude::*;
use scenes::Mesh;
use scenes::builtin::shapes::{MeshBuilder, Part, Rng};
use serde::Serialize;
use trace::progress::Progress;

use crate::Error;

/// The slack past the target, relative to `t_target + M` (see the module docs).
pub const TOLERANCE: f32 = 1e-5;

/// The end of a leak ray's interval: `t_target + TOLERANCE (t_target + M)`, `M` the largest
/// coordinate magnitude of the origin and the target.
pub fn leak_t_max(origin: Vec3, target: Vec3, t_target: f32) -> f32 {
    let m = origin.abs().max_element().max(target.abs().max_element());
    t_target + TOLERANCE * (t_target + m)
}

/// The least `|cos|` between a ray and the normal of every triangle at its target: the ray
/// crosses the surface at least about 11.5 degrees off it.
pub const MIN_COS: f64 = 0.2;

/// An edge target closer than this to an end, relative to `M + 2 L` (its largest coordinate
/// magnitude plus twice the origin's distance), must also cross every triangle around that
/// end: the aim's error (a few `f32::EPSILON (M + L)`) could put the crossing there. A
/// thousand times that error, so that the thinnest fans (4099 triangles around an apex)
/// are covered too.
pub const NEAR_VERTEX: f64 = 1e-3;

/// Rays generated and traced at a time (bounds the memory: 44 bytes a ray).
const BATCH: usize = 1 << 20;

/// The built-in scenes made of closed meshes that the leak test uses.
pub const BUILTIN: &[&str] = &["cube", "sphere", "touching-boxes", "arena", "atrium", "atrium-rotated", "grove"];

/// The options of the leak test (`rttest leaks`); [`Default`] gives the command line's
/// defaults.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LeaksConfig {
    /// Rays per intersector, over all meshes (split evenly between them; default ten
    /// million).
    pub rays: u64,
    /// Only these meshes (names of [`mesh_names`]); empty: all of them.
    pub meshes: Vec<String>,
}

impl Default for LeaksConfig {
    fn default() -> Self {
        LeaksConfig { rays: 10_000_000, meshes: Vec::new() }
    }
}

/// A closed test mesh and its name.
#[derive(Debug, Clone)]
pub struct LeakMesh {
    /// Name in the report.
    pub name: String,
    /// The mesh.
    pub mesh: Mesh,
}

/// Double cones ("spindles"): a ring of `k` vertices and two apexes, each apex the centre of
/// a fan of `k` thin triangles, for `k` = 97, 1024 and 4099 and apex heights from 2% (a nearly
/// flat fan) to 100% of the radius, rotated and moved so that no coordinate is round.
pub fn fan_mesh() -> Mesh {
    let mut b = MeshBuilder::new();
    let m = b.material("fan", Vec3::ONE);
    let cones = [(97u32, 0.02f32, 0.6f32), (1024, 0.3, 0.05), (4099, 1.0, 1.3), (1024, 0.02, 2.1)];
    for (i, &(k, h, angle)) in cones.iter().enumerate() {
        let mut part = Part::default();
        for j in 0..k {
            let a = std::f32::consts::TAU * j as f32 / k as f32;
            part.positions.push(Vec3::new(a.cos(), 0.0, a.sin()));
        }
        part.positions.push(Vec3::new(0.0, h, 0.0));
        part.positions.push(Vec3::new(0.0, -h, 0.0));
        let (top, bottom) = (k, k + 1);
        for j in 0..k {
            let next = (j + 1) % k;
            // Outward: counter-clockwise seen from outside.
            part.triangles.push([top, next, j]);
            part.triangles.push([bottom, j, next]);
        }
        let rot = Quat::from_euler(glam::EulerRot::XYZ, angle, 0.7 * angle + 0.1, 0.3);
        let at = Vec3::new(2.7 * i as f32 + 0.31, 0.17 * i as f32 - 0.4, 0.11);
        b.add(&part.transformed(glam::Affine3A::from_rotation_translation(rot, at)), m);
    }
    b.finish()
}

/// A geodesic sphere of 20,480 triangles, radius 1.3, rotated and moved off the origin.
pub fn sphere_mesh() -> Mesh {
    let mut b = MeshBuilder::new();
    let m = b.material("sphere", Vec3::ONE);
    let place = glam::Affine3A::from_rotation_translation(
        Quat::from_rotation_y(0.4) * Quat::from_rotation_x(0.9),
        Vec3::new(0.37, -1.21, 2.05),
    );
    b.add(&Part::icosphere(1.3, 5).transformed(place), m);
    b.finish()
}

/// The Stanford bunny in the shared scenes folder (the first file whose name contains
/// `bunny`), if there is one.
pub fn bunny_path() -> Option<std::path::PathBuf> {
    scenes::shared_scene_files()
        .into_iter()
        .find(|p| p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.contains("bunny")))
}

/// Every mesh name [`mesh_by_name`] knows, in report order.
pub fn mesh_names() -> Vec<&'static str> {
    let mut names = vec!["fan", "sphere-20k"];
    names.extend(BUILTIN);
    names.push("bunny");
    names
}

/// The test mesh `name`: `fan`, `sphere-20k`, a name of [`BUILTIN`], or `bunny` (`Ok(None)`
/// when the shared scenes folder has no bunny).
pub fn mesh_by_name(name: &str) -> Result<Option<LeakMesh>, Error> {
    let mesh = match name {
        "fan" => fan_mesh(),
        "sphere-20k" => sphere_mesh(),
        "bunny" => match bunny_path() {
            Some(path) => scenes::load_obj(&path)?.0,
            None => return Ok(None),
        },
        _ if BUILTIN.contains(&name) => scenes::builtin::by_name(name).ok_or_else(|| Error::Usage(name.into()))?.mesh,
        _ => {
            return Err(Error::Usage(format!("'{name}' is not a leak-test mesh (one of {})", mesh_names().join(", "))));
        }
    };
    Ok(Some(LeakMesh { name: name.to_string(), mesh }))
}

/// The shared edges and vertices of a mesh, with its triangles' unit normals.
#[derive(Debug, Default)]
pub struct Targets {
    /// Shared edges: the two vertices and the two triangles.
    pub edges: Vec<([u32; 2], [u32; 2])>,
    /// Shared vertices and the triangles around each: `(vertex, start, end)` into `fans`.
    pub vertices: Vec<(u32, u32, u32)>,
    /// The triangles around the shared vertices, concatenated.
    pub fans: Vec<u32>,
    /// Per vertex of the mesh, its index in `vertices`, or `u32::MAX` if it is not shared.
    pub fan_of: Vec<u32>,
    /// Unit normal of each triangle (`(b - a) x (c - a)`, in `f64`; zero if degenerate).
    pub normals: Vec<DVec3>,
}

impl Targets {
    /// The shared edges and vertices of `mesh` (see the module docs).
    pub fn of(mesh: &Mesh) -> Targets {
        let normals: Vec<DVec3> = (0..mesh.triangle_count())
            .map(|t| {
                let [a, b, c] = mesh.triangle(t).map(|p| p.as_dvec3());
                (b - a).cross(c - a).normalize_or_zero()
            })
            .collect();
        // Per undirected edge: its triangles and the direction each uses it in.
        let mut uses: HashMap<(u32, u32), Vec<(u32, bool)>> = HashMap::new();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                let (p, q) = (tri[k], tri[(k + 1) % 3]);
                uses.entry((p.min(q), p.max(q))).or_default().push((t as u32, p < q));
            }
        }
        let shared = |u: &[(u32, bool)]| {
            u.len() == 2 && u[0].1 != u[1].1 && u.iter().all(|&(t, _)| normals[t as usize] != DVec3::ZERO)
        };
        let mut edges: Vec<([u32; 2], [u32; 2])> =
            uses.iter().filter(|(_, u)| shared(u)).map(|(&(p, q), u)| ([p, q], [u[0].0, u[1].0])).collect();
        edges.sort_unstable();
        // A vertex is shared when every edge at it is.
        let mut open = vec![false; mesh.positions.len()];
        let mut around: Vec<Vec<u32>> = vec![Vec::new(); mesh.positions.len()];
        for (&(p, q), u) in &uses {
            if !shared(u) {
                open[p as usize] = true;
                open[q as usize] = true;
            }
        }
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for &v in tri {
                around[v as usize].push(t as u32);
            }
        }
        let (mut vertices, mut fans) = (Vec::new(), Vec::new());
        let mut fan_of = vec![u32::MAX; mesh.positions.len()];
        for (v, tris) in around.iter().enumerate() {
            if !open[v] && tris.len() >= 3 {
                let start = fans.len() as u32;
                fans.extend_from_slice(tris);
                fan_of[v] = vertices.len() as u32;
                vertices.push((v as u32, start, fans.len() as u32));
            }
        }
        Targets { edges, vertices, fans, fan_of, normals }
    }

    /// Appends the normals of the triangles around shared vertex `v` to `out`; false if `v`
    /// is not shared.
    fn fan_normals(&self, v: u32, out: &mut Vec<DVec3>) -> bool {
        let Some(&(_, s, e)) = self.vertices.get(self.fan_of[v as usize] as usize) else { return false };
        out.extend(self.fans[s as usize..e as usize].iter().map(|&t| self.normals[t as usize]));
        true
    }
}

/// A direction crossing every plane of `normals` at `|cos| >= MIN_COS` with the same sign,
/// near the mean normal (entering or leaving, picked at random), or `None` after a few tries.
fn crossing_direction(normals: &[DVec3], rng: &mut Rng) -> Option<DVec3> {
    let mean = normals.iter().copied().sum::<DVec3>().normalize_or_zero();
    if mean == DVec3::ZERO {
        return None;
    }
    let unit = |rng: &mut Rng| loop {
        let v = DVec3::new(
            f64::from(rng.range(-1.0, 1.0)),
            f64::from(rng.range(-1.0, 1.0)),
            f64::from(rng.range(-1.0, 1.0)),
        );
        if v.length_squared() <= 1.0 && v.length_squared() > 1e-6 {
            return v.normalize();
        }
    };
    for attempt in 0..8 {
        let sign = if rng.next_u64() & 1 == 0 { 1.0 } else { -1.0 };
        let spread = f64::from(rng.range(0.0, 0.9)) / f64::from(1 + attempt);
        let d = (sign * mean + spread * unit(rng)).normalize_or_zero();
        if normals.iter().all(|&n| sign * d.dot(n) >= MIN_COS) {
            return Some(d);
        }
    }
    None
}

/// `count` rays at the targets of `mesh` (see the module docs), from the random generator
/// seeded with `seed`; also the number of targets skipped for want of a crossing direction.
pub fn leak_rays(mesh: &Mesh, targets: &Targets, count: usize, seed: u64) -> (Vec<Ray>, usize) {
    let mut rng = Rng::new(seed);
    let mut rays = Vec::with_capacity(count);
    let mut skipped = 0;
    let (lo, hi) = mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
    let diag = f64::from((hi - lo).length()).max(1e-30);
    let (ne, nv) = (targets.edges.len() as u64, targets.vertices.len() as u64);
    if ne + nv == 0 {
        return (rays, 0);
    }
    let mut normals = Vec::new();
    while rays.len() < count && skipped <= 10 * count + 1000 {
        // Half the targets on edges, half on vertices.
        let on_edge = nv == 0 || (ne > 0 && rng.next_u64() & 1 == 0);
        let distance = diag * f64::from(rng.range(0.02, 1.5));
        normals.clear();
        let x: Vec3 = if on_edge {
            let ([p, q], [t0, t1]) = targets.edges[(rng.next_u64() % ne) as usize];
            let (a, b) = (mesh.positions[p as usize], mesh.positions[q as usize]);
            normals.extend([targets.normals[t0 as usize], targets.normals[t1 as usize]]);
            let x = if rng.next_u64() & 1 == 0 { 0.5 * (a + b) } else { a + rng.range(0.0, 1.0) * (b - a) };
            // Within reach of the aim's error of an end, the ray may cross the surface
            // around that vertex instead: every triangle there must be crossed too.
            let reach = NEAR_VERTEX * (f64::from(x.abs().max_element()) + 2.0 * distance);
            let mut shared = true;
            for (v, at) in [(p, a), (q, b)] {
                if f64::from((x - at).length()) < reach {
                    shared &= targets.fan_normals(v, &mut normals);
                }
            }
            if !shared {
                skipped += 1;
                continue;
            }
            x
        } else {
            let (v, s, e) = targets.vertices[(rng.next_u64() % nv) as usize];
            normals.extend(targets.fans[s as usize..e as usize].iter().map(|&t| targets.normals[t as usize]));
            mesh.positions[v as usize]
        };
        let Some(d) = crossing_direction(&normals, &mut rng) else {
            skipped += 1;
            continue;
        };
        let origin = (x.as_dvec3() - distance * d).as_vec3();
        let dir = d.as_vec3().normalize();
        // The target's distance along the ray as it is in f32.
        let t_target = (x.as_dvec3() - origin.as_dvec3()).dot(dir.as_dvec3()) as f32;
        rays.push(Ray::new(origin, dir, 0.0, leak_t_max(origin, x, t_target)));
    }
    (rays, skipped)
}

/// The rays of `rays` that hit nothing in their interval (leaks), traced on the rayon pool.
pub fn count_leaks(tree: &KdTree, rays: &[Ray]) -> u64 {
    rays.par_chunks(1024).map(|c| c.iter().filter(|r| !tree.occluded(r)).count() as u64).sum()
}

/// One row of the report: a mesh traced with one intersector.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct LeakResult {
    /// Mesh name (`all` for an intersector's total).
    pub mesh: String,
    /// Its triangles.
    pub triangles: u64,
    /// `wald` or `watertight`.
    pub intersector: String,
    /// Rays traced.
    pub rays: u64,
    /// Seconds of tracing (the rays' generation and the build are not timed).
    pub trace_secs: f64,
    /// `rays / trace_secs / 1e6`.
    pub mrays_per_s: f64,
    /// Rays that passed the surface without a hit.
    pub leaks: u64,
    /// `leaks / rays * 1e6`.
    pub leaks_per_million: f64,
    /// Targets skipped for want of a direction crossing every face at them.
    pub skipped_targets: u64,
    /// Threads of the pool.
    pub threads: usize,
}

/// Measures `mesh` with `rays` rays for each intersector (the same rays), seeded by `seed`.
pub fn measure(mesh: &LeakMesh, rays: u64, seed: u64) -> Result<Vec<LeakResult>, Error> {
    let targets = Targets::of(&mesh.mesh);
    let intersectors = [Intersector::Wald, Intersector::Watertight];
    let mut trees = Vec::new();
    for intersector in intersectors {
        let config = BuildConfig { intersector, ..BuildConfig::default() };
        trees.push(KdTree::build(&mesh.mesh.positions, &mesh.mesh.triangles, &config)?);
    }
    let mut rng = Rng::new(seed);
    let (mut traced, mut skipped) = (0u64, 0u64);
    let (mut secs, mut leaks) = ([0.0f64; 2], [0u64; 2]);
    while traced < rays {
        let n = (rays - traced).min(BATCH as u64) as usize;
        let (batch, s) = leak_rays(&mesh.mesh, &targets, n, rng.next_u64());
        skipped += s as u64;
        if batch.is_empty() {
            break;
        }
        for (i, tree) in trees.iter().enumerate() {
            let start = Instant::now();
            leaks[i] += count_leaks(tree, &batch);
            secs[i] += start.elapsed().as_secs_f64();
        }
        traced += batch.len() as u64;
    }
    Ok(intersectors
        .iter()
        .enumerate()
        .map(|(i, x)| row(&mesh.name, mesh.mesh.triangle_count() as u64, x.name(), traced, secs[i], leaks[i], skipped))
        .collect())
}

fn row(mesh: &str, triangles: u64, intersector: &str, rays: u64, secs: f64, leaks: u64, skipped: u64) -> LeakResult {
    LeakResult {
        mesh: mesh.to_string(),
        triangles,
        intersector: intersector.to_string(),
        rays,
        trace_secs: secs,
        mrays_per_s: trace::timing::mrays_per_s(rays, secs),
        leaks,
        leaks_per_million: if rays > 0 { leaks as f64 * 1e6 / rays as f64 } else { 0.0 },
        skipped_targets: skipped,
        threads: rayon::current_num_threads(),
    }
}

/// The per-intersector totals of `results` (mesh `all`; Mrays/s over the summed time).
pub fn totals(results: &[LeakResult]) -> Vec<LeakResult> {
    ["wald", "watertight"]
        .iter()
        .filter_map(|&x| {
            let rows: Vec<&LeakResult> = results.iter().filter(|r| r.intersector == x).collect();
            (!rows.is_empty()).then(|| {
                let sum = |f: fn(&LeakResult) -> u64| rows.iter().map(|r| f(r)).sum::<u64>();
                let secs = rows.iter().map(|r| r.trace_secs).sum();
                row("all", sum(|r| r.triangles), x, sum(|r| r.rays), secs, sum(|r| r.leaks), sum(|r| r.skipped_targets))
            })
        })
        .collect()
}

/// The results as a markdown table: mesh, triangles, intersector, rays, Mrays/s, leaks and
/// leaks per million.
pub fn markdown_table(results: &[LeakResult]) -> String {
    let mut out = String::from(
        "| mesh | triangles | intersector | rays | Mrays/s | leaks | leaks per million |\n|---|---:|---|---:|---:|---:|---:|\n",
    );
    for r in results {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {:.2} | {} | {:.2} |",
            r.mesh, r.triangles, r.intersector, r.rays, r.mrays_per_s, r.leaks, r.leaks_per_million
        );
    }
    out
}

impl std::fmt::Display for LeakResult {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(markdown_table(std::slice::from_ref(self)).trim_end())
    }
}

/// The leak test's report: the rows of every mesh and intersector, their totals and the
/// notes for the user.
#[derive(Clone, Debug, PartialEq)]
pub struct LeaksReport {
    /// One row per mesh and intersector (`wald`, then `watertight`), meshes in the order
    /// asked.
    pub results: Vec<LeakResult>,
    /// The per-intersector totals of `results` ([`totals`]).
    pub totals: Vec<LeakResult>,
    /// Notes for the user, such as a mesh skipped because its file is missing.
    pub notes: Vec<String>,
}

impl LeaksReport {
    /// Every row, the totals last: the rows of the table, or the JSON objects in order.
    pub fn rows(&self) -> impl Iterator<Item = &LeakResult> {
        self.results.iter().chain(&self.totals)
    }
}

/// The markdown table of every row, the totals last (one line each, ending with a newline).
impl std::fmt::Display for LeaksReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let rows: Vec<LeakResult> = self.rows().cloned().collect();
        f.write_str(&markdown_table(&rows))
    }
}

/// The leak test: every mesh of `config` (all of [`mesh_names`] when none is named),
/// `config.rays` rays per intersector split evenly between them, each mesh with its own
/// seed; on the rayon pool of the caller.
///
/// A missing bunny is skipped with a note; an unknown mesh name, or no mesh left to test, is
/// a usage error.
pub fn run(config: &LeaksConfig, progress: &dyn Progress) -> Result<LeaksReport, Error> {
    let names: Vec<String> = if config.meshes.is_empty() {
        mesh_names().iter().map(|s| s.to_string()).collect()
    } else {
        config.meshes.clone()
    };
    let (mut meshes, mut notes) = (Vec::new(), Vec::new());
    for name in &names {
        match mesh_by_name(name)? {
            Some(m) => meshes.push(m),
            None => notes.push("no bunny in the shared scenes folder, skipped".to_string()),
        }
    }
    if meshes.is_empty() {
        return Err(Error::Usage("no mesh to test".into()));
    }
    let per_mesh = config.rays.div_ceil(meshes.len() as u64);
    let task = progress.task("leaks", Some(meshes.len() as u64));
    let mut results = Vec::new();
    for (i, mesh) in meshes.iter().enumerate() {
        results.extend(measure(mesh, per_mesh, 0x5eed_0000 + i as u64)?);
        task.inc();
    }
    task.finish();
    let totals = totals(&results);
    Ok(LeaksReport { results, totals, notes })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_meshes_have_only_shared_edges_and_a_fan_shares_its_apex() {
        let fan = fan_mesh();
        let t = Targets::of(&fan);
        assert_eq!(t.edges.len(), 3 * fan.triangle_count() / 2, "every edge of a closed mesh is shared");
        assert_eq!(t.vertices.len(), fan.positions.len());
        // The apex of the 4099-triangle fan.
        assert!(t.vertices.iter().any(|&(_, s, e)| e - s == 4099));
        // An open mesh: a lone triangle has no shared edge or vertex.
        let tri = scenes::builtin::by_name("triangle").unwrap().mesh;
        let t = Targets::of(&tri);
        assert!(t.edges.is_empty() && t.vertices.is_empty());
    }

    #[test]
    fn rays_cross_every_face_at_their_target_and_end_just_past_it() {
        let mesh = scenes::builtin::by_name("cube").unwrap().mesh;
        let targets = Targets::of(&mesh);
        let (rays, skipped) = leak_rays(&mesh, &targets, 2000, 7);
        assert_eq!((rays.len(), skipped), (2000, 0), "a cube's edges and corners have crossing directions");
        for r in &rays {
            // The interval ends just past the cube's surface: one coordinate at +-1.
            let end = r.at(r.t_max);
            assert!((end.abs().max_element() - 1.0).abs() < 1e-3, "{end}");
            assert!(r.dir.is_normalized());
        }
        // Rays from a seed are the same every time.
        assert_eq!(leak_rays(&mesh, &targets, 50, 7).0, rays[..50].to_vec());
    }

    #[test]
    fn a_ray_that_stops_short_or_misses_is_a_leak() {
        let mesh = scenes::builtin::by_name("cube").unwrap().mesh;
        let tree = KdTree::build(&mesh.positions, &mesh.triangles, &BuildConfig::default()).unwrap();
        let o = Vec3::new(0.0, 0.0, -3.0);
        let through = Ray::new(o, Vec3::Z, 0.0, leak_t_max(o, Vec3::new(0.0, 0.0, -1.0), 2.0));
        let short = Ray::new(Vec3::new(0.0, 0.0, -3.0), Vec3::Z, 0.0, 1.99);
        let beside = Ray::new(Vec3::new(0.0, 2.0, -3.0), Vec3::Z, 0.0, 10.0);
        assert_eq!(count_leaks(&tree, &[through]), 0);
        assert_eq!(count_leaks(&tree, &[short, beside, through]), 2);
    }

    #[test]
    fn run_splits_the_rays_and_reports_rows_then_totals() {
        let config = LeaksConfig { rays: 300, meshes: vec!["cube".into(), "touching-boxes".into()] };
        let report = run(&config, &trace::progress::Quiet).unwrap();
        assert!(report.notes.is_empty());
        assert_eq!(report.results.len(), 4);
        assert!(report.results.iter().all(|r| r.rays == 150));
        assert_eq!(report.totals.iter().map(|r| (r.mesh.as_str(), r.rays)).collect::<Vec<_>>(), [("all", 300); 2]);
        let rows: Vec<LeakResult> = report.rows().cloned().collect();
        assert_eq!(report.to_string(), markdown_table(&rows));
        let unknown = LeaksConfig { meshes: vec!["teapot".into()], ..LeaksConfig::default() };
        assert!(run(&unknown, &trace::progress::Quiet).unwrap_err().to_string().contains("teapot"));
    }
}
