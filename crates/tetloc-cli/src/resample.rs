//! `tetloc resample`: a mesh's fields on a regular image (vtkResampleToImage), written as
//! `.vti` or `.npy` chunk by chunk (memory bounded for any image size).

use crate::{mesh_arg, progress, Common};
use anyhow::{bail, Context, Result};
use std::ffi::OsString;
use std::path::PathBuf;
use std::time::Instant;
use tetloc_core::ops::{fields, resample, ImageGrid};
use tetloc_core::{BatchLocator, Mesh};
use tetloc_io::image::IMAGE_EXTENSIONS;
use tetloc_io::ops_output;
use tetloc_io::output::{self, FileArg};
use tetloc_io::points;

#[derive(clap::Args, Clone)]
pub struct ResampleArgs {
    /// A mesh file (.vtu, .vtk, .msh, .node/.ele, or a partitioned .pvtu/.vtm, which runs
    /// distributed under mpirun), or SHAPE:N to generate one (e.g. fusion:1M).
    pub(crate) mesh: OsString,
    /// Fields to sample, comma-separated (a vector field by its name: `v` for `v[0]`, `v[1]`,
    /// `v[2]`); every field of the mesh when left out. `.npy` takes exactly one.
    #[arg(long, value_delimiter = ',')]
    field: Vec<String>,
    /// Grid points per axis: NX,NY,NZ (each at least 1), points on both ends of each axis.
    #[arg(long, value_delimiter = ',', num_args = 1, required = true)]
    dims: Vec<usize>,
    /// The grid's bounds X0,X1,Y0,Y1,Z0,Z1 (by default the mesh's bounds, nudged inwards by a
    /// millionth of their size as vtkResampleToImage does).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    bounds: Option<Vec<f64>>,
    /// The image: .vti (every field and vtkValidPointMask, for ParaView) or .npy (one float32
    /// array (NZ,NY,NX) or (NZ,NY,NX,k), x fastest, NaN where a point is outside the mesh).
    #[arg(short, long)]
    pub(crate) out: PathBuf,
    /// zlib-compress the .vti's arrays.
    #[arg(long)]
    zlib: bool,
    /// The backend: cpu, soft-bvh, rt-bvh, rt-rep-faces, rt-shared-faces, or auto.
    #[arg(long, default_value = "auto")]
    pub(crate) backend: String,
    #[command(flatten)]
    pub(crate) common: Common,
}

crate::time_steps::on_steps!(ResampleArgs, check, mesh);

/// What the arguments ask for, checked before any mesh is read.
pub(crate) struct Plan {
    dims: [usize; 3],
    bounds: Option<([f64; 3], [f64; 3])>,
}

/// Checks the arguments and the output (every rank of a distributed run does the same).
pub(crate) fn check(a: &ResampleArgs) -> Result<Plan> {
    let [nx, ny, nz] = a.dims[..] else { bail!("--dims takes three counts NX,NY,NZ, got {:?}", a.dims) };
    if a.dims.contains(&0) {
        bail!("--dims {nx},{ny},{nz}: every dimension must be at least 1");
    }
    let bounds = match &a.bounds {
        None => None,
        Some(b) if b.len() == 6 => Some(([b[0], b[2], b[4]], [b[1], b[3], b[5]])),
        Some(b) => bail!("--bounds takes six numbers X0,X1,Y0,Y1,Z0,Z1, got {}", b.len()),
    };
    output::check_output(&a.out, IMAGE_EXTENSIONS).context("--out")?;
    // The image's size against the format and the disk, before any work (the fields are not
    // known yet: one scalar at least).
    check_image_size(&a.out, [nx, ny, nz], 1, a.zlib)?;
    let inputs: Vec<PathBuf> = mesh_arg::input_files(&a.mesh, a.common.format.as_deref());
    let inputs: Vec<FileArg> = inputs.iter().map(|p| FileArg::new("MESH", p)).collect();
    let outputs: Vec<FileArg> = std::iter::once(FileArg::new("--out", &a.out)).chain(a.common.index_arg()).collect();
    crate::outputs::check_distinct(&inputs, &outputs)?;
    if output::extension(&a.out) == "npy" && a.field.len() != 1 {
        bail!("--out {}: .npy holds one array; name one --field (or write .vti)", a.out.display());
    }
    Ok(Plan { dims: [nx, ny, nz], bounds })
}

/// The most points per axis of a `.vti`: VTK reads its extents as 32-bit integers.
const VTI_MAX_DIM: usize = i32::MAX as usize;

/// Refuses an image of `dims` points with `width` values a point that `out`'s format cannot
/// hold or that the free disk cannot: a `.npy` takes 4 bytes a value; a `.vti` 4 bytes a
/// value and 1 for the mask, twice over while it is written (each array is spilled beside
/// the output, then copied into it; with zlib the size is not known in advance).
fn check_image_size(out: &std::path::Path, dims: [usize; 3], width: usize, zlib: bool) -> Result<()> {
    let [nx, ny, nz] = dims;
    let Some(n) = dims.iter().try_fold(1u128, |n, &d| n.checked_mul(d as u128)).filter(|&n| n <= usize::MAX as u128)
    else {
        bail!("--dims {nx},{ny},{nz}: more points than this machine can count");
    };
    let bytes = match output::extension(out).as_str() {
        "vti" => {
            if let Some(d) = dims.iter().find(|&&d| d > VTI_MAX_DIM) {
                bail!("--dims {nx},{ny},{nz}: a .vti holds at most {VTI_MAX_DIM} points per axis (VTK's extents are 32-bit), not {d}");
            }
            if zlib {
                return Ok(());
            }
            2 * n * (4 * width as u128 + 1)
        }
        _ => n * 4 * width as u128,
    };
    crate::limits::check_disk(out, bytes).with_context(|| format!("--dims {nx},{ny},{nz}: {n} points"))
}

pub fn run(a: &ResampleArgs) -> Result<()> {
    progress::set_quiet(a.common.quiet);
    let plan = check(a)?;
    let opts = a.common.opts()?;
    let m = a.common.load_mesh(&a.mesh)?;
    // On the CPU the search is built only if the grid needs it (its grid path rasterizes the
    // tets; only grid points on faces need the search's tie rule).
    let (_, builder) = opts.builder(&m, &a.backend)?;
    let builder = builder.defer_cpu_build(true);
    let build = || Ok(progress::with_spinner("building the locator", || builder.build())?.locator);
    a.common.with_locator(&m, build, |loc| execute(a, &plan, &m, m.file_bounds(), loc))
}

/// Resamples through `loc`: `fields_of` names the fields (the mesh, or one piece of it),
/// `mesh_bounds` are the whole mesh's bounds in the file's coordinates.
pub(crate) fn execute(
    a: &ResampleArgs,
    plan: &Plan,
    fields_of: &Mesh,
    mesh_bounds: ([f64; 3], [f64; 3]),
    loc: &mut dyn BatchLocator,
) -> Result<()> {
    let m = fields_of;
    let [nx, ny, nz] = plan.dims;
    let groups = fields::resolve_outputs(&m.fields, &a.field, &[points::VALID_MASK])?;
    let width = groups.iter().map(|g| g.n_components()).sum();
    check_image_size(&a.out, plan.dims, width, a.zlib)?;
    let grid = match plan.bounds {
        Some((lo, hi)) => ImageGrid::spanning(lo, hi, plan.dims)?,
        None => ImageGrid::over_bounds(mesh_bounds.0, mesh_bounds.1, plan.dims)?,
    };
    let grid = resample::grid_for(grid, m, loc);
    let pb = progress::bar(grid.n_points() as u64, format!("resampling on {}", loc.name()));
    let t0 = Instant::now();
    let stats = ops_output::resample_to_file(loc, &grid, &groups, &a.out, a.zlib, |d| pb.set_position(d as u64))?;
    pb.finish_and_clear();
    if !a.common.quiet {
        eprintln!(
            "{}: {nx}x{ny}x{nz} points on {} in {:.3} s; {} inside the mesh",
            a.out.display(),
            loc.name(),
            t0.elapsed().as_secs_f64(),
            stats.n_valid
        );
    }
    Ok(())
}
