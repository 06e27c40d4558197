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

/// A netCDF variable: name, dimension indices, `elem_type` attribute, type, data.
type NcVar = (String, Vec<usize>, Option<&'static str>, u32, Vec<u8>);

/// A classic (CDF-1) netCDF file, written by hand for the tests: `dims` (size 0: the record
/// dimension), then per variable its name, dimension indices, `elem_type` attribute, type
/// (2 char, 4 int, 6 double) and big-endian data (all records for a record variable).
struct Nc {
    dims: Vec<(&'static str, usize)>,
    vars: Vec<NcVar>,
    n_records: usize,
}

impl Nc {
    fn bytes(&self) -> Vec<u8> {
        fn name(out: &mut Vec<u8>, s: &str) {
            out.extend((s.len() as u32).to_be_bytes());
            out.extend(s.as_bytes());
            out.resize(out.len().next_multiple_of(4), 0);
        }
        let size = |ty: u32| match ty {
            2 => 1,
            4 => 4,
            _ => 8,
        };
        let is_rec = |dims: &[usize]| dims.first().is_some_and(|&d| self.dims[d].1 == 0);
        // One record's (or the whole fixed variable's) bytes, padded to 4.
        let vsize = |(_, dims, _, ty, _): &NcVar| {
            let n: usize = dims.iter().filter(|&&d| self.dims[d].1 != 0).map(|&d| self.dims[d].1).product();
            (n * size(*ty)).next_multiple_of(4)
        };
        let header = |begins: &[u32]| {
            let mut h = b"CDF\x01".to_vec();
            h.extend((self.n_records as u32).to_be_bytes());
            h.extend(10u32.to_be_bytes());
            h.extend((self.dims.len() as u32).to_be_bytes());
            for (n, len) in &self.dims {
                name(&mut h, n);
                h.extend((*len as u32).to_be_bytes());
            }
            h.extend([0u8; 8]); // no global attributes
            h.extend(11u32.to_be_bytes());
            h.extend((self.vars.len() as u32).to_be_bytes());
            for (v, b) in self.vars.iter().zip(begins) {
                name(&mut h, &v.0);
                h.extend((v.1.len() as u32).to_be_bytes());
                v.1.iter().for_each(|&d| h.extend((d as u32).to_be_bytes()));
                match v.2 {
                    None => h.extend([0u8; 8]),
                    Some(a) => {
                        h.extend(12u32.to_be_bytes());
                        h.extend(1u32.to_be_bytes());
                        name(&mut h, "elem_type");
                        h.extend(2u32.to_be_bytes());
                        name(&mut h, a);
                    }
                }
                h.extend(v.3.to_be_bytes());
                h.extend((vsize(v) as u32).to_be_bytes());
                h.extend(b.to_be_bytes());
            }
            h
        };
        let mut begins = vec![0u32; self.vars.len()];
        let mut at = header(&begins).len();
        for (v, b) in self.vars.iter().zip(&mut begins).filter(|(v, _)| !is_rec(&v.1)) {
            *b = at as u32;
            at += vsize(v);
        }
        let rec_size: usize = self.vars.iter().filter(|v| is_rec(&v.1)).map(vsize).sum();
        for (v, b) in self.vars.iter().zip(&mut begins).filter(|(v, _)| is_rec(&v.1)) {
            *b = at as u32;
            at += vsize(v);
        }
        let mut out = header(&begins);
        for v in self.vars.iter().filter(|v| !is_rec(&v.1)) {
            out.extend(&v.4);
            out.resize(out.len().next_multiple_of(4), 0);
        }
        for r in 0..self.n_records {
            for v in self.vars.iter().filter(|v| is_rec(&v.1)) {
                let n = v.4.len() / self.n_records;
                out.extend(&v.4[r * n..(r + 1) * n]);
                out.resize(out.len().next_multiple_of(4), 0);
            }
        }
        assert_eq!(out.len(), at + rec_size * self.n_records.saturating_sub(1));
        out
    }
}

/// A two-tet Exodus file with nodal variables: `n_vars` (the `num_nod_var` dimension) stored
/// `vals_nod_var<i>`, `names` in `name_nod_var` (none: no such variable), at `times`.
fn exodus_file(n_vars: usize, names: Option<&[&str]>, times: &[f64]) -> Vec<u8> {
    let f64s = |v: &[f64]| v.iter().flat_map(|x| x.to_be_bytes()).collect::<Vec<u8>>();
    let dims = vec![
        ("len_name", 33),
        ("num_dim", 3),
        ("num_nodes", 5),
        ("num_el_blk", 1),
        ("num_el_in_blk1", 2),
        ("num_nod_per_el1", 4),
        ("time_step", 0),
        ("num_nod_var", n_vars),
    ];
    let pts = crate::test_support::two_tets(vec![]).points;
    let mut vars = vec![("time_whole".to_string(), vec![6], None, 6, f64s(times))];
    for (k, axis) in ["coordx", "coordy", "coordz"].iter().enumerate() {
        vars.push((axis.to_string(), vec![2], None, 6, f64s(&pts.iter().map(|p| p[k] as f64).collect::<Vec<_>>())));
    }
    let conn: Vec<u8> = [1, 2, 3, 4, 2, 3, 4, 5].iter().flat_map(|i: &i32| i.to_be_bytes()).collect();
    vars.push(("connect1".into(), vec![4, 5], Some("TETRA4"), 4, conn));
    if let Some(names) = names {
        let mut chars = vec![0u8; 33 * n_vars];
        for (i, n) in names.iter().enumerate() {
            chars[33 * i..33 * i + n.len()].copy_from_slice(n.as_bytes());
        }
        vars.push(("name_nod_var".into(), vec![7, 0], None, 2, chars));
    }
    for i in 0..n_vars {
        let vals: Vec<f64> = (0..times.len() * 5).map(|j| (10 * i + j) as f64).collect();
        vars.push((format!("vals_nod_var{}", i + 1), vec![6, 2], None, 6, f64s(&vals)));
    }
    Nc { dims, vars, n_records: times.len() }.bytes()
}

/// Nodal variables are never dropped or shadowed silently: values without names, a count
/// above the names, an empty or repeated name are errors naming the file and the problem.
#[test]
fn nodal_variable_names_must_match_the_variables() {
    let path = Path::new("v.exo");
    let ok = parse(&exodus_file(2, Some(&["f", "g"]), &[0.0]), path).unwrap();
    let names: Vec<&str> = ok.fields.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["f", "g"]);
    assert_eq!(ok.fields[1].values, [10.0, 11.0, 12.0, 13.0, 14.0]);
    let cases: [(usize, Option<&[&str]>, &str); 3] = [
        (1, None, "the file has 1 (num_nod_var or vals_nod_var*) but name_nod_var names 0"),
        (2, Some(&["f"]), "variable 2 has an empty name"),
        (2, Some(&["f", "f"]), "'f' is named twice in name_nod_var"),
    ];
    for (n, names, want) in cases {
        let e = parse(&exodus_file(n, names, &[0.0]), path).unwrap_err().to_string();
        assert!(e.starts_with("v.exo") && e.contains("nodal variables") && e.contains(want), "{e}");
    }
}

/// Every time must be finite, a lone step's too (the increasing check compares neighbours).
#[test]
fn times_must_be_finite() {
    for times in [&[f64::NAN][..], &[f64::INFINITY], &[0.0, f64::NAN]] {
        let e = parse(&exodus_file(1, Some(&["f"]), times), Path::new("t.exo")).unwrap_err().to_string();
        assert!(e.starts_with("t.exo") && e.contains("time_whole") && e.contains("not a finite time"), "{e}");
    }
}
