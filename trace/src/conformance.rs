//! The conformance harness: every registered method gives the single-ray answer, on every
//! built-in scene and view, the shared scenes, random soups and the named hard cases.
//!
//! The model is Embree's `verify` (one verifier runs every scene through every path): a
//! [`Plan`] names methods and the single-ray twin each must agree with ([`Check`]), and
//! [`run`] traces every [`Case`], with each intersector of the plan, through the frame driver
//! exactly as `rttest render` does, comparing per ray:
//!
//! 1. primary tiles (the frame driver's tile order) against the twin's hits;
//! 2. hard shadows ([`crate::frame::shadow_pass`], on the twin's hits) per pixel;
//! 3. soft shadows ([`crate::frame::soft_pass`], 16 rays per point) per pixel;
//! 4. a ray stream ([`crate::frame::stream_pass`] and [`crate::frame::stream_occluded_pass`])
//!    mixing camera rays (runs sharing an origin: packets and frusta), scattered origins,
//!    negative `t_min`, origins on surfaces, and axis-parallel rays with `0.0` and `-0.0`
//!    direction components;
//! 5. on the cases marked for it (soups, hard cases), the twin itself against the
//!    brute-force oracle (`kdtree::BruteForce::check`) on the stream and the primary rays.
//!
//! How close is close enough is the check's [`Rule`]: our methods on our tree must give the
//! twin's hit or a tie ([`Rule::Exact`]); a method with its own triangle test against ours
//! may differ at ties and a handful of edge rays ([`Rule::Loose`]). `trace/tests/conformance.rs`
//! runs [`Plan::ours`] for every method of [`Registry::ours`]; `baselines/tests/conformance.rs`
//! the baselines against their own single rays and, loosely, against ours.

use std::cell::OnceCell;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt::Write as _;

use cones::shadows::{SAMPLES, light_samples, shadow_rays};
use glam::Vec3;
use kdtree::{BruteForce, BuildConfig, Hit, Intersector, KdTree, Ray};
use scenes::builtin::shapes::Rng;
use scenes::{Camera, Material, Mesh, Scene, SphereLight};

use crate::frame::{SoftStats, TileLayout, View};
use crate::method::{hard_shadow_segment, primary_ray};
use crate::registry::{KDTREE, Options, Registry, SoftGrouping, Structures};
use crate::soft;
use crate::ties::{coplanar, near_shared};

/// The tile sizes every tiled method is checked at (and the frame driver's tiles of the
/// others): 4, 8 and 16, with odd image sizes so that edge tiles are cut.
pub const TILES: [u32; 3] = [4, 8, 16];

/// Both triangle tests of our tree.
pub const INTERSECTORS: [Intersector; 2] = [Intersector::Wald, Intersector::Watertight];

/// Soft-shadow light radius in Sponza units (thesis Table 4.6's larger light).
pub const LIGHT_RADIUS: f32 = 2.0;

/// Uniform in `[-1, 1)`.
fn signed(rng: &mut Rng) -> f32 {
    rng.range(-1.0, 1.0)
}

/// A vector with components in `[-1, 1)`.
fn vec3(rng: &mut Rng) -> Vec3 {
    Vec3::new(signed(rng), signed(rng), signed(rng))
}

/// One scene with its cameras and ray stream.
#[derive(Clone, Debug)]
pub struct Case {
    /// What it is, for messages: `atrium`, `soup 3 x1e6`, ...
    pub name: String,
    /// The scene: mesh (triangle `i` is the tree's primitive `i`), point light.
    pub scene: Scene,
    /// The cameras, named.
    pub cameras: Vec<(String, Camera)>,
    /// The stream of [`ray_list`].
    pub rays: Vec<Ray>,
    /// Whether the single-ray twins are checked against the brute-force oracle here (small
    /// scenes: the oracle tests every triangle per ray).
    pub oracle: bool,
}

impl Case {
    /// A case of `scene` seen by `cameras`, its stream from the first camera
    /// ([`ray_list`], seeded by `seed`).
    pub fn new(name: impl Into<String>, scene: Scene, cameras: Vec<(String, Camera)>, oracle: bool, seed: u64) -> Case {
        let rays = ray_list(&scene, cameras.first().map(|c| &c.1), seed);
        Case { name: name.into(), scene, cameras, rays, oracle }
    }

    /// A case of `scene` at every view, `width` x `height`.
    pub fn views(name: impl Into<String>, scene: Scene, width: u32, height: u32, oracle: bool) -> Case {
        let cameras =
            scene.views.iter().filter_map(|v| Some((v.name.clone(), v.camera(width, height)?))).collect::<Vec<_>>();
        Case::new(name, scene, cameras, oracle, 7)
    }
}

/// A ray stream over `scene` (`camera`'s primary rays first, when given): every kind of ray
/// a stream may carry.
///
/// - the camera's rays, row by row: runs of one origin (packets, frusta, cones);
/// - 300 rays from scattered origins in the scene's box, a third axis-parallel with `0.0` and
///   `-0.0` components, every fifth with a negative `t_min`, every seventh unbounded;
/// - 200 rays from points on triangles (origins on surfaces), in random directions;
/// - runs of 70 rays from one point (the box centre, then a point on a triangle) in the six
///   axis directions (with signed zeros) and random ones: runs longer than a frustum's 64.
pub fn ray_list(scene: &Scene, camera: Option<&Camera>, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    let (lo, hi) = scene.mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
    let (centre, half) = (0.5 * (lo + hi), 0.5 * (hi - lo).max(Vec3::splat(1e-3 * (hi - lo).max_element())));
    let diag = 2.0 * half.length();
    let mut rays: Vec<Ray> = Vec::new();
    if let Some(camera) = camera {
        for y in 0..camera.height {
            rays.extend((0..camera.width).map(|x| primary_ray(camera, x, y)));
        }
    }
    let nonzero = |d: Vec3| if d == Vec3::ZERO { Vec3::X } else { d };
    for i in 0..300 {
        let o = centre + vec3(&mut rng) * half * 1.2;
        let d = match i % 6 {
            0 => Vec3::new(signed(&mut rng), 0.0, -0.0),
            2 => Vec3::new(-0.0, 0.0, signed(&mut rng)),
            4 => Vec3::new(0.0, signed(&mut rng), -0.0),
            _ => vec3(&mut rng),
        };
        let t_min = if i % 5 == 0 { -0.3 * diag } else { 0.0 };
        let t_max = if i % 7 == 0 { f32::INFINITY } else { 1.5 * diag };
        rays.push(Ray::new(o, nonzero(d), t_min, t_max));
    }
    let tris = scene.mesh.triangle_count();
    let on_surface = |rng: &mut Rng| {
        if tris == 0 {
            return centre;
        }
        let t = scene.mesh.triangle((rng.next_u64() % tris as u64) as usize);
        let (u, v) = (0.5 * (signed(rng) + 1.0), 0.5 * (signed(rng) + 1.0));
        let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
        t[0] + u * (t[1] - t[0]) + v * (t[2] - t[0])
    };
    for _ in 0..200 {
        let o = on_surface(&mut rng);
        rays.push(Ray::new(o, nonzero(vec3(&mut rng)), 0.0, f32::INFINITY));
    }
    for o in [centre, on_surface(&mut rng)] {
        let axes = [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z, Vec3::new(-0.0, 1.0, -0.0)];
        for i in 0..70 {
            let d = axes.get(i % 10).copied().unwrap_or_else(|| nonzero(vec3(&mut rng)));
            rays.push(Ray::new(o, d, 0.0, f32::INFINITY));
        }
    }
    rays
}

/// A scene of a triangle soup: one mesh vertex per corner, lights and a default view from
/// its bounds ([`Scene::from_mesh`]).
pub fn soup_scene(name: &str, tris: &[[Vec3; 3]]) -> Scene {
    let n = tris.len() as u32;
    let mesh = Mesh {
        positions: tris.iter().flatten().copied().collect(),
        triangles: (0..n).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect(),
        normals: None,
        material_ids: vec![0; n as usize],
        materials: vec![Material::default()],
        prim_ids: (0..n).collect(),
    };
    Scene::from_mesh(name, mesh)
}

/// A random soup of `n` triangles in `[-1, 1]^3`: half its vertices on a grid of quarters
/// (shared vertices, triangles in axis planes), and flat triangles among them: collinear
/// corners, repeated corners, a zero-width sliver.
pub fn random_soup(seed: u64, n: usize) -> Vec<[Vec3; 3]> {
    let mut rng = Rng::new(seed);
    let vertex = |rng: &mut Rng| {
        let v = vec3(rng);
        if signed(rng) < 0.0 { (v * 4.0).round() * 0.25 } else { v }
    };
    (0..n)
        .map(|i| {
            let (a, b, c) = (vertex(&mut rng), vertex(&mut rng), vertex(&mut rng));
            match i % 11 {
                3 => [a, b, 0.5 * (a + b)],
                5 => [a, a, b],
                7 => [a, b, Vec3::new(a.x, b.y, a.z)],
                9 => [a, b, a + 1e-7 * (b - a)],
                _ => [a, b, c],
            }
        })
        .collect()
}

/// The scene moved: every position `p * scale + shift`, views and lights with it.
pub fn transformed(scene: &Scene, scale: f32, shift: Vec3) -> Scene {
    let mut out = scene.clone();
    let f = |p: Vec3| p * scale + shift;
    out.mesh.positions.iter_mut().for_each(|p| *p = f(*p));
    for v in &mut out.views {
        (v.eye, v.target) = (f(v.eye), f(v.target));
    }
    out.point_light.position = f(out.point_light.position);
    out
}

/// Every built-in scene but those of `skip`, at every view, `width` x `height`; the scenes
/// of `default_only` at their default view only.
pub fn builtin_cases(width: u32, height: u32, skip: &[&str], default_only: &[&str]) -> Vec<Case> {
    let names = scenes::builtin::NAMES.iter().filter(|n| !skip.contains(n));
    names
        .map(|&name| {
            let mut scene = scenes::load_scene(name).expect("built-in scene");
            if default_only.contains(&name) {
                scene.views.truncate(1);
            }
            let small = scene.mesh.triangle_count() <= 64;
            Case::views(name, scene, width, height, small)
        })
        .collect()
}

/// The scenes of the shared folder (`scenes::shared_scenes_dir`), each at its default view,
/// `width` x `height`; none when the folder is absent.
pub fn shared_cases(width: u32, height: u32) -> Vec<Case> {
    let files = scenes::shared_scene_files();
    files
        .iter()
        .map(|f| {
            let scene = scenes::load_scene(&f.to_string_lossy()).expect("shared scene loads");
            let camera = scene.default_view().camera(width, height).expect("finite view");
            Case::new(scene.name.clone(), scene, vec![("default".into(), camera)], false, 7)
        })
        .collect()
}

/// [`shared_cases`] for a test of the shared scenes: `None`, after a note on stderr, when the
/// folder is absent or holds no scene (the test is then skipped).
pub fn shared_cases_or_skip(width: u32, height: u32) -> Option<Vec<Case>> {
    let cases = shared_cases(width, height);
    if cases.is_empty() {
        eprintln!("no shared scenes folder: skipped");
        return None;
    }
    Some(cases)
}

/// Random soups (with flat triangles), each seen from outside and from inside with a
/// 150-degree field of view, checked against the oracle too.
pub fn soup_cases(count: u64) -> Vec<Case> {
    (0..count)
        .map(|seed| {
            let tris = random_soup(seed, 40 + 40 * seed as usize);
            let scene = soup_scene(&format!("soup {seed}"), &tris);
            let outside = scene.default_view().camera(23, 17).expect("finite soup");
            let inside = Camera::look_at(Vec3::new(0.05, 0.1, 0.02), Vec3::new(0.9, -0.2, 0.4), 150.0, 21, 15)
                .expect("a fixed camera");
            Case::new(
                format!("soup {seed}"),
                scene,
                vec![("outside".into(), outside), ("inside".into(), inside)],
                true,
                seed,
            )
        })
        .collect()
}

/// The named hard cases:
/// - the atrium seen from eyes exactly on split planes of its tree, looking along an axis
///   with an odd width so that the centre column lies in the plane (both children visited);
/// - tiny and huge coordinates: the arena scaled by 1e-3 and 1e3, a soup by 1e-6 and 1e6;
/// - far from the origin: the arena and a soup translated by 1e5 (the tree is built there).
///
/// (Rays with zero direction components, origins on surfaces and negative `t_min` are in
/// every case's stream; a camera in a triangle's axis plane is the built-in
/// `axis-plane-triangle`; flat triangles are in every soup.)
pub fn hard_cases() -> Vec<Case> {
    let mut out = Vec::new();
    let atrium = scenes::load_scene("atrium").expect("built-in scene");
    let tree = KdTree::build(&atrium.mesh.positions, &atrium.mesh.triangles, &BuildConfig::default())
        .expect("the atrium builds");
    let view = atrium.default_view();
    let mut cameras = Vec::new();
    for node in tree.nodes().iter().filter(|n| !n.is_leaf() && n.axis() != 1).take(4) {
        let axis = node.axis();
        let mut eye = view.eye;
        eye[axis] = node.split();
        let mut target = eye;
        target[2 - axis] += 10.0;
        let camera = Camera::look_at(eye, target, 70.0, 33, 21).expect("a level camera");
        assert_eq!(camera.pixel_ray(16, 10).1[axis], 0.0, "the centre ray lies in the split plane");
        cameras.push((format!("eye on split {axis} = {}", node.split()), camera));
    }
    out.push(Case::new("atrium, eyes on split planes", atrium, cameras, false, 11));
    let arena = scenes::load_scene("arena").expect("built-in scene");
    for (scale, shift) in [(1e-3, Vec3::ZERO), (1e3, Vec3::ZERO), (1.0, Vec3::splat(1e5))] {
        let scene = transformed(&arena, scale, shift);
        let camera = scene.default_view().camera(25, 19).expect("finite view");
        out.push(Case::new(format!("arena x{scale} + {shift}"), scene, vec![("default".into(), camera)], false, 12));
    }
    let soup = soup_scene("soup", &random_soup(99, 60));
    for (scale, shift) in [(1e-6, Vec3::ZERO), (1e6, Vec3::ZERO), (1.0, Vec3::new(1e5, -1e5, 1e5))] {
        let scene = transformed(&soup, scale, shift);
        let camera = scene.default_view().camera(19, 13).expect("finite view");
        out.push(Case::new(format!("soup x{scale} + {shift}"), scene, vec![("default".into(), camera)], true, 13));
    }
    out
}

/// How close a method's answers must be to its reference's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Rule {
    /// The reference's hit, or a tie: another triangle the test hits at exactly the same
    /// distance; the same any-hit answers. Our methods against `mono` on our tree.
    Exact,
    /// [`Rule::Exact`], or a difference the oracle accepts on our tree
    /// (`BruteForce::equivalent_hits` / `equivalent_occlusion`: rounding artefacts on
    /// triangles the ray cannot reach in exact arithmetic).
    Equivalent,
    /// The same tracer's other kernel (Embree's packets against its single rays): the
    /// reference's hit, or a tie within 1e-4 of its distance on a triangle that is either
    /// an edge neighbour — sharing a vertex or an edge with the reference's, whose point lies
    /// within 1e-4 of the triangles' size from it (the kernels round `t` differently by an
    /// ulp there, and the nearer neighbour wins) — or a coincident face, coplanar with it
    /// and holding both hit points (two faces hit at one `t`: the traversal order picks one); or, where the reference's
    /// hit (or the method's) lies on an edge of its triangle (a barycentric within 1e-6 of
    /// 0: a ray grazing a silhouette edge, as axis-parallel rays along the touching boxes'
    /// and the scaled arena's faces) or within the origin's rounding (64 ulps of its
    /// coordinates: a ray starting on a surface), a farther hit or a miss. Any-hit answers that differ
    /// (the same grazing rays) count against `Plan::loose_per_10k`.
    Ties,
    /// Another tracer's triangle test against ours: the same triangle, or another within
    /// 1e-4 of the distance (a tie at a shared edge or on coincident faces), or either hit on
    /// a triangle whose plane holds the ray (a measure-zero case each test answers its own
    /// way), on all but
    /// `Plan::loose_per_10k` in 10,000 answers; everything else is counted and reported.
    Loose,
}

/// One method checked against one reference, both by full registry name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Check {
    /// The method: `mft-8`, `embree-16`.
    pub method: String,
    /// Its options (the frame driver's tile for untiled methods; culling).
    pub options: Options,
    /// The single-ray method it must agree with: `mono`, `embree-1`.
    pub reference: String,
    /// How closely.
    pub rule: Rule,
}

/// Which brute force a single-ray twin is checked against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OracleTest {
    /// The tree's triangle test (our methods).
    Tree,
    /// Always this test (a baseline that runs our Wald records whatever the tree's test).
    Fixed(Intersector),
}

/// A single-ray method checked against the brute-force oracle on the cases marked for it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OracleCheck {
    /// The method's full name.
    pub method: String,
    /// Which oracle.
    pub test: OracleTest,
    /// [`Rule::Exact`]: `BruteForce::check` must accept every answer; [`Rule::Loose`]:
    /// rejections are counted like loose disagreements.
    pub rule: Rule,
}

/// What to check.
#[derive(Clone, Debug)]
pub struct Plan {
    /// Methods against references.
    pub checks: Vec<Check>,
    /// Single-ray twins against the oracle.
    pub oracles: Vec<OracleCheck>,
    /// The trees' triangle tests.
    pub intersectors: Vec<Intersector>,
    /// How many answers in 10,000 may disagree under [`Rule::Loose`] (per check and query).
    pub loose_per_10k: f64,
}

impl Plan {
    /// Every method of `registry` on our kd-tree but `mono` itself against `mono`, exactly
    /// ([`Rule::Exact`]), at tiles 4, 8 and 16 (tiled methods also without packet/leaf
    /// culling at 8, and those with a per-point soft-shadow kernel also with it at 8), with
    /// both intersectors; `mono` against the oracle.
    pub fn ours(registry: &Registry) -> Plan {
        let mut checks = Vec::new();
        for e in registry.entries().iter().filter(|e| e.structure == KDTREE) {
            for tile in TILES {
                if e.name == "mono" {
                    continue; // the reference itself
                }
                let method = if e.tiled { format!("{}-{tile}", e.name) } else { e.name.to_string() };
                let options = Options { tile, ..Options::default() };
                checks.push(Check { method: method.clone(), options, reference: "mono".into(), rule: Rule::Exact });
                if e.per_point.is_some() && tile == 8 {
                    let options = Options { soft: SoftGrouping::PerPoint, ..options };
                    checks.push(Check { method: method.clone(), options, reference: "mono".into(), rule: Rule::Exact });
                }
                if e.tiled && tile == 8 {
                    let options = Options { culling: false, ..options };
                    checks.push(Check { method, options, reference: "mono".into(), rule: Rule::Exact });
                }
            }
        }
        let oracles = vec![OracleCheck { method: "mono".into(), test: OracleTest::Tree, rule: Rule::Exact }];
        Plan { checks, oracles, intersectors: INTERSECTORS.to_vec(), loose_per_10k: 1.0 }
    }
}

/// The suffix of keys that are reported but not judged: the streams and oracle rays under
/// [`Rule::Loose`], whose origins on surfaces make another tracer's `t` near 0 differ from
/// ours (self-hits at `t` ~ 1e-6 against 0 or a far hit).
pub const REPORTED: &str = "(reported, not judged)";

/// Answers compared and how they matched, per check and query.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Tally {
    /// Answers compared (rays, pixels).
    pub compared: u64,
    /// Different triangles at the same distance ([`Rule::Loose`]: other hits within 1e-4 of
    /// the distance, the same triangle included).
    pub ties: u64,
    /// Differences the oracle accepts ([`Rule::Equivalent`]).
    pub artefacts: u64,
    /// Differences counted under [`Rule::Loose`].
    pub loose: u64,
    /// Differences the rule refuses.
    pub failures: u64,
}

/// What [`run`] found.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Per `"method (options) vs reference: query"`.
    pub tallies: BTreeMap<String, Tally>,
    /// The first refused answers, described (at most 8 per key).
    pub messages: Vec<String>,
    /// (case, intersector, camera) combinations traced.
    pub views: u64,
    /// Loose disagreements described (at most 8 per key), for the report.
    pub loose_examples: Vec<String>,
    loose_per_10k: f64,
}

impl Report {
    /// The keys whose tallies fail: refused answers, or loose disagreements above the plan's
    /// fraction.
    pub fn failing(&self) -> Vec<String> {
        self.tallies
            .iter()
            .filter(|(k, t)| {
                t.failures > 0
                    || !k.ends_with(REPORTED) && t.loose as f64 * 10_000.0 > self.loose_per_10k * t.compared as f64
            })
            .map(|(k, t)| format!("{k}: {t:?}"))
            .collect()
    }

    /// A summary line per key with any difference.
    pub fn summary(&self) -> String {
        let mut s = format!("{} views, {} keys\n", self.views, self.tallies.len());
        for (k, t) in self.tallies.iter().filter(|(_, t)| t.ties + t.artefacts + t.loose + t.failures > 0) {
            let _ = writeln!(s, "{k}: {t:?}");
        }
        s
    }

    /// Panics naming the failing keys and the first refused answers.
    pub fn assert_ok(&self) {
        let failing = self.failing();
        assert!(
            failing.is_empty(),
            "{} failing:\n{}\nfirst refused answers:\n{}\nloose:\n{}",
            failing.len(),
            failing.join("\n"),
            self.messages.join("\n"),
            self.loose_examples.join("\n")
        );
    }

    /// Records one comparison's outcome.
    fn record(&mut self, key: &str, outcome: Outcome, what: impl FnOnce() -> String) {
        if !self.tallies.contains_key(key) {
            self.tallies.insert(key.to_string(), Tally::default());
        }
        let t = self.tallies.get_mut(key).expect("inserted above");
        t.compared += 1;
        let (list, count) = match outcome {
            Outcome::Same => return,
            Outcome::Tie => {
                t.ties += 1;
                return;
            }
            Outcome::Artefact => {
                t.artefacts += 1;
                return;
            }
            Outcome::Loose => {
                t.loose += 1;
                (&mut self.loose_examples, t.loose)
            }
            Outcome::Refused => {
                t.failures += 1;
                (&mut self.messages, t.failures)
            }
        };
        if count <= 8 {
            list.push(format!("{key}: {}", what()));
        }
    }
}

/// How one answer compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Outcome {
    Same,
    Tie,
    Artefact,
    Loose,
    Refused,
}

/// Whether `hit` lies on an edge of its triangle: a barycentric within 1e-6 of 0 (a ray
/// grazing the edge; which side it falls on is the triangle test's rounding).
fn on_edge(hit: Hit) -> bool {
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
struct Judge<'a> {
    tree: &'a KdTree,
    oracle: OnceCell<BruteForce>,
}

impl Judge<'_> {
    fn oracle(&self) -> &BruteForce {
        self.oracle.get_or_init(|| BruteForce::for_tree(self.tree))
    }

    fn hit(&self, rule: Rule, ray: &Ray, got: Option<Hit>, want: Option<Hit>) -> Outcome {
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

    fn occlusion(&self, rule: Rule, ray: &Ray, got: bool, want: bool) -> Outcome {
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
    fn soft(&self, rule: Rule, rays: &[Ray], got: u32, want: u32) -> Outcome {
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

/// The passes of one method on one camera, in the layout's tile order.
struct Frame {
    hits: Vec<Option<Hit>>,
    shadow: Vec<bool>,
    shadow_counts: (u64, u64),
    visible: Vec<f32>,
    soft: SoftStats,
}

/// Blocked soft-shadow rays of a pixel from its visible fraction.
fn blocked(visible: f32) -> u32 {
    ((1.0 - visible) * SAMPLES as f32).round() as u32
}

/// Runs `plan` over `cases` with the methods of `registry`; see the module documentation.
///
/// Panics when a case's tree or a structure fails to build or a method fails to bind (a
/// broken registry, not a wrong answer).
pub fn run(registry: &Registry, plan: &Plan, cases: &[Case]) -> Report {
    let mut report = Report { loose_per_10k: plan.loose_per_10k, ..Report::default() };
    let names = plan.checks.iter().map(|c| c.method.as_str()).chain(plan.checks.iter().map(|c| c.reference.as_str()));
    let needed: BTreeSet<&'static str> = names
        .chain(plan.oracles.iter().map(|o| o.method.as_str()))
        .map(|n| registry.entry(registry.select(n, Options::default()).expect("a registered method").entry).structure)
        .filter(|&s| s != KDTREE)
        .collect();
    for case in cases {
        for &intersector in &plan.intersectors {
            let config = BuildConfig { intersector, ..BuildConfig::default() };
            let mesh = &case.scene.mesh;
            let tree = KdTree::build(&mesh.positions, &mesh.triangles, &config)
                .unwrap_or_else(|e| panic!("{}: the tree does not build: {e}", case.name));
            let mut structures = Structures::new(&tree);
            for &name in &needed {
                let entry = registry.structure(name).unwrap_or_else(|| panic!("no structure '{name}'"));
                let built = (entry.build)(&case.scene).unwrap_or_else(|e| panic!("{}: {name}: {e}", case.name));
                structures.insert(name, built);
            }
            let judge = Judge { tree: &tree, oracle: OnceCell::new() };
            let light = soft::scene_light(&case.scene, &tree, LIGHT_RADIUS);
            let at = format!("{} {intersector:?}", case.name);
            if case.oracle {
                check_oracles(registry, plan, case, &tree, &structures, &at, &mut report);
            }
            check_case(registry, plan, case, &structures, &judge, &light, &at, &mut report);
        }
    }
    report
}

/// [`run`] as a test: prints the report's summary on stderr, then panics if any key fails
/// ([`Report::assert_ok`]). Returns the report.
pub fn assert_conforms(registry: &Registry, plan: &Plan, cases: &[Case]) -> Report {
    let report = run(registry, plan, cases);
    eprintln!("{}", report.summary());
    report.assert_ok();
    report
}

/// Binds `name` with `options` (panics on a broken registry).
fn bind<'s>(registry: &Registry, name: &str, options: Options, s: &'s Structures<'_>) -> crate::Bound<'s> {
    let selected = registry.select(name, options).unwrap_or_else(|e| panic!("{e}"));
    registry.bind(&selected, s).unwrap_or_else(|e| panic!("{e}"))
}

/// The single-ray twins against the brute-force oracle on the stream and primary rays.
fn check_oracles(
    registry: &Registry,
    plan: &Plan,
    case: &Case,
    tree: &KdTree,
    structures: &Structures<'_>,
    at: &str,
    report: &mut Report,
) {
    let mut rays = case.rays.clone();
    for (_, camera) in &case.cameras {
        rays.extend((0..camera.height).flat_map(|y| (0..camera.width).map(move |x| primary_ray(camera, x, y))));
    }
    for o in &plan.oracles {
        let oracle = match o.test {
            OracleTest::Tree => BruteForce::for_tree(tree),
            OracleTest::Fixed(test) => {
                let tris: Vec<[Vec3; 3]> =
                    (0..case.scene.mesh.triangle_count()).map(|i| case.scene.mesh.triangle(i)).collect();
                BruteForce::new(&tris, test)
            }
        };
        let m = bind(registry, &o.method, Options::default(), structures);
        let (mut hits, mut occluded) = (vec![None; rays.len()], vec![false; rays.len()]);
        m.tracer.stream(&rays, &mut hits);
        m.tracer.stream_occluded(&rays, &mut occluded);
        let key = match o.rule {
            Rule::Loose => format!("{} vs brute force: rays {REPORTED}", o.method),
            _ => format!("{} vs brute force: rays", o.method),
        };
        for (i, ray) in rays.iter().enumerate() {
            let outcome = match oracle.check(ray, hits[i], occluded[i]) {
                Ok(()) => Outcome::Same,
                // Another triangle test: the oracle's hit within 1e-4 of the distance.
                Err(_) if o.rule == Rule::Loose => {
                    let want = oracle.intersect(ray);
                    let near = match (hits[i], want) {
                        (Some(g), Some(w)) => (g.t - w.t).abs() <= 1e-4 * g.t.abs().max(w.t.abs()),
                        (g, w) => g.is_none() && w.is_none(),
                    };
                    if near && occluded[i] == want.is_some() { Outcome::Tie } else { Outcome::Loose }
                }
                Err(_) => Outcome::Refused,
            };
            report.record(&key, outcome, || {
                format!("{at}: ray {i}: {:?}", oracle.check(ray, hits[i], occluded[i]).unwrap_err())
            });
        }
    }
}

/// Every check of `plan` on one built case.
#[allow(clippy::too_many_arguments)]
fn check_case(
    registry: &Registry,
    plan: &Plan,
    case: &Case,
    structures: &Structures<'_>,
    judge: &Judge<'_>,
    light: &SphereLight,
    at: &str,
    report: &mut Report,
) {
    let scene = &case.scene;
    let surfaces = &crate::shade::surfaces(&scene.mesh);
    // The references' answers: per (reference, tile, camera) frames; per reference streams.
    let mut frames: HashMap<(String, u32, usize), Frame> = HashMap::new();
    let mut streams: HashMap<String, (Vec<Option<Hit>>, Vec<bool>)> = HashMap::new();
    let trace_stream = |m: &crate::Bound<'_>| {
        let (mut hits, mut occluded) = (vec![None; case.rays.len()], vec![false; case.rays.len()]);
        m.tracer.stream(&case.rays, &mut hits);
        m.tracer.stream_occluded(&case.rays, &mut occluded);
        (hits, occluded)
    };
    // Most soft-shadow kernels take no tile: one check per method, kernel (with its tile
    // where it takes one, `Bound::kernels`) and rule.
    let mut soft_done: BTreeSet<(&'static str, String, String, Rule)> = BTreeSet::new();
    for check in &plan.checks {
        let m = bind(registry, &check.method, check.options, structures);
        let kernel = m.kernels.soft.clone();
        let soft = soft_done.insert((m.entry.name, kernel, check.reference.clone(), check.rule));
        let tile = m.options.tile;
        let reference = bind(registry, &check.reference, Options { tile, ..Options::default() }, structures);
        let label = format!(
            "{} (tile {tile}{}{}) vs {} [{:?}]",
            check.method,
            if check.options.culling { "" } else { ", no culling" },
            if check.options.soft == SoftGrouping::PerPoint { ", per-point soft shadows" } else { "" },
            check.reference,
            check.rule
        );
        let key = |query: &str| format!("{label}: {query}");
        let [k_primary, k_shadow, k_soft, k_counts, k_stream, k_occluded] =
            ["primary", "shadow", "soft", "pass counts", "stream", "stream occluded"].map(key);
        let (k_stream, k_occluded) = if check.rule == Rule::Loose {
            (format!("{k_stream} {REPORTED}"), format!("{k_occluded} {REPORTED}"))
        } else {
            (k_stream, k_occluded)
        };
        for (ci, (view, camera)) in case.cameras.iter().enumerate() {
            report.views += 1;
            let layout = TileLayout::new(camera.width, camera.height, tile);
            let want = frames.entry((check.reference.clone(), tile, ci)).or_insert_with(|| {
                let mut hits = vec![None; layout.pixel_count()];
                reference.tracer.primary(&layout, camera, &mut hits, None);
                let mut shadow = vec![false; layout.pixel_count()];
                let shadow_counts = reference.tracer.shadow(
                    &View { layout: &layout, scene, surfaces, camera },
                    &hits,
                    &mut shadow,
                    None,
                );
                let mut visible = vec![0.0; layout.pixel_count()];
                let soft = reference.tracer.soft(
                    &View { layout: &layout, scene, surfaces, camera },
                    &hits,
                    light,
                    &mut visible,
                    None,
                );
                Frame { hits, shadow, shadow_counts, visible, soft }
            });
            let n = layout.pixel_count();
            let (mut hits, mut shadow, mut visible) = (vec![None; n], vec![false; n], vec![0.0; n]);
            m.tracer.primary(&layout, camera, &mut hits, None);
            // Shadows from the reference's hits, so that both trace the same rays.
            let counts =
                m.tracer.shadow(&View { layout: &layout, scene, surfaces, camera }, &want.hits, &mut shadow, None);
            let stats = if soft {
                m.tracer.soft(&View { layout: &layout, scene, surfaces, camera }, &want.hits, light, &mut visible, None)
            } else {
                want.soft
            };
            if !soft {
                visible.copy_from_slice(&want.visible);
            }
            let pixels = layout.tiles().iter().flat_map(|t| t.pixels());
            for (i, (x, y)) in pixels.enumerate() {
                let where_ = || format!("{at}, view {view}, pixel ({x}, {y})");
                let ray = primary_ray(camera, x, y);
                let outcome = judge.hit(check.rule, &ray, hits[i], want.hits[i]);
                report.record(&k_primary, outcome, || {
                    format!("{}: got {:?}, reference {:?}", where_(), hits[i], want.hits[i])
                });
                // Shadow rays that start on an edge (their primary ray grazed it) graze what
                // meets that edge: another triangle test may see them either way.
                let from_edge = check.rule == Rule::Loose && want.hits[i].is_some_and(on_edge);
                let outcome = match hard_shadow_segment(scene, surfaces, camera, x, y, &want.hits[i])
                    .map(|(s, e)| Ray::segment(s, e))
                {
                    Some(_) if from_edge && shadow[i] != want.shadow[i] => Outcome::Tie,
                    Some(r) => judge.occlusion(check.rule, &r, shadow[i], want.shadow[i]),
                    None if shadow[i] => Outcome::Refused,
                    None => Outcome::Same,
                };
                report.record(&k_shadow, outcome, || {
                    format!("{}: blocked {}, reference {}", where_(), shadow[i], want.shadow[i])
                });
                let (got_n, want_n) = (blocked(visible[i]), blocked(want.visible[i]));
                let outcome = if got_n == want_n && visible[i] == want.visible[i] {
                    Outcome::Same
                } else if from_edge {
                    Outcome::Tie
                } else {
                    let rays = want.hits[i]
                        .as_ref()
                        .and_then(|h| soft::shadow_start(surfaces, light, h, ray.dir))
                        .and_then(|(start, _)| Some(shadow_rays(start, &light_samples(start, light)?)));
                    judge.soft(check.rule, rays.as_ref().map_or(&[][..], |r| &r[..]), got_n, want_n)
                };
                report.record(&k_soft, outcome, || format!("{}: {got_n} of 16 blocked, reference {want_n}", where_()));
            }
            let same_counts =
                counts.0 == want.shadow_counts.0 && (stats.points, stats.rays) == (want.soft.points, want.soft.rays);
            let exact = check.rule != Rule::Loose;
            let counts_ok = same_counts && (!exact || counts == want.shadow_counts || check.rule == Rule::Equivalent);
            let outcome = if counts_ok {
                Outcome::Same
            } else if exact {
                Outcome::Refused
            } else {
                Outcome::Loose
            };
            report.record(&k_counts, outcome, || {
                format!(
                    "{at}, view {view}: shadow {counts:?} vs {:?}, soft {stats:?} vs {:?}",
                    want.shadow_counts, want.soft
                )
            });
        }
        let want = streams.entry(check.reference.clone()).or_insert_with(|| trace_stream(&reference));
        let (hits, occluded) = trace_stream(&m);
        for (i, ray) in case.rays.iter().enumerate() {
            report.record(&k_stream, judge.hit(check.rule, ray, hits[i], want.0[i]), || {
                format!("{at}: ray {i} {ray:?}: got {:?}, reference {:?}", hits[i], want.0[i])
            });
            let outcome = judge.occlusion(check.rule, ray, occluded[i], want.1[i]);
            report.record(&k_occluded, outcome, || {
                format!("{at}: ray {i} {ray:?}: got {}, reference {}", occluded[i], want.1[i])
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use cones::Cone;
    use kdtree::NoCounters;
    use scenes::Tile;

    use super::*;
    use crate::method::{Method, ShadowJob, SingleRays, TileCounters};
    use crate::registry::Binding;
    use crate::registry::Entry;

    /// Single rays with one query deliberately wrong on some rays: `K` = 0 primary, 1 hard
    /// shadow, 2 soft shadow, 3 stream, 4 stream any-hit.
    struct Faulty<'a, const K: u8>(SingleRays<&'a KdTree>);

    impl<const K: u8> Method for Faulty<'_, K> {
        type Scratch = ();

        fn scratch(&self) {}

        fn primary_tile<C: TileCounters>(&self, s: &mut (), c: &Camera, t: &Tile, out: &mut [Option<Hit>], n: &mut C) {
            self.0.primary_tile(s, c, t, out, n);
            if K == 0 {
                out.iter_mut().filter(|h| h.is_some()).step_by(7).for_each(|h| *h = None);
            }
        }

        fn shadow_tile<C: TileCounters>(
            &self,
            s: &mut (),
            job: &ShadowJob<'_>,
            out: &mut [bool],
            n: &mut C,
        ) -> (u64, u64) {
            let counts = self.0.shadow_tile(s, job, out, n);
            if K == 1 {
                out.iter_mut().zip(job.hits).filter(|(_, h)| h.is_some()).step_by(5).for_each(|(b, _)| *b = !*b);
            }
            counts
        }

        fn soft_point<C: TileCounters>(&self, s: &mut (), rays: &[Ray; SAMPLES], cone: &Cone, n: &mut C) -> u16 {
            self.0.soft_point(s, rays, cone, n) ^ u16::from(K == 2)
        }

        fn stream<C: TileCounters>(&self, s: &mut (), rays: &[Ray], out: &mut [Option<Hit>], n: &mut C) {
            self.0.stream(s, rays, out, n);
            if K == 3 {
                out.iter_mut().filter(|h| h.is_some()).step_by(9).for_each(|h| *h = None);
            }
        }

        fn stream_occluded<C: TileCounters>(&self, s: &mut (), rays: &[Ray], out: &mut [bool], n: &mut C) {
            self.0.stream_occluded(s, rays, out, n);
            if K == 4 {
                out.iter_mut().step_by(9).for_each(|b| *b = !*b);
            }
        }
    }

    fn faulty(name: &'static str, bind: crate::registry::Bind) -> Entry {
        Entry::whole(name, "test", "wrong on purpose", KDTREE, bind)
    }

    fn registry() -> Registry {
        let mut r = Registry::ours();
        r.add(faulty("faulty-primary", |s, _| Ok(Binding::method(Faulty::<0>(SingleRays(s.kdtree()))))));
        r.add(faulty("faulty-shadow", |s, _| Ok(Binding::method(Faulty::<1>(SingleRays(s.kdtree()))))));
        r.add(faulty("faulty-soft", |s, _| Ok(Binding::method(Faulty::<2>(SingleRays(s.kdtree()))))));
        r.add(faulty("faulty-stream", |s, _| Ok(Binding::method(Faulty::<3>(SingleRays(s.kdtree()))))));
        r.add(faulty("faulty-occluded", |s, _| Ok(Binding::method(Faulty::<4>(SingleRays(s.kdtree()))))));
        r
    }

    fn plan(method: &str, rule: Rule) -> Plan {
        let check = Check { method: method.into(), options: Options::default(), reference: "mono".into(), rule };
        Plan { checks: vec![check], oracles: Vec::new(), intersectors: vec![Intersector::Wald], loose_per_10k: 1.0 }
    }

    fn cases() -> Vec<Case> {
        let mut cases = builtin_cases(13, 9, &["atrium", "arena", "atrium-rotated", "grove"], &[]);
        cases.extend(soup_cases(1));
        cases
    }

    #[test]
    fn the_right_method_passes_and_each_wrong_query_is_caught() {
        let (r, cases) = (registry(), cases());
        let report = run(&r, &plan("mono", Rule::Exact), &cases);
        report.assert_ok();
        for query in ["primary", "shadow", "soft", "stream", "stream occluded"] {
            let t = report.tallies.iter().find(|(k, _)| k.ends_with(&format!(": {query}"))).unwrap().1;
            assert!(t.compared > 100, "{query}: {t:?}");
        }
        for (method, query) in [
            ("faulty-primary", ": primary"),
            ("faulty-shadow", ": shadow"),
            ("faulty-soft", ": soft"),
            ("faulty-stream", ": stream"),
            ("faulty-occluded", ": stream occluded"),
        ] {
            for rule in [Rule::Exact, Rule::Equivalent, Rule::Ties, Rule::Loose] {
                let report = run(&r, &plan(method, rule), &cases);
                if rule == Rule::Loose && query.starts_with(": stream") {
                    // Loose streams are reported, not judged: the faults must show in the tally.
                    let (_, t) = report
                        .tallies
                        .iter()
                        .find(|(k, _)| k.contains(&format!("{query} {REPORTED}")))
                        .expect("the stream is tallied");
                    assert!(t.loose > 0, "{method} {rule:?}: {t:?}");
                    continue;
                }
                let failing = report.failing();
                assert!(failing.iter().any(|k| k.contains(&format!("{query}:"))), "{method} {rule:?}: {failing:?}");
            }
        }
    }

    #[test]
    fn a_wrong_single_ray_twin_fails_the_oracle() {
        let r = registry();
        let mut p = plan("mono", Rule::Exact);
        p.oracles = vec![OracleCheck { method: "faulty-stream".into(), test: OracleTest::Tree, rule: Rule::Exact }];
        let failing = run(&r, &p, &soup_cases(1)).failing();
        assert!(failing.iter().any(|k| k.starts_with("faulty-stream vs brute force")), "{failing:?}");
        p.oracles[0].method = "mono".into();
        run(&r, &p, &soup_cases(1)).assert_ok();
    }

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
