//! `tetloc locate`: query points in; tet ids, sampled values and the valid-point mask out.
//! Every path is checked before the mesh is read, and nothing is written over an input.

use crate::{backend, bench, mesh_arg, progress, Common};
use anyhow::{bail, Context, Result};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tetloc_core::locate::{count_non_finite, is_finite, Precision, Tolerance};
use tetloc_core::ops::fields;
use tetloc_core::BatchLocator;
use tetloc_io::output::{self, FileArg};
use tetloc_io::points::{self, Results, Values};
use tetloc_io::vtk::write::{self as vtk_write, Coords};

#[derive(clap::Args, Clone)]
pub struct LocateArgs {
    /// A mesh file (.vtu, .vtk, .msh, .node/.ele, or a partitioned .pvtu/.vtm, which runs
    /// distributed under mpirun), or SHAPE:N to generate one (e.g. fusion:1M).
    pub(crate) mesh: OsString,
    /// Query points: .npy (f32/f64, (N,3)), .csv (x,y,z per line, an optional `x,y,z` header) or
    /// .bin/.f32 (raw little-endian f32 triplets). Points with a NaN coordinate get no answer.
    #[arg(long)]
    pub(crate) points: PathBuf,
    /// Where the answers go: tet ids (-1: no answer) as .npy (int32) or .bin (raw i32); a table
    /// as .csv (tet_id, the values with --field, vtkValidPointMask); or a point set for ParaView
    /// as .vtu or .vtp (the points with the same arrays).
    #[arg(long)]
    pub(crate) out: PathBuf,
    /// A field to sample at the points (NaN where a point gets no answer).
    #[arg(long)]
    pub(crate) field: Option<String>,
    /// Where the sampled values go: .npy (float32; float64 for a field the file stores in f64,
    /// or with --precision f64), .bin/.f32 (raw float32 always) or .csv (the field, every digit,
    /// and vtkValidPointMask). Not needed when --out is .csv, .vtu or .vtp, which carry the
    /// values (Float64 likewise).
    #[arg(long)]
    pub(crate) values: Option<PathBuf>,
    /// Boundary tolerance: a point outside the mesh but within this distance of its boundary
    /// gets the nearest boundary cell and the value at the closest boundary point (as VTK's
    /// probe filter with a tolerance). A distance in mesh units, or a percentage of the mean
    /// edge length (e.g. 1%). 0, the default, is the exact answer.
    #[arg(long, default_value = "0")]
    pub(crate) tolerance: Tolerance,
    /// The backend: cpu, soft-bvh, rt-bvh, rt-rep-faces, rt-shared-faces, or auto (cpu where the
    /// only Vulkan device runs on the CPU, else the fastest in a short measurement, cached per
    /// device and driver).
    #[arg(long, default_value = "auto")]
    pub(crate) backend: String,
    /// The values' precision: f32 (the default: the backend's own; GPU kernels interpolate
    /// the f32 copy of the field, within 1e-6 of its range) or f64 (the backend finds the
    /// cells, the values are interpolated on the host in f64 on the file's f64 values and
    /// coordinates: the CPU's values on every backend), written as float64. The CPU
    /// interpolates f64 fields in f64 at f64 points by itself (and writes them as float64);
    /// f64 makes GPU backends do the same, and f32 data near the origin take the f64 path too.
    #[arg(long, default_value = "f32")]
    pub(crate) precision: Precision,
    #[command(flatten)]
    pub(crate) common: Common,
}

crate::time_steps::on_steps!(LocateArgs, check_args, mesh, values);

/// What `--out` is, by its extension.
#[derive(Clone, Copy, PartialEq, Eq)]
enum OutKind {
    /// One array: the ids.
    Array,
    /// A CSV table of every column.
    Csv,
    Vtu,
    Vtp,
}

impl OutKind {
    fn of(path: &Path) -> OutKind {
        match output::extension(path).as_str() {
            "csv" | "txt" => OutKind::Csv,
            "vtu" => OutKind::Vtu,
            "vtp" => OutKind::Vtp,
            _ => OutKind::Array,
        }
    }
}

/// The extensions `--out` takes: the id arrays and tables, and the two point sets.
fn out_extensions() -> Vec<&'static str> {
    points::ID_EXTENSIONS.iter().copied().chain(["vtu", "vtp"]).collect()
}

/// Checks the arguments and every path before anything is read or computed (also for the
/// distributed `locate` under mpirun).
pub(crate) fn check_args(a: &LocateArgs) -> Result<()> {
    let kind = OutKind::of(&a.out);
    match (&a.field, &a.values) {
        (None, Some(_)) => bail!("--values needs --field NAME"),
        (Some(_), None) if kind == OutKind::Array => {
            bail!("--field needs --values FILE (or --out FILE.csv, .vtu or .vtp, which carry ids and values)")
        }
        _ => {}
    }
    if let Some(f) = &a.field {
        points::check_value_name(f).context("--field")?;
    }
    if a.backend == "all" || a.backend.contains(',') {
        bail!(
            "locate runs one backend, not '{}' (known: {}, auto); `tetloc bench` compares several",
            a.backend,
            backend::names().join(", ")
        );
    }
    // Outputs and inputs are checked before anything is read or computed.
    output::check_output(&a.out, &out_extensions()).context("--out")?;
    let mut outputs = vec![FileArg::new("--out", &a.out)];
    if let Some(v) = &a.values {
        output::check_output(v, points::VALUE_EXTENSIONS).context("--values")?;
        outputs.push(FileArg::new("--values", v));
    }
    let mesh_files = mesh_arg::input_files(&a.mesh, a.common.format.as_deref());
    let mut inputs: Vec<FileArg> = mesh_files.iter().map(|p| FileArg::new("MESH", p)).collect();
    inputs.push(FileArg::new("--points", &a.points));
    outputs.extend(a.common.index_arg());
    crate::outputs::check_distinct(&inputs, &outputs)?;
    Ok(())
}

/// Writes `--out` (and `--values`): the ids and, with `--field`, the values; `pts` are the
/// points of a .vtu or .vtp `--out`.
pub(crate) fn write_results(a: &LocateArgs, pts: Coords, ids: &[i32], values: Values) -> Result<()> {
    let results = Results { ids, values: a.field.as_deref().map(|f| (f, values)) };
    match OutKind::of(&a.out) {
        OutKind::Vtu => vtk_write::write_points_vtu(&a.out, pts, ids, results.values)?,
        OutKind::Vtp => vtk_write::write_points_vtp(&a.out, pts, ids, results.values)?,
        OutKind::Csv | OutKind::Array => points::write_ids(&a.out, &results)?,
    }
    if let Some(v) = &a.values {
        points::write_values(v, &results)?;
    }
    Ok(())
}

pub fn run(a: &LocateArgs) -> Result<()> {
    check_args(a)?;
    let opts = a.common.opts()?;

    let m = a.common.load_mesh(&a.mesh)?;
    if let Some(f) = &a.field {
        fields::resolve_scalar(&m.fields, f).context("--field")?;
    }
    tetloc_io::check_regular_input(&a.points).context("--points")?;
    let pts64 = points::read_points64(&a.points)?;
    let pts: Vec<[f32; 3]> = pts64.iter().map(|p| p.map(|c| c as f32)).collect();
    let non_finite = count_non_finite(&pts);
    if non_finite > 0 {
        let first = pts.iter().position(|&p| !is_finite(p)).unwrap_or(0);
        eprintln!(
            "warning: {}: {non_finite} of {} points have a NaN or infinite coordinate (the first is point {first}); they get tet id -1 and value NaN",
            a.points.display(),
            pts.len()
        );
    }
    let (_, builder) = opts.builder(&m, &a.backend)?;
    let builder = builder.precision(a.precision).tolerance(a.tolerance);
    let build = || Ok(progress::with_spinner("building the locator", || builder.build())?.locator);
    a.common.with_locator(&m, build, |loc| locate_all(a, &m, &pts64, &pts, loc))
}

/// Locates `pts` (and `pts64`, the file's precision) in `m` through `loc`, and writes the
/// results.
fn locate_all(
    a: &LocateArgs,
    m: &tetloc_core::Mesh,
    pts64: &[[f64; 3]],
    pts: &[[f32; 3]],
    loc: &mut dyn BatchLocator,
) -> Result<()> {
    // Chunks keep the progress bar moving and bound GPU batch memory.
    const CHUNK: usize = 1 << 22;
    let mut ids = vec![0i32; pts.len()];
    // f32 values, or f64 ones for a field the file stores in f64 or with --precision f64.
    let f64_field = a.field.as_deref().is_some_and(|f| m.field(f).is_ok_and(|f| f.values64.is_some()));
    let wide_values = a.field.is_some() && (a.precision == Precision::F64 || f64_field);
    let mut values = vec![0f32; if a.field.is_some() && !wide_values { pts.len() } else { 0 }];
    let mut values64 = vec![0f64; if wide_values { pts.len() } else { 0 }];
    let pb = progress::bar(pts.len() as u64, format!("locating on {}", loc.name()));
    let t0 = Instant::now();
    // On f64 data (or far from the origin) the points go in at the file's precision (exact
    // on the CPU; the mesh's working frame on the GPU); f32 data near the origin takes the
    // f32 path. The values come back in f64 there (the file's values, if f64, interpolated
    // in f64).
    let at_f64 = m.wants_f64_points() || wide_values;
    let fields: Vec<&str> = a.field.as_deref().into_iter().collect();
    let mut v64 = Vec::new();
    for (c, p) in pts.chunks(CHUNK).enumerate() {
        let r = c * CHUNK..c * CHUNK + p.len();
        match &a.field {
            _ if at_f64 => {
                // f64 values land in the output; f32 ones go through a chunk buffer, narrowed.
                let out = if wide_values {
                    &mut values64[r.clone()]
                } else {
                    v64.resize(if fields.is_empty() { 0 } else { p.len() }, 0.0);
                    &mut v64[..]
                };
                loc.sample_many64(&pts64[r.clone()], &fields, &mut ids[r.clone()], out)?;
                if !wide_values && !fields.is_empty() {
                    values[r].iter_mut().zip(&v64).for_each(|(v, &x)| *v = x as f32);
                }
            }
            Some(f) => loc.locate_and_sample(p, f, &mut ids[r.clone()], &mut values[r])?,
            None => loc.locate(p, &mut ids[r])?,
        }
        pb.inc(p.len() as u64);
    }
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();

    let values = if wide_values { Values::F64(&values64) } else { Values::F32(&values) };
    write_results(a, Coords::of(pts64, pts), &ids, values)?;
    if !a.common.quiet {
        let none = ids.iter().filter(|&&i| i < 0).count();
        let within = match a.tolerance.distance(m) {
            d if d > 0.0 => format!(" by more than the tolerance {} ({d:.3e})", a.tolerance),
            _ => String::new(),
        };
        eprintln!(
            "{} points located on {} in {secs:.3} s ({}); {none} outside the mesh{within}",
            pts.len(),
            loc.name(),
            bench::fmt_rate(pts.len() as f64 / secs)
        );
    }
    Ok(())
}
