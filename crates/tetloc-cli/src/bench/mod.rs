//! `tetloc bench`: samples/s per backend and query set (the paper's Table 1), build time and
//! memory (its Table 2). GPU kernels are timed with GPU timestamps and, for `centers`,
//! `random` and `bbox`, generate their sample points inside the kernel as the paper does;
//! `host` uploads points from a host array and includes the transfers. The CPU backend is
//! timed with the host clock. Warm-up, then the median of the repeats. `--trace` adds
//! particle tracing ([`trace`]).

pub mod trace;

use crate::backend::BackendOptions;
use anyhow::Result;
use serde::Serialize;
use std::sync::Arc;
use std::time::Instant;
use tetloc_core::queries::{self, QueryKind};
use tetloc_core::{BatchLocator, Mesh};
use tetloc_locator::BareLocator;
use tetloc_vulkan::BenchOptions;

#[derive(Debug, Serialize)]
pub struct BenchRow {
    pub backend: String,
    pub device: String,
    pub driver: String,
    pub mesh: String,
    pub n_tets: usize,
    pub queries: String,
    pub variant: String,
    pub n: usize,
    pub samples_per_s: f64,
    pub median_s: f64,
    pub outside: usize,
    pub build_s: f64,
    pub final_bytes: Option<u64>,
    pub peak_bytes: Option<u64>,
    pub timing: String,
    /// GPU kernels: the batch was sorted along the Morton curve on the GPU first (inside the timing).
    pub ordered: bool,
    pub repeats: usize,
    pub power_watts: Option<f64>,
    /// `--trace` rows on the GPU: how the lookups went.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trace: Option<trace::TraceStats>,
}

pub struct BenchArgs {
    pub backends: Vec<String>,
    pub queries: Vec<QueryKind>,
    pub n: Option<usize>,
    pub repeats: usize,
    pub field: Option<String>,
    pub seed: u64,
    pub json: bool,
    pub power: bool,
    /// GPU kernels: time every query set with and without query ordering.
    pub compare_order: bool,
    /// `--compare-refine` on a mesh stored in f64: the mesh rounded to f32, whose GPU kernels
    /// are timed too (rows "KERNEL unrefined").
    pub rounded: Option<Arc<Mesh>>,
    /// Also time particle tracing.
    pub trace: Option<trace::TraceBench>,
    pub opts: BackendOptions,
}

pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Host bytes a query takes (`--n`): its coordinates, id and value.
pub const BYTES_PER_QUERY: u128 = 12 + 4 + 4;

pub fn run(mesh: &Arc<Mesh>, args: &BenchArgs) -> Result<Vec<BenchRow>> {
    let mut rows = Vec::new();
    let n = args.n.unwrap_or(mesh.n_tets());
    let variant = args.field.as_ref().map_or("id".to_string(), |f| format!("value:{f}"));
    let emit = |row: BenchRow, rows: &mut Vec<BenchRow>| -> Result<()> {
        if args.json {
            println!("{}", serde_json::to_string(&row)?);
        } else {
            eprintln!("  {:<16} {:<8} {:>12}", row.backend, row.queries, fmt_rate(row.samples_per_s));
        }
        rows.push(row);
        Ok(())
    };
    let runs = args
        .backends
        .iter()
        .map(|b| (b, mesh, ""))
        .chain(args.rounded.iter().flat_map(|r| args.backends.iter().map(move |b| (b, r, " unrefined"))));
    for (name, mesh, suffix) in runs {
        let (backend, builder) = args.opts.builder(mesh, name)?;
        let name = format!("{}{suffix}", backend.name());
        let bare = builder.build_bare()?;
        let mut loc = match bare.locator {
            BareLocator::Vulkan(loc) => *loc,
            BareLocator::Cpu(_) if !suffix.is_empty() => continue,
            BareLocator::Cpu(mut loc) => {
                let build_s = bare.build_seconds;
                eprintln!("{}", loc.bvh().stats.report());
                for &q in &args.queries {
                    let points = queries::generate(mesh, q, n, args.seed);
                    let mut ids = vec![0i32; n];
                    let mut values = vec![0f32; n];
                    let mut run_once = |loc: &mut tetloc_core::CpuLocator| -> Result<f64> {
                        let t = Instant::now();
                        match &args.field {
                            Some(f) => loc.sample(&points, f, &mut values)?,
                            None => loc.locate(&points, &mut ids)?,
                        }
                        Ok(t.elapsed().as_secs_f64())
                    };
                    run_once(&mut loc)?; // warm-up
                    let times: Vec<f64> = (0..args.repeats).map(|_| run_once(&mut loc)).collect::<Result<_>>()?;
                    let med = median(times);
                    let outside = match &args.field {
                        Some(_) => values.iter().filter(|v| v.is_nan()).count(),
                        None => ids.iter().filter(|&&i| i < 0).count(),
                    };
                    let row = BenchRow {
                        backend: name.clone(),
                        device: format!("{} CPU threads", rayon::current_num_threads()),
                        driver: "rayon".into(),
                        mesh: mesh.info.source.clone(),
                        n_tets: mesh.n_tets(),
                        queries: q.name().to_string(),
                        variant: variant.clone(),
                        n,
                        samples_per_s: n as f64 / med,
                        median_s: med,
                        outside,
                        build_s,
                        final_bytes: None,
                        peak_bytes: None,
                        timing: "host clock".into(),
                        ordered: false,
                        repeats: args.repeats,
                        power_watts: None,
                        trace: None,
                    };
                    emit(row, &mut rows)?;
                }
                if let Some(tb) = &args.trace {
                    emit(trace::cpu(mesh, &loc, args, tb)?, &mut rows)?;
                }
                continue;
            }
        };
        if !args.opts.quiet {
            for (stage, s) in loc.build_stages() {
                eprintln!("{name} build: {s:>8.3} s  {stage}");
            }
        }
        let orders = if args.compare_order { vec![true, false] } else { vec![args.opts.order_queries] };
        for (&q, &ordered) in args.queries.iter().flat_map(|q| orders.iter().map(move |o| (q, o))) {
            loc.set_order_queries(ordered);
            let host = (q == QueryKind::Host).then(|| queries::generate(mesh, q, n, args.seed));
            let opts = BenchOptions {
                mode: q,
                field: args.field.clone(),
                samples: Some(n),
                seed: args.seed as u32,
                repeats: args.repeats,
                power: args.power,
                ..BenchOptions::default()
            };
            let r = loc.bench(&opts, host.as_deref())?;
            let row = BenchRow {
                // Compared: the unordered runs get rows of their own in the tables.
                backend: if args.compare_order && !ordered { format!("{name} unordered") } else { name.clone() },
                device: r.device.clone(),
                driver: r.driver.clone(),
                mesh: mesh.info.source.clone(),
                n_tets: mesh.n_tets(),
                queries: q.name().to_string(),
                variant: variant.clone(),
                n: r.samples,
                samples_per_s: r.samples_per_second,
                median_s: r.seconds,
                outside: r.outside,
                build_s: r.build_seconds,
                final_bytes: Some(r.final_bytes),
                peak_bytes: Some(r.peak_bytes),
                timing: r.timing.to_string(),
                ordered: r.ordered,
                repeats: opts.repeats,
                power_watts: r.power_watts,
                trace: None,
            };
            emit(row, &mut rows)?;
        }
        if let Some(tb) = &args.trace {
            for row in trace::gpu(mesh, &mut loc, args, tb)? {
                emit(row, &mut rows)?;
            }
        }
    }
    if !args.json {
        let mut shown = args.queries.iter().map(|q| q.name()).collect::<Vec<_>>();
        if args.trace.is_some() {
            shown.push("trace");
        }
        print_tables(&rows, &shown);
    }
    Ok(rows)
}

pub use tetloc_locator::fmt_rate;

/// The paper's Table 1 (samples/s, a column per query set) and Table 2 (build, memory).
pub fn print_tables(rows: &[BenchRow], queries: &[&str]) {
    let Some(first) = rows.first() else { return };
    println!(
        "\nmesh {} ({} tets), variant {}, median of {} runs",
        first.mesh, first.n_tets, first.variant, first.repeats
    );
    let mut backends: Vec<&str> = Vec::new();
    for r in rows {
        if !backends.contains(&r.backend.as_str()) {
            backends.push(&r.backend);
        }
    }
    let w = backends.iter().map(|b| b.len()).max().unwrap_or(0).max(16);
    print!("{:<w$}", "samples/s");
    for q in queries {
        print!(" {q:>12}");
    }
    println!("  device");
    for b in &backends {
        print!("{b:<w$}");
        let mut device = String::new();
        for q in queries {
            match rows.iter().find(|r| r.backend == *b && r.queries == *q) {
                Some(r) => {
                    print!(" {:>12}", fmt_rate(r.samples_per_s));
                    device = format!("{} ({})", r.device, r.driver);
                }
                None => print!(" {:>12}", "-"),
            }
        }
        println!("  {device}");
    }
    println!("\n{:<w$} {:>9} {:>11} {:>11} {:>10}", "build/memory", "build s", "final MiB", "peak MiB", "outside");
    for b in &backends {
        if let Some(r) = rows.iter().find(|r| r.backend == *b) {
            let mib = |x: Option<u64>| x.map_or("-".to_string(), |v| format!("{:.1}", v as f64 / (1 << 20) as f64));
            let outside: Vec<String> =
                rows.iter().filter(|x| x.backend == *b).map(|x| format!("{}:{}", x.queries, x.outside)).collect();
            println!(
                "{b:<w$} {:>9.3} {:>11} {:>11} {:>10}",
                r.build_s,
                mib(r.final_bytes),
                mib(r.peak_bytes),
                outside.join(" ")
            );
        }
    }
}
