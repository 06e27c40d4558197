//! `resample`, `probe` and `trace` end to end, against VTK itself (vtkResampleToImage,
//! vtkResampleWithDataSet, vtkStreamTracer through `scripts/vtk_ops.py`), on the oracle
//! meshes; and their bad inputs.

use std::path::{Path, PathBuf};
use std::process::Command;
use tetloc_testdata::{read_f64s, require_data, run_vtk_script};

fn tetloc(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_tetloc")).args(args).output().expect("run tetloc");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into(), String::from_utf8_lossy(&out.stderr).into())
}

fn tmp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tetloc-ops-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-5 * (1.0 + a.abs().max(b.abs()))
}

/// The image of every field and the valid mask are VTK's; the .npy of one field is the
/// .vti's array; the grid is VTK's (bounds nudged inwards, points on both ends).
#[test]
fn resample_matches_vtk() {
    const TEST: &str = "resample_matches_vtk";
    let Some(data) = require_data(TEST) else { return };
    for name in ["torus_s", "part_s"] {
        let dir = tmp_dir(&format!("resample-{name}"));
        let mesh = data.join(format!("{name}.vtu"));
        let (vti, npy) = (dir.join("r.vti"), dir.join("f.npy"));
        let (ok, _, err) = tetloc(&["resample", s(&mesh), "--dims", "23,19,11", "-o", s(&vti), "--backend", "cpu"]);
        assert!(ok, "{err}");
        let (ok, _, err) =
            tetloc(&["resample", s(&mesh), "--dims", "23,19,11", "--field", "f", "-o", s(&npy), "--backend", "cpu"]);
        assert!(ok, "{err}");
        let Some(()) = run_vtk_script(TEST, "vtk_ops.py", &["resample", s(&mesh), "23,19,11", s(&vti), s(&dir)]) else {
            return;
        };
        let geometry = |who: &str| -> serde_json::Value {
            serde_json::from_str(&std::fs::read_to_string(dir.join(format!("{who}.geometry.json"))).unwrap()).unwrap()
        };
        let (vg, tg) = (geometry("vtk"), geometry("tetloc"));
        assert_eq!(vg["dims"], tg["dims"]);
        // The same up to float32 rounding: tetloc keeps coordinates in float32, VTK's bounds
        // come from the file's float64 points.
        for key in ["origin", "spacing"] {
            for k in 0..3 {
                let (a, b) = (vg[key][k].as_f64().unwrap(), tg[key][k].as_f64().unwrap());
                assert!((a - b).abs() <= 1e-6 * (1.0 + a.abs()), "{name}: {key}: VTK {vg} vs {tg}");
            }
        }
        let mask = read_f64s(&dir.join("vtk.vtkValidPointMask.bin"));
        let ours = read_f64s(&dir.join("tetloc.vtkValidPointMask.bin"));
        // VTK's cell search accepts points a little outside a tet (see data/README.md: it
        // differs from the exact answer at 0.3-1 % of points): where the masks differ, VTK
        // must be the one saying "inside", for a point within 1 % of an edge of the boundary.
        let differ: Vec<usize> = (0..mask.len()).filter(|&i| mask[i] != ours[i]).collect();
        assert!(differ.len() * 200 <= mask.len(), "{name}: masks differ at {} of {} points", differ.len(), mask.len());
        if !differ.is_empty() {
            let g = |k: &str, a: usize| tg[k][a].as_f64().unwrap();
            let dims: Vec<usize> = (0..3).map(|a| tg["dims"][a].as_u64().unwrap() as usize).collect();
            let pts: Vec<[f32; 3]> = differ
                .iter()
                .map(|&i| {
                    let idx = [i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1])];
                    std::array::from_fn(|a| (g("origin", a) + idx[a] as f64 * g("spacing", a)) as f32)
                })
                .collect();
            let (p, ids) = (dir.join("differ.bin"), dir.join("differ.ids.bin"));
            std::fs::write(&p, bytemuck::cast_slice::<[f32; 3], u8>(&pts)).unwrap();
            let (ok, _, err) = tetloc(&[
                "locate",
                s(&mesh),
                "--points",
                s(&p),
                "--out",
                s(&ids),
                "--tolerance",
                "1%",
                "--backend",
                "cpu",
            ]);
            assert!(ok, "{err}");
            let near: Vec<i32> = bytemuck::pod_collect_to_vec(&std::fs::read(&ids).unwrap());
            for (k, &i) in differ.iter().enumerate() {
                assert!(mask[i] == 1.0 && near[k] >= 0, "{name}: grid point {i} {:?}: VTK mask {}", pts[k], mask[i]);
            }
            eprintln!("{name}: VTK counts {} grid points within its slack of the boundary as inside", differ.len());
        }
        let valid = ours.iter().filter(|&&m| m == 1.0).count();
        assert!(valid > mask.len() / 20 && valid < mask.len(), "{name}: {valid} valid");
        // Values: VTK's within 1e-5 relative, except where VTK's tolerant cell search picked
        // a neighbour of the containing tet (a point within its slack of a face) and
        // extrapolates there: few points, and a small difference for the smooth field `f`.
        for field in ["f", "cellval"] {
            let (v, t) =
                (read_f64s(&dir.join(format!("vtk.{field}.bin"))), read_f64s(&dir.join(format!("tetloc.{field}.bin"))));
            let off: Vec<usize> = (0..v.len()).filter(|&i| ours[i] == 1.0 && !close(v[i], t[i])).collect();
            eprintln!("{name}: {field} differs from VTK's at {} of {valid} points", off.len());
            assert!(off.len() * 100 <= valid, "{name}: {field} differs from VTK's at {} of {valid} points", off.len());
            if field == "f" {
                for &i in &off {
                    assert!((v[i] - t[i]).abs() < 1e-3, "{name}: f at grid point {i}: VTK {} vs {}", v[i], t[i]);
                }
            }
            assert!((0..v.len()).filter(|&i| ours[i] == 0.0).all(|i| t[i].is_nan()), "{name}: NaN outside");
        }
        let bytes = std::fs::read(&npy).unwrap();
        let header_len = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
        let header = String::from_utf8_lossy(&bytes[10..header_len]);
        assert!(header.contains("'shape': (11, 19, 23)") && header.contains("'<f4'"), "{header}");
        let f: Vec<f32> = bytemuck::pod_collect_to_vec(&bytes[header_len..]);
        let vti_f = read_f64s(&dir.join("tetloc.f.bin"));
        assert!(f.iter().zip(&vti_f).all(|(&a, &b)| (a.is_nan() && b.is_nan()) || a as f64 == b), "{name}: npy vs vti");
    }
}

/// Bad input gets a clear error and no output.
#[test]
fn bad_inputs_are_refused() {
    let dir = tmp_dir("bad");
    let out = dir.join("x.vti");
    let (ok, _, err) = tetloc(&["resample", "jets:2000", "--dims", "4,0,4", "-o", s(&out), "--backend", "cpu"]);
    assert!(!ok && err.contains("at least 1"), "{err}");
    let (ok, _, err) =
        tetloc(&["resample", "jets:2000", "--dims", "4,4,4", "-o", "/nonexistent-dir/x.vti", "--backend", "cpu"]);
    assert!(!ok && err.contains("does not exist"), "{err}");
    let (ok, _, err) = tetloc(&["resample", "jets:2000", "--dims", "4,4", "-o", s(&out), "--backend", "cpu"]);
    assert!(!ok && err.contains("three"), "{err}");
    let (ok, _, err) =
        tetloc(&["resample", "jets:2000", "--dims", "4,4,4", "--field", "nope", "-o", s(&out), "--backend", "cpu"]);
    assert!(!ok && err.contains("'nope'") && err.contains("'f'"), "{err}");
    assert!(!out.exists());
    let vtp = dir.join("l.vtp");
    let (ok, _, err) =
        tetloc(&["trace", "jets:2000", "--vector", "nope", "--seeds", "line:0,0,0,1,1,1,3", "-o", s(&vtp)]);
    assert!(!ok && err.contains("'nope'"), "{err}");
    let (ok, _, err) = tetloc(&["trace", "jets:2000", "--vector", "f", "--seeds", "line:0,0,0,1,1,1,3", "-o", s(&vtp)]);
    assert!(!ok && err.contains("3 components"), "{err}");
    let (ok, _, err) = tetloc(&[
        "trace",
        "jets:2000",
        "--vector",
        "f",
        "--seeds",
        "line:0,0,0,1,1,1,3",
        "-o",
        "/nonexistent-dir/l.vtp",
    ]);
    assert!(!ok && err.contains("does not exist"), "{err}");
    assert!(!vtp.exists());
}

/// Streamlines through a swirl on the torus (v = (-y + 0.2x, x + 0.2y, 0.3), so lines spiral
/// outwards and leave through the boundary) against vtkStreamTracer with the same RK4 step:
/// the same lines (seed, reason), the same points within 1e-4 of the domain size, ending at
/// the same boundary. A seed outside the mesh gives no line and a warning.
#[test]
fn trace_matches_vtk() {
    const TEST: &str = "trace_matches_vtk";
    let Some(data) = require_data(TEST) else { return };
    let dir = tmp_dir("trace");
    let mut m = tetloc_core::io::read_mesh(&data.join("torus_s.vtu"), None).unwrap();
    let swirl = |p: [f32; 3]| [-p[1] + 0.2 * p[0], p[0] + 0.2 * p[1], 0.3];
    for c in 0..3 {
        let values = m.points.iter().map(|&p| swirl(p)[c]).collect();
        m.fields.push(tetloc_core::Field {
            name: format!("v[{c}]"),
            location: tetloc_core::FieldLocation::Vertex,
            values,
        });
    }
    let mesh = dir.join("swirl.vtu");
    tetloc_core::io::vtk::write::write_mesh_vtu(&mesh, &m, false).unwrap();
    let seeds = dir.join("seeds.bin");
    let pts: Vec<[f32; 3]> =
        vec![[0.8, 0.0, 0.0], [1.0, 0.1, 0.1], [0.0, 1.2, -0.1], [-1.1, 0.0, 0.2], [0.0, 0.0, 0.0]];
    std::fs::write(&seeds, bytemuck::cast_slice::<[f32; 3], u8>(&pts)).unwrap();
    let out = dir.join("lines.vtp");
    let (ok, _, err) = tetloc(&[
        "trace",
        s(&mesh),
        "--vector",
        "v",
        "--seeds",
        s(&seeds),
        "-o",
        s(&out),
        "--step",
        "0.01",
        "--max-steps",
        "400",
        "--direction",
        "both",
        "--backend",
        "cpu",
    ]);
    assert!(ok, "{err}");
    assert!(err.contains("2 of 10 lines"), "the seed at the origin is outside: {err}");
    let Some(()) = run_vtk_script(
        TEST,
        "vtk_ops.py",
        &["trace", s(&mesh), "v", s(&seeds), "0.01", "400", "both", s(&out), s(&dir)],
    ) else {
        return;
    };
    let read = |who: &str, what: &str| read_f64s(&dir.join(format!("{who}.{what}.bin")));
    let offsets = |who: &str| -> Vec<i64> {
        bytemuck::pod_collect_to_vec(&std::fs::read(dir.join(format!("{who}.offsets.bin"))).unwrap())
    };
    let (vo, to) = (offsets("vtk"), offsets("tetloc"));
    assert_eq!(vo.len(), to.len(), "lines: VTK {} vs {}", vo.len() - 1, to.len() - 1);
    assert_eq!(read("vtk", "SeedIds"), read("tetloc", "SeedIds"));
    assert_eq!(read("vtk", "ReasonForTermination"), read("tetloc", "ReasonForTermination"));
    let (vp, tp) = (read("vtk", "points"), read("tetloc", "points"));
    let (vt, tt) = (read("vtk", "IntegrationTime"), read("tetloc", "IntegrationTime"));
    let size = 2.7; // the torus' extent
    for l in 0..vo.len() - 1 {
        let (va, vb, ta, tb) = (vo[l] as usize, vo[l + 1] as usize, to[l] as usize, to[l + 1] as usize);
        // Ending at the same boundary: at most one step apart at the end (VTK's cell search
        // accepts a point just outside).
        assert!((vb - va).abs_diff(tb - ta) <= 1, "line {l}: {} points in VTK, {} here", vb - va, tb - ta);
        for k in 0..(vb - va).min(tb - ta) {
            let d = (0..3).map(|a| (vp[3 * (va + k) + a] - tp[3 * (ta + k) + a]).powi(2)).sum::<f64>().sqrt();
            assert!(d <= 1e-4 * size, "line {l}, point {k}: {d:e} from VTK's");
            assert!((vt[va + k] - tt[ta + k]).abs() <= 1e-4 * (1.0 + vt[va + k].abs()), "line {l}, point {k}: time");
        }
    }
}

/// Probing the torus at its `bbox` query points (many outside) against vtkResampleWithDataSet:
/// the mask is the exact oracle's, and VTK's but at a few points (its cell search takes
/// points within its slack outside a tet as inside, and misses a few inside: about 0.1 %);
/// the values are VTK's; VTK reads the point set we write.
#[test]
fn probe_matches_vtk() {
    const TEST: &str = "probe_matches_vtk";
    let Some(data) = require_data(TEST) else { return };
    let dir = tmp_dir("probe");
    let (mesh, pts) = (data.join("torus_s.vtu"), data.join("torus_s.bbox.points.bin"));
    let out = dir.join("p.vtp");
    let (ok, _, err) = tetloc(&["probe", s(&mesh), s(&pts), "-o", s(&out), "--backend", "cpu"]);
    assert!(ok, "{err}");
    let Some(()) = run_vtk_script(TEST, "vtk_ops.py", &["probe", s(&mesh), s(&pts), s(&out), s(&dir)]) else { return };
    let (vm, tm) =
        (read_f64s(&dir.join("vtk.vtkValidPointMask.bin")), read_f64s(&dir.join("tetloc.vtkValidPointMask.bin")));
    let valid = tm.iter().filter(|&&m| m == 1.0).count();
    assert!(valid > tm.len() / 10 && valid < tm.len(), "{valid} of {} valid", tm.len());
    let differ: Vec<usize> = (0..vm.len()).filter(|&i| vm[i] != tm[i]).collect();
    assert!(differ.len() * 200 <= vm.len(), "masks differ at {} of {} points", differ.len(), vm.len());
    let oracle: Vec<i32> = bytemuck::pod_collect_to_vec(&std::fs::read(data.join("torus_s.bbox.cell.bin")).unwrap());
    let flags = std::fs::read(data.join("torus_s.bbox.flags.bin")).unwrap();
    let wrong = (0..tm.len()).filter(|&i| flags[i] & 1 == 0 && (tm[i] == 1.0) != (oracle[i] >= 0)).count();
    assert_eq!(wrong, 0, "the mask differs from the exact answer at {wrong} points");
    let (vf, tf) = (read_f64s(&dir.join("vtk.f.bin")), read_f64s(&dir.join("tetloc.f.bin")));
    // f: the exact interpolation (the oracle's f64 value) wherever the point is not within
    // rounding of a face; VTK's value where both have one, but where VTK's tolerant search
    // took a neighbouring tet and extrapolates.
    let exact = read_f64s(&data.join("torus_s.bbox.value.bin"));
    let inexact = (0..tf.len()).filter(|&i| flags[i] & 1 == 0 && oracle[i] >= 0 && !close(exact[i], tf[i])).count();
    assert_eq!(inexact, 0, "f differs from the exact interpolation at {inexact} points");
    let both = (0..vf.len()).filter(|&i| tm[i] == 1.0 && vm[i] == 1.0).count();
    let off = (0..vf.len()).filter(|&i| tm[i] == 1.0 && vm[i] == 1.0 && !close(vf[i], tf[i])).count();
    eprintln!("torus_s: masks differ at {} points, f at {off} of {both}", differ.len());
    assert!(off * 50 <= both, "f differs from VTK's at {off} of {both} points");
    assert!((0..tf.len()).filter(|&i| tm[i] == 0.0).all(|i| tf[i].is_nan()));
}
