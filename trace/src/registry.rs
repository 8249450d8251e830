//! The one method registry: a name (`mono`, `mft-16`, `embree-8`, ...) gives a method.
//!
//! The model is pbrt-v4's `CreateAccelerator`: every place that takes a method by name
//! (`rttest render --method`, `rttest compare --methods`, the tables, the benches, the viewer,
//! the conformance test) asks the registry, and the same registry lists the names and
//! summaries for `--help` and error messages. An [`Entry`] is one line: a method of ours
//! composes four typed kernels (`crate::kernel`, one per pass: primary, hard shadow, soft
//! shadow, stream), in `crate::ours`; another tracer registers a whole [`Method`] (crate
//! `baselines`). The catalogue is assembled in one place, `baselines::registry()`:
//! [`Registry::ours`] plus the baselines of the build.
//!
//! An entry names the structure it traces: our kd-tree ([`KDTREE`]), built by the caller
//! with its `kdtree::BuildConfig`, or a structure of its own (Embree's BVHs, a BVH crate's,
//! our 4- and 8-wide BVHs), built by a [`StructureEntry`] of the registry so that `rttest
//! compare` can time every build alike.

use std::any::Any;

use kdtree::KdTree;
use kdtree::isa::SimdLevel;
use packets::LaneWidth;
use scenes::Scene;

use crate::aov::Attribution;
use crate::error::Error;
pub use crate::frame::TILE_SIZE;
use crate::frame::{Driven, FrameTracer};
use crate::method::Method;

/// The name of our kd-tree as a structure.
pub const KDTREE: &str = "kdtree";

/// What a command asks of a method beyond its name. The frame driver reads the tile; every
/// other field is read by the one kernel that takes it, once, when the method is bound
/// (`crate::kernel::FromOptions`), and kept as that kernel's field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Options {
    /// Tile side: the frame driver's unit of work, and the frustum (or cone) of the tiled
    /// kernels (a multiple of 4 in `4..=64` for the packet kernels).
    pub tile: u32,
    /// Packet/leaf culling (thesis 4.1.4), for the frustum and cone kernels.
    pub culling: bool,
    /// Which of an entry's soft-shadow kernels is bound: its per-stratum one, or its
    /// per-point one ([`SoftGrouping::PerPoint`]; refused for an entry without one).
    pub soft: SoftGrouping,
    /// How many shadow frusta the lane kernels trace at once (`packets::lane_frusta`): by
    /// default the widest this CPU runs natively ([`LaneWidth::widest`]).
    pub lanes: LaneWidth,
    /// The widest SIMD level the kernels may bind to: by default the active one
    /// ([`SimdLevel::active`], the CPU's widest unless `--simd` caps it); a method named
    /// `NAME@LEVEL` (`mft-16@avx2`) sets it for that method alone. The packet kernels run
    /// 4 rays per instruction at `sse4.1` and 16 at `avx2` (two registers) and `avx512` (one)
    /// unless [`Options::packet_lanes`] asks for another width, and the other SIMD kernels
    /// (lane frusta, mbvh's node test) stay at or below it.
    pub simd: SimdLevel,
    /// Rays per packet instruction (4, 8 or 16) that a method named `NAME@wN` (`mft-16@w8`)
    /// asks its packet kernels for; `None`: the widest of its SIMD level
    /// ([`packets::Width::for_level`]). Resolved at bind by [`Options::packet_width`].
    pub packet_lanes: Option<usize>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            tile: TILE_SIZE,
            culling: true,
            soft: SoftGrouping::Strata,
            lanes: LaneWidth::widest(),
            simd: SimdLevel::active(),
            packet_lanes: None,
        }
    }
}

impl Options {
    /// The width of the packet kernels: [`Options::packet_lanes`] at [`Options::simd`]
    /// ([`packets::Width::at_level`]: 16 lanes in one AVX-512 register or in two AVX2 ones),
    /// else the widest of the level. An error where the level does not run the lanes asked
    /// for (8 or 16 below `avx2`).
    pub fn packet_width(&self) -> Result<packets::Width, Error> {
        match self.packet_lanes {
            None => Ok(packets::Width::for_level(self.simd)),
            Some(lanes) => packets::Width::at_level(lanes, self.simd).ok_or_else(|| {
                Error::Usage(format!("w{lanes}: {lanes}-ray packets need avx2 (SIMD level here: {})", self.simd))
            }),
        }
    }
}

/// Which soft-shadow kernel of an entry of ours is bound (`--soft-grouping`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SoftGrouping {
    /// The entry's own: for the packet, frustum and cone methods each tile's rays to each
    /// light stratum together (Benthin & Wald 2009), as 2x2 packets of neighbouring points'
    /// rays, or as shadow frusta for `multi-frusta`. The default: 1.3-1.5x single rays on
    /// Sponza, kitchen and atrium (`docs/results/coherent-shadows.md`).
    #[default]
    Strata,
    /// The entry's per-point kernel: each point's 16 rays on their own, under their pyramid
    /// (the packet, frustum and MFT methods) or their cone (the cone methods): the thesis's
    /// soft shadows (4.1.9, Table 4.6), slower than single rays on these scenes (0.3-0.9x).
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

/// Binds a method to the structures of a frame with the options of its selection.
pub type Bind = for<'s> fn(&'s Structures<'_>, &Options) -> Result<Binding<'s>, Error>;

/// Builds a structure of the registry for a scene.
pub type Build = fn(&Scene) -> Result<Box<dyn Any + Send + Sync>, Error>;

/// The names of a bound method's kernels, one per pass: their identities, by which `rttest
/// compare` times each distinct kernel once and reports name what traced a pass.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KernelNames {
    /// The primary-ray kernel: `kd-single`, `kd-mft-16`, `embree-8`, ...
    pub primary: String,
    /// The hard-shadow kernel: `kd-single`, `kd-packets`, `kd-frusta-16`, `kd-lane-frusta`, ...
    pub shadow: String,
    /// The 16-sample soft-shadow kernel: `kd-single`, `kd-stratum-packets`, `kd-pyramid`,
    /// `kd-cone`, `kd-multi-frusta-16`, `kd-lane-frusta`, ...
    pub soft: String,
    /// The stream kernel: `kd-single`, `kd-omni-packets`, `kd-mft-runs`, ...
    pub stream: String,
}

impl KernelNames {
    /// One kernel for every pass, named `name`: a method registered whole (a baseline).
    pub fn whole(name: &str) -> KernelNames {
        KernelNames { primary: name.into(), shadow: name.into(), soft: name.into(), stream: name.into() }
    }
}

/// What a [`Bind`] makes: the method's passes behind a `dyn` and, for a composition of
/// kernels, their names.
pub struct Binding<'s> {
    /// The passes.
    pub tracer: Box<dyn FrameTracer + 's>,
    /// The kernels' names; `None`: the method is one kernel for every pass, named by its
    /// entry.
    pub kernels: Option<KernelNames>,
}

impl<'s> Binding<'s> {
    /// A method whose passes are one kernel, named by its entry.
    pub fn method<M: Method + 's>(method: M) -> Binding<'s> {
        Binding { tracer: Box::new(Driven(method)), kernels: None }
    }

    /// The same binding with its kernels named.
    pub fn named(self, kernels: KernelNames) -> Binding<'s> {
        Binding { kernels: Some(kernels), ..self }
    }
}

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
    /// What the tile sizes a tiled method takes are a multiple of (4; 8 for `mft-x16`, whose
    /// 16 regions hold whole 2x2 packets): [`Registry::names`] lists only those.
    pub tile_multiple: u32,
    /// The structure it traces: [`KDTREE`] or a [`StructureEntry`]'s name.
    pub structure: &'static str,
    /// Makes the method.
    pub bind: Bind,
    /// Makes the method with its per-point soft-shadow kernel ([`SoftGrouping::PerPoint`]),
    /// for the tiled and packet methods of ours that have one; `None`: the option does not
    /// apply (selecting it is an error).
    pub per_point: Option<Bind>,
}

impl Entry {
    /// A method registered whole on `structure`: not tiled, no packets, no per-point
    /// soft-shadow kernel, one kernel for every pass named `name` (the baselines, `mbvh-4`).
    pub fn whole(
        name: &'static str,
        family: &'static str,
        summary: &'static str,
        structure: &'static str,
        bind: Bind,
    ) -> Entry {
        Entry {
            name,
            family,
            summary,
            tiled: false,
            packets: false,
            tile_multiple: 4,
            structure,
            bind,
            per_point: None,
        }
    }

    /// Its name in `--help`: `mft[-N]` for a tiled method.
    pub fn help_name(&self) -> String {
        if self.tiled { format!("{}[-N]", self.name) } else { self.name.to_string() }
    }

    /// How its cost images attribute counts to pixels: per ray for methods neither tiled nor
    /// tracing packets (single rays, the baselines), else per tile.
    pub fn attribution(&self) -> Attribution {
        if self.tiled || self.packets { Attribution::Tile } else { Attribution::Ray }
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
    /// The options it was selected with (the frame driver's tile among them).
    pub options: Options,
    /// Its kernels' names, one per pass.
    pub kernels: KernelNames,
    /// The passes.
    pub tracer: Box<dyn FrameTracer + 's>,
}

impl std::fmt::Debug for Bound<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bound")
            .field("name", &self.name)
            .field("options", &self.options)
            .field("kernels", &self.kernels)
            .finish_non_exhaustive()
    }
}

/// The methods and structures this build knows.
#[derive(Clone, Debug, Default)]
pub struct Registry {
    entries: Vec<Entry>,
    structures: Vec<StructureEntry>,
}

impl Registry {
    /// Adds a method: an [`Entry`], or a line of ours composing kernels (`crate::ours`).
    pub fn add(&mut self, entry: impl Into<Entry>) {
        self.entries.push(entry.into());
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

    /// Every full method name, in registration order, the tiled ones once per size of `tiles`
    /// that they take ([`Entry::tile_multiple`]).
    pub fn names(&self, tiles: &[u32]) -> Vec<String> {
        let mut out = Vec::new();
        for e in &self.entries {
            if e.tiled {
                let fits = tiles.iter().filter(|t| t.is_multiple_of(e.tile_multiple));
                out.extend(fits.map(|t| format!("{}-{t}", e.name)));
            } else {
                out.push(e.name.to_string());
            }
        }
        out
    }

    /// The base names, for `--help` and error messages (`mono, packet, ..., mft[-N], ...`).
    pub fn help(&self) -> String {
        let names: Vec<String> = self.entries.iter().map(Entry::help_name).collect();
        names.join(", ")
    }

    /// One line per entry, its base name and summary (`mft[-N]  Multiple Frustum ...`), for
    /// the long `--help` of a method option: made from the entries, so it lists every method
    /// this build has.
    pub fn summaries(&self) -> String {
        let names: Vec<String> = self.entries.iter().map(Entry::help_name).collect();
        let width = names.iter().map(String::len).max().unwrap_or(0);
        let lines: Vec<String> =
            names.iter().zip(&self.entries).map(|(n, e)| format!("{n:width$}  {}", e.summary)).collect();
        lines.join("\n")
    }

    /// The method `name`: an entry's name (tile from `options`) or, for a tiled method,
    /// `NAME-TILE` (e.g. `mft-16`), either with an optional `@LEVEL` (`mft-16@avx2`: the
    /// method with its SIMD level capped at `avx2`, [`Options::simd`]) and an optional
    /// `@wN` (`mft-16@w8`, `mft-16@avx512@w8`: its packets of N rays,
    /// [`Options::packet_lanes`]). An unknown name is an error listing the known ones, and
    /// so is [`SoftGrouping::PerPoint`] for a method without a per-point kernel.
    pub fn select(&self, name: &str, options: Options) -> Result<Selected, Error> {
        let selected = self.select_name(name, options)?;
        let entry = &self.entries[selected.entry];
        if options.soft == SoftGrouping::PerPoint && entry.per_point.is_none() {
            let with: Vec<&str> = self.entries.iter().filter(|e| e.per_point.is_some()).map(|e| e.name).collect();
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
        if let Some((base, level)) = name.rsplit_once('@') {
            if let Some(lanes) = level.strip_prefix('w').and_then(|n| n.parse::<usize>().ok()) {
                if ![4, 8, 16].contains(&lanes) {
                    return Err(Error::Usage(format!("{name}: packets of 4, 8 or 16 rays (w4, w8, w16), not {lanes}")));
                }
                let selected = self.select_name(base, Options { packet_lanes: Some(lanes), ..options })?;
                return Ok(Selected { name: format!("{}@{level}", selected.name), ..selected });
            }
            let simd = SimdLevel::from_name(level).filter(|l| *l >= SimdLevel::Sse2).ok_or_else(|| {
                Error::Usage(format!(
                    "{name}: unknown SIMD level or packet width '{level}' (known: sse, avx2, avx512, w4, w8, w16)"
                ))
            })?;
            let detected = SimdLevel::detect();
            if simd > detected {
                return Err(Error::Usage(format!("{name}: this CPU's widest SIMD level is {detected}")));
            }
            let selected = self.select_name(base, Options { simd, ..options })?;
            return Ok(Selected { name: format!("{}@{level}", selected.name), ..selected });
        }
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
        let bind = match (selected.options.soft, entry.per_point) {
            (SoftGrouping::PerPoint, Some(per_point)) => per_point,
            _ => entry.bind,
        };
        let binding =
            bind(structures, &selected.options).map_err(|e| Error::Usage(format!("{}: {e}", selected.name)))?;
        let kernels = binding.kernels.unwrap_or_else(|| KernelNames::whole(entry.name));
        Ok(Bound { name: selected.name.clone(), entry, options: selected.options, kernels, tracer: binding.tracer })
    }
}
