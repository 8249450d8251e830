//! Stats.
/// Stats.
pub struct TreeStats;
