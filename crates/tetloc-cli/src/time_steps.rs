//! `--time-step K|all`: commands over a time series (an Exodus file with steps, a `.pvd`).
//! `K` runs the command on step K's fields; `all` runs it once per step, each step's outputs
//! named `STEM_K.EXT` (each written atomically, as every output), and then writes a `.pvd`
//! beside `--out` that indexes them by time for ParaView. The steps' files and the index
//! appear together once the last step is written (an `OutputSet`): a failed step leaves the
//! previous run's files as they were. The series is read once, and each step's run takes the
//! locator of the step before, given its fields ([`with_locator`]).

use crate::{mesh_arg, progress, Common};
use anyhow::{Context, Result};
use std::any::Any;
use std::cell::RefCell;
use std::ffi::OsStr;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::Arc;
use tetloc_core::mesh::steps::no_steps;
use tetloc_core::mesh::{RawMesh, TimeSteps};
use tetloc_core::{BatchLocator, Mesh};
use tetloc_io::output::{FileArg, OutputSet};
use tetloc_io::{self as io, MeshFormat};

/// Which step(s) a command runs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeStep {
    One(usize),
    All,
}

impl std::str::FromStr for TimeStep {
    type Err = String;
    fn from_str(s: &str) -> Result<TimeStep, String> {
        match s {
            "all" => Ok(TimeStep::All),
            k => k.parse().map(TimeStep::One).map_err(|_| format!("'{k}': expected a step index (0, 1, ...) or `all`")),
        }
    }
}

fn format_of(format: Option<&str>) -> Result<Option<MeshFormat>> {
    format
        .map(|f| {
            MeshFormat::from_name(f)
                .with_context(|| format!("unknown --format '{f}' (known: {})", io::KNOWN_MESH_FORMATS))
        })
        .transpose()
}

/// The mesh `arg` with the fields of `step` (`None`: as `mesh_arg::load` reads it, the first
/// step's fields for a series).
pub fn load(arg: &OsStr, format: Option<&str>, seed: u64, step: Option<usize>) -> Result<Arc<Mesh>> {
    let Some(k) = step else { return mesh_arg::load(arg, format, seed) };
    let path = Path::new(arg);
    if mesh_arg::parse_generated(arg).is_some() {
        return Err(no_steps(&path.display().to_string(), k).into());
    }
    let series = progress::with_spinner(format!("reading {} step {k}", path.display()), || {
        Series::open(path, format).and_then(|s| s.into_mesh(k))
    })?;
    Ok(Arc::new(series))
}

/// The mesh `arg` at `step` (`None`: the first), and its series kept when it has steps, for
/// moving through them later ([`Series::mesh`]): `view`.
pub fn load_series(
    arg: &OsStr,
    format: Option<&str>,
    seed: u64,
    step: Option<usize>,
) -> Result<(Arc<Mesh>, Option<Series>)> {
    let path = Path::new(arg);
    let generated = mesh_arg::parse_generated(arg).is_some();
    if generated || !path.exists() {
        // A generated mesh has no steps; a missing file gets `mesh_arg::load`'s "no such file".
        if let (true, Some(k)) = (generated, step) {
            return Err(no_steps(&path.display().to_string(), k).into());
        }
        return Ok((mesh_arg::load(arg, format, seed)?, None));
    }
    progress::with_spinner(format!("reading {}", path.display()), || {
        let series = Series::open(path, format)?;
        if series.times().is_empty() {
            if let Some(k) = step {
                return Err(no_steps(&series.name, k).into());
            }
            return Ok((Arc::new(series.into_mesh_as_read()?), None));
        }
        let mesh = series.mesh(step.unwrap_or(0))?;
        Ok((Arc::new(mesh), Some(series)))
    })
}

/// Step `k`'s mesh from a series read once (`--time-step all`), made from the mesh of the
/// step before (`like`) where there is one, for its locator to take ([`with_locator`]).
pub fn step_mesh(series: &Series, k: usize, like: Option<&Mesh>) -> Result<Arc<Mesh>> {
    let mesh = progress::with_spinner(format!("{} step {k}", series.name), || match like {
        Some(shown) => series.mesh_like(k, shown),
        None => series.mesh(k),
    })?;
    Ok(Arc::new(mesh))
}

/// A file read once as a time series: its mesh, and its steps' fields read a step at a time.
/// `view`, `render --time-step all` and every command's `--time-step all` move through the
/// steps with it, reading no mesh again.
pub struct Series {
    raw: RawMesh,
    steps: Option<TimeSteps>,
    name: String,
}

impl Series {
    pub fn open(path: &Path, format: Option<&str>) -> Result<Series> {
        io::check_regular_input(path)?;
        let (mut raw, steps) = io::read_series(path, format_of(format)?)?;
        if steps.is_some() {
            // Each step's mesh takes that step's fields: the first step's are not kept twice.
            raw.fields = Vec::new();
        }
        Ok(Series { raw, steps, name: path.display().to_string() })
    }

    /// Each step's time (empty for a single snapshot).
    pub fn times(&self) -> &[f64] {
        self.steps.as_ref().map_or(&[], |s| &s.times)
    }

    /// The mesh with step `k`'s fields, as `--time-step K` reads it.
    pub fn mesh(&self, k: usize) -> Result<Mesh> {
        let mut raw = self.raw.clone();
        raw.fields = self.fields(k)?;
        Ok(Mesh::new(raw, self.name.clone())?)
    }

    /// Step `k`'s mesh made from `shown`, a mesh of this series, with step `k`'s fields
    /// ([`Mesh::with_fields`]: a locator built on `shown` can take it and keep its search
    /// structures).
    pub fn mesh_like(&self, k: usize, shown: &Mesh) -> Result<Mesh> {
        Ok(shown.with_fields(self.fields(k)?)?)
    }

    fn into_mesh_as_read(self) -> Result<Mesh> {
        Ok(Mesh::new(self.raw, self.name)?)
    }

    fn into_mesh(mut self, k: usize) -> Result<Mesh> {
        self.raw.fields = self.fields(k)?;
        Ok(Mesh::new(self.raw, self.name)?)
    }

    fn fields(&self, k: usize) -> Result<Vec<tetloc_core::mesh::Field>> {
        match &self.steps {
            Some(s) => Ok(s.fields(k)?),
            None => Err(no_steps(&self.name, k).into()),
        }
    }
}

/// The times of the steps of `arg` (empty for a single snapshot or a generated mesh).
pub fn times(arg: &OsStr, format: Option<&str>) -> Result<Vec<f64>> {
    if mesh_arg::parse_generated(arg).is_some() {
        return Ok(Vec::new());
    }
    Ok(Series::open(Path::new(arg), format)?.times().to_vec())
}

/// `STEM_K.EXT` for step `k` of `n` (K padded to the digits of the last step).
pub fn step_path(path: &Path, k: usize, n: usize) -> PathBuf {
    let width = (n.max(1) - 1).to_string().len();
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = match path.extension() {
        Some(e) => format!("{stem}_{k:0width$}.{}", e.to_string_lossy()),
        None => format!("{stem}_{k:0width$}"),
    };
    path.with_file_name(name)
}

/// A command that takes `--time-step`: its series, `--out`, and its outputs renamed for a step.
pub(crate) trait OnSteps: Clone {
    /// The mesh argument (the series) and `--out`.
    fn series(&self) -> (&OsStr, &Path);
    fn common(&self) -> &Common;
    fn common_mut(&mut self) -> &mut Common;
    /// Names its outputs for step `k` of `n` ([`step_path`]).
    fn rename_outputs(&mut self, k: usize, n: usize);
    /// The command's checks of its arguments and outputs, which read no mesh.
    fn check(&self) -> Result<()>;
}

/// Implements [`OnSteps`] for a command's arguments that hold `common: Common` and `out`:
/// `on_steps!(Args, check_fn, mesh_field, optional_output...)`, each optional output (an
/// `Option<PathBuf>`) renamed for a step as `--out` is; `check_fn(&Args)` checks them.
macro_rules! on_steps {
    ($args:ty, $check:path, $series:ident $(, $extra:ident)*) => {
        impl crate::time_steps::OnSteps for $args {
            fn series(&self) -> (&std::ffi::OsStr, &std::path::Path) {
                (&self.$series, &self.out)
            }
            fn common(&self) -> &crate::Common {
                &self.common
            }
            fn common_mut(&mut self) -> &mut crate::Common {
                &mut self.common
            }
            fn rename_outputs(&mut self, k: usize, n: usize) {
                self.out = crate::time_steps::step_path(&self.out, k, n);
                $(self.$extra = self.$extra.as_ref().map(|v| crate::time_steps::step_path(v, k, n));)*
            }
            fn check(&self) -> anyhow::Result<()> {
                $check(self).map(drop)
            }
        }
    };
}
pub(crate) use on_steps;

/// Runs the command: as it is, or once per step for `--time-step all` (see the module).
pub(crate) fn run<A: OnSteps>(args: &A, command: fn(&A) -> Result<()>) -> Result<()> {
    if args.common().time_step != Some(TimeStep::All) {
        return command(args);
    }
    let (mesh, out) = args.series();
    // The arguments and outputs first, as one step's run checks them, before the series is
    // read (a large one takes a while): a wrong `--out` is refused at once.
    let mut first = args.clone();
    first.common_mut().index = index_path(out);
    first.check()?;
    // Read once: each step's run takes its mesh from it (the file is not read again).
    let series = match mesh_arg::parse_generated(mesh) {
        Some(_) => None,
        None => Some(Arc::new(progress::with_spinner(format!("reading {}", Path::new(mesh).display()), || {
            Series::open(Path::new(mesh), args.common().format.as_deref())
        })?)),
    };
    let times = series.as_ref().map_or_else(Vec::new, |s| s.times().to_vec());
    if times.is_empty() {
        return Err(no_steps(&Path::new(mesh).display().to_string(), 0)).context("--time-step all");
    }
    // Every step's outputs and the index appear together, once the last step is written.
    let set = OutputSet::begin();
    let kept = KeptLocator::default();
    for (k, t) in times.iter().enumerate() {
        let mut a = args.clone();
        a.common_mut().time_step = Some(TimeStep::One(k));
        a.common_mut().series = series.clone();
        a.common_mut().kept = Some(kept.clone());
        // Each step's run checks the index too: none of them may read it.
        a.common_mut().index = index_path(out);
        a.rename_outputs(k, times.len());
        command(&a).with_context(|| format!("time step {k} (time {t}); {NOTHING_WRITTEN}"))?;
    }
    write_index(out, &times, args.common().quiet)?;
    commit_steps(set, out)
}

/// The locator a step's run of `--time-step all` leaves for the next one's, with the mesh it
/// locates in (the steps share their geometry: the next step's mesh is made from it). Any
/// locator type: the front door's stack, or the CPU's own for `trace`'s per-particle walks.
#[derive(Clone, Default)]
pub struct KeptLocator(Rc<RefCell<Option<Kept>>>);

/// A locator (a `L` of [`with_locator`], boxed) and the mesh it locates in now.
type Kept = (Arc<Mesh>, Box<dyn Any>);

impl KeptLocator {
    /// The mesh of the locator kept, if any.
    pub fn mesh(&self) -> Option<Arc<Mesh>> {
        self.0.borrow().as_ref().map(|(m, _)| m.clone())
    }
}

impl std::fmt::Debug for KeptLocator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("KeptLocator")
    }
}

/// Runs `work` with a locator for `mesh`: under `--time-step all` (`kept`), the step
/// before's when it is an `L` too, given this step's fields where it can take them
/// (`BatchLocator::take_fields`: its search kept), and kept in turn for the next step when
/// `work` succeeds; else the one `build` makes.
pub fn with_locator<L: BatchLocator + 'static, R>(
    kept: Option<&KeptLocator>,
    mesh: &Arc<Mesh>,
    build: impl FnOnce() -> Result<L>,
    work: impl FnOnce(&mut L) -> Result<R>,
) -> Result<R> {
    let old = kept.and_then(|k| k.0.borrow_mut().take()).and_then(|(_, old)| old.downcast::<L>().ok());
    let mut loc = taken_or_built(old.map(|old| *old), |old| Ok(old.take_fields(mesh)), build)?;
    let out = work(&mut loc);
    if let (Some(k), true) = (kept, out.is_ok()) {
        *k.0.borrow_mut() = Some((mesh.clone(), Box::new(loc)));
    }
    out
}

/// What a step is shown or run with: `old`, the step before's, where `take` makes it take
/// the step (true), else what `build` makes, `old` dropped first to free its memory. An error
/// from `take` drops it too.
pub fn taken_or_built<T>(
    old: Option<T>,
    take: impl FnOnce(&mut T) -> Result<bool>,
    build: impl FnOnce() -> Result<T>,
) -> Result<T> {
    match old.map(|mut old| take(&mut old).map(|taken| (taken, old))).transpose()? {
        Some((true, old)) => Ok(old),
        old => {
            drop(old);
            build()
        }
    }
}

/// What a failed step of `--time-step all` says of the outputs.
pub const NOTHING_WRITTEN: &str =
    "no step's output was written (a series' files appear only once every step is written)";

/// Puts the files of `--time-step all` with output `out`, written in `set`, in place: first
/// the old index goes (a crash during the renames leaves no index over a mix of old and new
/// steps), then the steps, then the new index.
pub fn commit_steps(set: OutputSet, out: &Path) -> Result<()> {
    let old_index = index_path(out);
    Ok(set.commit_after(|| match old_index {
        Some(index) => match std::fs::remove_file(&index) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(tetloc_core::Error::io(&index, e)),
            _ => Ok(()),
        },
        None => Ok(()),
    })?)
}

/// The `.pvd` that indexes `--out`'s steps (`OUT.pvd`), where they are VTK files ParaView
/// opens (.vtu, .vtp, .vti).
pub fn index_path(out: &Path) -> Option<PathBuf> {
    let ext = tetloc_io::output::extension(out);
    matches!(ext.as_str(), "vtu" | "vtp" | "vti").then(|| out.with_extension("pvd"))
}

/// The index as a command's output, for [`crate::outputs::check_distinct`].
pub fn index_arg(index: &Path) -> FileArg<'_> {
    FileArg::new("the --time-step all index", index)
}

/// Writes [`index_path`]'s `.pvd` of the files `step_path(out, k, n)` at `times` (a note
/// instead for other formats, unless `quiet`: `-q` prints nothing on success).
pub fn write_index(out: &Path, times: &[f64], quiet: bool) -> Result<()> {
    let Some(index) = index_path(out) else {
        if quiet {
            return Ok(());
        }
        eprintln!(
            "wrote {} steps as {}; no .pvd index (it lists VTK files: .vtu, .vtp, .vti)",
            times.len(),
            step_path(out, 0, times.len()).display()
        );
        return Ok(());
    };
    let mut f = io::output::AtomicFile::create(&index)?;
    let mut text = String::from("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n<Collection>\n");
    for (k, t) in times.iter().enumerate() {
        let file = step_path(out, k, times.len());
        let name = file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let name = name.replace('&', "&amp;").replace('"', "&quot;").replace('<', "&lt;");
        text.push_str(&format!("<DataSet timestep=\"{t:?}\" group=\"\" part=\"0\" file=\"{name}\"/>\n"));
    }
    text.push_str("</Collection>\n</VTKFile>\n");
    f.write_all(text.as_bytes()).map_err(|e| tetloc_core::Error::io(&index, e))?;
    f.commit()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_paths_and_arguments() {
        assert_eq!(step_path(Path::new("out/probe.vtu"), 3, 12), Path::new("out/probe_03.vtu"));
        assert_eq!(step_path(Path::new("ids.npy"), 0, 6), Path::new("ids_0.npy"));
        assert_eq!("all".parse::<TimeStep>().unwrap(), TimeStep::All);
        assert_eq!("4".parse::<TimeStep>().unwrap(), TimeStep::One(4));
        assert!("-1".parse::<TimeStep>().is_err());
    }
}
