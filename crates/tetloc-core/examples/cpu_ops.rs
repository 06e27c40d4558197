//! The CPU paths of resample, probe and trace on one mesh, timed (wall and process CPU
//! seconds), for profiling without Python: `cargo run --release -p tetloc-core --example
//! cpu_ops -- MESH [PROBE_MESH] [DIMS] [SEEDS] [STEPS]`, each mesh a file or `fusion:TETS`
//! (generated with its vector field `v`, as `tetloc gen fusion --vector`; TETS like 1.4M).
//! `OPS` picks the operations (letters of `rpt`, all by default; `s` times a time step's mesh
//! and the built locator taking its fields); `BUILD_PARTS=1` times the
//! face neighbours and the BVH alone; `PROBE_PARTS=N` splits the probe: N times more with its
//! search built (the walks and the values), then N times ids only (the walks alone);
//! `PROBE_FRESH=N` probes N more times with the build included, each on a fresh copy of the mesh;
//! `NO_FIELDS=1` resamples ids only (no field values); `AT_TETS=1` times the GPU trace's line
//! fields (sampled at the kernel's tets) on the CPU's lines. `OPS=l cpu_ops SERIES [SEEDS]`
//! times pathlines (`pathline_run`, RK4 at half an interval, the series' point fields on the
//! lines) through a time series (a `.pvd`), as `bench_time.py --pathlines` runs them.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;
use tetloc_core::ops::{fields, probe, resample, trace, ImageGrid};
use tetloc_core::{BatchLocator, CpuLocator, Vec3};
use tetloc_io as io;

/// User + system seconds of this process (all threads), from /proc/self/stat.
/// The process's CPU seconds (user and system) and its minor page faults, from /proc.
fn cpu_seconds_and_faults() -> (f64, u64) {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map_or("", |(_, s)| s);
    let f: Vec<f64> = after.split_whitespace().map(|x| x.parse().unwrap_or(0.0)).collect();
    // Fields 10, 14 and 15 (minflt, utime, stime) are the 8th, 12th and 13th after the
    // name; 100 ticks a second.
    let field = |i: usize| f.get(i).copied().unwrap_or(0.0);
    ((field(11) + field(12)) / 100.0, field(7) as u64)
}

fn timed<T>(what: &str, f: impl FnOnce() -> T) -> T {
    let (t, (c, faults)) = (Instant::now(), cpu_seconds_and_faults());
    let out = f();
    let (c2, faults2) = cpu_seconds_and_faults();
    eprintln!("{what}: {:.3} s wall, {:.2} s CPU, {} page faults", t.elapsed().as_secs_f64(), c2 - c, faults2 - faults);
    out
}

/// A mesh file, or `fusion:TETS` generated (seed 1 for the first mesh, 2 for the probe's).
fn mesh_of(arg: &str, seed: u64) -> tetloc_core::Result<tetloc_core::Mesh> {
    let Some(tets) = arg.strip_prefix("fusion:") else { return io::read_mesh(Path::new(arg), None) };
    let (digits, scale) = match tets.strip_suffix(['M', 'k']) {
        Some(d) if tets.ends_with('M') => (d, 1e6),
        Some(d) => (d, 1e3),
        None => (tets, 1.0),
    };
    let n = (digits.parse::<f64>().expect("a tet count") * scale) as usize;
    let shape = tetloc_core::gen::Shape::Fusion;
    let mut raw = tetloc_core::gen::generate(shape, n, seed);
    raw.fields.extend(tetloc_core::gen::flow::vector_fields(shape, &raw.points));
    tetloc_core::Mesh::new(raw, arg)
}

/// `n` seeds at the centres of pseudo-random tets (a fixed LCG, as reproducible as the
/// bench's).
fn tet_center_seeds(mesh: &tetloc_core::Mesh, n: usize) -> Vec<Vec3> {
    let mut s = 1u64;
    (0..n)
        .map(|_| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            mesh.tet_center(((s >> 33) as usize) % mesh.tets.len())
        })
        .collect()
}

/// Pathlines through the series at `path` from `n_seeds` seeds at the centres of
/// pseudo-random tets, timed `repeats` times.
fn pathlines(path: &str, n_seeds: usize, repeats: usize) -> tetloc_core::Result<()> {
    let (raw, steps) = io::read_series(Path::new(path), None)?;
    let steps = steps.expect("a time series");
    let mesh = Arc::new(tetloc_core::Mesh::new(raw, path)?);
    let loc = CpuLocator::new(mesh.clone());
    let seeds = tet_center_seeds(&mesh, n_seeds);
    let vector = trace::vector_field(&mesh, "v")?;
    let c = vector.component_refs();
    let out = trace::line_fields(&mesh, &vector);
    let o = trace::PathOptions::default();
    for _ in 0..repeats {
        let job =
            trace::PathJob { seeds: &seeds, options: &o, steps: &steps, vector: [c[0], c[1], c[2]], fields: &out };
        let run = timed("pathlines", || trace::pathline_run(job, &loc, |_| Ok(())))?;
        let lines = timed("  their output", || run.output());
        eprintln!("  {} lines, {} points", lines.ends.len(), lines.points.len());
    }
    Ok(())
}

fn main() -> tetloc_core::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    if std::env::var("OPS").is_ok_and(|o| o == "l") {
        let n: usize = args.get(2).map_or(100_000, |s| s.parse().unwrap());
        let repeats = std::env::var("REPEATS").map_or(3, |s| s.parse().unwrap());
        return pathlines(&args[1], n, repeats);
    }
    let mesh = Arc::new(mesh_of(&args[1], 1)?);
    // WRITE_VTU=PATH: write the mesh (for the Python benchmarks, without the CLI) and stop.
    if let Ok(path) = std::env::var("WRITE_VTU") {
        return io::vtk::write::write_mesh_vtu(Path::new(&path), &mesh, false);
    }
    let dims: usize = args.get(3).map_or(256, |s| s.parse().unwrap());
    let n_seeds: usize = args.get(4).map_or(10_000, |s| s.parse().unwrap());
    let steps: usize = args.get(5).map_or(1000, |s| s.parse().unwrap());
    let only = std::env::var("OPS").unwrap_or_else(|_| "rpt".into());
    eprintln!("{} tets; f64 points: {}", mesh.tets.len(), mesh.points64.is_some());
    if std::env::var("BUILD_PARTS").is_ok() {
        let m = mesh_of(&args[1], 1)?;
        timed("  face neighbours", || m.neighbors().len());
        timed("  BVH", || {
            tetloc_core::bvh::Bvh::build(&m.points, &m.tets, tetloc_core::bvh::BuildPreset::Fast).nodes.len()
        });
    }
    let groups = fields::groups(&mesh);
    if only.contains('r') {
        let (lo, hi) = mesh.file_bounds();
        let grid = ImageGrid::over_bounds(lo, hi, [dims; 3])?;
        let mut valid = 0usize;
        // A locator that builds only if some grid point needs its search (the grid's own
        // path rasterizes the tets).
        let mut loc = CpuLocator::deferred(mesh.clone(), tetloc_core::bvh::BuildPreset::Fast);
        timed(&format!("resample {dims}^3, every field (no build before)"), || {
            let groups: &[_] = if std::env::var("NO_FIELDS").is_ok() { &[] } else { &groups };
            resample::resample(&mut loc, &grid, groups, 1 << 20, |ids, _| {
                valid += ids.iter().filter(|&&i| i >= 0).count();
                Ok(())
            })
        })?;
        eprintln!("  {valid} inside; the search was built: {}", loc.index_built());
    }
    if let (true, Some(p)) = (only.contains('p'), args.get(2)) {
        let target = mesh_of(p, 2)?;
        // As Python's probe: a deferred locator, its batch index built by the probe.
        let mut fresh = CpuLocator::deferred(mesh.clone(), tetloc_core::bvh::BuildPreset::Fast);
        let probed = timed(&format!("probe {} points, build included", target.points.len()), || {
            probe::probe(&mut fresh, &target.points, &groups, |_| Ok(()))
        })?;
        eprintln!("  {} inside; the BVH was built: {}", probed.n_valid(), fresh.index_built());
        // Again on fresh copies of the mesh (made untimed), as the Python benchmark runs it.
        for _ in 0..std::env::var("PROBE_FRESH").ok().and_then(|n| n.parse().ok()).unwrap_or(0) {
            let copy = Arc::new(mesh_of(&args[1], 1)?);
            let mut fresh = CpuLocator::deferred(copy, tetloc_core::bvh::BuildPreset::Fast);
            timed("  again, fresh mesh", || probe::probe(&mut fresh, &target.points, &groups, |_| Ok(())))?;
        }
    }
    let mut loc = timed("locator build", || CpuLocator::new(mesh.clone()));
    if let (true, Some(p)) = (only.contains('p'), args.get(2)) {
        let target = mesh_of(p, 2)?;
        let probed = timed(&format!("probe {} points", target.points.len()), || {
            probe::probe(&mut loc, &target.points, &groups, |_| Ok(()))
        })?;
        eprintln!("  {} inside", probed.n_valid());
        if let Ok(repeats) = std::env::var("PROBE_PARTS") {
            let repeats = repeats.parse().unwrap_or(1);
            for _ in 0..repeats {
                timed("  probe again (bins built)", || probe::probe(&mut loc, &target.points, &groups, |_| Ok(())))?;
            }
            for _ in 0..repeats {
                timed("  ids only", || probe::probe(&mut loc, &target.points, &[], |_| Ok(())))?;
            }
        }
    }
    if only.contains('s') {
        // Another time step (this mesh's fields copied as if read anew): its mesh made from this
        // one's geometry, and the built locator taking its fields, as `view` moves through time.
        let fields = mesh.fields.clone();
        let step = Arc::new(timed("a time step's mesh (Mesh::with_fields)", || mesh.with_fields(fields))?);
        let taken = timed("  the built locator takes its fields", || loc.take_fields(&step));
        assert!(taken, "the same geometry");
    }
    if only.contains('t') {
        let seeds = tet_center_seeds(&mesh, n_seeds);
        let vector = trace::vector_field(&mesh, "v")?;
        let out = trace::line_fields(&mesh, &vector);
        let o = trace::TraceOptions {
            step: 0.1 * mesh.info.mean_edge_length as f64,
            max_steps: steps,
            ..Default::default()
        };
        let xyz = ["v[0]", "v[1]", "v[2]"];
        let arrays = timed("trace (lookups reused for the line fields)", || {
            trace::trace_sampled(&seeds, &o, &loc, xyz, &out, &|_| Ok(()))
        })?;
        eprintln!("  {} lines, {} steps", arrays.ends.len(), arrays.points.len() - arrays.ends.len());
        if std::env::var("AT_TETS").is_ok() {
            // The GPU trace's host side: these lines as its kernel returns them (points with
            // their tets), their fields sampled at those tets.
            let mut start = 0;
            let lines: Vec<trace::Line> = arrays
                .ends
                .iter()
                .map(|&end| {
                    let line = trace::Line {
                        seed: 0,
                        backward: false,
                        points: arrays.points[start..end].iter().map(|p| p.map(f64::from)).collect(),
                        time: arrays.time[start..end].to_vec(),
                        tets: arrays.fields.ids[start..end].to_vec(),
                        values: Vec::new(),
                        reason: trace::Reason::OutOfSteps,
                    };
                    start = end;
                    line
                })
                .collect();
            for _ in 0..3 {
                timed("  line fields at the tets (the GPU path's host side)", || {
                    trace::LineArrays::at_tets(&lines, &mesh, &out)
                })?;
            }
        }
        if std::env::var("OLD_TRACE").is_ok() {
            let field = loc.vector_field(xyz)?;
            let lines = timed("trace (old: integrate)", || trace::trace(&seeds, &o, &field, &|_| Ok(())))?;
            let mut again = tetloc_core::locate::FiniteOnly::new(CpuLocator::new(mesh.clone()));
            timed("  line arrays by probing again", || trace::LineArrays::new(&lines, &mut again, &out))?;
        }
    }
    Ok(())
}
