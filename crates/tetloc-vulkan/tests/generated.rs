//! Samples generated inside the kernels (the benchmarks' centers, random, bbox and grid sets):
//! the points are what the CPU computes, and every kernel locates them correctly.

mod common;

use tetloc_core::locate::GridSampler;
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
                    // The kernel's points are ImageGrid::point's, bit for bit (n = 20000: the
                    // first points of the 28³ grid, all its z slices but a part of the last).
                    let want = tetloc_core::queries::generate(&mesh, mode, n, 42);
                    assert!(points == want, "{label}: grid points differ from the CPU's");
                    let g = tetloc_core::queries::grid(&mesh, n);
                    assert_eq!(g.dims, [28; 3]);
                    assert!(points.iter().enumerate().all(|(i, p)| *p == g.point(i)));
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

/// `sample_grid` (the kernels make resample's grid points from its axes) answers exactly as
/// `sample_many` of the host's points: the same ids and values, bit for bit, on every
/// kernel, from launches that start inside a slab (chunks of 100), near the origin and far
/// from it (a mesh in UTM-like coordinates, searched in its centred working frame).
#[test]
fn grid_samples_are_the_host_points() {
    let name = "grid_samples_are_the_host_points";
    let Some(ctx) = common::context(name) else { return };
    let near = tetloc_testdata::KuhnGrid::new(5).jitter(0.25, 7).vertex_field(|p| p[0] + 2.0 * p[1]).raw();
    let shift = [512_345.037_5, 4_123_456.062_5, 0.3];
    let file: Vec<[f64; 3]> =
        near.points.iter().map(|p| std::array::from_fn(|k| p[k] as f64 * 1000.0 + shift[k])).collect();
    let far = tetloc_core::RawMesh {
        points: file.iter().map(|p| p.map(|c| c as f32)).collect(),
        points64: Some(file),
        ..near.clone()
    };
    for raw in [near, far] {
        let mesh = std::sync::Arc::new(tetloc_core::Mesh::new(raw, "grid").unwrap());
        let (lo, hi) = mesh.file_bounds();
        // A little beyond the mesh: some points outside.
        let pad: [f64; 3] = std::array::from_fn(|k| 0.05 * (hi[k] - lo[k]));
        let lo: [f64; 3] = std::array::from_fn(|k| lo[k] - pad[k]);
        let hi: [f64; 3] = std::array::from_fn(|k| hi[k] + pad[k]);
        let grid = tetloc_core::ops::ImageGrid::spanning(lo, hi, [13, 11, 9]).unwrap();
        let range = 5..grid.n_points() - 3;
        let points = tetloc_core::locate::grid_points(&grid, range.clone());
        let fields = ["f", "f"];
        for k in common::kernels(&ctx, name) {
            let opts = LocatorOptions { chunk_points: 100, ..Default::default() };
            let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), k, opts).unwrap();
            let (mut ids, mut values) = (vec![0; points.len()], vec![0f32; 2 * points.len()]);
            loc.sample_grid(&grid, range.clone(), &fields, &mut ids, &mut values).unwrap();
            let (mut ids2, mut values2) = (vec![0; points.len()], vec![0f32; 2 * points.len()]);
            loc.sample_many(&points, &fields, &mut ids2, &mut values2).unwrap();
            let label = format!("{k} {}", mesh.info.frame.is_identity());
            assert_eq!(ids, ids2, "{label}");
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&values), bits(&values2), "{label}");
            let inside = ids.iter().filter(|&&t| t >= 0).count();
            assert!(inside > points.len() / 2 && inside < points.len(), "{label}: {inside} inside");
        }
    }
    common::assert_no_validation_errors(&ctx);
}
