//! Cost images: where a method spends its traversal work, pixel by pixel (`rttest render
//! --aov nodes|leaves|isects|culled`).
//!
//! The thesis explains its results with the counts N (traversal steps) and I (intersection
//! tests) per ray or per 2x2 packet (Tables 4.1-4.3) and the share of packets culled at
//! leaves (4.1.4, Table 4.2). This module spreads those counts over the image:
//!
//! - a registry entry that is neither `tiled` nor `packets` ([`Attribution::Ray`]: `mono`,
//!   and the baselines) is run one pixel at a time (a 1x1 tile), so each pixel holds exactly
//!   what its own ray counted (the baselines count nothing: their images are 0);
//! - our methods that trace groups ([`Attribution::Tile`]: 2x2 packets, frusta, MFT, cones)
//!   are counted per render tile (the unit of one `Method::primary_tile` call, which for the
//!   frustum and cone methods is the frustum), and every pixel of the tile holds the tile's
//!   counts divided by its rays. The image of a frustum method is therefore constant over
//!   each tile: what the tile paid, per ray.
//!
//! So a pixel's value is always "work per ray", and summing a cost image gives the total the
//! counters report for the frame (tested below). Only primary rays are counted. The pass that
//! attributes counts is separate from the timed passes (`crate::frame::cost_pass`): with
//! cost images off nothing of this runs, and the kernels are the same monomorphic ones,
//! counting into a [`Counts`] per call.

use kdtree::Counts;
use scenes::ScalarImage;

/// Which traversal count a cost image shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Cost {
    /// Traversal steps (nodes fetched, inner and leaf): the thesis's N.
    Nodes,
    /// Leaves visited.
    Leaves,
    /// Intersection tests (ray-triangle, or packet-triangle for packets): the thesis's I.
    Isects,
    /// 2x2 packets culled at leaves before any triangle test (thesis 4.1.4); 0 for methods
    /// without packet/leaf culling.
    Culled,
}

impl Cost {
    /// Every cost, in the order of [`PixelCost`]'s fields.
    pub const ALL: [Cost; 4] = [Cost::Nodes, Cost::Leaves, Cost::Isects, Cost::Culled];

    /// The name on the command line and in file names.
    pub fn name(self) -> &'static str {
        match self {
            Cost::Nodes => "nodes",
            Cost::Leaves => "leaves",
            Cost::Isects => "isects",
            Cost::Culled => "culled",
        }
    }

    /// This count out of `counts`.
    pub fn of(self, counts: &Counts) -> u64 {
        match self {
            Cost::Nodes => counts.nodes,
            Cost::Leaves => counts.leaves,
            Cost::Isects => counts.tests,
            Cost::Culled => counts.culled,
        }
    }
}

/// How a method's counts are attributed to pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Attribution {
    /// Each pixel's ray is traced alone (a 1x1 tile): for registry entries neither `tiled`
    /// nor `packets`, whose `primary_tile` takes any tile (single rays, the baselines).
    Ray,
    /// Each render tile is traced whole; its counts are shared equally by its pixels.
    Tile,
}

/// One pixel's share of the traversal work: the counts of the call that traced it, divided
/// by the rays of that call.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelCost {
    /// Traversal steps per ray.
    pub nodes: f32,
    /// Leaves visited per ray.
    pub leaves: f32,
    /// Intersection tests per ray.
    pub isects: f32,
    /// Packets culled at leaves per ray.
    pub culled: f32,
}

impl PixelCost {
    /// `counts` shared by `rays` rays (a zero `rays` counts as one).
    pub fn share(counts: &Counts, rays: usize) -> PixelCost {
        let n = rays.max(1) as f64;
        let per = |v: u64| (v as f64 / n) as f32;
        PixelCost {
            nodes: per(counts.nodes),
            leaves: per(counts.leaves),
            isects: per(counts.tests),
            culled: per(counts.culled),
        }
    }

    /// The value of `cost`.
    pub fn get(&self, cost: Cost) -> f32 {
        match cost {
            Cost::Nodes => self.nodes,
            Cost::Leaves => self.leaves,
            Cost::Isects => self.isects,
            Cost::Culled => self.culled,
        }
    }
}

/// The cost images of one frame: every pixel's [`PixelCost`] (row-major) and the exact totals
/// the counters summed.
#[derive(Clone, Debug)]
pub struct CostFrame {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Row-major, one per pixel.
    pub pixels: Vec<PixelCost>,
    /// The counts of the whole frame (the sum of every call's counts).
    pub totals: Counts,
    /// How the counts were attributed.
    pub attribution: Attribution,
}

impl CostFrame {
    /// The image of one cost: per pixel, work per ray.
    pub fn image(&self, cost: Cost) -> ScalarImage {
        ScalarImage {
            width: self.width,
            height: self.height,
            values: self.pixels.iter().map(|p| p.get(cost)).collect(),
        }
    }

    /// The sum of `cost` over every pixel, in `f64`: the frame's total up to the rounding of
    /// each pixel's share to `f32`.
    pub fn sum(&self, cost: Cost) -> f64 {
        self.pixels.iter().map(|p| f64::from(p.get(cost))).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn share_divides_by_rays() {
        let c = Counts { nodes: 10, leaves: 4, tests: 6, leaf_packets: 3, culled: 2 };
        let p = PixelCost::share(&c, 4);
        assert_eq!((p.nodes, p.leaves, p.isects, p.culled), (2.5, 1.0, 1.5, 0.5));
        assert_eq!(PixelCost::share(&c, 0).nodes, 10.0, "no rays counts as one");
        for cost in Cost::ALL {
            assert_eq!(f64::from(p.get(cost)) * 4.0, cost.of(&c) as f64, "{}", cost.name());
        }
    }
}
