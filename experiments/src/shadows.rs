//! `rttest shadows`: Edge Width Soft Shadows (thesis chapter 5) against sampled soft
//! shadows, with the speed and the error of each method against a cached reference
//! ([`run`] with a [`ShadowsConfig`]; [`run_scene`] for one scene).
//!
//! Methods (each one frame: primary rays, visibility, shading, timed together):
//! - `hard`: one shadow ray to the light's centre;
//! - `hard-packets`: the same rays (the same image), each tile's in Morton order of their
//!   pixels as any-hit same-sign packets of the SIMD level's width (16 rays, 4x4 pixels, on
//!   AVX-512; `packets::samesign`), the way `edge-width-convolution` traces its probes;
//! - `edge-width` / `edge-width-packet`: one edge-width ray to the centre (single rays, or
//!   4-wide packets; identical images), occlusion from Eq. 5.1 with `R` from the light's size;
//! - `edge-width-silhouette`: one hard shadow ray to the centre, then the silhouette edges in
//!   the light's cone projected onto the light (`edgewidth::silhouette`): both halves of the
//!   penumbra, no leaks through thin occluders; a check ray per claimed exit in the dark half;
//!   the edges are searched only for pixels within the penumbra's reach of a hard shadow's
//!   edge (a frame pass of hard rays first), the others keep the hard answer, and among
//!   those only on a coarse lattice, the pixels between blended from their corners where
//!   that is safe (`edgewidth::sparse`);
//! - `edge-width-convolution`: one hard shadow ray to the centre per pixel (nearest hit: at
//!   the hard shadow's edge it gives the blocker), then, within the penumbra's reach, the
//!   hard answers of the neighbouring pixels on the same surface averaged over the light's
//!   image through that blocker (`edgewidth::convolution`; no search), on the sparse passes'
//!   lattice;
//! - `sampled-N`: `N` stratified samples of the area light (4, 8, 16, 32, 256);
//! - `sampled-N-packets` (4, 16): the same rays (the same image), each tile's rays to one
//!   stratum as packets of neighbouring pixels' rays, as `hard-packets`;
//! - `adaptive-16`: the 4 corner samples of `sampled-16`'s strata per pixel, and its other
//!   12 only where the probes of the pixel or of a neighbour disagree
//!   (`edgewidth::adaptive`); refined pixels get `sampled-16`'s answer bit for bit;
//! - `interleaved-16-raw`: Benthin & Wald's 4x4 interleaved sampling, 16 samples per pixel,
//!   unfiltered;
//! - `interleaved-16`: the same samples, then their 4x4 discontinuity filter. Its row also
//!   gives the filter's bias: the RMSE of the filtered reference against the reference, the
//!   error the filter adds even to exact visibilities (penumbrae narrower than the filter are
//!   blurred), which no choice of samples removes.
//!
//! Every frame runs on the tile loop of `rttest render`'s frame driver
//! (`trace::frame::for_tiles`): its primary pass is MFT in packets of the SIMD level's width
//! (the kernel of `rttest render --method mft-16`), the same for every method and for the
//! reference, then its visibility pass. The methods are named experiment
//! variants over the kernels the registry composes: single rays (`KdTree::occluded`, the
//! `kd-single` kernel), the same-sign segment packets of `kd-packets` /
//! `kd-stratum-packets` (`packets::samesign::occluded_segments`), the lane frusta of
//! `kd-lane-frusta` (`packets::LaneFrusta`) and the edge-width kernels; what they add is the
//! area light's samples and their filters, which no registry pass has.
//!
//! Shading is the light's centre times the visible fraction (both papers). The reference is
//! `--ref-samples` (1024) stratified samples per pixel, cached on disk (see
//! [`reference_cache_path`]); for the `analytic` scene (a sphere over a plane under a
//! spherical light) the plane's pixels take the closed form instead.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};
use std::time::Instant;

use crate::shadow_plot::{Point, plot};
use edgewidth::adaptive;
use edgewidth::analytic::sphere_visible_fraction;
use edgewidth::convolution;
use edgewidth::filter::{FilterParams, GBuffer, filter_pixel};
use edgewidth::packet::{EdgeScratch4, edge_width4};
use edgewidth::sampling::{InterleavedSets, Rng, ShadingPoint, strata, stratified, visible_fraction};
use edgewidth::silhouette::{Probe, hard_probe, penumbra_mask, silhouette_search};
use edgewidth::sparse::{self, Answer, Pixel, SparseFrame, Tolerances};
use edgewidth::{
    AreaLight, EdgeScratch, LeakRemedies, SilhouetteScratch, Silhouettes, edge_width, occlusion_factor,
    width_from_light,
};
use glam::{Vec2, Vec3};
use kdtree::isa::SimdLevel;
use kdtree::surface::Surfaces;
use kdtree::{BuildConfig, Hit, Intersector, KdTree, NoCounters, Ray};
use packets::{LaneFrusta, LaneWidth, RayPacket, Width, samesign};
use rayon::prelude::*;
use scenes::builtin::shapes::{MeshBuilder, Part};
use scenes::morton_order;
use scenes::{Camera, Image, Scene, SphereLight, View};
use serde::Serialize;
use trace::frame::for_tiles;
use trace::kernel::primary::Mft;
use trace::kernel::{self, shadow, soft, stream};
use trace::progress::Progress;
use trace::{FrameTracer, Options, TileLayout, shade};

use crate::Error;

/// The options of the soft-shadow comparison (`rttest shadows`); [`Default`] gives the
/// command line's defaults.
#[derive(Debug, Clone, PartialEq)]
pub struct ShadowsConfig {
    /// Scenes (built-in names, `analytic`, or OBJ paths). Empty: atrium, arena,
    /// atrium-rotated, grove, analytic and every .obj / .obj.gz in the shared scenes folder.
    pub scenes: Vec<String>,
    /// The view (`None`: each scene's default view).
    pub view: Option<String>,
    /// Image size, width and height (default 256x256).
    pub size: (u32, u32),
    /// The area light (default: the scene's rectangle).
    pub light: LightKind,
    /// Scale of the light about its centre (1 = the scene's light); a finite number > 0.
    pub light_size: f32,
    /// Scale of the edge width `R` (Eq. 5.1): `R = scale * light diameter / distance`; a
    /// finite number >= 0 (default 1).
    pub edge_scale: f32,
    /// Light-leak remedy: entry/exit pairs count only if their triangles share a vertex.
    pub shared_vertex: bool,
    /// Light-leak remedy: `NAME=SCALE` specs scaling edge widths through materials whose name
    /// contains `NAME` (e.g. `banner=8`; see [`thickness_scales`]).
    pub thickness: Vec<String>,
    /// Samples per pixel of the reference, at least 1 (default 1024).
    pub ref_samples: u32,
    /// Where references are cached (`None`: `target/shadow-cache` of the workspace).
    pub cache_dir: Option<PathBuf>,
    /// Where images, CSV and plots go, one folder per scene (default `shadows-out`).
    pub out_dir: PathBuf,
    /// Frames timed per method, interleaved across methods, at least 1; the median is
    /// reported (default 3).
    pub frames: u32,
    /// The ray-triangle test the trees are built for (default Wald's).
    pub intersector: Intersector,
    /// The rows to measure, by [`ShadowMethod::name`] (empty: every one of [`METHODS`]).
    /// Every frame is timed against a hard-shadow frame of its own either way.
    pub methods: Vec<String>,
}

impl Default for ShadowsConfig {
    fn default() -> Self {
        ShadowsConfig {
            scenes: Vec::new(),
            view: None,
            size: (256, 256),
            light: LightKind::Rect,
            light_size: 1.0,
            edge_scale: 1.0,
            shared_vertex: false,
            thickness: Vec::new(),
            ref_samples: 1024,
            cache_dir: None,
            out_dir: PathBuf::from("shadows-out"),
            frames: 3,
            intersector: Intersector::Wald,
            methods: Vec::new(),
        }
    }
}

impl ShadowsConfig {
    /// Checks the options before any scene is loaded or any reference computed: a light size
    /// or edge scale that is not a finite positive number (NaN included), a bad `thickness`
    /// spec, or no frame or reference sample is a usage error naming the option.
    pub fn validate(&self) -> Result<(), Error> {
        if !(self.light_size.is_finite() && self.light_size > 0.0) {
            return Err(Error::Usage(format!("--light-size {} must be a finite number > 0", self.light_size)));
        }
        if !(self.edge_scale.is_finite() && self.edge_scale >= 0.0) {
            return Err(Error::Usage(format!("--edge-scale {} must be a finite number >= 0", self.edge_scale)));
        }
        for spec in &self.thickness {
            parse_thickness(spec)?;
        }
        if self.frames == 0 {
            return Err(Error::Usage("--frames must be at least 1".into()));
        }
        if self.ref_samples == 0 {
            return Err(Error::Usage("--ref-samples must be at least 1".into()));
        }
        self.method_list()?;
        Ok(())
    }

    /// The methods measured, in [`METHODS`] order: those `methods` names, or every one when
    /// it is empty. An unknown name is a usage error listing the known ones.
    pub fn method_list(&self) -> Result<Vec<ShadowMethod>, Error> {
        if let Some(bad) = self.methods.iter().find(|n| !METHODS.iter().any(|m| m.name() == **n)) {
            let known: Vec<String> = METHODS.iter().map(|m| m.name()).collect();
            return Err(Error::Usage(format!("--methods: no method '{bad}' (known: {})", known.join(", "))));
        }
        Ok(METHODS.into_iter().filter(|m| self.methods.is_empty() || self.methods.contains(&m.name())).collect())
    }

    /// The scenes measured, in order: `scenes`, or when empty the experiments' default scenes
    /// ([`trace::setup::default_scenes`]) with `analytic` after the built-in ones.
    pub fn scene_list(&self) -> Vec<String> {
        if !self.scenes.is_empty() {
            return self.scenes.clone();
        }
        let mut list = trace::setup::default_scenes();
        list.insert(BUILTIN_DEFAULT_SCENES.min(list.len()), "analytic".to_string());
        list
    }

    /// The folder references are cached in: `cache_dir`, or `target/shadow-cache` of the
    /// workspace.
    pub fn cache_dir(&self) -> PathBuf {
        self.cache_dir.clone().unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/shadow-cache"))
    }
}

/// How many built-in scenes start [`trace::setup::default_scenes`] (atrium, arena,
/// atrium-rotated, grove): `analytic` goes after them.
const BUILTIN_DEFAULT_SCENES: usize = 4;

/// Which area light lights the scene.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum LightKind {
    /// The scene's rectangular area light.
    #[default]
    Rect,
    /// A sphere at the rectangle's centre with the rectangle's area as its disc.
    Sphere,
}

/// A shadow method (thesis Table 5.1, Benthin & Wald 2009 4.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadowMethod {
    /// One shadow ray to the light's centre.
    Hard,
    /// The same rays (the same image), each tile's in Morton order of their pixels as
    /// any-hit same-sign packets of the SIMD level's width ([`count_visible_by_sample`]).
    HardPackets,
    /// One edge-width ray to the centre (thesis chapter 5).
    EdgeWidth,
    /// Edge widths traced four rays at a time.
    EdgeWidthPacket,
    /// Silhouette widths (`edgewidth::silhouette`): the variant of Eq. 5.1 that draws both
    /// halves of the penumbra and lets no light through a closed occluder, searched only
    /// near the hard shadow's edges (`silhouette::penumbra_mask`) and there sparsely
    /// (`edgewidth::sparse`).
    Silhouette,
    /// Convolved edge widths (`edgewidth::convolution`): each pixel's hard shadow ray, then,
    /// within a penumbra's reach of the hard shadow's edge, the hard answers of the pixels on
    /// its surface averaged over the light's image through the edge's nearest blocker, on
    /// the sparse passes' lattice. No search: at most one shadow ray per pixel (on the
    /// 2-lattice, and between it where the lattice's answers disagree), whose nearest hit is
    /// the blocker at the hard shadow's edge.
    Convolution,
    /// `N` stratified samples of the light.
    Sampled(u32),
    /// The same `N` samples (the same rays, so the same image), traced per stratum as
    /// packets of neighbouring pixels' rays at the SIMD level's width (`trace::shadow_frusta`'s
    /// grouping, Benthin & Wald 2009; [`count_visible_by_sample`]).
    SampledPackets(u32),
    /// The same `N` samples (at most 16), each pixel's rays as one frustum, several pixels'
    /// in SIMD lanes (`packets::lane_frusta`, Benthin & Wald 2009's multi-frusta).
    SampledLanes(u32),
    /// Four probes of the 16 stratified samples per pixel, all 16 where the probes of the
    /// pixel or a neighbour disagree (`edgewidth::adaptive`).
    Adaptive,
    /// 4x4 interleaved sampling (16 samples), unfiltered.
    InterleavedRaw,
    /// The same interleaved samples (the same rays, so the same image), each pixel's 16 as
    /// one frustum in SIMD lanes (`packets::lane_frusta`), unfiltered.
    InterleavedLanes,
    /// 4x4 interleaved sampling (16 samples) and the 4x4 discontinuity filter.
    Interleaved,
}

/// Every method `rttest shadows` reports.
pub const METHODS: [ShadowMethod; 18] = [
    ShadowMethod::Hard,
    ShadowMethod::HardPackets,
    ShadowMethod::EdgeWidth,
    ShadowMethod::EdgeWidthPacket,
    ShadowMethod::Silhouette,
    ShadowMethod::Convolution,
    ShadowMethod::Sampled(4),
    ShadowMethod::SampledPackets(4),
    ShadowMethod::Sampled(8),
    ShadowMethod::Sampled(16),
    ShadowMethod::SampledPackets(16),
    ShadowMethod::SampledLanes(16),
    ShadowMethod::Adaptive,
    ShadowMethod::Sampled(32),
    ShadowMethod::Sampled(256),
    ShadowMethod::InterleavedRaw,
    ShadowMethod::InterleavedLanes,
    ShadowMethod::Interleaved,
];

impl ShadowMethod {
    /// The name in reports and file names.
    pub fn name(self) -> String {
        match self {
            ShadowMethod::Hard => "hard".into(),
            ShadowMethod::HardPackets => "hard-packets".into(),
            ShadowMethod::EdgeWidth => "edge-width".into(),
            ShadowMethod::EdgeWidthPacket => "edge-width-packet".into(),
            ShadowMethod::Silhouette => "edge-width-silhouette".into(),
            ShadowMethod::Convolution => "edge-width-convolution".into(),
            ShadowMethod::Sampled(n) => format!("sampled-{n}"),
            ShadowMethod::SampledPackets(n) => format!("sampled-{n}-packets"),
            ShadowMethod::SampledLanes(n) => format!("sampled-{n}-lanes"),
            ShadowMethod::Adaptive => "adaptive-16".into(),
            ShadowMethod::InterleavedRaw => "interleaved-16-raw".into(),
            ShadowMethod::InterleavedLanes => "interleaved-16-raw-lanes".into(),
            ShadowMethod::Interleaved => "interleaved-16".into(),
        }
    }
}

/// One scene, view and light, ready to render any [`ShadowMethod`].
pub struct ShadowSetup<'a> {
    scene: &'a Scene,
    tree: &'a KdTree,
    camera: Camera,
    light: AreaLight,
    layout: TileLayout,
    edge_scale: f32,
    shared_vertex: bool,
    thickness: Option<Vec<f32>>,
    /// Each triangle's surface record, made once (`ShadingPoint::on`).
    surfaces: Surfaces,
    /// The triangles' adjacency for [`ShadowMethod::Silhouette`], made on its first frame.
    silhouettes: OnceLock<Silhouettes>,
    /// [`ShadowMethod::Convolution`]'s buffers, kept from frame to frame.
    convolution: Mutex<convolution::ConvolutionBuffers>,
    /// Every frame's primary pass ([`ShadowSetup::primary_pass`]): MFT at the SIMD level's
    /// width, bound as `rttest render --method mft-16` binds its primary kernel.
    primary: Box<dyn FrameTracer + 'a>,
}

/// One rendered frame.
pub struct ShadowFrame {
    /// Visible fraction per pixel, row-major (0 where the primary ray misses).
    pub visibility: Vec<f32>,
    /// Primary hits, row-major.
    pub hits: Vec<Option<Hit>>,
    /// Shadow rays traced (edge-width rays count one each).
    pub shadow_rays: u64,
    /// Seconds for the whole frame: primary rays, visibility, filter, shading.
    pub secs: f64,
    /// The shaded image.
    pub image: Image,
}

/// The adjacency of no triangles (for the frames that do not use it).
static NO_SILHOUETTES: Silhouettes = Silhouettes::EMPTY;

/// A deterministic per-pixel seed.
fn pixel_seed(x: u32, y: u32, salt: u64) -> u64 {
    (u64::from(y) << 32 | u64::from(x)).wrapping_mul(0x2545_F491_4F6C_DD1D) ^ salt
}

impl<'a> ShadowSetup<'a> {
    /// The setup of `scene` (with its tree) seen by `camera`, lit by `light`. An error if its
    /// primary kernel does not bind (the tree's triangle test, or the registry's options).
    pub fn new(scene: &'a Scene, tree: &'a KdTree, camera: Camera, light: AreaLight) -> Result<Self, Error> {
        let options = Options::default();
        let layout = TileLayout::new(camera.width, camera.height, options.tile);
        let surfaces = trace::shade::surfaces(&scene.mesh);
        let primary = kernel::bind_tree::<Mft, shadow::Single, soft::Single, stream::Single>(tree, &options)?.tracer;
        Ok(ShadowSetup {
            scene,
            tree,
            camera,
            light,
            layout,
            edge_scale: 1.0,
            shared_vertex: false,
            thickness: None,
            surfaces,
            silhouettes: OnceLock::new(),
            convolution: Mutex::default(),
            primary,
        })
    }

    /// With the edge-width options: `R` scale, shared-vertex rule, per-triangle thickness.
    pub fn with_edge_options(mut self, scale: f32, shared_vertex: bool, thickness: Option<Vec<f32>>) -> Self {
        (self.edge_scale, self.shared_vertex, self.thickness) = (scale, shared_vertex, thickness);
        self
    }

    /// The light.
    pub fn light(&self) -> &AreaLight {
        &self.light
    }

    fn remedies(&self) -> LeakRemedies<'_> {
        LeakRemedies { thickness: self.thickness.as_deref(), shared_vertex: self.shared_vertex }
    }

    fn shading_point(&self, x: u32, y: u32, hit: &Hit) -> ShadingPoint {
        let (_, dir) = self.camera.pixel_ray(x, y);
        ShadingPoint::on(self.surfaces.get(hit.prim), hit, dir)
    }

    /// The triangles' adjacency (`edgewidth::silhouette`), made on first use.
    fn silhouettes(&self) -> &Silhouettes {
        self.silhouettes.get_or_init(|| Silhouettes::new(self.tree))
    }

    /// `R` (Eq. 5.1) and the edge-width ray of a shading point, or `None` when the light's
    /// centre is behind the surface.
    fn edge_ray(&self, p: &ShadingPoint) -> Option<(Ray, f32)> {
        let center = self.light.center();
        let ray = p.shadow_ray(center)?;
        Some((ray, width_from_light(self.light.radius(), (center - p.point).length(), self.edge_scale)))
    }

    /// Renders one frame with `method`, timing all of it.
    pub fn frame(&self, method: ShadowMethod) -> ShadowFrame {
        if method == ShadowMethod::Silhouette {
            // Made once per scene, like the tree: not part of any frame's time.
            self.silhouettes();
        }
        let start = Instant::now();
        let n = self.layout.pixel_count();
        let mut hits = vec![None; n];
        self.primary_pass(&mut hits);
        if method == ShadowMethod::Convolution {
            let hits = self.layout.to_row_major(&hits);
            let (visibility, shadow_rays) = self.convolution(&hits);
            let image = self.shade(&hits, &visibility);
            return ShadowFrame { visibility, hits, shadow_rays, secs: start.elapsed().as_secs_f64(), image };
        }
        let mut vis = vec![0.0f32; n];
        let shadow_rays = if method == ShadowMethod::Adaptive {
            self.adaptive(&hits, &mut vis)
        } else if method == ShadowMethod::Silhouette {
            self.silhouette(&hits, &mut vis)
        } else {
            let sets = InterleavedSets::new(7);
            let chunks: Vec<_> = self.layout.chunks(&hits).into_iter().zip(self.layout.chunks_mut(&mut vis)).collect();
            for_tiles(
                &self.layout,
                chunks,
                || (),
                |_, tile, (hits, out)| self.visibility_tile(method, tile, hits, out, &sets),
            )
        };
        let hits = self.layout.to_row_major(&hits);
        let mut visibility = self.layout.to_row_major(&vis);
        if method == ShadowMethod::Interleaved {
            visibility = self.filtered(&hits, &visibility);
        }
        let image = self.shade(&hits, &visibility);
        ShadowFrame { visibility, hits, shadow_rays, secs: start.elapsed().as_secs_f64(), image }
    }

    /// Every pixel's primary hit (tile order), as the thesis's renderer traces them: MFT
    /// (thesis 4.1.5) over 16x16 tiles, in packets of the SIMD level's width (the frame
    /// driver's primary pass of `rttest render --method mft-16`, `kd-mft-16-w16` on AVX-512),
    /// the fastest primary kernel of ours, so that the frames' times are what the shadows add
    /// to a fast renderer's frame. Every method's frame and the reference start from the same
    /// hits: the single rays' but on faces that coincide, where the packets may name the
    /// other triangle (`docs/results/targets.md`).
    fn primary_pass(&self, hits: &mut [Option<Hit>]) {
        self.primary.primary(&self.layout, &self.camera, hits, None);
    }

    /// The visible fractions of one tile's pixels (tile order). Returns the rays traced.
    fn visibility_tile(
        &self,
        method: ShadowMethod,
        tile: &scenes::Tile,
        hits: &[Option<Hit>],
        out: &mut [f32],
        sets: &InterleavedSets,
    ) -> u64 {
        let tree = self.tree;
        let remedies = self.remedies();
        let mut rays = 0u64;
        match method {
            ShadowMethod::EdgeWidthPacket => {
                let mut scratch = EdgeScratch4::default();
                let pixels: Vec<(u32, u32)> = tile.pixels().collect();
                for ((block, hits), out) in pixels.chunks(4).zip(hits.chunks(4)).zip(out.chunks_mut(4)) {
                    let mut lanes = [None; 4];
                    let mut r = [0.0f32; 4];
                    for (lane, (&(x, y), hit)) in block.iter().zip(hits).enumerate() {
                        if let Some(hit) = hit
                            && let Some((ray, rr)) = self.edge_ray(&self.shading_point(x, y, hit))
                        {
                            lanes[lane] = Some(ray);
                            r[lane] = rr;
                        }
                    }
                    let widths = edge_width4(tree, &RayPacket::from_lanes(lanes), r, &remedies, &mut scratch);
                    for lane in 0..out.len() {
                        out[lane] =
                            if lanes[lane].is_some() { 1.0 - occlusion_factor(widths[lane], r[lane]) } else { 0.0 };
                        rays += u64::from(lanes[lane].is_some());
                    }
                }
            }
            ShadowMethod::HardPackets => rays = self.hard_packets(tile, hits, out),
            ShadowMethod::SampledPackets(n) => rays = self.sampled_packets(n, tile, hits, out),
            ShadowMethod::SampledLanes(n) => rays = self.lanes(n, tile, hits, out, |x, y| pixel_samples(x, y, n)),
            ShadowMethod::InterleavedLanes => {
                rays = self.lanes(16, tile, hits, out, |x, y| sets.for_pixel(x, y).iter().copied())
            }
            _ => {
                let mut scratch = EdgeScratch::default();
                for (((x, y), hit), slot) in tile.pixels().zip(hits).zip(out) {
                    let Some(hit) = hit else {
                        *slot = 0.0;
                        continue;
                    };
                    let p = self.shading_point(x, y, hit);
                    *slot = match method {
                        ShadowMethod::Hard => {
                            rays += 1;
                            visible_fraction(tree, &self.light, &p, 1, &mut Rng::new(0))
                        }
                        ShadowMethod::EdgeWidth => match self.edge_ray(&p) {
                            Some((ray, r)) => {
                                rays += 1;
                                1.0 - occlusion_factor(edge_width(tree, &ray, r, &remedies, &mut scratch), r)
                            }
                            None => 0.0,
                        },
                        ShadowMethod::Sampled(n) => {
                            rays += u64::from(n);
                            visible_fraction(tree, &self.light, &p, n, &mut Rng::new(pixel_seed(x, y, u64::from(n))))
                        }
                        ShadowMethod::Interleaved | ShadowMethod::InterleavedRaw => {
                            rays += 16;
                            sets.visible_fraction(tree, &self.light, &p, x, y)
                        }
                        ShadowMethod::EdgeWidthPacket
                        | ShadowMethod::HardPackets
                        | ShadowMethod::SampledPackets(_)
                        | ShadowMethod::SampledLanes(_)
                        | ShadowMethod::InterleavedLanes
                        | ShadowMethod::Silhouette
                        | ShadowMethod::Convolution
                        | ShadowMethod::Adaptive => {
                            unreachable!("handled above")
                        }
                    };
                }
            }
        }
        rays
    }

    /// [`ShadowMethod::Adaptive`] over the frame (`hits` and `out` in tile order), in two
    /// passes over the tiles: every hit's four probes, then the other 12 samples of the
    /// pixels whose probes, or a neighbour's, disagree (`edgewidth::adaptive`). A pixel's
    /// samples are `sampled-16`'s (same generator and seed); each pass traces a tile's rays
    /// sample by sample as packets ([`count_visible_by_sample`]). Returns the rays
    /// traced: 4 per hit and 12 per refined pixel.
    fn adaptive(&self, hits: &[Option<Hit>], out: &mut [f32]) -> u64 {
        const NO_HIT: u8 = u8::MAX;
        // The shading point and sample generator of each pixel of `tile` that `keep` names.
        let points = |tile: &scenes::Tile, hits: &[Option<Hit>], keep: &dyn Fn(usize) -> bool| {
            tile.pixels()
                .zip(hits)
                .enumerate()
                .map(|(i, ((x, y), hit))| {
                    let hit = hit.as_ref().filter(|_| keep(i))?;
                    let rng = Rng::new(pixel_seed(x, y, u64::from(adaptive::SAMPLES)));
                    Some((self.shading_point(x, y, hit), rng))
                })
                .collect::<Vec<_>>()
        };
        let ray_of = |(p, rng): &(ShadingPoint, Rng), k: usize| {
            p.shadow_segment(self.light.sample(p.point, adaptive::sample_position(*rng, k)))
        };
        let mut probes = vec![NO_HIT; hits.len()];
        let chunks: Vec<_> = self.layout.chunks(hits).into_iter().zip(self.layout.chunks_mut(&mut probes)).collect();
        for_tiles(
            &self.layout,
            chunks,
            || (),
            |_, tile, (hits, probes)| {
                let points = points(tile, hits, &|_| true);
                let order = morton_order(tile.width(), tile.height());
                let mut visible = vec![0u32; points.len()];
                let ray = |i: usize, k: usize| points[i].as_ref().and_then(|point| ray_of(point, k));
                count_visible_by_sample(self.tree, &order, &adaptive::PROBES, ray, &mut visible);
                for ((slot, hit), v) in probes.iter_mut().zip(hits).zip(visible) {
                    if hit.is_some() {
                        *slot = v as u8;
                    }
                }
            },
        );
        let (w, h) = (self.camera.width, self.camera.height);
        let grid = self.layout.to_row_major(&probes);
        let at = |x: u32, y: u32| grid[(y * w + x) as usize];
        let chunks: Vec<_> = self.layout.chunks(hits).into_iter().zip(self.layout.chunks_mut(out)).collect();
        let refined: u64 = for_tiles(
            &self.layout,
            chunks,
            || (),
            |_, tile, (hits, out)| {
                let refine: Vec<bool> = tile
                    .pixels()
                    .map(|(x, y)| {
                        let own = at(x, y);
                        let neighbours = (y.saturating_sub(1)..(y + 2).min(h))
                            .flat_map(|ny| (x.saturating_sub(1)..(x + 2).min(w)).map(move |nx| at(nx, ny)))
                            .filter(|&n| n != NO_HIT);
                        own != NO_HIT && adaptive::needs_refining(own, neighbours)
                    })
                    .collect();
                let points = points(tile, hits, &|i| refine[i]);
                let order = morton_order(tile.width(), tile.height());
                let mut rest = vec![0u32; points.len()];
                let ray = |i: usize, k: usize| points[i].as_ref().and_then(|point| ray_of(point, k));
                count_visible_by_sample(self.tree, &order, &adaptive::REST, ray, &mut rest);
                for (((x, y), slot), (&refine, rest)) in tile.pixels().zip(out).zip(refine.iter().zip(rest)) {
                    let own = at(x, y);
                    *slot = if own == NO_HIT { 0.0 } else { adaptive::fraction(own, refine.then_some(rest as u8)) };
                }
                refine.iter().filter(|&&r| r).count() as u64
            },
        );
        let probed = hits.iter().filter(|h| h.is_some()).count() as u64;
        adaptive::PROBES.len() as u64 * probed + adaptive::REST.len() as u64 * refined
    }

    /// [`ShadowMethod::Silhouette`] over the frame (`hits` and `out` in tile order): a pass
    /// over the tiles for every hit's hard shadow ray (`silhouette::hard_probe`), the pixels
    /// near a hard shadow's edge (`silhouette::penumbra_mask`), then the sparse passes
    /// (`edgewidth::sparse`, each over the tiles): the cone search
    /// (`silhouette::silhouette_search`) on the mask's pixels of the 4-lattice, then on the
    /// 2-lattice and the rest only where blending the corners is not safe. The pixels outside
    /// the mask keep the hard answer (times the horizon's share). Returns the rays traced.
    fn silhouette(&self, hits: &[Option<Hit>], out: &mut [f32]) -> u64 {
        let silhouettes = self.silhouettes.get().unwrap_or(&NO_SILHOUETTES);
        let mut pixels = vec![None; hits.len()];
        let chunks: Vec<_> = self.layout.chunks(hits).into_iter().zip(self.layout.chunks_mut(&mut pixels)).collect();
        let probed: u64 = for_tiles(
            &self.layout,
            chunks,
            || (),
            |_, tile, (hits, pixels)| {
                let mut rays = 0u64;
                for (((x, y), hit), slot) in tile.pixels().zip(hits).zip(pixels.iter_mut()) {
                    let Some(hit) = hit else { continue };
                    let point = self.shading_point(x, y, hit);
                    let footprint = self.camera.footprint(point.point);
                    let probe = hard_probe(self.tree, &self.light, &point, footprint);
                    rays += match probe {
                        Probe::Done(v) => u64::from(v.rays),
                        _ => 1,
                    };
                    *slot = Some(Pixel::new(&point, footprint, probe));
                }
                rays
            },
        );
        let (w, h) = (self.camera.width, self.camera.height);
        let pixels = self.layout.to_row_major(&pixels);
        let probes: Vec<Option<Probe>> = pixels.iter().map(|p| p.map(|p| p.probe)).collect();
        let mask = penumbra_mask(w, h, &probes);
        let frame = SparseFrame::new(w, h, &pixels, &mask, Tolerances::DEFAULT);
        // Each pass reads the earlier passes' answers (row-major) and writes its own pixels'
        // (tile order).
        let mut answers = vec![Answer::Pending; hits.len()];
        let mut known = Vec::new();
        let mut searched = 0u64;
        for pass in 0..sparse::PASSES {
            let chunks = self.layout.chunks_mut(&mut answers);
            let chunks: Vec<_> = self.layout.chunks(hits).into_iter().zip(chunks).collect();
            searched +=
                for_tiles(&self.layout, chunks, SilhouetteScratch::default, |scratch, tile, (hits, answers)| {
                    let mut rays = 0u64;
                    for (((x, y), hit), slot) in tile.pixels().zip(hits).zip(answers) {
                        let Some(hit) = hit else { continue };
                        let search = |pixel: &Pixel| {
                            let p = self.shading_point(x, y, hit);
                            let blocked = matches!(pixel.probe, Probe::Blocked(_));
                            let v = silhouette_search(self.tree, silhouettes, &self.light, &p, blocked, scratch);
                            rays += u64::from(v.rays);
                            v.fraction
                        };
                        if let Some(answer) = frame.resolve(&known, x, y, pass, search) {
                            *slot = answer;
                        }
                    }
                    rays
                });
            known = self.layout.to_row_major(&answers);
        }
        for (slot, answer) in out.iter_mut().zip(&answers) {
            *slot = answer.fraction();
        }
        probed + searched
    }

    /// [`ShadowMethod::Convolution`] over the frame (`hits` row-major): the whole of
    /// `convolution::convolved_frame`, its passes over the rows in parallel. Returns the
    /// visible fractions (row-major) and the rays traced.
    fn convolution(&self, hits: &[Option<Hit>]) -> (Vec<f32>, u64) {
        let (w, h) = (self.camera.width, self.camera.height);
        let point = |x: u32, y: u32| {
            let p = self.shading_point(x, y, hits.get((y * w + x) as usize)?.as_ref()?);
            Some((p, self.camera.footprint(p.point)))
        };
        let params = convolution::Params::DEFAULT;
        // Locked once a frame, by the frame's one caller.
        let mut buffers = self.convolution.lock().unwrap_or_else(|e| e.into_inner());
        convolution::convolved_frame(
            self.tree,
            &self.light,
            (w, h),
            params,
            convolution::TOLERANCES,
            &mut buffers,
            point,
        )
    }

    /// [`ShadowMethod::HardPackets`] on one tile: each pixel's shadow ray to the light's
    /// centre as `visible_fraction` makes it, the tile's in Morton order of their pixels as
    /// packets ([`count_visible_by_sample`]). Returns the rays traced (one per hit, as
    /// [`ShadowMethod::Hard`] counts them).
    fn hard_packets(&self, tile: &scenes::Tile, hits: &[Option<Hit>], out: &mut [f32]) -> u64 {
        let (w, center) = (tile.width(), self.light.center());
        let segments: Vec<Option<(Vec3, Vec3)>> = hits
            .iter()
            .enumerate()
            .map(|(i, hit)| {
                let (x, y) = (tile.x0 + i as u32 % w, tile.y0 + i as u32 / w);
                hit.as_ref().and_then(|hit| self.shading_point(x, y, hit).shadow_segment(center))
            })
            .collect();
        let mut visible = vec![0u32; hits.len()];
        count_visible_by_sample(self.tree, &morton_order(w, tile.height()), &[0], |i, _| segments[i], &mut visible);
        for ((slot, hit), v) in out.iter_mut().zip(hits).zip(visible) {
            *slot = if hit.is_some() { v as f32 } else { 0.0 };
        }
        hits.iter().filter(|h| h.is_some()).count() as u64
    }

    /// [`ShadowMethod::SampledPackets`] on one tile: each pixel's `n` rays exactly as
    /// `visible_fraction` makes them (same seed), then, sample by sample, the tile's rays
    /// in Morton order of their pixels as same-sign any-hit packets at the SIMD level's
    /// width ([`count_visible_by_sample`]). Returns the rays traced (`n` per hit, as
    /// [`ShadowMethod::Sampled`] counts them).
    fn sampled_packets(&self, n: u32, tile: &scenes::Tile, hits: &[Option<Hit>], out: &mut [f32]) -> u64 {
        let w = tile.width();
        // Per pixel, its shading point; its `n` sample positions at `n * i ..`.
        let mut positions = Vec::with_capacity(n as usize * hits.len());
        let points: Vec<Option<ShadingPoint>> = hits
            .iter()
            .enumerate()
            .map(|(i, hit)| {
                let (x, y) = (tile.x0 + i as u32 % w, tile.y0 + i as u32 / w);
                positions.extend(pixel_samples(x, y, n));
                hit.as_ref().map(|hit| self.shading_point(x, y, hit))
            })
            .collect();
        let ray = |i: usize, k: usize| {
            points[i].as_ref().and_then(|p| p.shadow_segment(self.light.sample(p.point, positions[n as usize * i + k])))
        };
        let samples: Vec<usize> = (0..n as usize).collect();
        let mut visible = vec![0u32; hits.len()];
        count_visible_by_sample(self.tree, &morton_order(w, tile.height()), &samples, ray, &mut visible);
        for ((slot, hit), v) in out.iter_mut().zip(hits).zip(visible) {
            *slot = if hit.is_some() { v as f32 / n as f32 } else { 0.0 };
        }
        u64::from(n) * hits.iter().filter(|h| h.is_some()).count() as u64
    }

    /// [`ShadowMethod::SampledLanes`] and [`ShadowMethod::InterleavedLanes`] on one tile:
    /// each pixel's `n` rays (`n <= 16`, to the light positions `positions(x, y)`, as the
    /// single-ray methods make them) as one frustum, the tile's frusta in Morton order of
    /// their pixels, 8 or 4 at a time in SIMD lanes (`LaneWidth::widest`). A sample without a
    /// ray counts as blocked, as in [`count_visible_by_sample`]. Returns the rays traced (`n`
    /// per hit).
    fn lanes<P: IntoIterator<Item = Vec2>>(
        &self,
        n: u32,
        tile: &scenes::Tile,
        hits: &[Option<Hit>],
        out: &mut [f32],
        positions: impl Fn(u32, u32) -> P,
    ) -> u64 {
        let w = tile.width();
        let mut lanes = LaneFrusta::new();
        let (mut slots, mut starts, mut ends) = (Vec::new(), Vec::new(), Vec::new());
        for i in morton_order(w, tile.height()) {
            let i = i as usize;
            let (x, y) = (tile.x0 + i as u32 % w, tile.y0 + i as u32 / w);
            let Some(p) = hits[i].as_ref().map(|hit| self.shading_point(x, y, hit)) else { continue };
            starts.clear();
            ends.clear();
            for pos in positions(x, y) {
                if let Some((start, end)) = p.shadow_segment(self.light.sample(p.point, pos)) {
                    starts.push(start);
                    ends.push(end);
                }
            }
            lanes.push(&starts, &ends);
            slots.push((i, starts.len() as u32));
        }
        lanes.trace(self.tree, LaneWidth::widest(), &mut NoCounters);
        out.fill(0.0);
        for (&(i, rays), &blocked) in slots.iter().zip(lanes.blocked()) {
            out[i] = (rays - blocked.count_ones()) as f32 / n as f32;
        }
        u64::from(n) * hits.iter().filter(|h| h.is_some()).count() as u64
    }

    /// The discontinuity filter (`edgewidth::filter`, default thresholds) over a row-major
    /// visibility buffer, with the G-buffer of `hits` (hit distance, facing geometric normal).
    pub fn filtered(&self, hits: &[Option<Hit>], vis: &[f32]) -> Vec<f32> {
        let (w, h) = (self.camera.width, self.camera.height);
        let mesh = &self.scene.mesh;
        let mut depth = vec![f32::INFINITY; hits.len()];
        let mut normal = vec![Vec3::ZERO; hits.len()];
        for (i, hit) in hits.iter().enumerate() {
            if let Some(hit) = hit {
                let (_, dir) = self.camera.pixel_ray(i as u32 % w, i as u32 / w);
                depth[i] = hit.t;
                normal[i] = shade::facing_normal(mesh, hit, dir);
            }
        }
        let g = GBuffer { width: w, height: h, depth: &depth, normal: &normal };
        let params = FilterParams::default();
        let mut out = vec![0.0f32; vis.len()];
        out.par_chunks_mut(w as usize).enumerate().for_each(|(y, row)| {
            for (x, v) in row.iter_mut().enumerate() {
                *v = filter_pixel(x as u32, y as u32, vis, &g, &params);
            }
        });
        out
    }

    /// The shaded image: the light's centre as a point light, times the visible fraction
    /// (`trace::shade::shade` with it: the ambient term alone where it is 0).
    pub fn shade(&self, hits: &[Option<Hit>], vis: &[f32]) -> Image {
        let light = scenes::PointLight { position: self.light.center(), intensity: self.light.intensity() };
        let w = self.camera.width;
        let mut pixels = vec![shade::BACKGROUND; hits.len()];
        pixels.par_iter_mut().enumerate().for_each(|(i, px)| {
            if let Some(hit) = &hits[i] {
                let (o, d) = self.camera.pixel_ray(i as u32 % w, i as u32 / w);
                *px = shade::shade(&self.scene.mesh, &light, o, d, hit, vis[i]);
            }
        });
        Image { width: w, height: self.camera.height, pixels }
    }

    /// The reference visibility, `samples` stratified samples per pixel (row-major), from the
    /// frames' primary hits ([`ShadowSetup::primary_pass`]).
    pub fn reference(&self, samples: u32) -> Vec<f32> {
        let w = self.camera.width;
        let n = self.layout.pixel_count();
        let mut hits = vec![None; n];
        self.primary_pass(&mut hits);
        let hits = self.layout.to_row_major(&hits);
        let mut vis = vec![0.0f32; n];
        vis.par_chunks_mut(w as usize).enumerate().for_each(|(y, row)| {
            for (x, v) in row.iter_mut().enumerate() {
                let (x, y) = (x as u32, y as u32);
                if let Some(hit) = hits[y as usize * w as usize + x as usize] {
                    let p = self.shading_point(x, y, &hit);
                    let mut rng = Rng::new(pixel_seed(x, y, 0xC0FF_EE00 ^ u64::from(samples)));
                    *v = visible_fraction(self.tree, &self.light, &p, samples, &mut rng);
                }
            }
        });
        vis
    }
}

/// Pixel `(x, y)`'s `n` stratified light positions, as `visible_fraction` draws them for
/// `sampled-N` (the same seed, so the same rays).
fn pixel_samples(x: u32, y: u32, n: u32) -> impl Iterator<Item = Vec2> {
    let grid = strata(n);
    let mut rng = Rng::new(pixel_seed(x, y, u64::from(n)));
    (0..n).map(move |k| stratified(k, grid, &mut rng))
}

/// Adds to `visible[i]` how many of pixel `i`'s rays are not blocked, the ray of sample `k`
/// (`k` in `samples`) being `ray(i, k)`'s segment (`ShadingPoint::shadow_segment`); a `None`
/// ray counts as blocked. The rays go sample by sample, each sample's in the pixel order
/// `order` (Morton order of a tile: neighbours' rays to the same light stratum side by side)
/// as same-sign any-hit packets made from the segments, as many rays a packet as the SIMD
/// level has lanes (`packets::Width::for_level`: 16, 4x4 pixels, on AVX-512 and, in two
/// registers, on AVX2; the thesis's 2x2 otherwise; `samesign::occluded_segments`), as `trace::shadow_frusta`
/// groups a render's shadows (Benthin & Wald 2009).
fn count_visible_by_sample(
    tree: &KdTree,
    order: &[u32],
    samples: &[usize],
    ray: impl Fn(usize, usize) -> Option<(Vec3, Vec3)>,
    visible: &mut [u32],
) {
    let (mut starts, mut ends, mut slots, mut blocked) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let lanes = Width::for_level(SimdLevel::active());
    for &k in samples {
        starts.clear();
        ends.clear();
        slots.clear();
        for &i in order {
            if let Some((start, end)) = ray(i as usize, k) {
                starts.push(start);
                ends.push(end);
                slots.push(i as usize);
            }
        }
        packets::at_width!(lanes, V => samesign::occluded_segments::<V, _>(tree, &starts, &ends, &mut blocked, &mut NoCounters));
        for (&i, &b) in slots.iter().zip(&blocked) {
            visible[i] += u32::from(!b);
        }
    }
}

/// One method's result against the reference (one JSON object with `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct ShadowReport {
    /// Scene name.
    pub scene: String,
    /// Method name.
    pub method: String,
    /// Median frame time (primary rays, visibility, shading), milliseconds.
    pub ms_per_frame: f64,
    /// The median, over the rounds, of the frame time over that of a hard-shadow frame traced
    /// just before it (1 for hard shadows): the time against hard shadows, less exposed to a
    /// noisy machine than the ratio of two medians.
    pub per_hard: f64,
    /// Shadow rays per second over the median frame.
    pub shadow_rays_per_s: f64,
    /// RMSE of the visible fraction against the reference, over pixels with a hit.
    pub visibility_rmse: f64,
    /// Largest absolute visibility error.
    pub visibility_max_err: f64,
    /// PSNR of the visibility (peak 1), dB.
    pub psnr: f64,
    /// `interleaved-16` only: the discontinuity filter's bias, the RMSE of the filtered
    /// reference against the reference over the same pixels (`None` for other methods).
    pub filter_bias_rmse: Option<f64>,
    /// Whether the method is on the speed/error Pareto front of its scene.
    pub pareto: bool,
}

impl fmt::Display for ShadowReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:<16} {:<24} {:>9.2} ms {:>6.2}x hard {:>8.2} Mrays/s  rmse {:.4}  max {:.3}  psnr {:>6.2} dB{}",
            self.scene,
            self.method,
            self.ms_per_frame,
            self.per_hard,
            self.shadow_rays_per_s * 1e-6,
            self.visibility_rmse,
            self.visibility_max_err,
            self.psnr,
            if self.pareto { "  [pareto]" } else { "" }
        )?;
        match self.filter_bias_rmse {
            Some(b) => write!(f, "  (filter bias: rmse {b:.4} on the reference)"),
            None => Ok(()),
        }
    }
}

/// `(rmse, max abs, psnr)` of `a` against `b` over the pixels of `mask`.
pub fn masked_errors(a: &[f32], b: &[f32], mask: &[bool]) -> (f64, f64, f64) {
    let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
    for ((&x, &y), &m) in a.iter().zip(b).zip(mask) {
        if m {
            let e = f64::from(x) - f64::from(y);
            sum += e * e;
            max = max.max(e.abs());
            n += 1;
        }
    }
    let mse = if n == 0 { 0.0 } else { sum / n as f64 };
    (mse.sqrt(), max, if mse > 0.0 { -10.0 * mse.log10() } else { f64::INFINITY })
}

/// Marks the reports on the Pareto front: no other method is as fast and as accurate, and
/// strictly better in one.
pub fn mark_pareto(reports: &mut [ShadowReport]) {
    let points: Vec<(f64, f64)> = reports.iter().map(|r| (r.ms_per_frame, r.visibility_rmse)).collect();
    for (i, r) in reports.iter_mut().enumerate() {
        let (t, e) = points[i];
        r.pareto = !points.iter().enumerate().any(|(j, &(tj, ej))| j != i && tj <= t && ej <= e && (tj < t || ej < e));
    }
}

/// 64-bit FNV-1a.
fn fnv(bytes: impl IntoIterator<Item = u8>, mut h: u64) -> u64 {
    for b in bytes {
        h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// The cache file of a reference: keyed by the scene (name and a hash of its geometry), the
/// camera, the image size, the light, the sample count and the intersector; a `.key` file
/// beside it holds the full key, checked on load, so any change recomputes it. The key's
/// version names the reference's own inputs: `v2` from the frames' MFT primary hits
/// ([`ShadowSetup::primary_pass`]; `v1`, single rays', differed on coincident faces).
pub fn reference_cache_path(
    dir: &Path,
    scene: &Scene,
    camera: &Camera,
    light: &AreaLight,
    samples: u32,
    tree: &KdTree,
) -> (PathBuf, String) {
    let geometry =
        fnv(scene.mesh.positions.iter().flat_map(|p| p.to_array()).flat_map(f32::to_le_bytes), 0xcbf2_9ce4_8422_2325);
    let geometry = fnv(scene.mesh.triangles.iter().flatten().flat_map(|i| i.to_le_bytes()), geometry);
    let key = format!(
        "v2 scene={} geometry={geometry:016x} camera={:?} size={}x{} light={light:?} samples={samples} intersector={}",
        scene.name,
        (camera.pixel_ray(0, 0), camera.pixel_ray(camera.width - 1, camera.height - 1)),
        camera.width,
        camera.height,
        tree.intersector().name()
    );
    let hash = fnv(key.bytes(), 0xcbf2_9ce4_8422_2325);
    let safe: String =
        scene.name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect();
    (dir.join(format!("{safe}-{hash:016x}.pfm")), key)
}

/// The reference visibility of `setup`, from the cache when its key matches (then `true`),
/// else computed and stored; and the cache file.
fn cached_reference(setup: &ShadowSetup, dir: &Path, samples: u32) -> Result<(Vec<f32>, bool, PathBuf), Error> {
    let (path, key) = reference_cache_path(dir, setup.scene, &setup.camera, &setup.light, samples, setup.tree);
    let key_path = path.with_extension("key");
    if std::fs::read_to_string(&key_path).is_ok_and(|k| k == key)
        && let Ok(img) = scenes::ScalarImage::load_pfm(&path)
        && img.values.len() == setup.layout.pixel_count()
    {
        return Ok((img.values, true, path));
    }
    let values = setup.reference(samples);
    std::fs::create_dir_all(dir).map_err(|e| Error::File { path: dir.to_path_buf(), message: e.to_string() })?;
    scenes::ScalarImage { width: setup.camera.width, height: setup.camera.height, values: values.clone() }
        .save_pfm(&path)?;
    std::fs::write(&key_path, &key).map_err(|e| Error::File { path: key_path.clone(), message: e.to_string() })?;
    Ok((values, false, path))
}

/// The `analytic` scene: a unit sphere (icosphere, 5 subdivisions) 2 above a floor slab,
/// under a spherical light of radius 1 at height 8; returns the scene, the light, the
/// sphere (centre, radius) and the floor's material id.
pub fn analytic_scene() -> (Scene, AreaLight, (Vec3, f32), u32) {
    let mut b = MeshBuilder::new();
    let ball = b.material("sphere", Vec3::new(0.8, 0.6, 0.3));
    let floor = b.material("floor", Vec3::splat(0.7));
    let sphere = (Vec3::new(0.0, 2.0, 0.0), 1.0);
    b.add(&Part::icosphere(sphere.1, 5).translated(sphere.0), ball);
    b.add_box(Vec3::new(-12.0, -1.0, -12.0), Vec3::new(12.0, 0.0, 12.0), floor);
    let mut scene = Scene::from_mesh("analytic", b.finish());
    scene.views = vec![View {
        name: "default".into(),
        eye: Vec3::new(0.0, 9.0, 9.0),
        target: Vec3::new(0.5, 0.0, 0.0),
        fovy_deg: 45.0,
    }];
    let light =
        AreaLight::Sphere(SphereLight { center: Vec3::new(1.2, 8.0, 0.0), radius: 1.0, intensity: Vec3::splat(60.0) });
    (scene, light, sphere, floor)
}

/// Per-triangle thickness scales from `NAME=SCALE` arguments (materials whose name contains
/// `NAME`), or `None` when none are given.
pub fn thickness_scales(scene: &Scene, specs: &[String]) -> Result<Option<Vec<f32>>, Error> {
    if specs.is_empty() {
        return Ok(None);
    }
    let mut per_material = vec![1.0f32; scene.mesh.materials.len()];
    for spec in specs {
        let (name, scale) = parse_thickness(spec)?;
        for (m, material) in scene.mesh.materials.iter().enumerate() {
            if material.name.contains(name) {
                per_material[m] = scale;
            }
        }
    }
    Ok(Some(scene.mesh.material_ids.iter().map(|&m| per_material.get(m as usize).copied().unwrap_or(1.0)).collect()))
}

/// One `--thickness NAME=SCALE`: the name and a finite scale > 0 (NaN, infinities and
/// non-numbers are usage errors naming the argument).
fn parse_thickness(spec: &str) -> Result<(&str, f32), Error> {
    let (name, scale) =
        spec.split_once('=').ok_or_else(|| Error::Usage(format!("--thickness '{spec}': expected NAME=SCALE")))?;
    let scale: f32 = scale
        .trim()
        .parse()
        .ok()
        .filter(|s: &f32| s.is_finite() && *s > 0.0)
        .ok_or_else(|| Error::Usage(format!("--thickness '{spec}': the scale must be a finite number > 0")))?;
    Ok((name, scale))
}

/// The light of `light` and `light_size` for `scene`.
fn chosen_light(scene: &Scene, config: &ShadowsConfig) -> AreaLight {
    let rect = AreaLight::Rect(scene.area_light);
    let base = match config.light {
        LightKind::Rect => rect,
        LightKind::Sphere => AreaLight::Sphere(SphereLight {
            center: rect.center(),
            radius: rect.radius(),
            intensity: scene.area_light.intensity,
        }),
    };
    base.scaled(config.light_size)
}

/// The comparison's report: every scene's rows and files.
#[derive(Clone, Debug)]
pub struct ShadowsReport {
    /// The scenes, in the order measured.
    pub scenes: Vec<SceneShadows>,
}

impl ShadowsReport {
    /// Every row, scene by scene, each scene's in [`METHODS`] order (the JSON objects of
    /// `rttest shadows --json`, in order).
    pub fn rows(&self) -> impl Iterator<Item = &ShadowReport> {
        self.scenes.iter().flat_map(|s| &s.rows)
    }
}

/// One line per row ([`ShadowReport`]'s text), each ending with a newline.
impl fmt::Display for ShadowsReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.scenes.iter().try_for_each(|s| write!(f, "{s}"))
    }
}

/// One scene of the comparison: its rows and the files written for it.
#[derive(Clone, Debug)]
pub struct SceneShadows {
    /// The scene's name.
    pub scene: String,
    /// One row per method, in [`METHODS`] order.
    pub rows: Vec<ShadowReport>,
    /// The folder of its images, CSV and plot (`out_dir/<scene name>`).
    pub dir: PathBuf,
    /// The files written there: `reference.png`, then per method `<method>.png` and
    /// `error-<method>.png`, then `filtered-reference.png` and its error
    /// `error-filtered-reference.png` (the filter's bias), `strip.png`, `shadows.csv`,
    /// `pareto.svg` and `pareto.png`.
    pub files: Vec<PathBuf>,
    /// The reference's cache file (see [`reference_cache_path`]).
    pub reference: PathBuf,
    /// Whether the reference came from the cache (false: computed and stored there).
    pub reference_cached: bool,
}

/// One line per row ([`ShadowReport`]'s text), each ending with a newline.
impl fmt::Display for SceneShadows {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.rows.iter().try_for_each(|r| writeln!(f, "{r}"))
    }
}

/// The soft-shadow comparison: [`ShadowsConfig::validate`], then [`run_scene`] for every
/// scene of [`ShadowsConfig::scene_list`], on the rayon pool of the caller.
pub fn run(config: &ShadowsConfig, progress: &dyn Progress) -> Result<ShadowsReport, Error> {
    config.validate()?;
    let scenes =
        config.scene_list().iter().map(|spec| run_scene(config, spec, progress)).collect::<Result<Vec<_>, _>>()?;
    Ok(ShadowsReport { scenes })
}

/// One scene of the comparison (`spec`: a built-in name, `analytic` or an OBJ path): builds
/// its tree, takes the reference from the cache or computes it, times the chosen methods
/// ([`ShadowsConfig::method_list`]) over
/// `config.frames` interleaved frames (the median of each), measures their errors against
/// the reference, marks the Pareto front and writes the images, error images, strip, CSV
/// and plot into `out_dir/<scene name>`. Does not call [`ShadowsConfig::validate`]: `run`
/// does, once, before the first scene.
pub fn run_scene(config: &ShadowsConfig, spec: &str, progress: &dyn Progress) -> Result<SceneShadows, Error> {
    let methods = config.method_list()?;
    let cache_dir = config.cache_dir();
    let (scene, light, analytic) = if spec == "analytic" {
        let (scene, light, sphere, floor) = analytic_scene();
        let light = light.scaled(config.light_size);
        (scene, light, Some((sphere, floor)))
    } else {
        let scene = scenes::load_scene(spec)?;
        let light = chosen_light(&scene, config);
        (scene, light, None)
    };
    let build = BuildConfig { intersector: config.intersector, ..BuildConfig::default() };
    let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &build)?;
    let (camera, _) = trace::setup::view_camera(&scene, config.view.as_deref(), config.size.0, config.size.1)?;
    let thickness = thickness_scales(&scene, &config.thickness)?;
    let setup = ShadowSetup::new(&scene, &tree, camera, light)?.with_edge_options(
        config.edge_scale,
        config.shared_vertex,
        thickness,
    );
    let task = progress.task(&format!("shadows: {} reference", scene.name), None);
    let (mut reference, reference_cached, reference_path) = cached_reference(&setup, &cache_dir, config.ref_samples)?;
    task.finish();

    // Frames, interleaved across methods; the median time of each. Every other method's frame
    // follows a hard-shadow frame of its own, and the median of their ratios is its time
    // against hard shadows': two frames a few milliseconds apart share the machine's state,
    // where the medians of two methods a round apart move with its noise.
    let task =
        progress.task(&format!("shadows: {}", scene.name), Some(u64::from(config.frames) * methods.len() as u64));
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); methods.len()];
    let mut per_hard: Vec<Vec<f64>> = vec![Vec::new(); methods.len()];
    let mut frames: Vec<Option<ShadowFrame>> = methods.iter().map(|_| None).collect();
    for _ in 0..config.frames {
        for (i, &m) in methods.iter().enumerate() {
            let hard = (m != ShadowMethod::Hard).then(|| setup.frame(ShadowMethod::Hard).secs);
            let f = setup.frame(m);
            times[i].push(f.secs);
            per_hard[i].push(hard.map_or(1.0, |h| f.secs / h));
            frames[i] = Some(f);
            task.inc();
        }
    }
    task.finish();
    let frames: Vec<ShadowFrame> = frames.into_iter().flatten().collect();
    let hits = &frames[0].hits;
    let mut mask: Vec<bool> = hits.iter().map(Option::is_some).collect();
    if let Some(((center, radius), floor)) = analytic {
        // The floor's pixels: the closed form, and only those count.
        for (i, hit) in hits.iter().enumerate() {
            let on_floor = hit.is_some_and(|h| scene.mesh.material_ids[h.prim as usize] == floor);
            mask[i] = on_floor;
            if let (true, Some(h)) = (on_floor, hit) {
                let p = kdtree::ray::surface_point(&tree.triangle(h.prim), h);
                reference[i] = sphere_visible_fraction(p, light.center(), light.radius(), center, radius) as f32;
            }
        }
    }
    let filtered_reference = setup.filtered(hits, &reference);
    let filter_bias = masked_errors(&filtered_reference, &reference, &mask).0;
    let mut rows: Vec<ShadowReport> = methods
        .iter()
        .zip(&frames)
        .zip(times.iter().zip(&per_hard))
        .map(|((m, f), (t, per_hard))| {
            let secs = median(t);
            let (rmse, max, psnr) = masked_errors(&f.visibility, &reference, &mask);
            ShadowReport {
                scene: scene.name.clone(),
                method: m.name(),
                ms_per_frame: secs * 1e3,
                per_hard: median(per_hard),
                shadow_rays_per_s: f.shadow_rays as f64 / secs,
                visibility_rmse: rmse,
                visibility_max_err: max,
                psnr,
                filter_bias_rmse: (*m == ShadowMethod::Interleaved).then_some(filter_bias),
                pareto: false,
            }
        })
        .collect();
    mark_pareto(&mut rows);
    let dir = config.out_dir.join(&scene.name);
    let files = write_outputs(&dir, &setup, &frames, &reference, &filtered_reference, &mask, &rows)?;
    Ok(SceneShadows { scene: scene.name.clone(), rows, dir, files, reference: reference_path, reference_cached })
}

/// The upper median of `v` (the middle element, or the upper of the two middle ones), as
/// `rttest shadows` and Table 5.1 report it. `v` must not be empty.
pub(crate) fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |e| Error::File { path: path.to_path_buf(), message: e.to_string() }
}

/// Images, strip, error images, CSV and the plot of one scene; returns the files written.
fn write_outputs(
    dir: &Path,
    setup: &ShadowSetup,
    frames: &[ShadowFrame],
    reference: &[f32],
    filtered_reference: &[f32],
    mask: &[bool],
    reports: &[ShadowReport],
) -> Result<Vec<PathBuf>, Error> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let (w, h) = (setup.camera.width, setup.camera.height);
    let ref_image = setup.shade(&frames[0].hits, reference);
    let mut files = Vec::new();
    let mut save = |img: &Image, name: String| -> Result<(), Error> {
        let path = dir.join(name);
        img.save_png(&path)?;
        files.push(path);
        Ok(())
    };
    save(&ref_image, "reference.png".into())?;
    let error_image = |vis: &[f32]| Image {
        width: w,
        height: h,
        pixels: vis
            .iter()
            .zip(reference)
            .zip(mask)
            .map(|((a, b), &m)| if m { Vec3::splat(4.0 * (a - b).abs()) } else { Vec3::new(0.15, 0.0, 0.0) })
            .collect(),
    };
    // The strip: reference then each method, then the filtered reference; below, each one's
    // |error| x 4 (red: off the measured pixels).
    let mut strip = Image::new(w * (frames.len() as u32 + 2), 2 * h);
    let mut put = |col: u32, row: u32, img: &Image| {
        for y in 0..h {
            for x in 0..w {
                strip.set(col * w + x, row * h + y, img.get(x, y));
            }
        }
    };
    put(0, 0, &ref_image);
    for (i, (f, r)) in frames.iter().zip(reports).enumerate() {
        save(&f.image, format!("{}.png", r.method))?;
        let err = error_image(&f.visibility);
        save(&err, format!("error-{}.png", r.method))?;
        put(i as u32 + 1, 0, &f.image);
        put(i as u32 + 1, 1, &err);
    }
    let filtered = setup.shade(&frames[0].hits, filtered_reference);
    let err = error_image(filtered_reference);
    save(&filtered, "filtered-reference.png".into())?;
    save(&err, "error-filtered-reference.png".into())?;
    put(frames.len() as u32 + 1, 0, &filtered);
    put(frames.len() as u32 + 1, 1, &err);
    save(&strip, "strip.png".into())?;
    let mut csv = String::from(
        "scene,method,ms_per_frame,per_hard,shadow_rays_per_s,visibility_rmse,visibility_max_err,psnr,pareto,filter_bias_rmse\n",
    );
    for r in reports {
        csv += &format!(
            "{},{},{:.3},{:.4},{:.0},{:.6},{:.6},{:.3},{},{}\n",
            r.scene,
            r.method,
            r.ms_per_frame,
            r.per_hard,
            r.shadow_rays_per_s,
            r.visibility_rmse,
            r.visibility_max_err,
            r.psnr,
            r.pareto,
            r.filter_bias_rmse.map_or(String::new(), |b| format!("{b:.6}"))
        );
    }
    let csv_path = dir.join("shadows.csv");
    std::fs::write(&csv_path, csv).map_err(io(&csv_path))?;
    files.push(csv_path);
    let points: Vec<Point> = reports
        .iter()
        .map(|r| Point {
            scene: r.scene.clone(),
            method: r.method.clone(),
            ms_per_frame: r.ms_per_frame,
            visibility_rmse: r.visibility_rmse,
            pareto: r.pareto,
        })
        .collect();
    files.extend(plot(dir, &points)?);
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pareto_front_keeps_the_undominated() {
        let r = |m: &str, t: f64, e: f64| ShadowReport {
            scene: "s".into(),
            method: m.into(),
            ms_per_frame: t,
            per_hard: t,
            shadow_rays_per_s: 0.0,
            visibility_rmse: e,
            visibility_max_err: 0.0,
            psnr: 0.0,
            filter_bias_rmse: None,
            pareto: false,
        };
        let mut v = vec![r("a", 1.0, 0.5), r("b", 2.0, 0.2), r("c", 3.0, 0.3), r("d", 4.0, 0.1)];
        mark_pareto(&mut v);
        assert_eq!(v.iter().map(|r| r.pareto).collect::<Vec<_>>(), [true, true, false, true]);
    }

    #[test]
    fn edge_width_packet_frame_equals_single_rays_and_the_reference_cache_is_keyed() {
        let scene = scenes::load_scene("touching-boxes").unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let camera = scene.default_view().camera(40, 30).unwrap();
        let light = AreaLight::Rect(scene.area_light).scaled(2.0);
        let setup = ShadowSetup::new(&scene, &tree, camera, light).unwrap();
        let single = setup.frame(ShadowMethod::EdgeWidth);
        let packet = setup.frame(ShadowMethod::EdgeWidthPacket);
        assert_eq!(single.visibility, packet.visibility);
        assert!(single.visibility.iter().any(|&v| v > 0.0 && v < 1.0), "a penumbra");
        let dir = std::env::temp_dir().join(format!("rttest-shadow-cache-{}", std::process::id()));
        let (a, cached, path) = cached_reference(&setup, &dir, 4).unwrap();
        assert!(!cached && path.is_file());
        let (b, cached, same) = cached_reference(&setup, &dir, 4).unwrap();
        assert!(cached && a == b && same == path);
        // A different light or sample count is a different entry.
        let other = ShadowSetup::new(&scene, &tree, camera, light.scaled(0.5)).unwrap();
        assert!(!cached_reference(&other, &dir, 4).unwrap().1);
        assert!(!cached_reference(&setup, &dir, 8).unwrap().1);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A 24x16 run of `frames` frames against a 4-sample reference, its files under `dir`.
    fn small_run(dir: &Path, frames: u32) -> ShadowsConfig {
        ShadowsConfig {
            size: (24, 16),
            ref_samples: 4,
            frames,
            cache_dir: Some(dir.join("cache")),
            out_dir: dir.join("out"),
            ..ShadowsConfig::default()
        }
    }

    /// A whole scene's run: every method's row, hard shadows' time against its own 1, the
    /// others' against the hard frames traced beside theirs, and the CSV with that column.
    #[test]
    fn a_scene_reports_each_method_against_hard_shadows() {
        let dir = std::env::temp_dir().join(format!("rttest-shadows-run-{}", std::process::id()));
        let config = small_run(&dir, 3);
        let run = run_scene(&config, "touching-boxes", &trace::progress::Quiet).unwrap();
        assert_eq!(run.rows.len(), METHODS.len());
        for row in &run.rows {
            assert!(row.per_hard.is_finite() && row.per_hard > 0.0, "{row}");
            assert!(row.method != "hard" || row.per_hard == 1.0, "{row}");
            assert!(row.to_string().contains("x hard"), "{row}");
        }
        let csv = std::fs::read_to_string(run.dir.join("shadows.csv")).unwrap();
        assert!(csv.starts_with("scene,method,ms_per_frame,per_hard,") && csv.contains(",hard,"), "{csv}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Runs `test` on `touching-boxes` at 40x30 under its light scaled by 2 (penumbrae on
    /// the boxes and the floor), once per triangle test.
    fn on_touching_boxes(test: impl Fn(&ShadowSetup)) {
        let scene = scenes::load_scene("touching-boxes").unwrap();
        for intersector in [Intersector::Wald, Intersector::Watertight] {
            let config = BuildConfig { intersector, ..BuildConfig::default() };
            let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &config).unwrap();
            let camera = scene.default_view().camera(40, 30).unwrap();
            test(&ShadowSetup::new(&scene, &tree, camera, AreaLight::Rect(scene.area_light).scaled(2.0)).unwrap());
        }
    }

    /// The frames' primary pass (MFT packets) names each pixel's single-ray hit, with both
    /// triangle tests, and the frame reports it row-major.
    #[test]
    fn the_primary_pass_gives_the_single_rays_hits() {
        on_touching_boxes(|setup| {
            let frame = setup.frame(ShadowMethod::Hard);
            let (w, h) = (setup.camera.width, setup.camera.height);
            let mut hits = 0;
            for y in 0..h {
                for x in 0..w {
                    let single = setup.tree.intersect(&trace::method::primary_ray(&setup.camera, x, y));
                    assert_eq!(frame.hits[(y * w + x) as usize], single, "pixel ({x}, {y})");
                    hits += usize::from(single.is_some());
                }
            }
            assert!(hits > (w * h / 2) as usize, "{hits} hits");
        });
    }

    #[test]
    fn silhouette_frames_beat_hard_shadows_with_one_to_five_rays_a_hit() {
        on_touching_boxes(|setup| {
            let hard = setup.frame(ShadowMethod::Hard);
            let ours = setup.frame(ShadowMethod::Silhouette);
            assert_eq!(hard.hits, ours.hits);
            let reference = setup.reference(256);
            let mask: Vec<bool> = ours.hits.iter().map(Option::is_some).collect();
            let (rmse, _, _) = masked_errors(&ours.visibility, &reference, &mask);
            let (hard_rmse, _, _) = masked_errors(&hard.visibility, &reference, &mask);
            assert!(rmse < 0.5 * hard_rmse, "{rmse} against hard {hard_rmse}");
            assert!(ours.visibility.iter().any(|&v| v > 0.0 && v < 0.5), "the dark half of a penumbra");
            assert!(ours.visibility.iter().any(|&v| v > 0.5 && v < 1.0), "the lit half of a penumbra");
            let hits = ours.hits.iter().flatten().count() as u64;
            assert!(
                ours.shadow_rays >= hits / 2 && ours.shadow_rays <= 5 * hits,
                "{} rays, {hits} hits",
                ours.shadow_rays
            );
        });
    }

    #[test]
    fn sampled_packets_and_lanes_give_the_sampled_frame() {
        on_touching_boxes(|setup| {
            let hard = setup.frame(ShadowMethod::Hard);
            let packets = setup.frame(ShadowMethod::HardPackets);
            assert_eq!(hard.visibility, packets.visibility);
            assert_eq!(hard.shadow_rays, packets.shadow_rays);
            assert!(hard.visibility.contains(&0.0) && hard.visibility.contains(&1.0));
            let single = setup.frame(ShadowMethod::Sampled(4));
            let packets = setup.frame(ShadowMethod::SampledPackets(4));
            assert_eq!(single.visibility, packets.visibility);
            let single = setup.frame(ShadowMethod::Sampled(16));
            let packets = setup.frame(ShadowMethod::SampledPackets(16));
            assert_eq!(single.visibility, packets.visibility);
            assert_eq!(single.shadow_rays, packets.shadow_rays);
            let lanes = setup.frame(ShadowMethod::SampledLanes(16));
            assert_eq!(single.visibility, lanes.visibility);
            assert_eq!(single.shadow_rays, lanes.shadow_rays);
            assert!(single.visibility.iter().any(|&v| v > 0.0 && v < 1.0), "a penumbra");
        });
    }

    #[test]
    fn adaptive_frames_are_sampled_16_but_on_unrefined_pixels_whose_16_samples_disagree() {
        on_touching_boxes(|setup| {
            let sampled = setup.frame(ShadowMethod::Sampled(16));
            let adaptive = setup.frame(ShadowMethod::Adaptive);
            assert_eq!(sampled.hits, adaptive.hits);
            let (mut penumbra, mut differ) = (0, 0);
            for (&a, &s) in adaptive.visibility.iter().zip(&sampled.visibility) {
                // Refined pixels are sampled-16's; others keep their probes' 0 or 1, which is
                // sampled-16's wherever its 16 samples agree.
                assert!(a == s || ((a == 0.0 || a == 1.0) && s > 0.0 && s < 1.0), "{a} against {s}");
                penumbra += usize::from(a == s && s > 0.0 && s < 1.0);
                differ += usize::from(a != s);
            }
            assert!(penumbra > 20, "a refined penumbra: {penumbra} pixels");
            assert!(differ * 50 < penumbra, "{differ} pixels missed");
            let hits = adaptive.hits.iter().flatten().count() as u64;
            let refined = (adaptive.shadow_rays - 4 * hits) / 12;
            assert_eq!(adaptive.shadow_rays, 4 * hits + 12 * refined);
            assert!(refined > 0 && refined < hits / 2, "{refined} of {hits} refined");
            assert_eq!(sampled.shadow_rays, 16 * hits);
        });
    }

    #[test]
    fn interleaved_frames_are_the_raw_ones_filtered_and_lanes_give_the_raw_ones() {
        let scene = scenes::load_scene("touching-boxes").unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &BuildConfig::default()).unwrap();
        let camera = scene.default_view().camera(40, 30).unwrap();
        let setup = ShadowSetup::new(&scene, &tree, camera, AreaLight::Rect(scene.area_light).scaled(2.0)).unwrap();
        let raw = setup.frame(ShadowMethod::InterleavedRaw);
        let filtered = setup.frame(ShadowMethod::Interleaved);
        assert_eq!(raw.shadow_rays, filtered.shadow_rays);
        assert_eq!(raw.shadow_rays, 16 * raw.hits.iter().flatten().count() as u64);
        assert_eq!(setup.filtered(&raw.hits, &raw.visibility), filtered.visibility);
        assert_ne!(raw.visibility, filtered.visibility, "the filter changes something here");
        // The same rays as frusta in SIMD lanes: the raw image, bit for bit.
        let lanes = setup.frame(ShadowMethod::InterleavedLanes);
        assert_eq!((lanes.visibility, lanes.shadow_rays), (raw.visibility, raw.shadow_rays));
    }

    #[test]
    fn bad_thickness_and_light_size_are_usage_errors() {
        let scene = scenes::load_scene("cube").unwrap();
        assert!(thickness_scales(&scene, &["cube".into()]).is_err());
        for bad in ["cube=nan", "cube=inf", "cube=-inf", "cube=1e39", "cube=NaN"] {
            let e = thickness_scales(&scene, &[bad.into()]).unwrap_err().to_string();
            assert!(e.contains(bad) && e.contains("finite"), "{e}");
        }
        assert!(thickness_scales(&scene, &["cube=-1".into()]).is_err());
        let t = thickness_scales(&scene, &["cube=3".into()]).unwrap().unwrap();
        assert!(t.iter().all(|&s| s == 3.0));
        // The config is checked before any scene is loaded.
        assert!(ShadowsConfig::default().validate().is_ok());
        for light_size in [f32::NAN, f32::INFINITY, 0.0, -1.0] {
            let e = ShadowsConfig { light_size, ..ShadowsConfig::default() }.validate().unwrap_err().to_string();
            assert!(e.starts_with("--light-size") && e.contains("finite"), "{e}");
        }
        for edge_scale in [f32::NAN, f32::NEG_INFINITY, -0.5] {
            let e = ShadowsConfig { edge_scale, ..ShadowsConfig::default() }.validate().unwrap_err().to_string();
            assert!(e.starts_with("--edge-scale") && e.contains("finite"), "{e}");
        }
        let bad = ShadowsConfig { thickness: vec!["cube=nan".into()], ..ShadowsConfig::default() };
        assert!(bad.validate().unwrap_err().to_string().contains("cube=nan"));
        let bad = ShadowsConfig { methods: vec!["hard".into(), "sampled-5".into()], ..ShadowsConfig::default() };
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.starts_with("--methods") && e.contains("'sampled-5'") && e.contains("sampled-4-packets"), "{e}");
    }

    /// `methods` picks rows, reported in [`METHODS`] order whatever order they are named in.
    #[test]
    fn the_chosen_methods_are_the_rows() {
        let all = ShadowsConfig::default().method_list().unwrap();
        assert_eq!(all, METHODS);
        let names = vec!["sampled-4".into(), "hard".into()];
        let some = ShadowsConfig { methods: names, ..ShadowsConfig::default() }.method_list().unwrap();
        assert_eq!(some, [ShadowMethod::Hard, ShadowMethod::Sampled(4)]);
        let dir = std::env::temp_dir().join(format!("rttest-shadows-methods-{}", std::process::id()));
        let config = ShadowsConfig { methods: vec!["edge-width-convolution".into()], ..small_run(&dir, 1) };
        let run = run_scene(&config, "touching-boxes", &trace::progress::Quiet).unwrap();
        let rows: Vec<&str> = run.rows.iter().map(|r| r.method.as_str()).collect();
        assert_eq!(rows, ["edge-width-convolution"]);
        assert!(run.rows[0].per_hard.is_finite() && run.rows[0].per_hard > 0.0);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_default_scenes_are_the_experiments_with_analytic_after_the_built_in_ones() {
        let list = ShadowsConfig::default().scene_list();
        let mut expected = trace::setup::default_scenes();
        expected.insert(4, "analytic".into());
        assert_eq!(list, expected);
        assert_eq!(list[..5], ["atrium", "arena", "atrium-rotated", "grove", "analytic"]);
        let named = ShadowsConfig { scenes: vec!["cube".into()], ..ShadowsConfig::default() };
        assert_eq!(named.scene_list(), ["cube"]);
    }
}
