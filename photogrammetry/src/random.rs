//! The workspace's one seeded random generator: SplitMix64, counter-based, so that every pixel, frame and
//! sample draws the same numbers whatever the thread schedule, and a run repeats byte for byte. The synthetic
//! scenes, the benchmarks' noise and new samplers draw from here; do not add another generator.

/// SplitMix64's increment (2⁶⁴ / φ).
const GOLDEN_GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;

/// SplitMix64 finaliser: a well-mixed 64-bit hash of a 64-bit input.
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(GOLDEN_GAMMA);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A hash of several integers.
pub fn hash(parts: &[u64]) -> u64 {
    parts.iter().fold(0x243F_6A88_85A3_08D3, |h, &p| mix64(h ^ p))
}

/// Uniform in [0, 1) from a hash.
pub fn unit(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A small sequential generator for scene construction.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator for one purpose (`stream`) of one seed.
    pub fn new(seed: u64, stream: u64) -> Self {
        Rng(hash(&[seed, stream]))
    }
    /// A generator that continues a SplitMix64 stream from its raw state: the first draw is `mix64(state + γ)`.
    /// For sequences fixed before this module existed (ORB's comparison pattern, seed 004's start perturbations),
    /// which must not change; new code takes [`Rng::new`].
    pub fn from_state(state: u64) -> Self {
        Rng(state.wrapping_sub(GOLDEN_GAMMA))
    }
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(GOLDEN_GAMMA);
        mix64(self.0)
    }
    /// Uniform in `0..n` (0 when `n` is 0). The modulo bias is below 2⁻³² for any `n` a sample draws from.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * unit(self.next_u64())
    }
    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        gaussian(self.next_u64(), self.next_u64())
    }
}

/// A standard normal deviate from two hashes.
pub fn gaussian(a: u64, b: u64) -> f64 {
    let u1 = unit(a).max(1e-300);
    let u2 = unit(b);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stream_repeats_and_streams_differ() {
        let draw = |stream| {
            let mut r = Rng::new(7, stream);
            (0..4).map(|_| r.next_u64()).collect::<Vec<_>>()
        };
        assert_eq!(draw(1), draw(1));
        assert_ne!(draw(1), draw(2));
    }

    #[test]
    fn from_state_continues_a_raw_splitmix_stream() {
        // The textbook SplitMix64: add γ, then finalise.
        let mut state = 0x6C69_6E65_666C_6F77u64;
        let mut textbook = || {
            state = state.wrapping_add(GOLDEN_GAMMA);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        };
        let mut r = Rng::from_state(0x6C69_6E65_666C_6F77);
        for _ in 0..5 {
            assert_eq!(r.next_u64(), textbook());
        }
    }

    #[test]
    fn draws_stay_in_their_ranges() {
        let mut r = Rng::new(1, 0);
        for _ in 0..1000 {
            assert!(r.below(7) < 7);
            let u = r.uniform(-2.0, 3.0);
            assert!((-2.0..3.0).contains(&u));
        }
        assert_eq!(r.below(0), 0);
    }
}
