//! Issue 29, items 1-10: nothing lost (outputs onto an input's pieces, `partition` over its
//! own input or killed mid-way, temporaries after a signal) and nothing unbounded (counts,
//! sizes and steps refused before any work, with a message naming the limit), and a closed
//! stdout ending a command quietly. Each test is its reproduction scaled to CI: small files,
//! limits checked before allocation, the signals sent by the test.

mod common;

use common::{entries, s, tetloc, tmp_dir};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Every file under `dir` (relative path, bytes), sorted: a snapshot to compare.
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<(String, Vec<u8>)>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                out.push((p.strip_prefix(root).unwrap().display().to_string(), std::fs::read(&p).unwrap()));
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    out
}

/// A jets mesh of `cells` cells, `dir/MESH`, partitioned into `parts` pieces listed by
/// `dir/LISTING`, quietly (`-q`: nothing on stderr).
fn gen_and_partition(dir: &Path, mesh: &str, cells: &str, listing: &str, parts: &str) -> (PathBuf, PathBuf) {
    let mesh = dir.join(mesh);
    let (ok, _, err) = tetloc(&["gen", "jets", "--cells", cells, "-o", s(&mesh), "-q"]);
    assert!(ok, "{err}");
    let pvtu = dir.join(listing);
    let (ok, _, err) = tetloc(&["partition", s(&mesh), "--parts", parts, "-o", s(&pvtu), "-q"]);
    assert!(ok && err.is_empty(), "-q: {err}");
    (mesh, pvtu)
}

/// A small mesh partitioned into `m2.pvtu` (pieces `m2/m2_0.vtu`, `m2/m2_1.vtu`), and a
/// points file, in `dir`.
fn partitioned(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let (mesh, pvtu) = gen_and_partition(dir, "m.vtu", "2000", "m2.pvtu", "2");
    let points = dir.join("p.csv");
    std::fs::write(&points, "x,y,z\n0.5,0.5,0.5\n0.2,0.3,0.4\n").unwrap();
    (mesh, pvtu, points)
}

/// Item 1: every file an input reads, its pieces included, counts as an input: `locate` and
/// `probe` onto a piece of a .pvtu, or of a .pvtu inside a .vtm, are refused and the pieces
/// stay as they were.
#[test]
fn an_output_onto_a_piece_of_an_input_is_refused() {
    let dir = tmp_dir("piece");
    let (_, pvtu, points) = partitioned(&dir);
    let vtm = dir.join("m.vtm");
    std::fs::write(
        &vtm,
        r#"<VTKFile type="vtkMultiBlockDataSet" version="1.0"><vtkMultiBlockDataSet>
        <DataSet index="0" file="m2.pvtu"/></vtkMultiBlockDataSet></VTKFile>"#,
    )
    .unwrap();
    let before = snapshot(&dir);
    for (listing, piece) in [(&pvtu, "m2/m2_0.vtu"), (&vtm, "m2/m2_1.vtu")] {
        let out = dir.join(piece);
        let args = ["locate", s(listing), "--points", s(&points), "--field", "f", "--out", s(&out), "--backend", "cpu"];
        let (ok, _, err) = tetloc(&args);
        assert!(!ok && err.contains("same file") && err.contains(piece) && err.contains("MESH"), "{err}");
        let (ok, _, err) = tetloc(&["probe", s(listing), s(&points), "-o", s(&out), "--backend", "cpu"]);
        assert!(!ok && err.contains("same file") && err.contains(piece), "{err}");
        // The listing itself (the .vtm's nested .pvtu too) as a point set output.
    }
    let (ok, _, err) = tetloc(&["probe", s(&vtm), s(&points), "-o", s(&dir.join("m2/m2_0.vtu")), "--backend", "cpu"]);
    assert!(!ok && err.contains("same file"), "{err}");
    assert!(before == snapshot(&dir), "an input changed");
    // Another output is fine.
    let (ok, _, err) = tetloc(&["probe", s(&pvtu), s(&points), "-o", s(&dir.join("probed.vtu")), "--backend", "cpu"]);
    assert!(ok, "{err}");
}

/// Item 2: `partition` refuses an input inside the pieces folder its output replaces: a
/// piece of the old output, or a listing whose pieces lie there.
#[test]
fn partition_never_writes_over_its_input() {
    let dir = tmp_dir("own");
    let (_, pvtu, _) = partitioned(&dir);
    let other = dir.join("other.pvtu");
    std::fs::copy(&pvtu, &other).unwrap(); // lists m2/m2_*.vtu
    let before = snapshot(&dir);
    for (input, parts) in [(dir.join("m2/m2_0.vtu"), "2"), (other.clone(), "3")] {
        let (ok, _, err) = tetloc(&["partition", s(&input), "--parts", parts, "-o", s(&pvtu)]);
        assert!(
            !ok && err.contains("lies in") && err.contains("m2_0.vtu") && err.contains("never writes over"),
            "{err}"
        );
    }
    assert!(before == snapshot(&dir), "an input changed");
}

/// Item 3: a `partition` that fails (a file-size limit standing in for a full disk) keeps
/// the old `OUT.pvtu` and its pieces byte for byte and leaves no temporary; one that
/// succeeds replaces them (the new pieces in the other folder, the old folder removed).
#[test]
fn a_failed_partition_keeps_the_old_output() {
    let dir = tmp_dir("failed");
    let (mesh, _, _) = partitioned(&dir);
    let before = snapshot(&dir);
    let pvtu = dir.join("m2.pvtu");
    // `ulimit -f 8`: writes past 4 KiB fail (EFBIG) once SIGXFSZ is ignored.
    let run = Command::new("sh")
        .args(["-c", "ulimit -f 8; trap '' XFSZ; exec \"$@\"", "sh", env!("CARGO_BIN_EXE_tetloc")])
        .args(["partition", s(&mesh), "--parts", "3", "-o", s(&pvtu)])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success() && err.contains("too large"), "{err}");
    assert!(before == snapshot(&dir), "the old output changed or a temporary stayed: {:?}", entries(&dir));
    let (ok, _, err) = tetloc(&["partition", s(&mesh), "--parts", "3", "-o", s(&pvtu), "-q"]);
    assert!(ok, "{err}");
    assert_eq!(entries(&dir), ["m.vtu", "m2.1", "m2.pvtu", "p.csv"]);
    assert_eq!(entries(&dir.join("m2.1")), ["m2_0.vtu", "m2_1.vtu", "m2_2.vtu"]);
    assert_eq!(tets_of(&pvtu), tets_of(&mesh));
}

/// The number of tets `info` reports for `mesh`, or its error.
fn tets_of(mesh: &Path) -> Result<String, String> {
    let (ok, out, err) = tetloc(&["info", s(mesh)]);
    match ok {
        true => Ok(out.lines().find(|l| l.trim_start().starts_with("tets")).unwrap_or_default().to_string()),
        false => Err(err),
    }
}

/// Item 3 and the property test of issue 29: `partition` killed (SIGKILL) at any moment
/// leaves an output that reads whole, the old one or the new one, never a mix or none;
/// SIGTERM also removes its temporaries, and a later run names what SIGKILL left.
#[test]
fn a_killed_partition_keeps_a_whole_output() {
    let dir = tmp_dir("killed");
    let (mesh, pvtu) = gen_and_partition(&dir, "big.vtu", "150k", "out.pvtu", "4");
    let whole = tets_of(&pvtu).unwrap();
    let t0 = Instant::now();
    let (ok, _, _) = tetloc(&["partition", s(&mesh), "--parts", "6", "-o", s(&pvtu), "-q"]);
    let full = t0.elapsed();
    assert!(ok);
    for k in 0..8 {
        let mut child = Command::new(env!("CARGO_BIN_EXE_tetloc"))
            .args(["partition", s(&mesh), "--parts", &(3 + k % 4).to_string(), "-o", s(&pvtu), "-q"])
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(full.mul_f64(k as f64 / 8.0));
        let _ = child.kill();
        let _ = child.wait();
        assert_eq!(tets_of(&pvtu), Ok(whole.clone()), "killed after {k}/8 of a run");
    }
    // SIGTERM once the pieces are being written: no temporary stays.
    for leftover in entries(&dir).iter().filter(|n| n.starts_with(".out.pvtu.")) {
        let _ = std::fs::remove_dir_all(dir.join(leftover));
        let _ = std::fs::remove_file(dir.join(leftover));
    }
    // A run can end between the temporary's appearance and the signal (a fast machine): then
    // it exits 0, and the signal is sent again to a new run. Every run, signalled in time or not,
    // leaves no temporary and a whole output.
    let mut terminated = false;
    for _ in 0..5 {
        let mut child = Command::new(env!("CARGO_BIN_EXE_tetloc"))
            .args(["partition", s(&mesh), "--parts", "5", "-o", s(&pvtu), "-q"])
            .spawn()
            .unwrap();
        let seen = wait_for(&dir, ".out.pvtu.", Duration::from_secs(60));
        signal(&child, "TERM");
        let status = child.wait().unwrap();
        assert!(!entries(&dir).iter().any(|n| n.ends_with(".tmp")), "{:?}", entries(&dir));
        assert_eq!(tets_of(&pvtu), Ok(whole.clone()));
        match status.code() {
            Some(143) if seen => {
                terminated = true;
                break;
            }
            Some(0) => continue,
            _ => panic!("partition under SIGTERM: {status:?} (a temporary seen: {seen})"),
        }
    }
    assert!(terminated, "SIGTERM never reached a run while it wrote its pieces");
    // Whatever SIGKILL left is named by the next run, which still succeeds.
    std::fs::create_dir_all(dir.join(".out.pvtu.leftover.tmp")).unwrap();
    let (ok, _, err) = tetloc(&["partition", s(&mesh), "--parts", "2", "-o", s(&pvtu)]);
    assert!(ok && err.contains(".out.pvtu.leftover.tmp") && err.contains("interrupted"), "{err}");
    assert_eq!(tets_of(&pvtu), Ok(whole));
}

/// Waits until a file whose name starts with `prefix` appears in `dir`; false on timeout.
fn wait_for(dir: &Path, prefix: &str, timeout: Duration) -> bool {
    let t0 = Instant::now();
    while t0.elapsed() < timeout {
        if entries(dir).iter().any(|n| n.starts_with(prefix)) {
            return true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    false
}

fn signal(child: &std::process::Child, name: &str) {
    let ok = Command::new("kill").args([&format!("-{name}"), &child.id().to_string()]).status().unwrap();
    assert!(ok.success());
}

/// Item 4: SIGINT and SIGTERM remove the temporary of the output being written and end with
/// 130 and 143, SIGABRT removes it and ends as an abort; the old output stays. A leftover of
/// an earlier run is named.
#[test]
fn signals_remove_temporaries() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tmp_dir("signals");
    let out = dir.join("r.npy");
    for (sig, code) in [("INT", Some(130)), ("TERM", Some(143)), ("ABRT", None)] {
        std::fs::write(&out, "previous").unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_tetloc"))
            .args(["resample", "jets:5000", "--field", "f", "--dims", "400,400,400", "-o", s(&out), "--backend", "cpu"])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        assert!(wait_for(&dir, ".r.npy.", Duration::from_secs(120)), "no temporary appeared: {:?}", entries(&dir));
        signal(&child, sig);
        let status = child.wait().unwrap();
        assert_eq!(status.code(), code, "SIG{sig}");
        if code.is_none() {
            assert_eq!(status.signal(), Some(6), "SIG{sig}: not ended by the signal");
        }
        assert_eq!(entries(&dir), ["r.npy"], "SIG{sig}: a temporary stayed");
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "previous");
    }
    std::fs::write(dir.join(".r.npy.Ab12Cd.tmp"), "half an image").unwrap();
    let (ok, _, err) = tetloc(&["resample", "jets:2000", "--field", "f", "--dims", "4,4,4", "-o", s(&out), "-q"]);
    assert!(ok && err.contains(".r.npy.Ab12Cd.tmp") && err.contains("--out"), "{err}");
}

/// A run that fails fast: not ok, within `secs`, its stderr.
fn refused(args: &[&str], secs: u64) -> String {
    let t0 = Instant::now();
    let (ok, out, err) = tetloc(args);
    assert!(!ok, "{args:?} succeeded: {out}");
    assert!(t0.elapsed() < Duration::from_secs(secs), "{args:?} took {:?}", t0.elapsed());
    assert!(!err.contains("panicked") && !err.contains("memory allocation"), "{err}");
    err
}

/// Item 5: `bench --n` and `demo --points` beyond memory are refused before the mesh is
/// read or generated.
#[test]
fn query_counts_beyond_memory_are_refused() {
    let e = refused(&["bench", "jets:2000", "--n", "100000000000000", "--backend", "cpu"], 20);
    assert!(e.contains("--n 100000000000000") && e.contains("GB of memory"), "{e}");
    let e = refused(&["demo", "--points", "100000000000000"], 20);
    assert!(e.contains("--points") && e.contains("GB of memory"), "{e}");
}

/// Item 6: images larger than the disk, or than the format allows, are refused before any
/// work (the mesh is not even generated); an image that fits is written.
#[test]
fn resample_sizes_are_checked_before_any_work() {
    let dir = tmp_dir("resample");
    let npy = dir.join("r.npy");
    let args = ["resample", "jets:2000", "--field", "f", "-o"];
    let e = refused(&[&args[..], &[s(&npy), "--dims", "100000,100000,100000"]].concat(), 20);
    assert!(e.contains("1000000000000000 points") && e.contains("free"), "{e}");
    let e = refused(&[&args[..], &[s(&dir.join("r.vti")), "--dims", "4294967296,1,1"]].concat(), 20);
    assert!(e.contains(".vti holds at most 2147483647 points per axis"), "{e}");
    let e = refused(&[&args[..], &[s(&npy), "--dims", "18446744073709551615,2,1"]].concat(), 20);
    assert!(e.contains("more points than this machine can count"), "{e}");
    assert!(entries(&dir).is_empty());
    let (ok, _, err) = tetloc(&[&args[..], &[s(&npy), "--dims", "5,4,3", "--backend", "cpu"]].concat());
    assert!(ok, "{err}");
}

/// Items 7 and 8: a seed grid beyond memory (or SeedIds) and a step count whose line cannot
/// fit are refused before any line is traced.
#[test]
fn trace_seed_and_step_counts_are_bounded() {
    let dir = tmp_dir("trace");
    let out = dir.join("t.vtp");
    let args = ["trace", "jets:2000", "--vector", "v", "-o", s(&out), "--backend", "cpu"];
    let e = refused(&[&args[..], &["--seeds", "grid:0,1,0,1,0,2,100000,100000,100000"]].concat(), 20);
    assert!(e.contains("1000000000000000 seeds") && e.contains("at most"), "{e}");
    let steps = ["--seeds", "line:0.2,0.5,0.5,0.8,0.5,0.5,10", "--terminal-speed", "0", "--max-steps"];
    let e = refused(&[&args[..], &steps[..], &["100000000000000"]].concat(), 20);
    assert!(e.contains("--max-steps 100000000000000") && e.contains("GB of memory"), "{e}");
    let (ok, _, err) = tetloc(&[&args[..], &steps[..], &["300"]].concat());
    assert!(ok && out.exists(), "{err}");
}

/// Item 9: a step so small that a ray takes more samples than the cap, and an orbit of more
/// frames than the cap, are refused with the limit named, at once.
#[test]
fn render_samples_and_frames_are_capped() {
    let dir = tmp_dir("render");
    let args = ["render", "jets:2000", "--field", "f", "--backend", "cpu", "--size", "64x64"];
    let e = refused(&[&args[..], &["--step", "1e-9", "-o", s(&dir.join("r.png"))]].concat(), 20);
    assert!(e.contains("--step") && e.contains("samples") && e.contains("or more"), "{e}");
    let e = refused(&[&args[..], &["--frames", "1000000000", "-o", s(&dir.join("r.gif"))]].concat(), 5);
    assert!(e.contains("--frames 1000000000") && e.contains("at most 10000 frames"), "{e}");
    let e = refused(&[&args[..], &["--frames", "1000000000", "-o", s(&dir.join("r.png"))]].concat(), 5);
    assert!(e.contains("at most 10000 frames"), "{e}");
    assert!(entries(&dir).is_empty());
}

/// A pipe whose reading end is already closed: its writing end.
fn closed_pipe() -> std::fs::File {
    use std::os::fd::FromRawFd;
    let mut fds = [0; 2];
    // SAFETY: `fds` has room for the two descriptors pipe() returns.
    assert_eq!(unsafe { libc::pipe(fds.as_mut_ptr()) }, 0);
    // SAFETY: fds[0] is the reading end pipe() just opened, closed once here.
    unsafe { libc::close(fds[0]) };
    // SAFETY: fds[1] is the writing end, owned from now on by this File alone.
    unsafe { std::fs::File::from_raw_fd(fds[1]) }
}

/// Runs tetloc with its stdout a pipe whose reading end is already closed.
fn with_closed_stdout(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tetloc")).args(args).stdout(closed_pipe()).output().unwrap()
}

/// A closed stderr (`tetloc ... 2>&1 | true`) loses the messages, not the run: the output is
/// written and the exit code is the run's (std's `eprintln!` panicked, exit 101, no output);
/// a stdout that cannot be written for another reason (a full disk) is an error, not a panic.
#[test]
fn a_closed_stderr_loses_the_messages_not_the_run() {
    let dir = tmp_dir("closed-stderr");
    let (pts, out) = (dir.join("p.csv"), dir.join("ids.csv"));
    std::fs::write(&pts, "0.5,0.5,0.5\n0.2,0.3,0.4\n").unwrap();
    let run = |args: &[&str]| {
        let mut child = Command::new(env!("CARGO_BIN_EXE_tetloc"))
            .args(args)
            .stdout(Stdio::null())
            .stderr(closed_pipe())
            .spawn()
            .unwrap();
        child.wait().unwrap().code()
    };
    let locate = ["locate", "jets:2000", "--points", s(&pts), "--out", s(&out), "--backend", "cpu"];
    assert_eq!(run(&locate), Some(0));
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 3, "a header and two rows");
    // An error still exits 1, its message lost.
    assert_eq!(run(&["locate", s(&dir.join("missing.vtu")), "--points", s(&pts), "--out", s(&out)]), Some(1));
    if Path::new("/dev/full").exists() {
        let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
        let o = Command::new(env!("CARGO_BIN_EXE_tetloc")).args(["info", "jets:2000"]).stdout(full).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.starts_with("error: failed printing to stdout") && !err.contains("panicked"), "{err}");
        assert_eq!(o.status.code(), Some(1), "{err}");
    }
}

/// Item 10: `tetloc info x.vtu | head -1` and other printing commands end quietly, exit 0,
/// when stdout is closed: no panic message.
#[test]
fn a_closed_stdout_ends_quietly() {
    let bench = ["bench", "jets:2000", "--backend", "cpu", "--queries", "centers", "--repeats", "1", "--json", "-q"];
    for args in [&["info", "jets:2000"][..], &["info", "jets:2000", "--json"], &bench] {
        let o = with_closed_stdout(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!err.contains("panicked") && !err.contains("Broken pipe"), "{args:?}: {err}");
        assert_eq!(o.status.code(), Some(0), "{args:?}: {err}");
    }
}

/// Issue 30, item 9: `gen blob` names every mesh `gen` makes, the mixed ones too.
#[test]
fn gen_names_every_shape() {
    let dir = tmp_dir("gen");
    let (ok, _, err) = tetloc(&["gen", "blob", "-o", s(&dir.join("b.vtu"))]);
    assert!(!ok, "{err}");
    for name in ["jets", "fusion-hex", "agulhas-wedge", "japan-hybrid"] {
        assert!(err.contains(name), "{name}: {err}");
    }
    // `--tets` is still taken, `--cells` is its name, and -q silences the summary.
    let (ok, _, err) = tetloc(&["gen", "jets", "--tets", "500", "-o", s(&dir.join("a.vtu")), "-q"]);
    assert!(ok && err.is_empty(), "{err}");
}

/// `--time-step all`: a step that fails (here the series' last file, cut short) leaves the
/// previous run's files and index byte for byte, and no temporary: the steps' files and the
/// `.pvd` appear together once every step is written. So for `probe`'s files and for
/// `render`'s images; the error names the file and says nothing was written.
#[test]
fn a_failed_time_step_keeps_the_previous_steps() {
    let dir = tmp_dir("failed_step");
    let series = |name: &str, files: [&str; 3]| {
        let lines: String =
            files.iter().enumerate().map(|(k, f)| format!("<DataSet timestep=\"{k}\" file=\"{f}\"/>")).collect();
        let text = format!("<?xml version=\"1.0\"?><VTKFile type=\"Collection\" version=\"0.1\"><Collection>{lines}</Collection></VTKFile>");
        std::fs::write(dir.join(name), text).unwrap();
        dir.join(name)
    };
    for (name, seed) in [("a.vtu", "1"), ("b.vtu", "2")] {
        let (ok, _, err) = tetloc(&["gen", "fusion", "--tets", "3000", "--seed", seed, "-o", s(&dir.join(name)), "-q"]);
        assert!(ok, "{err}");
    }
    let b = std::fs::read(dir.join("b.vtu")).unwrap();
    std::fs::write(dir.join("cut.vtu"), &b[..b.len() / 2]).unwrap();
    let (good, bad) =
        (series("good.pvd", ["a.vtu", "a.vtu", "a.vtu"]), series("bad.pvd", ["b.vtu", "b.vtu", "cut.vtu"]));
    let target = dir.join("a.vtu");
    let (probe, render) = (dir.join("p.vtu"), dir.join("f.png"));
    // `probe` or `render` of the series, every step.
    let run = |command: &str, pvd: &Path| {
        let mut args = vec![command, s(pvd), "--time-step", "all", "--backend", "cpu", "-q"];
        match command {
            "probe" => args.extend([s(&target), "-o", s(&probe)]),
            _ => args.extend(["--field", "f", "--size", "16x16", "-o", s(&render)]),
        }
        tetloc(&args)
    };
    for command in ["probe", "render"] {
        let (ok, _, err) = run(command, &good);
        assert!(ok, "{err}");
    }
    let before = snapshot(&dir);
    assert!(["p.pvd", "p_0.vtu", "p_2.vtu", "f_0.png", "f_2.png"].iter().all(|f| before.iter().any(|(n, _)| n == f)));
    for command in ["probe", "render"] {
        let (ok, _, err) = run(command, &bad);
        assert!(
            !ok && err.contains("cut.vtu")
                && err.contains("time step 2")
                && err.contains("no step's output was written"),
            "{err}"
        );
        assert!(
            before == snapshot(&dir),
            "a failed step changed the previous files or left a temporary: {:?}",
            entries(&dir)
        );
    }
    // A series that succeeds replaces them all.
    let (ok, _, err) = run("probe", &series("new.pvd", ["b.vtu", "b.vtu", "b.vtu"]));
    assert!(ok, "{err}");
    let after = snapshot(&dir);
    let file = |snap: &[(String, Vec<u8>)], name: &str| snap.iter().find(|(n, _)| n == name).map(|(_, b)| b.clone());
    assert!(file(&after, "p_2.vtu") != file(&before, "p_2.vtu") && file(&after, "p.pvd").is_some());
}

/// `--time-step all` checks each command's arguments and outputs before it reads the series,
/// as a single step's run does: a wrong `--out` is refused at once, by name, here on a series
/// whose first file cannot be read (the error was that file's, or came after reading it).
#[test]
fn time_step_all_checks_the_output_before_the_series() {
    let dir = tmp_dir("step_out_first");
    let (ok, _, err) = tetloc(&["gen", "fusion", "--tets", "3000", "-o", s(&dir.join("a.vtu")), "-q"]);
    assert!(ok, "{err}");
    let a = std::fs::read(dir.join("a.vtu")).unwrap();
    std::fs::write(dir.join("cut.vtu"), &a[..a.len() / 2]).unwrap();
    let lines: String = (0..2).map(|k| format!("<DataSet timestep=\"{k}\" file=\"cut.vtu\"/>")).collect();
    let pvd = dir.join("s.pvd");
    std::fs::write(&pvd, format!("<VTKFile type=\"Collection\"><Collection>{lines}</Collection></VTKFile>")).unwrap();
    let (out, target) = (dir.join("o.bad"), dir.join("a.vtu"));
    let (pvd, out, target) = (s(&pvd), s(&out), s(&target));
    let before = entries(&dir);
    for command in [
        vec!["locate", pvd, "--points", "p.csv", "--out", out],
        vec!["resample", pvd, "--dims", "4,4,4", "-o", out],
        vec!["probe", pvd, target, "-o", out],
        vec!["trace", pvd, "--vector", "v", "--seeds", "line:0,0,0,1,1,1,3", "-o", out],
    ] {
        let args: Vec<&str> = command.iter().copied().chain(["--time-step", "all", "--backend", "cpu"]).collect();
        let (ok, _, err) = tetloc(&args);
        assert!(!ok && err.contains("--out") && err.contains("o.bad") && !err.contains("cut.vtu"), "{args:?}: {err}");
        assert_eq!(entries(&dir), before, "{args:?}");
    }
}

/// An orbit's numbered PNGs appear together: a run interrupted over an older orbit leaves
/// the older frames as they were, not a mix of both runs' frames (nor any temporary).
#[test]
fn an_interrupted_orbit_keeps_the_older_frames() {
    let dir = tmp_dir("orbit");
    let out = dir.join("g.png");
    let args = |frames: &'static str| {
        [
            "render",
            "jets:2000",
            "--field",
            "f",
            "--backend",
            "cpu",
            "--size",
            "32x32",
            "--frames",
            frames,
            "-o",
            s(&out),
        ]
        .map(String::from)
    };
    let (ok, _, err) = tetloc(&args("4").iter().map(String::as_str).collect::<Vec<_>>());
    assert!(ok, "{err}");
    let before = snapshot(&dir);
    assert_eq!(before.len(), 4);
    let mut child = Command::new(env!("CARGO_BIN_EXE_tetloc")).args(args("300")).stderr(Stdio::null()).spawn().unwrap();
    assert!(wait_for(&dir, ".g_0003.png.", Duration::from_secs(120)), "no fourth frame: {:?}", entries(&dir));
    signal(&child, "INT");
    assert_eq!(child.wait().unwrap().code(), Some(130));
    assert_eq!(snapshot(&dir), before, "the older orbit's frames changed");
}

/// Runs `tetloc ARGS`, killed after `secs` (a blocked open would otherwise hang the test):
/// its failure's stderr; a panic if it succeeded, hung, or panicked.
fn refused_within(args: &[&str], secs: u64) -> String {
    use std::io::Read;
    let mut child = Command::new(env!("CARGO_BIN_EXE_tetloc"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if t0.elapsed() > Duration::from_secs(secs) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{args:?} still ran after {secs} s");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    assert!(!status.success(), "{args:?} succeeded");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// A FIFO given as any input the CLI reads by name (the mesh, a series, points, seeds, a
/// probe's target, a view state, a preset, a surface) is refused before it is opened, with
/// the file named, instead of blocking for ever on the open.
#[test]
fn a_fifo_input_is_refused_not_opened() {
    let dir = tmp_dir("fifo");
    let fifo = |name: &str| {
        let p = dir.join(name);
        let made = Command::new("mkfifo").arg(&p).status();
        assert!(made.is_ok_and(|s| s.success()), "mkfifo");
        p
    };
    let (mesh, points, seeds, state) = (fifo("p.vtu"), fifo("p.csv"), fifo("s.npy"), fifo("view.json"));
    let (series, tf, surface) = (fifo("s.pvd"), fifo("tf.json"), fifo("ground.obj"));
    let out = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let (ids, vtu, vtp, png) = (out("ids.npy"), out("o.vtu"), out("t.vtp"), out("r.png"));
    let cpu = ["--backend", "cpu"];
    let cases: Vec<(Vec<&str>, &Path)> = vec![
        (vec!["info", s(&mesh)], &mesh),
        (vec!["locate", s(&mesh), "--points", "x.csv", "--out", &ids], &mesh),
        (vec!["locate", "jets:1000", "--points", s(&points), "--out", &ids, cpu[0], cpu[1]], &points),
        (vec!["locate", s(&series), "--points", "x.csv", "--out", &ids, "--time-step", "all"], &series),
        (vec!["probe", "jets:1000", s(&points), "-o", &vtu, cpu[0], cpu[1]], &points),
        (vec!["trace", "jets:1000", "--vector", "v", "--seeds", s(&seeds), "-o", &vtp, cpu[0], cpu[1]], &seeds),
        (
            vec!["trace", s(&series), "--vector", "v", "--seeds", "line:0,0,0,1,1,1,3", "--unsteady", "-o", &vtp],
            &series,
        ),
        (vec!["render", "jets:1000", "--state", s(&state), "-o", &png], &state),
        (vec!["render", "jets:1000", "--field", "f", "--tf", s(&tf), "-o", &png], &tf),
        (vec!["render", "jets:1000", "--field", "f", "--surface", s(&surface), "-o", &png], &surface),
    ];
    for (args, input) in cases {
        let err = refused_within(&args, 20);
        assert!(err.contains(s(input)) && err.contains("not a regular file"), "{args:?}: {err}");
    }
    assert!(!dir.join("ids.npy").exists() && !dir.join("r.png").exists());
}

/// Item 2 of the CLI defects: a seed grid within SeedIds whose trace cannot fit is refused at
/// once, counting what the trace holds for each seed (its point, its lines' ends, the lines
/// of a batch and their state), before the seeds are made or the mesh read; a small one runs.
#[test]
fn trace_memory_counts_what_each_seed_takes() {
    let dir = tmp_dir("trace-memory");
    let out = dir.join("t.vtp");
    let args = ["trace", "jets:2000", "--vector", "v", "-o", s(&out), "--backend", "cpu", "--step", "0.01"];
    // 2e9 seeds (under the 2^31 SeedIds), all lines in one batch (the hidden test hook).
    let one_batch = ["--max-steps", "1", "--batch-points", "1000000000000000"];
    let grid = ["--seeds", "grid:0,1,0,1,0,1,1000,1000,2000"];
    let e = refused(&[&args[..], &grid, &one_batch].concat(), 10);
    assert!(e.contains("2000000000 lines") && e.contains("GB of memory"), "{e}");
    assert!(entries(&dir).is_empty());
    let small = ["--seeds", "grid:0.2,0.8,0.2,0.8,0.2,0.8,3,3,3"];
    let (ok, _, err) = tetloc(&[&args[..], &small, &one_batch].concat());
    assert!(ok && out.exists(), "{err}");
}

/// `-q` prints nothing on success, `--time-step all` included (it said "wrote N steps" where
/// the outputs have no .pvd index).
#[test]
fn quiet_time_step_all_prints_nothing() {
    let dir = tmp_dir("quiet-steps");
    let series = dir.join("s.msh");
    common::gmsh_series(&series, &[0.0, 0.5, 1.0]);
    let points = dir.join("p.csv");
    std::fs::write(&points, "x,y,z\n0.5,0.5,0.5\n0.2,0.3,0.4\n").unwrap();
    let o = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let all = ["--time-step", "all", "--backend", "cpu", "-q"];
    for args in [
        vec!["locate", s(&series), "--points", s(&points), "--out", &o("ids.npy")],
        vec!["locate", s(&series), "--points", s(&points), "--out", &o("ids.csv")],
        vec!["resample", s(&series), "--field", "f", "--dims", "3,3,3", "-o", &o("r.npy")],
        vec!["probe", s(&series), s(&points), "-o", &o("p.vtu")],
    ] {
        let (ok, out, err) = tetloc(&[&args[..], &all].concat());
        assert!(ok && out.is_empty() && err.is_empty(), "{args:?}: {out}{err}");
    }
    assert!(dir.join("r_2.npy").exists() && dir.join("ids_2.csv").exists() && dir.join("p.pvd").exists());
}

/// Camera numbers beyond what the camera's f32 arithmetic takes (`--camera`, a view state's
/// camera) are refused naming the option or file and the value, not as "eye equals target"
/// or "9 numbers expected"; nothing is read or written first.
#[test]
fn huge_camera_numbers_are_named() {
    let dir = tmp_dir("camera");
    let png = dir.join("r.png");
    let args = ["render", "jets:1000", "--field", "f", "--backend", "cpu", "--size", "8x8", "-o", s(&png)];
    for (camera, named) in [("0,0,1e300,0,0,0,0,1,0", "ez = 1e300"), ("0,0,5,0,0,0,0,inf,0", "uy = inf")] {
        let e = refused(&[&args[..], &[&format!("--camera={camera}")]].concat(), 10);
        assert!(e.contains("--camera") && e.contains(named) && e.contains("finite"), "{e}");
    }
    let state = dir.join("view.json");
    let write = |eye: &str| {
        let text = format!(
            r#"{{"version":1,"field":"f","size":[8,8],"camera":{{"eye":[{eye}],"target":[0,0,0],"up":[0,1,0],"zoom":1}},"tf":{{"colormap":"viridis","opacity":[[0,0,0.5,0],[1,1,0.5,0]],"scale":1}},"background":[0,0,0]}}"#
        );
        std::fs::write(&state, text).unwrap();
    };
    for (eye, named) in [("0,0,1e30", "camera.eye[2] = 1e30"), ("1e300,0,0", "camera.eye[0] = 1e300")] {
        write(eye);
        let e = refused(&["render", "jets:1000", "--backend", "cpu", "--state", s(&state), "-o", s(&png)], 10);
        assert!(e.contains("--state") && e.contains(s(&state)) && e.contains(named), "{e}");
    }
    // A usable state still renders.
    write("0,0,5");
    let (ok, _, err) = tetloc(&["render", "jets:1000", "--backend", "cpu", "--state", s(&state), "-o", s(&png), "-q"]);
    assert!(ok && png.exists(), "{err}");
}

/// A process limit below the machine's free memory (`ulimit -v`, as batch systems set;
/// a cgroup's limit is read the same way, `tetloc_core::memory`) is what a memory check
/// compares with: a mesh too large for it is refused with the sizes named. The check
/// compared with the machine's free memory alone, so the generator started and aborted
/// ("memory allocation of ... failed").
#[cfg(target_os = "linux")]
#[test]
fn a_process_memory_limit_is_a_clear_error_not_an_abort() {
    let dir = tmp_dir("ulimit");
    let out = dir.join("big.vtu");
    let t0 = Instant::now();
    let run = Command::new("sh")
        .args(["-c", r#"ulimit -v 1500000 && exec "$@""#, "sh", env!("CARGO_BIN_EXE_tetloc")])
        .args(["gen", "fusion", "--tets", "100M", "-o", s(&out)])
        .output()
        .expect("run sh");
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success() && t0.elapsed() < Duration::from_secs(20), "{err}");
    assert!(err.contains("fusion:100000000") && err.contains("GB of memory"), "{err}");
    assert!(!err.contains("memory allocation") && !err.contains("panicked"), "{err}");
    assert!(entries(&dir).is_empty(), "{:?}", entries(&dir));
}
