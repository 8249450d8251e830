//! The render loop without a window: a [`ViewerState`] and a size in, a framebuffer of
//! `0x00RRGGBB` pixels and a status line out.
//!
//! Every method is taken by name from the one catalogue, `baselines::registry()` (a
//! `trace::Registry`), and bound to the scene's kd-tree; a frame is `trace::Renderer`'s passes
//! (primary, then hard, edge-width or soft shadows) and its shading (silhouette widths,
//! `edgewidth::silhouette`, and convolved edge widths, `edgewidth::convolution`, are filled
//! in after the renderer's primary pass), or, with a cost overlay, the cost pass of `trace::aov` drawn as a heat map.
//! Edge widths (thesis chapter 5) are traced over the kd-tree given to [`FrameLoop::new`]
//! whatever the method, to the centre of the soft shadows' light. Soft shadows
//! refine while the camera rests ([`crate::refine`]): the primary hits are kept and each frame
//! adds 16 rays per lit pixel, up to [`MAX_PASSES`] passes; then nothing is traced until
//! something changes ([`FrameLoop::render`] returns `None`). The overlay's colour scale is the
//! maximum of the first overlay frame after the method, the overlay or the named view changes,
//! kept while the camera moves, and kept whatever changes while it is locked (L).

use std::time::Instant;

use cones::shadows::SAMPLES;
use edgewidth::convolution::{ConvolutionBuffers, Params as ConvolutionParams, TOLERANCES, convolved_frame};
use edgewidth::sampling::ShadingPoint;
use edgewidth::{AreaLight, SilhouetteScratch, Silhouettes, silhouette_visibility};
use kdtree::surface::Surfaces;
use kdtree::{Counts, KdTree, Ray};
use rayon::prelude::*;
use scenes::colormap::{common_max, heatmap};
use scenes::font::{GLYPH_H, draw_text, text_width};
use scenes::{Rgb8Image, Scene, SphereLight};
use trace::aov::Cost;
use trace::frame::View;
use trace::{Error, FrameBuffers, Options, Registry, Renderer, Shadows, Structures};

use crate::refine;
use crate::state::{Change, ShadowMode, ViewerState};

/// Soft-shadow passes (16 rays per lit pixel each) before refinement stops: 256 rays.
pub const MAX_PASSES: u32 = 16;

/// Pixels per chunk of refinement rays (16 rays each).
const REFINE_PIXELS: usize = 4096;

/// What one frame did, for the status line.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameInfo {
    /// The method's full name.
    pub method: String,
    /// Rays traced by this frame.
    pub rays: u64,
    /// Seconds spent tracing them.
    pub trace_secs: f64,
    /// Seconds for the whole frame (tracing, shading, drawing; not the counted pass of N and
    /// I).
    pub frame_secs: f64,
    /// Rayon threads.
    pub threads: usize,
    /// N and I per 2x2 packet (per four rays for single rays) of the primary rays, from the
    /// last counted frame (the first frame after the camera comes to rest is counted).
    pub n_i: Option<(f64, f64)>,
    /// Soft-shadow passes so far (0 without soft shadows).
    pub passes: u32,
    /// With a cost overlay: the top of its colour scale.
    pub overlay_max: Option<f32>,
}

impl FrameInfo {
    /// Millions of rays per second of tracing.
    pub fn mrays_per_s(&self) -> f64 {
        if self.trace_secs > 0.0 { self.rays as f64 / self.trace_secs / 1e6 } else { 0.0 }
    }

    /// The status line: fps, Mrays/s, method, threads, N and I per packet, shadows or overlay.
    pub fn status(&self, state: &ViewerState) -> String {
        let fps = if self.frame_secs > 0.0 { 1.0 / self.frame_secs } else { 0.0 };
        let ni = self.n_i.map_or("N - I -".to_string(), |(n, i)| format!("N {n:.1} I {i:.1}"));
        let mode = match (state.overlay, self.overlay_max) {
            (Some(c), Some(max)) => {
                let lock = if state.scale_locked { " LOCKED" } else { "" };
                format!("{} / RAY 0-{}{lock}", c.name(), scenes::colormap::tick_label(max))
            }
            _ if state.shadows == ShadowMode::Soft => format!("SOFT {}/{MAX_PASSES}", self.passes),
            _ => state.shadows.name().to_string(),
        };
        format!(
            "{fps:.1} FPS  {:.2} MRAYS/S  {}  {} THREADS  {ni}  {mode}",
            self.mrays_per_s(),
            self.method,
            self.threads
        )
    }
}

/// The frame loop of one scene.
pub struct FrameLoop<'a> {
    scene: &'a Scene,
    tree: &'a KdTree,
    registry: Registry,
    structures: Structures<'a>,
    /// The scene's surface records (`trace::shade::surfaces`), made once for every frame.
    surfaces: Surfaces,
    /// The tree's triangle adjacency for silhouette widths, made on their first frame.
    silhouettes: Option<Silhouettes>,
    light: SphereLight,
    /// Size of `buffers` and the method/shadows they were traced with.
    size: (u32, u32),
    buffers: FrameBuffers,
    /// The convolved edge widths' buffers, kept from frame to frame.
    convolution: ConvolutionBuffers,
    soft: Refinement,
    /// Whether the last frame is final (nothing left to refine).
    done: bool,
    n_i: Option<(f64, f64)>,
    /// The camera moved since N and I were last counted.
    counts_stale: bool,
    /// The cost overlay's colour scale and what it was fixed for.
    overlay_scale: Option<(ScaleKey, f32)>,
}

/// What an unlocked overlay scale is fixed for: method (index), overlay and named view
/// ([`ViewerState::view_jumps`]).
type ScaleKey = (usize, Cost, u32);

/// The progressive soft shadows of the kept primary hits.
#[derive(Debug, Default)]
struct Refinement {
    /// Sum of the visible fractions of the passes so far (tile order).
    visible_sum: Vec<f32>,
    passes: u32,
    rays: Vec<Ray>,
    occluded: Vec<bool>,
}

impl<'a> FrameLoop<'a> {
    /// The loop over `scene` and its kd-tree; soft shadows go to a light of radius 1 Sponza
    /// unit at the point light (`trace::soft::scene_light`).
    ///
    /// Every other registered structure (the 4- and 8-wide BVHs of `mbvh-4` and `mbvh-8`) is
    /// built here too, so that every method binds; one that fails to build is named on stderr
    /// and its methods report the error when chosen.
    pub fn new(scene: &'a Scene, tree: &'a KdTree) -> FrameLoop<'a> {
        let registry = baselines::registry();
        let mut structures = Structures::new(tree);
        if let Err(e) = registry.build_structures(scene, &mut structures) {
            eprintln!("viewer: {e}");
        }
        FrameLoop {
            scene,
            tree,
            registry,
            structures,
            surfaces: trace::shade::surfaces(&scene.mesh),
            silhouettes: None,
            light: trace::soft::scene_light(scene, tree, 1.0),
            size: (0, 0),
            buffers: FrameBuffers::new(0),
            convolution: ConvolutionBuffers::default(),
            soft: Refinement::default(),
            done: false,
            n_i: None,
            counts_stale: true,
            overlay_scale: None,
        }
    }

    /// The method names the viewer switches between: every entry of the registry, the tiled
    /// ones with 16x16 tiles.
    pub fn method_names(&self) -> Vec<String> {
        self.registry.names(&[trace::registry::TILE_SIZE])
    }

    /// Renders `state` at `width` x `height` into `out` (`0x00RRGGBB`, row-major), `change`
    /// being what changed since the last call. Returns `None` when nothing new was traced: an
    /// empty (minimised) window, or nothing changed and nothing is left to refine.
    pub fn render(
        &mut self,
        state: &ViewerState,
        change: Change,
        width: u32,
        height: u32,
        out: &mut Vec<u32>,
    ) -> Result<Option<FrameInfo>, Error> {
        let start = Instant::now();
        let Some(camera) = state.pose.camera(state.fovy_deg, width, height) else { return Ok(None) };
        let resized = self.size != (width, height);
        if !(change.any() || resized || !self.done || self.counts_stale) {
            return Ok(None);
        }
        let selected = self.registry.select(state.method_name(), Options::default())?;
        let bound = self.registry.bind(&selected, &self.structures)?;
        if resized {
            self.size = (width, height);
            self.buffers = FrameBuffers::new(width as usize * height as usize);
        }
        let restart = change.any() || resized;
        let resting = !change.camera;
        self.counts_stale = change.camera;
        let mut info = FrameInfo {
            method: bound.name.clone(),
            rays: 0,
            trace_secs: 0.0,
            frame_secs: 0.0,
            threads: rayon::current_num_threads(),
            n_i: None,
            passes: 0,
            overlay_max: None,
        };
        let mut counting_secs = 0.0;
        if let Some(cost) = state.overlay {
            let renderer = Renderer::new(self.scene, &bound, camera, Shadows::None).with_surfaces(&self.surfaces);
            let t = Instant::now();
            let frame = renderer.trace_costs(&mut self.buffers);
            info.trace_secs = t.elapsed().as_secs_f64();
            info.rays = u64::from(width) * u64::from(height);
            self.n_i = Some(per_packet(&frame.totals, &renderer, bound.entry.packets));
            let values = frame.image(cost);
            let key = (state.method, cost, state.view_jumps);
            let max = match self.overlay_scale {
                Some((k, max)) if state.scale_locked || k == key => max,
                _ => common_max([&values]),
            };
            self.overlay_scale = Some((key, max));
            info.overlay_max = Some(max);
            self.done = true;
            pack(&heatmap(&values, max), out);
        } else {
            let shadows = renderer_shadows(state.shadows);
            let renderer = Renderer::new(self.scene, &bound, camera, shadows)
                .with_light(self.light)
                .with_tree(self.tree)
                .with_surfaces(&self.surfaces)
                .with_secondary(u32::from(state.secondary && state.shadows != ShadowMode::Soft));
            if state.shadows == ShadowMode::Soft && !restart {
                let t = Instant::now();
                info.rays = self.soft.pass(&bound, &renderer, self.scene, &self.light, &mut self.buffers);
                self.done = info.rays == 0;
                info.trace_secs = t.elapsed().as_secs_f64();
            } else {
                let stats = renderer.trace(&mut self.buffers);
                info.rays = stats.rays();
                info.trace_secs = stats.trace_secs();
                if state.shadows == ShadowMode::Silhouette {
                    let t = Instant::now();
                    let silhouettes = self.silhouettes.get_or_insert_with(|| Silhouettes::new(self.tree));
                    let light = AreaLight::Sphere(self.light);
                    info.rays += silhouette_pass(self.tree, silhouettes, &light, &renderer, &mut self.buffers);
                    info.trace_secs += t.elapsed().as_secs_f64();
                }
                if state.shadows == ShadowMode::Convolution {
                    let t = Instant::now();
                    let light = AreaLight::Sphere(self.light);
                    info.rays +=
                        convolution_pass(self.tree, &light, &renderer, &mut self.buffers, &mut self.convolution);
                    info.trace_secs += t.elapsed().as_secs_f64();
                }
                self.soft.passes = u32::from(state.shadows == ShadowMode::Soft);
                // The sum refinement adds to: soft shadows only (edge widths fill `visible` too).
                if state.shadows == ShadowMode::Soft {
                    self.soft.visible_sum.clone_from(&self.buffers.visible);
                } else {
                    self.soft.visible_sum.clear();
                }
                self.done = state.shadows != ShadowMode::Soft;
            }
            if resting {
                // Counted apart: its time is left out of the frame's.
                let t = Instant::now();
                let mut counts = Counts::default();
                let mut hits = vec![None; renderer.layout().pixel_count()];
                bound.tracer.primary(renderer.layout(), &camera, &mut hits, Some(&mut counts));
                self.n_i = Some(per_packet(&counts, &renderer, bound.entry.packets));
                counting_secs = t.elapsed().as_secs_f64();
            }
            renderer.color_packed(&self.buffers, out);
        }
        info.passes = self.soft.passes;
        info.n_i = self.n_i;
        info.frame_secs = start.elapsed().as_secs_f64() - counting_secs;
        draw_status(out, width, height, &info.status(state));
        Ok(Some(info))
    }
}

/// One round of [`FrameLoop::time_against_renderer`]: the viewer's frame and what
/// `rttest render` times for the same frame, in seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RoundTimes {
    /// The viewer's whole frame ([`FrameInfo::frame_secs`]: select and bind the method,
    /// trace, shade and gamma-encode into the packed buffer, status line).
    pub viewer_frame: f64,
    /// Its tracing ([`FrameInfo::trace_secs`]).
    pub viewer_trace: f64,
    /// `Renderer::trace` of the same frame (`trace_secs` of `rttest render`: primary and
    /// shadow passes).
    pub render_trace: f64,
    /// `Renderer::color` of it (`shade_secs` of `rttest render`: shading into an f32 image,
    /// no gamma encoding, no copy for display).
    pub render_shade: f64,
    /// Rays of the viewer's frame and of the renderer's (equal: the same work).
    pub rays: (u64, u64),
}

impl FrameLoop<'_> {
    /// Times the viewer's frame of `state` against `rttest render`'s timed parts of the same
    /// frame (the same method bound once, shadows, light and size, as `rttest render` does),
    /// in `rounds` interleaved rounds (the order alternating from round to round), so that
    /// load from other processes falls on both alike. The viewer's frames are traced as with
    /// a moving camera (no counted pass, no soft-shadow refinement).
    pub fn time_against_renderer(
        &mut self,
        state: &ViewerState,
        width: u32,
        height: u32,
        rounds: u32,
    ) -> Result<Vec<RoundTimes>, Error> {
        let camera =
            state.pose.camera(state.fovy_deg, width, height).ok_or_else(|| Error::Usage("no camera".into()))?;
        // Bound apart from the loop's own registry, as `rttest render` binds it: once.
        let (scene, tree) = (self.scene, self.tree);
        let registry = baselines::registry();
        let structures = Structures::new(tree);
        let bound = registry.bind(&registry.select(state.method_name(), Options::default())?, &structures)?;
        let shadows = renderer_shadows(state.shadows);
        let renderer = Renderer::new(scene, &bound, camera, shadows).with_light(self.light).with_tree(tree);
        let mut buf = renderer.buffers();
        let mut state = state.clone();
        state.overlay = None;
        let moving = Change { camera: true, settings: false };
        let mut out = Vec::new();
        let mut times = Vec::with_capacity(rounds as usize);
        for round in 0..rounds {
            let mut t = RoundTimes::default();
            for viewer_first in [round % 2 == 0, round % 2 != 0] {
                if viewer_first {
                    let info = self
                        .render(&state, moving, width, height, &mut out)?
                        .ok_or_else(|| Error::Usage("the viewer traced nothing".into()))?;
                    (t.viewer_frame, t.viewer_trace, t.rays.0) = (info.frame_secs, info.trace_secs, info.rays);
                } else {
                    let stats = renderer.trace(&mut buf);
                    let start = Instant::now();
                    let image = renderer.color(&buf);
                    t.render_shade = start.elapsed().as_secs_f64();
                    std::hint::black_box(image);
                    (t.render_trace, t.rays.1) = (stats.trace_secs(), stats.rays());
                }
            }
            times.push(t);
        }
        Ok(times)
    }
}

/// Silhouette widths (`edgewidth::silhouette`) of the primary hits in `buffers` (traced by
/// `renderer`, whose surfaces they use) to `light`, into `buffers.visible` (tile order; 0 for
/// misses). Returns the shadow rays traced.
fn silhouette_pass(
    tree: &KdTree,
    silhouettes: &Silhouettes,
    light: &AreaLight,
    renderer: &Renderer<'_>,
    buffers: &mut FrameBuffers,
) -> u64 {
    let (layout, camera, surfaces) = (renderer.layout(), renderer.camera(), renderer.surfaces());
    let pixels: Vec<(u32, u32)> = layout.tiles().iter().flat_map(|t| t.pixels()).collect();
    let hits = &buffers.hits;
    let mut visible = vec![0.0f32; hits.len()];
    let rays: u64 = visible
        .par_chunks_mut(REFINE_PIXELS)
        .enumerate()
        .map(|(c, out)| {
            let mut scratch = SilhouetteScratch::default();
            let mut rays = 0u64;
            for (k, slot) in out.iter_mut().enumerate() {
                let i = c * REFINE_PIXELS + k;
                let (Some(hit), Some(&(x, y))) = (&hits[i], pixels.get(i)) else { continue };
                let p = ShadingPoint::on(surfaces.get(hit.prim), hit, camera.pixel_ray(x, y).1);
                let v = silhouette_visibility(tree, silhouettes, light, &p, &mut scratch);
                *slot = v.fraction;
                rays += u64::from(v.rays);
            }
            rays
        })
        .sum();
    buffers.visible = visible;
    rays
}

/// Convolved edge widths (`edgewidth::convolution::convolved_frame`) of the primary hits in
/// `buffers` (traced by `renderer`, whose surfaces and camera they use) to `light`, into
/// `buffers.visible` (tile order; 0 for misses), in the `convolution`'s buffers of the last
/// frame. Returns the shadow rays traced.
fn convolution_pass(
    tree: &KdTree,
    light: &AreaLight,
    renderer: &Renderer<'_>,
    buffers: &mut FrameBuffers,
    convolution: &mut ConvolutionBuffers,
) -> u64 {
    let (layout, camera, surfaces) = (renderer.layout(), renderer.camera(), renderer.surfaces());
    let (w, h) = (camera.width, camera.height);
    let hits = layout.to_row_major(&buffers.hits);
    let point = |x: u32, y: u32| {
        let hit = hits.get((y * w + x) as usize)?.as_ref()?;
        let p = ShadingPoint::on(surfaces.get(hit.prim), hit, camera.pixel_ray(x, y).1);
        Some((p, camera.footprint(p.point)))
    };
    let params = ConvolutionParams::DEFAULT;
    let (visible, rays) = convolved_frame(tree, light, (w, h), params, TOLERANCES, convolution, point);
    let pixels = layout.tiles().iter().flat_map(|t| t.pixels());
    buffers.visible = pixels.map(|(x, y)| visible[(y * w + x) as usize]).collect();
    rays
}

impl Refinement {
    /// One refinement pass over the primary hits of `buffers`: 16 jittered rays per lit pixel
    /// through the method's stream kernel, averaged into `buffers.visible`. Returns the rays
    /// traced (0 once [`MAX_PASSES`] passes are done).
    fn pass(
        &mut self,
        bound: &trace::Bound<'_>,
        renderer: &Renderer<'_>,
        scene: &Scene,
        light: &SphereLight,
        buffers: &mut FrameBuffers,
    ) -> u64 {
        if self.passes >= MAX_PASSES || self.visible_sum.len() != buffers.hits.len() {
            return 0;
        }
        let layout = renderer.layout();
        let camera = renderer.camera();
        let view = View { layout, scene, surfaces: renderer.surfaces(), camera };
        let pass = self.passes;
        // Pixel indices (tile order) and coordinates.
        let pixels: Vec<(usize, u32, u32)> =
            layout.tiles().iter().flat_map(|t| t.pixels()).enumerate().map(|(i, (x, y))| (i, x, y)).collect();
        let mut traced = 0;
        for chunk in pixels.chunks(REFINE_PIXELS) {
            self.rays.clear();
            let mut lit = Vec::with_capacity(chunk.len());
            for &(i, x, y) in chunk {
                let Some(hit) = &buffers.hits[i] else { continue };
                let dir = view.camera.pixel_ray(x, y).1;
                let Some((start, _)) = trace::soft::shadow_start(view.surfaces, light, hit, dir) else { continue };
                let Some(rays) = refine::rays(start, light, pass) else { continue };
                self.rays.extend_from_slice(&rays);
                lit.push(i);
            }
            self.occluded.clear();
            self.occluded.resize(self.rays.len(), false);
            bound.tracer.stream_occluded(&self.rays, &mut self.occluded);
            for (&i, blocked) in lit.iter().zip(self.occluded.chunks_exact(SAMPLES)) {
                let n = blocked.iter().filter(|&&b| b).count();
                self.visible_sum[i] += 1.0 - n as f32 / SAMPLES as f32;
            }
            traced += self.rays.len() as u64;
        }
        self.passes += 1;
        let passes = self.passes as f32;
        buffers.visible.clear();
        buffers.visible.extend(self.visible_sum.iter().map(|v| v / passes));
        traced
    }
}

/// The renderer's shadows of a viewer mode (soft: the first 16-ray pass).
fn renderer_shadows(mode: ShadowMode) -> Shadows {
    match mode {
        ShadowMode::None => Shadows::None,
        ShadowMode::Hard => Shadows::Hard,
        ShadowMode::EdgeWidth => Shadows::EdgeWidth,
        // Primary rays only: `silhouette_pass` or `convolution_pass` fills the visible
        // fractions.
        ShadowMode::Silhouette | ShadowMode::Convolution => Shadows::None,
        ShadowMode::Soft => Shadows::Soft16,
    }
}

/// N and I per 2x2 packet of a counted primary pass (per four rays for single rays).
fn per_packet(counts: &Counts, renderer: &Renderer<'_>, packets: bool) -> (f64, f64) {
    let groups = if packets { renderer.packet_count() } else { (renderer.layout().pixel_count() as u64).div_ceil(4) };
    (counts.steps_per_packet(groups), counts.tests_per_packet(groups))
}

/// `image` packed as `0x00RRGGBB` into `out`.
fn pack(image: &Rgb8Image, out: &mut Vec<u32>) {
    out.clear();
    out.extend(image.rgb.chunks_exact(3).map(|c| u32::from(c[0]) << 16 | u32::from(c[1]) << 8 | u32::from(c[2])));
}

/// Draws `text` on a dark band at the top of the `width` x `height` packed image `out`, twice
/// as large from 1024 pixels wide.
fn draw_status(out: &mut [u32], width: u32, height: u32, text: &str) {
    let s = if width >= 1024 { 2 } else { 1 };
    let h = (GLYPH_H * s + 4 * s).min(height);
    let w = (text_width(text, s) + 6 * s).min(width);
    let mut band = Rgb8Image::filled(w, h, [0; 3]);
    for y in 0..h {
        for x in 0..w {
            let p = out[(y * width + x) as usize];
            let c = [(p >> 16) as u8, (p >> 8) as u8, p as u8];
            band.put(i64::from(x), i64::from(y), c.map(|v| v / 3));
        }
    }
    draw_text(&mut band, i64::from(3 * s), i64::from(2 * s), text, s, [255, 255, 255]);
    for y in 0..h {
        for x in 0..w {
            let [r, g, b] = band.get(x, y).map(u32::from);
            out[(y * width + x) as usize] = r << 16 | g << 8 | b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::{Action, Input};

    fn setup() -> (Scene, KdTree) {
        let scene = scenes::load_scene("atrium").unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &Default::default()).unwrap();
        (scene, tree)
    }

    /// Not black, not one colour: many distinct colours and a mean well above black.
    fn looks_like_a_scene(pixels: &[u32]) {
        let mut distinct: Vec<u32> = pixels.to_vec();
        distinct.sort_unstable();
        distinct.dedup();
        let mean: f64 = pixels
            .iter()
            .map(|p| f64::from((p >> 16) & 255) + f64::from((p >> 8) & 255) + f64::from(p & 255))
            .sum::<f64>()
            / (3.0 * pixels.len() as f64);
        assert!(distinct.len() > 100 && mean > 20.0, "{} colours, mean {mean}", distinct.len());
    }

    /// The loop without a window: input -> camera -> frame, every method, shadows and
    /// overlay; the frame equals `trace::Renderer`'s shaded image under the status line.
    #[test]
    fn renders_every_method_and_mode() {
        let (scene, tree) = setup();
        let mut frames = FrameLoop::new(&scene, &tree);
        let names = frames.method_names();
        assert!(names.contains(&"mft-16".to_string()) && names.contains(&"mono".to_string()));
        let mut state = ViewerState::new(&scene, names.clone(), 0);
        let mut out = Vec::new();
        let (w, h) = (96, 64);
        for _ in 0..names.len() {
            let info =
                frames.render(&state, Change { settings: true, camera: false }, w, h, &mut out).unwrap().unwrap();
            assert_eq!(out.len(), (w * h) as usize);
            assert_eq!(info.method, state.method_name());
            assert!(info.rays > u64::from(w * h) && info.n_i.is_some_and(|(n, i)| n > 0.0 && i > 0.0), "{info:?}");
            looks_like_a_scene(&out);
            // The picture below the status band is the renderer's shaded image.
            let bound = frames
                .registry
                .bind(&frames.registry.select(&info.method, Options::default()).unwrap(), &frames.structures)
                .unwrap();
            let camera = state.pose.camera(state.fovy_deg, w, h).unwrap();
            let r = Renderer::new(&scene, &bound, camera, Shadows::Hard);
            let mut buf = r.buffers();
            r.trace(&mut buf);
            let reference = r.color(&buf).to_rgb8();
            let y = h - 1;
            for x in 0..w {
                let c = reference.get(x, y);
                assert_eq!(out[(y * w + x) as usize], u32::from(c[0]) << 16 | u32::from(c[1]) << 8 | u32::from(c[2]));
            }
            state.apply(&Input { pressed: vec![Action::NextMethod], ..Input::default() });
        }
        assert!(frames.render(&state, Change::default(), w, h, &mut out).unwrap().is_none(), "nothing new");
        let status = FrameInfo {
            method: "mft-16".into(),
            rays: 3_000_000,
            trace_secs: 0.5,
            frame_secs: 0.25,
            threads: 2,
            n_i: Some((4.56, 6.1)),
            passes: 0,
            overlay_max: None,
        }
        .status(&state);
        assert!(status.starts_with("4.0 FPS  6.00 MRAYS/S  mft-16  2 THREADS  N 4.6 I 6.1"), "{status}");
        state.apply(&Input { pressed: vec![Action::NextOverlay], ..Input::default() });
        let info = frames.render(&state, Change { settings: true, camera: false }, w, h, &mut out).unwrap().unwrap();
        assert!(info.overlay_max.is_some_and(|m| m > 0.0));
        looks_like_a_scene(&out);
    }

    /// Soft shadows refine while the camera rests, stop after MAX_PASSES, and restart when it
    /// moves; resizing and a zero size never panic.
    #[test]
    fn soft_shadows_refine_at_rest() {
        let (scene, tree) = setup();
        let mut frames = FrameLoop::new(&scene, &tree);
        let mut state = ViewerState::new(&scene, frames.method_names(), 0);
        state.shadows = ShadowMode::Soft;
        let mut out = Vec::new();
        let first = frames.render(&state, Change { settings: true, camera: false }, 48, 32, &mut out).unwrap().unwrap();
        assert_eq!(first.passes, 1);
        let first_frame = out.clone();
        let mut passes = vec![];
        while let Some(info) = frames.render(&state, Change::default(), 48, 32, &mut out).unwrap() {
            passes.push(info.passes);
            assert!(passes.len() <= MAX_PASSES as usize + 1);
        }
        assert_eq!(passes.first(), Some(&2));
        assert_eq!(passes.iter().max(), Some(&MAX_PASSES));
        assert_ne!(out, first_frame, "refinement changes the penumbrae");
        let moved = Change { camera: true, settings: false };
        assert_eq!(frames.render(&state, moved, 48, 32, &mut out).unwrap().unwrap().passes, 1);
        assert!(frames.render(&state, Change::default(), 0, 0, &mut out).unwrap().is_none());
        assert!(frames.render(&state, Change::default(), 1, 1, &mut out).unwrap().is_some());
        assert!(frames.render(&state, Change::default(), 300, 7, &mut out).unwrap().is_some());
        assert_eq!(out.len(), 2100);
    }
    /// Silhouette widths and convolved edge widths (H after edge widths): a frame shaded with
    /// `edgewidth::silhouette`'s or `edgewidth::convolution`'s visible fractions, which are
    /// the hard shadow's outside the penumbrae and fractional in them; nothing to refine; the
    /// status line names the mode.
    #[test]
    fn edge_width_variants_soften_the_hard_shadows() {
        let (scene, tree) = setup();
        for (mode, name) in
            [(ShadowMode::Silhouette, "edge-width-silhouette"), (ShadowMode::Convolution, "edge-width-convolution")]
        {
            let mut frames = FrameLoop::new(&scene, &tree);
            let mut state = ViewerState::new(&scene, frames.method_names(), 0);
            let (w, h) = (96, 64);
            let settings = Change { settings: true, camera: false };
            let mut hard = Vec::new();
            frames.render(&state, settings, w, h, &mut hard).unwrap().unwrap();
            state.shadows = mode;
            let mut soft = Vec::new();
            let info = frames.render(&state, settings, w, h, &mut soft).unwrap().unwrap();
            assert!(info.status(&state).ends_with(name), "{}", info.status(&state));
            assert!(info.rays > u64::from(w * h), "primary and shadow rays: {}", info.rays);
            assert!(frames.render(&state, Change::default(), w, h, &mut soft).unwrap().is_none(), "nothing to refine");
            looks_like_a_scene(&soft);
            let visible = &frames.buffers.visible;
            assert_eq!(visible.len(), w as usize * h as usize);
            assert!(visible.iter().all(|v| (0.0..=1.0).contains(v)));
            assert!(visible.iter().any(|&v| v > 0.0 && v < 1.0), "{name}: a penumbra");
            assert!(visible.iter().filter(|&&v| v == 1.0).count() > visible.len() / 10, "lit pixels");
            assert_ne!(soft, hard);
        }
    }

    /// Edge-width shadows (H: none, hard, edge width, soft): the frame is the renderer's
    /// edge-width image; it differs from the hard-shadow frame only in the light's penumbra
    /// (0 < visible < 1, inside the hard shadows), in some pixels there, and is identical
    /// where the point is fully lit; the status line names the mode.
    #[test]
    fn edge_width_frames_differ_from_hard_in_the_penumbra_only() {
        let (scene, tree) = setup();
        let mut frames = FrameLoop::new(&scene, &tree);
        let mut state = ViewerState::new(&scene, frames.method_names(), 0);
        let (w, h) = (96, 64);
        let settings = Change { settings: true, camera: false };
        let mut hard = Vec::new();
        assert_eq!(state.shadows, ShadowMode::Hard);
        frames.render(&state, settings, w, h, &mut hard).unwrap().unwrap();
        state.apply(&Input { pressed: vec![Action::NextShadows], ..Input::default() });
        assert_eq!(state.shadows, ShadowMode::EdgeWidth);
        let mut edge = Vec::new();
        let info = frames.render(&state, settings, w, h, &mut edge).unwrap().unwrap();
        assert!(info.status(&state).ends_with("edge-width"), "{}", info.status(&state));
        assert_eq!(info.passes, 0);
        assert!(frames.render(&state, Change::default(), w, h, &mut edge).unwrap().is_none(), "nothing to refine");
        looks_like_a_scene(&edge);
        // The visibility the frame was shaded with, from the renderer itself.
        let bound = frames
            .registry
            .bind(&frames.registry.select(state.method_name(), Options::default()).unwrap(), &frames.structures)
            .unwrap();
        let camera = state.pose.camera(state.fovy_deg, w, h).unwrap();
        let r = Renderer::new(&scene, &bound, camera, Shadows::EdgeWidth).with_light(frames.light).with_tree(&tree);
        let mut buf = r.buffers();
        r.trace(&mut buf);
        let visible = r.layout().to_row_major(&buf.visible);
        let hits = r.layout().to_row_major(&buf.hits);
        let band = GLYPH_H + 4;
        let (mut lit, mut penumbra, mut differ) = (0, 0, 0);
        for y in band..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if hits[i].is_some() && visible[i] == 1.0 {
                    assert_eq!(edge[i], hard[i], "fully lit ({x}, {y})");
                    lit += 1;
                } else if visible[i] > 0.0 && visible[i] < 1.0 {
                    penumbra += 1;
                    differ += usize::from(edge[i] != hard[i]);
                } else {
                    assert_eq!(edge[i], hard[i], "umbra, unlit or background ({x}, {y})");
                }
            }
        }
        assert!(lit > 100 && penumbra > 10 && differ > penumbra / 2, "lit {lit}, penumbra {penumbra}, differ {differ}");
    }
    /// The overlay's scale is fixed per method, overlay and named view: moving the camera
    /// keeps it (although the moved frame's own maximum differs), a new method or named view
    /// sets it anew, and a locked scale survives both.
    #[test]
    fn overlay_scale_is_fixed_per_method_and_view_and_can_be_locked() {
        let (scene, tree) = setup();
        let mut frames = FrameLoop::new(&scene, &tree);
        let names = frames.method_names();
        let mut state = ViewerState::new(&scene, names, 0);
        let press = |a| Input { pressed: vec![a], ..Input::default() };
        let (w, h) = (64, 48);
        let mut out = Vec::new();
        let mut render = |frames: &mut FrameLoop, state: &ViewerState, change| {
            frames.render(state, change, w, h, &mut out).unwrap().unwrap().overlay_max.unwrap()
        };
        // The frame's own maximum, as an unfixed scale would be.
        let own_max = |frames: &FrameLoop, state: &ViewerState| {
            let b = frames
                .registry
                .bind(&frames.registry.select(state.method_name(), Options::default()).unwrap(), &frames.structures)
                .unwrap();
            let r = Renderer::new(&scene, &b, state.pose.camera(state.fovy_deg, w, h).unwrap(), Shadows::None);
            common_max([&r.trace_costs(&mut r.buffers()).image(Cost::Nodes)])
        };
        let settings = state.apply(&press(Action::NextOverlay));
        let first = render(&mut frames, &state, settings);
        assert_eq!(first, own_max(&frames, &state));
        // Fly forward: the scale stays although the frame's own maximum changes.
        for _ in 0..4 {
            assert!(state.apply(&Input { held: vec![Action::Forward], dt: 0.25, ..Input::default() }).camera);
        }
        assert_ne!(own_max(&frames, &state), first, "the move changes the frame's maximum");
        assert_eq!(render(&mut frames, &state, Change { camera: true, settings: false }), first);
        // A new method: a new scale.
        let c = state.apply(&press(Action::NextMethod));
        let second = render(&mut frames, &state, c);
        assert_eq!(second, own_max(&frames, &state));
        assert_ne!(second, first);
        // Locked: kept across methods and named views.
        let c = state.apply(&press(Action::LockScale));
        assert_eq!(render(&mut frames, &state, c), second);
        let c = state.apply(&press(Action::NextMethod));
        assert_eq!(render(&mut frames, &state, c), second);
        let c = state.apply(&press(Action::View(1)));
        let info = frames.render(&state, c, w, h, &mut out).unwrap().unwrap();
        assert_eq!(info.overlay_max, Some(second));
        assert!(info.status(&state).ends_with("LOCKED"), "{}", info.status(&state));
        // Unlocked: the named view and method get their own scale again.
        let c = state.apply(&press(Action::LockScale));
        let c2 = state.apply(&press(Action::View(1)));
        let third = frames
            .render(&state, Change { camera: true, settings: c.settings || c2.settings }, w, h, &mut out)
            .unwrap()
            .unwrap()
            .overlay_max
            .unwrap();
        assert_eq!(third, own_max(&frames, &state));
    }
    /// The timing against the renderer runs the same work on both sides.
    #[test]
    fn timing_against_the_renderer_traces_the_same_rays() {
        let (scene, tree) = setup();
        let mut frames = FrameLoop::new(&scene, &tree);
        let mut state = ViewerState::new(&scene, frames.method_names(), 0);
        for mode in [ShadowMode::Hard, ShadowMode::EdgeWidth] {
            state.shadows = mode;
            let times = frames.time_against_renderer(&state, 40, 30, 3).unwrap();
            assert_eq!(times.len(), 3);
            for t in times {
                assert!(t.rays.0 > 1200 && t.rays.0 == t.rays.1, "{mode:?}: {t:?}");
                assert!(t.viewer_frame >= t.viewer_trace && t.viewer_trace > 0.0 && t.render_trace > 0.0);
                assert!(t.render_shade > 0.0);
            }
        }
    }
}
