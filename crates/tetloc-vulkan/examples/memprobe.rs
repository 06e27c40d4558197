//! Random reads over growing spans of device memory (issue 12's collapse): one JSON line per
//! span and pattern. `cargo run --release --example memprobe -- [MAX_GIB] [DEVICE]`.

use tetloc_vulkan::memprobe::{random_reads, MemProbeOptions};
use tetloc_vulkan::Context;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let max_gib: f64 = args.next().map(|a| a.parse()).transpose()?.unwrap_or(48.0);
    let device: Option<usize> = args.next().map(|a| a.parse()).transpose()?;
    let ctx = Context::new(device)?;
    let mut opts = MemProbeOptions::default();
    opts.spans.retain(|&b| b as f64 <= max_gib * (1u64 << 30) as f64);
    eprintln!("{} ({}): spans up to {max_gib} GiB", ctx.info().name, ctx.info().driver);
    for r in random_reads(&ctx, &opts)? {
        println!(
            "{{\"device\":{:?},\"span_bytes\":{},\"pattern\":\"{}\",\"reads\":{},\"median_s\":{:.6e},\"reads_per_s\":{:.4e}}}",
            r.device, r.span_bytes, r.pattern, r.reads, r.median_s, r.reads_per_s
        );
    }
    Ok(())
}
