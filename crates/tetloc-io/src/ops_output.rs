//! The files the operations of [`tetloc_core::ops`] write: a probe's result (`.vtu`/`.vtp`), a
//! resampled image (`.vti`/`.npy`) and traced lines (`.vtp`). The operations compute; the
//! formats are written here.

use crate::image::{ImageArray, ImageWriter};
use crate::points::VALID_MASK;
use crate::vtk::write::{self, ArrayData, Coords, NamedArray, PolylineWriter};
use std::path::Path;
use tetloc_core::error::{Error, Result};
use tetloc_core::geom::ImageGrid;
use tetloc_core::locate::BatchLocator;
use tetloc_core::mesh::field_groups::FieldGroup;
use tetloc_core::mesh::Mesh;
use tetloc_core::ops::probe::Probed;
use tetloc_core::ops::resample::resample;
use tetloc_core::ops::trace::LineArrays;
use tetloc_core::ops::CHUNK;

/// A probe's arrays to write (the mask last), borrowing `mask` (`Probed::mask`).
pub fn probed_arrays<'a>(probed: &'a Probed, mask: &'a [u8]) -> Vec<NamedArray<'a>> {
    let mut out = probed_field_arrays(probed);
    out.push(NamedArray { name: VALID_MASK.into(), n_components: 1, data: ArrayData::U8(mask) });
    out
}

/// A probe's fields' arrays to write: Float64 where they were sampled in f64, else Float32.
pub fn probed_field_arrays(probed: &Probed) -> Vec<NamedArray<'_>> {
    probed
        .arrays
        .iter()
        .enumerate()
        .map(|(i, (g, v))| NamedArray {
            name: g.name.clone(),
            n_components: g.n_components(),
            data: match probed.arrays64.get(i) {
                Some(Some(v64)) => ArrayData::F64(v64),
                _ => ArrayData::F32(v),
            },
        })
        .collect()
}

/// What the probed values were sampled at: a mesh's vertices, a grid's points (a `.vtu` of
/// any cells: surfaces, vertices, volumes), or a set of points.
#[derive(Clone, Copy, Debug)]
pub enum Target<'a> {
    Mesh(&'a Mesh),
    Grid(&'a crate::vtk::vtu::AnyGrid),
    Points(Coords<'a>),
}

/// Writes the probe's result: a target mesh or grid with its cells and data plus the probed
/// arrays (a `.vtu`; probed arrays replace target point arrays of the same name, and cell
/// arrays stay, as in vtkResampleWithDataSet), or a target point set with
/// the probed arrays (`.vtu` or `.vtp`; Float64 coordinates where f32 cannot hold them).
pub fn write_probed(path: &Path, probed: &Probed, target: Target, zlib: bool) -> Result<()> {
    let mask = probed.mask();
    let arrays = probed_arrays(probed, &mask);
    match target {
        Target::Mesh(mesh) => write::write_mesh_with(path, mesh, &arrays, zlib),
        Target::Grid(grid) => write::write_any_grid(path, grid, &arrays, zlib),
        Target::Points(points) => write::write_point_set(path, points, &arrays, zlib),
    }
}

/// What [`resample_to_file`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ResampleStats {
    pub n_points: usize,
    /// Points that got a value (`vtkValidPointMask` = 1).
    pub n_valid: usize,
}

/// [`resample`] into `path`: `.vti` (every field and `vtkValidPointMask`; zlib-compressed
/// when `zlib`) or `.npy` (one field). `progress` gets the number of points done so far.
pub fn resample_to_file(
    loc: &mut dyn BatchLocator,
    grid: &ImageGrid,
    fields: &[FieldGroup],
    path: &Path,
    zlib: bool,
    mut progress: impl FnMut(usize),
) -> Result<ResampleStats> {
    let arrays: Vec<ImageArray> =
        fields.iter().map(|g| ImageArray { name: g.name.clone(), n_components: g.n_components() }).collect();
    let mut out = ImageWriter::create(path, grid, &arrays, zlib)?;
    let (mut done, mut n_valid) = (0, 0);
    resample(loc, grid, fields, CHUNK, |ids, values| {
        out.push(ids, values)?;
        done += ids.len();
        n_valid += ids.iter().filter(|&&i| i >= 0).count();
        progress(done);
        Ok(())
    })?;
    out.finish()?;
    Ok(ResampleStats { n_points: grid.n_points(), n_valid })
}

/// Appends `lines` to `w`, a VTK polydata (`.vtp`) file being written: the fields (Float64
/// where sampled in f64) and `IntegrationTime` (Float64; `ParticleAge` for streaklines:
/// [`LineArrays::time_name`]) as point data, `ReasonForTermination` and `SeedIds` (Int32)
/// as cell data, as vtkStreamTracer writes them; pathlines and streaklines add their
/// particles' point data as vtkParticlePathFilter does ([`tetloc_core::ops::trace::ParticleArrays`]:
/// `ParticleId`, `InjectedPointId`, `InjectionStepId`, `ParticleAge`; and VTK's `ErrorCode`
/// (Int32) and `ParticleSourceId` (Int8), 0 at every point: a point is recorded only where
/// its step succeeded, and the seeds are one source), and lines with
/// vorticity its arrays as vtkStreamTracer names them (Float64: `Vorticity`, `Rotation`,
/// `AngularVelocity`, and for streamlines `Normals`). Seed ids are `seed_base` + the line's.
pub fn push_lines(w: &mut PolylineWriter, lines: &LineArrays, seed_base: usize) -> Result<()> {
    let mut point_data = probed_field_arrays(&lines.fields);
    point_data.push(NamedArray { name: lines.time_name.into(), n_components: 1, data: ArrayData::F64(&lines.time) });
    let injected: std::borrow::Cow<[i64]>;
    // Zeroed pages that are only read stay unallocated (the kernel's zero page).
    let (error_code, source_id) = match lines.particles {
        Some(_) => (vec![0i32; lines.points.len()], vec![0i8; lines.points.len()]),
        None => (Vec::new(), Vec::new()),
    };
    if let Some(p) = &lines.particles {
        let array = |name: &str, data| NamedArray { name: name.into(), n_components: 1, data };
        // Pathlines are written as one batch (`seed_base` 0): no copy.
        injected = match seed_base {
            0 => (&p.injected_point_id).into(),
            b => p.injected_point_id.iter().map(|&s| s + b as i64).collect(),
        };
        point_data.push(array("ParticleId", ArrayData::I32(&p.particle_id)));
        point_data.push(array("InjectedPointId", ArrayData::I64(&injected)));
        point_data.push(array("InjectionStepId", ArrayData::I32(&p.injection_step_id)));
        point_data.push(array("ErrorCode", ArrayData::I32(&error_code)));
        if let Some(age) = &p.age {
            point_data.push(array("ParticleAge", ArrayData::F32(age)));
        }
        point_data.push(array("ParticleSourceId", ArrayData::I8(&source_id)));
    }
    if let Some(v) = &lines.vorticity {
        let array = |name: &str, n_components, data| NamedArray { name: name.into(), n_components, data };
        point_data.push(array("Vorticity", 3, ArrayData::F64(bytemuck::cast_slice(&v.vorticity))));
        point_data.push(array("Rotation", 1, ArrayData::F64(&v.rotation)));
        point_data.push(array("AngularVelocity", 1, ArrayData::F64(&v.angular_velocity)));
        if let Some(normals) = &v.normals {
            point_data.push(array("Normals", 3, ArrayData::F64(bytemuck::cast_slice(normals))));
        }
    }
    let seeds = lines
        .seeds
        .iter()
        .map(|&s| i32::try_from(s as usize + seed_base))
        .collect::<std::result::Result<Vec<i32>, _>>()
        .map_err(|_| Error::Invalid("more than 2^31 seeds: SeedIds is an Int32 array, as VTK writes it".into()))?;
    let cell_data = [
        NamedArray { name: "ReasonForTermination".into(), n_components: 1, data: ArrayData::I32(&lines.reasons) },
        NamedArray { name: "SeedIds".into(), n_components: 1, data: ArrayData::I32(&seeds) },
    ];
    w.push(&lines.points, &lines.ends, &point_data, &cell_data)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::KuhnGrid;
    use std::sync::Arc;
    use tetloc_core::locate::CpuLocator;
    use tetloc_core::mesh::{Field, FieldLocation};
    use tetloc_core::ops::{fields, probe};

    /// Probed onto a mesh, the written mesh keeps its own arrays, the probed ones replacing
    /// those of the same name, and the mask.
    #[test]
    fn probed_meshes_keep_their_own_arrays() {
        let m = Arc::new(KuhnGrid::new(3).mesh("cube"));
        let mut renamed = fields::groups(&m);
        renamed[0].name = "f_probed".into();
        let onto = probe::probe(&mut CpuLocator::new(m.clone()), &m.points, &renamed, |_| Ok(())).unwrap();
        let tmp = std::env::temp_dir().join(format!("tetloc-probe-{}.vtu", std::process::id()));
        write_probed(&tmp, &onto, Target::Mesh(&m), false).unwrap();
        let back = crate::vtk::vtu::read(&tmp).unwrap();
        let names: Vec<&str> = back.fields.iter().map(|f| f.name.as_str()).collect();
        // Probed (point) arrays replace the target's point arrays of their names; its cell
        // arrays stay.
        let mut want: Vec<&str> = m
            .fields
            .iter()
            .filter(|f| f.location == FieldLocation::Cell || !renamed.iter().skip(1).any(|g| g.name == f.name))
            .map(|f| f.name.as_str())
            .collect();
        want.extend(renamed.iter().map(|g| g.name.as_str()));
        want.push(VALID_MASK);
        let (mut names, mut want) = (names, want);
        names.sort();
        want.sort();
        assert_eq!(names, want);
        assert_eq!(back.tets.len(), m.tets.len());
        std::fs::remove_file(&tmp).unwrap();
    }

    /// Issue 29 item 14: probing a mesh onto itself (`probe s.vtu s.vtu`) keeps the target's
    /// cell array `c` beside the probed point array `c`, as vtkResampleWithDataSet does (point
    /// data and cell data are two sets of names); a probed point array replaces the target's
    /// point array of its name.
    #[test]
    fn probed_arrays_keep_the_targets_cell_arrays() {
        let m = Arc::new(KuhnGrid::new(2).cell_field("c", |i, _| i as f32).mesh("cube"));
        let groups = fields::groups(&m);
        let p = probe::probe(&mut CpuLocator::new(m.clone()), &m.points, &groups, |_| Ok(())).unwrap();
        let tmp = std::env::temp_dir().join(format!("tetloc-probe-names-{}.vtu", std::process::id()));
        write_probed(&tmp, &p, Target::Mesh(&m), false).unwrap();
        let back = crate::vtk::vtu::read(&tmp).unwrap();
        std::fs::remove_file(&tmp).unwrap();
        let mut names: Vec<(&str, FieldLocation)> = back.fields.iter().map(|f| (f.name.as_str(), f.location)).collect();
        names.sort_by_key(|(n, l)| (n.to_string(), *l == FieldLocation::Cell));
        use FieldLocation::{Cell, Vertex};
        assert_eq!(names, [("c", Vertex), ("c", Cell), ("f", Vertex), (VALID_MASK, Vertex)]);
        let cell = back.fields.iter().find(|f| f.name == "c" && f.location == Cell).unwrap();
        assert_eq!(cell.values, m.field("c").unwrap().values, "the target's own cell values");
    }

    /// Fields probed in f64 are written as Float64 (as VTK's probe keeps the source array's
    /// type), f32 fields as Float32.
    #[test]
    fn f64_fields_are_written_as_float64() {
        let mut m = KuhnGrid::new(3).mesh("cube");
        let g: Vec<f64> = m.points.iter().map(|p| 1e-9 + p[0] as f64 * 1e-12 + 1e-17).collect();
        m.fields.push(Field::from_f64("g", FieldLocation::Vertex, g));
        let m = Arc::new(m);
        let groups = fields::groups_of(&m.fields);
        let p = probe::probe(&mut CpuLocator::new(m.clone()), &m.points, &groups, |_| Ok(())).unwrap();
        let tmp = std::env::temp_dir().join(format!("tetloc-probe64-{}.vtp", std::process::id()));
        write_probed(&tmp, &p, Target::Points(Coords::F32(&m.points)), false).unwrap();
        let bytes = std::fs::read(&tmp).unwrap();
        let text = String::from_utf8_lossy(&bytes[..bytes.len().min(4000)]).to_string();
        std::fs::remove_file(&tmp).unwrap();
        assert!(
            text.contains(r#"type="Float64" Name="g""#) || text.contains(r#"Name="g" type="Float64""#),
            "{text:.400}"
        );
        assert!(text.contains(r#"Name="f" type="Float32""#) || text.contains(r#"type="Float32" Name="f""#));
    }

    /// The .npy holds (NZ, NY, NX, 3) with NaN outside; the .vti reads back through the
    /// header and holds the mask.
    #[test]
    fn resampled_files() {
        let m = KuhnGrid::new(4).mesh("cube");
        let mut with_v = m.fields.clone();
        for c in 0..3 {
            let values = m.points.iter().map(|p| (c + 1) as f32 * p[c]).collect();
            with_v.push(Field { values64: None, name: format!("v[{c}]"), location: FieldLocation::Vertex, values });
        }
        let raw = tetloc_core::RawMesh {
            points: m.points.to_vec(),
            tets: m.tets.to_vec(),
            fields: with_v,
            ..Default::default()
        };
        let m = Arc::new(Mesh::new(raw, "cube+v").unwrap());
        let v = fields::resolve(&m, "v").unwrap();
        let f = fields::resolve(&m, "f").unwrap();
        let grid = ImageGrid::spanning([0.0; 3], [1.5, 1.0, 1.0], [4, 3, 2]).unwrap();
        let dir = std::env::temp_dir();
        let npy = dir.join(format!("tetloc-resample-{}.npy", std::process::id()));
        let mut loc = CpuLocator::new(m.clone());
        let mut seen = 0;
        let stats = resample_to_file(&mut loc, &grid, std::slice::from_ref(&v), &npy, false, |d| seen = d).unwrap();
        assert_eq!((stats.n_points, seen), (24, 24));
        assert_eq!(stats.n_valid, 18); // x = 1.5 is outside
        let bytes = std::fs::read(&npy).unwrap();
        let arr = npyz::NpyFile::new(&bytes[..]).unwrap();
        assert_eq!(arr.shape(), &[2, 3, 4, 3]);
        let data = arr.into_vec::<f32>().unwrap();
        assert_eq!(data[3 * 2], 1.0); // point (1, 0, 0): v = (x, 2y, 3z)
        assert!(data[3 * 3].is_nan());
        std::fs::remove_file(&npy).unwrap();
        for zlib in [false, true] {
            let vti = dir.join(format!("tetloc-resample-{}-{zlib}.vti", std::process::id()));
            resample_to_file(&mut loc, &grid, &[f.clone(), v.clone()], &vti, zlib, |_| {}).unwrap();
            let text = String::from_utf8_lossy(&std::fs::read(&vti).unwrap()).into_owned();
            assert!(text.contains("WholeExtent=\"0 3 0 2 0 1\""), "{text:.400}");
            assert!(text.contains("Spacing=\"0.5 0.5 1.0\""), "{text:.400}");
            assert!(text.contains("Name=\"v\" NumberOfComponents=\"3\""));
            assert!(text.contains("Name=\"vtkValidPointMask\""));
            std::fs::remove_file(&vti).unwrap();
        }
    }
}
