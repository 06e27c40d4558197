//! The bodies of the fuzz targets, shared with a stable unit test that runs them over the
//! shared data files (the seed corpus). Each parses its input with one reader and, when that
//! succeeds, validates the mesh: any panic, overflow or runaway allocation is a bug.

use std::path::Path;
use tetloc_core::{Mesh, RawMesh, Result};
use tetloc_io::vtk::{legacy as vtk_legacy, pvtu, vtm, vtu};
use tetloc_io::{exodus, gmsh, tetgen};

fn validate(parsed: Result<RawMesh>) {
    if let Ok(raw) = parsed {
        let _ = Mesh::new(raw, "fuzz");
    }
}

/// A `.msh` read as a mesh, and as a probe target of any elements (`parse_any`).
pub fn gmsh(data: &[u8]) {
    validate(gmsh::parse(data, Path::new("fuzz.msh")));
    if let Ok(grid) = gmsh::parse_any(data, Path::new("fuzz.msh")) {
        assert_eq!(grid.types.len(), grid.ends.len());
        assert!(grid.conn.iter().all(|&i| (i as usize) < grid.points.len()));
    }
}

/// A `.vtu` read as a mesh, and as a probe target of any cells (`parse_any`).
pub fn vtu(data: &[u8]) {
    validate(vtu::parse(data, Path::new("fuzz.vtu")));
    if let Ok(grid) = vtu::parse_any(data, Path::new("fuzz.vtu")) {
        assert_eq!(grid.types.len(), grid.ends.len());
        assert!(grid.conn.iter().all(|&i| (i as usize) < grid.points.len()));
    }
}

pub fn vtk_legacy(data: &[u8]) {
    validate(vtk_legacy::parse(data, Path::new("fuzz.vtk")));
}

/// The listings of partitioned meshes: the same bytes as a `.pvtu` and as a `.vtm` (both XML
/// listing piece files; the pieces themselves are `.vtu`, the `vtu` target's input).
pub fn pieces(data: &[u8]) {
    if let Ok(files) = pvtu::parse(data, Path::new("fuzz.pvtu")) {
        assert!(!files.is_empty());
    }
    if let Ok(files) = vtm::parse(data, Path::new("fuzz.vtm")) {
        assert!(!files.is_empty());
    }
}

/// One file of an OpenFOAM case (points, faces, owner, neighbour, boundary, a field).
pub fn openfoam(data: &[u8]) {
    let _ = tetloc_io::openfoam::parse_file(data);
}

/// The input is the .node file, a NUL byte, then the .ele file (no NUL: an empty .ele).
/// Exodus II: netCDF classic and netCDF-4 (HDF5) bytes.
pub fn exodus(data: &[u8]) {
    validate(exodus::parse(data, Path::new("fuzz.e")));
}

pub fn tetgen(data: &[u8]) {
    let (node, ele) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    validate(tetgen::parse(node, ele, Path::new("fuzz.node")));
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    /// Files of the seed corpus with one of `exts`, from the data folder and `real/`.
    fn seeds(dir: &Path, exts: &[&str]) -> Vec<PathBuf> {
        let mut out: Vec<PathBuf> = [dir.to_path_buf(), dir.join("real")]
            .iter()
            .filter_map(|d| std::fs::read_dir(d).ok())
            .flatten()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().and_then(|e| e.to_str()).is_some_and(|e| exts.contains(&e)))
            .collect();
        out.sort();
        out
    }

    /// Runs a target over each seed, a spread of its truncations and a few byte flips, the
    /// way a short fuzzing session starts.
    fn run(target: fn(&[u8]), files: &[PathBuf]) {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for f in files {
            let bytes = std::fs::read(f).unwrap();
            target(&bytes);
            for k in 1..24 {
                target(&bytes[..bytes.len() * k / 24]);
            }
            for _ in 0..8 {
                let mut b = bytes.clone();
                for _ in 0..4 {
                    let i = (next() % b.len() as u64) as usize;
                    b[i] = next() as u8;
                }
                target(&b);
            }
        }
    }

    /// The fresh-clone counterpart of [`targets_survive_the_seed_corpus`]: the seeds are the
    /// files the project's writers make (`tetloc_testdata::written_files`: VTU raw and zlib,
    /// Gmsh 2.2 ASCII, legacy VTK binary), and the listings and TetGen seed made here.
    #[test]
    fn targets_survive_written_seeds() {
        let files = tetloc_testdata::written_files();
        let with = |ext: &str| -> Vec<PathBuf> {
            files.iter().filter(|p| p.extension().is_some_and(|e| e == ext)).cloned().collect()
        };
        let (msh, vtus, vtks) = (with("msh"), with("vtu"), with("vtk"));
        assert!(!msh.is_empty() && !vtus.is_empty() && !vtks.is_empty(), "no seeds in {files:?}");
        run(gmsh, &msh);
        run(vtu, &vtus);
        run(vtk_legacy, &vtks);
        run_made_here(&msh, &vtus);
    }

    /// The OpenFOAM case of `poly/`: each of its files.
    #[test]
    fn openfoam_target_survives_the_case_files() {
        let Some(dir) = tetloc_testdata::require_data("openfoam_target_survives_the_case_files") else { return };
        let case = dir.join("poly/octpoly_s_case");
        let files: Vec<PathBuf> = [
            "constant/polyMesh/points",
            "constant/polyMesh/faces",
            "constant/polyMesh/owner",
            "constant/polyMesh/boundary",
            "1/lin",
        ]
        .iter()
        .map(|f| case.join(f))
        .collect();
        for f in &files {
            assert!(tetloc_io::openfoam::parse_file(&std::fs::read(f).unwrap()).unwrap() > 0, "{}", f.display());
        }
        run(openfoam, &files);
    }

    #[test]
    fn targets_survive_the_seed_corpus() {
        let Some(dir) = tetloc_testdata::require_data("targets_survive_the_seed_corpus") else { return };
        let msh = seeds(&dir, &["msh"]);
        let vtus = seeds(&dir, &["vtu"]);
        let vtks = seeds(&dir, &["vtk"]);
        run(exodus, &seeds(&dir.join("time"), &["e", "exo"]));
        assert!(!msh.is_empty() && !vtus.is_empty() && !vtks.is_empty(), "no seeds in {}", dir.display());
        run(gmsh, &msh);
        run(vtu, &vtus);
        run(vtk_legacy, &vtks);
        run_made_here(&msh, &vtus);
    }

    /// The inputs made here: listings, a TetGen seed, and other formats' files fed to them.
    fn run_made_here(msh: &[PathBuf], vtus: &[PathBuf]) {
        // Listings are made here (the data holds none), and any VTK XML file is a fair input.
        let pvtu = b"<?xml version=\"1.0\"?>\n<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\">\n<PUnstructuredGrid GhostLevel=\"0\">\n<PPointData><PDataArray type=\"Float32\" Name=\"f\"/></PPointData>\n<Piece Source=\"m/m_0.vtu\"/><Piece Source=\"m/m_1.vtu\"/>\n</PUnstructuredGrid>\n</VTKFile>\n";
        let vtm = b"<VTKFile type=\"vtkMultiBlockDataSet\" version=\"1.0\"><vtkMultiBlockDataSet><Block index=\"0\"><DataSet index=\"0\" file=\"a.vtu\"/></Block><DataSet index=\"1\" file=\"b.pvtu\"/></vtkMultiBlockDataSet></VTKFile>";
        run(pieces, &[write_temp("seed.pvtu", pvtu), write_temp("seed.vtm", vtm)]);
        run(pieces, &vtus[..1]);
        // TetGen seeds are made here: the data holds none.
        let node = b"5 3 1 1\n1 0 0 0 0.5 1\n2 1 0 0 1 0\n3 0 1 0 2 0\n4 0 0 1 3 1\n5 1 1 1 4 0\n";
        let ele = b"2 4 1\n1 1 2 3 4 7\n2 2 3 4 5 -1\n# Generated by tetgen\n";
        let seed = [&node[..], b"\0", &ele[..]].concat();
        run(tetgen, &[write_temp("seed.tetgen", &seed)]);
        // Every target also takes any of the other formats' files without panicking.
        run(tetgen, &msh[..1]);
    }

    /// The seeds kept in `fuzz/seeds/<target>/` (byte-order marks, binary FIELD blocks,
    /// surfaces and vertices, empty pieces, pieces outside their listing's folder): each target
    /// reads its own, and they join the corpus of a `cargo fuzz run` (see the README).
    #[test]
    fn targets_survive_the_kept_seeds() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("seeds");
        type Target = fn(&[u8]);
        let targets: [(&str, Target); 5] =
            [("gmsh", gmsh), ("vtu", vtu), ("vtk_legacy", vtk_legacy), ("tetgen", tetgen), ("pieces", pieces)];
        for (name, target) in targets {
            let files = seeds(&dir.join(name), &["msh", "vtu", "vtk", "tetgen", "pvtu", "vtm"]);
            assert!(!files.is_empty(), "no seeds in {}", dir.join(name).display());
            run(target, &files);
        }
        // The readers accept what the seeds are there for.
        let read = |p: &str| std::fs::read(dir.join(p)).unwrap();
        assert!(vtk_legacy::parse(&read("vtk_legacy/field_binary.vtk"), Path::new("f.vtk")).is_ok());
        assert!(vtk_legacy::parse(&read("vtk_legacy/bom_ascii.vtk"), Path::new("b.vtk")).is_ok());
        assert!(gmsh::parse(&read("gmsh/bom_elementdata.msh"), Path::new("b.msh")).is_ok());
        assert!(vtu::parse(&read("vtu/bom_empty_piece.vtu"), Path::new("b.vtu")).is_ok());
        assert!(vtu::parse_any(&read("vtu/surface_and_vertices.vtu"), Path::new("s.vtu")).is_ok());
        assert_eq!(pvtu::parse(&read("pieces/outside.pvtu"), Path::new("o.pvtu")).unwrap().len(), 3);
    }

    fn write_temp(name: &str, bytes: &[u8]) -> PathBuf {
        let path = std::env::temp_dir().join(format!("tetloc-fuzz-{}-{name}", std::process::id()));
        std::fs::write(&path, bytes).unwrap();
        path
    }
}
