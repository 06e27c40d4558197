//! `tetloc probe SOURCE TARGET -o OUT`: SOURCE's fields at TARGET's points (ParaView's
//! Resample With Dataset). OUT is TARGET (a mesh with its cells and data, or a point set)
//! plus the sampled arrays and `vtkValidPointMask`.

use crate::{mesh_arg, progress, Common};
use anyhow::{bail, Context, Result};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tetloc_core::locate::{Points, Tolerance};
use tetloc_core::ops::{fields, probe};
use tetloc_core::{BatchLocator, Mesh};
use tetloc_io::ops_output;
use tetloc_io::output::{self, FileArg};
use tetloc_io::points;
use tetloc_io::vtk::write::Coords;
use tetloc_io::vtk::{legacy, vtu};

#[derive(clap::Args, Clone)]
pub struct ProbeArgs {
    /// The mesh whose fields are sampled (.vtu, .vtk, .msh, .node/.ele, SHAPE:N, or a
    /// partitioned .pvtu/.vtm, which runs distributed under mpirun).
    pub(crate) source: OsString,
    /// Where they are sampled: a mesh file (its vertices; OUT keeps its cells and data), or a
    /// point set (.npy (N,3), .csv x,y,z, .bin raw float32 triplets).
    target: OsString,
    /// The result: .vtu (a mesh TARGET, or a point set), or .vtp (a point set only).
    #[arg(short, long)]
    pub(crate) out: PathBuf,
    /// Fields of SOURCE to sample, comma-separated (a vector by its name); all by default.
    #[arg(long, value_delimiter = ',')]
    field: Vec<String>,
    /// Boundary tolerance, as for `locate`: points outside SOURCE but within this distance
    /// (mesh units, or a percentage of the mean edge such as 1%) get the closest boundary value.
    #[arg(long, default_value = "0")]
    pub(crate) tolerance: Tolerance,
    /// zlib-compress the output's arrays.
    #[arg(long)]
    zlib: bool,
    /// The backend: cpu, soft-bvh, rt-bvh, rt-rep-faces, rt-shared-faces, or auto.
    #[arg(long, default_value = "auto")]
    pub(crate) backend: String,
    /// TARGET's mesh format, overriding its extension (vtu, pvtu, vtm, vtk, msh, node).
    #[arg(long)]
    target_format: Option<String>,
    #[command(flatten)]
    pub(crate) common: Common,
}

crate::time_steps::on_steps!(ProbeArgs, check, source);

/// Whether TARGET names a point set (by its extension) rather than a mesh.
fn is_point_set(target: &Path) -> bool {
    points::POINT_EXTENSIONS.contains(&output::extension(target).as_str())
}

/// The reader of TARGET as any point set, its cells of any type kept as they are, when it is
/// a `.vtu`, a legacy `.vtk` or a Gmsh `.msh` file (by its extension or `--target-format`).
fn any_cells_reader(a: &ProbeArgs) -> Option<fn(&Path) -> tetloc_core::Result<vtu::AnyGrid>> {
    if mesh_arg::parse_generated(&a.target).is_some() {
        return None;
    }
    let format = a.target_format.clone().unwrap_or_else(|| output::extension(Path::new(&a.target)));
    match format.to_ascii_lowercase().as_str() {
        "vtu" => Some(vtu::read_any),
        "vtk" => Some(legacy::read_any),
        "msh" => Some(tetloc_io::gmsh::read_any),
        _ => None,
    }
}

/// Checks the arguments and the output; whether TARGET is a point set (every rank of a
/// distributed run does the same).
pub(crate) fn check(a: &ProbeArgs) -> Result<bool> {
    let target = Path::new(&a.target);
    let point_set = is_point_set(target) && a.target_format.is_none();
    let out_exts: &[&str] = if point_set { &["vtu", "vtp"] } else { &["vtu"] };
    output::check_output(&a.out, out_exts).with_context(|| {
        format!("--out: {} is written as {}", if point_set { "a point set" } else { "a mesh" }, out_exts.join(" or "))
    })?;
    let sources = mesh_arg::input_files(&a.source, a.common.format.as_deref());
    let targets = if point_set {
        vec![target.to_path_buf()]
    } else {
        mesh_arg::input_files(&a.target, a.target_format.as_deref())
    };
    let mut inputs: Vec<FileArg> = sources.iter().map(|p| FileArg::new("SOURCE", p)).collect();
    inputs.extend(targets.iter().map(|p| FileArg::new("TARGET", p)));
    let outputs: Vec<FileArg> = std::iter::once(FileArg::new("--out", &a.out)).chain(a.common.index_arg()).collect();
    crate::outputs::check_distinct(&inputs, &outputs)?;
    Ok(point_set)
}

pub fn run(a: &ProbeArgs) -> Result<()> {
    progress::set_quiet(a.common.quiet);
    let point_set = check(a)?;
    let opts = a.common.opts()?;
    let source = a.common.load_mesh(&a.source)?;
    let (_, builder) = opts.builder(&source, &a.backend)?;
    // cpu: the probe's batches search bins; the BVH is built only if a point lands on a face.
    let builder = builder.tolerance(a.tolerance).defer_cpu_build(true);
    let build = || Ok(progress::with_spinner("building the locator", || builder.build())?.locator);
    a.common.with_locator(&source, build, |loc| execute(a, point_set, &source, loc))
}

/// Probes through `loc`: `fields_of` names SOURCE's fields (the mesh, or one piece of it).
/// TARGET is read here.
pub(crate) fn execute(a: &ProbeArgs, point_set: bool, fields_of: &Mesh, loc: &mut dyn BatchLocator) -> Result<()> {
    let source = fields_of;
    let groups = fields::resolve_outputs(&source.fields, &a.field, &[points::VALID_MASK])?;
    if groups.is_empty() {
        bail!("{}: the source mesh has no fields to probe", source.info.source);
    }
    let target = Path::new(&a.target);
    // The target's points as its file has them (f64 where it stores them so), so that a
    // target far from the origin keeps its precision; a far mesh's working copy is centred.
    // A .vtu, .vtk or .msh target is any point set (a surface, vertices, volumes): read as it is,
    // its cells kept as they are; other mesh formats are read as meshes.
    let (mut target_mesh, mut target_grid) = (None, None);
    if mesh_arg::parse_generated(&a.target).is_none() {
        // Refused before it is opened: a FIFO would block for ever.
        tetloc_io::check_regular_input(target)?;
    }
    let pts: Vec<[f64; 3]> = if point_set {
        points::read_points64(target)?
    } else if let Some(read_any) = any_cells_reader(a) {
        let g = progress::with_spinner(format!("reading {}", target.display()), || read_any(target))?;
        let pts = (0..g.points.len()).map(|i| g.point64(i)).collect();
        target_grid = Some(g);
        pts
    } else {
        let m = mesh_arg::load(&a.target, a.target_format.as_deref(), a.common.seed)?;
        let pts = (0..m.points.len() as u32).map(|i| m.vertex64(i)).collect();
        target_mesh = Some(m);
        pts
    };
    let pb = progress::bar(pts.len() as u64, format!("probing on {}", loc.name()));
    let t0 = Instant::now();
    let probed = probe::probe_points(loc, Points::F64(&pts), &groups, |d| {
        pb.set_position(d as u64);
        Ok(())
    })?;
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    progress::with_spinner(format!("writing {}", a.out.display()), || {
        let pts32: Vec<[f32; 3]>;
        let target = match (target_mesh.as_deref(), &target_grid) {
            (Some(m), _) => ops_output::Target::Mesh(m), // the mesh writes its own coordinates
            (None, Some(g)) => ops_output::Target::Grid(g),
            (None, None) => {
                pts32 = pts.iter().map(|p| p.map(|c| c as f32)).collect();
                ops_output::Target::Points(Coords::of(&pts, &pts32))
            }
        };
        ops_output::write_probed(&a.out, &probed, target, a.zlib)
    })?;
    if !a.common.quiet {
        eprintln!(
            "{}: {} points probed on {} in {secs:.3} s; {} got values",
            a.out.display(),
            pts.len(),
            loc.name(),
            probed.n_valid()
        );
    }
    Ok(())
}
