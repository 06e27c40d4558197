//! The same small mesh rendered with the CPU backend and with every GPU kernel agrees
//! (PSNR ≥ 40 dB). Runs on whatever Vulkan device there is (lavapipe in CI); with `CI`
//! set, a missing device or missing ray tracing fails the test instead of skipping it.

use std::sync::Arc;
use tetloc_core::testdata::in_ci;
use tetloc_core::CpuLocator;
use tetloc_render::{compare_locators, testmesh, RenderOptions, Renderer};
use tetloc_vulkan::{Context, ContextOptions, Kernel, LocatorOptions, VulkanLocator};

#[test]
fn every_gpu_kernel_renders_like_the_cpu() {
    let ctx = match Context::with_options(ContextOptions { device_index: None, validation: true }) {
        Ok(c) => c,
        Err(e) if !in_ci() => {
            eprintln!("SKIPPED every_gpu_kernel_renders_like_the_cpu: {e}");
            return;
        }
        Err(e) => panic!("no Vulkan device in CI: {e}"),
    };
    assert!(ctx.info().ray_tracing || !in_ci(), "CI must run every kernel, but {} has no ray tracing", ctx.info().name);
    let mesh = Arc::new(testmesh::torus(10, 3));
    let opts = RenderOptions { width: 96, height: 72, azimuth: 30.0, elevation: 25.0, ..Default::default() };
    for field in ["f", "cellval"] {
        if mesh.field(field).is_err() {
            continue;
        }
        let renderer = Renderer::new(mesh.clone(), field, &opts).unwrap();
        let mut cpu = CpuLocator::new(mesh.clone());
        for kernel in Kernel::ALL.into_iter().filter(|k| ctx.info().ray_tracing || !k.needs_ray_tracing()) {
            let mut gpu = VulkanLocator::new(ctx.clone(), mesh.clone(), kernel, LocatorOptions::default()).unwrap();
            let cmp = compare_locators(&renderer, &mut cpu, &mut gpu).unwrap();
            eprintln!("{kernel} field {field}: PSNR {:.1} dB", cmp.psnr_db);
            assert!(cmp.psnr_db >= 40.0, "{kernel} field {field}: PSNR {:.1} dB against the CPU", cmp.psnr_db);
            assert!(cmp.stats[1].samples > 0);
        }
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}
