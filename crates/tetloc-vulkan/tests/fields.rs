//! One location for k fields (issue 28): `query` writes each point's id and every field's
//! value in one launch (OUT_FIELDS), and they equal, bit for bit, those of the launch a field
//! it replaced (`sample_per_field`), on every kernel: 1, 2 and 3 fields of 1 and 3
//! components, per vertex and per cell, linear and quadratic tets, a mesh stored in f64
//! (refined barycentrics), a mixed mesh, batches split over launches, more fields than one
//! launch takes, and the grid sampler.

mod common;

use std::sync::Arc;
use tetloc_core::gen::{flow, generate, Shape};
use tetloc_core::geom::{ImageGrid, Vec3};
use tetloc_core::locate::{grid_points, GridSampler};
use tetloc_core::mesh::{Field, FieldLocation, Mesh};
use tetloc_core::{BatchLocator, RawMesh};
use tetloc_testdata::KuhnGrid;
use tetloc_vulkan::{Kernel, LocatorOptions, SoftBvhOptions, VulkanLocator};

/// The field sets asked for: 1, 2 and 3 fields (a vector `v` is its 3 components), per
/// vertex (`f`, `v`) and per cell (`cellval`).
const SETS: &[&[&str]] = &[
    &["f"],
    &["cellval"],
    &["v[0]", "v[1]", "v[2]"],
    &["f", "cellval"],
    &["v[0]", "v[1]", "v[2]", "f"],
    &["cellval", "v[0]", "v[1]", "v[2]", "f"],
];

/// `raw` with the flow vector `v` (3 components) and, where it has none, the fields `f`
/// (per vertex) and `cellval` (per cell).
fn with_fields(mut raw: RawMesh, shape: Shape) -> RawMesh {
    let v = flow::vector_fields(shape, &raw.points);
    raw.fields.extend(v);
    if !raw.fields.iter().any(|f| f.name == "f") {
        let f = raw.points.iter().map(|p| p[0] - 2.0 * p[1] + 0.5 * p[2] * p[2]).collect();
        raw.fields.push(Field::new("f", FieldLocation::Vertex, f));
    }
    if !raw.fields.iter().any(|f| f.name == "cellval") {
        let n = raw.cells.as_ref().map_or(raw.tets.len(), |c| c.types.len());
        raw.fields.push(Field::new("cellval", FieldLocation::Cell, (0..n).map(|c| (c % 89) as f32 - 7.5).collect()));
    }
    raw
}

/// `n` points over the box of `mesh` widened by a tenth on each side (some outside).
fn points(mesh: &Mesh, n: usize, seed: u64) -> Vec<Vec3> {
    let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
    let mut s = seed;
    let mut unit = || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..n).map(|_| std::array::from_fn(|k| lo[k] + (hi[k] - lo[k]) * (1.2 * unit() - 0.1))).collect()
}

/// The one-launch answers equal the per-field launches', bits and all; returns how many
/// values were inside (a check that the comparison compared something).
fn same_as_per_field(label: &str, loc: &mut VulkanLocator, pts: &[Vec3], fields: &[&str]) -> usize {
    let (n, k) = (pts.len(), fields.len());
    let (mut ids, mut vals) = (vec![7i32; n], vec![1f32; n * k]);
    loc.sample_many(pts, fields, &mut ids, &mut vals).unwrap();
    let (mut ids1, mut vals1) = (vec![-7i32; n], vec![2f32; n * k]);
    loc.sample_per_field(pts, fields, &mut ids1, &mut vals1).unwrap();
    for i in 0..n {
        assert_eq!(ids[i], ids1[i], "{label} {fields:?}: point {i} {:?}", pts[i]);
        for j in 0..k {
            let (a, b) = (vals[i * k + j], vals1[i * k + j]);
            assert_eq!(a.to_bits(), b.to_bits(), "{label} {fields:?}: point {i}, field {}: {a} vs {b}", fields[j]);
            assert_eq!(a.is_nan(), ids[i] < 0, "{label} {fields:?}: point {i}: NaN exactly outside");
        }
    }
    ids.iter().filter(|&&t| t >= 0).count() * k
}

/// Every kernel, the field sets `sets`, on `mesh`; with `all`, also soft-bvh with deferred
/// exact tests, with the pure-f32 test and in batches of many launches (a small staging
/// buffer), and more fields than one launch takes.
fn check_mesh(test: &str, what: &str, mesh: Arc<Mesh>, n: usize, sets: &[&[&str]], all: bool) {
    let Some(ctx) = common::context(test) else { return };
    let pts = points(&mesh, n, 5);
    let mut configs: Vec<(String, Kernel, LocatorOptions)> =
        common::kernels(&ctx, test).into_iter().map(|k| (k.to_string(), k, LocatorOptions::default())).collect();
    if all {
        let defer = SoftBvhOptions { defer_exact: true, ..SoftBvhOptions::fast() };
        configs.push((
            "soft-bvh deferred".into(),
            Kernel::SoftBvh,
            LocatorOptions { soft_bvh: defer, ..Default::default() },
        ));
        configs.push(("soft-bvh f32".into(), Kernel::SoftBvh, LocatorOptions { float64: false, ..Default::default() }));
        // 64 KiB of staging: a few thousand points a launch, fewer the more fields.
        let small = LocatorOptions { staging_bytes: 64 << 10, ..Default::default() };
        configs.push(("soft-bvh small batches".into(), Kernel::SoftBvh, small));
    }
    for (name, kernel, opts) in configs {
        let label = format!("{what}, {name}");
        let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), kernel, opts).unwrap();
        let inside: usize = sets.iter().map(|set| same_as_per_field(&label, &mut loc, &pts, set)).sum();
        assert!(inside > n, "{label}: too few points inside to compare ({inside} values)");
        // Changing sets again (fields kept, reordered, dropped) keeps the answers.
        same_as_per_field(&label, &mut loc, &pts, sets[0]);
    }
    if all {
        // More fields than one launch samples: a pass each MAX_FIELDS, columns in place.
        let many: Vec<&str> = SETS[5].iter().cycle().take(tetloc_vulkan::MAX_FIELDS as usize + 3).copied().collect();
        let mut loc =
            VulkanLocator::new(ctx.clone(), mesh.clone(), Kernel::SoftBvh, LocatorOptions::default()).unwrap();
        same_as_per_field(&format!("{what}, soft-bvh, {} fields", many.len()), &mut loc, &pts, &many);
    }
    common::assert_no_validation_errors(&ctx);
}

/// Fewer sets for the other meshes (lavapipe compiles a pipeline a set): a vector, and 3 fields
/// of 1 and 3 components, per vertex and per cell.
const FEW: &[&[&str]] = &[&["v[0]", "v[1]", "v[2]"], &["cellval", "v[0]", "v[1]", "v[2]", "f"]];

/// Jets (linear tets), ordered batches (more points than ORDER_MIN_POINTS).
#[test]
fn one_launch_equals_a_launch_a_field_on_linear_tets() {
    let mesh = Arc::new(Mesh::new(with_fields(generate(Shape::Jets, 6_000, 3), Shape::Jets), "jets").unwrap());
    check_mesh("one_launch_equals_a_launch_a_field_on_linear_tets", "jets", mesh, 40_000, SETS, true);
}

/// Quadratic tets: the tets' own shape functions, once a field.
#[test]
fn one_launch_equals_a_launch_a_field_on_quadratic_tets() {
    let raw = KuhnGrid::new(4).jitter(0.1, 5).order(2).vertex_field(|p| p[0] * p[1] - p[2]).raw();
    let mesh = Arc::new(Mesh::new(with_fields(raw, Shape::Jets), "quadratic").unwrap());
    check_mesh("one_launch_equals_a_launch_a_field_on_quadratic_tets", "quadratic", mesh, 3_000, FEW, false);
}

/// A mesh stored in f64 (vertices a quarter ulp off their f32 copies): the barycentrics are
/// refined once a point and serve every field.
#[test]
fn one_launch_equals_a_launch_a_field_on_a_mesh_stored_in_f64() {
    let mut raw = with_fields(generate(Shape::Fusion, 4_000, 2), Shape::Fusion);
    let file = raw
        .points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            std::array::from_fn(|k| {
                let x = p[k].abs();
                let ulp = f64::from(f32::from_bits(x.to_bits() + 1) - x);
                f64::from(p[k]) + if (i >> k) & 1 == 0 { 0.25 } else { -0.25 } * ulp
            })
        })
        .collect();
    raw.points64 = Some(file);
    let mesh = Arc::new(Mesh::new(raw, "fusion f64").unwrap());
    assert!(mesh.working_residuals().is_some(), "the mesh is stored in f64");
    check_mesh("one_launch_equals_a_launch_a_field_on_a_mesh_stored_in_f64", "fusion f64", mesh, 3_000, FEW, false);
}

/// A mixed mesh (hexes, wedges, pyramids, tets): the kernels answer in its tet decomposition
/// (soft-bvh and rt-bvh with one box a cell); `CellLocator` computes its values on the host,
/// but the kernels' own must still agree.
#[test]
fn one_launch_equals_a_launch_a_field_on_a_mixed_mesh() {
    let spec = "jets-hybrid".parse().unwrap();
    let raw = tetloc_core::gen::generate_spec(spec, 3_000, 4, &|_| {});
    let mut mesh = Mesh::new(with_fields(raw, Shape::Jets), "jets-hybrid").unwrap();
    assert!(mesh.cells.is_some(), "a mixed mesh");
    // Per-cell values of the decomposition's tets (the kernels index cell fields by tet).
    let n_tets = mesh.n_tets();
    let c = mesh.fields.iter_mut().find(|f| f.name == "cellval").unwrap();
    *c = Field::new("cellval", FieldLocation::Cell, (0..n_tets).map(|t| (t % 89) as f32).collect());
    check_mesh("one_launch_equals_a_launch_a_field_on_a_mixed_mesh", "jets-hybrid", Arc::new(mesh), 3_000, FEW, false);
}

/// The grid sampler writes the ids and values in one launch too: those of the same points
/// sent from the host, on every kernel.
#[test]
fn the_grid_sampler_samples_every_field_in_one_launch() {
    let test = "the_grid_sampler_samples_every_field_in_one_launch";
    let Some(ctx) = common::context(test) else { return };
    let mesh = Arc::new(Mesh::new(with_fields(generate(Shape::Jets, 6_000, 3), Shape::Jets), "jets").unwrap());
    let (lo, hi) = mesh.file_bounds();
    let grid = ImageGrid::spanning(lo, hi, [23, 19, 17]).unwrap();
    let range = 100..grid.n_points() - 50;
    let pts = grid_points(&grid, range.clone());
    for kernel in common::kernels(&ctx, test) {
        let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), kernel, LocatorOptions::default()).unwrap();
        for set in FEW {
            let (n, k) = (range.len(), set.len());
            let (mut ids, mut vals) = (vec![0i32; n], vec![0f32; n * k]);
            loc.sample_grid(&grid, range.clone(), set, &mut ids, &mut vals).unwrap();
            let (mut ids1, mut vals1) = (vec![0i32; n], vec![0f32; n * k]);
            loc.sample_per_field(&pts, set, &mut ids1, &mut vals1).unwrap();
            assert_eq!(ids, ids1, "{kernel} {set:?}: grid ids");
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert!(bits(&vals) == bits(&vals1), "{kernel} {set:?}: grid values differ from the host points'");
            assert!(ids.iter().any(|&t| t >= 0), "{kernel}: the grid meets the mesh");
        }
    }
    common::assert_no_validation_errors(&ctx);
}

/// A built locator takes another time step's fields (`Mesh::with_fields`), its mesh and
/// structure kept on the device: its answers are then a new locator's on that mesh, bit for
/// bit, for host points and the grid sampler, on every kernel; a mesh of another geometry is
/// refused, nothing changed.
#[test]
fn a_built_locator_takes_another_steps_fields() {
    let test = "a_built_locator_takes_another_steps_fields";
    let Some(ctx) = common::context(test) else { return };
    let first = Arc::new(Mesh::new(with_fields(generate(Shape::Jets, 6_000, 3), Shape::Jets), "jets").unwrap());
    let flipped = |f: &Field| {
        Field::from_f64(f.name.clone(), f.location, (0..f.values.len()).map(|i| 3.0 - 2.0 * f.value64(i)).collect())
    };
    let step = Arc::new(first.with_fields(first.fields.iter().map(flipped).collect()).unwrap());
    let (lo, hi) = first.file_bounds();
    let grid = ImageGrid::spanning(lo, hi, [19, 17, 13]).unwrap();
    let pts = points(&first, 2_000, 5);
    let set = ["cellval", "v[0]", "v[1]", "v[2]", "f"];
    let answers = |loc: &mut VulkanLocator| {
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let (mut ids, mut vals) = (vec![0i32; pts.len()], vec![0f32; pts.len() * set.len()]);
        loc.sample_many(&pts, &set, &mut ids, &mut vals).unwrap();
        let n = grid.n_points();
        let (mut gids, mut gvals) = (vec![0i32; n], vec![0f32; n * set.len()]);
        loc.sample_grid(&grid, 0..n, &set, &mut gids, &mut gvals).unwrap();
        (ids, bits(&vals), gids, bits(&gvals))
    };
    for kernel in common::kernels(&ctx, test) {
        let new =
            |m: &Arc<Mesh>| VulkanLocator::new(ctx.clone(), m.clone(), kernel, LocatorOptions::default()).unwrap();
        let mut loc = new(&first);
        let before = answers(&mut loc);
        assert!(loc.take_fields(&step), "{kernel}");
        let taken = answers(&mut loc);
        assert!(taken == answers(&mut new(&step)), "{kernel}: not a new locator's answers on the step");
        assert!(taken.1 != before.1, "{kernel}: the step's values show");
        let other = Arc::new(Mesh::new(with_fields(generate(Shape::Jets, 6_000, 3), Shape::Jets), "jets").unwrap());
        assert!(!loc.take_fields(&other), "{kernel}: another geometry (the same numbers, read anew)");
        assert!(answers(&mut loc) == taken, "{kernel}: nothing changed");
    }
    common::assert_no_validation_errors(&ctx);
}
