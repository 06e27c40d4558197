//! OpenFOAM cases: `constant/polyMesh` (points, faces, owner, neighbour, boundary), ascii or
//! binary, each file possibly gzip-compressed (`NAME.gz`), and the `volScalarField` /
//! `volVectorField` (and tensor) internal fields of the time directories as cell data.
//!
//! A case opens through its `NAME.foam` file (as in ParaView) or its folder. Cells keep
//! OpenFOAM's order: cell id = `celli` (`poly.rs` builds them). A decomposed case
//! (`processor*/`, `decomposed.rs`) is read as one mesh: when the case folder has no
//! `constant/polyMesh`, or when asked (the format `foam-decomposed`, ParaView's "Case Type").
//!
//! **Time steps.** The case's time directories are its steps, ascending, as ParaView lists
//! them with "Skip Zero Time" (its default, and OpenFOAM's own tools' without `-withZero`):
//! the `0` directory (initial conditions, often written with macros) is a step only when it is
//! the only time. The mesh holds the first step's fields; [`read_series`] reads the others
//! when asked. Every step must hold the first step's fields. Vector fields become `NAME[0]`,
//! `NAME[1]`, `NAME[2]`.

mod decomposed;
mod foam;
mod poly;

use foam::Foam;
use poly::PolyMesh;
use std::path::{Path, PathBuf};
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{Field, FieldLocation, RawMesh, StepFields, TimeSteps};

/// The case folder of `path`: the folder a `.foam` file is in, or `path` itself.
pub fn case_dir(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.to_path_buf()
    } else {
        path.parent()
            .map_or_else(|| PathBuf::from("."), |p| if p.as_os_str().is_empty() { ".".into() } else { p.to_path_buf() })
    }
}

/// Whether `dir` looks like an OpenFOAM case (it has `constant/polyMesh`, or a decomposed
/// one in `processor0/`).
pub fn is_case(dir: &Path) -> bool {
    dir.join("constant/polyMesh").is_dir() || decomposed::mesh_dir(&dir.join("processor0")).is_dir()
}

/// The processor folders of the decomposed case `path` (a `.foam` file or the case folder),
/// in processor order: the pieces of a partitioned case.
pub fn processors(path: &Path) -> Result<Vec<PathBuf>> {
    decomposed::processors(&case_dir(path))
}

/// Whether `path` (a `.foam` file or a folder) is an OpenFOAM case with processor folders.
pub fn is_decomposed(path: &Path) -> bool {
    decomposed::mesh_dir(&case_dir(path).join("processor0")).is_dir()
}

/// A processor's mesh, and its global cell and point ids (when it has addressing files).
pub type ProcessorPiece = (RawMesh, Option<Vec<u64>>, Option<Vec<u64>>);

/// One processor folder of a decomposed case, read as a piece: its mesh with the first
/// step's fields, and its global cell and point ids from `cellProcAddressing` and
/// `pointProcAddressing` when it has them (see `decomposed`).
pub fn read_processor(processor: &Path) -> Result<ProcessorPiece> {
    decomposed::read_processor(processor)
}

/// Which time directory's fields to read.
#[derive(Clone, Debug, PartialEq)]
pub enum Time {
    /// The first time step (see the module: `0` only when it is the only time).
    First,
    /// The largest time (none when the case has no time directory).
    Latest,
    /// The time directory with this name (`"0"`, `"0.5"`).
    Named(String),
}

/// Reads the case `path` (a `.foam` file or the case folder) with the first step's fields.
pub fn read(path: &Path) -> Result<RawMesh> {
    read_case(path, &Time::First, false)
}

/// The time directories of `dir` (names that parse as numbers), ascending.
pub fn times(dir: &Path) -> Result<Vec<String>> {
    let rd = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut out: Vec<(f64, String)> = rd
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_dir())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            name.parse::<f64>().ok().filter(|t| t.is_finite()).map(|t| (t, name))
        })
        .collect();
    out.sort_by(|a, b| a.0.total_cmp(&b.0).then_with(|| a.1.cmp(&b.1)));
    // `1` and `1.0` would be two steps at one time, each with its own fields.
    if let Some(w) = out.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(Error::format(
            dir,
            format!("the time folders '{}' and '{}' name the same time, {}", w[0].1, w[1].1, w[0].0),
        ));
    }
    Ok(out.into_iter().map(|t| t.1).collect())
}

/// The steps among `times` (ascending): all but the zero time, unless it is the only one.
fn step_times(mut times: Vec<String>) -> Vec<String> {
    if times.len() > 1 {
        times.retain(|t| t.parse::<f64>() != Ok(0.0));
    }
    times
}

/// The file `dir/name`, or `dir/name.gz`.
fn find(dir: &Path, name: &str) -> Option<PathBuf> {
    [dir.join(name), dir.join(format!("{name}.gz"))].into_iter().find(|p| p.is_file())
}

/// Opens and parses the header of an OpenFOAM file; errors name it.
fn open(path: &Path) -> Result<Foam> {
    Foam::new(crate::read_file(path)?).map_err(|m| Error::format(path, m))
}

/// Where a case's mesh and time directories are: the case folder, or its processor folders.
fn parts(path: &Path, decomposed: bool) -> Result<(Vec<PathBuf>, bool)> {
    let case = case_dir(path);
    if !decomposed && case.join("constant/polyMesh").is_dir() {
        return Ok((vec![case], false));
    }
    match decomposed::processors(&case) {
        Ok(p) => Ok((p, true)),
        Err(_) if !case.is_dir() => Err(Error::format(
            path,
            format!(
                "not an OpenFOAM case: no {} (nor processor*/constant/polyMesh)",
                case.join("constant/polyMesh").display()
            ),
        )),
        Err(e) => Err(e),
    }
}

/// Every file reading the case reads (for refusing an output that is one of them): the
/// mesh's (each processor's, addressing included, when decomposed), every file of every time
/// directory, and the `.foam` file.
pub fn files_read(path: &Path, decomposed: bool) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Ok((parts, is_decomposed)) = parts(path, decomposed) {
        for part in &parts {
            let mesh = if is_decomposed { decomposed::mesh_dir(part) } else { part.join("constant/polyMesh") };
            let names = poly::MESH_FILES.iter().chain(if is_decomposed { &decomposed::ADDRESSING[..] } else { &[] });
            out.extend(names.filter_map(|n| find(&mesh, n)));
            for t in times(part).unwrap_or_default() {
                if let Ok(rd) = std::fs::read_dir(part.join(t)) {
                    out.extend(rd.filter_map(|e| e.ok()).map(|e| e.path()).filter(|p| p.is_file()));
                }
            }
        }
    }
    if path.is_file() {
        out.push(path.to_path_buf());
    }
    out
}

/// A case opened: where its fields are, and how its cells are ordered.
struct Case {
    /// The case as named (a `.foam` file or the folder).
    path: PathBuf,
    /// The folders holding time directories: the case, or each processor.
    parts: Vec<PathBuf>,
    /// Each part's cells.
    n_cells: Vec<usize>,
    /// For each mesh cell, its position in part order (`None`: the same).
    order: Option<Vec<u32>>,
    /// The steps' time directory names.
    steps: Vec<String>,
}

/// Reads the mesh of the case `path` (no fields yet) and where its fields are.
fn open_case(path: &Path, decomposed: bool) -> Result<(RawMesh, Case)> {
    let (parts, is_decomposed) = parts(path, decomposed)?;
    let (points64, cells, n_cells, order) = if is_decomposed {
        let j = decomposed::read(&parts)?;
        (j.points64, j.cells, j.n_cells, j.order)
    } else {
        let mesh = PolyMesh::read(&parts[0].join("constant/polyMesh"))?;
        let mut cells = tetloc_core::cell::CellBlock::default();
        (0..mesh.n_cells).for_each(|c| mesh.push_cell(c, &|p| p, &mut cells));
        let n = mesh.n_cells;
        (mesh.points64, cells, vec![n], None)
    };
    // Every processor must have the same times.
    let mut steps = Vec::new();
    for (k, part) in parts.iter().enumerate() {
        let t = step_times(times(part)?);
        if k == 0 {
            steps = t;
        } else if t != steps {
            return Err(Error::format(
                part,
                format!(
                    "has the times [{}] but {} has [{}]: the processors disagree",
                    t.join(", "),
                    parts[0].display(),
                    steps.join(", ")
                ),
            ));
        }
    }
    let points: Vec<[f32; 3]> = points64.iter().map(|p| p.map(|x| x as f32)).collect();
    let raw = RawMesh {
        points,
        points64: crate::points64_if_needed(points64),
        tets: Vec::new(),
        fields: Vec::new(),
        higher_order: None,
        cells: Some(cells),
    };
    Ok((raw, Case { path: path.to_path_buf(), parts, n_cells, order, steps }))
}

impl Case {
    /// The cell fields of the time directory `time` of every part, joined in mesh cell order.
    fn fields(&self, time: &str) -> Result<Vec<Field>> {
        let mut names: Vec<String> = Vec::new();
        let mut values: Vec<Vec<f64>> = Vec::new();
        for (k, (part, &n)) in self.parts.iter().zip(&self.n_cells).enumerate() {
            let dir = part.join(time);
            let read = read_fields(&dir, n)?;
            if k == 0 {
                names = read.iter().map(|f| f.0.clone()).collect();
                values = read.into_iter().map(|f| f.1).collect();
                continue;
            }
            let got: Vec<&String> = read.iter().map(|f| &f.0).collect();
            let file = |n: &str| n.split('[').next().unwrap_or(n).to_string();
            let first = self.parts[0].join(time);
            let disagree = |what: String| Err(Error::format(&dir, format!("{what}: the processors disagree")));
            if let Some(missing) = names.iter().find(|n| !got.contains(n)).map(|n| file(n)) {
                return disagree(format!("has no field '{missing}' ({} has it)", first.display()));
            }
            if let Some(extra) = got.iter().find(|n| !names.contains(n)).map(|n| file(n)) {
                return disagree(format!("has the field '{extra}' and {} has not", first.display()));
            }
            for (name, v) in read {
                let i = names.iter().position(|n| *n == name).expect("checked above");
                values[i].extend(v);
            }
        }
        Ok(names
            .into_iter()
            .zip(values)
            .map(|(name, v)| {
                let v = match &self.order {
                    Some(order) => order.iter().map(|&j| v[j as usize]).collect(),
                    None => v,
                };
                Field::from_f64(name, FieldLocation::Cell, v)
            })
            .collect())
    }
}

/// Reads the case `path` (a `.foam` file or the case folder; `decomposed`: its processor
/// folders even when it has a reconstructed mesh) with the fields of `time`.
pub fn read_case(path: &Path, time: &Time, decomposed: bool) -> Result<RawMesh> {
    let (mut raw, case) = open_case(path, decomposed)?;
    let all = times(&case.parts[0])?;
    let name = match time {
        Time::First => case.steps.first().cloned(),
        Time::Latest => all.last().cloned(),
        Time::Named(t) => {
            if !all.contains(t) {
                return Err(Error::format(
                    &case.parts[0],
                    format!("no time directory '{t}' (the case has: {})", all.join(", ")),
                ));
            }
            Some(t.clone())
        }
    };
    if let Some(t) = name {
        raw.fields = case.fields(&t)?;
    }
    Ok(raw)
}

/// Reads the case `path` with the first step's fields, and its steps (`None` without time
/// directories); `decomposed` as in [`read_case`].
pub fn read_series(path: &Path, decomposed: bool) -> Result<(RawMesh, Option<TimeSteps>)> {
    let (mut raw, case) = open_case(path, decomposed)?;
    let Some(first) = case.steps.first() else { return Ok((raw, None)) };
    raw.fields = case.fields(first)?;
    let names = raw.fields.iter().map(|f| f.name.clone()).collect();
    let times = case.steps.iter().map(|t| t.parse::<f64>().unwrap_or(f64::NAN)).collect();
    let steps = Steps { case, names };
    Ok((raw, Some(TimeSteps::new(path.display().to_string(), times, Box::new(steps)))))
}

/// The steps' fields, read when asked.
struct Steps {
    case: Case,
    /// The first step's fields: every step must have them.
    names: Vec<String>,
}

impl StepFields for Steps {
    fn read(&self, k: usize) -> Result<Vec<Field>> {
        let time = &self.case.steps[k];
        let mut fields = self.case.fields(time)?;
        let mut out = Vec::with_capacity(self.names.len());
        for name in &self.names {
            let Some(i) = fields.iter().position(|f| f.name == *name) else {
                let file = name.split('[').next().unwrap_or(name);
                return Err(Error::format(
                    self.case.parts[0].join(time),
                    format!(
                        "has no field '{file}' (time {} has it; {}): every time directory must hold the first's fields",
                        self.case.steps[0],
                        self.case.path.display()
                    ),
                ));
            };
            out.push(fields.swap_remove(i));
        }
        Ok(out)
    }
}

/// The `vol*Field`s of the time directory `dir`, as (name, values) per component, by file name.
fn read_fields(dir: &Path, n_cells: usize) -> Result<Vec<(String, Vec<f64>)>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .collect();
    paths.sort();
    let mut out = Vec::new();
    // Field name -> the file giving it (`lin` and `lin.gz`, or `v[0]` beside a vector `v`).
    let mut given = std::collections::HashMap::new();
    for path in paths {
        for (name, v) in read_field(&path, n_cells)? {
            if let Some(first) = given.insert(name.clone(), path.clone()) {
                let files = format!("{} and {}", first.display(), path.display());
                return Err(Error::format(dir, format!("{files} both give the field '{name}'; names must be unique")));
            }
            out.push((name, v));
        }
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
fn read_field(path: &Path, n_cells: usize) -> Result<Vec<(String, Vec<f64>)>> {
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
            (if k == 1 { name.clone() } else { format!("{name}[{c}]") }, v)
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
mod case_tests;
#[cfg(test)]
mod tests;
