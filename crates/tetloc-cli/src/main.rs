//! `tetloc`: which tetrahedron of this mesh contains this point, and what is the field value there?

mod backend;
mod bench;
mod demo;
mod mesh_arg;
mod progress;
mod render;

use anyhow::{bail, Context, Result};
use backend::BackendOptions;
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::time::Instant;
use tetloc_core::io::points;
use tetloc_core::io::vtk::write as vtu_write;

#[derive(Parser)]
#[command(name = "tetloc", version, about = "Locate points in tetrahedral meshes and sample fields, on GPUs and CPUs")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print what a mesh holds: counts, bounds, fields, reoriented and degenerate tets, faces.
    Info {
        mesh: String,
        #[arg(long)]
        json: bool,
        /// File format, overriding the extension (vtu, vtk, msh, node).
        #[arg(long)]
        format: Option<String>,
    },
    /// Generate a synthetic mesh shaped like the paper's data sets and write it as .vtu.
    Gen {
        /// jets, fusion, agulhas or japan.
        shape: String,
        /// Approximate number of tets (e.g. 1M, 12M).
        #[arg(long)]
        tets: String,
        #[arg(short, long)]
        out: PathBuf,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// zlib-compress the appended data.
        #[arg(long)]
        zlib: bool,
        /// Also write the shape's terrain (agulhas: sea floor and land) as a Wavefront OBJ
        /// surface, for `tetloc render --surface FILE`.
        #[arg(long)]
        terrain: Option<PathBuf>,
    },
    /// Locate points (and sample a field) and write the tet ids (and values).
    Locate {
        /// A mesh file, or SHAPE:N to generate one.
        mesh: String,
        /// Query points: .npy (f32/f64, (N,3)), .csv (x,y,z) or .bin/.f32 (raw little-endian f32 triplets).
        #[arg(long)]
        points: PathBuf,
        /// Tet ids (-1 outside): .npy (int32), .csv, .bin (raw i32), or .vtu for a ParaView point set.
        #[arg(long)]
        out: PathBuf,
        /// A field to sample at the points (NaN outside).
        #[arg(long)]
        field: Option<String>,
        /// Where the sampled values go: .npy/.bin (f32) or .csv. Not needed with --out *.vtu.
        #[arg(long)]
        values: Option<PathBuf>,
        #[command(flatten)]
        common: Common,
    },
    /// Measure samples/s per backend and query set.
    Bench {
        /// A mesh file, or SHAPE:N to generate one (e.g. fusion:1.4M).
        mesh: String,
        /// Query sets: centers (the paper's uniform), random, bbox (generated in the GPU kernel), host (uploaded).
        #[arg(long, value_delimiter = ',', default_value = "centers,random,bbox")]
        queries: Vec<tetloc_core::queries::QueryKind>,
        /// Number of queries per run (default: one per tet).
        #[arg(long)]
        n: Option<String>,
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// Sample this field (the scalar variant) instead of locating ids.
        #[arg(long)]
        field: Option<String>,
        /// One JSON object per line instead of a table.
        #[arg(long)]
        json: bool,
        /// Read board power through NVML while GPU kernels run (where NVML is present).
        #[arg(long)]
        power: bool,
        #[command(flatten)]
        common: Common,
    },
    /// List the Vulkan devices: name, driver, ray-tracing support, memory.
    Devices,
    /// Render a field with the sample-based volume ray marcher (PNG, PNG series or GIF).
    Render(render::RenderArgs),
    /// Generate a fusion-like mesh of about 1M tets, locate and sample a million points on
    /// every available backend, check that they agree and print samples/s.
    Demo {
        #[arg(long, default_value = "1M")]
        tets: String,
        #[arg(long, default_value = "1M")]
        points: String,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[arg(long)]
        device: Option<usize>,
    },
}

#[derive(clap::Args)]
struct Common {
    /// Backends, comma-separated: cpu, soft-bvh, rt-bvh, rt-rep-faces, rt-shared-faces, auto (the fastest here, measured once per device), all.
    #[arg(long, default_value = "auto")]
    backend: String,
    /// rt kernels: primitives per bottom-level acceleration structure (e.g. 1M), or `off` for one structure.
    #[arg(long, default_value = "1M")]
    split: String,
    /// rt kernels: do not compact the acceleration structures.
    #[arg(long)]
    no_compact: bool,
    /// Vulkan device index (see `tetloc devices`).
    #[arg(long)]
    device: Option<usize>,
    /// Mesh file format, overriding the extension.
    #[arg(long)]
    format: Option<String>,
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

impl Common {
    fn opts(&self) -> Result<BackendOptions> {
        let split = if self.split == "off" { None } else { Some(mesh_arg::parse_count(&self.split)?) };
        Ok(BackendOptions { device: self.device, split, compact: !self.no_compact })
    }
}

fn main() {
    if let Err(e) = run(Cli::parse()) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Info { mesh, json, format } => info(&mesh, json, format.as_deref()),
        Command::Gen { shape, tets, out, seed, zlib, terrain } => {
            let shape: tetloc_core::gen::Shape = shape.parse().map_err(|e| anyhow::anyhow!("{e}"))?;
            let n = mesh_arg::parse_count(&tets)?;
            if let Some(path) = &terrain {
                let ground = mesh_arg::terrain(shape, n, seed)?;
                let file = std::fs::File::create(path).with_context(|| format!("{}: cannot create", path.display()))?;
                ground
                    .write_obj(std::io::BufWriter::new(file))
                    .with_context(|| format!("{}: cannot write", path.display()))?;
                eprintln!("{}: terrain with {} triangles", path.display(), ground.triangles.len());
            }
            let t0 = Instant::now();
            let mesh = mesh_arg::generate(shape, n, seed)?;
            let gen_s = t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            progress::with_spinner(format!("writing {}", out.display()), || {
                vtu_write::write_mesh_vtu(&out, &mesh, zlib)
            })?;
            eprintln!(
                "{}: {shape} with {} tets, {} vertices (generated in {gen_s:.2} s, written in {:.2} s)",
                out.display(),
                mesh.n_tets(),
                mesh.points.len(),
                t1.elapsed().as_secs_f64()
            );
            Ok(())
        }
        Command::Locate { mesh, points: pts, out, field, values, common } => {
            locate(&mesh, &pts, &out, field.as_deref(), values.as_deref(), &common)
        }
        Command::Devices => devices(),
        Command::Bench { mesh, queries, n, repeats, field, json, power, common } => {
            let m = mesh_arg::load(&mesh, common.format.as_deref(), common.seed)?;
            if let Some(f) = &field {
                m.field(f)?;
            }
            let opts = common.opts()?;
            let backends = if common.backend == "all" {
                backend::available(&opts).into_iter().map(String::from).collect()
            } else {
                common.backend.split(',').map(String::from).collect()
            };
            let args = bench::BenchArgs {
                backends,
                queries,
                n: n.map(|s| mesh_arg::parse_count(&s)).transpose()?,
                repeats: repeats.max(1),
                field,
                seed: common.seed,
                json,
                power,
                opts,
            };
            bench::run(&m, &args)?;
            Ok(())
        }
        Command::Render(args) => render::run(args),
        Command::Demo { tets, points, seed, device } => demo::run(
            mesh_arg::parse_count(&tets)?,
            mesh_arg::parse_count(&points)?,
            seed,
            &BackendOptions { device, ..Default::default() },
        ),
    }
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

fn info(mesh: &str, json: bool, format: Option<&str>) -> Result<()> {
    let m = mesh_arg::load(mesh, format, 1)?;
    let faces = progress::with_spinner("computing shared faces", || m.faces().stats);
    if json {
        let fields: Vec<_> =
            m.fields.iter().map(|f| serde_json::json!({"name": f.name, "location": f.location})).collect();
        let out = serde_json::json!({"mesh": m.info, "faces": faces, "fields": fields});
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    let i = &m.info;
    println!("{}", i.source);
    println!("  tets        {}", i.n_tets);
    println!("  vertices    {}", i.n_points);
    println!("  bounds      {:?} .. {:?}", i.bounds_min, i.bounds_max);
    println!("  volume      {:.6e}", i.total_volume);
    println!("  edges       max {:.4e}, mean {:.4e}", i.max_edge_length, i.mean_edge_length);
    println!(
        "  faces       {} unique, {} on the boundary, {} non-manifold",
        faces.n_faces, faces.n_boundary, faces.n_non_manifold
    );
    println!("  reoriented  {} inverted tets (kept, reoriented)", i.n_reoriented);
    println!("  degenerate  {} zero-volume tets (they contain no point)", i.n_degenerate);
    if let Some(k) = i.higher_order {
        println!("  order       {k}: higher-order tets, located by their 4 corner vertices");
    }
    if m.fields.is_empty() {
        println!("  fields      none");
    }
    for f in &m.fields {
        let (lo, hi) = f
            .values
            .iter()
            .filter(|v| v.is_finite())
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
        println!("  field       '{}' per {:?}, range {lo} .. {hi}", f.name, f.location);
    }
    Ok(())
}

fn locate(
    mesh: &str,
    pts: &Path,
    out: &Path,
    field: Option<&str>,
    values_out: Option<&Path>,
    common: &Common,
) -> Result<()> {
    let m = mesh_arg::load(mesh, common.format.as_deref(), common.seed)?;
    if let Some(f) = field {
        m.field(f)?;
    }
    let to_vtu = out.extension().is_some_and(|e| e == "vtu");
    if field.is_some() && values_out.is_none() && !to_vtu {
        bail!("--field needs --values FILE (or --out FILE.vtu, which carries ids and values)");
    }
    if field.is_none() && values_out.is_some() {
        bail!("--values needs --field NAME");
    }
    let points = points::read_points(pts)?;
    let opts = common.opts()?;
    let mut loc = progress::with_spinner("building the locator", || backend::make(&common.backend, &m, &opts))?;
    // Chunks keep the progress bar moving and bound GPU batch memory.
    const CHUNK: usize = 1 << 22;
    let mut ids = vec![0i32; points.len()];
    let mut values = vec![0f32; if field.is_some() { points.len() } else { 0 }];
    let pb = progress::bar(points.len() as u64, format!("locating on {}", loc.name()));
    let t0 = Instant::now();
    for (c, p) in points.chunks(CHUNK).enumerate() {
        let r = c * CHUNK..c * CHUNK + p.len();
        match field {
            Some(f) => loc.locate_and_sample(p, f, &mut ids[r.clone()], &mut values[r])?,
            None => loc.locate(p, &mut ids[r])?,
        }
        pb.inc(p.len() as u64);
    }
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let outside = ids.iter().filter(|&&i| i < 0).count();
    if to_vtu {
        vtu_write::write_points_vtu(out, &points, &ids, field.map(|f| (f, values.as_slice())))?;
    } else {
        points::write_ids(out, &ids)?;
    }
    if let (Some(_), Some(vp)) = (field, values_out) {
        points::write_values(vp, &values)?;
    }
    eprintln!(
        "{} points located on {} in {secs:.3} s ({}); {outside} outside the mesh",
        points.len(),
        loc.name(),
        bench::fmt_rate(points.len() as f64 / secs)
    );
    Ok(())
}
