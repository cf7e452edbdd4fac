//! Seeded randomness: a SplitMix64 stream for sequential draws and a stateless
//! counter-based hash for per-item draws.
//!
//! Every random quantity in nrdepth derives from a `u64` seed through these two
//! functions, never from thread-local or OS entropy. The per-item hash makes a
//! draw a pure function of its key (seed, channel, frequency, ...), so results do
//! not depend on evaluation order, batch split or thread count.

/// The SplitMix64 output mixer (Steele, Lea & Flood 2014): a bijection on u64
/// with full avalanche.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

const GOLDEN: u64 = 0x9e37_79b9_7f4a_7c15;

/// Hash of a seed and a key of integers: `hash(seed, &[a, b, c])`.
#[inline]
pub fn hash(seed: u64, key: &[u64]) -> u64 {
    let mut h = mix64(seed ^ GOLDEN);
    for &k in key {
        h = mix64(h.wrapping_add(GOLDEN) ^ k);
    }
    h
}

/// Uniform in [0, 1) with 53 random bits.
#[inline]
pub fn unit_f64(bits: u64) -> f64 {
    (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A sequential SplitMix64 stream.
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        Self { state: mix64(seed) }
    }

    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN);
        mix64(self.state)
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn unit(&mut self) -> f64 {
        unit_f64(self.next_u64())
    }

    /// Uniform in [lo, hi] (lo when the range is empty).
    #[inline]
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Log-uniform in [lo, hi], both > 0.
    #[inline]
    pub fn log_uniform(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.unit()).exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stream_is_reproducible_and_uniform() {
        let mut a = SplitMix64::new(7);
        let mut b = SplitMix64::new(7);
        let xs: Vec<f64> = (0..100_000).map(|_| a.unit()).collect();
        assert!(xs.iter().all(|&x| (0.0..1.0).contains(&x)));
        assert_eq!(xs[..10], (0..10).map(|_| b.unit()).collect::<Vec<_>>()[..]);
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64;
        assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 0.002, "var {var}");
    }

    #[test]
    fn hash_depends_on_every_key_part_and_order() {
        let base = hash(1, &[2, 3]);
        assert_ne!(base, hash(2, &[2, 3]));
        assert_ne!(base, hash(1, &[3, 2]));
        assert_ne!(base, hash(1, &[2, 4]));
        assert_ne!(base, hash(1, &[2, 3, 0]));
        assert_eq!(base, hash(1, &[2, 3]));
    }
}
