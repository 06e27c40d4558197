//! VTK cell lists (cell types, offsets and connectivity: pyvista's arrays) in and out of a
//! mesh. In: the `RawMesh` cells the VTK readers make (linear tets as tets; any other volume
//! cell as a `CellBlock` that `Mesh::new` decomposes, as for a file). Out: the mesh's cells as
//! its input had them.

use rayon::prelude::*;
use tetloc_core::cell::{CellBlock, CellType};
use tetloc_core::Mesh;

/// VTK's code of the linear tet (vtkCellType.h).
const VTK_TETRA: u8 = 10;

/// A VTK cell list: cell `i` is of VTK type `types[i]` with the points
/// `conn[offsets[i]..offsets[i + 1]]`.
pub struct CellList {
    pub types: Vec<u8>,
    pub offsets: Vec<i64>,
    pub conn: Vec<i64>,
}

/// What a cell list gives a `RawMesh`: as `tetloc_io`'s VTK readers fill it.
pub struct Volume {
    /// The corners of the cells that are tets (of any order).
    pub tets: Vec<[u32; 4]>,
    /// The highest polynomial order, when above 1.
    pub higher_order: Option<u8>,
    /// Every cell with all its nodes, unless every cell is a linear tet.
    pub cells: Option<CellBlock>,
}

/// Every VTK cell type tetloc reads: (code, points, name).
pub fn vtk_cell_types() -> Vec<(u8, usize, &'static str)> {
    CellType::all().map(|t| (t.def().vtk_type(), t.def().n_nodes(), t.def().name())).collect()
}

/// The volume of a VTK cell list. Offsets start at 0, never decrease and end at the
/// connectivity's length; every cell must be a volume cell tetloc reads. Errors are messages
/// for `ValueError` (the caller names the argument).
pub fn from_vtk(types: &[u8], offsets: &[i64], conn: &[u32]) -> Result<Volume, String> {
    if offsets.len() != types.len() + 1 {
        return Err(format!("{} cell types but {} offsets (expected one more)", types.len(), offsets.len()));
    }
    if offsets[0] != 0 || offsets[types.len()] != conn.len() as i64 {
        return Err(format!(
            "offsets run from {} to {}; expected 0 to the connectivity's length {}",
            offsets[0],
            offsets[types.len()],
            conn.len()
        ));
    }
    if let Some(i) = offsets.windows(2).position(|w| w[1] < w[0]) {
        return Err(format!("offsets decrease at cell {i} ({} then {})", offsets[i], offsets[i + 1]));
    }
    let nodes = |i: usize| &conn[offsets[i] as usize..offsets[i + 1] as usize];
    // The common case: linear tets only, no block (a tet mesh pays nothing for other cells).
    if types.par_iter().all(|&t| t == VTK_TETRA) && offsets.par_iter().enumerate().all(|(i, &o)| o == 4 * i as i64) {
        let tets = conn.par_chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect();
        return Ok(Volume { tets, higher_order: None, cells: None });
    }
    let mut block = CellBlock::default();
    let mut tets = Vec::new();
    let mut higher_order: Option<u8> = None;
    // Lists repeat one type for long runs: look it up once per run.
    let mut last: Option<(u8, usize, CellType)> = None;
    for (i, &code) in types.iter().enumerate() {
        let ids = nodes(i);
        let ty = match last {
            Some((c, n, t)) if c == code && n == ids.len() => t,
            _ => CellType::from_vtk(code, ids.len()).ok_or_else(|| {
                format!(
                    "cell {i} has VTK cell type {code} with {} points, which is not a volume cell tetloc reads",
                    ids.len()
                )
            })?,
        };
        last = Some((code, ids.len(), ty));
        let order = ty.def().order();
        if order > 1 {
            higher_order = Some(higher_order.map_or(order, |o| o.max(order)));
        }
        if ty.shape().is_tet() {
            tets.push([ids[0], ids[1], ids[2], ids[3]]);
        }
        block.push(ty, ids);
    }
    Ok(Volume { tets, higher_order, cells: Some(block) })
}

/// The mesh's cells as its input had them: a mixed mesh's cells with all their nodes, in
/// their order; higher-order tets with all their nodes (corners in canonical order, the
/// other nodes following them); linear tets in canonical order.
pub fn to_vtk(mesh: &Mesh) -> CellList {
    let widen = |ids: &[u32]| ids.par_iter().map(|&i| i64::from(i)).collect::<Vec<i64>>();
    if let Some(cells) = &mesh.cells {
        let b = &cells.block;
        let types = b.types.iter().map(|t| t.def().vtk_type()).collect();
        let offsets = std::iter::once(0).chain(b.ends.iter().map(|&e| e as i64)).collect();
        return CellList { types, offsets, conn: widen(&b.conn) };
    }
    let n = mesh.n_tets();
    let (code, per_cell, conn) = match &mesh.tet_nodes {
        Some(nodes) => {
            let def = nodes.cell_type().def();
            let conn = (0..n)
                .into_par_iter()
                .flat_map_iter(|t| nodes.nodes(t, mesh.tets[t]).map(i64::from).collect::<Vec<_>>())
                .collect();
            (def.vtk_type(), def.n_nodes(), conn)
        }
        None => (VTK_TETRA, 4, widen(bytemuck::cast_slice(&mesh.tets))),
    };
    CellList { types: vec![code; n], offsets: (0..=n).map(|i| (i * per_cell) as i64).collect(), conn }
}

/// The VTK cell type of Gmsh element type `code`, if tetloc reads it: (VTK code, the Gmsh
/// element's node count, VTK node `i` = Gmsh node `vtk_from_gmsh[i]`). What meshio's blocks
/// of Gmsh's higher orders (`tetra20`, `hexahedron64`, ...: Gmsh's node order) convert with.
pub fn gmsh_cell_type(code: u8) -> Option<(u8, usize, Vec<u16>)> {
    CellType::from_gmsh(code).map(|(t, g)| (t.def().vtk_type(), g.n_nodes, g.vtk_from_gmsh.to_vec()))
}
