//! End-to-end tests of the marcher with the CPU backend (GPU backends plug into the same
//! helpers: everything here takes `&mut dyn BatchLocator`).

use super::*;
use crate::camera::LookAt;
use crate::image::psnr;
use crate::options::TfSpec;
use crate::tf::{Colormap, TransferFunction};
use crate::{compare_locators, measure_fps, render_to_file};
use tetloc_core::locate::{Points, Values};
use tetloc_core::{geom, CpuLocator, FieldLocation, Result as CoreResult, OUTSIDE};
use tetloc_testdata::testmesh;

/// Tests every tet for every point: slow, obviously right, and a second opinion for the
/// CPU locator (which walks a BVH).
struct BruteForce {
    mesh: Arc<Mesh>,
}

impl BruteForce {
    fn find(&self, p: Vec3) -> Option<(usize, geom::Bary)> {
        self.mesh
            .tets
            .iter()
            .enumerate()
            .find_map(|(i, &t)| geom::point_in_tet(t, &self.mesh.points, p).map(|b| (i, b)))
    }
}

impl BatchLocator for BruteForce {
    fn name(&self) -> &str {
        "brute-force"
    }
    fn query(&mut self, points: Points<'_>, fields: &[&str], ids: &mut [i32], values: Values<'_>) -> CoreResult<()> {
        let fields = fields.iter().map(|f| self.mesh.field(f)).collect::<CoreResult<Vec<_>>>()?;
        let points = points.narrow(0..points.len());
        let found: Vec<_> = points.par_iter().map(|&p| self.find(p)).collect();
        ids.iter_mut().zip(&found).for_each(|(id, f)| *id = f.map_or(OUTSIDE, |(t, _)| t as i32));
        values.via_f32(|values| {
            for (out, found) in values.chunks_mut(fields.len().max(1)).zip(&found) {
                for (v, f) in out.iter_mut().zip(&fields) {
                    *v = match *found {
                        None => f32::NAN,
                        Some((t, b)) => match f.location {
                            FieldLocation::Vertex => geom::interpolate(self.mesh.tets[t], b, &f.values),
                            FieldLocation::Cell => f.values[t],
                        },
                    };
                }
            }
            Ok(())
        })
    }
}

fn small(opts: RenderOptions) -> RenderOptions {
    RenderOptions { width: 48, height: 40, ..opts }
}

fn tmp_dir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("tetloc-render-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A constant field through a constant-opacity transfer function: the opacity along a
/// straight path of length L is 1 − exp(−σL) in closed form.
#[test]
fn constant_cube_matches_the_closed_form() {
    let side = 2.0;
    let mesh = Arc::new(testmesh::cube(4, side, 1.0));
    let o = 0.5;
    let tf = TransferFunction::builtin(Colormap::Grayscale).with_constant_opacity(o);
    let diagonal = side * 3f32.sqrt();
    for field in ["f", "c"] {
        for step in [side / 200.0, side / 333.0] {
            let opts = RenderOptions {
                tf: TfSpec::Custom(tf.clone()),
                opacity: 3.0,
                step: Some(step),
                range: Some((0.0, 2.0)),
                ..Default::default()
            };
            let r = Renderer::new(mesh.clone(), field, &opts).unwrap();
            let sigma = o * opts.opacity / diagonal;
            let expect = 1.0 - (-sigma * side).exp();
            let rays = [
                Ray { origin: [-1.0, 0.7, 1.3], dir: [1.0, 0.0, 0.0] },
                Ray { origin: [0.3, 5.0, 1.1], dir: [0.0, -1.0, 0.0] },
                Ray { origin: [1.6, 0.2, -3.0], dir: [0.0, 0.0, 1.0] },
            ];
            let (rgba, stats) = r.march(&mut CpuLocator::new(mesh.clone()), &rays).unwrap();
            let grey = r.table.lookup(1.0);
            for (ray, c) in rays.iter().zip(&rgba) {
                assert!(
                    (c[3] - expect).abs() <= 0.01 * expect,
                    "{field} step {step} {ray:?}: opacity {} vs {expect}",
                    c[3]
                );
                // A constant colour composites to opacity × colour.
                assert!((c[0] - c[3] * grey[0]).abs() < 1e-4);
            }
            assert_eq!(stats.in_mesh_samples, stats.samples, "every sample of these rays is inside the cube");
        }
    }
}

#[test]
fn a_constant_field_maps_to_the_middle_of_the_transfer_function() {
    let mesh = Arc::new(testmesh::cube(2, 1.0, 7.0));
    let r = Renderer::new(mesh.clone(), "f", &RenderOptions::default()).unwrap();
    let (lo, hi) = r.range();
    assert!(lo < 7.0 && hi > 7.0 && ((lo + hi) / 2.0 - 7.0).abs() < 1e-5);
    // The default ramp is half opaque there, so the cube shows.
    let ray = Ray { origin: [0.5, 0.5, 3.0], dir: [0.0, 0.0, -1.0] };
    let (rgba, _) = r.march(&mut CpuLocator::new(mesh), &[ray]).unwrap();
    assert!(rgba[0][3] > 0.5, "{:?}", rgba[0]);
}

/// One ray marched through `testmesh::cube(3, 1.0, 1.0)` (its field `f`) under a grey transfer
/// function of constant opacity, with `opts` otherwise: the renderer, the ray's colour and
/// what the march counted.
fn march_grey_cube(opts: RenderOptions, ray: Ray) -> (Renderer, [f32; 4], FrameStats) {
    let mesh = Arc::new(testmesh::cube(3, 1.0, 1.0));
    let tf = TransferFunction::builtin(Colormap::Grayscale).with_constant_opacity(1.0);
    let r = Renderer::new(mesh.clone(), "f", &RenderOptions { tf: TfSpec::Custom(tf), ..opts }).unwrap();
    let (rgba, stats) = r.march(&mut CpuLocator::new(mesh), &[ray]).unwrap();
    (r, rgba[0], stats)
}

/// An opaque enough volume stops each ray at 99 % and takes fewer samples than the path has.
#[test]
fn rays_stop_at_the_opacity_cutoff() {
    let opts = RenderOptions { opacity: 200.0, step: Some(0.001), range: Some((0.0, 1.0)), ..Default::default() };
    let (_, rgba, stats) = march_grey_cube(opts, Ray { origin: [-1.0, 0.5, 0.5], dir: [1.0, 0.0, 0.0] });
    assert!(rgba[3] >= OPACITY_CUTOFF && rgba[3] < 1.0);
    // σ = 200/√3 per unit: 99 % is reached after ln(100)/σ ≈ 0.04 of the 1.0 path.
    assert!(stats.in_mesh_samples < 60, "{stats:?}");
}

fn skip_vs_fixed(mesh: Mesh, field: &str) {
    let mesh = Arc::new(mesh);
    let mut cpu = CpuLocator::new(mesh.clone());
    let base = small(RenderOptions { opacity: 4.0, ..Default::default() });
    let skip = Renderer::new(mesh.clone(), field, &RenderOptions { skip: true, ..base.clone() }).unwrap();
    let fixed = Renderer::new(mesh.clone(), field, &RenderOptions { skip: false, ..base }).unwrap();
    let cam = skip.camera(0);
    let (a, sa) = skip.render(&mut cpu, &cam).unwrap();
    let (b, sb) = fixed.render(&mut cpu, &cam).unwrap();
    let db = psnr(&a, &b).unwrap();
    eprintln!(
        "{}: skip {} samples, fixed {} ({:.1}x fewer), in-mesh {} / {}, occupancy {:.2}, PSNR {db:.1} dB",
        mesh.info.source,
        sa.samples,
        sb.samples,
        sb.samples as f64 / sa.samples as f64,
        sa.in_mesh_samples,
        sb.in_mesh_samples,
        skip.grid().unwrap().occupancy()
    );
    assert!(db >= 45.0, "PSNR {db}");
    // Exactness: the same samples inside the mesh were composited.
    assert_eq!(sa.in_mesh_samples, sb.in_mesh_samples);
    assert!(sa.in_mesh_samples > 1000, "the mesh is in view");
    assert!((sa.samples as f64) < 0.7 * sb.samples as f64, "skipping saves samples: {} vs {}", sa.samples, sb.samples);
}

#[test]
fn skipping_gives_the_same_image_with_fewer_samples_blobs() {
    skip_vs_fixed(testmesh::two_blobs(20, 5), "f");
}

#[test]
fn skipping_gives_the_same_image_with_fewer_samples_torus() {
    skip_vs_fixed(testmesh::torus(24, 9), "c");
}

/// The generated Japan-like sheet fills ~7 % of its box: the case skipping is for.
#[test]
fn skipping_gives_the_same_image_with_fewer_samples_japan() {
    use tetloc_core::gen::{generate, Shape};
    skip_vs_fixed(Mesh::new(generate(Shape::Japan, 20_000, 1), "japan").unwrap(), "f");
}

#[test]
fn two_locators_computing_the_same_thing_agree() {
    let mesh = Arc::new(testmesh::two_blobs(8, 3));
    let r = Renderer::new(
        mesh.clone(),
        "f",
        &small(RenderOptions { tf: TfSpec::Builtin(Colormap::Coolwarm), ..Default::default() }),
    )
    .unwrap();
    let cmp = compare_locators(&r, &mut CpuLocator::new(mesh.clone()), &mut BruteForce { mesh: mesh.clone() }).unwrap();
    eprintln!("cpu vs brute force: PSNR {:.1} dB", cmp.psnr_db);
    assert!(cmp.psnr_db >= 40.0, "PSNR {}", cmp.psnr_db);
    assert_eq!(cmp.stats[0].samples, cmp.stats[1].samples);
    // And the helper does notice a backend that is wrong: one that returns a shifted field.
    struct Shifted(CpuLocator);
    impl BatchLocator for Shifted {
        fn name(&self) -> &str {
            "shifted"
        }
        fn query(&mut self, p: Points<'_>, fields: &[&str], ids: &mut [i32], v: Values<'_>) -> CoreResult<()> {
            v.via_f32(|v| {
                self.0.query(p, fields, ids, Values::F32(v))?;
                v.iter_mut().for_each(|x| *x += 0.5);
                Ok(())
            })
        }
    }
    let bad = compare_locators(&r, &mut CpuLocator::new(mesh.clone()), &mut Shifted(CpuLocator::new(mesh))).unwrap();
    assert!(bad.psnr_db < 35.0, "a wrong backend must show: {}", bad.psnr_db);
}

#[test]
fn the_fitted_view_shows_the_mesh_and_misses_are_background() {
    let mesh = Arc::new(testmesh::torus(10, 1));
    let bg = [0.2, 0.3, 0.4];
    let r = Renderer::new(mesh.clone(), "f", &small(RenderOptions { background: bg, ..Default::default() })).unwrap();
    let (img, _) = r.render(&mut CpuLocator::new(mesh), &r.camera(0)).unwrap();
    let bg8 =
        crate::image::Image { width: 1, height: 1, pixels: vec![bg.map(crate::colorspace::srgb_to_linear)] }.to_srgb8();
    let px = img.to_srgb8();
    let is_bg: Vec<bool> = px.chunks(3).map(|c| c == &bg8[..]).collect();
    let covered = is_bg.iter().filter(|b| !**b).count() as f64 / is_bg.len() as f64;
    assert!(covered > 0.1 && covered < 0.9, "torus covers {covered} of the image");
    // The border of a fitted view is empty: the whole mesh is in the picture.
    let (w, h) = (img.width as usize, img.height as usize);
    assert!((0..w).all(|x| is_bg[x] && is_bg[(h - 1) * w + x]));
    assert!((0..h).all(|y| is_bg[y * w] && is_bg[y * w + w - 1]));
}

#[test]
fn the_boundary_surface_hides_the_volume_and_is_lambert_shaded() {
    let mesh = Arc::new(testmesh::cube(2, 1.0, 1.0));
    let opts = small(RenderOptions { surface: Some(SurfaceSpec::Boundary), ..Default::default() });
    let r = Renderer::new(mesh.clone(), "f", &opts).unwrap();
    let ray = Ray { origin: [0.4, -2.7, 5.0], dir: [0.0, 0.6, -0.8] };
    let (rgba, stats) = r.march(&mut CpuLocator::new(mesh), &[ray]).unwrap();
    assert_eq!(stats.samples, 0, "the surface is hit where the volume begins");
    let base = opts.surface_color.map(crate::colorspace::srgb_to_linear);
    // The ray enters through the top face (normal ±z): |n·d| = 0.8.
    for k in 0..3 {
        assert!((rgba[0][k] - base[k] * (0.2 + 0.8 * 0.8)).abs() < 1e-5);
    }
    assert_eq!(rgba[0][3], 1.0);
}

#[test]
fn a_surface_file_ends_volume_integration() {
    let dir = tmp_dir("surface");
    // A square at z = 0.5 through the unit cube, as ascii STL.
    let stl = dir.join("plane.stl");
    let facet = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| {
        format!(
            "facet normal 0 0 1\nouter loop\nvertex {} {} {}\nvertex {} {} {}\nvertex {} {} {}\nendloop\nendfacet\n",
            a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]
        )
    };
    let text = format!(
        "solid p\n{}{}endsolid p\n",
        facet([-1.0, -1.0, 0.5], [2.0, -1.0, 0.5], [2.0, 2.0, 0.5]),
        facet([-1.0, -1.0, 0.5], [2.0, 2.0, 0.5], [-1.0, 2.0, 0.5])
    );
    std::fs::write(&stl, text).unwrap();
    let opts = RenderOptions {
        opacity: 2.0,
        step: Some(0.002),
        range: Some((0.0, 2.0)),
        surface: Some(SurfaceSpec::File(stl)),
        surface_color: [0.0; 3],
        ..Default::default()
    };
    let (r, rgba, _) = march_grey_cube(opts, Ray { origin: [0.3, 0.6, 3.0], dir: [0.0, 0.0, -1.0] });
    let half = 1.0 - (-2.0 / 3f32.sqrt() * 0.5).exp();
    let grey = r.table.lookup(1.0)[0];
    // A black surface adds nothing: what is left is the volume in front of it.
    assert!((rgba[0] / grey - half).abs() < 0.01 * half, "{} vs {half}", rgba[0] / grey);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn orbits_write_numbered_pngs_or_one_gif() {
    let dir = tmp_dir("orbit");
    let mesh = Arc::new(testmesh::two_blobs(6, 2));
    let opts = RenderOptions { width: 16, height: 12, frames: 3, ..Default::default() };
    let r = Renderer::new(mesh.clone(), "f", &opts).unwrap();
    let mut cpu = CpuLocator::new(mesh);
    let rep = render_to_file(&r, &mut cpu, &dir.join("orbit.png")).unwrap();
    let names: Vec<String> = rep.files.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["orbit_0000.png", "orbit_0001.png", "orbit_0002.png"]);
    assert!(rep.files.iter().all(|p| p.exists()));
    assert_eq!(rep.frames.len(), 3);
    let rep = render_to_file(&r, &mut cpu, &dir.join("orbit.gif")).unwrap();
    assert_eq!(rep.files, [dir.join("orbit.gif")]);
    let mut d = gif::DecodeOptions::new().read_info(std::fs::File::open(dir.join("orbit.gif")).unwrap()).unwrap();
    let mut n = 0;
    while d.read_next_frame().unwrap().is_some() {
        n += 1;
    }
    assert_eq!(n, 3);
    let e = render_to_file(&r, &mut cpu, &dir.join("orbit.jpg")).unwrap_err().to_string();
    assert!(e.contains("orbit.jpg") && e.contains(".png or .gif"), "{e}");
    // The orbit turns the eye about the vertical through the centre.
    let (c0, c1) = (r.camera(0), r.camera(1));
    assert!((c0.eye[2] - c1.eye[2]).abs() < 1e-4 && (c0.eye[1] - c1.eye[1]).abs() > 0.1);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn an_explicit_camera_orbits_its_target() {
    let mesh = Arc::new(testmesh::cube(2, 1.0, 1.0));
    let look = LookAt { eye: [0.5, -3.0, 0.5], target: [0.5, 0.5, 0.5], up: [0.0, 0.0, 1.0] };
    let r = Renderer::new(mesh, "f", &RenderOptions { camera: Some(look), frames: 4, ..Default::default() }).unwrap();
    let e = r.camera(1).eye;
    assert!((e[0] - 4.0).abs() < 1e-4 && (e[1] - 0.5).abs() < 1e-4 && (e[2] - 0.5).abs() < 1e-5, "{e:?}");
}

#[test]
fn fps_is_measured_per_backend() {
    let mesh = Arc::new(testmesh::two_blobs(6, 2));
    let r = Renderer::new(mesh.clone(), "f", &RenderOptions { width: 24, height: 24, ..Default::default() }).unwrap();
    let rep = measure_fps(&r, &mut CpuLocator::new(mesh), 3).unwrap();
    assert_eq!((rep.backend.as_str(), rep.frames, rep.width), ("cpu", 3, 24));
    assert!(rep.fps > 0.0 && rep.samples_per_frame > 0.0 && rep.sample_fraction > 0.0 && rep.sample_fraction <= 1.0);
    let line = rep.to_string();
    assert!(line.starts_with("cpu: ") && line.contains("FPS at 24x24"), "{line}");
    let st = FrameStats {
        rays: 4,
        samples: 10,
        in_mesh_samples: 5,
        rounds: 2,
        sample_seconds: 0.5,
        seconds: 1.0,
        gpu_seconds: 0.0,
    };
    assert_eq!(
        st.to_string(),
        "4 rays, 10 samples (50.0 % inside the mesh) in 2 batches, 1.00 s (50 % in the locator)"
    );
}

#[test]
fn bad_inputs_give_clear_errors() {
    let mesh = Arc::new(testmesh::cube(2, 1.0, 1.0));
    let err = |opts: RenderOptions, field: &str| {
        Renderer::new(mesh.clone(), field, &opts).err().expect("should fail").to_string()
    };
    let e = err(RenderOptions::default(), "pressure");
    assert!(e.contains("no field named 'pressure'") && e.contains("'f', 'c'"), "{e}");
    let e = err(RenderOptions { width: 0, ..Default::default() }, "f");
    assert!(e.contains("image size 0x1024"), "{e}");
    let dir = tmp_dir("bad");
    let bad_tf = dir.join("broken.json");
    std::fs::write(&bad_tf, r#"[{"Name": "x", "RGBPoints": [0, 1, 0]}]"#).unwrap();
    let e = err(RenderOptions { tf: TfSpec::File { path: bad_tf.clone(), preset: None }, ..Default::default() }, "f");
    assert!(e.contains("broken.json") && e.contains("RGBPoints has 3 numbers"), "{e}");
    let bad_obj = dir.join("broken.obj");
    std::fs::write(&bad_obj, "v 0 0 0\nf 1 2 3\n").unwrap();
    let e = err(RenderOptions { surface: Some(SurfaceSpec::File(bad_obj)), ..Default::default() }, "f");
    assert!(e.contains("broken.obj") && e.contains("line 2"), "{e}");
    let e = err(RenderOptions { surface: Some(SurfaceSpec::File(dir.join("none.stl"))), ..Default::default() }, "f");
    assert!(e.contains("none.stl"), "{e}");
    let empty = dir.join("empty.obj");
    std::fs::write(&empty, "# nothing\n").unwrap();
    let e = err(RenderOptions { surface: Some(SurfaceSpec::File(empty)), ..Default::default() }, "f");
    assert!(e.contains("empty.obj: the file holds no triangles"), "{e}");
    let e = err(RenderOptions { surface: Some(SurfaceSpec::File(dir.join("s.ply"))), ..Default::default() }, "f");
    assert!(e.contains("s.ply") && e.contains("unknown surface format"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_paraview_preset_renders() {
    let dir = tmp_dir("preset");
    let p = dir.join("map.json");
    std::fs::write(
        &p,
        r#"[{"Name": "Blue Red", "ColorSpace": "Lab", "RGBPoints": [-5, 0, 0, 1, 5, 1, 0, 0], "Points": [-5, 0, 0.5, 0, 5, 1, 0.5, 0]}]"#,
    )
    .unwrap();
    let mesh = Arc::new(testmesh::two_blobs(6, 4));
    let opts =
        RenderOptions { width: 20, height: 20, tf: TfSpec::parse(p.to_str().unwrap()).unwrap(), ..Default::default() };
    let r = Renderer::new(mesh.clone(), "f", &opts).unwrap();
    let (img, stats) = r.render(&mut CpuLocator::new(mesh), &r.camera(0)).unwrap();
    assert!(stats.in_mesh_samples > 0);
    // Only blue-to-red colours appear over the dark background: no green.
    assert!(img.pixels.iter().all(|p| p[1] <= crate::colorspace::srgb_to_linear(0.1) + 1e-3));
    std::fs::remove_dir_all(&dir).ok();
}

/// A mesh far from the origin (UTM-like offsets, f64 coordinates) renders as the same mesh
/// at the origin: rays run in the mesh's working frame, samples reach the locator in the
/// file's coordinates, and an explicit camera is placed in the file's coordinates.
#[test]
fn a_mesh_far_from_the_origin_renders_as_at_the_origin() {
    let near = testmesh::two_blobs(8, 3);
    let offset = [512_345.0, 4_123_456.0, 0.0];
    let raw = tetloc_core::mesh::RawMesh {
        points: near.points.to_vec(),
        points64: None,
        tets: near.tets.to_vec(),
        fields: near.fields.clone(),
        higher_order: None,
        cells: None,
    };
    let far = Arc::new(Mesh::new(tetloc_testdata::mixed::moved(raw, offset), "two-blobs far away").unwrap());
    assert!(!far.info.frame.is_identity(), "the far mesh gets its own working frame");
    let near = Arc::new(near);
    let render = |mesh: &Arc<Mesh>, camera: Option<LookAt>| {
        let opts = small(RenderOptions { opacity: 4.0, camera, ..Default::default() });
        let r = Renderer::new(mesh.clone(), "f", &opts).unwrap();
        r.render(&mut CpuLocator::new(mesh.clone()), &r.camera(0)).unwrap()
    };
    // The fitted view.
    let ((a, sa), (b, sb)) = (render(&near, None), render(&far, None));
    let db = psnr(&a, &b).unwrap();
    eprintln!("fitted view: PSNR {db:.1} dB, in-mesh samples {} / {}", sa.in_mesh_samples, sb.in_mesh_samples);
    assert!(sa.in_mesh_samples > 300, "the mesh is in view");
    assert!(db >= 40.0, "PSNR {db}");
    // An explicit camera (these shifted coordinates are exact in f32).
    let look = LookAt { eye: [0.5, -3.0, 0.5], target: [0.5, 0.5, 0.5], up: [0.0, 0.0, 1.0] };
    let shift = |p: Vec3| std::array::from_fn(|k| (f64::from(p[k]) + offset[k]) as f32);
    let far_look = LookAt { eye: shift(look.eye), target: shift(look.target), ..look };
    let ((a, _), (b, sb)) = (render(&near, Some(look)), render(&far, Some(far_look)));
    let db = psnr(&a, &b).unwrap();
    eprintln!("explicit camera: PSNR {db:.1} dB, in-mesh samples {}", sb.in_mesh_samples);
    assert!(sb.in_mesh_samples > 300, "the mesh is in view");
    assert!(db >= 40.0, "PSNR {db}");
}

/// Another time step's renderer keeps the occupancy grid and the surface, takes the new
/// step's range, and renders what a fresh renderer of that step renders; a mesh of other
/// geometry is refused.
#[test]
fn another_time_step_renders_as_a_fresh_renderer_of_it() {
    use tetloc_testdata::KuhnGrid;
    let step = |scale: f32| Arc::new(KuhnGrid::new(4).vertex_field(move |p| scale * (p[0] + 2.0 * p[1])).mesh("s"));
    let (first, later) = (step(1.0), step(5.0));
    let opts = small(RenderOptions { surface: Some(SurfaceSpec::Boundary), ..Default::default() });
    let r0 = Renderer::new(first.clone(), "f", &opts).unwrap();
    let r1 = r0.for_step(later.clone(), "f", &opts).unwrap();
    let fresh = Renderer::new(later.clone(), "f", &opts).unwrap();
    assert!(Arc::ptr_eq(r0.grid.as_ref().unwrap(), r1.grid.as_ref().unwrap()), "the grid is kept");
    assert!(Arc::ptr_eq(r0.surface.as_ref().unwrap(), r1.surface.as_ref().unwrap()), "the surface is kept");
    assert_eq!(r0.range(), (0.0, 3.0));
    assert_eq!(r1.range(), fresh.range());
    assert_eq!(r1.range(), (0.0, 15.0), "the new step's range");
    let mut cpu = CpuLocator::new(later);
    let (a, _) = r1.render(&mut cpu, &r1.camera(0)).unwrap();
    let (b, _) = fresh.render(&mut cpu, &fresh.camera(0)).unwrap();
    assert_eq!(a.pixels, b.pixels);
    let other = Arc::new(KuhnGrid::new(3).mesh("other"));
    let e = r0.for_step(other, "f", &opts).err().unwrap().to_string();
    assert!(e.contains("differs"), "{e}");
}
