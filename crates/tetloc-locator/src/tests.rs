//! The front door: names, the stack each option gives (the same for every front end, which
//! all build through [`Locator::builder`]), and what the built locators answer.

use crate::{Backend, Error, Kernel, Layer, Locator};
use std::sync::Arc;
use tetloc_core::locate::{CellLocator, F64Values, FiniteOnly, Precision, Tolerance, WithTolerance};
use tetloc_core::{BatchLocator, CpuLocator, Mesh};
use tetloc_testdata::{in_ci, KuhnGrid};

fn mesh() -> Arc<Mesh> {
    Arc::new(KuhnGrid::new(6).jitter(0.2, 3).mesh("grid"))
}

#[test]
fn every_name_parses_back_and_unknown_names_list_the_known_ones() {
    for name in crate::names().into_iter().chain(["auto"]) {
        assert_eq!(name.parse::<Backend>().unwrap().name(), name);
    }
    assert_eq!("soft-bvh".parse::<Backend>().unwrap(), Backend::Kernel(Kernel::SoftBvh));
    let e = "warp-drive".parse::<Backend>().unwrap_err();
    assert_eq!(
        e.to_string(),
        "unknown backend 'warp-drive' (known: cpu, soft-bvh, rt-bvh, rt-rep-faces, rt-shared-faces, auto)"
    );
    assert!(!e.is_device());
}

/// The layers for every combination of precision and tolerance, planned and built.
#[test]
fn the_options_give_one_stack() {
    use Layer::*;
    let m = mesh();
    let cases = [
        (Precision::F32, "0", vec![FiniteOnly, CellLocator]),
        (Precision::F64, "0", vec![FiniteOnly, CellLocator, F64Values]),
        (Precision::F32, "1%", vec![FiniteOnly, CellLocator, WithTolerance]),
        (Precision::F64, "0.01", vec![FiniteOnly, CellLocator, F64Values, WithTolerance]),
    ];
    for (precision, tolerance, want) in cases {
        let b = Locator::builder(m.clone())
            .backend(Backend::Cpu)
            .precision(precision)
            .tolerance(tolerance.parse().unwrap())
            .quiet(true);
        assert_eq!(b.stack(), want, "{precision} {tolerance}");
        let built = b.build().unwrap();
        assert_eq!(built.stack, want);
        assert_eq!(built.backend, Backend::Cpu);
        let names: Vec<&str> = want.iter().map(|l| l.name()).collect();
        assert_eq!(built.describe(), format!("cpu > {}", names.join(" > ")));
    }
}

/// The built stack answers as the wrappers stacked by hand in that order.
#[test]
fn the_built_stack_answers_as_the_wrappers_by_hand() {
    let m = mesh();
    let tolerance: Tolerance = "5%".parse().unwrap();
    let built = Locator::builder(m.clone())
        .backend(Backend::Cpu)
        .precision(Precision::F64)
        .tolerance(tolerance)
        .quiet(true)
        .build()
        .unwrap();
    let exact = CellLocator::new(FiniteOnly::new(CpuLocator::new(m.clone())), m.clone());
    let mut by_hand = WithTolerance::new(F64Values::new(exact, m.clone()), m.clone(), tolerance);
    // Points inside, just outside (within the tolerance), far outside, and NaN.
    let mut pts: Vec<[f64; 3]> = (0..2000).map(|i| [(i % 13) as f64 / 12.0, (i % 7) as f64 / 6.0, 0.5]).collect();
    pts.extend([[-0.004, 0.5, 0.5], [1.003, 0.2, 0.7], [3.0, 3.0, 3.0], [f64::NAN, 0.1, 0.1]]);
    let run = |loc: &mut dyn BatchLocator| {
        let (mut ids, mut values) = (vec![0; pts.len()], vec![0.0; pts.len()]);
        loc.sample_many64(&pts, &["f"], &mut ids, &mut values).unwrap();
        (ids, values)
    };
    let (mut loc, want) = (built.locator, run(&mut by_hand));
    let got = run(&mut *loc);
    assert_eq!(got.0, want.0);
    assert_eq!(
        got.1.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        want.1.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
    assert!(got.0[2000] >= 0 && got.0[2001] >= 0 && got.0[2002] < 0 && got.0[2003] < 0, "{:?}", &got.0[2000..]);
}

#[test]
fn a_deferred_cpu_build_reports_the_mesh_only() {
    let m = mesh();
    let now = Locator::builder(m.clone()).backend(Backend::Cpu).build().unwrap();
    let later = Locator::builder(m.clone()).backend(Backend::Cpu).defer_cpu_build(true).build().unwrap();
    assert_eq!(now.memory.on, "host");
    assert_eq!(now.memory.items["tet neighbours"], 16 * m.n_tets() as u64);
    assert_eq!(now.memory.final_bytes, now.memory.items.values().sum::<u64>());
    assert_eq!(later.memory.items.keys().collect::<Vec<_>>(), ["mesh points", "mesh tets"]);
}

/// `true` when this machine has a Vulkan device; otherwise SKIPPED (a failure in CI).
fn has_vulkan(test: &str) -> bool {
    match crate::context(None) {
        Ok(_) => true,
        Err(e) => {
            assert!(!in_ci(), "{test}: no Vulkan device in CI: {}", e.msg);
            eprintln!("SKIPPED {test}: {}", e.msg);
            false
        }
    }
}

/// On a GPU kernel: the same layers, the device's memory, and the device's errors typed.
#[test]
fn gpu_kernels_get_the_same_stack() {
    if !has_vulkan("gpu_kernels_get_the_same_stack") {
        return;
    }
    let m = mesh();
    let b = Locator::builder(m.clone()).backend(Backend::Kernel(Kernel::SoftBvh)).tolerance("1%".parse().unwrap());
    let built = b.build().unwrap();
    assert_eq!(built.describe(), "soft-bvh > FiniteOnly > CellLocator > WithTolerance");
    assert_eq!(built.memory.on, "device");
    assert!(built.memory.final_bytes > 0 && built.memory.peak_bytes >= built.memory.final_bytes);
    let bad = crate::available(None).len() + 5;
    let e = b.clone().device(Some(bad)).build().err().expect("no such device");
    assert!(e.is_device() && matches!(e, Error::NoDevice { .. }), "{e}");
    assert!(e.to_string().starts_with("soft-bvh: no Vulkan device: "), "{e}");
    // `auto` on a device that cannot be opened: cpu, and why.
    let auto = Locator::builder(m.clone()).device(Some(bad)).quiet(true).build().unwrap();
    assert_eq!(auto.backend, Backend::Cpu);
    assert!(matches!(auto.auto.unwrap().reason, crate::AutoReason::Unusable(_)));
    let ctx = crate::context(None).unwrap();
    if !ctx.info().ray_tracing {
        let e = b.backend(Backend::Kernel(Kernel::RtBvh)).build().err().expect("no ray tracing");
        assert!(matches!(e, Error::NoRayTracing { .. }), "{e}");
    }
}

/// `auto` on a Vulkan device that runs on the CPU (lavapipe) is `cpu`, decided without a
/// measurement; on a GPU it is one of the backends that run there.
#[test]
fn auto_takes_cpu_on_a_cpu_device() {
    if !has_vulkan("auto_takes_cpu_on_a_cpu_device") {
        return;
    }
    let built = Locator::builder(mesh()).quiet(true).build().unwrap();
    let choice = built.auto.expect("auto says why");
    assert_eq!(choice.backend, built.backend);
    if crate::context(None).unwrap().info().device_type == "cpu" {
        assert_eq!(built.backend, Backend::Cpu);
        assert!(matches!(choice.reason, crate::AutoReason::CpuDevice(_)), "{}", choice.reason);
    } else {
        assert!(crate::available(None).contains(&built.backend));
    }
}

/// Every stack the front door builds takes another time step's fields (`Mesh::with_fields`)
/// through all its layers, on the CPU and on a GPU kernel: the search is kept where a viewer
/// or `render --time-step all` moves through time, and the answers are then a new stack's.
/// The layers pass the backend's preferred batch on too.
#[test]
fn every_built_stack_takes_another_steps_fields() {
    let m = mesh();
    let later = |f: &tetloc_core::mesh::Field| {
        let values = (0..f.values.len()).map(|i| 1.0 - f.value64(i)).collect();
        tetloc_core::mesh::Field::from_f64(f.name.clone(), f.location, values)
    };
    let step = Arc::new(m.with_fields(m.fields.iter().map(later).collect()).unwrap());
    let mut backends = vec![Backend::Cpu];
    if has_vulkan("every_built_stack_takes_another_steps_fields") {
        backends.push(Backend::Kernel(Kernel::SoftBvh));
    }
    let points: Vec<[f32; 3]> = (0..200).map(|i| [0.1 + 0.004 * i as f32, 0.5, 0.3 + 0.002 * i as f32]).collect();
    for backend in backends {
        for (precision, tolerance) in [(Precision::F32, "0"), (Precision::F64, "1%")] {
            let b = |m: &Arc<Mesh>| {
                let b = Locator::builder(m.clone()).backend(backend).precision(precision).quiet(true);
                b.tolerance(tolerance.parse().unwrap()).build().unwrap()
            };
            let mut built = b(&m);
            // (And the backend's preferred batch comes through every layer: the CPU's alone.)
            assert_eq!(built.locator.preferred_batch().is_some(), backend == Backend::Cpu, "{}", built.describe());
            assert!(built.locator.take_fields(&step), "{}", built.describe());
            let sampled = |loc: &mut dyn BatchLocator| {
                let (mut ids, mut values) = (vec![0; points.len()], vec![0f32; points.len()]);
                loc.locate_and_sample(&points, "f", &mut ids, &mut values).unwrap();
                (ids, values.iter().map(|v| v.to_bits()).collect::<Vec<_>>())
            };
            let taken = sampled(&mut *built.locator);
            assert!(taken == sampled(&mut *b(&step).locator), "{}: not a new stack's answers", built.describe());
        }
    }
}
