//! Higher-order tets on every kernel (issue 9 item 8): per-vertex fields are interpolated
//! with the tets' own shape functions (high_order.glsl), exactly like the CPU: a quadratic
//! field on quadratic tets and a cubic on cubic tets come back exact to f32 rounding, Bezier
//! tets agree with the CPU, and the node table shows in the memory report.

mod common;

use std::sync::Arc;
use tetloc_core::cell::CellType;
use tetloc_core::geom::Vec3;
use tetloc_core::{BatchLocator, CpuLocator, Mesh};
use tetloc_testdata::KuhnGrid;
use tetloc_vulkan::{LocatorOptions, VulkanLocator};

fn quadratic(p: [f64; 3]) -> f64 {
    p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
}

fn cubic(p: [f64; 3]) -> f64 {
    p[0] * p[0] * p[0] - 2.0 * p[0] * p[1] * p[2] + p[2] * p[2] + p[1]
}

/// Points in the unit cube (the mesh) and some beyond it.
fn points(n: usize) -> Vec<Vec3> {
    let mut s = 99u64;
    let mut unit = || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..n).map(|i| std::array::from_fn(|_| if i % 10 == 0 { unit() * 1.4 - 0.2 } else { unit() })).collect()
}

#[test]
fn higher_order_tets_sample_like_the_cpu_on_every_kernel() {
    let name = "higher_order_tets_sample_like_the_cpu_on_every_kernel";
    let Some(ctx) = common::context(name) else { return };
    let pts = points(6000);
    type Field = fn([f64; 3]) -> f64;
    let cases: [(&str, u8, Field, bool); 4] = [
        ("quadratic", 2, quadratic, false),
        ("cubic", 3, cubic, false),
        ("quartic", 4, cubic, false),
        ("Bezier quadratic", 2, quadratic, true),
    ];
    for (what, order, f, bezier) in cases {
        let mut raw = KuhnGrid::new(3).jitter(0.1, 5).order(order).vertex_field(|p| f(p.map(f64::from)) as f32).raw();
        if bezier {
            // The same node rows as control points: only CPU agreement is expected.
            let cells = raw.cells.as_mut().unwrap();
            let ty = CellType::from_vtk(78, cells.types[0].def().n_nodes()).unwrap();
            cells.types.iter_mut().for_each(|t| *t = ty);
        }
        let mesh = Arc::new(Mesh::new(raw, what).unwrap());
        let (mut cpu_ids, mut cpu) = (vec![0; pts.len()], vec![0f32; pts.len()]);
        CpuLocator::new(mesh.clone()).locate_and_sample(&pts, "f", &mut cpu_ids, &mut cpu).unwrap();
        let scale = cpu.iter().filter(|v| v.is_finite()).fold(1f32, |a, v| a.max(v.abs()));
        for k in common::kernels(&ctx, name) {
            let label = format!("{what}, {k}");
            let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap();
            let items = &loc.memory_report().items;
            let table = mesh.tet_nodes.as_ref().unwrap().memory_bytes() as u64;
            assert!(items.iter().any(|m| m.name == "higher-order nodes" && m.bytes >= table), "{label}: {items:?}");
            let (mut ids, mut got) = (vec![0; pts.len()], vec![0f32; pts.len()]);
            loc.locate(&pts, &mut ids).unwrap();
            loc.sample(&pts, "f", &mut got).unwrap();
            common::check_ids(&label, &mesh, &pts, &ids, &cpu_ids);
            let (mut worst_cpu, mut worst_exact) = (0f64, 0f64);
            for (i, p) in pts.iter().enumerate() {
                assert_eq!(got[i].is_nan(), cpu[i].is_nan(), "{label}: {p:?}");
                if cpu[i].is_nan() {
                    continue;
                }
                worst_cpu = worst_cpu.max(f64::from((got[i] - cpu[i]).abs() / scale));
                worst_exact = worst_exact.max((f64::from(got[i]) - f(p.map(f64::from))).abs() / f64::from(scale));
            }
            eprintln!("{label}: worst {worst_cpu:.1e} from the CPU, {worst_exact:.1e} from f (of max|f|)");
            assert!(worst_cpu < 2e-6, "{label}: GPU values differ from the CPU's by {worst_cpu} of max|f|");
            if !bezier {
                assert!(worst_exact < 2e-6, "{label}: the polynomial is missed by {worst_exact} of max|f|");
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}
