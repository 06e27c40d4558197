//! `japan`: a thin irregular layer like the Japan earthquake data set, of which only the
//! nonzero cells (7.15 % of the box) are tets: a sheet of varying thickness (mean 0.04)
//! along an island arc with ragged edges, dipping steeply under the arc like a subducting
//! plate, inside a box 1 × 1.6 wide and as tall as the sheet's dip.

use super::grid::{column_xy, keep_lowest, ColumnShape, Columns, LayerPlan, LEVEL_JITTER};
use super::noise::{level_jitter, splitmix64, Noise2};
use crate::geom::Vec3;
use rand::SeedableRng;
use rand_pcg::Pcg64;
use rayon::prelude::*;

pub(super) const OCCUPANCY: f64 = 0.0715;
const WIDTH: f64 = 1.0;
const LENGTH: f64 = 1.6;
/// Mean sheet thickness; the thickness varies from half to 1.5 times this.
const THICKNESS: f64 = 0.04;
/// Share of the grid's columns in the sheet's footprint.
const FOOTPRINT: f64 = 0.55;
/// The arc: a circle (centre, radius) crossing the grid, and the footprint's half-width.
const ARC_CENTRE: (f64, f64) = (1.9, 0.8);
const ARC_RADIUS: f64 = 1.45;
const BAND: f64 = 0.3;

pub(super) struct Japan {
    columns: Columns,
    h: f64,
    undulation: Noise2,
    thickness: Noise2,
    /// Normalises the raw surface to [0, 1] over the footprint.
    s_min: f64,
    s_max: f64,
    /// Depth of the sheet's dip: set so that the occupancy comes out right.
    dip: f64,
    seed: u64,
}

/// Signed distance inside the arc (towards its centre, where the plate has dived).
fn inside_arc(x: f64, y: f64) -> f64 {
    ARC_RADIUS - (x - ARC_CENTRE.0).hypot(y - ARC_CENTRE.1)
}

impl Japan {
    pub fn new(cells: usize, seed: u64) -> Japan {
        let mut rng = Pcg64::seed_from_u64(seed ^ 0x4a50_4e00);
        // Footprint columns of nk layers, layer thickness ≈ spacing h.
        let plan = LayerPlan::new(cells, FOOTPRINT, WIDTH, LENGTH, THICKNESS);
        let LayerPlan { ni, nj, nk, n_keep, h } = plan;

        let edges = Noise2::new(&mut rng, 6, 0.08, 0.8);
        let undulation = Noise2::new(&mut rng, 5, 0.2, 1.2);
        let thickness = Noise2::new(&mut rng, 5, 0.15, 1.0);
        let centre = |c: usize| plan.centre(c);
        // Footprint: the columns nearest the arc, with ragged edges.
        let outline: Vec<f64> = (0..ni * nj)
            .into_par_iter()
            .map(|c| {
                let (x, y) = centre(c);
                inside_arc(x, y).abs() / BAND + 0.6 * edges.at(x, y)
            })
            .collect();
        let columns = Columns { ni, nj, nk, periodic_k: false, keep: keep_lowest(&outline, n_keep) };

        let mut sheet =
            Japan { columns, h, undulation, thickness, s_min: 0.0, s_max: 1.0, dip: 0.0, seed: splitmix64(seed) };
        let kept: Vec<(f64, f64)> = (0..ni * nj).filter(|&c| sheet.columns.keep[c]).map(centre).collect();
        let s: Vec<f64> = kept.par_iter().map(|&(x, y)| sheet.raw_surface(x, y)).collect();
        sheet.s_min = s.iter().copied().fold(f64::MAX, f64::min);
        sheet.s_max = s.iter().copied().fold(f64::MIN, f64::max).max(sheet.s_min + 1e-9);
        // Occupancy = footprint share of the box × mean thickness / box height, and the box
        // is as tall as the dip plus about a mean thickness.
        let mean_thickness = {
            // Summed in order, not in parallel: the result must not depend on the thread count.
            let th: Vec<f64> = kept.par_iter().map(|&(x, y)| sheet.thickness_at(x, y)).collect();
            th.iter().sum::<f64>() / th.len() as f64
        };
        let height = mean_thickness * sheet.columns.kept_box_fraction() / OCCUPANCY;
        sheet.dip = (height - mean_thickness).max(mean_thickness);
        sheet
    }

    /// The plate bends down under the arc, with gentle undulations.
    fn raw_surface(&self, x: f64, y: f64) -> f64 {
        (inside_arc(x, y) / 0.15).tanh() + 0.3 * self.undulation.at(x, y)
    }

    fn thickness_at(&self, x: f64, y: f64) -> f64 {
        THICKNESS * (1.0 + 0.5 * self.thickness.at(x, y))
    }
}

impl ColumnShape for Japan {
    fn columns(&self) -> &Columns {
        &self.columns
    }

    fn column_points(&self, i: usize, j: usize, out: &mut [Vec3]) {
        let nk = self.columns.nk;
        let (x, y) = column_xy(self.seed, i, j, self.h);
        let s = ((self.raw_surface(x, y) - self.s_min) / (self.s_max - self.s_min)).clamp(-0.1, 1.1);
        let mid = -self.dip * s;
        let th = self.thickness_at(x, y);
        for (k, p) in out.iter_mut().enumerate() {
            let jz = if k == 0 || k == nk { 0.0 } else { LEVEL_JITTER * level_jitter(self.seed, i, j, k) };
            let z = mid + th * ((k as f64 + jz) / nk as f64 - 0.5);
            *p = [x as f32, y as f32, z as f32];
        }
    }
}
