//! Backend selection: `cpu`, the four Vulkan kernels, and `auto` (the fastest on this
//! machine, chosen from a measurement that is cached per device).

use anyhow::{bail, Context as _, Result};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::{Arc, OnceLock};
use std::time::Instant;
use tetloc_core::queries::{self, QueryKind};
use tetloc_core::{BatchLocator, CpuLocator, Mesh};
use tetloc_vulkan::{Context, Kernel, LocatorOptions, VulkanLocator};

pub const CPU: &str = "cpu";

/// Every backend name the CLI accepts (besides `auto` and `all`).
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
}

impl Default for BackendOptions {
    fn default() -> Self {
        let d = LocatorOptions::default();
        BackendOptions { device: None, split: d.split, compact: d.compact }
    }
}

impl BackendOptions {
    fn locator_options(&self) -> LocatorOptions {
        LocatorOptions { split: self.split, compact: self.compact, ..LocatorOptions::default() }
    }
}

/// The process' one Vulkan context, or why there is none.
pub fn vulkan(device: Option<usize>) -> Result<Arc<Context>, String> {
    static CTX: OnceLock<Result<Arc<Context>, String>> = OnceLock::new();
    CTX.get_or_init(|| Context::new(device).map_err(|e| e.to_string())).clone()
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

/// Builds the named backend over `mesh`.
pub fn make(name: &str, mesh: &Arc<Mesh>, opts: &BackendOptions) -> Result<Box<dyn BatchLocator>> {
    if name == "auto" {
        let best = auto_choice(opts)?;
        return make(&best, mesh, opts);
    }
    if name == CPU {
        return Ok(Box::new(CpuLocator::new(mesh.clone())));
    }
    let kernel: Kernel = name
        .parse()
        .map_err(|_| anyhow::anyhow!("unknown backend '{name}' (known: {}, auto, all)", names().join(", ")))?;
    Ok(Box::new(make_vulkan(kernel, mesh, opts)?))
}

pub fn make_vulkan(kernel: Kernel, mesh: &Arc<Mesh>, opts: &BackendOptions) -> Result<VulkanLocator> {
    let ctx = vulkan(opts.device).map_err(|e| anyhow::anyhow!("{}: no Vulkan device: {e}", kernel.name()))?;
    if kernel.needs_ray_tracing() && !ctx.info().ray_tracing {
        bail!("{}: the device '{}' has no ray-tracing pipelines; use soft-bvh or cpu", kernel.name(), ctx.info().name);
    }
    Ok(VulkanLocator::new(ctx, mesh.clone(), kernel, opts.locator_options())?)
}

/// The cached ranking of backends on one device.
#[derive(Serialize, Deserialize)]
struct AutoCache {
    device: String,
    ranking: Vec<(String, f64)>,
}

fn cache_path(device: &str) -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    let key: String = device.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    Some(base.join("tetloc").join(format!("auto-{key}.json")))
}

/// `auto`: the backend that located random points fastest on a probe mesh on this device
/// (measured once per device and driver, then read from the cache).
pub fn auto_choice(opts: &BackendOptions) -> Result<String> {
    let avail = available(opts);
    if avail.len() == 1 {
        return Ok(avail[0].to_string());
    }
    let device = vulkan(opts.device).map(|c| format!("{} {}", c.info().name, c.info().driver)).unwrap_or_default();
    let path = cache_path(&device);
    if let Some(cached) =
        path.as_ref().and_then(|p| std::fs::read(p).ok()).and_then(|b| serde_json::from_slice::<AutoCache>(&b).ok())
    {
        if let Some((best, _)) = cached.ranking.iter().find(|(n, _)| avail.contains(&n.as_str())) {
            return Ok(best.clone());
        }
    }
    let ranking = measure_ranking(&avail, opts)?;
    eprintln!(
        "auto: measured on this device ({device}): {}",
        ranking.iter().map(|(n, r)| format!("{n} {}", crate::bench::fmt_rate(*r))).collect::<Vec<_>>().join(", ")
    );
    if let Some(p) = &path {
        let _ = std::fs::create_dir_all(p.parent().unwrap());
        let _ = std::fs::write(p, serde_json::to_vec(&AutoCache { device, ranking: ranking.clone() })?);
    }
    Ok(ranking[0].0.clone())
}

fn measure_ranking(avail: &[&str], opts: &BackendOptions) -> Result<Vec<(String, f64)>> {
    let probe =
        Arc::new(Mesh::new(tetloc_core::gen::generate(tetloc_core::gen::Shape::Fusion, 300_000, 7), "auto probe")?);
    let points = queries::generate(&probe, QueryKind::Random, 1 << 20, 7);
    let mut ids = vec![0; points.len()];
    let mut ranking = Vec::new();
    for &name in avail {
        let mut loc = make(name, &probe, opts).with_context(|| format!("auto: measuring {name}"))?;
        loc.locate(&points, &mut ids)?;
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let t = Instant::now();
            loc.locate(&points, &mut ids)?;
            best = best.min(t.elapsed().as_secs_f64());
        }
        ranking.push((name.to_string(), points.len() as f64 / best));
    }
    ranking.sort_by(|a, b| b.1.total_cmp(&a.1));
    Ok(ranking)
}
