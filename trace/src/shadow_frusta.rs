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
//! - [`Grouping::Packets`]: each run of four as a same-sign 2x2 packet (thesis 2.3.1,
//!   `packets::samesign::occluded`): one traversal for four rays, each lane in its own
//!   interval, finished at its first hit.
//! - [`Grouping::Frusta`] (Benthin & Wald 2009): the tile's rays (per light stratum, for soft
//!   shadows: "multi-frusta") as one frustum from the box of their starts to the box of their
//!   ends, split into its 4x4 and 2x2 blocks where it is much wider than a voxel (MFT's
//!   quadrants, thesis 4.1.5, applied again), 2x2 blocks handed over as packets.
//!
//! Every ray is the one single rays trace ([`crate::method::hard_shadow_segment`],
//! [`SoftJob::point`]), and every kernel here answers each ray exactly as the single ray does
//! (the conformance harness checks it).

use cones::shadows::SAMPLES;
use glam::Vec3;
use kdtree::{KdTree, Ray};
use packets::lane_frusta::FRUSTUM_RAYS;
use packets::{LaneFrusta, LaneWidth, ShadowFrustum, samesign};
use scenes::Tile;

use crate::method::{ShadowJob, SoftJob, SoftStats, TileCounters};

/// How a tile's shadow rays are grouped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Grouping {
    /// 2x2 packets of neighbouring pixels' rays.
    Packets,
    /// One shadow frustum per tile (and light stratum), split where wide.
    Frusta,
    /// Frusta that share one end, several in SIMD lanes (`packets::lane_frusta`): each 4x4
    /// block's hard shadow rays (the light their apex), each point's 16 soft-shadow rays.
    Lanes(LaneWidth),
}

/// Per-thread space for one tile's shadow rays.
#[derive(Debug, Default)]
pub struct ShadowScratch {
    frustum: ShadowFrustum,
    lanes: LaneFrusta,
    /// The rays of one group as segments (ray `i` is `Ray::segment(starts[i],
    /// ends[i])`), and the pixel (tile index) of each.
    starts: Vec<Vec3>,
    ends: Vec<Vec3>,
    slots: Vec<u32>,
    blocked: Vec<bool>,
    /// Per pixel: its hard shadow ray's ends, `None` where none is cast.
    hard: Vec<Option<(Vec3, Vec3)>>,
    /// Per pixel: its soft shadow rays' origin and light samples.
    soft: Vec<Option<(Vec3, [Vec3; SAMPLES])>>,
    masks: Vec<u16>,
    /// The tile's pixels (row-major indices) in Morton order, for tiles of `order_size`.
    order: Vec<u32>,
    order_size: (u32, u32),
}

impl ShadowScratch {
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

    /// Traces the group with `grouping`, the answers into `blocked`. Packets are made from
    /// the segments four at a time (`samesign::occluded_segments`).
    fn trace<C: TileCounters>(&mut self, tree: &KdTree, grouping: Grouping, counters: &mut C) {
        self.blocked.clear();
        match grouping {
            Grouping::Packets => {
                samesign::occluded_segments(tree, &self.starts, &self.ends, &mut self.blocked, counters);
            }
            Grouping::Lanes(width) => {
                // Each run of 16 (a 4x4 block in Morton order) as one frustum.
                self.lanes.clear();
                for (starts, ends) in self.starts.chunks(FRUSTUM_RAYS).zip(self.ends.chunks(FRUSTUM_RAYS)) {
                    self.lanes.push(starts, ends);
                }
                self.lanes.trace(tree, width, counters);
                for (&mask, run) in self.lanes.blocked().iter().zip(self.starts.chunks(FRUSTUM_RAYS)) {
                    self.blocked.extend((0..run.len()).map(|k| mask >> k & 1 != 0));
                }
            }
            Grouping::Frusta => {
                self.frustum.clear();
                for (&start, &end) in self.starts.iter().zip(&self.ends) {
                    self.frustum.push(Ray::segment(start, end));
                }
                self.frustum.trace(tree, counters);
                self.blocked.extend_from_slice(self.frustum.blocked());
            }
        }
    }
}

/// The pixels of a `w` x `h` tile (row-major indices) in Morton (Z) order: each run of 4,
/// 16, 64 of them is a 2x2, 4x4, 8x8 block.
pub fn morton_order(w: u32, h: u32) -> Vec<u32> {
    let mut order: Vec<u32> = (0..w * h).collect();
    order.sort_by_key(|&i| morton(i % w, i / w));
    order
}

/// The Morton (Z-order) code of `(x, y)` (16 bits each).
fn morton(x: u32, y: u32) -> u64 {
    let spread = |v: u32| {
        let mut v = u64::from(v & 0xffff);
        v = (v | v << 8) & 0x00ff_00ff;
        v = (v | v << 4) & 0x0f0f_0f0f;
        v = (v | v << 2) & 0x3333_3333;
        (v | v << 1) & 0x5555_5555
    };
    spread(x) | spread(y) << 1
}

/// The hard shadow rays of `job`, grouped by `grouping`, into `out`; returns (rays traced,
/// rays blocked) as [`crate::Method::shadow_tile`].
pub fn hard<C: TileCounters>(
    tree: &KdTree,
    grouping: Grouping,
    scratch: &mut ShadowScratch,
    job: &ShadowJob<'_>,
    out: &mut [bool],
    counters: &mut C,
) -> (u64, u64) {
    scratch.hard.clear();
    scratch.hard.extend(job.pixels().map(|(x, y, hit)| job.segment(x, y, hit)));
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
    scratch.trace(tree, grouping, counters);
    out.fill(false);
    let mut blocked = 0;
    for (&slot, &b) in scratch.slots.iter().zip(&scratch.blocked) {
        out[slot as usize] = b;
        blocked += u64::from(b);
    }
    (scratch.slots.len() as u64, blocked)
}

/// The 16-sample soft shadows of `job`, the tile's rays to each light stratum grouped by
/// `grouping` (Benthin & Wald's multi-frusta for [`Grouping::Frusta`]), the visible fraction
/// per pixel into `visible`, as [`crate::Method::soft_tile`].
pub fn soft<C: TileCounters>(
    tree: &KdTree,
    grouping: Grouping,
    scratch: &mut ShadowScratch,
    job: &SoftJob<'_>,
    visible: &mut [f32],
    counters: &mut C,
) -> SoftStats {
    scratch.soft.clear();
    scratch.soft.extend((0..visible.len()).map(|i| job.samples(i).map(|(start, samples, _)| (start, samples))));
    scratch.masks.clear();
    scratch.masks.resize(visible.len(), 0);
    scratch.morton_order(job.hits.tile);
    if let Grouping::Lanes(width) = grouping {
        // Each point's 16 rays, which share its origin, as one frustum.
        let ShadowScratch { soft, order, lanes, slots, masks, .. } = &mut *scratch;
        lanes.clear();
        slots.clear();
        for &i in order.iter() {
            if let Some((start, samples)) = &soft[i as usize] {
                lanes.push(&[*start; SAMPLES], samples);
                slots.push(i);
            }
        }
        lanes.trace(tree, width, counters);
        for (&slot, &mask) in slots.iter().zip(lanes.blocked()) {
            masks[slot as usize] = mask;
        }
    } else {
        for k in 0..SAMPLES {
            scratch.clear();
            let ShadowScratch { soft, order, starts, ends, slots, .. } = &mut *scratch;
            for &i in order.iter() {
                if let Some((start, samples)) = &soft[i as usize] {
                    // Ray `k` of `SoftJob::point` (`cones::shadows::shadow_ray`).
                    starts.push(*start);
                    ends.push(samples[k]);
                    slots.push(i);
                }
            }
            scratch.trace(tree, grouping, counters);
            for (&slot, &b) in scratch.slots.iter().zip(&scratch.blocked) {
                scratch.masks[slot as usize] |= u16::from(b) << k;
            }
        }
    }
    let mut stats = SoftStats::default();
    for ((slot, rays), &mask) in visible.iter_mut().zip(&scratch.soft).zip(&scratch.masks) {
        *slot = if rays.is_some() { stats.add_point(mask) } else { 0.0 };
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_order_visits_blocks_of_four_together() {
        let tile = Tile { x0: 0, y0: 0, x1: 4, y1: 4 };
        let mut s = ShadowScratch::default();
        s.morton_order(&tile);
        // The first 2x2 block, then the one to its right.
        assert_eq!(s.order[..8], [0, 1, 4, 5, 2, 3, 6, 7]);
        let mut sorted = s.order.clone();
        sorted.sort();
        assert_eq!(sorted, (0..16).collect::<Vec<_>>());
    }
}
