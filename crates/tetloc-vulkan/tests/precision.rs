//! The cost of f64 values (issue 12.6), measured, never asserted: run with
//! `cargo test -p tetloc-vulkan --test precision -- --ignored --nocapture`.

mod common;

use std::sync::Arc;
use std::time::Instant;
use tetloc_core::gen::{generate, Shape};
use tetloc_core::locate::F64Values;
use tetloc_core::mesh::Field;
use tetloc_core::{BatchLocator, CpuLocator, Mesh};
use tetloc_vulkan::{Kernel, LocatorOptions, VulkanLocator};

/// Best of 3 runs of `f`, in M points/s.
fn rate(n: usize, mut f: impl FnMut()) -> f64 {
    let best = (0..3)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min);
    n as f64 / best / 1e6
}

/// fusion (TETLOC_BENCH_TETS, default 200k tets) with its field `f` also as f64 data (f +
/// 1e-12, which f32 cannot hold), queried at TETLOC_BENCH_POINTS (default 200k) random points
/// in random tets: the f32 path (f32 points and values), the f64 path with each backend's own
/// values, and with `F64Values` (host f64 values at the backend's ids).
#[test]
#[ignore]
fn cost_of_f64_values() {
    let env = |k: &str, d: usize| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
    let mut raw = generate(Shape::Fusion, env("TETLOC_BENCH_TETS", 200_000), 1);
    let f = raw.fields.iter().find(|f| f.name == "f").unwrap().clone();
    raw.fields.push(Field::from_f64("g", f.location, f.values.iter().map(|&v| f64::from(v) + 1e-12).collect()));
    let mesh = Arc::new(Mesh::new(raw, "fusion").unwrap());
    let n = env("TETLOC_BENCH_POINTS", 200_000);
    let mut unit = common::unit_f64(12345);
    let pts64: Vec<[f64; 3]> =
        (0..n).map(|_| common::point_in_a_tet(&mesh, &mut unit, 0.01, |v| mesh.vertex64(v))).collect();
    let pts: Vec<[f32; 3]> = pts64.iter().map(|p| p.map(|c| c as f32)).collect();
    let (mut ids, mut v32, mut v64) = (vec![0i32; n], vec![0f32; n], vec![0f64; n]);
    let mut report = |name: &str, loc: &mut dyn BatchLocator| {
        let a = rate(n, || loc.sample_many(&pts, &["g"], &mut ids, &mut v32).unwrap());
        let b = rate(n, || loc.sample_many64(&pts64, &["g"], &mut ids, &mut v64).unwrap());
        eprintln!("{name:<16} f32 path {a:8.2} M/s   f64 points {b:8.2} M/s");
    };
    report("cpu", &mut CpuLocator::new(mesh.clone()));
    report("cpu F64Values", &mut F64Values::new(CpuLocator::new(mesh.clone()), mesh.clone()));
    if let Some(ctx) = common::context("cost_of_f64_values") {
        let loc = VulkanLocator::new(ctx.clone(), mesh.clone(), Kernel::SoftBvh, LocatorOptions::default()).unwrap();
        let mut loc = F64Values::new(loc, mesh.clone());
        let a = rate(n, || loc.inner_mut().sample_many64(&pts64, &["g"], &mut ids, &mut v64).unwrap());
        let b = rate(n, || loc.sample_many64(&pts64, &["g"], &mut ids, &mut v64).unwrap());
        eprintln!("soft-bvh         f64 points, f32 values {a:8.2} M/s   F64Values {b:8.2} M/s");
    }
}
