use super::*;
use std::sync::Arc;
use tetloc_core::cell::CellType;
use tetloc_core::locate::CpuLocator;
use tetloc_core::ops::weights::Weights;
use tetloc_core::Mesh;

/// `../shared/data/time`'s README: the steps' times.
const TIMES: [f64; 6] = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5];

fn time_dir(test: &str) -> Option<PathBuf> {
    tetloc_testdata::require_data(test).map(|d| d.join("time"))
}

/// The oracle: each step's value of `f` at the `part_s.random` points, (steps, points).
fn oracle(dir: &Path) -> (Vec<[f64; 3]>, Vec<Vec<f64>>) {
    let points = crate::points::read_points(&dir.join("../part_s.random.points.bin")).unwrap();
    let bytes = std::fs::read(dir.join("part_s.random.values_by_step.npy")).unwrap();
    let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
    let shape = npy.shape().to_vec();
    let values: Vec<f64> = npy.into_vec().unwrap();
    let n = shape[1] as usize;
    (points.iter().map(|p| p.map(f64::from)).collect(), values.chunks(n).map(<[f64]>::to_vec).collect())
}

/// Each step of each form of the series (Exodus netCDF-4, Exodus classic, `.pvd`) read a step
/// at a time, its `f` applied through weights located once, equals the data's oracle values.
#[test]
fn every_form_of_the_series_matches_the_oracle_at_every_step() {
    let Some(dir) = time_dir("every_form_of_the_series_matches_the_oracle_at_every_step") else { return };
    let (points, want) = oracle(&dir);
    assert_eq!(want.len(), TIMES.len());
    for file in ["part_s.e", "part_s.classic.exo", "part_s.pvd"] {
        let path = dir.join(file);
        let (raw, steps) = crate::read_series(&path, None).unwrap();
        let steps = steps.unwrap_or_else(|| panic!("{file}: no steps"));
        assert_eq!(steps.times, TIMES, "{file}");
        let mesh = Arc::new(Mesh::new(raw, file).unwrap());
        assert_eq!(mesh.n_tets(), 24459, "{file}");
        let w = Weights::locate(&mut CpuLocator::new(mesh.clone()), &mesh, &points).unwrap();
        for (k, want) in want.iter().enumerate() {
            let f = steps.field("f", k).unwrap();
            let mut got = vec![0f64; points.len()];
            w.apply_field(&f, &mut got).unwrap();
            let worst = got.iter().zip(want).map(|(g, w)| (g - w).abs() / w.abs().max(1.0)).fold(0f64, f64::max);
            assert!(worst < 1e-12, "{file} step {k}: off by {worst:e}");
        }
        let e = steps.fields(TIMES.len()).unwrap_err().to_string();
        assert!(e.contains("out of range") && e.contains("6 steps"), "{file}: {e}");
    }
}

/// The two Exodus encodings and the `.pvd` hold the same mesh and values.
#[test]
fn netcdf4_classic_and_pvd_agree() {
    let Some(dir) = time_dir("netcdf4_classic_and_pvd_agree") else { return };
    let read = |f: &str| crate::read_series(&dir.join(f), None).unwrap();
    let (a, sa) = read("part_s.e");
    let (b, sb) = read("part_s.classic.exo");
    let (c, _) = read("part_s.pvd");
    assert_eq!(a.points, b.points);
    assert_eq!(a.points, c.points);
    assert_eq!(a.tets, b.tets);
    assert_eq!(a.tets, c.tets);
    let (sa, sb) = (sa.unwrap(), sb.unwrap());
    for k in 0..TIMES.len() {
        let (fa, fb) = (sa.field("f", k).unwrap(), sb.field("f", k).unwrap());
        assert!((0..fa.values.len()).all(|i| fa.value64(i) == fb.value64(i)), "step {k}");
    }
}

/// Exodus node orders, as the Exodus II manual numbers them (1-based: node, edge ends): after
/// the reorder, every edge node sits at the middle of its edge (VTK's node, mapped by the
/// linear cell onto a reference cell whose pyramid apex is a point). An independent
/// statement of each convention, so a wrong table fails.
#[test]
fn exodus_edge_nodes_land_on_vtk_edge_midpoints() {
    let tetra10: &[(usize, usize, usize)] = &[(5, 1, 2), (6, 2, 3), (7, 3, 1), (8, 1, 4), (9, 2, 4), (10, 3, 4)];
    let hex20: &[(usize, usize, usize)] = &[
        (9, 1, 2),
        (10, 2, 3),
        (11, 3, 4),
        (12, 4, 1),
        (13, 1, 5),
        (14, 2, 6),
        (15, 3, 7),
        (16, 4, 8),
        (17, 5, 6),
        (18, 6, 7),
        (19, 7, 8),
        (20, 8, 5),
    ];
    let wedge15: &[(usize, usize, usize)] =
        &[(7, 1, 2), (8, 2, 3), (9, 3, 1), (10, 1, 4), (11, 2, 5), (12, 3, 6), (13, 4, 5), (14, 5, 6), (15, 6, 4)];
    let pyramid13: &[(usize, usize, usize)] =
        &[(6, 1, 2), (7, 2, 3), (8, 3, 4), (9, 4, 1), (10, 1, 5), (11, 2, 5), (12, 3, 5), (13, 4, 5)];
    for (name, n, edges) in
        [("TETRA10", 10, tetra10), ("HEX20", 20, hex20), ("WEDGE15", 15, wedge15), ("PYRAMID13", 13, pyramid13)]
    {
        let cell = vtk_cell(name, n).unwrap().unwrap();
        let def = CellType::from_vtk(cell.code, n).unwrap().def();
        let pc = def.node_pcoords();
        let shape = def.shape();
        let mut corners: Vec<[f64; 3]> = shape.corners.to_vec();
        if corners.len() == 5 {
            corners[4] = [0.5, 0.5, 1.0];
        }
        let exo_of_vtk = |i: usize| cell.from_exodus.map_or(i, |p| p[i]);
        for &(node, a, b) in edges {
            let vtk = (0..n).find(|&i| exo_of_vtk(i) == node - 1).unwrap();
            let mid: [f64; 3] = std::array::from_fn(|k| (corners[a - 1][k] + corners[b - 1][k]) / 2.0);
            let at = tetloc_core::cell::forward(shape.linear, &corners, pc[vtk]);
            let off = (0..3).map(|k| (at[k] - mid[k]).abs()).fold(0.0, f64::max);
            assert!(off < 1e-12, "{name}: Exodus node {node} on edge {a}-{b} is VTK node {vtk} at {at:?}, not {mid:?}");
        }
    }
    assert!(vtk_cell("QUAD4", 4).unwrap().is_none());
    assert!(vtk_cell("SHELL4", 4).unwrap().is_none());
    let e = vtk_cell("HEX27", 27).err().unwrap();
    assert!(e.contains("HEX27") && e.contains("TETRA4/10"), "{e}");
    assert!(vtk_cell("POLYHEDRON", 12).is_err());
}

/// `_x/_y/_z` triples become vectors; lone components and other names stay scalars.
#[test]
fn xyz_components_group_into_vectors() {
    let arrays = ["vel_x", "p", "vel_y", "vel_Z", "disp_x", "disp_y"].map(|n| (n.to_string(), vec![0.0]));
    let names: Vec<String> = grouped(arrays.to_vec(), FieldLocation::Vertex).into_iter().map(|f| f.name).collect();
    assert_eq!(names, ["vel[0]", "p", "vel[1]", "vel[2]", "disp_x", "disp_y"]);
}

/// A file that is not netCDF, and a netCDF file without a mesh, are clear errors.
#[test]
fn non_exodus_files_are_refused_clearly() {
    let dir = std::env::temp_dir().join(format!("tetloc-exodus-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.e");
    std::fs::write(&bad, b"not netcdf at all").unwrap();
    let e = read(&bad).unwrap_err().to_string();
    assert!(e.contains("bad.e") && e.contains("netCDF"), "{e}");
    let e = read(&dir.join("missing.exo")).unwrap_err().to_string();
    assert!(e.contains("missing.exo"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An array's values in order whatever its layout: standard (its own buffer), transposed
/// (gathered), and an owned window of a larger buffer (an offset).
#[test]
fn values_in_order_for_every_layout() {
    use ndarray::{s, ArrayD, IxDyn};
    let a = ArrayD::from_shape_vec(IxDyn(&[2, 3]), (0..6).collect::<Vec<i32>>()).unwrap();
    assert_eq!(values(a.clone()), vec![0, 1, 2, 3, 4, 5]);
    assert!(matches!(contiguous(&a), Cow::Borrowed(_)));
    let t = a.clone().reversed_axes();
    assert_eq!(values(t.clone()), vec![0, 3, 1, 4, 2, 5]);
    assert_eq!(contiguous(&t).into_owned(), vec![0, 3, 1, 4, 2, 5]);
    let window = a.slice_move(s![1.., ..]).into_dyn();
    assert_eq!(values(window), vec![3, 4, 5]);
}
