//! The polyhedral oracle sets of `poly/` (`octpoly_s`: an affinely mapped octree of hexes and
//! polyhedra, as a `.vtu` and as an OpenFOAM case; exact cell ids and the exact values of the
//! affine point field `lin`), and the comparison every backend's test makes against them.
//!
//! `tetloc-testdata` includes this same file (`#[path]`) for every other crate's tests.

use super::{require_data, BatchLocator, Vec3};
use std::path::{Path, PathBuf};

/// One query set of `poly/`: points, exact cells (-1 outside), exact `lin` (NaN outside).
pub struct PolySet {
    /// e.g. `octpoly_s.random`
    pub label: String,
    pub points: Vec<Vec3>,
    pub cell: Vec<i32>,
    pub lin: Vec<f64>,
    /// bit0: within 1e-6 (box units) of a face: either cell is right.
    pub flags: Vec<u8>,
}

fn read_le<T: bytemuck::Pod>(path: &Path) -> Vec<T> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    bytemuck::pod_collect_to_vec(&bytes)
}

/// The `poly/` folder and its sets (`random`, `bbox`), or `None` after a skip (no data).
pub fn poly_sets(test: &str) -> Option<(PathBuf, Vec<PolySet>)> {
    let dir = require_data(test)?.join("poly");
    let sets = ["random", "bbox"]
        .iter()
        .map(|set| {
            let f = |what: &str| dir.join(format!("octpoly_s.{set}.{what}.bin"));
            let points: Vec<f32> = read_le(&f("points"));
            PolySet {
                label: format!("octpoly_s.{set}"),
                points: points.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
                cell: read_le(&f("cell")),
                lin: read_le(&f("lin")),
                flags: read_le(&f("flags")),
            }
        })
        .collect();
    Some((dir, sets))
}

/// How a set's answers compare with the oracle, outside the points near faces.
#[derive(Debug, Default, PartialEq)]
pub struct PolyMismatch {
    /// Oracle inside, answer outside (a crack).
    pub lost: usize,
    /// Oracle outside, answer inside.
    pub extra: usize,
    /// Both inside, other cells.
    pub other: usize,
    /// `lin` off by more than rounding (1e-9 relative), in f64.
    pub values: usize,
    /// The f32 path (`sample_many`) answers another cell than the f64 one, or a value off by
    /// more than 1e-5 relative (off the near-face points).
    pub f32_path: usize,
}

/// Compares `loc`'s cells (f32 `locate` and f64 `sample_many64`) and `field`'s values (the
/// point field `lin`, or its cell values `lin_cell` when `cell_values` is given) on `set`.
pub fn compare_poly(
    loc: &mut dyn BatchLocator,
    set: &PolySet,
    field: &str,
    cell_values: Option<&[f64]>,
) -> PolyMismatch {
    let n = set.points.len();
    let points64: Vec<[f64; 3]> = set.points.iter().map(|p| p.map(f64::from)).collect();
    let (mut ids, mut values) = (vec![0; n], vec![0f64; n]);
    loc.sample_many64(&points64, &[field], &mut ids, &mut values).unwrap();
    let (mut ids32, mut values32) = (vec![0; n], vec![0f32; n]);
    loc.sample_many(&set.points, &[field], &mut ids32, &mut values32).unwrap();
    let mut m = PolyMismatch::default();
    for i in 0..n {
        if set.flags[i] & 1 != 0 {
            continue;
        }
        let (got, want) = (ids[i], set.cell[i]);
        let want_value = (want >= 0).then(|| cell_values.map_or(set.lin[i], |c| c[want as usize]));
        let value32_ok = want_value.is_none_or(|w| (f64::from(values32[i]) - w).abs() <= 1e-5 * w.abs());
        if ids32[i] != got || !value32_ok {
            m.f32_path += 1;
        }
        match (want >= 0, got >= 0) {
            (true, false) => m.lost += 1,
            (false, true) => m.extra += 1,
            (true, true) if got != want => m.other += 1,
            (true, true) => {
                let want = want_value.expect("inside");
                if (values[i] - want).abs() > 1e-9 * want.abs() {
                    m.values += 1;
                }
            }
            (false, false) => {}
        }
    }
    m
}

/// A little-endian `.npy` of f64 (the `lin_cell` values: `lin` at each cell's centroid).
pub fn read_npy_f64(path: &Path) -> Vec<f64> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    bytemuck::pod_collect_to_vec(&bytes[10 + header_len..])
}
