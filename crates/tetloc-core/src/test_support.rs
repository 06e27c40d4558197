//! The core's unit-test meshes: a [`KuhnGrid`] on [0,1]³ with a smooth vertex field `f`
//! and the tet ids as cell field `cellval`.

use crate::mesh::{Mesh, RawMesh};
use crate::testdata::KuhnGrid;

/// `n`³ cubes on [0,1]³, interior vertices jittered by up to `jitter` × spacing.
pub fn jittered_grid(n: usize, jitter: f32, seed: u64) -> RawMesh {
    KuhnGrid::new(n)
        .jitter(jitter, seed)
        .vertex_field(|p| (3.0 * p[0]).sin() + p[1] * p[2])
        .cell_field("cellval", |t, _| t as f32)
        .raw()
}

pub fn grid_mesh(n: usize, jitter: f32, seed: u64) -> Mesh {
    Mesh::new(jittered_grid(n, jitter, seed), "test grid").unwrap()
}
