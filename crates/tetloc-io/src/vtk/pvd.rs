//! ParaView's `.pvd` collections: a list of `<DataSet timestep=".." file=".."/>`, one
//! unstructured grid (`.vtu`, or a partitioned `.pvtu`/`.vtm`) per time step.
//!
//! The mesh must stay the same through the steps (what changes is its fields): each step's
//! file is checked against the first step's points and cells when it is read, and a step
//! whose mesh differs is refused with an error that says so (a mesh that moves or is
//! refined in time would need a locator per step). Several parts per step (`part=`) are
//! refused too. Files are listed relative to the `.pvd`; as for `.pvtu` pieces, files
//! outside its folder are refused unless allowed.

use super::xml;
use crate::{MeshFormat, ReadOptions};
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{Field, RawMesh, StepFields, TimeSteps};

/// The steps of a `.pvd`: (time, file), by time.
pub fn list(path: &Path, options: ReadOptions) -> Result<Vec<(f64, PathBuf)>> {
    let bytes = super::read_file(path)?;
    let doc = xml::parse(&bytes, "").map_err(|m| Error::format(path, m))?;
    let root = Some(&doc.root)
        .filter(|n| n.name == "VTKFile" && n.attr("type") == Some("Collection"))
        .ok_or_else(|| Error::format(path, "not a ParaView collection (<VTKFile type=\"Collection\">)"))?;
    let collection =
        root.child("Collection").ok_or_else(|| Error::format(path, "the <VTKFile> has no <Collection>"))?;
    let root_dir = if options.allow_outside_pieces { None } else { Some(super::pieces::listing_folder(path)?) };
    let mut steps = Vec::new();
    for (i, d) in collection.children_named("DataSet").enumerate() {
        let file = d.attr("file").ok_or_else(|| Error::format(path, format!("DataSet {i} has no file=")))?;
        let time =
            match d.attr("timestep") {
                None => i as f64,
                Some(t) => t.trim().parse::<f64>().ok().filter(|t| t.is_finite()).ok_or_else(|| {
                    Error::format(path, format!("DataSet {i}: timestep=\"{t}\" is not a finite number"))
                })?,
            };
        let file = super::pieces::resolve(path, file);
        if let Some(root) = &root_dir {
            super::pieces::check_inside(root, path, &file)?;
        }
        if !file.is_file() {
            return Err(Error::format(
                path,
                format!("step {i} (time {time}) lists {}, which does not exist", file.display()),
            ));
        }
        if !matches!(MeshFormat::from_path(&file), Ok(MeshFormat::Vtu | MeshFormat::Pieces)) {
            return Err(Error::format(
                path,
                format!("lists {}: tetloc reads series of unstructured grids (.vtu, .pvtu, .vtm)", file.display()),
            ));
        }
        steps.push((time, file));
    }
    if steps.is_empty() {
        return Err(Error::format(path, "the collection lists no DataSet"));
    }
    steps.sort_by(|a, b| a.0.total_cmp(&b.0));
    if let Some(w) = steps.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(Error::format(
            path,
            format!(
                "{} and {} share the time {}: several parts per step are not supported (write one .pvtu per step)",
                w[0].1.display(),
                w[1].1.display(),
                w[0].0
            ),
        ));
    }
    Ok(steps)
}

/// Every file reading the `.pvd` reads: itself and its steps' files (their pieces included).
pub fn files_read(path: &Path) -> Vec<PathBuf> {
    let mut out = vec![path.to_path_buf()];
    if let Ok(steps) = list(path, ReadOptions::default()) {
        out.extend(steps.iter().flat_map(|(_, f)| crate::input_files(f, None)));
    }
    out
}

/// The mesh of the first step, with its fields.
pub fn read(path: &Path, options: ReadOptions) -> Result<RawMesh> {
    Ok(read_series(path, options)?.0)
}

/// The mesh with the first step's fields, and the steps.
pub fn read_series(path: &Path, options: ReadOptions) -> Result<(RawMesh, TimeSteps)> {
    let steps = list(path, options)?;
    let raw = read_step(path, 0, &steps[0].1, options)?;
    let times = steps.iter().map(|s| s.0).collect();
    let fields = Steps {
        path: path.to_path_buf(),
        all_tets: raw.cells.is_none(),
        files: steps.into_iter().map(|s| s.1).collect(),
        geometry: geometry(&raw),
        stored: std::sync::OnceLock::new(),
        options,
    };
    Ok((raw, TimeSteps::new(path.display().to_string(), times, Box::new(fields))))
}

fn read_step(path: &Path, k: usize, file: &Path, options: ReadOptions) -> Result<RawMesh> {
    crate::read_raw_with(file, None, options)
        .map_err(|e| Error::format(path, format!("step {k} ({}): {e}", file.display())))
}

/// A digest of a mesh's points and cells: equal meshes have equal digests.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct Geometry {
    n_points: usize,
    n_cells: usize,
    digest: u64,
}

fn geometry(raw: &RawMesh) -> Geometry {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    let bits = |p: &[f32; 3]| p.map(f32::to_bits);
    raw.points.iter().for_each(|p| bits(p).hash(&mut h));
    raw.points64.as_ref().inspect(|p| p.iter().for_each(|q| q.map(f64::to_bits).hash(&mut h)));
    raw.tets.hash(&mut h);
    if let Some(c) = &raw.cells {
        (&c.types, &c.ends, &c.conn).hash(&mut h);
    }
    Geometry {
        n_points: raw.points.len(),
        n_cells: raw.cells.as_ref().map_or(raw.tets.len(), |c| c.len()),
        digest: h.finish(),
    }
}

struct Steps {
    path: PathBuf,
    files: Vec<PathBuf>,
    geometry: Geometry,
    /// Step 0's mesh is all linear tets (its cell data needs no filtering).
    all_tets: bool,
    /// Step 0's `vtu::stored_geometry` (`None`: not a one-piece `.vtu`), on first need.
    stored: std::sync::OnceLock<Option<u64>>,
    options: ReadOptions,
}

/// What the fast read of a step found ([`Steps::stored_fields`]).
enum Stored {
    /// The step's fields.
    Fields(Vec<Field>),
    /// Another mesh is stored (or it could not tell): the step's `.vtu` bytes, for the whole read.
    Bytes(Vec<u8>),
    /// Not a one-piece `.vtu` of linear tets: nothing read.
    NotRead,
}

impl Steps {
    /// Step `k`'s fields without decoding its points and cells, when it is a one-piece `.vtu`
    /// of linear tets storing step 0's points and cells byte for byte (what a series that
    /// repeats its mesh writes): about half the work of a whole read on a tet mesh. Otherwise
    /// the whole read compares the decoded geometry, from the bytes read here if any.
    fn stored_fields(&self, k: usize, wanted: &dyn Fn(&str) -> bool) -> Result<Stored> {
        let is_vtu = |f: &Path| crate::MeshFormat::from_path(f).is_ok_and(|m| m == crate::MeshFormat::Vtu);
        if !self.all_tets || !is_vtu(&self.files[0]) || !is_vtu(&self.files[k]) {
            return Ok(Stored::NotRead);
        }
        let fail =
            |k: usize, e: Error| Error::format(&self.path, format!("step {k} ({}): {e}", self.files[k].display()));
        let first = self.stored.get_or_init(|| {
            let bytes = crate::read_file(&self.files[0]).ok()?;
            super::vtu::stored_geometry(&bytes, &self.files[0]).ok().flatten()
        });
        let bytes = crate::read_file(&self.files[k]).map_err(|e| fail(k, e))?;
        match (first, super::vtu::stored_geometry(&bytes, &self.files[k])) {
            (Some(a), Ok(Some(b))) if *a == b => {
                super::vtu::tet_fields(&bytes, &self.files[k], wanted).map(Stored::Fields).map_err(|e| fail(k, e))
            }
            _ => Ok(Stored::Bytes(bytes)),
        }
    }

    /// Step `k`'s fields that `wanted` names: the fast read, else the whole file (parsed from
    /// the bytes the fast read took, not read again) with its mesh compared with step 0's.
    fn fields(&self, k: usize, wanted: &dyn Fn(&str) -> bool) -> Result<Vec<Field>> {
        let file = &self.files[k];
        let raw = match self.stored_fields(k, wanted)? {
            Stored::Fields(fields) => return Ok(fields),
            Stored::Bytes(bytes) => super::vtu::parse(&bytes, file)
                .map_err(|e| Error::format(&self.path, format!("step {k} ({}): {e}", file.display())))?,
            Stored::NotRead => read_step(&self.path, k, file, self.options)?,
        };
        let g = geometry(&raw);
        if g != self.geometry {
            return Err(Error::format(
                &self.path,
                format!(
                    "step {k} ({}) has another mesh than step 0 ({} points and {} cells, step 0 {} and {}{}): \
                     tetloc reads series whose mesh stays the same (only the fields change); sample each step's \
                     file on its own",
                    file.display(),
                    g.n_points,
                    g.n_cells,
                    self.geometry.n_points,
                    self.geometry.n_cells,
                    if (g.n_points, g.n_cells) == (self.geometry.n_points, self.geometry.n_cells) {
                        ", moved or renumbered"
                    } else {
                        ""
                    }
                ),
            ));
        }
        Ok(raw.fields.into_iter().filter(|f| wanted(&f.name)).collect())
    }
}

impl StepFields for Steps {
    fn read(&self, k: usize) -> Result<Vec<Field>> {
        self.fields(k, &|_| true)
    }

    fn read_named(&self, k: usize, names: &[String]) -> Result<Vec<Field>> {
        self.fields(k, &|name| names.iter().any(|n| n == name))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("tetloc-pvd-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn write_pvd(dir: &Path, files: &[(f64, &Path)]) -> PathBuf {
        let sets: String = files
            .iter()
            .map(|(t, f)| format!("<DataSet timestep=\"{t}\" group=\"\" part=\"0\" file=\"{}\"/>\n", f.display()))
            .collect();
        let pvd = dir.join("s.pvd");
        std::fs::write(&pvd, format!("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\"><Collection>\n{sets}</Collection></VTKFile>")).unwrap();
        pvd
    }

    const ALLOW: ReadOptions = ReadOptions { allow_outside_pieces: true };

    /// A step that names a missing file is refused when the collection is opened, naming it.
    #[test]
    fn a_missing_step_file_is_a_clear_error() {
        let dir = temp_dir("missing");
        let pvd = write_pvd(&dir, &[(0.0, Path::new("there.vtu")), (1.0, Path::new("gone.vtu"))]);
        std::fs::write(dir.join("there.vtu"), b"").unwrap();
        let e = list(&pvd, ALLOW).unwrap_err().to_string();
        assert!(e.contains("s.pvd") && e.contains("gone.vtu") && e.contains("does not exist"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Steps are ordered by time; two files at one time (parts) and files outside the folder
    /// are refused; the first step's mesh is read, and a step whose mesh differs is refused
    /// when it is read.
    #[test]
    fn steps_are_checked_against_the_first_mesh() {
        let Some(data) = tetloc_testdata::require_data("steps_are_checked_against_the_first_mesh") else { return };
        let dir = temp_dir("changing");
        let (same, other) = (data.join("time/part_s_series/part_s_1.vtu"), data.join("torus_s.vtu"));
        let pvd = write_pvd(&dir, &[(2.0, &other), (1.0, &same)]);
        let e = list(&pvd, ReadOptions { allow_outside_pieces: false }).unwrap_err().to_string();
        assert!(e.contains("outside"), "{e}");
        let (raw, steps) = read_series(&pvd, ALLOW).unwrap();
        assert_eq!(steps.times, [1.0, 2.0]);
        assert_eq!(steps.fields(0).unwrap().len(), raw.fields.len());
        let e = steps.fields(1).unwrap_err().to_string();
        assert!(e.contains("step 1") && e.contains("another mesh") && e.contains("torus_s.vtu"), "{e}");
        let pvd = write_pvd(&dir, &[(1.0, &same), (1.0, &same)]);
        let e = list(&pvd, ALLOW).unwrap_err().to_string();
        assert!(e.contains("several parts"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A series that repeats its mesh byte for byte (VTK's writer) has each step's fields read
    /// without decoding the mesh again: the fields a whole read of the step's file gives.
    #[test]
    fn repeated_meshes_read_only_their_fields() {
        let Some(data) = tetloc_testdata::require_data("repeated_meshes_read_only_their_fields") else { return };
        let pvd = data.join("time/part_s.pvd");
        let (_, steps) = read_series(&pvd, ALLOW).unwrap();
        let files = list(&pvd, ALLOW).unwrap();
        let parsed = Steps {
            path: pvd.clone(),
            files: files.iter().map(|f| f.1.clone()).collect(),
            geometry: geometry(&crate::read_raw_with(&files[0].1, None, ALLOW).unwrap()),
            all_tets: true,
            stored: std::sync::OnceLock::new(),
            options: ALLOW,
        };
        assert!(steps.len() > 2);
        type Key = (String, tetloc_core::mesh::FieldLocation, Vec<u32>, Option<Vec<u64>>);
        let key = |fields: Vec<Field>| -> Vec<Key> {
            let bits64 = |v: &Vec<f64>| v.iter().map(|x| x.to_bits()).collect();
            let bits = |f: &Field| f.values.iter().map(|x| x.to_bits()).collect();
            fields.iter().map(|f| (f.name.clone(), f.location, bits(f), f.values64.as_ref().map(bits64))).collect()
        };
        for (k, (_, file)) in files.iter().enumerate() {
            let whole = key(crate::read_raw_with(file, None, ALLOW).unwrap().fields);
            let Stored::Fields(fast) = parsed.stored_fields(k, &|_| true).unwrap() else {
                panic!("step {k}: read whole")
            };
            assert!(key(fast) == whole, "step {k}");
            assert!(key(steps.fields(k).unwrap()) == whole, "step {k}");
            // One field asked for: that field alone, as the whole read has it.
            let one: Vec<Key> = whole.iter().filter(|f| f.0 == "f").cloned().collect();
            assert!(one.len() == 1 && key(steps.fields_named(k, &["f".into()]).unwrap()) == one, "step {k}");
        }
    }
}
