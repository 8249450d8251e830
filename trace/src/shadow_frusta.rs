//! A tile's shadow rays traced together: as 2x2 packets, or as Benthin & Wald's shadow
//! frusta (`packets::shadow_frustum`).
//!
//! Every shadow ray of a tile ends at the point light (hard shadows), or at one stratum of
//! the light's 4x4 stratified samples (soft shadows, ray `k` of every point going to stratum
//! `k`, `cones::shadows::light_samples`). So the rays of neighbouring pixels run side by side
//! to nearly the same end, and are traced in groups of neighbours: the tile's pixels are
//! taken in Morton (Z) order, so that each run of 4, 16 or 64 rays is a 2x2, 4x4 or 8x8
//! block of the tile.
//!
//! How a run of those rays is traced is a [`Grouping`], a type: the hard-shadow kernels
//! `crate::kernel::shadow::{Packets, Frusta, Lanes}` are the groupings, and [`hard`] and
//! [`soft_strata`] are generic over them, so each is one monomorphic loop:
//! - 2x2 packets: each run of four as a same-sign 2x2 packet (thesis 2.3.1,
//!   `packets::samesign::occluded_segments`): one traversal for four rays, each lane in its own
//!   interval, finished at its first hit.
//! - shadow frusta (Benthin & Wald 2009): the tile's rays (per light stratum, for soft
//!   shadows: "multi-frusta") as one frustum from the box of their starts to the box of their
//!   ends, split into its 4x4 and 2x2 blocks where it is much wider than a voxel (MFT's
//!   quadrants, thesis 4.1.5, applied again), 2x2 blocks handed over as packets.
//! - frusta in SIMD lanes (`packets::lane_frusta`): each run of 16 hard rays (a 4x4 block)
//!   as one frustum; for soft shadows each point's 16 rays as one frustum ([`soft_lanes`]).
//!
//! Every ray is the one single rays trace ([`crate::method::hard_shadow_segment`],
//! [`SoftJob::point`]), and every kernel here answers each ray exactly as the single ray does
//! (the conformance harness checks it).

use cones::shadows::SAMPLES;
use glam::Vec3;
use kdtree::KdTree;
use packets::{LaneFrusta, LaneWidth, PacketTreeTest};
use scenes::{Tile, morton_order};

use crate::method::{ShadowJob, SoftJob, SoftStats, TileCounters};

/// How a run of shadow segments is traced: the answer for each segment, blocked or not.
/// Implemented by the hard-shadow kernels that group rays (`crate::kernel::shadow`).
pub trait Grouping: Sync {
    /// What the grouping keeps between runs (a frustum's buffers), per thread.
    type Scratch: Default + Send;

    /// Whether each segment `starts[i]` to `ends[i]` (the ray `Ray::segment(starts[i],
    /// ends[i])`) is blocked, appended to `blocked` (empty on entry), in order, with the
    /// tree's triangle test `I` (bound once with the method, `crate::kernel::bind`).
    fn occluded<I: PacketTreeTest, C: TileCounters>(
        &self,
        tree: &KdTree,
        scratch: &mut Self::Scratch,
        starts: &[Vec3],
        ends: &[Vec3],
        blocked: &mut Vec<bool>,
        counters: &mut C,
    );
}

/// Per-thread space for one tile's shadow rays, with the grouping's own `S`.
#[derive(Debug, Default)]
pub struct ShadowScratch<S> {
    group: S,
    /// The tile's points that cast rays, in Morton order: each one's origin, and its pixel
    /// (tile index).
    starts: Vec<Vec3>,
    slots: Vec<u32>,
    /// The rays' ends, stratum by stratum: end `k` of point `j` at `k * stride + j`, so that
    /// stratum `k`'s rays are `starts` and one slice of `ends`. Hard shadows have one stratum
    /// (the light); soft shadows 16 (the light samples), with the tile's pixel count as stride.
    ends: Vec<Vec3>,
    blocked: Vec<bool>,
    /// Per pixel: its hard shadow ray's ends, `None` where none is cast.
    hard: Vec<Option<(Vec3, Vec3)>>,
    masks: Vec<u16>,
    /// The tile's pixels (row-major indices) in Morton order, for tiles of `order_size`.
    order: Vec<u32>,
    order_size: (u32, u32),
}

impl<S> ShadowScratch<S> {
    /// The grouping's own scratch (a frustum's buffers), for a kernel that traces one group
    /// of its own (a point's 16 rays).
    pub fn group(&mut self) -> &mut S {
        &mut self.group
    }

    /// Computes the Morton (Z) order of `tile`'s pixels (row-major indices) into `order`,
    /// unless it holds that of a tile of the same size.
    fn morton_order(&mut self, tile: &Tile) {
        let size = (tile.width(), tile.height());
        if self.order_size != size || self.order.is_empty() {
            self.order = morton_order(size.0, size.1);
            self.order_size = size;
        }
    }

    /// Empties the group.
    fn clear(&mut self) {
        self.starts.clear();
        self.ends.clear();
        self.slots.clear();
    }

    /// Traces stratum `k` of the points (`stride` apart in `ends`) with `grouping`, the
    /// answers into `blocked`.
    fn trace<I: PacketTreeTest, G: Grouping<Scratch = S>, C: TileCounters>(
        &mut self,
        tree: &KdTree,
        grouping: &G,
        (k, stride): (usize, usize),
        counters: &mut C,
    ) {
        self.blocked.clear();
        let ends = &self.ends[k * stride..][..self.starts.len()];
        grouping.occluded::<I, C>(tree, &mut self.group, &self.starts, ends, &mut self.blocked, counters);
    }

    /// The points of `job` (a tile of `n` pixels) that cast rays, in Morton order: each
    /// one's origin into `starts`, its pixel into `slots` and its light samples into `ends`
    /// (stride `n`), and the masks cleared. Laid out once per tile, so that each stratum's
    /// rays are two slices and no copy.
    fn gather_soft(&mut self, job: &SoftJob<'_>, n: usize) {
        self.morton_order(job.hits.tile);
        self.clear();
        self.ends.resize(SAMPLES * n, Vec3::ZERO);
        self.masks.clear();
        self.masks.resize(n, 0);
        let ShadowScratch { order, starts, slots, ends, .. } = self;
        for &i in order.iter() {
            if let Some((start, samples, _)) = job.samples(i as usize) {
                let j = starts.len();
                for (k, &sample) in samples.iter().enumerate() {
                    ends[k * n + j] = sample;
                }
                starts.push(start);
                slots.push(i);
            }
        }
    }

    /// The visible fraction per pixel from the masks (0 for the pixels that cast no rays),
    /// and what was traced.
    fn finish_soft(&self, visible: &mut [f32]) -> SoftStats {
        let mut stats = SoftStats::default();
        visible.fill(0.0);
        for &slot in &self.slots {
            visible[slot as usize] = stats.add_point(self.masks[slot as usize]);
        }
        stats
    }
}

/// The hard shadow rays of `job`, in Morton order, traced by `grouping`, into `out`; returns
/// (rays traced, rays blocked) as [`crate::method::Method::shadow_tile`]; `I` is the tree's
/// triangle test.
pub fn hard<I: PacketTreeTest, G: Grouping, C: TileCounters>(
    tree: &KdTree,
    grouping: &G,
    scratch: &mut ShadowScratch<G::Scratch>,
    job: &ShadowJob<'_>,
    out: &mut [bool],
    counters: &mut C,
) -> (u64, u64) {
    job.segments(&mut scratch.hard);
    scratch.morton_order(job.tile);
    scratch.clear();
    let ShadowScratch { hard, order, starts, ends, slots, .. } = &mut *scratch;
    for &i in order.iter() {
        if let Some((start, end)) = hard[i as usize] {
            starts.push(start);
            ends.push(end);
            slots.push(i);
        }
    }
    scratch.trace::<I, G, C>(tree, grouping, (0, 0), counters);
    out.fill(false);
    let mut blocked = 0;
    for (&slot, &b) in scratch.slots.iter().zip(&scratch.blocked) {
        out[slot as usize] = b;
        blocked += u64::from(b);
    }
    (scratch.slots.len() as u64, blocked)
}

/// The 16-sample soft shadows of `job`, the tile's rays to each light stratum traced together
/// by `grouping` (Benthin & Wald's multi-frusta for shadow frusta), the visible fraction per
/// pixel into `visible`, as [`crate::method::Method::soft_tile`]; `I` is the tree's triangle
/// test.
pub fn soft_strata<I: PacketTreeTest, G: Grouping, C: TileCounters>(
    tree: &KdTree,
    grouping: &G,
    scratch: &mut ShadowScratch<G::Scratch>,
    job: &SoftJob<'_>,
    visible: &mut [f32],
    counters: &mut C,
) -> SoftStats {
    let n = visible.len();
    scratch.gather_soft(job, n);
    for k in 0..SAMPLES {
        // Ray `k` of `SoftJob::point` (`cones::shadows::shadow_ray`) of every point.
        scratch.trace::<I, G, C>(tree, grouping, (k, n), counters);
        for (&slot, &b) in scratch.slots.iter().zip(&scratch.blocked) {
            scratch.masks[slot as usize] |= u16::from(b) << k;
        }
    }
    scratch.finish_soft(visible)
}

/// The 16-sample soft shadows of `job` with each point's 16 rays, which share its origin, as
/// one frustum of `packets::lane_frusta`, `width` of them at once, the points in Morton
/// order; the visible fraction per pixel into `visible`, as
/// [`crate::method::Method::soft_tile`]; `I` is the tree's triangle test.
pub fn soft_lanes<I: PacketTreeTest, C: TileCounters>(
    tree: &KdTree,
    width: LaneWidth,
    scratch: &mut ShadowScratch<LaneFrusta>,
    job: &SoftJob<'_>,
    visible: &mut [f32],
    counters: &mut C,
) -> SoftStats {
    let n = visible.len();
    scratch.gather_soft(job, n);
    let ShadowScratch { group: lanes, starts, slots, ends, masks, .. } = &mut *scratch;
    lanes.clear();
    for (j, &start) in starts.iter().enumerate() {
        let samples: [Vec3; SAMPLES] = std::array::from_fn(|k| ends[k * n + j]);
        lanes.push(&[start; SAMPLES], &samples);
    }
    lanes.trace_with::<I, C>(tree, width, counters);
    for (&slot, &mask) in slots.iter().zip(lanes.blocked()) {
        masks[slot as usize] = mask;
    }
    scratch.finish_soft(visible)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_order_visits_blocks_of_four_together() {
        let tile = Tile { x0: 0, y0: 0, x1: 4, y1: 4 };
        let mut s = ShadowScratch::<()>::default();
        s.morton_order(&tile);
        // The first 2x2 block, then the one to its right.
        assert_eq!(s.order[..8], [0, 1, 4, 5, 2, 3, 6, 7]);
        let mut sorted = s.order.clone();
        sorted.sort();
        assert_eq!(sorted, (0..16).collect::<Vec<_>>());
    }
}
