//! The volume cells of `$Elements`, collected for both format versions: each cell's first four
//! nodes (a tet's corners) mapped to dense vertex indices, its other nodes likewise (in Gmsh's
//! order), its Gmsh type (run-length encoded), element tags kept for `$ElementData`, the
//! highest order seen, and the volume elements tetloc does not read counted by type (they
//! make the file an error that lists them). Cell ids are the volume cells' file order.

use super::elements::Kind;
use super::tags::TagMap;
use super::Nodes;
use crate::cursor::{Cursor, Words};
use rayon::prelude::*;
use tetloc_core::cell::{CellBlock, CellType};
use tetloc_core::error::Result;

/// The volume cells and other volume elements of one chunk of ASCII element lines.
#[derive(Default)]
pub(super) struct Chunk {
    tets: Vec<[u32; 4]>,
    tags: Vec<u64>,
    other_tags: Vec<u64>,
    extra: Vec<u32>,
    runs: Vec<Run>,
    order: u8,
    /// (family, nodes, count)
    others: Vec<(&'static str, usize, usize)>,
}

impl Chunk {
    /// Reads an element's `nn` node tags; keeps its nodes if it is a volume cell tetloc reads.
    pub fn element(&mut self, t: &mut Words, map: &TagMap, tag: u64, kind: Kind, nn: usize) -> Option<()> {
        match kind {
            Kind::Cell { code, order } => {
                let mut c = [0u32; 4];
                for v in &mut c {
                    *v = map.get(t.u64()?)?;
                }
                for _ in 4..nn {
                    self.extra.push(map.get(t.u64()?)?);
                }
                self.tets.push(c);
                self.tags.push(tag);
                add_run(&mut self.runs, code, nn, 1);
                self.order = self.order.max(order);
                return Some(());
            }
            Kind::Volume(name) => match self.others.iter_mut().find(|o| o.0 == name && o.1 == nn) {
                Some(o) => o.2 += 1,
                None => self.others.push((name, nn, 1)),
            },
            Kind::Lower => {}
        }
        self.other_tags.push(tag);
        for _ in 0..nn {
            t.u64()?;
        }
        Some(())
    }
}

/// A run of consecutive cells of one Gmsh type: (type code, nodes per cell, cells).
pub(super) type Run = (u8, usize, usize);

/// Appends `count` cells of Gmsh type `code` with `nn` nodes to run-length encoded types.
fn add_run(runs: &mut Vec<Run>, code: u8, nn: usize, count: usize) {
    match runs.last_mut() {
        Some((t, n, c)) if *t == code && *n == nn => *c += count,
        _ => runs.push((code, nn, count)),
    }
}

/// Points, lines and surface elements, kept when a file is read as a point set with its
/// cells as they are (`probe`'s targets): their Gmsh types (run-length encoded), all their
/// nodes in Gmsh's order, and their tags (after the volume cells' in `$ElementData` rows).
#[derive(Default)]
pub(super) struct LowerElements {
    pub runs: Vec<Run>,
    pub nodes: Vec<u32>,
    pub tags: Vec<u64>,
}

/// Collects the volume cells of `$Elements` and counts the volume elements tetloc does not read.
pub(super) struct ElementSink<'n> {
    pub nodes: &'n Nodes,
    /// Each cell's first four nodes: a tet's corners.
    pub tets: Vec<[u32; 4]>,
    pub tags: Vec<u64>,
    /// The tags of the other elements (lower-dimensional ones, volumes not read).
    pub other_tags: Vec<u64>,
    /// The cells' nodes after their first four, in Gmsh's order (none for linear tets).
    pub extra: Vec<u32>,
    /// The cells' Gmsh types, run-length encoded.
    pub runs: Vec<Run>,
    pub order: u8,
    /// Volume elements that are not tetrahedra, by type name.
    pub others: Vec<(String, usize)>,
    /// Lower-dimensional elements, when kept (else their tags go to `other_tags`).
    pub lower: Option<LowerElements>,
}

impl ElementSink<'_> {
    /// The dense vertex index of a corner, or an error message.
    #[inline]
    pub fn node(&self, elem: u64, tag: u64) -> Result<u32, String> {
        self.nodes.map.get(tag).ok_or_else(|| format!("element {elem} refers to node {tag}, which is not in $Nodes"))
    }

    /// Adds a cell of Gmsh type `code` read from an ASCII line: its first four nodes, its other
    /// nodes, its tag.
    pub fn push_cell(&mut self, code: u8, first: [u32; 4], extra: &[u32], tag: u64) {
        self.tets.push(first);
        self.extra.extend_from_slice(extra);
        self.tags.push(tag);
        add_run(&mut self.runs, code, 4 + extra.len(), 1);
    }

    /// Adds a block of binary records of cells of Gmsh type `code` with `nn` nodes, decoded in
    /// parallel: they are the bulk of a large binary file. `tag(r)` and `node(r, k)` read a
    /// record's element tag and k-th node.
    pub fn add_binary_cells(
        &mut self,
        data: &[u8],
        record: usize,
        code: u8,
        nn: usize,
        tag: impl Fn(&[u8]) -> u64 + Sync + Send,
        node: impl Fn(&[u8], usize) -> u64 + Sync + Send,
    ) -> Result<(), String> {
        const MISSING: u32 = u32::MAX; // never an index: there are fewer than u32::MAX nodes
        let map = &self.nodes.map;
        let (start, extra_start) = (self.tets.len(), self.extra.len());
        let records = || data.par_chunks_exact(record);
        self.tets.par_extend(records().map(|r| std::array::from_fn(|k| map.get(node(r, k)).unwrap_or(MISSING))));
        let node = &node;
        self.extra
            .par_extend(records().flat_map_iter(|r| (4..nn).map(move |k| map.get(node(r, k)).unwrap_or(MISSING))));
        self.tags.par_extend(records().map(&tag));
        add_run(&mut self.runs, code, nn, data.len() / record);
        let bad = tetloc_core::par::first_position(&self.tets[start..], |t| t.contains(&MISSING)).or_else(|| {
            let i = tetloc_core::par::first_position(&self.extra[extra_start..], |&v| v == MISSING)?;
            Some(i / (nn - 4))
        });
        if let Some(i) = bad {
            let r = &data[i * record..];
            let k = (0..nn).find(|&k| map.get(node(r, k)).is_none()).unwrap_or(0);
            return Err(self.node(tag(r), node(r, k)).err().unwrap_or_default());
        }
        Ok(())
    }

    /// Appends the chunks of a parallel parse, in order.
    pub fn merge(&mut self, chunks: Vec<Chunk>, count_others: bool) {
        let n = chunks.iter().map(|c| c.tets.len()).sum();
        self.tets.reserve(n);
        self.tags.reserve(n);
        for c in chunks {
            self.tets.extend_from_slice(&c.tets);
            self.tags.extend_from_slice(&c.tags);
            self.other_tags.extend_from_slice(&c.other_tags);
            self.extra.extend_from_slice(&c.extra);
            c.runs.iter().for_each(|&(code, nn, k)| add_run(&mut self.runs, code, nn, k));
            self.order = self.order.max(c.order);
            if count_others {
                c.others.iter().for_each(|&(name, nn, n)| self.other(name, nn, n));
            }
        }
    }

    /// A point, line or surface element of Gmsh type `code` read from an ASCII line: kept with
    /// its `nodes` when lower elements are kept, else its tag is noted.
    pub fn push_lower(&mut self, code: i64, nodes: &[u32], tag: u64) {
        match &mut self.lower {
            Some(l) => {
                l.nodes.extend_from_slice(nodes);
                l.tags.push(tag);
                add_run(&mut l.runs, code as u8, nodes.len(), 1); // lower types are below 256
            }
            None => self.other_tags.push(tag),
        }
    }

    /// Adds a block of binary records of point, line or surface elements of Gmsh type `code`
    /// with `nn` nodes, when lower elements are kept (else only their tags); see
    /// [`Self::add_binary_cells`]. Sequential: a target's surface is small beside a volume.
    pub fn add_binary_lower(
        &mut self,
        data: &[u8],
        record: usize,
        code: i64,
        nn: usize,
        tag: impl Fn(&[u8]) -> u64,
        node: impl Fn(&[u8], usize) -> u64,
    ) -> Result<(), String> {
        let mut nodes = Vec::with_capacity(nn);
        for r in data.chunks_exact(record) {
            if self.lower.is_some() {
                nodes.clear();
                for k in 0..nn {
                    nodes.push(self.node(tag(r), node(r, k))?);
                }
            }
            self.push_lower(code, &nodes, tag(r));
        }
        Ok(())
    }

    pub fn other(&mut self, name: &str, nodes: usize, count: usize) {
        let key = format!("{name} ({nodes} nodes)");
        match self.others.iter_mut().find(|(k, _)| *k == key) {
            Some((_, n)) => *n += count,
            None => self.others.push((key, count)),
        }
    }

    pub fn reserve(&mut self, kind: Kind, count: usize) {
        if let (Kind::Cell { order, .. }, 1..) = (kind, count) {
            self.order = self.order.max(order);
            self.tets.reserve(count);
            self.tags.reserve(count);
        }
    }
}

/// Reads the `nn` node tags of an ASCII element; if it is a volume cell tetloc reads, its first
/// four nodes, and its other nodes into `extra` (cleared first); if it is a lower element that
/// `acc` keeps, all its nodes into `extra`.
pub(super) fn read_ascii_nodes(
    c: &mut Cursor,
    acc: &ElementSink,
    kind: Kind,
    nn: usize,
    tag: u64,
    pos: usize,
    extra: &mut Vec<u32>,
) -> Result<[u32; 4]> {
    let mut t = [0u32; 4];
    extra.clear();
    if let Kind::Cell { .. } = kind {
        for k in 0..nn {
            let v = acc.node(tag, c.ascii_u64("a node tag")?).map_err(|m| c.fail_at(pos, m))?;
            match t.get_mut(k) {
                Some(corner) => *corner = v,
                None => extra.push(v),
            }
        }
        return Ok(t);
    }
    if kind == Kind::Lower && acc.lower.is_some() {
        for _ in 0..nn {
            extra.push(acc.node(tag, c.ascii_u64("a node tag")?).map_err(|m| c.fail_at(pos, m))?);
        }
        return Ok(t);
    }
    for _ in 0..nn {
        c.ascii_u64("a node tag")?;
    }
    Ok(t)
}

/// The cells with all their nodes in VTK's order, from their first four nodes, their other
/// nodes in Gmsh's order, and their Gmsh types (run-length encoded). Errors are messages.
pub(super) fn vtk_cells(first: &[[u32; 4]], extra: &[u32], runs: &[Run]) -> Result<CellBlock, String> {
    let mut block = CellBlock::default();
    let (mut t, mut e) = (0, 0);
    let mut gmsh = Vec::new();
    for &(code, nn, count) in runs {
        let (ty, g) = CellType::from_gmsh(code).ok_or_else(|| {
            format!(
                "tetrahedra with {nn} nodes are incomplete (serendipity) elements, whose values \
                 tetloc cannot interpolate; use complete ones (Mesh.SecondOrderIncomplete = 0)"
            )
        })?;
        let mut vtk = vec![0u32; g.vtk_from_gmsh.len()];
        for _ in 0..count {
            gmsh.clear();
            gmsh.extend_from_slice(&first[t][..nn.min(4)]);
            gmsh.extend_from_slice(&extra[e..e + nn.saturating_sub(4)]);
            for (v, &i) in vtk.iter_mut().zip(g.vtk_from_gmsh.iter()) {
                *v = gmsh[usize::from(i)];
            }
            block.push(ty, &vtk);
            (t, e) = (t + 1, e + nn.saturating_sub(4));
        }
    }
    Ok(block)
}
