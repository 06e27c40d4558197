//! `fusion`: a tokamak-like torus (major radius 1, elongated cross-section), its cells ~10×
//! finer near the centre line, like the Fusion data set, whose tets "are densely packed
//! around the center line of the torus".
//!
//! The cross-section is a square grid of columns, kept where the cell centre lies in the
//! unit disk (a staircase boundary), warped radially towards the centre line; each column is
//! swept around the torus axis in `nk` toroidal steps (periodic).

use super::grid::{ColumnShape, Columns, LEVEL_JITTER, XY_JITTER};
use super::noise::{column_jitter, level_jitter, splitmix64};
use crate::geom::Vec3;
use std::f64::consts::{PI, TAU};

/// Occupancy π²ρ / (4(1+ρ)²) of a torus with aspect ρ = minor / major radius in its box
/// (independent of the elongation); ρ = 0.4786 gives the 54 % we aim for.
pub(super) const OCCUPANCY: f64 = 0.54;
const MINOR: f64 = 0.4786;
/// The torus's major radius (the centre line's).
pub(super) const MAJOR: f64 = 1.0;
/// Vertical stretch of the cross-section (tokamak plasmas are taller than wide).
pub(super) const ELONGATION: f64 = 1.4;
/// Radial warp: spacing at the centre line over the mean spacing...
const CORE_SPACING: f64 = 0.1;
/// ...reached within about √CORE_RADIUS2 of the minor radius.
const CORE_RADIUS2: f64 = 0.3;
/// Toroidal cell length at the major radius, over the cross-section's grid spacing.
const TOROIDAL_SPACING: f64 = 0.6;
/// Rotates the sweep so no toroidal step lands on a coordinate plane.
const PHI0: f64 = 0.1;

pub(super) struct Fusion {
    columns: Columns,
    /// Columns per minor radius.
    m: usize,
    seed: u64,
}

impl Fusion {
    pub fn new(cells: usize, seed: u64) -> Fusion {
        // ~π m² columns in the disk, each swept in ~2π m / (ρ·TOROIDAL_SPACING) steps.
        let per_m3 = PI * TAU / (MINOR * TOROIDAL_SPACING);
        let m = ((cells as f64 / per_m3).cbrt().round() as usize).max(2);
        let n = 2 * m;
        let keep: Vec<bool> = (0..n * n)
            .map(|c| {
                let (a, b) = ((c % n) as f64 + 0.5 - m as f64, (c / n) as f64 + 0.5 - m as f64);
                a * a + b * b < (m * m) as f64
            })
            .collect();
        let mut columns = Columns { ni: n, nj: n, nk: 0, periodic_k: true, keep };
        columns.nk = ((cells as f64 / columns.n_kept() as f64).round() as usize).max(12);
        Fusion { columns, m, seed: splitmix64(seed ^ 0x4655_5349) }
    }
}

/// Radial warp factor g(s)/s at squared normalised radius s²: CORE_SPACING at the centre
/// line, 1 on the unit circle, growing monotonically. A smooth function of s², so the warp
/// is smooth across the centre line; g(s) increases, so it preserves orientation.
fn warp(s2: f64) -> f64 {
    CORE_SPACING + (1.0 - CORE_SPACING) * (1.0 + CORE_RADIUS2) * s2 / (CORE_RADIUS2 + s2)
}

impl ColumnShape for Fusion {
    fn columns(&self) -> &Columns {
        &self.columns
    }

    fn column_points(&self, i: usize, j: usize, out: &mut [Vec3]) {
        let m = self.m as f64;
        let nk = self.columns.nk;
        let (ja, jb) = column_jitter(self.seed, i, j);
        let a = (i as f64 - m + XY_JITTER * ja) / m;
        let b = (j as f64 - m + XY_JITTER * jb) / m;
        let w = MINOR * warp(a * a + b * b);
        // (a, b, -φ) is right-handed in (radius, height, toroidal angle): φ decreases with k.
        let (radius, z) = (MAJOR + a * w, ELONGATION * b * w);
        for (k, p) in out.iter_mut().enumerate() {
            let phi = PHI0 - (k as f64 + LEVEL_JITTER * level_jitter(self.seed, i, j, k)) * TAU / nk as f64;
            *p = [(radius * phi.cos()) as f32, (radius * phi.sin()) as f32, z as f32];
        }
    }
}
