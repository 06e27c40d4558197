//! Reader of VTK legacy files (`.vtk`) that hold an `UNSTRUCTURED_GRID`: ASCII or BINARY
//! (big-endian), file versions up to 4.2 (`CELLS n size` with a count before each cell's
//! ids) and 5.x (`CELLS` followed by `OFFSETS` and `CONNECTIVITY` arrays).
//!
//! The file is a sequence of keyword lines, each followed by its data: whitespace-separated
//! numbers in ASCII files, raw big-endian values right after the line's newline in BINARY
//! ones. Point and cell attributes (SCALARS, VECTORS, NORMALS, TENSORS, FIELD arrays, ...)
//! become fields; METADATA blocks and lookup tables are skipped.

use super::cells;
use super::num::{self, Array, NumType};
use super::vtu::AnyGrid;
use crate::cursor::Cursor;
use std::borrow::Cow;
use std::path::Path;
use tetloc_core::cell::PolyFaces;
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{Field, FieldLocation, RawMesh};

pub fn read(path: &Path) -> Result<RawMesh> {
    let bytes = super::read_file(path)?;
    parse(&bytes, path)
}

/// Parses a whole file held in memory; `path` only names it in errors.
pub fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh> {
    parse_grid(bytes, path)?.finish(path)
}

/// Reads a `.vtk` of any cells (volumes, surfaces, lines, vertices) as the file has them:
/// what `probe` keeps of a target, which may be any point set.
pub fn read_any(path: &Path) -> Result<AnyGrid> {
    let bytes = super::read_file(path)?;
    parse_any(&bytes, path)
}

/// [`read_any`] of a file held in memory.
pub fn parse_any(bytes: &[u8], path: &Path) -> Result<AnyGrid> {
    let list = parse_grid(bytes, path)?.cell_list(path)?;
    if list.types.contains(&cells::POLYHEDRON) {
        return Err(Error::format(path, "polyhedron cells (type 42) are not supported"));
    }
    let CellList { points, points64, types, ends, conn, fields, .. } = list;
    Ok(AnyGrid { points, points64, types, ends, conn, fields })
}

/// The file's sections, read.
fn parse_grid<'a>(bytes: &'a [u8], path: &'a Path) -> Result<Grid<'a>> {
    let mut r = Reader { c: Cursor::new(bytes, path), at: 0 };
    let magic = r.c.line().unwrap_or_default();
    if !String::from_utf8_lossy(magic).to_ascii_lowercase().starts_with("# vtk datafile version") {
        return Err(r.c.fail_at(0, "not a VTK legacy file: the first line is not '# vtk DataFile Version x.y'"));
    }
    r.c.line(); // title
    r.at = r.c.pos;
    let mode = String::from_utf8_lossy(r.c.line().unwrap_or_default()).trim().to_ascii_uppercase();
    r.c.binary = match mode.as_str() {
        "ASCII" => false,
        "BINARY" => true,
        _ => return Err(r.fail(format!("the third line is '{mode}', not ASCII or BINARY"))),
    };
    let kw = r.keyword()?;
    let args = r.args();
    if kw != "DATASET" {
        return Err(r.fail(format!("expected DATASET, found '{kw}'")));
    }
    match args.first().map(|s| s.to_ascii_uppercase()) {
        Some(t) if t == "UNSTRUCTURED_GRID" => {}
        t => {
            return Err(r.fail(format!(
                "dataset type {}: tetloc reads UNSTRUCTURED_GRID files",
                t.unwrap_or_else(|| "(none)".into())
            )))
        }
    }

    let mut g = Grid::default();
    // The attribute section being read: where its values go and how many tuples it has.
    let mut section: Option<(FieldLocation, usize)> = None;
    while let Some(kw) = r.keyword_opt() {
        let args = r.args();
        let arg = |i: usize| args.get(i).map(String::as_str);
        match kw.as_str() {
            // A second section would replace the first silently.
            "POINTS" | "CELLS" | "CELL_TYPES"
                if match kw.as_str() {
                    "POINTS" => g.points.is_some(),
                    "CELLS" => g.cells.is_some(),
                    _ => g.types.is_some(),
                } =>
            {
                return Err(r.fail(format!("a second {kw} section; a file has one")));
            }
            "POINTS" => {
                let n = r.count(arg(0), "POINTS count")?;
                let ty = r.num_type(arg(1))?;
                let a = r.values(ty, n.saturating_mul(3), "POINTS")?;
                g.points64 = num::to_points64(&a);
                g.points = Some(num::to_points(&a));
            }
            "CELLS" => {
                let (a, b) = (r.count(arg(0), "CELLS count")?, r.count(arg(1), "CELLS size")?);
                if r.c.next_line_starts_with("OFFSETS") {
                    g.cells = Some(r.offsets_and_connectivity(a, b)?);
                } else {
                    g.cells = Some(Cells::List(r.values(NumType::I32, b, "CELLS")?));
                }
            }
            "CELL_TYPES" => {
                let n = r.count(arg(0), "CELL_TYPES count")?;
                let arr = r.values(NumType::I32, n, "CELL_TYPES")?;
                let types = num::map_ints(&arr, |v| u8::try_from(v).ok())
                    .map_err(|i| r.fail(format!("CELL_TYPES: value {i} ({}) is not a VTK cell type", arr.show(i))))?;
                g.types = Some(types);
            }
            "POINT_DATA" => section = Some((FieldLocation::Vertex, r.count(arg(0), "POINT_DATA count")?)),
            "CELL_DATA" => section = Some((FieldLocation::Cell, r.count(arg(0), "CELL_DATA count")?)),
            "FIELD" => {
                let n_arrays = r.count(arg(1), "FIELD array count")?;
                for _ in 0..n_arrays {
                    r.field_array(section, &mut g.fields)?;
                }
            }
            "METADATA" => r.skip_metadata(),
            "LOOKUP_TABLE" => {
                // A table of RGBA colours: floats in ASCII, bytes in BINARY.
                let n = r.count(arg(1), "LOOKUP_TABLE size")?;
                let ty = if r.c.binary { NumType::U8 } else { NumType::F32 };
                r.values(ty, n.saturating_mul(4), "LOOKUP_TABLE")?;
            }
            "SCALARS"
            | "VECTORS"
            | "NORMALS"
            | "TENSORS"
            | "TENSORS6"
            | "TEXTURE_COORDINATES"
            | "COLOR_SCALARS"
            | "GLOBAL_IDS"
            | "PEDIGREE_IDS"
            | "EDGE_FLAGS" => {
                let Some((location, n)) = section else {
                    return Err(r.fail(format!("{kw} before POINT_DATA or CELL_DATA")));
                };
                let name = decode_name(arg(0).unwrap_or("(unnamed)"));
                let (ty, ncomp) = match kw.as_str() {
                    "SCALARS" => {
                        let nc = match arg(2) {
                            Some(s) => r.count(Some(s), "SCALARS components")?,
                            None => 1,
                        };
                        if r.c.next_line_starts_with("LOOKUP_TABLE") {
                            let at = r.at; // errors about the array still name the SCALARS line
                            r.keyword()?;
                            r.args();
                            r.at = at;
                        }
                        (arg(1), nc)
                    }
                    "VECTORS" | "NORMALS" => (arg(1), 3),
                    "TENSORS" => (arg(1), 9),
                    "TENSORS6" => (arg(1), 6),
                    "TEXTURE_COORDINATES" => (arg(2), r.count(arg(1), "TEXTURE_COORDINATES dimension")?),
                    // Colours: bytes in BINARY files, floats in [0, 1] in ASCII ones.
                    "COLOR_SCALARS" => (
                        Some(if r.c.binary { "unsigned_char" } else { "float" }),
                        r.count(arg(1), "COLOR_SCALARS size")?,
                    ),
                    _ => (arg(1), 1),
                };
                r.attribute(&name, ty, n, ncomp, location, &mut g.fields, kw == "COLOR_SCALARS")?;
            }
            _ => {
                return Err(r.fail(format!(
                "unexpected keyword '{kw}' (expected POINTS, CELLS, CELL_TYPES, POINT_DATA, CELL_DATA or an attribute)"
            )))
            }
        }
    }
    Ok(g)
}

/// The file's cells as a VTK cell list, checked (point ids, offsets, the data's lengths).
struct CellList {
    points: Vec<[f32; 3]>,
    points64: Option<Vec<[f64; 3]>>,
    types: Vec<u8>,
    /// Where each cell's point ids end in `conn`.
    ends: Vec<u64>,
    conn: Vec<u32>,
    /// The faces of the polyhedra among the cells.
    polyhedra: PolyFaces,
    fields: Vec<Field>,
}

/// The cells as the file gives them.
enum Cells<'a> {
    /// Version ≤ 4.2: each cell's point count, then its ids.
    List(Array<'a>),
    /// Version 5: `n + 1` offsets and the connectivity.
    Arrays(Array<'a>, Array<'a>),
}

#[derive(Default)]
struct Grid<'a> {
    points: Option<Vec<[f32; 3]>>,
    points64: Option<Vec<[f64; 3]>>,
    cells: Option<Cells<'a>>,
    types: Option<Vec<u8>>,
    fields: Vec<Field>,
}

impl Grid<'_> {
    /// The mesh of the file's volume cells (0-2-D cells dropped with their cell data).
    fn finish(self, path: &Path) -> Result<RawMesh> {
        let CellList { points, points64, types, ends, conn, polyhedra, mut fields } = self.cell_list(path)?;
        let ex = cells::extract(&types, &ends, &conn, Some(&polyhedra)).map_err(|m| Error::format(path, m))?;
        if ex.unsupported {
            return Err(cells::non_tet_error(path, &ex.other));
        }
        for f in fields.iter_mut().filter(|f| f.location == FieldLocation::Cell) {
            f.values = cells::filter_cells(std::mem::take(&mut f.values), ex.kept.as_deref());
            f.values64 = f.values64.take().map(|v| cells::filter_cells(v, ex.kept.as_deref()));
        }
        crate::check_distinct_fields(path, &fields)?;
        Ok(ex.into_mesh(points, points64, fields))
    }

    fn cell_list(self, path: &Path) -> Result<CellList> {
        let fail = |msg: String| Error::format(path, msg);
        let points = self.points.ok_or_else(|| fail("no POINTS section".into()))?;
        let cells = self.cells.ok_or_else(|| fail("no CELLS section".into()))?;
        let types = self.types.ok_or_else(|| fail("no CELL_TYPES section".into()))?;
        let n_points = points.len();
        let bad_id = |arr: &Array, i: usize, what: &str| {
            fail(format!("{what}: value {i} ({}) is not a point id (the file has {n_points} points)", arr.show(i)))
        };
        // Legacy files (≤ 4.2) give a polyhedron's face stream in place of its points.
        let mut polyhedra = PolyFaces::default();
        let (ends, conn) = match cells {
            Cells::List(list) => {
                let v = num::map_ints(&list, |v| u32::try_from(v).ok())
                    .map_err(|i| fail(format!("CELLS: value {i} ({}) is negative", list.show(i))))?;
                let mut ends = Vec::with_capacity(types.len());
                let mut conn = Vec::with_capacity(v.len().saturating_sub(types.len()));
                let mut pos = 0;
                while pos < v.len() {
                    let k = v[pos] as usize;
                    let ids = v.get(pos + 1..pos + 1 + k).ok_or_else(|| {
                        fail(format!("CELLS: cell {} claims {k} points, past the end of the list", ends.len()))
                    })?;
                    if types.get(ends.len()) == Some(&cells::POLYHEDRON) {
                        let stream: Vec<i64> = ids.iter().map(|&v| i64::from(v)).collect();
                        let one = cells::faces_from_stream(&[cells::POLYHEDRON], &stream, n_points)
                            .map_err(|m| fail(format!("CELLS: cell {}: {m}", ends.len())))?;
                        polyhedra.append(&one, ends.len() as u32, 0);
                        conn.extend(tetloc_core::cell::polyhedron::distinct_points(one.faces(0)));
                        ends.push(conn.len() as u64);
                        pos += 1 + k;
                        continue;
                    }
                    if let Some(&id) = ids.iter().find(|&&id| id as usize >= n_points) {
                        return Err(fail(format!(
                            "CELLS: cell {} uses point {id}, but the file has {n_points} points",
                            ends.len()
                        )));
                    }
                    conn.extend_from_slice(ids);
                    ends.push(conn.len() as u64);
                    pos += 1 + k;
                }
                (ends, conn)
            }
            Cells::Arrays(offsets, connectivity) => {
                let mut ends = num::map_ints(&offsets, |v| u64::try_from(v).ok())
                    .map_err(|i| fail(format!("OFFSETS: value {i} ({}) is not an offset", offsets.show(i))))?;
                // n + 1 offsets from 0; the cells end at the last n.
                if ends.first().is_some_and(|&s| s != 0) {
                    return Err(fail(format!("OFFSETS: the first cell starts at {}, not 0", ends[0])));
                }
                if !ends.is_empty() {
                    ends.remove(0);
                }
                let conn =
                    num::to_ids(&connectivity, n_points).map_err(|i| bad_id(&connectivity, i, "CONNECTIVITY"))?;
                (ends, conn)
            }
        };
        let fields = self.fields;
        for f in &fields {
            let (want, what) = match f.location {
                FieldLocation::Vertex => (n_points, "POINT_DATA"),
                FieldLocation::Cell => (types.len(), "CELL_DATA"),
            };
            if f.values.len() != want {
                return Err(fail(format!(
                    "{what} array '{}' has {} values, but the file has {want} {}",
                    f.name,
                    f.values.len(),
                    if what == "POINT_DATA" { "points" } else { "cells" }
                )));
            }
        }
        Ok(CellList { points, points64: self.points64, types, ends, conn, polyhedra, fields })
    }
}

/// The reader's state: the cursor, whose `binary` says whether data is raw (big-endian) or text.
struct Reader<'a> {
    c: Cursor<'a>,
    /// Where the current keyword (or FIELD array) line starts: errors about it point there.
    at: usize,
}

impl<'a> Reader<'a> {
    /// An error about the current keyword line.
    fn fail(&self, msg: String) -> Error {
        self.c.fail_at(self.at, msg)
    }

    /// The next word, lossy, which starts a line; `None` at the end of the file.
    fn word(&mut self) -> Option<String> {
        self.at = self.c.here();
        self.c.word().map(|w| String::from_utf8_lossy(w).into_owned())
    }

    /// The next word, upper-cased: keywords are case-insensitive.
    fn keyword_opt(&mut self) -> Option<String> {
        self.word().map(|w| w.to_ascii_uppercase())
    }

    fn keyword(&mut self) -> Result<String> {
        self.keyword_opt().ok_or_else(|| self.fail("unexpected end of file".into()))
    }

    /// The words after the keyword on its line; consumes the line, so BINARY data starts
    /// right here.
    fn args(&mut self) -> Vec<String> {
        let line = self.c.line().unwrap_or_default();
        String::from_utf8_lossy(line).split_ascii_whitespace().map(str::to_string).collect()
    }

    fn count(&self, s: Option<&str>, what: &str) -> Result<usize> {
        let s = s.ok_or_else(|| self.fail(format!("{what} is missing")))?;
        s.parse().map_err(|_| self.fail(format!("{what} '{s}' is not a count")))
    }

    fn num_type(&self, s: Option<&str>) -> Result<NumType> {
        let s = s.ok_or_else(|| self.fail("data type is missing".into()))?;
        NumType::from_legacy(s).ok_or_else(|| self.fail(format!("data type '{s}' is not a numeric type tetloc reads")))
    }

    /// `n` values of `ty`: raw big-endian bytes (BINARY) or numbers (ASCII).
    fn values(&mut self, ty: NumType, n: usize, what: &str) -> Result<Array<'a>> {
        if self.c.binary {
            let bytes = self.c.take_records(n as u64, ty.size(), &format!("{what} ({n} values of {})", ty.name()))?;
            Ok(Array::from_bytes(ty, Cow::Borrowed(bytes), true))
        } else {
            let c = &mut self.c;
            let (arr, used) =
                num::parse_ascii(&c.buf[c.pos..], ty, Some(n)).map_err(|m| c.fail(format!("{what}: {m}")))?;
            c.pos += used;
            Ok(arr)
        }
    }

    /// Reads, or skips, `n` values of a non-numeric type; `false` if `ty` is numeric.
    fn skip_non_numeric(&mut self, ty: &str, n: usize, what: &str) -> Result<bool> {
        match ty.to_ascii_lowercase().as_str() {
            "bit" if self.c.binary => {
                self.c.take(n.div_ceil(8), &format!("{what} ({n} bits)"))?;
            }
            "bit" => {
                self.values(NumType::U8, n, what)?;
            }
            "string" | "utf8_string" if !self.c.binary => {
                for _ in 0..n {
                    self.c.line().ok_or_else(|| self.fail(format!("{what}: the file ends inside a string array")))?;
                }
            }
            "string" | "utf8_string" | "variant" => {
                return Err(self.fail(format!("{what}: {ty} arrays are not supported in BINARY files")))
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// One attribute array of `n` tuples × `ncomp` values, added to `fields`.
    #[allow(clippy::too_many_arguments)]
    fn attribute(
        &mut self,
        name: &str,
        ty: Option<&str>,
        n: usize,
        ncomp: usize,
        location: FieldLocation,
        fields: &mut Vec<Field>,
        colour: bool,
    ) -> Result<()> {
        let ty_name = ty.ok_or_else(|| self.fail(format!("'{name}': data type is missing")))?;
        let total = n.saturating_mul(ncomp);
        if ncomp == 0 || self.skip_non_numeric(ty_name, total, name)? {
            return Ok(());
        }
        let ty = self.num_type(Some(ty_name))?;
        let arr = self.values(ty, total, name)?;
        for c in 0..ncomp {
            let mut values = num::component_f32(&arr, ncomp, c);
            if colour && ty == NumType::U8 {
                values.iter_mut().for_each(|v| *v /= 255.0);
            }
            let name = if ncomp == 1 { name.to_string() } else { format!("{name}[{c}]") };
            fields.push(Field { name, location, values, values64: num::component_f64(&arr, ncomp, c) });
        }
        Ok(())
    }

    /// One array of a FIELD: `name ncomp ntuples type`, then data. Outside POINT_DATA and
    /// CELL_DATA (field data of the whole dataset) it is read and dropped.
    fn field_array(&mut self, section: Option<(FieldLocation, usize)>, fields: &mut Vec<Field>) -> Result<()> {
        let raw_name = self.word().ok_or_else(|| self.fail("the file ends inside a FIELD".into()))?;
        if raw_name == "NULL_ARRAY" {
            self.args();
            return Ok(());
        }
        let args = self.args();
        let arg = |i: usize| args.get(i).map(String::as_str);
        let ncomp = self.count(arg(0), "FIELD array components")?;
        let ntuples = self.count(arg(1), "FIELD array tuples")?;
        let ty = arg(2).ok_or_else(|| self.fail(format!("FIELD array '{raw_name}': data type is missing")))?;
        let name = decode_name(&raw_name);
        match section {
            Some((location, n)) => {
                if ntuples != n {
                    return Err(self.fail(format!("FIELD array '{name}' has {ntuples} tuples, expected {n}")));
                }
                self.attribute(&name, Some(ty), n, ncomp, location, fields, false)?;
            }
            None => {
                let total = ncomp.saturating_mul(ntuples);
                if !self.skip_non_numeric(ty, total, &name)? {
                    let ty = self.num_type(Some(ty))?;
                    self.values(ty, total, &name)?;
                }
            }
        }
        if self.c.next_line_starts_with("METADATA") {
            self.keyword()?;
            self.skip_metadata();
        }
        Ok(())
    }

    /// Skips a METADATA block: lines up to a blank one.
    fn skip_metadata(&mut self) {
        self.c.line(); // the rest of the METADATA line
        while let Some(l) = self.c.line() {
            if l.trim_ascii().is_empty() {
                break;
            }
        }
    }

    fn offsets_and_connectivity(&mut self, n_offsets: usize, n_conn: usize) -> Result<Cells<'a>> {
        let read = |this: &mut Self, kw: &str, n: usize| -> Result<Array<'a>> {
            let k = this.keyword()?;
            let args = this.args();
            if k != kw {
                return Err(this.fail(format!("expected {kw}, found '{k}'")));
            }
            let ty = this.num_type(args.first().map(String::as_str))?;
            let arr = this.values(ty, n, kw)?;
            if this.c.next_line_starts_with("METADATA") {
                this.keyword()?;
                this.skip_metadata();
            }
            Ok(arr)
        };
        let offsets = read(self, "OFFSETS", n_offsets)?;
        let conn = read(self, "CONNECTIVITY", n_conn)?;
        Ok(Cells::Arrays(offsets, conn))
    }
}

/// Legacy names encode spaces and other special characters as `%XX`.
fn decode_name(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex =
            b.get(i + 1..i + 3).and_then(|h| std::str::from_utf8(h).ok()).and_then(|h| u8::from_str_radix(h, 16).ok());
        match (b[i], hex) {
            (b'%', Some(v)) => {
                out.push(v);
                i += 3;
            }
            (c, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(s: &str) -> Result<RawMesh> {
        parse(s.as_bytes(), Path::new("test.vtk"))
    }

    const ASCII_42: &str = "# vtk DataFile Version 4.2
a title
ASCII

DATASET UNSTRUCTURED_GRID
FIELD FieldData 2
TIME 1 1 double
0.5
names 1 1 string
hello world
POINTS 5 float
0 0 0 1 0 0 0 1 0
0 0 1 1 1 1
METADATA
INFORMATION 0

CELLS 3 13
4 0 1 2 3
3 0 1 2
3 4 1 2
CELL_TYPES 3
10 5
10
CELL_DATA 3
SCALARS cell%20id int 1
LOOKUP_TABLE default
7 8 9
POINT_DATA 5
SCALARS s double
LOOKUP_TABLE default
0 1 2 3 4
VECTORS v float
1 2 3 4 5 6 7 8 9 10 11 12 13 14 15
FIELD FieldData 1
w 2 5 int
1 2 3 4 5 6 7 8 9 10
";

    #[test]
    fn ascii_legacy() {
        let m = parse_str(ASCII_42).unwrap_err();
        // cell 2 is a tet with 3 points
        assert!(m.to_string().contains("cell 2 (tetra) has 3 points"), "{m}");
        let src = ASCII_42.replace("3 4 1 2\n", "4 4 1 2 0\n").replace("CELLS 3 13", "CELLS 3 14");
        let m = parse_str(&src).unwrap();
        assert_eq!(m.points.len(), 5);
        assert_eq!(m.points[4], [1.0, 1.0, 1.0]);
        assert_eq!(m.tets, vec![[0, 1, 2, 3], [4, 1, 2, 0]]);
        let get = |n: &str| m.fields.iter().find(|f| f.name == n).unwrap_or_else(|| panic!("no field {n}"));
        assert_eq!(get("cell id").values, vec![7.0, 9.0]);
        assert_eq!(get("cell id").location, FieldLocation::Cell);
        assert_eq!(get("s").values, vec![0., 1., 2., 3., 4.]);
        assert_eq!(get("v[1]").values, vec![2., 5., 8., 11., 14.]);
        assert_eq!(get("w[0]").values, vec![1., 3., 5., 7., 9.]);
        assert_eq!(m.fields.len(), 1 + 1 + 3 + 2);
    }

    /// A second POINTS (CELLS, CELL_TYPES) section, or two attributes of one name at one
    /// location, is an error rather than one of them used silently; a point and a cell
    /// attribute of one name are two fields.
    #[test]
    fn repeated_sections_and_names_are_refused() {
        let ok = ASCII_42.replace("3 4 1 2\n", "4 4 1 2 0\n").replace("CELLS 3 13", "CELLS 3 14");
        let points = "POINTS 5 float\n0 0 0 1 0 0 0 1 0\n0 0 1 1 1 1\n";
        let types = "CELL_TYPES 3\n10 5\n10\n";
        let cases = [
            (ok.replace("METADATA", &format!("{points}METADATA")), "line 14: a second POINTS section"),
            (ok.replace("CELL_DATA 3", &format!("{types}CELL_DATA 3")), "a second CELL_TYPES section"),
            (
                ok.replace("VECTORS v float\n1 2 3 4 5 6 7 8 9 10 11 12 13 14 15", "SCALARS s float\n5 6 7 8 9"),
                "two point fields named 's'",
            ),
            (
                ok.replace("VECTORS v float", "VECTORS s float").replace("SCALARS s double", "SCALARS s[1] double"),
                "'s[1]'",
            ),
        ];
        for (src, want) in cases {
            let e = parse_str(&src).unwrap_err().to_string();
            assert!(e.starts_with("test.vtk") && e.contains(want), "{want}: {e}");
        }
        let m = parse_str(&ok.replace("cell%20id", "s")).unwrap();
        assert_eq!(m.fields.iter().filter(|f| f.name == "s").count(), 2, "a point and a cell 's'");
    }

    #[test]
    fn ascii_51_offsets() {
        let src = "# vtk DataFile Version 5.1\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n\
                   0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 3 5\nOFFSETS vtktypeint64\n0 4 5\n\
                   CONNECTIVITY vtktypeint64\n3 2 1 0 2\nCELL_TYPES 2\n10 1\n";
        let m = parse_str(src).unwrap();
        assert_eq!(m.tets, vec![[3, 2, 1, 0]]);
        let bad = src.replace("3 2 1 0 2", "3 2 1 7 2");
        assert!(parse_str(&bad).unwrap_err().to_string().contains("CONNECTIVITY: value 3"));
    }

    #[test]
    fn clear_errors() {
        let ok = ASCII_42.replace("3 4 1 2\n", "4 4 1 2 0\n").replace("CELLS 3 13", "CELLS 3 14");
        let cases = [
            (ok.replace("# vtk", "# vtx"), "not a VTK legacy file"),
            (ok.replace("ASCII", "TEXT"), "not ASCII or BINARY"),
            (ok.replace("UNSTRUCTURED_GRID", "POLYDATA"), "POLYDATA"),
            (ok.replace("CELL_TYPES 3\n10 5\n10", "CELL_TYPES 3\n10 5\n12"), "hexahedron"),
            (ok.replace("POINTS 5 float", "POINTS 5 floot"), "test.vtk: line 11: data type 'floot'"),
            (ok.replace("4 4 1 2 0", "4 4 1 2 9"), "uses point 9"),
            (ok.replace("4 4 1 2 0", "9 4 1 2 0"), "past the end"),
            (ok.replace("POINT_DATA 5", "POINT_DATA 6"), "'VECTORS' is not a valid Float64"),
            (ok.replace("CELL_DATA 3\n", ""), "before POINT_DATA"),
            (
                ok.replace("CELLS 3 14", "CELLS 3 1000000000000"),
                "test.vtk: line 18: CELLS: value 14: 'CELL_TYPES' is not a valid Int32",
            ),
            (ok.replace("POINTS 5 float", "POINTS 99999999999999999999 float"), "not a count"),
            (ok[..ok.find("CELL_TYPES").unwrap()].to_string(), "no CELL_TYPES"),
            (ok.replace("VECTORS", "VECTOR"), "unexpected keyword 'VECTOR'"),
        ];
        for (src, want) in cases {
            let e = parse_str(&src).unwrap_err().to_string();
            assert!(e.contains(want) && e.starts_with("test.vtk"), "{e:?} should say {want:?}");
        }
    }

    /// A VTK 9 BINARY file laid out as vtkUnstructuredGridWriter writes it: dataset field
    /// data, then FIELD blocks of two arrays each in CELL_DATA and POINT_DATA.
    pub(crate) fn binary_fields_file() -> Vec<u8> {
        let mut f: Vec<u8> = Vec::new();
        f.extend(b"# vtk DataFile Version 5.1\nvtk output\nBINARY\nDATASET UNSTRUCTURED_GRID\n");
        f.extend(b"FIELD FieldData 1\nTIME 1 1 double\n");
        f.extend(0.5f64.to_be_bytes());
        f.extend(b"\nPOINTS 4 float\n");
        for c in [0f32, 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1.] {
            f.extend(c.to_be_bytes());
        }
        f.extend(b"\nCELLS 2 4\nOFFSETS vtktypeint64\n");
        [0i64, 4].iter().for_each(|v| f.extend(v.to_be_bytes()));
        f.extend(b"\nCONNECTIVITY vtktypeint64\n");
        [0i64, 1, 2, 3].iter().for_each(|v| f.extend(v.to_be_bytes()));
        f.extend(b"\nCELL_TYPES 1\n");
        f.extend(10i32.to_be_bytes());
        f.extend(b"\n\nCELL_DATA 1\nFIELD FieldData 2\nc 1 1 double\n");
        f.extend(5f64.to_be_bytes());
        // Component names (or information keys) make VTK write a METADATA block after an array.
        f.extend(b"\nMETADATA\nCOMPONENT_NAMES\ncx\n\nd 1 1 double\n");
        f.extend(7f64.to_be_bytes());
        f.extend(b"\nPOINT_DATA 4\nFIELD FieldData 2\na 1 4 double\n");
        [1f64, 2., 3., 4.].iter().for_each(|v| f.extend(v.to_be_bytes()));
        f.extend(b"\nb 2 4 int\n");
        (1i32..=8).for_each(|v| f.extend(v.to_be_bytes()));
        f.extend(b"\n");
        f
    }

    /// Issue 29 item 15: a BINARY file whose FIELD blocks hold two arrays reads as its ASCII
    /// twin does.
    #[test]
    fn binary_field_blocks() {
        let ascii = "# vtk DataFile Version 5.1\nvtk output\nASCII\nDATASET UNSTRUCTURED_GRID\n\
                     FIELD FieldData 1\nTIME 1 1 double\n0.5 \nPOINTS 4 float\n0 0 0 1 0 0 0 1 0 \n0 0 1 \n\
                     CELLS 2 4\nOFFSETS vtktypeint64\n0 4 \nCONNECTIVITY vtktypeint64\n0 1 2 3 \n\
                     CELL_TYPES 1\n10\n\nCELL_DATA 1\nFIELD FieldData 2\nc 1 1 double\n5 \nMETADATA\nCOMPONENT_NAMES\ncx\n\n\
                     d 1 1 double\n7 \n\
                     POINT_DATA 4\nFIELD FieldData 2\na 1 4 double\n1 2 3 4 \nb 2 4 int\n1 2 3 4 5 6 7 8 \n";
        let want = parse_str(ascii).unwrap();
        let got = parse(&binary_fields_file(), Path::new("test.vtk")).unwrap_or_else(|e| panic!("{e}"));
        let show = |m: &RawMesh| m.fields.iter().map(|f| (f.name.clone(), f.values.clone())).collect::<Vec<_>>();
        assert_eq!(show(&got), show(&want));
        assert_eq!(show(&got).len(), 5, "c, d, a, b[0], b[1]");
        assert_eq!(got.tets, want.tets);
    }

    #[test]
    fn names() {
        assert_eq!(decode_name("a%20b%2"), "a b%2");
        assert_eq!(decode_name("%zz"), "%zz");
    }
}
