//! `tetloc`: which tetrahedron of this mesh contains this point, and what is the field value there?

/// `eprintln!` that never panics (std's does when stderr is closed or full), for every module
/// below: a lost stderr loses the messages, not the run and its outputs.
macro_rules! eprintln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

mod backend;
mod bench;
mod demo;
mod limits;
mod locate;
mod mesh_arg;
#[cfg(feature = "mpi")]
mod mpi;
mod outputs;
mod partition;
mod probe;
mod progress;
mod render;
mod resample;
mod signals;
mod time_steps;
mod trace;
mod view;

use anyhow::{Context, Result};
use backend::BackendOptions;
use clap::{Parser, Subcommand};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tetloc_io::output::{self, FileArg};
use tetloc_io::vtk::write as vtu_write;

#[derive(Parser)]
#[command(name = "tetloc", version, about = "Locate points in tetrahedral meshes and sample fields, on GPUs and CPUs")]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// .pvtu/.vtm inputs: also read pieces that lie outside the listing's folder (`../`,
    /// absolute paths, symbolic links that lead out), which are refused by default.
    #[arg(long, global = true)]
    allow_outside_pieces: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Print what a mesh holds: counts, bounds, fields, reoriented and degenerate tets, faces.
    Info {
        /// A mesh file (.vtu, .vtk, .msh, .node/.ele, or a partitioned .pvtu/.vtm), or SHAPE:N to
        /// generate one (e.g. fusion:1M).
        mesh: OsString,
        /// Print one JSON object (counts, bounds, faces, fields with their value ranges) instead of text.
        #[arg(long)]
        json: bool,
        /// File format, overriding the extension (vtu, pvtu, vtm, vtk, msh, node, exo, pvd).
        #[arg(long)]
        format: Option<String>,
    },
    /// Generate a synthetic mesh shaped like the paper's data sets and write it as .vtu.
    Gen {
        /// jets, fusion, agulhas or japan; SHAPE-hex, SHAPE-wedge or SHAPE-hybrid for a mesh
        /// of hexahedra, of wedges, or of hexes, pyramids, tets and wedges in layers.
        shape: String,
        /// Approximate number of cells (tets; hexes, wedges or mixed cells for SHAPE-KIND),
        /// e.g. 1M, 12M. --tets is another name for it.
        #[arg(long = "cells", visible_alias = "tets", value_name = "N", default_value = "1M")]
        tets: String,
        /// The mesh file to write: .vtu.
        #[arg(short, long)]
        out: PathBuf,
        /// Seed of the generator's random numbers (the same seed gives the same mesh).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// zlib-compress the appended data.
        #[arg(long)]
        zlib: bool,
        /// Also write the shape's terrain (agulhas: sea floor and land) as a Wavefront OBJ
        /// surface, for `tetloc render --surface FILE`.
        #[arg(long)]
        terrain: Option<PathBuf>,
        /// Also write a closed-form vector field `v` for `tetloc trace` (fusion: toroidal plus
        /// poloidal flow around the centre line; other shapes: a rotation about the vertical axis).
        #[arg(long)]
        vector: bool,
        /// Write the coordinates as Float64 with detail below f32's resolution (each vertex
        /// moved by a quarter of an f32 ulp, in a direction set by its index), as simulation
        /// codes write theirs: a mesh whose values the GPU kernels refine in f64.
        #[arg(long)]
        f64: bool,
        /// Print only errors and warnings on stderr (no progress, no summary).
        #[arg(short, long)]
        quiet: bool,
    },
    /// Locate points (and sample a field) and write the tet ids (and values).
    Locate(locate::LocateArgs),
    /// Cut a mesh into N pieces (recursive coordinate bisection) and write them as OUT.pvtu,
    /// for `mpirun -n N tetloc locate OUT.pvtu ...`.
    Partition(partition::PartitionArgs),
    /// Sample fields on a regular image (as ParaView's Resample To Image): .vti or .npy.
    Resample(resample::ResampleArgs),
    /// Sample one mesh's fields at another mesh's (or a point set's) points (as ParaView's
    /// Resample With Dataset).
    Probe(probe::ProbeArgs),
    /// Trace streamlines through a vector field (as ParaView's Stream Tracer: RK4 or adaptive RK45).
    Trace(trace::TraceArgs),
    /// Measure samples/s per backend and query set.
    Bench {
        /// A mesh file, or SHAPE:N to generate one (e.g. fusion:1.4M).
        mesh: OsString,
        /// Query sets: centers (the paper's uniform), random, bbox, grid (resample's grid over the bounds, N³ ≥ n
        /// points), all generated in the GPU kernel; host (uploaded).
        #[arg(long, value_delimiter = ',', default_value = "centers,random,bbox")]
        queries: Vec<tetloc_core::queries::QueryKind>,
        /// Number of queries per run (default: one per tet).
        #[arg(long)]
        n: Option<String>,
        /// Timed runs per measurement (after the warm-up); the median is reported.
        #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..))]
        repeats: u64,
        /// Sample this field (the scalar variant) instead of locating ids.
        #[arg(long)]
        field: Option<String>,
        /// One JSON object per line instead of a table.
        #[arg(long)]
        json: bool,
        /// Read board power through NVML while GPU kernels run (where NVML is present).
        #[arg(long)]
        power: bool,
        /// GPU kernels: time each query set twice, with and without sorting the batch along
        /// the Morton curve first (rows "KERNEL unordered").
        #[arg(long)]
        compare_order: bool,
        /// GPU kernels on a mesh stored in f64 (`gen --f64`, or f64 files): time each query
        /// set also on the mesh rounded to f32 (rows "KERNEL unrefined"), which skips the f64
        /// refinement of values; with `--field`, this is the refinement's cost.
        #[arg(long)]
        compare_refine: bool,
        /// Also trace this many particles (RK4, random seeds inside the mesh, a tenth of the
        /// mean edge a step) through `--vector`: RK4 samples/s, and on soft-bvh how many
        /// lookups the hint's walk answers (rows with and without it).
        #[arg(long)]
        trace: Option<String>,
        /// `--trace`: steps per line.
        #[arg(long, default_value_t = 1000)]
        steps: usize,
        /// `--trace`: the vector field (3 components).
        #[arg(long, default_value = "v")]
        vector: String,
        /// Backends, comma-separated: cpu, soft-bvh, rt-bvh, rt-rep-faces, rt-shared-faces, auto (the one
        /// `locate` would choose here), or all (every backend this machine can run).
        #[arg(long, default_value = "auto")]
        backend: String,
        #[command(flatten)]
        common: Common,
    },
    /// List the Vulkan devices: name, driver, ray-tracing support, memory.
    Devices,
    /// Render a field with the sample-based volume ray marcher (PNG, PNG series or GIF).
    Render(render::RenderArgs),
    /// Serve an interactive volume viewer to a browser (HTTP + WebSocket, with a token).
    View(view::ViewArgs),
    /// Benchmark a running `tetloc view`: orbit over a WebSocket, decode every frame.
    #[command(hide = true)]
    ViewBench(view::bench::BenchArgs),
    /// Generate a fusion-like mesh of about 1M tets, locate and sample a million points on
    /// every available backend, check that they agree and print samples/s.
    Demo {
        /// Approximate number of tets of the generated mesh.
        #[arg(long, default_value = "1M")]
        tets: String,
        /// Number of random query points.
        #[arg(long, default_value = "1M")]
        points: String,
        /// Seed of the mesh generator and the query points.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Vulkan device index (see `tetloc devices`).
        #[arg(long)]
        device: Option<usize>,
        /// Also run the ray-tracing kernels on a CPU-emulated Vulkan device (lavapipe), where
        /// they take minutes; by default only soft-bvh cross-checks the cpu backend there.
        #[arg(long)]
        all_backends: bool,
    },
}

/// Options of the commands that build locators.
#[derive(clap::Args, Clone)]
struct Common {
    /// rt kernels: primitives per bottom-level acceleration structure (e.g. 1M), or `off` for one structure.
    #[arg(long, default_value = "1M")]
    split: String,
    /// rt kernels: do not compact the acceleration structures.
    #[arg(long)]
    no_compact: bool,
    /// soft-bvh layout: fast (default), compact (40 % less GPU memory: four tets a leaf and ids
    /// packed to the bits the mesh needs; 4 % slower on random points, 36 % on coherent ones)
    /// or small (60 % less memory, half the speed on random points). See BENCHMARKS.md.
    #[arg(long, default_value = "fast", value_parser = clap::builder::PossibleValuesParser::new(tetloc_vulkan::PRESETS))]
    preset: String,
    /// soft-bvh: where to build its structure (BVH, entry grid, neighbours): gpu (compute
    /// shaders, the default) or cpu (the reference builder); the same structure either way.
    #[arg(long, default_value = "gpu", value_parser = ["gpu", "cpu"])]
    build: String,
    /// GPU kernels: locate points in the order given, without sorting each batch along the
    /// Morton curve first (for comparisons; sorting keeps random points over large meshes fast).
    #[arg(long)]
    no_order: bool,
    /// Vulkan device index (see `tetloc devices`).
    #[arg(long)]
    device: Option<usize>,
    /// Mesh file format, overriding the extension (vtu, pvtu, vtm, vtk, msh, node, exo, pvd).
    #[arg(long)]
    format: Option<String>,
    /// Seed of a generated mesh (SHAPE:N) and of generated query points.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print only errors and warnings on stderr (not the backend `auto` chose, nor timings).
    #[arg(short, long)]
    quiet: bool,
    /// A time series (an Exodus file with steps, a .pvd, a Gmsh file of several steps): use
    /// the fields of time step K (0-based; the first step's by default), or run on `all` of
    /// them: one output per step,
    /// named STEM_K.EXT, and a .pvd beside --out that indexes them by time.
    #[arg(long, value_name = "K|all")]
    time_step: Option<time_steps::TimeStep>,
    /// The `.pvd` index that `--time-step all` writes beside --out (set for each step's run,
    /// not an argument): an output of every step, so checked against its inputs.
    #[arg(skip)]
    index: Option<PathBuf>,
    /// The series `--time-step all` read once, for each step's run to take its mesh from
    /// (set for each step's run, not an argument).
    #[arg(skip)]
    series: Option<std::sync::Arc<time_steps::Series>>,
    /// The locator the step before left (set for each step's run of `--time-step all`).
    #[arg(skip)]
    kept: Option<time_steps::KeptLocator>,
}

impl Common {
    /// The index as one of a command's outputs, when `--time-step all` writes one.
    fn index_arg(&self) -> Option<FileArg<'_>> {
        self.index.as_deref().map(time_steps::index_arg)
    }

    /// The one time step to run on (`all` is run step by step by [`run`]).
    fn step(&self) -> Option<usize> {
        match self.time_step {
            Some(time_steps::TimeStep::One(k)) => Some(k),
            _ => None,
        }
    }

    /// The mesh `arg` at the step to run on: from the series `--time-step all` read once, else
    /// read now ([`time_steps::load`]).
    fn load_mesh(&self, arg: &std::ffi::OsStr) -> Result<std::sync::Arc<tetloc_core::Mesh>> {
        match (&self.series, self.step()) {
            (Some(series), Some(k)) => {
                let like = self.kept.as_ref().and_then(time_steps::KeptLocator::mesh);
                time_steps::step_mesh(series, k, like.as_deref())
            }
            _ => time_steps::load(arg, self.format.as_deref(), self.seed, self.step()),
        }
    }

    /// Runs `work` with the locator `build` makes for `mesh`, or under `--time-step all` the
    /// step before's given this step's fields ([`time_steps::with_locator`]).
    fn with_locator<R>(
        &self,
        mesh: &std::sync::Arc<tetloc_core::Mesh>,
        build: impl FnOnce() -> Result<Box<dyn tetloc_core::BatchLocator + Send>>,
        work: impl FnOnce(&mut dyn tetloc_core::BatchLocator) -> Result<R>,
    ) -> Result<R> {
        time_steps::with_locator(self.kept.as_ref(), mesh, build, |loc| work(loc.as_mut()))
    }

    fn opts(&self) -> Result<BackendOptions> {
        let split = if self.split == "off" { None } else { Some(mesh_arg::parse_count(&self.split)?) };
        Ok(BackendOptions {
            device: self.device,
            split,
            compact: !self.no_compact,
            order_queries: !self.no_order,
            preset: self.preset.clone(),
            build: self.build.parse().map_err(anyhow::Error::msg)?,
            quiet: self.quiet,
        })
    }
}

fn main() {
    signals::install();
    let cli = Cli::parse();
    tetloc_io::vtk::pieces::set_allow_outside_by_default(cli.allow_outside_pieces);
    // Started by mpirun (or srun): one rank of a distributed run.
    if let Some(size) = tetloc_mpi::launch::world_size() {
        std::process::exit(distributed(cli, size));
    }
    if let Err(e) = run(cli) {
        eprintln!("error: {}", error_text(&e));
        std::process::exit(1);
    }
}

/// A rank's run under an MPI launcher: `locate`, `bench`, `resample` and `probe` of a partitioned mesh (`.pvtu`,
/// `.vtm`, a decomposed OpenFOAM case) run distributed; anything else runs as usual when it is the only rank. Returns the
/// exit code.
fn distributed(cli: Cli, size: usize) -> i32 {
    let listing = match &cli.command {
        Command::Locate(a) => Some(a.mesh.clone()),
        Command::Bench { mesh, .. } => Some(mesh.clone()),
        Command::Resample(a) => Some(a.mesh.clone()),
        Command::Probe(a) => Some(a.source.clone()),
        _ => None,
    };
    let is_listing = listing.as_ref().is_some_and(|m| tetloc_io::parts::is_partitioned(Path::new(m)));
    let time_step = match &cli.command {
        Command::Locate(a) => a.common.time_step,
        Command::Bench { common, .. } => common.time_step,
        Command::Resample(a) => a.common.time_step,
        Command::Probe(a) => a.common.time_step,
        _ => None,
    };
    // One rank runs as one process, unless it is to load a partitioned mesh through MPI.
    if size == 1 && !(is_listing && cfg!(feature = "mpi")) {
        return main_exit(run(cli));
    }
    if is_listing && time_step.is_some() {
        // The ranks read their pieces' first step: refused rather than answered on it.
        eprintln!("error: {size} ranks: --time-step is not supported under mpirun; run each step without mpirun");
        return 1;
    }
    #[cfg(feature = "mpi")]
    if is_listing {
        return mpi::run(cli);
    }
    let why = if is_listing {
        "this tetloc was built without MPI (build it with `--features mpi`)".to_string()
    } else if listing.is_some() {
        "under mpirun the mesh must be partitioned: a .pvtu or .vtm (see `tetloc partition`), or a decomposed OpenFOAM case (processor*/)".to_string()
    } else {
        "this command does not run distributed; run it without mpirun".to_string()
    };
    eprintln!("error: {size} ranks: {why}");
    1
}

fn main_exit(r: Result<()>) -> i32 {
    match r {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {}", error_text(&e));
            1
        }
    }
}

/// The error and its causes, each said once: errors that name their cause in their own
/// message (`path: No such file or directory`) would otherwise repeat it.
fn error_text(e: &anyhow::Error) -> String {
    let mut text = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !text.contains(&c) {
            text = format!("{text}: {c}");
        }
    }
    text
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Info { mesh, json, format } => info(&mesh, json, format.as_deref()),
        Command::Gen { shape, tets, out, seed, zlib, terrain, vector, f64, quiet } => {
            progress::set_quiet(quiet);
            gen(&shape, &tets, &out, seed, zlib, terrain.as_deref(), vector, f64)
        }
        Command::Locate(args) => time_steps::run(&args, locate::run),
        Command::Partition(args) => partition::run(&args),
        Command::Resample(args) => time_steps::run(&args, resample::run),
        Command::Probe(args) => time_steps::run(&args, probe::run),
        Command::Trace(args) => trace::run(&args),
        Command::Devices => devices(),
        Command::Bench {
            mesh,
            queries,
            n,
            repeats,
            field,
            json,
            power,
            compare_order,
            compare_refine,
            trace,
            steps,
            vector,
            backend,
            common,
        } => {
            if common.time_step.is_some() {
                // It reads the first step's fields: refused rather than measured on them.
                anyhow::bail!("bench measures one snapshot; --time-step is for locate, resample, probe and trace");
            }
            let opts = common.opts()?;
            // The query arrays are checked before the mesh is read.
            let n = n.map(|s| mesh_arg::parse_count(&s)).transpose()?;
            if let Some(n) = n {
                limits::check_memory(&format!("--n {n}: the queries"), n as u128, bench::BYTES_PER_QUERY)?;
            }
            let read_start = std::time::Instant::now();
            let m = match trace {
                Some(_) => mesh_arg::load_with_flow(&mesh, common.format.as_deref(), common.seed)?,
                None => mesh_arg::load(&mesh, common.format.as_deref(), common.seed)?,
            };
            // A file's read rate, so that loading is measured next to the kernels (issue 12).
            if let (false, Ok(meta)) = (common.quiet, std::fs::metadata(&mesh)) {
                let secs = read_start.elapsed().as_secs_f64();
                let mb = meta.len() as f64 / 1e6;
                eprintln!("mesh read: {mb:.0} MB in {secs:.2} s ({:.0} MB/s)", mb / secs);
            }
            if let Some(f) = &field {
                m.field(f)?;
            }
            let backends = if backend == "all" {
                backend::available(&opts).into_iter().map(String::from).collect()
            } else {
                backend.split(',').map(String::from).collect()
            };
            let args = bench::BenchArgs {
                backends,
                queries,
                n,
                repeats: repeats as usize,
                field,
                seed: common.seed,
                json,
                power,
                compare_order,
                // The same file read again, its vertices rounded to f32 (no residuals to refine by).
                rounded: match compare_refine {
                    false => None,
                    true => {
                        let mut m = mesh_arg::load(&mesh, common.format.as_deref(), common.seed)?;
                        let fresh = std::sync::Arc::get_mut(&mut m).expect("a mesh just read has one owner");
                        let stored_f64 = fresh.points64.take().is_some();
                        if !stored_f64 {
                            eprintln!(
                                "--compare-refine: the mesh is stored in f32 (nothing to refine): no unrefined rows"
                            );
                        }
                        stored_f64.then_some(m)
                    }
                },
                trace: trace.map(|t| mesh_arg::parse_count(&t)).transpose()?.map(|lines| bench::trace::TraceBench {
                    lines,
                    max_steps: steps,
                    vector,
                }),
                opts,
            };
            bench::run(&m, &args)?;
            Ok(())
        }
        Command::Render(args) => render::run(args),
        Command::View(args) => view::run(args),
        Command::ViewBench(args) => view::bench::run(args),
        Command::Demo { tets, points, seed, device, all_backends } => {
            let n_points = mesh_arg::parse_count(&points)?;
            // Checked before the mesh is generated.
            limits::check_memory(
                &format!("--points {n_points}: the query points"),
                n_points as u128,
                demo::BYTES_PER_POINT,
            )?;
            demo::run(
                mesh_arg::parse_count(&tets)?,
                n_points,
                seed,
                all_backends,
                &BackendOptions { device, ..Default::default() },
            )
        }
    }
}

/// The mesh's vertices in f64, each non-zero coordinate moved by a quarter of an f32 ulp (the
/// sign from the vertex index's bits), so that it does not round to f32 exactly and the moves
/// are far below the cells' sizes.
fn below_f32_resolution(mesh: &tetloc_core::Mesh) -> Vec<[f64; 3]> {
    (0..mesh.points.len() as u32)
        .map(|i| {
            let p = mesh.vertex64(i);
            std::array::from_fn(|k| {
                // Zeros stay (a plane of the shape's box stays a plane).
                let x = (p[k] as f32).abs();
                let ulp = f64::from(f32::from_bits(x.to_bits() + 1) - x);
                let sign = if (i >> k) & 1 == 0 { 0.25 } else { -0.25 };
                if x == 0.0 {
                    0.0
                } else {
                    p[k] + sign * ulp
                }
            })
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn gen(
    shape: &str,
    tets: &str,
    out: &Path,
    seed: u64,
    zlib: bool,
    terrain: Option<&Path>,
    vector: bool,
    f64: bool,
) -> Result<()> {
    let spec: tetloc_core::gen::Spec = shape.parse().map_err(|e| anyhow::anyhow!("{e}"))?;
    let shape = spec.shape;
    let n = mesh_arg::parse_count(tets)?;
    // Every output is checked before the (possibly long) generation.
    output::check_output(out, &["vtu"]).context("-o/--out: gen writes VTK XML unstructured grids")?;
    let mut outputs = vec![FileArg::new("--out", out)];
    if let Some(t) = terrain {
        output::check_output(t, &["obj"]).context("--terrain: the terrain is written as Wavefront OBJ")?;
        mesh_arg::terrain_shape_check(shape)?;
        outputs.push(FileArg::new("--terrain", t));
    }
    crate::outputs::check_distinct(&[], &outputs)?;
    if let Some(path) = terrain {
        let ground = mesh_arg::terrain(shape, n, seed)?;
        output::write_atomically(path, |f| ground.write_obj(f).map_err(|e| tetloc_core::Error::io(path, e)))?;
        if !progress::quiet() {
            eprintln!("{}: terrain with {} triangles", path.display(), ground.triangles.len());
        }
    }
    let t0 = Instant::now();
    let mut mesh = mesh_arg::generate(spec, n, seed)?;
    if vector {
        let v = tetloc_core::gen::flow::vector_fields(shape, &mesh.points);
        mesh.fields.extend(v);
    }
    if f64 {
        mesh.points64 = Some(std::sync::Arc::new(below_f32_resolution(&mesh)));
    }
    let gen_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    progress::with_spinner(format!("writing {}", out.display()), || vtu_write::write_mesh_vtu(out, &mesh, zlib))?;
    if progress::quiet() {
        return Ok(());
    }
    eprintln!(
        "{}: {spec} with {} cells, {} vertices (generated in {gen_s:.2} s, written in {:.2} s)",
        out.display(),
        mesh.n_cells(),
        mesh.points.len(),
        t1.elapsed().as_secs_f64()
    );
    Ok(())
}

fn devices() -> Result<()> {
    let list = tetloc_vulkan::devices()?;
    if list.is_empty() {
        println!("no Vulkan devices (the cpu backend still works)");
    }
    for d in list {
        println!(
            "{}: {} ({}, {}), Vulkan {}, {:.1} GiB, ray tracing: {}, float64: {}",
            d.index,
            d.name,
            d.driver,
            d.device_type,
            d.api_version,
            d.memory_bytes as f64 / (1u64 << 30) as f64,
            if d.ray_tracing { "yes" } else { "no" },
            if d.float64 { "yes" } else { "no" }
        );
    }
    Ok(())
}

fn info(mesh: &std::ffi::OsStr, json: bool, format: Option<&str>) -> Result<()> {
    let m = mesh_arg::load(mesh, format, 1)?;
    let times = time_steps::times(mesh, format)?;
    let summary = progress::with_spinner("computing shared faces", || m.summary());
    if json {
        // The summary's own fields as they serialize (f32 figures in their shortest f32 form, as
        // Python's `info()` gives them; a `serde_json::Value` would widen them to f64 digits),
        // and the steps' times of a series.
        #[derive(serde::Serialize)]
        struct WithTimes<'a, T: serde::Serialize> {
            #[serde(flatten)]
            summary: &'a T,
            #[serde(skip_serializing_if = "<[f64]>::is_empty")]
            times: &'a [f64],
        }
        println!("{}", serde_json::to_string_pretty(&WithTimes { summary: &summary, times: &times })?);
        return Ok(());
    }
    let faces = summary.faces;
    let i = &m.info;
    println!("{}", i.source);
    if m.cells.is_some() {
        let types: Vec<String> = i.cell_types.iter().map(|(t, n)| format!("{n} {t}")).collect();
        println!("  cells       {}: {}", i.n_cells, types.join(", "));
        println!("  tets        {} (the cells' conforming decomposition, located in)", i.n_tets);
        println!("  warped      {} cells with a non-planar quad face", i.n_warped_cells);
        if let Some(n) = i.cell_types.get("polyhedron") {
            println!("  polyhedra   {n} cells with {} faces; {} centroids added", i.n_polyhedron_faces, i.n_centroids);
        }
    } else {
        println!("  tets        {}", i.n_tets);
    }
    println!("  vertices    {}", i.n_points);
    if !times.is_empty() {
        let list: Vec<String> = times.iter().enumerate().map(|(k, t)| format!("{k}: {t}")).collect();
        println!("  steps       {} ({}); the fields below are step 0's", times.len(), list.join(", "));
    }
    if i.frame.is_identity() {
        println!("  bounds      {:?} .. {:?}", i.bounds_min, i.bounds_max);
    } else {
        let (lo, hi) = m.file_bounds();
        println!("  bounds      {lo:?} .. {hi:?}");
        println!("  frame       origin {:?}, scale {} (the f32 copy is centred there)", i.frame.origin, i.frame.scale);
    }
    println!("  volume      {:.6e}", i.total_volume);
    println!("  edges       max {:.4e}, mean {:.4e}", i.max_edge_length, i.mean_edge_length);
    println!(
        "  faces       {} unique, {} on the boundary, {} non-manifold",
        faces.n_faces, faces.n_boundary, faces.n_non_manifold
    );
    let what = if m.cells.is_some() { "cells" } else { "tets" };
    println!("  reoriented  {} inverted {what} (kept, reoriented)", i.n_reoriented);
    println!("  degenerate  {} zero-volume {what} (they contain no point)", i.n_degenerate);
    if i.n_tangled > 0 {
        println!("  tangled     {} cells fold over themselves (located by their tets as they are)", i.n_tangled);
    }
    if let Some(k) = i.higher_order {
        println!("  order       {k}: higher-order {what}, located by their corner vertices");
    }
    if m.fields.is_empty() {
        println!("  fields      none");
    }
    for f in &summary.fields {
        println!("  field       '{}' per {:?}, {}", f.name, f.location, f.describe_values());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    /// Every option and argument of every command says what it is for.
    #[test]
    fn every_option_has_help() {
        let cli = Cli::command();
        let mut missing = Vec::new();
        for cmd in cli.get_subcommands() {
            for arg in cmd.get_arguments() {
                let builtin = matches!(arg.get_id().as_str(), "help" | "version");
                if !builtin && arg.get_help().is_none() && arg.get_long_help().is_none() {
                    missing.push(format!("{} {}", cmd.get_name(), arg.get_id()));
                }
            }
        }
        assert!(missing.is_empty(), "options without help: {missing:?}");
    }

    /// `locate` takes one backend: its help offers no `all` (which it refuses).
    #[test]
    fn locate_help_offers_no_backend_all() {
        let mut cli = Cli::command();
        let locate = cli.find_subcommand_mut("locate").unwrap();
        let help = locate.render_long_help().to_string();
        let backend = help.split("--backend").nth(1).unwrap().split("\n      --").next().unwrap();
        assert!(backend.contains("auto") && !backend.contains("all"), "{backend}");
    }

    /// Issue 30, item 9: `gen`'s count is optional and named `--cells` (`--tets` another name
    /// for it); `info` and `locate` name the partitioned formats; every command that writes
    /// takes `-q`.
    #[test]
    fn help_names_cells_formats_and_quiet() {
        let mut cli = Cli::command();
        let gen = cli.find_subcommand_mut("gen").unwrap();
        let usage = gen.render_usage().to_string();
        assert!(!usage.contains("--tets") && !usage.contains("--cells"), "required in: {usage}");
        let help = gen.render_long_help().to_string();
        assert!(help.contains("--cells <N>") && help.contains("--tets"), "{help}");
        for name in ["info", "locate"] {
            let help = cli.find_subcommand_mut(name).unwrap().render_long_help().to_string();
            assert!(help.contains(".pvtu") && help.contains(".vtm"), "{name}: {help}");
        }
        for name in ["gen", "partition", "locate", "resample", "probe", "trace", "render", "bench"] {
            let cmd = cli.find_subcommand(name).unwrap();
            assert!(cmd.get_arguments().any(|a| a.get_short() == Some('q')), "{name} has no -q");
        }
    }

    #[test]
    fn causes_are_said_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory (os error 2)");
        let e = anyhow::Error::new(tetloc_core::Error::io("/x/p.bin", io)).context("reading points");
        assert_eq!(error_text(&e), "reading points: /x/p.bin: No such file or directory (os error 2)");
    }
}
