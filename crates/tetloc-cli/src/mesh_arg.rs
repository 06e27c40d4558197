//! A mesh argument: a file, or a generated shape written `SHAPE:N` (e.g. `fusion:1.4M`), or
//! `SHAPE-KIND:N` for N cells of another kind (`jets-hex:12M`, `jets-hybrid:12M`).

use crate::{limits, progress};
use anyhow::{bail, Context, Result};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use tetloc_core::gen::{self, CellKind, Shape, Spec};
use tetloc_core::Mesh;
use tetloc_io::{self as io, MeshFormat};

/// Parses counts like `1000`, `1.4M`, `250k`, `2G`.
pub fn parse_count(s: &str) -> Result<usize> {
    let s = s.trim();
    let (num, mult) = match s.chars().last() {
        Some('k' | 'K') => (&s[..s.len() - 1], 1e3),
        Some('m' | 'M') => (&s[..s.len() - 1], 1e6),
        // G or B: a billion (jets:1B).
        Some('g' | 'G' | 'b' | 'B') => (&s[..s.len() - 1], 1e9),
        _ => (s, 1.0),
    };
    let v: f64 =
        num.replace('_', "").parse().with_context(|| format!("'{s}' is not a count (e.g. 1000, 1.4M, 250k, 1B)"))?;
    if v.is_nan() || v <= 0.0 {
        bail!("'{s}': the count must be positive");
    }
    let n = (v * mult).round();
    // Said as written: an f64 would print 2^64 as 18446744073709552000.
    if n >= usize::MAX as f64 {
        bail!("'{s}': the count is more than {}", usize::MAX);
    }
    Ok(n as usize)
}

/// `SHAPE:N` when `arg` is not an existing file and parses that way.
pub fn parse_generated(arg: &OsStr) -> Option<(Spec, usize)> {
    if Path::new(arg).exists() {
        return None;
    }
    let (shape, n) = arg.to_str()?.split_once(':')?;
    Some((shape.parse().ok()?, parse_count(n).ok()?))
}

/// The files a mesh argument reads (an output must be none of them): none for `SHAPE:N`;
/// both `.node` and `.ele` for TetGen; a partitioned mesh's listings and all its pieces;
/// else the file itself.
pub fn input_files(arg: &OsStr, format: Option<&str>) -> Vec<PathBuf> {
    if parse_generated(arg).is_some() {
        return Vec::new();
    }
    io::input_files(Path::new(arg), format.and_then(MeshFormat::from_name))
}

/// [`load`], with the closed-form vector field `v` of `gen --vector` added to a generated mesh
/// (`bench --trace`, `trace`).
pub fn load_with_flow(arg: &OsStr, format: Option<&str>, seed: u64) -> Result<Arc<Mesh>> {
    let Some((spec, n)) = parse_generated(arg) else { return load(arg, format, seed) };
    let mut m = generate(spec, n, seed)?;
    let v = tetloc_core::gen::flow::vector_fields(spec.shape, &m.points);
    m.fields.extend(v);
    Ok(Arc::new(m))
}

/// Bytes a generated mesh of `n` tets takes while it is built and validated (tets, vertices,
/// fields and temporaries, measured: 1.42 GB at 62M tets), with headroom.
const GEN_BYTES_PER_TET: u64 = 40;

pub fn generate(spec: impl Into<Spec>, n: usize, seed: u64) -> Result<Mesh> {
    let spec = spec.into();
    // Mixed cells: their decomposition tets (6 per hex, 3 per wedge) and the cells.
    let tets_per_cell = match spec.cells {
        CellKind::Tets => 1,
        CellKind::Hexes => 7,
        CellKind::Wedges => 4,
        CellKind::Hybrid => 5,
        // Hexes (7) and polyhedra (about 30 tets each, and their centroids).
        CellKind::Octree => 10,
    };
    limits::check_memory(
        &format!("{spec}:{n}: {n} generated cells"),
        n as u128,
        (tets_per_cell * GEN_BYTES_PER_TET).into(),
    )?;
    let what = if spec.cells == CellKind::Tets { "tets" } else { "cells" };
    let pb = progress::bar(1000, format!("generating {spec} with ~{n} {what}"));
    let raw = gen::generate_spec(spec, n, seed, &|f| pb.set_position((f * 1000.0) as u64));
    pb.finish_and_clear();
    let mesh = progress::with_spinner("validating mesh", || Mesh::new(raw, format!("{spec}:{n}")))?;
    Ok(mesh)
}

/// The terrain that goes with a generated shape, or an error naming the shapes that have one.
pub fn terrain(shape: Shape, n: usize, seed: u64) -> Result<gen::Terrain> {
    terrain_shape_check(shape)?;
    gen::terrain(shape, n, seed).with_context(|| format!("{shape}: no terrain was generated"))
}

/// Whether `shape` has a terrain, as an error naming the shapes that have one.
pub fn terrain_shape_check(shape: Shape) -> Result<()> {
    if !shape.has_terrain() {
        let with: Vec<_> = Shape::ALL.into_iter().filter(|s| s.has_terrain()).map(|s| s.name()).collect();
        bail!("{shape} has no terrain (shapes with one: {})", with.join(", "));
    }
    Ok(())
}

/// Loads a mesh file (format from the extension unless given) or generates `SHAPE:N`.
/// File names need not be UTF-8.
pub fn load(arg: &OsStr, format: Option<&str>, seed: u64) -> Result<Arc<Mesh>> {
    if let Some((spec, n)) = parse_generated(arg) {
        return Ok(Arc::new(generate(spec, n, seed)?));
    }
    let format = match format {
        Some(f) => Some(
            MeshFormat::from_name(f)
                .with_context(|| format!("unknown --format '{f}' (known: {})", io::KNOWN_MESH_FORMATS))?,
        ),
        None => None,
    };
    let path = Path::new(arg);
    if !path.exists() {
        bail!(
            "{}: no such file (and not a generated mesh like fusion:1M; shapes: {})",
            path.display(),
            Spec::all_names().join(", ")
        );
    }
    // Refused before it is opened: a FIFO would block for ever.
    io::check_regular_input(path)?;
    let mesh = progress::with_spinner(format!("reading {}", path.display()), || io::read_mesh(path, format))?;
    Ok(Arc::new(mesh))
}

/// The options of a mesh argument: the seed of a generated one, the format of a file.
#[derive(clap::Args)]
pub struct MeshOptions {
    /// Seed of a generated mesh (SHAPE:N).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Mesh file format, overriding the extension (vtu, pvtu, vtm, vtk, msh, node).
    #[arg(long)]
    pub format: Option<String>,
}
