//! Partitioned meshes: the VTU pieces that a `.pvtu` ([`super::pvtu`]) or `.vtm`
//! ([`super::vtm`]) lists, read as one mesh, or a subset of them as one rank's part of it
//! (`tetloc-mpi`).
//!
//! **Cell ids are global ids.** A piece's cells carry them in an integer cell array
//! `GlobalCellIds` or `vtkGlobalIds` (or the one `<CellData GlobalIds="NAME">` names); without
//! one in any piece, the global id is the position in piece order × cell order. Read whole, the
//! mesh's cells are renumbered by them (cell `g` is the cell with global id `g`), so every
//! command answers in global ids; the ids must then be `0..N` once each.
//!
//! **Vertices.** A vertex on a face between two pieces is in both pieces. When every piece
//! has global point ids (an integer point array `GlobalPointIds` or `vtkGlobalIds`, or the one
//! `<PointData GlobalIds="NAME">` names; `tetloc partition` writes them), the copies are
//! merged into one vertex (numbered in global id order: a partitioned mesh read whole is the
//! mesh it was cut from); copies of one id at different coordinates are an error. Without
//! them the copies stay two vertices at the same coordinates. Tets do not mind: the two copies
//! of a shared face have the same coordinates, so the point-in-tet test and the tie rule treat
//! them as one face (a point on it is claimed by the tets on both sides exactly as if they were
//! neighbours, and the tie rule picks one; see `geom`), and walks fall back to the BVH at such
//! faces. Mixed cells do mind where a *warped* quad face lies between two pieces: the step to
//! the neighbour across it (`locate::CellLocator`) needs the shared vertices, so a point in the
//! sliver between the face's two triangles and its bilinear patch may come back outside.

use super::vtu;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use tetloc_core::cell::CellBlock;
use tetloc_core::error::{Error, Result};
use tetloc_core::mesh::{FieldLocation, RawMesh};

/// How deep listings may nest (a `.vtm` of `.pvtu`s is 2): a listing that lists itself stops here.
const MAX_NESTING: usize = 4;

/// `file` as named in the listing `listing`: relative paths are relative to its folder.
pub fn resolve(listing: &Path, file: &str) -> PathBuf {
    let file = Path::new(file);
    match listing.parent() {
        Some(dir) if file.is_relative() => dir.join(file),
        _ => file.to_path_buf(),
    }
}

/// The `<KIND>` element of a listing whose root is `<VTKFile type="KIND">` (a `.pvtu`'s
/// `PUnstructuredGrid`, a `.vtm`'s `vtkMultiBlockDataSet`); `what` names the listing in the
/// errors, which name `path`.
pub(super) fn listing_element<'d, 'a>(
    doc: &'d super::xml::Document<'a>,
    path: &Path,
    kind: &str,
    what: &str,
) -> Result<&'d super::xml::Node<'a>> {
    let fail = |msg: String| Error::format(path, msg);
    let root = &doc.root;
    if root.name != "VTKFile" {
        return Err(fail(format!("not a VTK XML file: the root element is <{}>, not <VTKFile>", root.name)));
    }
    if root.attr("type") != Some(kind) {
        let found = root.attr("type").unwrap_or("(none)");
        return Err(fail(format!("a VTK XML file of type '{found}': {what} is a {kind}")));
    }
    root.child(kind).ok_or_else(|| fail(format!("no <{kind}> element")))
}

/// Whether `path` names a listing of pieces (`.pvtu`, `.vtm`).
pub fn is_listing(path: &Path) -> bool {
    matches!(crate::output::extension(path).as_str(), "pvtu" | "vtm")
}

/// Whether listings may name pieces outside their folder tree when the caller does not say
/// ([`list`], [`read`]); the CLI's `--allow-outside-pieces` sets it for the whole run.
static ALLOW_OUTSIDE_BY_DEFAULT: AtomicBool = AtomicBool::new(false);

/// Lets listings read in this process without an explicit choice ([`list`], [`read`]) name
/// pieces outside their folder tree (`false`, the default, refuses them).
pub fn set_allow_outside_by_default(allow: bool) {
    ALLOW_OUTSIDE_BY_DEFAULT.store(allow, Ordering::Relaxed);
}

/// Whether [`set_allow_outside_by_default`] allowed pieces outside their listing's folder.
pub fn allows_outside_by_default() -> bool {
    ALLOW_OUTSIDE_BY_DEFAULT.load(Ordering::Relaxed)
}

/// The VTU pieces of a `.pvtu` or `.vtm`, in order (listings inside a `.vtm` expanded).
/// Pieces outside the listing's folder tree are refused unless allowed (see [`list_with`]).
pub fn list(path: &Path) -> Result<Vec<PathBuf>> {
    list_with(path, allows_outside_by_default())
}

/// [`list`]; `allow_outside`: whether pieces (and nested listings) may lie outside the folder
/// of the listing `path` (`../`, absolute paths, symbolic links that lead out). A listing
/// from an untrusted source should not make tetloc read arbitrary files, so by default they
/// are refused.
pub fn list_with(path: &Path, allow_outside: bool) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let root = if allow_outside { None } else { Some(listing_folder(path)?) };
    list_into(path, 0, root.as_deref(), &mut out, &mut Vec::new(), &mut HashMap::new())?;
    Ok(out)
}

/// Every file that reading the listing `path` reads: the listings (itself first, then those
/// it nests) and the pieces.
pub fn files_read(path: &Path) -> Result<Vec<PathBuf>> {
    let (mut pieces, mut listings) = (Vec::new(), Vec::new());
    let root = if allows_outside_by_default() { None } else { Some(listing_folder(path)?) };
    list_into(path, 0, root.as_deref(), &mut pieces, &mut listings, &mut HashMap::new())?;
    listings.extend(pieces);
    Ok(listings)
}

/// The folder a listing's pieces must lie in: the listing's own, symbolic links resolved.
pub(crate) fn listing_folder(listing: &Path) -> Result<PathBuf> {
    let dir = match listing.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    std::fs::canonicalize(dir).map_err(|e| Error::io(dir, e))
}

/// An error unless `piece` (as listed in `listing`) lies inside `root` once `..` and symbolic
/// links are resolved. A piece that does not exist is judged by its path as written.
pub(crate) fn check_inside(root: &Path, listing: &Path, piece: &Path) -> Result<()> {
    let resolved = match std::fs::canonicalize(piece) {
        Ok(p) => p,
        Err(_) => {
            // Missing: judged by the name as listed (reading it then says that it is missing).
            let named = listing.parent().and_then(|d| piece.strip_prefix(d).ok()).unwrap_or(piece);
            if !climbs_out(named) {
                return Ok(());
            }
            // Outside by its name alone (`starts_with` would take `root/../x` for inside).
            PathBuf::new()
        }
    };
    if resolved.starts_with(root) {
        return Ok(());
    }
    Err(Error::format(
        listing,
        format!(
            "lists {}, which lies outside the listing's folder {}; pieces outside it are refused \
             (a listing should not make tetloc read other files): pass --allow-outside-pieces \
             (Python: allow_outside_pieces=True) to read it",
            piece.display(),
            root.display()
        ),
    ))
}

/// Whether a relative path leaves its folder (`../`, or more `..` than folders before them),
/// or is absolute.
fn climbs_out(path: &Path) -> bool {
    use std::path::Component;
    let mut depth = 0usize;
    for c in path.components() {
        match c {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir if depth > 0 => depth -= 1,
            _ => return true,
        }
    }
    false
}

/// What makes two names one file: (device, inode) on Unix, so hard links count too; the
/// canonical path elsewhere.
#[cfg(unix)]
type FileKey = (u64, u64);
#[cfg(not(unix))]
type FileKey = PathBuf;

/// The identity of the listed file `f`, or `None` if it does not exist (reading it says so);
/// an error if it is not a regular file: opening a FIFO blocks forever, a device never ends.
fn listed_file_key(listing: &Path, f: &Path) -> Result<Option<FileKey>> {
    // `metadata` follows symbolic links: a link to a FIFO is a FIFO.
    let Ok(meta) = std::fs::metadata(f) else { return Ok(None) };
    if !meta.is_file() {
        let kind = if meta.is_dir() { "a folder" } else { "not a regular file (a FIFO, socket or device?)" };
        return Err(Error::format(listing, format!("lists {}, which is {kind}; pieces must be files", f.display())));
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        Ok(Some((meta.dev(), meta.ino())))
    }
    #[cfg(not(unix))]
    {
        Ok(std::fs::canonicalize(f).ok())
    }
}

/// Collects the pieces of `path` into `out` (and the listings read into `listings`); `seen`
/// maps every file listed so far to its name, so that no piece is read twice.
fn list_into(
    path: &Path,
    depth: usize,
    root: Option<&Path>,
    out: &mut Vec<PathBuf>,
    listings: &mut Vec<PathBuf>,
    seen: &mut HashMap<FileKey, PathBuf>,
) -> Result<()> {
    listings.push(path.to_path_buf());
    if depth > MAX_NESTING {
        return Err(Error::format(path, format!("listings nest more than {MAX_NESTING} deep (does one list itself?)")));
    }
    let bytes = super::read_file(path)?;
    let files = match crate::output::extension(path).as_str() {
        "pvtu" => super::pvtu::parse(&bytes, path)?,
        "vtm" => super::vtm::parse(&bytes, path)?,
        other => return Err(Error::format(path, format!("'.{other}' is not a listing of pieces (.pvtu, .vtm)"))),
    };
    for f in files {
        if let Some(root) = root {
            check_inside(root, path, &f)?;
        }
        let key = listed_file_key(path, &f)?;
        let is_piece = crate::output::extension(&f) == "vtu";
        // Without global ids a repeated piece would be read twice, silently. (A listing met
        // again is left to the nesting limit: its pieces repeat anyway.)
        if let Some(key) = key.filter(|_| is_piece) {
            if let Some(first) = seen.insert(key, f.clone()) {
                let again = if first == f { String::new() } else { format!(" (first as {})", first.display()) };
                return Err(Error::format(
                    path,
                    format!("lists {} a second time{again}: each piece must be listed once", f.display()),
                ));
            }
        }
        match crate::output::extension(&f).as_str() {
            "vtu" => out.push(f),
            "pvtu" | "vtm" => list_into(&f, depth + 1, root, out, listings, seen)?,
            _ => {
                return Err(Error::format(
                    path,
                    format!("lists {}: tetloc reads pieces that are unstructured grids (.vtu)", f.display()),
                ))
            }
        }
    }
    Ok(())
}

/// One piece as read: its mesh (cells in the piece's order) and its global cell ids, if it has them.
pub struct Piece {
    pub path: PathBuf,
    pub raw: RawMesh,
    pub global_ids: Option<Vec<u64>>,
    /// One global id per point, when the piece has them.
    pub global_point_ids: Option<Vec<u64>>,
}

impl Piece {
    pub fn n_cells(&self) -> usize {
        n_cells(&self.raw)
    }
}

fn n_cells(raw: &RawMesh) -> usize {
    raw.cells.as_ref().map_or(raw.tets.len(), CellBlock::len)
}

/// Reads piece `index` of `listing` (errors name both).
pub fn read_piece(listing: &Path, index: usize, path: &Path) -> Result<Piece> {
    let in_listing = |e: Error| Error::format(listing, format!("piece {index} ({}): {e}", path.display()));
    let bytes = super::read_file(path).map_err(in_listing)?;
    let (raw, ids) = vtu::parse_with_ids(&bytes, path).map_err(in_listing)?;
    let (global_ids, global_point_ids) = (ids.cells, ids.points);
    if let Some(ids) = &global_ids {
        if ids.len() != n_cells(&raw) {
            return Err(in_listing(Error::format(path, "the global cell ids are not one per volume cell")));
        }
    }
    Ok(Piece { path: path.to_path_buf(), raw, global_ids, global_point_ids })
}

/// What a piece carries, for comparing pieces: its fields (name, location) in order, and
/// whether it has global ids.
fn signature(p: &Piece) -> (Vec<(&str, FieldLocation)>, bool) {
    (p.raw.fields.iter().map(|f| (f.name.as_str(), f.location)).collect(), p.global_ids.is_some())
}

/// Every piece must carry the same arrays as the first: a field missing in one piece would
/// have no value there.
pub fn check_same_arrays(listing: &Path, pieces: &[(usize, Piece)]) -> Result<()> {
    let Some((k0, first)) = pieces.first() else { return Ok(()) };
    let (fields0, ids0) = signature(first);
    for (k, p) in &pieces[1..] {
        let (fields, ids) = signature(p);
        if ids != ids0 {
            let (with, without) = if ids0 { ((k0, first), (k, p)) } else { ((k, p), (k0, first)) };
            return Err(Error::format(
                listing,
                format!(
                    "piece {} ({}) has global cell ids and piece {} ({}) has none",
                    with.0,
                    with.1.path.display(),
                    without.0,
                    without.1.path.display()
                ),
            ));
        }
        if fields != fields0 {
            let show = |f: &[(&str, FieldLocation)]| {
                f.iter().map(|(n, l)| format!("{n} ({l:?})").to_lowercase()).collect::<Vec<_>>().join(", ")
            };
            return Err(Error::format(
                listing,
                format!(
                    "piece {k} ({}) has the arrays [{}] but piece {k0} ({}) has [{}]",
                    p.path.display(),
                    show(&fields),
                    first.path.display(),
                    show(&fields0)
                ),
            ));
        }
    }
    Ok(())
}

/// Joins pieces (each with its index in the listing and the default global id of its first
/// cell: the cells of the pieces before it) into one mesh in piece order, and returns each
/// cell's global id. The global-id arrays are dropped from the fields (the ids say it).
pub fn join(listing: &Path, pieces: Vec<(usize, Piece)>, first_ids: &[u64]) -> Result<(RawMesh, Vec<u64>)> {
    check_same_arrays(listing, &pieces)?;
    let mut ids = Vec::with_capacity(pieces.iter().map(|(_, p)| p.n_cells()).sum());
    let mut raws = Vec::with_capacity(pieces.len());
    let mut point_ids = pieces.iter().all(|(_, p)| p.global_point_ids.is_some()).then(Vec::new);
    for ((_, p), &first) in pieces.into_iter().zip(first_ids) {
        match &p.global_ids {
            Some(g) => ids.extend_from_slice(g),
            None => ids.extend(first..first + p.n_cells() as u64),
        }
        if let (Some(all), Some(g)) = (&mut point_ids, &p.global_point_ids) {
            all.extend_from_slice(g);
        }
        raws.push(p.raw);
    }
    let mut raw = vtu::join(raws, listing)?;
    raw.fields.retain(|f| match f.location {
        FieldLocation::Cell => !vtu::GLOBAL_CELL_IDS.contains(&f.name.as_str()),
        FieldLocation::Vertex => point_ids.is_none() || !vtu::GLOBAL_POINT_IDS.contains(&f.name.as_str()),
    });
    if let Some(point_ids) = point_ids {
        raw = weld(raw, &point_ids, listing)?;
    }
    Ok((raw, ids))
}

/// Merges the points that share a global point id into one, numbered in ascending global id.
fn weld(mut raw: RawMesh, ids: &[u64], listing: &Path) -> Result<RawMesh> {
    use rayon::prelude::*;
    if ids.len() != raw.points.len() {
        return Err(Error::format(listing, "the pieces' global point ids are not one per point"));
    }
    let mut order: Vec<u32> = (0..ids.len() as u32).collect();
    order.par_sort_unstable_by_key(|&i| (ids[i as usize], i));
    let mut new_of = vec![0u32; ids.len()];
    let mut kept: Vec<u32> = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        let i = i as usize;
        if k == 0 || ids[order[k - 1] as usize] != ids[i] {
            kept.push(i as u32);
        } else {
            let first = *kept.last().unwrap() as usize;
            let differ = match &raw.points64 {
                Some(p64) => p64[first] != p64[i],
                None => raw.points[first] != raw.points[i],
            };
            if differ {
                return Err(Error::format(
                    listing,
                    format!(
                        "global point id {} is at {:?} in one piece and at {:?} in another",
                        ids[i], raw.points[first], raw.points[i]
                    ),
                ));
            }
            // Keeping one copy's value would drop the other's silently. Bitwise: NaN == NaN.
            let vertex = raw.fields.iter().filter(|f| f.location == FieldLocation::Vertex);
            if let Some(f) = vertex.clone().find(|f| match &f.values64 {
                Some(v) => v[first].to_bits() != v[i].to_bits(),
                None => f.values[first].to_bits() != f.values[i].to_bits(),
            }) {
                let at = |j: usize| f.values64.as_ref().map_or(f.values[j] as f64, |v| v[j]);
                return Err(Error::format(
                    listing,
                    format!(
                        "point field '{}' is {} at global point id {} in one piece and {} in another",
                        f.name,
                        at(first),
                        ids[i],
                        at(i)
                    ),
                ));
            }
        }
        new_of[i] = (kept.len() - 1) as u32;
    }
    raw.points = kept.iter().map(|&i| raw.points[i as usize]).collect();
    if let Some(p64) = &mut raw.points64 {
        *p64 = kept.iter().map(|&i| p64[i as usize]).collect();
    }
    for f in raw.fields.iter_mut().filter(|f| f.location == FieldLocation::Vertex) {
        *f = f.select(|j| kept[j] as usize, kept.len());
    }
    raw.tets.par_iter_mut().for_each(|t| *t = t.map(|i| new_of[i as usize]));
    if let Some(b) = &mut raw.cells {
        b.conn.par_iter_mut().for_each(|i| *i = new_of[*i as usize]);
    }
    Ok(raw)
}

/// Reads a whole partitioned mesh (`.pvtu`, `.vtm`), cells numbered by their global ids.
/// Pieces outside the listing's folder tree are refused unless allowed (see [`list_with`]).
pub fn read(path: &Path) -> Result<RawMesh> {
    read_with(path, allows_outside_by_default())
}

/// [`read`]; `allow_outside` as in [`list_with`].
pub fn read_with(path: &Path, allow_outside: bool) -> Result<RawMesh> {
    let files = list_with(path, allow_outside)?;
    let pieces = files.iter().enumerate().map(|(k, f)| Ok((k, read_piece(path, k, f)?))).collect::<Result<Vec<_>>>()?;
    let mut first_ids = Vec::with_capacity(pieces.len());
    let mut n = 0u64;
    for (_, p) in &pieces {
        first_ids.push(n);
        n += p.n_cells() as u64;
    }
    let (raw, ids) = join(path, pieces, &first_ids)?;
    renumber(raw, &ids, path, &first_ids)
}

/// The mesh with cell `c` moved to position `ids[c]`; `ids` must hold `0..N` once each
/// (errors name the piece, found from `first_ids`, the piece starts).
fn renumber(mut raw: RawMesh, ids: &[u64], listing: &Path, first_ids: &[u64]) -> Result<RawMesh> {
    let n = ids.len();
    let piece_of = |c: usize| first_ids.partition_point(|&f| f <= c as u64).saturating_sub(1);
    let mut cell_of = vec![usize::MAX; n];
    let mut identity = true;
    for (c, &g) in ids.iter().enumerate() {
        let bad = |why: String| {
            let k = piece_of(c);
            Error::format(
                listing,
                format!(
                    "piece {k}, cell {}: global cell id {g} {why}",
                    c as u64 - first_ids.get(k).copied().unwrap_or(0)
                ),
            )
        };
        if g >= n as u64 {
            return Err(bad(format!("is not below the number of cells, {n} (ids must be 0..{n} once each)")));
        }
        let slot = &mut cell_of[g as usize];
        if *slot != usize::MAX {
            let (k, other) = (piece_of(*slot), *slot as u64);
            let local = other - first_ids.get(k).copied().unwrap_or(0);
            return Err(bad(format!("is also the id of piece {k}, cell {local} (ghost cells?)")));
        }
        *slot = c;
        identity &= g == c as u64;
    }
    if identity {
        return Ok(raw);
    }
    if !raw.tets.is_empty() {
        raw.tets = cell_of.iter().map(|&c| raw.tets[c]).collect();
    }
    if let Some(block) = &raw.cells {
        let mut out = CellBlock::default();
        cell_of.iter().for_each(|&c| out.push(block.types[c], block.nodes(c)));
        raw.cells = Some(out);
    }
    for f in raw.fields.iter_mut().filter(|f| f.location == FieldLocation::Cell) {
        *f = f.select(|j| cell_of[j], cell_of.len());
    }
    Ok(raw)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::KuhnGrid;
    use std::sync::Arc;
    use tetloc_core::locate::{BatchLocator, CpuLocator};
    use tetloc_core::Mesh;

    fn cube() -> Mesh {
        KuhnGrid::new(6).jitter(0.2, 3).cell_field("c", |i, _| i as f32).mesh("cube")
    }

    /// [`cube`] partitioned into `parts` pieces, listed as `name` in a fresh folder (removed
    /// with the guard).
    fn partitioned_cube(name: &str, parts: usize, zlib: bool) -> (tempfile::TempDir, Mesh, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let (m, out) = (cube(), dir.path().join(name));
        crate::partition::write_pvtu(&m, parts, &out, zlib, |_| {}).unwrap();
        (dir, m, out)
    }

    /// f64 fields (values f32 cannot hold, a point and a cell field) survive partitioning
    /// into pieces and the pieces' merge, bit for bit, through .pvtu and .vtm.
    #[test]
    fn f64_fields_survive_the_pieces() {
        use tetloc_core::mesh::{Field, FieldLocation};
        let dir = tempfile::tempdir().unwrap();
        let mut m = cube();
        let g = (0..m.points.len()).map(|i| 1e-9 + i as f64 * 1e-12 + 1e-17).collect();
        m.fields.push(Field::from_f64("g", FieldLocation::Vertex, g));
        m.fields.push(Field::from_f64("h", FieldLocation::Cell, (0..m.n_cells()).map(|t| t as f64 / 3.0).collect()));
        crate::partition::write_pvtu(&m, 3, &dir.path().join("cube.pvtu"), false, |_| {}).unwrap();
        let vtm = r#"<VTKFile type="vtkMultiBlockDataSet" version="1.0"><vtkMultiBlockDataSet>
            <DataSet index="0" file="cube.pvtu"/></vtkMultiBlockDataSet></VTKFile>"#;
        std::fs::write(dir.path().join("cube.vtm"), vtm).unwrap();
        for ext in ["pvtu", "vtm"] {
            let out = dir.path().join(format!("cube.{ext}"));
            let back = crate::read_mesh(&out, None).unwrap();
            assert_eq!(back.points, m.points, "{ext}");
            for name in ["g", "h"] {
                let bits = |m: &Mesh| {
                    m.field(name).unwrap().values64.clone().unwrap().iter().map(|x| x.to_bits()).collect::<Vec<_>>()
                };
                assert_eq!(bits(&back), bits(&m), "{ext}: {name}");
            }
            assert!(back.field("c").unwrap().values64.is_none(), "{ext}: f32 data stays f32");
        }
    }

    /// Partitioned and read back whole, the mesh has the same cells under the same ids (its
    /// cell field says so), and every point gets the same cell and value as in the original.
    #[test]
    fn partition_round_trip() {
        let (dir, m, out) = partitioned_cube("cube.pvtu", 5, true);
        assert_eq!(list(&out).unwrap().len(), 5);
        let back = crate::read_mesh(&out, None).unwrap();
        assert_eq!(back.n_cells(), m.n_cells());
        assert_eq!(back.points, m.points, "the copies of a vertex are merged by GlobalPointIds, in id order");
        assert_eq!(back.tets, m.tets);
        assert_eq!(back.field("c").unwrap().values, m.field("c").unwrap().values, "cells renumbered by global id");
        assert!(back.field("GlobalCellIds").is_err(), "the ids are the numbering, not a field");
        for (a, b) in back.tets.iter().zip(m.tets.iter()) {
            assert_eq!(a.map(|i| back.points[i as usize]), b.map(|i| m.points[i as usize]));
        }
        let pts: Vec<[f32; 3]> =
            (0..20_000).map(|i| [(i % 97) as f32 / 96.0, (i % 89) as f32 / 88.0, (i % 83) as f32 / 82.0]).collect();
        let (mut a, mut b, mut va, mut vb) =
            (vec![0; pts.len()], vec![0; pts.len()], vec![0.0; pts.len()], vec![0.0; pts.len()]);
        CpuLocator::new(Arc::new(m)).locate_and_sample(&pts, "f", &mut a, &mut va).unwrap();
        let back = Arc::new(back);
        CpuLocator::new(back.clone()).locate_and_sample(&pts, "f", &mut b, &mut vb).unwrap();
        for i in 0..pts.len() {
            if a[i] != b[i] {
                // Only a point on a face between pieces may go either way: both tets hold it.
                let t = back.tets[a[i] as usize];
                assert!(tetloc_core::geom::point_in_tet(t, &back.points, pts[i]).is_some(), "{:?}", pts[i]);
            } else {
                assert_eq!(va[i].to_bits(), vb[i].to_bits(), "{:?}", pts[i]);
            }
        }
        // Written again over itself: replaced, still complete, the new pieces in the other
        // folder and the old ones gone; a third write goes back to the first folder.
        crate::partition::write_pvtu(&back, 2, &out, false, |_| {}).unwrap();
        assert_eq!(list(&out).unwrap(), [0, 1].map(|k| dir.path().join(format!("cube.1/cube_{k}.vtu"))));
        assert!(!dir.path().join("cube").exists(), "the old pieces are gone");
        crate::partition::write_pvtu(&back, 3, &out, false, |_| {}).unwrap();
        assert_eq!(std::fs::read_dir(dir.path().join("cube")).unwrap().count(), 3);
        assert!(!dir.path().join("cube.1").exists());
        assert_eq!(crate::read_mesh(&out, None).unwrap().field("c").unwrap().values, back.field("c").unwrap().values);
    }

    /// A mesh far from the origin (UTM-like, f64 coordinates that do not round to f32) keeps
    /// its file coordinates through partition and read-back: the pieces are written in Float64
    /// file coordinates (not the centred working copy), welded by GlobalPointIds in f64.
    #[test]
    fn far_from_the_origin_pieces_keep_the_file_coordinates() {
        let dir = tempfile::tempdir().unwrap();
        let raw = crate::test_support::jittered_grid(4, 0.25, 7);
        let shift = [512_345.037_5, 4_123_456.062_5, 0.3];
        let file: Vec<[f64; 3]> =
            raw.points.iter().map(|p| std::array::from_fn(|k| p[k] as f64 * 1000.0 + shift[k] + 1e-7)).collect();
        let raw = RawMesh { points: file.iter().map(|p| p.map(|c| c as f32)).collect(), points64: Some(file), ..raw };
        let m = Mesh::new(raw, "far grid").unwrap();
        assert!(!m.info.frame.is_identity());
        let out = dir.path().join("far.pvtu");
        crate::partition::write_pvtu(&m, 3, &out, false, |_| {}).unwrap();
        for piece in list(&out).unwrap() {
            let p = crate::read_mesh(&piece, None).unwrap();
            assert!(p.points64.is_some(), "{}: written in f64", piece.display());
        }
        let back = crate::read_mesh(&out, None).unwrap();
        assert_eq!(back.points64, m.points64, "the file's coordinates, welded in f64");
        assert_eq!(back.tets, m.tets);
    }

    /// Mixed cells and higher-order tets keep every node through a partition.
    fn hybrid() -> Mesh {
        use tetloc_core::gen::{generate_spec, CellKind, Shape, Spec};
        Mesh::new(generate_spec(Spec { shape: Shape::Jets, cells: CellKind::Hybrid }, 3000, 1, &|_| {}), "hybrid")
            .unwrap()
    }

    #[test]
    fn mixed_and_higher_order_pieces() {
        let dir = tempfile::tempdir().unwrap();
        for (name, m) in [("p2", KuhnGrid::new(3).order(2).mesh("p2")), ("hybrid", hybrid())] {
            let out = dir.path().join(format!("{name}.pvtu"));
            crate::partition::write_pvtu(&m, 3, &out, false, |_| {}).unwrap();
            let back = crate::read_mesh(&out, None).unwrap();
            assert_eq!((back.n_cells(), back.n_tets()), (m.n_cells(), m.n_tets()), "{name}");
            assert_eq!(back.info.cell_types, m.info.cell_types, "{name}");
            assert_eq!(back.info.total_volume, m.info.total_volume, "{name}");
        }
    }

    #[test]
    fn vtm_and_order_without_ids() {
        let (dir, m, _) = partitioned_cube("a.pvtu", 2, false);
        // Pieces without global ids: numbered in piece order × cell order.
        let plain = |k: usize| {
            let raw = crate::vtk::vtu::read(&dir.path().join(format!("a/a_{k}.vtu"))).unwrap();
            let mut mesh = Mesh::new(raw, "p").unwrap();
            mesh.fields.retain(|f| f.name != "GlobalCellIds");
            let p = dir.path().join(format!("plain_{k}.vtu"));
            crate::vtk::write::write_mesh_vtu(&p, &mesh, false).unwrap();
            mesh
        };
        let (p0, p1) = (plain(0), plain(1));
        let vtm = r#"<VTKFile type="vtkMultiBlockDataSet" version="1.0"><vtkMultiBlockDataSet>
            <Block index="0"><DataSet index="0" file="plain_0.vtu"/></Block><DataSet index="1" file="plain_1.vtu"/>
            </vtkMultiBlockDataSet></VTKFile>"#;
        std::fs::write(dir.path().join("b.vtm"), vtm).unwrap();
        let back = crate::read_mesh(&dir.path().join("b.vtm"), None).unwrap();
        let c = &back.field("c").unwrap().values;
        assert_eq!(c[..p0.n_cells()], p0.field("c").unwrap().values[..]);
        assert_eq!(c[p0.n_cells()..], p1.field("c").unwrap().values[..]);
        // A .vtm of the .pvtu: its pieces, with their ids.
        std::fs::write(
            dir.path().join("c.vtm"),
            vtm.replace("plain_0.vtu", "a.pvtu").replace("<DataSet index=\"1\" file=\"plain_1.vtu\"/>", ""),
        )
        .unwrap();
        assert_eq!(
            crate::read_mesh(&dir.path().join("c.vtm"), None).unwrap().field("c").unwrap().values,
            m.field("c").unwrap().values
        );
    }

    /// The files a partitioned mesh reads: its listings and every piece (item 1 of issue 29:
    /// an output onto one of them is refused); an unreadable listing counts as itself.
    #[test]
    fn input_files_list_every_piece() {
        use crate::{input_files, MeshFormat};
        let (dir, _, _) = partitioned_cube("a.pvtu", 2, false);
        let vtm = r#"<VTKFile type="vtkMultiBlockDataSet" version="1.0"><vtkMultiBlockDataSet>
            <DataSet index="0" file="a.pvtu"/></vtkMultiBlockDataSet></VTKFile>"#;
        std::fs::write(dir.path().join("b.vtm"), vtm).unwrap();
        let pieces = ["a/a_0.vtu", "a/a_1.vtu"].map(|p| dir.path().join(p));
        let pvtu = input_files(&dir.path().join("a.pvtu"), None);
        assert_eq!(pvtu, [vec![dir.path().join("a.pvtu")], pieces.to_vec()].concat());
        let vtm = input_files(&dir.path().join("b.vtm"), None);
        assert_eq!(vtm, [vec![dir.path().join("b.vtm"), dir.path().join("a.pvtu")], pieces.to_vec()].concat());
        let tetgen = input_files(Path::new("m.ele"), None);
        assert_eq!(tetgen, [PathBuf::from("m.node"), PathBuf::from("m.ele")]);
        let missing = dir.path().join("none.pvtu");
        assert_eq!(input_files(&missing, Some(MeshFormat::Pieces)), std::slice::from_ref(&missing));
    }

    #[test]
    fn errors_name_the_file() {
        let (dir, m, out) = partitioned_cube("e.pvtu", 3, false);
        let err = |p: &Path| crate::read_mesh(p, None).unwrap_err().to_string();
        // A piece missing.
        std::fs::rename(dir.path().join("e/e_1.vtu"), dir.path().join("e1.vtu")).unwrap();
        let e = err(&out);
        assert!(e.starts_with(&out.display().to_string()) && e.contains("piece 1") && e.contains("e_1.vtu"), "{e}");
        // A piece with other arrays.
        let raw = crate::vtk::vtu::read(&dir.path().join("e1.vtu")).unwrap();
        let mut other = Mesh::new(raw, "x").unwrap();
        other.fields.retain(|f| f.name != "c");
        let gids: Vec<i32> = other.field("GlobalCellIds").unwrap().values.iter().map(|&v| v as i32).collect();
        other.fields.retain(|f| f.name != "GlobalCellIds");
        let ids = crate::vtk::write::NamedArray {
            name: "GlobalCellIds".into(),
            n_components: 1,
            data: crate::vtk::write::ArrayData::I32(&gids),
        };
        crate::vtk::write::write_mesh_with_cell_data(&dir.path().join("e/e_1.vtu"), &other, &[], &[ids], false)
            .unwrap();
        let e = err(&out);
        assert!(e.contains("piece 1") && e.contains("e_1.vtu") && e.contains("has the arrays"), "{e}");
        // Global ids twice.
        std::fs::copy(dir.path().join("e/e_0.vtu"), dir.path().join("e/e_1.vtu")).unwrap();
        assert!(err(&out).contains("is also the id of piece 0"), "{}", err(&out));
        // Bad XML.
        std::fs::write(&out, "<VTKFile type=\"PUnstructuredGrid\"><PUnstructuredGrid>").unwrap();
        assert!(err(&out).starts_with(&out.display().to_string()), "{}", err(&out));
        // A listing that lists itself.
        std::fs::write(dir.path().join("self.vtm"), "<VTKFile type=\"vtkMultiBlockDataSet\"><vtkMultiBlockDataSet><DataSet file=\"self.vtm\"/></vtkMultiBlockDataSet></VTKFile>").unwrap();
        assert!(err(&dir.path().join("self.vtm")).contains("nest more than"));
        // An output folder that holds other files is not replaced.
        std::fs::write(dir.path().join("e/notes.txt"), "mine").unwrap();
        let e = crate::partition::write_pvtu(&m, 2, &out, false, |_| {}).unwrap_err().to_string();
        assert!(e.contains("notes.txt") && e.contains("refusing"), "{e}");
    }

    /// Two pieces that share a vertex (same global id and coordinates) but disagree on a
    /// point field's value there: an error naming the field and the id, not one value kept.
    #[test]
    fn shared_vertices_with_different_values_are_refused() {
        use tetloc_core::mesh::Field;
        // Two pieces' tets, joined: points 1 and 4 are copies of global point id 1.
        let ids = [0, 1, 2, 3, 1];
        let raw = |f: Field| {
            let mut raw = crate::test_support::two_tets(vec![f]);
            raw.points[4] = raw.points[1];
            raw
        };
        let listing = Path::new("w.pvtu");
        let nan = Field::from_f64("g", FieldLocation::Vertex, vec![f64::NAN; 5]);
        assert_eq!(weld(raw(nan), &ids, listing).unwrap().points.len(), 4, "NaN == NaN by bits");
        let f32s = Field::new("f", FieldLocation::Vertex, vec![0.0, 1.0, 2.0, 3.0, 1000.0]);
        let f64s = Field::from_f64("h", FieldLocation::Vertex, vec![0.0, 0.1, 2.0, 3.0, 0.1 + 1e-12]);
        for (f, name) in [(f32s, "'f'"), (f64s, "'h'")] {
            let e = weld(raw(f), &ids, listing).unwrap_err().to_string();
            assert!(e.starts_with("w.pvtu") && e.contains(name) && e.contains("global point id 1"), "{e}");
        }
    }

    /// A `<Piece Source>` listing for the test folder.
    fn pvtu_of(sources: &[&str]) -> String {
        let pieces: String = sources.iter().map(|s| format!("<Piece Source=\"{s}\"/>")).collect();
        format!("<VTKFile type=\"PUnstructuredGrid\"><PUnstructuredGrid>{pieces}</PUnstructuredGrid></VTKFile>")
    }

    /// One piece listed twice (same name, another spelling, a link, via a nested listing) is
    /// an error naming the listing and the piece: without global ids it would be read twice.
    #[test]
    fn a_piece_listed_twice_is_refused() {
        let (dir, _, _) = partitioned_cube("a.pvtu", 2, false);
        let d = dir.path();
        #[cfg(unix)]
        std::fs::hard_link(d.join("a/a_0.vtu"), d.join("hard.vtu")).unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink("a/a_0.vtu", d.join("soft.vtu")).unwrap();
        let mut cases = vec![
            ("same", pvtu_of(&["a/a_0.vtu", "a/a_0.vtu"]), "a_0.vtu a second time"),
            ("spelt", pvtu_of(&["a/a_0.vtu", "a/a_1.vtu", "./a/../a/a_0.vtu"]), "(first as"),
        ];
        if cfg!(unix) {
            cases.push(("hard", pvtu_of(&["a/a_0.vtu", "hard.vtu"]), "hard.vtu a second time"));
            cases.push(("soft", pvtu_of(&["soft.vtu", "a/a_1.vtu", "a/a_0.vtu"]), "soft.vtu)"));
        }
        for (name, text, want) in &cases {
            let listing = d.join(format!("{name}.pvtu"));
            std::fs::write(&listing, text).unwrap();
            let e = crate::read_mesh(&listing, None).unwrap_err().to_string();
            assert!(e.starts_with(&listing.display().to_string()) && e.contains(want), "{name}: {e}");
            assert!(list(&listing).is_err(), "{name}");
        }
        // Across a nested listing: a .vtm of the .pvtu and one of its pieces.
        let vtm = "<VTKFile type=\"vtkMultiBlockDataSet\"><vtkMultiBlockDataSet><DataSet file=\"a.pvtu\"/>\
                   <DataSet file=\"a/a_1.vtu\"/></vtkMultiBlockDataSet></VTKFile>";
        std::fs::write(d.join("n.vtm"), vtm).unwrap();
        let e = crate::read_mesh(&d.join("n.vtm"), None).unwrap_err().to_string();
        assert!(e.contains("n.vtm") && e.contains("a_1.vtu a second time"), "{e}");
    }

    /// A piece that is not a regular file (a FIFO, a link to a device, a folder) is refused
    /// before it is opened: opening a FIFO blocks until a writer comes, which may be never.
    #[cfg(unix)]
    #[test]
    fn pieces_that_are_not_regular_files_are_refused() {
        let (dir, _, _) = partitioned_cube("a.pvtu", 2, false);
        let d = dir.path();
        let made = std::process::Command::new("mkfifo").arg(d.join("pipe.vtu")).status();
        assert!(made.is_ok_and(|s| s.success()), "mkfifo");
        std::os::unix::fs::symlink("/dev/zero", d.join("zero.vtu")).unwrap();
        std::fs::create_dir(d.join("dir.vtu")).unwrap();
        for (piece, want) in
            [("pipe.vtu", "not a regular file"), ("zero.vtu", "not a regular file"), ("dir.vtu", "a folder")]
        {
            let listing = d.join("x.pvtu");
            std::fs::write(&listing, pvtu_of(&["a/a_0.vtu", piece])).unwrap();
            // Allowed outside: the link to /dev/zero leads out of the folder.
            let opts = crate::ReadOptions { allow_outside_pieces: true };
            let e = crate::read_mesh_with(&listing, None, opts).unwrap_err().to_string();
            assert!(e.starts_with(&listing.display().to_string()) && e.contains(piece) && e.contains(want), "{e}");
        }
    }

    /// Issue 29 item 20: pieces outside the listing's folder tree (`../`, absolute paths,
    /// symbolic links that lead out, nested listings outside) are refused by default with an
    /// error naming the listing and the piece, and read when allowed.
    #[test]
    fn pieces_outside_the_listing_folder_are_refused() {
        let (dir, m, _) = partitioned_cube("cube.pvtu", 2, false);
        let sub = dir.path().join("sub");
        std::fs::create_dir_all(&sub).unwrap();
        let pvtu = |sources: &[String]| {
            let pieces: String = sources.iter().map(|s| format!("<Piece Source=\"{s}\"/>")).collect();
            format!(
                "<VTKFile type=\"PUnstructuredGrid\" version=\"1.0\"><PUnstructuredGrid GhostLevel=\"0\">{pieces}\
                 </PUnstructuredGrid></VTKFile>"
            )
        };
        let absolute = dir.path().join("cube/cube_1.vtu").display().to_string();
        #[cfg(unix)]
        std::os::unix::fs::symlink(dir.path().join("cube/cube_1.vtu"), sub.join("link.vtu")).unwrap();
        let vtm = "<VTKFile type=\"vtkMultiBlockDataSet\"><vtkMultiBlockDataSet>\
                   <DataSet index=\"0\" file=\"../cube.pvtu\"/></vtkMultiBlockDataSet></VTKFile>";
        std::fs::write(sub.join("nested.vtm"), vtm).unwrap();
        let mut cases = vec![
            ("up.pvtu", pvtu(&["../cube/cube_0.vtu".into(), "../cube/cube_1.vtu".into()])),
            ("abs.pvtu", pvtu(&["../cube/cube_0.vtu".into(), absolute])),
            ("missing.pvtu", pvtu(&["../../elsewhere/x.vtu".into()])),
        ];
        if cfg!(unix) {
            cases.push(("link.pvtu", pvtu(&["link.vtu".into()])));
        }
        for (name, text) in &cases {
            std::fs::write(sub.join(name), text).unwrap();
        }
        cases.push(("nested.vtm", String::new()));
        for (name, _) in &cases {
            let listing = sub.join(name);
            let e = crate::read_mesh(&listing, None).unwrap_err().to_string();
            assert!(
                e.starts_with(&listing.display().to_string()) && e.contains("outside the listing's folder"),
                "{name}: {e}"
            );
            assert!(e.contains("--allow-outside-pieces"), "{e}");
            let allowed = list_with(&listing, true);
            if *name != "missing.pvtu" {
                assert!(!allowed.unwrap().is_empty(), "{name}");
            }
            // The listings of the whole cube read whole when allowed.
            if matches!(*name, "up.pvtu" | "abs.pvtu" | "nested.vtm") {
                let opts = crate::ReadOptions { allow_outside_pieces: true };
                let back = crate::read_mesh_with(&listing, None, opts).unwrap();
                assert!(back.n_cells() > 0, "{name}");
            }
        }
        // Inside the folder tree (a subfolder, `./`, `a/../`) is read as before.
        std::fs::write(
            dir.path().join("inside.pvtu"),
            pvtu(&["./cube/cube_0.vtu".into(), "sub/../cube/cube_1.vtu".into()]),
        )
        .unwrap();
        assert_eq!(crate::read_mesh(&dir.path().join("inside.pvtu"), None).unwrap().n_cells(), m.n_cells());
    }
}
