//! Our methods: the registry lines that compose them from typed kernels
//! ([`crate::kernel`]), and our 4- and 8-wide BVHs ([`crate::multibvh`]).
//!
//! Each line of [`Registry::ours`] is one method: its name, its summary and four kernels, one
//! per pass (primary, hard shadow, soft shadow, stream), plus, for the packet, frustum and
//! cone methods, the per-point soft-shadow kernel that `--soft-grouping per-point` binds
//! instead (thesis Table 4.6). Whether the method is tiled (one name per tile size) and
//! traces 2x2 packets follows from its primary kernel. A new method from existing kernels is
//! one line here; a new kernel is its own type in `crate::kernel` plus the lines that compose
//! it.

use std::marker::PhantomData;

use crate::kernel::{self, HardShadow, Primary, SoftShadow, Stream, primary, shadow, soft, stream};
use crate::multibvh;
use crate::registry::{Entry, KDTREE, Registry, StructureEntry};

/// The four kernel types of a [`Line`], as a type.
type Kernels<P, H, S, R> = fn() -> (P, H, S, R);

/// A registry line of ours being written: the composition of `P`, `H`, `S` and `R` on our
/// kd-tree; [`Line::per_point`] adds its per-point soft-shadow kernel.
#[derive(Debug)]
struct Line<P, H, S, R> {
    entry: Entry,
    kernels: PhantomData<Kernels<P, H, S, R>>,
}

/// The method `name` of ours composing `P`, `H`, `S` and `R` (see [`Line`]).
fn compose<P, H, S, R>(name: &'static str, summary: &'static str) -> Line<P, H, S, R>
where
    P: Primary + 'static,
    H: HardShadow + 'static,
    S: SoftShadow + 'static,
    R: Stream + 'static,
{
    let entry = Entry {
        name,
        family: "ours",
        summary,
        tiled: P::TILED,
        packets: P::PACKETS,
        tile_multiple: P::TILE_MULTIPLE,
        structure: KDTREE,
        bind: kernel::bind::<P, H, S, R>,
        per_point: None,
    };
    Line { entry, kernels: PhantomData }
}

impl<P, H, S, R> Line<P, H, S, R>
where
    P: Primary + 'static,
    H: HardShadow + 'static,
    S: SoftShadow + 'static,
    R: Stream + 'static,
{
    /// The entry, with `Q` in place of `S` under `--soft-grouping per-point`.
    fn per_point<Q: SoftShadow + 'static>(self) -> Entry {
        Entry { per_point: Some(kernel::bind::<P, H, Q, R>), ..self.entry }
    }
}

impl<P, H, S, R> From<Line<P, H, S, R>> for Entry {
    fn from(line: Line<P, H, S, R>) -> Entry {
        line.entry
    }
}

use primary::{Cone, Frustum, Mft, MftCone, MftX16, Packet, SameSign, Single};
use stream::Runs;

impl Registry {
    /// Our methods: single rays, packets, frusta, MFT, cones (thesis 2.2.1, 4.1.2-4.1.9) and
    /// Benthin & Wald's shadow frusta on our kd-tree, and single rays on our 4- and 8-wide
    /// BVHs (`mbvh-4`, structure `mbvh`; `mbvh-8`, structure `mbvh8`). The registry every
    /// command uses is `baselines::registry()`, these and the baselines of the build; the
    /// tests of `trace` and the fuzz target use these alone.
    #[rustfmt::skip]
    pub fn ours() -> Registry {
        let mut r = Registry::default();
        r.add(compose::<Single, shadow::Single, soft::Single, stream::Single>("mono", "single rays, closest and any hit (thesis 2.2.1)"));
        r.add(compose::<Packet, shadow::Packets, soft::StratumPackets, stream::Packets>("packet", "omni-directional 2x2 packets (thesis 4.1.2)").per_point::<soft::Pyramid>());
        r.add(compose::<SameSign, shadow::Packets, soft::StratumPackets, stream::SameSign>("samesign", "same-sign 2x2 packets, split where signs differ (thesis 2.3.1)").per_point::<soft::Pyramid>());
        r.add(compose::<Frustum, shadow::Packets, soft::StratumPackets, Runs<Frustum>>("frustum", "one frustum per tile, packet/leaf culling (thesis 2.3.2, 4.1.3-4.1.4)").per_point::<soft::Pyramid>());
        r.add(compose::<Mft, shadow::Packets, soft::StratumPackets, Runs<Mft>>("mft", "Multiple Frustum Traversal, four quadrant frusta per tile (thesis 4.1.5)").per_point::<soft::Pyramid>());
        r.add(compose::<MftX16, shadow::Packets, soft::StratumPackets, Runs<Mft>>("mft-x16", "MFT with 16 frusta per tile (4 x 4 regions, one per SIMD lane) instead of four quadrants (thesis 4.1.5, at AVX-512's width)"));
        r.add(compose::<Mft, shadow::Packets, soft::OmniPoints, Runs<Mft>>("mft-omni", "MFT primaries; each point's 16 soft-shadow rays as four omni-directional 2x2 packets from the point, with no pyramid or cone (thesis 4.1.2, Table 4.6)"));
        r.add(compose::<Mft, shadow::Frusta, soft::Frusta, Runs<Mft>>("multi-frusta", "MFT primaries; shadows as Benthin & Wald's (2009) frusta: one per tile, one per tile and light stratum"));
        r.add(compose::<Mft, shadow::Lanes, soft::Lanes, Runs<Mft>>("lane-frusta", "MFT primaries; shadows as Benthin & Wald's (2009) multi-frusta in SIMD lanes: a 4x4 block's or a point's rays per frustum, 16 (AVX-512), 8 (AVX2) or 4 frusta at once"));
        r.add(compose::<Cone, shadow::Packets, soft::StratumPackets, Runs<Cone>>("cone", "one cone per tile as the proxy of its rays (thesis 4.1.6-4.1.8)").per_point::<soft::Cone>());
        r.add(compose::<MftCone, shadow::Packets, soft::StratumPackets, Runs<MftCone>>("mft-cone", "four quadrant cones per tile (thesis 4.1.9)").per_point::<soft::Cone>());
        r.add_structure(StructureEntry { name: multibvh::MBVH, build: |scene| Ok(Box::new(multibvh::build(scene)?)) });
        r.add(Entry::whole("mbvh-4", "ours", "4-wide BVH, single rays, SIMD over children and leaf triangles (Wald, Benthin & Boulos 2008)", multibvh::MBVH, |s, _| multibvh::bind(s.get(multibvh::MBVH)?, s.kdtree())));
        r.add_structure(StructureEntry { name: multibvh::MBVH8, build: |scene| Ok(Box::new(multibvh::build8(scene)?)) });
        r.add(Entry::whole("mbvh-8", "ours", "8-wide BVH, single rays, AVX2 over children (chosen at run time), SIMD over leaf triangles (Wald, Benthin & Boulos 2008)", multibvh::MBVH8, |s, o| multibvh::bind8(s.get(multibvh::MBVH8)?, s.kdtree(), o.simd)));
        r.add(Entry::whole("mbvh-8-p16", "ours", "8-wide BVH, ray streams and soft-shadow points by 16-ray packets (AVX-512 over the packet, or two AVX2 halves without it, chosen at run time), single rays below 7 (closest hit) or 4 (any hit; 7 in AVX2 halves) active lanes and for primary and hard-shadow tiles (Benthin et al. 2012's hybrid traversal, Embree's incoherent embree-16)", multibvh::MBVH8, |s, o| multibvh::bind8_p16(s.get(multibvh::MBVH8)?, s.kdtree(), o.simd)));
        r.add_structure(StructureEntry { name: multibvh::MBVH16, build: |scene| Ok(Box::new(multibvh::build16(scene)?)) });
        r.add(Entry::whole("mbvh-16", "ours", "16-wide BVH, single rays, one ray against 16 children per AVX-512 step (chosen at run time), SIMD over leaf triangles (Wald, Benthin & Boulos 2008, as published)", multibvh::MBVH16, |s, o| multibvh::bind16(s.get(multibvh::MBVH16)?, s.kdtree(), o.simd)));
        r
    }
}
