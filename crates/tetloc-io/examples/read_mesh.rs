//! Times reading a mesh file, twice (the second from the page cache): the format's reader
//! (`read_raw`) and the mesh's checks and set-up (`Mesh::new`, the same for every format).
//! `cargo run --release -p tetloc-io --example read_mesh -- FILE`

use std::path::Path;
use std::time::Instant;

fn main() -> tetloc_core::Result<()> {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: read_mesh FILE");
        std::process::exit(2);
    };
    let mb = std::fs::metadata(&path).map(|m| m.len() as f64 / 1e6).unwrap_or(0.0);
    for _ in 0..2 {
        let t = Instant::now();
        let raw = tetloc_io::read_raw(Path::new(&path), None)?;
        let read = t.elapsed().as_secs_f64();
        let mesh = tetloc_core::Mesh::new(raw, path.clone())?;
        let all = t.elapsed().as_secs_f64();
        println!(
            "{path}: {} cells, {mb:.0} MB; read_raw {read:.3} s ({:.0} MB/s), Mesh::new {:.3} s, both {all:.3} s ({:.0} MB/s)",
            mesh.n_cells(),
            mb / read,
            all - read,
            mb / all
        );
    }
    Ok(())
}
