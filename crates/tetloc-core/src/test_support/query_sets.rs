//! The oracle query sets of the data folder: points, expected cell ids, values and flags.
//!
//! `tetloc-testdata` includes this same file (`#[path]`) for every other crate's tests.

use super::Vec3;
use std::path::{Path, PathBuf};

/// One oracle query set: points and the expected answers.
pub struct QuerySet {
    /// e.g. `torus_s.random`
    pub label: String,
    /// The mesh file the answers refer to.
    pub mesh_path: PathBuf,
    pub points: Vec<Vec3>,
    /// The points in f64 when the set stores them so (`utm/`: far from the origin, where f32
    /// cannot hold them).
    pub points64: Option<Vec<[f64; 3]>>,
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
                points64: None,
                cell: read_le(&arr("cell").unwrap()),
                value: arr("value").map(|p| read_le(&p)),
                flags: read_le(&arr("flags").unwrap()),
            });
        }
    }
    out
}

/// The sets of `dir/utm`: a mesh far from the origin (UTM-like coordinates) with float64
/// `.npy` query points (see that folder's README).
pub fn utm_sets(dir: &Path) -> Vec<QuerySet> {
    let folder = dir.join("utm");
    let Ok(rd) = std::fs::read_dir(&folder) else { return Vec::new() };
    let mut jsons: Vec<PathBuf> =
        rd.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.extension().is_some_and(|e| e == "json")).collect();
    jsons.sort();
    jsons
        .iter()
        .map(|j| {
            let meta: serde_json::Value = serde_json::from_slice(&std::fs::read(j).unwrap()).unwrap();
            let (mesh, set) = (meta["mesh"].as_str().unwrap(), meta["set"].as_str().unwrap());
            let stem = folder.join(format!("{mesh}.{set}"));
            let with = |ext: &str| PathBuf::from(format!("{}.{ext}", stem.display()));
            let points64 = read_npy_f64_points(&with("points.npy"));
            let value = with("value.bin");
            QuerySet {
                label: format!("utm/{mesh}.{set}"),
                mesh_path: folder.join(format!("{mesh}.vtu")),
                points: points64.iter().map(|p| p.map(|c| c as f32)).collect(),
                points64: Some(points64),
                cell: read_le(&with("cell.bin")),
                value: value.exists().then(|| read_le(&value)),
                flags: read_le(&with("flags.bin")),
            }
        })
        .collect()
}

/// A little-endian float64 (N, 3) C-order `.npy` file.
fn read_npy_f64_points(path: &Path) -> Vec<[f64; 3]> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(bytes.starts_with(b"\x93NUMPY"), "{}: not an .npy file", path.display());
    let (len, start) = if bytes[6] == 1 {
        (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10)
    } else {
        (u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize, 12)
    };
    let header = String::from_utf8_lossy(&bytes[start..start + len]);
    assert!(header.contains("'<f8'") && header.contains("False"), "{}: expected C-order <f8: {header}", path.display());
    let data: Vec<f64> = bytemuck::pod_collect_to_vec(&bytes[start + len..]);
    data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}
