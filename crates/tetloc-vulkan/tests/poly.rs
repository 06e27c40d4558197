//! Polyhedral meshes (VTK_POLYHEDRON, OpenFOAM cases) on the CPU and every kernel: each
//! locates in the polyhedra's centroid decomposition, and `CellLocator` turns its answers
//! into cells and values. Against the exact answers of ../shared/data/poly (`octpoly_s`, as a
//! `.vtu` and as an OpenFOAM case), where VTK's own locator is wrong at about 13 % of the
//! inside points.

mod common;

use std::sync::Arc;
use tetloc_core::locate::{CellLocator, CpuLocator, FiniteOnly};
use tetloc_core::Mesh;
use tetloc_testdata::poly::{compare_poly, poly_sets, read_npy_f64, PolyMismatch, PolySet};
use tetloc_vulkan::{Kernel, LocatorOptions, VulkanLocator};

/// The CPU's and every kernel's cells and `field` values on `sets` are the oracle's (`lin`
/// interpolated, or the cell values `cell_values`).
fn check_every_backend(
    test: &str,
    label: &str,
    mesh: Arc<Mesh>,
    sets: &[PolySet],
    field: &str,
    cell_values: Option<&[f64]>,
) {
    assert_eq!(mesh.n_cells(), 289, "{label}");
    assert_eq!(mesh.info.cell_types.get("polyhedron"), Some(&32), "{label}");
    assert_eq!(mesh.info.cell_types.get("hexahedron"), Some(&257), "{label}");
    let mut cpu = CellLocator::new(FiniteOnly::new(CpuLocator::new(mesh.clone())), mesh.clone());
    for set in sets {
        let inside = set.cell.iter().filter(|&&c| c >= 0).count();
        assert!(inside > set.cell.len() / 10, "{}: points inside", set.label);
        let m = compare_poly(&mut cpu, set, field, cell_values);
        println!("{label} cpu {}: {m:?}", set.label);
        assert_eq!(m, PolyMismatch::default(), "{label} cpu {}", set.label);
    }
    let Some(ctx) = common::context(test) else { return };
    for k in common::kernels(&ctx, test) {
        let gpu = VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap();
        let mut loc = CellLocator::new(FiniteOnly::new(gpu), mesh.clone());
        for set in sets {
            let mut m = compare_poly(&mut loc, set, field, cell_values);
            println!("{label} {k} {}: {m:?}", set.label);
            if k == Kernel::RtSharedFaces {
                // Known limit: octpoly_s has hanging nodes that only one of a face's two
                // cells lists (T-junctions), so a polyhedron's own decomposition has faces
                // with a tet on one side only; the face kernel's f32 path can stop there (a
                // few points in 10⁵). Its f64 path (certified) is exact, as every other's.
                assert!(m.f32_path <= set.points.len() / 10_000, "{label} {k} {}: {m:?}", set.label);
                m.f32_path = 0;
            }
            assert_eq!(m, PolyMismatch::default(), "{label} {k} {}", set.label);
        }
    }
    common::assert_no_validation_errors(&ctx);
}

#[test]
fn every_backend_finds_the_exact_cells_and_values_of_a_polyhedral_vtu() {
    let test = "every_backend_finds_the_exact_cells_and_values_of_a_polyhedral_vtu";
    let Some((dir, sets)) = poly_sets(test) else { return };
    let mesh = Arc::new(tetloc_io::read_mesh(&dir.join("octpoly_s.vtu"), None).unwrap());
    check_every_backend(test, "vtu", mesh, &sets, "lin", None);
}

#[test]
fn every_backend_finds_the_exact_cells_of_an_openfoam_case() {
    let test = "every_backend_finds_the_exact_cells_of_an_openfoam_case";
    let Some((dir, sets)) = poly_sets(test) else { return };
    let mesh = Arc::new(tetloc_io::read_mesh(&dir.join("octpoly_s_case/octpoly_s.foam"), None).unwrap());
    // The latest time (1) holds 2·lin at the cell centroids; `lin_cell` is lin there.
    let lin_cell: Vec<f64> = read_npy_f64(&dir.join("octpoly_s.lin_cell.npy")).iter().map(|v| 2.0 * v).collect();
    check_every_backend(test, "case", mesh, &sets, "lin", Some(&lin_cell));
}
