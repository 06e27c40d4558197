//! Surface readers. Each returns a message without the file name; the caller adds it.

use super::TriMesh;
use crate::vec::Vec3;

type Parsed = Result<TriMesh, String>;

/// Wavefront OBJ: `v` lines and `f` lines (`i`, `i/t`, `i//n`, `i/t/n`, negative indices
/// relative to the end); polygons are fanned into triangles; everything else is ignored.
pub fn parse_obj(bytes: &[u8]) -> Parsed {
    let text = std::str::from_utf8(bytes).map_err(|e| format!("not a text file: {e}"))?;
    let mut m = TriMesh::default();
    for (ln, line) in text.lines().enumerate() {
        let ln = ln + 1;
        let mut tok = line.split_whitespace();
        match tok.next() {
            Some("v") => {
                let mut p = [0f32; 3];
                for (k, c) in p.iter_mut().enumerate() {
                    let s = tok.next().ok_or(format!("line {ln}: vertex has {k} coordinates, expected 3"))?;
                    *c = s.parse().map_err(|_| format!("line {ln}: '{s}' is not a number"))?;
                }
                m.positions.push(p);
            }
            Some("f") => {
                let n = m.positions.len() as i64;
                let ids = tok
                    .map(|t| {
                        let first = t.split('/').next().unwrap_or("");
                        let i: i64 = first.parse().map_err(|_| format!("line {ln}: '{t}' is not a vertex index"))?;
                        let idx = if i < 0 { n + i } else { i - 1 };
                        if i == 0 || idx < 0 || idx >= n {
                            return Err(format!(
                                "line {ln}: vertex index {i} out of range (there are {n} vertices so far)"
                            ));
                        }
                        Ok(idx as u32)
                    })
                    .collect::<Result<Vec<u32>, String>>()?;
                if ids.len() < 3 {
                    return Err(format!("line {ln}: a face needs at least 3 vertices, found {}", ids.len()));
                }
                for k in 1..ids.len() - 1 {
                    m.triangles.push([ids[0], ids[k], ids[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok(m)
}

/// STL, binary (when the size is exactly 84 + 50·n for the n in its header, which also
/// catches binary files whose header starts with "solid") or ascii.
pub fn parse_stl(bytes: &[u8]) -> Parsed {
    if bytes.len() >= 84 {
        let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize;
        if bytes.len() as u64 == 84 + 50 * n as u64 {
            let mut m = TriMesh::default();
            for rec in bytes[84..].chunks_exact(50) {
                let f = |o: usize| f32::from_le_bytes(rec[o..o + 4].try_into().unwrap());
                let base = m.positions.len() as u32;
                for v in 0..3 {
                    let o = 12 + 12 * v;
                    m.positions.push([f(o), f(o + 4), f(o + 8)]);
                }
                m.triangles.push([base, base + 1, base + 2]);
            }
            return Ok(m);
        }
    }
    let starts_solid = bytes.iter().skip_while(|b| b.is_ascii_whitespace()).take(5).eq(b"solid".iter());
    if !starts_solid {
        let header_n = if bytes.len() >= 84 { u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as u64 } else { 0 };
        return Err(format!(
            "not an STL file: ascii STL starts with 'solid', and binary STL is 84 + 50·n bytes \
             (the header says n = {header_n}, so {} bytes, but the file has {})",
            84 + 50 * header_n,
            bytes.len()
        ));
    }
    let text = std::str::from_utf8(bytes).map_err(|e| format!("ascii STL that is not text: {e}"))?;
    let mut m = TriMesh::default();
    let mut facet: Option<(usize, Vec<Vec3>)> = None;
    for (ln, line) in text.lines().enumerate() {
        let ln = ln + 1;
        let mut tok = line.split_whitespace();
        match tok.next() {
            Some("facet") => facet = Some((ln, Vec::new())),
            Some("vertex") => {
                let (_, vs) = facet.as_mut().ok_or(format!("line {ln}: 'vertex' outside a facet"))?;
                let mut p = [0f32; 3];
                for (k, c) in p.iter_mut().enumerate() {
                    let s = tok.next().ok_or(format!("line {ln}: vertex has {k} coordinates, expected 3"))?;
                    *c = s.parse().map_err(|_| format!("line {ln}: '{s}' is not a number"))?;
                }
                vs.push(p);
            }
            Some("endfacet") => {
                let (start, vs) = facet.take().ok_or(format!("line {ln}: 'endfacet' without 'facet'"))?;
                if vs.len() != 3 {
                    return Err(format!("line {start}: facet has {} vertices, expected 3", vs.len()));
                }
                let base = m.positions.len() as u32;
                m.positions.extend(vs);
                m.triangles.push([base, base + 1, base + 2]);
            }
            _ => {}
        }
    }
    if let Some((start, _)) = facet {
        return Err(format!("line {start}: facet is not closed by 'endfacet' (file truncated?)"));
    }
    Ok(m)
}

/// VTK legacy POLYDATA, ascii or binary (big-endian), with classic cell arrays
/// (`POLYGONS n size` then `count i0 i1 ...`) or the 5.x layout (`OFFSETS`, `CONNECTIVITY`).
/// Polygons are fanned, triangle strips split; vertices and lines are skipped; reading stops
/// at the first attribute section (POINT_DATA, CELL_DATA).
pub fn parse_vtk_polydata(bytes: &[u8]) -> Parsed {
    let mut r = Reader { b: bytes, pos: 0, binary: false };
    let first = r.line();
    if !first.starts_with("# vtk DataFile Version") {
        return Err("not a VTK legacy file: the first line should be '# vtk DataFile Version x.y'".into());
    }
    r.line(); // title
    match r.line().trim().to_ascii_uppercase().as_str() {
        "ASCII" => {}
        "BINARY" => r.binary = true,
        other => return Err(format!("line 3 should be ASCII or BINARY, found '{other}'")),
    }
    let ds = r.token().ok_or("no DATASET line")?;
    let kind = r.token().unwrap_or_default();
    if !ds.eq_ignore_ascii_case("DATASET") || !kind.eq_ignore_ascii_case("POLYDATA") {
        return Err(format!("'{ds} {kind}': --surface reads only DATASET POLYDATA (polygons)"));
    }
    let mut m = TriMesh::default();
    let mut have_points = false;
    while let Some(key) = r.token() {
        match key.to_ascii_uppercase().as_str() {
            "POINTS" => {
                let n = r.count("POINTS")?;
                let ty = r.token().ok_or("POINTS: missing data type")?;
                let v = r.values(3 * n, &ty, "POINTS")?;
                m.positions = v.chunks_exact(3).map(|c| [c[0] as f32, c[1] as f32, c[2] as f32]).collect();
                have_points = true;
            }
            kw @ ("POLYGONS" | "TRIANGLE_STRIPS" | "VERTICES" | "LINES") => {
                let cells = r.cells(kw)?;
                if kw == "POLYGONS" || kw == "TRIANGLE_STRIPS" {
                    if !have_points {
                        return Err(format!("{kw} before POINTS"));
                    }
                    let n = m.positions.len() as i64;
                    for (c, ids) in cells.iter().enumerate() {
                        if let Some(&bad) = ids.iter().find(|&&i| i < 0 || i >= n) {
                            return Err(format!("{kw} cell {c} references point {bad} but there are {n} points"));
                        }
                        let ids: Vec<u32> = ids.iter().map(|&i| i as u32).collect();
                        for k in 2..ids.len() {
                            m.triangles.push(match kw {
                                "POLYGONS" => [ids[0], ids[k - 1], ids[k]],
                                _ if k % 2 == 0 => [ids[k - 2], ids[k - 1], ids[k]],
                                _ => [ids[k - 1], ids[k - 2], ids[k]],
                            });
                        }
                    }
                }
            }
            "METADATA" => r.skip_metadata(),
            "POINT_DATA" | "CELL_DATA" | "FIELD" => break,
            other => return Err(format!("unexpected keyword '{other}' in POLYDATA")),
        }
    }
    if !have_points {
        return Err("no POINTS section".into());
    }
    Ok(m)
}

/// A cursor over a VTK legacy file: whitespace tokens for the keywords, ascii numbers or
/// big-endian binary blocks for the data.
struct Reader<'a> {
    b: &'a [u8],
    pos: usize,
    binary: bool,
}

impl Reader<'_> {
    fn line(&mut self) -> String {
        let rest = &self.b[self.pos.min(self.b.len())..];
        let end = rest.iter().position(|&c| c == b'\n').unwrap_or(rest.len());
        self.pos += (end + 1).min(rest.len());
        String::from_utf8_lossy(&rest[..end]).trim_end_matches('\r').to_string()
    }

    fn token(&mut self) -> Option<String> {
        while self.pos < self.b.len() && self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        let start = self.pos;
        while self.pos < self.b.len() && !self.b[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        (self.pos > start).then(|| String::from_utf8_lossy(&self.b[start..self.pos]).into_owned())
    }

    fn count(&mut self, what: &str) -> Result<usize, String> {
        let t = self.token().ok_or(format!("{what}: missing count"))?;
        t.parse().map_err(|_| format!("{what}: '{t}' is not a count"))
    }

    /// `n` numbers of VTK type `ty`, as f64 (exact for every index and coordinate type).
    fn values(&mut self, n: usize, ty: &str, what: &str) -> Result<Vec<f64>, String> {
        if !self.binary {
            return (0..n)
                .map(|i| {
                    let t = self.token().ok_or(format!("{what}: file ends after {i} of {n} values"))?;
                    t.parse::<f64>().map_err(|_| format!("{what}: value {i} '{t}' is not a number"))
                })
                .collect();
        }
        let size = match ty.to_ascii_lowercase().as_str() {
            "float" | "int" | "unsigned_int" | "vtktypeint32" => 4,
            "double" | "long" | "unsigned_long" | "vtktypeint64" | "vtkidtype" => 8,
            other => return Err(format!("{what}: unsupported binary data type '{other}'")),
        };
        // The block starts after the rest of the keyword line.
        self.line();
        let end = self.pos + n * size;
        if end > self.b.len() {
            return Err(format!("{what}: binary block of {n} × {size} bytes runs past the end of the file"));
        }
        let data = &self.b[self.pos..end];
        self.pos = end;
        let ty = ty.to_ascii_lowercase();
        Ok(data
            .chunks_exact(size)
            .map(|c| match (ty.as_str(), size) {
                ("float", _) => f32::from_be_bytes(c.try_into().unwrap()) as f64,
                ("double", _) => f64::from_be_bytes(c.try_into().unwrap()),
                ("unsigned_int", _) => u32::from_be_bytes(c.try_into().unwrap()) as f64,
                ("unsigned_long", _) => u64::from_be_bytes(c.try_into().unwrap()) as f64,
                (_, 4) => i32::from_be_bytes(c.try_into().unwrap()) as f64,
                _ => i64::from_be_bytes(c.try_into().unwrap()) as f64,
            })
            .collect())
    }

    /// A cell array in either layout, as lists of point ids.
    fn cells(&mut self, what: &str) -> Result<Vec<Vec<i64>>, String> {
        let n = self.count(what)?;
        let size = self.count(what)?;
        let save = self.pos;
        if self.token().is_some_and(|t| t.eq_ignore_ascii_case("OFFSETS")) {
            // 5.x: n offsets, then `size` connectivity entries.
            let ty = self.token().ok_or(format!("{what}: OFFSETS without a data type"))?;
            let offsets = self.values(n, &ty, what)?;
            match self.token() {
                Some(t) if t.eq_ignore_ascii_case("CONNECTIVITY") => {}
                _ => return Err(format!("{what}: OFFSETS not followed by CONNECTIVITY")),
            }
            let ty = self.token().ok_or(format!("{what}: CONNECTIVITY without a data type"))?;
            let conn = self.values(size, &ty, what)?;
            let mut cells = Vec::with_capacity(n.saturating_sub(1));
            for w in offsets.windows(2) {
                let (a, b) = (w[0] as usize, w[1] as usize);
                if a > b || b > conn.len() {
                    return Err(format!("{what}: offsets {a}..{b} do not fit {} connectivity entries", conn.len()));
                }
                cells.push(conn[a..b].iter().map(|&i| i as i64).collect());
            }
            return Ok(cells);
        }
        self.pos = save;
        let flat = self.values(size, "int", what)?;
        let mut cells = Vec::with_capacity(n);
        let mut i = 0;
        for c in 0..n {
            let k =
                *flat.get(i).ok_or(format!("{what}: {size} numbers hold fewer than the {n} cells announced"))? as usize;
            let ids = flat
                .get(i + 1..i + 1 + k)
                .ok_or(format!("{what}: cell {c} with {k} points runs past the {size} numbers announced"))?;
            cells.push(ids.iter().map(|&x| x as i64).collect());
            i += 1 + k;
        }
        Ok(cells)
    }

    /// A METADATA block ends at the first blank line.
    fn skip_metadata(&mut self) {
        self.line();
        while self.pos < self.b.len() && !self.line().trim().is_empty() {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obj_faces_are_fanned_and_indices_resolved() {
        let m = parse_obj(b"# quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\nf -4 -3 -2\n")
            .unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 2]]);
    }

    #[test]
    fn obj_errors_name_the_line() {
        let e = parse_obj(b"v 0 0 0\nv 1 x 0\n").unwrap_err();
        assert!(e.contains("line 2") && e.contains("'x'"), "{e}");
        let e = parse_obj(b"v 0 0 0\nf 1 2 3\n").unwrap_err();
        assert!(e.contains("line 2") && e.contains("index 2 out of range"), "{e}");
        let e = parse_obj(b"v 0 0 0\nv 0 0 0\nf 1 2\n").unwrap_err();
        assert!(e.contains("at least 3"), "{e}");
    }

    fn binary_stl(tris: &[[Vec3; 3]], header: &[u8]) -> Vec<u8> {
        let mut b = vec![0u8; 80];
        b[..header.len()].copy_from_slice(header);
        b.extend((tris.len() as u32).to_le_bytes());
        for t in tris {
            b.extend([0u8; 12]);
            for v in t {
                for c in v {
                    b.extend(c.to_le_bytes());
                }
            }
            b.extend([0u8; 2]);
        }
        b
    }

    #[test]
    fn stl_binary_and_ascii() {
        let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        // A binary file whose header starts with "solid" is still read as binary.
        let m = parse_stl(&binary_stl(&[tri, tri], b"solid but binary")).unwrap();
        assert_eq!(m.triangles.len(), 2);
        assert_eq!(m.positions[4], [1.0, 0.0, 0.0]);
        let ascii = "solid t\nfacet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 1 0\n endloop\nendfacet\nendsolid t\n";
        let m = parse_stl(ascii.as_bytes()).unwrap();
        assert_eq!(m.positions, tri.to_vec());
    }

    #[test]
    fn stl_errors() {
        let mut b = binary_stl(&[[[0.0; 3]; 3]], b"x");
        b.pop();
        let e = parse_stl(&b).unwrap_err();
        assert!(e.contains("not an STL file") && e.contains("133"), "{e}");
        let e = parse_stl(b"solid t\nfacet normal 0 0 1\nvertex 0 0 0\nvertex 1 0 0\nendfacet\n").unwrap_err();
        assert!(e.contains("line 2: facet has 2 vertices"), "{e}");
        let e = parse_stl(b"solid t\nfacet normal 0 0 1\nvertex 0 0 0\n").unwrap_err();
        assert!(e.contains("not closed"), "{e}");
    }

    const VTK_ASCII: &str =
        "# vtk DataFile Version 3.0\nsquare\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n0 0 0 1 0 0 1 1 0 0 1 0\n\
        LINES 1 3\n2 0 1\nPOLYGONS 1 5\n4 0 1 2 3\nPOINT_DATA 4\nSCALARS s float 1\nLOOKUP_TABLE default\n0 1 2 3\n";

    #[test]
    fn vtk_ascii_classic() {
        let m = parse_vtk_polydata(VTK_ASCII.as_bytes()).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn vtk_5_offsets_and_strips() {
        let text = "# vtk DataFile Version 5.1\ns\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n0 0 0 1 0 0 0 1 0 1 1 0\n\
            METADATA\nINFORMATION 0\n\nTRIANGLE_STRIPS 2 4\nOFFSETS vtktypeint64\n0 4\nCONNECTIVITY vtktypeint64\n0 1 2 3\n";
        let m = parse_vtk_polydata(text.as_bytes()).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [2, 1, 3]]);
    }

    #[test]
    fn vtk_binary() {
        let mut b = b"# vtk DataFile Version 3.0\nbin\nBINARY\nDATASET POLYDATA\nPOINTS 3 double\n".to_vec();
        for c in [0.0f64, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 2.0, 0.0] {
            b.extend(c.to_be_bytes());
        }
        b.extend(b"\nPOLYGONS 1 4\n");
        for i in [3i32, 0, 1, 2] {
            b.extend(i.to_be_bytes());
        }
        b.push(b'\n');
        let m = parse_vtk_polydata(&b).unwrap();
        assert_eq!(m.positions[1], [2.0, 0.0, 0.0]);
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn vtk_errors() {
        let e = parse_vtk_polydata(b"hello\n").unwrap_err();
        assert!(e.contains("not a VTK legacy file"), "{e}");
        let grid = VTK_ASCII.replace("POLYDATA", "UNSTRUCTURED_GRID");
        assert!(parse_vtk_polydata(grid.as_bytes()).unwrap_err().contains("only DATASET POLYDATA"));
        let bad_id = VTK_ASCII.replace("4 0 1 2 3", "4 0 1 2 9");
        let e = parse_vtk_polydata(bad_id.as_bytes()).unwrap_err();
        assert!(e.contains("references point 9"), "{e}");
        let short = VTK_ASCII.replace("0 0 0 1 0 0 1 1 0 0 1 0\nLINES 1 3\n2 0 1\nPOLYGONS 1 5\n4 0 1 2 3\nPOINT_DATA 4\nSCALARS s float 1\nLOOKUP_TABLE default\n0 1 2 3\n", "0 0 0 1\n");
        let e = parse_vtk_polydata(short.as_bytes()).unwrap_err();
        assert!(e.contains("POINTS") && e.contains("4 of 12"), "{e}");
    }
}
