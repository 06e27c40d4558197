//! `tetloc trace MESH --vector NAME --seeds SEEDS -o OUT.vtp`: streamlines through a vector
//! field (ParaView's Stream Tracer, RK4 with a fixed step or RK45 with an adaptive one, in
//! length units). On `cpu` each particle starts its lookups from its last tet; on soft-bvh
//! with RK4 one GPU kernel runs every particle to its end, each lookup walking from the
//! particle's last tet; on the other GPU backends (and the adaptive integrators) all particles
//! advance together, one batched lookup per Runge–Kutta stage. The fields at the line points
//! are sampled on the same backend. Lines are traced and written in batches of seeds, so
//! memory stays bounded whatever the number of seeds.
//!
//! `--unsteady`: pathlines (ParaView's Particle Path filter) through a time series, one point
//! per particle at the start time, each step time and the end time ([`run_unsteady`]).

use crate::time_steps::{self, TimeStep};
use crate::{mesh_arg, progress, Common};
use anyhow::{Context, Result};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Instant;
use tetloc_core::geom::Vec3;
use tetloc_core::ops::trace::{self, Direction, Integrator, PathOptions, TraceOptions};
use tetloc_io::ops_output;
use tetloc_io::output::{self, FileArg};
use tetloc_io::points;
use tetloc_io::vtk::write::PolylineWriter;
use tetloc_locator::{Backend, BareLocator};

#[derive(clap::Args, Clone)]
pub struct TraceArgs {
    /// A mesh file (.vtu, .vtk, .msh, .node/.ele, .pvtu/.vtm), or SHAPE:N to generate one (e.g. fusion:1M)
    /// with its closed-form flow `v` (as `tetloc gen --vector`).
    mesh: OsString,
    /// The vector field to follow: a 3-component array of the mesh (point or cell data).
    #[arg(long)]
    vector: String,
    /// Seed points: a file (.npy (N,3), .csv x,y,z, .bin raw float32 triplets),
    /// `line:X0,Y0,Z0,X1,Y1,Z1,N` (N points from P0 to P1) or `grid:X0,X1,Y0,Y1,Z0,Z1,NX,NY,NZ`.
    #[arg(long)]
    seeds: String,
    /// The streamlines: VTK polydata (.vtp) with the point fields, IntegrationTime,
    /// ReasonForTermination and SeedIds, as vtkStreamTracer writes them. With --unsteady,
    /// IntegrationTime is the simulation time at each point and SeedIds each particle's seed,
    /// and each point carries its particle as vtkParticlePathFilter writes it: ParticleId (its
    /// index among the particles of its injection inside the mesh), InjectedPointId (its
    /// seed), InjectionStepId (its injection's output time), ParticleAge, and ErrorCode and
    /// ParticleSourceId (0: points are recorded where a step succeeded; one seed source).
    #[arg(short, long)]
    out: PathBuf,
    /// Step length (mesh units; by default a tenth of the mean edge); with rk45 the first step.
    /// With --unsteady a time (by default half of each interval between output times, as
    /// vtkParticlePathFilter); the step bounds are times too.
    #[arg(long)]
    step: Option<f64>,
    /// rk4 (fixed step, vtkRungeKutta4), rk45 (adaptive, Dormand-Prince 5(4)) or cash-karp
    /// (adaptive, the Cash-Karp tableau of VTK's vtkRungeKutta45), both adaptive ones with
    /// vtkRungeKutta45's step control.
    #[arg(long, default_value = "rk4")]
    integrator: String,
    /// Adaptive steps: the largest error estimate of a step (mesh units).
    #[arg(long, default_value_t = 1e-6)]
    max_error: f64,
    /// Adaptive steps: the smallest step (by default step / 50, as VTK's 0.01 around its 0.5).
    #[arg(long)]
    min_step: Option<f64>,
    /// Adaptive steps: the largest step (by default 2 step, as VTK's 1 around its 0.5).
    #[arg(long)]
    max_step: Option<f64>,
    /// Steps per line before it stops (OUT_OF_STEPS; VTK takes one more).
    #[arg(long, default_value_t = 2000)]
    max_steps: usize,
    /// Longest line (mesh units; VTK's maximum propagation). Unlimited by default.
    #[arg(long)]
    max_length: Option<f64>,
    /// Longest integration time: the last step lands on it, reason 7 (VTK has no such limit;
    /// 7 is its first code for custom criteria). Unlimited by default.
    #[arg(long)]
    max_time: Option<f64>,
    /// forward, backward or both (two lines per seed: the forward ones, then the backward ones).
    #[arg(long, default_value = "forward")]
    direction: String,
    /// Speeds at or below this stop a line (STAGNATION).
    #[arg(long, default_value_t = 1e-12)]
    terminal_speed: f64,
    /// zlib-compress the output's arrays.
    #[arg(long)]
    zlib: bool,
    /// Also write ParaView's "Compute Vorticity" arrays at each line point (vtkStreamTracer's,
    /// Float64): Vorticity (the curl of the vector in the cell holding the point),
    /// AngularVelocity (the vorticity along the unit velocity), Rotation (the angular velocity
    /// integrated along the line in IntegrationTime) and Normals (sliding normals turned by the
    /// rotation, for ribbons and tubes). With --unsteady the first three, as
    /// vtkParticlePathFilter's: the curl and velocity interpolated in time, the rotation
    /// integrated in simulation time from the injection (no Normals).
    #[arg(long)]
    vorticity: bool,
    /// The backend: cpu (each particle walks from its last tet), a GPU kernel (soft-bvh with
    /// rk4: whole lines in one kernel, each particle walking from its last tet; otherwise
    /// every particle advanced together, one batch per stage), or auto.
    #[arg(long, default_value = "auto")]
    backend: String,
    /// Pathlines (vtkParticlePathFilter): MESH is a time series (an Exodus file with steps, a
    /// .pvd); the particles, injected at the seeds at --start-time, move through the vector
    /// interpolated linearly in time between the steps, time being the integration variable,
    /// until --end-time or until they leave the mesh. Two steps are held in memory at a time.
    /// With --time-step all: OUT_K.vtp at each output time after the start (the lines as a run
    /// ending there draws them) and OUT.pvd indexing them by time.
    #[arg(long)]
    unsteady: bool,
    /// --unsteady: the time the particles are injected at (by default the first step's).
    #[arg(long, requires = "unsteady")]
    start_time: Option<f64>,
    /// --unsteady: the time the particles stop at (by default the last step's).
    #[arg(long, requires = "unsteady")]
    end_time: Option<f64>,
    /// --unsteady: inject the seeds again at every N-th output time after the start (ParaView's
    /// "Force Reinjection Every NSteps"; 0: once). Each injection's particles are new lines,
    /// injection after injection; a line's first IntegrationTime is its injection time.
    #[arg(long, requires = "unsteady", default_value_t = 0, value_name = "N")]
    reinject_every: usize,
    /// --unsteady: streaklines instead of pathlines (ParaView's Streak Line filter): for each
    /// seed, the line through its particles at the end time, the oldest first and the seed
    /// itself last, with ParticleAge (the time since each particle's injection) instead of
    /// IntegrationTime. The seeds are injected at every output time unless --reinject-every
    /// says otherwise.
    #[arg(long, requires = "unsteady")]
    streaklines: bool,
    /// Line points a batch holds (its memory; at least one line a batch). For tests that
    /// need several batches of a small run; hidden from the help.
    #[arg(long, default_value_t = trace::BATCH_POINTS, hide = true)]
    batch_points: usize,
    #[command(flatten)]
    common: Common,
}

/// Bytes a line point takes while its batch is traced and written (the point in f64, its
/// time, tet and sampled values, the spilled copy; measured at about 106).
const LINE_POINT_BYTES: u128 = 128;

/// Bytes a line takes in its batch besides its points: its `Line`, its job and order entries,
/// the tracer's state (measured at about 360 with --max-steps 1: 700 bytes a seed in all).
const LINE_STATE_BYTES: u128 = 512;

/// Bytes a seed holds for the whole run: its point (12) and, per line, the end the writer
/// keeps until the file is written (8).
fn seed_bytes(dirs: u128) -> u128 {
    std::mem::size_of::<Vec3>() as u128 + dirs * std::mem::size_of::<usize>() as u128
}

/// Refuses `n` seeds (`dirs` lines each) whose points and lines' ends cannot fit, before
/// they are made and before the mesh is read.
fn check_seeds_memory(n: usize, dirs: u128) -> Result<()> {
    let what =
        format!("--seeds: {n} seeds ({} lines, each seed's point and line ends held to the end)", n as u128 * dirs);
    crate::limits::check_memory(&what, n as u128, seed_bytes(dirs))
}

/// Refuses a trace whose memory cannot fit, before any line is traced: every seed's point
/// and line ends ([`seed_bytes`]), the list of batches, and two batches at once (one written
/// while the next is traced), each of the lines `TraceOptions::batches` puts in one, every
/// line holding its state and the most points it can take (--max-steps, or fewer by
/// --max-length). Seeds already made (`!unmade`) count only through what they add.
fn check_trace_memory(
    o: &TraceOptions,
    n_seeds: usize,
    batch_points: usize,
    max_steps: usize,
    unmade: bool,
) -> Result<()> {
    let dirs: u128 = if o.direction == Direction::Both { 2 } else { 1 };
    let n = n_seeds as u128;
    let points = o.steps_bound() as u128 + 2;
    // As `TraceOptions::batches`: at least one line a batch, one direction a batch.
    let per_batch = (batch_points as u128 / points).max(1).min(n.max(1));
    let n_batches = dirs * n.div_ceil(per_batch);
    let batch_entry = std::mem::size_of::<(TraceOptions, std::ops::Range<usize>)>() as u128;
    let held = if unmade { 0 } else { std::mem::size_of::<Vec3>() as u128 };
    let whole_run = n * (seed_bytes(dirs) - held) + n_batches * batch_entry;
    let batches = 2 * per_batch.saturating_mul(LINE_STATE_BYTES + points.saturating_mul(LINE_POINT_BYTES));
    let what = format!(
        "--seeds ({n_seeds} seeds) with --max-steps {max_steps}: {} lines of up to {} steps, {per_batch} a batch \
         (two batches at once),",
        n * dirs,
        o.steps_bound()
    );
    crate::limits::check_memory(&what, whole_run.saturating_add(batches), 1)
}

crate::time_steps::on_steps!(TraceArgs, check_steady, mesh);

/// Streamlines in one step's field (`--time-step K|all` as the other commands take it), or
/// pathlines through the steps (`--unsteady`, whose `--time-step all` is its output times).
pub fn run(a: &TraceArgs) -> Result<()> {
    progress::set_quiet(a.common.quiet);
    if a.unsteady {
        return run_unsteady(a);
    }
    time_steps::run(a, run_steady)
}

/// Checks streamlines' direction, output and inputs (no file is read).
fn check_steady(a: &TraceArgs) -> Result<Direction> {
    let direction: Direction = a.direction.parse()?;
    output::check_output(&a.out, &["vtp"]).context("--out: streamlines are written as VTK polydata")?;
    let meshes = mesh_arg::input_files(&a.mesh, a.common.format.as_deref());
    let seeds_file = PathBuf::from(&a.seeds);
    let mut inputs: Vec<FileArg> = meshes.iter().map(|p| FileArg::new("MESH", p)).collect();
    if !is_seed_spec(&a.seeds) {
        inputs.push(FileArg::new("--seeds", &seeds_file));
    }
    let outputs: Vec<FileArg> = std::iter::once(FileArg::new("--out", &a.out)).chain(a.common.index_arg()).collect();
    crate::outputs::check_distinct(&inputs, &outputs)?;
    Ok(direction)
}

fn run_steady(a: &TraceArgs) -> Result<()> {
    let direction = check_steady(a)?;
    let mut o = TraceOptions {
        step: a.step.unwrap_or(1.0), // checked now, the default set once the mesh is read
        max_steps: a.max_steps,
        max_length: a.max_length.unwrap_or(f64::INFINITY),
        max_time: a.max_time.unwrap_or(f64::INFINITY),
        terminal_speed: a.terminal_speed,
        direction,
        integrator: a.integrator.parse::<Integrator>().context("--integrator")?,
        max_error: a.max_error,
        min_step: a.min_step,
        max_step: a.max_step,
    };
    o.check()?;
    let opts = a.common.opts()?;
    // Before the mesh is read: all the trace needs where --step is given, else the seeds'.
    let seeds = make_seeds(&a.seeds, |n| match a.step {
        Some(_) => check_trace_memory(&o, n, a.batch_points, a.max_steps, true),
        None => check_seeds_memory(n, if direction == Direction::Both { 2 } else { 1 }),
    })?;

    // Generated shapes come with their closed-form flow `v` (`gen --vector`).
    let m = match a.common.step() {
        None => mesh_arg::load_with_flow(&a.mesh, a.common.format.as_deref(), a.common.seed)?,
        Some(_) => a.common.load_mesh(&a.mesh)?,
    };
    if a.step.is_none() {
        o.step = 0.1 * m.info.mean_edge_length as f64;
        o.check()?;
    }
    let (lo, hi) = m.file_bounds();
    o.check_scale(lo.iter().chain(&hi).fold(0.0, |s, c| s.max(c.abs()))).context("--step")?;
    check_trace_memory(&o, seeds.len(), a.batch_points, a.max_steps, false)?;
    let vector = trace::vector_field(&m, &a.vector).context("--vector")?;
    let c = vector.component_refs();
    let [x, y, z] = [c[0], c[1], c[2]];
    let (backend, builder) = opts.builder(&m, &a.backend)?;
    let name = backend.name();
    let n_lines = seeds.len() * if direction == Direction::Both { 2 } else { 1 };
    let out_fields = trace::line_fields(&m, &vector);
    // Lines go to the file batch after batch (temporary files until it is complete), so an
    // output of any size needs the memory of two batches: one spilled while the next is traced.
    let mut writer = PolylineWriter::new(&a.out)?;
    let batches = o.batches(seeds.len(), a.batch_points);
    // Seconds spilling the batches (overlapping the next batch's tracing).
    let mut spilling = 0.0;
    let spill = |(arrays, seed_base): (trace::LineArrays, usize)| -> Result<()> {
        let t = Instant::now();
        ops_output::push_lines(&mut writer, &arrays, seed_base)?;
        spilling += t.elapsed().as_secs_f64();
        Ok(())
    };
    // Under --time-step all each step's run takes the locator the step before left.
    let kept = a.common.kept.as_ref();
    // The per-particle walk runs on tets: mixed meshes take the batch tracer, whose locator
    // maps answers to cells and interpolates with the cells' shape functions.
    let (secs, sampling) = if backend == Backend::Cpu && m.cells.is_none() {
        // Deferred: the tracer builds the search it needs (the bins, not the BVH).
        let build = || {
            let bare = progress::with_spinner("building the locator", || builder.defer_cpu_build(true).build_bare())?;
            let BareLocator::Cpu(cpu) = bare.locator else { anyhow::bail!("cpu: not the CPU's locator") };
            Ok(cpu)
        };
        time_steps::with_locator(kept, &m, build, |cpu| {
            trace_in_batches(&seeds, batches, n_lines, name, spill, &mut |seeds, ob, progress| {
                // The line fields come from the integrator's own lookups (no second pass).
                let arrays = trace::trace_sampled(seeds, ob, cpu, [x, y, z], &out_fields, &progress)?;
                let t = Instant::now();
                let arrays = arrays.with_vorticity(a.vorticity.then_some((&*m, &vector)))?;
                Ok((arrays, t.elapsed().as_secs_f64()))
            })
        })?
    } else {
        let build = || Ok(progress::with_spinner("building the locator", || builder.build())?.locator);
        time_steps::with_locator(kept, &m, build, |loc| {
            trace_in_batches(&seeds, batches, n_lines, name, spill, &mut |seeds, ob, progress| {
                let lines = trace::trace_with(seeds, ob, loc.as_mut(), [x, y, z], &out_fields, progress)?;
                let t = Instant::now();
                let arrays = trace::LineArrays::sample(&lines, &m, loc.as_mut(), &out_fields)?;
                let arrays = arrays.with_vorticity(a.vorticity.then_some((&*m, &vector)))?;
                Ok((arrays, t.elapsed().as_secs_f64()))
            })
        })?
    };
    let (n_points, n_made) = (writer.n_points(), writer.n_lines());
    let t_write = Instant::now();
    progress::with_spinner(format!("writing {}", a.out.display()), || writer.finish(a.zlib))?;
    let writing = t_write.elapsed().as_secs_f64();
    let without = n_lines - n_made;
    if without > 0 {
        eprintln!(
            "warning: {without} of {n_lines} lines have no step inside the mesh (their seed is outside it, or on its boundary going out); VTK makes no line for them either"
        );
    }
    if !a.common.quiet {
        eprintln!(
            "{}: {} lines, {n_points} points (steps at {}) on {name} in {secs:.3} s",
            a.out.display(),
            n_made,
            crate::bench::fmt_rate((n_points - n_made) as f64 / secs)
        );
        eprintln!(
            "  then: line fields sampled {sampling:.3} s, batches spilled {spilling:.3} s, file written {writing:.3} s"
        );
    }
    Ok(())
}

/// `--unsteady`: pathlines through the series MESH, on cpu (each particle walking from its
/// last tet) or through the backend's batched lookups, written as one batch.
fn run_unsteady(a: &TraceArgs) -> Result<()> {
    output::check_output(&a.out, &["vtp"]).context("--out: pathlines are written as VTK polydata")?;
    let path = Path::new(&a.mesh);
    if a.direction.parse::<Direction>()? != Direction::Forward {
        anyhow::bail!(
            "--unsteady: pathlines go forward in time from --start-time; --direction {} is for streamlines",
            a.direction
        );
    }
    let frames = match a.common.time_step {
        None => false,
        Some(TimeStep::All) => true,
        Some(TimeStep::One(_)) => anyhow::bail!(
            "--unsteady runs through the steps from --start-time to --end-time; --time-step K picks one step (--time-step all writes the lines at every output time)"
        ),
    };
    if mesh_arg::parse_generated(&a.mesh).is_some() {
        anyhow::bail!(
            "{}: --unsteady needs a time series (an Exodus file with time steps, or a .pvd); a generated mesh is a single snapshot",
            path.display()
        );
    }
    let meshes = mesh_arg::input_files(&a.mesh, a.common.format.as_deref());
    let mut inputs: Vec<FileArg> = meshes.iter().map(|p| FileArg::new("MESH", p)).collect();
    if !is_seed_spec(&a.seeds) {
        inputs.push(FileArg::new("--seeds", Path::new(&a.seeds)));
    }
    if !frames {
        crate::outputs::check_distinct(&inputs, &[FileArg::new("--out", &a.out)])?;
    }
    let seeds = make_seeds(&a.seeds, |n| check_seeds_memory(n, 1))?;
    if seeds.len() > trace::MAX_SEEDS {
        anyhow::bail!("--seeds: {} particles; at most {} (their ids are 32-bit)", seeds.len(), trace::MAX_SEEDS);
    }
    let o = PathOptions {
        integrator: a.integrator.parse::<Integrator>().context("--integrator")?,
        step: a.step,
        max_error: a.max_error,
        min_step: a.min_step,
        max_step: a.max_step,
        terminal_speed: a.terminal_speed,
        start_time: a.start_time,
        end_time: a.end_time,
        reinject_every: a.reinject_every,
        streaklines: a.streaklines,
        vorticity: a.vorticity,
    };
    o.check()?;
    let format = a
        .common
        .format
        .as_deref()
        .map(|f| {
            tetloc_io::MeshFormat::from_name(f)
                .with_context(|| format!("unknown --format '{f}' (known: {})", tetloc_io::KNOWN_MESH_FORMATS))
        })
        .transpose()?;
    tetloc_io::check_regular_input(path)?;
    let (raw, steps) =
        progress::with_spinner(format!("reading {}", path.display()), || tetloc_io::read_series(path, format))?;
    let Some(steps) = steps else {
        anyhow::bail!(
            "{}: --unsteady needs a time series (an Exodus file with time steps, or a .pvd); this file is a single snapshot",
            path.display()
        );
    };
    let legs = o.legs(&steps.source, &steps.times)?;
    // --time-step all: a file at each output time after the start, and their index.
    let frame_files: Vec<PathBuf> = match frames {
        true => (0..legs.len()).map(|k| time_steps::step_path(&a.out, k, legs.len())).collect(),
        false => Vec::new(),
    };
    if frames {
        let index = time_steps::index_path(&a.out);
        let mut outputs: Vec<FileArg> = frame_files.iter().map(|p| FileArg::new("--out (a time's file)", p)).collect();
        outputs.extend(index.as_deref().map(time_steps::index_arg));
        crate::outputs::check_distinct(&inputs, &outputs)?;
    }
    let m = std::sync::Arc::new(tetloc_core::Mesh::new(raw, path.display().to_string())?);
    let vector = trace::vector_field(&m, &a.vector).context("--vector")?;
    let c = vector.component_refs();
    let xyz = [c[0], c[1], c[2]];
    let out_fields = trace::line_fields(&m, &vector);
    let opts = a.common.opts()?;
    let (backend, builder) = opts.builder(&m, &a.backend)?;
    let name = backend.name();
    let pb = progress::bar(legs.len() as u64, format!("pathlines on {name}"));
    let tick = |n: usize| -> tetloc_core::Result<()> {
        pb.set_position(n as u64);
        Ok(())
    };
    let job = trace::PathJob { seeds: &seeds, options: &o, steps: &steps, vector: xyz, fields: &out_fields };
    let t0 = Instant::now();
    // The per-particle walk runs on tets; a mixed mesh goes through its cell locator (every
    // particle a batch, each answer a cell interpolated with its own shape functions).
    let run = if backend == Backend::Cpu && m.cells.is_none() {
        let bare = progress::with_spinner("building the locator", || builder.build_bare())?;
        let BareLocator::Cpu(cpu) = bare.locator else { anyhow::bail!("cpu: not the CPU's locator") };
        trace::pathline_run(job, &cpu, tick)?
    } else {
        let mut loc = progress::with_spinner("building the locator", || builder.build())?.locator;
        trace::pathline_run_batch(job, loc.as_mut(), &m, tick)?
    };
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let write = |path: &Path, arrays: &trace::LineArrays| -> Result<(usize, usize)> {
        let mut writer = PolylineWriter::new(path)?;
        ops_output::push_lines(&mut writer, arrays, 0)?;
        let made = (writer.n_points(), writer.n_lines());
        progress::with_spinner(format!("writing {}", path.display()), || writer.finish(a.zlib))?;
        Ok(made)
    };
    let (n_points, n_made) = if frames {
        let times = run.frame_times();
        let mut last = (0, 0);
        // The times' files and their index appear together once the last is written.
        let set = tetloc_io::output::OutputSet::begin();
        for (k, file) in frame_files.iter().enumerate() {
            last = write(file, &run.frame(k))
                .with_context(|| format!("output time {k}; {}", time_steps::NOTHING_WRITTEN))?;
        }
        time_steps::write_index(&a.out, &times, a.common.quiet)?;
        time_steps::commit_steps(set, &a.out)?;
        last
    } else {
        write(&a.out, &run.output())?
    };
    let particles = seeds.len() * o.injections(&legs);
    let what = if a.streaklines { "streaklines" } else { "pathlines" };
    if a.streaklines && n_made < seeds.len() {
        eprintln!(
            "warning: {} of {} seeds make no streakline (fewer than two of their particles are in the mesh at the end time)",
            seeds.len() - n_made,
            seeds.len()
        );
    } else if !a.streaklines && n_made < particles {
        eprintln!(
            "warning: {} of {particles} particles make no line (injected outside the mesh, or gone before the next output time)",
            particles - n_made,
        );
    }
    if !a.common.quiet {
        let written = match (frames, time_steps::index_path(&a.out)) {
            (true, index) => {
                let shown = index.unwrap_or_else(|| frame_files[0].clone());
                format!("{}: {} files, one an output time; at the end time", shown.display(), legs.len())
            }
            (false, _) => format!("{}:", a.out.display()),
        };
        eprintln!(
            "{written} {n_made} {what}, {n_points} points over {} legs ({} to {}) on {name} in {secs:.3} s",
            legs.len(),
            legs[0].from,
            legs[legs.len() - 1].to
        );
    }
    Ok(())
}

/// Whether `--seeds` is a `line:`/`grid:` spec (else a file of points).
fn is_seed_spec(seeds: &str) -> bool {
    trace::seed_spec_count(seeds).is_some()
}

/// The seeds of `--seeds`: a spec's made, after `check` of their count where it parses (they
/// are made at once, and core's own check counts only their points); a file's read, refused
/// first if it is not a regular file (opening a FIFO blocks until a writer comes).
fn make_seeds(arg: &str, check: impl FnOnce(usize) -> Result<()>) -> Result<Vec<Vec3>> {
    // (A spec that does not parse, or of more than MAX_SEEDS: making them says why.)
    if let Some(Ok(n)) = trace::seed_spec_count(arg) {
        if n <= trace::MAX_SEEDS {
            check(n)?;
        }
    }
    match trace::seeds_from_spec(arg) {
        Some(made) => made.context("--seeds"),
        None => {
            let path = Path::new(arg);
            tetloc_io::check_regular_input(path).and_then(|()| points::read_points(path)).context("--seeds")
        }
    }
}

/// A batch's tracer: `(seeds, options, progress)` to the batch's line arrays and the seconds
/// of it spent sampling the line fields apart from the tracing (0 where the tracer samples
/// them as it goes). `progress` takes the lines of the batch done so far.
type TraceOne<'a> = dyn FnMut(
        &[Vec3],
        &TraceOptions,
        &(dyn Fn(usize) -> tetloc_core::Result<()> + Sync),
    ) -> Result<(trace::LineArrays, f64)>
    + 'a;

/// Traces `seeds` in `batches`, each batch's lines handed to `spill` while the next is traced
/// ([`overlapped`]), under a bar of the `n_lines` lines on backend `name`. Returns the seconds
/// tracing and the seconds sampling the line fields apart.
fn trace_in_batches(
    seeds: &[Vec3],
    batches: Vec<(TraceOptions, std::ops::Range<usize>)>,
    n_lines: usize,
    name: &str,
    spill: impl FnMut((trace::LineArrays, usize)) -> Result<()> + Send,
    trace_one: &mut TraceOne<'_>,
) -> Result<(f64, f64)> {
    let pb = progress::bar(n_lines as u64, format!("tracing on {name}"));
    let (mut secs, mut sampling, mut base) = (0.0, 0.0, 0);
    let trace_batch = |(ob, seeds_in): (TraceOptions, std::ops::Range<usize>)| {
        let t = Instant::now();
        let done = base;
        let (arrays, sampled) = trace_one(&seeds[seeds_in.clone()], &ob, &|d| {
            pb.set_position((done + d) as u64);
            Ok(())
        })?;
        secs += t.elapsed().as_secs_f64() - sampled;
        sampling += sampled;
        base += seeds_in.len();
        Ok((arrays, seeds_in.start))
    };
    overlapped(batches, trace_batch, spill)?;
    pb.finish_and_clear();
    Ok((secs, sampling))
}

/// Makes each of `items` into a batch with `make` on this thread and hands it to `write` on
/// another, so that writing one batch overlaps making the next (at most two batches exist at
/// once: the one being written and the one being made). The first error of either stops
/// both and is returned.
fn overlapped<I, T: Send>(
    items: impl IntoIterator<Item = I>,
    mut make: impl FnMut(I) -> Result<T>,
    mut write: impl FnMut(T) -> Result<()> + Send,
) -> Result<()> {
    std::thread::scope(|s| {
        // No buffer: a batch is handed over only when the writer has finished the one before.
        let (tx, rx) = std::sync::mpsc::sync_channel::<T>(0);
        let writer = s.spawn(move || rx.into_iter().try_for_each(&mut write));
        let mut made = Ok(());
        for item in items {
            match make(item) {
                // A closed channel: the writer stopped on an error, which its join returns.
                Ok(batch) => {
                    if tx.send(batch).is_err() {
                        break;
                    }
                }
                Err(e) => {
                    made = Err(e);
                    break;
                }
            }
        }
        drop(tx);
        let written = writer.join().unwrap_or_else(|_| Err(anyhow::anyhow!("the thread writing the lines panicked")));
        made.and(written)
    })
}

#[cfg(test)]
mod tests {
    use super::overlapped;

    /// Every batch is written, in order; a failing batch stops the making and the writing
    /// after it, and its error is the one returned, whichever side it came from.
    #[test]
    fn overlapped_writes_every_batch_in_order_and_stops_at_the_first_error() {
        let mut written = Vec::new();
        overlapped(
            0..20,
            |i| Ok(i * i),
            |x| {
                written.push(x);
                Ok(())
            },
        )
        .unwrap();
        assert_eq!(written, (0..20).map(|i| i * i).collect::<Vec<_>>());

        let (mut made, mut written) = (0, Vec::new());
        let e = overlapped(
            0..20,
            |i| {
                made += 1;
                if i == 5 {
                    anyhow::bail!("batch {i} failed")
                }
                Ok(i)
            },
            |x| {
                written.push(x);
                Ok(())
            },
        )
        .unwrap_err();
        assert_eq!((e.to_string(), made), ("batch 5 failed".to_string(), 6));
        assert_eq!(written, vec![0, 1, 2, 3, 4]);

        let mut made = 0;
        let e = overlapped(
            0..20,
            |i| {
                made += 1;
                Ok(i)
            },
            |x| if x == 3 { anyhow::bail!("disk full at {x}") } else { Ok(()) },
        )
        .unwrap_err();
        assert_eq!(e.to_string(), "disk full at 3");
        // The maker stops at the first batch the writer no longer takes.
        assert!(made <= 5, "{made} batches made");
    }
}
