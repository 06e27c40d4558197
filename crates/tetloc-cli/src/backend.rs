//! Backend selection: `cpu`, the four Vulkan kernels, and `auto`.
//!
//! `auto` is decided in seconds and said on stderr: `cpu` when there is no Vulkan device or
//! when the device runs on the CPU itself (lavapipe, llvmpipe, SwiftShader: Vulkan's CPU device
//! type), where a GPU kernel only competes with the cpu backend for the same cores; otherwise
//! the fastest backend in a microbenchmark of at most [`AUTO_BUDGET_S`], cached per device and
//! driver. A cache that cannot be written is said once, and the choice is kept in memory.

use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;
use tetloc_core::locate::{CellLocator, FiniteOnly};
use tetloc_core::queries::{self, QueryKind};
use tetloc_core::{BatchLocator, CpuLocator, Mesh};
use tetloc_vulkan::{BuildOn, Context, Kernel, LocatorOptions, VulkanLocator};

pub const CPU: &str = "cpu";

/// Every backend name the CLI accepts (besides `auto`, and `all` for bench).
pub fn names() -> Vec<&'static str> {
    std::iter::once(CPU).chain(Kernel::ALL.iter().map(|k| k.name())).collect()
}

/// Options that matter to some backends.
#[derive(Clone, Debug)]
pub struct BackendOptions {
    pub device: Option<usize>,
    /// rt kernels: primitives per bottom-level structure (`None`: one structure).
    pub split: Option<usize>,
    pub compact: bool,
    /// GPU kernels: sort each batch along the Morton curve before locating it.
    pub order_queries: bool,
    /// soft-bvh layout (tetloc_vulkan::PRESETS).
    pub preset: String,
    /// soft-bvh: build its structure on the GPU or on the CPU.
    pub build: BuildOn,
    /// Do not say which backend `auto` chose.
    pub quiet: bool,
}

impl Default for BackendOptions {
    fn default() -> Self {
        let d = LocatorOptions::default();
        BackendOptions {
            device: None,
            split: d.split,
            compact: d.compact,
            order_queries: d.order_queries,
            preset: "fast".into(),
            build: d.build,
            quiet: false,
        }
    }
}

impl BackendOptions {
    fn locator_options(&self) -> LocatorOptions {
        // The CLI offers only the known names (clap checks them).
        let base = LocatorOptions::preset(&self.preset).unwrap_or_default();
        LocatorOptions {
            split: self.split,
            compact: self.compact,
            order_queries: self.order_queries,
            build: self.build,
            ..base
        }
    }
}

/// The process' one Vulkan context, or why there is none.
pub fn vulkan(device: Option<usize>) -> Result<Arc<Context>, String> {
    static CTX: OnceLock<Result<Arc<Context>, String>> = OnceLock::new();
    CTX.get_or_init(|| Context::new(device).map_err(|e| e.to_string())).clone()
}

/// Whether the Vulkan device is Vulkan's CPU device type (lavapipe, llvmpipe, SwiftShader):
/// its kernels compete with the cpu backend for the same cores.
pub fn runs_on_cpu(ctx: &Context) -> bool {
    ctx.info().device_type == "cpu"
}

/// Backends that can run here: the Vulkan kernels this device supports, then `cpu`.
pub fn available(opts: &BackendOptions) -> Vec<&'static str> {
    let mut out = Vec::new();
    if let Ok(ctx) = vulkan(opts.device) {
        let rt = ctx.info().ray_tracing;
        out.extend(Kernel::ALL.iter().filter(|k| rt || !k.needs_ray_tracing()).map(|k| k.name()));
    }
    out.push(CPU);
    out
}

/// Builds the named backend over `mesh`. Points with a NaN or infinite coordinate are
/// answered -1 / NaN before any backend sees them; on mixed meshes the answers in the tet
/// decomposition become cells ([`CellLocator`]).
pub fn make(name: &str, mesh: &Arc<Mesh>, opts: &BackendOptions) -> Result<Box<dyn BatchLocator>> {
    make_with(name, mesh, opts, false)
}

/// [`make`] for a resample: on the CPU the search is built only if the grid needs it (its
/// grid path rasterizes the tets; only grid points on faces need the search's tie rule).
pub fn make_for_grid(name: &str, mesh: &Arc<Mesh>, opts: &BackendOptions) -> Result<Box<dyn BatchLocator>> {
    make_with(name, mesh, opts, true)
}

/// [`make`], the CPU's search built on first need when `defer_cpu_build`.
fn make_with(
    name: &str,
    mesh: &Arc<Mesh>,
    opts: &BackendOptions,
    defer_cpu_build: bool,
) -> Result<Box<dyn BatchLocator>> {
    if name == "auto" {
        return make_with(&auto_choice(opts)?, mesh, opts, defer_cpu_build);
    }
    let backend: Box<dyn BatchLocator> = if name == CPU {
        Box::new(if defer_cpu_build {
            CpuLocator::deferred(mesh.clone(), tetloc_core::bvh::BuildPreset::Fast)
        } else {
            CpuLocator::new(mesh.clone())
        })
    } else {
        let kernel: Kernel = name
            .parse()
            .map_err(|_| anyhow::anyhow!("unknown backend '{name}' (known: {}, auto)", names().join(", ")))?;
        Box::new(make_vulkan(kernel, mesh, opts)?)
    };
    Ok(Box::new(CellLocator::new(FiniteOnly::new(backend), mesh.clone())))
}

pub fn make_vulkan(kernel: Kernel, mesh: &Arc<Mesh>, opts: &BackendOptions) -> Result<VulkanLocator> {
    let ctx = vulkan(opts.device).map_err(|e| anyhow::anyhow!("{}: no Vulkan device: {e}", kernel.name()))?;
    if kernel.needs_ray_tracing() && !ctx.info().ray_tracing {
        bail!("{}: the device '{}' has no ray-tracing pipelines; use soft-bvh or cpu", kernel.name(), ctx.info().name);
    }
    Ok(VulkanLocator::new(ctx, mesh.clone(), kernel, opts.locator_options())?)
}

/// Longest time `auto` spends measuring, builds included.
pub const AUTO_BUDGET_S: f64 = 2.0;

/// `auto`: the backend for this machine, said on stderr unless `opts.quiet` (see the module
/// documentation). Decided once per process.
pub fn auto_choice(opts: &BackendOptions) -> Result<String> {
    static CHOICE: OnceLock<String> = OnceLock::new();
    if let Some(c) = CHOICE.get() {
        return Ok(c.clone());
    }
    let (choice, why) = decide(opts)?;
    if !opts.quiet {
        eprintln!("auto: {choice} ({why})");
    }
    Ok(CHOICE.get_or_init(|| choice).clone())
}

fn decide(opts: &BackendOptions) -> Result<(String, String)> {
    let ctx = match vulkan(opts.device) {
        Ok(c) => c,
        Err(e) => return Ok((CPU.into(), format!("no Vulkan device: {e}"))),
    };
    let info = ctx.info();
    if runs_on_cpu(&ctx) {
        return Ok((CPU.into(), format!("the Vulkan device, {}, runs on the CPU", info.name)));
    }
    let key = format!("{} {}", info.name, info.driver);
    let avail = available(opts);
    let path = cache_path(&key);
    let (ranking, source) = ranking(path.as_deref(), &key, &mut || measure(&avail, opts, AUTO_BUDGET_S))?;
    let best = ranking.iter().find(|(n, _)| avail.contains(&n.as_str())).map_or(CPU.to_string(), |b| b.0.clone());
    let rates: Vec<String> = ranking.iter().map(|(n, r)| format!("{n} {}", crate::bench::fmt_rate(*r))).collect();
    Ok((best, format!("{source} on {key}: {}", rates.join(", "))))
}

/// A ranking of backends by samples/s on one device, fastest first.
type Ranking = Vec<(String, f64)>;

/// The cached ranking of backends on one device and driver.
#[derive(Serialize, Deserialize)]
struct AutoCache {
    device: String,
    ranking: Ranking,
}

fn cache_path(key: &str) -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    let name: String = key.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    Some(base.join("tetloc").join(format!("auto-{name}.json")))
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
    let cached = path.and_then(|p| std::fs::read(p).ok()).and_then(|b| serde_json::from_slice::<AutoCache>(&b).ok());
    if let Some(c) = cached.filter(|c| c.device == key && !c.ranking.is_empty()) {
        memory.insert(key.to_string(), c.ranking.clone());
        return Ok((c.ranking, "cached"));
    }
    let ranking = measure()?;
    memory.insert(key.to_string(), ranking.clone());
    match path {
        Some(p) => {
            let json = serde_json::to_vec(&AutoCache { device: key.to_string(), ranking: ranking.clone() })?;
            let written = p
                .parent()
                .map_or(Ok(()), std::fs::create_dir_all)
                .map_err(|e| tetloc_core::Error::io(p.parent().unwrap_or(p), e))
                .and_then(|_| tetloc_io::output::write_atomically(p, |f| write_all(f, p, &json)));
            if let Err(e) = written {
                eprintln!("warning: auto: cannot cache the measurement ({e}); it is kept for this run only");
            }
        }
        None => eprintln!("warning: auto: no cache directory (neither XDG_CACHE_HOME nor HOME is set); the measurement is kept for this run only"),
    }
    Ok((ranking, "measured"))
}

fn write_all(f: &mut impl std::io::Write, p: &Path, bytes: &[u8]) -> tetloc_core::Result<()> {
    f.write_all(bytes).map_err(|e| tetloc_core::Error::io(p, e))
}

/// Samples/s of each backend locating random points in a small probe mesh, within about
/// `budget_s` seconds in all (a build or a run already started is not interrupted): each
/// backend gets an equal share of what is left, in which batches grow from 4096 points while
/// they are short against the share; its rate is the best batch's. Backends not reached in
/// time are left out of the ranking.
fn measure(avail: &[&str], opts: &BackendOptions, budget_s: f64) -> Result<Ranking> {
    let start = Instant::now();
    let probe =
        Arc::new(Mesh::new(tetloc_core::gen::generate(tetloc_core::gen::Shape::Fusion, 50_000, 7), "auto probe")?);
    let points = queries::generate(&probe, QueryKind::Random, 1 << 20, 7);
    let mut ids = vec![0; points.len()];
    let mut ranking = Vec::new();
    for (k, &name) in avail.iter().enumerate() {
        let left = budget_s - start.elapsed().as_secs_f64();
        if left <= 0.0 {
            break;
        }
        let share = left / (avail.len() - k) as f64;
        let t = Instant::now();
        let mut loc = match make(name, &probe, opts) {
            Ok(l) => l,
            Err(e) => {
                eprintln!("warning: auto: {name} left out: {e:#}");
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
        ranking.push((name.to_string(), rate));
    }
    ranking.sort_by(|a, b| b.1.total_cmp(&a.1));
    Ok(ranking)
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let (r, from) = ranking(Some(&good), "test device C", &mut || bail!("not measured again")).unwrap();
        assert_eq!((r[0].0.as_str(), from), ("rt-bvh", "cached"));
        let e = ranking(Some(&good), "test device D", &mut || bail!("measured")).unwrap_err();
        assert_eq!(e.to_string(), "measured");
    }
}
