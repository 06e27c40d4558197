//! The mixed-cell oracle sets of `mixed/` (hexwarp, hybrid, prisms; VTK's `EvaluatePosition`
//! answers) and the comparison every backend's test makes against them.
//!
//! `tetloc-testdata` includes this same file (`#[path]`) for every other crate's tests.

use super::{query_sets, require_data, BatchLocator, Mesh, QuerySet};
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
    let max_f = mesh.field("f").unwrap().values.iter().fold(0f64, |a, &x| a.max(f64::from(x).abs()));
    let g = &mesh.field("g").unwrap().values;
    let want_values = set.value.as_ref().expect("mixed sets carry values");
    let mut m = Mismatch::default();
    for i in 0..n {
        let (got, want) = (ids[i], set.cell[i]);
        if got >= 0 && v[2 * i + 1] != g[got as usize] {
            m.cell_values += 1;
        }
        if got < 0 && !(v[2 * i].is_nan() && v[2 * i + 1].is_nan()) {
            m.cell_values += 1;
        }
        if set.ambiguous(i) {
            continue;
        }
        match (want >= 0, got >= 0) {
            (true, false) => m.lost += 1,
            (false, true) => m.extra += 1,
            (true, true) if got != want => m.other += 1,
            (true, true) => {
                let (got, want) = (f64::from(v[2 * i]), want_values[i]);
                if (got - want).abs() > 1e-5 * want.abs() + 2e-6 * max_f {
                    m.values += 1;
                }
            }
            (false, false) => {}
        }
    }
    m
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
