//! The seeded uniform generator of the estimators' unit tests: Marsaglia's xorshift
//! (shifts 13, 7, 17; Marsaglia, *J. Statistical Software* 8 (14), 2003), the top 53 bits
//! as a uniform number in [0, 1). Deterministic, so a Monte Carlo test gives the same
//! figures on every run and machine.

/// A xorshift state (any nonzero seed).
pub(crate) struct Xorshift(u64);

impl Xorshift {
    /// The generator started at `seed` (nonzero).
    pub(crate) fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next uniform number in [0, 1), 53 bits.
    pub(crate) fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}
