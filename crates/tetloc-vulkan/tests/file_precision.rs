//! Answers and values on the file's data as stored (issue 29, items 11 and 12), on every
//! kernel of the device: an f32 mesh far from the origin answers f64 points exactly, and
//! the default (f32) values on meshes stored in f64 match the CPU's f64 values on slivers.

mod common;

use std::sync::Arc;
use tetloc_core::geom::predicates::orient3d;
use tetloc_core::geom::Vec3;
use tetloc_core::{BatchLocator, CpuLocator, Mesh};
use tetloc_vulkan::{LocatorOptions, VulkanLocator};

/// Whether the closed tet `v` holds `p`, by exact orient3d signs on the f64 coordinates: on
/// each face's side of the opposite vertex, or on the face.
fn holds(v: [[f64; 3]; 4], p: [f64; 3]) -> bool {
    const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]];
    FACES.iter().enumerate().all(|(i, f)| {
        let inner = orient3d(v[f[0]], v[f[1]], v[f[2]], v[i]);
        let side = orient3d(v[f[0]], v[f[1]], v[f[2]], p);
        side == 0.0 || (side > 0.0) == (inner > 0.0)
    })
}

/// Issue 29.11 at CI scale: jets (20k tets) ×1000, offset by (512345.25, 4012345.5, 100) and
/// stored in f32, queried at 20,000 random f64 points (half in random tets, half in the
/// box) through each kernel's f64 path: every answer holds its point under exact orient3d
/// on the stored coordinates (the f32 values, widened), and -1 only where no tet does.
#[test]
fn f32_mesh_far_from_the_origin_answers_f64_points_exactly() {
    let test = "f32_mesh_far_from_the_origin_answers_f64_points_exactly";
    let Some(ctx) = common::context(test) else { return };
    let (n, offset) = (20_000usize, [512_345.25, 4_012_345.5, 100.0]);
    let mut raw = tetloc_core::gen::generate(tetloc_core::gen::Shape::Jets, n, 3);
    for p in &mut raw.points {
        *p = std::array::from_fn(|k| (p[k] as f64 * 1000.0 + offset[k]) as f32);
    }
    let stored: Vec<[f64; 3]> = raw.points.iter().map(|p| p.map(f64::from)).collect();
    let mesh = Arc::new(Mesh::new(raw, "far f32 jets").unwrap());
    assert!(!mesh.info.frame.is_identity() && mesh.wants_f64_points(), "a centred frame, f64 points");
    let (lo, hi) = mesh.file_box();
    let mut unit = common::unit_f64(29);
    let points: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            if i % 2 == 0 {
                common::point_in_a_tet(&mesh, &mut unit, 0.0, |v| stored[v as usize])
            } else {
                std::array::from_fn(|k| lo[k] + unit() * (hi[k] - lo[k]))
            }
        })
        .collect();
    let box_holds = |t: [u32; 4], p: [f64; 3]| {
        let v = t.map(|i| stored[i as usize]);
        (0..3).all(|k| v.iter().any(|q| q[k] <= p[k]) && v.iter().any(|q| q[k] >= p[k])) && holds(v, p)
    };
    let mut locators: Vec<Box<dyn BatchLocator>> = vec![Box::new(CpuLocator::new(mesh.clone()))];
    for k in common::kernels(&ctx, test) {
        locators.push(Box::new(VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap()));
    }
    for loc in &mut locators {
        let mut ids = vec![0i32; n];
        loc.sample_many64(&points, &[], &mut ids, &mut []).unwrap();
        let wrong: Vec<usize> = (0..n)
            .filter(|&i| match ids[i] {
                t if t >= 0 => !box_holds(mesh.tets[t as usize], points[i]),
                _ => mesh.tets.iter().any(|&t| box_holds(t, points[i])),
            })
            .collect();
        let first = wrong.first().map(|&i| (points[i], ids[i]));
        assert!(wrong.is_empty(), "{}: {} of {n} answers wrong, e.g. {first:?}", loc.name(), wrong.len());
    }
    common::assert_no_validation_errors(&ctx);
}

/// Largest minus smallest of the f64 values of field `f`.
fn range_of(mesh: &Mesh) -> f64 {
    let f = mesh.field("f").unwrap();
    let v: Vec<f64> = (0..f.values.len()).map(|i| f.value64(i)).collect();
    v.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b)) - v.iter().fold(f64::INFINITY, |a, &b| a.min(b))
}

/// Issue 29.12: on meshes stored in f64 with slivers (the Delaunay oracle mesh, and a
/// generated one of flat tets for a fresh clone), every kernel's default values (f32, from
/// f32 and from f64 points) are within 1e-5 of the field's range of the CPU's f64 values,
/// and its ids are the CPU's, f32 points included: the kernels decide on the f32 copy, so
/// the host checks their answers even for f32 points (the vertices rounded to f32, within
/// rounding of several tets' faces, are the points the copy gets wrong).
#[test]
fn default_values_on_slivers_stored_in_f64_match_the_cpu() {
    let test = "default_values_on_slivers_stored_in_f64_match_the_cpu";
    let Some(ctx) = common::context(test) else { return };
    let flat = Arc::new(Mesh::new(tetloc_testdata::slivers::flat_layers(8, 1e-5), "flat layers").unwrap());
    let mut unit = common::unit_f64(12);
    let mut in_tets: Vec<Vec3> = (0..20_000)
        .map(|_| common::point_in_a_tet(&flat, &mut unit, 0.01, |v| flat.vertex64(v)).map(|c| c as f32))
        .collect();
    in_tets.extend((0..flat.points.len() as u32).map(|v| flat.vertex64(v).map(|c| c as f32)));
    let mut cases = vec![(flat.clone(), in_tets)];
    if let Some(dir) = tetloc_testdata::require_data(test) {
        let sets = tetloc_testdata::query_sets(&dir);
        let delaunay: Vec<_> = sets.iter().filter(|s| s.label.starts_with("delaunay_s.")).collect();
        assert!(delaunay.len() >= 3, "expected the delaunay_s sets in {}", dir.display());
        let mesh = Arc::new(tetloc_io::read_mesh(&delaunay[0].mesh_path, None).unwrap());
        cases.push((mesh, delaunay.iter().flat_map(|s| s.points.iter().copied()).collect()));
    }
    for (mesh, points) in cases {
        assert!(mesh.points64.is_some(), "{}: stored in f64", mesh.info.source);
        let (n, range) = (points.len(), range_of(&mesh));
        let wide: Vec<[f64; 3]> = points.iter().map(|p| p.map(f64::from)).collect();
        let (mut cpu_ids, mut cpu) = (vec![0i32; n], vec![0f64; n]);
        CpuLocator::new(mesh.clone()).sample_many64(&wide, &["f"], &mut cpu_ids, &mut cpu).unwrap();
        for k in common::kernels(&ctx, test) {
            let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap();
            assert!(loc.uses_float64(), "{k}: the device has shaderFloat64");
            let (mut ids, mut v32, mut v64) = (vec![0i32; n], vec![0f32; n], vec![0f64; n]);
            loc.sample_many(&points, &["f"], &mut ids, &mut v32).unwrap();
            let mut ids64 = vec![0i32; n];
            loc.sample_many64(&wide, &["f"], &mut ids64, &mut v64).unwrap();
            let differ = |ids: &[i32]| (0..n).filter(|&i| ids[i] != cpu_ids[i]).count();
            assert_eq!(differ(&ids64), 0, "{k} {}: the f64 path's ids are exact", mesh.info.source);
            assert_eq!(differ(&ids), 0, "{k} {}: the f32 path's ids are exact", mesh.info.source);
            let paths = [("f32 points", ids, v32.iter().map(|&v| f64::from(v)).collect()), ("f64 points", ids64, v64)];
            for (path, ids, values) in paths {
                let (mut worst, mut at) = (0f64, 0);
                for i in 0..n {
                    let (g, c) = (values[i], cpu[i]);
                    assert_eq!(g.is_nan(), ids[i] < 0, "{k} {path}: point {i}: NaN exactly outside");
                    if !g.is_nan() && (g - c).abs() > worst {
                        (worst, at) = ((g - c).abs(), i);
                    }
                }
                let label = format!("{k} {} {path}", mesh.info.source);
                println!("{label}: worst {:.2e} of the range (point {at})", worst / range);
                assert!(worst <= 1e-5 * range, "{label}: values off by {:e} of the range at point {at}", worst / range);
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}

/// The grid sampler (resample's path) on meshes the kernels hold as a copy: stored in f64
/// (slivers), and stored in f32 far from the origin (a shifted working frame, the kernel's
/// grid made from the working frame's axes), the grid's points in f64 and rounded to f32;
/// and the f64 points of a grid over a mesh near the origin that is its own f32 copy (the
/// kernels mark nothing there: every answer is checked). The kernels make the grid's points
/// themselves and decide on the copy; every kernel's ids are still the CPU's (its raster, on
/// the file's data), and its values within 1e-5 of the range of the CPU's. A grid through
/// the thin layer of slivers puts many points within the copy's rounding of a face.
#[test]
fn the_grid_sampler_on_a_copy_of_the_mesh_gives_the_cpus_ids() {
    let test = "the_grid_sampler_on_a_copy_of_the_mesh_gives_the_cpus_ids";
    let Some(ctx) = common::context(test) else { return };
    let flat = Mesh::new(tetloc_testdata::slivers::flat_layers(8, 1e-5), "flat layers").unwrap();
    let mut raw = tetloc_core::gen::generate(tetloc_core::gen::Shape::Jets, 6_000, 3);
    let offset = [512_345.25, 4_012_345.5, 100.0];
    for p in &mut raw.points {
        *p = std::array::from_fn(|k| (p[k] as f64 * 1000.0 + offset[k]) as f32);
    }
    let far = Mesh::new(raw, "far jets").unwrap();
    assert!(!far.info.frame.is_identity(), "a shifted frame");
    let near = Mesh::new(tetloc_core::gen::generate(tetloc_core::gen::Shape::Jets, 6_000, 3), "jets").unwrap();
    let (flat, far, near) = (Arc::new(flat), Arc::new(far), Arc::new(near));
    let cases = [(&flat, [41, 37, 97], false), (&flat, [41, 37, 97], true), (&far, [53, 47, 41], false)];
    let cases = cases.into_iter().chain([(&far, [53, 47, 41], true), (&near, [41, 43, 47], true)]);
    let mut far_ids: Vec<Vec<i32>> = vec![];
    for (mesh, dims, wide) in cases {
        let (lo, hi) = mesh.file_bounds();
        let grid = tetloc_core::geom::ImageGrid::spanning(lo, hi, dims).unwrap().with_f64_points(wide);
        let (n, range) = (grid.n_points(), range_of(mesh));
        let (mut cpu_ids, mut cpu) = (vec![0i32; n], vec![0f32; n]);
        let mut cpu_loc = CpuLocator::new(mesh.clone());
        tetloc_core::locate::sample_grid(&mut cpu_loc, &grid, 0..n, &["f"], &mut cpu_ids, &mut cpu).unwrap();
        assert!(cpu_ids.iter().filter(|&&t| t >= 0).count() > n / 3, "the grid meets the mesh");
        if Arc::ptr_eq(mesh, &far) {
            far_ids.push(cpu_ids.clone());
        }
        for k in common::kernels(&ctx, test) {
            let label = format!("{k} {} (f64 points: {wide})", mesh.info.source);
            let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions::default()).unwrap();
            let (mut ids, mut values) = (vec![0i32; n], vec![0f32; n]);
            tetloc_core::locate::sample_grid(&mut loc, &grid, 0..n, &["f"], &mut ids, &mut values).unwrap();
            let differ: Vec<usize> = (0..n).filter(|&i| ids[i] != cpu_ids[i]).collect();
            assert!(
                differ.is_empty(),
                "{label}: {} of {n} grid points in another tet, e.g. {:?}",
                differ.len(),
                differ.first()
            );
            for i in 0..n {
                let (g, c) = (f64::from(values[i]), f64::from(cpu[i]));
                assert_eq!(g.is_nan(), ids[i] < 0, "{label}: point {i}: NaN exactly outside");
                assert!(g.is_nan() || (g - c).abs() <= 1e-5 * range, "{label}: point {i}: {g} against the CPU's {c}");
            }
        }
    }
    // Far from the origin, f32 moves some of the grid's points into other tets.
    assert!(far_ids[0].iter().zip(&far_ids[1]).any(|(a, b)| a != b), "the far grid's f32 points stay in their tets");
    common::assert_no_validation_errors(&ctx);
}
