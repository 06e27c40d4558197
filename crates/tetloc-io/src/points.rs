//! Query points in, ids and values out: `.npy`, `.csv` and raw little-endian arrays
//! (`.bin`/`.f32`: f32 x,y,z triplets in; `.bin`: i32 ids or f32 values out), the layout of
//! the oracle data's `*.points.bin`. Values keep their precision where the format says it:
//! `.npy` and `.csv` carry f64 values as f64, raw files are always f32.
//!
//! Points with a NaN or infinite coordinate are read as they are: they are in no cell, and
//! the locators answer them -1 / NaN (see [`tetloc_core::locate::FiniteOnly`]).
//!
//! Outputs are arrays (`.npy`, `.bin`: one array a file) or tables (`.csv`: every column,
//! `vtkValidPointMask` included, as ParaView's probe writes it), always written atomically.

pub use super::arrays::{check_value_name, Values, RESULT_NAMES, VALID_MASK};
use super::output::{extension, write_atomically};
use std::io::Write;
use std::path::Path;
use tetloc_core::error::{Error, Result};
use tetloc_core::geom::Vec3;

/// Extensions of the query-point files [`read_points`] reads.
pub const POINT_EXTENSIONS: &[&str] = &["npy", "csv", "txt", "bin", "f32", "raw"];
/// Extensions [`write_ids`] writes.
pub const ID_EXTENSIONS: &[&str] = &["npy", "csv", "txt", "bin", "i32", "raw"];
/// Extensions [`write_values`] writes.
pub const VALUE_EXTENSIONS: &[&str] = &["npy", "csv", "txt", "bin", "f32", "raw"];

/// Reads query points: `.npy` (f32 or f64, shape (N, 3)), `.csv` (x,y,z per line, an
/// optional `x,y,z` header line) or `.bin`/`.f32` (raw little-endian f32 triplets). Reads are
/// bounded (see [`super::read_file`]).
pub fn read_points(path: &Path) -> Result<Vec<Vec3>> {
    Ok(read_points64(path)?.into_iter().map(|p| p.map(|c| c as f32)).collect())
}

/// [`read_points`] at the file's precision: f64 `.npy` and text keep every digit (f32 data
/// widens exactly).
pub fn read_points64(path: &Path) -> Result<Vec<[f64; 3]>> {
    let ext = extension(path);
    if !POINT_EXTENSIONS.contains(&ext.as_str()) {
        return Err(Error::UnknownFormat { path: path.to_path_buf(), known: "points: npy, csv, bin/f32" });
    }
    let bytes = super::read_file(path)?;
    match ext.as_str() {
        "npy" => read_points_npy(path, &bytes),
        "csv" | "txt" => read_points_csv(path, &bytes),
        _ => {
            if bytes.len() % 12 != 0 {
                return Err(Error::format(
                    path,
                    format!("{} bytes is not a whole number of f32 x,y,z triplets (12 bytes each)", bytes.len()),
                ));
            }
            Ok(bytes
                .chunks_exact(12)
                .map(|c| std::array::from_fn(|k| f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap()) as f64))
                .collect())
        }
    }
}

fn read_points_npy(path: &Path, bytes: &[u8]) -> Result<Vec<[f64; 3]>> {
    let mut data = bytes;
    let header = npyz::NpyHeader::from_reader(&mut data)
        .map_err(|e| Error::format(path, format!("not a valid .npy file: {e}")))?;
    let shape = header.shape().to_vec();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(Error::format(path, format!("expected an array of shape (N, 3), found {shape:?}")));
    }
    if header.order() != npyz::Order::C {
        return Err(Error::format(path, "Fortran-ordered arrays are not supported; save with np.ascontiguousarray"));
    }
    let dtype = header.dtype().descr();
    let item = match dtype.as_str() {
        "'<f4'" => 4,
        "'<f8'" => 8,
        other => {
            return Err(Error::format(
                path,
                format!("expected dtype float32 or float64 (little-endian), found {other}"),
            ))
        }
    };
    let want = shape[0].saturating_mul(3 * item);
    if data.len() as u64 != want {
        let what = if (data.len() as u64) < want { "truncated" } else { "longer than its header says" };
        return Err(Error::format(
            path,
            format!(
                "{what}: the header says {} points of {}, {want} bytes of data, but the file holds {} bytes after its header",
                shape[0],
                if item == 4 { "float32" } else { "float64" },
                data.len()
            ),
        ));
    }
    let npy = npyz::NpyFile::with_header(header, data);
    let flat: Vec<f64> = if item == 4 {
        npy.into_vec::<f32>().map_err(|e| Error::format(path, e.to_string()))?.into_iter().map(f64::from).collect()
    } else {
        npy.into_vec::<f64>().map_err(|e| Error::format(path, e.to_string()))?
    };
    Ok(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// One point per line: three numbers separated by commas, semicolons or white space. Blank
/// lines and `#` comments are skipped. The first line may be a header only when it is not
/// numeric and names the columns x, y, z; any other line that does not parse is an error
/// with its line number, so that output rows always line up with input rows.
fn read_points_csv(path: &Path, bytes: &[u8]) -> Result<Vec<[f64; 3]>> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let line = 1 + bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count();
        Error::format(path, format!("line {line}: not UTF-8 text"))
    })?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text); // a byte-order mark (Excel's "CSV UTF-8")
    let mut out = Vec::new();
    let mut first = true;
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> =
            line.split(|c: char| c == ',' || c == ';' || c.is_whitespace()).filter(|s| !s.is_empty()).collect();
        let parsed: std::result::Result<Vec<f64>, _> = fields.iter().map(|s| s.parse::<f64>()).collect();
        match parsed {
            Ok(v) if v.len() == 3 => out.push([v[0], v[1], v[2]]),
            _ if first && is_xyz_header(&fields) => {}
            _ => {
                return Err(Error::format(
                    path,
                    format!(
                        "line {}: expected three numbers x,y,z, found '{}'",
                        n + 1,
                        tetloc_core::error::excerpt(line.as_bytes(), 80)
                    ),
                ))
            }
        }
        first = false;
    }
    Ok(out)
}

/// `x,y,z` in any case, each name optionally quoted.
fn is_xyz_header(fields: &[&str]) -> bool {
    let names: Vec<String> =
        fields.iter().map(|f| f.trim_matches(|c| c == '"' || c == '\'').to_ascii_lowercase()).collect();
    names == ["x", "y", "z"]
}

/// What a locate wrote for each point: the tet id (-1: no answer) and, when a field was
/// sampled, its name and values.
#[derive(Clone, Copy, Debug)]
pub struct Results<'a> {
    pub ids: &'a [i32],
    pub values: Option<(&'a str, Values<'a>)>,
}

impl Results<'_> {
    /// 1 for points that got an answer (inside a cell, or within the boundary tolerance),
    /// 0 for the others: VTK's `vtkValidPointMask`.
    pub fn valid_mask(&self) -> Vec<u8> {
        self.ids.iter().map(|&i| u8::from(i >= 0)).collect()
    }

    fn check(&self) -> Result<()> {
        match self.values {
            Some((name, v)) if v.len() != self.ids.len() => {
                Err(Error::Invalid(format!("{} tet ids but {} values of '{name}'", self.ids.len(), v.len())))
            }
            Some((name, _)) => check_value_name(name),
            None => Ok(()),
        }
    }
}

/// Writes the tet ids: `.npy` (int32) or `.bin` (raw little-endian i32), or `.csv`, the whole
/// table: `tet_id`, the values when there are some, and `vtkValidPointMask`.
pub fn write_ids(path: &Path, r: &Results) -> Result<()> {
    r.check()?;
    match extension(path).as_str() {
        "csv" | "txt" => write_csv(path, r, true),
        "npy" | "bin" | "i32" | "raw" => write_array(path, r.ids),
        _ => Err(unknown_output(path, ID_EXTENSIONS)),
    }
}

/// Writes the sampled values: `.npy` (float32, or float64 for f64 values) or `.bin`/`.f32`
/// (raw little-endian f32, f64 values rounded once), NaN where there is no answer; or `.csv`:
/// the field's column (every digit of f64 values) and `vtkValidPointMask`.
pub fn write_values(path: &Path, r: &Results) -> Result<()> {
    r.check()?;
    let Some((_, values)) = r.values else {
        return Err(Error::Invalid(format!("{}: no values to write", path.display())));
    };
    match extension(path).as_str() {
        "csv" | "txt" => write_csv(path, r, false),
        "npy" => match values {
            Values::F32(v) => write_array(path, v),
            Values::F64(v) => write_array(path, v),
        },
        "bin" | "f32" | "raw" => match values {
            Values::F32(v) => write_array(path, v),
            Values::F64(v) => write_array(path, &v.iter().map(|&x| x as f32).collect::<Vec<f32>>()),
        },
        _ => Err(unknown_output(path, VALUE_EXTENSIONS)),
    }
}

fn unknown_output(path: &Path, known: &[&str]) -> Error {
    Error::format(path, format!("unknown output format (known: {})", known.join(", ")))
}

/// A CSV table, one row per point in input order.
fn write_csv(path: &Path, r: &Results, with_ids: bool) -> Result<()> {
    let mask = r.valid_mask();
    write_atomically(path, |w| {
        let io = |e| Error::io(path, e);
        let mut header = Vec::new();
        if with_ids {
            header.push("tet_id".to_string());
        }
        if let Some((name, _)) = r.values {
            header.push(csv_field(name));
        }
        header.push(VALID_MASK.to_string());
        writeln!(w, "{}", header.join(",")).map_err(io)?;
        for (i, (id, m)) in r.ids.iter().zip(&mask).enumerate() {
            if with_ids {
                write!(w, "{id},").map_err(io)?;
            }
            if let Some((_, v)) = r.values {
                write!(w, "{},", v.text(i)).map_err(io)?;
            }
            writeln!(w, "{m}").map_err(io)?;
        }
        Ok(())
    })
}

/// A CSV header field, quoted when it holds a separator or a quote.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn write_array<T>(path: &Path, data: &[T]) -> Result<()>
where
    T: bytemuck::Pod + npyz::AutoSerialize,
{
    write_atomically(path, |w| {
        let io = |e: std::io::Error| Error::io(path, e);
        if extension(path) == "npy" {
            use npyz::WriterBuilder;
            let mut npy = npyz::WriteOptions::new()
                .default_dtype()
                .shape(&[data.len() as u64])
                .writer(w)
                .begin_nd()
                .map_err(io)?;
            npy.extend(data.iter()).map_err(io)?;
            npy.finish().map_err(io)?;
        } else {
            w.write_all(bytemuck::cast_slice(data)).map_err(io)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("tetloc-points-{}-{name}", std::process::id()))
    }

    #[test]
    fn every_points_format_reads_the_oracle_points() {
        let Some(dir) = crate::test_support::require_data("every_points_format_reads_the_oracle_points") else {
            return;
        };
        let bin = read_points(&dir.join("torus_s.random.points.bin")).unwrap();
        assert_eq!(bin.len(), 20000);
        // CSV written by hand, npy written by us: all three give the same points.
        let csv = tmp("p.csv");
        let mut s = String::from("x,y,z\n");
        for p in &bin {
            s += &format!("{:?},{:?},{:?}\n", p[0], p[1], p[2]);
        }
        std::fs::write(&csv, s).unwrap();
        assert_eq!(read_points(&csv).unwrap(), bin);
        let npy = tmp("p.npy");
        {
            use npyz::WriterBuilder;
            let mut w = std::io::BufWriter::new(std::fs::File::create(&npy).unwrap());
            let mut n = npyz::WriteOptions::new()
                .default_dtype()
                .shape(&[bin.len() as u64, 3])
                .writer(&mut w)
                .begin_nd()
                .unwrap();
            n.extend(bin.iter().flat_map(|p| p.iter().map(|&c| c as f64))).unwrap();
            n.finish().unwrap();
        }
        assert_eq!(read_points(&npy).unwrap(), bin);
    }

    #[test]
    fn ids_and_values_round_trip() {
        let ids = vec![3, -1, 7, 0];
        let r = Results { ids: &ids, values: None };
        for e in ["npy", "csv", "bin"] {
            let p = tmp(&format!("ids.{e}"));
            write_ids(&p, &r).unwrap();
            if e == "bin" {
                assert_eq!(std::fs::read(&p).unwrap(), bytemuck::cast_slice::<i32, u8>(&ids));
            }
        }
        let p = tmp("ids.npy");
        let npy = npyz::NpyFile::new(std::fs::File::open(&p).unwrap()).unwrap();
        assert_eq!(npy.into_vec::<i32>().unwrap(), ids);
        assert_eq!(std::fs::read_to_string(tmp("ids.csv")).unwrap(), "tet_id,vtkValidPointMask\n3,1\n-1,0\n7,1\n0,1\n");
        // Values: the field's column and the mask; a table with ids carries everything.
        let ids = [2, -1];
        let r = Results { ids: &ids, values: Some(("f, g", Values::F32(&[1.5, f32::NAN]))) };
        let p = tmp("v.csv");
        write_values(&p, &r).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "\"f, g\",vtkValidPointMask\n1.5,1\nNaN,0\n");
        write_ids(&p, &r).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "tet_id,\"f, g\",vtkValidPointMask\n2,1.5,1\n-1,NaN,0\n");
        let p = tmp("v.f32");
        write_values(&p, &r).unwrap();
        assert_eq!(std::fs::read(&p).unwrap().len(), 8);
    }

    /// f64 values keep every digit in `.npy` (float64) and `.csv`; raw files stay f32.
    #[test]
    fn f64_values_keep_their_precision_where_the_format_can() {
        let v = [0.1f64 + 1e-12, f64::NAN];
        let r = Results { ids: &[0, -1], values: Some(("f", Values::F64(&v))) };
        let p = tmp("v64.npy");
        write_values(&p, &r).unwrap();
        let got = npyz::NpyFile::new(std::fs::File::open(&p).unwrap()).unwrap().into_vec::<f64>().unwrap();
        assert_eq!(got[0], v[0]);
        assert!(got[1].is_nan());
        let p = tmp("v64.csv");
        write_values(&p, &r).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert_eq!(text.lines().nth(1).unwrap().split(',').next().unwrap().parse::<f64>().unwrap(), v[0], "{text}");
        let p = tmp("v64.f32");
        write_values(&p, &r).unwrap();
        let raw: Vec<f32> = bytemuck::pod_collect_to_vec(&std::fs::read(&p).unwrap());
        assert_eq!(raw[0], v[0] as f32);
        assert!(raw[1].is_nan());
    }

    #[test]
    fn an_unknown_output_extension_creates_nothing() {
        let p = tmp("o.h5");
        let _ = std::fs::remove_file(&p);
        let e = write_ids(&p, &Results { ids: &[1], values: None }).unwrap_err().to_string();
        assert!(e.contains("o.h5") && e.contains("unknown output format"), "{e}");
        assert!(!p.exists());
        let e =
            write_values(&p, &Results { ids: &[1], values: Some(("f", Values::F32(&[1.0]))) }).unwrap_err().to_string();
        assert!(e.contains("unknown output format"), "{e}");
        assert!(!p.exists());
    }

    #[test]
    fn bad_points_files_are_clear_errors() {
        let p = tmp("bad.bin");
        std::fs::write(&p, [0u8; 13]).unwrap();
        assert!(read_points(&p).unwrap_err().to_string().contains("13 bytes is not a whole number"));
        let p = tmp("bad.csv");
        std::fs::write(&p, "1,2,3\n4,5\n").unwrap();
        assert!(read_points(&p).unwrap_err().to_string().contains("line 2"));
        let p = tmp("bad.npy");
        std::fs::write(&p, b"not numpy").unwrap();
        assert!(read_points(&p).unwrap_err().to_string().contains("not a valid .npy"));
        assert!(read_points(Path::new("x.xyz")).is_err());
        assert!(read_points(Path::new("/nonexistent/p.bin")).unwrap_err().to_string().contains("/nonexistent/p.bin"));
    }

    /// A first line that does not parse is a header only when it names x, y, z; otherwise it
    /// is an error with its line number (it used to be dropped silently, shifting every row).
    #[test]
    fn a_bad_first_csv_line_is_an_error_not_a_header() {
        for (text, line) in [
            ("1.0D-01,0.2,0.3\n1,2,3\n", 1),
            ("a,b,c\n1,2,3\n", 1),
            ("x,y\n1,2,3\n", 1),
            ("# comment\n\nlon,lat,depth\n1,2,3\n", 3),
            ("x,y,z\n1,2,3\nx,y,z\n", 3),
            ("1,2,3\n4,5,6,7\n", 2),
        ] {
            let p = tmp("first.csv");
            std::fs::write(&p, text).unwrap();
            let e = read_points(&p).unwrap_err().to_string();
            assert!(e.contains("first.csv") && e.contains(&format!("line {line}:")), "{text:?}: {e}");
        }
        for header in ["x,y,z", "X, Y, Z", "\"x\";\"y\";\"z\"", "x y z"] {
            let p = tmp("header.csv");
            std::fs::write(&p, format!("# points\n{header}\n1,2,3\n4 5 6\n")).unwrap();
            assert_eq!(read_points(&p).unwrap(), vec![[1., 2., 3.], [4., 5., 6.]], "{header}");
        }
    }

    /// NaN and infinite coordinates are read: such a point is answered -1 / NaN, not a
    /// refusal of the whole file.
    #[test]
    fn non_finite_points_are_read() {
        let p = tmp("nan.csv");
        std::fs::write(&p, "1,nan,3\ninf,0,0\n0,0,0\n").unwrap();
        let pts = read_points(&p).unwrap();
        assert_eq!(pts.len(), 3);
        assert!(pts[0][1].is_nan() && pts[1][0].is_infinite() && pts[2] == [0.0; 3]);
    }

    /// A truncated .npy names the file and says how many bytes the header promised and how
    /// many there are (it used to say only "failed to fill whole buffer").
    #[test]
    fn a_truncated_npy_says_what_is_missing() {
        let p = tmp("cut.npy");
        let mut bytes = Vec::new();
        {
            use npyz::WriterBuilder;
            let mut n =
                npyz::WriteOptions::new().default_dtype().shape(&[100, 3]).writer(&mut bytes).begin_nd().unwrap();
            n.extend((0..300).map(|i| i as f32)).unwrap();
            n.finish().unwrap();
        }
        std::fs::write(&p, &bytes[..bytes.len() - 7]).unwrap();
        let e = read_points(&p).unwrap_err().to_string();
        assert!(
            e.contains("cut.npy") && e.contains("truncated") && e.contains("1200 bytes") && e.contains("1193"),
            "{e}"
        );
        std::fs::write(&p, &bytes).unwrap();
        assert_eq!(read_points(&p).unwrap().len(), 100);
    }

    /// Points from a pipe or a device are read up to a cap, not until memory runs out.
    #[cfg(unix)]
    #[test]
    fn devices_are_read_boundedly() {
        let e = read_points(Path::new("/dev/null.bin")).unwrap_err().to_string();
        assert!(e.contains("/dev/null.bin"), "{e}");
        // /dev/zero as a mesh: refused after the cap, quickly, with the file named.
        let e = crate::read_mesh(Path::new("/dev/zero"), Some(crate::MeshFormat::Vtu)).unwrap_err().to_string();
        assert!(e.contains("/dev/zero") && e.contains("not a regular file"), "{e}");
        let e = crate::read_mesh(Path::new("/dev/zero"), Some(crate::MeshFormat::Gmsh)).unwrap_err().to_string();
        assert!(e.contains("/dev/zero") && e.contains("not a regular file"), "{e}");
    }
}
