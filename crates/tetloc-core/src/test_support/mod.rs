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
pub(crate) mod poly;
// Shared whole with tetloc-testdata.
#[allow(dead_code)]
pub(crate) mod slivers;

pub(crate) use data_dir::require_data;
pub(crate) use kuhn::{jittered_grid, KuhnGrid};
#[allow(unused_imports)]
pub(crate) use query_sets::{query_sets, utm_sets, QuerySet};

// What kuhn.rs takes from its includer.
use crate::cell::{barycentric_lattice, CellBlock, CellType, PolyFaces};
use crate::geom::Vec3;
use crate::mesh::{Field, FieldLocation, Mesh, RawMesh};
// What mixed.rs takes from its includer.
use crate::locate::BatchLocator;

/// A mesh file read by tetloc-io, as this crate's own types. Core's unit tests see the core
/// that tetloc-io links as another crate (tetloc-io depends on core), so its mesh is copied
/// over through the encodings core publishes: a cell type by its VTK code and node count, a
/// field's location by its serialized name (what `tetloc info --json` prints).
pub(crate) fn read_raw(path: &std::path::Path, format: Option<tetloc_io::MeshFormat>) -> Result<RawMesh, String> {
    let raw = tetloc_io::read_raw(path, format).map_err(|e| e.to_string())?;
    let fields = raw
        .fields
        .into_iter()
        .map(|f| {
            let location = match serde_json::to_value(f.location).map_err(|e| e.to_string())?.as_str() {
                Some("vertex") => FieldLocation::Vertex,
                Some("cell") => FieldLocation::Cell,
                other => return Err(format!("field '{}': unknown location {other:?}", f.name)),
            };
            Ok(Field { name: f.name, location, values: f.values, values64: f.values64 })
        })
        .collect::<Result<_, String>>()?;
    let cells = match raw.cells {
        None => None,
        Some(b) => {
            let type_of = |code: u8, n: usize| {
                CellType::from_vtk(code, n).ok_or_else(|| format!("VTK cell type {code} with {n} nodes"))
            };
            let types = b.types.iter().map(|t| match t.is_polyhedron() {
                true => Ok(CellType::polyhedron()),
                false => type_of(t.def().vtk_type(), t.def().n_nodes()),
            });
            let p = b.polyhedra;
            let polyhedra =
                PolyFaces { cells: p.cells, cell_ends: p.cell_ends, face_ends: p.face_ends, points: p.points };
            Some(CellBlock { types: types.collect::<Result<_, String>>()?, ends: b.ends, conn: b.conn, polyhedra })
        }
    };
    Ok(RawMesh {
        points: raw.points,
        points64: raw.points64,
        tets: raw.tets,
        fields,
        higher_order: raw.higher_order,
        cells,
    })
}

/// [`read_raw`], validated.
pub(crate) fn read_mesh(path: &std::path::Path) -> Result<Mesh, String> {
    Mesh::new(read_raw(path, None)?, path.display().to_string()).map_err(|e| e.to_string())
}

pub fn grid_mesh(n: usize, jitter: f32, seed: u64) -> Mesh {
    Mesh::new(jittered_grid(n, jitter, seed), "test grid").unwrap()
}
