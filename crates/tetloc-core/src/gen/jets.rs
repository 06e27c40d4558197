//! `jets`: a box [0,1]×[0,1]×[0,2] filled completely, like the Jets data set: cells ~3× finer
//! near the jet axis (x = y = 0.5) and ~4× finer near the inflow plane z = 0. The box faces
//! stay exactly flat (boundary vertices move only within their face) so the box is full.

use super::grid::{ColumnShape, Columns, LEVEL_JITTER, XY_JITTER};
use super::noise::{column_jitter, level_jitter, splitmix64};
use crate::geom::Vec3;
use std::f64::consts::TAU;

const HEIGHT: f64 = 2.0;
/// Spacing across the box goes from 1 - SIDE_GRADING (axis) to 1 + SIDE_GRADING (walls).
const SIDE_GRADING: f64 = 0.5;
/// Spacing along z grows from INFLOW_SPACING at z = 0 to 2 - INFLOW_SPACING at the top.
const INFLOW_SPACING: f64 = 0.4;

pub(super) struct Jets {
    columns: Columns,
    seed: u64,
}

impl Jets {
    pub fn new(cells: usize, seed: u64) -> Jets {
        // n × n columns of 2n cells (the box is twice as tall), then the column height that
        // best matches the cell count.
        let n = ((cells as f64 / HEIGHT).cbrt().round() as usize).max(2);
        let nk = ((cells as f64 / (n * n) as f64).round() as usize).max(2);
        Jets { columns: Columns::full(n, n, nk), seed: splitmix64(seed ^ 0x4a45_5453) }
    }
}

/// Monotone map of [0,1] onto itself, finer in the middle.
fn across(u: f64) -> f64 {
    u + SIDE_GRADING * (TAU * u).sin() / TAU
}

/// Monotone map of [0,1] onto itself, finer at 0.
fn along(w: f64) -> f64 {
    w * (INFLOW_SPACING + (1.0 - INFLOW_SPACING) * w)
}

impl ColumnShape for Jets {
    fn columns(&self) -> &Columns {
        &self.columns
    }

    fn column_points(&self, i: usize, j: usize, out: &mut [Vec3]) {
        let Columns { ni, nj, nk, .. } = self.columns;
        let (ju, jv) = column_jitter(self.seed, i, j);
        // Vertices on a side wall move only along it.
        let ju = if i == 0 || i == ni { 0.0 } else { XY_JITTER * ju };
        let jv = if j == 0 || j == nj { 0.0 } else { XY_JITTER * jv };
        let x = across((i as f64 + ju) / ni as f64);
        let y = across((j as f64 + jv) / nj as f64);
        for (k, p) in out.iter_mut().enumerate() {
            let jw = if k == 0 || k == nk { 0.0 } else { LEVEL_JITTER * level_jitter(self.seed, i, j, k) };
            let z = HEIGHT * along((k as f64 + jw) / nk as f64);
            *p = [x as f32, y as f32, z as f32];
        }
    }
}
