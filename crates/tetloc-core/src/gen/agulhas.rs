//! `agulhas`: an ocean layer like the Agulhas Current data set, whose tets cover only the
//! "wet" cells: a thin slab (2 × 1.5 wide, at most 0.1 deep) from a gently waving sea surface
//! down to a smooth bathymetry that shoals towards the coasts, with continents (smooth noise)
//! cut out as holes through the whole layer. Terrain-following layers, finer near the surface.

use super::grid::{column_xy, keep_lowest, ColumnShape, Columns, LayerPlan, LEVEL_JITTER};
use super::noise::{level_jitter, smoothstep, splitmix64, Noise2};
use super::terrain::Terrain;
use crate::geom::Vec3;
use rand::SeedableRng;
use rand_pcg::Pcg64;
use rayon::prelude::*;

pub(super) const OCCUPANCY: f64 = 0.49;
const WIDTH: f64 = 2.0;
const LENGTH: f64 = 1.5;
const DEPTH: f64 = 0.1;
/// Share of the columns that are sea.
const WET: f64 = 0.7;
/// Mean layer thickness over horizontal spacing (ocean cells are flat).
const FLATNESS: f64 = 0.5;
/// Sea surface height amplitude, relative to DEPTH.
const SURFACE: f64 = 0.01;
/// Mean depth over DEPTH we expect when choosing the number of layers.
const MEAN_DEPTH: f64 = 0.7;
/// Highest land of the terrain above the sea surface, relative to DEPTH.
const LAND_HEIGHT: f64 = 0.4;
/// The terrain's grid has at most this many squares along its longer side.
const TERRAIN_SIDE: usize = 512;

pub(super) struct Agulhas {
    columns: Columns,
    /// Horizontal spacing.
    h: f64,
    land: Noise2,
    bottom: Noise2,
    surface: Noise2,
    /// Land noise at the coast (the largest wet value), and its typical spread.
    coast: f64,
    spread: f64,
    /// Normalises the raw bathymetry to [0, 1] over the sea.
    t_min: f64,
    t_max: f64,
    /// Depth of the shallowest sea, relative to DEPTH: set so that the occupancy comes out right.
    shallow: f64,
    seed: u64,
}

impl Agulhas {
    pub fn new(cells: usize, seed: u64) -> Agulhas {
        let mut rng = Pcg64::seed_from_u64(seed ^ 0x4147_554c);
        // Wet columns of nk layers, layer thickness ≈ FLATNESS · h.
        let plan = LayerPlan::new(cells, WET, WIDTH, LENGTH, MEAN_DEPTH * DEPTH / FLATNESS);
        let LayerPlan { ni, nj, nk, n_keep: n_wet, h } = plan;

        let land = Noise2::new(&mut rng, 8, 0.25, 2.0);
        let bottom = Noise2::new(&mut rng, 6, 0.15, 1.2);
        let surface = Noise2::new(&mut rng, 4, 0.3, 1.0);
        let centre = |c: usize| plan.centre(c);
        let land_at: Vec<f64> = (0..ni * nj)
            .into_par_iter()
            .map(|c| {
                let (x, y) = centre(c);
                land.at(x, y)
            })
            .collect();
        let keep = keep_lowest(&land_at, n_wet);
        let coast = (0..ni * nj).filter(|&c| keep[c]).map(|c| land_at[c]).fold(f64::MIN, f64::max);
        let mean = land_at.iter().sum::<f64>() / land_at.len() as f64;
        let spread = (land_at.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / land_at.len() as f64).sqrt().max(1e-6);
        let columns = Columns { ni, nj, nk, periodic_k: false, keep };

        let mut sea = Agulhas {
            columns,
            h,
            land,
            bottom,
            surface,
            coast,
            spread,
            t_min: 0.0,
            t_max: 1.0,
            shallow: 0.0,
            seed: splitmix64(seed),
        };
        // Normalise the bathymetry over the sea, then pick the shallowest depth that gives
        // the occupancy: wet share of the box × mean depth / box height.
        let t: Vec<f64> = (0..ni * nj)
            .into_par_iter()
            .filter(|&c| sea.columns.keep[c])
            .map(|c| {
                let (x, y) = centre(c);
                sea.raw_bathymetry(x, y)
            })
            .collect();
        sea.t_min = t.iter().copied().fold(f64::MAX, f64::min);
        sea.t_max = t.iter().copied().fold(f64::MIN, f64::max).max(sea.t_min + 1e-9);
        let t_mean = t.iter().map(|&v| (v - sea.t_min) / (sea.t_max - sea.t_min)).sum::<f64>() / t.len() as f64;
        let mean_depth = OCCUPANCY * (1.0 + SURFACE) / sea.columns.kept_box_fraction();
        sea.shallow = ((mean_depth - t_mean) / (1.0 - t_mean).max(1e-9)).clamp(0.1, 0.95);
        sea
    }

    /// Deep away from the coast (continental shelves), roughened by its own noise.
    fn raw_bathymetry(&self, x: f64, y: f64) -> f64 {
        let offshore = (self.coast - self.land.at(x, y)) / self.spread;
        0.6 * smoothstep(0.0, 0.6, offshore) + 0.4 * self.bottom.at(x, y)
    }

    /// The ground: the sea floor under the wet columns, rising into land where the continents
    /// cut through the layer. Sampled at every `stride`-th vertex column (at most
    /// TERRAIN_SIDE squares a side); a node of a wet column sits exactly on the mesh's bottom.
    pub fn terrain(&self) -> Terrain {
        let Columns { ni, nj, ref keep, .. } = self.columns;
        let stride = ni.max(nj).div_ceil(TERRAIN_SIDE).max(1);
        // Vertex column (i, j) is a corner of columns i-1..=i, j-1..=j.
        let wet = |i: usize, j: usize| {
            (i.saturating_sub(1)..=i.min(ni - 1))
                .any(|ci| (j.saturating_sub(1)..=j.min(nj - 1)).any(|cj| keep[cj * ni + ci]))
        };
        Terrain::height_field(ni.div_ceil(stride), nj.div_ceil(stride), |ti, tj| {
            let (i, j) = ((ti * stride).min(ni), (tj * stride).min(nj));
            let (x, y) = column_xy(self.seed, i, j, self.h);
            let floor = -self.depth(x, y);
            let z = if wet(i, j) {
                floor
            } else {
                // How far inland, in units of the land noise's spread.
                let inland = (self.land.at(x, y) - self.coast) / self.spread;
                floor + (LAND_HEIGHT * DEPTH - floor) * smoothstep(0.0, 1.0, inland)
            };
            [x as f32, y as f32, z as f32]
        })
    }

    fn depth(&self, x: f64, y: f64) -> f64 {
        let t = ((self.raw_bathymetry(x, y) - self.t_min) / (self.t_max - self.t_min)).clamp(0.0, 1.0);
        DEPTH * (self.shallow + (1.0 - self.shallow) * t)
    }
}

impl ColumnShape for Agulhas {
    fn columns(&self) -> &Columns {
        &self.columns
    }

    fn column_points(&self, i: usize, j: usize, out: &mut [Vec3]) {
        let nk = self.columns.nk;
        let (x, y) = column_xy(self.seed, i, j, self.h);
        let top = SURFACE * DEPTH * self.surface.at(x, y);
        let bottom = -self.depth(x, y);
        for (k, p) in out.iter_mut().enumerate() {
            let jz = if k == 0 || k == nk { 0.0 } else { LEVEL_JITTER * level_jitter(self.seed, i, j, k) };
            let s = (k as f64 + jz) / nk as f64;
            // Layers 3× thinner at the surface than at the bottom (monotone in s).
            let s = s + 0.5 * s * (1.0 - s);
            *p = [x as f32, y as f32, (bottom + (top - bottom) * s) as f32];
        }
    }
}
