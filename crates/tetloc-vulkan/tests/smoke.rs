mod common;

use tetloc_core::{BatchLocator, CpuLocator};
use tetloc_vulkan::{Kernel, LocatorOptions, VulkanLocator};

#[test]
fn soft_bvh_matches_cpu_on_tet_centres() {
    let Some(ctx) = common::context("soft_bvh_matches_cpu_on_tet_centres") else { return };
    let mesh = common::jets(5000, 1);
    let points: Vec<_> = (0..mesh.n_tets()).map(|t| mesh.tet_center(t)).collect();
    let mut cpu = vec![0; points.len()];
    CpuLocator::new(mesh.clone()).locate(&points, &mut cpu).unwrap();
    for k in common::kernels(&ctx, "smoke") {
        let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap();
        let mut gpu = vec![0; points.len()];
        loc.locate(&points, &mut gpu).unwrap();
        println!("{k}: {} outside", gpu.iter().filter(|&&g| g < 0).count());
        let d = common::check_ids(k.name(), &mesh, &points, &gpu, &cpu);
        println!("{k}: {d} differ; {:?}", loc.memory_report().final_bytes);
    }
    common::assert_no_validation_errors(&ctx);
    assert!(ctx.validation_enabled());
    let _ = Kernel::ALL;
}
