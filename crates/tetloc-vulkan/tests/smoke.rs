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

/// The memory probe (issue 12's random-read microbenchmark) reads what the host says it
/// reads, for every address pattern, with its array in one buffer and split over four.
#[test]
fn memory_probe_reads_the_host_sequence() {
    use tetloc_vulkan::memprobe::{expected_sums, MemProbe, Pattern, ELEMENT_BYTES};
    let Some(ctx) = common::context("memory_probe_reads_the_host_sequence") else { return };
    let span = 3 * 4096 + 160; // with a 4 KiB buffer limit: four buffers, the last one short
    for max_buffer in [Some(4096), None] {
        let mut probe = MemProbe::new(&ctx, span, 512, max_buffer).unwrap();
        for pattern in Pattern::ALL {
            for sub_span in [span, 1000] {
                let got = probe.sums(pattern, 7, sub_span).unwrap();
                let want = expected_sums(pattern, 512, 7, (sub_span / ELEMENT_BYTES) as u32);
                assert_eq!(got, want, "{pattern:?}, span {sub_span}, buffer limit {max_buffer:?}");
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}
