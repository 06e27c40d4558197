//! The cell wrapper on the CPU locator: VTK's answers on the mixed oracle sets, no cracks
//! across warped faces, hex/tet agreement, and the wrapper's pass-through on tet meshes.

use super::*;
use crate::locate::{CpuLocator, FiniteOnly};
use crate::test_support::mixed::{compare, mixed_sets, Mismatch};
use std::path::Path;

fn load(path: &Path) -> Arc<Mesh> {
    Arc::new(crate::io::read_mesh(path, None).unwrap_or_else(|e| panic!("{e}")))
}

/// Every mixed oracle set, from both files of each mesh, through the CPU locator: VTK's ids
/// and values everywhere outside the ambiguous points.
#[test]
fn cpu_matches_vtk_on_the_mixed_sets() {
    for (name, (files, sets)) in mixed_sets("cpu_matches_vtk_on_the_mixed_sets") {
        for file in files {
            let mesh = load(&file);
            assert!(mesh.cells.is_some(), "{name}: a mixed mesh");
            let mut loc = CellLocator::new(FiniteOnly::new(CpuLocator::new(mesh.clone())), mesh.clone());
            for set in &sets {
                let m = compare(&mut loc, &mesh, set);
                eprintln!("{} ({}): {m:?}", set.label, file.file_name().unwrap().to_string_lossy());
                assert_eq!(m, Mismatch::default(), "{} from {}", set.label, file.display());
            }
        }
    }
}
