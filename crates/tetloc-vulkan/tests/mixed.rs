//! Mixed meshes (hexes, wedges, pyramids, tets) on every kernel: each kernel locates in the
//! conforming tet decomposition, and `CellLocator` turns its answers into VTK's cells and
//! values. Against the oracle sets of ../shared/data/mixed.

mod common;

use std::sync::Arc;
use tetloc_core::locate::{CellLocator, FiniteOnly};
use tetloc_testdata::mixed::{compare, compare_far, far_mesh, mixed_sets, Mismatch};
use tetloc_vulkan::{Kernel, LocatorOptions, SoftBvhOptions, VulkanLocator};

/// The mixed sets on every kernel, and on soft-bvh traversing from the root.
#[test]
fn every_kernel_matches_vtk_on_mixed_meshes() {
    let root = (Kernel::SoftBvh, common::soft_bvh(SoftBvhOptions { walk_start: false, ..Default::default() }));
    every_kernel_matches_vtk("every_kernel_matches_vtk_on_mixed_meshes", false, Some(root));
}

/// The mixed sets moved far from the origin (`mixed::FAR`, where f32 cannot hold their cells)
/// and queried in f64: every kernel searches the centred working copy, and the answers are
/// VTK's, as at the origin.
#[test]
fn every_kernel_matches_vtk_on_mixed_meshes_far_from_the_origin() {
    every_kernel_matches_vtk("every_kernel_matches_vtk_on_mixed_meshes_far_from_the_origin", true, None);
}

/// Every kernel, and `extra`, through `CellLocator` on each mixed oracle set: VTK's cells and
/// values; `far`, with the sets moved far from the origin.
fn every_kernel_matches_vtk(test: &str, far: bool, extra: Option<(Kernel, LocatorOptions)>) {
    let sets = mixed_sets(test);
    if sets.is_empty() {
        return;
    }
    let Some(ctx) = common::context(test) else { return };
    let mut configs: Vec<_> = common::kernels(&ctx, test).into_iter().map(|k| (k, LocatorOptions::default())).collect();
    configs.extend(extra);
    let score = if far { compare_far } else { compare };
    for (name, (files, sets)) in sets {
        let mesh = Arc::new(if far { far_mesh(&files[0]) } else { tetloc_io::read_mesh(&files[0], None).unwrap() });
        assert!(mesh.cells.is_some(), "{name}: a mixed mesh");
        for (k, opts) in &configs {
            let gpu = VulkanLocator::new(ctx.clone(), mesh.clone(), *k, opts.clone()).unwrap();
            let mut loc = CellLocator::new(FiniteOnly::new(gpu), mesh.clone());
            for set in &sets {
                let m = score(&mut loc, &mesh, set);
                let label =
                    format!("{k} (walk {}){} {}", opts.soft_bvh.walk_start, if far { " far" } else { "" }, set.label);
                println!("{label}: {m:?}");
                assert_eq!(m, Mismatch::default(), "{label}");
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}

/// Generated mixed meshes (no ../shared needed): a hybrid (hex layers, pyramids, tets, wedges)
/// and terrain-following hexes (warped faces), at cell centres and random points over the
/// bounds. Every kernel (soft-bvh and rt-bvh with one box a cell) gives the CPU's cells and
/// values.
#[test]
fn every_kernel_gives_the_cpus_cells_on_generated_mixed_meshes() {
    use tetloc_core::gen::{self, CellKind, Shape};
    use tetloc_core::BatchLocator;
    let test = "every_kernel_gives_the_cpus_cells_on_generated_mixed_meshes";
    let Some(ctx) = common::context(test) else { return };
    let specs = [(Shape::Fusion, CellKind::Hybrid, 3_000), (Shape::Japan, CellKind::Hexes, 2_000)];
    for (shape, cells, n) in specs {
        let raw = gen::generate_spec(gen::Spec { shape, cells }, n, 5, &|_| {});
        let mesh = Arc::new(tetloc_core::mesh::Mesh::new(raw, "generated mixed").unwrap());
        let block = &mesh.cells.as_ref().expect("a mixed mesh").block;
        assert!(block.len() < mesh.n_tets(), "{shape:?} {cells:?}: cells of more than one tet");
        let mut points: Vec<_> = (0..mesh.n_tets()).step_by(3).map(|t| mesh.tet_center(t)).collect();
        let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
        let mut s = 0x9e37_79b9_u32;
        for _ in 0..4_000 {
            points.push(std::array::from_fn(|k| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                lo[k] + (hi[k] - lo[k]) * (s as f32 / u32::MAX as f32)
            }));
        }
        let run = |loc: &mut dyn BatchLocator| {
            let (mut ids, mut values) = (vec![0; points.len()], vec![0.0; points.len()]);
            loc.locate_and_sample(&points, "f", &mut ids, &mut values).unwrap();
            (ids, values)
        };
        let cpu = tetloc_core::locate::CpuLocator::new(mesh.clone());
        let (want_ids, want_values) = run(&mut CellLocator::new(FiniteOnly::new(cpu), mesh.clone()));
        assert!(want_ids.iter().filter(|&&c| c >= 0).count() > points.len() / 2, "{shape:?}: most points inside");
        for k in common::kernels(&ctx, test) {
            let gpu = VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap();
            let (ids, values) = run(&mut CellLocator::new(FiniteOnly::new(gpu), mesh.clone()));
            let differ = (0..points.len()).filter(|&i| ids[i] != want_ids[i]).count();
            assert_eq!(differ, 0, "{k} on {shape:?} {cells:?}: cells differ from the CPU's");
            for i in 0..points.len() {
                assert!(
                    values[i].to_bits() == want_values[i].to_bits() || (values[i].is_nan() && want_values[i].is_nan()),
                    "{k} on {shape:?} {cells:?}: point {i} value {} vs the CPU's {}",
                    values[i],
                    want_values[i]
                );
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}
