//! The unit tests' random numbers: Marsaglia's xorshift64 (shifts 13, 7, 17), seeded, the
//! same sequence on every run and platform.

/// A xorshift64 generator; the seed must not be zero.
pub(crate) struct XorShift(pub(crate) u64);

impl XorShift {
    /// The next state.
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// An integer in `0..m` (from the state's bits 33 and up).
    pub(crate) fn below(&mut self, m: u64) -> u64 {
        (self.next_u64() >> 33) % m
    }

    /// A float in `[0, 1)` with 24 random bits.
    pub(crate) fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
}
