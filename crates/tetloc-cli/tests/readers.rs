//! Issue 29 items 13-20 end to end: what `info` says about fields, probe targets of any
//! cells, byte-order marks, one rule for naming fields and components, messages, and pieces
//! outside a listing's folder.

mod common;

use common::{s, tetloc, tetloc_cpu, tmp_dir};
use std::path::{Path, PathBuf};
use tetloc_core::FieldLocation;
use tetloc_io::vtk::vtu;

/// An ASCII `.vtu` piece: `points` (x y z ...), cells of `types` with `conn` and `offsets`,
/// and `data` (the `<PointData>`/`<CellData>` elements).
fn piece(n_points: usize, points: &str, types: &[u8], conn: &str, offsets: &str, data: &str) -> String {
    let types: Vec<String> = types.iter().map(|t| t.to_string()).collect();
    format!(
        "<Piece NumberOfPoints=\"{n_points}\" NumberOfCells=\"{}\">{data}\
         <Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">{points}</DataArray></Points>\
         <Cells><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">{conn}</DataArray>\
         <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">{offsets}</DataArray>\
         <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">{}</DataArray></Cells></Piece>",
        types.len(),
        types.join(" ")
    )
}

fn vtu_file(pieces: &[String]) -> String {
    format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\"><UnstructuredGrid>{}\
         </UnstructuredGrid></VTKFile>\n",
        pieces.concat()
    )
}

const TET: &str = "0 0 0 1 0 0 0 1 0 0 0 1";

/// A generated mesh (point field `f`, cell field `cellval`, vector `v` with --vector).
fn jets(dir: &Path) -> PathBuf {
    let mesh = dir.join("m.vtu");
    let (ok, _, err) = tetloc(&["gen", "jets", "--tets", "2000", "--vector", "-o", s(&mesh)]);
    assert!(ok, "{err}");
    mesh
}

/// A fresh folder `name` with a [`jets`] mesh and the points `csv` in `p.csv`: (folder, mesh,
/// points).
fn jets_and_csv(name: &str, csv: &str) -> (PathBuf, PathBuf, PathBuf) {
    let dir = tmp_dir(name);
    let mesh = jets(&dir);
    let pts = dir.join("p.csv");
    std::fs::write(&pts, csv).unwrap();
    (dir, mesh, pts)
}

/// Item 13: a field of [0, NaN, inf, -inf] is not "range 0 .. 0" alone: the non-finite values
/// are counted, in the text and in --json.
#[test]
fn info_counts_non_finite_values() {
    let dir = tmp_dir("nonfinite");
    let data =
        "<PointData><DataArray type=\"Float64\" Name=\"g\" format=\"ascii\">0 NaN inf -inf</DataArray></PointData>";
    let path = dir.join("nan.vtu");
    std::fs::write(&path, vtu_file(&[piece(4, TET, &[10], "0 1 2 3", "4", data)])).unwrap();
    let (ok, out, err) = tetloc(&["info", s(&path)]);
    assert!(ok, "{err}");
    assert!(out.contains("'g' per Vertex, range 0 .. 0; 3 non-finite values (1 NaN, 1 +inf, 1 -inf)"), "{out}");
    let (ok, out, err) = tetloc(&["info", "--json", s(&path)]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let g = &v["fields"][0];
    assert_eq!((g["n_nan"].as_u64(), g["n_inf"].as_u64(), g["n_neg_inf"].as_u64()), (Some(1), Some(1), Some(1)));
}

/// Item 14: an empty second `<Piece>` keeps the fields; pieces whose arrays differ are an
/// error naming the file; `probe s.vtu s.vtu` keeps the target's cell array beside the probed
/// point array of the same name (as vtkResampleWithDataSet does).
#[test]
fn fields_never_vanish() {
    let dir = tmp_dir("vanish");
    let data = "<PointData><DataArray type=\"Float64\" Name=\"g\" format=\"ascii\">0 1 2 3</DataArray></PointData>";
    let first = piece(4, TET, &[10], "0 1 2 3", "4", data);
    let path = dir.join("two.vtu");
    std::fs::write(&path, vtu_file(&[first.clone(), "<Piece NumberOfPoints=\"0\" NumberOfCells=\"0\"/>".into()]))
        .unwrap();
    let (ok, out, err) = tetloc(&["info", s(&path)]);
    assert!(ok && out.contains("field       'g'") && !out.contains("fields      none"), "{out}{err}");
    let other = piece(4, TET, &[10], "0 1 2 3", "4", "");
    std::fs::write(&path, vtu_file(&[first, other])).unwrap();
    let (ok, _, err) = tetloc(&["info", s(&path)]);
    assert!(!ok && err.contains(s(&path)) && err.contains("<Piece> 1 has the point arrays []"), "{err}");

    let mesh = jets(&dir);
    let out = dir.join("probed.vtu");
    let (ok, _, err) = tetloc_cpu(&["probe", s(&mesh), s(&mesh), "-o", s(&out)]);
    assert!(ok, "{err}");
    let grid = vtu::read_any(&out).unwrap();
    let has = |name: &str, at: FieldLocation| grid.fields.iter().any(|f| f.name == name && f.location == at);
    assert!(has("cellval", FieldLocation::Cell), "the target's own cell array is kept");
    assert!(has("cellval", FieldLocation::Vertex), "the probed one is point data");
}

/// Item 16: a probe target is any point set: a plane of triangles and a cloud of VTK_VERTEX
/// cells get values, their cells written back as they were.
#[test]
fn probe_targets_of_any_cells() {
    let dir = tmp_dir("targets");
    let mesh = jets(&dir);
    let plane = piece(4, "0.2 0.2 0.5 0.8 0.2 0.5 0.8 0.8 0.5 0.2 0.8 0.5", &[5, 5], "0 1 2 0 2 3", "3 6", "");
    let cloud = piece(3, "0.5 0.5 0.5 0.4 0.5 0.5 0.6 0.5 0.5", &[1, 1, 1], "0 1 2", "1 2 3", "");
    for (name, text) in [("plane", plane), ("cloud", cloud)] {
        let target = dir.join(format!("{name}.vtu"));
        std::fs::write(&target, vtu_file(&[text])).unwrap();
        let out = dir.join(format!("{name}.out.vtu"));
        let (ok, _, err) = tetloc_cpu(&["probe", s(&mesh), s(&target), "-o", s(&out)]);
        assert!(ok, "{name}: {err}");
        let (before, after) = (vu_read(&target), vu_read(&out));
        assert_eq!((after.types, after.ends, after.conn), (before.types, before.ends, before.conn), "{name}");
        let mask = after.fields.iter().find(|f| f.name == "vtkValidPointMask").unwrap();
        assert_eq!(mask.values.len(), before.points.len(), "{name}");
        assert!(mask.values.contains(&1.0), "{name}: points inside the mesh get values");
    }
    // The same as legacy .vtk targets, and one of every kind at once (a tet, a triangle, a
    // line and a vertex), its cell data kept: the cells written back as the file has them.
    let points = "0.2 0.2 0.5 0.8 0.2 0.5 0.8 0.8 0.5 0.2 0.8 0.5 0.5 0.5 0.7";
    let cases = [
        ("plane", 4, "3 0 1 2\n3 0 2 3", vec![5, 5]),
        ("cloud", 3, "1 0\n1 1\n1 2", vec![1, 1, 1]),
        ("mixed", 5, "4 0 1 2 4\n3 0 2 3\n2 1 3\n1 4", vec![10, 5, 3, 1]),
    ];
    for (name, n_points, cells, types) in cases {
        let n_values = cells.split_whitespace().count();
        let coords: Vec<&str> = points.split_whitespace().take(3 * n_points).collect();
        let types_text: Vec<String> = types.iter().map(|t| t.to_string()).collect();
        let ids: Vec<String> = (0..types.len()).map(|i| i.to_string()).collect();
        let text = format!(
            "# vtk DataFile Version 4.2\n{name}\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {n_points} float\n{}\n\
             CELLS {} {n_values}\n{cells}\nCELL_TYPES {}\n{}\nCELL_DATA {}\nSCALARS id float 1\n\
             LOOKUP_TABLE default\n{}\n",
            coords.join(" "),
            types.len(),
            types.len(),
            types_text.join("\n"),
            types.len(),
            ids.join(" ")
        );
        let target = dir.join(format!("{name}.vtk"));
        std::fs::write(&target, text).unwrap();
        let out = dir.join(format!("{name}.vtk.out.vtu"));
        let (ok, _, err) = tetloc_cpu(&["probe", s(&mesh), s(&target), "-o", s(&out)]);
        assert!(ok, "{name}.vtk: {err}");
        let before = tetloc_io::vtk::legacy::read_any(&target).unwrap();
        let after = vu_read(&out);
        assert_eq!(before.types, types, "{name}.vtk");
        assert_eq!((after.types, after.ends, after.conn), (before.types, before.ends, before.conn), "{name}.vtk");
        let id = after.fields.iter().find(|f| f.name == "id" && f.location == FieldLocation::Cell).unwrap();
        assert_eq!(id.values, (0..types.len()).map(|i| i as f32).collect::<Vec<_>>(), "{name}.vtk: cell data kept");
        let mask = after.fields.iter().find(|f| f.name == "vtkValidPointMask").unwrap();
        assert_eq!(mask.values.len(), n_points, "{name}.vtk");
        assert!(mask.values.contains(&1.0), "{name}.vtk: points inside the mesh get values");
    }
    // A Gmsh .msh target of a triangle, a line and a point, with no volume cell: its elements
    // written back as VTK cells with their element data; its points get the same values as
    // the same points of the .vtk above.
    let msh = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n1 0.2 0.2 0.5\n2 0.8 0.2 0.5\n\
               3 0.8 0.8 0.5\n4 0.2 0.8 0.5\n5 0.5 0.5 0.7\n$EndNodes\n$Elements\n3\n1 2 2 0 1 1 2 3\n\
               2 1 2 0 1 2 4\n3 15 2 0 1 5\n$EndElements\n$ElementData\n1\n\"id\"\n1\n0.0\n3\n0\n1\n3\n\
               1 10\n2 20\n3 30\n$EndElementData\n";
    let target = dir.join("surface.msh");
    std::fs::write(&target, msh).unwrap();
    let out = dir.join("surface.msh.out.vtu");
    let (ok, _, err) = tetloc_cpu(&["probe", s(&mesh), s(&target), "-o", s(&out)]);
    assert!(ok, "surface.msh: {err}");
    let after = vu_read(&out);
    assert_eq!(
        (after.types.clone(), after.ends.clone(), after.conn.clone()),
        (vec![5, 3, 1], vec![3, 5, 6], vec![0, 1, 2, 1, 3, 4])
    );
    let id = after.fields.iter().find(|f| f.name == "id" && f.location == FieldLocation::Cell).unwrap();
    assert_eq!(id.values, [10.0, 20.0, 30.0], "surface.msh: element data kept");
    // (The .vtk's points are f32 and the .msh's f64: the values agree to f32 rounding.)
    let same = vu_read(&dir.join("mixed.vtk.out.vtu"));
    let values = |g: &vtu::AnyGrid, name: &str| {
        g.fields.iter().find(|f| f.name == name && f.location == FieldLocation::Vertex).unwrap().values.clone()
    };
    for f in same.fields.iter().filter(|f| f.location == FieldLocation::Vertex) {
        let (got, want) = (values(&after, &f.name), values(&same, &f.name));
        let close =
            got.iter().zip(&want).all(|(a, b)| (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-6 * b.abs().max(1.0));
        assert!(close && got.len() == want.len(), "surface.msh: probed '{}': {got:?} against {want:?}", f.name);
    }
}

fn vu_read(path: &Path) -> vtu::AnyGrid {
    vtu::read_any(path).unwrap_or_else(|e| panic!("{e}"))
}

/// Item 17: a UTF-8 byte-order mark before a CSV of points is skipped.
#[test]
fn csv_points_with_a_byte_order_mark() {
    let (dir, mesh, csv) = jets_and_csv("bom", "\u{feff}x,y,z\n0.5,0.5,0.5\n0.4,0.5,0.5\n");
    let out = dir.join("ids.csv");
    let (ok, _, err) = tetloc_cpu(&["locate", s(&mesh), "--points", s(&csv), "--out", s(&out)]);
    assert!(ok, "{err}");
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 3);
}

/// Item 18: `v` is the whole vector and `v[1]` a component, in every command that can use
/// them; duplicate and reserved names are refused the same way for every output.
#[test]
fn one_rule_for_vector_names() {
    let (dir, mesh, pts) = jets_and_csv("names", "0.5,0.5,0.5\n0.4,0.5,0.5\n");
    let locate = |field: &str, out: &str| {
        tetloc_cpu(&["locate", s(&mesh), "--points", s(&pts), "--field", field, "--out", s(&dir.join(out))])
    };
    let (ok, _, err) = locate("v[1]", "a.csv");
    assert!(ok, "{err}");
    let (ok, _, err) = locate("v", "a.csv");
    assert!(!ok && err.contains("'v' is a vector of 3 components") && err.contains("'v[1]'"), "{err}");
    for out in ["m.csv", "m.vtp", "m.vtu"] {
        let (ok, _, err) = locate("vtkValidPointMask", out);
        assert!(!ok && err.contains("'vtkValidPointMask' has the name of a column"), "{out}: {err}");
    }
    let resample = |fields: &str, out: &str| {
        tetloc_cpu(&["resample", s(&mesh), "--dims", "4,4,4", "--field", fields, "-o", s(&dir.join(out))])
    };
    let (ok, _, err) = resample("f,f", "r.vti");
    assert!(!ok && err.contains("the field 'f' is named twice"), "{err}");
    for fields in ["v", "v[1]", "v,v[1],f"] {
        let (ok, _, err) = resample(fields, "r.vti");
        assert!(ok, "{fields}: {err}");
    }
    let (ok, _, err) = resample("v[2]", "r.npy");
    assert!(ok, "a component is one array: {err}");
    let (ok, _, err) = tetloc_cpu(&["probe", s(&mesh), s(&pts), "--field", "v[0],v", "-o", s(&dir.join("p.vtp"))]);
    assert!(ok, "{err}");
    let trace = |vector: &str| {
        tetloc_cpu(&[
            "trace",
            s(&mesh),
            "--seeds",
            "line:0.4,0.5,0.5,0.6,0.5,0.5,2",
            "--vector",
            vector,
            "--max-steps",
            "5",
            "-o",
            s(&dir.join("t.vtp")),
        ])
    };
    let (ok, _, err) = trace("v");
    assert!(ok, "{err}");
    let (ok, _, err) = trace("v[1]");
    assert!(!ok && err.contains("'v[1]' is one component of the vector 'v'"), "{err}");
}

/// Item 19: a bad CSV line is quoted short, raw bytes escaped; a step too small to move is
/// said to be so; probe's same-file error names SOURCE or TARGET.
#[test]
fn messages_are_short_and_say_what_is_wrong() {
    let long = format!("1,2,\x1b[31m{}\n", "9".repeat(4 << 20));
    let (dir, mesh, csv) = jets_and_csv("messages", &long);
    let out = dir.join("ids.npy");
    let (ok, _, err) = tetloc_cpu(&["locate", s(&mesh), "--points", s(&csv), "--out", s(&out)]);
    assert!(
        !ok && err.contains("line 1") && err.len() < 400 && !err.contains('\x1b'),
        "{}",
        &err[..err.len().min(600)]
    );
    let (ok, _, err) = tetloc_cpu(&[
        "trace",
        s(&mesh),
        "--seeds",
        "line:0.4,0.5,0.5,0.6,0.5,0.5,2",
        "--vector",
        "v",
        "--step",
        "1e-30",
        "-o",
        s(&dir.join("t.vtp")),
    ]);
    assert!(!ok && err.contains("too small") && !err.contains("outside"), "{err}");
    let (ok, _, err) = tetloc_cpu(&["probe", s(&mesh), s(&mesh), "-o", s(&mesh)]);
    assert!(!ok && err.contains("same file") && err.contains("SOURCE") && !err.contains("input input"), "{err}");
    let (ok, _, err) = tetloc(&["gen", "jets", "--tets", "18446744073709551616", "-o", s(&dir.join("g.vtu"))]);
    assert!(!ok && err.contains("'18446744073709551616'") && !err.contains("552000"), "{err}");
}

/// Item 20: a .pvtu naming pieces outside its folder is refused, naming the listing and the
/// way to allow it; `--allow-outside-pieces` reads it.
#[test]
fn pieces_outside_the_listing_need_a_flag() {
    let dir = tmp_dir("outside");
    let mesh = jets(&dir);
    let pvtu = dir.join("m.pvtu");
    let (ok, _, err) = tetloc(&["partition", s(&mesh), "--parts", "2", "-o", s(&pvtu)]);
    assert!(ok, "{err}");
    let sub = dir.join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    let listing = sub.join("up.pvtu");
    let text = std::fs::read_to_string(&pvtu).unwrap().replace("Source=\"m/", "Source=\"../m/");
    std::fs::write(&listing, text).unwrap();
    let (ok, _, err) = tetloc(&["info", s(&listing)]);
    assert!(
        !ok && err.contains(s(&listing)) && err.contains("outside") && err.contains("--allow-outside-pieces"),
        "{err}"
    );
    let (ok, out, err) = tetloc(&["info", s(&listing), "--allow-outside-pieces"]);
    assert!(ok && out.contains("tets"), "{err}");
}

/// A Gmsh file whose `$NodeData` views hold several steps is a time series: `info` lists the
/// steps, `--time-step K` samples step K, a step out of range is a clear error.
#[test]
fn gmsh_views_of_several_steps_are_time_steps() {
    let dir = tmp_dir("gmsh-steps");
    // One tet; the field is 1 + x at t = 0.5 and 10 + x at t = 2 (linear: sampled exactly).
    let view = |step: u32, time: f64, base: f64| {
        format!(
            "$NodeData\n1\n\"f\"\n1\n{time:?}\n3\n{step}\n1\n4\n1 {}\n2 {}\n3 {}\n4 {}\n$EndNodeData\n",
            base,
            base + 1.0,
            base,
            base
        )
    };
    let msh = format!(
        "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n\
         0 0 1\n$EndNodes\n$Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n{}{}",
        view(0, 0.5, 1.0),
        view(1, 2.0, 10.0)
    );
    let mesh = dir.join("steps.msh");
    std::fs::write(&mesh, msh).unwrap();
    let (ok, out, err) = tetloc(&["info", s(&mesh)]);
    assert!(ok && out.contains("steps       2 (0: 0.5, 1: 2)"), "{out}{err}");
    let pts = dir.join("p.csv");
    std::fs::write(&pts, "0.25,0.25,0.25\n").unwrap();
    for (step, want) in [("0", 1.25), ("1", 10.25)] {
        let out = dir.join(format!("v{step}.csv"));
        let args = ["locate", s(&mesh), "--points", s(&pts), "--field", "f", "--time-step", step, "--out", s(&out)];
        let (ok, _, err) = tetloc_cpu(&args);
        assert!(ok, "step {step}: {err}");
        let text = std::fs::read_to_string(&out).unwrap();
        let column = text.lines().next().unwrap().split(',').position(|c| c == "f").unwrap();
        let value: f64 = text.lines().nth(1).and_then(|l| l.split(',').nth(column)).unwrap().trim().parse().unwrap();
        assert_eq!(value, want, "step {step}: {text}");
    }
    let out = dir.join("v2.csv");
    let (ok, _, err) =
        tetloc_cpu(&["locate", s(&mesh), "--points", s(&pts), "--field", "f", "--time-step", "2", "--out", s(&out)]);
    assert!(!ok && err.contains("time step 2 is out of range") && err.contains("steps.msh has 2 steps"), "{err}");
}
