//! Tests of the VTK readers against the shared data: every file reads, encodings of one mesh
//! agree bit for bit, higher-order and non-tet files, and damaged files fail cleanly.

use crate::error::Error;
use crate::io::{vtk_legacy, vtu};
use crate::mesh::{FieldLocation, RawMesh};
use crate::testdata::require_data;
use std::path::{Path, PathBuf};

fn read(path: &Path) -> crate::Result<RawMesh> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("vtu") => vtu::read(path),
        _ => vtk_legacy::read(path),
    }
}

fn parse(bytes: &[u8], path: &Path) -> crate::Result<RawMesh> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("vtu") => vtu::parse(bytes, path),
        _ => vtk_legacy::parse(bytes, path),
    }
}

fn field<'m>(m: &'m RawMesh, name: &str) -> &'m [f32] {
    &m.fields.iter().find(|f| f.name == name).unwrap_or_else(|| panic!("no field '{name}'")).values
}

/// The VTK files of the data folder and its `real/` folder.
fn vtk_files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for d in [dir.to_path_buf(), dir.join("real")] {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if matches!(p.extension().and_then(|e| e.to_str()), Some("vtu" | "vtk")) {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

#[test]
fn generated_meshes_match_their_descriptions() {
    let Some(dir) = require_data("generated_meshes_match_their_descriptions") else { return };
    for name in ["torus_s", "part_s", "delaunay_s"] {
        let meta: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join(format!("{name}.mesh.json"))).unwrap()).unwrap();
        let files: Vec<&String> = meta["files"].as_object().unwrap().keys().collect();
        let vtk: Vec<&&String> = files.iter().filter(|f| f.ends_with(".vtu") || f.ends_with(".vtk")).collect();
        assert!(vtk.len() >= 2, "{name}: {files:?}");
        for file in vtk {
            let m = read(&dir.join(file)).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(m.points.len() as u64, meta["n_points"].as_u64().unwrap(), "{file}");
            assert_eq!(m.tets.len() as u64, meta["n_tets"].as_u64().unwrap(), "{file}");
            assert_eq!(m.higher_order, None);
            // The data's cell field is a hash of the 0-based cell id: checks cell order.
            let cellval = field(&m, "cellval");
            assert_eq!(m.fields.iter().find(|f| f.name == "cellval").unwrap().location, FieldLocation::Cell);
            for (id, &v) in cellval.iter().enumerate() {
                let want = ((id as u64 * 2654435761) % (1 << 32)) as f64 / (1u64 << 32) as f64;
                assert_eq!(v, want as f32, "{file}: cellval of cell {id}");
            }
            // The point field is a formula of the point: checks point order.
            let f = field(&m, "f");
            for (p, &v) in m.points.iter().zip(f) {
                let [x, y, z] = p.map(|c| c as f64);
                let want = (3.0 * x + 1.0).sin() * (2.0 * y).cos() + 0.5 * (4.0 * z).sin() + 0.3 * x * y;
                assert!((v as f64 - want).abs() < 1e-5, "{file}: f at {p:?} is {v}, want {want}");
            }
        }
    }
}

#[test]
fn encodings_of_one_mesh_are_identical() {
    let Some(dir) = require_data("encodings_of_one_mesh_are_identical") else { return };
    let groups: [&[&str]; 3] = [
        &["torus_s.vtu", "torus_s.b64.vtu"],
        &["part_s.vtu", "part_s.zlib.vtu", "part_s.v42.vtk"],
        &["delaunay_s.vtu", "delaunay_s.zlib.vtu", "delaunay_s.vtk"],
    ];
    for group in groups {
        let first = read(&dir.join(group[0])).unwrap();
        for other in &group[1..] {
            let m = read(&dir.join(other)).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(m.points, first.points, "{other} vs {}", group[0]);
            assert_eq!(m.tets, first.tets, "{other}");
            assert_eq!(m.fields.len(), first.fields.len(), "{other}");
            for f in &m.fields {
                let g = first.fields.iter().find(|g| g.name == f.name).unwrap();
                assert_eq!((&f.name, f.location), (&g.name, g.location), "{other}");
                assert!(f.values.iter().zip(&g.values).all(|(a, b)| a.to_bits() == b.to_bits()), "{other}: {}", f.name);
                assert_eq!(f.values.len(), g.values.len());
            }
        }
    }
}

#[test]
fn real_files() {
    let Some(dir) = require_data("real_files") else { return };
    let real = dir.join("real");
    let tet_files: [(&str, usize, Option<u8>); 4] = [
        ("post.vtk", 8750, None),
        ("kiefer.vtu", 56786, Some(2)),
        ("tetrahedron.vtu", 96, None),
        ("quadratic_tetra.vtu", 96, Some(2)),
    ];
    for (file, n_tets, order) in tet_files {
        let m = read(&real.join(file)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((m.tets.len(), m.higher_order), (n_tets, order), "{file}");
        let mesh = crate::Mesh::new(m, file).unwrap_or_else(|e| panic!("{e}"));
        assert!(mesh.info.total_volume > 0.0);
    }
    let post = read(&real.join("post.vtk")).unwrap();
    assert_eq!(field(&post, "Pressure").len(), post.points.len());
    let kiefer = read(&real.join("kiefer.vtu")).unwrap();
    assert_eq!(kiefer.points.len(), 102578);
    assert_eq!(field(&kiefer, "Equivalent (von-Mises) Stress (psi)").len(), 56786);

    // Counted independently from the files' type arrays.
    let non_tet: [(&str, &[(&str, usize)]); 3] = [
        ("can.vtu", &[("hexahedron", 4800)]),
        ("penta_hexa.vtk", &[("pentagonal prism", 60), ("hexagonal prism", 150)]),
        ("notch_disp.vtu", &[("quadratic hexahedron", 2188), ("quadratic wedge", 4)]),
    ];
    for (file, want) in non_tet {
        match read(&real.join(file)) {
            Err(Error::NonTetCells { path, counts }) => {
                assert_eq!(path, real.join(file));
                let want: Vec<(String, usize)> = want.iter().map(|&(s, n)| (s.to_string(), n)).collect();
                assert_eq!(counts, want, "{file}");
            }
            other => panic!("{file}: expected NonTetCells, got {other:?}"),
        }
    }
}

#[test]
fn every_vtk_file_in_the_data_reads() {
    let Some(dir) = require_data("every_vtk_file_in_the_data_reads") else { return };
    let files = vtk_files(&dir);
    assert!(files.len() >= 14, "{files:?}");
    for p in files {
        match read(&p) {
            Ok(m) => assert!(!m.tets.is_empty(), "{}", p.display()),
            Err(Error::NonTetCells { .. }) => {}
            Err(e) => panic!("{e}"),
        }
    }
}

/// Runs the parser, turning a panic into a test failure that names the input.
fn parse_no_panic(bytes: &[u8], path: &Path, what: &str) -> crate::Result<RawMesh> {
    std::panic::catch_unwind(|| parse(bytes, path)).unwrap_or_else(|_| panic!("{}: parser panicked on {what}", path.display()))
}

#[test]
fn truncated_files_fail_cleanly() {
    let Some(dir) = require_data("truncated_files_fail_cleanly") else { return };
    for p in vtk_files(&dir) {
        let bytes = std::fs::read(&p).unwrap();
        // Legacy files have no end marker: data after the last array (METADATA) may go.
        let end = if p.extension().unwrap() == "vtk" {
            bytes.windows(10).rposition(|w| w == b"\nMETADATA\n").filter(|&i| i > bytes.len() - 200)
                .unwrap_or(bytes.len() - usize::from(bytes.ends_with(b"\n")))
        } else {
            bytes.trim_ascii_end().len() // trailing whitespace may go
        };
        let ascii = p.ends_with("penta_hexa.vtk");
        let mut cuts: Vec<usize> = (0..40).map(|k| end * k / 40).collect();
        cuts.extend((1..16).map(|k| end - k));
        cuts.extend([100, 200, 300, 500, 1000, 2000].into_iter().filter(|&c| c < end));
        for cut in cuts {
            // An ASCII file cut inside its last number still ends in a number.
            if ascii && cut + 20 > end {
                continue;
            }
            let r = parse_no_panic(&bytes[..cut], &p, &format!("a cut at {cut}"));
            assert!(r.is_err(), "{} cut at {cut} of {} read without error", p.display(), bytes.len());
        }
    }
}

#[test]
fn corrupted_files_never_panic() {
    use rand::{Rng, SeedableRng};
    let Some(dir) = require_data("corrupted_files_never_panic") else { return };
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let mut errors = 0;
    let mut runs = 0;
    for p in vtk_files(&dir) {
        let bytes = std::fs::read(&p).unwrap();
        for trial in 0..30 {
            let mut b = bytes.clone();
            // Half the trials hit the first 4 KiB, where the structure is.
            let span = if trial % 2 == 0 { b.len().min(4096) } else { b.len() };
            for _ in 0..rng.gen_range(1..8) {
                let i = rng.gen_range(0..span);
                b[i] = rng.gen();
            }
            runs += 1;
            if parse_no_panic(&b, &p, &format!("corruption trial {trial}")).is_err() {
                errors += 1;
            }
        }
    }
    // Flipped bytes inside float data give a valid file with other values; the rest fail.
    assert!(errors > runs / 4, "only {errors} of {runs} corrupted files were rejected");
}

#[test]
fn gigantic_declared_sizes_fail_fast() {
    let Some(dir) = require_data("gigantic_declared_sizes_fail_fast") else { return };
    let t = std::time::Instant::now();
    let vtu = std::fs::read(dir.join("part_s.vtu")).unwrap();
    let legacy = std::fs::read(dir.join("part_s.v42.vtk")).unwrap();
    let patch = |b: &[u8], from: &str, to: &str| -> Vec<u8> {
        let i = b.windows(from.len()).position(|w| w == from.as_bytes()).unwrap();
        [&b[..i], to.as_bytes(), &b[i + from.len()..]].concat()
    };
    let cases = [
        ("part_s.vtu", patch(&vtu, "NumberOfPoints=\"7011\"", "NumberOfPoints=\"1000000000000\"")),
        ("part_s.vtu", patch(&vtu, "NumberOfCells=\"24459\"", "NumberOfCells=\"999999999999999\"")),
        ("part_s.v42.vtk", patch(&legacy, "POINTS 7011", "POINTS 1000000000000")),
        ("part_s.v42.vtk", patch(&legacy, "CELLS 24459 122295", "CELLS 24459 1000000000000000")),
    ];
    for (name, b) in &cases {
        assert!(parse_no_panic(b, Path::new(name), "a gigantic size").is_err());
    }
    // The block header of the first appended array, claiming 2^60 bytes.
    let tag = vtu.windows(13).position(|w| w == b"<AppendedData").unwrap();
    let at = tag + vtu[tag..].iter().position(|&c| c == b'_').unwrap();
    let mut b = vtu.clone();
    b[at + 1..at + 9].copy_from_slice(&(1u64 << 60).to_le_bytes());
    let e = parse_no_panic(&b, Path::new("part_s.vtu"), "a gigantic block").unwrap_err();
    assert!(e.to_string().contains("DataArray 'f'"), "{e}");
    assert!(t.elapsed().as_secs_f64() < 2.0, "{:?}", t.elapsed());
}

