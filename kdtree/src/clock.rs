//! The split of a pass's time between traversal and intersection (thesis Table 3.1, which
//! profiles "primary traversal" apart from "primary intersection", and the same for secondary
//! rays).
//!
//! [`LeafClock`] is a [`Counters`] that counts nothing but reads the time-stamp counter
//! around the primary kernels' ray generation ([`Counters::generation_start`]: a tile's
//! packets, or each single primary ray) and around every leaf visit of the kd descent ([`Counters::leaf_visit_start`] and
//! [`Counters::leaf_visit_end`]): the triangle tests
//! (with their packet/leaf culling) of every kernel built on [`crate::descent::descend`].
//! Everything else a pass does (ray setup, node steps, the stack) is traversal. The clock's
//! own cost, measured once per process ([`clock_cost`]), is taken off both parts, so
//! [`LeafClock::intersection_share`] estimates the share of the unclocked pass: a profiler's
//! answer without a profiler, and close to it only where leaves are long enough against two
//! reads of the counter (tens of cycles).
//!
//! The clock is `rdtsc` on x86-64 (constant-rate and synchronised across cores on the CPUs
//! this workspace runs on), elsewhere nanoseconds from a monotonic clock. With
//! [`Counters::ENABLED`] false, kernels do exactly the work of an uncounted pass.

use std::ops::AddAssign;
use std::sync::OnceLock;

use crate::counters::Counters;

/// The current tick of the time-stamp counter (x86-64), or nanoseconds since the first call
/// elsewhere. Only differences mean anything.
#[inline(always)]
pub fn ticks() -> u64 {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: `rdtsc` has no preconditions; every x86-64 CPU has it.
        #[allow(unused_unsafe)]
        unsafe {
            core::arch::x86_64::_rdtsc()
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        static START: OnceLock<std::time::Instant> = OnceLock::new();
        START.get_or_init(std::time::Instant::now).elapsed().as_nanos() as u64
    }
}

/// Time spent in leaf visits, summed over the rays, packets, tiles and threads of a pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LeafClock {
    /// Leaf visits timed.
    pub leaves: u64,
    /// [`ticks`] inside them.
    pub leaf_ticks: u64,
    /// Ray generations timed (tiles, or single primary rays).
    pub generations: u64,
    /// [`ticks`] inside them.
    pub generation_ticks: u64,
    /// The tick the open visit or generation started at.
    started: u64,
}

impl Counters for LeafClock {
    const ENABLED: bool = false;
    #[inline(always)]
    fn node(&mut self) {}
    #[inline(always)]
    fn leaf(&mut self) {}
    #[inline(always)]
    fn tests(&mut self, _n: u64) {}
    #[inline(always)]
    fn leaf_visit_start(&mut self) {
        self.started = ticks();
    }
    #[inline(always)]
    fn leaf_visit_end(&mut self) {
        self.leaf_ticks += ticks().wrapping_sub(self.started);
        self.leaves += 1;
    }
    #[inline(always)]
    fn generation_start(&mut self) {
        self.started = ticks();
    }
    #[inline(always)]
    fn generation_end(&mut self) {
        self.generation_ticks += ticks().wrapping_sub(self.started);
        self.generations += 1;
    }
}

impl AddAssign for LeafClock {
    fn add_assign(&mut self, o: LeafClock) {
        self.leaves += o.leaves;
        self.leaf_ticks += o.leaf_ticks;
        self.generations += o.generations;
        self.generation_ticks += o.generation_ticks;
    }
}

impl LeafClock {
    /// The share of a pass's time spent in leaf visits: the clocked ticks over `busy_ticks`
    /// (the pass's [`ticks`] on the clock times its threads), each less the clock's own cost
    /// per leaf ([`clock_cost`]). `None` when no leaf was clocked (a kernel outside the kd
    /// descent, such as Embree's or the multi-BVH's).
    pub fn intersection_share(&self, busy_ticks: u64) -> Option<f64> {
        (self.leaves > 0).then(|| self.share(self.leaf_ticks, self.leaves, busy_ticks))
    }

    /// The share of a pass's time spent generating rays, as
    /// [`LeafClock::intersection_share`]; `None` when no generation was clocked (a method
    /// that makes its rays itself, such as Embree's).
    pub fn generation_share(&self, busy_ticks: u64) -> Option<f64> {
        (self.generations > 0).then(|| self.share(self.generation_ticks, self.generations, busy_ticks))
    }

    /// `ticks` clocked in `spans` spans, over `busy_ticks`: each less the clock's own cost
    /// (the busy time that of every span clocked).
    fn share(&self, ticks: u64, spans: u64, busy_ticks: u64) -> f64 {
        let cost = clock_cost();
        let all = (self.leaves + self.generations) as f64;
        let inside = (ticks as f64 - spans as f64 * cost.inside).max(0.0);
        let busy = (busy_ticks as f64 - all * cost.whole).max(inside).max(1.0);
        inside / busy
    }
}

/// What clocking one leaf costs, in [`ticks`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClockCost {
    /// Ticks a leaf visit that does nothing reads as its own.
    pub inside: f64,
    /// Ticks an empty leaf visit takes in all.
    pub whole: f64,
}

/// The cost of clocking one leaf, measured once per process: the fastest of a few runs of
/// empty leaf visits.
pub fn clock_cost() -> ClockCost {
    static COST: OnceLock<ClockCost> = OnceLock::new();
    *COST.get_or_init(|| {
        const N: u64 = 1 << 14;
        let mut best = ClockCost { inside: f64::INFINITY, whole: f64::INFINITY };
        for _ in 0..8 {
            let mut clock = LeafClock::default();
            let start = ticks();
            for i in 0..N {
                clock.leaf_visit_start();
                std::hint::black_box(i);
                clock.leaf_visit_end();
            }
            let whole = ticks().wrapping_sub(start) as f64 / N as f64;
            best.inside = best.inside.min(clock.leaf_ticks as f64 / N as f64);
            best.whole = best.whole.min(whole);
        }
        best
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BuildConfig, KdTree, NoCounters, Ray};
    use glam::Vec3;

    #[test]
    fn every_leaf_visit_is_clocked_and_answers_are_unchanged() {
        let tris: Vec<[Vec3; 3]> = (0..200)
            .map(|i| {
                let x = (i % 20) as f32;
                let z = (i / 20) as f32;
                [Vec3::new(x, 0.0, z), Vec3::new(x + 0.9, 0.0, z), Vec3::new(x, 0.0, z + 0.9)]
            })
            .collect();
        let tree = KdTree::build_soup(&tris, &BuildConfig::default()).unwrap();
        let (mut clock, mut counts) = (LeafClock::default(), crate::Counts::default());
        for i in 0..100 {
            let o = Vec3::new(i as f32 * 0.2, 5.0, (i % 7) as f32 + 0.3);
            let ray = Ray::new(o, Vec3::new(0.01, -1.0, 0.02), 0.0, f32::INFINITY);
            let plain = tree.intersect_counted(&ray, &mut NoCounters);
            assert_eq!(tree.intersect_counted(&ray, &mut clock), plain);
            assert_eq!(tree.intersect_counted(&ray, &mut counts), plain);
        }
        assert_eq!(clock.leaves, counts.leaves, "one clocked visit per leaf");
        assert!(clock.leaves > 0 && clock.leaf_ticks > 0);
    }

    #[test]
    fn shares_lie_in_the_unit_interval_and_need_leaves() {
        assert_eq!(LeafClock::default().intersection_share(1000), None);
        let cost = clock_cost();
        assert!(cost.inside >= 0.0 && cost.whole >= cost.inside && cost.whole.is_finite(), "{cost:?}");
        let clock = LeafClock { leaves: 10, leaf_ticks: 50_000, ..LeafClock::default() };
        assert_eq!(clock.generation_share(100_000), None);
        let share = clock.intersection_share(100_000).unwrap();
        assert!(share > 0.0 && share <= 1.0, "{share}");
        // More busy time, a smaller share; a pass that was all leaves, all of it.
        assert!(clock.intersection_share(400_000).unwrap() < share);
        assert!(clock.intersection_share(50_000).unwrap() > 0.99);
    }
}
