//! Test support for every tetloc crate's tests (a dev-dependency only, never published):
//! the oracle query sets of `../shared/data` (`TETLOC_DATA` overrides the folder; a missing
//! folder skips a test, except in CI), the one test-mesh builder [`KuhnGrid`], the small
//! meshes of the renderer's tests ([`testmesh`]), the f64 reference interpolation
//! [`exact_value`], and [`generated_data`], a small oracle folder made at test time in the
//! shared data's layout (with exact answers): what the oracle tests check on a fresh clone.
//!
//! Core's own unit tests cannot use this crate: through it they would see a second copy of
//! core's types. So the parts they need, [`KuhnGrid`] and the data folder, are written once
//! in core's private `test_support` module and included here by path.

use tetloc_core::cell::{barycentric_lattice, CellBlock, CellType};
use tetloc_core::mesh::{Field, FieldLocation};
use tetloc_core::{BatchLocator, Mesh, RawMesh, Vec3};
use tetloc_io::read_raw;
// What generated.rs takes from its includer.
use tetloc_core::gen::{generate, Shape};
use tetloc_core::geom::predicates::orient3d;
use tetloc_io::{read_mesh, vtk::write::write_mesh_vtu};

#[path = "../../tetloc-core/src/test_support/data_dir.rs"]
mod data_dir;
pub mod foam_case;
mod generated;
#[path = "../../tetloc-core/src/test_support/kuhn.rs"]
mod kuhn;
#[path = "../../tetloc-core/src/test_support/mixed.rs"]
pub mod mixed;
#[path = "../../tetloc-core/src/test_support/poly.rs"]
pub mod poly;
#[path = "../../tetloc-core/src/test_support/query_sets.rs"]
mod query_sets;
#[path = "../../tetloc-core/src/test_support/slivers.rs"]
pub mod slivers;
pub mod testmesh;

pub use data_dir::{data_dir, in_ci, require_data, skip, NO_DATA};
pub use generated::{generated_data, written_files};
pub use kuhn::{jittered_grid, KuhnGrid};
pub use query_sets::{query_sets, utm_sets, QuerySet};

/// Why VTK comparisons skip: the reason [`run_vtk_script`] records.
pub const NO_VTK: &str = "no Python with vtk and numpy [TETLOC_PYTHON]";

/// Runs `scripts/SCRIPT` (a VTK reference: `vtk_probe.py`, `vtk_ops.py`) with `args` under
/// `TETLOC_PYTHON` (default `python3`). `None` (after a [`skip`]) when that Python or its
/// `vtk` module is missing (the scripts exit 3), outside CI; in CI that fails the test, as does
/// any failure of the script.
pub fn run_vtk_script(test: &str, script: &str, args: &[&str]) -> Option<()> {
    let python = std::env::var("TETLOC_PYTHON").unwrap_or_else(|_| "python3".into());
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts").join(script);
    let missing = |why: String| {
        assert!(!in_ci(), "{test}: {why}; CI needs Python with vtk (set TETLOC_PYTHON)");
        eprintln!("{test}: {why}");
        skip(test, NO_VTK);
        None
    };
    let out = match std::process::Command::new(&python).arg(&path).args(args).output() {
        Ok(o) => o,
        Err(e) => return missing(format!("cannot run {python}: {e}")),
    };
    let err = String::from_utf8_lossy(&out.stderr);
    if out.status.code() == Some(3) {
        return missing(format!("{python} has no vtk module: {err}"));
    }
    assert!(out.status.success(), "{test}: {script} failed: {err}");
    Some(())
}

/// A file of little-endian f64 values (what the VTK scripts write).
pub fn read_f64s(path: &std::path::Path) -> Vec<f64> {
    bytemuck::pod_collect_to_vec(&std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

/// The value of a per-vertex field at `p` by barycentric interpolation in tet `t`, with the
/// barycentrics computed in f64 on the file's coordinates (`Mesh::vertex64`): the reference
/// a locator's value must match.
pub fn exact_value(mesh: &Mesh, t: usize, p: Vec3, values: &[f32]) -> f64 {
    use tetloc_core::geom::predicates::orient3d;
    let ids = mesh.tets[t];
    let v: [[f64; 3]; 4] = ids.map(|i| mesh.vertex64(i));
    let vol6 = |w: [[f64; 3]; 4]| -orient3d(w[0], w[1], w[2], w[3]);
    let vol = vol6(v);
    (0..4)
        .map(|i| {
            let mut w = v;
            w[i] = p.map(f64::from);
            vol6(w) / vol * values[ids[i] as usize] as f64
        })
        .sum()
}

/// Whether a value `got` matches the oracle's f64 value `want` within `rel` relative to
/// max(|want|, `floor`) (a floor of 1e-30 holds values near zero to their own size); NaN
/// matches NaN.
pub fn close_rel(got: f64, want: f64, rel: f64, floor: f64) -> bool {
    if want.is_nan() || got.is_nan() {
        return want.is_nan() && got.is_nan();
    }
    (got - want).abs() <= rel * want.abs().max(floor)
}

/// Value checks of [`compare_f64_set`]: 1e-5 relative to max(|oracle|, floor).
pub const F64_VALUES: f64 = 1e-30;
/// The default GPU path's f32 values: 1e-5 relative to max(|oracle|, 1).
pub const F32_VALUES: f64 = 1.0;

/// A set with f64 points (a UTM set of [`utm_sets`], or any set's f32 points widened)
/// through `loc`'s f64 path: (id mismatches outside flags bit0, values off the oracle's by
/// more than 1e-5 relative to max(|oracle|, `floor`) ([`F64_VALUES`]: the f64 values'
/// promise, even near zero; [`F32_VALUES`]: f32 values), interior points lost), printing the
/// first few of each.
pub fn compare_f64_set(loc: &mut dyn BatchLocator, set: &QuerySet, floor: f64) -> (usize, usize, usize) {
    let widened: Vec<[f64; 3]>;
    let points = match &set.points64 {
        Some(p) => p,
        None => {
            widened = set.points.iter().map(|p| p.map(f64::from)).collect();
            &widened
        }
    };
    // Sets without values (meshes without the field `f`): ids only.
    let fields: &[&str] = if set.value.is_some() { &["f"] } else { &[] };
    let (mut ids, mut values) = (vec![0i32; points.len()], vec![0f64; points.len() * fields.len()]);
    loc.sample_many64(points, fields, &mut ids, &mut values).unwrap_or_else(|e| panic!("{}: {e}", set.label));
    let (mut mismatches, mut bad_values, mut lost) = (0, 0, 0);
    for i in 0..points.len() {
        if set.cell[i] >= 0 && ids[i] < 0 {
            lost += 1;
        }
        if set.ambiguous(i) {
            continue;
        }
        if ids[i] != set.cell[i] {
            mismatches += 1;
            if mismatches <= 3 {
                eprintln!(
                    "{} {}: point {i} {:?}: got {} want {}",
                    loc.name(),
                    set.label,
                    points[i],
                    ids[i],
                    set.cell[i]
                );
            }
        }
        if let Some(want) = &set.value {
            let (g, w) = (values[i], want[i]);
            if !close_rel(g, w, 1e-5, floor) {
                bad_values += 1;
                if bad_values <= 3 {
                    eprintln!("{} {}: point {i}: value {g} want {w}", loc.name(), set.label);
                }
            }
        }
    }
    (mismatches, bad_values, lost)
}
