//! Images out, written as they are sampled: `.npy` (one float32 array of shape (NZ, NY, NX)
//! or (NZ, NY, NX, k), x fastest, NaN where a point got no value) or VTK `.vti` (ImageData:
//! every array plus `vtkValidPointMask`, see [`super::vtk::vti`]). Points arrive in chunks
//! in grid order, so memory stays bounded for any image size; the file appears complete or
//! not at all (see [`super::output`]).

pub use super::arrays::ImageArray;
use super::output::{extension, AtomicFile};
use super::vtk::vti::VtiWriter;
use std::io::Write;
use std::path::Path;
use tetloc_core::error::{Error, Result};
use tetloc_core::geom::ImageGrid;

/// Extensions [`ImageWriter`] writes.
pub const IMAGE_EXTENSIONS: &[&str] = &["vti", "npy"];

/// An image being written, chunk after chunk in grid order (x fastest).
pub struct ImageWriter {
    out: Out,
    /// Values per point: the components of every array.
    width: usize,
    written: usize,
    total: usize,
    path: std::path::PathBuf,
}

enum Out {
    Npy(AtomicFile),
    Vti(VtiWriter),
}

impl ImageWriter {
    /// Starts writing `path` (`.npy`: exactly one array; `.vti`: any number, zlib-compressed
    /// when `zlib`).
    pub fn create(path: &Path, grid: &ImageGrid, arrays: &[ImageArray], zlib: bool) -> Result<ImageWriter> {
        let width = arrays.iter().map(|a| a.n_components).sum();
        let out = match extension(path).as_str() {
            "npy" => {
                let [a] = arrays else {
                    return Err(Error::format(
                        path,
                        format!(
                            ".npy holds one array but {} were asked for ({}); sample one field, or write .vti",
                            arrays.len(),
                            arrays.iter().map(|a| format!("'{}'", a.name)).collect::<Vec<_>>().join(", ")
                        ),
                    ));
                };
                let [nx, ny, nz] = grid.dims;
                let mut shape = vec![nz, ny, nx];
                if a.n_components > 1 {
                    shape.push(a.n_components);
                }
                let mut f = AtomicFile::create(path)?;
                f.write_all(&npy_header("<f4", &shape)).map_err(|e| Error::io(path, e))?;
                Out::Npy(f)
            }
            "vti" => Out::Vti(VtiWriter::create(path, grid, arrays, zlib)?),
            _ => {
                return Err(Error::format(
                    path,
                    format!("unknown image format (known: {})", IMAGE_EXTENSIONS.join(", ")),
                ))
            }
        };
        Ok(ImageWriter { out, width, written: 0, total: grid.n_points(), path: path.to_path_buf() })
    }

    /// The next points' answers: `ids` (-1: no value) and `values` (every array's components
    /// per point, in array order).
    pub fn push(&mut self, ids: &[i32], values: &[f32]) -> Result<()> {
        if values.len() != ids.len() * self.width || self.written + ids.len() > self.total {
            return Err(Error::Invalid(format!(
                "{}: a chunk of {} points and {} values does not fit an image of {} points with {} values each ({} written)",
                self.path.display(),
                ids.len(),
                values.len(),
                self.total,
                self.width,
                self.written
            )));
        }
        match &mut self.out {
            Out::Npy(f) => {
                let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
                f.write_all(&bytes).map_err(|e| Error::io(&self.path, e))?;
            }
            Out::Vti(w) => w.push(ids, values)?,
        }
        self.written += ids.len();
        Ok(())
    }

    /// Completes the file; an error if some points were never pushed.
    pub fn finish(self) -> Result<()> {
        if self.written != self.total {
            return Err(Error::Invalid(format!(
                "{}: {} of {} points written; the file is not complete",
                self.path.display(),
                self.written,
                self.total
            )));
        }
        match self.out {
            Out::Npy(f) => f.commit(),
            Out::Vti(w) => w.finish(),
        }
    }
}

/// A `.npy` version 1.0 header (little-endian `descr`, C order), padded to 64 bytes.
pub(crate) fn npy_header(descr: &str, shape: &[usize]) -> Vec<u8> {
    let dims = match shape {
        [n] => format!("{n},"),
        _ => shape.iter().map(|n| n.to_string()).collect::<Vec<_>>().join(", "),
    };
    let mut dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({dims}), }}");
    let unpadded = 10 + dict.len() + 1;
    dict.extend(std::iter::repeat_n(' ', unpadded.next_multiple_of(64) - unpadded));
    dict.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    out.extend_from_slice(dict.as_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// npyz reads what we write, shape and values, and a short image is not committed.
    #[test]
    fn npy_images_read_back() {
        let grid = ImageGrid::spanning([0.0; 3], [1.0; 3], [3, 2, 2]).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("v.npy");
        let arrays = [ImageArray { name: "v".into(), n_components: 2 }];
        let mut w = ImageWriter::create(&path, &grid, &arrays, false).unwrap();
        let values: Vec<f32> = (0..24).map(|i| i as f32).collect();
        w.push(&[0; 5], &values[..10]).unwrap();
        assert!(w.push(&[0; 8], &values[10..]).is_err(), "more points than the image has");
        w.push(&[0; 7], &values[10..]).unwrap();
        w.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
        assert_eq!(npy.shape(), &[2, 2, 3, 2]);
        assert_eq!(npy.into_vec::<f32>().unwrap(), values);
        std::fs::remove_file(&path).unwrap();

        let mut w = ImageWriter::create(&path, &grid, &arrays, false).unwrap();
        w.push(&[0; 1], &values[..2]).unwrap();
        assert!(w.finish().is_err());
        assert!(!path.exists(), "an incomplete image must not appear");
        let two = [arrays[0].clone(), ImageArray { name: "f".into(), n_components: 1 }];
        let e = ImageWriter::create(&path, &grid, &two, false).err().unwrap().to_string();
        assert!(e.contains("one array") && e.contains("'f'"), "{e}");
    }

    #[test]
    fn npy_headers_are_aligned() {
        for shape in [&[7][..], &[1, 2, 3], &[1024, 1024, 1024, 3]] {
            let h = npy_header("<f4", shape);
            assert_eq!(h.len() % 64, 0);
            assert_eq!(*h.last().unwrap(), b'\n');
        }
    }
}
