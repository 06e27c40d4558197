//! The `tetloc` binary end to end: exit codes, messages, files written (CPU backend, so
//! these run anywhere; the GPU backends are tested in tetloc-vulkan).

use std::path::PathBuf;
use std::process::Command;
use tetloc_testdata::{query_sets, require_data};

fn tetloc(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_tetloc")).args(args).output().expect("run tetloc");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into(), String::from_utf8_lossy(&out.stderr).into())
}

fn tmp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("tetloc-cli-{}-{name}", std::process::id()))
}

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

#[test]
fn locate_writes_the_oracle_answers() {
    let Some(dir) = require_data("locate_writes_the_oracle_answers") else { return };
    let set = query_sets(&dir).into_iter().find(|s| s.label == "torus_s.random").unwrap();
    let ids = tmp("ids.bin");
    let vals = tmp("vals.npy");
    let (ok, _, err) = tetloc(&[
        "locate",
        dir.join("torus_s.msh").to_str().unwrap(),
        "--points",
        dir.join("torus_s.random.points.bin").to_str().unwrap(),
        "--out",
        ids.to_str().unwrap(),
        "--field",
        "f",
        "--values",
        vals.to_str().unwrap(),
        "--backend",
        "cpu",
    ]);
    assert!(ok, "{err}");
    let got: Vec<i32> =
        std::fs::read(&ids).unwrap().chunks_exact(4).map(|c| i32::from_le_bytes(c.try_into().unwrap())).collect();
    assert_eq!(got.len(), set.cell.len());
    let wrong = (0..got.len()).filter(|&i| got[i] != set.cell[i] && !set.ambiguous(i)).count();
    assert_eq!(wrong, 0);
    assert!(std::fs::metadata(&vals).unwrap().len() > 4 * got.len() as u64);
    // A ParaView point set with ids and values.
    let vtu = tmp("pts.vtu");
    let (ok, _, err) = tetloc(&[
        "locate",
        dir.join("torus_s.vtu").to_str().unwrap(),
        "--points",
        dir.join("torus_s.random.points.bin").to_str().unwrap(),
        "--out",
        vtu.to_str().unwrap(),
        "--field",
        "f",
        "--backend",
        "cpu",
    ]);
    assert!(ok, "{err}");
    let text = std::fs::read(&vtu).unwrap();
    assert!(String::from_utf8_lossy(&text[..2000.min(text.len())]).contains("tet_id"));
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
    let (ok, _, err) =
        tetloc(&["locate", "jets:1000", "--points", "/nonexistent/p.bin", "--out", "x.bin", "--backend", "cpu"]);
    assert!(!ok && err.contains("/nonexistent/p.bin"), "{err}");
    let (ok, _, err) = tetloc(&["info", "jets:100G"]);
    assert!(!ok && err.contains("GB of memory"), "{err}");
    let (ok, _, err) = tetloc(&["bench", "jets:1000", "--backend", "warp-drive"]);
    assert!(!ok && err.contains("unknown backend 'warp-drive'"), "{err}");
    if let Some(dir) = require_data("bad_input_is_a_clear_error_and_a_nonzero_exit") {
        let (ok, _, err) = tetloc(&["info", dir.join("real/can.vtu").to_str().unwrap()]);
        assert!(!ok && err.contains("4800 hexahedron"), "{err}");
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
    let (ok, out, err) = tetloc(&[
        "bench",
        "jets:5k",
        "--backend",
        "cpu",
        "--queries",
        "centers,random,bbox",
        "--json",
        "--repeats",
        "1",
    ]);
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
