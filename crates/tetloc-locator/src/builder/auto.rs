//! `auto`: the backend for this machine, with one meaning for every front end. `cpu` when
//! there is no Vulkan device or when the device runs on the CPU itself (lavapipe, llvmpipe,
//! SwiftShader: Vulkan's CPU device type), where a GPU kernel only competes with the cpu
//! backend for the same cores; otherwise the fastest backend in a measurement of at most
//! [`AUTO_BUDGET_S`], cached per device and driver (in `$XDG_CACHE_HOME/tetloc` or
//! `~/.cache/tetloc`). Decided once per device in a process, and said once on stderr unless
//! quiet. A cache that cannot be written is said once, and the ranking kept in memory.

use crate::{contexts, fmt_rate, Backend, LocatorOptions, Result};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::fmt;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tetloc_core::queries::{self, QueryKind};
use tetloc_core::{BatchLocator, Mesh};

/// Longest time `auto` spends measuring, builds included.
pub const AUTO_BUDGET_S: f64 = 2.0;

/// What `auto` chose, and why.
#[derive(Clone, Debug)]
pub struct AutoChoice {
    /// Never [`Backend::Auto`].
    pub backend: Backend,
    pub reason: AutoReason,
}

/// Why `auto` chose its backend.
#[derive(Clone, Debug)]
pub enum AutoReason {
    /// No Vulkan on this machine (no loader, driver or device).
    NoVulkan(String),
    /// A Vulkan device is there but cannot be used (a bad device index, a failed call).
    Unusable(String),
    /// The Vulkan device runs on the CPU (its name).
    CpuDevice(String),
    /// The fastest in the ranking of `device` (name and driver), measured now, before in this
    /// process, or cached (`source`).
    Measured { source: &'static str, device: String, ranking: Ranking },
}

impl fmt::Display for AutoReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AutoReason::NoVulkan(e) => write!(f, "no Vulkan device: {e}"),
            AutoReason::Unusable(e) => write!(f, "the Vulkan device cannot be used: {e}"),
            AutoReason::CpuDevice(name) => write!(f, "the Vulkan device, {name}, runs on the CPU"),
            AutoReason::Measured { source, device, ranking } => {
                let rates: Vec<String> = ranking.iter().map(|(n, r)| format!("{n} {}", fmt_rate(*r))).collect();
                write!(f, "{source} on {device}: {}", rates.join(", "))
            }
        }
    }
}

/// `auto` on `device` (the GPU kernels measured with `options`): decided once per device in
/// this process and said on stderr the first time unless `quiet`.
pub fn choose(device: Option<usize>, options: &LocatorOptions, quiet: bool) -> Result<AutoChoice> {
    static CHOICES: Mutex<Option<HashMap<Option<usize>, AutoChoice>>> = Mutex::new(None);
    let mut choices = CHOICES.lock().unwrap_or_else(|e| e.into_inner());
    let choices = choices.get_or_insert_with(HashMap::new);
    if let Some(c) = choices.get(&device) {
        return Ok(c.clone());
    }
    let choice = decide(device, options)?;
    if !quiet {
        let _ = writeln!(std::io::stderr(), "auto: {} ({})", choice.backend, choice.reason);
    }
    choices.insert(device, choice.clone());
    Ok(choice)
}

fn decide(device: Option<usize>, options: &LocatorOptions) -> Result<AutoChoice> {
    let cpu = |reason| Ok(AutoChoice { backend: Backend::Cpu, reason });
    let ctx = match contexts::context(device) {
        Ok(c) => c,
        Err(e) if e.no_vulkan && device.is_none() => return cpu(AutoReason::NoVulkan(e.msg)),
        Err(e) => return cpu(AutoReason::Unusable(e.msg)),
    };
    let info = ctx.info();
    if info.device_type == "cpu" {
        return cpu(AutoReason::CpuDevice(info.name.clone()));
    }
    let key = format!("{} {}", info.name, info.driver);
    let avail = crate::available(device);
    let path = cache_path(&key);
    let (ranking, source) = ranking(path.as_deref(), &key, &mut || measure(&avail, device, options, AUTO_BUDGET_S))?;
    let best = pick(&ranking, &avail);
    Ok(AutoChoice { backend: best, reason: AutoReason::Measured { source, device: key, ranking } })
}

/// A ranking of backends by samples/s on one device, fastest first.
pub type Ranking = Vec<(String, f64)>;

/// Backends within this fraction of the fastest measured rate count as tied.
const TIE: f64 = 0.8;

/// The backend `auto` takes from a ranking: among those within [`TIE`] of the fastest, the first
/// in `avail`'s order (soft-bvh, then the rt kernels, then cpu). The measurement locates host
/// points end to end, so on a GPU it times mostly the transfers, which are the same for every
/// kernel: its small differences are noise (the H200, 2026-12-05: rt-shared-faces came first,
/// then ran a 12M-tet mesh at 0.07 G/s where soft-bvh's kernel runs 3 G/s). Ties go to the
/// order, whose first kernel is the fastest in every kernel-time measurement (BENCHMARKS.md).
fn pick(ranking: &Ranking, avail: &[Backend]) -> Backend {
    let rate = |b: &Backend| ranking.iter().find(|(n, _)| n.parse::<Backend>().ok() == Some(*b)).map(|r| r.1);
    let top = avail.iter().filter_map(rate).fold(0.0, f64::max);
    avail.iter().copied().find(|b| rate(b).is_some_and(|r| r >= TIE * top)).unwrap_or(Backend::Cpu)
}

/// The cached ranking of backends on one device and driver.
#[derive(Serialize, Deserialize)]
struct AutoCache {
    device: String,
    ranking: Ranking,
}

fn cache_path(key: &str) -> Option<PathBuf> {
    let name: String = key.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    Some(tetloc_core::cache::dir()?.join(format!("auto-{name}.json")))
}

/// The ranking for device `key`: from this process' memory, from the cache file, or measured
/// (and then cached; a cache that cannot be written is said once and the ranking kept in
/// memory). Also says where it came from.
fn ranking(
    path: Option<&Path>,
    key: &str,
    measure: &mut dyn FnMut() -> Result<Ranking>,
) -> Result<(Ranking, &'static str)> {
    static MEMORY: Mutex<Option<HashMap<String, Ranking>>> = Mutex::new(None);
    let mut memory = MEMORY.lock().unwrap_or_else(|e| e.into_inner());
    let memory = memory.get_or_insert_with(HashMap::new);
    if let Some(r) = memory.get(key) {
        return Ok((r.clone(), "measured before in this process"));
    }
    let cached = path.and_then(tetloc_core::cache::read).and_then(|b| serde_json::from_slice::<AutoCache>(&b).ok());
    if let Some(c) = cached.filter(|c| c.device == key && !c.ranking.is_empty()) {
        memory.insert(key.to_string(), c.ranking.clone());
        return Ok((c.ranking, "cached"));
    }
    let ranking = measure()?;
    memory.insert(key.to_string(), ranking.clone());
    match path {
        Some(p) => {
            let json = serde_json::to_vec(&AutoCache { device: key.to_string(), ranking: ranking.clone() })
                .map_err(|e| tetloc_core::Error::Invalid(e.to_string()))?;
            if let Err(e) = tetloc_core::cache::write_atomically(p, &json) {
                let _ = writeln!(
                    std::io::stderr(),
                    "warning: auto: cannot cache the measurement ({e}); it is kept for this run only"
                );
            }
        }
        None => {
            let _ = writeln!(std::io::stderr(), "warning: auto: no cache directory (neither XDG_CACHE_HOME nor HOME is set); the measurement is kept for this run only");
        }
    }
    Ok((ranking, "measured"))
}

/// Samples/s of each backend locating random points in a small probe mesh, within about
/// `budget_s` seconds in all (a build or a run already started is not interrupted): each
/// backend gets an equal share of what is left, in which batches grow from 4096 points while
/// they are short against the share; its rate is the best batch's. Backends not reached in
/// time are left out of the ranking.
fn measure(avail: &[Backend], device: Option<usize>, options: &LocatorOptions, budget_s: f64) -> Result<Ranking> {
    let start = Instant::now();
    let probe =
        Arc::new(Mesh::new(tetloc_core::gen::generate(tetloc_core::gen::Shape::Fusion, 50_000, 7), "auto probe")?);
    let points = queries::generate(&probe, QueryKind::Random, 1 << 20, 7);
    let mut ids = vec![0; points.len()];
    let mut ranking = Vec::new();
    for (k, &backend) in avail.iter().enumerate() {
        let left = budget_s - start.elapsed().as_secs_f64();
        if left <= 0.0 {
            break;
        }
        let share = left / (avail.len() - k) as f64;
        let t = Instant::now();
        let built = crate::Locator::builder(probe.clone())
            .backend(backend)
            .device(device)
            .vulkan_options(options.clone())
            .quiet(true)
            .build_unexplained();
        let mut loc = match built {
            Ok(b) => b.locator,
            Err(e) => {
                let _ = writeln!(std::io::stderr(), "warning: auto: {backend} left out: {e}");
                continue;
            }
        };
        let (mut n, mut rate) = (1 << 12, 0f64);
        loop {
            let run = Instant::now();
            loc.locate(&points[..n], &mut ids[..n])?;
            let secs = run.elapsed().as_secs_f64();
            rate = rate.max(n as f64 / secs.max(1e-9));
            if t.elapsed().as_secs_f64() >= share {
                break;
            }
            if secs < share / 16.0 && n < points.len() {
                n *= 2;
            }
        }
        ranking.push((backend.name().to_string(), rate));
    }
    ranking.sort_by(|a, b| b.1.total_cmp(&a.1));
    Ok(ranking)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rates within 20 % of the fastest are a tie, which goes to the first available backend;
    /// a backend that is not available (or not measured) is never taken.
    #[test]
    fn ties_go_to_the_first_available_backend() {
        let soft = Backend::Kernel(tetloc_vulkan::Kernel::SoftBvh);
        let shared = Backend::Kernel(tetloc_vulkan::Kernel::RtSharedFaces);
        let avail = [soft, shared, Backend::Cpu];
        let ranking = |r: &[(&str, f64)]| -> Ranking { r.iter().map(|(n, x)| (n.to_string(), *x)).collect() };
        assert_eq!(pick(&ranking(&[("rt-shared-faces", 1.1e9), ("soft-bvh", 1.0e9), ("cpu", 1e7)]), &avail), soft);
        assert_eq!(pick(&ranking(&[("rt-shared-faces", 2.0e9), ("soft-bvh", 1.0e9)]), &avail), shared);
        assert_eq!(pick(&ranking(&[("rt-shared-faces", 2.0e9), ("cpu", 1e7)]), &[Backend::Cpu]), Backend::Cpu);
        assert_eq!(pick(&ranking(&[]), &avail), Backend::Cpu);
    }

    fn fail(msg: &str) -> crate::Error {
        tetloc_core::Error::Invalid(msg.into()).into()
    }

    /// A cache that cannot be written: the measurement is made once, said once, and kept.
    #[test]
    fn an_unwritable_cache_measures_once() {
        let dir = std::env::temp_dir().join(format!("tetloc-auto-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        // A regular file where the cache directory should be: not writable, even for root.
        std::fs::write(dir.join("not-a-dir"), "").unwrap();
        let path = dir.join("not-a-dir/tetloc/auto-x.json");
        let mut calls = 0;
        let mut measure = || -> Result<Ranking> {
            calls += 1;
            Ok(vec![("soft-bvh".into(), 2e9), ("cpu".into(), 1e8)])
        };
        let (r, from) = ranking(Some(&path), "test device A", &mut measure).unwrap();
        assert_eq!((r[0].0.as_str(), from), ("soft-bvh", "measured"));
        let (r, from) = ranking(Some(&path), "test device A", &mut measure).unwrap();
        assert_eq!((r[0].0.as_str(), from), ("soft-bvh", "measured before in this process"));
        assert_eq!(calls, 1);
        // A writable cache is written, and read back by a later process (a key this one has
        // not measured); a cache of another device is not used.
        let good = dir.join("cache/tetloc/auto-y.json");
        ranking(Some(&good), "test device B", &mut || Ok(vec![("rt-bvh".into(), 1e9)])).unwrap();
        let text = std::fs::read_to_string(&good).unwrap();
        assert!(text.contains("rt-bvh") && text.contains("test device B"), "{text}");
        std::fs::write(&good, text.replace("test device B", "test device C")).unwrap();
        let (r, from) = ranking(Some(&good), "test device C", &mut || Err(fail("not measured again"))).unwrap();
        assert_eq!((r[0].0.as_str(), from), ("rt-bvh", "cached"));
        let e = ranking(Some(&good), "test device D", &mut || Err(fail("measured"))).unwrap_err();
        assert_eq!(e.to_string(), "measured");
        // No temporary file is left beside the cache.
        let left: Vec<_> = std::fs::read_dir(good.parent().unwrap()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(left, [std::ffi::OsString::from("auto-y.json")]);
    }
}
