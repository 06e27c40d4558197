//! Access to the oracle data in `../shared/data` (made with VTK, scipy and gmsh) for the
//! tests of every crate. `TETLOC_DATA` overrides the folder. When the data is absent the
//! tests say so and skip — except in CI (`CI` set), where that is a failure.

use crate::geom::Vec3;
use std::path::{Path, PathBuf};

/// The data folder, if it exists.
pub fn data_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("TETLOC_DATA") {
        Some(d) => PathBuf::from(d),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
    };
    dir.is_dir().then(|| dir.canonicalize().unwrap_or(dir))
}

/// True when running in CI, where nothing may be skipped.
pub fn in_ci() -> bool {
    std::env::var("CI").map(|v| !v.is_empty() && v != "false" && v != "0").unwrap_or(false)
}

/// The data folder for a test, or `None` (after saying so) when a user's clone lacks it.
/// Panics in CI.
pub fn require_data(test: &str) -> Option<PathBuf> {
    match data_dir() {
        Some(d) => Some(d),
        None if in_ci() => panic!("{test}: oracle data not found (set TETLOC_DATA or lay out ../shared/data); CI must not skip"),
        None => {
            eprintln!("SKIPPED {test}: oracle data not found (set TETLOC_DATA to ../shared/data)");
            None
        }
    }
}

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
pub fn exact_value(mesh: &crate::Mesh, t: usize, p: Vec3, values: &[f32]) -> f64 {
    let ids = mesh.tets[t];
    let v: [Vec3; 4] = ids.map(|i| mesh.points[i as usize]);
    let vol = crate::geom::tet_volume6(v);
    (0..4)
        .map(|i| {
            let mut w = v;
            w[i] = p;
            crate::geom::tet_volume6(w) / vol * values[ids[i] as usize] as f64
        })
        .sum()
}
