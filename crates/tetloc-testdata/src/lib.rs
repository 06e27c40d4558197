//! Test support for every tetloc crate's tests (a dev-dependency only, never published):
//! the oracle query sets of `../shared/data` (`TETLOC_DATA` overrides the folder; a missing
//! folder skips a test, except in CI), the one test-mesh builder [`KuhnGrid`], the small
//! meshes of the renderer's tests ([`testmesh`]) and the f64 reference interpolation
//! [`exact_value`].
//!
//! Core's own unit tests cannot use this crate: through it they would see a second copy of
//! core's types. So the parts they need, [`KuhnGrid`] and the data folder, are written once
//! in core's private `test_support` module and included here by path.

use std::path::{Path, PathBuf};
use tetloc_core::mesh::{Field, FieldLocation};
use tetloc_core::{Mesh, RawMesh, Vec3};

#[path = "../../tetloc-core/src/test_support/data_dir.rs"]
mod data_dir;
#[path = "../../tetloc-core/src/test_support/kuhn.rs"]
mod kuhn;
pub mod testmesh;

pub use data_dir::{data_dir, in_ci, require_data};
pub use kuhn::KuhnGrid;

/// One oracle query set: points and the expected answers.
pub struct QuerySet {
    /// e.g. `torus_s.random`
    pub label: String,
    /// The mesh file the answers refer to.
    pub mesh_path: PathBuf,
    pub points: Vec<Vec3>,
    /// Expected tet id, -1 outside.
    pub cell: Vec<i32>,
    /// Expected interpolated value of point field `f` (generated meshes only), NaN outside.
    pub value: Option<Vec<f64>>,
    /// bit0: within rounding of a face, so another answer is also right.
    pub flags: Vec<u8>,
}

impl QuerySet {
    pub fn ambiguous(&self, i: usize) -> bool {
        self.flags[i] & 1 != 0
    }
}

fn read_le<T: bytemuck::Pod>(path: &Path) -> Vec<T> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    bytemuck::pod_collect_to_vec(&bytes)
}

/// Every query set in `dir` and `dir/real`, each with the mesh file it belongs to.
pub fn query_sets(dir: &Path) -> Vec<QuerySet> {
    let mut out = Vec::new();
    for folder in [dir.to_path_buf(), dir.join("real")] {
        let Ok(rd) = std::fs::read_dir(&folder) else { continue };
        let mut jsons: Vec<PathBuf> = rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                let n = p.file_name().unwrap().to_string_lossy().to_string();
                n.ends_with(".json") && !n.ends_with(".mesh.json") && n.matches('.').count() == 2
            })
            .collect();
        jsons.sort();
        for j in jsons {
            let meta: serde_json::Value = serde_json::from_slice(&std::fs::read(&j).unwrap()).unwrap();
            let mesh = meta["mesh"].as_str().unwrap().to_string();
            let set = meta["set"].as_str().unwrap().to_string();
            let mesh_path = ["vtu", "msh", "vtk"]
                .iter()
                .map(|ext| folder.join(format!("{mesh}.{ext}")))
                .find(|p| p.exists())
                .unwrap_or_else(|| panic!("{}: no mesh file named {mesh}.vtu/.msh/.vtk", j.display()));
            // Real meshes list a `value` array but ship none (ids only): take only files that exist.
            let arr = |key: &str| meta["arrays"][key]["file"].as_str().map(|f| folder.join(f)).filter(|p| p.exists());
            let points: Vec<f32> = read_le(&arr("points").unwrap());
            out.push(QuerySet {
                label: format!("{mesh}.{set}"),
                mesh_path,
                points: points.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
                cell: read_le(&arr("cell").unwrap()),
                value: arr("value").map(|p| read_le(&p)),
                flags: read_le(&arr("flags").unwrap()),
            });
        }
    }
    out
}

/// The value of a per-vertex field at `p` by barycentric interpolation in tet `t`, with the
/// barycentrics computed in f64 on the stored (f32) vertices: the reference a locator's
/// value must match. The oracle's own values use the file's f64 vertices; in slivers the
/// rounding of the vertices to f32 alone moves them by more than 1e-5.
pub fn exact_value(mesh: &Mesh, t: usize, p: Vec3, values: &[f32]) -> f64 {
    let ids = mesh.tets[t];
    let v: [Vec3; 4] = ids.map(|i| mesh.points[i as usize]);
    let vol = tetloc_core::geom::tet_volume6(v);
    (0..4)
        .map(|i| {
            let mut w = v;
            w[i] = p;
            tetloc_core::geom::tet_volume6(w) / vol * values[ids[i] as usize] as f64
        })
        .sum()
}
