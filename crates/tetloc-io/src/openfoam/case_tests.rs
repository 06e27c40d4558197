//! Decomposed cases, time steps, and VTK's reader on the same cases. Cases are written here:
//! a polyMesh (read from `poly/octpoly_s_case`, or a generated grid of hexes), its fields at
//! several times, and its decomposition as `decomposePar` writes it.

use super::foam::Foam;
use super::*;
use tetloc_testdata::foam_case::{decompose, hex_grid, write_case, Poly};

/// `poly/octpoly_s_case`'s mesh (257 hexes, 32 polyhedra), with fields `lin` (its file's) and
/// a vector `U`, at the times 0, 0.5 and 1 (`lin` scaled by 1, 2, 3).
fn octpoly(test: &str) -> Option<Poly> {
    let dir = tetloc_testdata::require_data(test)?.join("poly/octpoly_s_case");
    let mesh = dir.join("constant/polyMesh");
    let open = |n: &str| Foam::new(std::fs::read(mesh.join(n)).unwrap()).unwrap();
    let xyz = open("points").values(3, "points").unwrap();
    let (ends, labels) = open("faces").faces().unwrap();
    let mut faces = Vec::new();
    let mut start = 0;
    for e in ends {
        faces.push(labels[start..e as usize].iter().map(|&l| l as u32).collect());
        start = e as usize;
    }
    let cells = |n: &str| open(n).labels(n).unwrap().into_iter().map(|l| l as u32).collect::<Vec<u32>>();
    let patches = open("boundary").patches().unwrap().into_iter().map(|p| (p.name, p.ty, p.start, p.n_faces)).collect();
    let lin = read_fields(&dir.join("0"), 289).unwrap().remove(0).1;
    let times = [("0", 1.0), ("0.5", 2.0), ("1", 3.0)]
        .map(|(t, s)| {
            let u = lin.iter().enumerate().flat_map(|(c, v)| [s * v, c as f64, -s]).collect();
            (
                t.to_string(),
                vec![
                    ("U".into(), "volVectorField".into(), u),
                    ("lin".into(), "volScalarField".into(), lin.iter().map(|v| s * v).collect()),
                ],
            )
        })
        .to_vec();
    Some(Poly {
        points: xyz.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        faces,
        owner: cells("owner"),
        neighbour: cells("neighbour"),
        patches,
        times,
    })
}

/// [`octpoly`] written as a case in a fresh folder (removed with the guard).
fn octpoly_case(test: &str) -> Option<(Poly, tempfile::TempDir)> {
    let poly = octpoly(test)?;
    let dir = tempfile::tempdir().unwrap();
    write_case(dir.path(), &poly, None);
    Some((poly, dir))
}

/// Processors of octpoly's cells: scattered (cell `c` on `c * 7 % 3`), so most faces are
/// between processors and every processor borders every other.
fn scattered(n: usize) -> Vec<usize> {
    (0..n).map(|c| c * 7 % 3).collect()
}

/// The cells of processor 0, then of 1 and 2 (`proc_of`: each cell's processor): the order of
/// a decomposed case's cells read without cellProcAddressing, and VTK's.
fn processor_order(proc_of: &[usize]) -> Vec<usize> {
    (0..3).flat_map(|k| (0..proc_of.len()).filter(move |&c| proc_of[c] == k)).collect()
}

/// Cell `c`'s centre: the mean of its distinct points.
fn centre(raw: &RawMesh, c: usize) -> [f32; 3] {
    let (_, pts) = cell_shape(raw, c);
    let s = pts.iter().fold([0.0; 3], |s, p| [0, 1, 2].map(|i| s[i] + f64::from_bits(p[i])));
    s.map(|x| (x / pts.len() as f64) as f32)
}

/// The cell `c` of `raw`: its type and its distinct points' coordinates, sorted (compares
/// cells across point numberings).
fn cell_shape(raw: &RawMesh, c: usize) -> (u8, Vec<[u64; 3]>) {
    cell_shape_as(raw, c, f64::to_bits)
}

/// [`cell_shape`] with the coordinates as `bits` gives them.
fn cell_shape_as(raw: &RawMesh, c: usize, bits: impl Fn(f64) -> u64) -> (u8, Vec<[u64; 3]>) {
    let b = raw.cells.as_ref().unwrap();
    let p64 = |i: u32| raw.points64.as_ref().map_or(raw.points[i as usize].map(f64::from), |p| p[i as usize]);
    let mut pts: Vec<[u64; 3]> = b.nodes(c).iter().map(|&i| p64(i).map(&bits)).collect();
    pts.sort_unstable();
    pts.dedup();
    (b.types[c].def().vtk_type(), pts)
}

fn mesh_of(raw: RawMesh, name: &str) -> tetloc_core::Mesh {
    tetloc_core::Mesh::new(raw, name).unwrap()
}

#[test]
fn decomposed_cases_read_as_the_undecomposed_mesh() {
    let test = "decomposed_cases_read_as_the_undecomposed_mesh";
    let Some(poly) = octpoly(test) else { return };
    let dir = tempfile::tempdir().unwrap();
    write_case(&dir.path().join("whole"), &poly, None);
    let whole = dir.path().join("whole/whole.foam");
    std::fs::write(&whole, "").unwrap();
    let proc_of = scattered(poly.n_cells());
    for addressing in [true, false] {
        let case = dir.path().join(format!("cut-{addressing}"));
        decompose(&case, &poly, &proc_of, addressing);
        let (a, sa) = crate::read_series(&whole, None).unwrap();
        // The folder has only processor*/: read as decomposed, through the folder too.
        let (b, sb) = crate::read_series(&case, None).unwrap();
        let (sa, sb) = (sa.unwrap(), sb.unwrap());
        assert_eq!(sa.times, [0.5, 1.0], "the zero time is skipped");
        assert_eq!(sb.times, sa.times);
        assert_eq!(b.points.len(), a.points.len(), "addressing {addressing}: shared points merged");
        let n = poly.n_cells();
        // Cell order: the undecomposed one with cellProcAddressing, processor order without.
        let order: Vec<usize> = if addressing { (0..n).collect() } else { processor_order(&proc_of) };
        for (j, &c) in order.iter().enumerate() {
            assert_eq!(cell_shape(&b, j), cell_shape(&a, c), "addressing {addressing}: cell {j}");
        }
        if addressing {
            // Cells list their faces in another order (a processor's boundary faces come last).
            assert_eq!((&b.points, &b.points64), (&a.points, &a.points64), "the undecomposed numbering, exactly");
        }
        for k in 0..2 {
            let (fa, fb) = (sa.fields(k).unwrap(), sb.fields(k).unwrap());
            assert_eq!(fb.iter().map(|f| &f.name).collect::<Vec<_>>(), ["U[0]", "U[1]", "U[2]", "lin"]);
            for (x, y) in fa.iter().zip(&fb) {
                let ys: Vec<f64> = order.iter().map(|&c| x.value64(c)).collect();
                assert_eq!((0..n).map(|j| y.value64(j)).collect::<Vec<_>>(), ys, "step {k} {}", y.name);
            }
        }
        // No cracks: the decomposition has the boundary of the whole.
        let (ma, mb) = (mesh_of(a, "whole"), mesh_of(b, "cut"));
        assert_eq!(mb.summary().faces.n_boundary, ma.summary().faces.n_boundary, "addressing {addressing}");
        // And every cell's centroid is found in it.
        let mb = std::sync::Arc::new(mb);
        let cpu = tetloc_core::locate::CpuLocator::new(mb.clone());
        let mut loc = tetloc_core::locate::CellLocator::new(cpu, mb.clone());
        let cut = crate::read_raw(&case, None).unwrap();
        let centres: Vec<[f32; 3]> = (0..n).map(|j| centre(&cut, j)).collect();
        let mut ids = vec![0; n];
        use tetloc_core::BatchLocator;
        loc.locate(&centres, &mut ids).unwrap();
        assert_eq!(ids, (0..n as i32).collect::<Vec<_>>(), "addressing {addressing}");
    }
}

#[test]
fn the_layout_is_chosen_and_every_file_is_an_input() {
    let Some((poly, dir)) = octpoly_case("the_layout_is_chosen_and_every_file_is_an_input") else { return };
    decompose(dir.path(), &poly, &(0..poly.n_cells()).map(|c| usize::from(c >= 100)).collect::<Vec<_>>(), false);
    let foam = dir.path().join("c.foam");
    std::fs::write(&foam, "").unwrap();
    // Both: reconstructed by default (ParaView's default), decomposed when asked.
    let a = crate::read_raw(&foam, None).unwrap();
    let b = crate::read_raw(&foam, Some(crate::MeshFormat::OpenFoamDecomposed)).unwrap();
    let c = crate::read_raw(&foam, crate::MeshFormat::from_name("foam-decomposed")).unwrap();
    assert_eq!((&b.points, &b.cells), (&c.points, &c.cells));
    assert_eq!(a.points.len(), b.points.len());
    let files = crate::input_files(&foam, Some(crate::MeshFormat::OpenFoamDecomposed));
    for want in ["processor1/constant/polyMesh/owner", "processor0/0.5/lin", "processor1/1/U", "c.foam"] {
        assert!(files.contains(&dir.path().join(want)), "{want} in {files:?}");
    }
    assert!(!files.contains(&dir.path().join("constant/polyMesh/owner")));
    let files = crate::input_files(&foam, None);
    assert!(files.contains(&dir.path().join("constant/polyMesh/owner")) && files.contains(&dir.path().join("0/lin")));
}

#[test]
fn bad_decomposed_cases_name_the_file() {
    let test = "bad_decomposed_cases_name_the_file";
    let Some(poly) = octpoly(test) else { return };
    let dir = tempfile::tempdir().unwrap();
    let err = |tag: &str, spoil: &dyn Fn(&Path)| {
        let case = dir.path().join(tag);
        decompose(&case, &poly, &scattered(poly.n_cells()), true);
        spoil(&case);
        let e = crate::read_series(&case, None).and_then(|(_, s)| s.unwrap().fields(1)).unwrap_err().to_string();
        e.replace(&case.display().to_string(), "CASE")
    };
    // A processor without its owner file.
    let e = err("owner", &|c| std::fs::remove_file(c.join("processor1/constant/polyMesh/owner")).unwrap());
    assert!(e.contains("CASE/processor1/constant/polyMesh") && e.contains("no 'owner' file"), "{e}");
    // Processors that disagree on the times.
    let e = err("times", &|c| std::fs::remove_dir_all(c.join("processor2/0.5")).unwrap());
    assert!(e.contains("CASE/processor2") && e.contains("has the times [1]") && e.contains("[0.5, 1]"), "{e}");
    // ... on the fields.
    let e = err("fields", &|c| std::fs::remove_file(c.join("processor1/1/U")).unwrap());
    assert!(e.contains("CASE/processor1/1") && e.contains("no field 'U'") && e.contains("processors disagree"), "{e}");
    // Addressing that does not fit.
    let e = err("addr", &|c| {
        let f = c.join("processor0/constant/polyMesh/cellProcAddressing");
        let text = std::fs::read_to_string(&f).unwrap().replacen("\n0\n", "\n1\n", 1);
        std::fs::write(f, text).unwrap()
    });
    assert!(
        e.contains("/constant/polyMesh/cellProcAddressing") && e.contains("is cell 1 of the case, as another cell is"),
        "{e}"
    );
    // A missing processor, and a collated case.
    let e = err("gap", &|c| std::fs::rename(c.join("processor1"), c.join("old")).unwrap());
    assert!(e.contains("processor1 is missing"), "{e}");
    let collated = dir.path().join("collated");
    std::fs::create_dir_all(collated.join("processors3/constant")).unwrap();
    let e = crate::read_raw(&collated, Some(crate::MeshFormat::OpenFoamDecomposed)).unwrap_err().to_string();
    assert!(e.contains("collated") && e.contains("processors3"), "{e}");
}

#[test]
fn time_steps_are_the_time_directories() {
    let Some((poly, dir)) = octpoly_case("time_steps_are_the_time_directories") else { return };
    let (raw, steps) = crate::read_series(dir.path(), None).unwrap();
    let steps = steps.unwrap();
    assert_eq!(steps.times, [0.5, 1.0]);
    let lin0 = read_fields(&dir.path().join("0"), 289).unwrap().pop().unwrap().1;
    let lin = |fields: &[Field]| {
        let f = fields.iter().find(|f| f.name == "lin").unwrap();
        (0..f.values.len()).map(|i| f.value64(i)).collect::<Vec<f64>>()
    };
    // The mesh holds the first step's fields; each step reads its own.
    assert_eq!(lin(&raw.fields), lin0.iter().map(|v| 2.0 * v).collect::<Vec<_>>());
    assert_eq!(lin(&steps.fields(1).unwrap()), lin0.iter().map(|v| 3.0 * v).collect::<Vec<_>>());
    assert_eq!(steps.field("U[2]", 1).unwrap().values, vec![-3.0; 289]);
    // A field missing at a later time: an error naming the time directory.
    std::fs::remove_file(dir.path().join("1/U")).unwrap();
    let e = steps.fields(1).unwrap_err().to_string();
    assert!(
        e.contains(&dir.path().join("1").display().to_string())
            && e.contains("no field 'U'")
            && e.contains("time 0.5 has it"),
        "{e}"
    );
    // A case with only the zero time: that is its one step.
    let only = tempfile::tempdir().unwrap();
    write_case(only.path(), &Poly { times: poly.times[..1].to_vec(), ..poly.clone() }, None);
    assert_eq!(crate::read_series(only.path(), None).unwrap().1.unwrap().times, [0.0]);
}

/// Runs `scripts/vtk_openfoam.py` on `case`: VTK's view of it.
fn vtk_view(test: &str, case: &Path, decomposed: bool) -> Option<serde_json::Value> {
    let out = case.join("vtk.json");
    let foam = case.join("vtk.foam");
    std::fs::write(&foam, "").unwrap();
    let mut args = vec![foam.to_str().unwrap(), out.to_str().unwrap()];
    if decomposed {
        args.push("decomposed");
    }
    tetloc_testdata::run_vtk_script(test, "vtk_openfoam.py", &args)?;
    let v = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    std::fs::remove_file(foam).unwrap();
    Some(v)
}

/// VTK's reader gives float32 points: coordinates compared so.
fn f32_bits(x: f64) -> u64 {
    u64::from((x as f32).to_bits())
}

/// Checks tetloc's reading of `case` against VTK's: times, cells (type and points, in VTK's
/// order: `order[j]` is VTK's cell `j`), fields per time (VTK reads them as float32).
fn agree_with_vtk(test: &str, case: &Path, decomposed: bool, order: &[usize], vtk_points: usize) {
    let Some(vtk) = vtk_view(test, case, decomposed) else { return };
    let format = decomposed.then_some(crate::MeshFormat::OpenFoamDecomposed);
    let (raw, steps) = crate::read_series(case, format).unwrap();
    let steps = steps.unwrap();
    let times: Vec<f64> = vtk["times"].as_array().unwrap().iter().map(|t| t.as_f64().unwrap()).collect();
    assert_eq!(steps.times, times, "{test}: times");
    assert_eq!(vtk["n_points"].as_u64().unwrap() as usize, vtk_points, "{test}: VTK's points");
    let cells = vtk["cells"].as_array().unwrap();
    assert_eq!(cells.len(), order.len(), "{test}: cells");
    for (j, c) in cells.iter().enumerate() {
        let ty = c[0].as_u64().unwrap() as u8;
        let mut pts: Vec<[u64; 3]> =
            c[1].as_array().unwrap().iter().map(|p| [0, 1, 2].map(|i| f32_bits(p[i].as_f64().unwrap()))).collect();
        pts.sort_unstable();
        pts.dedup();
        assert_eq!(cell_shape_as(&raw, order[j], f32_bits), (ty, pts), "{test}: VTK's cell {j}");
    }
    for k in 0..steps.len() {
        let ours = steps.fields(k).unwrap();
        let theirs = vtk["steps"][k].as_object().unwrap();
        let mut names: Vec<&String> = theirs.keys().collect();
        names.sort();
        let mut our_names: Vec<String> = ours.iter().map(|f| f.name.split('[').next().unwrap().to_string()).collect();
        our_names.dedup();
        our_names.sort();
        assert_eq!(names, our_names.iter().collect::<Vec<_>>(), "{test}: fields at step {k}");
        for (name, values) in theirs {
            let values: Vec<f64> = values.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
            let comps: Vec<&Field> =
                ours.iter().filter(|f| f.name == *name || f.name.starts_with(&format!("{name}["))).collect();
            let k_comps = comps.len();
            for (j, &c) in order.iter().enumerate() {
                for (i, f) in comps.iter().enumerate() {
                    // VTK holds the values in float32 or float64: equal to float32's rounding.
                    let (got, want) = (values[j * k_comps + i], f.value64(c));
                    assert!((got - want).abs() <= 1e-6 * want.abs(), "{test}: {name} step {k} cell {j}: {got} {want}");
                }
            }
        }
    }
}

#[test]
fn vtk_reads_the_octpoly_case_alike() {
    let test = "vtk_reads_the_octpoly_case_alike";
    let Some(dir) = tetloc_testdata::require_data(test) else { return };
    let case = tempfile::tempdir().unwrap();
    // The data set's case, copied (the script writes beside it).
    let src = dir.join("poly/octpoly_s_case");
    for sub in ["constant/polyMesh", "0", "1", "system"] {
        std::fs::create_dir_all(case.path().join(sub)).unwrap();
        for e in std::fs::read_dir(src.join(sub)).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), case.path().join(sub).join(e.file_name())).unwrap();
        }
    }
    agree_with_vtk(test, case.path(), false, &(0..289).collect::<Vec<_>>(), 476);
}

#[test]
fn vtk_reads_a_generated_and_a_decomposed_case_alike() {
    let test = "vtk_reads_a_generated_and_a_decomposed_case_alike";
    let Some((poly, dir)) = octpoly_case(test) else { return };
    let n = poly.n_cells();
    agree_with_vtk(test, dir.path(), false, &(0..n).collect::<Vec<_>>(), poly.points.len());
    // Decomposed: VTK lists each processor's cells (and points) in turn, unmerged; tetloc's
    // cells are in the undecomposed order (cellProcAddressing).
    let proc_of = scattered(n);
    decompose(dir.path(), &poly, &proc_of, true);
    let order = processor_order(&proc_of);
    let vtk_points = (0..3)
        .map(|k| PolyMesh::read(&dir.path().join(format!("processor{k}/constant/polyMesh"))).unwrap().points64.len())
        .sum();
    agree_with_vtk(test, dir.path(), true, &order, vtk_points);
}

/// A decomposed case's processors, read as pieces (`crate::parts`) and joined as the MPI path
/// joins a rank's pieces, give the mesh that reading the whole case gives: every cell's
/// centroid is found in the cell of its global id, with that cell's value of `lin`; with
/// `pointProcAddressing` the processors are welded (the boundary is the whole's).
#[test]
fn processors_are_the_pieces_of_a_partitioned_case() {
    use crate::parts;
    let poly = hex_grid(4);
    let dir = tempfile::tempdir().unwrap();
    let proc_of = scattered(poly.n_cells());
    for addressing in [true, false] {
        let case = dir.path().join(format!("cut-{addressing}"));
        decompose(&case, &poly, &proc_of, addressing);
        let foam = case.join("cut.foam");
        std::fs::write(&foam, "").unwrap();
        assert!(parts::is_partitioned(&foam) && parts::is_partitioned(&case));
        let files = parts::list(&foam).unwrap();
        assert_eq!(files.len(), 3);
        let read: Vec<_> =
            files.iter().enumerate().map(|(k, f)| (k, parts::read_piece(&foam, k, f).unwrap())).collect();
        assert_eq!(read.iter().all(|(_, p)| p.global_ids.is_some()), addressing);
        let counts: Vec<u64> = read.iter().map(|(_, p)| p.n_cells() as u64).collect();
        let first: Vec<u64> = counts.iter().scan(0, |a, &c| Some(std::mem::replace(a, *a + c))).collect();
        let (joined, ids) = crate::vtk::pieces::join(&foam, read, &first).unwrap();
        let centres: Vec<[f32; 3]> = (0..ids.len()).map(|c| centre(&joined, c)).collect();
        let whole = mesh_of(crate::read_raw(&foam, None).unwrap(), "whole");
        let parts_mesh = mesh_of(joined, "parts");
        assert_eq!(parts_mesh.n_cells(), whole.n_cells());
        if addressing {
            assert_eq!(parts_mesh.summary().faces.n_boundary, whole.summary().faces.n_boundary, "welded");
        }
        let whole = std::sync::Arc::new(whole);
        let loc = tetloc_core::CpuLocator::new(whole.clone());
        let (lin_parts, lin_whole) = (parts_mesh.field("lin").unwrap(), whole.field("lin").unwrap());
        let mut seen = vec![false; ids.len()];
        for (c, &g) in ids.iter().enumerate() {
            let found = loc.locate_point(centres[c]).map(|(t, _)| whole.cell_of_tet(t as usize));
            assert_eq!(found, Some(g as usize), "addressing {addressing}: cell {c}");
            assert_eq!(lin_parts.values[c], lin_whole.values[g as usize], "addressing {addressing}: cell {c}");
            seen[g as usize] = true;
        }
        assert!(seen.iter().all(|&s| s), "every cell once");
    }
    // A case without processors is not partitioned, and says so.
    let plain = dir.path().join("plain");
    write_case(&plain, &poly, None);
    assert!(!parts::is_partitioned(&plain));
    let e = parts::list(&plain).unwrap_err().to_string();
    assert!(e.contains("not partitioned") && e.contains("processor"), "{e}");
}
