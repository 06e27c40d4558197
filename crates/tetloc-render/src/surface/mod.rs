//! Opaque surface geometry drawn with the volume: the mesh's own boundary or a triangle file
//! (OBJ, STL, VTK legacy polydata). Each pixel's ray is intersected with it once, before
//! marching, and the volume is integrated only up to the hit (paper, section 6.3).

mod bvh;
mod io;

pub use bvh::{Hit, SurfaceBvh};

use crate::error::{RenderError, Result};
use crate::vec::Vec3;
use std::path::Path;
use tetloc_core::Mesh;

/// An indexed triangle mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

impl From<tetloc_core::gen::Terrain> for TriMesh {
    fn from(t: tetloc_core::gen::Terrain) -> TriMesh {
        TriMesh { positions: t.positions, triangles: t.triangles }
    }
}

impl TriMesh {
    /// The faces of `mesh` that have a tet on one side only.
    pub fn boundary(mesh: &Mesh) -> TriMesh {
        let triangles = mesh.faces().faces.iter().filter(|f| f.front < 0 || f.back < 0).map(|f| f.v).collect();
        TriMesh { positions: mesh.points.to_vec(), triangles }
    }

    /// The surface in a mesh's working frame (its positions are in the file's coordinates).
    pub fn in_frame(&self, frame: &tetloc_core::mesh::Frame) -> TriMesh {
        let positions = self.positions.iter().map(|&p| frame.to_working_f32(p)).collect();
        TriMesh { positions, triangles: self.triangles.clone() }
    }

    /// Reads a surface file chosen by extension: `.obj`, `.stl` (ascii or binary) or `.vtk`
    /// (legacy POLYDATA).
    pub fn load(path: &Path) -> Result<TriMesh> {
        format_of(path)?;
        let bytes = std::fs::read(path).map_err(|e| RenderError::io(path, e))?;
        Self::parse(&bytes, path)
    }

    /// Parses a surface file held in memory; `path` names it in errors and picks the format.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<TriMesh> {
        let mesh = match format_of(path)? {
            Format::Obj => io::parse_obj(bytes),
            Format::Stl => io::parse_stl(bytes),
            Format::Vtk => io::parse_vtk_polydata(bytes),
        }
        .map_err(|msg| RenderError::file(path, msg))?;
        if mesh.triangles.is_empty() {
            return Err(RenderError::file(path, "the file holds no triangles"));
        }
        if let Some(i) = mesh.positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(RenderError::file(
                path,
                format!("vertex {i} has a non-finite coordinate {:?}", mesh.positions[i]),
            ));
        }
        Ok(mesh)
    }
}

enum Format {
    Obj,
    Stl,
    Vtk,
}

fn format_of(path: &Path) -> Result<Format> {
    match tetloc_io::output::extension(path).as_str() {
        "obj" => Ok(Format::Obj),
        "stl" => Ok(Format::Stl),
        "vtk" => Ok(Format::Vtk),
        _ => Err(RenderError::file(path, "unknown surface format (known: obj, stl, vtk)")),
    }
}
