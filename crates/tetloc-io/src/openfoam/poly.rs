//! One `polyMesh` folder (points, faces, owner, neighbour, boundary), checked, and its cells
//! as tetloc's cells: each the polyhedron of its faces (owner faces as they are, neighbour
//! faces reversed, so that all face out), or a hexahedron when it has the shape of one (6
//! quads on 8 points), as ParaView's reader makes it.

use super::foam::Patch;
use super::{find, open};
use std::path::{Path, PathBuf};
use tetloc_core::cell::{CellBlock, CellType};
use tetloc_core::error::{Error, Result};

/// The files of a polyMesh, in the order they are read.
pub(super) const MESH_FILES: [&str; 5] = ["points", "faces", "owner", "neighbour", "boundary"];

/// A polyMesh as read and checked.
pub(super) struct PolyMesh {
    pub points64: Vec<[f64; 3]>,
    face_ends: Vec<u64>,
    face_points: Vec<u32>,
    pub patches: Vec<Patch>,
    pub n_cells: usize,
    /// Each cell's faces, outward: `cell_faces[cell_starts[c]..cell_starts[c + 1]]`, as
    /// (face, reversed).
    cell_starts: Vec<u32>,
    cell_faces: Vec<(u32, bool)>,
}

/// The file `dir/name` (or `name.gz`), or an error naming the folder.
pub(super) fn mesh_file(dir: &Path, name: &str) -> Result<PathBuf> {
    find(dir, name).ok_or_else(|| Error::format(dir, format!("the mesh has no '{name}' file (nor '{name}.gz')")))
}

impl PolyMesh {
    /// Reads the polyMesh folder `dir`; errors name the file at fault.
    pub fn read(dir: &Path) -> Result<PolyMesh> {
        let [points_path, faces_path, owner_path, neighbour_path, boundary_path] =
            MESH_FILES.map(|n| mesh_file(dir, n));
        let (points_path, faces_path, owner_path, neighbour_path, boundary_path) =
            (points_path?, faces_path?, owner_path?, neighbour_path?, boundary_path?);

        let xyz = open(&points_path)?.values(3, "points").map_err(|m| Error::format(&points_path, m))?;
        let points64: Vec<[f64; 3]> = xyz.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        let n_points = points64.len();
        let (face_ends, face_labels) = open(&faces_path)?.faces().map_err(|m| Error::format(&faces_path, m))?;
        let n_faces = face_ends.len();
        let labels =
            |path: &Path| -> Result<Vec<i64>> { open(path)?.labels("labels").map_err(|m| Error::format(path, m)) };
        let owner = labels(&owner_path)?;
        let mut neighbour = labels(&neighbour_path)?;
        // Some writers pad the neighbours of boundary faces with -1.
        while neighbour.last() == Some(&-1) {
            neighbour.pop();
        }
        let patches = open(&boundary_path)?.patches().map_err(|m| Error::format(&boundary_path, m))?;

        if owner.len() != n_faces {
            return Err(Error::format(
                &owner_path,
                format!("{} owners for {n_faces} faces: one owner per face", owner.len()),
            ));
        }
        let n_internal = neighbour.len();
        if n_internal > n_faces {
            return Err(Error::format(
                &neighbour_path,
                format!("{n_internal} neighbours for {n_faces} faces: more internal faces than faces"),
            ));
        }
        // The faces past the internal ones are boundary faces: every one in exactly one patch.
        let mut covered = vec![0u8; n_faces - n_internal];
        for p in &patches {
            if p.start < n_internal || p.start + p.n_faces > n_faces {
                return Err(Error::format(
                    &boundary_path,
                    format!(
                        "patch '{}' ({}) lists faces {}..{}, outside the boundary faces {n_internal}..{n_faces}",
                        p.name,
                        p.ty,
                        p.start,
                        p.start + p.n_faces
                    ),
                ));
            }
            covered[p.start - n_internal..p.start - n_internal + p.n_faces].iter_mut().for_each(|c| *c += 1);
        }
        if let Some(i) = covered.iter().position(|&c| c != 1) {
            let f = n_internal + i;
            let why = if covered[i] == 0 { "no boundary patch lists it" } else { "more than one patch lists it" };
            return Err(Error::format(
                &boundary_path,
                format!(
                    "face {f} is owned by cell {} and has no neighbour, but {why} ({} such faces)",
                    owner[f],
                    covered.iter().filter(|&&c| c != 1).count()
                ),
            ));
        }

        let check_cell = |v: i64, path: &Path, i: usize| -> Result<u32> {
            u32::try_from(v).map_err(|_| Error::format(path, format!("entry {i} ({v}) is not a cell id")))
        };
        let owner: Vec<u32> =
            owner.iter().enumerate().map(|(i, &v)| check_cell(v, &owner_path, i)).collect::<Result<_>>()?;
        let neighbour: Vec<u32> =
            neighbour.iter().enumerate().map(|(i, &v)| check_cell(v, &neighbour_path, i)).collect::<Result<_>>()?;
        let face_points: Vec<u32> = face_labels
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                u32::try_from(v).ok().filter(|&p| (p as usize) < n_points).ok_or_else(|| {
                    Error::format(&faces_path, format!("face label {i} ({v}) is not a point id ({n_points} points)"))
                })
            })
            .collect::<Result<_>>()?;
        let n_cells = owner.iter().chain(&neighbour).map(|&c| c as usize + 1).max().unwrap_or(0);
        if n_cells == 0 {
            return Err(Error::format(&owner_path, "the mesh has no cells"));
        }

        // Each cell's faces, outward: (face, reversed).
        let mut cell_starts = vec![0u32; n_cells + 1];
        owner.iter().chain(&neighbour).for_each(|&c| cell_starts[c as usize + 1] += 1);
        for i in 0..n_cells {
            cell_starts[i + 1] += cell_starts[i];
        }
        let mut cell_faces = vec![(0u32, false); cell_starts[n_cells] as usize];
        let mut fill = cell_starts.clone();
        for (f, &c) in owner.iter().enumerate() {
            cell_faces[fill[c as usize] as usize] = (f as u32, false);
            fill[c as usize] += 1;
        }
        for (f, &c) in neighbour.iter().enumerate() {
            cell_faces[fill[c as usize] as usize] = (f as u32, true);
            fill[c as usize] += 1;
        }
        Ok(PolyMesh { points64, face_ends, face_points, patches, n_cells, cell_starts, cell_faces })
    }

    /// The point ids of face `f`, as listed.
    pub fn face(&self, f: usize) -> &[u32] {
        let start = if f == 0 { 0 } else { self.face_ends[f - 1] as usize };
        &self.face_points[start..self.face_ends[f] as usize]
    }

    /// The points of the faces of the patches of type `processor`: those a neighbouring
    /// processor has too.
    pub fn processor_points(&self) -> Vec<u32> {
        let mut out: Vec<u32> = self
            .patches
            .iter()
            .filter(|p| p.ty == "processor")
            .flat_map(|p| (p.start..p.start + p.n_faces).flat_map(|f| self.face(f).iter().copied()))
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Appends cell `c` to `block`, its point ids mapped by `point`.
    pub fn push_cell(&self, c: usize, point: &impl Fn(u32) -> u32, block: &mut CellBlock) {
        let faces: Vec<Vec<u32>> = self.cell_faces[self.cell_starts[c] as usize..self.cell_starts[c + 1] as usize]
            .iter()
            .map(|&(f, reversed)| {
                let mut v: Vec<u32> = self.face(f as usize).iter().map(|&p| point(p)).collect();
                if reversed {
                    v.reverse();
                }
                v
            })
            .collect();
        match hex_nodes(&faces) {
            Some(nodes) => block.push(CellType::from_vtk(12, 8).expect("hexahedra are read"), &nodes),
            None => block.push_polyhedron(faces.iter().map(Vec::as_slice)),
        }
    }
}

/// A cell's nodes in VTK's hexahedron order, when its faces (outward) are 6 quads on 8 points
/// with the hexahedron's connectivity; `None` otherwise (it stays a polyhedron).
fn hex_nodes(faces: &[Vec<u32>]) -> Option<[u32; 8]> {
    if faces.len() != 6 || faces.iter().any(|f| f.len() != 4) {
        return None;
    }
    // The bottom: the first face, reversed so that it faces in (VTK's 0-1-2-3 turn towards 4-7).
    let bottom = [faces[0][0], faces[0][3], faces[0][2], faces[0][1]];
    // Each bottom corner's edge off the bottom face: the one neighbour (by a face edge) not in
    // the bottom.
    let mut top = [u32::MAX; 4];
    for (k, &b) in bottom.iter().enumerate() {
        let mut up = None;
        for f in faces {
            for i in 0..4 {
                let (a, c) = (f[i], f[(i + 1) % 4]);
                let other = if a == b {
                    c
                } else if c == b {
                    a
                } else {
                    continue;
                };
                if !bottom.contains(&other) {
                    match up {
                        None => up = Some(other),
                        Some(u) if u == other => {}
                        Some(_) => return None,
                    }
                }
            }
        }
        top[k] = up?;
    }
    let nodes = [bottom[0], bottom[1], bottom[2], bottom[3], top[0], top[1], top[2], top[3]];
    let mut sorted = nodes;
    sorted.sort_unstable();
    if sorted.windows(2).any(|w| w[0] == w[1]) {
        return None;
    }
    // The top face must be one of the faces (else it is not a hexahedron's connectivity).
    let mut want = top;
    want.sort_unstable();
    faces
        .iter()
        .any(|f| {
            let mut s = [f[0], f[1], f[2], f[3]];
            s.sort_unstable();
            s == want
        })
        .then_some(nodes)
}
