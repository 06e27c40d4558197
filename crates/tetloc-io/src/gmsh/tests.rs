//! The reader over a small mesh written in every encoding by a test-only writer, over bad,
//! truncated and corrupted files, and over the shared data files.

use super::*;
use crate::test_support::require_data;
use rand::{Rng, SeedableRng};
use std::path::PathBuf;
use tetloc_core::mesh::{Field, Mesh};

// -----------------------------------------------------------------------------------------
// A small mesh written in every encoding by a test-only writer

/// (name, step, components, [(entity tag, values)]), as in $NodeData / $ElementData
type View = (&'static str, i64, usize, Vec<(u64, Vec<f64>)>);

#[derive(Clone)]
struct Spec {
    nodes: Vec<(u64, [f64; 3])>,
    /// (tag, gmsh type, node tags)
    elems: Vec<(u64, i32, Vec<u64>)>,
    node_data: Vec<View>,
    elem_data: Vec<View>,
}

fn spec() -> Spec {
    // Sparse, unordered node tags; a point and a triangle among the tets.
    let nodes = vec![
        (10, [0.0, 0.0, 0.0]),
        (3, [1.0, 0.0, 0.0]),
        (7, [0.0, 1.0, 0.0]),
        (100, [0.0, 0.0, 1.0]),
        (5000, [1.0, 1.0, 1.0]),
    ];
    let elems =
        vec![(5, 15, vec![10]), (9, 4, vec![10, 3, 7, 100]), (1, 2, vec![3, 7, 100]), (2, 4, vec![3, 7, 100, 5000])];
    let node_data = vec![
        ("temp", 0, 1, nodes.iter().map(|&(t, p)| (t, vec![p[0] + 2.0 * p[1]])).collect()),
        // A later step that covers only two nodes: the mesh holds step 0; in the series' step
        // 1 the others are NaN.
        ("temp", 1, 1, vec![(7, vec![-1.5]), (3, vec![2.5])]),
        ("vel", 0, 3, nodes.iter().map(|&(t, p)| (t, vec![p[0], p[1], t as f64])).collect()),
    ];
    // The triangle's value is dropped.
    let elem_data = vec![("mat", 0, 1, vec![(1, vec![7.0]), (2, vec![20.0]), (9, vec![90.0])])];
    Spec { nodes, elems, node_data, elem_data }
}

fn expected() -> RawMesh {
    let field = |name: &str, location, values: Vec<f32>| Field::new(name, location, values);
    crate::test_support::two_tets(vec![
        field("temp", FieldLocation::Vertex, vec![0.0, 1.0, 2.0, 0.0, 3.0]),
        field("vel[0]", FieldLocation::Vertex, vec![0.0, 1.0, 0.0, 0.0, 1.0]),
        field("vel[1]", FieldLocation::Vertex, vec![0.0, 0.0, 1.0, 0.0, 1.0]),
        field("vel[2]", FieldLocation::Vertex, vec![10.0, 3.0, 7.0, 100.0, 5000.0]),
        field("mat", FieldLocation::Cell, vec![90.0, 20.0]),
    ])
}

/// Bit-exact comparison (NaN equals NaN).
fn assert_same(got: &RawMesh, want: &RawMesh, what: &str) {
    assert_eq!(got.points, want.points, "{what}: points");
    assert_eq!(got.tets, want.tets, "{what}: tets");
    assert_eq!(got.higher_order, want.higher_order, "{what}: higher_order");
    let names = |m: &RawMesh| m.fields.iter().map(|f| (f.name.clone(), f.location)).collect::<Vec<_>>();
    assert_eq!(names(got), names(want), "{what}: fields");
    for (g, w) in got.fields.iter().zip(&want.fields) {
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&g.values), bits(&w.values), "{what}: field {}", g.name);
    }
}

#[derive(Clone, Copy, Debug)]
struct Enc {
    v41: bool,
    binary: bool,
    big: bool,
}

const ENCODINGS: [Enc; 6] = [
    Enc { v41: false, binary: false, big: false },
    Enc { v41: false, binary: true, big: false },
    Enc { v41: false, binary: true, big: true },
    Enc { v41: true, binary: false, big: false },
    Enc { v41: true, binary: true, big: false },
    Enc { v41: true, binary: true, big: true },
];

struct W {
    out: Vec<u8>,
    e: Enc,
}

impl W {
    fn s(&mut self, s: &str) {
        self.out.extend_from_slice(s.as_bytes());
    }
    fn int(&mut self, v: i64) {
        match (self.e.binary, self.e.big) {
            (false, _) => self.s(&format!("{v} ")),
            (true, false) => self.out.extend((v as i32).to_le_bytes()),
            (true, true) => self.out.extend((v as i32).to_be_bytes()),
        }
    }
    fn size(&mut self, v: u64) {
        match (self.e.binary, self.e.big) {
            (false, _) => self.s(&format!("{v} ")),
            (true, false) => self.out.extend(v.to_le_bytes()),
            (true, true) => self.out.extend(v.to_be_bytes()),
        }
    }
    fn f(&mut self, v: f64) {
        match (self.e.binary, self.e.big) {
            (false, _) => self.s(&format!("{v:?} ")),
            (true, false) => self.out.extend(v.to_le_bytes()),
            (true, true) => self.out.extend(v.to_be_bytes()),
        }
    }
    fn nl(&mut self) {
        if !self.e.binary {
            self.s("\n");
        }
    }
}

fn dim_of(ty: i32) -> i64 {
    match ty {
        15 => 0,
        1 => 1,
        2 | 3 => 2,
        _ => 3,
    }
}

fn write(spec: &Spec, e: Enc) -> Vec<u8> {
    let mut w = W { out: Vec::new(), e };
    w.s(&format!("$MeshFormat\n{} {} 8\n", if e.v41 { "4.1" } else { "2.2" }, e.binary as u8));
    if e.binary {
        w.int(1);
        w.s("\n");
    }
    w.s("$EndMeshFormat\n$PhysicalNames\n1\n3 1 \"$Nodes and $EndNodes\"\n$EndPhysicalNames\n");
    if e.v41 {
        // Skipped unread: binary bytes, including '$', must not confuse the parser.
        w.s("$Entities\n");
        w.out.extend_from_slice(b"\x00$\x01\x02$Nodes\n\xff\n");
        w.s("\n$EndEntities\n");
    }
    w.s("$Nodes\n");
    let n = spec.nodes.len();
    if e.v41 {
        // Two blocks; the second is parametric on a surface (u, v follow x y z).
        let (a, b) = spec.nodes.split_at(2);
        w.size(2);
        w.size(n as u64);
        w.size(spec.nodes.iter().map(|x| x.0).min().unwrap());
        w.size(spec.nodes.iter().map(|x| x.0).max().unwrap());
        w.nl();
        for (block, param) in [(a, 0), (b, 2)] {
            w.int(if param > 0 { 2 } else { 3 });
            w.int(1);
            w.int((param > 0) as i64);
            w.size(block.len() as u64);
            w.nl();
            for &(t, _) in block {
                w.size(t);
                w.nl();
            }
            for &(_, p) in block {
                p.iter().for_each(|&c| w.f(c));
                (0..param).for_each(|k| w.f(0.25 * k as f64));
                w.nl();
            }
        }
    } else {
        w.s(&format!("{n}\n"));
        for &(t, p) in &spec.nodes {
            w.int(t as i64);
            p.iter().for_each(|&c| w.f(c));
            w.nl();
        }
    }
    w.s("\n$EndNodes\n$Elements\n");
    // Runs of one type: blocks in 4.1 and in binary 2.2.
    let mut runs: Vec<&[(u64, i32, Vec<u64>)]> = Vec::new();
    let mut rest = &spec.elems[..];
    while let Some(first) = rest.first() {
        let len = rest.iter().take_while(|x| x.1 == first.1).count();
        runs.push(&rest[..len]);
        rest = &rest[len..];
    }
    if e.v41 {
        w.size(runs.len() as u64);
        w.size(spec.elems.len() as u64);
        w.size(1);
        w.size(9);
        w.nl();
        for run in runs {
            w.int(dim_of(run[0].1));
            w.int(1);
            w.int(run[0].1 as i64);
            w.size(run.len() as u64);
            w.nl();
            for (t, _, nodes) in run {
                w.size(*t);
                nodes.iter().for_each(|&x| w.size(x));
                w.nl();
            }
        }
    } else {
        w.s(&format!("{}\n", spec.elems.len()));
        for run in runs {
            if e.binary {
                w.int(run[0].1 as i64);
                w.int(run.len() as i64);
                w.int(2);
            }
            for (t, ty, nodes) in run {
                w.int(*t as i64);
                if !e.binary {
                    w.int(*ty as i64);
                    w.int(2);
                }
                w.int(1); // physical tag
                w.int(1); // elementary tag
                nodes.iter().for_each(|&x| w.int(x as i64));
                w.nl();
            }
        }
    }
    w.s("\n$EndElements\n");
    for (section, data) in [("NodeData", &spec.node_data), ("ElementData", &spec.elem_data)] {
        for (name, step, ncomp, rows) in data {
            let time = 0.5 + 0.25 * *step as f64;
            w.s(&format!(
                "${section}\n2\n\"{name}\"\n\"scheme\"\n1\n{time:?}\n4\n{step}\n{ncomp}\n{}\n0\n",
                rows.len()
            ));
            for (t, vals) in rows {
                w.int(*t as i64);
                vals.iter().for_each(|&v| w.f(v));
                w.nl();
            }
            w.s(&format!("\n$End{section}\n"));
        }
    }
    w.out
}

fn p() -> PathBuf {
    PathBuf::from("test.msh")
}

#[test]
fn every_encoding_gives_the_same_mesh() {
    let want = expected();
    for e in ENCODINGS {
        let bytes = write(&spec(), e);
        // Sequential, and parallel on even the shortest runs of ASCII records.
        for min_parallel in [usize::MAX, 1] {
            let got = parse_with(&bytes, &p(), min_parallel).unwrap_or_else(|err| panic!("{e:?}: {err}"));
            assert_same(&got, &want, &format!("{e:?}, min_parallel {min_parallel}"));
        }
    }
}

/// $NodeData and $ElementData values that f32 cannot hold come back exactly (the fields keep
/// the file's f64 values) in Gmsh 2.2 and 4.1, ASCII and binary; values f32 holds exactly get
/// no f64 copy.
#[test]
fn f64_values_read_back_exactly() {
    let mut spec = spec();
    let near_zero = |t: u64| 1e-9 + t as f64 * 1e-12 + 1e-17;
    spec.node_data.push(("tiny", 0, 1, spec.nodes.iter().map(|&(t, _)| (t, vec![near_zero(t)])).collect()));
    spec.elem_data.push(("third", 0, 2, vec![(9, vec![1.0 / 3.0, 0.1]), (2, vec![2.0 / 3.0, 0.2])]));
    let tiny = [10u64, 3, 7, 100, 5000].map(near_zero);
    for e in ENCODINGS {
        let got = parse(&write(&spec, e), &p()).unwrap_or_else(|err| panic!("{e:?}: {err}"));
        let field = |name: &str| got.fields.iter().find(|f| f.name == name).unwrap_or_else(|| panic!("{e:?}: {name}"));
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(field("tiny").values64.as_deref().map(bits), Some(bits(&tiny)), "{e:?}");
        assert_eq!(field("third[0]").values64.as_deref().map(bits), Some(bits(&[1.0 / 3.0, 2.0 / 3.0])), "{e:?}");
        assert_eq!(field("third[1]").values64.as_deref().map(bits), Some(bits(&[0.1, 0.2])), "{e:?}");
        assert!(field("mat").values64.is_none() && field("vel[2]").values64.is_none(), "{e:?}");
    }
}

/// The error for a bad file: the same whether ASCII runs are tried in parallel or not.
fn err_of(bytes: &[u8]) -> String {
    let msgs = [1, usize::MAX].map(|min_parallel| match parse_with(bytes, &p(), min_parallel) {
        Ok(_) => panic!("parsed a bad file:\n{}", String::from_utf8_lossy(bytes)),
        Err(e) => e.to_string(),
    });
    assert_eq!(msgs[0], msgs[1]);
    msgs[1].clone()
}

/// A tetra10 keeps all its nodes, reordered from Gmsh's edge order (0,1) (1,2) (2,0) (0,3)
/// (2,3) (1,3) to VTK's (… (1,3) (2,3)), in every encoding.
#[test]
fn higher_order_tets_keep_their_nodes() {
    let mut s = spec();
    // Midpoints of the first tet's edges (corners 10, 3, 7, 100), in Gmsh's order.
    let mids = [[0.5, 0.0, 0.0], [0.5, 0.5, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.5], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]];
    s.nodes.extend(mids.iter().enumerate().map(|(i, &x)| (200 + i as u64, x)));
    s.elems[1] = (9, 11, vec![10, 3, 7, 100, 200, 201, 202, 203, 204, 205]);
    s.elems.pop(); // the linear tet: one order per mesh
    s.node_data.clear();
    s.elem_data.clear();
    for (e, min_parallel) in ENCODINGS.iter().flat_map(|&e| [(e, 1), (e, usize::MAX)]) {
        let m = parse_with(&write(&s, e), &p(), min_parallel).unwrap();
        assert_eq!(m.tets, vec![[0, 1, 2, 3]], "{e:?}");
        assert_eq!(m.higher_order, Some(2), "{e:?}");
        assert_eq!(m.points.len(), 11);
        let cells = m.cells.as_ref().unwrap();
        assert_eq!(cells.nodes(0), &[0, 1, 2, 3, 5, 6, 7, 8, 10, 9], "{e:?}");
        assert_eq!(cells.types[0].def().name(), "quadratic tetra");
    }
    // With the linear tet too: tets of two orders are refused by the mesh, naming both.
    let mut s2 = spec();
    s2.nodes.extend(mids.iter().enumerate().map(|(i, &x)| (200 + i as u64, x)));
    s2.elems[1] = (9, 11, vec![10, 3, 7, 100, 200, 201, 202, 203, 204, 205]);
    s2.elem_data.clear();
    let raw = parse_with(&write(&s2, ENCODINGS[0]), &p(), 1).unwrap();
    let err = Mesh::new(raw, "test.msh").unwrap_err().to_string();
    assert!(err.contains("test.msh") && err.contains("quadratic tetra") && err.contains("one kind of tet"), "{err}");
}

/// Incomplete (serendipity) tets have no shape functions in tetloc: a clear error.
#[test]
fn incomplete_tets_are_refused() {
    let mut s = spec();
    s.nodes.extend((0..12).map(|i| (300 + i, [0.1 * i as f64, 0.2, 0.3])));
    s.elems[1] = (9, 137, [10, 3, 7, 100].into_iter().chain(300..312).collect());
    s.elems.pop();
    s.node_data.clear();
    s.elem_data.clear();
    let err = err_of(&write(&s, ENCODINGS[0]));
    assert!(err.contains("16 nodes") && err.contains("incomplete"), "{err}");
}

/// Hexahedra and prisms are cells (in file order among the tets, node order mapped to VTK's);
/// volume elements tetloc does not read (a trihedron) are refused, counted by type.
#[test]
fn other_volume_elements_are_read_or_counted() {
    let mut s = spec();
    s.nodes.extend((0..4).map(|i| (300 + i, [2.0, i as f64, 0.0])));
    let hex: Vec<u64> = vec![10, 3, 7, 100, 300, 301, 302, 303];
    s.elems.push((20, 5, hex.clone()));
    s.elems.push((21, 5, hex));
    s.elems.push((22, 6, vec![10, 3, 7, 300, 301, 302]));
    for (e, min_parallel) in ENCODINGS.iter().flat_map(|&e| [(e, 1), (e, usize::MAX)]) {
        let m = parse_with(&write(&s, e), &p(), min_parallel).unwrap_or_else(|err| panic!("{e:?}: {err}"));
        let cells = m.cells.as_ref().expect("a cell block");
        let names: Vec<&str> = cells.types.iter().map(|t| t.def().name()).collect();
        assert_eq!(names, ["tetra", "tetra", "hexahedron", "hexahedron", "wedge"], "{e:?}");
        assert!(m.tets.is_empty(), "{e:?}");
        assert_eq!(cells.nodes(4), &[0, 1, 2, 5, 6, 7], "{e:?}");
        let mut bad = s.clone();
        bad.elems.push((23, 140, vec![10, 3, 7, 300]));
        match parse_with(&write(&bad, e), &p(), min_parallel) {
            Err(Error::NonTetCells { path, counts }) => {
                assert_eq!(path, p());
                assert_eq!(counts, vec![("trihedron (4 nodes)".to_string(), 1)]);
            }
            other => panic!("{e:?}: {other:?}"),
        }
    }
}

#[test]
fn bad_files_give_clear_errors() {
    let ascii = |v41| String::from_utf8_lossy(&write(&spec(), Enc { v41, binary: false, big: false })).into_owned();
    let cases: Vec<(String, &str)> = vec![
        (ascii(false).replace("2.2 0 8", "4.0 0 8"), "version 4.0 is not supported"),
        (ascii(false).replace("2.2 0 8", "2.2 0 4"), "data size 4"),
        (ascii(false).replace("$MeshFormat", "$Mesh"), "does not start with $MeshFormat"),
        // Element 9 refers to a node that does not exist (line 15).
        (ascii(false).replace("9 4 2 1 1 10 3", "9 4 2 1 1 11 3"), "line 20: element 9 refers to node 11"),
        (ascii(false).replace("9 4 2 1 1", "9 999 2 1 1"), "line 20: element type 999"),
        (ascii(false).replace("\n100 0.0 0.0 1.0", "\n7 0.0 0.0 1.0"), "line 8: node tag 7 appears twice"),
        (ascii(false).replace("5000 1.0 1.0 1.0", "5000 1.0 1.0 x"), "line 14: expected z (a number), found 'x'"),
        (ascii(false).replace("$Nodes\n5\n", "$Nodes\n4\n"), "expected $EndNodes"),
        (ascii(false).replace("$Nodes\n5\n", "$Nodes\n500000\n"), "declares 500000 nodes"),
        (ascii(true).replace("\n2 5 3 5000", "\n2 6 3 5000"), "line 13: $Nodes declares 6 nodes but its blocks hold 5"),
        (
            ascii(false).replace("\"vel\"\n\"scheme\"\n1\n0.5\n4\n0\n3", "\"vel\"\n\"scheme\"\n1\n0.5\n4\n0\n4"),
            "expected an entity tag (an integer), found '1.0'",
        ),
        (ascii(false).replace("0\n3\n5\n0\n10 ", "0\n3\n5\n0\n11 "), "gives a value for node 11"),
        (ascii(false).replace("$Elements", "$Elementz"), "no $EndElementz"),
        (ascii(false)[..ascii(false).find("$Elements").unwrap()].to_string(), "no $Elements section"),
    ];
    for (text, want) in cases {
        let msg = err_of(text.as_bytes());
        assert!(msg.starts_with("test.msh: "), "{msg}");
        assert!(msg.contains(want), "expected '{want}' in: {msg}");
    }
    // A surface mesh: no tetrahedra.
    let mut s = spec();
    s.elems.retain(|e| e.1 != 4);
    s.elem_data.clear();
    let msg = err_of(&write(&s, ENCODINGS[0]));
    assert!(msg.contains("no volume cells"), "{msg}");
    // The same for the parallel decoding of binary tets.
    let mut s = spec();
    s.elems[3].2[2] = 11;
    s.elem_data.clear();
    for e in ENCODINGS {
        let msg = err_of(&write(&s, e));
        assert!(msg.contains("element 2 refers to node 11, which is not in $Nodes"), "{e:?}: {msg}");
    }
    // A binary file whose endianness marker is not 1.
    let mut bin = write(&spec(), ENCODINGS[4]);
    let at = bin.windows(4).position(|w| w == 1i32.to_le_bytes()).unwrap();
    bin[at] = 7;
    assert!(err_of(&bin).contains("endianness marker"));
}

/// Issue 29 item 19: a type that is not the element's (99, a 32-node hexahedron, over a tet)
/// is named as such, not called a truncated file; and `$ElementData` for an element tag that
/// `$Elements` does not have is refused as `$NodeData` for a missing node is.
#[test]
fn wrong_element_types_and_unknown_element_tags() {
    for e in ENCODINGS.into_iter().filter(|e| !e.binary) {
        let mut s = spec();
        s.elems[1].1 = 99;
        s.elem_data.clear();
        let msg = err_of(&write(&s, e));
        assert!(msg.contains("element type 99 is a hexahedron of 32 nodes"), "{e:?}: {msg}");
        assert!(!msg.contains("truncated"), "{e:?}: {msg}");
    }
    for e in ENCODINGS {
        let mut s = spec();
        s.elem_data[0].3.push((77, vec![1.0]));
        let msg = err_of(&write(&s, e));
        assert!(
            msg.contains("$ElementData 'mat' gives a value for element 77, which is not in $Elements"),
            "{e:?}: {msg}"
        );
        // The triangle's value (element 1) is still dropped without complaint.
        assert!(parse(&write(&spec(), e), &p()).is_ok(), "{e:?}");
    }
}

/// A view giving one node (or element) two different values, within a section or across
/// sections of one step, is an error naming the view and the entity; the same value again (a
/// node shared by two partitions' sections) is fine.
#[test]
fn one_entity_given_two_values_is_refused() {
    for e in ENCODINGS {
        let mut s = spec();
        s.node_data[0].3.push((7, vec![2.0])); // node 7's value again: fine
        s.node_data.push(("temp", 0, 1, vec![(3, vec![1.0])])); // another section, same value
        assert!(parse(&write(&s, e), &p()).is_ok(), "{e:?}");
        let mut within = spec();
        within.node_data[0].3.push((7, vec![1000.0]));
        let mut across = spec();
        across.node_data.push(("temp", 0, 1, vec![(3, vec![-500.0])]));
        let mut cells = spec();
        cells.elem_data[0].3.push((9, vec![91.0]));
        for (s, want) in [
            (within, "$NodeData 'temp' step 0 gives node 7 two values: [2.0] and [1000.0]"),
            (across, "$NodeData 'temp' step 0 gives node 3 two values: [1.0] and [-500.0]"),
            (cells, "$ElementData 'mat' step 0 gives element 9 two values: [90.0] and [91.0]"),
        ] {
            let msg = err_of(&write(&s, e));
            assert!(msg.starts_with("test.msh") && msg.contains(want), "{e:?}: {msg}");
        }
    }
}

/// `$ElementNodeData` is refused, naming the view, not skipped silently.
#[test]
fn element_node_data_is_refused() {
    for e in ENCODINGS.into_iter().filter(|e| !e.binary) {
        let mut bytes = write(&spec(), e);
        bytes.extend(b"$ElementNodeData\n1\n\"grad\"\n1\n0.0\n3\n0\n1\n1\n9 4 1 2 3 4\n$EndElementNodeData\n");
        let msg = err_of(&bytes);
        assert!(msg.starts_with("test.msh") && msg.contains("$ElementNodeData view 'grad'"), "{e:?}: {msg}");
        assert!(msg.contains("not supported"), "{msg}");
    }
}

/// Ok only where the cut falls right after a section's `$End...` line (a shorter but whole
/// file); everything else is an error, never a panic.
fn check_truncations(bytes: &[u8], lengths: impl Iterator<Item = usize>, what: &str) {
    for len in lengths {
        let cut = &bytes[..len];
        if let Ok(m) = parse(cut, &p()) {
            let last = cut.split(|&b| b == b'\n').rev().map(<[u8]>::trim_ascii).find(|l| !l.is_empty()).unwrap_or(b"");
            assert!(last.starts_with(b"$End"), "{what}: cut at {len} parsed ({} tets)", m.tets.len());
        }
    }
}

#[test]
fn truncated_files_are_errors() {
    for e in ENCODINGS {
        let bytes = write(&spec(), e);
        check_truncations(&bytes, 0..bytes.len(), &format!("{e:?}"));
    }
    let Some(dir) = require_data("truncated_files_are_errors") else { return };
    for f in ["torus_s.msh", "part_s.msh22.msh", "part_s.meshio.msh", "real/cubes_v41.msh", "real/P3.msh"] {
        let bytes = std::fs::read(dir.join(f)).unwrap();
        let step = bytes.len() / 47;
        check_truncations(&bytes, (0..bytes.len()).step_by(step).chain(bytes.len() - 40..bytes.len()), f);
    }
}

#[test]
fn corrupted_files_do_not_panic() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let corrupt = |bytes: &[u8], rng: &mut rand_pcg::Pcg64| {
        let mut b = bytes.to_vec();
        for _ in 0..rng.gen_range(1..6) {
            let i = rng.gen_range(0..b.len());
            b[i] = match rng.gen_range(0..4) {
                0 => rng.gen(),
                1 => b"0123456789"[rng.gen_range(0..10)],
                2 => 0xff,
                _ => b' ',
            };
        }
        // Whatever the outcome, it must come back, the same from the sequential and the
        // parallel parser; a mesh that comes back must validate or fail cleanly.
        match (parse_with(&b, &p(), usize::MAX), parse_with(&b, &p(), 1)) {
            (Ok(seq), Ok(par)) => {
                assert_same(&par, &seq, "corrupt file");
                let _ = Mesh::new(seq, "corrupt");
            }
            (Err(seq), Err(par)) => assert_eq!(seq.to_string(), par.to_string()),
            (seq, par) => panic!("sequential {seq:?}\nparallel {par:?}"),
        }
    };
    for e in ENCODINGS {
        let bytes = write(&spec(), e);
        for _ in 0..1500 {
            corrupt(&bytes, &mut rng);
        }
    }
    let Some(dir) = require_data("corrupted_files_do_not_panic") else { return };
    for f in ["torus_s.msh", "real/bunny.msh", "part_s.msh22.msh"] {
        let bytes = std::fs::read(dir.join(f)).unwrap();
        for _ in 0..30 {
            corrupt(&bytes, &mut rng);
        }
    }
}

// -----------------------------------------------------------------------------------------
// The shared data files

fn mesh_json(dir: &Path, name: &str) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join(format!("{name}.mesh.json"))).unwrap()).unwrap()
}

/// The generators' fields: point field `f` and cell field `cellval` (data README).
fn check_generated_fields(m: &RawMesh, f: &str) {
    let field = |name: &str, loc| {
        let x = m.fields.iter().find(|x| x.name == name).unwrap_or_else(|| panic!("{f}: no field {name}"));
        assert_eq!(x.location, loc, "{f}: {name}");
        x
    };
    for (p, &v) in m.points.iter().zip(&field("f", FieldLocation::Vertex).values) {
        let [x, y, z] = p.map(|c| c as f64);
        let want = (3.0 * x + 1.0).sin() * (2.0 * y).cos() + 0.5 * (4.0 * z).sin() + 0.3 * x * y;
        assert!((v as f64 - want).abs() < 2e-5, "{f}: f at {p:?} is {v}, expected {want}");
    }
    for (id, &v) in field("cellval", FieldLocation::Cell).values.iter().enumerate() {
        let want = ((id as u64 * 2654435761) % (1 << 32)) as f64 / (1u64 << 32) as f64;
        assert!((v as f64 - want).abs() < 1e-7, "{f}: cellval[{id}] is {v}, expected {want}");
    }
}

#[test]
fn every_shared_msh_file_reads() {
    let Some(dir) = require_data("every_shared_msh_file_reads") else { return };
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let file = path.file_name().unwrap().to_string_lossy().to_string();
        if !file.ends_with(".msh") {
            continue;
        }
        let name = file.split('.').next().unwrap();
        let meta = mesh_json(&dir, name);
        assert!(meta["files"].get(&file).is_some(), "{file} is not in {name}.mesh.json");
        let m = read(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.points.len() as u64, meta["n_points"].as_u64().unwrap(), "{file}");
        assert_eq!(m.tets.len() as u64, meta["n_tets"].as_u64().unwrap(), "{file}");
        assert_eq!(m.higher_order, None);
        check_generated_fields(&m, &file);
        // Corners in the file's order: the inverted tets are those the generator counted.
        let mesh = Mesh::new(m, file.clone()).unwrap();
        assert_eq!(mesh.info.n_reoriented as u64, meta["n_negative_volume"].as_u64().unwrap(), "{file}");
        seen += 1;
    }
    assert_eq!(seen, 4, "generated .msh files");

    // Real files: counts from the data README. cubes_v22.msh and cubes_v41.msh hold the
    // same 32,981 tets in three volumes (three element blocks in 4.1, of which the last
    // has 11,970), whatever the README says about them differing.
    let real = [
        ("bunny.msh", 19_379, None),
        ("cubes_v22.msh", 32_981, None),
        ("cubes_v41.msh", 32_981, None),
        ("ArmadilloP4.msh", 4_680, Some(4)),
        ("P3.msh", 6_414, Some(3)),
    ];
    for (file, tets, order) in real {
        let m = read(&dir.join("real").join(file)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.tets.len(), tets, "{file}");
        assert_eq!(m.higher_order, order, "{file}");
        assert!(m.fields.is_empty(), "{file}");
        Mesh::new(m, file).unwrap();
    }
    let v22 = read(&dir.join("real/cubes_v22.msh")).unwrap();
    let v41 = read(&dir.join("real/cubes_v41.msh")).unwrap();
    assert_eq!(v22.points.len(), v41.points.len());
}

/// Long runs of ASCII records parse in parallel, to the same arrays; a file that does not
/// keep one record per line falls back to the sequential parser.
#[test]
fn parallel_ascii_parsing_agrees() {
    let Some(dir) = require_data("parallel_ascii_parsing_agrees") else { return };
    for f in ["part_s.msh22.msh", "real/bunny.msh", "real/cubes_v22.msh", "real/cubes_v41.msh"] {
        let bytes = std::fs::read(dir.join(f)).unwrap();
        let seq = parse_with(&bytes, &p(), usize::MAX).unwrap();
        assert_same(&parse_with(&bytes, &p(), 1).unwrap(), &seq, f);
        assert_same(&parse(&bytes, &p()).unwrap(), &seq, f);
    }
    // Each element of part_s.msh22.msh spread over two lines: still valid Gmsh.
    let text = std::fs::read_to_string(dir.join("part_s.msh22.msh")).unwrap();
    let (head, rest) = text.split_once("$Elements\n").unwrap();
    let (elems, tail) = rest.split_once("$EndElements").unwrap();
    let split: String = elems
        .lines()
        .map(|l| match l.split_once(' ') {
            Some((tag, more)) => format!("{tag}\n  {more}\n"),
            None => format!("{l}\n"),
        })
        .collect();
    let odd = format!("{head}$Elements\n{split}$EndElements{tail}");
    let want = parse_with(text.as_bytes(), &p(), usize::MAX).unwrap();
    assert_same(&parse_with(odd.as_bytes(), &p(), 1).unwrap(), &want, "split lines");
}

/// The `centers` query sets hold each tet's centroid in file order: our tets must sit
/// around them, which checks node mapping and cell order against the files' other readers.
#[test]
fn tets_are_in_oracle_order() {
    let Some(dir) = require_data("tets_are_in_oracle_order") else { return };
    for file in ["torus_s.msh", "part_s.msh22.msh", "part_s.meshio.msh", "delaunay_s.msh", "real/bunny.msh"] {
        let path = dir.join(file);
        let name = path.file_name().unwrap().to_string_lossy().split('.').next().unwrap().to_string();
        let centers = path.with_file_name(format!("{name}.centers.points.bin"));
        let c: Vec<f32> = bytemuck::pod_collect_to_vec(&std::fs::read(&centers).unwrap());
        let ids = centers.with_file_name(format!("{name}.centers.cell.bin"));
        let ids: Vec<i32> = bytemuck::pod_collect_to_vec(&std::fs::read(ids).unwrap());
        let m = Mesh::new(read(&path).unwrap(), file).unwrap();
        assert_eq!(c.len(), 3 * ids.len(), "{file}");
        let tol = 1e-5 * m.info.max_edge_length;
        for (&t, want) in ids.iter().zip(c.chunks_exact(3)) {
            let got = m.tet_center(t as usize);
            let d = (0..3).map(|k| (got[k] - want[k]).abs()).fold(0.0, f32::max);
            assert!(d <= tol, "{file}: tet {t} centroid {got:?}, oracle {want:?}");
        }
    }
}

/// `read_any` (a probe target): every node, the volume cells, then the points, lines and
/// surface elements that VTK has, in file order, with element data on all of them; in every
/// encoding, with or without volume cells. Element types VTK lacks are an error naming them.
#[test]
fn point_sets_keep_every_element() {
    let nan = f32::NAN.to_bits();
    for e in ENCODINGS {
        let g = parse_any(&write(&spec(), e), &p()).unwrap_or_else(|err| panic!("{e:?}: {err}"));
        assert_eq!(g.points.len(), 5, "{e:?}");
        // tet 9, tet 2, then the point 5 and the triangle 1.
        assert_eq!(g.types, [10, 10, 1, 5], "{e:?}");
        assert_eq!(g.ends, [4, 8, 9, 12], "{e:?}");
        assert_eq!(g.conn, [0, 1, 2, 3, 1, 2, 3, 4, 0, 1, 2, 3], "{e:?}");
        let mat = g.fields.iter().find(|f| f.name == "mat").unwrap();
        let bits: Vec<u32> = mat.values.iter().map(|v| v.to_bits()).collect();
        assert_eq!(bits, [90f32.to_bits(), 20f32.to_bits(), nan, 7f32.to_bits()], "{e:?}: the triangle's value kept");
        assert!(g.fields.iter().any(|f| f.name == "vel[2]" && f.values.len() == 5), "{e:?}");

        // A surface: no volume cells, and no error.
        let mut s = spec();
        s.elems.retain(|x| x.1 != 4);
        s.elem_data[0].3.retain(|(t, _)| *t == 1);
        let g = parse_any(&write(&s, e), &p()).unwrap_or_else(|err| panic!("{e:?}: {err}"));
        assert_eq!((g.types, g.conn), (vec![1, 5], vec![0, 1, 2, 3]), "{e:?}");

        // A 10-node triangle has no VTK cell type that tetloc writes.
        let mut s = spec();
        s.elems.push((20, 21, vec![10, 3, 7, 100, 5000, 10, 3, 7, 100, 5000]));
        let msg = parse_any(&write(&s, e), &p()).err().map(|x| x.to_string()).unwrap_or_default();
        assert!(msg.starts_with("test.msh: ") && msg.contains("element type 21 (10 nodes)"), "{e:?}: {msg}");
        // Read as a mesh, the same file ignores it.
        assert!(parse(&write(&s, e), &p()).is_ok(), "{e:?}");
    }
}

/// A file whose views hold several steps is a time series: the steps in the order of their
/// numbers, at their times (the sections' first real tag); a view written at fewer steps keeps
/// its last values; the mesh itself holds each view's first step.
#[test]
fn views_of_several_steps_are_a_time_series() {
    let dir = std::env::temp_dir().join(format!("tetloc-gmsh-steps-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("steps.msh");
    let values = |f: &[Field], name: &str| -> Vec<u32> {
        let f = f.iter().find(|f| f.name == name).unwrap_or_else(|| panic!("no field {name}"));
        f.values.iter().map(|v| v.to_bits()).collect()
    };
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let nan = f32::NAN;
    for e in ENCODINGS {
        std::fs::write(&path, write(&spec(), e)).unwrap();
        let (raw, steps) = read_series(&path).unwrap_or_else(|err| panic!("{e:?}: {err}"));
        let steps = steps.unwrap_or_else(|| panic!("{e:?}: no steps"));
        assert_eq!(steps.times, [0.5, 0.75], "{e:?}");
        assert_eq!(values(&raw.fields, "temp"), bits(&[0.0, 1.0, 2.0, 0.0, 3.0]), "{e:?}: the first step");
        let first = steps.fields(0).unwrap();
        assert_eq!(values(&first, "temp"), bits(&[0.0, 1.0, 2.0, 0.0, 3.0]), "{e:?}: step 0");
        let second = steps.fields(1).unwrap();
        assert_eq!(values(&second, "temp"), bits(&[nan, 2.5, -1.5, nan, nan]), "{e:?}: step 1");
        assert_eq!(values(&second, "vel[2]"), values(&first, "vel[2]"), "{e:?}: kept from step 0");
        assert_eq!(values(&second, "mat"), bits(&[90.0, 20.0]), "{e:?}");
        assert!(steps.fields(2).is_err(), "{e:?}");
    }
    // One step: a snapshot.
    let mut one = spec();
    one.node_data.retain(|v| v.1 == 0);
    std::fs::write(&path, write(&one, ENCODINGS[0])).unwrap();
    assert!(read_series(&path).unwrap().1.is_none());
    // Times that fall as the step numbers rise are refused, naming the file.
    let mut back = spec();
    back.node_data.push(("temp", -4, 1, vec![(7, vec![0.0])]));
    back.node_data.push(("temp", 5, 1, vec![(7, vec![0.0])]));
    let bytes = write(&back, ENCODINGS[0]);
    // -4 is at time -0.5, 5 at 1.75: they rise; make step 5's time fall below step 1's.
    let text = String::from_utf8(bytes).unwrap().replacen("1.75", "0.6", 1);
    std::fs::write(&path, text).unwrap();
    let msg = read_series(&path).err().map(|x| x.to_string()).unwrap_or_default();
    assert!(msg.contains("steps.msh") && msg.contains("steps 1 and 5 (0.75 and 0.6) do not increase"), "{msg}");
    std::fs::remove_dir_all(&dir).ok();
}
