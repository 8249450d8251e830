//! Pre-BVH culling for shadow rays (Selgrad, Müller & Stamminger, "Faster Ray-Traced Shadows
//! via Pre-BVH Culling", `../shared/seeds/selgrad-muller-stamminger-pre-bvh-culling-shadows.txt`).
//!
//! Before the structure that a frame's shadow rays are traced against is built, the triangles
//! no shadow ray can reach are thrown away. Every shadow ray is a segment from a visible point
//! to the light, so all of them lie in the convex hull of the visible points and the light,
//! and so in the box of the visible points joined with the light ([`shadow_region`]; a point
//! light here, for an area light its box). Here the visible points are the shadow rays' own
//! origins (the primary hits moved off their surfaces, `kdtree::ray::offset_origin`) and ends
//! (`origin + dir`, the light), so the region holds every computed point of every ray; it is
//! widened by `2^-12` of its extent plus `2^-16` of its largest coordinate, far more than the
//! triangle tests' rounding, so no triangle that a test could report is culled. A triangle
//! whose box misses the region is culled ([`cull`]); the kd-tree and the 4-wide BVH are built
//! over the rest.
//!
//! [`run`] measures, per scene and view: the culled fraction, the build of each structure with
//! and without culling (culling included in the culled build's time), the shadow rays' trace
//! time on each, and the total per frame (build plus trace, the cost of a dynamic scene whose
//! shadow structure is rebuilt every frame), in interleaved rounds with medians; and whether
//! every shadow answer of the culled structures equals the unculled one's (it must: tested on
//! every built-in scene and view and on random cameras in the tests below).

use std::fmt::Write as _;

use glam::Vec3;
use kdtree::{Aabb, BuildConfig, Hit, KdTree, Ray};
use mbvh::Mbvh;
use rayon::prelude::*;
use scenes::{Camera, Mesh, Scene};
use serde::Serialize;
use trace::frame::stream_occluded_pass;
use trace::method::{hard_shadow_segment, primary_ray};
use trace::progress::Progress;
use trace::setup::view_camera;
use trace::timing::{median, timed};
use trace::{Error, SingleRays};

/// What `culling` measures.
#[derive(Clone, Debug, PartialEq)]
pub struct CullingConfig {
    /// Built-in scenes or paths to .obj / .obj.gz files.
    pub scenes: Vec<String>,
    /// Image size.
    pub size: (u32, u32),
    /// Interleaved timed rounds; medians are reported.
    pub rounds: u32,
}

impl Default for CullingConfig {
    fn default() -> Self {
        CullingConfig { scenes: vec!["atrium".into()], size: (512, 512), rounds: 5 }
    }
}

/// The shadow rays of a frame: one per primary hit facing the point light (`mono`'s hits).
/// Rows in parallel (rayon), in row-major order whatever the thread count.
pub fn shadow_rays(scene: &Scene, tree: &KdTree, camera: &Camera) -> Vec<Ray> {
    let surfaces = trace::shade::surfaces(&scene.mesh);
    let rows: Vec<Vec<Ray>> = (0..camera.height)
        .into_par_iter()
        .map(|y| {
            let mut out = Vec::new();
            for x in 0..camera.width {
                let hit: Option<Hit> = tree.intersect(&primary_ray(camera, x, y));
                if let Some((start, end)) = hard_shadow_segment(scene, &surfaces, camera, x, y, &hit) {
                    out.push(Ray::segment(start, end));
                }
            }
            out
        })
        .collect();
    rows.concat()
}

/// The region the shadow `rays` (segments `t` in `[t_min, t_max]` within `[0, 1]`) sweep:
/// the box of their origins and ends (the visible points and the light), widened (module
/// docs). Empty without rays.
pub fn shadow_region(rays: &[Ray]) -> Aabb {
    let mut b = Aabb::EMPTY;
    for r in rays {
        b = b.grow(r.origin).grow(r.origin + r.dir);
    }
    if b.is_empty() {
        return b;
    }
    let extent = (b.max - b.min).max_element();
    let scale = b.min.abs().max(b.max.abs()).max_element();
    let pad = Vec3::splat(extent * (1.0 / 4096.0) + scale * (1.0 / 65536.0));
    Aabb { min: b.min - pad, max: b.max + pad }
}

/// The triangles of `mesh` whose box meets `region` (closed boxes), as indices into the same
/// positions, with each kept triangle's index in the mesh.
pub fn cull(mesh: &Mesh, region: &Aabb) -> (Vec<[u32; 3]>, Vec<u32>) {
    let mut triangles = Vec::new();
    let mut kept = Vec::new();
    for (i, t) in mesh.triangles.iter().enumerate() {
        let b = Aabb::from_points(&t.map(|v| mesh.positions[v as usize]));
        if b.overlaps(region) {
            triangles.push(*t);
            kept.push(i as u32);
        }
    }
    (triangles, kept)
}

/// The shadow answers of `rays` on the kd-tree and the 4-wide BVH built over `triangles`
/// (the kd-tree with `config`'s triangle test, the BVH with the same).
pub fn answers(mesh: &Mesh, triangles: &[[u32; 3]], config: &BuildConfig, rays: &[Ray]) -> [Vec<bool>; 2] {
    let tree = KdTree::build(&mesh.positions, triangles, config).expect("a valid mesh");
    let bvh = Mbvh::build(&mesh.positions, triangles).expect("a valid mesh");
    let mut kd = vec![false; rays.len()];
    stream_occluded_pass(&SingleRays(&tree), rays, &mut kd);
    let mut mb = vec![false; rays.len()];
    match config.intersector {
        kdtree::Intersector::Wald => stream_occluded_pass(&SingleRays(bvh.wald()), rays, &mut mb),
        kdtree::Intersector::Watertight => stream_occluded_pass(&SingleRays(bvh.watertight()), rays, &mut mb),
    }
    [kd, mb]
}

/// One scene and view (one JSON object per row with `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct CullingRow {
    /// Scene name.
    pub scene: String,
    /// View name.
    pub view: String,
    /// Triangles of the scene.
    pub triangles: u64,
    /// Triangles kept after culling.
    pub kept: u64,
    /// Percent of the triangles culled.
    pub culled_percent: f64,
    /// Shadow rays traced (one per lit primary hit).
    pub shadow_rays: u64,
    /// Median ms to compute the region and cull.
    pub cull_ms: f64,
    /// Per structure (`kdtree`, `mbvh`): build ms without culling.
    pub build_ms: [f64; 2],
    /// Per structure: cull plus build ms with culling.
    pub build_culled_ms: [f64; 2],
    /// Per structure: shadow trace ms without culling.
    pub trace_ms: [f64; 2],
    /// Per structure: shadow trace ms with culling.
    pub trace_culled_ms: [f64; 2],
    /// Per structure: build plus trace without culling.
    pub frame_ms: [f64; 2],
    /// Per structure: cull, build and trace with culling.
    pub frame_culled_ms: [f64; 2],
    /// Whether every shadow answer with culling equals the one without, on both structures.
    pub identical: bool,
    /// Threads of the pool.
    pub threads: usize,
}

impl CullingRow {
    /// The table cells shared by `rttest culling` and `rttest dynamic` for structure `i`
    /// (0 kd-tree, 1 mbvh): build, trace and frame ms without and with culling, the speed-up
    /// and whether the answers were identical.
    pub(crate) fn timing_cells(&self, i: usize) -> String {
        format!(
            "{:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} | {}",
            self.build_ms[i],
            self.build_culled_ms[i],
            self.trace_ms[i],
            self.trace_culled_ms[i],
            self.frame_ms[i],
            self.frame_culled_ms[i],
            self.frame_ms[i] / self.frame_culled_ms[i],
            if self.identical { "yes" } else { "NO" },
        )
    }
}

/// The report: rows and the configuration.
#[derive(Clone, Debug)]
pub struct CullingReport {
    /// One row per scene.
    pub rows: Vec<CullingRow>,
    /// The configuration measured.
    pub config: CullingConfig,
}

/// Measures every scene of `config` at its default view (module docs).
pub fn run(config: &CullingConfig, progress: &dyn Progress) -> Result<CullingReport, Error> {
    let mut rows = Vec::new();
    let build_config = BuildConfig::default();
    for name in &config.scenes {
        let scene = scenes::load_scene(name)?;
        let (w, h) = config.size;
        let (camera, view) = view_camera(&scene, None, w, h)?;
        let mesh = &scene.mesh;
        let tree = KdTree::build(&mesh.positions, &mesh.triangles, &build_config)?;
        let rays = shadow_rays(&scene, &tree, &camera);
        let bar = progress.task(&format!("culling: {}", scene.name), Some(u64::from(config.rounds)));
        rows.push(measure(&scene, &view, &rays, config.rounds, &build_config, || bar.inc())?);
        bar.finish();
    }
    Ok(CullingReport { rows, config: config.clone() })
}

/// Measures pre-BVH culling for the shadow `rays` of one frame of `scene` (seen from `view`):
/// per round, interleaved, the cull, the four builds (kd-tree and 4-wide BVH, without and with
/// culling) and the four shadow traces; medians of `rounds` (at least one). `tick` is called
/// after each round. `identical` says whether every culled answer equals the unculled one.
pub fn measure(
    scene: &Scene,
    view: &str,
    rays: &[Ray],
    rounds: u32,
    build_config: &BuildConfig,
    mut tick: impl FnMut(),
) -> Result<CullingRow, Error> {
    let mesh = &scene.mesh;
    let mut t = vec![Vec::new(); 9];
    let mut identical = true;
    let mut kept = 0;
    let bvh_err = |e: mbvh::BuildError| Error::Usage(format!("mbvh build: {e}"));
    for _ in 0..rounds.max(1) {
        // Builds, interleaved: full kd-tree, culled kd-tree, full BVH, culled BVH.
        let (cull_s, (triangles, k)) = timed(|| cull(mesh, &shadow_region(rays)));
        kept = k.len();
        let (s0, full_kd) = timed(|| KdTree::build(&mesh.positions, &mesh.triangles, build_config));
        let (s1, culled_kd) = timed(|| KdTree::build(&mesh.positions, &triangles, build_config));
        let (s2, full_bvh) = timed(|| Mbvh::build(&mesh.positions, &mesh.triangles));
        let (s3, culled_bvh) = timed(|| Mbvh::build(&mesh.positions, &triangles));
        let (full_kd, culled_kd) = (full_kd?, culled_kd?);
        let (full_bvh, culled_bvh) = (full_bvh.map_err(bvh_err)?, culled_bvh.map_err(bvh_err)?);
        // Traces, interleaved likewise.
        let mut out = vec![vec![false; rays.len()]; 4];
        let (s4, ()) = timed(|| stream_occluded_pass(&SingleRays(&full_kd), rays, &mut out[0]));
        let (s5, ()) = timed(|| stream_occluded_pass(&SingleRays(&culled_kd), rays, &mut out[1]));
        let (s6, ()) = match build_config.intersector {
            kdtree::Intersector::Wald => {
                timed(|| stream_occluded_pass(&SingleRays(full_bvh.wald()), rays, &mut out[2]))
            }
            kdtree::Intersector::Watertight => {
                timed(|| stream_occluded_pass(&SingleRays(full_bvh.watertight()), rays, &mut out[2]))
            }
        };
        let (s7, ()) = match build_config.intersector {
            kdtree::Intersector::Wald => {
                timed(|| stream_occluded_pass(&SingleRays(culled_bvh.wald()), rays, &mut out[3]))
            }
            kdtree::Intersector::Watertight => {
                timed(|| stream_occluded_pass(&SingleRays(culled_bvh.watertight()), rays, &mut out[3]))
            }
        };
        identical &= out[0] == out[1] && out[2] == out[3];
        for (v, s) in t.iter_mut().zip([cull_s, s0, s1, s2, s3, s4, s5, s6, s7]) {
            v.push(s * 1e3);
        }
        tick();
    }
    let m: Vec<f64> = t.iter().map(|v| median(v)).collect();
    let n = mesh.triangles.len();
    let build_ms = [m[1], m[3]];
    let build_culled_ms = [m[0] + m[2], m[0] + m[4]];
    let trace_ms = [m[5], m[7]];
    let trace_culled_ms = [m[6], m[8]];
    Ok(CullingRow {
        scene: scene.name.clone(),
        view: view.to_string(),
        triangles: n as u64,
        kept: kept as u64,
        culled_percent: 100.0 * (n - kept) as f64 / n.max(1) as f64,
        shadow_rays: rays.len() as u64,
        cull_ms: m[0],
        build_ms,
        build_culled_ms,
        trace_ms,
        trace_culled_ms,
        frame_ms: [build_ms[0] + trace_ms[0], build_ms[1] + trace_ms[1]],
        frame_culled_ms: [build_culled_ms[0] + trace_culled_ms[0], build_culled_ms[1] + trace_culled_ms[1]],
        identical,
        threads: rayon::current_num_threads(),
    })
}

impl std::fmt::Display for CullingReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (w, h) = self.config.size;
        let threads = self.rows.first().map_or(0, |r| r.threads);
        let mut out = String::new();
        let _ = writeln!(
            out,
            "rttest culling: {w}x{h}, {threads} threads, default views, hard shadow rays to the point light; medians of {} interleaved rounds. Build with culling includes the cull; frame = build + shadow trace.\n",
            self.config.rounds
        );
        let _ = writeln!(
            out,
            "| scene | structure | triangles | kept | culled % | build ms | build ms culled | trace ms | trace ms culled | frame ms | frame ms culled | speed-up | identical |"
        );
        let _ = writeln!(out, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|");
        for r in &self.rows {
            for (i, s) in ["kdtree", "mbvh"].iter().enumerate() {
                let (t, k, c, cells) = (r.triangles, r.kept, r.culled_percent, r.timing_cells(i));
                let _ = writeln!(out, "| {} | {s} | {t} | {k} | {c:.1} | {cells} |", r.scene);
            }
        }
        f.write_str(&out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scenes::builtin::shapes::Rng;

    /// Culled and unculled shadow answers of both structures, both triangle tests.
    fn assert_identical(scene: &Scene, camera: &Camera, at: &str) -> (usize, usize) {
        let mesh = &scene.mesh;
        let tree = KdTree::build(&mesh.positions, &mesh.triangles, &BuildConfig::default()).unwrap();
        let rays = shadow_rays(scene, &tree, camera);
        let (triangles, kept) = cull(mesh, &shadow_region(&rays));
        for intersector in [kdtree::Intersector::Wald, kdtree::Intersector::Watertight] {
            let config = BuildConfig { intersector, ..BuildConfig::default() };
            let full = answers(mesh, &mesh.triangles, &config, &rays);
            let culled = answers(mesh, &triangles, &config, &rays);
            for s in 0..2 {
                if let Some(i) = (0..rays.len()).find(|&i| full[s][i] != culled[s][i]) {
                    panic!(
                        "{at} {intersector:?} structure {s}: ray {i} {:?}: {} unculled, {} culled",
                        rays[i], full[s][i], culled[s][i]
                    );
                }
            }
        }
        (kept.len(), rays.len())
    }

    #[test]
    fn culled_shadows_equal_unculled_on_every_builtin_scene_and_view() {
        let mut culled_somewhere = false;
        for &name in scenes::builtin::NAMES.iter().filter(|n| !scenes::builtin::MATERIAL_VARIANTS.contains(n)) {
            let scene = scenes::load_scene(name).unwrap();
            let large = ["grove", "garage"].contains(&name);
            let views: Vec<_> = if large { vec![scene.default_view().clone()] } else { scene.views.clone() };
            for view in views {
                let camera = view.camera(48, 32).unwrap();
                let (kept, _) = assert_identical(&scene, &camera, &format!("{name}/{}", view.name));
                culled_somewhere |= kept < scene.mesh.triangles.len();
            }
        }
        assert!(culled_somewhere, "no view culls anything: the test would not test culling");
    }

    #[test]
    fn culled_shadows_equal_unculled_from_random_cameras() {
        let mut rng = Rng::new(17);
        for name in ["atrium", "arena", "touching-boxes"] {
            let scene = scenes::load_scene(name).unwrap();
            let lo = scene.mesh.positions.iter().fold(Vec3::INFINITY, |a, &b| a.min(b));
            let hi = scene.mesh.positions.iter().fold(Vec3::NEG_INFINITY, |a, &b| a.max(b));
            let mut point = || Vec3::new(rng.range(lo.x, hi.x), rng.range(lo.y, hi.y), rng.range(lo.z, hi.z));
            for k in 0..6 {
                let (eye, target) = (point(), point());
                let fovy = if k % 2 == 0 { 40.0 } else { 100.0 };
                let Some(camera) = Camera::look_at(eye, target, fovy, 40, 30) else { continue };
                assert_identical(&scene, &camera, &format!("{name} random camera {k}"));
            }
        }
    }

    #[test]
    fn the_region_holds_every_ray_and_the_light() {
        let scene = scenes::load_scene("atrium").unwrap();
        let camera = scene.default_view().camera(32, 24).unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let rays = shadow_rays(&scene, &tree, &camera);
        assert!(!rays.is_empty());
        let region = shadow_region(&rays);
        assert!(region.contains(scene.point_light.position));
        for r in &rays {
            assert!(region.contains(r.origin) && region.contains(r.at(0.5)));
        }
        assert!(shadow_region(&[]).is_empty());
    }

    #[test]
    fn a_run_reports_identical_answers() {
        let config = CullingConfig { scenes: vec!["arena".into()], size: (32, 24), rounds: 1 };
        let report = run(&config, &trace::progress::Quiet).unwrap();
        let r = &report.rows[0];
        assert!(r.identical && r.kept <= r.triangles && r.shadow_rays > 0, "{r:?}");
        assert!(report.to_string().contains("| arena | mbvh |"));
    }
}
