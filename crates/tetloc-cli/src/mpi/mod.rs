//! One rank of a distributed run (feature `mpi`): `mpirun -n N tetloc locate MESH.pvtu ...`,
//! `bench`, and `resample` and `probe` (rank 0 drives them, `driven.rs`). Each rank loads its pieces and builds its
//! locator (`tetloc_mpi::dist`); rank 0 reads the points, scatters them, gathers the answers
//! and writes them; progress and timings come from rank 0 only. Any failure before the query
//! ends every rank with an error naming the rank and its cause (said once, by rank 0); a
//! failure during a query aborts the job (MPI_Abort).

mod driven;

use crate::{bench, error_text, locate, mesh_arg, probe, progress, resample, Cli, Command, Common};
use anyhow::{bail, Result};
use rand::{Rng, SeedableRng};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;
use tetloc_core::locate::Precision;
use tetloc_core::queries::{self, QueryKind};
use tetloc_core::{BatchLocator, Mesh, Vec3};
use tetloc_io::points::{self, Values};
use tetloc_io::vtk::write::Coords;
use tetloc_mpi::dist::{load_part, Cluster, DistLocator, Part};
use tetloc_mpi::launch;
use tetloc_mpi::mpi::datatype::{Partition, PartitionMut};
use tetloc_mpi::mpi::traits::*;
use tetloc_mpi::mpi::Count;

/// Runs the command on this rank; the exit code.
pub fn run(cli: Cli) -> i32 {
    let cluster = match Cluster::init() {
        Ok(c) => c,
        Err(e) => {
            eprintln!("error: {e}");
            return 1;
        }
    };
    progress::set_quiet(!cluster.is_root());
    let r = match cli.command {
        Command::Locate(a) => run_locate(&cluster, &a),
        Command::Bench { trace: Some(_), .. } => Err(anyhow::anyhow!("bench --trace does not run distributed")),
        Command::Bench { mesh, queries, n, repeats, field, json, backend, common, .. } => {
            let n = n.map(|s| mesh_arg::parse_count(&s)).transpose();
            n.and_then(|n| {
                let args = BenchArgs { queries, n, repeats: repeats as usize, field, json, backend, common };
                run_bench(&cluster, Path::new(&mesh), &args)
            })
        }
        Command::Resample(a) => run_resample(&cluster, &a),
        Command::Probe(a) => run_probe(&cluster, &a),
        _ => unreachable!("main runs only locate, bench, resample and probe distributed"),
    };
    match r {
        Ok(()) => 0,
        Err(e) => {
            // Every rank has the same error (failures are agreed on): rank 0 says it.
            if cluster.is_root() {
                eprintln!("error: {}", error_text(&e));
            }
            1
        }
    }
}

/// This rank's locator: the backend (`auto` decided here), on device `local rank` modulo the
/// node's Vulkan devices unless `--device` says.
fn build<'c>(
    cluster: &'c Cluster,
    name: &str,
    common: &Common,
    part: Option<&Part>,
) -> Result<DistLocator<'c, Box<dyn BatchLocator>>> {
    let mut opts = common.opts()?;
    opts.quiet |= !cluster.is_root();
    if opts.device.is_none() && name != tetloc_locator::CPU {
        let n = tetloc_vulkan::devices().map_or(0, |d| d.len());
        if n > 0 {
            opts.device = Some(cluster.local_rank % n);
        }
    }
    let make = |mesh: &Arc<Mesh>| -> Result<Box<dyn BatchLocator>, String> {
        let built = opts.builder(mesh, name).and_then(|(_, b)| Ok(b.build()?));
        built.map(|b| -> Box<dyn BatchLocator> { b.locator }).map_err(|e| error_text(&e))
    };
    let loc = DistLocator::new(cluster, part, make)?;
    // Which backend and device each rank took (said by rank 0).
    let mine = match (loc.local(), opts.device) {
        (None, _) => "no pieces".to_string(),
        (Some(l), Some(d)) if l.name() != tetloc_locator::CPU => format!("{} on device {d}", l.name()),
        (Some(l), _) => l.name().to_string(),
    };
    let placed = cluster.all_gather_strings(&format!(
        "rank {} (local rank {} of {}): {mine}",
        cluster.rank, cluster.local_rank, cluster.local_size
    ));
    if cluster.is_root() && !common.quiet {
        placed.iter().for_each(|p| eprintln!("{p}"));
    }
    Ok(loc)
}

fn run_locate(cluster: &Cluster, a: &locate::LocateArgs) -> Result<()> {
    let checked = locate::check_args(a).and_then(|()| no_tolerance(a.tolerance));
    cluster.agree("check the arguments", checked.map_err(|e| error_text(&e)))?;
    let listing = Path::new(&a.mesh);
    let t0 = Instant::now();
    let part = load_part(cluster, listing)?;
    let has_field = match (&a.field, &part) {
        (Some(f), Some(p)) => p.mesh.field(f).map(|f| f.values64.is_some()).map_err(|e| e.to_string()),
        _ => Ok(false),
    };
    let f64_field = cluster.agree("find the field", has_field)?;
    // As one process locates: at the file's precision where any rank's pieces want it (f64
    // data, or far from the origin), values in f64 for an f64 field or `--precision f64`.
    let any = |b: bool| cluster.max_u64(u64::from(b)) == 1;
    let wide_values = a.field.is_some() && (a.precision == Precision::F64 || any(f64_field));
    let at_f64 = any(part.as_ref().is_some_and(|p| p.mesh.wants_f64_points())) || wide_values;
    let mut loc = build(cluster, &a.backend, &a.common, part.as_ref())?;
    let setup_s = t0.elapsed().as_secs_f64();

    // Rank 0 reads the points and hands each rank a contiguous slice.
    let pts64 = match cluster.is_root() {
        // A FIFO is refused before it is opened (opening it would block for ever).
        true => tetloc_io::check_regular_input(&a.points)
            .and_then(|()| points::read_points64(&a.points))
            .map_err(|e| e.to_string()),
        false => Ok(Vec::new()),
    };
    let pts64 = cluster.agree("read the points", pts64)?;
    let pts: Vec<Vec3> = pts64.iter().map(|p| p.map(|c| c as f32)).collect();
    let fields: Vec<&str> = a.field.as_deref().into_iter().collect();
    let t1 = Instant::now();
    let (got_ids, ties, values32, values64) = if at_f64 {
        let got = loc.query(&scatter(cluster, &pts64), &fields);
        (got.ids, got.ties, Vec::new(), got.values)
    } else {
        let got = loc.query(&scatter(cluster, &pts), &fields);
        (got.ids, got.ties, got.values, Vec::new())
    };
    cluster.world.barrier();
    let query_s = t1.elapsed().as_secs_f64();
    let ties = cluster.sum_u64(ties as u64);
    let ids = gather(cluster, &got_ids);
    let (values32, values64) = (gather(cluster, &values32), gather(cluster, &values64));
    if !cluster.is_root() {
        return Ok(());
    }
    let ids = ids
        .iter()
        .map(|&g| i32::try_from(g).map_err(|_| anyhow::anyhow!("global cell id {g} does not fit the int32 outputs")))
        .collect::<Result<Vec<i32>>>()?;
    let narrowed: Vec<f32>;
    let values = match (at_f64, wide_values) {
        (_, true) => Values::F64(&values64),
        (true, false) => {
            narrowed = values64.iter().map(|&v| v as f32).collect();
            Values::F32(&narrowed)
        }
        (false, false) => Values::F32(&values32),
    };
    locate::write_results(a, Coords::of(&pts64, &pts), &ids, values)?;
    if !a.common.quiet {
        let none = ids.iter().filter(|&&i| i < 0).count();
        eprintln!(
            "{} points located on {} ranks in {query_s:.3} s ({}; setup {setup_s:.2} s); {none} outside the mesh; {ties} claimed by several ranks",
            pts.len(),
            cluster.size,
            bench::fmt_rate(pts.len() as f64 / query_s),
        );
    }
    Ok(())
}

/// Refuses a boundary tolerance: it needs the nearest boundary cell over all ranks.
fn no_tolerance(t: tetloc_core::locate::Tolerance) -> Result<()> {
    use tetloc_core::locate::Tolerance;
    match t {
        Tolerance::Absolute(d) | Tolerance::PercentOfMeanEdge(d) if d == 0.0 => Ok(()),
        _ => bail!("--tolerance does not run distributed yet (the nearest boundary cell over all ranks)"),
    }
}

/// `resample` of a partitioned mesh: every rank checks the arguments and loads its pieces;
/// rank 0 resamples through the ranks (the grid over the whole mesh's bounds) and writes the
/// image.
fn run_resample(cluster: &Cluster, a: &resample::ResampleArgs) -> Result<()> {
    let plan = cluster.agree("check the arguments", resample::check(a).map_err(|e| error_text(&e)))?;
    let part = load_part(cluster, Path::new(&a.mesh))?;
    let bounds = whole_bounds(cluster, part.as_ref());
    let loc = build(cluster, &a.backend, &a.common, part.as_ref())?;
    drive(cluster, part.as_ref(), loc, |m, loc| resample::execute(a, &plan, m, bounds, loc))
}

/// `probe` with a partitioned SOURCE: rank 0 reads TARGET, probes through the ranks and writes.
fn run_probe(cluster: &Cluster, a: &probe::ProbeArgs) -> Result<()> {
    let checked = probe::check(a).and_then(|point_set| no_tolerance(a.tolerance).map(|()| point_set));
    let point_set = cluster.agree("check the arguments", checked.map_err(|e| error_text(&e)))?;
    let part = load_part(cluster, Path::new(&a.source))?;
    let loc = build(cluster, &a.backend, &a.common, part.as_ref())?;
    drive(cluster, part.as_ref(), loc, |m, loc| probe::execute(a, point_set, m, loc))
}

/// Runs `command` on rank 0 with the ranks' locator while the others serve it; every rank
/// returns rank 0's outcome. Rank 0 names the fields from its own pieces (they all carry the
/// same fields).
fn drive(
    cluster: &Cluster,
    part: Option<&Part>,
    loc: DistLocator<'_, Box<dyn BatchLocator>>,
    command: impl FnOnce(&Mesh, &mut dyn BatchLocator) -> Result<()>,
) -> Result<()> {
    let outcome = if cluster.is_root() {
        let mut driven = driven::Driven::new(cluster, loc);
        let r = match part {
            Some(p) => command(&p.mesh, &mut driven),
            None => Err(anyhow::anyhow!("rank 0 holds no piece: run fewer ranks than pieces")),
        };
        driven.finish();
        r.map_err(|e| error_text(&e))
    } else {
        let mut loc = loc;
        driven::serve(cluster, &mut loc);
        Ok(())
    };
    Ok(cluster.agree("run", outcome)?)
}

/// The whole mesh's bounds in the file's coordinates: the union of the ranks' pieces.
fn whole_bounds(cluster: &Cluster, part: Option<&Part>) -> ([f64; 3], [f64; 3]) {
    let (lo, hi) = part.map_or(([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]), |p| p.mesh.file_box());
    (lo.map(|x| -cluster.max_f64(-x)), hi.map(|x| cluster.max_f64(x)))
}

/// Rank 0's points, a contiguous slice to each rank.
fn scatter<T: Equivalence + Copy + Default>(cluster: &Cluster, pts: &[[T; 3]]) -> Vec<[T; 3]> {
    let root = cluster.world.process_at_rank(0);
    let mut n = pts.len() as u64;
    root.broadcast_into(&mut n);
    let counts: Vec<Count> =
        (0..cluster.size).map(|r| (launch::pieces_of(n as usize, cluster.size, r).len() * 3) as Count).collect();
    let displs = displacements(&counts);
    let mut mine = vec![T::default(); counts[cluster.rank] as usize];
    if cluster.is_root() {
        let flat: Vec<T> = pts.iter().flatten().copied().collect();
        let send = Partition::new(&flat[..], &counts[..], &displs[..]);
        root.scatter_varcount_into_root(&send, &mut mine[..]);
    } else {
        root.scatter_varcount_into(&mut mine[..]);
    }
    mine.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

/// Every rank's values, in rank order, on rank 0 (empty elsewhere).
fn gather<T: Equivalence + Copy + Default>(cluster: &Cluster, mine: &[T]) -> Vec<T> {
    let root = cluster.world.process_at_rank(0);
    let len = mine.len() as Count;
    if !cluster.is_root() {
        root.gather_into(&len);
        root.gather_varcount_into(mine);
        return Vec::new();
    }
    let mut counts = vec![0 as Count; cluster.size];
    root.gather_into_root(&len, &mut counts[..]);
    let displs = displacements(&counts);
    let mut all = vec![T::default(); counts.iter().map(|&c| c as usize).sum()];
    {
        let mut part = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
        root.gather_varcount_into_root(mine, &mut part);
    }
    all
}

fn displacements(counts: &[Count]) -> Vec<Count> {
    counts.iter().scan(0, |a, &c| Some(std::mem::replace(a, *a + c))).collect()
}

struct BenchArgs {
    queries: Vec<QueryKind>,
    n: Option<usize>,
    repeats: usize,
    field: Option<String>,
    json: bool,
    backend: String,
    common: Common,
}

/// The distributed benchmark: every query set is made by the ranks that hold the cells and
/// handed to owner ranks the way points would arrive from a file sliced over the ranks
/// (`centers`: in global cell order, a contiguous slice per rank; `random`: each point to a
/// random rank; `bbox`: made by its owner); then each timed run queries all of them at once.
/// Rows: samples/s over all ranks, the slowest rank's time in its own locator ("local") and
/// the rest of the run ("routing": planning, the all-to-alls, the reduction, waiting).
fn run_bench(cluster: &Cluster, listing: &Path, a: &BenchArgs) -> Result<()> {
    if a.backend == "all" || a.backend.contains(',') {
        bail!("under mpirun bench runs one backend, not '{}'", a.backend);
    }
    let t0 = Instant::now();
    let part = load_part(cluster, listing)?;
    let load_s = cluster.max_f64(t0.elapsed().as_secs_f64());
    if let (Some(f), Some(p)) = (&a.field, &part) {
        cluster.agree("find the field", p.mesh.field(f).map(|_| ()).map_err(|e| e.to_string()))?;
    } else {
        cluster.agree("find the field", Ok(()))?;
    }
    let t1 = Instant::now();
    let mut loc = build(cluster, &a.backend, &a.common, part.as_ref())?;
    let build_s = cluster.max_f64(t1.elapsed().as_secs_f64());
    let backend_name = loc.local().map_or("-".to_string(), |l| l.name().to_string());
    let n_cells = cluster.sum_u64(part.as_ref().map_or(0, |p| p.mesh.n_cells() as u64));
    let n_tets = cluster.sum_u64(part.as_ref().map_or(0, |p| p.mesh.n_tets() as u64));
    let fields: Vec<&str> = a.field.as_deref().into_iter().collect();
    if cluster.is_root() && !a.json {
        println!(
            "{}: {n_cells} cells on {} ranks (load {load_s:.2} s, build {build_s:.2} s, slowest rank), backend {backend_name}",
            listing.display(),
            cluster.size
        );
        println!(
            "{:<8} {:>12} {:>12} {:>10} {:>10} {:>10} {:>8}",
            "queries", "points", "samples/s", "total s", "local s", "routing s", "ties"
        );
    }
    for &kind in &a.queries {
        let total = a.n.unwrap_or(n_tets as usize);
        let pts = bench_points(cluster, part.as_ref(), kind, total, a.common.seed);
        let n_all = cluster.sum_u64(pts.len() as u64);
        loc.query(&pts, &fields); // warm-up
        let mut runs = Vec::with_capacity(a.repeats);
        for _ in 0..a.repeats {
            let before = loc.stats;
            cluster.world.barrier();
            let t = Instant::now();
            let got = loc.query(&pts, &fields);
            cluster.world.barrier();
            let total_s = t.elapsed().as_secs_f64();
            let local_s = cluster.max_f64(loc.stats.local_secs - before.local_secs);
            runs.push((total_s, local_s, got.ties as u64));
        }
        runs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (total_s, local_s, ties) = runs[runs.len() / 2];
        let ties = cluster.sum_u64(ties);
        if cluster.is_root() {
            let rate = n_all as f64 / total_s;
            if a.json {
                let row = serde_json::json!({
                    "mesh": listing.display().to_string(), "ranks": cluster.size, "backend": backend_name,
                    "queries": kind.name(), "points": n_all, "samples_per_s": rate, "total_s": total_s,
                    "local_s": local_s, "routing_s": total_s - local_s, "ties": ties,
                    "cells": n_cells, "load_s": load_s, "build_s": build_s,
                });
                println!("{row}");
            } else {
                println!(
                    "{:<8} {:>12} {:>12} {:>10.4} {:>10.4} {:>10.4} {:>8}",
                    kind.name(),
                    n_all,
                    bench::fmt_rate(rate),
                    total_s,
                    local_s,
                    total_s - local_s,
                    ties
                );
            }
        }
    }
    Ok(())
}

/// This rank's share of a query set of about `total` points (see [`run_bench`]).
fn bench_points(cluster: &Cluster, part: Option<&Part>, kind: QueryKind, total: usize, seed: u64) -> Vec<Vec3> {
    let size = cluster.size;
    let seed = seed ^ (cluster.rank as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    if kind == QueryKind::Bbox {
        // Uniform in the box of every rank's cells, made by the owner itself.
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        if let Some(p) = part {
            (lo, hi) = (p.mesh.info.bounds_min, p.mesh.info.bounds_max);
        }
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let lo: [f32; 3] = std::array::from_fn(|k| -cluster.max_f64(-(lo[k] as f64)) as f32);
        let hi: [f32; 3] = std::array::from_fn(|k| cluster.max_f64(hi[k] as f64) as f32);
        let n = launch::pieces_of(total, size, cluster.rank).len();
        return (0..n).map(|_| std::array::from_fn(|k| lo[k] + rng.gen::<f32>() * (hi[k] - lo[k]))).collect();
    }
    // Every rank takes part in the same collectives, with cells or without.
    let n_all = cluster.sum_u64(part.map_or(0, |p| p.mesh.n_tets() as u64)).max(1);
    let total_cells = cluster.sum_u64(part.map_or(0, |p| p.mesh.n_cells() as u64)).max(1);
    let Some(p) = part else { return redistribute(cluster, &[], &[]) };
    // This rank's share of the set, made from its own tets.
    let n = (total as u128 * p.mesh.n_tets() as u128 / n_all as u128) as usize;
    let kind = if kind == QueryKind::Host { QueryKind::Random } else { kind };
    let pts = queries::generate(&p.mesh, kind, n, seed);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed ^ 1);
    let owners: Vec<usize> = (0..pts.len())
        .map(|i| match kind {
            QueryKind::Centers => {
                let g = p.global_ids[p.mesh.cell_of_tet(i % p.mesh.n_tets())];
                (g as u128 * size as u128 / total_cells as u128) as usize
            }
            _ => rng.gen_range(0..size),
        })
        .collect();
    redistribute(cluster, &pts, &owners)
}

/// Hands each point to its owner rank (collective); the points this rank owns.
fn redistribute(cluster: &Cluster, pts: &[Vec3], owners: &[usize]) -> Vec<Vec3> {
    let mut order: Vec<usize> = (0..pts.len()).collect();
    order.sort_by_key(|&i| owners[i]);
    let mut counts = vec![0 as Count; cluster.size];
    owners.iter().for_each(|&o| counts[o] += 3);
    let send: Vec<f32> = order.iter().flat_map(|&i| pts[i]).collect();
    let mut recv_counts = vec![0 as Count; cluster.size];
    cluster.world.all_to_all_into(&counts[..], &mut recv_counts[..]);
    let (sd, rd) = (displacements(&counts), displacements(&recv_counts));
    let mut recv = vec![0f32; recv_counts.iter().map(|&c| c as usize).sum()];
    {
        let s = Partition::new(&send[..], &counts[..], &sd[..]);
        let mut r = PartitionMut::new(&mut recv[..], &recv_counts[..], &rd[..]);
        cluster.world.all_to_all_varcount_into(&s, &mut r);
    }
    recv.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}
