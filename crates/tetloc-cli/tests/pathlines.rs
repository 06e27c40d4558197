//! `trace` through a `.pvd` series end to end: pathlines (`--unsteady`) against VTK's
//! vtkParticlePathFilter (through `scripts/vtk_pathlines.py`), on cpu and soft-bvh, their
//! files at every output time (`--time-step all`), streamlines in one step's field; and the
//! bad inputs (a single snapshot, times outside the series, an index over the series).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use tetloc_testdata::{read_f64s, require_data, run_vtk_script};

fn tetloc(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_tetloc")).args(args).output().expect("run tetloc");
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into())
}

fn tmp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tetloc-path-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A folder with `vtk_pathlines.py`'s series (`series.pvd` over `step_K.vtu`) and its seeds
/// (`seeds.bin`); `None` where the test is skipped (no VTK outside CI).
fn series(test: &str) -> Option<PathBuf> {
    series_of(test, "tet")
}

/// [`series`] of `kind` cells: `tet`, or `hex` (hexahedra: trilinear interpolation).
fn series_of(test: &str, kind: &str) -> Option<PathBuf> {
    let dir = tmp_dir(test);
    run_vtk_script(test, "vtk_pathlines.py", &["series", s(&dir), kind])?;
    Some(dir)
}

/// Each pathline point, by (particle, time in 1e-4 units): its position.
fn points_by_time(dir: &Path, who: &str) -> HashMap<(i64, i64), [f64; 3]> {
    by_time(dir, who, "points")
}

/// Each pathline point, by (particle, time in 1e-4 units): its three values in `who.what.bin`.
fn by_time(dir: &Path, who: &str, what: &str) -> HashMap<(i64, i64), [f64; 3]> {
    let pts = read_f64s(&dir.join(format!("{who}.{what}.bin")));
    let ids = read_f64s(&dir.join(format!("{who}.ids.bin")));
    let times = read_f64s(&dir.join(format!("{who}.times.bin")));
    assert_eq!((pts.len(), times.len()), (3 * ids.len(), ids.len()), "{who}");
    ids.iter()
        .zip(&times)
        .enumerate()
        .map(|(i, (&id, &t))| ((id as i64, (t * 1e4).round() as i64), [pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]]))
        .collect()
}

/// The same particles at the same times as vtkParticlePathFilter (RK4, half an interval a
/// step, velocity interpolated linearly in time), within float32 rounding: on cpu (each
/// particle walking from its last tet) and on soft-bvh (one batched lookup per stage).
#[test]
fn pathlines_match_vtk_particle_paths() {
    // 40 particles at 0.4, 0.8, 1.2, 1.6: all stay inside, and all reach 1.6.
    match_vtk("pathlines_match_vtk_particle_paths", &[], &["compare"], 160, (16000, 40));
}

/// The same through hexahedra, whose trilinear interpolation of the swirl differs from the
/// tets' linear one: VTK's paths within float32 rounding.
#[test]
fn pathlines_through_hexahedra_match_vtk_particle_paths() {
    let test = "pathlines_through_hexahedra_match_vtk_particle_paths";
    let Some(dir) = series_of(test, "hex") else { return };
    match_vtk_in(&dir, test, &[], &["compare"], 160, (16000, 40));
}

/// Reinjection against VTK's ForceReinjectionEveryNSteps: every second output time, the
/// seeds injected at 0.4 (4 points each) and 1.2 (2 points each) are particles of their own.
/// (VTK also injects at the end time, 1.6: one point each, which makes no line here; the
/// script leaves those out.)
#[test]
fn reinjected_pathlines_match_vtk_particle_paths() {
    let test = "reinjected_pathlines_match_vtk_particle_paths";
    match_vtk(test, &["--reinject-every", "2"], &["compare", "2"], 40 * (4 + 2), (16000, 2 * 40));
}

/// `--streaklines` against VTK's vtkStreaklineFilter (RK4, half an interval a step): each
/// seed's particles injected at 0.4, 0.8, 1.2 and 1.6 (the seed itself) at 1.6, by age, within
/// float32 rounding, on cpu and soft-bvh.
#[test]
fn streaklines_match_vtk_streak_lines() {
    // Keyed by (particle, age), each side's particle by its own ParticleId, InjectedPointId
    // and InjectionStepId: the oldest particles (age 1.2) are the ones that moved most.
    match_vtk("streaklines_match_vtk_streak_lines", &["--streaklines"], &["streaks"], 40 * 4, (12000, 40));
}

/// `trace --unsteady` from 0.4 to 1.6 with `flags`, on cpu and soft-bvh, against VTK's run by
/// `vtk_pathlines.py OP DIR 0.4 1.6 OURS [N]` (`script`: OP, then N if any): the same `n_points`
/// points by (particle, time), each side's particle named by its own point arrays
/// (ParticleId, InjectedPointId, InjectionStepId), each point within float32 rounding; `moved.1` of them at time key
/// `moved.0`, those that moved (a rotation of about 2 radians: not a comparison of seeds).
fn match_vtk(test: &str, flags: &[&str], script: &[&str], n_points: usize, moved: (i64, usize)) {
    let Some(dir) = series(test) else { return };
    match_vtk_in(&dir, test, flags, script, n_points, moved);
}

/// [`match_vtk`] on the series in `dir`.
fn match_vtk_in(dir: &Path, test: &str, flags: &[&str], script: &[&str], n_points: usize, moved: (i64, usize)) {
    let (pvd, seeds) = (dir.join("series.pvd"), dir.join("seeds.bin"));
    for backend in ["cpu", "soft-bvh"] {
        let out = dir.join(format!("paths-{backend}.vtp"));
        let mut args = vec!["trace", s(&pvd), "--vector", "v", "--seeds", s(&seeds), "--unsteady"];
        args.extend(["--start-time", "0.4", "--end-time", "1.6", "-o", s(&out), "--backend", backend]);
        args.extend(flags);
        let (ok, err) = tetloc(&args);
        assert!(ok, "{backend}: {err}");
        let mut call = vec![script[0], s(dir), "0.4", "1.6", s(&out)];
        call.extend(&script[1..]);
        run_vtk_script(test, "vtk_pathlines.py", &call).unwrap();
        let (vtk, ours) = (points_by_time(dir, "vtk"), points_by_time(dir, "tetloc"));
        assert_eq!(vtk.len(), n_points, "VTK's points");
        assert_eq!(ours.len(), vtk.len(), "{backend}: our points");
        let mut worst: f64 = 0.0;
        for (key, v) in &vtk {
            let o = ours.get(key).unwrap_or_else(|| panic!("{backend}: no point for particle {} at {}", key.0, key.1));
            worst = worst.max((0..3).map(|k| (o[k] - v[k]).abs()).fold(0.0, f64::max));
        }
        // Both in f64 on float32 data: the positions agree to float32 rounding.
        assert!(worst < 1e-5, "{backend}: {worst:e} from VTK's points");
        assert_eq!(vtk.keys().filter(|k| k.1 == moved.0).count(), moved.1, "{backend}: the points that moved");
    }
}

/// `--vorticity` against vtkParticlePathFilter's ComputeVorticity, on cpu and soft-bvh: the
/// vorticity (its x component: VTK 9.7's array holds one) and the angular velocity agree
/// within rounding at nearly every point (elsewhere VTK's cell search took the neighbour of a
/// face the point is near, whose curl differs), and so do the rotation's increments between a
/// particle's points. VTK's Rotation itself starts from an angular velocity of 0 at time 0
/// rather than at the injection, and stays 0 for the particles of ParticleId 0: tetloc's starts
/// at 0 at the injection, as vtkStreamTracer's at the seed, so only the increments compare.
#[test]
fn pathline_vorticity_matches_vtk() {
    let test = "pathline_vorticity_matches_vtk";
    let Some(dir) = series(test) else { return };
    let (pvd, seeds) = (dir.join("series.pvd"), dir.join("seeds.bin"));
    for backend in ["cpu", "soft-bvh"] {
        let out = dir.join(format!("paths-{backend}.vtp"));
        let (ok, err) = tetloc(&[
            "trace",
            s(&pvd),
            "--vector",
            "v",
            "--seeds",
            s(&seeds),
            "--unsteady",
            "--vorticity",
            "--start-time",
            "0.4",
            "--end-time",
            "1.6",
            "-o",
            s(&out),
            "--backend",
            backend,
        ]);
        assert!(ok, "{backend}: {err}");
        run_vtk_script(test, "vtk_pathlines.py", &["compare", s(&dir), "0.4", "1.6", s(&out)]).unwrap();
        let (vtk, ours) = (by_time(&dir, "vtk", "turning"), by_time(&dir, "tetloc", "turning"));
        assert_eq!((vtk.len(), ours.len()), (160, 160), "{backend}");
        let scale = vtk.values().map(|v| v[0].abs().max(v[1].abs())).fold(0.0, f64::max);
        let agree = |key: &(i64, i64)| {
            let (v, o) = (vtk[key], ours[key]);
            (v[0] - o[0]).abs() <= 1e-6 * scale && (v[1] - o[1]).abs() <= 1e-6 * scale
        };
        let same = vtk.keys().filter(|k| agree(k)).count();
        assert!(same >= 150, "{backend}: {same} of 160 points agree with VTK's vorticity");
        let mut increments = 0;
        for (key, v) in &vtk {
            // The point before on the same particle (output times 0.4 apart).
            let before = (key.0, key.1 - 4000);
            let particle_id = key.0 / 100_000_000;
            if particle_id == 0 || !vtk.contains_key(&before) || !agree(key) || !agree(&before) {
                continue;
            }
            let theirs = v[2] - vtk[&before][2];
            let mine = ours[key][2] - ours[&before][2];
            assert!((theirs - mine).abs() <= 1e-6 * scale, "{backend} {key:?}: rotation +{mine}, VTK's +{theirs}");
            increments += 1;
        }
        assert!(increments >= 90, "{backend}: {increments} rotation increments compared");
    }
}

/// `--unsteady` on one snapshot, and start or end times outside the series, are refused
/// with a message naming the file.
#[test]
fn unsteady_bad_inputs_are_refused() {
    const TEST: &str = "unsteady_bad_inputs_are_refused";
    let Some(data) = require_data(TEST) else { return };
    let dir = tmp_dir(TEST);
    let out = dir.join("p.vtp");
    let one = data.join("delaunay_s.vtu");
    let (ok, err) =
        tetloc(&["trace", s(&one), "--vector", "v", "--seeds", "line:0,0,0,1,1,1,3", "--unsteady", "-o", s(&out)]);
    assert!(!ok && err.contains("delaunay_s.vtu") && err.contains("single snapshot"), "{err}");
    let series = data.join("time/part_s.pvd");
    for (flag, value, want) in [
        ("--start-time", "-1", "the start time -1 is outside the time steps of"),
        ("--end-time", "3", "the end time 3 is outside the time steps of"),
    ] {
        let (ok, err) = tetloc(&[
            "trace",
            s(&series),
            "--vector",
            "v",
            "--seeds",
            "line:0,0,0,1,1,1,3",
            "--unsteady",
            &format!("{flag}={value}"), // `=`: a value that starts with '-' is not taken for a flag
            "-o",
            s(&out),
        ]);
        assert!(!ok && err.contains(want) && err.contains("part_s.pvd") && err.contains("(0 to 2.5)"), "{err}");
    }
    let (ok, err) = tetloc(&[
        "trace",
        s(&one),
        "--vector",
        "v",
        "--seeds",
        "line:0,0,0,1,1,1,3",
        "--start-time",
        "1",
        "-o",
        s(&out),
    ]);
    assert!(!ok && err.contains("--unsteady"), "--start-time without --unsteady: {err}");
    assert!(!out.exists());
}

/// `--time-step all`: a file at each output time after the start, each the run that ends
/// there (byte for byte: pathlines with reinjection, and streaklines), on cpu and soft-bvh,
/// and the `.pvd` that indexes them by time. An index that would write over the series, and
/// `--time-step K`, are refused before anything is written.
#[test]
fn every_output_time_is_the_run_that_ends_there() {
    let test = "every_output_time_is_the_run_that_ends_there";
    let Some(dir) = series(test) else { return };
    let (pvd, seeds) = (dir.join("series.pvd"), dir.join("seeds.bin"));
    let series = std::fs::read(&pvd).unwrap();
    let trace = |out: &Path, flags: &[&str]| {
        let mut args = vec!["trace", s(&pvd), "--vector", "v", "--seeds", s(&seeds), "--unsteady", "-q"];
        args.extend(["--start-time", "0.4", "-o", s(out)]);
        args.extend(flags);
        tetloc(&args)
    };
    for backend in ["cpu", "soft-bvh"] {
        for what in [&["--reinject-every", "2"][..], &["--streaklines"]] {
            let out = dir.join(format!("frames-{backend}.vtp"));
            let (ok, err) = trace(&out, &[&["--backend", backend, "--time-step", "all"], what].concat());
            assert!(ok, "{backend} {what:?}: {err}");
            assert!(!out.exists(), "{backend} {what:?}: --out itself is not written");
            // Output times after 0.4: the series' 0.8, 1.2, 1.6 and 2.0.
            let index = std::fs::read_to_string(dir.join(format!("frames-{backend}.pvd"))).unwrap();
            for (k, t) in ["0.8", "1.2", "1.6", "2.0"].iter().enumerate() {
                let frame = dir.join(format!("frames-{backend}_{k}.vtp"));
                let entry = format!("timestep=\"{t}\" group=\"\" part=\"0\" file=\"frames-{backend}_{k}.vtp\"");
                assert!(index.contains(&entry), "{backend} {what:?}: no {entry} in {index}");
                let end = dir.join("end.vtp");
                let (ok, err) = trace(&end, &[&["--backend", backend, "--end-time", t], what].concat());
                assert!(ok, "{backend} {what:?} to {t}: {err}");
                let (a, b) = (std::fs::read(&frame).unwrap(), std::fs::read(&end).unwrap());
                assert!(a == b, "{backend} {what:?}: {} differs from the run that ends at {t}", frame.display());
            }
            assert_eq!(index.matches("<DataSet").count(), 4, "{index}");
        }
    }
    let (ok, err) = trace(&dir.join("series.vtp"), &["--backend", "cpu", "--time-step", "all"]);
    assert!(!ok && err.contains("index") && err.contains("series.pvd"), "{err}");
    assert!(std::fs::read(&pvd).unwrap() == series, "the series was written over");
    assert!(!dir.join("series_0.vtp").exists());
    let (ok, err) = trace(&dir.join("one.vtp"), &["--backend", "cpu", "--time-step", "1"]);
    assert!(!ok && err.contains("--time-step all"), "{err}");
}

/// `--time-step all` on probe: an index (`OUT.pvd`) that is the input series is refused at
/// the first step, before any step's file or the index is written.
#[test]
fn a_time_step_index_never_writes_over_the_series() {
    let test = "a_time_step_index_never_writes_over_the_series";
    let Some(dir) = series(test) else { return };
    let pvd = dir.join("series.pvd");
    let series = std::fs::read(&pvd).unwrap();
    let target = dir.join("step_0.vtu");
    let out = dir.join("series.vtu");
    let (ok, err) = tetloc(&["probe", s(&pvd), s(&target), "--time-step", "all", "-o", s(&out), "--backend", "cpu"]);
    assert!(!ok && err.contains("index") && err.contains("series.pvd") && err.contains("input"), "{err}");
    assert!(std::fs::read(&pvd).unwrap() == series, "the series was written over");
    assert!(!dir.join("series_0.vtu").exists());
    // Another name works: a file a step and the index.
    let out = dir.join("probed.vtu");
    let (ok, err) = tetloc(&["probe", s(&pvd), s(&target), "--time-step", "all", "-o", s(&out), "--backend", "cpu"]);
    assert!(ok, "{err}");
    let index = std::fs::read_to_string(dir.join("probed.pvd")).unwrap();
    assert_eq!(index.matches("<DataSet").count(), 6, "{index}");
}

/// Streamlines in one step of a series: `--time-step K` traces step K's field (the same file
/// as tracing that step's `.vtu` alone), `--time-step all` writes each step's and their index,
/// and no flag traces the first step. `bench`, which measures one snapshot, refuses a step.
#[test]
fn streamlines_in_a_step_trace_that_steps_field() {
    let test = "streamlines_in_a_step_trace_that_steps_field";
    let Some(dir) = series(test) else { return };
    let (pvd, seeds) = (dir.join("series.pvd"), dir.join("seeds.bin"));
    let trace = |mesh: &Path, out: &Path, flags: &[&str]| {
        let mut args = vec!["trace", s(mesh), "--vector", "v", "--seeds", s(&seeds), "-q", "--backend", "cpu"];
        args.extend(["-o", s(out)]);
        args.extend(flags);
        let (ok, err) = tetloc(&args);
        assert!(ok, "{flags:?}: {err}");
        std::fs::read(out).unwrap_or_default()
    };
    let alone: Vec<Vec<u8>> =
        (0..6).map(|k| trace(&dir.join(format!("step_{k}.vtu")), &dir.join("a.vtp"), &[])).collect();
    assert!(alone[0] != alone[4], "the steps' fields differ");
    for k in [0, 4] {
        assert!(trace(&pvd, &dir.join("k.vtp"), &["--time-step", &k.to_string()]) == alone[k], "step {k}");
    }
    assert!(trace(&pvd, &dir.join("first.vtp"), &[]) == alone[0], "no --time-step: the first step");
    trace(&pvd, &dir.join("all.vtp"), &["--time-step", "all"]);
    for (k, want) in alone.iter().enumerate() {
        assert!(std::fs::read(dir.join(format!("all_{k}.vtp"))).unwrap() == *want, "--time-step all, step {k}");
    }
    let index = std::fs::read_to_string(dir.join("all.pvd")).unwrap();
    assert!(index.contains("timestep=\"1.6\" group=\"\" part=\"0\" file=\"all_4.vtp\""), "{index}");
    let (ok, err) = tetloc(&["bench", s(&pvd), "--time-step", "1", "--backend", "cpu"]);
    assert!(!ok && err.contains("--time-step"), "{err}");
}
