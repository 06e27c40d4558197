//! What the readers' and writers' unit tests share: tetloc-testdata's data folder and test
//! meshes, and core's usual test grid.

use tetloc_core::RawMesh;
pub(crate) use tetloc_testdata::{require_data, written_files, KuhnGrid};

/// `n`³ cubes on [0,1]³, interior vertices jittered by up to `jitter` × spacing, with a
/// smooth vertex field `f` and the tet ids as cell field `cellval` (as core's tests build it).
pub fn jittered_grid(n: usize, jitter: f32, seed: u64) -> RawMesh {
    KuhnGrid::new(n)
        .jitter(jitter, seed)
        .vertex_field(|p| (3.0 * p[0]).sin() + p[1] * p[2])
        .cell_field("cellval", |t, _| t as f32)
        .raw()
}
