//! The VTK XML ImageData writer (`.vti`) of `resample`: `Origin`, `Spacing`, `WholeExtent`,
//! every array as Float32 point data (k components where the array has k) and
//! `vtkValidPointMask` (UInt8), as vtkResampleToImage gives them; appended raw data with
//! UInt64 block headers, optionally zlib-compressed.
//!
//! Points arrive in chunks, but appended data holds each array whole, one after the other:
//! each array is spilled to its own anonymous temporary file (compressed block by block
//! when asked) and copied into the output at the end, so memory stays bounded.

use super::num::NumType;
use crate::arrays::{ImageArray, VALID_MASK};
use crate::output::AtomicFile;
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};
use tetloc_core::error::{Error, Result};
use tetloc_core::geom::ImageGrid;

/// Uncompressed bytes per zlib block (VTK reads any size).
const ZLIB_BLOCK: usize = 1 << 18;

pub struct VtiWriter {
    path: PathBuf,
    header: String,
    /// The arrays (the mask last) with their spills.
    spills: Vec<Spill>,
    /// Components per point of each array but the mask.
    ncomp: Vec<usize>,
}

/// One array's bytes, on disk until the end.
struct Spill {
    name: String,
    ty: NumType,
    ncomp: usize,
    file: BufWriter<File>,
    /// zlib: bytes not yet a whole block, and each block's compressed size.
    zlib: Option<(Vec<u8>, Vec<u64>)>,
    raw_len: u64,
}

impl Spill {
    fn new(path: &Path, name: &str, ty: NumType, ncomp: usize, zlib: bool) -> Result<Spill> {
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let file = tempfile::tempfile_in(dir).map_err(|e| Error::io(path, e))?;
        Ok(Spill {
            name: name.into(),
            ty,
            ncomp,
            file: BufWriter::with_capacity(1 << 20, file),
            zlib: zlib.then(|| (Vec::new(), Vec::new())),
            raw_len: 0,
        })
    }

    fn push(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.raw_len += bytes.len() as u64;
        let Some((pending, sizes)) = &mut self.zlib else { return self.file.write_all(bytes) };
        pending.extend_from_slice(bytes);
        let whole = pending.len() / ZLIB_BLOCK * ZLIB_BLOCK;
        if whole > 0 {
            for block in compress(&pending[..whole]) {
                sizes.push(block.len() as u64);
                self.file.write_all(&block)?;
            }
            pending.drain(..whole);
        }
        Ok(())
    }

    /// Compresses the last partial block; returns the block header (raw: the byte count;
    /// zlib: block count, block size, last block size, compressed sizes).
    fn finish(&mut self) -> std::io::Result<Vec<u8>> {
        let Some((pending, sizes)) = &mut self.zlib else { return Ok(self.raw_len.to_ne_bytes().to_vec()) };
        if !pending.is_empty() {
            for block in compress(pending) {
                sizes.push(block.len() as u64);
                self.file.write_all(&block)?;
            }
        }
        let last = self.raw_len % ZLIB_BLOCK as u64;
        let head = [sizes.len() as u64, ZLIB_BLOCK as u64, last].into_iter().chain(sizes.iter().copied());
        Ok(head.flat_map(u64::to_ne_bytes).collect())
    }

    /// Bytes of the block (header included) in the appended section.
    fn stored_len(&self, header: &[u8]) -> u64 {
        header.len() as u64 + self.zlib.as_ref().map_or(self.raw_len, |(_, s)| s.iter().sum())
    }
}

/// Compresses whole blocks in parallel (level 3, as the mesh writer).
fn compress(data: &[u8]) -> Vec<Vec<u8>> {
    use rayon::prelude::*;
    data.par_chunks(ZLIB_BLOCK)
        .map(|c| {
            let mut z = flate2::write::ZlibEncoder::new(Vec::with_capacity(c.len() / 2), flate2::Compression::new(3));
            z.write_all(c).expect("writing to a Vec");
            z.finish().expect("writing to a Vec")
        })
        .collect()
}

impl VtiWriter {
    pub fn create(path: &Path, grid: &ImageGrid, arrays: &[ImageArray], zlib: bool) -> Result<VtiWriter> {
        if let Some(a) = arrays.iter().find(|a| a.name == VALID_MASK) {
            return Err(Error::Invalid(format!("an image array cannot be named '{}'", a.name)));
        }
        let mut spills = Vec::with_capacity(arrays.len() + 1);
        for a in arrays {
            spills.push(Spill::new(path, &a.name, NumType::F32, a.n_components, zlib)?);
        }
        spills.push(Spill::new(path, VALID_MASK, NumType::U8, 1, zlib)?);
        let [nx, ny, nz] = grid.dims;
        let extent = format!("0 {} 0 {} 0 {}", nx - 1, ny - 1, nz - 1);
        let v = |a: [f64; 3]| format!("{:?} {:?} {:?}", a[0], a[1], a[2]);
        let compressor = if zlib { " compressor=\"vtkZLibDataCompressor\"" } else { "" };
        let order = if cfg!(target_endian = "little") { "LittleEndian" } else { "BigEndian" };
        let header = format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"{order}\" header_type=\"UInt64\"{compressor}>\n  <ImageData WholeExtent=\"{extent}\" Origin=\"{}\" Spacing=\"{}\" Direction=\"1 0 0 0 1 0 0 0 1\">\n    <Piece Extent=\"{extent}\">\n",
            v(grid.origin),
            v(grid.spacing)
        );
        Ok(VtiWriter {
            path: path.to_path_buf(),
            header,
            spills,
            ncomp: arrays.iter().map(|a| a.n_components).collect(),
        })
    }

    pub fn push(&mut self, ids: &[i32], values: &[f32]) -> Result<()> {
        let io = |e| Error::io(&self.path, e);
        let width: usize = self.ncomp.iter().sum();
        let mut at = 0;
        let mut bytes = Vec::with_capacity(4 * values.len());
        for (spill, &k) in self.spills.iter_mut().zip(&self.ncomp) {
            bytes.clear();
            for p in values.chunks_exact(width.max(1)).take(ids.len()) {
                p[at..at + k].iter().for_each(|v| bytes.extend_from_slice(&v.to_ne_bytes()));
            }
            spill.push(&bytes).map_err(io)?;
            at += k;
        }
        let mask: Vec<u8> = ids.iter().map(|&i| u8::from(i >= 0)).collect();
        self.spills.last_mut().expect("the mask's spill").push(&mask).map_err(io)
    }

    pub fn finish(mut self) -> Result<()> {
        let path = self.path.clone();
        let io = |e| Error::io(&path, e);
        let heads = self.spills.iter_mut().map(Spill::finish).collect::<std::io::Result<Vec<_>>>().map_err(io)?;
        use std::fmt::Write as _;
        let mut xml = std::mem::take(&mut self.header);
        let _ = writeln!(xml, "      <PointData Scalars=\"{VALID_MASK}\">");
        let mut offset = 0u64;
        for (s, h) in self.spills.iter().zip(&heads) {
            let comps = if s.ncomp > 1 { format!(" NumberOfComponents=\"{}\"", s.ncomp) } else { String::new() };
            let _ = writeln!(
                xml,
                "        <DataArray type=\"{}\" Name=\"{}\"{comps} format=\"appended\" offset=\"{offset}\"/>",
                s.ty.name(),
                super::write::escape(&s.name)
            );
            offset += s.stored_len(h);
        }
        let _ = write!(
            xml,
            "      </PointData>\n      <CellData>\n      </CellData>\n    </Piece>\n  </ImageData>\n  <AppendedData encoding=\"raw\">\n   _"
        );
        let mut out = AtomicFile::create(&path)?;
        out.write_all(xml.as_bytes()).map_err(io)?;
        for (s, h) in self.spills.into_iter().zip(heads) {
            out.write_all(&h).map_err(io)?;
            let mut f = s.file.into_inner().map_err(|e| io(e.into_error()))?;
            f.rewind().map_err(io)?;
            std::io::copy(&mut f, &mut out).map_err(io)?;
        }
        out.write_all(b"\n  </AppendedData>\n</VTKFile>\n").map_err(io)?;
        out.commit()
    }
}
