//! Decomposed cases (`processor0/`, `processor1/`, ... as `decomposePar` writes them), read as
//! one mesh, as ParaView's reader does with "Decomposed Case".
//!
//! Each processor folder holds a whole polyMesh of its cells; the faces between processors are
//! boundary faces of both, in patches of type `processor` (`procBoundary0to1`), and their
//! points are in both. Joined:
//! - **Points**: with a `pointProcAddressing` file in every processor (decomposePar writes
//!   them), point ids are the undecomposed case's; the copies of a point must have the same
//!   coordinates. Without, the points of `processor` patches are merged by exact coordinates
//!   (decomposePar copies them, so copies are bit-identical) and point ids follow processor
//!   order. Either way the mesh has no cracks between processors.
//! - **Cells**: with a `cellProcAddressing` file in every processor, cell ids are the
//!   undecomposed case's `celli` (what `reconstructPar` gives); without, cells are in
//!   processor order, then each processor's own order (cell id = the cells of the processors
//!   before + the processor's `celli`).
//! - **Times and fields** come from each processor's time folders (`processorN/TIME/NAME`),
//!   which must agree: the same times, the same fields.
//!
//! **As partitions** (the MPI path, `mpirun -n N tetloc locate CASE.foam`): each rank reads
//! some processors, each as a case of its own ([`read_processor`]), with its addressing as the
//! global cell and point ids of a `.pvtu` piece; `tetloc-mpi` joins a rank's processors as it
//! joins pieces. Without `cellProcAddressing` the global cell ids are processor order, as
//! above; without `pointProcAddressing` a rank's processors are not welded (a point on the
//! faces between two of them is in both, and the tie rule picks one).
//!
//! Not read: the collated format (`processorsN/`, one folder for all).

use super::poly::PolyMesh;
use super::{find, open};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use tetloc_core::cell::CellBlock;
use tetloc_core::error::{Error, Result};

/// The addressing files read when present, beside the polyMesh files.
pub(super) const ADDRESSING: [&str; 2] = ["pointProcAddressing", "cellProcAddressing"];

/// The processor folders of `case` (`processor0`, `processor1`, ...), in processor order; an
/// error when a number is missing or the case is collated (`processors4/`, one folder).
pub(super) fn processors(case: &Path) -> Result<Vec<PathBuf>> {
    let rd = std::fs::read_dir(case).map_err(|e| Error::io(case, e))?;
    let (mut found, mut collated) = (Vec::new(), None);
    for e in rd.filter_map(|e| e.ok()).filter(|e| e.path().is_dir()) {
        let name = e.file_name().to_string_lossy().into_owned();
        if let Some(k) = name.strip_prefix("processor").and_then(|k| k.parse::<usize>().ok()) {
            found.push((k, e.path()));
        } else if name.starts_with("processors") {
            collated = Some(name);
        }
    }
    found.sort();
    if found.is_empty() {
        return Err(Error::format(
            case,
            match collated {
                Some(c) => format!(
                    "the case is decomposed in the collated format ({c}/), which tetloc does not read: \
                     reconstruct it (reconstructPar) or decompose it with -fileHandler uncollated"
                ),
                None => "not an OpenFOAM case: no constant/polyMesh and no processor*/constant/polyMesh".into(),
            },
        ));
    }
    if let Some((k, _)) = found.iter().enumerate().find(|(k, (n, _))| k != n) {
        return Err(Error::format(
            case,
            format!(
                "processor{k} is missing ({} processor folders, numbered up to {})",
                found.len(),
                found.last().unwrap().0
            ),
        ));
    }
    Ok(found.into_iter().map(|(_, p)| p).collect())
}

/// The polyMesh folder of a processor.
pub(super) fn mesh_dir(processor: &Path) -> PathBuf {
    processor.join("constant/polyMesh")
}

/// The decomposed case joined: its points and cells, each processor's cell count, and the
/// position in processor order of each cell (`None`: cells are in processor order).
pub(super) struct Joined {
    pub points64: Vec<[f64; 3]>,
    pub cells: CellBlock,
    pub n_cells: Vec<usize>,
    pub order: Option<Vec<u32>>,
}

/// An addressing file and its ids.
type Addressing = (PathBuf, Vec<u32>);

/// An addressing file of a processor (`None` when it has none), checked: `n` ids.
fn addressing(processor: &Path, name: &str, n: usize) -> Result<Option<Addressing>> {
    let Some(path) = find(&mesh_dir(processor), name) else { return Ok(None) };
    let ids = open(&path)?.labels(name).map_err(|m| Error::format(&path, m))?;
    if ids.len() != n {
        return Err(Error::format(&path, format!("{} ids for the processor's {n} {}", ids.len(), what(name))));
    }
    let ids = ids
        .iter()
        .enumerate()
        .map(|(i, &v)| u32::try_from(v).map_err(|_| Error::format(&path, format!("entry {i} ({v}) is not an id"))))
        .collect::<Result<Vec<u32>>>()?;
    Ok(Some((path, ids)))
}

fn what(name: &str) -> &'static str {
    if name.starts_with("point") {
        "points"
    } else {
        "cells"
    }
}

/// Reads and joins the processors' meshes (see the module).
pub(super) fn read(processors: &[PathBuf]) -> Result<Joined> {
    let meshes = processors.iter().map(|p| PolyMesh::read(&mesh_dir(p))).collect::<Result<Vec<_>>>()?;
    let all_of = |name: &str, len: &dyn Fn(&PolyMesh) -> usize| -> Result<Option<Vec<Addressing>>> {
        let each =
            processors.iter().zip(&meshes).map(|(p, m)| addressing(p, name, len(m))).collect::<Result<Vec<_>>>()?;
        Ok(each.into_iter().collect())
    };
    let point_addressing = all_of("pointProcAddressing", &|m| m.points64.len())?;
    let cell_addressing = all_of("cellProcAddressing", &|m| m.n_cells)?;

    let (points64, maps) = match point_addressing {
        Some(a) => points_by_addressing(&meshes, &a)?,
        None => points_by_coordinates(&meshes),
    };
    let n_cells: Vec<usize> = meshes.iter().map(|m| m.n_cells).collect();
    let order = cell_addressing.map(|a| cell_order(&a, n_cells.iter().sum())).transpose()?;
    let mut cells = CellBlock::default();
    let mut push = |k: usize, c: usize| meshes[k].push_cell(c, &|p| maps[k][p as usize], &mut cells);
    match &order {
        Some(order) => {
            let starts: Vec<usize> = n_cells.iter().scan(0, |a, &n| Some(std::mem::replace(a, *a + n))).collect();
            for &j in order {
                let k = starts.partition_point(|&s| s <= j as usize) - 1;
                push(k, j as usize - starts[k]);
            }
        }
        None => (0..meshes.len()).for_each(|k| (0..n_cells[k]).for_each(|c| push(k, c))),
    }
    Ok(Joined { points64, cells, n_cells, order })
}

/// Points numbered by `pointProcAddressing`: each processor's local→global map.
type Points = (Vec<[f64; 3]>, Vec<Vec<u32>>);

fn points_by_addressing(meshes: &[PolyMesh], addressing: &[Addressing]) -> Result<Points> {
    let n = addressing.iter().flat_map(|a| a.1.iter()).map(|&g| g as usize + 1).max().unwrap_or(0);
    let mut points: Vec<Option<([f64; 3], usize)>> = vec![None; n];
    for (k, (m, (path, ids))) in meshes.iter().zip(addressing).enumerate() {
        for (p, &g) in m.points64.iter().zip(ids) {
            match points[g as usize] {
                None => points[g as usize] = Some((*p, k)),
                Some((q, other)) if q != *p => {
                    return Err(Error::format(
                        path,
                        format!("point {g} is at {p:?} here and at {q:?} in processor{other}: the processors disagree"),
                    ))
                }
                Some(_) => {}
            }
        }
    }
    let points = points
        .into_iter()
        .enumerate()
        .map(|(g, p)| {
            p.map(|p| p.0).ok_or_else(|| {
                Error::format(&addressing[0].0, format!("point {g} is in no processor's pointProcAddressing"))
            })
        })
        .collect::<Result<_>>()?;
    Ok((points, addressing.iter().map(|a| a.1.clone()).collect()))
}

/// Points in processor order, the points of `processor` patches merged by exact coordinates.
fn points_by_coordinates(meshes: &[PolyMesh]) -> Points {
    // -0.0 and 0.0 are one coordinate.
    let key = |p: &[f64; 3]| p.map(|x| (x + 0.0).to_bits());
    let mut shared: HashMap<[u64; 3], u32> = HashMap::new();
    let mut points = Vec::new();
    let mut maps = Vec::with_capacity(meshes.len());
    for m in meshes {
        let on_boundary = m.processor_points();
        let mut map = Vec::with_capacity(m.points64.len());
        for (i, p) in m.points64.iter().enumerate() {
            let fresh = points.len() as u32;
            let id = if on_boundary.binary_search(&(i as u32)).is_ok() {
                *shared.entry(key(p)).or_insert(fresh)
            } else {
                fresh
            };
            if id == fresh {
                points.push(*p);
            }
            map.push(id);
        }
        maps.push(map);
    }
    (points, maps)
}

/// The cells' order from `cellProcAddressing`: for each undecomposed cell, its position in
/// processor order; the ids must be `0..n` once each.
fn cell_order(addressing: &[Addressing], n: usize) -> Result<Vec<u32>> {
    let mut order = vec![u32::MAX; n];
    let mut j = 0u32;
    for (path, ids) in addressing {
        for (c, &g) in ids.iter().enumerate() {
            let slot = order
                .get_mut(g as usize)
                .ok_or_else(|| Error::format(path, format!("cell {c} is cell {g} of the case, which has {n} cells")))?;
            if *slot != u32::MAX {
                return Err(Error::format(path, format!("cell {c} is cell {g} of the case, as another cell is")));
            }
            *slot = j;
            j += 1;
        }
    }
    Ok(order)
}

/// One processor read as a case of its own with the first step's fields, and its
/// `cellProcAddressing` and `pointProcAddressing` (when it has them) as global cell and point
/// ids: a piece of a partitioned mesh.
pub(super) fn read_processor(processor: &Path) -> Result<super::ProcessorPiece> {
    let raw = super::read_case(processor, &super::Time::First, false)?;
    let n_cells = raw.cells.as_ref().map_or(raw.tets.len(), CellBlock::len);
    let widen = |a: Option<Addressing>| a.map(|(_, ids)| ids.into_iter().map(u64::from).collect());
    let cells = widen(addressing(processor, "cellProcAddressing", n_cells)?);
    let points = widen(addressing(processor, "pointProcAddressing", raw.points.len())?);
    Ok((raw, cells, points))
}
