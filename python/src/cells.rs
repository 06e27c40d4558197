//! VTK cell lists (cell types, offsets and connectivity: pyvista's arrays) out of a mesh: its
//! cells as its input had them. (In: `tetloc_io::vtk::from_cell_list`, the VTK readers' own
//! picking of the volume cells.)

use rayon::prelude::*;
use tetloc_core::cell::CellType;
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

/// Every VTK cell type tetloc reads: (code, points, name).
pub fn vtk_cell_types() -> Vec<(u8, usize, &'static str)> {
    CellType::all().map(|t| (t.def().vtk_type(), t.def().n_nodes(), t.def().name())).collect()
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
