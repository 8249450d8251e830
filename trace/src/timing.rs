//! Timing helpers shared by every experiment: a timed call, interleaved rounds and medians.
//!
//! The machine is noisy, so comparisons time every contender once per round, in turn (A, B,
//! C, A, B, C, ...), and report medians: a slow phase of the machine then hits every
//! contender alike.

use std::time::Instant;

/// Runs `f` and returns its seconds and its result.
pub fn timed<T>(f: impl FnOnce() -> T) -> (f64, T) {
    let start = Instant::now();
    let out = f();
    (start.elapsed().as_secs_f64(), out)
}

/// Median of `v`, NaNs left out (0 for an empty list).
pub fn median(v: &[f64]) -> f64 {
    let mut v: Vec<f64> = v.iter().copied().filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

/// Runs `rounds` rounds, each calling `run` once on every contender in turn, then `step`;
/// returns each contender's seconds, one per round (feed them to [`median`]).
pub fn interleaved<P>(
    rounds: u32,
    contenders: &mut [P],
    mut run: impl FnMut(&mut P) -> f64,
    mut step: impl FnMut(),
) -> Vec<Vec<f64>> {
    let mut secs = vec![Vec::with_capacity(rounds as usize); contenders.len()];
    for _ in 0..rounds {
        for (c, s) in contenders.iter_mut().zip(&mut secs) {
            s.push(run(c));
            step();
        }
    }
    secs
}

/// Millions of rays per second (0 when no time was measured).
pub fn mrays_per_s(rays: u64, secs: f64) -> f64 {
    if secs > 0.0 { rays as f64 / secs / 1e6 } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medians() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert_eq!(median(&[f64::NAN, 1.0]), 1.0);
        assert_eq!(median(&[]), 0.0);
    }

    #[test]
    fn rounds_interleave_the_contenders() {
        let mut order = Vec::new();
        let mut names = ['a', 'b', 'c'];
        let secs = interleaved(
            2,
            &mut names,
            |c| {
                order.push(*c);
                1.0
            },
            || {},
        );
        assert_eq!(order, ['a', 'b', 'c', 'a', 'b', 'c']);
        assert_eq!(secs, vec![vec![1.0, 1.0]; 3]);
    }
}
