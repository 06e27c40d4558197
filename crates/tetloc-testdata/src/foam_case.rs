//! OpenFOAM cases written for tests: a polyMesh with its fields at several times
//! ([`write_case`]), its decomposition as `decomposePar` writes it ([`decompose`]), and a
//! generated grid of hexes ([`hex_grid`]). Plain text files, no OpenFOAM needed.

use std::collections::BTreeMap;
use std::path::Path;

/// A field file: name, class, values (components interleaved).
pub type FieldFile = (String, String, Vec<f64>);

/// A polyMesh as its files hold it, and its fields by time.
#[derive(Clone)]
pub struct Poly {
    pub points: Vec<[f64; 3]>,
    pub faces: Vec<Vec<u32>>,
    pub owner: Vec<u32>,
    pub neighbour: Vec<u32>,
    /// (name, type, first face, face count)
    pub patches: Vec<(String, String, usize, usize)>,
    pub times: Vec<(String, Vec<FieldFile>)>,
}

impl Poly {
    pub fn n_cells(&self) -> usize {
        self.owner.iter().map(|&c| c as usize + 1).max().unwrap()
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
pub fn write_case(dir: &Path, p: &Poly, addressing: Option<(&[u32], &[u32])>) {
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
pub fn decompose(case: &Path, p: &Poly, proc_of: &[usize], addressing: bool) {
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
        write_case(&case.join(format!("processor{k}")), &proc, addr);
    }
}

/// A generated case: n³ unit hexes as polyMesh faces (internal faces first, owner the lower
/// cell, normals from owner to neighbour; the boundary in one patch, normals outwards), with
/// the cell field `lin` = x + 2y + 3z at the cell's centre, at time 0.
pub fn hex_grid(n: u32) -> Poly {
    let m = n + 1;
    let p = |i: u32, j: u32, k: u32| i + m * (j + m * k);
    let c = |i: u32, j: u32, k: u32| i + n * (j + n * k);
    let points = (0..m * m * m).map(|q| [q % m, q / m % m, q / (m * m)].map(f64::from)).collect();
    // The quad at (i, j, k) across `axis`, its normal along +axis.
    let quad = |axis: usize, i: u32, j: u32, k: u32| -> Vec<u32> {
        match axis {
            0 => vec![p(i, j, k), p(i, j + 1, k), p(i, j + 1, k + 1), p(i, j, k + 1)],
            1 => vec![p(i, j, k), p(i, j, k + 1), p(i + 1, j, k + 1), p(i + 1, j, k)],
            _ => vec![p(i, j, k), p(i + 1, j, k), p(i + 1, j + 1, k), p(i, j + 1, k)],
        }
    };
    let (mut faces, mut owner, mut neighbour) = (Vec::new(), Vec::new(), Vec::new());
    let mut boundary = Vec::new();
    for axis in 0..3 {
        for a in 0..=n {
            for b in 0..n {
                for d in 0..n {
                    // (i, j, k) with the axis' coordinate `a`.
                    let ijk = match axis {
                        0 => [a, b, d],
                        1 => [b, a, d],
                        _ => [b, d, a],
                    };
                    let cell_at = |s: u32| {
                        let mut q = ijk;
                        q[axis] = s;
                        c(q[0], q[1], q[2])
                    };
                    let f = quad(axis, ijk[0], ijk[1], ijk[2]);
                    if a == 0 {
                        boundary.push((f.into_iter().rev().collect::<Vec<u32>>(), cell_at(0)));
                    } else if a == n {
                        boundary.push((f, cell_at(n - 1)));
                    } else {
                        faces.push(f);
                        owner.push(cell_at(a - 1));
                        neighbour.push(cell_at(a));
                    }
                }
            }
        }
    }
    let start = faces.len();
    for (f, o) in boundary {
        faces.push(f);
        owner.push(o);
    }
    let lin = (0..n * n * n)
        .map(|q| [q % n, q / n % n, q / (n * n)])
        .map(|[i, j, k]| f64::from(i) + 0.5 + 2.0 * (f64::from(j) + 0.5) + 3.0 * (f64::from(k) + 0.5));
    let n_boundary = faces.len() - start;
    Poly {
        points,
        faces,
        owner,
        neighbour,
        patches: vec![("walls".into(), "wall".into(), start, n_boundary)],
        times: vec![("0".into(), vec![("lin".into(), "volScalarField".into(), lin.collect())])],
    }
}
