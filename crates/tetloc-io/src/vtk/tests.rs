//! Tests of the VTK readers against the shared data: every file reads, encodings of one mesh
//! agree bit for bit, higher-order and non-tet files, and damaged files fail cleanly.

use crate::test_support::require_data;
use crate::vtk::{legacy as vtk_legacy, vtu};
use std::path::{Path, PathBuf};
use tetloc_core::error::Error;
use tetloc_core::mesh::{FieldLocation, RawMesh};

fn read(path: &Path) -> tetloc_core::Result<RawMesh> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("vtu") => vtu::read(path),
        _ => vtk_legacy::read(path),
    }
}

fn parse(bytes: &[u8], path: &Path) -> tetloc_core::Result<RawMesh> {
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
        let Ok(entries) = std::fs::read_dir(&d) else { continue };
        for e in entries {
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
        let mesh = tetloc_core::Mesh::new(m, file).unwrap_or_else(|e| panic!("{e}"));
        assert!(mesh.info.total_volume > 0.0);
    }
    let post = read(&real.join("post.vtk")).unwrap();
    assert_eq!(field(&post, "Pressure").len(), post.points.len());
    let kiefer = read(&real.join("kiefer.vtu")).unwrap();
    assert_eq!(kiefer.points.len(), 102578);
    assert_eq!(field(&kiefer, "Equivalent (von-Mises) Stress (psi)").len(), 56786);

    // Counted independently from the files' type arrays: mixed meshes load, with their cells
    // counted by type; cells tetloc does not read are refused, counted by type.
    let read_mesh = |p: &Path| read(p).and_then(|raw| tetloc_core::Mesh::new(raw, p.display().to_string()));
    let mixed: [(&str, &[(&str, usize)]); 2] = [
        ("can.vtu", &[("hexahedron", 4800)]),
        ("notch_disp.vtu", &[("quadratic hexahedron", 2188), ("quadratic wedge", 4)]),
    ];
    for (file, want) in mixed {
        let m = read_mesh(&real.join(file)).unwrap_or_else(|e| panic!("{e}"));
        let want: std::collections::BTreeMap<String, usize> = want.iter().map(|&(s, n)| (s.to_string(), n)).collect();
        assert_eq!(m.info.cell_types, want, "{file}");
        assert_eq!(m.n_cells(), want.values().sum::<usize>(), "{file}");
        assert!(m.info.total_volume > 0.0 && m.info.n_degenerate == 0, "{file}");
        eprintln!("{file}: {} cells, {} tangled, {} reoriented", m.n_cells(), m.info.n_tangled, m.info.n_reoriented);
    }
    match read_mesh(&real.join("penta_hexa.vtk")) {
        Err(Error::NonTetCells { path, counts }) => {
            assert_eq!(path, real.join("penta_hexa.vtk"));
            assert_eq!(counts, vec![("pentagonal prism".to_string(), 60), ("hexagonal prism".to_string(), 150)]);
        }
        other => panic!("penta_hexa.vtk: expected NonTetCells, got {other:?}"),
    }
}

#[test]
fn every_vtk_file_in_the_data_reads() {
    let Some(dir) = require_data("every_vtk_file_in_the_data_reads") else { return };
    let files = vtk_files(&dir);
    assert!(files.len() >= 14, "{files:?}");
    for p in files {
        match read(&p) {
            Ok(m) => assert!(!m.tets.is_empty() || m.cells.is_some(), "{}", p.display()),
            Err(Error::NonTetCells { .. }) => {}
            Err(e) => panic!("{e}"),
        }
    }
}

/// Runs the parser, turning a panic into a test failure that names the input.
fn parse_no_panic(bytes: &[u8], path: &Path, what: &str) -> tetloc_core::Result<RawMesh> {
    std::panic::catch_unwind(|| parse(bytes, path))
        .unwrap_or_else(|_| panic!("{}: parser panicked on {what}", path.display()))
}

#[test]
fn truncated_files_fail_cleanly() {
    let Some(dir) = require_data("truncated_files_fail_cleanly") else { return };
    truncations_fail_cleanly(&vtk_files(&dir));
}

/// The fresh-clone counterpart: the files the project's writers make (`written_files`).
#[test]
fn truncated_written_files_fail_cleanly() {
    truncations_fail_cleanly(&written_vtk_files());
}

/// The VTK files of `test_support::written_files`.
fn written_vtk_files() -> Vec<PathBuf> {
    let vtk = |p: &&PathBuf| p.extension().is_some_and(|e| e == "vtu" || e == "vtk");
    crate::test_support::written_files().iter().filter(vtk).cloned().collect()
}

fn truncations_fail_cleanly(files: &[PathBuf]) {
    for p in files {
        let bytes = std::fs::read(p).unwrap();
        // Legacy files have no end marker: data after the last array (METADATA) may go.
        let end = if p.extension().unwrap() == "vtk" {
            bytes
                .windows(10)
                .rposition(|w| w == b"\nMETADATA\n")
                .filter(|&i| i > bytes.len() - 200)
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
            let r = parse_no_panic(&bytes[..cut], p, &format!("a cut at {cut}"));
            assert!(r.is_err(), "{} cut at {cut} of {} read without error", p.display(), bytes.len());
        }
    }
}

#[test]
fn corrupted_files_never_panic() {
    let Some(dir) = require_data("corrupted_files_never_panic") else { return };
    corruptions_never_panic(&vtk_files(&dir));
}

/// The fresh-clone counterpart: the files the project's writers make (`written_files`).
#[test]
fn corrupted_written_files_never_panic() {
    corruptions_never_panic(&written_vtk_files());
}

fn corruptions_never_panic(files: &[PathBuf]) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let mut errors = 0;
    let mut runs = 0;
    for p in files {
        let bytes = std::fs::read(p).unwrap();
        for trial in 0..30 {
            let mut b = bytes.clone();
            // Half the trials hit the first 4 KiB, where the structure is.
            let span = if trial % 2 == 0 { b.len().min(4096) } else { b.len() };
            for _ in 0..rng.gen_range(1..8) {
                let i = rng.gen_range(0..span);
                b[i] = rng.gen();
            }
            runs += 1;
            if parse_no_panic(&b, p, &format!("corruption trial {trial}")).is_err() {
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

/// A grid of `n`³ cubes, 6 tets each (Kuhn split), every vertex jittered (boundary too),
/// with a point and a cell field.
pub(crate) fn jittered_grid(n: usize, seed: u64) -> tetloc_core::Mesh {
    crate::test_support::KuhnGrid::new(n)
        .jitter(0.15, seed)
        .jitter_boundary()
        .vertex_field(|p| p[0] + 2.0 * p[1] - p[2])
        .cell_field("cell id", |t, _| t as f32)
        .mesh("jittered grid")
}

#[test]
fn written_grid_reads_back() {
    use crate::vtk::write as vtu_write;
    let mesh = jittered_grid(12, 1);
    for zlib in [false, true] {
        let path = std::env::temp_dir().join(format!("tetloc-{}-grid-{zlib}.vtu", std::process::id()));
        vtu_write::write_mesh_vtu(&path, &mesh, zlib).unwrap();
        let back = tetloc_core::Mesh::new(vtu::read(&path).unwrap(), "back").unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(back.tets, mesh.tets);
        assert_eq!(back.points, mesh.points);
        assert_eq!(back.fields[1].values, mesh.fields[1].values);
    }
}

/// Higher-order tets keep all their nodes through the VTU writer and reader (raw, zlib and
/// every other encoding) and through a legacy file: the same node rows come back.
#[test]
fn higher_order_tets_round_trip() {
    use crate::test_support::KuhnGrid;
    use crate::vtk::write as vtu_write;
    for order in [2u8, 3] {
        let mesh = KuhnGrid::new(3).jitter(0.1, 2).order(order).mesh("elevated");
        let nodes = mesh.tet_nodes.as_ref().unwrap();
        let same = |back: &tetloc_core::Mesh, what: &str| {
            assert_eq!(back.tets, mesh.tets, "{what}");
            assert_eq!(back.points, mesh.points, "{what}");
            let b = back.tet_nodes.as_ref().unwrap_or_else(|| panic!("{what}: the nodes were dropped"));
            assert_eq!(b.cell_type(), nodes.cell_type(), "{what}");
            assert_eq!(b.table(), nodes.table(), "{what}");
        };
        for zlib in [false, true] {
            let path = std::env::temp_dir().join(format!("tetloc-{}-ho{order}-{zlib}.vtu", std::process::id()));
            vtu_write::write_mesh_vtu(&path, &mesh, zlib).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            std::fs::remove_file(&path).unwrap();
            same(
                &tetloc_core::Mesh::new(vtu::parse(&bytes, &path).unwrap(), "back").unwrap(),
                &format!("order {order} zlib {zlib}"),
            );
            if !zlib {
                for enc in [Enc::AppendedBase64, Enc::BigEndian, Enc::Header32, Enc::Ascii, Enc::Inline] {
                    let raw = vtu::parse(&reencode(&bytes, enc), &path).unwrap();
                    same(&tetloc_core::Mesh::new(raw, "back").unwrap(), &format!("order {order} {enc:?}"));
                }
            }
        }
        // Legacy ASCII, the cells as VTK lists them: count, then the node ids.
        let n = 4 + nodes.n_extra();
        let mut text = format!(
            "# vtk DataFile Version 3.0\nho\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {} float\n",
            mesh.points.len()
        );
        mesh.points.iter().for_each(|p| text += &format!("{:?} {:?} {:?}\n", p[0], p[1], p[2]));
        text += &format!("CELLS {} {}\n", mesh.n_tets(), (n + 1) * mesh.n_tets());
        for (t, &c) in mesh.tets.iter().enumerate() {
            text += &format!("{n} {}\n", nodes.nodes(t, c).map(|i| i.to_string()).collect::<Vec<_>>().join(" "));
        }
        text += &format!("CELL_TYPES {}\n", mesh.n_tets());
        text += &format!("{}\n", nodes.cell_type().def().vtk_type()).repeat(mesh.n_tets());
        let raw = vtk_legacy::parse(text.as_bytes(), Path::new("ho.vtk")).unwrap();
        same(&tetloc_core::Mesh::new(raw, "legacy").unwrap(), &format!("order {order} legacy"));
    }
}

/// Load speed of a ~10M-tet appended raw file (run with `--ignored --nocapture`; set
/// TETLOC_BENCH_KEEP=1 to keep the files in the temp folder).
#[test]
#[ignore]
fn bench_load_10m_tets() {
    use crate::vtk::write as vtu_write;
    use std::time::Instant;
    let t = Instant::now();
    let mesh = jittered_grid(119, 2);
    eprintln!("grid: {} points, {} tets in {:.2?}", mesh.points.len(), mesh.tets.len(), t.elapsed());
    let keep = std::env::var_os("TETLOC_BENCH_KEEP").is_some();
    for (label, zlib, wide) in [("int32", false, false), ("int64", false, true), ("zlib", true, false)] {
        let path = std::env::temp_dir().join(format!("tetloc-bench-10m-{label}.vtu"));
        let t = Instant::now();
        vtu_write::write_mesh(&path, &mesh, &[], zlib, wide).unwrap();
        let w = t.elapsed().as_secs_f64();
        let size = std::fs::metadata(&path).unwrap().len() as f64 / 1e6;
        let (mut best, mut cpu) = (f64::INFINITY, f64::INFINITY);
        let mut raw = None;
        for _ in 0..3 {
            drop(raw.take());
            let (t, c) = (Instant::now(), cpu_seconds());
            raw = Some(vtu::read(&path).unwrap());
            best = best.min(t.elapsed().as_secs_f64());
            cpu = cpu.min(cpu_seconds() - c);
        }
        let raw = raw.unwrap();
        assert_eq!(raw.tets.len(), mesh.tets.len());
        let t = Instant::now();
        let bytes = std::fs::read(&path).unwrap();
        let fs_read = t.elapsed().as_secs_f64();
        drop(bytes);
        eprintln!(
            "{label}: {size:.0} MB written in {w:.2} s ({:.0} MB/s); read in {best:.3} s = {:.0} MB/s, {cpu:.2} s of CPU (fs::read alone {fs_read:.3} s)",
            size / w,
            size / best
        );
        if !keep {
            std::fs::remove_file(&path).unwrap();
        }
    }
}

/// CPU time (user + system) of this process so far, in seconds.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // Fields after the command name (which may hold spaces): utime and stime are 14 and 15.
    let rest = stat.rsplit(')').next().unwrap_or("");
    let f: Vec<f64> = rest.split_whitespace().map(|x| x.parse().unwrap_or(0.0)).collect();
    f.get(11).zip(f.get(12)).map_or(f64::NAN, |(u, s)| (u + s) / 100.0)
}

/// Load time of the VTU file named by $TETLOC_BENCH_FILE (run with --ignored --nocapture).
#[test]
#[ignore]
fn bench_load_file() {
    let Some(p) = std::env::var_os("TETLOC_BENCH_FILE") else { return };
    let size = std::fs::metadata(&p).unwrap().len() as f64 / 1e6;
    for _ in 0..5 {
        let (t, c) = (std::time::Instant::now(), cpu_seconds());
        let m = vtu::read(Path::new(&p)).unwrap();
        let (wall, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
        eprintln!("{size:.0} MB, {} tets: {wall:.3} s = {:.0} MB/s (cpu {cpu:.2} s)", m.tets.len(), size / wall);
    }
}

/// Encodings to re-encode a VTU into, for the encodings the shared data lacks.
#[derive(Clone, Copy, Debug)]
enum Enc {
    AppendedBase64,
    BigEndian,
    Header32,
    Ascii,
    Inline,
}

/// Re-encodes an uncompressed, little-endian, UInt64-header appended-raw VTU whose
/// DataArray tags are self-closing: the values stay, their representation changes.
fn reencode(bytes: &[u8], enc: Enc) -> Vec<u8> {
    use super::num::{Array, NumType};
    use base64::Engine;
    let b64 = |b: &[u8]| base64::engine::general_purpose::STANDARD.encode(b);
    let tag_at = bytes.windows(13).position(|w| w == b"<AppendedData").unwrap();
    let data = &bytes[tag_at + bytes[tag_at..].iter().position(|&c| c == b'_').unwrap() + 1..];
    let head = std::str::from_utf8(&bytes[..tag_at]).unwrap();
    let attr = |tag: &str, key: &str| -> String {
        let i = tag.find(&format!(" {key}=\"")).unwrap() + key.len() + 3;
        tag[i..i + tag[i..].find('"').unwrap()].to_string()
    };
    let mut out = String::new();
    let mut appended: Vec<u8> = Vec::new();
    let mut rest = head;
    let mut k = 0;
    while let Some(i) = rest.find("<DataArray") {
        let end = i + rest[i..].find("/>").unwrap() + 2;
        let tag = &rest[i..end];
        out += &rest[..i];
        rest = &rest[end..];
        let ty = NumType::from_xml(&attr(tag, "type")).unwrap();
        let off: usize = attr(tag, "offset").trim().parse().unwrap();
        let n = u64::from_le_bytes(data[off..off + 8].try_into().unwrap()) as usize;
        let values = &data[off + 8..off + 8 + n];
        let open = tag[..tag.find(" format=").unwrap()].to_string();
        match enc {
            Enc::Ascii => {
                let a = Array { ty, bytes: values.into() };
                let text: Vec<String> = (0..a.len())
                    .map(|j| match ty {
                        NumType::F32 => format!("{:?}", a.get_f64(j) as f32),
                        NumType::F64 => format!("{:?}", a.get_f64(j)),
                        _ => a.get_i64(j).unwrap().to_string(),
                    })
                    .collect();
                out += &format!("{open} format=\"ascii\">\n{}\n</DataArray>", text.join(" "));
            }
            Enc::Inline => {
                let block = [&(n as u64).to_le_bytes()[..], values].concat();
                out += &format!("{open} format=\"binary\">\n{}\n</DataArray>", b64(&block));
            }
            Enc::AppendedBase64 => {
                out += &format!("{open} format=\"appended\" offset=\"{}\"/>", appended.len());
                let header = (n as u64).to_le_bytes();
                // Header and data encoded together, or apart as VTK does.
                let text = if k % 2 == 0 { b64(&[&header[..], values].concat()) } else { b64(&header) + &b64(values) };
                appended.extend_from_slice(text.as_bytes());
            }
            Enc::BigEndian | Enc::Header32 => {
                out += &format!("{open} format=\"appended\" offset=\"{}\"/>", appended.len());
                if let Enc::Header32 = enc {
                    appended.extend_from_slice(&(n as u32).to_le_bytes());
                    appended.extend_from_slice(values);
                } else {
                    appended.extend_from_slice(&(n as u64).to_be_bytes());
                    values.chunks_exact(ty.size()).for_each(|e| appended.extend(e.iter().rev()));
                }
            }
        }
        k += 1;
    }
    out += rest;
    let out = match enc {
        Enc::BigEndian => out.replace("byte_order=\"LittleEndian\"", "byte_order=\"BigEndian\""),
        Enc::Header32 => out.replace("header_type=\"UInt64\"", "header_type=\"UInt32\""),
        _ => out,
    };
    match enc {
        Enc::Ascii | Enc::Inline => (out + "</VTKFile>\n").into_bytes(),
        Enc::AppendedBase64 => {
            let mut v = (out + "<AppendedData encoding=\"base64\">\n   _").into_bytes();
            v.extend_from_slice(&appended);
            v.extend_from_slice(b"\n  </AppendedData>\n</VTKFile>\n");
            v
        }
        _ => {
            let mut v = (out + "<AppendedData encoding=\"raw\">\n   _").into_bytes();
            v.extend_from_slice(&appended);
            v.extend_from_slice(b"\n  </AppendedData>\n</VTKFile>\n");
            v
        }
    }
}

#[test]
fn other_encodings_read_the_same() {
    let Some(dir) = require_data("other_encodings_read_the_same") else { return };
    for name in ["part_s.vtu", "delaunay_s.vtu", "torus_s.vtu"] {
        let bytes = std::fs::read(dir.join(name)).unwrap();
        let first = vtu::parse(&bytes, Path::new(name)).unwrap();
        for enc in [Enc::AppendedBase64, Enc::BigEndian, Enc::Header32, Enc::Ascii, Enc::Inline] {
            let b = reencode(&bytes, enc);
            let m = vtu::parse(&b, Path::new(name)).unwrap_or_else(|e| panic!("{enc:?}: {e}"));
            assert_eq!(m.points, first.points, "{name} {enc:?}");
            assert_eq!(m.tets, first.tets, "{name} {enc:?}");
            assert_eq!(m.fields.len(), first.fields.len());
            for (f, g) in m.fields.iter().zip(&first.fields) {
                assert_eq!(f.name, g.name);
                assert!(
                    f.values.iter().zip(&g.values).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{name} {enc:?} {}",
                    f.name
                );
            }
            // Damaged copies of the re-encoded file fail cleanly too.
            for cut in [b.len() / 3, b.len() / 2, b.len() - 40] {
                assert!(parse_no_panic(&b[..cut], Path::new(name), "a cut").is_err(), "{name} {enc:?} cut at {cut}");
            }
        }
    }
}

/// Writes sample files into $TETLOC_WRITE_DIR for checks with other tools (VTK, ParaView):
/// a jittered grid in each writer variant, and a point set.
#[test]
#[ignore]
fn write_samples() {
    use crate::vtk::write as vtu_write;
    let Some(dir) = std::env::var_os("TETLOC_WRITE_DIR").map(PathBuf::from) else { return };
    std::fs::create_dir_all(&dir).unwrap();
    let mesh = jittered_grid(10, 3);
    for (name, zlib, wide) in
        [("grid", false, false), ("grid_zlib", true, false), ("grid_i64", false, true), ("grid_i64_zlib", true, true)]
    {
        vtu_write::write_mesh(&dir.join(format!("{name}.vtu")), &mesh, &[], zlib, wide).unwrap();
    }
    let pts: Vec<[f32; 3]> = (0..100).map(|i| mesh.tet_center(i * 7)).collect();
    let ids: Vec<i32> = (0..100).map(|i| if i % 10 == 9 { -1 } else { i * 7 }).collect();
    let vals: Vec<f32> = ids.iter().map(|&i| i as f32 * 0.5).collect();
    let (coords, values) = (vtu_write::Coords::F32(&pts), crate::arrays::Values::F32(&vals));
    vtu_write::write_points_vtu(&dir.join("points.vtu"), coords, &ids, Some(("value", values))).unwrap();
}

/// Reads every .vtu/.vtk in $TETLOC_COMPARE_DIR and compares it with $TETLOC_COMPARE_REF:
/// for files written by other tools (VTK) in encodings the shared data lacks.
#[test]
#[ignore]
fn compare_dir() {
    let (Some(dir), Some(reference)) = (std::env::var_os("TETLOC_COMPARE_DIR"), std::env::var_os("TETLOC_COMPARE_REF"))
    else {
        return;
    };
    let first = read(Path::new(&reference)).unwrap();
    for p in vtk_files(Path::new(&dir)) {
        let m = match read(&p) {
            Ok(m) => m,
            Err(e) => panic!("{e}"),
        };
        // Legacy ASCII files hold 6 significant digits: compare those within rounding.
        let tol = if p.extension().unwrap() == "vtk" && std::fs::read(&p).unwrap().windows(6).any(|w| w == b"\nASCII") {
            1e-5
        } else {
            0.0
        };
        let close = |a: &[f32], b: &[f32]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol * y.abs().max(1.0))
        };
        let same_points = close(bytemuck::cast_slice(&m.points), bytemuck::cast_slice(&first.points));
        let same_fields =
            first.fields.iter().all(|g| m.fields.iter().any(|f| f.name == g.name && close(&f.values, &g.values)));
        eprintln!(
            "{}: points {same_points} tets {} fields {same_fields} (tolerance {tol})",
            p.display(),
            m.tets == first.tets
        );
        assert!(same_points && m.tets == first.tets && same_fields, "{}", p.display());
    }
}

/// f64 values that f32 cannot hold, and the mesh with them: a point field of values near
/// zero and a 2-component cell field.
fn with_f64_fields(mut mesh: tetloc_core::Mesh) -> tetloc_core::Mesh {
    use tetloc_core::mesh::{Field, FieldLocation};
    let n = mesh.points.len();
    let g: Vec<f64> = (0..n).map(|i| 1e-9 + i as f64 * 1e-12 + 1.0 / 3.0 * 1e-15).collect();
    mesh.fields.push(Field::from_f64("g", FieldLocation::Vertex, g));
    for c in 0..2 {
        let v = (0..mesh.n_cells()).map(|t| t as f64 / 3.0 + c as f64 * 0.1).collect();
        mesh.fields.push(Field::from_f64(format!("w[{c}]"), FieldLocation::Cell, v));
    }
    assert!(mesh.fields.iter().skip(2).all(|f| f.values64.is_some()));
    mesh
}

/// The f64 fields of `back` are `mesh`'s, bit for bit, and its f32 fields stay f32 only.
fn same_f64_fields(back: &RawMesh, mesh: &tetloc_core::Mesh, what: &str) {
    for f in &mesh.fields {
        let g = back.fields.iter().find(|g| g.name == f.name).unwrap_or_else(|| panic!("{what}: no {}", f.name));
        let bits = |v: &Option<Vec<f64>>| v.as_ref().map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>());
        assert_eq!(bits(&g.values64), bits(&f.values64), "{what}: {}", f.name);
        assert!(g.values.iter().zip(&f.values).all(|(a, b)| a.to_bits() == b.to_bits()), "{what}: {}", f.name);
    }
}

/// A Float64 field that f32 cannot hold reads back exactly from a VTU in every encoding
/// (appended raw, zlib, ascii, inline binary, appended base64, big-endian, UInt32 headers)
/// and from a legacy file (ASCII and binary); Float32 fields get no f64 copy.
#[test]
fn f64_fields_round_trip_exactly() {
    use crate::vtk::write as vtu_write;
    let mesh = with_f64_fields(jittered_grid(3, 4));
    for zlib in [false, true] {
        let path = std::env::temp_dir().join(format!("tetloc-{}-f64-{zlib}.vtu", std::process::id()));
        vtu_write::write_mesh_vtu(&path, &mesh, zlib).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        same_f64_fields(&vtu::parse(&bytes, &path).unwrap(), &mesh, &format!("zlib {zlib}"));
        if !zlib {
            for enc in [Enc::AppendedBase64, Enc::BigEndian, Enc::Header32, Enc::Ascii, Enc::Inline] {
                same_f64_fields(&vtu::parse(&reencode(&bytes, enc), &path).unwrap(), &mesh, &format!("{enc:?}"));
            }
        }
    }
    // Legacy, ASCII and binary (big-endian doubles).
    for binary in [false, true] {
        let mut bytes = format!(
            "# vtk DataFile Version 3.0\nf64\n{}\nDATASET UNSTRUCTURED_GRID\nPOINTS {} float\n",
            if binary { "BINARY" } else { "ASCII" },
            mesh.points.len()
        )
        .into_bytes();
        let put = |bytes: &mut Vec<u8>, text: String| bytes.extend_from_slice(text.as_bytes());
        for p in mesh.points.iter() {
            match binary {
                true => p.iter().for_each(|c| bytes.extend_from_slice(&c.to_be_bytes())),
                false => put(&mut bytes, format!("{:?} {:?} {:?}\n", p[0], p[1], p[2])),
            }
        }
        put(&mut bytes, format!("\nCELLS {} {}\n", mesh.n_tets(), 5 * mesh.n_tets()));
        for t in mesh.tets.iter() {
            match binary {
                true => [4, t[0], t[1], t[2], t[3]].iter().for_each(|i| bytes.extend_from_slice(&i.to_be_bytes())),
                false => put(&mut bytes, format!("4 {} {} {} {}\n", t[0], t[1], t[2], t[3])),
            }
        }
        put(&mut bytes, format!("\nCELL_TYPES {}\n", mesh.n_tets()));
        for _ in mesh.tets.iter() {
            match binary {
                true => bytes.extend_from_slice(&10i32.to_be_bytes()),
                false => put(&mut bytes, "10\n".into()),
            }
        }
        for (section, names, n) in
            [("POINT_DATA", &["f", "g"][..], mesh.points.len()), ("CELL_DATA", &["cell id"][..], mesh.n_tets())]
        {
            put(&mut bytes, format!("\n{section} {n}\n"));
            for name in names {
                let f = mesh.field(name).unwrap();
                let ty = if f.values64.is_some() { "double" } else { "float" };
                put(&mut bytes, format!("SCALARS {} {ty} 1\nLOOKUP_TABLE default\n", name.replace(' ', "%20")));
                for i in 0..n {
                    match (binary, f.values64.is_some()) {
                        (true, true) => bytes.extend_from_slice(&f.value64(i).to_be_bytes()),
                        (true, false) => bytes.extend_from_slice(&f.values[i].to_be_bytes()),
                        (false, true) => put(&mut bytes, format!("{:?}\n", f.value64(i))),
                        (false, false) => put(&mut bytes, format!("{:?}\n", f.values[i])),
                    }
                }
            }
            if section == "CELL_DATA" {
                put(&mut bytes, "FIELD FieldData 1\n".into());
                put(&mut bytes, format!("w 2 {n} double\n"));
                let w: [&tetloc_core::Field; 2] = [mesh.field("w[0]").unwrap(), mesh.field("w[1]").unwrap()];
                for i in 0..n {
                    for f in w {
                        match binary {
                            true => bytes.extend_from_slice(&f.value64(i).to_be_bytes()),
                            false => put(&mut bytes, format!("{:?}\n", f.value64(i))),
                        }
                    }
                }
            }
        }
        let back = vtk_legacy::parse(&bytes, Path::new("f64.vtk")).unwrap_or_else(|e| panic!("binary {binary}: {e}"));
        same_f64_fields(&back, &mesh, &format!("legacy binary {binary}"));
    }
}

/// Cell types tetloc does not read are refused, counted by type; an unknown type code is named.
#[test]
fn unsupported_cells_are_refused_counted_by_type() {
    // A legacy file with a hex, a voxel and a polyhedron-free pentagonal prism.
    let legacy = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 8 float\n\
        0 0 0 1 0 0 0 1 0 1 1 0 0 0 1 1 0 1 0 1 1 1 1 1\nCELLS 3 27\n8 0 1 3 2 4 5 7 6\n8 0 1 2 3 4 5 6 7\n8 0 1 3 2 4 5 7 6\n\
        CELL_TYPES 3\n12\n11\n11\n";
    match vtk_legacy::parse(legacy.as_bytes(), Path::new("bad.vtk")) {
        Err(Error::NonTetCells { counts, .. }) => {
            // Only the types tetloc does not read: the hexahedron it reads is not listed.
            assert_eq!(counts, vec![("voxel".to_string(), 2)]);
        }
        other => panic!("expected NonTetCells, got {other:?}"),
    }
    let e = vtk_legacy::parse(legacy.replace("\n11\n11\n", "\n12\n200\n").as_bytes(), Path::new("bad.vtk"));
    assert!(e.unwrap_err().to_string().contains("200"));
}

/// A polyhedral mesh written (VTK 9.4's face arrays) and read back: the same cells, types,
/// faces and located cells; in the older `faces` stream too, and refused without faces.
#[test]
fn polyhedra_round_trip_through_vtu() {
    let Some(dir) = tetloc_testdata::require_data("polyhedra_round_trip_through_vtu") else { return };
    let mesh = crate::read_mesh(&dir.join("poly/octpoly_s.vtu"), None).unwrap();
    let block = &mesh.cells.as_ref().unwrap().block;
    assert_eq!(block.polyhedra.len(), 32);
    let tmp = std::env::temp_dir().join(format!("tetloc-poly-rt-{}.vtu", std::process::id()));
    crate::vtk::write::write_mesh_vtu(&tmp, &mesh, true).unwrap();
    let back = crate::read_mesh(&tmp, None);
    std::fs::remove_file(&tmp).unwrap();
    let back = back.unwrap();
    let b = &back.cells.as_ref().unwrap().block;
    assert_eq!((&b.types, &b.polyhedra), (&block.types, &block.polyhedra));
    assert_eq!(back.info.cell_types, mesh.info.cell_types);
    assert_eq!(back.info.n_polyhedron_faces, 312);
}

#[test]
fn polyhedra_in_the_older_faces_stream() {
    use crate::vtk::cells::{faces_from_arrays, faces_from_stream, POLYHEDRON};
    // Cells: a hex (no faces), then a tet-shaped polyhedron of 4 triangles.
    let types = [12, POLYHEDRON];
    let stream = [4, 3, 8, 9, 10, 3, 8, 11, 9, 3, 9, 11, 10, 3, 8, 10, 11];
    let a = faces_from_stream(&types, &stream, 12).unwrap();
    let conn = [8, 9, 10, 8, 11, 9, 9, 11, 10, 8, 10, 11];
    let b = faces_from_arrays(&types, &conn, &[3, 6, 9, 12], &[0, 1, 2, 3], &[0, 4], 12).unwrap();
    assert_eq!(a, b);
    assert_eq!(a.faces(0).collect::<Vec<_>>(), vec![&[8, 9, 10][..], &[8, 11, 9], &[9, 11, 10], &[8, 10, 11]]);
    assert!(faces_from_stream(&types, &stream[..10], 12).unwrap_err().contains("ends"));
    assert!(faces_from_stream(&types, &stream, 10).unwrap_err().contains("not a point id"));
    assert!(faces_from_arrays(&types, &conn, &[3, 6, 9, 12], &[0, 1, 2, 7], &[0, 4], 12)
        .unwrap_err()
        .contains("face 7"));
}

/// A legacy file (≤ 4.2) with a polyhedron: its CELLS entry is its face stream.
#[test]
fn legacy_polyhedra_read_from_their_face_stream() {
    use tetloc_core::BatchLocator;
    let points: String = (0..12).map(|p| format!("{} {} {}\n", p % 3, (p / 3) % 2, p / 6)).collect();
    let legacy = format!(
        "# vtk DataFile Version 4.2\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 12 double\n{points}\
         CELLS 2 41\n8 0 1 4 3 6 7 10 9\n31 6 4 1 4 10 7 4 2 5 11 8 4 1 2 8 7 4 4 5 11 10 4 1 2 5 4 4 7 8 11 10\n\
         CELL_TYPES 2\n12\n42\nCELL_DATA 2\nSCALARS c double 1\nLOOKUP_TABLE default\n5 7\n"
    );
    let raw = vtk_legacy::parse(legacy.as_bytes(), Path::new("poly.vtk")).unwrap();
    let mesh = std::sync::Arc::new(tetloc_core::Mesh::new(raw, "poly.vtk").unwrap());
    assert_eq!(mesh.info.cell_types.get("polyhedron"), Some(&1));
    let cpu = tetloc_core::locate::CpuLocator::new(mesh.clone());
    let mut loc = tetloc_core::locate::CellLocator::new(cpu, mesh);
    let (mut ids, mut v) = (vec![0; 3], vec![0f32; 3]);
    loc.locate_and_sample(&[[0.5, 0.5, 0.5], [1.5, 0.2, 0.7], [2.5, 0.5, 0.5]], "c", &mut ids, &mut v).unwrap();
    assert_eq!(ids, [0, 1, -1]);
    assert_eq!(&v[..2], &[5.0, 7.0]);
    // A face stream that runs short is an error naming the cell.
    let short = legacy.replace("31 6 4 1", "31 7 4 1");
    let e = vtk_legacy::parse(short.as_bytes(), Path::new("poly.vtk")).unwrap_err().to_string();
    assert!(e.contains("cell 1"), "{e}");
}
