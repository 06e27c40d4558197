//! Mesh readers and writers, chosen by file extension (or an explicit [`MeshFormat`]), and
//! query-point / result array I/O.

pub mod gmsh;
pub mod points;
pub mod tetgen;
pub mod vtk_legacy;
/// What the VTK XML and legacy readers and the VTU writer share: cell types, arrays, blocks.
pub(crate) mod vtk;
pub mod vtu;
pub mod vtu_write;
#[cfg(test)]
mod tests;

use crate::error::{Error, Result};
use crate::mesh::{Mesh, RawMesh};
use std::path::Path;

/// The mesh formats tetloc reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// VTK XML unstructured grid (`.vtu`).
    Vtu,
    /// VTK legacy (`.vtk`), versions up to 5.1, ascii or binary.
    VtkLegacy,
    /// Gmsh `.msh` 2.2 and 4.1, ascii or binary.
    Gmsh,
    /// TetGen `.node` + `.ele` (either file may be named).
    TetGen,
}

pub const KNOWN_MESH_FORMATS: &str = "vtu, vtk, msh, node/ele";

impl MeshFormat {
    pub fn from_name(name: &str) -> Option<MeshFormat> {
        match name.to_ascii_lowercase().as_str() {
            "vtu" => Some(MeshFormat::Vtu),
            "vtk" => Some(MeshFormat::VtkLegacy),
            "msh" | "gmsh" => Some(MeshFormat::Gmsh),
            "node" | "ele" | "tetgen" => Some(MeshFormat::TetGen),
            _ => None,
        }
    }

    pub fn from_path(path: &Path) -> Result<MeshFormat> {
        path.extension()
            .and_then(|e| e.to_str())
            .and_then(MeshFormat::from_name)
            .ok_or_else(|| Error::UnknownFormat { path: path.to_path_buf(), known: KNOWN_MESH_FORMATS })
    }
}

/// Reads a mesh file into a raw mesh (tets in file order, not yet validated).
pub fn read_raw(path: &Path, format: Option<MeshFormat>) -> Result<RawMesh> {
    let format = match format {
        Some(f) => f,
        None => MeshFormat::from_path(path)?,
    };
    match format {
        MeshFormat::Vtu => vtu::read(path),
        MeshFormat::VtkLegacy => vtk_legacy::read(path),
        MeshFormat::Gmsh => gmsh::read(path),
        MeshFormat::TetGen => tetgen::read(path),
    }
}

/// Reads and validates a mesh file.
pub fn read_mesh(path: &Path, format: Option<MeshFormat>) -> Result<Mesh> {
    let raw = read_raw(path, format)?;
    Mesh::new(raw, path.display().to_string())
}
