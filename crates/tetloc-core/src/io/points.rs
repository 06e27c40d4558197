//! Query points in, ids and values out: `.npy`, `.csv` and raw little-endian arrays
//! (`.bin`/`.f32`: f32 x,y,z triplets in; `.bin`: i32 ids or f32 values out), the layout of
//! the oracle data's `*.points.bin`.

use crate::error::{Error, Result};
use crate::geom::Vec3;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::Path;

fn ext(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

/// Reads query points: `.npy` (f32 or f64, shape (N, 3)), `.csv` (x,y,z per line, an
/// optional header line) or `.bin`/`.f32` (raw little-endian f32 triplets).
pub fn read_points(path: &Path) -> Result<Vec<Vec3>> {
    let points = match ext(path).as_str() {
        "npy" => read_points_npy(path)?,
        "csv" | "txt" => read_points_csv(path)?,
        "bin" | "f32" | "raw" => {
            let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
            if bytes.len() % 12 != 0 {
                return Err(Error::format(
                    path,
                    format!("{} bytes is not a whole number of f32 x,y,z triplets (12 bytes each)", bytes.len()),
                ));
            }
            bytes
                .chunks_exact(12)
                .map(|c| std::array::from_fn(|k| f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap())))
                .collect()
        }
        _ => {
            return Err(Error::UnknownFormat { path: path.to_path_buf(), known: "points: npy, csv, bin/f32" });
        }
    };
    if let Some(i) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(Error::format(path, format!("point {i} has a non-finite coordinate {:?}", points[i])));
    }
    Ok(points)
}

fn read_points_npy(path: &Path) -> Result<Vec<Vec3>> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let npy = npyz::NpyFile::new(BufReader::new(file))
        .map_err(|e| Error::format(path, format!("not a valid .npy file: {e}")))?;
    let shape = npy.shape().to_vec();
    if shape.len() != 2 || shape[1] != 3 {
        return Err(Error::format(path, format!("expected an array of shape (N, 3), found {shape:?}")));
    }
    if npy.order() != npyz::Order::C {
        return Err(Error::format(path, "Fortran-ordered arrays are not supported; save with np.ascontiguousarray"));
    }
    let dtype = npy.dtype().descr();
    let flat: Vec<f32> = match dtype.as_str() {
        "'<f4'" => npy.into_vec::<f32>().map_err(|e| Error::format(path, e.to_string()))?,
        "'<f8'" => npy
            .into_vec::<f64>()
            .map_err(|e| Error::format(path, e.to_string()))?
            .into_iter()
            .map(|x| x as f32)
            .collect(),
        other => {
            return Err(Error::format(
                path,
                format!("expected dtype float32 or float64 (little-endian), found {other}"),
            ))
        }
    };
    Ok(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

fn read_points_csv(path: &Path) -> Result<Vec<Vec3>> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut out = Vec::new();
    for (n, line) in BufReader::new(file).lines().enumerate() {
        let line = line.map_err(|e| Error::io(path, e))?;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> =
            line.split(|c: char| c == ',' || c == ';' || c.is_whitespace()).filter(|s| !s.is_empty()).collect();
        let parsed: std::result::Result<Vec<f32>, _> = fields.iter().map(|s| s.parse::<f32>()).collect();
        match parsed {
            Ok(v) if v.len() == 3 => out.push([v[0], v[1], v[2]]),
            // A header line (x,y,z) is allowed before the first point.
            Err(_) if out.is_empty() && n == 0 => continue,
            _ => {
                return Err(Error::format(
                    path,
                    format!("line {}: expected three numbers x,y,z, found '{line}'", n + 1),
                ))
            }
        }
    }
    Ok(out)
}

/// Writes tet ids: `.npy` (int32), `.csv` (one per line) or `.bin` (raw little-endian i32).
pub fn write_ids(path: &Path, ids: &[i32]) -> Result<()> {
    write_array(path, ids, "id")
}

/// Writes values: `.npy` (float32), `.csv` (one per line, `nan` outside) or `.bin`/`.f32` (raw little-endian f32).
pub fn write_values(path: &Path, values: &[f32]) -> Result<()> {
    write_array(path, values, "value")
}

fn write_array<T>(path: &Path, data: &[T], header: &str) -> Result<()>
where
    T: bytemuck::Pod + std::fmt::Display + npyz::AutoSerialize,
{
    let io = |e: std::io::Error| Error::io(path, e);
    let file = std::fs::File::create(path).map_err(io)?;
    let mut w = BufWriter::new(file);
    match ext(path).as_str() {
        "npy" => {
            use npyz::WriterBuilder;
            let mut npy = npyz::WriteOptions::new()
                .default_dtype()
                .shape(&[data.len() as u64])
                .writer(&mut w)
                .begin_nd()
                .map_err(io)?;
            npy.extend(data.iter()).map_err(io)?;
            npy.finish().map_err(io)?;
        }
        "csv" | "txt" => {
            writeln!(w, "{header}").map_err(io)?;
            for x in data {
                writeln!(w, "{x}").map_err(io)?;
            }
        }
        "bin" | "f32" | "i32" | "raw" => w.write_all(bytemuck::cast_slice(data)).map_err(io)?,
        _ => {
            return Err(Error::UnknownFormat {
                path: path.to_path_buf(),
                known: "npy, csv, bin (or vtu for a point set)",
            })
        }
    }
    w.flush().map_err(io)
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
        for e in ["npy", "csv", "bin"] {
            let p = tmp(&format!("ids.{e}"));
            write_ids(&p, &ids).unwrap();
            if e == "bin" {
                assert_eq!(std::fs::read(&p).unwrap(), bytemuck::cast_slice::<i32, u8>(&ids));
            }
        }
        let p = tmp("ids.npy");
        let npy = npyz::NpyFile::new(std::fs::File::open(&p).unwrap()).unwrap();
        assert_eq!(npy.into_vec::<i32>().unwrap(), ids);
        let p = tmp("v.csv");
        write_values(&p, &[1.5, f32::NAN]).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "value\n1.5\nNaN\n");
    }

    #[test]
    fn bad_points_files_are_clear_errors() {
        let p = tmp("bad.bin");
        std::fs::write(&p, [0u8; 13]).unwrap();
        assert!(read_points(&p).unwrap_err().to_string().contains("13 bytes is not a whole number"));
        let p = tmp("bad.csv");
        std::fs::write(&p, "1,2,3\n4,5\n").unwrap();
        assert!(read_points(&p).unwrap_err().to_string().contains("line 2"));
        let p = tmp("nan.csv");
        std::fs::write(&p, "1,nan,3\n").unwrap();
        assert!(read_points(&p).unwrap_err().to_string().contains("non-finite"));
        let p = tmp("bad.npy");
        std::fs::write(&p, b"not numpy").unwrap();
        assert!(read_points(&p).unwrap_err().to_string().contains("not a valid .npy"));
        assert!(read_points(Path::new("x.xyz")).is_err());
        assert!(read_points(Path::new("/nonexistent/p.bin")).unwrap_err().to_string().contains("/nonexistent/p.bin"));
    }
}
