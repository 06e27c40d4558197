//! `tetloc render`: the volume ray marcher over any backend.

use crate::backend::BackendOptions;
use crate::{mesh_arg, time_steps};
use anyhow::{Context, Result};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use tetloc_core::Mesh;
use tetloc_io::output::{self, FileArg};
use tetloc_locator::{Backend, BareLocator};
use tetloc_render as tr;
use time_steps::{Series, TimeStep};

#[derive(clap::Args)]
pub struct RenderArgs {
    /// A mesh file, or SHAPE:N to generate one.
    mesh: OsString,
    /// The scalar field to render (with --state: instead of the state's; by default the
    /// state's, else the mesh's first, as `view` shows it).
    #[arg(long)]
    field: Option<String>,
    /// A view state (JSON) exported by `tetloc view`: camera, transfer function, step,
    /// background and surface, rendered as the viewer showed them.
    #[arg(long, conflicts_with_all = ["view", "zoom", "camera", "step", "tf", "range", "opacity", "surface", "no_skip", "background"])]
    state: Option<PathBuf>,
    /// Output: .png (numbered PNGs with --frames), or .gif for an animated orbit. With --fps,
    /// frame 0 of the first backend is written here when given.
    #[arg(short, long)]
    out: Option<PathBuf>,
    /// Backends, comma-separated (with --fps each is measured): cpu, soft-bvh, rt-bvh, rt-rep-faces, rt-shared-faces, auto.
    #[arg(long, default_value = "auto")]
    backend: String,
    /// Vulkan device index (see `tetloc devices`).
    #[arg(long)]
    device: Option<usize>,
    /// Image size WIDTHxHEIGHT in pixels [default: 1024x1024, or the state's].
    #[arg(long)]
    size: Option<String>,
    /// Azimuth,elevation in degrees around the bounds centre.
    #[arg(long)]
    view: Option<String>,
    /// Magnification: 2 shows half as much of the mesh.
    #[arg(long)]
    zoom: Option<String>,
    /// eye,target,up as 9 comma-separated numbers.
    #[arg(long)]
    camera: Option<String>,
    /// Sampling step in mesh units (default: the mean tet size).
    #[arg(long)]
    step: Option<String>,
    /// viridis (the default), plasma, coolwarm, grayscale, or a ParaView preset FILE.json[#NAME].
    #[arg(long)]
    tf: Option<String>,
    /// Value range LO,HI of the transfer function (default: the field's range).
    #[arg(long)]
    range: Option<String>,
    /// Optical depth across the bounds' diagonal of a fully opaque value.
    #[arg(long)]
    opacity: Option<String>,
    /// `boundary` (the mesh's boundary faces), `terrain` (a generated shape's ground, e.g.
    /// agulhas: sea floor and continents), or an OBJ, STL or VTK polydata file.
    #[arg(long)]
    surface: Option<String>,
    /// Render an orbit of N frames.
    #[arg(long, default_value = "1")]
    frames: String,
    /// Fixed stepping everywhere (the paper's), no empty-space skipping.
    #[arg(long)]
    no_skip: bool,
    /// GPU backends: march on the host and hand each round's samples to the kernel, instead
    /// of marching whole frames on the GPU.
    #[arg(long)]
    host_march: bool,
    /// Background colour behind the volume: R,G,B in 0..1, or #RRGGBB.
    #[arg(long)]
    background: Option<String>,
    /// Measure frames per second over an orbit of this many frames instead of writing images.
    #[arg(long, num_args = 0..=1, default_missing_value = "16")]
    fps: Option<u32>,
    /// A time series (an Exodus file with steps, a .pvd, a Gmsh file of several steps): render
    /// the fields of time step K (0-based; with --state: instead of the state's; by default
    /// the state's, else the first), or `all` of them with one camera and one range (the
    /// first step's unless --range or the state sets one): OUT_K.png a step, or one GIF
    /// through time when --out ends in .gif.
    #[arg(long, value_name = "K|all")]
    time_step: Option<TimeStep>,
    #[command(flatten)]
    source: mesh_arg::MeshOptions,
    /// Print only errors and warnings on stderr (not the backend `auto` chose, nor the files written).
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(a: RenderArgs) -> Result<()> {
    let state = a.state.as_deref().map(load_state).transpose()?;
    let mut o = match &state {
        Some(s) => s.render_options()?,
        None => tr::RenderOptions::default(),
    };
    let field = a.field.clone().or_else(|| state.as_ref().map(|s| s.field.clone()));
    if let Some(size) = &a.size {
        (o.width, o.height) = tr::parse_size(size)?;
    }
    if let Some(v) = &a.view {
        (o.azimuth, o.elevation) = tr::parse_view(v)?;
    }
    if let Some(z) = &a.zoom {
        o.zoom = tr::parse_positive("--zoom", z)?;
    }
    if let Some(c) = &a.camera {
        o.camera = Some(tr::parse_camera(c)?);
    }
    if let Some(s) = &a.step {
        o.step = Some(tr::parse_positive("--step", s)?);
    }
    if let Some(tf) = &a.tf {
        o.tf = tr::TfSpec::parse(tf)?;
    }
    if let Some(r) = &a.range {
        o.range = Some(tr::parse_range(r)?);
    }
    if let Some(k) = &a.opacity {
        o.opacity = tr::parse_opacity(k)?;
    }
    o.surface = match a.surface.as_deref() {
        Some("terrain") => {
            let Some((spec, n)) = mesh_arg::parse_generated(&a.mesh) else {
                anyhow::bail!(
                    "--surface terrain: {} is not a generated shape (SHAPE:N)",
                    std::path::Path::new(&a.mesh).display()
                );
            };
            let ground = mesh_arg::terrain(spec.shape, n, a.source.seed)?;
            Some(tr::SurfaceSpec::Mesh(std::sync::Arc::new(ground.into())))
        }
        s => s.map(tr::SurfaceSpec::parse),
    };
    o.frames = tr::parse_frames(&a.frames)?;
    for (option, frames) in [("--frames", Some(o.frames)), ("--fps", a.fps)] {
        if let Some(n) = frames.filter(|&n| n > MAX_FRAMES) {
            anyhow::bail!(
                "{option} {n}: at most {MAX_FRAMES} frames (an orbit of {MAX_FRAMES} is 5.5 minutes at 30 fps)"
            );
        }
    }
    o.skip &= !a.no_skip;
    if let Some(b) = &a.background {
        o.background = tr::parse_color("--background", b)?;
    }
    check_input_files(&o)?;
    if a.time_step == Some(TimeStep::All) {
        return render_steps(&a, o, field.as_deref());
    }
    // The image files are checked, and kept apart from every input, before any work.
    let out = a.out.clone().unwrap_or_else(|| "render.png".into());
    let files = match a.fps {
        Some(_) => a.out.iter().map(|o| tr::check_outputs(o, 1)).collect::<tr::Result<Vec<_>>>()?.concat(),
        None => tr::check_outputs(&out, o.frames)?,
    };
    check_inputs(&a, &o, &files)?;
    let step = match a.time_step {
        Some(TimeStep::One(k)) => Some(k),
        _ => state.as_ref().and_then(|s| s.time_step),
    };
    let mesh = time_steps::load(&a.mesh, a.source.format.as_deref(), a.source.seed, step)?;
    let field = field_or_first(field.as_deref(), &mesh)?;
    let mesh = with_magnitudes(mesh, &field)?;
    let renderer = tr::Renderer::new(mesh.clone(), &field, &o)?;
    check_samples_per_ray(&mesh, renderer.step())?;
    let opts = BackendOptions { device: a.device, quiet: a.quiet, ..Default::default() };
    for (i, name) in a.backend.split(',').enumerate() {
        let first = i == 0;
        let mut marcher = build_marcher(&opts, &mesh, name, &renderer, a.host_march)?;
        if let (Some(_), AnyMarcher::Gpu(m)) = (a.fps, &mut marcher) {
            // Keep the GPU busy between frames (image downloads), so its clocks stay up.
            m.set_busy_dispatches(FPS_BUSY_DISPATCHES);
        }
        let marcher: &mut dyn tr::Marcher = &mut marcher;
        match a.fps {
            Some(frames) => {
                println!("{}", tr::measure_fps(&renderer, marcher, frames.max(1))?);
                // With an explicit --out, the first backend's frame 0 too: what was measured.
                if let (Some(out), true) = (&a.out, first) {
                    renderer.render(marcher, &renderer.camera(0))?.0.write_png(out)?;
                    if !a.quiet {
                        eprintln!("wrote {}", out.display());
                    }
                }
            }
            None => {
                // An orbit's numbered PNGs reach their names together, after the last frame:
                // an interrupted run over an older orbit leaves the old set, not a mix.
                let set = output::OutputSet::begin();
                let report = tr::render_to_file(&renderer, marcher, &out)?;
                set.commit()?;
                if !a.quiet {
                    for f in &report.frames {
                        eprintln!("{f}");
                    }
                    for f in &report.files {
                        eprintln!("wrote {}", f.display());
                    }
                }
            }
        }
    }
    Ok(())
}

/// `--time-step all`: the series read once, one image a step with one camera and one range
/// (the first step's unless one is set, so that colours mean the same values throughout):
/// `OUT_K.png` a step, or one animated GIF through time. Step K's image is `--time-step K`'s
/// with that range.
fn render_steps(a: &RenderArgs, mut o: tr::RenderOptions, field: Option<&str>) -> Result<()> {
    if a.fps.is_some() || o.frames > 1 || a.backend.contains(',') {
        anyhow::bail!(
            "--time-step all renders one image a step with one backend: not with --fps, --frames or several backends"
        );
    }
    crate::progress::set_quiet(a.quiet);
    let out = a.out.clone().unwrap_or_else(|| "render.png".into());
    // The output's kind and folder before the series is read; each step's name once it is.
    tetloc_io::output::check_output(&out, &["png", "gif"])?;
    let (mesh, series) = time_steps::load_series(&a.mesh, a.source.format.as_deref(), a.source.seed, Some(0))
        .context("--time-step all")?;
    let series = series.context("--time-step all: the mesh has no time steps")?;
    let n = series.times().len();
    let gif = tetloc_io::output::extension(&out) == "gif";
    let files: Vec<PathBuf> =
        if gif { vec![out.clone()] } else { (0..n).map(|k| time_steps::step_path(&out, k, n)).collect() };
    for f in &files {
        tetloc_io::output::check_output(f, &["png", "gif"])?;
    }
    check_inputs(a, &o, &files)?;
    let field = &field_or_first(field, &mesh)?;
    let mut mesh = with_magnitudes(mesh, field)?;
    let mut renderer = tr::Renderer::new(mesh.clone(), field, &o)?;
    check_samples_per_ray(&mesh, renderer.step())?;
    if o.range.is_none() {
        o.range = Some(renderer.range());
        renderer = renderer.with_options(field, &o)?;
    }
    let opts = BackendOptions { device: a.device, quiet: a.quiet, ..Default::default() };
    let mut writer = match gif {
        true => Some(tr::GifWriter::create(&out, o.width, o.height, (400 / n as u32).clamp(2, 100) as u16)?),
        false => None,
    };
    let bar = crate::progress::bar(n as u64, "rendering the steps");
    // The steps' images appear together once the last is written.
    let set = tetloc_io::output::OutputSet::begin();
    let mut marcher = None;
    for k in 0..n {
        let mut step = || -> Result<()> {
            if k > 0 {
                (mesh, renderer) = step_renderer(&series, k, &renderer, field, &o)?;
            }
            let marcher = kept_or_built(&mut marcher, &renderer, || {
                build_marcher(&opts, &mesh, &a.backend, &renderer, a.host_march)
            })?;
            let (image, _) = renderer.render(marcher, &renderer.camera(0))?;
            match &mut writer {
                Some(w) => Ok(w.add(&image)?),
                None => Ok(image.write_png(&time_steps::step_path(&out, k, n))?),
            }
        };
        step().with_context(|| {
            format!("{}: time step {k}; {}", Path::new(&a.mesh).display(), time_steps::NOTHING_WRITTEN)
        })?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    if let Some(w) = writer {
        w.finish()?;
    }
    time_steps::commit_steps(set, &out)?;
    if !a.quiet {
        let (lo, hi) = renderer.range();
        eprintln!("rendered {n} time steps over the range {lo},{hi}");
        for f in &files {
            eprintln!("wrote {}", f.display());
        }
    }
    Ok(())
}

/// Time step `k` of `series` to render as `renderer` does, its grid and surface kept: the mesh
/// with that step's fields and `|NAME|` magnitudes (as the viewer colours vectors), and its
/// renderer (`render --time-step all`, and `view`'s time slider).
pub fn step_renderer(
    series: &Series,
    k: usize,
    renderer: &tr::Renderer,
    field: &str,
    o: &tr::RenderOptions,
) -> Result<(Arc<Mesh>, tr::Renderer)> {
    let mut mesh = series.mesh_like(k, renderer.mesh())?;
    tr::state::add_magnitudes(&mut mesh);
    let mesh = Arc::new(mesh);
    let renderer = renderer.for_step(mesh.clone(), field, o)?;
    Ok((mesh, renderer))
}

/// A view state file (`render --state`, `view --state`), refused before it is opened if it
/// is not a regular file (a FIFO would block).
pub fn load_state(path: &Path) -> Result<tr::ViewState> {
    tetloc_io::check_regular_input(path).context("--state")?;
    tr::ViewState::load(path).context("--state")
}

/// Refuses a `--tf` preset or `--surface` file that is not a regular file (a FIFO, a
/// device) before it is read: opening a FIFO blocks until a writer comes.
pub fn check_input_files(o: &tr::RenderOptions) -> Result<()> {
    if let tr::TfSpec::File { path, .. } = &o.tf {
        tetloc_io::check_regular_input(path).context("--tf")?;
    }
    if let Some(tr::SurfaceSpec::File(path)) = &o.surface {
        tetloc_io::check_regular_input(path).context("--surface")?;
    }
    Ok(())
}

/// Refuses outputs that are inputs: the mesh's files, the state, a preset, a surface.
fn check_inputs(a: &RenderArgs, o: &tr::RenderOptions, files: &[PathBuf]) -> Result<()> {
    let outputs: Vec<FileArg> = files.iter().map(|f| FileArg::new("--out", f)).collect();
    let mesh_files = mesh_arg::input_files(&a.mesh, a.source.format.as_deref());
    let mut inputs: Vec<FileArg> = mesh_files.iter().map(|p| FileArg::new("MESH", p)).collect();
    if let Some(path) = &a.state {
        inputs.push(FileArg::new("--state", path));
    }
    if let tr::TfSpec::File { path, .. } = &o.tf {
        inputs.push(FileArg::new("--tf", path));
    }
    if let Some(tr::SurfaceSpec::File(path)) = &o.surface {
        inputs.push(FileArg::new("--surface", path));
    }
    crate::outputs::check_distinct(&inputs, &outputs)
}

/// The field named, else the mesh's first (what `view` and `render` show by default).
pub fn field_or_first(named: Option<&str>, mesh: &Mesh) -> Result<String> {
    match named {
        Some(f) => Ok(f.to_string()),
        None => {
            let first = mesh.fields.first().map(|f| f.name.clone());
            first.with_context(|| format!("{}: the mesh has no fields to show", mesh.info.source))
        }
    }
}

/// The mesh with `|NAME|` magnitudes when `field` is one (as the viewer colours a vector),
/// `field` checked to be a scalar of it.
fn with_magnitudes(mut mesh: Arc<Mesh>, field: &str) -> Result<Arc<Mesh>> {
    if let (true, Some(m)) = (field.starts_with('|'), Arc::get_mut(&mut mesh)) {
        tr::state::add_magnitudes(m);
    }
    tetloc_core::ops::fields::resolve_scalar(&mesh.fields, field).context("--field")?;
    Ok(mesh)
}

/// Most frames of an orbit (GIF frames, numbered PNGs, or frames measured by `--fps`).
const MAX_FRAMES: u32 = 10_000;

/// Most samples a ray takes across the mesh's bounds: a 1024² image then takes at most
/// 7e10 samples a frame (about a minute on a large GPU).
const MAX_SAMPLES_PER_RAY: f64 = 65_536.0;

/// Refuses a step so small that a ray across the mesh takes more than
/// [`MAX_SAMPLES_PER_RAY`] samples, naming the smallest step allowed.
pub fn check_samples_per_ray(mesh: &tetloc_core::Mesh, step: f32) -> Result<()> {
    let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
    let diagonal = (0..3).map(|k| (hi[k] as f64 - lo[k] as f64).powi(2)).sum::<f64>().sqrt();
    let samples = diagonal / step as f64;
    if samples > MAX_SAMPLES_PER_RAY {
        anyhow::bail!(
            "--step {step}: a ray across the mesh (diagonal {diagonal:.4e}) would take {samples:.2e} samples, more than {MAX_SAMPLES_PER_RAY}; use --step {:.3e} or more",
            diagonal / MAX_SAMPLES_PER_RAY
        );
    }
    Ok(())
}

/// `--fps` with the GPU marcher: untimed marches of each frame before the timed one.
const FPS_BUSY_DISPATCHES: u32 = 3;

/// The marcher of one backend: whole frames on the GPU, or the host marcher over a locator.
pub enum AnyMarcher {
    Gpu(Box<tr::GpuMarcher>),
    Host(Box<dyn tetloc_core::BatchLocator>),
}

impl tr::Marcher for AnyMarcher {
    fn name(&self) -> &str {
        match self {
            AnyMarcher::Gpu(m) => m.name(),
            AnyMarcher::Host(l) => l.name(),
        }
    }
    fn march_frame(&mut self, r: &tr::Renderer, cam: &tr::Camera) -> tr::Result<(Vec<[f32; 4]>, tr::FrameStats)> {
        match self {
            AnyMarcher::Gpu(m) => m.march_frame(r, cam),
            AnyMarcher::Host(l) => tr::HostMarcher(l.as_mut()).march_frame(r, cam),
        }
    }
}

impl AnyMarcher {
    /// Takes the fields of `renderer`'s time step, a mesh made from this marcher's by
    /// `Mesh::with_fields` ([`step_renderer`]), keeping its search structures (and the
    /// GPU's copy of the mesh); false where it cannot: build a new marcher.
    pub fn take_step(&mut self, renderer: &tr::Renderer) -> Result<bool> {
        match self {
            AnyMarcher::Gpu(m) => Ok(m.take_step(renderer)?),
            AnyMarcher::Host(l) => Ok(l.take_fields(renderer.mesh())),
        }
    }
}

/// `marcher` made ready for `renderer`'s time step: the one there takes the step's fields
/// ([`AnyMarcher::take_step`]), else it is dropped (its memory freed first) and `build`
/// makes a new one. A failed step leaves no marcher.
pub fn kept_or_built<'a>(
    marcher: &'a mut Option<AnyMarcher>,
    renderer: &tr::Renderer,
    build: impl FnOnce() -> Result<AnyMarcher>,
) -> Result<&'a mut AnyMarcher> {
    let ready = crate::time_steps::taken_or_built(marcher.take(), |m| m.take_step(renderer), build)?;
    Ok(marcher.insert(ready))
}

/// The marcher of backend `name` for `renderer`'s frames (`render` and `view`). GPU
/// backends march whole frames on the GPU, for tet meshes only (the GPU marcher samples
/// tets, not the cells of a mixed mesh); `host_march` hands each round's samples to the
/// kernel instead.
pub fn build_marcher(
    opts: &BackendOptions,
    mesh: &std::sync::Arc<tetloc_core::Mesh>,
    name: &str,
    renderer: &tr::Renderer,
    host_march: bool,
) -> Result<AnyMarcher> {
    let (backend, builder) = opts.builder(mesh, name)?;
    let gpu = matches!(backend, Backend::Kernel(_));
    if gpu && !host_march && mesh.cells.is_none() {
        let BareLocator::Vulkan(loc) = builder.build_bare()?.locator else {
            anyhow::bail!("{backend}: not a Vulkan kernel")
        };
        return Ok(AnyMarcher::Gpu(Box::new(tr::GpuMarcher::new(*loc, renderer)?)));
    }
    if gpu && mesh.cells.is_some() && !host_march && !opts.quiet {
        eprintln!("note: a mixed mesh is marched on the host through {backend} (the GPU marcher samples tets only)");
    }
    Ok(AnyMarcher::Host(builder.build()?.locator))
}
