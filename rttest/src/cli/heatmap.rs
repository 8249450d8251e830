//! Cost images on the command line: `rttest render --aov nodes|leaves|isects|culled` (one
//! method) and `--compare-methods A,B,...` (a strip of methods on one colour scale).
//!
//! Each pixel holds the work per ray of the call that traced it ([`trace::aov`]): its own ray
//! for single-ray methods, its tile's counts divided by the tile's rays for packets, frusta and
//! cones. The exact values go to PFM, the picture (viridis, a legend bar with the scale
//! written on it) to PNG.

use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

use scenes::colormap::{Panel, common_max, strip};
use scenes::{Camera, ScalarImage};
use serde::Serialize;
use trace::aov::{Attribution, Cost, CostFrame};
use trace::{Error, FrameBuffers, Options, Renderer, Shadows};

use super::{Built, GlobalArgs, RenderArgs, camera_for, emit, structures_for};

/// The PNG's legend title for `cost`: `NODES / RAY`.
fn title(cost: Cost) -> String {
    format!("{} / RAY", cost.name())
}

/// The PFM and PNG paths of `out`: the same stem with each extension.
pub fn pfm_and_png(out: &Path) -> (PathBuf, PathBuf) {
    (out.with_extension("pfm"), out.with_extension("png"))
}

/// The colour scale's top: `--cost-max` or the largest value of `images`.
fn scale_max<'a>(args: &RenderArgs, images: impl IntoIterator<Item = &'a ScalarImage>) -> f32 {
    args.cost_max.unwrap_or_else(|| common_max(images))
}

/// Traces the cost pass of `renderer` into `buffers` and writes the `cost` image as PFM and as
/// a heat-map PNG labelled `label` next to `out`. Returns (trace and shade seconds, write
/// seconds).
pub fn write_one(
    renderer: &Renderer<'_>,
    buffers: &mut FrameBuffers,
    cost: Cost,
    label: &str,
    args: &RenderArgs,
    out: &Path,
) -> Result<(f64, f64), Error> {
    let start = Instant::now();
    let frame = renderer.trace_costs(buffers);
    let image = frame.image(cost);
    let shade_secs = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let (pfm, png) = pfm_and_png(out);
    image.save_pfm(&pfm)?;
    let max = scale_max(args, [&image]);
    strip(&[Panel { label, image: &image }], max, &title(cost)).save_png(&png)?;
    Ok((shade_secs, start.elapsed().as_secs_f64()))
}

/// One method's row of a [`CostReport`].
#[derive(Clone, Debug, Serialize)]
pub struct CostRow {
    /// The method's full name.
    pub method: String,
    /// `ray` (each pixel its own ray) or `tile` (the tile's counts per ray).
    pub attribution: &'static str,
    /// Primary rays (pixels).
    pub rays: u64,
    /// The frame's total of the cost (exact, from the counters).
    pub total: u64,
    /// Total per ray.
    pub mean: f64,
    /// The largest pixel value.
    pub max: f32,
    /// The PFM written.
    pub pfm: String,
}

/// What `rttest render --compare-methods` did: one row per method, one strip.
#[derive(Clone, Debug, Serialize)]
pub struct CostReport {
    /// The scene.
    pub scene: String,
    /// The view.
    pub view: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// `nodes`, `leaves`, `isects` or `culled`.
    pub aov: &'static str,
    /// The colour scale's top (all panels).
    pub scale_max: f32,
    /// The strip PNG.
    pub strip: String,
    /// The methods.
    pub rows: Vec<CostRow>,
}

impl fmt::Display for CostReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} per primary ray, {} view '{}', {}x{} (colour scale 0..{}): {}",
            self.aov, self.scene, self.view, self.width, self.height, self.scale_max, self.strip
        )?;
        writeln!(
            f,
            "{:<14} {:>11} {:>14} {:>10} {:>10}  pfm",
            "method", "attribution", "total", "per ray", "max pixel"
        )?;
        for r in &self.rows {
            writeln!(
                f,
                "{:<14} {:>11} {:>14} {:>10.2} {:>10.2}  {}",
                r.method, r.attribution, r.total, r.mean, r.max, r.pfm
            )?;
        }
        Ok(())
    }
}

/// `rttest render --compare-methods A,B,... --aov COST`: the cost image of every method on one
/// view, each as PFM (`STEM-METHOD.pfm`) and all side by side on one colour scale in one PNG
/// (`STEM.png`).
pub fn compare(global: &GlobalArgs, built: &Built, args: &RenderArgs, methods: &[String]) -> Result<(), Error> {
    let cost = args
        .aov
        .cost()
        .ok_or_else(|| Error::Usage("--compare-methods needs a cost --aov: nodes, leaves, isects or culled".into()))?;
    if methods.is_empty() {
        return Err(Error::Usage("--compare-methods needs at least one method".into()));
    }
    let registry = baselines::registry();
    let options = Options { tile: args.tile, culling: !args.no_culling, ..Options::default() };
    let selected: Vec<_> = methods.iter().map(|m| registry.select(m, options)).collect::<Result<_, _>>()?;
    let (camera, view): (Camera, String) = camera_for(&built.scene, args)?;
    let stem = args.out.clone().unwrap_or_else(|| PathBuf::from(format!("{}-{}", built.scene.name, cost.name())));
    let mut frames: Vec<(String, CostFrame)> = Vec::new();
    for s in &selected {
        let structures = structures_for(&registry, s, built)?;
        let method = registry.bind(s, &structures)?;
        let renderer = Renderer::new(&built.scene, &method, camera, Shadows::None);
        let frame = renderer.trace_costs(&mut renderer.buffers());
        frames.push((method.name.clone(), frame));
    }
    let images: Vec<ScalarImage> = frames.iter().map(|(_, f)| f.image(cost)).collect();
    let max = scale_max(args, &images);
    let mut rows = Vec::new();
    for ((name, frame), image) in frames.iter().zip(&images) {
        let pfm = stem.with_file_name(format!(
            "{}-{name}.pfm",
            stem.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
        ));
        image.save_pfm(&pfm)?;
        let rays = u64::from(camera.width) * u64::from(camera.height);
        let total = cost.of(&frame.totals);
        rows.push(CostRow {
            method: name.clone(),
            attribution: match frame.attribution {
                Attribution::Ray => "ray",
                Attribution::Tile => "tile",
            },
            rays,
            total,
            mean: total as f64 / rays.max(1) as f64,
            max: image.finite_range().map_or(0.0, |r| r.1),
            pfm: pfm.display().to_string(),
        });
    }
    let panels: Vec<Panel<'_>> =
        rows.iter().zip(&images).map(|(r, image)| Panel { label: r.method.as_str(), image }).collect();
    let png = stem.with_extension("png");
    strip(&panels, max, &title(cost)).save_png(&png)?;
    emit(
        global,
        &CostReport {
            scene: built.scene.name.clone(),
            view,
            width: camera.width,
            height: camera.height,
            aov: cost.name(),
            scale_max: max,
            strip: png.display().to_string(),
            rows,
        },
    )
}
