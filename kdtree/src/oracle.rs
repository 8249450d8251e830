//! Brute force.
/// Brute force.
pub struct BruteForce;
