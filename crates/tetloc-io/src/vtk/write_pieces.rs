//! Writes a partitioned mesh: a `.pvtu` listing and, in the folder of the same name beside
//! it, one VTU piece per part (ParaView's layout: `OUT.pvtu`, `OUT/OUT_0.vtu`, ...), each
//! piece with its cells' and points' global ids in the integer arrays `GlobalCellIds` and
//! `GlobalPointIds` (VTK's names).
//!
//! Complete or absent: the pieces are written into a temporary folder, which replaces the
//! pieces folder only when all are written; the listing is written last (atomically), and an
//! older listing of the same name is removed first, so no listing ever points at a mix of
//! old and new pieces or at pieces still being written.

use super::write::{write_mesh_with_cell_data, ArrayData, NamedArray};
use crate::output::write_atomically;
use std::io::Write;
use std::path::{Path, PathBuf};
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{FieldLocation, Mesh};

/// The pieces folder of a listing `OUT.pvtu` (`OUT`) and the name stem of its pieces.
fn pieces_dir(path: &Path) -> Result<(PathBuf, String)> {
    let stem = path.file_stem().and_then(|s| s.to_str()).filter(|s| !s.is_empty());
    let stem = stem.ok_or_else(|| Error::format(path, "the output needs a file name (OUT.pvtu)"))?;
    Ok((path.with_extension(""), stem.to_string()))
}

/// Checks before any work that the output can be written: the pieces folder is absent, or a
/// folder of pieces (`STEM_*.vtu` only) that may be replaced.
pub fn check_pvtu_output(path: &Path) -> Result<()> {
    let (dir, stem) = pieces_dir(path)?;
    if !dir.exists() {
        return Ok(());
    }
    if !dir.is_dir() {
        return Err(Error::format(&dir, "exists and is not a folder: it would hold the pieces"));
    }
    for e in std::fs::read_dir(&dir).map_err(|e| Error::io(&dir, e))? {
        let name = e.map_err(|e| Error::io(&dir, e))?.file_name().to_string_lossy().into_owned();
        if !(name.starts_with(&format!("{stem}_")) && name.ends_with(".vtu")) {
            return Err(Error::format(
                &dir,
                format!("holds '{name}', which is not a piece: refusing to replace the folder (remove it or choose another output)"),
            ));
        }
    }
    Ok(())
}

/// Writes `pieces` (meshes, the global id of each of their cells and of each of their points)
/// as `path` (`.pvtu`) and its pieces folder; `done(k)` after each piece.
pub fn write_pvtu(
    path: &Path,
    pieces: impl ExactSizeIterator<Item = Result<(Mesh, Vec<u64>, Vec<u64>)>>,
    zlib: bool,
    done: impl Fn(usize),
) -> Result<()> {
    check_pvtu_output(path)?;
    let (dir, stem) = pieces_dir(path)?;
    let parent = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    // An older listing would point at the pieces being replaced.
    if path.exists() {
        std::fs::remove_file(path).map_err(|e| Error::io(path, e))?;
    }
    let tmp = tempfile::Builder::new()
        .prefix(&format!(".{stem}."))
        .suffix(".tmp")
        .tempdir_in(&parent)
        .map_err(|e| Error::io(&dir, e))?;
    let n = pieces.len();
    let mut declared: Option<String> = None;
    for (k, piece) in pieces.enumerate() {
        let (mesh, ids, point_ids) = piece?;
        let name = format!("{stem}_{k}.vtu");
        let wide = ids.iter().chain(&point_ids).any(|&g| g > i32::MAX as u64);
        let (ids32, ids64): (Vec<i32>, Vec<i64>) = if wide {
            (Vec::new(), ids.iter().map(|&g| g as i64).collect())
        } else {
            (ids.iter().map(|&g| g as i32).collect(), Vec::new())
        };
        let data = if wide { ArrayData::I64(&ids64) } else { ArrayData::I32(&ids32) };
        let global = NamedArray { name: "GlobalCellIds".into(), n_components: 1, data };
        let (p32, p64): (Vec<i32>, Vec<i64>) = if wide {
            (Vec::new(), point_ids.iter().map(|&g| g as i64).collect())
        } else {
            (point_ids.iter().map(|&g| g as i32).collect(), Vec::new())
        };
        let data = if wide { ArrayData::I64(&p64) } else { ArrayData::I32(&p32) };
        let points = NamedArray { name: "GlobalPointIds".into(), n_components: 1, data };
        write_mesh_with_cell_data(&tmp.path().join(&name), &mesh, &[points], &[global], zlib)?;
        if declared.is_none() {
            declared = Some(declarations(&mesh, if wide { "Int64" } else { "Int32" }));
        }
        done(k);
    }
    // Swap the folders: the old one aside, the new one in, the old one removed.
    let old = parent.join(format!(".{stem}.{}.old", std::process::id()));
    if dir.exists() {
        std::fs::rename(&dir, &old).map_err(|e| Error::io(&dir, e))?;
    }
    let tmp = tmp.keep();
    std::fs::rename(&tmp, &dir).map_err(|e| Error::io(&dir, e))?;
    if old.exists() {
        std::fs::remove_dir_all(&old).map_err(|e| Error::io(&old, e))?;
    }
    let declared = declared.unwrap_or_default();
    write_atomically(path, |f| -> Result<()> {
        let io = |e| Error::io(path, e);
        writeln!(f, "<?xml version=\"1.0\"?>").map_err(io)?;
        writeln!(
            f,
            "<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">"
        )
        .map_err(io)?;
        writeln!(f, "  <PUnstructuredGrid GhostLevel=\"0\">").map_err(io)?;
        f.write_all(declared.as_bytes()).map_err(io)?;
        for k in 0..n {
            let src = format!("{stem}/{stem}_{k}.vtu");
            writeln!(f, "    <Piece Source=\"{}\"/>", super::write::escape(&src)).map_err(io)?;
        }
        writeln!(f, "  </PUnstructuredGrid>\n</VTKFile>").map_err(io)?;
        Ok(())
    })
}

/// The listing's `<PPointData>`, `<PCellData>` and `<PPoints>`: what every piece carries.
fn declarations(mesh: &Mesh, id_type: &str) -> String {
    let groups = tetloc_core::mesh::field_groups::groups_of(&mesh.fields);
    let mut out = String::new();
    for (tag, location) in [("PPointData", FieldLocation::Vertex), ("PCellData", FieldLocation::Cell)] {
        out += &format!("    <{tag}>\n");
        for g in groups
            .iter()
            .filter(|g| g.location == location && !["GlobalCellIds", "GlobalPointIds"].contains(&g.name.as_str()))
        {
            out += &format!(
                "      <PDataArray type=\"Float32\" Name=\"{}\" NumberOfComponents=\"{}\"/>\n",
                super::write::escape(&g.name),
                g.n_components()
            );
        }
        let ids = if location == FieldLocation::Cell { "GlobalCellIds" } else { "GlobalPointIds" };
        out += &format!("      <PDataArray type=\"{id_type}\" Name=\"{ids}\"/>\n");
        out += &format!("    </{tag}>\n");
    }
    out += &format!(
        "    <PPoints><PDataArray type=\"{}\" NumberOfComponents=\"3\"/></PPoints>\n",
        super::write::points_type(mesh)
    );
    out
}
