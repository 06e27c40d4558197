//! GPU backends against the CPU: the host marcher over every GPU kernel, and the GPU
//! marcher (whole frames on the GPU) on every kernel, render the same small mesh like the
//! CPU backend (PSNR ≥ 40 dB); the GPU marcher skips exactly and matches the closed form
//! of a constant cube. Runs on whatever Vulkan device there is (lavapipe in CI); with `CI`
//! set, a missing device or missing ray tracing fails the test instead of skipping it.

use std::sync::Arc;
use tetloc_core::{CpuLocator, Mesh};
use tetloc_render::tf::{Colormap, TransferFunction};
use tetloc_render::{
    compare_locators, psnr, GpuMarcher, LookAt, Marcher, RenderOptions, Renderer, SurfaceSpec, TfSpec,
};
use tetloc_testdata::{in_ci, testmesh};
use tetloc_vulkan::{Context, ContextOptions, Kernel, LocatorOptions, VulkanLocator};

/// The device, or `None` (test skipped) outside CI when there is none.
fn context(test: &str) -> Option<Arc<Context>> {
    let ctx = match Context::with_options(ContextOptions {
        device_index: None,
        validation: true,
        pipeline_cache_dir: None,
    }) {
        Ok(c) => c,
        Err(e) if !in_ci() => {
            eprintln!("{test}: {e}");
            tetloc_testdata::skip(test, "no Vulkan device");
            return None;
        }
        Err(e) => panic!("no Vulkan device in CI: {e}"),
    };
    assert!(ctx.info().ray_tracing || !in_ci(), "CI must run every kernel, but {} has no ray tracing", ctx.info().name);
    if !ctx.info().ray_tracing {
        tetloc_testdata::skip(&format!("{test} (rt-* kernels)"), "no ray tracing on the Vulkan device");
    }
    Some(ctx)
}

fn kernels(ctx: &Context) -> Vec<Kernel> {
    Kernel::ALL.into_iter().filter(|k| ctx.info().ray_tracing || !k.needs_ray_tracing()).collect()
}

fn gpu_marcher(ctx: &Arc<Context>, mesh: &Arc<Mesh>, kernel: Kernel, r: &Renderer) -> GpuMarcher {
    let loc = VulkanLocator::new(ctx.clone(), mesh.clone(), kernel, LocatorOptions::default()).unwrap();
    GpuMarcher::new(loc, r).unwrap()
}

#[test]
fn every_gpu_kernel_renders_like_the_cpu() {
    let Some(ctx) = context("every_gpu_kernel_renders_like_the_cpu") else { return };
    let mesh = Arc::new(testmesh::torus(10, 3));
    let opts = RenderOptions { width: 96, height: 72, azimuth: 30.0, elevation: 25.0, ..Default::default() };
    let with_surface = RenderOptions { surface: Some(SurfaceSpec::Boundary), opacity: 20.0, ..opts.clone() };
    for (field, opts) in [("f", &opts), ("c", &opts), ("f", &with_surface)] {
        let renderer = Renderer::new(mesh.clone(), field, opts).unwrap();
        let mut cpu = CpuLocator::new(mesh.clone());
        for kernel in kernels(&ctx) {
            let what = format!("{kernel} field {field} surface {}", opts.surface.is_some());
            // The host marcher handing batches to the kernel.
            let mut gpu = VulkanLocator::new(ctx.clone(), mesh.clone(), kernel, LocatorOptions::default()).unwrap();
            let cmp = compare_locators(&renderer, &mut cpu, &mut gpu).unwrap();
            eprintln!("{what}, host marcher: PSNR {:.1} dB", cmp.psnr_db);
            assert!(cmp.psnr_db >= 40.0, "{what}, host marcher: PSNR {:.1} dB against the CPU", cmp.psnr_db);
            assert!(cmp.stats[1].samples > 0);
            // The whole march on the GPU.
            let mut march = GpuMarcher::new(gpu, &renderer).unwrap();
            let cmp = compare_locators(&renderer, &mut cpu, &mut march).unwrap();
            let [c, g] = cmp.stats;
            eprintln!("{what}, GPU marcher: PSNR {:.1} dB, samples {} / {} (CPU)", cmp.psnr_db, g.samples, c.samples);
            assert!(cmp.psnr_db >= 40.0, "{what}, GPU marcher: PSNR {:.1} dB against the CPU", cmp.psnr_db);
            // The same samples inside the mesh were composited, up to rays whose last round
            // on the host took samples past the cutoff (the GPU stops at the sample).
            // (The boundary surface hides the whole volume.)
            assert!(g.in_mesh_samples <= c.in_mesh_samples, "{g:?} vs {c:?}");
            assert!(g.in_mesh_samples > 0 || opts.surface.is_some(), "{g:?}");
            assert!(g.gpu_seconds > 0.0);
        }
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// Higher-order tets: the GPU marcher samples a quadratic field on quadratic tets with the
/// tets' own shape functions, like the CPU; by the corners alone the image differs clearly.
#[test]
fn gpu_marcher_samples_higher_order_tets_like_the_cpu() {
    let Some(ctx) = context("gpu_marcher_samples_higher_order_tets_like_the_cpu") else { return };
    let f = |p: [f32; 3]| 4.0 * ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) + (p[2] - 0.5).powi(2));
    let raw = tetloc_testdata::KuhnGrid::new(3).order(2).vertex_field(f).raw();
    let linear = tetloc_core::RawMesh { cells: None, higher_order: None, ..raw.clone() };
    let mesh = Arc::new(Mesh::new(raw, "quadratic").unwrap());
    let linear = Arc::new(Mesh::new(linear, "by corners").unwrap());
    let opts = RenderOptions { width: 64, height: 48, azimuth: 30.0, elevation: 25.0, ..Default::default() };
    let renderer = Renderer::new(mesh.clone(), "f", &opts).unwrap();
    let mut cpu = CpuLocator::new(mesh.clone());
    let by_corners = compare_locators(&renderer, &mut cpu, &mut CpuLocator::new(linear)).unwrap().psnr_db;
    for kernel in kernels(&ctx) {
        let mut march = gpu_marcher(&ctx, &mesh, kernel, &renderer);
        let gpu = compare_locators(&renderer, &mut cpu, &mut march).unwrap().psnr_db;
        eprintln!("{kernel}: GPU marcher PSNR {gpu:.1} dB against the CPU (by the corners: {by_corners:.1} dB)");
        assert!(gpu >= 40.0 && gpu > by_corners + 6.0, "{kernel}: PSNR {gpu:.1} dB (by the corners {by_corners:.1})");
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// Skipping on and off give the same image on the GPU, with fewer samples.
#[test]
fn gpu_skipping_is_exact() {
    let Some(ctx) = context("gpu_skipping_is_exact") else { return };
    let mesh = Arc::new(testmesh::two_blobs(16, 5));
    let base = RenderOptions { width: 64, height: 48, opacity: 4.0, ..Default::default() };
    let skip = Renderer::new(mesh.clone(), "f", &RenderOptions { skip: true, ..base.clone() }).unwrap();
    let fixed = Renderer::new(mesh.clone(), "f", &RenderOptions { skip: false, ..base }).unwrap();
    let cam = skip.camera(0);
    for kernel in kernels(&ctx) {
        let (a, sa) = skip.render(&mut gpu_marcher(&ctx, &mesh, kernel, &skip), &cam).unwrap();
        let (b, sb) = fixed.render(&mut gpu_marcher(&ctx, &mesh, kernel, &fixed), &cam).unwrap();
        let db = psnr(&a, &b).unwrap();
        eprintln!(
            "{kernel}: skip {} samples, fixed {}, in-mesh {} / {}, PSNR {db:.1} dB",
            sa.samples, sb.samples, sa.in_mesh_samples, sb.in_mesh_samples
        );
        assert!(db >= 45.0, "{kernel}: PSNR {db}");
        assert_eq!(sa.in_mesh_samples, sb.in_mesh_samples, "{kernel}: the same samples inside the mesh");
        assert!(sa.in_mesh_samples > 1000, "the mesh is in view");
        assert!(
            (sa.samples as f64) < 0.7 * sb.samples as f64,
            "{kernel}: skipping saves samples: {} vs {}",
            sa.samples,
            sb.samples
        );
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// A constant field through a constant-opacity transfer function, seen along an axis by a
/// one-pixel camera: opacity 1 − exp(−σL) over the path length L, within 1 %.
#[test]
fn gpu_constant_cube_matches_the_closed_form() {
    let Some(ctx) = context("gpu_constant_cube_matches_the_closed_form") else { return };
    let side = 2.0;
    let mesh = Arc::new(testmesh::cube(4, side, 1.0));
    let o = 0.5;
    let tf = TransferFunction::builtin(Colormap::Grayscale).with_constant_opacity(o);
    let camera = LookAt { eye: [0.7, 1.3, 6.0], target: [0.7, 1.3, 0.0], up: [0.0, 1.0, 0.0] };
    for field in ["f", "c"] {
        let opts = RenderOptions {
            width: 1,
            height: 1,
            camera: Some(camera),
            tf: TfSpec::Custom(tf.clone()),
            opacity: 3.0,
            step: Some(side / 333.0),
            range: Some((0.0, 2.0)),
            ..Default::default()
        };
        let r = Renderer::new(mesh.clone(), field, &opts).unwrap();
        let expect = 1.0 - (-o * opts.opacity / (side * 3f32.sqrt()) * side).exp();
        for kernel in kernels(&ctx) {
            let (rgba, stats) = gpu_marcher(&ctx, &mesh, kernel, &r).march_frame(&r, &r.camera(0)).unwrap();
            let a = rgba[0][3];
            assert!((a - expect).abs() <= 0.01 * expect, "{kernel} {field}: opacity {a} vs {expect}");
            assert_eq!(stats.in_mesh_samples, stats.samples, "{kernel}: every sample is inside the cube");
        }
    }
}

#[test]
fn a_gpu_marcher_refuses_another_renderer() {
    let Some(ctx) = context("a_gpu_marcher_refuses_another_renderer") else { return };
    let mesh = Arc::new(testmesh::cube(2, 1.0, 1.0));
    let opts = RenderOptions { width: 8, height: 8, ..Default::default() };
    let r = Renderer::new(mesh.clone(), "f", &opts).unwrap();
    let other = Renderer::new(mesh.clone(), "c", &opts).unwrap();
    let mut m = gpu_marcher(&ctx, &mesh, Kernel::SoftBvh, &r);
    let e = m.march_frame(&other, &other.camera(0)).unwrap_err().to_string();
    assert!(e.contains("built for field 'f'"), "{e}");
    // Zero-size images never reach the GPU: the options are refused first.
    let e = Renderer::new(mesh, "f", &RenderOptions { width: 0, ..opts }).err().unwrap().to_string();
    assert!(e.contains("size") || e.contains("0"), "{e}");
}

/// The GPU marcher binds the locator's buffers as they are: split over several buffers
/// (arrays larger than a buffer may be) or not, without the walk start or with it, the
/// images are the same.
#[test]
fn gpu_marcher_follows_the_locators_buffer_layout() {
    let Some(ctx) = context("gpu_marcher_follows_the_locators_buffer_layout") else { return };
    let mesh = Arc::new(testmesh::torus(10, 3));
    let opts = RenderOptions { width: 64, height: 48, azimuth: 30.0, elevation: 25.0, ..Default::default() };
    let renderer = Renderer::new(mesh.clone(), "f", &opts).unwrap();
    let render = |lo: LocatorOptions| {
        let loc = VulkanLocator::new(ctx.clone(), mesh.clone(), Kernel::SoftBvh, lo).unwrap();
        let mut march = GpuMarcher::new(loc, &renderer).unwrap();
        renderer.render(&mut march, &renderer.camera(0)).unwrap().0
    };
    let one = render(LocatorOptions::default());
    // Buffers of a quarter of the tets: tets, nodes and neighbours each split over several.
    let quarter = (mesh.n_tets() as u64 * 16 / 4).next_multiple_of(256);
    let mut split = LocatorOptions::default();
    split.test_hooks.max_buffer_bytes = Some(quarter);
    let split = render(split);
    let mut no_walk = LocatorOptions::default();
    no_walk.soft_bvh.walk_start = false;
    let no_walk = render(no_walk);
    assert_eq!(psnr(&one, &split).unwrap(), f64::INFINITY, "split buffers");
    assert_eq!(psnr(&one, &no_walk).unwrap(), f64::INFINITY, "without the walk start");
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// The viewer's paths: 8-bit sRGB composited and encoded on the GPU equals the float frame
/// encoded on the host (to a level of rounding), with and without a surface; and a marcher
/// retargeted to another transfer function and step renders like one built for them.
#[test]
fn gpu_srgb8_frames_and_retargeting() {
    let Some(ctx) = context("gpu_srgb8_frames_and_retargeting") else { return };
    let mesh = Arc::new(testmesh::torus(10, 3));
    let opts = RenderOptions { width: 64, height: 48, background: [0.2, 0.4, 0.1], ..Default::default() };
    let with_surface = RenderOptions { surface: Some(SurfaceSpec::Boundary), opacity: 20.0, ..opts.clone() };
    for (kernel, opts) in kernels(&ctx).into_iter().flat_map(|k| [(k, &opts), (k, &with_surface)]) {
        let r = Renderer::new(mesh.clone(), "f", opts).unwrap();
        let mut m = gpu_marcher(&ctx, &mesh, kernel, &r);
        let cam = r.camera(0);
        let host = r.render(&mut m, &cam).unwrap().0.to_srgb8();
        let (rgba, stats) = m.march_srgb8(&r, &cam).unwrap();
        assert!(stats.gpu_seconds > 0.0);
        let device: Vec<u8> = rgba.iter().flat_map(|p| p.to_le_bytes()[..3].to_vec()).collect();
        let worst = host.iter().zip(&device).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
        assert!(worst <= 1, "{kernel}: 8-bit frames on the GPU differ from the host's encoding by {worst} levels");
        assert!(rgba.iter().all(|p| p >> 24 == 255), "opaque");
    }
    // Retargeting: another colormap, range and step, same field.
    let r = Renderer::new(mesh.clone(), "f", &opts).unwrap();
    let mut m = gpu_marcher(&ctx, &mesh, Kernel::SoftBvh, &r);
    let edited = RenderOptions {
        tf: TfSpec::Builtin(Colormap::Plasma),
        range: Some((0.2, 0.8)),
        step: Some(r.step() * 0.7),
        ..opts.clone()
    };
    let r2 = r.with_options("f", &edited).unwrap();
    m.retarget(&r2).unwrap();
    let mut fresh = gpu_marcher(&ctx, &mesh, Kernel::SoftBvh, &r2);
    let a = r2.render(&mut m, &r2.camera(0)).unwrap().0;
    let b = r2.render(&mut fresh, &r2.camera(0)).unwrap().0;
    assert_eq!(psnr(&a, &b).unwrap(), f64::INFINITY, "a retargeted marcher renders as a new one");
    let before = r.render(&mut gpu_marcher(&ctx, &mesh, Kernel::SoftBvh, &r), &r.camera(0)).unwrap().0;
    assert!(psnr(&a, &before).unwrap() < 40.0, "the edit shows");
    let other_field = r.with_options("c", &opts).unwrap();
    assert!(m.retarget(&other_field).unwrap_err().to_string().contains("marches field 'f'"));
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}

/// A GPU marcher takes another time step of its mesh (`Mesh::with_fields`, the renderer's
/// `for_step`), its mesh and structure kept on the device: its frames are then a new
/// marcher's, bit for bit, on every kernel, and the step shows. A mesh of another geometry,
/// or a field that moved from the points to the cells, needs a new marcher: refused, and
/// the marcher renders as before.
#[test]
fn a_gpu_marcher_takes_another_time_step() {
    use tetloc_core::mesh::{Field, FieldLocation};
    let Some(ctx) = context("a_gpu_marcher_takes_another_time_step") else { return };
    let mesh = Arc::new(testmesh::torus(10, 3));
    let opts = RenderOptions { width: 64, height: 48, ..Default::default() };
    let later = |f: &Field| {
        Field::from_f64(f.name.clone(), f.location, (0..f.values.len()).map(|i| (3.0 * f.value64(i)).sin()).collect())
    };
    let step = Arc::new(mesh.with_fields(mesh.fields.iter().map(later).collect()).unwrap());
    let frame = |r: &Renderer, m: &mut GpuMarcher| r.render(m, &r.camera(0)).unwrap().0;
    for kernel in kernels(&ctx) {
        let r = Renderer::new(mesh.clone(), "f", &opts).unwrap();
        let mut m = gpu_marcher(&ctx, &mesh, kernel, &r);
        let before = frame(&r, &mut m);
        let r2 = r.for_step(step.clone(), "f", &opts).unwrap();
        assert!(m.take_step(&r2).unwrap(), "{kernel}");
        let taken = frame(&r2, &mut m);
        let fresh = frame(&r2, &mut gpu_marcher(&ctx, &step, kernel, &r2));
        assert_eq!(psnr(&taken, &fresh).unwrap(), f64::INFINITY, "{kernel}: a new marcher's frame");
        assert!(psnr(&taken, &before).unwrap() < 40.0, "{kernel}: the step shows");
        let read_anew = Arc::new(testmesh::torus(10, 3));
        assert!(!m.take_step(&r2.for_step(read_anew, "f", &opts).unwrap()).unwrap(), "{kernel}: another geometry");
        assert_eq!(psnr(&frame(&r2, &mut m), &taken).unwrap(), f64::INFINITY, "{kernel}: nothing changed");
    }
    let per_cell = Field::new("f", FieldLocation::Cell, (0..mesh.n_cells()).map(|c| (c % 7) as f32).collect());
    let moved = Arc::new(mesh.with_fields(vec![per_cell]).unwrap());
    let r = Renderer::new(mesh.clone(), "f", &opts).unwrap();
    let mut m = gpu_marcher(&ctx, &mesh, Kernel::SoftBvh, &r);
    assert!(!m.take_step(&r.for_step(moved, "f", &opts).unwrap()).unwrap(), "a field now per cell");
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors");
}
