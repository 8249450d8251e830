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
//! slow phase of a noisy machine hits every method alike; medians are reported. Our renderer
//! traces shadow rays one by one whatever the primary method, so every row of ours shows the
//! one single-ray shadow kernel; our soft shadows are single rays (`mono`), the pyramid of the
//! 16 rays (`packet`, `samesign`, `frustum-N`, `mft-N`) or their cone (`cone-N`, `mft-cone-N`).

use std::fmt::Write as _;
use std::rc::Rc;
use std::time::Instant;

use clap::Args;
use cones::ShadowMethod;
use kdtree::{BuildConfig, Hit, KdTree, NoCounters};
use scenes::{Camera, Scene, SphereLight};
use serde::Serialize;

use crate::Error;
use crate::baselines::{self, BlockTracer, SingleRays};
use crate::cli::{GlobalArgs, parse_size};
use crate::progress::{self, Progress};
use crate::render::{Method, Renderer, Shadows, TILE_SIZE, TileLayout};
use crate::report::mrays_per_s;
use crate::soft;

/// `rttest compare` options.
#[derive(Debug, Clone, Args)]
pub struct CompareArgs {
    /// A built-in scene or a path to an .obj or .obj.gz file.
    #[arg(long, default_value = "atrium", value_name = "NAME|PATH")]
    pub scene: String,
    /// A named view of the scene (default: its first view).
    #[arg(long, value_name = "NAME")]
    pub view: Option<String>,
    /// Image size.
    #[arg(long, value_name = "WxH", default_value = "512x512", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Timed rounds; each times every method once, in turn; medians are reported.
    #[arg(long, default_value_t = 5, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub rounds: u32,
    /// Timed builds of each structure, interleaved; the median is reported.
    #[arg(long, default_value_t = 3, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=100))]
    pub build_rounds: u32,
    /// Methods, comma-separated: names (`mono`, `mft-16`, `embree-16`, `bvh`, ...) or groups
    /// (`all`, `ours`, `embree`, `bvh-crates`). `all` takes the baselines this build has.
    #[arg(long, value_delimiter = ',', default_value = "all", value_name = "LIST")]
    pub methods: Vec<String>,
    /// Tile sizes of our frustum, MFT, cone and MFT-cone methods (multiples of 4, 4 to 64).
    #[arg(long, value_delimiter = ',', default_value = "8,16", value_name = "LIST",
          value_parser = clap::value_parser!(u32).range(4..=64))]
    pub tiles: Vec<u32>,
    /// Radius of the spherical light of the soft shadows, in Sponza units (scaled by the
    /// scene's diagonal, as Table 4.6): a finite number >= 0.
    #[arg(long, default_value_t = 1.0, value_name = "R")]
    pub light_radius: f32,
    /// Leave out the 16-sample soft shadows (the slowest column).
    #[arg(long)]
    pub no_soft: bool,
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
    /// The shadow kernel (rows of ours share the single-ray one).
    pub shadow_kernel: Option<String>,
    /// The soft-shadow kernel (rows of ours share the single, pyramid and cone ones).
    pub soft16_kernel: Option<String>,
    /// Threads of the pool.
    pub threads: usize,
    /// Timed rounds.
    pub rounds: u32,
}

/// What a method group needs to exist in this build.
fn feature_hint(name: &str) -> Option<&'static str> {
    if name.starts_with("embree") {
        (!cfg!(feature = "embree")).then_some(
            "Embree baselines need the `embree` feature: `apt-get install -y libembree-dev`, then build with `cargo build --release -p bench --features embree`",
        )
    } else if matches!(name, "bvh" | "obvhs" | "bvh-crates") {
        (!cfg!(feature = "bvh-crates")).then_some(
            "the bvh and obvhs baselines need the `bvh-crates` feature: build with `cargo build --release -p bench --features bvh-crates`",
        )
    } else {
        None
    }
}

/// Every method name this build knows, in table order.
pub fn all_method_names(tiles: &[u32]) -> Vec<String> {
    let mut names: Vec<String> = ["mono", "packet", "samesign"].map(String::from).to_vec();
    for m in ["frustum", "mft", "cone", "mft-cone"] {
        names.extend(tiles.iter().map(|t| format!("{m}-{t}")));
    }
    if cfg!(feature = "embree") {
        names.extend(
            [
                "embree-1",
                "embree-4",
                "embree-8",
                "embree-16",
                "embree-1-incoherent",
                "embree-16-incoherent",
                "embree-1-medium",
                "embree-16-medium",
            ]
            .map(String::from),
        );
    }
    if cfg!(feature = "bvh-crates") {
        names.extend(["bvh", "obvhs"].map(String::from));
    }
    names
}

/// The methods `--methods` selects, in table order, `mono` always first (the reference).
pub fn select_methods(args: &CompareArgs) -> Result<Vec<String>, Error> {
    for &t in &args.tiles {
        if t % 4 != 0 {
            return Err(Error::Usage(format!("--tiles: {t} is not a multiple of 4")));
        }
    }
    let all = all_method_names(&args.tiles);
    let mut wanted = vec![false; all.len()];
    for token in &args.methods {
        let token = token.trim();
        if let Some(hint) = feature_hint(token) {
            return Err(Error::Usage(format!("--methods {token}: {hint}")));
        }
        let matched: Vec<usize> = match token {
            "all" => (0..all.len()).collect(),
            "ours" => (0..all.len()).filter(|&i| family(&all[i]) == "ours").collect(),
            "embree" => (0..all.len()).filter(|&i| family(&all[i]) == "embree").collect(),
            "bvh-crates" => (0..all.len()).filter(|&i| matches!(family(&all[i]), "bvh" | "obvhs")).collect(),
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
    Ok(all.into_iter().zip(wanted).filter(|(_, w)| *w).map(|(n, _)| n).collect())
}

/// `ours`, `embree`, `bvh` or `obvhs`.
fn family(name: &str) -> &'static str {
    if name.starts_with("embree") {
        "embree"
    } else if name == "bvh" {
        "bvh"
    } else if name == "obvhs" {
        "obvhs"
    } else {
        "ours"
    }
}

/// Our primary method and tile of a name such as `mft-cone-16`.
fn our_method(name: &str) -> Option<(Method, u32)> {
    let fixed = match name {
        "mono" => Some(Method::Mono),
        "packet" => Some(Method::Packet),
        "samesign" => Some(Method::Samesign),
        _ => None,
    };
    if let Some(m) = fixed {
        return Some((m, TILE_SIZE));
    }
    let (m, tile) = name.rsplit_once('-')?;
    let tile: u32 = tile.parse().ok()?;
    let method = match m {
        "frustum" => Method::Frustum,
        "mft" => Method::Mft,
        "cone" => Method::Cone,
        "mft-cone" => Method::MftCone,
        _ => return None,
    };
    Some((method, tile))
}

/// Our soft-shadow kernel behind a primary method.
fn our_soft_kernel(method: Method) -> ShadowMethod {
    match method {
        Method::Mono => ShadowMethod::Single,
        Method::Packet | Method::Samesign | Method::Frustum | Method::Mft => ShadowMethod::Pyramid,
        Method::Cone | Method::MftCone => ShadowMethod::Cone,
    }
}

/// The fixed inputs of every pass: the view, our reference hits and the light.
pub struct Frame<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// The camera.
    pub camera: Camera,
    /// The 16 x 16 tiles the baselines' passes run over (as our renderer's).
    pub layout: TileLayout,
    /// Our single-ray primary hits, tile order of `layout`: the shadow rays start from them.
    pub reference_tiles: Vec<Option<Hit>>,
    /// The same, row-major: the soft-shadow rays start from them, and mismatches are
    /// counted against them.
    pub reference: Vec<Option<Hit>>,
    /// The soft shadows' spherical light.
    pub light: SphereLight,
}

impl<'a> Frame<'a> {
    /// The frame of `scene` seen by `camera`, with `tree`'s single-ray hits as the reference
    /// and a light of `radius` Sponza units at the scene's point light.
    pub fn new(scene: &'a Scene, tree: &KdTree, camera: Camera, radius: f32) -> Frame<'a> {
        let layout = TileLayout::new(camera.width, camera.height, TILE_SIZE);
        let mut reference_tiles = vec![None; layout.pixel_count()];
        baselines::primary_pass(&SingleRays(tree), &camera, &layout, &mut reference_tiles);
        let reference = layout.to_row_major(&reference_tiles);
        let diag = (tree.bounds().max - tree.bounds().min).length();
        let light = SphereLight {
            center: scene.point_light.position,
            radius: soft::scaled_radius(radius, diag),
            intensity: scene.point_light.intensity,
        };
        Frame { scene, camera, layout, reference_tiles, reference, light }
    }
}

/// A timed primary pass: returns its seconds and, when asked, the hits (row-major).
pub type PrimaryPass<'a> = Box<dyn FnMut(bool) -> (f64, Option<Vec<Option<Hit>>>) + 'a>;
/// A timed shadow pass: returns its seconds and the rays traced.
pub type RaysPass<'a> = Box<dyn FnMut() -> (f64, u64) + 'a>;

/// One method under test.
struct Contender<'a> {
    name: String,
    build_ms: f64,
    primary: PrimaryPass<'a>,
    /// Index into the shadow kernels.
    shadow: Option<usize>,
    /// Index into the soft-shadow kernels.
    soft: Option<usize>,
}

/// The distinct shadow (or soft-shadow) kernels, each timed once per round.
#[derive(Default)]
struct Kernels<'a> {
    names: Vec<String>,
    passes: Vec<RaysPass<'a>>,
}

impl<'a> Kernels<'a> {
    /// The index of kernel `name`, adding it with `make` the first time.
    fn get(&mut self, name: &str, make: impl FnOnce() -> RaysPass<'a>) -> usize {
        if let Some(i) = self.names.iter().position(|n| n == name) {
            return i;
        }
        self.names.push(name.to_string());
        self.passes.push(make());
        self.names.len() - 1
    }
}

/// Seconds of `f`.
fn timed<T>(f: impl FnOnce() -> T) -> (f64, T) {
    let start = Instant::now();
    let out = f();
    (start.elapsed().as_secs_f64(), out)
}

/// A shadow or soft-shadow pass, made when its kernel is first needed.
pub type MakePass<'a> = Box<dyn FnOnce() -> RaysPass<'a> + 'a>;

/// The primary, shadow and soft-shadow passes of a baseline.
pub type Passes<'a> = (PrimaryPass<'a>, MakePass<'a>, MakePass<'a>);

/// The primary, shadow and soft-shadow passes of a baseline [`BlockTracer`] on `frame`.
pub fn block_passes<'a, B: BlockTracer + 'a>(b: B, frame: &'a Frame<'a>) -> Passes<'a> {
    let b = Rc::new(b);
    let mut hits = vec![None; frame.layout.pixel_count()];
    let pb = Rc::clone(&b);
    let primary: PrimaryPass<'a> = Box::new(move |want| {
        let (secs, _) = timed(|| baselines::primary_pass(&*pb, &frame.camera, &frame.layout, &mut hits));
        (secs, want.then(|| frame.layout.to_row_major(&hits)))
    });
    let sb = Rc::clone(&b);
    let shadow: MakePass<'a> = Box::new(move || -> RaysPass<'a> {
        let mut occluded = vec![false; frame.layout.pixel_count()];
        Box::new(move || {
            let (secs, (rays, _)) = timed(|| {
                baselines::shadow_pass(
                    &*sb,
                    frame.scene,
                    &frame.camera,
                    &frame.layout,
                    &frame.reference_tiles,
                    &mut occluded,
                )
            });
            (secs, rays)
        })
    });
    let soft: MakePass<'a> = Box::new(move || -> RaysPass<'a> {
        Box::new(move || {
            let (secs, (_, rays, _)) =
                timed(|| baselines::soft_pass(&*b, frame.scene, &frame.camera, &frame.reference, &frame.light));
            (secs, rays)
        })
    });
    (primary, shadow, soft)
}

/// Median of `v` (0 for an empty list).
pub fn median(v: &[f64]) -> f64 {
    let mut v: Vec<f64> = v.iter().copied().filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
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

/// Whether two triangles lie in one plane (normals parallel within 1e-4 rad, the second's
/// vertices within 1e-4 of the triangles' size from the first's plane).
fn coplanar(a: &[glam::Vec3; 3], b: &[glam::Vec3; 3]) -> bool {
    let [a, b] = [a, b].map(|t| t.map(|v| v.as_dvec3()));
    let (na, nb) = ((a[1] - a[0]).cross(a[2] - a[0]), (b[1] - b[0]).cross(b[2] - b[0]));
    let (Some(na), Some(nb)) = (na.try_normalize(), nb.try_normalize()) else { return false };
    let size = a.iter().chain(&b).fold(0.0f64, |m, v| m.max((*v - a[0]).length()));
    na.cross(nb).length() <= 1e-4 && b.iter().all(|v| na.dot(*v - a[0]).abs() <= 1e-4 * size)
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
    let tol = 1e-4 * size.max(f32::MIN_POSITIVE);
    match shared[..] {
        [] => false,
        [v] => (p - v).length() <= tol,
        [v, w, ..] => {
            let e = w - v;
            let s = ((p - v).dot(e) / e.length_squared().max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
            (p - (v + s * e)).length() <= tol
        }
    }
}

/// `rttest compare`.
pub fn compare_command(global: &GlobalArgs, args: &CompareArgs) -> Result<(), Error> {
    if !(args.light_radius.is_finite() && args.light_radius >= 0.0) {
        return Err(Error::Usage(format!("--light-radius {} must be a finite number >= 0", args.light_radius)));
    }
    let names = select_methods(args)?;
    let show = progress::enabled(global.json);
    let scene = scenes::load_scene(&args.scene)?;
    let (w, h) = args.size;
    let (camera, view_name) = crate::cli::view_camera(&scene, args.view.as_deref(), w, h)?;

    // Builds, interleaved: ours, then each baseline's structures, `build_rounds` times.
    let bar = Progress::bar(u64::from(args.build_rounds), &format!("builds: {}", scene.name), show);
    let mut kd_ms = Vec::new();
    let mut tree = None;
    #[cfg(feature = "embree")]
    let mut embree = EmbreeBuilds::new(names.iter().any(|n| family(n) == "embree"))?;
    #[cfg(feature = "bvh-crates")]
    let mut crates = baselines::bvh_crates::Builds::new(
        names.iter().any(|n| family(n) == "bvh"),
        names.iter().any(|n| family(n) == "obvhs"),
    );
    for _ in 0..args.build_rounds {
        let (secs, t) = timed(|| KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()));
        kd_ms.push(secs * 1e3);
        tree = Some(t?);
        #[cfg(feature = "embree")]
        embree.build(&scene)?;
        #[cfg(feature = "bvh-crates")]
        crates.build(&scene);
        bar.inc();
    }
    bar.finish();
    let tree = tree.ok_or_else(|| Error::Usage("no build was run".into()))?;
    let frame = Frame::new(&scene, &tree, camera, args.light_radius);
    #[cfg(feature = "embree")]
    let embree_tracers = embree.tracers();
    #[cfg(feature = "bvh-crates")]
    let crate_tracers = crates.tracers();

    // The contenders and their kernels.
    let mut contenders: Vec<Contender<'_>> = Vec::new();
    let mut shadows = Kernels::default();
    let mut softs = Kernels::default();
    let kd_build = median(&kd_ms);
    for name in &names {
        let Some((method, tile)) = our_method(name) else { continue };
        let renderer = Renderer::new(&scene, &tree, camera, method, Shadows::None)
            .with_tile(tile)
            .map_err(|e| Error::Usage(format!("{name}: {e}")))?;
        let mut buf = renderer.buffers();
        let primary: PrimaryPass<'_> = Box::new(move |want| {
            let stats = renderer.trace(&mut buf);
            (stats.primary_secs, want.then(|| renderer.layout().to_row_major(&buf.hits)))
        });
        let shadow = shadows.get("kd-single", || {
            let renderer = Renderer::new(&scene, &tree, camera, Method::Mono, Shadows::Hard);
            let mut buf = renderer.buffers();
            Box::new(move || {
                let stats = renderer.trace(&mut buf);
                (stats.shadow_secs, stats.shadow_rays)
            })
        });
        let soft_kernel = our_soft_kernel(method);
        let soft = (!args.no_soft).then(|| {
            softs.get(&format!("kd-{}", soft_kernel.name()), || {
                let (frame, tree) = (&frame, &tree);
                Box::new(move || {
                    let (secs, pass) = timed(|| {
                        soft::soft_shadow_pass::<NoCounters>(
                            frame.scene,
                            tree,
                            &frame.camera,
                            &frame.reference,
                            &frame.light,
                            soft_kernel,
                        )
                    });
                    (secs, pass.rays)
                })
            })
        });
        contenders.push(Contender { name: name.clone(), build_ms: kd_build, primary, shadow: Some(shadow), soft });
    }
    #[cfg(feature = "embree")]
    for t in embree_tracers.iter().filter(|t| names.contains(&t.name)) {
        let (primary, shadow, soft) = t.passes(&frame);
        let shadow = shadows.get(&t.name, shadow);
        let soft = (!args.no_soft).then(|| softs.get(&t.name, soft));
        contenders.push(Contender { name: t.name.clone(), build_ms: t.build_ms, primary, shadow: Some(shadow), soft });
    }
    #[cfg(feature = "bvh-crates")]
    for t in crate_tracers.iter().filter(|t| names.iter().any(|n| n == t.name())) {
        let (primary, shadow, soft) = t.passes(&frame);
        let shadow = shadows.get(t.name(), shadow);
        let soft = (!args.no_soft).then(|| softs.get(t.name(), soft));
        contenders.push(Contender {
            name: t.name().into(),
            build_ms: t.build_ms(),
            primary,
            shadow: Some(shadow),
            soft,
        });
    }

    // Warm-up frame: the hits of every method, for the mismatch column.
    let mut checks = Vec::new();
    for c in &mut contenders {
        let (_, hits) = (c.primary)(true);
        let hits = hits.unwrap_or_default();
        checks.push(mismatches(&scene, &camera, &frame.reference, &hits));
    }

    // Interleaved rounds.
    let steps = u64::from(args.rounds) * (contenders.len() + shadows.passes.len() + softs.passes.len()) as u64;
    let bar = Progress::bar(steps, &format!("compare: {}", scene.name), show);
    let mut primary_secs = vec![Vec::new(); contenders.len()];
    let mut shadow_secs = vec![Vec::new(); shadows.passes.len()];
    let mut soft_secs = vec![Vec::new(); softs.passes.len()];
    let mut shadow_rays = vec![0u64; shadows.passes.len()];
    let mut soft_rays = vec![0u64; softs.passes.len()];
    for _ in 0..args.rounds {
        for (c, secs) in contenders.iter_mut().zip(&mut primary_secs) {
            secs.push((c.primary)(false).0);
            bar.inc();
        }
        for (i, pass) in shadows.passes.iter_mut().enumerate() {
            let (secs, rays) = pass();
            shadow_secs[i].push(secs);
            shadow_rays[i] = rays;
            bar.inc();
        }
        for (i, pass) in softs.passes.iter_mut().enumerate() {
            let (secs, rays) = pass();
            soft_secs[i].push(secs);
            soft_rays[i] = rays;
            bar.inc();
        }
    }
    bar.finish();

    let pixels = u64::from(camera.width) * u64::from(camera.height);
    let threads = rayon::current_num_threads();
    let rows: Vec<CompareRow> = contenders
        .iter()
        .zip(&primary_secs)
        .zip(&checks)
        .map(|((c, secs), &mismatches)| {
            let primary = median(secs);
            let shadow = c.shadow.map(|i| (median(&shadow_secs[i]), shadow_rays[i], shadows.names[i].clone()));
            let soft = c.soft.map(|i| (median(&soft_secs[i]), soft_rays[i], softs.names[i].clone()));
            CompareRow {
                scene: scene.name.clone(),
                method: c.name.clone(),
                family: family(&c.name).to_string(),
                build_ms: c.build_ms,
                primary_mrays_per_s: mrays_per_s(pixels, primary),
                shadow_mrays_per_s: shadow.as_ref().map(|s| mrays_per_s(s.1, s.0)),
                soft16_mrays_per_s: soft.as_ref().map(|s| mrays_per_s(s.1, s.0)),
                mismatches,
                pixels,
                primary_ms: primary * 1e3,
                shadow_ms: shadow.as_ref().map(|s| s.0 * 1e3),
                soft16_ms: soft.as_ref().map(|s| s.0 * 1e3),
                shadow_kernel: shadow.map(|s| s.2),
                soft16_kernel: soft.map(|s| s.2),
                threads,
                rounds: args.rounds,
            }
        })
        .collect();

    if global.json {
        for row in &rows {
            crate::cli::emit(global, &Json(row))?;
        }
        return Ok(());
    }
    #[cfg(feature = "embree")]
    let embree_note = embree.note();
    #[cfg(not(feature = "embree"))]
    let embree_note = Some("Embree: not in this build (`--features embree`, needs libembree-dev)".to_string());
    let header = Header {
        scene: &scene.name,
        view: &view_name,
        size: args.size,
        threads,
        rounds: args.rounds,
        build_rounds: args.build_rounds,
        light_radius: args.light_radius,
        embree_note,
    };
    print!("{}", table(&header, &rows));
    Ok(())
}

/// A row printed as JSON (its `Display` is never used: `--json` only).
struct Json<'a>(&'a CompareRow);

impl Serialize for Json<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.serialize(s)
    }
}

impl std::fmt::Display for Json<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0.method)
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
        "rttest compare: {}, view {}, {w}x{ht}, {} threads; medians of {} interleaved rounds (builds: {}); soft16 = 16 rays per point to a spherical light of radius {} Sponza units.",
        h.scene, h.view, h.threads, h.rounds, h.build_rounds, h.light_radius
    );
    if let Some(note) = &h.embree_note {
        let _ = writeln!(out, "{note}");
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "| method | build ms | primary Mrays/s | shadow Mrays/s | soft16 Mrays/s | prim mismatch | ties | of which edge | of which coincident | hit vs miss | shadow kernel | soft16 kernel |"
    );
    let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|");
    for r in rows {
        let _ = writeln!(
            out,
            "| {} | {:.1} | {:.2} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.method,
            r.build_ms,
            r.primary_mrays_per_s,
            opt(r.shadow_mrays_per_s, 2),
            opt(r.soft16_mrays_per_s, 2),
            r.mismatches.prim_mismatch,
            r.mismatches.prim_ties,
            r.mismatches.prim_edge_ties,
            r.mismatches.prim_coincident,
            r.mismatches.prim_hit_vs_miss,
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
    let columns: [(&str, Column); 3] = [
        ("primary", |r| Some(r.primary_mrays_per_s)),
        ("shadow", |r| r.shadow_mrays_per_s),
        ("soft16", |r| r.soft16_mrays_per_s),
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

#[cfg(feature = "embree")]
use embree_setup::EmbreeBuilds;

/// The Embree device, its high- and medium-quality scenes and their build times.
#[cfg(feature = "embree")]
mod embree_setup {
    use super::*;
    use crate::baselines::embree::{
        BuildQuality, Coherence, Device, DeviceInfo, EmbreeScene, Packet4, Packet8, Packet16,
    };
    use crate::baselines::embree_blocks::{EmbreeBlocks, EmbreeSingle};

    /// Embree's builds for `rttest compare`.
    pub(super) struct EmbreeBuilds {
        device: Option<(Device, DeviceInfo)>,
        high: Option<EmbreeScene>,
        medium: Option<EmbreeScene>,
        high_ms: Vec<f64>,
        medium_ms: Vec<f64>,
    }

    /// One Embree configuration: a packet width, a context flag, a BVH.
    pub(super) struct EmbreeTracer<'s> {
        pub(super) name: String,
        pub(super) build_ms: f64,
        width: usize,
        coherence: Coherence,
        scene: &'s EmbreeScene,
    }

    impl<'s> EmbreeTracer<'s> {
        /// The passes of this configuration on `frame`.
        pub(super) fn passes<'a>(&self, frame: &'a Frame<'a>) -> Passes<'a>
        where
            's: 'a,
        {
            let (scene, coherence) = (self.scene, self.coherence);
            match self.width {
                4 => block_passes(EmbreeBlocks::<Packet4>::new(scene, coherence), frame),
                8 => block_passes(EmbreeBlocks::<Packet8>::new(scene, coherence), frame),
                16 => block_passes(EmbreeBlocks::<Packet16>::new(scene, coherence), frame),
                _ => block_passes(SingleRays(EmbreeSingle { scene, coherence }), frame),
            }
        }
    }

    impl EmbreeBuilds {
        /// A device with the pool's threads, when Embree is wanted.
        pub(super) fn new(wanted: bool) -> Result<Self, Error> {
            let device = if wanted {
                let d = Device::new(Some(rayon::current_num_threads()))
                    .map_err(|e| Error::Usage(format!("Embree: {e}")))?;
                let info = d.info();
                Some((d, info))
            } else {
                None
            };
            Ok(EmbreeBuilds { device, high: None, medium: None, high_ms: Vec::new(), medium_ms: Vec::new() })
        }

        /// Builds (and times) the high- and medium-quality BVHs once more.
        pub(super) fn build(&mut self, scene: &Scene) -> Result<(), Error> {
            let Some((device, _)) = &self.device else { return Ok(()) };
            let mesh = &scene.mesh;
            for (quality, slot, times) in [
                (BuildQuality::High, &mut self.high, &mut self.high_ms),
                (BuildQuality::Medium, &mut self.medium, &mut self.medium_ms),
            ] {
                *slot = None;
                let (secs, built) = timed(|| EmbreeScene::build(device, &mesh.positions, &mesh.triangles, quality));
                *slot = Some(built.map_err(|e| Error::Usage(format!("Embree: {e}")))?);
                times.push(secs * 1e3);
            }
            Ok(())
        }

        /// Every Embree configuration of the compare table.
        pub(super) fn tracers(&self) -> Vec<EmbreeTracer<'_>> {
            let mut out = Vec::new();
            let (Some(high), Some(medium)) = (&self.high, &self.medium) else { return out };
            let (hm, mm) = (median(&self.high_ms), median(&self.medium_ms));
            let mut add = |name: &str, width, coherence, scene, build_ms| {
                out.push(EmbreeTracer { name: name.into(), build_ms, width, coherence, scene });
            };
            add("embree-1", 1, Coherence::Coherent, high, hm);
            add("embree-4", 4, Coherence::Coherent, high, hm);
            add("embree-8", 8, Coherence::Coherent, high, hm);
            add("embree-16", 16, Coherence::Coherent, high, hm);
            add("embree-1-incoherent", 1, Coherence::Incoherent, high, hm);
            add("embree-16-incoherent", 16, Coherence::Incoherent, high, hm);
            add("embree-1-medium", 1, Coherence::Coherent, medium, mm);
            add("embree-16-medium", 16, Coherence::Coherent, medium, mm);
            out
        }

        /// The device line of the text report.
        pub(super) fn note(&self) -> Option<String> {
            let (_, info) = self.device.as_ref()?;
            let yes = |b: bool| if b { "native" } else { "emulated" };
            Some(format!(
                "Embree {} ({} tasking): packets of 4 {}, of 8 {}, of 16 {}; build qualities high (embree-N) and medium (embree-N-medium); `-incoherent`: Embree's default context flag, the others coherent.",
                info.version_string(),
                match info.tasking_system {
                    0 => "internal",
                    1 => "TBB",
                    2 => "PPL",
                    _ => "unknown",
                },
                yes(info.native_ray4),
                yes(info.native_ray8),
                yes(info.native_ray16)
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(methods: &[&str]) -> CompareArgs {
        CompareArgs {
            scene: "atrium".into(),
            view: None,
            size: (16, 16),
            rounds: 1,
            build_rounds: 1,
            methods: methods.iter().map(|s| s.to_string()).collect(),
            tiles: vec![8, 16],
            light_radius: 1.0,
            no_soft: false,
        }
    }

    #[test]
    fn method_selection() {
        let all = select_methods(&args(&["ours"])).unwrap();
        assert_eq!(all[0], "mono");
        assert!(all.contains(&"mft-cone-16".to_string()) && all.contains(&"frustum-8".to_string()));
        assert_eq!(select_methods(&args(&["mft-16"])).unwrap(), vec!["mono", "mft-16"]);
        assert!(select_methods(&args(&["nonsense"])).is_err());
        let mut bad = args(&["all"]);
        bad.tiles = vec![6];
        assert!(select_methods(&bad).is_err());
        for name in ["embree", "embree-16", "bvh", "obvhs", "bvh-crates"] {
            match (select_methods(&args(&[name])), feature_hint(name)) {
                (Ok(list), None) => assert!(list.len() > 1, "{name}: {list:?}"),
                (Err(e), Some(_)) => assert!(e.to_string().contains("--features"), "{name}: {e}"),
                (r, hint) => panic!("{name}: {r:?} with hint {hint:?}"),
            }
        }
        assert_eq!(our_method("mft-cone-16"), Some((Method::MftCone, 16)));
        assert_eq!(our_method("frustum-4"), Some((Method::Frustum, 4)));
        assert_eq!(our_method("embree-4"), None);
    }

    #[test]
    fn medians() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert_eq!(median(&[]), 0.0);
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
