//! Samples generated inside the kernels (the benchmarks' centers, random, bbox and grid sets):
//! the points are what the CPU computes, and every kernel locates them correctly.

mod common;

use tetloc_core::{BatchLocator, CpuLocator};
use tetloc_vulkan::{LocatorOptions, QueryKind, VulkanLocator};

#[test]
fn generated_samples_are_located_correctly() {
    let name = "generated_samples_are_located_correctly";
    let Some(ctx) = common::context(name) else { return };
    let mesh = common::jets(8000, 5);
    let mut cpu_loc = CpuLocator::new(mesh.clone());
    let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
    for k in common::kernels(&ctx, name) {
        let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap();
        let mut chunked = VulkanLocator::new(
            ctx.clone(),
            mesh.clone(),
            k,
            LocatorOptions { chunk_points: 1000, ..Default::default() },
        )
        .unwrap();
        for mode in [QueryKind::Centers, QueryKind::Random, QueryKind::Bbox, QueryKind::Grid] {
            let n = if mode == QueryKind::Centers { mesh.n_tets() } else { 20_000 };
            let (points, ids) = loc.locate_generated(mode, n, 42).unwrap();
            let mut cpu = vec![0; n];
            cpu_loc.locate(&points, &mut cpu).unwrap();
            let label = format!("{k} {}", mode.name());
            common::check_ids(&label, &mesh, &points, &ids, &cpu);
            match mode {
                QueryKind::Centers => {
                    // The kernel computes Mesh::tet_center bit for bit.
                    for (t, p) in points.iter().enumerate() {
                        assert_eq!(*p, mesh.tet_center(t), "{label}: centre of tet {t}");
                    }
                    assert!(ids.iter().all(|&t| t >= 0), "{label}: a tet centre came back outside");
                }
                QueryKind::Random => {
                    let outside = cpu.iter().filter(|&&t| t < 0).count();
                    assert!(outside <= n / 1000, "{label}: {outside} random points in tets are outside the mesh");
                    let distinct: std::collections::HashSet<i32> = ids.iter().copied().collect();
                    assert!(distinct.len() > mesh.n_tets() / 2, "{label}: only {} tets sampled", distinct.len());
                }
                QueryKind::Bbox => {
                    assert!(
                        points.iter().all(|p| (0..3).all(|a| p[a] >= lo[a] && p[a] <= hi[a])),
                        "{label}: outside the box"
                    );
                }
                QueryKind::Grid => {
                    // The kernel computes queries::grid_point bit for bit (n = 20000: the
                    // first points of the 28³ grid, all its z slices but a part of the last).
                    let want = tetloc_core::queries::generate(&mesh, mode, n, 42);
                    assert!(points == want, "{label}: grid points differ from the CPU's");
                    let g = tetloc_core::queries::grid(&mesh, n);
                    assert_eq!(g.dims, [28; 3]);
                    for (i, p) in points.iter().enumerate().step_by(97) {
                        let exact = g.point(i);
                        assert!((0..3).all(|k| (p[k] - exact[k]).abs() <= 4.0 * f32::EPSILON * exact[k].abs().max(1.0)));
                    }
                    let inside = ids.iter().filter(|&&t| t >= 0).count();
                    assert!(inside > n / 2, "{label}: only {inside} grid points inside a box-filling mesh");
                }
                QueryKind::Host => unreachable!(),
            }
            // Launches in chunks generate the same points (global sample index).
            let (p2, ids2) = chunked.locate_generated(mode, n, 42).unwrap();
            assert!(p2 == points && ids2 == ids, "{label}: chunked launches differ");
            // Another seed, other points.
            if mode != QueryKind::Centers && mode != QueryKind::Grid {
                assert!(loc.locate_generated(mode, 100, 43).unwrap().0 != points[..100], "{label}: seed ignored");
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}
