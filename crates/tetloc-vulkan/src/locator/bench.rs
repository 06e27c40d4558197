//! Benchmarks as in the paper's Table 1: samples generated inside the kernel (`centers`,
//! `random`, `bbox`) timed with GPU timestamps, or host points (`host`) timed on the host
//! clock with their transfers; warm-up runs, repeats, medians; optionally board power.

use super::{sample_mode, Output, Variant, VulkanLocator};
use crate::error::VkResult;
use crate::interface::{Params, OUT_CELL, OUT_VERTEX};
use crate::nvml::{Nvml, PowerSampler};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tetloc_core::geom::Vec3;
use tetloc_core::mesh::FieldLocation;
use tetloc_core::queries::QueryKind;
use tetloc_core::BatchLocator;

/// What to benchmark.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub mode: QueryKind,
    /// `None`: the id variant; `Some(name)`: the scalar variant sampling that field (its
    /// values only).
    pub field: Option<String>,
    /// Not empty: the ids and these fields' values, all in one launch (what
    /// `BatchLocator::query` runs), instead of `field`.
    pub fields: Vec<String>,
    /// With `fields` and host points: the k + 1 launches that one launch replaced
    /// ([`VulkanLocator::sample_per_field`]), to compare.
    pub per_field: bool,
    /// Samples per run for `random` and `bbox` (default: one per tet). `centers` always
    /// takes one sample per tet; `host` takes the given points.
    pub samples: Option<usize>,
    pub seed: u32,
    /// Untimed runs first (pipeline creation, caches).
    pub warmup: usize,
    /// Before those, keep the GPU busy with the kernel for this long: clocks ramp up under
    /// load (on the H100 the first benchmark of a process ran 5x slower without this).
    pub warmup_seconds: f64,
    /// Timed runs; the result is their median. At least 1.
    pub repeats: usize,
    /// Also read the board's power through NVML while the kernel runs for about a second.
    pub power: bool,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            mode: QueryKind::Centers,
            field: None,
            fields: vec![],
            per_field: false,
            samples: None,
            seed: 1,
            warmup: 2,
            warmup_seconds: 0.5,
            repeats: 7,
            power: false,
        }
    }
}

/// One benchmark's result.
#[derive(Clone, Debug)]
pub struct BenchResult {
    pub kernel: String,
    pub mode: QueryKind,
    /// "ids" or the sampled field's name.
    pub variant: String,
    pub samples: usize,
    /// Median, fastest and slowest of the timed runs, seconds.
    pub seconds: f64,
    pub seconds_min: f64,
    pub seconds_max: f64,
    pub samples_per_second: f64,
    /// Samples of the last run reported outside every tet.
    pub outside: usize,
    /// "gpu timestamps" or "host clock (transfers included)".
    pub timing: &'static str,
    /// The points were sorted along the Morton curve on the GPU before being located (query
    /// ordering, inside the timing).
    pub ordered: bool,
    pub build_seconds: f64,
    pub final_bytes: u64,
    pub peak_bytes: u64,
    pub device: String,
    pub driver: String,
    /// Mean board power while the kernel ran (NVML), when asked for and available.
    pub power_watts: Option<f64>,
}

fn median(mut v: Vec<f64>) -> (f64, f64, f64) {
    v.sort_by(f64::total_cmp);
    let m = if v.len() % 2 == 1 { v[v.len() / 2] } else { 0.5 * (v[v.len() / 2 - 1] + v[v.len() / 2]) };
    (m, v[0], v[v.len() - 1])
}

impl VulkanLocator {
    /// Runs one benchmark. `host_points` are the points of `QueryKind::Host` (ignored otherwise).
    pub fn bench(&mut self, opts: &BenchOptions, host_points: Option<&[Vec3]>) -> tetloc_core::Result<BenchResult> {
        if opts.repeats == 0 {
            return Err(tetloc_core::Error::Invalid("0 repeats: a benchmark takes at least one timed run".into()));
        }
        if opts.per_field && (opts.mode != QueryKind::Host || opts.fields.is_empty()) {
            return Err(tetloc_core::Error::Invalid("per_field compares host points with fields".into()));
        }
        let output = match &opts.field {
            _ if !opts.fields.is_empty() => {
                let mut cells = 0u32;
                // (More than MAX_FIELDS fields run only as host points, a pass each MAX_FIELDS.)
                for (j, f) in opts.fields.iter().enumerate().take(crate::interface::MAX_FIELDS as usize) {
                    cells |= u32::from(self.mesh.field(f)?.location == FieldLocation::Cell) << j;
                }
                Output::fields(opts.fields.len() as u32, cells)
            }
            None => Output::IDS,
            Some(name) => Output::single(self.mesh.field(name)?.location == FieldLocation::Cell),
        };
        let nvml = if opts.power { Nvml::open(&self.dev.ctx().uuid).map(Arc::new) } else { None };
        let (times, samples, outside, timing, power) = match opts.mode {
            QueryKind::Host => {
                let pts =
                    host_points.ok_or_else(|| tetloc_core::Error::Invalid("the host benchmark needs points".into()))?;
                let (times, outside, power) = self.bench_host(opts, pts, nvml)?;
                (times, pts.len(), outside, "host clock (transfers included)", power)
            }
            mode => {
                if opts.fields.len() > crate::interface::MAX_FIELDS as usize {
                    let e = format!(
                        "{} fields: one launch samples at most {}",
                        opts.fields.len(),
                        crate::interface::MAX_FIELDS
                    );
                    return Err(tetloc_core::Error::Invalid(e));
                }
                if !opts.fields.is_empty() {
                    let names: Vec<&str> = opts.fields.iter().map(String::as_str).collect();
                    self.ensure_fields(&names)?;
                } else if let Some(f) = &opts.field {
                    self.ensure_field(f)?;
                }
                let n = match mode {
                    QueryKind::Centers => self.mesh.n_tets(),
                    _ => opts.samples.unwrap_or(self.mesh.n_tets()),
                };
                super::check_generated_count(n)?;
                let (times, outside, power) = self.bench_gpu(opts, mode, output, n, nvml)?;
                (times, n, outside, "gpu timestamps", power)
            }
        };
        let (seconds, seconds_min, seconds_max) = median(times);
        let info = self.dev.ctx().info();
        Ok(BenchResult {
            kernel: self.kernel.name().into(),
            mode: opts.mode,
            variant: opts.variant(),
            samples,
            seconds,
            seconds_min,
            seconds_max,
            samples_per_second: samples as f64 / seconds,
            outside,
            timing,
            ordered: self.orders(sample_mode(opts.mode), samples),
            build_seconds: self.build_seconds(),
            final_bytes: self.memory_report().final_bytes,
            peak_bytes: self.memory_report().peak_bytes,
            device: info.name.clone(),
            driver: info.driver.clone(),
            power_watts: power,
        })
    }

    fn bench_host(
        &mut self,
        opts: &BenchOptions,
        pts: &[Vec3],
        nvml: Option<Arc<Nvml>>,
    ) -> tetloc_core::Result<(Vec<f64>, usize, Option<f64>)> {
        let mut ids = vec![0i32; pts.len()];
        let mut vals = vec![0f32; pts.len() * opts.fields.len().max(1)];
        let names: Vec<&str> = opts.fields.iter().map(String::as_str).collect();
        let mut run = |loc: &mut VulkanLocator| -> tetloc_core::Result<()> {
            match &opts.field {
                _ if opts.per_field => loc.sample_per_field(pts, &names, &mut ids, &mut vals),
                _ if !names.is_empty() => loc.sample_many(pts, &names, &mut ids, &mut vals),
                None => loc.locate(pts, &mut ids),
                Some(f) => loc.sample(pts, f, &mut vals),
            }
        };
        let t = Instant::now();
        for k in 0.. {
            if k >= opts.warmup && t.elapsed().as_secs_f64() >= opts.warmup_seconds {
                break;
            }
            run(self)?;
        }
        let mut times = vec![];
        for _ in 0..opts.repeats {
            let t = Instant::now();
            run(self)?;
            times.push(t.elapsed().as_secs_f64());
        }
        let power = match nvml {
            Some(n) => {
                let sampler = PowerSampler::start(n);
                let t = Instant::now();
                while t.elapsed() < Duration::from_secs(1) {
                    run(self)?;
                }
                sampler.finish()
            }
            None => None,
        };
        let outside = match &opts.field {
            Some(_) if names.is_empty() => vals.iter().filter(|v| v.is_nan()).count(),
            _ => ids.iter().filter(|&&t| t < 0).count(),
        };
        Ok((times, outside, power))
    }

    fn bench_gpu(
        &mut self,
        opts: &BenchOptions,
        mode: QueryKind,
        output: Output,
        n: usize,
        nvml: Option<Arc<Nvml>>,
    ) -> VkResult<(Vec<f64>, usize, Option<f64>)> {
        let sample = sample_mode(mode);
        let v = Variant { sample, output, record: false, ordered: self.orders(sample, n) };
        if mode == QueryKind::Grid {
            self.ensure_grid_axes(&tetloc_core::queries::grid(&self.mesh, n), false)?;
        }
        let chunk = self.launch_limit(v.ordered).min(n.max(1));
        self.ensure_io(chunk, output.words())?;
        self.pipeline(v)?;
        let launches: Vec<Params> = (0..n)
            .step_by(chunk)
            .map(|base| self.generated_params(mode, chunk.min(n - base), base, n, opts.seed))
            .collect();
        let io = self.io.as_ref().expect("ensure_io made it");
        let deferred = io.deferred.as_ref().map(|d| d.buffer);
        let launch = self.launcher.launch(v, deferred);
        // Ordered: each launch's points are generated and sorted first, inside the timing.
        let order = io.order.as_ref().filter(|_| v.ordered);
        let l = |r: &crate::device::Recording, p: &Params| {
            if let Some(o) = order {
                o.record(r, p, sample);
            }
            launch.record(r, p)
        };
        // Warm up by time, one run per submission, until the clocks have ramped up.
        let t = Instant::now();
        while t.elapsed().as_secs_f64() < opts.warmup_seconds {
            self.dev.run(|r| {
                for p in &launches {
                    l(r, p);
                }
            })?;
        }
        let runs = opts.warmup + opts.repeats;
        let times = self.dev.time_runs(runs, |r| {
            for p in &launches {
                l(r, p);
            }
        })?;
        let times = times[opts.warmup..].to_vec();

        // Power: keep the GPU busy for about a second, one run per submission.
        let power = match nvml {
            Some(nv) => {
                let sampler = PowerSampler::start(nv);
                let t = Instant::now();
                while t.elapsed() < Duration::from_secs(1) {
                    self.dev.run(|r| {
                        for p in &launches {
                            l(r, p);
                        }
                    })?;
                }
                sampler.finish()
            }
            None => None,
        };

        // The first words of the results: ids, or single values.
        let count_outside = |out: &[u32]| match output.mode {
            OUT_VERTEX | OUT_CELL => out.iter().filter(|&&b| f32::from_bits(b).is_nan()).count(),
            _ => out.iter().filter(|&&t| t as i32 == -1).count(),
        };
        let outside = if mode == QueryKind::Grid {
            // A grid's slabs are not alike (the last one may lie above the mesh): every
            // launch again, untimed, each one's answers counted.
            let mut outside = 0;
            for p in &launches {
                self.dev.run(|r| l(r, p))?;
                let io = self.io.as_ref().expect("ensure_io made it");
                let mut out = vec![0u32; p.counts[0] as usize];
                self.dev.download(&io.results, 0, bytemuck::cast_slice_mut(&mut out))?;
                outside += count_outside(&out);
            }
            outside
        } else {
            // The last chunk of the last run, scaled (the other sets' chunks are alike samples).
            let last = launches.last().map_or(0, |p| p.counts[0] as usize);
            let mut out = vec![0u32; last];
            let io = self.io.as_ref().expect("ensure_io made it");
            self.dev.download(&io.results, 0, bytemuck::cast_slice_mut(&mut out))?;
            (count_outside(&out) as f64 * n as f64 / last.max(1) as f64).round() as usize
        };
        Ok((times, outside, power))
    }
}

impl BenchOptions {
    /// The variant's name: `ids`, the field's, or `ids+F+G` (one launch; `per-field:F+G`:
    /// the k + 1 launches).
    pub fn variant(&self) -> String {
        match &self.field {
            _ if !self.fields.is_empty() => {
                format!("{}{}", if self.per_field { "per-field:" } else { "ids+" }, self.fields.join("+"))
            }
            None => "ids".into(),
            Some(f) => f.clone(),
        }
    }
}

impl BenchResult {
    /// Column names matching [`BenchResult::row`].
    pub fn header() -> String {
        format!(
            "{:<16} {:<8} {:<8} {:>11} {:>10} {:>12} {:>8} {:>9} {:>10} {:>10} {:>7}",
            "kernel",
            "mode",
            "variant",
            "samples",
            "median ms",
            "samples/s",
            "outside",
            "build s",
            "final MiB",
            "peak MiB",
            "watts"
        )
    }

    /// One table row.
    pub fn row(&self) -> String {
        let mib = |b: u64| b as f64 / (1 << 20) as f64;
        format!(
            "{:<16} {:<8} {:<8} {:>11} {:>10.3} {:>12} {:>8} {:>9.2} {:>10.1} {:>10.1} {:>7}",
            self.kernel,
            format!("{}{}", self.mode.name(), if self.ordered { "/o" } else { "" }),
            self.variant,
            self.samples,
            self.seconds * 1e3,
            si(self.samples_per_second),
            self.outside,
            self.build_seconds,
            mib(self.final_bytes),
            mib(self.peak_bytes),
            self.power_watts.map_or("-".into(), |w| format!("{w:.0}")),
        )
    }
}

/// 1.23G, 456M, 7.8k: the paper's notation for rates.
pub fn si(x: f64) -> String {
    match x {
        x if x >= 1e9 => format!("{:.2}G", x / 1e9),
        x if x >= 1e6 => format!("{:.1}M", x / 1e6),
        x if x >= 1e3 => format!("{:.1}k", x / 1e3),
        x => format!("{x:.0}"),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn median_and_si() {
        assert_eq!(super::median(vec![3.0, 1.0, 2.0]), (2.0, 1.0, 3.0));
        assert_eq!(super::median(vec![4.0, 1.0, 2.0, 3.0]).0, 2.5);
        assert_eq!(super::si(2.39e9), "2.39G");
        assert_eq!(super::si(407e6), "407.0M");
    }
}
