//! The mixed-cell oracle sets of `mixed/` (hexwarp, hybrid, prisms; VTK's `EvaluatePosition`
//! answers) and the comparison every backend's test makes against them.
//!
//! `tetloc-testdata` includes this same file (`#[path]`) for every other crate's tests.

use super::{query_sets, read_raw, require_data, BatchLocator, Mesh, QuerySet, RawMesh};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// How a set's answers compare with the oracle, outside its ambiguous points (flags bit0).
#[derive(Debug, Default, PartialEq)]
pub struct Mismatch {
    /// Oracle inside, answer outside (a crack).
    pub lost: usize,
    /// Oracle outside, answer inside.
    pub extra: usize,
    /// Both inside, other cells.
    pub other: usize,
    /// Values off by more than 1e-5·|ref| + 2e-6·max|f| (the data README's f32 bound).
    pub values: usize,
    /// Cell field `g` not the answer cell's value.
    pub cell_values: usize,
}

/// Compares `loc`'s ids and values of `f` and `g` on `set` with the oracle's.
pub fn compare(loc: &mut dyn BatchLocator, mesh: &Mesh, set: &QuerySet) -> Mismatch {
    let n = set.points.len();
    let (mut ids, mut v) = (vec![0; n], vec![0f32; 2 * n]);
    loc.sample_many(&set.points, &["f", "g"], &mut ids, &mut v).unwrap();
    let mut ids_only = vec![0; n];
    loc.locate(&set.points, &mut ids_only).unwrap();
    assert_eq!(ids, ids_only, "{}: locate and sample_many disagree", set.label);
    let g = &mesh.field("g").unwrap().values;
    // g is the answer cell's value exactly; outside, f and g are NaN.
    let g_right = |i: usize| match ids[i] {
        got if got >= 0 => v[2 * i + 1] == g[got as usize],
        _ => v[2 * i].is_nan() && v[2 * i + 1].is_nan(),
    };
    score(mesh, set, &ids, |i| f64::from(v[2 * i]), g_right)
}

/// The mismatches of answers `ids` (f's value at point i `f(i)`, g's right or not
/// `g_right(i)`) with `set`'s oracle: [`compare`]'s and [`compare_far`]'s one scoring.
fn score(
    mesh: &Mesh,
    set: &QuerySet,
    ids: &[i32],
    f: impl Fn(usize) -> f64,
    g_right: impl Fn(usize) -> bool,
) -> Mismatch {
    let max_f = mesh.field("f").unwrap().values.iter().fold(0f64, |a, &x| a.max(f64::from(x).abs()));
    let want_values = set.value.as_ref().expect("mixed sets carry values");
    let mut m = Mismatch::default();
    for (i, &got) in ids.iter().enumerate() {
        if !g_right(i) {
            m.cell_values += 1;
        }
        if set.ambiguous(i) {
            continue;
        }
        match (set.cell[i] >= 0, got >= 0) {
            (true, false) => m.lost += 1,
            (false, true) => m.extra += 1,
            (true, true) if got != set.cell[i] => m.other += 1,
            (true, true) => {
                if (f(i) - want_values[i]).abs() > 1e-5 * want_values[i].abs() + 2e-6 * max_f {
                    m.values += 1;
                }
            }
            (false, false) => {}
        }
    }
    m
}

/// Where [`compare_far`] moves a mixed mesh and its points: far from the origin (f32 cannot
/// hold a cell of these meshes there), by powers of two, so that most coordinates move exactly.
pub const FAR: [f64; 3] = [8_388_608.0, 16_777_216.0, -4_194_304.0];

/// `file` read and moved by [`FAR`] in f64 (the f64 data a far mesh's file would hold).
pub fn far_mesh(file: &std::path::Path) -> Mesh {
    let raw = read_raw(file, None).unwrap_or_else(|e| panic!("{e}"));
    Mesh::new(moved(raw, FAR), "far mixed mesh").unwrap_or_else(|e| panic!("{}: {e}", file.display()))
}

/// `raw` moved by `by` in f64: the f64 coordinates a file of the mesh far from the origin
/// would hold, with their f32 rounding.
pub fn moved(mut raw: RawMesh, by: [f64; 3]) -> RawMesh {
    let moved: Vec<[f64; 3]> = match raw.points64.take() {
        Some(p) => p,
        None => raw.points.iter().map(|p| p.map(f64::from)).collect(),
    }
    .iter()
    .map(|p| std::array::from_fn(|k| p[k] + by[k]))
    .collect();
    raw.points = moved.iter().map(|p| p.map(|c| c as f32)).collect();
    raw.points64 = Some(moved);
    raw
}

/// [`compare`] on [`far_mesh`], the set's points moved as the mesh and given in f64
/// (`sample_many64`): the same answers as at the origin.
pub fn compare_far(loc: &mut dyn BatchLocator, mesh: &Mesh, set: &QuerySet) -> Mismatch {
    let points: Vec<[f64; 3]> = set.points.iter().map(|p| std::array::from_fn(|k| f64::from(p[k]) + FAR[k])).collect();
    let n = points.len();
    let (mut ids, mut v) = (vec![0; n], vec![0f64; 2 * n]);
    loc.sample_many64(&points, &["f", "g"], &mut ids, &mut v).unwrap();
    let g = &mesh.field("g").unwrap().values;
    let g_right = |i: usize| match ids[i] {
        got if got >= 0 => v[2 * i + 1] as f32 == g[got as usize],
        _ => v[2 * i].is_nan() && v[2 * i + 1].is_nan(),
    };
    score(mesh, set, &ids, |i| v[2 * i], g_right)
}

/// The mixed oracle sets by mesh file (`.zlib.vtu` and `.msh` of each mesh).
pub fn mixed_sets(test: &str) -> BTreeMap<String, (Vec<PathBuf>, Vec<QuerySet>)> {
    let mut out: BTreeMap<String, (Vec<PathBuf>, Vec<QuerySet>)> = BTreeMap::new();
    let Some(dir) = require_data(test) else { return out };
    let dir = dir.join("mixed");
    for s in query_sets(&dir) {
        let name = s.label.split('.').next().unwrap().to_string();
        let files = ["zlib.vtu", "msh"].map(|e| dir.join(format!("{name}.{e}"))).to_vec();
        out.entry(name).or_insert_with(|| (files, Vec::new())).1.push(s);
    }
    assert_eq!(out.values().map(|v| v.1.len()).sum::<usize>(), 9, "{test}: the 9 sets of {}", dir.display());
    out
}
