//! Generates (or loads) a mesh, checks every kernel against the CPU locator and prints a
//! benchmark table like the paper's Table 1, plus memory like its Table 2.
//!
//! cargo run --release -p tetloc-vulkan --example vkbench -- --tets 1000000 --shape jets
//!
//! Options: --tets N, --shape jets|fusion|agulhas|japan, --regular (an unjittered grid of
//! n³ cubes, 6 Kuhn tets each, like the lead's throwaway probe), --mesh FILE, --seed S, --device I,
//! --kernels a,b (default all the device runs), --modes centers,random,bbox,host (uniform: centers),
//! --field NAME (also the scalar variant), --check N (points checked per kernel, 0: none),
//! --split N|none, --no-compact, --leaf 1|4, --pack (ids in as few bits as the mesh needs), --tet-order on|off (random points
//! made in tet order; default by mesh size), --chunk N (points a launch), --workgroup N, --repeats R, --power,
//! --grid (soft-bvh entry grid), --walk / --no-walk (soft-bvh walk start, the default),
//! --cell-tets N (grid resolution), --f32-first, --f32 (pure-f32 test), --max-buffer BYTES
//! (split arrays above this size over several buffers, as when they exceed the device's
//! limits), --defer (soft-bvh: exact tests deferred to a second dispatch), --variants
//! (soft-bvh variants: root traversal, entry grid, walk start at two grid resolutions,
//! f32-first, pure-f32 and deferred exact tests).

mod common;

use common::num;
use std::sync::Arc;
use std::time::Instant;
use tetloc_core::gen::{generate, Shape};
use tetloc_core::geom;
use tetloc_core::{BatchLocator, CpuLocator, Mesh};
use tetloc_vulkan::{
    devices, BenchOptions, BenchResult, Context, Kernel, LocatorOptions, QueryKind, SoftBvhOptions, VulkanLocator,
};

struct Args {
    tets: usize,
    shape: Shape,
    mesh: Option<String>,
    seed: u64,
    device: Option<usize>,
    kernels: Option<Vec<Kernel>>,
    modes: Vec<QueryKind>,
    field: Option<String>,
    check: usize,
    opts: LocatorOptions,
    repeats: usize,
    power: bool,
    variants: bool,
    regular: bool,
}

fn parse() -> Result<Args, String> {
    let mut a = Args {
        tets: 1_000_000,
        shape: Shape::Jets,
        mesh: None,
        seed: 1,
        device: None,
        kernels: None,
        modes: QueryKind::ALL.to_vec(),
        field: None,
        check: 1_000_000,
        opts: LocatorOptions::default(),
        repeats: 7,
        power: false,
        variants: false,
        regular: false,
    };
    common::each_flag(|flag, val| {
        match flag {
            "--tets" => a.tets = num(val()?)?,
            "--shape" => a.shape = val()?.parse().map_err(|e: tetloc_core::Error| e.to_string())?,
            "--mesh" => a.mesh = Some(val()?),
            "--seed" => a.seed = num(val()?)? as u64,
            "--device" => a.device = Some(num(val()?)?),
            "--kernels" => a.kernels = Some(val()?.split(',').map(|k| k.parse()).collect::<Result<_, _>>()?),
            "--modes" => a.modes = val()?.split(',').map(|m| m.parse()).collect::<Result<_, _>>()?,
            "--field" => a.field = Some(val()?),
            "--check" => a.check = num(val()?)?,
            "--split" => {
                a.opts.rt.split = match val()?.as_str() {
                    "none" => None,
                    s => Some(num(s.into())?),
                }
            }
            "--no-compact" => a.opts.rt.compact = false,
            "--leaf" => a.opts.soft_bvh.leaf_size = num(val()?)?,
            "--pack" => a.opts.pack_ids = true,
            "--tet-order" => {
                a.opts.random_in_tet_order = match val()?.as_str() {
                    "on" => Some(true),
                    "off" => Some(false),
                    v => return Err(format!("--tet-order takes on or off, not {v}")),
                }
            }
            "--chunk" => a.opts.chunk_points = num(val()?)?,
            "--workgroup" => a.opts.soft_bvh.workgroup_size = num(val()?)? as u32,
            "--grid" => a.opts.soft_bvh.grid_start = true,
            "--walk" => a.opts.soft_bvh.walk_start = true,
            "--no-walk" => a.opts.soft_bvh.walk_start = false,
            "--cell-tets" => a.opts.soft_bvh.grid_tets_per_cell = num(val()?)?,
            "--f32-first" => a.opts.soft_bvh.f32_first = true,
            "--defer" => a.opts.soft_bvh.defer_exact = true,
            "--f32" => a.opts.float64 = false,
            "--max-buffer" => a.opts.test_hooks.max_buffer_bytes = Some(num(val()?)? as u64),
            "--repeats" => a.repeats = num(val()?)?,
            "--power" => a.power = true,
            "--variants" => a.variants = true,
            "--regular" => a.regular = true,
            _ => return Err(format!("unknown option {flag} (see the header of examples/vkbench.rs)")),
        }
        Ok(())
    })?;
    Ok(a)
}

/// Locates `n` random in-kernel samples and checks them against the CPU definition:
/// (points checked, GPU ids not containing their point, interior points lost, ids differing).
fn check(
    loc: &mut VulkanLocator,
    cpu: &mut CpuLocator,
    mesh: &Mesh,
    n: usize,
) -> Result<(usize, usize, usize, usize), Box<dyn std::error::Error>> {
    let mut bad = (0, 0, 0);
    for mode in [QueryKind::Random, QueryKind::Bbox] {
        let (points, ids) = loc.locate_generated(mode, n / 2, 7)?;
        let mut want = vec![0; points.len()];
        cpu.locate(&points, &mut want)?;
        for i in 0..points.len() {
            if ids[i] == want[i] {
                continue;
            }
            bad.2 += 1;
            if ids[i] < 0 {
                bad.1 += 1;
            } else if geom::point_in_tet(mesh.tets[ids[i] as usize], &mesh.points, points[i]).is_none() {
                bad.0 += 1;
            }
        }
    }
    Ok((n / 2 * 2, bad.0, bad.1, bad.2))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse()?;
    println!("Vulkan devices:");
    for d in devices()? {
        println!(
            "  [{}] {} ({}, {}), Vulkan {}, {:.1} GiB, ray tracing: {}, float64: {}",
            d.index,
            d.name,
            d.device_type,
            d.driver,
            d.api_version,
            d.memory_bytes as f64 / (1u64 << 30) as f64,
            d.ray_tracing,
            d.float64
        );
    }
    let ctx = Context::new(args.device)?;
    println!("using [{}] {} ({})", ctx.info().index, ctx.info().name, ctx.info().driver);

    let t = Instant::now();
    let mesh = Arc::new(match &args.mesh {
        Some(path) => tetloc_io::read_mesh(std::path::Path::new(path), None)?,
        None if args.regular => {
            let n = (args.tets as f64 / 6.0).cbrt().round().max(1.0) as usize;
            tetloc_testdata::KuhnGrid::new(n).mesh(&format!("regular {n}^3 cubes"))
        }
        None => Mesh::new(generate(args.shape, args.tets, args.seed), args.shape.name())?,
    });
    println!(
        "mesh {}: {} tets, {} points, max edge {:.4}, made in {:.1} s",
        mesh.info.source,
        mesh.n_tets(),
        mesh.points.len(),
        mesh.info.max_edge_length,
        t.elapsed().as_secs_f64()
    );
    // The CPU reference only when checking (its BVH takes a minute at 250M tets).
    let t = Instant::now();
    let mut cpu = (args.check > 0).then(|| CpuLocator::new(mesh.clone()));
    if cpu.is_some() {
        println!("cpu locator built in {:.1} s", t.elapsed().as_secs_f64());
    }

    let kernels = args.kernels.clone().unwrap_or_else(|| {
        Kernel::ALL.into_iter().filter(|k| ctx.info().ray_tracing || !k.needs_ray_tracing()).collect()
    });
    let mut configs: Vec<(String, Kernel, LocatorOptions)> =
        kernels.iter().map(|&k| (k.name().to_string(), k, args.opts.clone())).collect();
    if args.variants {
        // (grid, walk, tets per cell, f32 first, f64); leaf size and workgroup size were
        // measured before (BENCHMARKS.md: within noise).
        // (grid, walk, tets per cell, f32 first, f64, deferred exact tests)
        for (grid, walk, cell, first, f64, defer) in [
            (false, false, 1, false, true, false),
            (false, false, 1, true, true, false),
            (true, false, 2, false, true, false),
            (false, true, 2, false, true, false),
            (false, true, 1, true, true, false),
            (false, true, 1, false, false, false),
            (false, true, 1, false, true, true),
        ] {
            let o = LocatorOptions {
                float64: f64,
                soft_bvh: SoftBvhOptions {
                    grid_start: grid,
                    walk_start: walk,
                    grid_tets_per_cell: cell,
                    f32_first: first,
                    defer_exact: defer,
                    ..args.opts.clone().soft_bvh
                },
                ..args.opts.clone()
            };
            let label = format!(
                "soft-bvh{}{}{}{}",
                if walk {
                    format!(" walk {cell}")
                } else if grid {
                    format!(" grid {cell}")
                } else {
                    " root".into()
                },
                if first { " f32-first" } else { "" },
                if f64 { "" } else { " pure-f32" },
                if defer { " deferred" } else { "" }
            );
            configs.push((label, Kernel::SoftBvh, o));
        }
    }
    let host_points: Vec<_> = {
        // Host mode: the tet centres in a shuffled-by-stride order (not the mesh order).
        let n = mesh.n_tets();
        let stride = 1_000_003 % n.max(1);
        (0..n).map(|i| mesh.tet_center((i * stride.max(1)) % n)).collect()
    };
    let mut rows = vec![];
    let mut memory = vec![];
    for (label, k, opts) in configs {
        let t = Instant::now();
        let mut loc = match VulkanLocator::new(ctx.clone(), mesh.clone(), k, opts) {
            Ok(l) => l,
            Err(e) => {
                println!("{label}: build failed: {e}");
                continue;
            }
        };
        println!("{label}: built in {:.2} s (float64 test: {})", t.elapsed().as_secs_f64(), loc.uses_float64());
        if let Some(cpu) = cpu.as_mut() {
            let (n, wrong, lost, differ) = check(&mut loc, cpu, &mesh, args.check)?;
            println!("{label}: check of {n} random+bbox samples vs CPU: {wrong} wrong tets, {lost} lost, {differ} differ (valid ties)");
        }
        for &mode in &args.modes {
            let mut variants = vec![None];
            if args.field.is_some() {
                variants.push(args.field.clone());
            }
            for field in variants {
                let o = BenchOptions {
                    mode,
                    field,
                    repeats: args.repeats,
                    power: args.power,
                    seed: 1,
                    ..Default::default()
                };
                match loc.bench(&o, Some(&host_points)) {
                    Ok(r) => {
                        println!("{label}: {}", r.row());
                        rows.push((label.clone(), r));
                    }
                    Err(e) => println!("{label} {}: {e}", mode.name()),
                }
            }
        }
        let m = loc.memory_report();
        memory.push((label.clone(), m.clone()));
    }

    println!("\n{} | {} | {}", ctx.info().name, ctx.info().driver, mesh.info.source);
    println!("{:<28} {}", "config", BenchResult::header());
    for (label, r) in &rows {
        println!("{:<28} {}", label, r.row());
    }
    println!("\nmemory (MiB): final = resident after build, peak = during build");
    for (label, m) in &memory {
        let mib = |b: u64| b as f64 / (1 << 20) as f64;
        let accel = m.accel.map_or(String::new(), |a| {
            format!(
                "  BLAS x{} ({} prims): built {:.1}, compacted {:.1}, TLAS {:.3}",
                a.blas_count,
                a.primitives,
                mib(a.blas_bytes_built),
                mib(a.blas_bytes),
                mib(a.tlas_bytes)
            )
        });
        println!("{label:<28} final {:>9.1} peak {:>9.1}{accel}", mib(m.final_bytes), mib(m.peak_bytes));
        // Where the final bytes go, per allocation (split buffers summed under one name).
        let mut named: Vec<(String, u64)> = vec![];
        for item in &m.items {
            let name = match item.name.rsplit_once(' ') {
                Some((base, part)) if part.contains('/') && part.chars().all(|c| c.is_ascii_digit() || c == '/') => {
                    base
                }
                _ => item.name.as_str(),
            }
            .to_string();
            match named.iter_mut().find(|(n, _)| *n == name) {
                Some(entry) => entry.1 += item.bytes,
                None => named.push((name, item.bytes)),
            }
        }
        for (name, bytes) in named {
            println!("    {name:<32} {:>9.1} MiB  {:>6.2} B a tet", mib(bytes), bytes as f64 / mesh.n_tets() as f64);
        }
    }
    if ctx.validation_enabled() {
        println!("validation errors: {}", ctx.validation_errors());
    }
    Ok(())
}
