//! tetloc-io: the mesh readers and writers, chosen by file extension (or an explicit
//! [`MeshFormat`]), query-point / result array I/O, and the files the operations write. It
//! sits above the mesh model (`tetloc-core`), which never reads or writes a file itself.

pub mod arrays;
pub(crate) mod cursor;
pub mod exodus;
pub mod gmsh;
pub mod image;
/// OpenFOAM cases (`constant/polyMesh` and a time's cell fields).
pub mod openfoam;
pub mod ops_output;
pub mod output;
pub mod partition;
pub mod parts;
pub mod points;
#[cfg(test)]
mod test_support;
#[cfg(test)]
mod tests;
pub mod tetgen;
pub mod vtk;

use std::path::{Path, PathBuf};
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{Mesh, RawMesh, TimeSteps};

/// The mesh formats tetloc reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// VTK XML unstructured grid (`.vtu`).
    Vtu,
    /// A partitioned mesh: VTK's parallel unstructured grid (`.pvtu`) or multiblock data set
    /// (`.vtm`) listing VTU pieces, read as one mesh with cells numbered by global id.
    Pieces,
    /// VTK legacy (`.vtk`), versions up to 5.1, ascii or binary.
    VtkLegacy,
    /// Gmsh `.msh` 2.2 and 4.1, ascii or binary.
    Gmsh,
    /// TetGen `.node` + `.ele` (either file may be named).
    TetGen,
    /// Exodus II (`.e`, `.exo`, `.ex2`), classic netCDF or netCDF-4; with time steps.
    Exodus,
    /// ParaView's collection of time steps (`.pvd`) of unstructured grids.
    Pvd,
    /// An OpenFOAM case: its `NAME.foam` file or its folder (decomposed when it has no
    /// `constant/polyMesh` but `processor*/`); with time steps.
    OpenFoam,
    /// An OpenFOAM case read from its `processor*/` folders even when it has a reconstructed
    /// mesh too (ParaView's "Case Type: Decomposed Case").
    OpenFoamDecomposed,
}

pub const KNOWN_MESH_FORMATS: &str =
    "vtu, pvtu, vtm, vtk, msh, node/ele, e/exo/ex2, pvd, foam (or an OpenFOAM case folder), foam-decomposed";

impl MeshFormat {
    pub fn from_name(name: &str) -> Option<MeshFormat> {
        match name.to_ascii_lowercase().as_str() {
            "vtu" => Some(MeshFormat::Vtu),
            "pvtu" | "vtm" => Some(MeshFormat::Pieces),
            "vtk" => Some(MeshFormat::VtkLegacy),
            "msh" | "gmsh" => Some(MeshFormat::Gmsh),
            "node" | "ele" | "tetgen" => Some(MeshFormat::TetGen),
            "e" | "exo" | "ex2" | "exodus" => Some(MeshFormat::Exodus),
            "pvd" => Some(MeshFormat::Pvd),
            "foam" | "openfoam" => Some(MeshFormat::OpenFoam),
            "foam-decomposed" | "openfoam-decomposed" => Some(MeshFormat::OpenFoamDecomposed),
            _ => None,
        }
    }

    pub fn from_path(path: &Path) -> Result<MeshFormat> {
        if path.is_dir() && openfoam::is_case(path) {
            return Ok(MeshFormat::OpenFoam);
        }
        path.extension()
            .and_then(|e| e.to_str())
            .and_then(MeshFormat::from_name)
            .ok_or_else(|| Error::UnknownFormat { path: path.to_path_buf(), known: KNOWN_MESH_FORMATS })
    }
}

/// The UTF-8 byte-order mark that some editors (Excel, Notepad) put before a text file's first
/// byte. Every text reader skips it.
pub(crate) const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// `bytes` without a leading UTF-8 byte-order mark.
pub(crate) fn strip_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(UTF8_BOM).unwrap_or(bytes)
}

/// Every file that reading the mesh `path` reads, for refusing an output that is one of them:
/// the file; a TetGen mesh's `.node` and `.ele`; a listing (`.pvtu`, `.vtm`), the listings
/// it nests and all their pieces. A listing that cannot be read counts as itself alone
/// (reading the mesh then fails before anything is written).
pub fn input_files(path: &Path, format: Option<MeshFormat>) -> Vec<PathBuf> {
    if check_regular_input(path).is_err() {
        // A listing that is a FIFO is not opened to list it (that would block); reading it
        // is refused with a clear error.
        return vec![path.to_path_buf()];
    }
    match format.or_else(|| MeshFormat::from_path(path).ok()) {
        Some(MeshFormat::TetGen) => vec![path.with_extension("node"), path.with_extension("ele")],
        Some(MeshFormat::Pieces) => vtk::pieces::files_read(path).unwrap_or_else(|_| vec![path.to_path_buf()]),
        Some(MeshFormat::Pvd) => vtk::pvd::files_read(path),
        // The MPI path reads a case's processors even beside a reconstructed mesh: both count.
        Some(MeshFormat::OpenFoam) => {
            let mut files = openfoam::files_read(path, false);
            if openfoam::is_decomposed(path) {
                files.extend(openfoam::files_read(path, true));
            }
            files
        }
        Some(MeshFormat::OpenFoamDecomposed) => openfoam::files_read(path, true),
        _ => vec![path.to_path_buf()],
    }
}

/// An error naming `path` and the name if two of `fields` share a name and location: commands
/// would use the first silently. A point and a cell field of one name are two fields (as in VTK).
pub(crate) fn check_distinct_fields(path: &Path, fields: &[tetloc_core::mesh::Field]) -> Result<()> {
    use tetloc_core::mesh::FieldLocation;
    let mut seen = std::collections::HashSet::new();
    match fields.iter().find(|f| !seen.insert((f.name.as_str(), f.location == FieldLocation::Vertex))) {
        None => Ok(()),
        Some(f) => {
            let at = if f.location == FieldLocation::Vertex { "point" } else { "cell" };
            Err(Error::format(path, format!("two {at} fields named '{}'; field names must be unique", f.name)))
        }
    }
}

/// Memory the system can still hand out (Linux `MemAvailable`), if known.
pub fn available_memory_bytes() -> Option<u64> {
    tetloc_core::memory::available_bytes()
}

/// Refuses, with a clear error, to start reading a file that cannot fit in memory: readers
/// hold the file's bytes and the arrays decoded from them at once (about twice its size).
pub(crate) fn check_fits_in_memory(path: &Path) -> Result<()> {
    let len = std::fs::metadata(path).map_err(|e| Error::io(path, e))?.len();
    if let Some(avail) = available_memory_bytes() {
        if len.saturating_mul(2) > avail {
            let gb = |b: u64| b as f64 / 1e9;
            return Err(Error::format(
                path,
                format!(
                    "the file is {:.1} GB; reading it needs about {:.1} GB of memory but {:.1} GB are available",
                    gb(len),
                    gb(2 * len),
                    gb(avail)
                ),
            ));
        }
    }
    Ok(())
}

/// Refuses, before it is opened, an input that is neither a regular file nor a folder (an
/// OpenFOAM case): opening a FIFO blocks until a writer comes, which may be never, and a
/// device may never end. A path that does not exist passes (opening it says so).
pub fn check_regular_input(path: &Path) -> Result<()> {
    // `metadata` follows symbolic links: a link to a FIFO is a FIFO.
    match std::fs::metadata(path) {
        Ok(meta) if !meta.is_file() && !meta.is_dir() => Err(Error::format(
            path,
            "not a regular file (a FIFO, socket or device?); inputs are read from files, save it to one first",
        )),
        _ => Ok(()),
    }
}

/// Most bytes read from a file that is not a regular file (a pipe, a device such as
/// `/dev/zero`), whose size cannot be known in advance; less when memory is short.
pub const NON_REGULAR_READ_CAP: u64 = 1 << 30;

// The readers' test of whether a file's coordinates need f64; the mesh model owns it.
pub(crate) use tetloc_core::mesh::{needs_f64, points64_if_needed};

/// Reads a whole file, boundedly: a regular file must fit in memory (its size is known),
/// and anything else (pipes, devices) is read up to [`NON_REGULAR_READ_CAP`] and refused
/// beyond. Large regular files are read by all threads at once: copying from the page cache
/// is a good part of loading a big mesh, and it parallelises.
pub fn read_file(path: &Path) -> Result<Vec<u8>> {
    use std::io::Read;
    let io = |e| Error::io(path, e);
    let file = std::fs::File::open(path).map_err(io)?;
    let meta = file.metadata().map_err(io)?;
    if meta.is_dir() {
        // The OS's own error (EISDIR: "Is a directory"), so callers see an I/O error kind
        // (Python raises IsADirectoryError).
        let os_error = (&file).read(&mut [0u8; 1]).err();
        return Err(io(os_error.unwrap_or_else(|| std::io::ErrorKind::IsADirectory.into())));
    }
    if !meta.is_file() {
        let cap = available_memory_bytes().map_or(NON_REGULAR_READ_CAP, |a| (a / 2).min(NON_REGULAR_READ_CAP));
        let mut buf = Vec::new();
        file.take(cap + 1).read_to_end(&mut buf).map_err(io)?;
        if buf.len() as u64 > cap {
            return Err(Error::format(
                path,
                format!(
                    "not a regular file (a pipe or a device) and longer than {} MiB, the most read from one; \
                     save it to a file first",
                    cap >> 20
                ),
            ));
        }
        return Ok(buf);
    }
    check_fits_in_memory(path)?;
    let len = usize::try_from(meta.len()).map_err(|_| Error::format(path, "file too large for this machine"))?;
    #[cfg(unix)]
    {
        use rayon::prelude::*;
        use std::os::unix::fs::FileExt;
        const PART: usize = 8 << 20;
        if len > 4 * PART && rayon::current_num_threads() > 1 {
            let mut buf = vec![0u8; len];
            buf.par_chunks_mut(PART)
                .enumerate()
                .try_for_each(|(i, part)| file.read_exact_at(part, (i * PART) as u64))
                .map_err(io)?;
            return Ok(buf);
        }
    }
    let mut buf = Vec::with_capacity(len);
    (&file).read_to_end(&mut buf).map_err(io)?;
    Ok(buf)
}

/// Choices of how a mesh file is read.
#[derive(Clone, Copy, Debug)]
pub struct ReadOptions {
    /// `.pvtu`/`.vtm`: read pieces (and nested listings) that lie outside the listing's folder
    /// tree (`../`, absolute paths, symbolic links out). Refused by default: a listing from an
    /// untrusted source should not make tetloc read arbitrary files.
    pub allow_outside_pieces: bool,
}

impl Default for ReadOptions {
    /// Pieces outside the listing's folder refused, unless this process allows them
    /// ([`vtk::pieces::set_allow_outside_by_default`], the CLI's `--allow-outside-pieces`).
    fn default() -> Self {
        ReadOptions { allow_outside_pieces: vtk::pieces::allows_outside_by_default() }
    }
}

/// Reads a mesh file into a raw mesh (tets in file order, not yet validated).
pub fn read_raw(path: &Path, format: Option<MeshFormat>) -> Result<RawMesh> {
    read_raw_with(path, format, ReadOptions::default())
}

/// [`read_raw`] with explicit [`ReadOptions`].
pub fn read_raw_with(path: &Path, format: Option<MeshFormat>, options: ReadOptions) -> Result<RawMesh> {
    let format = match format {
        Some(f) => f,
        None => MeshFormat::from_path(path)?,
    };
    if !matches!(format, MeshFormat::TetGen | MeshFormat::Pvd | MeshFormat::OpenFoam | MeshFormat::OpenFoamDecomposed) {
        check_fits_in_memory(path)?;
    }
    let regular = std::fs::metadata(path).map_or(true, |m| m.is_file());
    if matches!(format, MeshFormat::Gmsh | MeshFormat::TetGen) && !regular {
        // These readers read with `std::fs::read`, unbounded on a pipe or a device.
        // TODO(iohygiene): read through `io::read_file` and drop this refusal.
        return Err(Error::format(path, "not a regular file; Gmsh and TetGen meshes are read from regular files only"));
    }
    match format {
        MeshFormat::Vtu => vtk::vtu::read(path),
        MeshFormat::Pieces => vtk::pieces::read_with(path, options.allow_outside_pieces),
        MeshFormat::VtkLegacy => vtk::legacy::read(path),
        MeshFormat::Gmsh => gmsh::read(path),
        MeshFormat::TetGen => tetgen::read(path),
        MeshFormat::Exodus => exodus::read(path),
        MeshFormat::Pvd => vtk::pvd::read(path, options),
        MeshFormat::OpenFoam => openfoam::read(path),
        MeshFormat::OpenFoamDecomposed => openfoam::read_case(path, &openfoam::Time::First, true),
    }
}

/// Reads a mesh file with its time steps: the mesh holds the first step's fields, and the
/// steps (`None` for a file without time steps) read the others when asked. Exodus files with
/// `time_whole` steps, `.pvd` collections, OpenFOAM cases' time directories and Gmsh files
/// whose views hold several steps have steps; every other format is one snapshot.
pub fn read_series(path: &Path, format: Option<MeshFormat>) -> Result<(RawMesh, Option<TimeSteps>)> {
    read_series_with(path, format, ReadOptions::default())
}

/// [`read_series`] with explicit [`ReadOptions`].
pub fn read_series_with(
    path: &Path,
    format: Option<MeshFormat>,
    options: ReadOptions,
) -> Result<(RawMesh, Option<TimeSteps>)> {
    let format = match format {
        Some(f) => f,
        None => MeshFormat::from_path(path)?,
    };
    match format {
        MeshFormat::Exodus => exodus::read_series(path),
        MeshFormat::Gmsh => gmsh::read_series(path),
        MeshFormat::Pvd => vtk::pvd::read_series(path, options).map(|(raw, steps)| (raw, Some(steps))),
        MeshFormat::OpenFoam => openfoam::read_series(path, false),
        MeshFormat::OpenFoamDecomposed => openfoam::read_series(path, true),
        other => Ok((read_raw_with(path, Some(other), options)?, None)),
    }
}

/// Reads and validates a mesh file.
pub fn read_mesh(path: &Path, format: Option<MeshFormat>) -> Result<Mesh> {
    read_mesh_with(path, format, ReadOptions::default())
}

/// [`read_mesh`] with explicit [`ReadOptions`].
pub fn read_mesh_with(path: &Path, format: Option<MeshFormat>, options: ReadOptions) -> Result<Mesh> {
    let raw = read_raw_with(path, format, options)?;
    Mesh::new(raw, path.display().to_string())
}

#[cfg(test)]
mod memory_tests {
    use super::*;

    /// A FIFO (which would block the open until a writer comes) and a device are refused
    /// before they are opened, naming the file; files, folders and missing paths pass.
    #[cfg(unix)]
    #[test]
    fn non_regular_inputs_are_refused_before_opening() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("p.vtu");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        assert!(made.is_ok_and(|s| s.success()), "mkfifo");
        for p in [fifo.as_path(), Path::new("/dev/null")] {
            let e = check_regular_input(p).unwrap_err().to_string();
            assert!(e.contains(&p.display().to_string()) && e.contains("not a regular file"), "{e}");
        }
        let file = dir.path().join("m.vtu");
        std::fs::write(&file, "x").unwrap();
        for p in [file.as_path(), dir.path(), &dir.path().join("missing.vtu")] {
            check_regular_input(p).unwrap();
        }
    }

    /// A (sparse) file larger than memory is refused up front with a clear error, not an
    /// allocation failure.
    #[test]
    fn files_too_big_for_memory_are_refused() {
        let Some(avail) = available_memory_bytes() else { return };
        let path = std::env::temp_dir().join(format!("tetloc-huge-{}.vtu", std::process::id()));
        let f = std::fs::File::create(&path).unwrap();
        f.set_len(avail).unwrap();
        let msg = read_mesh(&path, None).unwrap_err().to_string();
        std::fs::remove_file(&path).unwrap();
        assert!(msg.contains(&path.display().to_string()) && msg.contains("GB of memory"), "{msg}");
    }
}
