//! `tetloc bench --trace N`: particles per second, the issue's "1M particles × 1,000 RK4
//! steps". N lines from random points inside the mesh, RK4 with the trace command's default
//! step (a tenth of the mean edge), through the vector field `--vector`. The CPU traces with
//! `ops::trace::trace` (each particle walking from its last tet; host clock); soft-bvh with
//! its stream kernel, timed by GPU timestamps with the line points written but not read back,
//! once walking from each particle's last tet (the hint) and once with a fresh search (entry
//! grid, walk, BVH) for every lookup, to show what the hint saves. Rates are RK4 samples
//! (four lookups a step) per second.

use super::{median, BenchArgs, BenchRow};
use anyhow::{Context, Result};
use std::sync::Arc;
use std::time::Instant;
use tetloc_core::ops::trace::{self, TraceOptions};
use tetloc_core::queries::{self, QueryKind};
use tetloc_core::Mesh;
use tetloc_vulkan::VulkanLocator;

/// What `--trace` asks for.
pub struct TraceBench {
    pub lines: usize,
    pub max_steps: usize,
    pub vector: String,
}

/// The seeds, options and vector components of the benchmark.
fn setup(mesh: &Mesh, tb: &TraceBench, seed: u64) -> Result<(Vec<tetloc_core::geom::Vec3>, TraceOptions, Vec<String>)> {
    let vector = trace::vector_field(mesh, &tb.vector).context("--vector")?;
    let seeds = queries::generate(mesh, QueryKind::Random, tb.lines, seed);
    let o =
        TraceOptions { step: 0.1 * mesh.info.mean_edge_length as f64, max_steps: tb.max_steps, ..Default::default() };
    Ok((seeds, o, vector.component_refs().iter().map(|s| s.to_string()).collect()))
}

fn row(args: &BenchArgs, mesh: &Mesh, backend: String, steps: u64, seconds: f64) -> BenchRow {
    BenchRow {
        backend,
        device: String::new(),
        driver: String::new(),
        mesh: mesh.info.source.clone(),
        n_tets: mesh.n_tets(),
        queries: "trace".into(),
        variant: "rk4".into(),
        n: 4 * steps as usize,
        samples_per_s: 4.0 * steps as f64 / seconds,
        median_s: seconds,
        outside: 0,
        build_s: 0.0,
        final_bytes: None,
        peak_bytes: None,
        timing: String::new(),
        ordered: false,
        repeats: args.repeats,
        power_watts: None,
        trace: None,
    }
}

/// The CPU row.
pub fn cpu(mesh: &Arc<Mesh>, loc: &tetloc_core::CpuLocator, args: &BenchArgs, tb: &TraceBench) -> Result<BenchRow> {
    let (seeds, o, c) = setup(mesh, tb, args.seed)?;
    let field = loc.vector_field([&c[0], &c[1], &c[2]])?;
    let mut steps = 0;
    let times: Vec<f64> = (0..args.repeats)
        .map(|_| {
            let t = Instant::now();
            let lines = trace::trace(&seeds, &o, &field, &|_| Ok(()))?;
            steps = lines.iter().map(|l| l.points.len() as u64 - 1).sum();
            Ok(t.elapsed().as_secs_f64())
        })
        .collect::<Result<_>>()?;
    let mut r = row(args, mesh, "cpu".into(), steps, median(times));
    r.device = format!("{} CPU threads", rayon::current_num_threads());
    r.driver = "rayon".into();
    r.timing = "host clock".into();
    Ok(r)
}

/// soft-bvh's rows, with the hint and without; none where the kernel has no stream shader.
pub fn gpu(mesh: &Arc<Mesh>, loc: &mut VulkanLocator, args: &BenchArgs, tb: &TraceBench) -> Result<Vec<BenchRow>> {
    let (seeds, o, c) = setup(mesh, tb, args.seed)?;
    let mut rows = Vec::new();
    for hint in [true, false] {
        let Some(s) = loc.bench_trace(&seeds, &o, [&c[0], &c[1], &c[2]], hint, args.repeats)? else {
            eprintln!("  {}: no stream kernel (trace runs through batched lookups)", loc.kernel());
            return Ok(rows);
        };
        let name = if hint { loc.kernel().to_string() } else { format!("{} no hint", loc.kernel()) };
        let mut r = row(args, mesh, name, s.steps, s.seconds);
        r.device = loc.context().info().name.clone();
        r.driver = loc.context().info().driver.clone();
        r.timing = "GPU timestamps".into();
        r.trace = Some(TraceStats {
            lines: s.lines,
            lookups: s.lookups,
            fresh_per_lookup: s.fallbacks as f64 / s.lookups.max(1) as f64,
            walk_tets_per_lookup: s.walk_tets as f64 / s.lookups.max(1) as f64,
            launches: s.launches,
        });
        eprintln!(
            "  {:<16} trace {:>12}  {} lines, {} steps, {} lookups: {:.4} fresh searches and {:.2} walk tets a lookup",
            r.backend,
            super::fmt_rate(r.samples_per_s),
            s.lines,
            s.steps,
            s.lookups,
            s.fallbacks as f64 / s.lookups.max(1) as f64,
            s.walk_tets as f64 / s.lookups.max(1) as f64
        );
        rows.push(r);
    }
    Ok(rows)
}

/// How the GPU's lookups went (the JSON rows carry it).
#[derive(Debug, serde::Serialize)]
pub struct TraceStats {
    pub lines: usize,
    pub lookups: u64,
    /// Lookups that needed the fresh search (the hint's walk failed, or no hint).
    pub fresh_per_lookup: f64,
    /// Tets the walks visited per lookup.
    pub walk_tets_per_lookup: f64,
    pub launches: usize,
}
