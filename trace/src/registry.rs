//! The one method registry: a name (`mono`, `mft-16`, `embree-8`, ...) gives a method.
//!
//! The model is pbrt-v4's `CreateAccelerator`: every place that takes a method by name
//! (`rttest render --method`, `rttest compare --methods`, the tables, the benches, the
//! conformance test) asks the registry, and the same registry lists the names for `--help`
//! and error messages. Adding a method is its own module plus one [`Entry`] line in
//! [`Registry::ours`] (or in `baselines::register` for another tracer).
//!
//! An entry names the structure it traces: our kd-tree ([`KDTREE`]), built by the caller
//! with its `kdtree::BuildConfig`, or a structure of its own (Embree's BVHs, a BVH crate's),
//! built by a [`StructureEntry`] of the registry so that `rttest compare` can time every
//! build alike.

use std::any::Any;

use kdtree::KdTree;
use packets::{LaneWidth, TileMethod};
use scenes::Scene;

use crate::Error;
use crate::frame::{Driven, FrameTracer};
use crate::method::SingleRays;
use crate::multibvh;
use crate::ours::{Kernel, TileShadows, Tiled};

/// The name of our kd-tree as a structure.
pub const KDTREE: &str = "kdtree";

/// Default tile side: the unit of work of a thread, and the frustum of the tiled methods.
pub const TILE_SIZE: u32 = 16;

/// How a method is bound to its structure: tile size, packet/leaf culling, soft-shadow
/// grouping and the SIMD lanes of `lane-frusta`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Options {
    /// Tile side: the frame driver's unit of work, and the frustum (or cone) of the tiled
    /// methods (a multiple of 4 in `4..=64` for the packet methods).
    pub tile: u32,
    /// Packet/leaf culling (thesis 4.1.4), for the frustum and cone methods.
    pub culling: bool,
    /// How the tiled methods group their 16-sample soft-shadow rays.
    pub soft: SoftGrouping,
    /// How many shadow frusta `lane-frusta` traces at once (`packets::lane_frusta`): by
    /// default the widest this CPU runs natively ([`LaneWidth::widest`]).
    pub lanes: LaneWidth,
}

impl Default for Options {
    fn default() -> Self {
        Options { tile: TILE_SIZE, culling: true, soft: SoftGrouping::Strata, lanes: LaneWidth::widest() }
    }
}

/// How a tiled method of ours traces the 16 soft-shadow rays of its points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SoftGrouping {
    /// Each tile's rays to each light stratum together (Benthin & Wald 2009): as 2x2
    /// packets of neighbouring points' rays, or as shadow frusta for `multi-frusta`. The
    /// default: 1.3-1.5x single rays on Sponza, kitchen and atrium
    /// (`docs/results/coherent-shadows.md`).
    #[default]
    Strata,
    /// Each point's 16 rays on their own, under their pyramid (the packet, frustum and MFT
    /// kernels) or their cone (the cone kernels): the thesis's soft shadows (4.1.9, Table
    /// 4.6), slower than single rays on these scenes (0.3-0.9x).
    PerPoint,
}

/// The structures a frame's methods trace: our kd-tree, and the others built by the
/// registry's [`StructureEntry`]s.
pub struct Structures<'a> {
    kdtree: &'a KdTree,
    others: Vec<(&'static str, Box<dyn Any + Send + Sync>)>,
}

impl std::fmt::Debug for Structures<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names: Vec<&str> = self.others.iter().map(|o| o.0).collect();
        f.debug_struct("Structures").field("others", &names).finish_non_exhaustive()
    }
}

impl<'a> Structures<'a> {
    /// Our kd-tree alone.
    pub fn new(kdtree: &'a KdTree) -> Self {
        Structures { kdtree, others: Vec::new() }
    }

    /// Our kd-tree.
    pub fn kdtree(&self) -> &'a KdTree {
        self.kdtree
    }

    /// Adds (or replaces) the structure `name`.
    pub fn insert(&mut self, name: &'static str, built: Box<dyn Any + Send + Sync>) {
        self.others.retain(|o| o.0 != name);
        self.others.push((name, built));
    }

    /// Whether the structure `name` is there (our kd-tree always is).
    pub fn has(&self, name: &str) -> bool {
        name == KDTREE || self.others.iter().any(|o| o.0 == name)
    }

    /// The structure `name` as a `T`; an error when it was not built or is another type.
    pub fn get<T: 'static>(&self, name: &str) -> Result<&T, Error> {
        self.others
            .iter()
            .find(|o| o.0 == name)
            .and_then(|o| o.1.downcast_ref::<T>())
            .ok_or_else(|| Error::Usage(format!("structure '{name}' was not built")))
    }
}

/// Binds a method to the structures of a frame.
pub type Bind = for<'s> fn(&'s Structures<'_>, &Options) -> Result<Box<dyn FrameTracer + 's>, Error>;

/// Builds a structure of the registry for a scene.
pub type Build = fn(&Scene) -> Result<Box<dyn Any + Send + Sync>, Error>;

/// One registered method.
#[derive(Clone, Copy, Debug)]
pub struct Entry {
    /// Its name: `mono`, `mft`, `embree-8`, ... (tiled methods also answer to `NAME-TILE`).
    pub name: &'static str,
    /// Who made it: `ours`, `embree`, `bvh`, `obvhs`.
    pub family: &'static str,
    /// One line for `--help`, citing the thesis or paper.
    pub summary: &'static str,
    /// Whether the tile is part of the method (the frustum or cone of a tile): then the
    /// method has one name per tile size, `mft-8`, `mft-16`, ...
    pub tiled: bool,
    /// Whether the method traces primary rays as 2x2 packets (N and I are then counted per
    /// packet, single rays per 4 rays).
    pub packets: bool,
    /// The structure it traces: [`KDTREE`] or a [`StructureEntry`]'s name.
    pub structure: &'static str,
    /// Its hard-shadow kernel: methods sharing one are timed once (`rttest compare`). A name
    /// ending in `-N` is a kernel that takes the tile as its frustum: `N` stands for the tile
    /// size ([`Entry::shadow_kernel_for`]).
    pub shadow_kernel: &'static str,
    /// Its 16-sample soft-shadow kernel, shared like the hard-shadow one.
    pub soft_kernel: &'static str,
    /// Its soft-shadow kernel with [`SoftGrouping::PerPoint`], for the tiled methods of ours
    /// that have one; `None`: the option does not apply (selecting it is an error).
    pub per_point_soft_kernel: Option<&'static str>,
    /// Makes the method.
    pub bind: Bind,
}

impl Entry {
    /// The hard-shadow kernel's name with `options`: `kd-frusta-N` with 16-pixel tiles is
    /// `kd-frusta-16`; a name without `-N` is the same for every tile.
    pub fn shadow_kernel_for(&self, options: &Options) -> String {
        with_tile(self.shadow_kernel, options)
    }

    /// The soft-shadow kernel's name with `options`, as [`Entry::shadow_kernel_for`]: the
    /// per-point kernel with [`SoftGrouping::PerPoint`].
    pub fn soft_kernel_for(&self, options: &Options) -> String {
        match (options.soft, self.per_point_soft_kernel) {
            (SoftGrouping::PerPoint, Some(kernel)) => with_tile(kernel, options),
            _ => with_tile(self.soft_kernel, options),
        }
    }
}

/// `kernel` with a trailing `-N` replaced by the tile size of `options`.
fn with_tile(kernel: &str, options: &Options) -> String {
    match kernel.strip_suffix("-N") {
        Some(base) => format!("{base}-{}", options.tile),
        None => kernel.to_string(),
    }
}

/// A structure that methods of the registry trace, other than our kd-tree.
#[derive(Clone, Copy, Debug)]
pub struct StructureEntry {
    /// Its name, as methods name it.
    pub name: &'static str,
    /// Builds it.
    pub build: Build,
}

/// A method named and configured: an entry with its options and full name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Selected {
    /// The full name: `mono`, `mft-16`, `embree-8`.
    pub name: String,
    /// The entry's index in the registry.
    pub entry: usize,
    /// Tile and culling.
    pub options: Options,
}

/// A method bound to its structure, ready for the frame driver.
pub struct Bound<'s> {
    /// The full name: `mono`, `mft-16`, `embree-8`.
    pub name: String,
    /// The registry entry.
    pub entry: Entry,
    /// Tile and culling.
    pub options: Options,
    /// The passes.
    pub tracer: Box<dyn FrameTracer + 's>,
}

impl std::fmt::Debug for Bound<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bound").field("name", &self.name).field("options", &self.options).finish_non_exhaustive()
    }
}

/// The methods and structures this build knows.
#[derive(Clone, Debug, Default)]
pub struct Registry {
    entries: Vec<Entry>,
    structures: Vec<StructureEntry>,
}

impl Registry {
    /// Our methods: single rays, packets, frusta, MFT, cones (thesis 2.2.1, 4.1.2-4.1.9) on
    /// our kd-tree, and single rays on our 4- and 8-wide BVHs (`mbvh-4`, structure `mbvh`;
    /// `mbvh-8`, structure `mbvh8`).
    pub fn ours() -> Registry {
        let mut r = Registry::default();
        r.add(ours(
            "mono",
            "single rays, closest and any hit (thesis 2.2.1)",
            false,
            false,
            ("kd-single", "kd-single", None),
            |s, _| Ok(Box::new(Driven(SingleRays(s.kdtree())))),
        ));
        r.add(ours(
            "packet",
            "omni-directional 2x2 packets (thesis 4.1.2)",
            false,
            true,
            ("kd-packets", "kd-stratum-packets", Some("kd-pyramid")),
            |s, o| tiled(s, o, Kernel::Packets(TileMethod::Packet)),
        ));
        r.add(ours(
            "samesign",
            "same-sign 2x2 packets, split where signs differ (thesis 2.3.1)",
            false,
            true,
            ("kd-packets", "kd-stratum-packets", Some("kd-pyramid")),
            |s, o| tiled(s, o, Kernel::Packets(TileMethod::SameSign)),
        ));
        r.add(ours(
            "frustum",
            "one frustum per tile, packet/leaf culling (thesis 2.3.2, 4.1.3-4.1.4)",
            true,
            true,
            ("kd-packets", "kd-stratum-packets", Some("kd-pyramid")),
            |s, o| tiled(s, o, Kernel::Packets(TileMethod::Frustum)),
        ));
        r.add(ours(
            "mft",
            "Multiple Frustum Traversal, four quadrant frusta per tile (thesis 4.1.5)",
            true,
            true,
            ("kd-packets", "kd-stratum-packets", Some("kd-pyramid")),
            |s, o| tiled(s, o, Kernel::Packets(TileMethod::Mft)),
        ));
        r.add(ours(
            "multi-frusta",
            "MFT primaries; shadows as Benthin & Wald's (2009) frusta: one per tile, one per tile and light stratum",
            true,
            true,
            ("kd-frusta-N", "kd-multi-frusta-N", None),
            |s, o| {
                Ok(Box::new(Driven(
                    tiled_method(s, o, Kernel::Packets(TileMethod::Mft))?.with_shadows(TileShadows::Frusta),
                )))
            },
        ));
        r.add(ours(
            "lane-frusta",
            "MFT primaries; shadows as Benthin & Wald's (2009) multi-frusta in SIMD lanes: a 4x4 block's or a point's rays per frustum, 8 (AVX2) or 4 frusta at once",
            true,
            true,
            ("kd-lane-frusta", "kd-lane-frusta", None),
            |s, o| {
                Ok(Box::new(Driven(
                    tiled_method(s, o, Kernel::Packets(TileMethod::Mft))?.with_shadows(TileShadows::Lanes(o.lanes)),
                )))
            },
        ));
        r.add(ours(
            "cone",
            "one cone per tile as the proxy of its rays (thesis 4.1.6-4.1.8)",
            true,
            true,
            ("kd-packets", "kd-stratum-packets", Some("kd-cone")),
            |s, o| tiled(s, o, Kernel::Cones(cones::ConeMethod::Cone)),
        ));
        r.add(ours(
            "mft-cone",
            "four quadrant cones per tile (thesis 4.1.9)",
            true,
            true,
            ("kd-packets", "kd-stratum-packets", Some("kd-cone")),
            |s, o| tiled(s, o, Kernel::Cones(cones::ConeMethod::MftCone)),
        ));
        r.add_structure(StructureEntry { name: multibvh::MBVH, build: |scene| Ok(Box::new(multibvh::build(scene)?)) });
        r.add(Entry {
            name: "mbvh-4",
            family: "ours",
            summary: "4-wide BVH, single rays, SIMD over children and leaf triangles (Wald, Benthin & Boulos 2008)",
            tiled: false,
            packets: false,
            structure: multibvh::MBVH,
            shadow_kernel: "mbvh-4",
            soft_kernel: "mbvh-4",
            per_point_soft_kernel: None,
            bind: |s, _| multibvh::bind(s),
        });
        r.add_structure(StructureEntry {
            name: multibvh::MBVH8,
            build: |scene| Ok(Box::new(multibvh::build8(scene)?)),
        });
        r.add(Entry {
            name: "mbvh-8",
            family: "ours",
            summary: "8-wide BVH, single rays, AVX2 over children (chosen at run time), SIMD over leaf triangles (Wald, Benthin & Boulos 2008)",
            tiled: false,
            packets: false,
            structure: multibvh::MBVH8,
            shadow_kernel: "mbvh-8",
            soft_kernel: "mbvh-8",
            per_point_soft_kernel: None,
            bind: |s, _| multibvh::bind8(s),
        });
        r
    }

    /// Adds a method.
    pub fn add(&mut self, entry: Entry) {
        self.entries.push(entry);
    }

    /// Adds a structure that methods name.
    pub fn add_structure(&mut self, structure: StructureEntry) {
        self.structures.push(structure);
    }

    /// Builds every registered structure for `scene` into `structures`, so that every method
    /// binds (tests and tools that run every method; `rttest compare` builds only those its
    /// methods need, timed).
    pub fn build_structures(&self, scene: &Scene, structures: &mut Structures<'_>) -> Result<(), Error> {
        for s in &self.structures {
            structures.insert(s.name, (s.build)(scene)?);
        }
        Ok(())
    }

    /// Every entry, in registration order.
    pub fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// The entry at `index` (from a [`Selected`]).
    pub fn entry(&self, index: usize) -> Entry {
        self.entries[index]
    }

    /// The structure `name`, if registered.
    pub fn structure(&self, name: &str) -> Option<&StructureEntry> {
        self.structures.iter().find(|s| s.name == name)
    }

    /// Every full method name, in registration order, the tiled ones once per size of `tiles`.
    pub fn names(&self, tiles: &[u32]) -> Vec<String> {
        let mut out = Vec::new();
        for e in &self.entries {
            if e.tiled {
                out.extend(tiles.iter().map(|t| format!("{}-{t}", e.name)));
            } else {
                out.push(e.name.to_string());
            }
        }
        out
    }

    /// The base names, for `--help` and error messages (`mono, packet, ..., mft[-N], ...`).
    pub fn help(&self) -> String {
        let names: Vec<String> =
            self.entries.iter().map(|e| if e.tiled { format!("{}[-N]", e.name) } else { e.name.to_string() }).collect();
        names.join(", ")
    }

    /// The method `name`: an entry's name (tile from `options`) or, for a tiled method,
    /// `NAME-TILE` (e.g. `mft-16`). An unknown name is an error listing the known ones, and
    /// so is [`SoftGrouping::PerPoint`] for a method without a per-point kernel.
    pub fn select(&self, name: &str, options: Options) -> Result<Selected, Error> {
        let selected = self.select_name(name, options)?;
        let entry = &self.entries[selected.entry];
        if options.soft == SoftGrouping::PerPoint && entry.per_point_soft_kernel.is_none() {
            let with: Vec<&str> =
                self.entries.iter().filter(|e| e.per_point_soft_kernel.is_some()).map(|e| e.name).collect();
            return Err(Error::Usage(format!(
                "{}: no per-point soft-shadow kernel (methods with one: {})",
                selected.name,
                with.join(", ")
            )));
        }
        Ok(selected)
    }

    /// [`Registry::select`] without the soft-grouping check.
    fn select_name(&self, name: &str, options: Options) -> Result<Selected, Error> {
        let name = name.trim();
        if let Some(entry) = self.entries.iter().position(|e| e.name == name) {
            let e = &self.entries[entry];
            let full = if e.tiled { format!("{}-{}", e.name, options.tile) } else { e.name.to_string() };
            return Ok(Selected { name: full, entry, options });
        }
        if let Some((base, tile)) = name.rsplit_once('-')
            && let Ok(tile) = tile.parse::<u32>()
            && let Some(entry) = self.entries.iter().position(|e| e.tiled && e.name == base)
        {
            return Ok(Selected { name: name.to_string(), entry, options: Options { tile, ..options } });
        }
        Err(Error::Usage(format!("unknown method '{name}' (known: {})", self.help())))
    }

    /// Binds `selected` to `structures`. Fails when its structure was not built or its
    /// options do not fit it (a tile size a packet method cannot take).
    pub fn bind<'s>(&self, selected: &Selected, structures: &'s Structures<'_>) -> Result<Bound<'s>, Error> {
        let entry = self.entry(selected.entry);
        if !structures.has(entry.structure) {
            return Err(Error::Usage(format!("{}: structure '{}' was not built", selected.name, entry.structure)));
        }
        let tracer =
            (entry.bind)(structures, &selected.options).map_err(|e| Error::Usage(format!("{}: {e}", selected.name)))?;
        Ok(Bound { name: selected.name.clone(), entry, options: selected.options, tracer })
    }
}

/// An entry of ours on our kd-tree, with its hard- and soft-shadow kernels (and its
/// per-point soft-shadow kernel, if any).
fn ours(
    name: &'static str,
    summary: &'static str,
    tiled: bool,
    packets: bool,
    (shadow, soft, per_point_soft): (&'static str, &'static str, Option<&'static str>),
    bind: Bind,
) -> Entry {
    Entry {
        name,
        family: "ours",
        summary,
        tiled,
        packets,
        structure: KDTREE,
        shadow_kernel: shadow,
        soft_kernel: soft,
        per_point_soft_kernel: per_point_soft,
        bind,
    }
}

/// A tile kernel of ours bound to the kd-tree.
fn tiled<'s>(s: &'s Structures<'_>, o: &Options, kernel: Kernel) -> Result<Box<dyn FrameTracer + 's>, Error> {
    Ok(Box::new(Driven(tiled_method(s, o, kernel)?)))
}

/// The [`Tiled`] method of `kernel` on the kd-tree, with the tile, culling and soft-shadow
/// grouping of `o`.
fn tiled_method<'s>(s: &'s Structures<'_>, o: &Options, kernel: Kernel) -> Result<Tiled<'s>, Error> {
    let tiled = Tiled::new(s.kdtree(), kernel, o.tile, o.culling).map_err(|e| Error::Usage(format!("tile: {e}")))?;
    Ok(tiled.with_soft(o.soft))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_resolve_with_and_without_tiles() {
        let r = Registry::ours();
        let o = Options::default();
        assert_eq!(r.select("mft-8", o).unwrap().options.tile, 8);
        assert_eq!(r.select("mft-8", o).unwrap().name, "mft-8");
        assert_eq!(r.select("mft", o).unwrap().name, "mft-16");
        assert_eq!(r.select("mft-cone-16", o).unwrap().name, "mft-cone-16");
        assert_eq!(r.entry(r.select("mft-cone-16", o).unwrap().entry).name, "mft-cone");
        assert_eq!(r.select("mono", o).unwrap().name, "mono");
        assert!(r.select("mono-8", o).is_err());
        let e = r.select("nonsense", o).unwrap_err().to_string();
        assert!(e.contains("mft[-N]") && e.contains("mono"), "{e}");
        let names = r.names(&[8, 16]);
        assert_eq!(names[..3], ["mono", "packet", "samesign"]);
        assert!(names.contains(&"mft-cone-8".to_string()));
    }

    #[test]
    fn a_bad_tile_is_an_error_naming_the_method() {
        let scene = scenes::load_scene("cube").unwrap();
        let tree = KdTree::build(&scene.mesh.positions, &scene.mesh.triangles, &Default::default()).unwrap();
        let s = Structures::new(&tree);
        let r = Registry::ours();
        let bad = r.select("mft-6", Options::default()).unwrap();
        assert!(r.bind(&bad, &s).unwrap_err().to_string().starts_with("mft-6:"));
        let good = r.select("mono", Options { tile: 7, ..Options::default() }).unwrap();
        assert!(r.bind(&good, &s).is_ok());
    }

    #[test]
    fn per_point_soft_shadows_name_their_kernel_or_are_refused() {
        let r = Registry::ours();
        let per_point = Options { soft: SoftGrouping::PerPoint, ..Options::default() };
        for (method, strata, thesis) in [
            ("packet", "kd-stratum-packets", "kd-pyramid"),
            ("mft-8", "kd-stratum-packets", "kd-pyramid"),
            ("cone-16", "kd-stratum-packets", "kd-cone"),
        ] {
            let e = r.entry(r.select(method, Options::default()).unwrap().entry);
            assert_eq!(e.soft_kernel_for(&Options::default()), strata);
            assert_eq!(e.soft_kernel_for(&r.select(method, per_point).unwrap().options), thesis);
        }
        for method in ["mono", "multi-frusta-16", "mbvh-8"] {
            let e = r.select(method, per_point).unwrap_err().to_string();
            assert!(e.contains("no per-point") && e.contains("packet, samesign"), "{e}");
        }
    }
}
