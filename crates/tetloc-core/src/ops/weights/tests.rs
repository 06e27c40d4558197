use super::*;
use crate::cell::{CellBlock, CellType};
use crate::locate::{CellLocator, CpuLocator, FiniteOnly};
use crate::mesh::RawMesh;
use crate::test_support::{mixed::mixed_sets, read_mesh, KuhnGrid};
use std::sync::Arc;

/// The CPU stack of the front door for mixed meshes: ids are cell ids.
fn stack(mesh: &Arc<Mesh>) -> CellLocator<FiniteOnly<CpuLocator>> {
    CellLocator::new(FiniteOnly::new(CpuLocator::new(mesh.clone())), mesh.clone())
}

/// Points spread over the mesh's box and a little beyond (some fall outside).
fn box_points(mesh: &Mesh, n: usize, seed: u64) -> Vec<[f64; 3]> {
    let (lo, hi) = mesh.file_box();
    let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    let mut next = || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n).map(|_| std::array::from_fn(|k| lo[k] - 0.05 * (hi[k] - lo[k]) + 1.1 * (hi[k] - lo[k]) * next())).collect()
}

/// `W @ f` equals the locator's f64 sample of every field of the mesh (to rounding), cell ids
/// included, on `points`; returns how many points were inside.
fn check_against_sample(mesh: &Arc<Mesh>, points: &[[f64; 3]], what: &str) -> usize {
    let mut loc = stack(mesh);
    let w = Weights::locate(&mut loc, mesh, points).unwrap();
    assert_eq!((w.n_points(), w.n_vertices), (points.len(), mesh.points.len()));
    let names: Vec<&str> = mesh.fields.iter().map(|f| f.name.as_str()).collect();
    assert!(!names.is_empty(), "{what}: no fields to compare");
    let (mut ids, mut want) = (vec![0; points.len()], vec![0f64; points.len() * names.len()]);
    loc.sample_many64(points, &names, &mut ids, &mut want).unwrap();
    assert_eq!(w.cells, ids, "{what}: the weights' cells are the locator's");
    for (j, f) in mesh.fields.iter().enumerate() {
        let mut got = vec![0f64; points.len()];
        w.apply_field(f, &mut got).unwrap();
        let scale = f.values.iter().fold(0f32, |m, v| m.max(v.abs())) as f64;
        for (i, &g) in got.iter().enumerate() {
            let s = want[i * names.len() + j];
            assert_eq!(g.is_nan(), s.is_nan(), "{what} field {}: point {i}: W gives {g}, sample {s}", f.name);
            assert!(g.is_nan() || (g - s).abs() <= 1e-12 * scale.max(1.0), "{what} {}: point {i}: {g} vs {s}", f.name);
        }
    }
    // Rows are empty exactly outside; inside they sum to one (a partition of unity).
    for i in 0..w.n_points() {
        let (v, ws) = w.row(i);
        assert_eq!(v.is_empty(), w.cells[i] < 0, "{what}: point {i}");
        if !v.is_empty() {
            assert!((ws.iter().sum::<f64>() - 1.0).abs() < 1e-9, "{what}: row {i} sums to {}", ws.iter().sum::<f64>());
        }
    }
    w.cells.iter().filter(|&&c| c >= 0).count()
}

/// One cell of `ty`: its nodes at their parametric coordinates under an affine map, the
/// nodes past the corners moved a little (a curved cell), with a nonlinear vertex field and
/// a cell field.
fn one_cell(ty: CellType) -> Mesh {
    let def = ty.def();
    let a = [[1.0, 0.2, 0.1], [0.1, 0.9, -0.2], [0.05, 0.15, 1.1]];
    let n_corners = def.shape().n_corners();
    let points: Vec<[f32; 3]> = def
        .node_pcoords()
        .iter()
        .enumerate()
        .map(|(i, pc)| {
            let bend = if i < n_corners { 0.0 } else { 0.02 * (7.0 * i as f64).sin() };
            std::array::from_fn(|r| (a[r][0] * pc[0] + a[r][1] * pc[1] + a[r][2] * pc[2] + bend) as f32)
        })
        .collect();
    let f = points.iter().map(|p| (3.0 * p[0]).sin() + p[1] * p[2] * 2.0 - p[2]).collect();
    let mut block = CellBlock::default();
    let ids: Vec<u32> = (0..def.n_nodes() as u32).collect();
    block.push(ty, &ids);
    let is_tet = def.shape().is_tet();
    let raw = RawMesh {
        tets: if is_tet { vec![[0, 1, 2, 3]] } else { Vec::new() },
        fields: vec![Field::new("f", FieldLocation::Vertex, f), Field::new("g", FieldLocation::Cell, vec![4.5])],
        higher_order: (def.order() > 1).then_some(def.order()),
        cells: Some(block),
        points,
        points64: None,
    };
    Mesh::new(raw, def.name()).unwrap()
}

/// Every cell type tetloc knows, with all its nodes: the weights are its shape functions.
#[test]
fn weights_equal_sample_on_every_cell_type() {
    // Polyhedra are refused (next test).
    for ty in CellType::all().filter(|t| !t.is_polyhedron()) {
        let mesh = Arc::new(one_cell(ty));
        let inside = check_against_sample(&mesh, &box_points(&mesh, 400, 7), ty.def().name());
        assert!(inside > 20, "{}: only {inside} points inside", ty.def().name());
    }
}

/// A mesh with polyhedra gets a clear error, not weights in columns (the decomposition's
/// centroids) that no file has.
#[test]
fn polyhedral_meshes_are_refused() {
    use crate::gen::{generate_spec, CellKind, Shape, Spec};
    let raw = generate_spec(Spec { shape: Shape::Jets, cells: CellKind::Octree }, 2000, 1, &|_| {});
    let mesh = Arc::new(Mesh::new(raw, "jets-octree").unwrap());
    assert!(mesh.info.n_centroids > 0);
    let pts = box_points(&mesh, 50, 3);
    let err = Weights::locate(&mut stack(&mesh), &mesh, &pts).unwrap_err().to_string();
    assert!(err.contains("polyhedral") && err.contains("jets-octree"), "{err}");
}

/// Meshes of quadratic (and cubic) tets, with a field that is not linear: their rows hold all
/// of the tet's nodes.
#[test]
fn weights_equal_sample_on_higher_order_tet_meshes() {
    for order in [2u8, 3] {
        let raw =
            KuhnGrid::new(3).jitter(0.15, 3).order(order).vertex_field(|p| (4.0 * p[0]).sin() + p[1] * p[2]).raw();
        let mesh = Arc::new(Mesh::new(raw, "elevated").unwrap());
        let pts = box_points(&mesh, 2000, u64::from(order));
        assert!(check_against_sample(&mesh, &pts, &format!("order {order}")) > 1000);
        let w = Weights::locate(&mut stack(&mesh), &mesh, &pts).unwrap();
        let n_nodes = mesh.tet_nodes.as_ref().unwrap().n_extra() + 4;
        assert!((0..w.n_points()).all(|i| w.row(i).0.is_empty() || w.row(i).0.len() == n_nodes));
    }
}

/// The mixed oracle meshes of the data folder (hexes, wedges, pyramids, tets), at their query
/// points: `W @ f == sample`, and the ids of the oracle answer per-cell fields.
#[test]
fn weights_equal_sample_on_the_mixed_meshes() {
    for (name, (files, sets)) in mixed_sets("weights_equal_sample_on_the_mixed_meshes") {
        let mesh = Arc::new(read_mesh(&files[0]).unwrap());
        for set in &sets {
            let pts: Vec<[f64; 3]> = set.points.iter().map(|p| p.map(f64::from)).collect();
            let inside = check_against_sample(&mesh, &pts, &format!("{name} {}", set.label));
            assert!(inside > 0, "{name} {}: no point inside", set.label);
        }
    }
}

/// `apply` of a k-component field is `apply` of each component; f32 fields give the f64
/// sums rounded; lengths that do not fit are errors, not panics.
#[test]
fn apply_takes_components_and_refuses_bad_lengths() {
    let mesh = Arc::new(KuhnGrid::new(2).jitter(0.1, 1).mesh("grid"));
    let pts = box_points(&mesh, 300, 2);
    let w = Weights::locate(&mut stack(&mesh), &mesh, &pts).unwrap();
    let n = mesh.points.len();
    let vec3: Vec<f64> = (0..3 * n).map(|i| (i as f64 * 0.37).cos()).collect();
    let mut all = vec![0f64; 3 * pts.len()];
    w.apply(&vec3, 3, &mut all).unwrap();
    for j in 0..3 {
        let comp: Vec<f64> = vec3.iter().skip(j).step_by(3).copied().collect();
        let mut one = vec![0f64; pts.len()];
        w.apply(&comp, 1, &mut one).unwrap();
        for i in 0..pts.len() {
            assert!(one[i] == all[3 * i + j] || (one[i].is_nan() && all[3 * i + j].is_nan()));
        }
    }
    let narrow: Vec<f32> = vec3.iter().map(|&x| x as f32).collect();
    let mut out32 = vec![0f32; 3 * pts.len()];
    w.apply(&narrow, 3, &mut out32).unwrap();
    assert!(out32.iter().zip(&all).all(|(a, b)| (f64::from(*a) - b).abs() < 1e-6 || a.is_nan() && b.is_nan()));
    assert!(w.apply(&vec3, 2, &mut all).is_err());
    assert!(w.apply(&vec3[1..], 3, &mut all).is_err());
    assert!(w.apply_cells(&[1.0f64, 2.0], 1, &mut vec![0.0; pts.len()]).is_err());
    assert!(Weights::from_cells(&mesh, &pts[..2], vec![0]).is_err());
    assert!(Weights::from_cells(&mesh, &pts[..1], vec![mesh.n_cells() as i32]).is_err());
}
