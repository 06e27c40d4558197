//! Mixed meshes (hexes, wedges, pyramids, tets) on every kernel: each kernel locates in the
//! conforming tet decomposition, and `CellLocator` turns its answers into VTK's cells and
//! values. Against the oracle sets of ../shared/data/mixed.

mod common;

use std::sync::Arc;
use tetloc_core::locate::{CellLocator, FiniteOnly};
use tetloc_testdata::mixed::{compare, compare_far, far_mesh, mixed_sets, Mismatch};
use tetloc_vulkan::{Kernel, LocatorOptions, VulkanLocator};

#[test]
fn every_kernel_matches_vtk_on_mixed_meshes() {
    let test = "every_kernel_matches_vtk_on_mixed_meshes";
    let sets = mixed_sets(test);
    if sets.is_empty() {
        return;
    }
    let Some(ctx) = common::context(test) else { return };
    let mut configs: Vec<_> = common::kernels(&ctx, test).into_iter().map(|k| (k, LocatorOptions::default())).collect();
    configs.push((Kernel::SoftBvh, LocatorOptions { walk_start: false, ..Default::default() }));
    for (name, (files, sets)) in sets {
        let mesh = Arc::new(tetloc_core::io::read_mesh(&files[0], None).unwrap());
        assert!(mesh.cells.is_some(), "{name}: a mixed mesh");
        for (k, opts) in &configs {
            let gpu = VulkanLocator::new(ctx.clone(), mesh.clone(), *k, opts.clone()).unwrap();
            let mut loc = CellLocator::new(FiniteOnly::new(gpu), mesh.clone());
            for set in &sets {
                let m = compare(&mut loc, &mesh, set);
                println!("{k} (walk {}) {}: {m:?}", opts.walk_start, set.label);
                assert_eq!(m, Mismatch::default(), "{k} {}", set.label);
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}

/// The mixed sets moved far from the origin (`mixed::FAR`, where f32 cannot hold their cells)
/// and queried in f64: every kernel searches the centred working copy, and the answers are
/// VTK's, as at the origin.
#[test]
fn every_kernel_matches_vtk_on_mixed_meshes_far_from_the_origin() {
    let test = "every_kernel_matches_vtk_on_mixed_meshes_far_from_the_origin";
    let sets = mixed_sets(test);
    if sets.is_empty() {
        return;
    }
    let Some(ctx) = common::context(test) else { return };
    for (_, (files, sets)) in sets {
        let mesh = Arc::new(far_mesh(&files[0]));
        for k in common::kernels(&ctx, test) {
            let gpu = VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap();
            let mut loc = CellLocator::new(FiniteOnly::new(gpu), mesh.clone());
            for set in &sets {
                let m = compare_far(&mut loc, &mesh, set);
                println!("{k} far {}: {m:?}", set.label);
                assert_eq!(m, Mismatch::default(), "{k} far {}", set.label);
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}
