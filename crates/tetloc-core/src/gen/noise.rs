//! Reproducible randomness: per-vertex jitter from a hash (the same whichever thread computes
//! a vertex) and smooth 2D noise from a few random plane waves.

use rand::Rng;
use rand_pcg::Pcg64;
use std::f64::consts::TAU;

#[inline]
pub(super) fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[inline]
fn hash(seed: u64, i: usize, j: usize, k: u64) -> u64 {
    splitmix64(splitmix64(splitmix64(seed ^ i as u64) ^ j as u64) ^ k)
}

/// 32 random bits as a value in [-1, 1).
#[inline]
fn signed_unit(bits: u32) -> f64 {
    bits as f64 / 2_147_483_648.0 - 1.0
}

/// Jitter of vertex column (i, j) in its two in-plane directions, each in [-1, 1).
#[inline]
pub(super) fn column_jitter(seed: u64, i: usize, j: usize) -> (f64, f64) {
    let h = hash(seed, i, j, u64::MAX);
    (signed_unit((h >> 32) as u32), signed_unit(h as u32))
}

/// Jitter of level k of vertex column (i, j), in [-1, 1).
#[inline]
pub(super) fn level_jitter(seed: u64, i: usize, j: usize, k: usize) -> f64 {
    signed_unit((hash(seed, i, j, k as u64) >> 32) as u32)
}

/// Smooth 2D noise: a sum of plane waves with random directions and phases, wavelengths
/// spread log-uniformly between two scales and amplitudes proportional to wavelength, so
/// large features dominate (continents, basins) and small ones roughen them.
pub(super) struct Noise2 {
    /// kx, ky, phase, amplitude (amplitudes sum to 1, so values lie in [-1, 1]).
    waves: Vec<[f64; 4]>,
}

impl Noise2 {
    pub fn new(rng: &mut Pcg64, n: usize, min_wavelength: f64, max_wavelength: f64) -> Noise2 {
        let n = n.max(1);
        let mut waves: Vec<[f64; 4]> = (0..n)
            .map(|m| {
                let t = if n > 1 { m as f64 / (n - 1) as f64 } else { 0.0 };
                let wavelength = max_wavelength * (min_wavelength / max_wavelength).powf(t);
                let angle = rng.gen::<f64>() * TAU;
                let k = TAU / wavelength;
                [k * angle.cos(), k * angle.sin(), rng.gen::<f64>() * TAU, wavelength]
            })
            .collect();
        let sum: f64 = waves.iter().map(|w| w[3]).sum();
        for w in &mut waves {
            w[3] /= sum;
        }
        Noise2 { waves }
    }

    #[inline]
    pub fn at(&self, x: f64, y: f64) -> f64 {
        self.waves.iter().map(|w| w[3] * (w[0] * x + w[1] * y + w[2]).sin()).sum()
    }
}

/// 0 below `a`, 1 above `b`, smooth in between.
#[inline]
pub(super) fn smoothstep(a: f64, b: f64, x: f64) -> f64 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}
