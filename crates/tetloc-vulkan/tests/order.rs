//! Query ordering (src/locator/order.rs): batches sorted along the Morton curve on the GPU
//! give exactly the answers of the same batches located as given, in the given order.

mod common;

use tetloc_core::BatchLocator;
use tetloc_vulkan::{Kernel, LocatorOptions, QueryKind, VulkanLocator};

#[test]
fn ordered_batches_give_the_unordered_answers() {
    let name = "ordered_batches_give_the_unordered_answers";
    let Some(ctx) = common::context(name) else { return };
    let mesh = common::jets(8000, 7);
    // Above the ordering threshold (32k points), and in launches of a few thousand points.
    let n = 40_000;
    // The ordering is the same for every kernel (samples.glsl): soft-bvh and one rt kernel.
    let kernels = common::kernels(&ctx, name);
    for k in kernels.into_iter().filter(|k| matches!(k, Kernel::SoftBvh | Kernel::RtBvh)) {
        let make = |order_queries, chunk_points| {
            let opts = LocatorOptions { order_queries, chunk_points, ..Default::default() };
            VulkanLocator::new(ctx.clone(), mesh.clone(), k, opts).unwrap()
        };
        let (mut plain, mut ordered, mut chunked) = (make(false, 1 << 22), make(true, 1 << 22), make(true, 7000));
        for mode in [QueryKind::Random, QueryKind::Bbox] {
            let label = format!("{k} {}", mode.name());
            let (points, ids) = plain.locate_generated(mode, n, 3).unwrap();
            for loc in [&mut ordered, &mut chunked] {
                let (p2, ids2) = loc.locate_generated(mode, n, 3).unwrap();
                assert!(p2 == points, "{label}: ordering changed the generated points");
                let diff = ids.iter().zip(&ids2).filter(|(a, b)| a != b).count();
                assert_eq!(diff, 0, "{label}: {diff} of {n} ids differ when ordered");
            }
            // The launch really ran in Morton order of the 64^3 grid over the mesh bounds.
            let perm = ordered.last_order(n).unwrap().expect("ordering buffers");
            let mut seen = vec![false; n];
            perm.iter().for_each(|&i| seen[i as usize] = true);
            assert!(seen.iter().all(|&s| s), "{label}: the order is not a permutation");
            let keys: Vec<u64> = perm.iter().map(|&i| morton_cell(&mesh, points[i as usize])).collect();
            // (The shader rounds in f32: a point within rounding of a cell wall may sit one cell off.)
            let unsorted = keys.windows(2).filter(|w| w[0] > w[1]).count();
            assert!(unsorted <= 10, "{label}: {unsorted} of {n} neighbours out of Morton order");
            assert!(perm.windows(2).any(|w| w[0] > w[1]), "{label}: the order is the identity");
            // Host points: ids and values, in the caller's order.
            let mut a = vec![0i32; n];
            let mut b = vec![0i32; n];
            plain.locate(&points, &mut a).unwrap();
            ordered.locate(&points, &mut b).unwrap();
            assert!(a == ids && b == ids, "{label}: host batch ids differ");
            let mut fa = vec![0f32; n];
            let mut fb = vec![0f32; n];
            plain.sample(&points, "f", &mut fa).unwrap();
            chunked.sample(&points, "f", &mut fb).unwrap();
            let same = fa.iter().zip(&fb).all(|(x, y)| x.to_bits() == y.to_bits());
            assert!(same, "{label}: host batch values differ when ordered");
            assert!(ids.iter().filter(|&&t| t >= 0).count() > n / 4, "{label}: too few points inside");
        }
    }
    common::assert_no_validation_errors(&ctx);
}

/// The Morton key of p's cell in the 64^3 grid over the mesh bounds (order.comp's key,
/// computed in f64 here: only points within rounding of a cell wall could differ).
fn morton_cell(mesh: &tetloc_core::mesh::Mesh, p: [f32; 3]) -> u64 {
    let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
    let mut key = 0u64;
    for a in 0..3 {
        let c = (((p[a] - lo[a]) as f64 / (hi[a] - lo[a]) as f64 * 64.0).floor()).clamp(0.0, 63.0) as u64;
        for bit in 0..6 {
            key |= ((c >> bit) & 1) << (3 * bit + a);
        }
    }
    key
}
