use super::*;
use std::io::Write;

/// Two unit hexes side by side along x (cells 0 and 1), as OpenFOAM lists them: the internal
/// face first (owner 0 → neighbour 1), then the 10 boundary faces, all outward from their owner.
/// Points, faces, owners and neighbours of a polyMesh.
type PolyMesh = (Vec<[f64; 3]>, Vec<Vec<u32>>, Vec<u32>, Vec<u32>);

fn two_hexes() -> PolyMesh {
    let id = |i: u32, j: u32, k: u32| i + 3 * (j + 2 * k);
    let points = (0..12).map(|p| [(p % 3) as f64, ((p / 3) % 2) as f64, (p / 6) as f64]).collect();
    // VTK's hexahedron faces (outward) over a cell's nodes.
    const FACES: [[usize; 4]; 6] = [[0, 4, 7, 3], [1, 2, 6, 5], [0, 1, 5, 4], [3, 7, 6, 2], [0, 3, 2, 1], [4, 5, 6, 7]];
    let nodes = |i: u32| {
        [
            id(i, 0, 0),
            id(i + 1, 0, 0),
            id(i + 1, 1, 0),
            id(i, 1, 0),
            id(i, 0, 1),
            id(i + 1, 0, 1),
            id(i + 1, 1, 1),
            id(i, 1, 1),
        ]
    };
    let face = |c: u32, f: usize| FACES[f].iter().map(|&k| nodes(c)[k]).collect::<Vec<u32>>();
    let mut faces = vec![face(0, 1)];
    let mut owner = vec![0];
    for (c, f) in [(0, 0), (0, 2), (0, 3), (0, 4), (0, 5), (1, 1), (1, 2), (1, 3), (1, 4), (1, 5)] {
        faces.push(face(c, f));
        owner.push(c);
    }
    (points, faces, owner, vec![1])
}

fn header(class: &str, binary: bool) -> String {
    let format = if binary { "binary" } else { "ascii" };
    format!("FoamFile\n{{\n    version 2.0;\n    format {format};\n    class {class};\n    arch \"LSB;label=32;scalar=64\";\n    object x;\n}}\n\n")
}

struct Case {
    dir: PathBuf,
}

impl Drop for Case {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Writes a case of `two_hexes` (binary and gzip as asked), with `boundary` as the patch list
/// and the time directory `1` holding `fields` (file name, text).
fn write_case(tag: &str, binary: bool, gzip: bool, patch: &str, owner_extra: usize, fields: &[(&str, String)]) -> Case {
    let dir = std::env::temp_dir().join(format!("tetloc-foam-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mesh = dir.join("constant/polyMesh");
    std::fs::create_dir_all(&mesh).unwrap();
    let (points, faces, mut owner, neighbour) = two_hexes();
    owner.extend(std::iter::repeat_n(0, owner_extra));
    let put = |name: &str, body: Vec<u8>| {
        let (path, bytes) = if gzip {
            let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(&body).unwrap();
            (mesh.join(format!("{name}.gz")), z.finish().unwrap())
        } else {
            (mesh.join(name), body)
        };
        std::fs::write(path, bytes).unwrap();
    };
    let labels = |v: &[u32]| -> Vec<u8> {
        if binary {
            let mut b = format!("{}\n(", v.len()).into_bytes();
            b.extend(v.iter().flat_map(|&x| (x as i32).to_le_bytes()));
            b.extend(b")\n");
            b
        } else {
            format!("{}\n(\n{}\n)\n", v.len(), v.iter().map(|x| x.to_string()).collect::<Vec<_>>().join("\n"))
                .into_bytes()
        }
    };
    let with = |class: &str, body: Vec<u8>| -> Vec<u8> {
        let mut b = header(class, binary).into_bytes();
        b.extend(body);
        b
    };
    let pts = if binary {
        let mut b = format!("{}\n(", points.len()).into_bytes();
        b.extend(points.iter().flatten().flat_map(|x| x.to_le_bytes()));
        b.extend(b")\n");
        b
    } else {
        let rows: Vec<String> = points.iter().map(|p| format!("({} {} {})", p[0], p[1], p[2])).collect();
        format!("{}\n(\n{}\n)\n", points.len(), rows.join("\n")).into_bytes()
    };
    put("points", with("vectorField", pts));
    if binary {
        let mut offsets = vec![0u32];
        faces.iter().for_each(|f| offsets.push(offsets.last().unwrap() + f.len() as u32));
        let mut body = labels(&offsets);
        body.extend(labels(&faces.concat()));
        put("faces", with("faceCompactList", body));
    } else {
        let rows: Vec<String> = faces
            .iter()
            .map(|f| format!("{}({})", f.len(), f.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(" ")))
            .collect();
        put("faces", with("faceList", format!("{}\n(\n{}\n)\n", faces.len(), rows.join("\n")).into_bytes()));
    }
    put("owner", with("labelList", labels(&owner)));
    put("neighbour", with("labelList", labels(&neighbour)));
    put("boundary", with("polyBoundaryMesh", patch.as_bytes().to_vec()));
    let time = dir.join("1");
    std::fs::create_dir_all(&time).unwrap();
    std::fs::create_dir_all(dir.join("0")).unwrap();
    for (name, text) in fields {
        std::fs::write(time.join(name), text).unwrap();
    }
    std::fs::write(dir.join("case.foam"), "").unwrap();
    Case { dir }
}

const WALLS: &str = "1\n(\n    walls\n    {\n        type wall;\n        nFaces 10;\n        startFace 1;\n    }\n)\n";

fn field(class: &str, internal: &str) -> String {
    format!("{}dimensions [0 0 0 0 0 0 0];\n\ninternalField {internal};\n\nboundaryField\n{{\n    walls {{ type zeroGradient; }}\n}}\n", header(class, false))
}

fn fields() -> Vec<(&'static str, String)> {
    vec![
        ("p", field("volScalarField", "nonuniform List<scalar> 2(1.5 -2.5)")),
        ("U", field("volVectorField", "uniform (1 2 3)")),
        ("phi", field("surfaceScalarField", "nonuniform List<scalar> 1(0.5)")),
    ]
}

#[test]
fn cases_in_every_encoding_read_alike() {
    for (tag, binary, gzip) in
        [("ascii", false, false), ("binary", true, false), ("gzip", true, true), ("ascii-gz", false, true)]
    {
        let case = write_case(tag, binary, gzip, WALLS, 0, &fields());
        for path in [case.dir.join("case.foam"), case.dir.clone()] {
            let mesh = crate::read_mesh(&path, None).unwrap_or_else(|e| panic!("{tag}: {e}"));
            assert_eq!(mesh.n_cells(), 2, "{tag}");
            assert_eq!(mesh.info.cell_types.get("hexahedron"), Some(&2), "{tag}: hex-shaped cells are hexahedra");
            let names: Vec<&str> = mesh.fields.iter().map(|f| f.name.as_str()).collect();
            assert_eq!(names, ["U[0]", "U[1]", "U[2]", "p"], "{tag}: phi (face data) skipped");
            assert_eq!(mesh.field("p").unwrap().values, vec![1.5, -2.5]);
            assert_eq!(mesh.field("U[2]").unwrap().values, vec![3.0, 3.0]);
            let mesh = std::sync::Arc::new(mesh);
            let cpu = tetloc_core::locate::CpuLocator::new(mesh.clone());
            let mut loc = tetloc_core::locate::CellLocator::new(cpu, mesh);
            let (mut ids, mut v) = (vec![0; 3], vec![0f32; 3]);
            use tetloc_core::BatchLocator;
            loc.locate_and_sample(&[[0.5, 0.5, 0.5], [1.7, 0.2, 0.9], [2.5, 0.5, 0.5]], "p", &mut ids, &mut v).unwrap();
            assert_eq!(ids, [0, 1, -1], "{tag}");
            assert_eq!(&v[..2], &[1.5, -2.5], "{tag}");
        }
    }
}

#[test]
fn a_chosen_time_and_the_latest() {
    let case = write_case("times", false, false, WALLS, 0, &fields());
    std::fs::write(case.dir.join("0/p"), field("volScalarField", "uniform 7")).unwrap();
    let at0 = read_case(&case.dir, &Time::Named("0".into()), false).unwrap();
    assert_eq!(at0.fields.len(), 1);
    assert_eq!(at0.fields[0].values, vec![7.0, 7.0]);
    assert_eq!(times(&case.dir).unwrap(), ["0", "1"]);
    assert!(read_case(&case.dir, &Time::Named("3".into()), false)
        .unwrap_err()
        .to_string()
        .contains("no time directory '3'"));
}

#[test]
fn bad_cases_are_named() {
    let err = |case: &Case| crate::read_mesh(&case.dir.join("case.foam"), None).unwrap_err().to_string();
    // A boundary face that no patch lists.
    let short = WALLS.replace("nFaces 10", "nFaces 9");
    let e = err(&write_case("nopatch", false, false, &short, 0, &[]));
    assert!(e.contains("boundary") && e.contains("face 10") && e.contains("no boundary patch"), "{e}");
    // More owners than faces.
    let e = err(&write_case("owners", false, false, WALLS, 2, &[]));
    assert!(e.contains("owner") && e.contains("13 owners for 11 faces"), "{e}");
    // A field class tetloc does not know.
    let e = err(&write_case("class", false, false, WALLS, 0, &[("q", field("volFooField", "uniform 1"))]));
    assert!(e.contains("q") && e.contains("volFooField"), "{e}");
    // A field of the wrong length.
    let e = err(&write_case(
        "len",
        false,
        false,
        WALLS,
        0,
        &[("q", field("volScalarField", "nonuniform List<scalar> 3(1 2 3)"))],
    ));
    assert!(e.contains("3 values, expected 2"), "{e}");
    // Not a case.
    let e = crate::read_mesh(Path::new("/nonexistent/x.foam"), None).unwrap_err().to_string();
    assert!(e.contains("not an OpenFOAM case"), "{e}");
}

/// Two files giving one field (`p` and `p.gz`; a scalar `U[0]` beside the vector `U`) are an
/// error naming the folder and both files, not the first kept silently.
#[test]
fn one_field_from_two_files_is_refused() {
    let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    z.write_all(field("volScalarField", "uniform 9").as_bytes()).unwrap();
    let gz = z.finish().unwrap();
    let case = write_case("dupfield", false, false, WALLS, 0, &fields());
    std::fs::write(case.dir.join("1/p.gz"), gz).unwrap();
    let e = crate::read_mesh(&case.dir, None).unwrap_err().to_string();
    assert!(e.contains("p.gz") && e.contains("both give the field 'p'"), "{e}");
    let mut clash = fields();
    clash.push(("U[0]", field("volScalarField", "uniform 9")));
    let e = crate::read_mesh(&write_case("clash", false, false, WALLS, 0, &clash).dir, None).unwrap_err().to_string();
    assert!(e.contains("U[0]") && e.contains("both give the field 'U[0]'"), "{e}");
}

/// Time folders that name one time (`1` and `1.0`) are an error naming both.
#[test]
fn two_folders_of_one_time_are_refused() {
    let case = write_case("sametime", false, false, WALLS, 0, &fields());
    std::fs::create_dir_all(case.dir.join("1.0")).unwrap();
    std::fs::write(case.dir.join("1.0/p"), field("volScalarField", "uniform 9")).unwrap();
    let e = crate::read_series(&case.dir, None).err().unwrap().to_string();
    assert!(e.contains("'1' and '1.0' name the same time"), "{e}");
}
