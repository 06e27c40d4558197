//! Shared helpers of the integration tests: a context with validation (or a SKIPPED
//! message outside CI when there is no Vulkan), meshes, and the checks every kernel must pass.
#![allow(dead_code)]

use std::sync::Arc;
use tetloc_core::geom::{self, Vec3};
use tetloc_core::mesh::Mesh;
use tetloc_testdata::in_ci;
use tetloc_vulkan::{Context, ContextOptions, Kernel, LocatorOptions, SoftBvhOptions, VkError};

/// A validating context on the default device; `None` (after printing SKIPPED) when this
/// machine has no Vulkan loader or device, except in CI where that fails the test.
pub fn context(test: &str) -> Option<Arc<Context>> {
    match Context::with_options(ContextOptions { device_index: None, validation: true, pipeline_cache_dir: None }) {
        Ok(c) => Some(c),
        Err(e @ (VkError::NoLoader(_) | VkError::NoDevice)) => {
            if in_ci() {
                panic!("{test}: no Vulkan device in CI: {e}");
            }
            eprintln!("{test}: {e}");
            tetloc_testdata::skip(test, "no Vulkan device");
            None
        }
        Err(e) => panic!("{test}: {e}"),
    }
}

/// The kernels this device can run; in CI every kernel must be runnable.
pub fn kernels(ctx: &Context, test: &str) -> Vec<Kernel> {
    if !ctx.info().ray_tracing {
        if in_ci() {
            panic!("{test}: {} has no ray tracing; CI must run every kernel", ctx.info().name);
        }
        eprintln!("{test}: {} has no ray-tracing pipelines", ctx.info().name);
        tetloc_testdata::skip(&format!("{test} (rt-* kernels)"), "no ray tracing on the Vulkan device");
    }
    Kernel::ALL.into_iter().filter(|k| ctx.info().ray_tracing || !k.needs_ray_tracing()).collect()
}

/// Fails the test if the validation layer reported errors.
pub fn assert_no_validation_errors(ctx: &Context) {
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors (printed above)");
}

/// The default options but soft-bvh's, which are `soft_bvh`: the kernel sweeps' variants.
pub fn soft_bvh(soft_bvh: SoftBvhOptions) -> LocatorOptions {
    LocatorOptions { soft_bvh, ..Default::default() }
}

/// Uniform f64s in [0, 1) from `seed` (an LCG: the same points on every run).
pub fn unit_f64(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed;
    move || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A point of a random tet of `mesh` (its vertices as `vertex` gives them), at random weights
/// `unit() + lift` (normalised; a `lift` > 0 keeps the point off the tet's faces).
pub fn point_in_a_tet(
    mesh: &Mesh,
    unit: &mut impl FnMut() -> f64,
    lift: f64,
    vertex: impl Fn(u32) -> [f64; 3],
) -> [f64; 3] {
    let v = mesh.tets[(unit() * mesh.n_tets() as f64) as usize].map(vertex);
    let w: [f64; 4] = std::array::from_fn(|_| unit() + lift);
    let s: f64 = w.iter().sum();
    std::array::from_fn(|k| (0..4).map(|j| w[j] / s * v[j][k]).sum())
}

/// A jittered grid mesh of about `n` tets from the core generator.
pub fn jets(n: usize, seed: u64) -> Arc<Mesh> {
    Arc::new(Mesh::new(tetloc_core::gen::generate(tetloc_core::gen::Shape::Jets, n, seed), "jets").unwrap())
}

/// A regular (not jittered) grid of n^3 cubes, 6 Kuhn tets each: axis-aligned faces and a
/// shared diagonal per cube, the worst case for rays along structured directions. Vertex
/// field `f` = x + 2y + 3z (linear, so interpolation is exact), cell field `c` = id.
pub fn regular_grid(n: usize) -> Arc<Mesh> {
    Arc::new(tetloc_testdata::KuhnGrid::new(n).spacing([1.0; 3]).mesh("regular grid"))
}

/// Checks GPU ids against the watertight definition: every id >= 0 is a tet that contains
/// the point (CPU test), and -1 only where the CPU finds no tet. Returns the number of
/// points where GPU and CPU picked different (both valid) tets.
pub fn check_ids(label: &str, mesh: &Mesh, points: &[Vec3], gpu: &[i32], cpu: &[i32]) -> usize {
    check_ids_allowing(label, mesh, points, gpu, cpu, |_| false)
}

/// [`check_ids`], where `may_be_outside(i)` points (on the mesh's boundary surface) may
/// also come back -1.
pub fn check_ids_allowing(
    label: &str,
    mesh: &Mesh,
    points: &[Vec3],
    gpu: &[i32],
    cpu: &[i32],
    may_be_outside: impl Fn(usize) -> bool,
) -> usize {
    let mut differ = 0;
    for (i, (&g, &c)) in gpu.iter().zip(cpu).enumerate() {
        if g == c {
            continue;
        }
        let p = points[i];
        assert!(g >= -1 && g < mesh.n_tets() as i32, "{label}: point {i} {p:?}: id {g} out of range");
        if g < 0 && may_be_outside(i) {
            continue;
        }
        assert!(g >= 0, "{label}: point {i} {p:?} came back outside, but tet {c} contains it (a crack)");
        assert!(
            geom::point_in_tet(mesh.tets[g as usize], &mesh.points, p).is_some(),
            "{label}: point {i} {p:?}: tet {g} does not contain it (CPU says {c})"
        );
        differ += 1;
    }
    differ
}
