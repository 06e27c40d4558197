//! Writes a partitioned mesh: a `.pvtu` listing and, in a folder beside it, one VTU piece
//! per part (ParaView's layout: `OUT.pvtu`, `OUT/OUT_0.vtu`, ...), each piece with its
//! cells' and points' global ids in the integer arrays `GlobalCellIds` and `GlobalPointIds`
//! (VTK's names).
//!
//! Complete or absent, and the old output whole until the new one is: the pieces are written
//! into a temporary folder, renamed to a pieces folder the old listing does not use (`OUT`,
//! or `OUT.1` when the old pieces are in `OUT`), and the listing naming it replaces the old
//! listing in one rename. Only then is the old pieces folder removed. A failure or a kill at
//! any point leaves the old listing with all its pieces (and at most a leftover folder that
//! no listing names, which the next write replaces).

use super::write::{write_mesh_with_cell_data, ArrayData, NamedArray};
use crate::output::{write_atomically, Registered};
use std::io::Write;
use std::path::{Path, PathBuf};
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{FieldLocation, Mesh};

/// The two pieces folders of a listing `OUT.pvtu` (`OUT` and `OUT.1`: a write uses the one
/// the old listing does not) and the name stem of its pieces.
fn pieces_dirs(path: &Path) -> Result<([PathBuf; 2], String)> {
    let stem = path.file_stem().and_then(|s| s.to_str()).filter(|s| !s.is_empty());
    let stem = stem.ok_or_else(|| Error::format(path, "the output needs a file name (OUT.pvtu)"))?;
    let dir = path.with_extension("");
    Ok(([dir.clone(), dir.with_file_name(format!("{stem}.1"))], stem.to_string()))
}

/// The folders a write of `path` may remove or replace (those that exist): an input inside
/// one would be lost.
pub fn replaced_folders(path: &Path) -> Result<Vec<PathBuf>> {
    Ok(pieces_dirs(path)?.0.into_iter().filter(|d| d.exists()).collect())
}

/// Checks before any work that the output can be written: each pieces folder is absent, or a
/// folder of pieces (`STEM_*.vtu` only) that may be replaced.
pub fn check_pvtu_output(path: &Path) -> Result<()> {
    let (dirs, stem) = pieces_dirs(path)?;
    for dir in dirs.iter().filter(|d| d.exists()) {
        if !dir.is_dir() {
            return Err(Error::format(dir, "exists and is not a folder: it would hold the pieces"));
        }
        for e in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
            let name = e.map_err(|e| Error::io(dir, e))?.file_name().to_string_lossy().into_owned();
            if !(name.starts_with(&format!("{stem}_")) && name.ends_with(".vtu")) {
                return Err(Error::format(
                    dir,
                    format!("holds '{name}', which is not a piece: refusing to replace the folder (remove it or choose another output)"),
                ));
            }
        }
    }
    Ok(())
}

/// The pieces folder the listing `path` uses now: the one of `dirs` holding its pieces.
fn folder_in_use(path: &Path, dirs: &[PathBuf; 2]) -> Option<usize> {
    let pieces = super::pieces::list(path).ok()?;
    let first = pieces.first()?.parent()?.to_path_buf();
    let k = dirs.iter().position(|d| crate::output::same_file(d, &first))?;
    Some(k)
}

/// Removes a pieces folder (its pieces, then itself; nothing else is in it, see
/// [`check_pvtu_output`]).
fn remove_folder(dir: &Path) -> Result<()> {
    match std::fs::remove_dir_all(dir) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(Error::io(dir, e)),
        _ => Ok(()),
    }
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
    let (dirs, stem) = pieces_dirs(path)?;
    // The new pieces go into the folder the old listing does not use.
    let (new_dir, old_dir) = match folder_in_use(path, &dirs) {
        Some(0) => (&dirs[1], &dirs[0]),
        _ => (&dirs[0], &dirs[1]),
    };
    let parent = crate::output::parent_dir(path).to_path_buf();
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let make = || tempfile::Builder::new().prefix(&format!(".{name}.")).suffix(".tmp").tempdir_in(&parent);
    let (tmp, registered) = Registered::create(make, |t| t.path()).map_err(|e| Error::io(new_dir, e))?;
    let n = pieces.len();
    let mut declared: Option<String> = None;
    for (k, piece) in pieces.enumerate() {
        let (mesh, ids, point_ids) = piece?;
        let name = format!("{stem}_{k}.vtu");
        let wide = ids.iter().chain(&point_ids).any(|&g| g > i32::MAX as u64);
        let (cells, points) = (GlobalIds::new(&ids, wide), GlobalIds::new(&point_ids, wide));
        let (cells, points) = (cells.array("GlobalCellIds"), points.array("GlobalPointIds"));
        write_mesh_with_cell_data(&tmp.path().join(&name), &mesh, &[points], &[cells], zlib)?;
        if declared.is_none() {
            declared = Some(declarations(&mesh, if wide { "Int64" } else { "Int32" }));
        }
        done(k);
    }
    // The complete pieces under a name no listing uses (a leftover of an interrupted write
    // there is replaced).
    remove_folder(new_dir)?;
    let tmp = tmp.keep();
    std::fs::rename(&tmp, new_dir).map_err(|e| {
        let _ = std::fs::remove_dir_all(&tmp);
        Error::io(new_dir, e)
    })?;
    drop(registered);
    let folder = new_dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
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
            let src = format!("{folder}/{stem}_{k}.vtu");
            writeln!(f, "    <Piece Source=\"{}\"/>", super::write::escape(&src)).map_err(io)?;
        }
        writeln!(f, "  </PUnstructuredGrid>\n</VTKFile>").map_err(io)?;
        Ok(())
    })
    .inspect_err(|_| {
        // Nothing names the new pieces: the old listing and its pieces stay as they were.
        let _ = remove_folder(new_dir);
    })?;
    // The listing names the new pieces: the old ones go.
    remove_folder(old_dir)
}

/// A piece's global ids as written: Int32, or Int64 where some id of the piece needs it
/// (`wide`: cell and point ids take one type, which the listing declares).
enum GlobalIds {
    I32(Vec<i32>),
    I64(Vec<i64>),
}

impl GlobalIds {
    fn new(ids: &[u64], wide: bool) -> GlobalIds {
        if wide {
            GlobalIds::I64(ids.iter().map(|&g| g as i64).collect())
        } else {
            GlobalIds::I32(ids.iter().map(|&g| g as i32).collect())
        }
    }

    fn array(&self, name: &str) -> NamedArray<'_> {
        let data = match self {
            GlobalIds::I32(v) => ArrayData::I32(v),
            GlobalIds::I64(v) => ArrayData::I64(v),
        };
        NamedArray { name: name.into(), n_components: 1, data }
    }
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
