//! What the readers' and writers' unit tests share: tetloc-testdata's data folder and test
//! meshes (core's usual test grid among them).

pub(crate) use tetloc_testdata::{jittered_grid, require_data, written_files, KuhnGrid};

/// The two tets over five points that the Gmsh and TetGen readers' tests write (the corner
/// tet of the unit cube and its neighbour across the face (1, 2, 3)), with `fields`.
pub(crate) fn two_tets(fields: Vec<tetloc_core::mesh::Field>) -> tetloc_core::mesh::RawMesh {
    tetloc_core::mesh::RawMesh {
        points64: None,
        points: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]],
        tets: vec![[0, 1, 2, 3], [1, 2, 3, 4]],
        fields,
        higher_order: None,
        cells: None,
    }
}
