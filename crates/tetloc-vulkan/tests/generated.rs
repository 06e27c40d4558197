//! Samples generated inside the kernels (the benchmarks' centers, random and bbox sets):
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
        for mode in [QueryKind::Centers, QueryKind::Random, QueryKind::Bbox] {
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
                QueryKind::Host => unreachable!(),
            }
            // Launches in chunks generate the same points (global sample index).
            let (p2, ids2) = chunked.locate_generated(mode, n, 42).unwrap();
            assert!(p2 == points && ids2 == ids, "{label}: chunked launches differ");
            // Another seed, other points.
            if mode != QueryKind::Centers {
                assert!(loc.locate_generated(mode, 100, 43).unwrap().0 != points[..100], "{label}: seed ignored");
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}
