//! The `tetloc` binary end to end: exit codes, messages, files written (CPU backend, so
//! these run anywhere; the GPU backends are tested in tetloc-vulkan).

mod common;

use common::{entries, read, s, tetloc, tetloc_cpu, tmp, tmp_dir, vulkan_devices};
use std::path::{Path, PathBuf};
use std::process::Command;
use tetloc_testdata::{query_sets, read_f64s, require_data, run_vtk_script, QuerySet};

#[test]
fn info_reports_counts_reorientation_and_fields() {
    let Some(dir) = require_data("info_reports_counts_reorientation_and_fields") else { return };
    let (ok, out, err) = tetloc(&["info", dir.join("delaunay_s.vtu").to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(out.contains("tets        25575"), "{out}");
    assert!(out.contains("reoriented  12713"), "{out}");
    assert!(out.contains("'f' per Vertex") && out.contains("'cellval' per Cell"), "{out}");
    let (ok, out, _) = tetloc(&["info", "--json", dir.join("real/P3.msh").to_str().unwrap()]);
    assert!(ok);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["mesh"]["n_tets"], 6414);
    assert_eq!(v["mesh"]["higher_order"], 3);
}

/// `tetloc locate MESH --points POINTS --out OUT --backend cpu`, then `more` arguments; it must
/// succeed.
fn locate_cpu(mesh: &Path, points: &Path, out: &Path, more: &[&str]) {
    let mut args = vec!["locate", s(mesh), "--points", s(points), "--out", s(out)];
    args.extend(more);
    let (ok, _, err) = tetloc_cpu(&args);
    assert!(ok, "{err}");
}

/// How many of the ids in `ids` (one a point of `set`) differ from the oracle's, its
/// ambiguous points aside.
fn wrong_ids(ids: &Path, set: &QuerySet) -> usize {
    let got: Vec<i32> = read(ids);
    assert_eq!(got.len(), set.cell.len());
    (0..got.len()).filter(|&i| got[i] != set.cell[i] && !set.ambiguous(i)).count()
}

#[test]
fn locate_writes_the_oracle_answers() {
    let Some(dir) = require_data("locate_writes_the_oracle_answers") else { return };
    let set = query_sets(&dir).into_iter().find(|s| s.label == "torus_s.random").unwrap();
    let points = dir.join("torus_s.random.points.bin");
    let (ids, vals) = (tmp("ids.bin"), tmp("vals.npy"));
    locate_cpu(&dir.join("torus_s.msh"), &points, &ids, &["--field", "f", "--values", s(&vals)]);
    assert_eq!(wrong_ids(&ids, &set), 0);
    assert!(std::fs::metadata(&vals).unwrap().len() > 4 * set.cell.len() as u64);
    // A ParaView point set with ids and values.
    let vtu = tmp("pts.vtu");
    locate_cpu(&dir.join("torus_s.vtu"), &points, &vtu, &["--field", "f"]);
    let text = std::fs::read(&vtu).unwrap();
    assert!(String::from_utf8_lossy(&text[..2000.min(text.len())]).contains("tet_id"));
}

/// A mesh in UTM-like coordinates with float64 query points (`utm/`): `info` reports the
/// file's bounds and the centred frame, and `locate` answers at the points' f64 precision.
#[test]
fn locate_keeps_float64_points_far_from_the_origin() {
    let Some(dir) = require_data("locate_keeps_float64_points_far_from_the_origin") else { return };
    let set = tetloc_testdata::utm_sets(&dir).into_iter().find(|s| s.label.ends_with(".random")).unwrap();
    let mesh = dir.join("utm/part_utm.vtu");
    let (ok, out, err) = tetloc(&["info", mesh.to_str().unwrap()]);
    assert!(ok && out.contains("frame       origin") && out.contains("512"), "{out}{err}");
    let ids = tmp("utm-ids.bin");
    locate_cpu(&mesh, &dir.join("utm/part_utm.random.points.npy"), &ids, &[]);
    assert_eq!(wrong_ids(&ids, &set), 0, "ids differ from the oracle");
}

#[test]
fn bad_input_is_a_clear_error_and_a_nonzero_exit() {
    let (ok, _, err) = tetloc(&["info", "/nonexistent/mesh.vtu"]);
    assert!(!ok && err.contains("/nonexistent/mesh.vtu"), "{err}");
    let junk = tmp("junk.xyz");
    std::fs::write(&junk, "x").unwrap();
    let (ok, _, err) = tetloc(&["info", junk.to_str().unwrap()]);
    assert!(!ok && err.contains("unknown file format"), "{err}");
    let truncated = tmp("cut.vtu");
    std::fs::write(&truncated, "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece NumberOfPoints=\"4\"")
        .unwrap();
    let (ok, _, err) = tetloc(&["info", truncated.to_str().unwrap()]);
    assert!(!ok && err.contains("cut.vtu"), "{err}");
    let (ok, _, err) = tetloc_cpu(&["locate", "jets:1000", "--points", "/nonexistent/p.bin", "--out", "x.bin"]);
    assert!(!ok && err.contains("/nonexistent/p.bin"), "{err}");
    let (ok, _, err) = tetloc(&["info", "jets:100G"]);
    assert!(!ok && err.contains("GB of memory"), "{err}");
    let (ok, _, err) = tetloc(&["bench", "jets:1000", "--backend", "warp-drive"]);
    assert!(!ok && err.contains("unknown backend 'warp-drive'"), "{err}");
    if let Some(dir) = require_data("bad_input_is_a_clear_error_and_a_nonzero_exit") {
        // Mixed meshes read (counted by type); cells tetloc does not read are refused, counted.
        let (ok, out, err) = tetloc(&["info", dir.join("real/can.vtu").to_str().unwrap()]);
        assert!(ok && out.contains("4800 hexahedron"), "{out}{err}");
        let (ok, _, err) = tetloc(&["info", dir.join("real/penta_hexa.vtk").to_str().unwrap()]);
        assert!(!ok && err.contains("60 pentagonal prism"), "{err}");
    }
}

#[test]
fn gen_writes_a_mesh_that_reads_back() {
    let out = tmp("fusion.vtu");
    let (ok, _, err) = tetloc(&["gen", "fusion", "--tets", "20k", "-o", out.to_str().unwrap(), "--seed", "3"]);
    assert!(ok, "{err}");
    let (ok, info, err) = tetloc(&["info", "--json", out.to_str().unwrap()]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&info).unwrap();
    let n = v["mesh"]["n_tets"].as_u64().unwrap();
    assert!((18_000..=22_000).contains(&n), "{n}");
    assert_eq!(v["mesh"]["n_reoriented"], 0);
    assert_eq!(v["faces"]["n_non_manifold"], 0);
}

#[test]
fn bench_json_has_the_documented_keys() {
    let (ok, out, err) =
        tetloc_cpu(&["bench", "jets:5k", "--queries", "centers,random,bbox", "--json", "--repeats", "1"]);
    assert!(ok, "{err}");
    let rows: Vec<serde_json::Value> = out.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(rows.len(), 3);
    for r in &rows {
        for key in ["backend", "queries", "n", "samples_per_s", "build_s", "device"] {
            assert!(!r[key].is_null(), "{key} missing in {r}");
        }
        assert!(r["samples_per_s"].as_f64().unwrap() > 0.0);
    }
    assert_eq!(rows[0]["outside"], 0, "tet centres are inside");
}

#[test]
fn agulhas_terrain_is_written_and_drawn() {
    let (obj, vtu) = (tmp("land.obj"), tmp("agulhas.vtu"));
    let (obj_s, vtu_s) = (obj.to_str().unwrap(), vtu.to_str().unwrap());
    let (ok, _, err) = tetloc(&["gen", "agulhas", "--tets", "20k", "-o", vtu_s, "--terrain", obj_s]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&obj).unwrap();
    assert!(text.lines().filter(|l| l.starts_with("f ")).count() > 100, "{err}");
    // A small CPU render of `mesh` with extra arguments.
    let render = |mesh: &str, extra: &[&str]| {
        let args = ["render", mesh, "--field", "f", "--backend", "cpu", "--size", "48x32"];
        tetloc(&[&args[..], extra].concat())
    };
    // The OBJ file and `--surface terrain` draw the same ground; without it the image differs.
    let (a, b, c) = (tmp("a.png"), tmp("b.png"), tmp("c.png"));
    for (extra, out) in [(vec!["--surface", obj_s], &a), (vec!["--surface", "terrain"], &b), (vec![], &c)] {
        let (ok, _, err) = render("agulhas:20k", &[&extra[..], &["-o", out.to_str().unwrap()]].concat());
        assert!(ok, "{err}");
    }
    let read = |p: &PathBuf| std::fs::read(p).unwrap();
    assert_eq!(read(&a), read(&b));
    assert_ne!(read(&a), read(&c), "the terrain changed nothing");
    // Shapes without terrain and mesh files say so.
    let (ok, _, err) = render("jets:5k", &["--surface", "terrain"]);
    assert!(!ok && err.contains("jets has no terrain (shapes with one: agulhas)"), "{err}");
    let (ok, _, err) = render(vtu_s, &["--surface", "terrain"]);
    assert!(!ok && err.contains("is not a generated shape"), "{err}");
    for f in [obj, vtu, a, b, c] {
        let _ = std::fs::remove_file(f);
    }
}

// ---- Issue 9: nothing lost, nothing silent. ----

/// `n` points in the unit cube (the bounds of every generated test mesh but agulhas), some
/// outside, as raw f32 triplets.
fn write_points(path: &std::path::Path, n: usize) -> Vec<[f32; 3]> {
    let pts: Vec<[f32; 3]> = (0..n)
        .map(|i| {
            let h = |k: u32| ((i as u32).wrapping_mul(2654435761).wrapping_add(k * 40503) % 10007) as f32 / 10007.0;
            [h(1) * 1.2 - 0.1, h(2), h(3)]
        })
        .collect();
    std::fs::write(path, bytemuck::cast_slice::<[f32; 3], u8>(&pts)).unwrap();
    pts
}

/// A small mesh file and a points file in `dir`.
fn mesh_and_points(dir: &std::path::Path) -> (PathBuf, PathBuf) {
    let mesh = dir.join("mesh.vtu");
    let (ok, _, err) = tetloc(&["gen", "jets", "--tets", "2000", "-o", s(&mesh)]);
    assert!(ok, "{err}");
    let points = dir.join("p.bin");
    write_points(&points, 500);
    (mesh, points)
}

/// An output that is one of the inputs (by name, another spelling, a hard or a symbolic
/// link), or another output, is refused before anything is read, naming both arguments;
/// nothing changes on disk.
#[test]
fn an_output_that_is_an_input_is_refused() {
    let dir = tmp_dir("same");
    let (mesh, points) = mesh_and_points(&dir);
    let csv = dir.join("p.csv");
    std::fs::write(&csv, "x,y,z\n0.5,0.5,0.5\n").unwrap();
    let hard = dir.join("hard.vtu");
    std::fs::hard_link(&mesh, &hard).unwrap();
    let soft = dir.join("soft.csv");
    std::os::unix::fs::symlink(&csv, &soft).unwrap();
    let dotted = dir.join(".").join("p.bin");
    // A mesh whose name has an output's extension (its format given by --format).
    let mesh_bin = dir.join("mesh.bin");
    std::fs::copy(&mesh, &mesh_bin).unwrap();
    let before: Vec<Vec<u8>> = [&mesh, &points, &csv, &mesh_bin].iter().map(|p| std::fs::read(p).unwrap()).collect();
    let ids = dir.join("ids.npy");
    let locate = |pts: &PathBuf, out: &PathBuf, values: Option<&PathBuf>| {
        let mut args = vec!["locate", s(&mesh), "--points", s(pts), "--out", s(out), "--backend", "cpu"];
        if out == &mesh_bin || values == Some(&mesh_bin) {
            args[1] = s(&mesh_bin);
            args.extend(["--format", "vtu"]);
        }
        if let Some(v) = values {
            args.extend(["--field", "f", "--values", s(v)]);
        }
        tetloc(&args)
    };
    let cases: Vec<(&PathBuf, &PathBuf, Option<&PathBuf>, &str, &str)> = vec![
        (&points, &mesh, None, "--out", "MESH"),
        (&points, &hard, None, "--out", "MESH"),
        (&points, &points, None, "--out", "--points"),
        (&points, &dotted, None, "--out", "--points"),
        (&csv, &soft, None, "--out", "--points"),
        (&points, &mesh_bin, None, "--out", "MESH"),
        (&points, &ids, Some(&mesh_bin), "--values", "MESH"),
        (&points, &ids, Some(&points), "--values", "--points"),
        (&points, &ids, Some(&ids), "--values", "--out"),
    ];
    for (pts, out, values, a, b) in cases {
        let (ok, _, err) = locate(pts, out, values);
        assert!(!ok && err.contains(a) && err.contains(b) && err.contains("same file"), "{out:?} {values:?}: {err}");
        assert!(!err.contains("located"), "{err}");
    }
    let after: Vec<Vec<u8>> = [&mesh, &points, &csv, &mesh_bin].iter().map(|p| std::fs::read(p).unwrap()).collect();
    assert!(before == after, "an input changed");
    assert!(!ids.exists());
    // gen: its two outputs; render: the image over its surface file.
    let (ok, _, err) = tetloc(&["gen", "agulhas", "--tets", "2k", "-o", s(&mesh), "--terrain", s(&dir.join("t.obj"))]);
    assert!(ok, "{err}");
    let link = dir.join("t.png");
    std::os::unix::fs::symlink(dir.join("t.obj"), &link).unwrap();
    let args = ["render", s(&mesh), "--field", "f", "--backend", "cpu", "--size", "8x8", "--surface"];
    let (ok, _, err) = tetloc(&[&args[..], &[s(&dir.join("t.obj")), "-o", s(&link)]].concat());
    assert!(!ok && err.contains("--out") && err.contains("--surface") && err.contains("same file"), "{err}");
    // A dangling link names the file it would create.
    std::os::unix::fs::symlink("t2.obj", dir.join("t2.vtu")).unwrap();
    let (t2_vtu, t2_obj) = (dir.join("t2.vtu"), dir.join("t2.obj"));
    let (ok, _, err) = tetloc(&["gen", "agulhas", "--tets", "2k", "-o", s(&t2_vtu), "--terrain", s(&t2_obj)]);
    assert!(!ok && err.contains("--terrain") && err.contains("--out") && err.contains("same file"), "{err}");
    assert!(!t2_obj.exists());
}

/// A write that fails (here a file-size limit, a full-disk stand-in, after 1 KiB) leaves the
/// previous output as it was and no temporary file; the exit code says so.
#[test]
fn a_failed_write_leaves_the_old_output_and_no_temporary() {
    let dir = tmp_dir("full");
    let points = dir.join("p.bin");
    write_points(&points, 20_000);
    let out_dir = dir.join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let names = ["ids.csv", "ids.npy", "pts.vtp", "pts.vtu"];
    for (k, name) in names.into_iter().enumerate() {
        let out = out_dir.join(name);
        std::fs::write(&out, "previous result").unwrap();
        // `ulimit -f 2`: writes past 1 KiB fail (EFBIG) once SIGXFSZ is ignored.
        let run = Command::new("sh")
            .args(["-c", "ulimit -f 2; trap '' XFSZ; exec \"$@\"", "sh", env!("CARGO_BIN_EXE_tetloc")])
            .args(["locate", "jets:2000", "--points", s(&points), "--out", s(&out), "--backend", "cpu"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&run.stderr);
        assert!(!run.status.success(), "{name}: {err}");
        assert!(err.contains(name) && err.contains("too large"), "{name}: {err}");
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "previous result", "{name}");
        assert_eq!(entries(&out_dir), names[..=k], "{name}: a temporary file stayed");
    }
}

/// Output paths are checked before any work: an unknown extension, a missing directory, a
/// directory or a device is refused at once and creates nothing.
#[test]
fn output_paths_are_checked_before_any_work() {
    let dir = tmp_dir("paths");
    let points = dir.join("p.bin");
    write_points(&points, 10);
    // A mesh too large to generate: reaching it would be a different error.
    let locate = |out: &str, extra: &[&str]| {
        let args = ["locate", "jets:100G", "--points", s(&points), "--out", out, "--backend", "cpu"];
        tetloc(&[&args[..], extra].concat())
    };
    let h5 = dir.join("o.h5");
    let sub = dir.join("d.npy");
    std::fs::create_dir(&sub).unwrap();
    for (out, want) in [
        (s(&h5), "'.h5'"),
        ("/nonexistent-dir/x.npy", "does not exist"),
        (s(&sub), "is a directory"),
        ("/dev/null", "not a regular file"),
    ] {
        let (ok, _, err) = locate(out, &[]);
        assert!(!ok && err.contains(want) && err.contains("--out") && !err.contains("GB of memory"), "{out}: {err}");
    }
    let (ok, _, err) = locate(s(&dir.join("ids.npy")), &["--field", "f", "--values", s(&dir.join("v.h5"))]);
    assert!(!ok && err.contains("--values") && err.contains("'.h5'"), "{err}");
    // gen: -o must be .vtu (it used to write VTU into x.npy); nothing is generated first.
    let (ok, _, err) = tetloc(&["gen", "jets", "--tets", "100G", "-o", s(&dir.join("x.npy"))]);
    assert!(!ok && err.contains("x.npy") && err.contains("vtu") && !err.contains("GB of memory"), "{err}");
    let (ok, _, err) = tetloc(&["render", "jets:100G", "--field", "f", "-o", s(&dir.join("x.jpg"))]);
    assert!(!ok && err.contains("x.jpg") && !err.contains("GB of memory"), "{err}");
    assert_eq!(entries(&dir), ["d.npy", "p.bin"], "something was created");
}

/// A first CSV line that is not `x,y,z` is an error with its line number, not a dropped
/// header (which shifted every output row against the input).
#[test]
fn a_bad_first_csv_line_is_an_error() {
    let dir = tmp_dir("csv");
    let csv = dir.join("p.csv");
    std::fs::write(&csv, "1.0D-01,0.2,0.3\n0.5,0.5,0.5\n").unwrap();
    let out = dir.join("ids.csv");
    let (ok, _, err) = tetloc_cpu(&["locate", "jets:1000", "--points", s(&csv), "--out", s(&out)]);
    assert!(!ok && err.contains("p.csv") && err.contains("line 1:") && err.contains("1.0D-01"), "{err}");
    assert!(!out.exists());
    std::fs::write(&csv, "x,y,z\n0.5,0.5,0.5\n2,2,2\n").unwrap();
    let (ok, _, err) = tetloc_cpu(&["locate", "jets:1000", "--points", s(&csv), "--out", s(&out)]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(rows.len(), 3, "{text}");
    assert_eq!(rows[0], "tet_id,vtkValidPointMask");
    assert!(rows[1].ends_with(",1") && rows[2] == "-1,0", "{text}");
}

/// Devices and pipes are read up to a cap: `/dev/zero` is refused, not read until memory
/// runs out.
#[test]
fn dev_zero_is_refused() {
    for format in ["vtu", "vtk", "msh"] {
        let (ok, _, err) = tetloc(&["info", "/dev/zero", "--format", format]);
        assert!(!ok && err.contains("/dev/zero") && err.contains("not a regular file"), "{format}: {err}");
    }
}

/// `auto` decides in seconds and says what it chose: on a CPU-emulated Vulkan device
/// (lavapipe in CI) it picks `cpu` without measuring anything, even with a cache directory
/// that cannot be written; with --quiet it says nothing.
#[test]
fn auto_is_fast_and_visible() {
    let Some(devices) = vulkan_devices("auto_is_fast_and_visible") else { return };
    let dir = tmp_dir("auto");
    let points = dir.join("p.bin");
    write_points(&points, 100);
    let not_a_dir = dir.join("cache");
    std::fs::write(&not_a_dir, "").unwrap();
    let run = |extra: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_tetloc"))
            .args(["locate", "jets:2000", "--points", s(&points), "--out", s(&dir.join("ids.npy"))])
            .args(extra)
            .env("XDG_CACHE_HOME", &not_a_dir)
            .env("HOME", &not_a_dir)
            .output()
            .unwrap();
        (out.status.success(), String::from_utf8_lossy(&out.stderr).into_owned())
    };
    let (ok, err) = run(&[]);
    assert!(ok, "{err}");
    let said: Vec<&str> = err.lines().filter(|l| l.starts_with("auto: ")).collect();
    assert_eq!(said.len(), 1, "{err}");
    if devices.iter().all(|(kind, _)| kind == "cpu") {
        assert!(said[0].starts_with("auto: cpu (the Vulkan device") && said[0].contains("runs on the CPU"), "{err}");
        assert!(!err.contains("measured") && !err.contains("cannot cache"), "nothing to measure or cache here: {err}");
    } else {
        assert_eq!(err.matches("cannot cache").count(), 1, "{err}");
    }
    let (ok, err) = run(&["--quiet"]);
    assert!(ok && !err.contains("auto: ") && !err.contains("located"), "{err}");
}

/// Points with NaN coordinates get -1 (and NaN values) on every backend, with a count on
/// stderr, instead of a refusal of the file; the other points get their usual answers. The
/// boundary tolerance works over every backend too.
#[test]
fn nan_points_get_no_answer_on_every_backend() {
    let dir = tmp_dir("nan");
    let points = dir.join("p.bin");
    let mut pts = write_points(&points, 300);
    for i in [0, 17, 299] {
        pts[i][i % 3] = f32::NAN;
    }
    pts[50] = [f32::INFINITY, 0.5, 0.5];
    std::fs::write(&points, bytemuck::cast_slice::<[f32; 3], u8>(&pts)).unwrap();
    let mut backends = vec!["cpu"];
    if let Some(devices) = vulkan_devices("nan_points_get_no_answer_on_every_backend") {
        backends.push("soft-bvh");
        if devices.iter().any(|d| d.1) {
            backends.extend(["rt-bvh", "rt-rep-faces", "rt-shared-faces"]);
        }
    }
    let mut reference: Option<(Vec<i32>, Vec<i32>)> = None;
    for b in backends {
        let (ids, vals) = (dir.join(format!("{b}.bin")), dir.join(format!("{b}.f32")));
        let args = ["locate", "jets:3000", "--points", s(&points), "--out", s(&ids), "--backend", b];
        let (ok, _, err) = tetloc(&[&args[..], &["--field", "f", "--values", s(&vals)]].concat());
        assert!(ok, "{b}: {err}");
        assert!(err.contains("4 of 300 points have a NaN or infinite coordinate"), "{b}: {err}");
        let got = read::<i32>(&ids);
        let v: Vec<f32> = bytemuck::pod_collect_to_vec(&std::fs::read(&vals).unwrap());
        for i in [0, 17, 50, 299] {
            assert_eq!(got[i], -1, "{b}: point {i}");
            assert!(v[i].is_nan(), "{b}: point {i}");
        }
        assert!(got.iter().filter(|&&i| i >= 0).count() > 200, "{b}: the finite points were not located");
        // The boundary tolerance over this backend: a tenth of the cube's side around it.
        let (ok, _, err) = tetloc(&[&args[..], &["--tolerance", "0.05"]].concat());
        assert!(ok, "{b}: {err}");
        let tol = read::<i32>(&ids);
        assert!((0..300).all(|i| got[i] < 0 || tol[i] == got[i]), "{b}: an inside answer changed");
        assert!([0, 17, 50, 299].iter().all(|&i| tol[i] == -1), "{b}: a NaN point got an answer");
        match &reference {
            None => {
                let rescued = (0..300).filter(|&i| got[i] < 0 && tol[i] >= 0).count();
                assert!(rescued > 0, "the tolerance changed nothing");
                reference = Some((got, tol));
            }
            // A point on a face shared by two tets may go to either; which points get an
            // answer does not depend on the backend.
            Some((r, rt)) => {
                assert!((0..300).all(|i| (r[i] < 0) == (got[i] < 0)), "{b}: {got:?}");
                assert!((0..300).all(|i| (rt[i] < 0) == (tol[i] < 0)), "{b} with the tolerance: {tol:?}");
            }
        }
    }
}

/// The small ones of issue 9.
#[test]
fn small_defects() {
    let dir = tmp_dir("small");
    // The OS error is said once.
    let (ok, _, err) =
        tetloc_cpu(&["locate", "jets:1000", "--points", "/nonexistent/p.bin", "--out", s(&dir.join("x.bin"))]);
    assert!(!ok && err.matches("os error 2").count() == 1, "{err}");
    // A mesh path that is not UTF-8.
    use std::os::unix::ffi::OsStrExt;
    let odd = dir.join(std::ffi::OsStr::from_bytes(b"mesh-\xff.vtu"));
    let (ok, _, err) = tetloc(&["gen", "jets", "--tets", "1000", "-o", s(&dir.join("m.vtu"))]);
    assert!(ok, "{err}");
    std::fs::rename(dir.join("m.vtu"), &odd).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_tetloc")).arg("info").arg("--json").arg(&odd).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // info --json: each field's range.
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let f = v["fields"].as_array().unwrap().iter().find(|f| f["name"] == "f").unwrap();
    let (lo, hi) = (f["min"].as_f64().unwrap(), f["max"].as_f64().unwrap());
    assert!(lo < hi, "{f}");
    // bench --repeats 1 is honoured on GPU backends too.
    if vulkan_devices("small_defects: bench --repeats 1").is_some() {
        let (ok, out, err) =
            tetloc(&["bench", "jets:5k", "--backend", "soft-bvh", "--queries", "random", "--json", "--repeats", "1"]);
        assert!(ok, "{err}");
        let row: serde_json::Value = serde_json::from_str(out.lines().next().unwrap()).unwrap();
        assert_eq!(row["repeats"], 1, "{row}");
    }
    let (ok, _, err) = tetloc(&["bench", "jets:5k", "--backend", "cpu", "--repeats", "0"]);
    assert!(!ok && err.contains("repeats"), "{err}");
    // locate takes one backend.
    let (ok, _, err) = tetloc(&["locate", "jets:1000", "--points", "p.bin", "--out", "x.bin", "--backend", "all"]);
    assert!(!ok && err.contains("one backend"), "{err}");
}

oracle_tests! {
    /// The boundary tolerance against VTK's probe filter with the same tolerance, on the oracle
    /// meshes: at the centroids of the boundary faces (on the boundary up to rounding, where the
    /// exact answer is "outside" for about half of them) every point gets the boundary tet and
    /// the value interpolated on the face, as VTK's probe says; points moved out along the face
    /// normal by half the tolerance are valid, by one and a half mostly not, as VTK says point by
    /// point. VTK also reads the `.vtp` tetloc writes.
    ///
    /// On `delaunay_s` (scipy's Delaunay: half its tets inverted, slivers on the hull) VTK's probe
    /// misses about a sixth of the boundary centroids even with the tolerance, and extrapolates
    /// in slivers it accepts within the tolerance; there the reference is the exact value on the
    /// face, and VTK is only reported.
    fn boundary_tolerance_matches_vtk_probe;
    /// The fresh-clone counterpart: [`boundary_tolerance_matches_vtk_probe`] on meshes generated
    /// at test time (`tetloc_testdata::generated_data`; its `delaunay_s`, a jittered block, has
    /// no slivers, but is held to the exact values all the same).
    fn boundary_tolerance_matches_vtk_probe_on_generated_meshes;
    boundary_tolerance_matches_vtk_probe_on
}

fn boundary_tolerance_matches_vtk_probe_on(test: &str, data: &Path) {
    use tetloc_core::locate::tolerance::build_boundary;
    use tetloc_core::locate::Tolerance;
    for name in ["torus_s", "part_s", "delaunay_s"] {
        let dir = tmp_dir(&format!("{test}-{name}"));
        let mesh_path = data.join(format!("{name}.vtu"));
        let mesh = tetloc_io::read_mesh(&mesh_path, None).unwrap();
        let tol = Tolerance::PercentOfMeanEdge(1.0);
        let d = tol.distance(&mesh);
        let boundary = build_boundary(&mesh);
        let n = boundary.triangles.len();
        // Centroids, then the centroids moved out by 0.5 D and by 1.5 D.
        let mut pts = vec![[0f32; 3]; 3 * n];
        for (k, (&tri, &tet)) in boundary.triangles.iter().zip(&boundary.tets).enumerate() {
            let v = tri.map(|i| mesh.points[i as usize].map(f64::from));
            let apex = mesh.tets[tet as usize].into_iter().find(|i| !tri.contains(i)).unwrap();
            let apex = mesh.points[apex as usize].map(f64::from);
            let c: [f64; 3] = std::array::from_fn(|a| (v[0][a] + v[1][a] + v[2][a]) / 3.0);
            let (e1, e2) = ([0, 1, 2].map(|a| v[1][a] - v[0][a]), [0, 1, 2].map(|a| v[2][a] - v[0][a]));
            let mut nrm = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
            let len = nrm.iter().map(|x| x * x).sum::<f64>().sqrt();
            let inward = (0..3).map(|a| nrm[a] * (apex[a] - v[0][a])).sum::<f64>() > 0.0;
            nrm = nrm.map(|x| x / len * if inward { -1.0 } else { 1.0 });
            for (j, off) in [0.0, 0.5, 1.5].into_iter().enumerate() {
                pts[j * n + k] = std::array::from_fn(|a| (c[a] + off * d * nrm[a]) as f32);
            }
        }
        let points = dir.join("p.bin");
        std::fs::write(&points, bytemuck::cast_slice::<[f32; 3], u8>(&pts)).unwrap();
        let (vtp, csv, exact) = (dir.join("r.vtp"), dir.join("r.csv"), dir.join("exact.bin"));
        let locate = |out: &PathBuf, field: &str, tol: &str| {
            let args = ["locate", s(&mesh_path), "--points", s(&points), "--out", s(out), "--field", field];
            let (ok, _, err) = tetloc(
                &[&args[..], &["--tolerance", tol, "--backend", "cpu", "--values", s(&dir.join("v.f32"))]].concat(),
            );
            assert!(ok, "{name}: {err}");
        };
        locate(&vtp, "f", "1%");
        locate(&csv, "cellval", "1%");
        locate(&exact, "f", "0");
        let Some(()) = run_vtk_script(
            test,
            "vtk_probe.py",
            &[s(&mesh_path), s(&points), &format!("{d:e}"), s(&vtp), s(&dir), "f", "cellval"],
        ) else {
            return;
        };
        let vtk_mask = std::fs::read(dir.join("vtk.vtkValidPointMask.bin")).unwrap();
        let (vtk_f, vtk_cell) = (read_f64s(&dir.join("vtk.f.bin")), read_f64s(&dir.join("vtk.cellval.bin")));
        // Our .vtp as VTK read it.
        let back: Vec<f64> = read_f64s(&dir.join("tetloc.points.bin"));
        assert!(back.chunks(3).zip(&pts).all(|(b, p)| (0..3).all(|a| b[a] == p[a] as f64)), "{name}: points");
        let (our_mask, our_f, our_id) = (
            read_f64s(&dir.join("tetloc.vtkValidPointMask.bin")),
            read_f64s(&dir.join("tetloc.f.bin")),
            read_f64s(&dir.join("tetloc.tet_id.bin")),
        );
        let table = std::fs::read_to_string(&csv).unwrap();
        let our_cell: Vec<f64> = table.lines().skip(1).map(|l| l.split(',').nth(1).unwrap().parse().unwrap()).collect();
        let exact_ids = read::<i32>(&exact);
        let exact_outside = exact_ids[..n].iter().filter(|&&i| i < 0).count();
        eprintln!("{name}: {n} boundary faces, D = {d:.3e}; exact: {exact_outside} centroids outside");
        let f = &mesh.field("f").unwrap().values;
        let vtk_is_reference = name != "delaunay_s";
        let mut vtk_disagrees = 0;
        for (k, tri) in boundary.triangles.iter().enumerate() {
            assert!(our_mask[k] == 1.0 && our_id[k] >= 0.0, "{name}: centroid {k} not valid");
            // Inside a tet: the exact interpolation there (in a sliver, the apex's weight
            // of a point rounded off the face counts); outside: the value on the face at its
            // centroid, the mean of its vertices' values.
            let on_face = match exact_ids[k] {
                t if t >= 0 => tetloc_testdata::exact_value(&mesh, t as usize, pts[k], f),
                _ => tri.iter().map(|&v| f[v as usize] as f64).sum::<f64>() / 3.0,
            };
            assert!(
                (our_f[k] - on_face).abs() <= 1e-5 * (1.0 + on_face.abs()),
                "{name}: f at centroid {k}: {} vs {on_face}",
                our_f[k]
            );
            let cell = mesh.field("cellval").unwrap().values[boundary.tets[k] as usize];
            assert_eq!(our_cell[k] as f32, cell, "{name}: cellval at centroid {k}");
            let agree = vtk_mask[k] == 1
                && (our_f[k] - vtk_f[k]).abs() <= 1e-5 * (1.0 + vtk_f[k].abs())
                && our_cell[k] as f32 == vtk_cell[k] as f32;
            assert!(
                agree || !vtk_is_reference,
                "{name}: centroid {k}: f {} vs VTK {} (VTK mask {})",
                our_f[k],
                vtk_f[k],
                vtk_mask[k]
            );
            vtk_disagrees += usize::from(!agree);
        }
        let (mut valid, mut compared) = ([0; 2], 0);
        for i in n..3 * n {
            // Where the distance to the boundary is within rounding of D, either answer is right.
            let dist = boundary
                .nearest(&mesh.points, pts[i].map(f64::from), 2.0 * d)
                .map_or(f64::INFINITY, |b| b.dist2.sqrt());
            if (dist - d).abs() < 1e-3 * d {
                continue;
            }
            compared += 1;
            assert_eq!(our_mask[i] == 1.0, dist <= d, "{name}: point {i} at distance {dist:.4e}, D = {d:.4e}");
            if our_mask[i] as u8 != vtk_mask[i] {
                assert!(
                    !vtk_is_reference,
                    "{name}: point {i} at distance {dist:.4e}, D = {d:.4e}: VTK says {}",
                    vtk_mask[i]
                );
                vtk_disagrees += 1;
            }
            valid[(i >= 2 * n) as usize] += our_mask[i] as usize;
        }
        eprintln!("{name}: VTK's probe disagrees at {vtk_disagrees} of {} points", 3 * n);
        assert!(compared > 2 * n * 9 / 10, "{name}: {compared} of {} compared", 2 * n);
        assert!(valid[0] > n * 9 / 10 && valid[1] < n / 10, "{name}: valid at 0.5 D and 1.5 D: {valid:?} of {n}");
    }
}

/// `gen SHAPE-KIND` writes a mixed mesh that reads back with its cells, and `locate` answers
/// cell ids on it.
#[test]
fn gen_mixed_shapes_read_back_and_locate() {
    for spec in ["jets-hex", "agulhas-wedge", "japan-hybrid"] {
        let out = tmp(&format!("{spec}.vtu"));
        let (ok, _, err) = tetloc(&["gen", spec, "--cells", "3000", "-o", out.to_str().unwrap()]);
        assert!(ok, "{spec}: {err}");
        let (ok, text, err) = tetloc(&["info", out.to_str().unwrap()]);
        assert!(ok && text.contains("cells ") && text.contains("decomposition"), "{spec}: {text}{err}");
        let pts = tmp(&format!("{spec}.csv"));
        std::fs::write(&pts, "x,y,z\n1e9,0,0\n").unwrap();
        let ids = tmp(&format!("{spec}.ids.csv"));
        let args = ["locate", out.to_str().unwrap(), "--points", pts.to_str().unwrap(), "--out", ids.to_str().unwrap()];
        let (ok, _, err) = tetloc_cpu(&args);
        assert!(ok, "{spec}: {err}");
        for p in [out, pts, ids] {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// `--precision f64`: the same ids as the default, values interpolated in f64 (here on f32
/// data: within f32 rounding of the default's); a bad value is an error that names it.
#[test]
fn locate_precision_f64() {
    let dir = tmp_dir("precision");
    let (mesh, points) = mesh_and_points(&dir);
    let run = |p: &str| {
        let (ids, vals) = (dir.join(format!("ids-{p}.bin")), dir.join(format!("v-{p}.bin")));
        let args = ["locate", s(&mesh), "--points", s(&points), "--out", s(&ids), "--field", "f", "--values", s(&vals)];
        let (ok, _, err) = tetloc(&[&args[..], &["--backend", "cpu", "--precision", p]].concat());
        assert!(ok, "{p}: {err}");
        (read::<i32>(&ids), read::<f32>(&vals))
    };
    let ((ids, v), (ids64, v64)) = (run("f32"), run("f64"));
    assert_eq!(ids, ids64);
    assert!(ids.iter().any(|&i| i >= 0) && ids.iter().any(|&i| i < 0));
    for (a, b) in v.iter().zip(&v64) {
        assert!((a - b).abs() <= 1e-6 * a.abs().max(1.0) || (a.is_nan() && b.is_nan()), "{a} vs {b}");
    }
    // The option does something: interpolated in f64, some values round differently.
    let differ = v.iter().zip(&v64).filter(|(a, b)| !a.is_nan() && a.to_bits() != b.to_bits()).count();
    assert!(differ > 0, "--precision f64 gave the f32 path's values bit for bit");
    // .npy keeps the precision the values were interpolated in (raw .bin is always f32):
    // float32 by default, float64 with f64, the same values the .bin files rounded.
    for (p, want) in [("f32", &v), ("f64", &v64)] {
        let (ids, npy) = (dir.join("ids.npy"), dir.join(format!("v-{p}.npy")));
        let args = ["locate", s(&mesh), "--points", s(&points), "--out", s(&ids), "--field", "f", "--values", s(&npy)];
        let (ok, _, err) = tetloc(&[&args[..], &["--backend", "cpu", "--precision", p]].concat());
        assert!(ok, "{p}: {err}");
        let npy = npyz::NpyFile::new(std::fs::File::open(&npy).unwrap()).unwrap();
        let got: Vec<f64> = match (p, npy.dtype().num_bytes()) {
            ("f32", Some(4)) => npy.into_vec::<f32>().unwrap().into_iter().map(f64::from).collect(),
            ("f64", Some(8)) => npy.into_vec::<f64>().unwrap(),
            (_, bytes) => panic!("{p}: values written with {bytes:?} bytes each"),
        };
        for (g, w) in got.iter().zip(want.iter()) {
            assert!(*g as f32 == *w || (g.is_nan() && w.is_nan()), "{p}: {g} vs {w}");
        }
    }
    let (ok, _, err) = tetloc(&["locate", s(&mesh), "--points", s(&points), "--out", "x.bin", "--precision", "f16"]);
    assert!(!ok && err.contains("f16"), "{err}");
}

/// `render` without `--field` shows the mesh's first field, as `view` does; a mesh without
/// fields is refused by both, naming the file.
#[test]
fn render_shows_the_first_field_by_default() {
    let dir = tmp_dir("render_first_field");
    let render = |mesh: &str, out: &str, extra: &[&str]| {
        let args = ["render", mesh, "--backend", "cpu", "--size", "24x20", "-q", "-o", out];
        tetloc(&[&args[..], extra].concat())
    };
    let (a, b) = (dir.join("a.png"), dir.join("b.png"));
    for (out, extra) in [(&a, &[][..]), (&b, &["--field", "f"][..])] {
        let (ok, _, err) = render("fusion:2k", s(out), extra);
        assert!(ok, "{err}");
    }
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "fusion's first field is f");
    let (ok, _, err) = render("fusion:2k", s(&a), &["--field", "cellval"]);
    assert!(ok, "{err}");
    assert_ne!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    std::fs::write(dir.join("bare.node"), "4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n").unwrap();
    std::fs::write(dir.join("bare.ele"), "1 4 0\n1 1 2 3 4\n").unwrap();
    let bare = dir.join("bare.node");
    let (ok, _, err) = render(s(&bare), s(&a), &[]);
    assert!(!ok && err.contains("bare.node: the mesh has no fields to show"), "{err}");
    let (ok, _, err) = tetloc(&["view", s(&bare), "--port", "0", "--backend", "cpu", "-q"]);
    assert!(!ok && err.contains("bare.node: the mesh has no fields to show"), "{err}");
}
