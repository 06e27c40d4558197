//! What the core's unit tests share: the test-mesh builder [`KuhnGrid`], the oracle data
//! folder ([`require_data`]) and its query sets ([`query_sets`]), the same source files that
//! `tetloc-testdata` includes for the other crates' tests (core's unit tests cannot depend on that crate: they would see a second
//! copy of core's types), and the core's usual test grid.

mod data_dir;
// Shared whole with tetloc-testdata: core's tests read only part of a query set.
#[allow(dead_code)]
mod query_sets;
// Shared whole with tetloc-testdata: core's tests use only part of the builder.
#[allow(dead_code)]
mod kuhn;
pub(crate) mod mixed;
// Shared whole with tetloc-testdata.
#[allow(dead_code)]
pub(crate) mod slivers;

pub(crate) use data_dir::require_data;
pub(crate) use kuhn::KuhnGrid;
#[allow(unused_imports)]
pub(crate) use query_sets::{query_sets, utm_sets, QuerySet};

// What kuhn.rs takes from its includer.
use crate::cell::{barycentric_lattice, CellBlock, CellType};
use crate::geom::Vec3;
use crate::mesh::{Field, FieldLocation, Mesh, RawMesh};
// What mixed.rs takes from its includer.
use crate::io::read_raw;
use crate::locate::BatchLocator;

/// `n`³ cubes on [0,1]³, interior vertices jittered by up to `jitter` × spacing, with a
/// smooth vertex field `f` and the tet ids as cell field `cellval`.
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
