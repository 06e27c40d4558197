//! OpenFOAM cases: `constant/polyMesh` (points, faces, owner, neighbour, boundary), ascii or
//! binary, each file possibly gzip-compressed (`NAME.gz`), and the `volScalarField` /
//! `volVectorField` internal fields of one time directory as cell data.
//!
//! A case opens through its `NAME.foam` file (as in ParaView) or its folder. Cells keep
//! OpenFOAM's order: cell id = `celli`. Each cell is the polyhedron of its faces (owner faces
//! as they are, neighbour faces reversed, so that all face out), or a hexahedron when it has
//! the shape of one (6 quads on 8 points), as ParaView's reader makes it. Fields come from the
//! latest time directory ([`read_case`](crate::openfoam::read_case) takes another); a time series is for later (the
//! steps axis of the time-series work). Vector fields become `NAME[0]`, `NAME[1]`, `NAME[2]`.

mod foam;

use foam::Foam;
use std::path::{Path, PathBuf};
use tetloc_core::cell::{CellBlock, CellType};
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{Field, FieldLocation, RawMesh};

/// The case folder of `path`: the folder a `.foam` file is in, or `path` itself.
pub fn case_dir(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.to_path_buf()
    } else {
        path.parent()
            .map_or_else(|| PathBuf::from("."), |p| if p.as_os_str().is_empty() { ".".into() } else { p.to_path_buf() })
    }
}

/// Whether `dir` looks like an OpenFOAM case (it has `constant/polyMesh`).
pub fn is_case(dir: &Path) -> bool {
    dir.join("constant/polyMesh").is_dir()
}

/// Which time directory's fields to read.
#[derive(Clone, Debug, PartialEq)]
pub enum Time {
    /// The largest time (none when the case has no time directory).
    Latest,
    /// The time directory with this name (`"0"`, `"0.5"`).
    Named(String),
}

/// Reads the case `path` (a `.foam` file or the case folder) with the latest time's fields.
pub fn read(path: &Path) -> Result<RawMesh> {
    read_case(path, &Time::Latest)
}

/// The case's time directories (names that parse as numbers), ascending.
pub fn times(case: &Path) -> Result<Vec<String>> {
    let rd = std::fs::read_dir(case).map_err(|e| Error::io(case, e))?;
    let mut out: Vec<(f64, String)> = rd
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_dir())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            name.parse::<f64>().ok().filter(|t| t.is_finite()).map(|t| (t, name))
        })
        .collect();
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(out.into_iter().map(|t| t.1).collect())
}

/// The file `dir/name`, or `dir/name.gz`.
fn find(dir: &Path, name: &str) -> Option<PathBuf> {
    [dir.join(name), dir.join(format!("{name}.gz"))].into_iter().find(|p| p.is_file())
}

/// Opens and parses the header of an OpenFOAM file; errors name it.
fn open(path: &Path) -> Result<Foam> {
    Foam::new(crate::read_file(path)?).map_err(|m| Error::format(path, m))
}

/// Every file reading the case reads (for refusing an output that is one of them).
pub fn files_read(path: &Path) -> Vec<PathBuf> {
    let case = case_dir(path);
    let mesh = case.join("constant/polyMesh");
    let mut out: Vec<PathBuf> =
        ["points", "faces", "owner", "neighbour", "boundary"].iter().filter_map(|n| find(&mesh, n)).collect();
    if let Some(t) = times(&case).ok().and_then(|t| t.last().cloned()) {
        if let Ok(rd) = std::fs::read_dir(case.join(t)) {
            out.extend(rd.filter_map(|e| e.ok()).map(|e| e.path()).filter(|p| p.is_file()));
        }
    }
    if path.is_file() {
        out.push(path.to_path_buf());
    }
    out
}

/// Reads the case `path` (a `.foam` file or the case folder) with the fields of `time`.
pub fn read_case(path: &Path, time: &Time) -> Result<RawMesh> {
    let case = case_dir(path);
    let dir = case.join("constant/polyMesh");
    if !dir.is_dir() {
        return Err(Error::format(path, format!("not an OpenFOAM case: no {}", dir.display())));
    }
    let file = |name: &str| {
        find(&dir, name).ok_or_else(|| Error::format(&dir, format!("the mesh has no '{name}' file (nor '{name}.gz')")))
    };
    let (points_path, faces_path, owner_path, neighbour_path, boundary_path) =
        (file("points")?, file("faces")?, file("owner")?, file("neighbour")?, file("boundary")?);

    let xyz = open(&points_path)?.values(3, "points").map_err(|m| Error::format(&points_path, m))?;
    let points64: Vec<[f64; 3]> = xyz.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let n_points = points64.len();
    let (face_ends, face_labels) = open(&faces_path)?.faces().map_err(|m| Error::format(&faces_path, m))?;
    let n_faces = face_ends.len();
    let labels = |path: &Path| -> Result<Vec<i64>> { open(path)?.labels("labels").map_err(|m| Error::format(path, m)) };
    let owner = labels(&owner_path)?;
    let mut neighbour = labels(&neighbour_path)?;
    // Some writers pad the neighbours of boundary faces with -1.
    while neighbour.last() == Some(&-1) {
        neighbour.pop();
    }
    let patches = open(&boundary_path)?.patches().map_err(|m| Error::format(&boundary_path, m))?;

    if owner.len() != n_faces {
        return Err(Error::format(
            &owner_path,
            format!("{} owners for {n_faces} faces: one owner per face", owner.len()),
        ));
    }
    let n_internal = neighbour.len();
    if n_internal > n_faces {
        return Err(Error::format(
            &neighbour_path,
            format!("{n_internal} neighbours for {n_faces} faces: more internal faces than faces"),
        ));
    }
    // The faces past the internal ones are boundary faces: every one in exactly one patch.
    let mut covered = vec![0u8; n_faces - n_internal];
    for p in &patches {
        if p.start < n_internal || p.start + p.n_faces > n_faces {
            return Err(Error::format(
                &boundary_path,
                format!(
                    "patch '{}' ({}) lists faces {}..{}, outside the boundary faces {n_internal}..{n_faces}",
                    p.name,
                    p.ty,
                    p.start,
                    p.start + p.n_faces
                ),
            ));
        }
        covered[p.start - n_internal..p.start - n_internal + p.n_faces].iter_mut().for_each(|c| *c += 1);
    }
    if let Some(i) = covered.iter().position(|&c| c != 1) {
        let f = n_internal + i;
        let why = if covered[i] == 0 { "no boundary patch lists it" } else { "more than one patch lists it" };
        return Err(Error::format(
            &boundary_path,
            format!(
                "face {f} is owned by cell {} and has no neighbour, but {why} ({} such faces)",
                owner[f],
                covered.iter().filter(|&&c| c != 1).count()
            ),
        ));
    }

    let check_cell = |v: i64, path: &Path, i: usize| -> Result<u32> {
        u32::try_from(v).map_err(|_| Error::format(path, format!("entry {i} ({v}) is not a cell id")))
    };
    let owner: Vec<u32> =
        owner.iter().enumerate().map(|(i, &v)| check_cell(v, &owner_path, i)).collect::<Result<_>>()?;
    let neighbour: Vec<u32> =
        neighbour.iter().enumerate().map(|(i, &v)| check_cell(v, &neighbour_path, i)).collect::<Result<_>>()?;
    let face_points: Vec<u32> = face_labels
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            u32::try_from(v).ok().filter(|&p| (p as usize) < n_points).ok_or_else(|| {
                Error::format(&faces_path, format!("face label {i} ({v}) is not a point id ({n_points} points)"))
            })
        })
        .collect::<Result<_>>()?;
    let n_cells = owner.iter().chain(&neighbour).map(|&c| c as usize + 1).max().unwrap_or(0);
    if n_cells == 0 {
        return Err(Error::format(&owner_path, "the mesh has no cells"));
    }

    // Each cell's faces, outward: (face, reversed).
    let mut counts = vec![0u32; n_cells + 1];
    owner.iter().chain(&neighbour).for_each(|&c| counts[c as usize + 1] += 1);
    for i in 0..n_cells {
        counts[i + 1] += counts[i];
    }
    let mut cell_faces = vec![(0u32, false); counts[n_cells] as usize];
    let mut fill = counts.clone();
    for (f, &c) in owner.iter().enumerate() {
        cell_faces[fill[c as usize] as usize] = (f as u32, false);
        fill[c as usize] += 1;
    }
    for (f, &c) in neighbour.iter().enumerate() {
        cell_faces[fill[c as usize] as usize] = (f as u32, true);
        fill[c as usize] += 1;
    }
    let face = |f: u32| {
        let f = f as usize;
        let start = if f == 0 { 0 } else { face_ends[f - 1] as usize };
        &face_points[start..face_ends[f] as usize]
    };
    let mut block = CellBlock::default();
    for c in 0..n_cells {
        let faces: Vec<Vec<u32>> = cell_faces[counts[c] as usize..counts[c + 1] as usize]
            .iter()
            .map(|&(f, reversed)| {
                let mut v = face(f).to_vec();
                if reversed {
                    v.reverse();
                }
                v
            })
            .collect();
        match hex_nodes(&faces) {
            Some(nodes) => block.push(CellType::from_vtk(12, 8).expect("hexahedra are read"), &nodes),
            None => block.push_polyhedron(faces.iter().map(Vec::as_slice)),
        }
    }

    let fields = read_fields(&case, time, n_cells)?;
    let points: Vec<[f32; 3]> = points64.iter().map(|p| p.map(|x| x as f32)).collect();
    Ok(RawMesh {
        points,
        points64: crate::points64_if_needed(points64),
        tets: Vec::new(),
        fields,
        higher_order: None,
        cells: Some(block),
    })
}

/// A cell's nodes in VTK's hexahedron order, when its faces (outward) are 6 quads on 8 points
/// with the hexahedron's connectivity; `None` otherwise (it stays a polyhedron).
fn hex_nodes(faces: &[Vec<u32>]) -> Option<[u32; 8]> {
    if faces.len() != 6 || faces.iter().any(|f| f.len() != 4) {
        return None;
    }
    // The bottom: the first face, reversed so that it faces in (VTK's 0-1-2-3 turn towards 4-7).
    let bottom = [faces[0][0], faces[0][3], faces[0][2], faces[0][1]];
    // Each bottom corner's edge off the bottom face: in the side face through it and the next
    // corner, the point after... found as the one neighbour (by a face edge) not in the bottom.
    let mut top = [u32::MAX; 4];
    for (k, &b) in bottom.iter().enumerate() {
        let mut up = None;
        for f in faces {
            for i in 0..4 {
                let (a, c) = (f[i], f[(i + 1) % 4]);
                let other = if a == b {
                    c
                } else if c == b {
                    a
                } else {
                    continue;
                };
                if !bottom.contains(&other) {
                    match up {
                        None => up = Some(other),
                        Some(u) if u == other => {}
                        Some(_) => return None,
                    }
                }
            }
        }
        top[k] = up?;
    }
    let nodes = [bottom[0], bottom[1], bottom[2], bottom[3], top[0], top[1], top[2], top[3]];
    let mut sorted = nodes;
    sorted.sort_unstable();
    if sorted.windows(2).any(|w| w[0] == w[1]) {
        return None;
    }
    // The top face must be one of the faces (else it is not a hexahedron's connectivity).
    let mut want = top;
    want.sort_unstable();
    faces
        .iter()
        .any(|f| {
            let mut s = [f[0], f[1], f[2], f[3]];
            s.sort_unstable();
            s == want
        })
        .then_some(nodes)
}

/// The `vol*Field`s of the chosen time directory, as cell fields.
fn read_fields(case: &Path, time: &Time, n_cells: usize) -> Result<Vec<Field>> {
    let all = times(case)?;
    let name = match time {
        Time::Latest => match all.last() {
            Some(t) => t.clone(),
            None => return Ok(Vec::new()),
        },
        Time::Named(t) => {
            if !all.contains(t) {
                return Err(Error::format(case, format!("no time directory '{t}' (the case has: {})", all.join(", "))));
            }
            t.clone()
        }
    };
    let dir = case.join(&name);
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map_err(|e| Error::io(&dir, e))?
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .collect();
    paths.sort();
    let mut out = Vec::new();
    for path in paths {
        out.extend(read_field(&path, n_cells)?);
    }
    Ok(out)
}

/// Components of the cell fields tetloc reads, by class.
const VOL_FIELDS: &[(&str, usize)] = &[
    ("volScalarField", 1),
    ("volVectorField", 3),
    ("volSphericalTensorField", 1),
    ("volSymmTensorField", 6),
    ("volTensorField", 9),
];

/// Classes that are OpenFOAM's but not cell data (face, point and uniform data, dictionaries):
/// skipped. Any other class is an error.
const OTHER_CLASSES: &[&str] = &["surface", "point", "uniformDimensioned", "dictionary", "pointVectorField"];

/// One field file: cell fields named as the file (components `NAME[i]`), or none for a class
/// that is not cell data.
fn read_field(path: &Path, n_cells: usize) -> Result<Vec<Field>> {
    let name = path.file_name().unwrap_or_default().to_string_lossy().trim_end_matches(".gz").to_string();
    if name.starts_with('.') || name.ends_with('~') || name.ends_with(".orig") {
        return Ok(Vec::new());
    }
    let mut f = match open(path) {
        Ok(f) => f,
        // Not an OpenFOAM file at all (a note, a log): not a field.
        Err(_) if !crate::read_file(path).is_ok_and(|b| b.windows(8).any(|w| w == b"FoamFile")) => {
            return Ok(Vec::new())
        }
        Err(e) => return Err(e),
    };
    let class = f.class().to_string();
    let Some(&(_, k)) = VOL_FIELDS.iter().find(|c| c.0 == class) else {
        if OTHER_CLASSES.iter().any(|c| class.starts_with(c)) {
            return Ok(Vec::new());
        }
        return Err(Error::format(
            path,
            format!(
                "field class '{class}' is not one tetloc reads (cell data: {}; face and point data are skipped)",
                VOL_FIELDS.iter().map(|c| c.0).collect::<Vec<_>>().join(", ")
            ),
        ));
    };
    let values = internal_field(&mut f, k, Some(n_cells)).map_err(|m| Error::format(path, m))?;
    Ok((0..k)
        .map(|c| {
            let v: Vec<f64> = values.iter().skip(c).step_by(k).copied().collect();
            let name = if k == 1 { name.clone() } else { format!("{name}[{c}]") };
            Field::from_f64(name, FieldLocation::Cell, v)
        })
        .collect())
}

/// A field file's `internalField`: `k` components a cell, `n_cells` of them (`None`: as many
/// as a nonuniform list holds, one for a uniform value).
fn internal_field(f: &mut Foam, k: usize, n_cells: Option<usize>) -> std::result::Result<Vec<f64>, String> {
    if !f.seek_entry("internalField")? {
        return Err("no internalField".into());
    }
    match f.word()?.as_str() {
        "uniform" => {
            let v = f.value(k, "internalField")?;
            Ok((0..n_cells.unwrap_or(1)).flat_map(|_| v.iter().copied()).collect())
        }
        "nonuniform" => {
            f.word()?; // List<scalar>, List<vector>, ...
            let v = f.values(k, "internalField")?;
            match n_cells {
                Some(n) if v.len() != n * k => {
                    Err(format!("internalField has {} values, expected {n} (one per cell)", v.len() / k))
                }
                _ => Ok(v),
            }
        }
        other => Err(format!("internalField is '{other}', not uniform or nonuniform")),
    }
}

/// Parses one OpenFOAM file as the case reader would, by its class (points, faces, owner or
/// neighbour, boundary, a cell field): how many entries it holds. The fuzz target's entry.
pub fn parse_file(bytes: &[u8]) -> std::result::Result<usize, String> {
    let mut f = Foam::new(bytes.to_vec())?;
    match f.class() {
        "faceList" | "faceCompactList" => Ok(f.faces()?.0.len()),
        "labelList" => Ok(f.labels("labels")?.len()),
        "vectorField" => Ok(f.values(3, "points")?.len() / 3),
        "polyBoundaryMesh" => Ok(f.patches()?.len()),
        class => match VOL_FIELDS.iter().find(|c| c.0 == class) {
            Some(&(_, k)) => Ok(internal_field(&mut f, k, None)?.len() / k),
            None => Err(format!("class '{class}'")),
        },
    }
}

#[cfg(test)]
mod tests;
