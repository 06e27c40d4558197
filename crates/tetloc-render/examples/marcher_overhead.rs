//! The marcher's own cost per sample, without any point location: a locator that answers
//! instantly stands in for the backend. This is the floor under every backend's frame time.
//!
//!     cargo run --release -p tetloc-render --example marcher_overhead -- [TETS] [SIZE]

use std::sync::Arc;
use tetloc_core::gen::{generate, Shape};
use tetloc_core::locate::{Points, Values};
use tetloc_core::{BatchLocator, Mesh};
use tetloc_render::{RenderOptions, Renderer};

/// Every point gets the value 0.3, as fast as memory allows.
struct Instant03;

impl BatchLocator for Instant03 {
    fn name(&self) -> &str {
        "constant"
    }
    fn query(&mut self, _: Points<'_>, _: &[&str], ids: &mut [i32], values: Values<'_>) -> tetloc_core::Result<()> {
        ids.fill(0);
        values.via_f32(|v| {
            v.fill(0.3);
            Ok(())
        })
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let tets: usize = args.first().map(|s| s.parse()).transpose()?.unwrap_or(200_000);
    let size: u32 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(512);
    let mesh = Arc::new(Mesh::new(generate(Shape::Jets, tets, 1), "jets")?);
    // Low opacity so rays run the whole box.
    let opts = RenderOptions { width: size, height: size, opacity: 0.5, range: Some((0.0, 1.0)), ..Default::default() };
    let r = Renderer::new(mesh, "f", &opts)?;
    for _ in 0..3 {
        let (_, st) = r.render(&mut Instant03, &r.camera(0))?;
        println!(
            "{} samples in {} rounds: {:.3} s, {:.1} ns per sample outside the locator ({} threads)",
            st.samples,
            st.rounds,
            st.seconds,
            (st.seconds - st.sample_seconds) / st.samples as f64 * 1e9,
            rayon::current_num_threads()
        );
    }
    Ok(())
}
