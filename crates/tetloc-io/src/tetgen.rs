//! TetGen `.node` + `.ele` reader.
//!
//! `.node`: a header `<#points> [<dimension = 3> [<#attributes> [<#markers 0|1>]]]`, then one
//! line per point: `<id> <x> <y> <z> [attributes] [marker]`. The first point's id (0 or 1) is
//! the numbering base of both files; ids must then be consecutive. Point attributes become
//! vertex fields `attr[i]`; boundary markers are read and dropped.
//!
//! `.ele`: a header `<#tets> [<nodes per tet 4|10> [<#attributes>]]`, then one line per tet:
//! `<id> <nodes...> [attributes]`. 10-node (quadratic, `tetgen -o2`) tets keep their corners
//! in `tets`, set `higher_order = Some(2)`, and keep all 10 nodes in `cells` as VTK quadratic
//! tets: TetGen puts the 6 extra nodes at edge midpoints, so each is matched to the edge whose
//! midpoint it is (a node at no edge midpoint is an error). One attribute (TetGen's region number) becomes the cell field
//! `region`; several become `region[i]`.
//!
//! `#` starts a comment anywhere on a line; blank lines are skipped. Errors name the file and
//! the line.

use super::cursor::{Cursor, Line};
use std::path::{Path, PathBuf};
use tetloc_core::cell::{CellBlock, CellType};
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{Field, FieldLocation, RawMesh};

/// Reads `NAME.node` and `NAME.ele` (either may be named).
pub fn read(path: &Path) -> Result<RawMesh> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("node" | "ele") => {}
        _ => return Err(Error::format(path, "a TetGen mesh is named by its .node or .ele file")),
    }
    let (node_path, ele_path) = siblings(path);
    for p in [&node_path, &ele_path] {
        // Checked before opening: a FIFO blocks the open, a device never ends.
        if std::fs::metadata(p).is_ok_and(|m| !m.is_file()) {
            return Err(Error::format(p, "not a regular file (a folder, FIFO or device); TetGen meshes are files"));
        }
    }
    let node = std::fs::read(&node_path).map_err(|e| Error::io(&node_path, e))?;
    let ele = std::fs::read(&ele_path).map_err(|e| Error::io(&ele_path, e))?;
    parse(&node, &ele, path)
}

/// Parses a .node and a .ele file held in memory; `path` only names them in errors (as
/// `path` with the extension `.node` or `.ele`).
pub fn parse(node: &[u8], ele: &[u8], path: &Path) -> Result<RawMesh> {
    let (node_path, ele_path) = siblings(path);
    let nodes = read_nodes(&mut Cursor::new(node, &node_path))?;
    let tets = read_tets(&mut Cursor::new(ele, &ele_path), &nodes)?;
    let mut fields = attribute_fields(nodes.attrs, nodes.n_attrs, FieldLocation::Vertex, |i| format!("attr[{i}]"));
    let n_regions = tets.n_attrs;
    fields.extend(attribute_fields(tets.attrs, n_regions, FieldLocation::Cell, |i| {
        if n_regions == 1 {
            "region".to_string()
        } else {
            format!("region[{i}]")
        }
    }));
    let cells = match tets.higher_order {
        Some(_) => {
            Some(quadratic_cells(&tets.tets, &tets.extra, &nodes.points).map_err(|m| Error::format(&ele_path, m))?)
        }
        None => None,
    };
    let points = nodes.points.iter().map(|p| p.map(|x| x as f32)).collect();
    let points64 = super::points64_if_needed(nodes.points);
    Ok(RawMesh { points, points64, tets: tets.tets, fields, higher_order: tets.higher_order, cells })
}

/// 10-node tets as VTK quadratic tets: each extra node goes to the edge (VTK's order (0,1),
/// (1,2), (2,0), (0,3), (1,3), (2,3)) whose midpoint is nearest to it, which must be a
/// one-to-one match with every node within rounding of its midpoint.
fn quadratic_cells(tets: &[[u32; 4]], extra: &[u32], points: &[[f64; 3]]) -> std::result::Result<CellBlock, String> {
    const EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]];
    let ty = CellType::from_vtk(24, 10).expect("the quadratic tet is a cell type");
    let p = |i: u32| points[i as usize];
    let mut block = CellBlock::default();
    for (t, (c, x)) in tets.iter().zip(extra.chunks_exact(6)).enumerate() {
        let mut nodes = [0u32; 10];
        nodes[..4].copy_from_slice(c);
        let mut used = [false; 6];
        for (e, [a, b]) in EDGES.iter().enumerate() {
            let (pa, pb) = (p(c[*a]), p(c[*b]));
            let mid: [f64; 3] = std::array::from_fn(|k| 0.5 * (pa[k] + pb[k]));
            let len2: f64 = (0..3).map(|k| (pa[k] - pb[k]).powi(2)).sum();
            let dist2 = |i: u32| (0..3).map(|k| (p(i)[k] - mid[k]).powi(2)).sum::<f64>();
            let k = (0..6).filter(|&k| !used[k]).min_by(|&i, &j| dist2(x[i]).total_cmp(&dist2(x[j]))).unwrap();
            // TetGen writes exact midpoints; the slack covers f32 rounding far from the origin.
            if dist2(x[k]) > 0.0625 * len2 {
                return Err(format!(
                    "tetrahedron {}: none of its extra nodes is at the midpoint of its edge {a}-{b}; \
                     tetloc reads the midpoint nodes of `tetgen -o2`",
                    t + 1
                ));
            }
            used[k] = true;
            nodes[4 + e] = x[k];
        }
        block.push(ty, &nodes);
    }
    Ok(block)
}

fn siblings(path: &Path) -> (PathBuf, PathBuf) {
    (path.with_extension("node"), path.with_extension("ele"))
}

/// Splits row-major attributes (`n` per item) into one field each.
fn attribute_fields(values: Vec<f64>, n: usize, location: FieldLocation, name: impl Fn(usize) -> String) -> Vec<Field> {
    // f64 as in the file (`from_f64` keeps them where f32 would round).
    (0..n).map(|i| Field::from_f64(name(i), location, values.iter().skip(i).step_by(n).copied().collect())).collect()
}

/// The next data line (`#` starts a comment; blank lines are skipped), which must be there:
/// `what` says what it should hold.
fn expect_line<'a>(c: &mut Cursor<'a>, what: &str) -> Result<Line<'a>> {
    c.data_line(b'#').ok_or_else(|| c.fail(format!("unexpected end of file: expected {what}")))
}

/// Only comments and blank lines may follow the `count` declared records.
fn expect_no_more(c: &mut Cursor, count: usize, what: &str) -> Result<()> {
    match c.data_line(b'#') {
        None => Ok(()),
        Some(r) => Err(r.fail(format!("more {what} than the {count} that the header declares"))),
    }
}

struct Nodes {
    points: Vec<[f64; 3]>,
    /// `n_attrs` per point, row-major.
    attrs: Vec<f64>,
    n_attrs: usize,
    /// The id of the first point: 0 or 1.
    base: u64,
}

// What a record line with too many values ends with.
const MORE_VALUES_AFTER_POINT: &str = "the point's values (more values than the header declares)";
const MORE_VALUES_AFTER_TET: &str = "the tetrahedron's values (more values than the header declares)";

/// Attributes per point or tet beyond this are surely a corrupt header.
const MAX_ATTRS: u64 = 1024;

fn read_nodes(c: &mut Cursor) -> Result<Nodes> {
    let mut h = expect_line(c, "the header '<#points> 3 <#attributes> <#markers>'")?;
    let n = h.u64("the number of points")?;
    let dim = h.u64_or("the dimension", 3)?;
    let n_attrs = h.u64_or("the number of attributes", 0)?;
    let n_markers = h.u64_or("the number of boundary markers", 0)?;
    h.expect_end("the header")?;
    if dim != 3 {
        return Err(h.fail(format!("dimension {dim}: tetloc reads 3-D meshes only")));
    }
    if n_attrs > MAX_ATTRS || n_markers > 1 {
        return Err(h.fail(format!("{n_attrs} attributes and {n_markers} markers per point: corrupt header")));
    }
    let n_attrs = n_attrs as usize;
    if n == 0 {
        return Err(h.fail("no points (TetGen then keeps them in a .poly or .smesh file, which tetloc does not read)"));
    }
    if n >= u32::MAX as u64 {
        return Err(h.fail(format!("{n} points: more than tetloc's 32-bit indices can address")));
    }
    // "1 0 0 0\n": at least 8 bytes a point, and 2 more an attribute.
    let n = c.check_room(n, 8 + 2 * n_attrs, "points")?;
    let mut points = Vec::with_capacity(n);
    let mut attrs = Vec::with_capacity(n * n_attrs);
    let mut base = 0;
    for i in 0..n {
        let mut r = expect_line(c, &format!("point {} of {n}", i + 1))?;
        let id = r.u64("a point number")?;
        if i == 0 {
            if id > 1 {
                return Err(r.fail(format!("the first point is numbered {id}; TetGen numbers from 0 or 1")));
            }
            base = id;
        } else if id != base + i as u64 {
            return Err(r.fail(format!(
                "point number {id}: expected {} (points must be numbered consecutively)",
                base + i as u64
            )));
        }
        points.push([r.f64("x")?, r.f64("y")?, r.f64("z")?]);
        for _ in 0..n_attrs {
            attrs.push(r.f64("a point attribute")?);
        }
        if n_markers == 1 && !r.at_end() {
            r.i64("a boundary marker")?;
        }
        r.expect_end(MORE_VALUES_AFTER_POINT)?;
    }
    expect_no_more(c, n, "points")?;
    Ok(Nodes { points, attrs, n_attrs, base })
}

struct Tets {
    /// Corners only.
    tets: Vec<[u32; 4]>,
    /// The 6 other nodes of 10-node tets, as the file lists them.
    extra: Vec<u32>,
    higher_order: Option<u8>,
    /// `n_attrs` per tet, row-major.
    attrs: Vec<f64>,
    n_attrs: usize,
}

fn read_tets(c: &mut Cursor, nodes: &Nodes) -> Result<Tets> {
    let mut h = expect_line(c, "the header '<#tets> <nodes per tet> <#attributes>'")?;
    let n = h.u64("the number of tetrahedra")?;
    let per_tet = h.u64_or("the number of nodes per tetrahedron", 4)?;
    let n_attrs = h.u64_or("the number of attributes", 0)?;
    h.expect_end("the header")?;
    if per_tet != 4 && per_tet != 10 {
        return Err(h.fail(format!("{per_tet} nodes per tetrahedron: TetGen writes 4 or 10")));
    }
    if n_attrs > MAX_ATTRS {
        return Err(h.fail(format!("{n_attrs} attributes per tetrahedron: corrupt header")));
    }
    let (per_tet, n_attrs) = (per_tet as usize, n_attrs as usize);
    if n == 0 {
        return Err(h.fail("no tetrahedra"));
    }
    // "1 1 2 3 4\n": at least 10 bytes a tet, and 2 more an attribute.
    let n = c.check_room(n, 2 * (1 + per_tet + n_attrs), "tetrahedra")?;
    let n_points = nodes.points.len() as u64;
    let mut tets = Vec::with_capacity(n);
    let mut extra = Vec::with_capacity(n * (per_tet - 4));
    let mut attrs = Vec::with_capacity(n * n_attrs);
    for i in 0..n {
        let mut r = expect_line(c, &format!("tetrahedron {} of {n}", i + 1))?;
        r.u64("a tetrahedron number")?;
        let mut t = [0u32; 4];
        for k in 0..per_tet {
            let id = r.u64("a point number")?;
            let Some(index) = id.checked_sub(nodes.base).filter(|&x| x < n_points) else {
                return Err(r.fail(format!(
                    "point {id} does not exist: the .node file numbers its points {} to {}",
                    nodes.base,
                    nodes.base + n_points - 1
                )));
            };
            match t.get_mut(k) {
                Some(corner) => *corner = index as u32,
                None => extra.push(index as u32),
            }
        }
        tets.push(t);
        for _ in 0..n_attrs {
            attrs.push(r.f64("a tetrahedron attribute")?);
        }
        r.expect_end(MORE_VALUES_AFTER_TET)?;
    }
    expect_no_more(c, n, "tetrahedra")?;
    Ok(Tets { tets, extra, higher_order: (per_tet == 10).then_some(2), attrs, n_attrs })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use tetloc_core::mesh::Mesh;

    /// Two tets sharing a face, numbered from `base`, with two point attributes, boundary
    /// markers and a region attribute, and comments in odd places.
    fn files(base: u32) -> (String, String) {
        let pts = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0]];
        let mut node = String::from("# written by a test\n5 3 2 1\n\n");
        for (i, p) in pts.iter().enumerate() {
            node +=
                &format!("  {}  {} {} {}  {} {}  {}  # point\n", i as u32 + base, p[0], p[1], p[2], i * 10, 0.5, i % 2);
        }
        let ele = format!(
            "2 4 1 # header\n{} {} {} {} {} 3\n{} {} {} {} {} -1\n# Generated by tetgen\n",
            base,
            base,
            base + 1,
            base + 2,
            base + 3,
            base + 1,
            base + 1,
            base + 2,
            base + 3,
            base + 4
        );
        (node, ele)
    }

    fn expected() -> RawMesh {
        let f = |name: &str, location, values: Vec<f32>| Field::new(name, location, values);
        crate::test_support::two_tets(vec![
            f("attr[0]", FieldLocation::Vertex, vec![0.0, 10.0, 20.0, 30.0, 40.0]),
            f("attr[1]", FieldLocation::Vertex, vec![0.5; 5]),
            f("region", FieldLocation::Cell, vec![3.0, -1.0]),
        ])
    }

    fn assert_same(got: &RawMesh, want: &RawMesh) {
        assert_eq!(got.points, want.points);
        assert_eq!(got.tets, want.tets);
        assert_eq!(got.higher_order, want.higher_order);
        let fields =
            |m: &RawMesh| m.fields.iter().map(|f| (f.name.clone(), f.location, f.values.clone())).collect::<Vec<_>>();
        assert_eq!(fields(got), fields(want));
    }

    #[test]
    fn reads_both_numberings_from_either_file() {
        let dir = tempfile::tempdir().unwrap();
        for base in [0, 1] {
            let (node, ele) = files(base);
            let stem = dir.path().join(format!("mesh{base}.1"));
            std::fs::write(stem.with_extension("node"), node).unwrap();
            std::fs::write(stem.with_extension("ele"), ele).unwrap();
            for ext in ["node", "ele"] {
                let m = read(&stem.with_extension(ext)).unwrap();
                assert_same(&m, &expected());
                Mesh::new(m, "tetgen").unwrap();
            }
        }
    }

    #[test]
    fn minimal_headers_and_quadratic_tets() {
        // Header fields after the count are optional; 10-node tets keep their corners.
        let mut node = String::from("8\n");
        for i in 0..8 {
            node += &format!("{} {} {} {}\n", i + 1, i % 2, (i / 2) % 2, i / 4);
        }
        let ele = "1 10\n1 1 2 3 5 4 6 7 8 8 8\n";
        let err = parse(node.as_bytes(), ele.as_bytes(), Path::new("q.node")).unwrap_err().to_string();
        assert!(err.contains("q.ele") && err.contains("midpoint"), "{err}");
        // The corners (0,0,0) (1,0,0) (0,1,0) (0,0,1), then their edge midpoints in another order.
        let mut node = String::from("10\n");
        let pts = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.], [0.5, 0.5, 0.], [0.5, 0., 0.]];
        let more = [[0., 0.5, 0.], [0., 0., 0.5], [0.5, 0., 0.5], [0., 0.5, 0.5]];
        for (i, p) in pts.iter().chain(&more).enumerate() {
            node += &format!("{} {} {} {}\n", i + 1, p[0], p[1], p[2]);
        }
        let ele = "1 10\n1 1 2 3 4 5 6 7 8 9 10\n";
        let m = parse(node.as_bytes(), ele.as_bytes(), Path::new("q.node")).unwrap();
        assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
        assert_eq!(m.higher_order, Some(2));
        assert!(m.fields.is_empty());
        // VTK's edges (0,1) (1,2) (2,0) (0,3) (1,3) (2,3).
        assert_eq!(m.cells.unwrap().nodes(0), &[0, 1, 2, 3, 5, 4, 6, 7, 8, 9]);
    }

    /// Point and region attributes keep the file's f64 values (ones f32 would round).
    #[test]
    fn attributes_keep_f64() {
        let (node, _) = files(0);
        let node = node.replace("  0  0 0 0  0 0.5", "  0  0 0 0  0.1000000000000001 1e300");
        let ele = "1 4 1\n0 0 1 2 3 16777217\n";
        let m = parse(node.as_bytes(), ele.as_bytes(), Path::new("m.node")).unwrap();
        let v64 = |name: &str| m.fields.iter().find(|f| f.name == name).unwrap().values64.clone().unwrap();
        assert_eq!(v64("attr[0]")[0], 0.1000000000000001);
        assert_eq!(v64("attr[1]")[0], 1e300);
        assert_eq!(v64("region"), [16777217.0]);
    }

    #[test]
    fn several_region_attributes() {
        let (node, _) = files(0);
        let ele = "1 4 2\n0 0 1 2 3 7 8\n";
        let m = parse(node.as_bytes(), ele.as_bytes(), Path::new("m.node")).unwrap();
        let cell: Vec<_> = m.fields.iter().filter(|f| f.location == FieldLocation::Cell).collect();
        assert_eq!(cell.len(), 2);
        assert_eq!((cell[0].name.as_str(), cell[0].values.as_slice()), ("region[0]", &[7.0f32][..]));
        assert_eq!((cell[1].name.as_str(), cell[1].values.as_slice()), ("region[1]", &[8.0f32][..]));
    }

    fn err_of(node: &str, ele: &str) -> String {
        match parse(node.as_bytes(), ele.as_bytes(), Path::new("/d/m.1.ele")) {
            Ok(_) => panic!("parsed a bad mesh:\n{node}\n{ele}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn bad_files_give_clear_errors() {
        let (node, ele) = files(1);
        let cases: Vec<(String, String, &str)> = vec![
            (node.replace("5 3 2 1", "5 2 2 1"), ele.clone(), "/d/m.1.node: line 2: dimension 2"),
            (node.replace("  1  0 0 0", "  2  0 0 0"), ele.clone(), "line 4: the first point is numbered 2"),
            (node.replace("  3  0 1 0", "  4  0 1 0"), ele.clone(), "line 6: point number 4: expected 3"),
            (node.replace("  3  0 1 0", "  3  0 y 0"), ele.clone(), "line 6: expected y (a number), found 'y'"),
            (node.replace("  3  0 1 0  20 0.5  0", "  3  0 1 0  20"), ele.clone(), "line 6: missing a point attribute"),
            (
                node.replace("5 3 2 1", "5 3 1 1"),
                ele.clone(),
                "line 4: expected a boundary marker (an integer), found '0.5'",
            ),
            (node.replace("5 3 2 1", "5 3 1 0"), ele.clone(), "line 4: unexpected '0.5' after the point's values"),
            (node.replace("5 3 2 1", "6 3 2 1"), ele.clone(), "expected point 6 of 6"),
            (node.replace("5 3 2 1", "4 3 2 1"), ele.clone(), "line 8: more points than the 4"),
            (node.replace("5 3 2 1", "9999999 3 2 1"), ele.clone(), "declares 9999999 points"),
            (node.replace("5 3 2 1", "0 3 0 0"), ele.clone(), "no points"),
            (node.clone(), ele.replace("2 4 1", "2 6 1"), "/d/m.1.ele: line 1: 6 nodes per tetrahedron"),
            (
                node.clone(),
                ele.replace("2 3 4 5 -1", "2 3 4 6 -1"),
                "line 3: point 6 does not exist: the .node file numbers its points 1 to 5",
            ),
            (node.clone(), ele.replace("2 3 4 5 -1", "2 3 4 0 -1"), "line 3: point 0 does not exist"),
            (node.clone(), ele.replace("2 4 1", "3 4 1"), "expected tetrahedron 3 of 3"),
            (
                node.clone(),
                ele.replace(" 3\n", " 3.5.1\n"),
                "line 2: expected a tetrahedron attribute (a number), found '3.5.1'",
            ),
        ];
        for (node, ele, want) in cases {
            let msg = err_of(&node, &ele);
            assert!(msg.contains(want), "expected '{want}' in: {msg}");
        }
        // A missing sibling names the file that is missing.
        let dir = tempfile::tempdir().unwrap();
        let (node, _) = files(0);
        std::fs::write(dir.path().join("m.node"), node).unwrap();
        match read(&dir.path().join("m.node")) {
            Err(Error::Io { path, .. }) => assert_eq!(path, dir.path().join("m.ele")),
            other => panic!("{other:?}"),
        }
        assert!(read(&dir.path().join("m.face")).unwrap_err().to_string().contains(".node or .ele"));
        // A sibling that is a FIFO is refused, not opened (which would block for a writer).
        #[cfg(unix)]
        {
            let made = std::process::Command::new("mkfifo").arg(dir.path().join("m.ele")).status();
            assert!(made.is_ok_and(|s| s.success()), "mkfifo");
            let e = read(&dir.path().join("m.node")).unwrap_err().to_string();
            assert!(e.contains("m.ele") && e.contains("not a regular file"), "{e}");
        }
    }

    #[test]
    fn truncated_and_corrupted_files_are_errors() {
        let (node, ele) = files(0);
        let (node, ele) = (node.as_bytes(), ele.as_bytes());
        let path = Path::new("t.node");
        // A cut before the last data line loses a record; a cut inside it may still parse
        // (a line-based format cannot tell a shortened last number), but never panics.
        let last_line = |b: &[u8]| {
            let text = std::str::from_utf8(b).unwrap();
            let data_lines: Vec<usize> = text
                .lines()
                .scan(0, |at, l| {
                    let start = *at;
                    *at += l.len() + 1;
                    Some((start, l))
                })
                .filter(|(_, l)| !l.trim_start().starts_with('#') && !l.trim().is_empty())
                .map(|(start, _)| start)
                .collect();
            *data_lines.last().unwrap()
        };
        for len in 0..node.len() {
            let res = parse(&node[..len], ele, path);
            assert!(len > last_line(node) || res.is_err(), "node cut at {len}");
        }
        for len in 0..ele.len() {
            let res = parse(node, &ele[..len], path);
            assert!(len > last_line(ele) || res.is_err(), "ele cut at {len}");
        }
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for _ in 0..3000 {
            let (mut n, mut e) = (node.to_vec(), ele.to_vec());
            for _ in 0..rng.gen_range(1..4) {
                let target = if rng.gen() { &mut n } else { &mut e };
                let i = rng.gen_range(0..target.len());
                target[i] = [rng.gen(), b'9', b'-', b' ', b'\n', b'#', b'e'][rng.gen_range(0..7)];
            }
            if let Ok(m) = parse(&n, &e, path) {
                let _ = Mesh::new(m, "corrupt");
            }
        }
    }
}
