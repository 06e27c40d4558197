//! Exodus II (`.e`, `.exo`, `.ex2`): the netCDF files that SEACAS, MOOSE and Sierra write,
//! both classic netCDF (CDF-1/2/5) and netCDF-4 (HDF5).
//!
//! Read with `netcdf-reader` (and its `hdf5-reader`): pure Rust, so building tetloc needs
//! nothing installed (the C netCDF and HDF5 libraries would need either system packages or a
//! CMake build of both inside `cargo build`), and it reads one step's slice of a variable
//! without the others. Chosen after comparing it with the `netcdf` crate (bindings to the C
//! library), `netcdf3` (classic only) and `hdf5-metno` (bindings).
//!
//! What is read, as ParaView's Exodus reader reads it:
//! - coordinates `coordx/y/z` (or `coord`), in f64 where the file has f64;
//! - element blocks `connect<b>` of TETRA4/10, HEX8/20, WEDGE6/15, PYRAMID5/13, in block
//!   order (cell ids follow the file's element order), nodes reordered to VTK's where Exodus
//!   differs (HEX20 and WEDGE15 list their vertical edges before their top edges); blocks of
//!   surface and line elements (TRI, QUAD, SHELL, BAR, BEAM, TRUSS, SPHERE, ...) are skipped;
//!   other types are refused (HEX27's face nodes are among them: not mapped yet);
//! - nodal variables `vals_nod_var<i>` (or the older `vals_nod_var`) and element variables
//!   `vals_elem_var<i>eb<b>` (NaN in blocks whose truth table leaves them out), named by
//!   `name_nod_var`/`name_elem_var`; `NAME_x`, `NAME_y`, `NAME_z` become the vector `NAME`
//!   (fields `NAME[0..3]`), as ParaView groups them (VTK's reader names the vector `NAME_`);
//! - `time_whole`: the steps; each step's values are read when asked for ([`TimeSteps`]);
//! - `node_num_map` and `elem_num_map` as the fields `GlobalNodeId` and `GlobalElementId`.

use netcdf_reader::{NcFile, NcSliceInfo, NcSliceInfoElem, NcVariable};
use rayon::prelude::*;
use std::borrow::Cow;
use std::path::{Path, PathBuf};
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{Field, FieldLocation, RawMesh, StepFields, TimeSteps};

/// Reads the mesh with the first step's fields (a file without steps: none but the id maps).
pub fn read(path: &Path) -> Result<RawMesh> {
    Ok(read_series(path)?.0)
}

/// Reads the mesh with the first step's fields, and the steps (`None` without `time_whole`
/// steps).
pub fn read_series(path: &Path) -> Result<(RawMesh, Option<TimeSteps>)> {
    guarded(path, || {
        let file = open(path)?;
        let (raw, layout) = read_from(&file, path)?;
        let times = layout.times.clone();
        let steps = Steps { path: path.to_path_buf(), layout };
        let series = (!times.is_empty()).then(|| TimeSteps::new(path.display().to_string(), times, Box::new(steps)));
        Ok((raw, series))
    })
}

/// Parses a whole file held in memory (the first step's fields); `path` only names it in errors.
pub fn parse(bytes: &[u8], path: &Path) -> Result<RawMesh> {
    guarded(path, || {
        let file = NcFile::from_bytes(bytes).map_err(|e| Error::format(path, format!("not a netCDF file: {e}")))?;
        Ok(read_from(&file, path)?.0)
    })
}

/// `read`, with a panic of the netCDF/HDF5 decoder on a corrupt file turned into an error
/// naming the file (never an abort).
fn guarded<T>(path: &Path, read: impl FnOnce() -> Result<T>) -> Result<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(read))
        .unwrap_or_else(|_| Err(Error::format(path, "the netCDF decoder failed on this file (corrupt?)")))
}

/// The mesh with the first step's fields, and the file's layout.
fn read_from(file: &NcFile, path: &Path) -> Result<(RawMesh, Layout)> {
    let layout = Layout::of(file, path)?;
    let points = layout.read_points(file, path)?;
    let (tets, higher_order, cells) = match layout.read_tets(file, path)? {
        Some(tets) => (tets, None, None),
        None => {
            let cells = layout.read_cells(file, path)?;
            let ex = crate::vtk::cells::extract(&cells.types, &cells.ends, &cells.conn, None)
                .map_err(|m| Error::format(path, m))?;
            (ex.tets, ex.higher_order, ex.cells)
        }
    };
    let mut raw = RawMesh {
        points: points.par_iter().map(|p| p.map(|c| c as f32)).collect(),
        points64: crate::points64_if_needed(points),
        tets,
        fields: Vec::new(),
        higher_order,
        cells,
    };
    raw.fields = match layout.times.len() {
        0 => layout.id_maps.clone(),
        _ => read_step(file, path, &layout, 0)?,
    };
    Ok((raw, layout))
}

fn open(path: &Path) -> Result<NcFile> {
    crate::check_fits_in_memory(path)?;
    NcFile::open(path).map_err(|e| match e {
        netcdf_reader::Error::Io(io) => Error::io(path, io),
        e => Error::format(path, format!("not a netCDF file that tetloc can read (Exodus II is netCDF): {e}")),
    })
}

/// A netCDF error while reading `what`.
fn nc_err(path: &Path, what: &str) -> impl Fn(netcdf_reader::Error) -> Error {
    let (path, what) = (path.to_path_buf(), what.to_string());
    move |e| Error::format(&path, format!("{what}: {e}"))
}

/// The element block `b` (1-based, the file's numbering) and its VTK type.
struct Block {
    index: usize,
    n_elems: usize,
    /// `None`: a surface or line block, skipped.
    vtk: Option<VtkCell>,
}

#[derive(Clone, Copy)]
struct VtkCell {
    code: u8,
    n_nodes: usize,
    /// VTK node `i` is Exodus node `from_exodus[i]` (`None`: the same order).
    from_exodus: Option<&'static [usize]>,
}

/// Quadratic hex: Exodus lists the 4 vertical edges (nodes 12-15) before the 4 top edges
/// (16-19); VTK the top edges first.
const HEX20: [usize; 20] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 16, 17, 18, 19, 12, 13, 14, 15];
/// Quadratic wedge: Exodus lists the vertical edges (9-11) before the top edges (12-14).
const WEDGE15: [usize; 15] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 13, 14, 9, 10, 11];

/// The VTK cell of an Exodus element type with `n` nodes; `Ok(None)` for surface and line
/// elements (skipped); an error message for anything else.
fn vtk_cell(elem_type: &str, n: usize) -> Result<Option<VtkCell>, String> {
    let t = elem_type.trim().to_ascii_uppercase();
    let cell = |code, from_exodus| Ok(Some(VtkCell { code, n_nodes: n, from_exodus }));
    let family = t.trim_end_matches(|c: char| c.is_ascii_digit());
    match (family, n) {
        ("TETRA" | "TET", 4) => cell(10, None),
        ("TETRA" | "TET", 10) => cell(24, None),
        ("HEX" | "HEXAHEDRON", 8) => cell(12, None),
        ("HEX" | "HEXAHEDRON", 20) => cell(25, Some(&HEX20)),
        ("WEDGE", 6) => cell(13, None),
        ("WEDGE", 15) => cell(26, Some(&WEDGE15)),
        ("PYRAMID" | "PYRA", 5) => cell(14, None),
        ("PYRAMID" | "PYRA", 13) => cell(27, None),
        (
            "TRI" | "TRIANGLE" | "TRISHELL" | "QUAD" | "SHELL" | "BAR" | "BEAM" | "TRUSS" | "EDGE" | "SPHERE"
            | "CIRCLE" | "POINT" | "NULL",
            _,
        ) => Ok(None),
        _ => Err(format!(
            "element type '{elem_type}' with {n} nodes is not one tetloc reads (TETRA4/10, HEX8/20, WEDGE6/15, \
             PYRAMID5/13; surface and line blocks are skipped)"
        )),
    }
}

/// A variable of the file: its name and where its values are stored.
#[derive(Clone)]
struct Var {
    name: String,
    /// The netCDF variable(s): one per element block for element variables (`None`: not in
    /// that block), one for nodal variables.
    storage: Vec<Option<String>>,
    /// For the older layout (`vals_nod_var[time, var, node]`): the variable's index.
    combined: Option<usize>,
}

/// What the file holds, from its header.
struct Layout {
    n_nodes: usize,
    blocks: Vec<Block>,
    times: Vec<f64>,
    node_vars: Vec<Var>,
    elem_vars: Vec<Var>,
    id_maps: Vec<Field>,
}

fn dim(file: &NcFile, name: &str) -> Option<usize> {
    file.dimension(name).ok().map(|d| d.size as usize)
}

fn names(file: &NcFile, var: &str, path: &Path) -> Result<Vec<String>> {
    match file.variable(var) {
        Err(_) => Ok(Vec::new()),
        Ok(_) => Ok(file
            .read_variable_as_strings(var)
            .map_err(nc_err(path, var))?
            .into_iter()
            .map(|s| s.trim_end_matches(['\0', ' ']).to_string())
            .collect()),
    }
}

/// The variables' names must be one per variable (`count` of them, as `count_of` says), none
/// empty, none twice: else variables would be dropped or shadowed silently.
fn check_var_names(path: &Path, what: &str, var: &str, count_of: &str, names: &[String], count: usize) -> Result<()> {
    let fail = |msg: String| Err(Error::format(path, format!("{what} variables: {msg}")));
    if names.len() != count {
        return fail(format!("the file has {count} ({count_of}) but {var} names {}; each needs a name", names.len()));
    }
    if let Some(i) = names.iter().position(|n| n.trim().is_empty()) {
        return fail(format!("variable {} has an empty name in {var}", i + 1));
    }
    let mut seen = std::collections::HashSet::new();
    match names.iter().find(|n| !seen.insert(n.as_str())) {
        Some(n) => fail(format!("'{n}' is named twice in {var}")),
        None => Ok(()),
    }
}

impl Layout {
    fn of(file: &NcFile, path: &Path) -> Result<Layout> {
        let need = |name: &str| {
            dim(file, name).ok_or_else(|| {
                Error::format(path, format!("no '{name}' dimension: not an Exodus II file (or one without a mesh)"))
            })
        };
        let n_dim = need("num_dim")?;
        if n_dim != 3 {
            return Err(Error::format(path, format!("a {n_dim}-D Exodus mesh; tetloc reads 3-D meshes")));
        }
        let n_nodes = need("num_nodes")?;
        let n_blocks = dim(file, "num_el_blk").unwrap_or(0);
        let mut blocks = Vec::with_capacity(n_blocks);
        for b in 1..=n_blocks {
            let connect = format!("connect{b}");
            let v = file
                .variable(&connect)
                .map_err(|_| Error::format(path, format!("element block {b} has no {connect}")))?;
            let shape = v.shape();
            let [n_elems, n] = shape[..] else {
                return Err(Error::format(path, format!("{connect} has {} dimensions, expected 2", shape.len())));
            };
            let elem_type = attr_string(v, "elem_type").unwrap_or_default();
            let vtk =
                vtk_cell(&elem_type, n as usize).map_err(|m| Error::format(path, format!("element block {b}: {m}")))?;
            blocks.push(Block { index: b, n_elems: n_elems as usize, vtk });
        }
        let times = match (dim(file, "time_step"), file.variable("time_whole")) {
            (Some(n), Ok(_)) if n > 0 => {
                values(file.read_variable_as_f64("time_whole").map_err(nc_err(path, "time_whole"))?)
            }
            _ => Vec::new(),
        };
        if let Some(i) = times.iter().position(|t| !t.is_finite()) {
            // The increasing check below compares neighbours only: a lone NaN would pass.
            return Err(Error::format(path, format!("time_whole at step {i} is {}, not a finite time", times[i])));
        }
        if let Some(i) =
            times.windows(2).position(|w: &[f64]| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
        {
            return Err(Error::format(
                path,
                format!("time_whole is not increasing at step {}: {} then {}", i + 1, times[i], times[i + 1]),
            ));
        }
        // Nodal variables: one netCDF variable each, or all in one.
        let node_names = names(file, "name_nod_var", path)?;
        let combined = file.variable("vals_nod_var").is_ok();
        let stored = (1..).take_while(|i| file.variable(&format!("vals_nod_var{i}")).is_ok()).count();
        let n_node_vars = dim(file, "num_nod_var").unwrap_or(if combined { node_names.len() } else { stored });
        let count_of = "num_nod_var or vals_nod_var*";
        check_var_names(path, "nodal", "name_nod_var", count_of, &node_names, n_node_vars)?;
        let node_vars = node_names
            .iter()
            .enumerate()
            .map(|(i, name)| Var {
                name: name.clone(),
                storage: vec![Some(if combined { "vals_nod_var".into() } else { format!("vals_nod_var{}", i + 1) })],
                combined: combined.then_some(i),
            })
            .collect();
        // Element variables, per block, as the truth table says.
        let elem_names = names(file, "name_elem_var", path)?;
        let n_elem_vars = dim(file, "num_elem_var").unwrap_or(elem_names.len());
        check_var_names(path, "element", "name_elem_var", "num_elem_var", &elem_names, n_elem_vars)?;
        let table: Option<Vec<i32>> = match file.variable("elem_var_tab") {
            Ok(_) => Some(
                file.read_variable::<i32>("elem_var_tab")
                    .map_err(nc_err(path, "elem_var_tab"))?
                    .iter()
                    .copied()
                    .collect(),
            ),
            Err(_) => None,
        };
        let elem_vars = elem_names
            .iter()
            .enumerate()
            .map(|(i, name)| Var {
                name: name.clone(),
                storage: blocks
                    .iter()
                    .map(|b| {
                        let stored = format!("vals_elem_var{}eb{}", i + 1, b.index);
                        let in_table =
                            table.as_ref().is_none_or(|t| t.get((b.index - 1) * elem_names.len() + i) != Some(&0));
                        (in_table && file.variable(&stored).is_ok()).then_some(stored)
                    })
                    .collect(),
                combined: None,
            })
            .collect();
        let mut layout = Layout { n_nodes, blocks, times, node_vars, elem_vars, id_maps: Vec::new() };
        layout.id_maps = layout.read_id_maps(file, path)?;
        Ok(layout)
    }

    fn read_points(&self, file: &NcFile, path: &Path) -> Result<Vec<[f64; 3]>> {
        let axes: Vec<Vec<f64>> = if file.variable("coordx").is_ok() {
            ["coordx", "coordy", "coordz"]
                .iter()
                .map(|v| Ok(values(file.read_variable_as_f64(v).map_err(nc_err(path, v))?)))
                .collect::<Result<_>>()?
        } else {
            let all: Vec<f64> = values(file.read_variable_as_f64("coord").map_err(nc_err(path, "coord"))?);
            all.chunks(self.n_nodes.max(1)).map(<[f64]>::to_vec).collect()
        };
        if axes.len() != 3 || axes.iter().any(|a| a.len() != self.n_nodes) {
            return Err(Error::format(path, format!("the coordinates do not hold 3 × {} values", self.n_nodes)));
        }
        Ok((0..self.n_nodes).into_par_iter().map(|i| [axes[0][i], axes[1][i], axes[2][i]]).collect())
    }

    /// The tets of a mesh whose volume blocks are all linear tets (the common Exodus mesh),
    /// straight from the connectivity and checked in parallel; `None` for any other mesh
    /// ([`Self::read_cells`] reads it). The same tets and errors as that general path.
    fn read_tets(&self, file: &NcFile, path: &Path) -> Result<Option<Vec<[u32; 4]>>> {
        let volume = || self.blocks.iter().filter_map(|b| b.vtk.map(|c| (b, c)));
        if volume().any(|(_, c)| c.code != crate::vtk::cells::TETRA || c.n_nodes != 4 || c.from_exodus.is_some()) {
            return Ok(None);
        }
        let mut tets: Vec<[u32; 4]> = Vec::with_capacity(volume().map(|(b, _)| b.n_elems).sum());
        for (b, _) in volume() {
            let name = format!("connect{}", b.index);
            match file.read_variable::<i32>(&name) {
                Ok(a) => self.block_tets(b, &contiguous(&a), path, &mut tets)?,
                Err(_) => {
                    let a = file.read_variable::<i64>(&name).map_err(nc_err(path, &name))?;
                    self.block_tets(b, &contiguous(&a), path, &mut tets)?
                }
            }
        }
        Ok(Some(tets))
    }

    /// Block `b`'s tets from its 1-based node ids, four an element, onto `tets`.
    fn block_tets<T: Copy + Into<i64> + Sync>(
        &self,
        b: &Block,
        ids: &[T],
        path: &Path,
        tets: &mut Vec<[u32; 4]>,
    ) -> Result<()> {
        let name = format!("connect{}", b.index);
        if ids.len() != b.n_elems * 4 {
            return Err(Error::format(path, format!("{name} holds {} ids, expected {} × 4", ids.len(), b.n_elems)));
        }
        let n = self.n_nodes as i64;
        if let Some(at) = tetloc_core::par::first_position(ids, |id| !(1..=n).contains(&(*id).into())) {
            return Err(Error::format(
                path,
                format!(
                    "element {} of block {} names node {}; the nodes are 1 to {}",
                    at / 4 + 1,
                    b.index,
                    ids[at].into(),
                    self.n_nodes
                ),
            ));
        }
        let id = |i: T| (i.into() - 1) as u32;
        // (Written straight into `tets`' reserved room.)
        tets.par_extend(ids.par_chunks_exact(4).map(|e| [id(e[0]), id(e[1]), id(e[2]), id(e[3])]));
        Ok(())
    }

    /// The volume cells of every block, in VTK's terms (type codes, ends, 0-based ids in VTK's
    /// node order).
    fn read_cells(&self, file: &NcFile, path: &Path) -> Result<VtkCells> {
        let mut out = VtkCells { types: Vec::new(), ends: Vec::new(), conn: Vec::new() };
        for b in &self.blocks {
            let Some(cell) = b.vtk else { continue };
            let name = format!("connect{}", b.index);
            let ids: Vec<i64> = file
                .read_variable::<i32>(&name)
                .map(|a| contiguous(&a).iter().map(|&i| i64::from(i)).collect())
                .or_else(|_| file.read_variable::<i64>(&name).map(values))
                .map_err(nc_err(path, &name))?;
            if ids.len() != b.n_elems * cell.n_nodes {
                return Err(Error::format(
                    path,
                    format!("{name} holds {} ids, expected {} × {}", ids.len(), b.n_elems, cell.n_nodes),
                ));
            }
            for (e, elem) in ids.chunks_exact(cell.n_nodes).enumerate() {
                for i in 0..cell.n_nodes {
                    let id = elem[cell.from_exodus.map_or(i, |p| p[i])];
                    if id < 1 || id as usize > self.n_nodes {
                        return Err(Error::format(
                            path,
                            format!(
                                "element {} of block {} names node {id}; the nodes are 1 to {}",
                                e + 1,
                                b.index,
                                self.n_nodes
                            ),
                        ));
                    }
                    out.conn.push(id as u32 - 1);
                }
                out.types.push(cell.code);
                out.ends.push(out.conn.len() as u64);
            }
        }
        Ok(out)
    }

    /// `node_num_map` and `elem_num_map` (the latter over the volume blocks) as fields.
    fn read_id_maps(&self, file: &NcFile, path: &Path) -> Result<Vec<Field>> {
        let mut out = Vec::new();
        for (var, name, location) in [
            ("node_num_map", "GlobalNodeId", FieldLocation::Vertex),
            ("elem_num_map", "GlobalElementId", FieldLocation::Cell),
        ] {
            if file.variable(var).is_err() {
                continue;
            }
            let ids: Vec<f64> = values(file.read_variable_as_f64(var).map_err(nc_err(path, var))?);
            let ids = match location {
                FieldLocation::Vertex => ids,
                FieldLocation::Cell => self.volume_values(ids.len(), path, var, |_, range| Ok(ids[range].to_vec()))?,
            };
            if location == FieldLocation::Vertex && ids.len() != self.n_nodes {
                return Err(Error::format(path, format!("{var} has {} ids for {} nodes", ids.len(), self.n_nodes)));
            }
            out.push(Field::from_f64(name, location, ids));
        }
        Ok(out)
    }

    /// Values of the volume blocks' elements, from `read(block, its range in the file's
    /// element order)`, for an element array of `n` values over all blocks.
    fn volume_values(
        &self,
        n: usize,
        path: &Path,
        what: &str,
        mut read: impl FnMut(&Block, std::ops::Range<usize>) -> Result<Vec<f64>>,
    ) -> Result<Vec<f64>> {
        let total: usize = self.blocks.iter().map(|b| b.n_elems).sum();
        if n != total {
            return Err(Error::format(path, format!("{what} has {n} values for {total} elements")));
        }
        let mut out = Vec::new();
        let mut start = 0;
        for b in &self.blocks {
            if b.vtk.is_some() {
                out.extend(read(b, start..start + b.n_elems)?);
            }
            start += b.n_elems;
        }
        Ok(out)
    }
}

/// An array's values in order: borrowed where it is contiguous (as netcdf-reader's arrays
/// are), else gathered by ndarray's element iterator, whose n-dimensional indexing costs more
/// than a slice copy.
fn contiguous<T: Clone>(a: &ndarray::ArrayD<T>) -> Cow<'_, [T]> {
    a.as_slice().map_or_else(|| Cow::Owned(a.iter().cloned().collect()), Cow::Borrowed)
}

/// An array's values in order, as a vector: its own buffer where it is contiguous (no copy),
/// else [`contiguous`]'s gathered copy.
fn values<T: Clone>(a: ndarray::ArrayD<T>) -> Vec<T> {
    if !a.is_standard_layout() {
        return contiguous(&a).into_owned();
    }
    let n = a.len();
    let (mut buffer, offset) = a.into_raw_vec_and_offset();
    let start = offset.unwrap_or(0);
    if start > 0 || buffer.len() != n {
        // (A view's window of a larger buffer: only its own values.)
        buffer = buffer[start..start + n].to_vec();
    }
    buffer
}

fn attr_string(v: &NcVariable, name: &str) -> Option<String> {
    v.attribute(name).and_then(|a| a.value.as_string()).map(|s| s.trim_end_matches(['\0', ' ']).to_string())
}

struct VtkCells {
    types: Vec<u8>,
    ends: Vec<u64>,
    conn: Vec<u32>,
}

/// Reads a step's values from the file, reopened for each step.
struct Steps {
    path: PathBuf,
    layout: Layout,
}

impl StepFields for Steps {
    fn read(&self, k: usize) -> Result<Vec<Field>> {
        guarded(&self.path, || read_step(&open(&self.path)?, &self.path, &self.layout, k))
    }
}

/// The fields of step `k`: the nodal and element variables, and the id maps.
fn read_step(file: &NcFile, path: &Path, layout: &Layout, k: usize) -> Result<Vec<Field>> {
    // Step k of the stored variable `name` (`index`: its column in a combined variable), which
    // must hold `want` values; `what` names the variable and `whose` what has `want` of them.
    let slice = |name: &str, index: Option<usize>, want: usize, what: String, whose: String| -> Result<Vec<f64>> {
        let v = file.variable(name).map_err(nc_err(path, name))?;
        let mut sel = vec![NcSliceInfoElem::Index(k as u64)];
        if let Some(i) = index {
            sel.push(NcSliceInfoElem::Index(i as u64));
        }
        sel.resize(v.shape().len(), NcSliceInfoElem::Slice { start: 0, end: u64::MAX, step: 1 });
        let a = file.read_variable_slice_as_f64(name, &NcSliceInfo { selections: sel }).map_err(nc_err(path, name))?;
        if a.len() != want {
            return Err(Error::format(path, format!("{what} ({name}) has {} values at step {k} but {whose}", a.len())));
        }
        Ok(values(a))
    };
    let mut node = Vec::with_capacity(layout.node_vars.len());
    for v in &layout.node_vars {
        let stored = v.storage[0].as_deref().expect("nodal variables have one storage");
        let (what, n) = (format!("nodal variable '{}'", v.name), layout.n_nodes);
        let values = slice(stored, v.combined, n, what, format!("the mesh has {n} nodes"))?;
        node.push((v.name.clone(), values));
    }
    let mut elem = Vec::with_capacity(layout.elem_vars.len());
    for v in &layout.elem_vars {
        let mut values = Vec::new();
        for (b, stored) in layout.blocks.iter().zip(&v.storage) {
            if b.vtk.is_none() {
                continue;
            }
            match stored {
                None => values.extend(std::iter::repeat_n(f64::NAN, b.n_elems)),
                Some(s) => {
                    let (what, n) = (format!("element variable '{}'", v.name), b.n_elems);
                    values.extend(slice(s, None, n, what, format!("block {} has {n} elements", b.index))?);
                }
            }
        }
        elem.push((v.name.clone(), values));
    }
    let mut fields = grouped(node, FieldLocation::Vertex);
    fields.extend(grouped(elem, FieldLocation::Cell));
    fields.extend(layout.id_maps.iter().cloned());
    // Distinct names can still meet after grouping (`v_x`.. as `v[0]`.. beside a `v[0]`).
    crate::check_distinct_fields(path, &fields)?;
    Ok(fields)
}

/// Fields from named arrays, `NAME_x`, `NAME_y`, `NAME_z` (any case) as the vector `NAME`
/// (`NAME[0..3]`), as ParaView groups them; the others as they are.
fn grouped(arrays: Vec<(String, Vec<f64>)>, location: FieldLocation) -> Vec<Field> {
    let base = |name: &str, axis: usize| {
        let suffix = ["_x", "_y", "_z"][axis];
        (name.len() > 2 && name[name.len() - 2..].eq_ignore_ascii_case(suffix))
            .then(|| name[..name.len() - 2].to_string())
    };
    let names: Vec<String> = arrays.iter().map(|a| a.0.clone()).collect();
    let is_vector = |b: &str| (0..3).all(|axis| names.iter().any(|n| base(n, axis).as_deref() == Some(b)));
    let mut out = Vec::with_capacity(arrays.len());
    for (name, values) in arrays {
        match (0..3).find_map(|axis| base(&name, axis).filter(|b| is_vector(b)).map(|b| (b, axis))) {
            Some((b, axis)) => out.push(Field::from_f64(format!("{b}[{axis}]"), location, values)),
            None => out.push(Field::from_f64(name, location, values)),
        }
    }
    out
}

#[cfg(test)]
mod tests;
