//! The renderer: one view of a scene traced with one registered method, then shaded.
//!
//! A frame is the frame driver's passes ([`crate::frame`]) over preallocated per-pixel
//! buffers in tile order: the primary pass, then with `Shadows::Hard` one shadow ray per hit
//! facing the point light, or with `Shadows::Soft16` 16 rays per hit to a spherical light at
//! the point light (thesis Table 4.6), or with `Shadows::EdgeWidth` one edge-width ray per
//! hit to the same light's centre (Edge Width Soft Shadows, thesis chapter 5: the `edgewidth`
//! kernels over our kd-tree, given by [`Renderer::with_tree`]). Tracing is the timed part (ray generation, traversal
//! and intersection); shading into an image ([`Renderer::color`]) or taking the depth or
//! primitive id comes after and is timed apart.
//!
//! The method's tile (the `tile` of its `crate::registry::Options`) is the work unit of a
//! thread and, for the frustum and cone methods, the frustum.

use std::sync::OnceLock;
use std::time::Instant;

use cones::shadows::{SAMPLES, light_samples, shadow_rays};
use edgewidth::packet::{EdgeScratch4, edge_width4_with};
use edgewidth::{LeakRemedies, occlusion_factor, width_from_light};
use glam::Vec3;
use kdtree::Counts;
use kdtree::surface::Surfaces;
use kdtree::{Hit, Intersector, KdTree, Ray, WaldTest, WatertightTest};
use packets::{PacketTreeTest, RayPacket};
use rayon::prelude::*;
use scenes::PointLight;
use scenes::{Camera, Image, ScalarImage, Scene, SphereLight};

use crate::aov::{CostFrame, PixelCost};
use crate::frame::{SoftStats, TileLayout, View};
use crate::registry::Bound;
use crate::secondary::{Generation, spawn_generation};
use crate::{shade, soft};

/// Which shadow rays a frame traces.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Shadows {
    /// No shadow rays: every surface facing the light is lit.
    None,
    /// One shadow ray per hit towards the point light.
    #[default]
    Hard,
    /// 16 rays per hit to a spherical light at the point light (thesis Table 4.6), traced
    /// with the method's soft-shadow kernel.
    Soft16,
    /// Edge Width Soft Shadows (thesis chapter 5, Eq. 5.1): one ray per hit facing the light,
    /// from the hard shadow ray's origin to the centre of the spherical light of `Soft16`,
    /// traced four at a time by `edgewidth::packet::edge_width4` over our kd-tree (whatever
    /// the primary method; [`Renderer::with_tree`] gives the tree), `R` from the light's
    /// radius (`edgewidth::width_from_light`, scale 1), no leak remedies. The visible
    /// fraction is `1 - occlusion_factor(width, R)`. The kernels have no counters: a counted
    /// frame counts its primary pass only.
    #[serde(rename = "edge-width")]
    EdgeWidth,
}

impl Shadows {
    /// The name on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Shadows::None => "none",
            Shadows::Hard => "hard",
            Shadows::Soft16 => "soft16",
            Shadows::EdgeWidth => "edge-width",
        }
    }
}

/// The per-pixel results of tracing one frame, in tile order (see [`TileLayout`]).
#[derive(Clone, Debug)]
pub struct FrameBuffers {
    /// The closest hit of each pixel's primary ray.
    pub hits: Vec<Option<Hit>>,
    /// Whether each hit's hard shadow ray found a blocker (`false` without hard shadows, for
    /// misses and for surfaces facing away from the light).
    pub occluded: Vec<bool>,
    /// With soft or edge-width shadows, the visible fraction of the light per pixel (0 for
    /// pixels without a lit hit); empty otherwise.
    pub visible: Vec<f32>,
    /// With secondary rays ([`Renderer::with_secondary`]), the weight of each pixel's own
    /// shading (1 unless its material reflects or refracts); empty otherwise.
    pub local: Vec<f32>,
    /// The secondary rays' generations, the first spawned from the primary hits (empty
    /// without secondary rays).
    pub secondary: Vec<Generation>,
}

impl FrameBuffers {
    /// Buffers for `pixels` pixels.
    pub fn new(pixels: usize) -> FrameBuffers {
        FrameBuffers {
            hits: vec![None; pixels],
            occluded: vec![false; pixels],
            visible: Vec::new(),
            local: Vec::new(),
            secondary: Vec::new(),
        }
    }
}

/// What tracing one frame did and how long it took.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Primary rays traced (one per pixel).
    pub primary_rays: u64,
    /// Shadow rays traced (one per hit facing the light with hard shadows, 16 with soft).
    pub shadow_rays: u64,
    /// Primary rays that hit a triangle.
    pub hits: u64,
    /// Shadow rays that found a blocker (edge widths: rays with a width above 0).
    pub occluded: u64,
    /// Seconds for the primary pass.
    pub primary_secs: f64,
    /// Seconds for the shadow pass (0 without shadows).
    pub shadow_secs: f64,
    /// Secondary (reflection and refraction) rays traced, every generation.
    pub secondary_rays: u64,
    /// Secondary rays that hit a triangle.
    pub secondary_hits: u64,
    /// Shadow rays traced from the secondary hits.
    pub secondary_shadow_rays: u64,
    /// Seconds spawning the secondary rays from the hits (the shader proxy's ray
    /// generation).
    pub spawn_secs: f64,
    /// Seconds tracing the secondary rays (the method's stream kernel).
    pub secondary_secs: f64,
    /// Seconds for the shadows at the secondary hits.
    pub secondary_shadow_secs: f64,
}

impl FrameStats {
    /// All rays traced.
    pub fn rays(&self) -> u64 {
        self.primary_rays + self.shadow_rays + self.secondary_rays + self.secondary_shadow_rays
    }

    /// Seconds spent tracing (every pass, the spawning of secondary rays included).
    pub fn trace_secs(&self) -> f64 {
        self.primary_secs + self.shadow_secs + self.spawn_secs + self.secondary_secs + self.secondary_shadow_secs
    }
}

/// The share of a pass's time in leaf visits (triangle tests), per kind of ray:
/// [`Renderer::intersection_shares`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IntersectionShares {
    /// The share of the primary pass making its rays (ray generation), where clocked.
    pub generation: Option<f64>,
    /// Of the primary pass (ray generation, traversal and intersection).
    pub primary: Option<f64>,
    /// Of the secondary rays, every generation.
    pub secondary: Option<f64>,
}

/// Renders one scene through one camera with one bound method: the fixed part of a frame.
#[derive(Debug)]
pub struct Renderer<'a> {
    scene: &'a Scene,
    /// The scene's surface records: given ([`Renderer::with_surfaces`]) or made on first use.
    surfaces: Option<&'a Surfaces>,
    own_surfaces: OnceLock<Surfaces>,
    method: &'a Bound<'a>,
    camera: Camera,
    layout: TileLayout,
    shadows: Shadows,
    light: SphereLight,
    tree: Option<&'a KdTree>,
    /// Generations of secondary rays (0: none).
    depth: u32,
    /// Whether reflections in runs off one plane leave from the virtual eye.
    virtual_eyes: bool,
    /// The pixels in tile order and the order the first generation spawns from (each tile's
    /// pixels in Morton order), made on first use.
    spawn_order: OnceLock<SpawnOrder>,
}

/// The pixels of a frame in tile order, and the order its first generation of secondary
/// rays is spawned in (each tile's pixels in Morton order, as tile-order indices).
type SpawnOrder = (Vec<(u32, u32)>, Vec<u32>);

impl<'a> Renderer<'a> {
    /// A renderer of `scene` seen by `camera` with `method`, in the method's tiles. Soft
    /// shadows go to the light of radius 1 Sponza unit at the point light
    /// ([`soft::light_in_bounds`] of the mesh's bounds) unless [`Renderer::with_light`]
    /// gives another.
    pub fn new(scene: &'a Scene, method: &'a Bound<'a>, camera: Camera, shadows: Shadows) -> Self {
        let layout = TileLayout::new(camera.width, camera.height, method.options.tile.max(1));
        let (lo, hi) = scene.mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let light = soft::light_in_bounds(scene, lo, hi, 1.0);
        let (surfaces, own_surfaces) = (None, OnceLock::new());
        Renderer {
            scene,
            surfaces,
            own_surfaces,
            method,
            camera,
            layout,
            shadows,
            light,
            tree: None,
            depth: 0,
            virtual_eyes: false,
            spawn_order: OnceLock::new(),
        }
    }

    /// The same renderer with the scene's surface records made elsewhere
    /// ([`shade::surfaces`] of the same scene), for callers that make many renderers of one
    /// scene (the viewer makes one per frame).
    pub fn with_surfaces(mut self, surfaces: &'a Surfaces) -> Self {
        self.surfaces = Some(surfaces);
        self
    }

    /// The scene's surface records, which the shadow rays start from (made on the first call
    /// unless given).
    pub fn surfaces(&self) -> &Surfaces {
        self.surfaces.unwrap_or_else(|| self.own_surfaces.get_or_init(|| shade::surfaces(&self.scene.mesh)))
    }

    /// The same renderer with our kd-tree of the scene, which [`Shadows::EdgeWidth`] traces
    /// (the edge-width kernels are ours alone, so they need the tree whatever the method).
    pub fn with_tree(mut self, tree: &'a KdTree) -> Self {
        self.tree = Some(tree);
        self
    }

    /// The same renderer with `depth` generations of secondary rays (the thesis's shader
    /// proxy, [`crate::secondary`]; 0 for none, the default): reflections and refractions
    /// from the hits on materials that reflect or refract, traced by the method's stream
    /// kernel, their hits shaded with the frame's kind of shadows. The thesis renders with 1
    /// ([`crate::secondary::DEFAULT_DEPTH`]). At most [`crate::secondary::MAX_DEPTH`].
    pub fn with_secondary(mut self, depth: u32) -> Self {
        self.depth = depth.min(crate::secondary::MAX_DEPTH);
        self
    }

    /// Reflections in runs off one flat mirror leave from the virtual eye
    /// ([`crate::secondary::ReflectFrom`]); off (the default), every reflection starts at its
    /// hit point.
    pub fn with_virtual_eyes(mut self, on: bool) -> Self {
        self.virtual_eyes = on;
        self
    }

    /// Generations of secondary rays a frame traces.
    pub fn secondary_depth(&self) -> u32 {
        self.depth
    }

    /// The same renderer with the spherical light of soft shadows.
    pub fn with_light(mut self, light: SphereLight) -> Self {
        self.light = light;
        self
    }

    /// The camera of the primary rays.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The tile layout of the per-pixel buffers.
    pub fn layout(&self) -> &TileLayout {
        &self.layout
    }

    /// Buffers of the right size for [`Renderer::trace`].
    pub fn buffers(&self) -> FrameBuffers {
        FrameBuffers::new(self.layout.pixel_count())
    }

    /// Number of 2x2 packets the primary pass of a packet method traces (the denominator of
    /// the thesis's N and I).
    pub fn packet_count(&self) -> u64 {
        self.layout.packet_count()
    }

    /// Traces one frame into `buf`: the primary pass, then the shadow pass if shadows are on.
    /// Runs on the current rayon pool.
    ///
    /// # Panics
    /// With [`Shadows::EdgeWidth`] and no [`Renderer::with_tree`] (a programming error: the
    /// callers that offer edge widths always give the tree).
    pub fn trace(&self, buf: &mut FrameBuffers) -> FrameStats {
        self.trace_with(buf, false).0
    }

    /// [`Renderer::trace`] counting traversal steps, leaves and intersection tests, for the
    /// primary and the shadow pass apart. Slower: not for timing.
    pub fn trace_counted(&self, buf: &mut FrameBuffers) -> (FrameStats, Counts, Counts) {
        self.trace_with(buf, true)
    }

    /// The primary pass counted for cost images ([`crate::aov`]): hits into `buf.hits` (the
    /// shadow buffers are left alone), and each pixel's share of the traversal counts, per
    /// ray for single-ray methods and per tile for packets, frusta and cones
    /// (`Entry::attribution`). Slower than [`Renderer::trace`]: not for timing.
    pub fn trace_costs(&self, buf: &mut FrameBuffers) -> CostFrame {
        let attribution = self.method.entry.attribution();
        let mut costs = vec![PixelCost::default(); self.layout.pixel_count()];
        let totals =
            self.method.tracer.primary_costs(&self.layout, &self.camera, attribution, &mut buf.hits, &mut costs);
        CostFrame {
            width: self.camera.width,
            height: self.camera.height,
            pixels: self.layout.to_row_major(&costs),
            totals,
            attribution,
        }
    }

    fn trace_with(&self, buf: &mut FrameBuffers, counted: bool) -> (FrameStats, Counts, Counts) {
        let tracer = &self.method.tracer;
        let (scene, camera, layout) = (self.scene, &self.camera, &self.layout);
        // Made (once) before the clock starts: scene setup, not tracing.
        let surfaces = self.surfaces();
        let start = Instant::now();
        let (mut primary_counts, mut shadow_counts) = (Counts::default(), Counts::default());
        let hits = tracer.primary(layout, camera, &mut buf.hits, counted.then_some(&mut primary_counts));
        let primary_secs = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let counts = counted.then_some(&mut shadow_counts);
        let (shadow_rays, occluded) = match self.shadows {
            Shadows::None => {
                buf.occluded.fill(false);
                buf.visible.clear();
                (0, 0)
            }
            Shadows::Soft16 => {
                buf.occluded.fill(false);
                buf.visible.resize(layout.pixel_count(), 0.0);
                let SoftStats { rays, blocked, .. } = tracer.soft(
                    &View { layout, scene, surfaces, camera },
                    &buf.hits,
                    &self.light,
                    &mut buf.visible,
                    counts,
                );
                (rays, blocked)
            }
            Shadows::Hard => {
                buf.visible.clear();
                tracer.shadow(&View { layout, scene, surfaces, camera }, &buf.hits, &mut buf.occluded, counts)
            }
            Shadows::EdgeWidth => {
                let tree = self.tree.expect("Shadows::EdgeWidth needs Renderer::with_tree");
                buf.occluded.fill(false);
                buf.visible.resize(layout.pixel_count(), 0.0);
                self.edge_width_pass(tree, &buf.hits, &mut buf.visible)
            }
        };
        let shadow_secs = if self.shadows == Shadows::None { 0.0 } else { start.elapsed().as_secs_f64() };
        let mut stats = FrameStats {
            primary_rays: layout.pixel_count() as u64,
            shadow_rays,
            hits,
            occluded,
            primary_secs,
            shadow_secs,
            ..FrameStats::default()
        };
        self.secondary_pass(buf, &mut stats);
        (stats, primary_counts, shadow_counts)
    }

    /// The secondary rays of a frame ([`Renderer::with_secondary`]): each generation spawned
    /// from the hits before it, traced by the method's stream kernel, its hits' shadows
    /// traced as the primary hits' are. Fills `buf.local` and `buf.secondary`; adds the
    /// counts and times to `stats`.
    fn secondary_pass(&self, buf: &mut FrameBuffers, stats: &mut FrameStats) {
        buf.secondary.clear();
        buf.local.clear();
        if self.depth == 0 {
            return;
        }
        let (scene, surfaces) = (self.scene, self.surfaces());
        let (pixels, order) = self.spawn_order.get_or_init(|| {
            let pixels: Vec<(u32, u32)> = self.layout.tiles().iter().flat_map(|t| t.pixels()).collect();
            let mut order = Vec::with_capacity(pixels.len());
            let mut base = 0u32;
            for t in self.layout.tiles() {
                order.extend(scenes::morton_order(t.width(), t.height()).into_iter().map(|i| base + i));
                base += t.pixel_count() as u32;
            }
            (pixels, order)
        });
        let start = Instant::now();
        buf.local.resize(buf.hits.len(), 1.0);
        let (hits, camera) = (&buf.hits, &self.camera);
        let primary = |i: u32| {
            let hit = hits.get(i as usize).copied().flatten()?;
            let (x, y) = pixels[i as usize];
            let (eye, dir) = camera.pixel_ray(x, y);
            Some((hit, eye, dir))
        };
        let mut next = spawn_generation(surfaces, &scene.mesh, order, primary, self.virtual_eyes, &mut buf.local);
        stats.spawn_secs += start.elapsed().as_secs_f64();
        for level in 1..=self.depth {
            let mut generation = std::mem::take(&mut next);
            let start = Instant::now();
            generation.hits = vec![None; generation.len()];
            self.method.tracer.stream(&generation.rays, &mut generation.hits);
            stats.secondary_secs += start.elapsed().as_secs_f64();
            stats.secondary_rays += generation.len() as u64;
            stats.secondary_hits += generation.hits.par_iter().filter(|h| h.is_some()).count() as u64;
            let start = Instant::now();
            stats.secondary_shadow_rays += self.point_shadows(&mut generation);
            stats.secondary_shadow_secs += start.elapsed().as_secs_f64();
            generation.local = vec![1.0; generation.len()];
            if level < self.depth {
                let start = Instant::now();
                let all: Vec<u32> = (0..generation.len() as u32).collect();
                let (rays, hits) = (&generation.rays, &generation.hits);
                let point = |i: u32| Some((hits[i as usize]?, rays[i as usize].origin, rays[i as usize].dir));
                next = spawn_generation(surfaces, &scene.mesh, &all, point, self.virtual_eyes, &mut generation.local);
                stats.spawn_secs += start.elapsed().as_secs_f64();
            }
            let done = next.is_empty();
            buf.secondary.push(generation);
            if done {
                break;
            }
        }
    }

    /// The share of the primary and of the secondary rays' time spent in leaf visits, the
    /// thesis's intersection against traversal (Table 3.1), and of the primary pass in ray
    /// generation, from one clocked run of each pass
    /// ([`kdtree::LeafClock`]) over the frame `buf` holds: call it after [`Renderer::trace`].
    /// Each is `None` where the method's kernels are not kd descents (nothing clocked) or
    /// the frame has no such rays. A pass's busy time is its wall time times the pool's
    /// threads, so an unbalanced pool understates the share.
    pub fn intersection_shares(&self, buf: &FrameBuffers) -> IntersectionShares {
        let tracer = &self.method.tracer;
        let threads = rayon::current_num_threads() as u64;
        let mut hits = vec![None; buf.hits.len()];
        let start = kdtree::clock::ticks();
        let (_, clock) = tracer.primary_clocked(&self.layout, &self.camera, &mut hits);
        let busy = kdtree::clock::ticks().wrapping_sub(start) * threads;
        let (generation, primary) = (clock.generation_share(busy), clock.intersection_share(busy));
        let (mut clock, mut busy) = (kdtree::LeafClock::default(), 0);
        for generation in &buf.secondary {
            hits.clear();
            hits.resize(generation.len(), None);
            let start = kdtree::clock::ticks();
            clock += tracer.stream_clocked(&generation.rays, &mut hits);
            busy += kdtree::clock::ticks().wrapping_sub(start) * threads;
        }
        IntersectionShares { generation, primary, secondary: clock.intersection_share(busy) }
    }

    /// The shadows at a generation's hits, the frame's kind ([`Shadows`]) traced by the
    /// method's stream queries (edge widths by our kernels, as for the primary hits): the
    /// visible fraction into `generation.visible`. Returns the shadow rays traced.
    fn point_shadows(&self, generation: &mut Generation) -> u64 {
        let surfaces = self.surfaces();
        let n = generation.len();
        let (hits, rays) = (&generation.hits, &generation.rays);
        // Each point's shadow query, made in parallel, in point order with its point's index.
        fn gather<T: Send>(n: usize, make: impl Fn(usize) -> Option<T> + Sync + Send) -> (Vec<u32>, Vec<T>) {
            (0..n).into_par_iter().filter_map(|i| Some((i as u32, make(i)?))).unzip()
        }
        let point = |i: usize| Some((hits[i]?, rays[i].dir));
        // Misses stay 0; a lit point is 1 unless its query says otherwise.
        let mut visible: Vec<f32> = hits.par_iter().map(|h| if h.is_some() { 1.0 } else { 0.0 }).collect();
        let traced = match self.shadows {
            Shadows::None => 0,
            Shadows::Hard => {
                let light = &self.scene.point_light;
                // Facing away from the light: no ray, shaded ambient whatever lies between.
                let (owner, segments) = gather(n, |i| {
                    let (hit, dir) = point(i)?;
                    let (a, b) = shade::shadow_segment(surfaces, light, dir, &hit)?;
                    Some(Ray::segment(a, b))
                });
                let mut blocked = vec![false; segments.len()];
                self.method.tracer.stream_occluded(&segments, &mut blocked);
                for (&i, &b) in owner.iter().zip(&blocked) {
                    visible[i as usize] = if b { 0.0 } else { 1.0 };
                }
                segments.len() as u64
            }
            Shadows::Soft16 => {
                let light = &self.light;
                let (owner, points) = gather(n, |i| {
                    let (hit, dir) = point(i)?;
                    let (start, _) = soft::shadow_start(surfaces, light, &hit, dir)?;
                    Some(shadow_rays(start, &light_samples(start, light)?))
                });
                // Points without rays (facing away, inside the light) see nothing of it.
                for (v, h) in visible.iter_mut().zip(hits) {
                    *v = if h.is_some() { 0.0 } else { *v };
                }
                let samples: Vec<Ray> = points.par_iter().flat_map_iter(|r| r.iter().copied()).collect();
                let mut blocked = vec![false; samples.len()];
                self.method.tracer.stream_occluded(&samples, &mut blocked);
                for (&i, b) in owner.iter().zip(blocked.chunks(SAMPLES)) {
                    let k = b.iter().filter(|&&b| b).count();
                    visible[i as usize] = 1.0 - k as f32 / SAMPLES as f32;
                }
                samples.len() as u64
            }
            Shadows::EdgeWidth => {
                let tree = self.tree.expect("Shadows::EdgeWidth needs Renderer::with_tree");
                let light = &self.light;
                let center = PointLight { position: light.center, intensity: light.intensity };
                let (owner, queries) = gather(n, |i| {
                    let (hit, dir) = point(i)?;
                    let ray = shade::shadow_ray(surfaces, &center, dir, &hit)?;
                    let p = surfaces.get(hit.prim).point(&hit);
                    Some((ray, width_from_light(light.radius, (light.center - p).length(), 1.0)))
                });
                for (v, h) in visible.iter_mut().zip(hits) {
                    *v = if h.is_some() { 0.0 } else { *v };
                }
                let mut seen = vec![0.0; queries.len()];
                match tree.intersector() {
                    Intersector::Wald => edge_width_rays::<WaldTest>(tree, &queries, &mut seen),
                    Intersector::Watertight => edge_width_rays::<WatertightTest>(tree, &queries, &mut seen),
                }
                for (&i, &v) in owner.iter().zip(&seen) {
                    visible[i as usize] = v;
                }
                queries.len() as u64
            }
        };
        generation.visible = visible;
        traced
    }

    /// The edge-width pass ([`Shadows::EdgeWidth`]): the visible fraction of each pixel of
    /// `hits` into `visible` (tile order), in parallel over tiles, each tile's pixels four at
    /// a time in tile order. Returns the rays traced and those with a width above 0.
    fn edge_width_pass(&self, tree: &KdTree, hits: &[Option<Hit>], visible: &mut [f32]) -> (u64, u64) {
        // The tree's triangle test, chosen once for the pass (not per packet).
        match tree.intersector() {
            Intersector::Wald => self.edge_width_pass_with::<WaldTest>(tree, hits, visible),
            Intersector::Watertight => self.edge_width_pass_with::<WatertightTest>(tree, hits, visible),
        }
    }

    /// [`Renderer::edge_width_pass`] with the tree's triangle test `I`.
    fn edge_width_pass_with<I: PacketTreeTest>(
        &self,
        tree: &KdTree,
        hits: &[Option<Hit>],
        visible: &mut [f32],
    ) -> (u64, u64) {
        let surfaces = self.surfaces();
        let center = PointLight { position: self.light.center, intensity: self.light.intensity };
        let remedies = LeakRemedies::default();
        let inputs = self.layout.chunks(hits);
        let outputs = self.layout.chunks_mut(visible);
        self.layout
            .tiles()
            .par_iter()
            .zip(inputs)
            .zip(outputs)
            .map_init(EdgeScratch4::default, |scratch, ((tile, hits), out)| {
                let (mut rays, mut blocked) = (0u64, 0u64);
                let mut pixels = tile.pixels();
                for (hits, out) in hits.chunks(4).zip(out.chunks_mut(4)) {
                    let mut lanes = [None; 4];
                    let mut r = [0.0f32; 4];
                    for (lane, hit) in hits.iter().enumerate() {
                        let Some((x, y)) = pixels.next() else { break };
                        let Some(hit) = hit else { continue };
                        let dir = self.camera.pixel_ray(x, y).1;
                        let Some(ray) = shade::shadow_ray(surfaces, &center, dir, hit) else { continue };
                        let p = surfaces.get(hit.prim).point(hit);
                        r[lane] = width_from_light(self.light.radius, (self.light.center - p).length(), 1.0);
                        lanes[lane] = Some(ray);
                    }
                    let widths = edge_width4_with::<I>(tree, &RayPacket::from_lanes(lanes), r, &remedies, scratch);
                    for (lane, slot) in out.iter_mut().enumerate() {
                        *slot = match lanes[lane] {
                            Some(_) => {
                                rays += 1;
                                blocked += u64::from(widths[lane] > 0.0);
                                1.0 - occlusion_factor(widths[lane], r[lane])
                            }
                            None => 0.0,
                        };
                    }
                }
                (rays, blocked)
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    }

    /// The shaded image (`--aov color`): diffuse shading with the point light, dimmed by the
    /// hard shadow or by the visible fraction of the soft-shadow light (soft or edge-width
    /// shadows).
    pub fn color(&self, buf: &FrameBuffers) -> Image {
        let colors = self.shade_tiles(buf, |c| c);
        Image { width: self.camera.width, height: self.camera.height, pixels: self.layout.to_row_major(&colors) }
    }

    /// [`Renderer::color`] for display: each pixel gamma-encoded as `Image::save_png` does
    /// (`scenes::image::encode_gamma`, bit for bit, through [`GammaTable`]) and packed as `0x00RRGGBB`, row-major, into `out`.
    /// Shading and encoding run in parallel over the tiles; the one serial step is the copy
    /// into row order.
    pub fn color_packed(&self, buf: &FrameBuffers, out: &mut Vec<u32>) {
        let gamma = GammaTable::get();
        let packed = self.shade_tiles(buf, |c| {
            let [r, g, b] = c.to_array().map(|v| u32::from(gamma.encode(v)));
            r << 16 | g << 8 | b
        });
        out.clear();
        out.extend(self.layout.to_row_major(&packed));
    }

    /// The shaded colour of every pixel through `f`, in tile order, in parallel over tiles.
    fn shade_tiles<T: Copy + Default + Send>(&self, buf: &FrameBuffers, f: impl Fn(Vec3) -> T + Sync) -> Vec<T> {
        let light = &self.scene.point_light;
        let mesh = &self.scene.mesh;
        let mut colors = vec![T::default(); self.layout.pixel_count()];
        let chunks = self.layout.chunks_mut(&mut colors);
        let visible = if buf.visible.len() == buf.hits.len() { Some(self.layout.chunks(&buf.visible)) } else { None };
        let reflected = self.secondary_colors(buf);
        let reflected = reflected.as_ref().map(|c| (self.layout.chunks(c), self.layout.chunks(&buf.local)));
        let inputs: Vec<_> = self.layout.chunks(&buf.hits).into_iter().zip(self.layout.chunks(&buf.occluded)).collect();
        self.layout.tiles().par_iter().zip(chunks).zip(inputs).enumerate().for_each(
            |(i, ((tile, out), (hits, occluded)))| {
                let soft = visible.as_ref().map(|v| v[i]);
                let reflected = reflected.as_ref().map(|(c, l)| (c[i], l[i]));
                for (j, (((x, y), slot), hit)) in tile.pixels().zip(out).zip(hits).enumerate() {
                    let (origin, dir) = self.camera.pixel_ray(x, y);
                    let seen = match soft {
                        Some(v) => v[j],
                        None if occluded[j] => 0.0,
                        None => 1.0,
                    };
                    let color = match hit {
                        Some(hit) => shade::shade(mesh, light, origin, dir, hit, seen),
                        None => shade::BACKGROUND,
                    };
                    *slot = f(match reflected {
                        Some((c, l)) if hit.is_some() => l[j] * color + c[j],
                        _ => color,
                    });
                }
            },
        );
        colors
    }

    /// What the secondary rays add to each pixel (tile order), weighted: `None` without
    /// secondary rays. Each generation's colour is its hits' own shading, weighted by their
    /// `local`, plus what the next generation adds; misses see the background.
    fn secondary_colors(&self, buf: &FrameBuffers) -> Option<Vec<Vec3>> {
        if buf.local.len() != buf.hits.len() {
            return None;
        }
        let (mesh, light) = (&self.scene.mesh, &self.scene.point_light);
        let mut added: Vec<Vec3> = Vec::new();
        for (k, g) in buf.secondary.iter().enumerate().rev() {
            let colors: Vec<Vec3> = (0..g.len())
                .into_par_iter()
                .map(|i| {
                    let ray = &g.rays[i];
                    let own = match &g.hits[i] {
                        Some(hit) => g.local[i] * shade::shade(mesh, light, ray.origin, ray.dir, hit, g.visible[i]),
                        None => shade::BACKGROUND,
                    };
                    own + added.get(i).copied().unwrap_or(Vec3::ZERO)
                })
                .collect();
            let parents = if k == 0 { buf.hits.len() } else { buf.secondary[k - 1].len() };
            added = vec![Vec3::ZERO; parents];
            for ((&p, &w), c) in g.parent.iter().zip(&g.weight).zip(colors) {
                added[p as usize] += w * c;
            }
        }
        if added.is_empty() {
            added = vec![Vec3::ZERO; buf.hits.len()];
        }
        Some(added)
    }

    /// The distance of each primary hit (`--aov depth`, `+inf` for misses).
    pub fn depth(&self, buf: &FrameBuffers) -> ScalarImage {
        let values: Vec<f32> = buf.hits.iter().map(|h| h.map_or(f32::INFINITY, |h| h.t)).collect();
        ScalarImage { width: self.camera.width, height: self.camera.height, values: self.layout.to_row_major(&values) }
    }

    /// The hit triangle's primitive id in the source file's numbering (`Mesh::prim_ids`) as
    /// f32, `-1` for misses (`--aov prim`).
    pub fn prim(&self, buf: &FrameBuffers) -> ScalarImage {
        let ids = &self.scene.mesh.prim_ids;
        let values: Vec<f32> = buf
            .hits
            .iter()
            .map(|h| h.map_or(-1.0, |h| ids.get(h.prim as usize).map_or(-1.0, |&id| id as f32)))
            .collect();
        ScalarImage { width: self.camera.width, height: self.camera.height, values: self.layout.to_row_major(&values) }
    }
}

/// The visible fraction `1 - occlusion_factor(width, R)` of each edge-width ray `(ray, R)`
/// into `out`, four at a time with `edge_width4_with::<I>`, in parallel over chunks.
fn edge_width_rays<I: PacketTreeTest>(tree: &KdTree, rays: &[(Ray, f32)], out: &mut [f32]) {
    let remedies = LeakRemedies::default();
    out.par_chunks_mut(1024).zip(rays.par_chunks(1024)).for_each_init(EdgeScratch4::default, |scratch, (out, rays)| {
        for (out, rays) in out.chunks_mut(4).zip(rays.chunks(4)) {
            let mut lanes = [None; 4];
            let mut r = [0.0f32; 4];
            for (lane, &(ray, radius)) in rays.iter().enumerate() {
                lanes[lane] = Some(ray);
                r[lane] = radius;
            }
            let widths = edge_width4_with::<I>(tree, &RayPacket::from_lanes(lanes), r, &remedies, scratch);
            for (lane, slot) in out.iter_mut().enumerate() {
                *slot = 1.0 - occlusion_factor(widths[lane], r[lane]);
            }
        }
    });
}

/// `scenes::image::encode_gamma` without a `powf` per channel: the 255 thresholds where its
/// byte goes up (found once, by bisection over the f32 bit patterns of `[0, 1]`, on which
/// `encode_gamma` is non-decreasing) and, per 1/4096 of `[0, 1]`, the byte at the bucket's
/// start. A value's byte is its bucket's, moved up past the thresholds it reaches: the same
/// byte as `encode_gamma` for every f32 (tested at each threshold and around it).
#[derive(Debug)]
pub struct GammaTable {
    /// `thresholds[k]`: the smallest value whose byte is above `k`.
    thresholds: [f32; 255],
    /// The byte of each bucket's first value.
    buckets: Vec<u8>,
}

/// Buckets of [`GammaTable`] over `[0, 1]`.
const GAMMA_BUCKETS: usize = 4096;

impl GammaTable {
    /// The table, built on first use.
    pub fn get() -> &'static GammaTable {
        static TABLE: std::sync::OnceLock<GammaTable> = std::sync::OnceLock::new();
        TABLE.get_or_init(GammaTable::new)
    }

    fn new() -> GammaTable {
        use scenes::image::encode_gamma;
        let mut thresholds = [1.0f32; 255];
        for (k, t) in thresholds.iter_mut().enumerate() {
            let (mut lo, mut hi) = (0.0f32.to_bits(), 1.0f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if usize::from(encode_gamma(f32::from_bits(mid))) > k { hi = mid } else { lo = mid + 1 }
            }
            *t = f32::from_bits(lo);
        }
        let buckets = (0..GAMMA_BUCKETS).map(|b| encode_gamma(b as f32 / GAMMA_BUCKETS as f32)).collect();
        GammaTable { thresholds, buckets }
    }

    /// `scenes::image::encode_gamma(v)`: clamped to [0, 1] (NaN as 0), gamma 1/2.2, rounded.
    #[inline]
    pub fn encode(&self, v: f32) -> u8 {
        if v.is_nan() || v <= 0.0 {
            return 0;
        }
        if v >= 1.0 {
            return 255;
        }
        let mut code = self.buckets[((v * GAMMA_BUCKETS as f32) as usize).min(GAMMA_BUCKETS - 1)];
        while code < 255 && v >= self.thresholds[usize::from(code)] {
            code += 1;
        }
        code
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The gamma table gives `encode_gamma`'s byte at every threshold, one ulp either side,
    /// at every bucket start, on a million spread values, and for NaN, infinities, negatives.
    #[test]
    fn gamma_table_is_encode_gamma() {
        use scenes::image::encode_gamma;
        let table = GammaTable::get();
        let mut values = vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1.0, -0.0, 0.0, 1.0, 1.5, f32::MIN_POSITIVE];
        for &t in &table.thresholds {
            values.extend([f32::from_bits(t.to_bits() - 1), t, f32::from_bits(t.to_bits() + 1)]);
        }
        values.extend((0..=GAMMA_BUCKETS).map(|b| b as f32 / GAMMA_BUCKETS as f32));
        let one = 1.0f32.to_bits();
        values.extend((0..1_000_000u32).map(|i| f32::from_bits((u64::from(i) * u64::from(one) / 1_000_000) as u32)));
        values.extend((0..1_000_000u32).map(|i| i as f32 / 1e6));
        for v in values {
            assert_eq!(table.encode(v), encode_gamma(v), "{v:e}");
        }
        assert!(table.thresholds.windows(2).all(|w| w[0] < w[1]));
    }
}
