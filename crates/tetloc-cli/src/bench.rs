//! `tetloc bench`: samples/s per backend and query set, warm-up, repeats, medians.

use crate::backend::{self, BackendOptions};
use anyhow::Result;
use serde::Serialize;
use std::sync::Arc;
use std::time::Instant;
use tetloc_core::queries::{self, QueryKind};
use tetloc_core::Mesh;

#[derive(Debug, Serialize)]
pub struct BenchRow {
    pub backend: String,
    pub device: String,
    pub mesh: String,
    pub n_tets: usize,
    pub queries: String,
    pub variant: String,
    pub n: usize,
    pub samples_per_s: f64,
    pub median_s: f64,
    pub build_s: f64,
    pub repeats: usize,
}

pub struct BenchArgs {
    pub backends: Vec<String>,
    pub queries: Vec<QueryKind>,
    pub n: Option<usize>,
    pub repeats: usize,
    pub field: Option<String>,
    pub seed: u64,
    pub json: bool,
    pub opts: BackendOptions,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

pub fn cpu_name() -> String {
    format!("{} CPU threads", rayon::current_num_threads())
}

pub fn run(mesh: &Arc<Mesh>, args: &BenchArgs) -> Result<Vec<BenchRow>> {
    let mut rows = Vec::new();
    let n = args.n.unwrap_or(mesh.n_tets());
    for name in &args.backends {
        let t0 = Instant::now();
        let mut loc = backend::make(name, mesh, &args.opts)?;
        let build_s = t0.elapsed().as_secs_f64();
        for &q in &args.queries {
            let points = queries::generate(mesh, q, n, args.seed);
            let mut ids = vec![0i32; n];
            let mut values = vec![0f32; n];
            let mut run_once = |loc: &mut dyn tetloc_core::BatchLocator| -> Result<f64> {
                let t = Instant::now();
                match &args.field {
                    Some(f) => loc.sample(&points, f, &mut values)?,
                    None => loc.locate(&points, &mut ids)?,
                }
                Ok(t.elapsed().as_secs_f64())
            };
            run_once(loc.as_mut())?; // warm-up
            let times: Vec<f64> = (0..args.repeats).map(|_| run_once(loc.as_mut())).collect::<Result<_>>()?;
            let med = median(times);
            let row = BenchRow {
                backend: loc.name().to_string(),
                device: cpu_name(),
                mesh: mesh.info.source.clone(),
                n_tets: mesh.n_tets(),
                queries: q.to_string(),
                variant: args.field.as_ref().map_or("id".to_string(), |f| format!("value:{f}")),
                n,
                samples_per_s: n as f64 / med,
                median_s: med,
                build_s,
                repeats: args.repeats,
            };
            if args.json {
                println!("{}", serde_json::to_string(&row)?);
            }
            rows.push(row);
        }
    }
    if !args.json {
        print_table(&rows);
    }
    Ok(rows)
}

pub fn fmt_rate(r: f64) -> String {
    if r >= 1e9 {
        format!("{:.2} G/s", r / 1e9)
    } else if r >= 1e6 {
        format!("{:.1} M/s", r / 1e6)
    } else {
        format!("{:.0} k/s", r / 1e3)
    }
}

pub fn print_table(rows: &[BenchRow]) {
    if let Some(r) = rows.first() {
        println!("mesh {} ({} tets), {} queries per run, median of {}", r.mesh, r.n_tets, r.n, r.repeats);
    }
    println!("{:<16} {:<10} {:<10} {:>14} {:>12} {:>10}  device", "backend", "queries", "variant", "samples/s", "median", "build");
    for r in rows {
        println!(
            "{:<16} {:<10} {:<10} {:>14} {:>10.2}ms {:>9.3}s  {}",
            r.backend,
            r.queries,
            r.variant,
            fmt_rate(r.samples_per_s),
            r.median_s * 1e3,
            r.build_s,
            r.device
        );
    }
}
