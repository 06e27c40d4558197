//! The tetrahedra of `$Elements`, collected for both format versions: corners mapped to
//! dense vertex indices, element tags kept for `$ElementData`, the highest order seen, and
//! the other volume elements counted by type (they make the file an error that lists them).

use super::elements::Kind;
use super::tags::TagMap;
use super::Nodes;
use crate::error::Result;
use crate::io::cursor::{Cursor, Words};
use rayon::prelude::*;

/// The tetrahedra and other volume elements of one chunk of ASCII element lines.
#[derive(Default)]
pub(super) struct Chunk {
    tets: Vec<[u32; 4]>,
    tags: Vec<u64>,
    order: u8,
    /// (family, nodes, count)
    others: Vec<(&'static str, usize, usize)>,
}

impl Chunk {
    /// Reads an element's `nn` node tags; keeps its corners if it is a tetrahedron.
    pub fn element(&mut self, t: &mut Words, map: &TagMap, tag: u64, kind: Kind, nn: usize) -> Option<()> {
        match kind {
            Kind::Tet(order) => {
                let mut c = [0u32; 4];
                for v in &mut c {
                    *v = map.get(t.u64()?)?;
                }
                self.tets.push(c);
                self.tags.push(tag);
                self.order = self.order.max(order);
            }
            Kind::Volume(name) => match self.others.iter_mut().find(|o| o.0 == name && o.1 == nn) {
                Some(o) => o.2 += 1,
                None => self.others.push((name, nn, 1)),
            },
            Kind::Lower => {}
        }
        let skip = if let Kind::Tet(_) = kind { nn - 4 } else { nn };
        for _ in 0..skip {
            t.u64()?;
        }
        Some(())
    }
}

/// Collects the tetrahedra of `$Elements` and counts other volume elements.
pub(super) struct ElementSink<'n> {
    pub nodes: &'n Nodes,
    pub tets: Vec<[u32; 4]>,
    pub tags: Vec<u64>,
    pub order: u8,
    /// Volume elements that are not tetrahedra, by type name.
    pub others: Vec<(String, usize)>,
}

impl ElementSink<'_> {
    /// The dense vertex index of a corner, or an error message.
    #[inline]
    pub fn node(&self, elem: u64, tag: u64) -> Result<u32, String> {
        self.nodes.map.get(tag).ok_or_else(|| format!("element {elem} refers to node {tag}, which is not in $Nodes"))
    }

    /// Adds a block of binary tetrahedron records, decoded in parallel: they are the bulk of a
    /// large binary file. `tag(r)` and `node(r, k)` read a record's element tag and k-th node.
    pub fn add_binary_tets(
        &mut self,
        data: &[u8],
        record: usize,
        tag: impl Fn(&[u8]) -> u64 + Sync + Send,
        node: impl Fn(&[u8], usize) -> u64 + Sync + Send,
    ) -> Result<(), String> {
        const MISSING: u32 = u32::MAX; // never an index: there are fewer than u32::MAX nodes
        let map = &self.nodes.map;
        let start = self.tets.len();
        let records = || data.par_chunks_exact(record);
        self.tets.par_extend(records().map(|r| std::array::from_fn(|k| map.get(node(r, k)).unwrap_or(MISSING))));
        self.tags.par_extend(records().map(&tag));
        if let Some(i) = self.tets[start..].par_iter().position_first(|t| t.contains(&MISSING)) {
            let r = &data[i * record..];
            let k = (0..4).find(|&k| map.get(node(r, k)).is_none()).unwrap_or(0);
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
            self.order = self.order.max(c.order);
            if count_others {
                c.others.iter().for_each(|&(name, nn, n)| self.other(name, nn, n));
            }
        }
    }

    pub fn other(&mut self, name: &str, nodes: usize, count: usize) {
        let key = format!("{name} ({nodes} nodes)");
        match self.others.iter_mut().find(|(k, _)| *k == key) {
            Some((_, n)) => *n += count,
            None => self.others.push((key, count)),
        }
    }

    pub fn reserve(&mut self, kind: Kind, count: usize) {
        if let (Kind::Tet(order), 1..) = (kind, count) {
            self.order = self.order.max(order);
            self.tets.reserve(count);
            self.tags.reserve(count);
        }
    }
}

/// Reads the `nn` node tags of an ASCII element; the corners if it is a tetrahedron.
pub(super) fn read_ascii_nodes(
    c: &mut Cursor,
    acc: &ElementSink,
    kind: Kind,
    nn: usize,
    tag: u64,
    pos: usize,
) -> Result<[u32; 4]> {
    let mut t = [0u32; 4];
    let corners = if let Kind::Tet(_) = kind { 4 } else { 0 };
    for v in &mut t[..corners] {
        *v = acc.node(tag, c.ascii_u64("a node tag")?).map_err(|m| c.fail_at(pos, m))?;
    }
    for _ in corners..nn {
        c.ascii_u64("a node tag")?;
    }
    Ok(t)
}
