//! Cross-format identity: one mesh read from each of its encodings (VTU raw / zlib / base64,
//! VTK legacy 4.2 / 5.1, Gmsh 2.2 ASCII / 4.1 binary from gmsh and from meshio) gives the
//! same points, tets and fields. Every file here stores coordinates and both fields (`f` per
//! point, `cellval` per cell) as float64 and every one of these formats carries both fields,
//! so names must match and the f32 arrays must agree bit for bit — except against ASCII files
//! (`part_s.msh22.msh`), where gmsh printed 16 significant digits: a value that lies on an f32
//! rounding tie (`cellval` = k/2³² often does) may then round to the neighbouring f32, so
//! there one unit in the last place is allowed.

use super::read_raw;
use crate::test_support::require_data;
use tetloc_core::mesh::RawMesh;

/// Files whose numbers are decimal text.
const ASCII: &[&str] = &["part_s.msh22.msh"];

const GROUPS: [&[&str]; 3] = [
    &["part_s.vtu", "part_s.zlib.vtu", "part_s.v42.vtk", "part_s.msh22.msh", "part_s.meshio.msh"],
    &["torus_s.vtu", "torus_s.b64.vtu", "torus_s.msh"],
    &["delaunay_s.vtu", "delaunay_s.zlib.vtu", "delaunay_s.vtk", "delaunay_s.msh"],
];

/// The differences between two reads of one mesh, as readable lines (empty: identical).
/// Floats may differ by `ulps` units in the last place.
fn differences(a: &RawMesh, b: &RawMesh, ulps: i64) -> Vec<String> {
    let mut out = Vec::new();
    let first_diff =
        |x: &[u32], y: &[u32]| x.iter().zip(y).position(|(&p, &q)| (p as i32 as i64 - q as i32 as i64).abs() > ulps);
    let bits = |v: &[[f32; 3]]| v.iter().flatten().map(|c| c.to_bits()).collect::<Vec<_>>();
    if a.points.len() != b.points.len() {
        out.push(format!("{} vs {} points", a.points.len(), b.points.len()));
    } else if let Some(i) = first_diff(&bits(&a.points), &bits(&b.points)) {
        out.push(format!("point {}: {:?} vs {:?}", i / 3, a.points[i / 3], b.points[i / 3]));
    }
    if a.tets.len() != b.tets.len() {
        out.push(format!("{} vs {} tets", a.tets.len(), b.tets.len()));
    } else if let Some(i) = a.tets.iter().zip(&b.tets).position(|(p, q)| p != q) {
        out.push(format!("tet {i}: {:?} vs {:?}", a.tets[i], b.tets[i]));
    }
    if a.higher_order != b.higher_order {
        out.push(format!("higher_order {:?} vs {:?}", a.higher_order, b.higher_order));
    }
    let names = |m: &RawMesh| {
        let mut v: Vec<_> = m.fields.iter().map(|f| (f.name.clone(), f.location)).collect();
        v.sort_by(|x, y| x.0.cmp(&y.0));
        v
    };
    if names(a) != names(b) {
        out.push(format!("fields {:?} vs {:?}", names(a), names(b)));
    }
    for fa in &a.fields {
        let Some(fb) = b.fields.iter().find(|f| f.name == fa.name) else { continue };
        let (va, vb) = (
            fa.values.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            fb.values.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        );
        if va.len() != vb.len() {
            out.push(format!("field {}: {} vs {} values", fa.name, va.len(), vb.len()));
        } else if let Some(i) = first_diff(&va, &vb) {
            out.push(format!("field {}[{i}]: {} vs {}", fa.name, fa.values[i], fb.values[i]));
        }
    }
    out
}

#[test]
fn every_encoding_of_a_mesh_reads_the_same() {
    let Some(dir) = require_data("every_encoding_of_a_mesh_reads_the_same") else { return };
    let mut failures = Vec::new();
    for group in GROUPS {
        let read = |f: &str| read_raw(&dir.join(f), None).map_err(|e| format!("{f}: {e}"));
        let reference = match read(group[0]) {
            Ok(m) => m,
            Err(e) => {
                failures.push(e);
                continue;
            }
        };
        assert!(reference.fields.len() == 2 && !reference.tets.is_empty(), "{}: expected f and cellval", group[0]);
        for file in &group[1..] {
            match read(file) {
                Ok(m) => {
                    let ulps = if ASCII.contains(file) { 1 } else { 0 };
                    failures.extend(
                        differences(&reference, &m, ulps).into_iter().map(|d| format!("{} vs {file}: {d}", group[0])),
                    )
                }
                Err(e) => failures.push(e),
            }
        }
    }
    assert!(failures.is_empty(), "encodings disagree:\n{}", failures.join("\n"));
}

/// The comparison itself must see a difference in any array.
#[test]
fn differences_are_found() {
    use tetloc_core::mesh::{Field, FieldLocation};
    let a = RawMesh {
        points64: None,
        points: vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        tets: vec![[0, 1, 2, 3]],
        fields: vec![Field {
            values64: None,
            name: "f".into(),
            location: FieldLocation::Vertex,
            values: vec![f32::NAN, 1.0, 2.0, 3.0],
        }],
        higher_order: None,
        cells: None,
    };
    assert!(differences(&a, &a.clone(), 0).is_empty(), "NaN compares equal to itself by bits");
    let mut b = a.clone();
    b.points[2][1] = 1.0 + f32::EPSILON;
    assert_eq!(differences(&a, &b, 0).len(), 1);
    assert!(differences(&a, &b, 1).is_empty());
    b.points[2][1] = 1.0 + 2.0 * f32::EPSILON;
    assert_eq!(differences(&a, &b, 1).len(), 1);
    let mut b = a.clone();
    b.tets[0].swap(2, 3);
    assert_eq!(differences(&a, &b, 0).len(), 1);
    let mut b = a.clone();
    b.fields[0].values[3] = 3.5;
    assert_eq!(differences(&a, &b, 0).len(), 1);
    let mut b = a.clone();
    b.fields[0].name = "g".into();
    assert_eq!(differences(&a, &b, 0).len(), 1);
}

/// Small files of the text formats, one tet each (TetGen's as .node and .ele).
pub(crate) const LEGACY_ASCII: &str = "# vtk DataFile Version 4.2\ntitle\nASCII\nDATASET UNSTRUCTURED_GRID\n\
    POINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n\
    POINT_DATA 4\nSCALARS f float 1\nLOOKUP_TABLE default\n0 1 2 3\n";
pub(crate) const MSH_ASCII: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n\
    4 0 0 1\n$EndNodes\n$Elements\n1\n1 4 2 0 1 1 2 3 4\n$EndElements\n";
pub(crate) const TETGEN_NODE: &str = "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n";
pub(crate) const TETGEN_ELE: &str = "1 4 0\n1 1 2 3 4\n";

/// Issue 29 item 17: a UTF-8 byte-order mark before a text file (Excel's "CSV UTF-8",
/// Notepad) is skipped by every text reader: CSV points, .vtu, legacy .vtk, .msh, TetGen.
#[test]
fn a_byte_order_mark_is_skipped() {
    use crate::{gmsh, points, tetgen, vtk};
    use std::path::Path;
    let bom = |text: &[u8]| [super::UTF8_BOM, text].concat();
    let same = |a: &RawMesh, b: &RawMesh, what: &str| {
        let d = differences(a, b, 0);
        assert!(d.is_empty() && !a.tets.is_empty(), "{what}: {d:?}");
    };
    let p = |name: &str| Path::new(name).to_path_buf();
    let plain = vtk::legacy::parse(LEGACY_ASCII.as_bytes(), &p("a.vtk")).unwrap();
    same(&plain, &vtk::legacy::parse(&bom(LEGACY_ASCII.as_bytes()), &p("a.vtk")).unwrap(), "vtk");
    let plain = gmsh::parse(MSH_ASCII.as_bytes(), &p("a.msh")).unwrap();
    same(&plain, &gmsh::parse(&bom(MSH_ASCII.as_bytes()), &p("a.msh")).unwrap(), "msh");
    let (node, ele) = (TETGEN_NODE.as_bytes(), TETGEN_ELE.as_bytes());
    let plain = tetgen::parse(node, ele, &p("a.node")).unwrap();
    same(&plain, &tetgen::parse(&bom(node), &bom(ele), &p("a.node")).unwrap(), "tetgen");
    // A .vtu with appended raw data: offsets count from the `_` marker, not the file's start.
    let dir = std::env::temp_dir().join(format!("tetloc-bom-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let vtu = dir.join("m.vtu");
    let mesh = crate::test_support::KuhnGrid::new(2).mesh("cube");
    vtk::write::write_mesh_vtu(&vtu, &mesh, false).unwrap();
    let bytes = std::fs::read(&vtu).unwrap();
    let plain = vtk::vtu::parse(&bytes, &vtu).unwrap();
    same(&plain, &vtk::vtu::parse(&bom(&bytes), &vtu).unwrap(), "vtu");
    assert_eq!(vtk::vtu::parse_any(&bom(&bytes), &vtu).unwrap().points.len(), mesh.points.len());
    // CSV points, with and without a header.
    for text in ["x,y,z\n1,2,3\n4,5,6\n", "1,2,3\n4,5,6\n"] {
        let csv = dir.join("p.csv");
        std::fs::write(&csv, bom(text.as_bytes())).unwrap();
        assert_eq!(points::read_points64(&csv).unwrap(), [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]], "{text:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
