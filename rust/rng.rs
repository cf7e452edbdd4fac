//! Seeded randomness: a SplitMix64 stream for sequential draws and a stateless
//! counter-based hash for per-item draws.
//!
//! Every random quantity in nrdepth derives from a `u64` seed through these two
//! functions, never from thread-local or OS entropy. The per-item hash makes a
//! draw a pure function of its key (seed, channel, frequency, ...), so results do
//! not depend on evaluation order, batch split or thread count.
//!
//! Standard normals (`normals8`) come from those bits by Box–Muller in f32
//! with plain IEEE operations only, so they too are the same on every platform.

use std::f32::consts::{FRAC_1_SQRT_2, FRAC_PI_2, LN_2, SQRT_2};

use wide::{f32x4, i32x4, u32x4};

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

/// Eight independent standard normals from four random words (Box–Muller):
/// word j gives normals 2j and 2j + 1 as r·(cos φ, sin φ), r = √(−2 ln u₁),
/// with u₁ = (2k + 1)/2²⁴ from its top 23 bits and φ uniform on the circle
/// from its low 24 bits. Polynomial ln, sin and cos in plain f32 operations
/// (no libm, no fused multiply-add): the same bits on every platform, within
/// 1e-5 of the exact transform of the same uniforms (tested).
#[inline]
pub fn normals8(words: [u64; 4]) -> [f32; 8] {
    let splat = f32x4::splat;
    // ln u₁ = e ln 2 + ln m, m in [√½, √2): ln m = 2 atanh s, s = (m − 1)/(m + 1), |s| < 0.172.
    let u1 = f32x4::new(words.map(|w| (((w >> 41) << 1) | 1) as f32 * (1.0 / (1u32 << 24) as f32)));
    let bits: u32x4 = wide::bytemuck::cast(u1);
    let m: f32x4 = wide::bytemuck::cast((bits & u32x4::splat(0x007f_ffff)) | u32x4::splat(0x3f80_0000));
    let e = f32x4::from_i32x4(wide::bytemuck::cast::<u32x4, i32x4>(bits >> 23) - i32x4::splat(127));
    let high = m.simd_gt(splat(SQRT_2));
    let (m, e) = (high.select(m * splat(0.5), m), high.select(e + splat(1.0), e));
    let s = (m - splat(1.0)) / (m + splat(1.0));
    let s2 = s * s;
    let ln_m = s * (splat(2.0) + s2 * (splat(2.0 / 3.0) + s2 * (splat(2.0 / 5.0) + s2 * splat(2.0 / 7.0))));
    let r = (splat(-2.0) * (e * splat(LN_2) + ln_m)).sqrt();
    // φ = q·π/2 + π/4 + θ: quadrant q from two bits, θ in (−π/4, π/4) from 22.
    let theta = f32x4::new(words.map(|w| ((w & 0x3f_ffff) as f32 + 0.5) * (1.0 / (1u32 << 22) as f32) - 0.5)) * splat(FRAC_PI_2);
    let t2 = theta * theta;
    let sin = theta * (splat(1.0) + t2 * (splat(-1.0 / 6.0) + t2 * (splat(1.0 / 120.0) + t2 * splat(-1.0 / 5040.0))));
    let cos = splat(1.0) + t2 * (splat(-0.5) + t2 * (splat(1.0 / 24.0) + t2 * (splat(-1.0 / 720.0) + t2 * splat(1.0 / 40320.0))));
    let (x, y) = ((cos - sin) * splat(FRAC_1_SQRT_2) * r, (cos + sin) * splat(FRAC_1_SQRT_2) * r);
    // Rotate (x, y) by q quarter turns, branch-free (q is random: a branch
    // would be mispredicted half the time): q odd swaps, (−y, x) and (y, −x);
    // the first is negated for q in {1, 2}, the second for q in {2, 3}
    // (sign flips, exact).
    let q = u32x4::new(words.map(|w| ((w >> 22) & 3) as u32));
    let sign = |flip: u32x4| wide::bytemuck::cast::<u32x4, f32x4>(flip & u32x4::splat(0x8000_0000));
    let (low, high): (u32x4, u32x4) = (q & u32x4::ONE, q >> 1);
    let odd: f32x4 = wide::bytemuck::cast(low.simd_eq(u32x4::ONE));
    let (first, second) = (odd.bitselect(y, x) ^ sign((low ^ high).simd_eq(u32x4::ONE)), odd.bitselect(x, y) ^ sign(high.simd_eq(u32x4::ONE)));
    let (first, second) = (first.to_array(), second.to_array());
    std::array::from_fn(|k| if k % 2 == 0 { first[k / 2] } else { second[k / 2] })
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

    /// The exact Box–Muller transform, in f64, of the uniforms `normals8` reads.
    fn exact_pair(w: u64) -> [f64; 2] {
        let u1 = (((w >> 41) << 1) | 1) as f64 / (1u64 << 24) as f64;
        let turn = (((w >> 22) & 3) as f64 + ((w & 0x3f_ffff) as f64 + 0.5) / (1u64 << 22) as f64) / 4.0;
        let (r, phi) = ((-2.0 * u1.ln()).sqrt(), std::f64::consts::TAU * turn);
        [r * phi.cos(), r * phi.sin()]
    }

    #[test]
    fn normals_are_the_box_muller_transform_and_standard() {
        let mut stream = SplitMix64::new(11);
        let mut samples = Vec::new();
        // Random words, and the extremes of every bit field.
        let edges = [0, u64::MAX, 1 << 41, (1 << 41) - 1, 0x3f_ffff, 0x40_0000, 0xc0_0000, 0xff_ffff];
        for g in 0..60_000 {
            let words = if g < 2 { std::array::from_fn(|j| edges[4 * g + j]) } else { std::array::from_fn(|_| stream.next_u64()) };
            let n = normals8(words);
            for (j, &w) in words.iter().enumerate() {
                let exact = exact_pair(w);
                for k in 0..2 {
                    assert!((n[2 * j + k] as f64 - exact[k]).abs() < 1e-5, "word {w:#x}: {} vs {}", n[2 * j + k], exact[k]);
                }
            }
            samples.extend(n.map(f64::from));
        }
        let count = samples.len() as f64;
        let mean = samples.iter().sum::<f64>() / count;
        let var = samples.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / count;
        let beyond_2 = samples.iter().filter(|x| x.abs() > 2.0).count() as f64 / count;
        // Normals of one pair are uncorrelated.
        let pair_corr = samples.chunks_exact(2).map(|p| p[0] * p[1]).sum::<f64>() / (count / 2.0);
        assert!(mean.abs() < 0.005 && (var - 1.0).abs() < 0.01, "mean {mean}, var {var}");
        assert!((beyond_2 - 0.0455).abs() < 0.002, "P(|n| > 2) = {beyond_2}");
        assert!(pair_corr.abs() < 0.01, "pair correlation {pair_corr}");
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
