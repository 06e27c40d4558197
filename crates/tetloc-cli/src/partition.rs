//! `tetloc partition`: a mesh cut into pieces by recursive coordinate bisection of its cell
//! centroids, written as a `.pvtu` and its folder of VTU pieces (each with `GlobalCellIds`),
//! for `mpirun -n N tetloc locate OUT.pvtu ...` and for ParaView.

use crate::{mesh_arg, progress};
use anyhow::{Context, Result};
use std::ffi::OsString;
use std::path::PathBuf;
use std::time::Instant;
use tetloc_io::output::{self, FileArg};
use tetloc_io::vtk::write_pieces;

#[derive(clap::Args)]
pub struct PartitionArgs {
    /// A mesh file (.vtu, .pvtu, .vtm, .vtk, .msh, .node/.ele), or SHAPE:N to generate one (e.g. jets:12M).
    mesh: OsString,
    /// Number of pieces (any number up to the number of cells).
    #[arg(long)]
    parts: usize,
    /// The listing to write, OUT.pvtu; the pieces go into the folder OUT beside it
    /// (OUT/OUT_0.vtu, ...), or OUT.1 when an older OUT.pvtu uses OUT: the old listing and
    /// its pieces stay whole until the new ones are complete, then are replaced (a pieces
    /// folder holding other files is refused).
    #[arg(short, long)]
    out: PathBuf,
    /// zlib-compress the pieces' appended data.
    #[arg(long)]
    zlib: bool,
    #[command(flatten)]
    source: mesh_arg::MeshOptions,
    /// Print only errors and warnings on stderr (no progress bar, no summary).
    #[arg(short, long)]
    quiet: bool,
}

pub fn run(a: &PartitionArgs) -> Result<()> {
    output::check_output(&a.out, &["pvtu"]).context("-o/--out: partition writes a .pvtu and its pieces")?;
    write_pieces::check_pvtu_output(&a.out)?;
    progress::set_quiet(a.quiet);
    let mesh_files = mesh_arg::input_files(&a.mesh, a.source.format.as_deref());
    let inputs: Vec<FileArg> = mesh_files.iter().map(|p| FileArg::new("MESH", p)).collect();
    crate::outputs::check_distinct(&inputs, &[FileArg::new("--out", &a.out)])?;
    // The pieces folders are replaced: an input inside one would be lost.
    for dir in write_pieces::replaced_folders(&a.out)? {
        let Ok(dir_c) = dir.canonicalize() else { continue };
        if let Some(f) = mesh_files.iter().find(|f| f.canonicalize().is_ok_and(|f| f.starts_with(&dir_c))) {
            anyhow::bail!(
                "MESH {} lies in {}, the pieces folder that writing --out {} replaces; tetloc never writes over an input (write another OUT.pvtu)",
                f.display(),
                dir.display(),
                a.out.display()
            );
        }
    }
    if a.parts == 0 {
        anyhow::bail!("--parts must be at least 1");
    }
    let mesh = mesh_arg::load(&a.mesh, a.source.format.as_deref(), a.source.seed)?;
    let t0 = Instant::now();
    let pb = progress::bar(a.parts as u64, format!("writing {} pieces", a.parts));
    tetloc_io::partition::write_pvtu(&mesh, a.parts, &a.out, a.zlib, |_| pb.inc(1))?;
    pb.finish_and_clear();
    if a.quiet {
        return Ok(());
    }
    eprintln!(
        "{}: {} cells in {} pieces (recursive coordinate bisection), written in {:.2} s",
        a.out.display(),
        mesh.n_cells(),
        a.parts,
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
