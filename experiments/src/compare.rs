//! `rttest compare`: our methods against peer tracers on exactly the same rays.
//!
//! One scene, one view: every method of ours (single rays, 2x2 packets, frusta, MFT, cones,
//! MFT cones at the `--tiles` sizes) and every baseline built in (Embree single rays and
//! packets of 4, 8 and 16 over 2x2, 4x2 and 4x4 pixel blocks with the coherent context flag,
//! plus single rays and 16-packets with Embree's default incoherent flag and on its
//! medium-quality BVH, with `--features embree`; the `bvh` and `obvhs` crates with
//! `--features bvh-crates`). For each: the build time of its structure, Mrays/s of primary
//! rays, of hard shadow rays and of 16-sample soft-shadow rays, and how many pixels' primary
//! hit names another triangle than our single-ray traversal (with those that are ties at a
//! shared edge or vertex, same distance, counted apart).
//!
//! The rays are ours for everyone: primary rays from the camera convention
//! ([`scenes::Camera::pixel_ray`]); shadow rays made from *our* single-ray hits by
//! [`crate::shade::shadow_ray`] (origins from `kdtree::ray::offset_origin`); soft-shadow rays
//! from [`crate::soft::shadow_start`] and `cones::shadows` (16 per point, light radius
//! `--light-radius` in Sponza units scaled to the scene, as Table 4.6). See
//! [`crate::baselines`] for how baselines trace them.
//!
//! Timing: builds are interleaved (ours, Embree high, Embree medium, ...) `--build-rounds`
//! times; then one untimed warm-up frame per method (its hits give the mismatch column), then
//! `--rounds` rounds, each timing every method's primary pass in turn, then every distinct
//! shadow kernel, then every distinct soft-shadow kernel (A, B, C, A, B, C, ...), so that a
//! slow phase of a noisy machine hits every method alike; medians are reported. A kernel is
//! known by its identity, read from the bound method (`trace::Bound::kernels`: `kd-single`,
//! `kd-packets`, `kd-frusta-16`, `kd-stratum-packets`, `embree-8`, ...), so methods sharing
//! a shadow or soft-shadow kernel (every packet and cone method of ours shares `kd-packets`
//! and `kd-stratum-packets`) are timed once and show the same column.
//!
//! The incoherent columns (`ao`, `diffuse`; Wald, Benthin & Boulos 2008): from our single-ray
//! primary hits, `--ao-rays` ambient-occlusion rays per hit and one diffuse bounce per hit
//! ([`trace::workload`], seeded, generated once), traced by every method's stream queries
//! (any hit and closest hit) in every round after the soft shadows; every method is timed on
//! them (our packet methods group rays sharing an origin into packets and frusta). Their
//! answers are compared with `mono`'s ray by ray (`ao_mismatch`, `diffuse_mismatch`: ties at
//! equal distance included).

use std::fmt::Write as _;

use kdtree::{BuildConfig, Hit, KdTree};
use scenes::{Camera, Scene};
use serde::Serialize;
use trace::progress::Progress;
use trace::registry::{KDTREE, Selected, TILE_SIZE};
use trace::setup::view_camera;
use trace::ties::{coplanar, near_shared};
use trace::timing::{median, mrays_per_s, timed};
use trace::workload::{self, Incoherent};
use trace::{Bound, Error, Options, Registry, Structures, TileLayout, soft};

/// What `compare` measures.
#[derive(Clone, Debug, PartialEq)]
pub struct CompareConfig {
    /// A built-in scene or a path to an .obj or .obj.gz file.
    pub scene: String,
    /// A named view of the scene (default: its first view).
    pub view: Option<String>,
    /// Image size.
    pub size: (u32, u32),
    /// Timed rounds; each times every method once, in turn; medians are reported.
    pub rounds: u32,
    /// Timed builds of each structure, interleaved; the median is reported.
    pub build_rounds: u32,
    /// Methods: registry names (`mono`, `mft-16`, `embree-16`, `bvh`, ...) or groups (`all`,
    /// `ours`, `embree`, `bvh-crates`). `all` takes the baselines this build has.
    pub methods: Vec<String>,
    /// Tile sizes of our tiled methods (frustum, MFT, cone, MFT cone): multiples of 4, 4 to 64.
    pub tiles: Vec<u32>,
    /// Radius of the spherical light of the soft shadows, in Sponza units (scaled by the
    /// scene's diagonal, as Table 4.6): a finite number >= 0.
    pub light_radius: f32,
    /// Leave out the 16-sample soft shadows (the slowest column).
    pub no_soft: bool,
    /// Ambient-occlusion rays per primary hit (1 to 64; the incoherent `ao` column).
    pub ao_rays: u32,
    /// Leave out the incoherent columns (`ao`, `diffuse`).
    pub no_incoherent: bool,
}

impl Default for CompareConfig {
    fn default() -> Self {
        CompareConfig {
            scene: "atrium".into(),
            view: None,
            size: (512, 512),
            rounds: 5,
            build_rounds: 3,
            methods: vec!["all".into()],
            tiles: vec![8, 16],
            light_radius: 1.0,
            no_soft: false,
            ao_rays: 4,
            no_incoherent: false,
        }
    }
}

/// The result of one method (one JSON object per method with `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct CompareRow {
    /// Scene name.
    pub scene: String,
    /// The method: `mono`, `packet`, `frustum-8`, `mft-16`, `embree-1`, `embree-16`,
    /// `embree-16-incoherent`, `embree-1-medium`, `bvh`, `obvhs`, ...
    pub method: String,
    /// Who made it: `ours`, `embree`, `bvh` or `obvhs`.
    pub family: String,
    /// Median milliseconds to build the method's structure (our kd-tree for ours).
    pub build_ms: f64,
    /// Primary rays per second (millions), median over rounds.
    pub primary_mrays_per_s: f64,
    /// Hard shadow rays per second (millions), median; `null` when not measured.
    pub shadow_mrays_per_s: Option<f64>,
    /// 16-sample soft-shadow rays per second (millions), median; `null` with `--no-soft`.
    pub soft16_mrays_per_s: Option<f64>,
    /// How the mismatches divide into ties (of which edge ties and coincident faces) and
    /// hit-vs-miss (flattened: `prim_mismatch`, `prim_ties`, `prim_edge_ties`,
    /// `prim_coincident`, `prim_hit_vs_miss`); the rest hit another triangle at another
    /// distance.
    #[serde(flatten)]
    pub mismatches: Mismatches,
    /// Pixels.
    pub pixels: u64,
    /// Median milliseconds of the primary pass.
    pub primary_ms: f64,
    /// Median milliseconds of the shadow pass (`null` when not measured).
    pub shadow_ms: Option<f64>,
    /// Median milliseconds of the soft-shadow pass (`null` when not measured).
    pub soft16_ms: Option<f64>,
    /// Ambient-occlusion rays per second (millions), median; `null` with `--no-incoherent`.
    pub ao_mrays_per_s: Option<f64>,
    /// Diffuse-bounce rays per second (millions), median; `null` with `--no-incoherent`.
    pub diffuse_mrays_per_s: Option<f64>,
    /// Median milliseconds of the AO stream (`null` when not measured).
    pub ao_ms: Option<f64>,
    /// Median milliseconds of the diffuse stream (`null` when not measured).
    pub diffuse_ms: Option<f64>,
    /// Mirror-reflection rays per second (millions), median; `null` with `--no-incoherent`.
    pub reflect_mrays_per_s: Option<f64>,
    /// Median milliseconds of the reflection stream (`null` when not measured).
    pub reflect_ms: Option<f64>,
    /// Reflection rays traced (one per primary hit).
    pub reflect_rays: u64,
    /// Reflection hits naming another triangle than `mono`'s (ties at equal distance
    /// included).
    pub reflect_mismatch: u64,
    /// AO rays traced (`--ao-rays` per primary hit).
    pub ao_rays: u64,
    /// Diffuse rays traced (one per primary hit).
    pub diffuse_rays: u64,
    /// AO answers (blocked or not) that differ from `mono`'s.
    pub ao_mismatch: u64,
    /// Diffuse hits naming another triangle than `mono`'s (ties at equal distance included).
    pub diffuse_mismatch: u64,
    /// The shadow kernel (rows of ours share the single-ray one).
    pub shadow_kernel: Option<String>,
    /// The soft-shadow kernel (rows of ours share the single, pyramid and cone ones).
    pub soft16_kernel: Option<String>,
    /// Threads of the pool.
    pub threads: usize,
    /// Timed rounds.
    pub rounds: u32,
}

/// The methods `config.methods` selects from `registry`, in registry order, `mono` always
/// first (the reference); then those named at a SIMD level (`mft-16@avx2`, the width
/// ladder's rows), in the order given.
pub fn select_methods(registry: &Registry, config: &CompareConfig) -> Result<Vec<Selected>, Error> {
    for &t in &config.tiles {
        if t % 4 != 0 || !(4..=64).contains(&t) {
            return Err(Error::Usage(format!("--tiles: {t} is not a multiple of 4 in 4..=64")));
        }
    }
    let all = registry.names(&config.tiles);
    let selected: Vec<Selected> =
        all.iter().map(|n| registry.select(n, Options::default())).collect::<Result<_, _>>()?;
    let family = |i: usize| registry.entry(selected[i].entry).family;
    let mut wanted = vec![false; all.len()];
    let mut at_levels = Vec::new();
    for token in &config.methods {
        let token = token.trim();
        if let Some(hint) = baselines::feature_hint(token) {
            return Err(Error::Usage(format!("--methods {token}: {hint}")));
        }
        if token.contains('@') {
            // A method at a capped SIMD level (`mft-16@avx2`) or packet width (`mft-16@w8`):
            // the width ladder's rows.
            at_levels.push(registry.select(token, Options::default()).map_err(|e| match e {
                Error::Usage(m) => Error::Usage(format!("--methods: {m}")),
                e => e,
            })?);
            continue;
        }
        let matched: Vec<usize> = match token {
            "all" => (0..all.len()).collect(),
            "ours" | "embree" => (0..all.len()).filter(|&i| family(i) == token).collect(),
            "bvh-crates" => (0..all.len()).filter(|&i| matches!(family(i), "bvh" | "obvhs")).collect(),
            name => all.iter().position(|n| n == name).into_iter().collect(),
        };
        if matched.is_empty() {
            return Err(Error::Usage(format!(
                "--methods: unknown method '{token}' (known: all, ours, embree, bvh-crates, {})",
                all.join(", ")
            )));
        }
        for i in matched {
            wanted[i] = true;
        }
    }
    wanted[0] = true;
    let mut methods: Vec<Selected> = selected.into_iter().zip(wanted).filter(|(_, w)| *w).map(|(s, _)| s).collect();
    methods.extend(at_levels.into_iter().filter(|s| !methods.iter().any(|m| m.name == s.name)).collect::<Vec<_>>());
    Ok(methods)
}

/// The fixed inputs of every pass: the view, our reference hits and the light.
#[derive(Debug)]
pub struct Frame<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// The camera.
    pub camera: Camera,
    /// The 16 x 16 tiles of the shadow and soft-shadow passes.
    pub layout: TileLayout,
    /// Our single-ray primary hits, tile order of `layout`: the shadow rays start from them.
    pub reference_tiles: Vec<Option<Hit>>,
    /// The same, row-major: mismatches are counted against them.
    pub reference: Vec<Option<Hit>>,
    /// The soft shadows' spherical light.
    pub light: scenes::SphereLight,
    /// The incoherent rays from the reference hits (empty when not asked for).
    pub incoherent: Incoherent,
}

impl<'a> Frame<'a> {
    /// The frame of `scene` seen by `camera`, with `tree`'s single-ray hits as the reference
    /// and a light of `radius` Sponza units at the scene's point light, with `ao_rays`
    /// ambient-occlusion rays and one diffuse ray per reference hit when `incoherent`.
    pub fn new(
        scene: &'a Scene,
        tree: &KdTree,
        camera: Camera,
        radius: f32,
        ao_rays: u32,
        incoherent: bool,
    ) -> Frame<'a> {
        let layout = TileLayout::new(camera.width, camera.height, TILE_SIZE);
        let mut reference_tiles = vec![None; layout.pixel_count()];
        let (_, kdtree::NoCounters) =
            trace::frame::primary_pass(&trace::SingleRays(tree), &layout, &camera, &mut reference_tiles);
        let reference = layout.to_row_major(&reference_tiles);
        let light = soft::scene_light(scene, tree, radius);
        let incoherent = if incoherent {
            let pixels = layout.tiles().iter().flat_map(|t| t.pixels());
            let diagonal = (tree.bounds().max - tree.bounds().min).length();
            Incoherent::generate(scene, &camera, pixels, &reference_tiles, diagonal, ao_rays, workload::SEED)
        } else {
            Incoherent::default()
        };
        Frame { scene, camera, layout, reference_tiles, reference, light, incoherent }
    }
}

/// One method under test and its scratch buffers.
struct Contender<'s> {
    method: Bound<'s>,
    build_ms: f64,
    layout: TileLayout,
    hits: Vec<Option<Hit>>,
    /// Index into the shadow kernels.
    shadow: usize,
    /// Index into the soft-shadow kernels.
    soft: Option<usize>,
}

/// The distinct kernels of a column, each timed once per round by the first method that has
/// it: (kernel name, contender index).
#[derive(Default)]
struct Kernels {
    kernels: Vec<(String, usize)>,
}

impl Kernels {
    /// The index of kernel `name`, timed through contender `by` the first time.
    fn get(&mut self, name: &str, by: usize) -> usize {
        if let Some(i) = self.kernels.iter().position(|k| k.0 == name) {
            return i;
        }
        self.kernels.push((name.to_string(), by));
        self.kernels.len() - 1
    }
}

/// A built structure of the registry, by name.
type Built = (&'static str, Box<dyn std::any::Any + Send + Sync>);

/// What [`build_all`] built.
struct Builds {
    tree: KdTree,
    others: Vec<Built>,
    /// Median build milliseconds per structure name ([`KDTREE`] for ours).
    build_ms: Vec<(&'static str, f64)>,
}

/// Builds our kd-tree and every other structure `names` need, `rounds` times interleaved
/// (ours, then each other structure in turn). Returns the tree, the structures and the median
/// build milliseconds per structure name.
fn build_all(
    registry: &Registry,
    scene: &Scene,
    needed: &[&'static str],
    rounds: u32,
    progress: &dyn Progress,
) -> Result<Builds, Error> {
    let bar = progress.task(&format!("builds: {}", scene.name), Some(u64::from(rounds)));
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); needed.len() + 1];
    let mut tree = None;
    let mut built: Vec<Option<Box<dyn std::any::Any + Send + Sync>>> = needed.iter().map(|_| None).collect();
    for _ in 0..rounds.max(1) {
        let (secs, t) = timed(|| KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()));
        times[0].push(secs * 1e3);
        tree = Some(t?);
        for (i, name) in needed.iter().enumerate() {
            let entry =
                registry.structure(name).ok_or_else(|| Error::Usage(format!("no structure '{name}' in this build")))?;
            built[i] = None;
            let (secs, b) = timed(|| (entry.build)(scene));
            built[i] = Some(b?);
            times[i + 1].push(secs * 1e3);
        }
        bar.inc();
    }
    bar.finish();
    let tree = tree.ok_or_else(|| Error::Usage("no build was run".into()))?;
    let others = needed.iter().zip(built).filter_map(|(n, b)| Some((*n, b?))).collect();
    let medians = std::iter::once(KDTREE).chain(needed.iter().copied()).zip(times.iter().map(|t| median(t))).collect();
    Ok(Builds { tree, others, build_ms: medians })
}

/// The measured rows and what the text table's heading says.
#[derive(Clone, Debug)]
pub struct CompareReport {
    /// One row per method, `mono` first.
    pub rows: Vec<CompareRow>,
    /// The view's name.
    pub view: String,
    /// The configuration measured.
    pub config: CompareConfig,
    /// Threads of the pool.
    pub threads: usize,
    /// The Embree device line (version, packet widths), or why Embree is missing.
    pub embree_note: Option<String>,
}

/// `rttest compare`: every method of `config` on the same rays, builds and passes
/// interleaved (see the module documentation).
pub fn run(config: &CompareConfig, progress: &dyn Progress) -> Result<CompareReport, Error> {
    if !(config.light_radius.is_finite() && config.light_radius >= 0.0) {
        return Err(Error::Usage(format!("--light-radius {} must be a finite number >= 0", config.light_radius)));
    }
    if !(1..=64).contains(&config.ao_rays) {
        return Err(Error::Usage(format!("--ao-rays {} must be in 1..=64", config.ao_rays)));
    }
    let registry = baselines::registry();
    let selected = select_methods(&registry, config)?;
    let scene = scenes::load_scene(&config.scene)?;
    let (w, h) = config.size;
    let (camera, view) = view_camera(&scene, config.view.as_deref(), w, h)?;

    // Builds, interleaved: our kd-tree, then each other structure, `build_rounds` times.
    let mut needed: Vec<&'static str> = Vec::new();
    for s in &selected {
        let structure = registry.entry(s.entry).structure;
        if structure != KDTREE && !needed.contains(&structure) {
            needed.push(structure);
        }
    }
    let Builds { tree, others, build_ms } = build_all(&registry, &scene, &needed, config.build_rounds, progress)?;
    let mut structures = Structures::new(&tree);
    for (name, built) in others {
        structures.insert(name, built);
    }
    let frame = Frame::new(&scene, &tree, camera, config.light_radius, config.ao_rays, !config.no_incoherent);
    let (ao, diffuse, reflect) = (&frame.incoherent.ao, &frame.incoherent.diffuse, &frame.incoherent.reflect);

    // The contenders and their kernels.
    let mut contenders = Vec::new();
    let mut shadows = Kernels::default();
    let mut softs = Kernels::default();
    for s in &selected {
        let method = registry.bind(s, &structures)?;
        let entry = method.entry;
        let index = contenders.len();
        let build = build_ms.iter().find(|b| b.0 == entry.structure).map_or(0.0, |b| b.1);
        let layout = TileLayout::new(w, h, method.options.tile);
        let hits = vec![None; layout.pixel_count()];
        let shadow = shadows.get(&method.kernels.shadow, index);
        let soft = (!config.no_soft).then(|| softs.get(&method.kernels.soft, index));
        contenders.push(Contender { method, build_ms: build, layout, hits, shadow, soft });
    }

    // Warm-up frame: the hits of every method, for the mismatch column; the incoherent
    // answers of every method against the first's (`mono`).
    let mut checks = Vec::new();
    let mut ao_occluded = vec![false; ao.len()];
    let mut diffuse_hits = vec![None; diffuse.len()];
    let mut reflect_hits = vec![None; reflect.len()];
    let (mut ao_reference, mut diffuse_reference, mut reflect_reference) = (Vec::new(), Vec::new(), Vec::new());
    let mut incoherent_checks = Vec::new();
    for (i, c) in contenders.iter_mut().enumerate() {
        c.method.tracer.primary(&c.layout, &camera, &mut c.hits, None);
        checks.push(mismatches(&scene, &camera, &frame.reference, &c.layout.to_row_major(&c.hits)));
        c.method.tracer.stream_occluded(ao, &mut ao_occluded);
        c.method.tracer.stream(diffuse, &mut diffuse_hits);
        c.method.tracer.stream(reflect, &mut reflect_hits);
        if i == 0 {
            (ao_reference, diffuse_reference, reflect_reference) =
                (ao_occluded.clone(), diffuse_hits.clone(), reflect_hits.clone());
        }
        let ao_mismatch = ao_occluded.iter().zip(&ao_reference).filter(|(a, b)| a != b).count() as u64;
        let other_prim = |hits: &[Option<Hit>], reference: &[Option<Hit>]| {
            hits.iter().zip(reference).filter(|(a, b)| a.map(|h| h.prim) != b.map(|h| h.prim)).count() as u64
        };
        let diffuse_mismatch = other_prim(&diffuse_hits, &diffuse_reference);
        let reflect_mismatch = other_prim(&reflect_hits, &reflect_reference);
        incoherent_checks.push((ao_mismatch, diffuse_mismatch, reflect_mismatch));
    }

    // Interleaved rounds: every primary pass, then every distinct shadow kernel, then every
    // distinct soft-shadow kernel.
    let incoherent = if ao.is_empty() && diffuse.is_empty() { 0 } else { contenders.len() };
    let steps =
        u64::from(config.rounds) * (contenders.len() + shadows.kernels.len() + softs.kernels.len() + incoherent) as u64;
    let bar = progress.task(&format!("compare: {}", scene.name), Some(steps));
    let mut primary_secs = vec![Vec::new(); contenders.len()];
    let mut shadow_secs = vec![Vec::new(); shadows.kernels.len()];
    let mut soft_secs = vec![Vec::new(); softs.kernels.len()];
    let mut shadow_rays = vec![0u64; shadows.kernels.len()];
    let mut soft_rays = vec![0u64; softs.kernels.len()];
    let mut occluded = vec![false; frame.layout.pixel_count()];
    let surfaces = trace::shade::surfaces(&scene.mesh);
    let frame_view = trace::frame::View { layout: &frame.layout, scene: &scene, surfaces: &surfaces, camera: &camera };
    let mut visible = vec![0.0f32; frame.layout.pixel_count()];
    let mut ao_secs = vec![Vec::new(); incoherent];
    let mut diffuse_secs = vec![Vec::new(); incoherent];
    let mut reflect_secs = vec![Vec::new(); incoherent];
    for _ in 0..config.rounds {
        for (c, secs) in contenders.iter_mut().zip(&mut primary_secs) {
            secs.push(timed(|| c.method.tracer.primary(&c.layout, &camera, &mut c.hits, None)).0);
            bar.inc();
        }
        for (i, &(_, by)) in shadows.kernels.iter().enumerate() {
            let tracer = &contenders[by].method.tracer;
            let (secs, (rays, _)) = timed(|| tracer.shadow(&frame_view, &frame.reference_tiles, &mut occluded, None));
            shadow_secs[i].push(secs);
            shadow_rays[i] = rays;
            bar.inc();
        }
        for (i, &(_, by)) in softs.kernels.iter().enumerate() {
            let tracer = &contenders[by].method.tracer;
            let (secs, stats) =
                timed(|| tracer.soft(&frame_view, &frame.reference_tiles, &frame.light, &mut visible, None));
            soft_secs[i].push(secs);
            soft_rays[i] = stats.rays;
            bar.inc();
        }
        for (i, c) in contenders.iter().take(incoherent).enumerate() {
            ao_secs[i].push(timed(|| c.method.tracer.stream_occluded(ao, &mut ao_occluded)).0);
            diffuse_secs[i].push(timed(|| c.method.tracer.stream(diffuse, &mut diffuse_hits)).0);
            reflect_secs[i].push(timed(|| c.method.tracer.stream(reflect, &mut reflect_hits)).0);
            bar.inc();
        }
    }
    bar.finish();

    let pixels = u64::from(w) * u64::from(h);
    let threads = rayon::current_num_threads();
    let rows = contenders
        .iter()
        .zip(&primary_secs)
        .zip(checks)
        .zip(incoherent_checks)
        .enumerate()
        .map(|(i, (((c, secs), mismatches), (ao_mismatch, diffuse_mismatch, reflect_mismatch)))| {
            let ao_s = ao_secs.get(i).map(|s| median(s));
            let diffuse_s = diffuse_secs.get(i).map(|s| median(s));
            let reflect_s = reflect_secs.get(i).map(|s| median(s));
            let primary = median(secs);
            let shadow = (median(&shadow_secs[c.shadow]), shadow_rays[c.shadow], shadows.kernels[c.shadow].0.clone());
            let soft = c.soft.map(|i| (median(&soft_secs[i]), soft_rays[i], softs.kernels[i].0.clone()));
            CompareRow {
                scene: scene.name.clone(),
                method: c.method.name.clone(),
                family: c.method.entry.family.to_string(),
                build_ms: c.build_ms,
                primary_mrays_per_s: mrays_per_s(pixels, primary),
                shadow_mrays_per_s: Some(mrays_per_s(shadow.1, shadow.0)),
                soft16_mrays_per_s: soft.as_ref().map(|s| mrays_per_s(s.1, s.0)),
                mismatches,
                pixels,
                primary_ms: primary * 1e3,
                shadow_ms: Some(shadow.0 * 1e3),
                soft16_ms: soft.as_ref().map(|s| s.0 * 1e3),
                ao_mrays_per_s: ao_s.map(|s| mrays_per_s(ao.len() as u64, s)),
                diffuse_mrays_per_s: diffuse_s.map(|s| mrays_per_s(diffuse.len() as u64, s)),
                ao_ms: ao_s.map(|s| s * 1e3),
                diffuse_ms: diffuse_s.map(|s| s * 1e3),
                reflect_mrays_per_s: reflect_s.map(|s| mrays_per_s(reflect.len() as u64, s)),
                reflect_ms: reflect_s.map(|s| s * 1e3),
                reflect_rays: reflect.len() as u64,
                reflect_mismatch,
                ao_rays: ao.len() as u64,
                diffuse_rays: diffuse.len() as u64,
                ao_mismatch,
                diffuse_mismatch,
                shadow_kernel: Some(shadow.2),
                soft16_kernel: soft.map(|s| s.2),
                threads,
                rounds: config.rounds,
            }
        })
        .collect();
    let embree_note = if cfg!(feature = "embree") {
        baselines::embree_note()
    } else {
        Some("Embree: not in this build (`--features embree`, needs libembree-dev)".to_string())
    };
    Ok(CompareReport { rows, view, config: config.clone(), threads, embree_note })
}

/// How the primary hits of a method differ from ours, pixel by pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Mismatches {
    /// Pixels whose hit names another triangle (or hits where ours misses, or misses where
    /// ours hits).
    pub prim_mismatch: u64,
    /// Of those, ties: both hit at the same distance (relative 1e-4), so the ray meets both
    /// triangles there (at a shared edge or vertex, where two surfaces meet, or on coincident
    /// faces) and either is a right answer.
    pub prim_ties: u64,
    /// Of the ties, those at a shared edge or vertex (triangles sharing a vertex position,
    /// our hit point within 1e-4 of the triangles' size of the shared edge or vertex).
    pub prim_edge_ties: u64,
    /// Of the ties, those on coincident faces: coplanar triangles sharing no edge there
    /// (faces of touching objects, z-fighting).
    pub prim_coincident: u64,
    /// Of those, a hit where the other misses (a ray through a crack or an edge).
    pub prim_hit_vs_miss: u64,
}

/// The pixels whose hit in `got` differs from `reference` (row-major, rays of `camera`),
/// classified (see [`Mismatches`]).
pub fn mismatches(scene: &Scene, camera: &Camera, reference: &[Option<Hit>], got: &[Option<Hit>]) -> Mismatches {
    let mut m = Mismatches::default();
    for (i, (r, g)) in reference.iter().zip(got).enumerate() {
        if r.map(|h| h.prim) == g.map(|h| h.prim) {
            continue;
        }
        m.prim_mismatch += 1;
        let (Some(r), Some(g)) = (r, g) else {
            m.prim_hit_vs_miss += 1;
            continue;
        };
        if (r.t - g.t).abs() > 1e-4 * r.t.abs().max(g.t.abs()) {
            continue;
        }
        let (x, y) = ((i % camera.width as usize) as u32, (i / camera.width as usize) as u32);
        let (origin, dir) = camera.pixel_ray(x, y);
        m.prim_ties += 1;
        if is_edge_tie(scene, origin + r.t * dir, r, g) {
            m.prim_edge_ties += 1;
        } else if coplanar(&scene.mesh.triangle(r.prim as usize), &scene.mesh.triangle(g.prim as usize)) {
            m.prim_coincident += 1;
        }
    }
    m
}

/// Whether hits `a` and `b` on different triangles are a tie at their shared edge or vertex
/// (see [`mismatches`]); `p` is the point of `a`.
fn is_edge_tie(scene: &Scene, p: glam::Vec3, a: &Hit, b: &Hit) -> bool {
    if (a.t - b.t).abs() > 1e-4 * a.t.abs().max(b.t.abs()) {
        return false;
    }
    let (ta, tb) = (scene.mesh.triangle(a.prim as usize), scene.mesh.triangle(b.prim as usize));
    let shared: Vec<glam::Vec3> = ta.iter().copied().filter(|v| tb.contains(v)).collect();
    let size = ta.iter().chain(&tb).fold(0.0f32, |m, v| m.max((*v - ta[0]).length()));
    near_shared(&shared, p, 1e-4 * size.max(f32::MIN_POSITIVE))
}

impl std::fmt::Display for CompareReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let c = &self.config;
        let header = Header {
            scene: self.rows.first().map_or("", |r| r.scene.as_str()),
            view: &self.view,
            size: c.size,
            threads: self.threads,
            rounds: c.rounds,
            build_rounds: c.build_rounds,
            light_radius: c.light_radius,
            ao_rays: c.ao_rays,
            embree_note: self.embree_note.clone(),
        };
        write!(f, "{}", table(&header, &self.rows))
    }
}

/// The text table's heading facts.
struct Header<'a> {
    scene: &'a str,
    view: &'a str,
    size: (u32, u32),
    threads: usize,
    rounds: u32,
    build_rounds: u32,
    light_radius: f32,
    ao_rays: u32,
    embree_note: Option<String>,
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".into(), |v| format!("{v:.digits$}"))
}

/// A column of the table, read from a row.
type Column = fn(&CompareRow) -> Option<f64>;

/// The markdown table, with the best of ours over the best baseline per column.
fn table(h: &Header<'_>, rows: &[CompareRow]) -> String {
    let mut out = String::new();
    let (w, ht) = h.size;
    let _ = writeln!(
        out,
        "rttest compare: {}, view {}, {w}x{ht}, {} threads; medians of {} interleaved rounds (builds: {}); soft16 = 16 rays per point to a spherical light of radius {} Sponza units; ao = {} cosine rays per primary hit, a tenth of the scene's diagonal long; diffuse = 1 cosine ray per primary hit; reflect = 1 mirror reflection per primary hit (every surface a mirror).",
        h.scene, h.view, h.threads, h.rounds, h.build_rounds, h.light_radius, h.ao_rays
    );
    if let Some(note) = &h.embree_note {
        let _ = writeln!(out, "{note}");
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "| method | build ms | primary Mrays/s | shadow Mrays/s | soft16 Mrays/s | ao Mrays/s | diffuse Mrays/s | reflect Mrays/s | prim mismatch | ties | of which edge | of which coincident | hit vs miss | ao / diffuse / reflect mismatch | shadow kernel | soft16 kernel |"
    );
    let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|");
    for r in rows {
        let _ = writeln!(
            out,
            "| {} | {:.1} | {:.2} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} / {} / {} | {} | {} |",
            r.method,
            r.build_ms,
            r.primary_mrays_per_s,
            opt(r.shadow_mrays_per_s, 2),
            opt(r.soft16_mrays_per_s, 2),
            opt(r.ao_mrays_per_s, 2),
            opt(r.diffuse_mrays_per_s, 2),
            opt(r.reflect_mrays_per_s, 2),
            r.mismatches.prim_mismatch,
            r.mismatches.prim_ties,
            r.mismatches.prim_edge_ties,
            r.mismatches.prim_coincident,
            r.mismatches.prim_hit_vs_miss,
            r.ao_mismatch,
            r.diffuse_mismatch,
            r.reflect_mismatch,
            r.shadow_kernel.as_deref().unwrap_or("-"),
            r.soft16_kernel.as_deref().unwrap_or("-"),
        );
    }
    let best = |fam: &dyn Fn(&str) -> bool, col: Column| {
        rows.iter().filter(|r| fam(&r.family)).filter_map(|r| col(r).map(|v| (v, r.method.clone()))).fold(
            None,
            |best: Option<(f64, String)>, x| match best {
                Some(b) if b.0 >= x.0 => Some(b),
                _ => Some(x),
            },
        )
    };
    let columns: [(&str, Column); 6] = [
        ("primary", |r| Some(r.primary_mrays_per_s)),
        ("shadow", |r| r.shadow_mrays_per_s),
        ("soft16", |r| r.soft16_mrays_per_s),
        ("ao", |r| r.ao_mrays_per_s),
        ("diffuse", |r| r.diffuse_mrays_per_s),
        ("reflect", |r| r.reflect_mrays_per_s),
    ];
    for base in ["embree", "bvh", "obvhs"] {
        if !rows.iter().any(|r| r.family == base) {
            continue;
        }
        let _ = writeln!(out);
        for (label, col) in columns {
            if let (Some(o), Some(b)) = (best(&|f| f == "ours", col), best(&|f| f == base, col)) {
                let _ = writeln!(
                    out,
                    "- {label}: best of ours {} {:.2} Mrays/s, best {base} {} {:.2} Mrays/s: ours / {base} = {:.2}",
                    o.1,
                    o.0,
                    b.1,
                    b.0,
                    o.0 / b.0
                );
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(methods: &[&str]) -> CompareConfig {
        CompareConfig {
            size: (16, 16),
            rounds: 1,
            build_rounds: 1,
            methods: methods.iter().map(|s| s.to_string()).collect(),
            ..CompareConfig::default()
        }
    }

    fn names(methods: &[&str]) -> Result<Vec<String>, Error> {
        let selected = select_methods(&baselines::registry(), &config(methods))?;
        Ok(selected.into_iter().map(|s| s.name).collect())
    }

    #[test]
    fn method_selection() {
        let all = names(&["ours"]).unwrap();
        assert_eq!(all[0], "mono");
        assert!(all.contains(&"mft-cone-16".to_string()) && all.contains(&"frustum-8".to_string()));
        assert_eq!(names(&["mft-16"]).unwrap(), vec!["mono", "mft-16"]);
        assert!(names(&["nonsense"]).is_err());
        let mut bad = config(&["all"]);
        bad.tiles = vec![6];
        assert!(select_methods(&baselines::registry(), &bad).is_err());
        for name in ["embree", "embree-16", "bvh", "obvhs", "bvh-crates"] {
            match (names(&[name]), baselines::feature_hint(name)) {
                (Ok(list), None) => assert!(list.len() > 1, "{name}: {list:?}"),
                (Err(e), Some(_)) => assert!(e.to_string().contains("--features"), "{name}: {e}"),
                (r, hint) => panic!("{name}: {r:?} with hint {hint:?}"),
            }
        }
    }

    /// A whole (tiny) run: every method of ours gives the reference hits, and the rows share
    /// their hard-shadow kernels (single rays, 2x2 packets, or each tile's frusta) and name
    /// their soft-shadow kernels.
    #[test]
    fn a_run_of_ours_has_no_mismatch() {
        let report = run(&config(&["ours"]), &trace::progress::Quiet).unwrap();
        assert_eq!(report.rows.len(), names(&["ours"]).unwrap().len());
        // The packet kernels run at the widest width of this CPU, and so do the lane frusta
        // (16 with AVX-512, 8 with AVX2, else 4: their names say so, `kd-packets-w16`,
        // `kd-lane-frusta-x16`, `kd-lane-frusta`, `kd-lane-frusta-x4`).
        let simd = kdtree::isa::SimdLevel::active();
        let wide = packets::Width::for_level(simd).suffix();
        let lanes = match packets::LaneWidth::widest() {
            packets::LaneWidth::Eight => "kd-lane-frusta".to_string(),
            w => format!("kd-lane-frusta-x{}", w.lanes()),
        };
        for r in &report.rows {
            // mbvh-4 and mbvh-8 trace other structures: at equal distance they may name the
            // other triangle of a tie (the harness's rules); the kd-tree methods name `mono`'s.
            let m = &r.mismatches;
            let bvh = r.method.starts_with("mbvh-");
            let differing = if bvh { m.prim_mismatch - m.prim_ties } else { m.prim_mismatch };
            assert_eq!(differing, 0, "{}: {m:?}", r.method);
            // Hard shadows: the BVHs' own, single rays for `mono`, shadow frusta for
            // `multi-frusta-N`, frusta in SIMD lanes for `lane-frusta-N`, 2x2 packets for the
            // other tiled and packet methods.
            let kernel = match r.method.as_str() {
                // The entry's name, or with the lanes it fell back to where the CPU lacks
                // its widest (`mbvh-8-p16-avx2`, `mbvh-16-scalar-nodes`).
                m if bvh => {
                    let k = r.shadow_kernel.as_deref().unwrap_or_default();
                    assert!(k == m || k.starts_with(&format!("{m}-")), "{m}: {k}");
                    k.to_string()
                }
                "mono" => "kd-single".to_string(),
                m if m.starts_with("lane-frusta-") => lanes.clone(),
                m => m.strip_prefix("multi-frusta-").map_or(format!("kd-packets{wide}"), |t| format!("kd-frusta-{t}")),
            };
            assert_eq!(r.shadow_kernel.as_deref(), Some(kernel.as_str()));
            assert!(r.primary_mrays_per_s > 0.0);
            // The incoherent columns: every method timed on the same rays, same answers.
            assert!(r.ao_rays > 0 && r.diffuse_rays > 0 && r.ao_rays == 4 * r.diffuse_rays, "{}", r.method);
            assert!(r.ao_mrays_per_s.is_some_and(|v| v > 0.0) && r.diffuse_mrays_per_s.is_some_and(|v| v > 0.0));
            assert!(r.reflect_rays == r.diffuse_rays && r.reflect_mrays_per_s.is_some_and(|v| v > 0.0));
            if !bvh {
                assert_eq!((r.ao_mismatch, r.diffuse_mismatch, r.reflect_mismatch), (0, 0, 0), "{}", r.method);
            } else {
                // Ties again (none at the time of writing); the conformance test judges them.
                assert!(100 * (r.ao_mismatch + r.diffuse_mismatch) <= r.diffuse_rays, "{r:?}");
            }
        }
        let soft = |m: &str| report.rows.iter().find(|r| r.method == m).and_then(|r| r.soft16_kernel.clone());
        assert_eq!(soft("mono").as_deref(), Some("kd-single"));
        // Every packet and cone method: its tile's rays per light stratum as 2x2 packets
        // (the per-point pyramid and cone are `SoftGrouping::PerPoint`, Table 4.6).
        let strata = format!("kd-stratum-packets{wide}");
        assert_eq!(soft("packet").as_deref(), Some(strata.as_str()));
        assert_eq!(soft("mft-8").as_deref(), Some(strata.as_str()));
        assert_eq!(soft("cone-16").as_deref(), Some(strata.as_str()));
        assert_eq!(soft("multi-frusta-16").as_deref(), Some("kd-multi-frusta-16"));
        assert_eq!(soft("lane-frusta-16").as_deref(), Some(lanes.as_str()));
        let text = report.to_string();
        assert!(text.contains("| mft-cone-16 |") && text.contains("| mbvh-4 |") && text.contains("ao Mrays/s"));
        let quiet = CompareConfig { no_incoherent: true, ..config(&["mbvh-4"]) };
        let report = run(&quiet, &trace::progress::Quiet).unwrap();
        assert!(report.rows.iter().all(|r| r.ao_mrays_per_s.is_none() && r.ao_rays == 0));
    }

    #[test]
    fn ties_at_a_shared_edge() {
        // Two triangles of a quad in the plane z = 0, seen from above.
        let mesh = scenes::Mesh {
            positions: vec![
                glam::Vec3::new(0.0, 0.0, 0.0),
                glam::Vec3::new(1.0, 0.0, 0.0),
                glam::Vec3::new(1.0, 1.0, 0.0),
                glam::Vec3::new(0.0, 1.0, 0.0),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            normals: None,
            material_ids: vec![0, 0],
            materials: vec![],
            prim_ids: vec![0, 1],
        };
        let scene = Scene { mesh, ..scenes::load_scene("triangle").unwrap() };
        let a = Hit { t: 1.0, u: 0.0, v: 0.0, prim: 0 };
        let b = Hit { t: 1.0, u: 0.0, v: 0.0, prim: 1 };
        // On the diagonal: a tie; far from it: not; another distance: not.
        assert!(is_edge_tie(&scene, glam::Vec3::new(0.5, 0.5, 0.0), &a, &b));
        assert!(!is_edge_tie(&scene, glam::Vec3::new(0.9, 0.1, 0.0), &a, &b));
        assert!(!is_edge_tie(&scene, glam::Vec3::new(0.5, 0.5, 0.0), &a, &Hit { t: 1.1, ..b }));
    }
}
