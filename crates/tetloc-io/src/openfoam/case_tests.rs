//! Decomposed cases, time steps, and VTK's reader on the same cases. Cases are written here:
//! a polyMesh (read from `poly/octpoly_s_case`, or a generated grid of hexes), its fields at
//! several times, and its decomposition as `decomposePar` writes it.

use super::foam::Foam;
use super::*;
use std::collections::BTreeMap;

/// A field file: name, class, values (components interleaved).
type FieldFile = (String, String, Vec<f64>);

/// A polyMesh as its files hold it, and its fields by time.
#[derive(Clone)]
struct Poly {
    points: Vec<[f64; 3]>,
    faces: Vec<Vec<u32>>,
    owner: Vec<u32>,
    neighbour: Vec<u32>,
    /// (name, type, first face, face count)
    patches: Vec<(String, String, usize, usize)>,
    times: Vec<(String, Vec<FieldFile>)>,
}

impl Poly {
    fn n_cells(&self) -> usize {
        self.owner.iter().map(|&c| c as usize + 1).max().unwrap()
    }
}

/// A fresh folder, removed at the end.
struct Dir(PathBuf);
impl Dir {
    fn new(tag: &str) -> Dir {
        let d = std::env::temp_dir().join(format!("tetloc-foamcase-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        Dir(d)
    }
}
impl Drop for Dir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn header(class: &str, object: &str) -> String {
    format!("FoamFile\n{{\n    version 2.0;\n    format ascii;\n    class {class};\n    object {object};\n}}\n\n")
}

fn list<T: ToString>(v: &[T]) -> String {
    format!("{}\n(\n{}\n)\n", v.len(), v.iter().map(T::to_string).collect::<Vec<_>>().join("\n"))
}

/// Writes `p`'s mesh into `dir/constant/polyMesh` (with the addressing files given) and its
/// time directories into `dir`.
fn write_poly(dir: &Path, p: &Poly, addressing: Option<(&[u32], &[u32])>) {
    let mesh = dir.join("constant/polyMesh");
    std::fs::create_dir_all(&mesh).unwrap();
    let put = |name: &str, class: &str, body: String| {
        std::fs::write(mesh.join(name), header(class, name) + &body).unwrap();
    };
    let pts: Vec<String> = p.points.iter().map(|q| format!("({:?} {:?} {:?})", q[0], q[1], q[2])).collect();
    put("points", "vectorField", list(&pts));
    let faces: Vec<String> = p
        .faces
        .iter()
        .map(|f| format!("{}({})", f.len(), f.iter().map(u32::to_string).collect::<Vec<_>>().join(" ")))
        .collect();
    put("faces", "faceList", list(&faces));
    put("owner", "labelList", list(&p.owner));
    put("neighbour", "labelList", list(&p.neighbour));
    let patches: Vec<String> = p
        .patches
        .iter()
        .map(|(name, ty, start, n)| format!("{name}\n{{\n    type {ty};\n    nFaces {n};\n    startFace {start};\n}}"))
        .collect();
    put("boundary", "polyBoundaryMesh", list(&patches));
    if let Some((points, cells)) = addressing {
        put("pointProcAddressing", "labelList", list(points));
        put("cellProcAddressing", "labelList", list(cells));
    }
    for (t, fields) in &p.times {
        let d = dir.join(t);
        std::fs::create_dir_all(&d).unwrap();
        for (name, class, values) in fields {
            let k = if class == "volVectorField" { 3 } else { 1 };
            let rows: Vec<String> = values
                .chunks(k)
                .map(|c| if k == 1 { format!("{:?}", c[0]) } else { format!("({:?} {:?} {:?})", c[0], c[1], c[2]) })
                .collect();
            let ty = if k == 1 { "scalar" } else { "vector" };
            let body = format!(
                "dimensions [0 0 0 0 0 0 0];\ninternalField nonuniform List<{ty}> {}boundaryField\n{{\n    \".*\" {{ type zeroGradient; }}\n}}\n",
                list(&rows).trim_end().to_string() + ";\n"
            );
            std::fs::write(d.join(name), header(class, name) + &body).unwrap();
        }
    }
}

/// Cuts `p` into processors by `proc_of` (a processor per cell), as decomposePar does: each
/// processor's cells in ascending order, its points in ascending order, its internal faces,
/// then its share of each patch, then one `processor` patch per neighbouring processor (faces
/// in ascending order, turned so that the processor's cell owns them). Writes `processorK/`
/// into `case`, with the addressing files when asked.
fn decompose(case: &Path, p: &Poly, proc_of: &[usize], addressing: bool) {
    let n_procs = proc_of.iter().max().unwrap() + 1;
    for k in 0..n_procs {
        let cells: Vec<u32> = (0..p.n_cells() as u32).filter(|&c| proc_of[c as usize] == k).collect();
        let local_cell: BTreeMap<u32, u32> = cells.iter().enumerate().map(|(i, &c)| (c, i as u32)).collect();
        let mut faces: Vec<(Vec<u32>, u32, Option<u32>)> = Vec::new();
        let on = |c: u32| proc_of[c as usize] == k;
        // Internal faces within the processor.
        for (f, &nb) in p.neighbour.iter().enumerate() {
            let o = p.owner[f];
            if on(o) && on(nb) {
                faces.push((p.faces[f].clone(), local_cell[&o], Some(local_cell[&nb])));
            }
        }
        let n_internal = faces.len();
        let mut patches = Vec::new();
        for (name, ty, start, n) in &p.patches {
            let first = faces.len();
            for f in *start..start + n {
                if on(p.owner[f]) {
                    faces.push((p.faces[f].clone(), local_cell[&p.owner[f]], None));
                }
            }
            patches.push((name.clone(), ty.clone(), first, faces.len() - first));
        }
        for q in (0..n_procs).filter(|&q| q != k) {
            let first = faces.len();
            for (f, &nb) in p.neighbour.iter().enumerate() {
                let o = p.owner[f];
                if on(o) && proc_of[nb as usize] == q {
                    faces.push((p.faces[f].clone(), local_cell[&o], None));
                } else if on(nb) && proc_of[o as usize] == q {
                    faces.push((p.faces[f].iter().rev().copied().collect(), local_cell[&nb], None));
                }
            }
            if faces.len() > first {
                patches.push((format!("procBoundary{k}to{q}"), "processor".into(), first, faces.len() - first));
            }
        }
        let mut points: Vec<u32> = faces.iter().flat_map(|f| f.0.iter().copied()).collect();
        points.sort_unstable();
        points.dedup();
        let local_point: BTreeMap<u32, u32> = points.iter().enumerate().map(|(i, &g)| (g, i as u32)).collect();
        let proc = Poly {
            points: points.iter().map(|&g| p.points[g as usize]).collect(),
            faces: faces.iter().map(|f| f.0.iter().map(|g| local_point[g]).collect()).collect(),
            owner: faces.iter().map(|f| f.1).collect(),
            neighbour: faces[..n_internal].iter().map(|f| f.2.unwrap()).collect(),
            patches,
            times: p
                .times
                .iter()
                .map(|(t, fields)| {
                    let split = fields
                        .iter()
                        .map(|(name, class, v)| {
                            let k = v.len() / p.n_cells();
                            let mine =
                                cells.iter().flat_map(|&c| v[c as usize * k..(c as usize + 1) * k].to_vec()).collect();
                            (name.clone(), class.clone(), mine)
                        })
                        .collect();
                    (t.clone(), split)
                })
                .collect(),
        };
        let addr = addressing.then_some((&points[..], &cells[..]));
        write_poly(&case.join(format!("processor{k}")), &proc, addr);
    }
}

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

/// Processors of octpoly's cells: scattered (cell `c` on `c * 7 % 3`), so most faces are
/// between processors and every processor borders every other.
fn scattered(n: usize) -> Vec<usize> {
    (0..n).map(|c| c * 7 % 3).collect()
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
    let dir = Dir::new("decomposed");
    write_poly(&dir.0.join("whole"), &poly, None);
    let whole = dir.0.join("whole/whole.foam");
    std::fs::write(&whole, "").unwrap();
    let proc_of = scattered(poly.n_cells());
    for addressing in [true, false] {
        let case = dir.0.join(format!("cut-{addressing}"));
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
        let order: Vec<usize> = if addressing {
            (0..n).collect()
        } else {
            let proc_of = &proc_of;
            (0..3).flat_map(|k| (0..n).filter(move |&c| proc_of[c] == k)).collect()
        };
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
        let centres: Vec<[f32; 3]> = (0..n)
            .map(|j| {
                let (_, pts) = cell_shape(&crate::read_raw(&case, None).unwrap(), j);
                let s = pts.iter().fold([0.0; 3], |s, p| [0, 1, 2].map(|i| s[i] + f64::from_bits(p[i])));
                s.map(|x| (x / pts.len() as f64) as f32)
            })
            .collect();
        let mut ids = vec![0; n];
        use tetloc_core::BatchLocator;
        loc.locate(&centres, &mut ids).unwrap();
        assert_eq!(ids, (0..n as i32).collect::<Vec<_>>(), "addressing {addressing}");
    }
}

#[test]
fn the_layout_is_chosen_and_every_file_is_an_input() {
    let test = "the_layout_is_chosen_and_every_file_is_an_input";
    let Some(poly) = octpoly(test) else { return };
    let dir = Dir::new("layout");
    write_poly(&dir.0, &poly, None);
    decompose(&dir.0, &poly, &(0..poly.n_cells()).map(|c| usize::from(c >= 100)).collect::<Vec<_>>(), false);
    let foam = dir.0.join("c.foam");
    std::fs::write(&foam, "").unwrap();
    // Both: reconstructed by default (ParaView's default), decomposed when asked.
    let a = crate::read_raw(&foam, None).unwrap();
    let b = crate::read_raw(&foam, Some(crate::MeshFormat::OpenFoamDecomposed)).unwrap();
    let c = crate::read_raw(&foam, crate::MeshFormat::from_name("foam-decomposed")).unwrap();
    assert_eq!((&b.points, &b.cells), (&c.points, &c.cells));
    assert_eq!(a.points.len(), b.points.len());
    let files = crate::input_files(&foam, Some(crate::MeshFormat::OpenFoamDecomposed));
    for want in ["processor1/constant/polyMesh/owner", "processor0/0.5/lin", "processor1/1/U", "c.foam"] {
        assert!(files.contains(&dir.0.join(want)), "{want} in {files:?}");
    }
    assert!(!files.contains(&dir.0.join("constant/polyMesh/owner")));
    let files = crate::input_files(&foam, None);
    assert!(files.contains(&dir.0.join("constant/polyMesh/owner")) && files.contains(&dir.0.join("0/lin")));
}

#[test]
fn bad_decomposed_cases_name_the_file() {
    let test = "bad_decomposed_cases_name_the_file";
    let Some(poly) = octpoly(test) else { return };
    let dir = Dir::new("bad");
    let err = |tag: &str, spoil: &dyn Fn(&Path)| {
        let case = dir.0.join(tag);
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
    let collated = dir.0.join("collated");
    std::fs::create_dir_all(collated.join("processors3/constant")).unwrap();
    let e = crate::read_raw(&collated, Some(crate::MeshFormat::OpenFoamDecomposed)).unwrap_err().to_string();
    assert!(e.contains("collated") && e.contains("processors3"), "{e}");
}

#[test]
fn time_steps_are_the_time_directories() {
    let test = "time_steps_are_the_time_directories";
    let Some(poly) = octpoly(test) else { return };
    let dir = Dir::new("steps");
    write_poly(&dir.0, &poly, None);
    let (raw, steps) = crate::read_series(&dir.0, None).unwrap();
    let steps = steps.unwrap();
    assert_eq!(steps.times, [0.5, 1.0]);
    let lin0 = read_fields(&dir.0.join("0"), 289).unwrap().pop().unwrap().1;
    let lin = |fields: &[Field]| {
        let f = fields.iter().find(|f| f.name == "lin").unwrap();
        (0..f.values.len()).map(|i| f.value64(i)).collect::<Vec<f64>>()
    };
    // The mesh holds the first step's fields; each step reads its own.
    assert_eq!(lin(&raw.fields), lin0.iter().map(|v| 2.0 * v).collect::<Vec<_>>());
    assert_eq!(lin(&steps.fields(1).unwrap()), lin0.iter().map(|v| 3.0 * v).collect::<Vec<_>>());
    assert_eq!(steps.field("U[2]", 1).unwrap().values, vec![-3.0; 289]);
    // A field missing at a later time: an error naming the time directory.
    std::fs::remove_file(dir.0.join("1/U")).unwrap();
    let e = steps.fields(1).unwrap_err().to_string();
    assert!(
        e.contains(&dir.0.join("1").display().to_string())
            && e.contains("no field 'U'")
            && e.contains("time 0.5 has it"),
        "{e}"
    );
    // A case with only the zero time: that is its one step.
    let only = Dir::new("only0");
    write_poly(&only.0, &Poly { times: poly.times[..1].to_vec(), ..poly.clone() }, None);
    assert_eq!(crate::read_series(&only.0, None).unwrap().1.unwrap().times, [0.0]);
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
    let case = Dir::new("vtk-octpoly");
    // The data set's case, copied (the script writes beside it).
    let src = dir.join("poly/octpoly_s_case");
    for sub in ["constant/polyMesh", "0", "1", "system"] {
        std::fs::create_dir_all(case.0.join(sub)).unwrap();
        for e in std::fs::read_dir(src.join(sub)).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), case.0.join(sub).join(e.file_name())).unwrap();
        }
    }
    agree_with_vtk(test, &case.0, false, &(0..289).collect::<Vec<_>>(), 476);
}

#[test]
fn vtk_reads_a_generated_and_a_decomposed_case_alike() {
    let test = "vtk_reads_a_generated_and_a_decomposed_case_alike";
    let Some(poly) = octpoly(test) else { return };
    let dir = Dir::new("vtk-gen");
    write_poly(&dir.0, &poly, None);
    let n = poly.n_cells();
    agree_with_vtk(test, &dir.0, false, &(0..n).collect::<Vec<_>>(), poly.points.len());
    // Decomposed: VTK lists each processor's cells (and points) in turn, unmerged; tetloc's
    // cells are in the undecomposed order (cellProcAddressing).
    let proc_of = scattered(n);
    decompose(&dir.0, &poly, &proc_of, true);
    let proc_of = &proc_of;
    let order: Vec<usize> = (0..3).flat_map(|k| (0..n).filter(move |&c| proc_of[c] == k)).collect();
    let vtk_points = (0..3)
        .map(|k| PolyMesh::read(&dir.0.join(format!("processor{k}/constant/polyMesh"))).unwrap().points64.len())
        .sum();
    agree_with_vtk(test, &dir.0, true, &order, vtk_points);
}
