//! A mesh argument: a file, or a generated shape written `SHAPE:N` (e.g. `fusion:1.4M`).

use crate::progress;
use anyhow::{bail, Context, Result};
use std::path::Path;
use std::sync::Arc;
use tetloc_core::gen::{self, Shape};
use tetloc_core::io::{self, MeshFormat};
use tetloc_core::Mesh;

/// Parses counts like `1000`, `1.4M`, `250k`, `2G`.
pub fn parse_count(s: &str) -> Result<usize> {
    let s = s.trim();
    let (num, mult) = match s.chars().last() {
        Some('k' | 'K') => (&s[..s.len() - 1], 1e3),
        Some('m' | 'M') => (&s[..s.len() - 1], 1e6),
        Some('g' | 'G') => (&s[..s.len() - 1], 1e9),
        _ => (s, 1.0),
    };
    let v: f64 =
        num.replace('_', "").parse().with_context(|| format!("'{s}' is not a count (e.g. 1000, 1.4M, 250k)"))?;
    if v.is_nan() || v <= 0.0 {
        bail!("'{s}': the count must be positive");
    }
    Ok((v * mult).round() as usize)
}

/// `SHAPE:N` when `arg` is not an existing file and parses that way.
pub fn parse_generated(arg: &str) -> Option<(Shape, usize)> {
    if Path::new(arg).exists() {
        return None;
    }
    let (shape, n) = arg.split_once(':')?;
    Some((shape.parse().ok()?, parse_count(n).ok()?))
}

/// Bytes a generated mesh of `n` tets takes while it is built and validated (tets, vertices,
/// fields and temporaries, measured: 1.42 GB at 62M tets), with headroom.
const GEN_BYTES_PER_TET: u64 = 40;

pub fn generate(shape: Shape, n: usize, seed: u64) -> Result<Mesh> {
    if let Some(avail) = tetloc_core::io::available_memory_bytes() {
        let need = n as u64 * GEN_BYTES_PER_TET;
        if need > avail {
            bail!(
                "{shape}:{n}: generating {n} tets needs about {:.1} GB of memory, {:.1} GB are available",
                need as f64 / 1e9,
                avail as f64 / 1e9
            );
        }
    }
    let pb = progress::bar(1000, format!("generating {shape} with ~{n} tets"));
    let raw = gen::generate_with_progress(shape, n, seed, &|f| pb.set_position((f * 1000.0) as u64));
    pb.finish_and_clear();
    let mesh = progress::with_spinner("validating mesh", || Mesh::new(raw, format!("{shape}:{n}")))?;
    Ok(mesh)
}

/// The terrain that goes with a generated shape, or an error naming the shapes that have one.
pub fn terrain(shape: Shape, n: usize, seed: u64) -> Result<gen::Terrain> {
    gen::terrain(shape, n, seed).with_context(|| {
        let with: Vec<_> = Shape::ALL.into_iter().filter(|s| s.has_terrain()).map(|s| s.name()).collect();
        format!("{shape} has no terrain (shapes with one: {})", with.join(", "))
    })
}

/// Loads a mesh file (format from the extension unless given) or generates `SHAPE:N`.
pub fn load(arg: &str, format: Option<&str>, seed: u64) -> Result<Arc<Mesh>> {
    if let Some((shape, n)) = parse_generated(arg) {
        return Ok(Arc::new(generate(shape, n, seed)?));
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
            "{arg}: no such file (and not a generated mesh like fusion:1M; shapes: {})",
            Shape::ALL.map(|s| s.to_string()).join(", ")
        );
    }
    let mesh = progress::with_spinner(format!("reading {arg}"), || io::read_mesh(path, format))?;
    Ok(Arc::new(mesh))
}
