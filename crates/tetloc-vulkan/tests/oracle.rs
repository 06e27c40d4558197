//! Every kernel, id and scalar variant, against the oracle query sets of ../shared/data.

mod common;

use std::collections::BTreeMap;
use std::sync::Arc;
use tetloc_core::locate::F64Values;
use tetloc_core::{BatchLocator, CpuLocator, Mesh};
use tetloc_testdata::{query_sets, require_data, QuerySet, F32_VALUES, F64_VALUES};
use tetloc_vulkan::{Kernel, LocatorOptions, SoftBvhOptions, VulkanLocator};

/// Relative tolerance of interpolated values (relative to max(|expected|, 1)).
const VALUE_TOL: f64 = 1e-5;

fn check_set(loc: &mut VulkanLocator, mesh: &Mesh, set: &QuerySet, cpu: &[i32]) {
    let label = format!("{} {}", loc.kernel(), set.label);
    let n = set.points.len();
    let mut ids = vec![0; n];
    loc.locate(&set.points, &mut ids).unwrap();

    // Oracle: exact ids except at points within rounding of a face.
    let wrong: Vec<usize> = (0..n).filter(|&i| ids[i] != set.cell[i] && !set.ambiguous(i)).collect();
    assert!(
        wrong.is_empty(),
        "{label}: {} ids differ from the oracle at unambiguous points, e.g. point {} {:?}: {} vs {}",
        wrong.len(),
        wrong[0],
        set.points[wrong[0]],
        ids[wrong[0]],
        set.cell[wrong[0]]
    );
    // No cracks: centres and random points lie in tets.
    if set.label.ends_with(".centers") || set.label.ends_with(".random") {
        let outside = ids.iter().filter(|&&t| t < 0).count();
        assert_eq!(outside, 0, "{label}: {outside} points inside the mesh came back outside");
    }
    // The CPU definition: every answer contains its point; -1 only where the CPU finds none.
    let differ = common::check_ids(&label, mesh, &set.points, &ids, cpu);
    let ambiguous_differ = (0..n).filter(|&i| ids[i] != cpu[i]).filter(|&i| set.ambiguous(i)).count();
    assert_eq!(differ, ambiguous_differ, "{label}: GPU and CPU ids differ at unambiguous points");

    // Scalar variants.
    let mut oracle_off = vec![];
    if let (Some(expected), Ok(f)) = (&set.value, mesh.field("f")) {
        let mut v = vec![0f32; n];
        loc.sample(&set.points, "f", &mut v).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= VALUE_TOL * b.abs().max(1.0);
        for i in 0..n {
            let (got, want) = (v[i] as f64, expected[i]);
            if want.is_nan() || got.is_nan() {
                assert!(want.is_nan() == got.is_nan() || set.ambiguous(i), "{label}: f at point {i}: {got} vs {want}");
                continue;
            }
            // The reference: f64 barycentrics on the file's coordinates, in the tet the kernel
            // chose (on a mesh stored in f64 the kernels refine theirs there: the slivers of
            // delaunay_s are off by up to 3e-4 on the working copy).
            let exact = tetloc_testdata::exact_value(mesh, ids[i] as usize, set.points[i], &f.values);
            assert!(close(got, exact), "{label}: f at point {i}: {got}, exact {exact}");
            if !close(exact, want) {
                oracle_off.push(i); // the oracle itself is off here (or another tet was chosen)
                continue;
            }
            assert!(close(got, want), "{label}: f at point {i}: {got} vs oracle {want}");
        }
    }
    if let Ok(cell) = mesh.field("cellval") {
        let mut v = vec![0f32; n];
        loc.sample(&set.points, "cellval", &mut v).unwrap();
        for i in 0..n {
            let want = if ids[i] >= 0 { cell.values[ids[i] as usize] } else { f32::NAN };
            assert!(
                v[i] == want || (v[i].is_nan() && want.is_nan()),
                "{label}: cellval at point {i}: {} vs {want}",
                v[i]
            );
        }
    }
    println!(
        "{label}: ok ({ambiguous_differ} ambiguous points answered differently from the CPU; \
         oracle value off from f64 interpolation at {oracle_off:?})"
    );
}

#[test]
fn every_kernel_matches_the_oracle() {
    let Some(dir) = require_data("every_kernel_matches_the_oracle") else { return };
    every_kernel_matches_the_oracle_of("every_kernel_matches_the_oracle", &dir);
}

/// The fresh-clone counterpart: the same checks on meshes generated at test time, with exact
/// answers (`tetloc_testdata::generated_data`).
#[test]
fn every_kernel_matches_the_generated_oracle() {
    every_kernel_matches_the_oracle_of("every_kernel_matches_the_generated_oracle", tetloc_testdata::generated_data());
}

/// The checks over the query sets of `dir`, on every kernel.
fn every_kernel_matches_the_oracle_of(test: &str, dir: &std::path::Path) {
    let Some(ctx) = common::context(test) else { return };
    let kernels = common::kernels(&ctx, test);
    let mut by_mesh: BTreeMap<_, Vec<QuerySet>> = BTreeMap::new();
    for s in query_sets(dir) {
        by_mesh.entry(s.mesh_path.clone()).or_default().push(s);
    }
    assert!(by_mesh.len() >= 3, "expected the oracle meshes in {}", dir.display());
    for (path, sets) in by_mesh {
        let mesh = Arc::new(tetloc_io::read_mesh(&path, None).unwrap());
        let mut cpu_loc = CpuLocator::new(mesh.clone());
        let cpu: Vec<Vec<i32>> = sets
            .iter()
            .map(|s| {
                let mut ids = vec![0; s.points.len()];
                cpu_loc.locate(&s.points, &mut ids).unwrap();
                ids
            })
            .collect();
        let mut configs: Vec<_> = kernels.iter().map(|&k| (k, LocatorOptions::default())).collect();
        let soft_bvh = [
            // soft-bvh's entry grid: cells no tet overlaps (holes, sparse meshes) answer -1 at once.
            SoftBvhOptions { grid_start: true, walk_start: false, ..Default::default() },
            // The default walks from the grid; walks leave non-convex meshes and end on faces,
            // where traversal takes over. Traversal from the root:
            SoftBvhOptions { walk_start: false, ..Default::default() },
            // f32 first: the f64 fallback must still decide the points near faces here.
            SoftBvhOptions { walk_start: true, f32_first: true, ..Default::default() },
            // Deferred exact tests: the points near faces go through the second, exact pass.
            SoftBvhOptions { defer_exact: true, ..Default::default() },
            SoftBvhOptions { defer_exact: true, walk_start: false, ..Default::default() },
        ];
        configs.extend(soft_bvh.map(|o| (Kernel::SoftBvh, common::soft_bvh(o))));
        let n_kernels = kernels.len();
        for (c, (k, opts)) in configs.into_iter().enumerate() {
            let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), k, opts).unwrap();
            for (set, cpu) in sets.iter().zip(&cpu) {
                check_set(&mut loc, &mesh, set, cpu);
            }
            // Each kernel's default options with the f64 option: the oracle's values within
            // 1e-5 of |oracle| even near zero, and the CPU's f64 values bit for bit.
            if c < n_kernels {
                let mut f64_loc = F64Values::new(loc, mesh.clone());
                for set in &sets {
                    let (mismatches, bad_values, _) = tetloc_testdata::compare_f64_set(&mut f64_loc, set, F64_VALUES);
                    assert_eq!((mismatches, bad_values), (0, 0), "{k:?} {} f64", set.label);
                    let widened: Vec<[f64; 3]> = set.points.iter().map(|p| p.map(f64::from)).collect();
                    same_as_cpu(&mut f64_loc, &mesh, &widened, &format!("{k:?} {}", set.label));
                }
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}

/// `loc`'s f64 path gives the CPU's ids and f64 values, bit for bit (the values of mesh `m`'s
/// field `f`, when it has one).
fn same_as_cpu(loc: &mut dyn BatchLocator, m: &Arc<Mesh>, points: &[[f64; 3]], label: &str) {
    let fields: &[&str] = if m.field("f").is_ok() { &["f"] } else { &[] };
    let n = points.len();
    let run = |loc: &mut dyn BatchLocator| {
        let (mut ids, mut values) = (vec![0i32; n], vec![0f64; n * fields.len()]);
        loc.sample_many64(points, fields, &mut ids, &mut values).unwrap();
        (ids, values.iter().map(|v| v.to_bits()).collect::<Vec<_>>())
    };
    let (gpu, cpu) = (run(loc), run(&mut CpuLocator::new(m.clone())));
    assert_eq!(gpu.0, cpu.0, "{label}: ids");
    assert!(gpu.1 == cpu.1, "{label}: f64 values differ from the CPU's");
}

/// A mesh far from the origin (`utm/`, f64 vertices and points): every kernel searches the
/// mesh's centred working frame and gives the oracle's cells and values, as at the origin.
#[test]
fn every_kernel_matches_the_oracle_far_from_the_origin() {
    let test = "every_kernel_matches_the_oracle_far_from_the_origin";
    let Some(dir) = require_data(test) else { return };
    let Some(ctx) = common::context(test) else { return };
    let sets = tetloc_testdata::utm_sets(&dir);
    assert!(sets.len() >= 3, "expected the utm query sets in {}", dir.display());
    let mesh = Arc::new(tetloc_io::read_mesh(&sets[0].mesh_path, None).unwrap());
    for k in common::kernels(&ctx, test) {
        let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap();
        for set in &sets {
            // The kernels' f32 values (widened): within 1e-5 of max(|oracle|, 1).
            let (mismatches, bad_values, lost) = tetloc_testdata::compare_f64_set(&mut loc, set, F32_VALUES);
            assert_eq!((mismatches, bad_values, lost), (0, 0, 0), "{} {}", k.name(), set.label);
        }
        // The f64 option: within 1e-5 of |oracle| even near zero, the CPU's values bit for bit.
        let mut f64_loc = F64Values::new(loc, mesh.clone());
        for set in &sets {
            let (mismatches, bad_values, lost) = tetloc_testdata::compare_f64_set(&mut f64_loc, set, F64_VALUES);
            assert_eq!((mismatches, bad_values, lost), (0, 0, 0), "{} {} f64", k.name(), set.label);
            same_as_cpu(&mut f64_loc, &mesh, set.points64.as_ref().unwrap(), &format!("{} {}", k.name(), set.label));
        }
    }
    common::assert_no_validation_errors(&ctx);
}
