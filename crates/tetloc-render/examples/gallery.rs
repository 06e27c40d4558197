//! Renders the four generated shapes (jets, fusion, agulhas, japan) with the CPU backend,
//! with and without empty-space skipping, and writes `DIR/<shape>.png`. `agulhas` is drawn
//! over its terrain (sea floor and continents), with a denser transfer function since the
//! ocean layer is thin.
//!
//!     cargo run --release -p tetloc-render --example gallery -- DIR [TETS] [SIZE]
//!
//! TETS defaults to 200000 and SIZE to 256 (pixels a side).

use std::sync::Arc;
use tetloc_core::gen::{generate, terrain, Shape};
use tetloc_core::{CpuLocator, Mesh};
use tetloc_render::surface::TriMesh;
use tetloc_render::{RenderOptions, Renderer, SurfaceSpec};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = std::path::PathBuf::from(args.first().ok_or("usage: gallery DIR [TETS] [SIZE]")?);
    let tets: usize = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(200_000);
    let size: u32 = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(256);
    std::fs::create_dir_all(&dir)?;
    for shape in Shape::ALL {
        let mesh = Arc::new(Mesh::new(generate(shape, tets, 1), shape.name())?);
        let mut cpu = CpuLocator::new(mesh.clone());
        let mut opts = RenderOptions { width: size, height: size, ..Default::default() };
        if let Some(ground) = terrain(shape, tets, 1) {
            opts.surface = Some(SurfaceSpec::Mesh(Arc::new(TriMesh::from(ground))));
            opts.opacity = 60.0;
        }
        let mut line = format!("{:8} {:>9} tets", shape.name(), mesh.n_tets());
        for skip in [false, true] {
            let r = Renderer::new(mesh.clone(), "f", &RenderOptions { skip, ..opts.clone() })?;
            let (img, st) = r.render(&mut cpu, &r.camera(0))?;
            line += &format!(
                " | {}: {:>9} samples ({:>5.1}% in mesh) {:.2} s ({:.0}% sampling)",
                if skip { "skip" } else { "fixed" },
                st.samples,
                100.0 * st.in_mesh_samples as f64 / st.samples as f64,
                st.seconds,
                100.0 * st.sample_seconds / st.seconds
            );
            if skip {
                img.write_png(&dir.join(format!("{}.png", shape.name())))?;
            }
        }
        println!("{line}");
    }
    Ok(())
}
