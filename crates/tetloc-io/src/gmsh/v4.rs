//! Format 4.1: `$Nodes` and `$Elements` in blocks, one per entity, each behind a header
//! (entity dimension and tag, element type or parametric flag, count); a node block lists its
//! tags, then their coordinates. In binary files the headers are binary too: `int`s of 4
//! bytes and `size_t`s of 8, as are the tags.

use super::cells::{read_ascii_nodes, Chunk, ElementSink};
use super::elements::{check_line, element_type, unknown_type, Kind};
use crate::cursor::{get_f64, get_i32, get_u64, Cursor};
use tetloc_core::error::Result;

/// An `int` in the file's data encoding (ASCII word or 4 binary bytes).
fn int(c: &mut Cursor, what: &str) -> Result<i64> {
    if c.binary {
        Ok(get_i32(c.take(4, what)?, c.big_endian) as i64)
    } else {
        c.ascii_i64(what)
    }
}

/// A `size_t` in the file's data encoding (ASCII word or 8 binary bytes).
fn size(c: &mut Cursor, what: &str) -> Result<u64> {
    if c.binary {
        Ok(get_u64(c.take(8, what)?, c.big_endian))
    } else {
        c.ascii_u64(what)
    }
}

/// `start`: where the section begins, for errors about it as a whole.
pub(super) fn read_nodes(c: &mut Cursor, start: usize, min_parallel: usize) -> Result<(Vec<[f64; 3]>, Vec<u64>)> {
    let blocks = size(c, "the number of node blocks")?;
    let declared = size(c, "the number of nodes")?;
    size(c, "the smallest node tag")?;
    size(c, "the largest node tag")?;
    let n = c.check_room(declared, if c.binary { 32 } else { 8 }, "nodes")?;
    let mut points = Vec::with_capacity(n);
    let mut tags = Vec::with_capacity(n);
    for _ in 0..blocks {
        let dim = int(c, "an entity dimension")?;
        int(c, "an entity tag")?;
        let parametric = int(c, "the parametric flag")?;
        let count = size(c, "the number of nodes in a block")?;
        if !(0..=3).contains(&dim) || !(0..=1).contains(&parametric) {
            return Err(c.fail(format!("bad node block header: dimension {dim}, parametric {parametric}")));
        }
        if count > (n - points.len()) as u64 {
            return Err(c.fail(format!("node blocks hold more nodes than the {n} declared")));
        }
        // Parametric nodes carry u (curves), u v (surfaces) or u v w (volumes) after x y z.
        let per_node = 3 + (parametric * dim) as usize;
        if c.binary {
            let big = c.big_endian;
            let tag_bytes = c.take_records(count, 8, "node tags")?;
            let xyz = c.take_records(count, 8 * per_node, "node coordinates")?;
            tags.extend(tag_bytes.chunks_exact(8).map(|b| get_u64(b, big)));
            points.extend(
                xyz.chunks_exact(8 * per_node)
                    .map(|r| [get_f64(r, big), get_f64(&r[8..], big), get_f64(&r[16..], big)]),
            );
        } else {
            let count = count as usize;
            if let Some(chunks) = c.par_lines(count, min_parallel, |t, s: &mut Vec<u64>| {
                s.push(t.u64()?);
                Some(())
            }) {
                chunks.into_iter().for_each(|ch| tags.extend(ch));
            } else {
                for _ in 0..count {
                    tags.push(c.ascii_u64("a node tag")?);
                }
            }
            if let Some(chunks) = c.par_lines(count, min_parallel, |t, s: &mut Vec<[f64; 3]>| {
                s.push([t.f64()?, t.f64()?, t.f64()?]);
                (3..per_node).try_for_each(|_| t.f32().map(drop))
            }) {
                chunks.into_iter().for_each(|ch| points.extend(ch));
            } else {
                for _ in 0..count {
                    points.push([c.ascii_f64("x")?, c.ascii_f64("y")?, c.ascii_f64("z")?]);
                    for _ in 3..per_node {
                        c.ascii_f64("a parametric coordinate")?;
                    }
                }
            }
        }
    }
    if points.len() != n {
        return Err(c.fail_at(start, format!("$Nodes declares {n} nodes but its blocks hold {}", points.len())));
    }
    Ok((points, tags))
}

/// `start`: where the section begins, for errors about it as a whole.
pub(super) fn read_elements(c: &mut Cursor, acc: &mut ElementSink, start: usize, min_parallel: usize) -> Result<()> {
    let blocks = size(c, "the number of element blocks")?;
    let declared = size(c, "the number of elements")?;
    size(c, "the smallest element tag")?;
    size(c, "the largest element tag")?;
    c.check_room(declared, if c.binary { 16 } else { 4 }, "elements")?;
    let mut seen = 0u64;
    for _ in 0..blocks {
        let pos = c.here();
        int(c, "an entity dimension")?;
        int(c, "an entity tag")?;
        let ty = int(c, "an element type")?;
        let count = size(c, "the number of elements in a block")?;
        let (nn, kind) = element_type(ty).ok_or_else(|| unknown_type(c, pos, ty))?;
        if count > declared - seen {
            return Err(c.fail_at(pos, format!("element blocks hold more elements than the {declared} declared")));
        }
        seen += count;
        if let Kind::Volume(name) = kind {
            acc.other(name, nn, count as usize);
        }
        if c.binary {
            let big = c.big_endian;
            let record = 8 * (1 + nn);
            let data = c.take_records(count, record, "elements")?;
            acc.reserve(kind, count as usize);
            let (tag, node) = (|r: &[u8]| get_u64(r, big), |r: &[u8], k: usize| get_u64(&r[8 + 8 * k..], big));
            match kind {
                Kind::Cell { code, .. } => {
                    acc.add_binary_cells(data, record, code, nn, tag, node).map_err(|m| c.fail_at(pos, m))?
                }
                Kind::Lower => acc.add_binary_lower(data, record, ty, nn, tag, node).map_err(|m| c.fail_at(pos, m))?,
                Kind::Volume(_) => acc.other_tags.extend(data.chunks_exact(record).map(tag)),
            }
        } else {
            if count > 0 {
                // The first element line says whether the type is right before its size counts.
                let (p, buf) = (c.here(), c.buf);
                let first_word = buf[p..].split(|b| b.is_ascii_whitespace()).next().unwrap_or(&[]);
                let tag = crate::cursor::parse_u64(first_word).unwrap_or(0);
                check_line(c, p, tag, ty, 1 + nn)?;
            }
            let count = c.check_room(count, 2 * (1 + nn), "elements")?;
            let map = &acc.nodes.map;
            // Kept lower elements are read in the sequential loop below.
            let min_parallel = if acc.lower.is_some() && kind == Kind::Lower { usize::MAX } else { min_parallel };
            if let Some(chunks) = c.par_lines(count, min_parallel, |t, s: &mut Chunk| {
                let tag = t.u64()?;
                s.element(t, map, tag, kind, nn)
            }) {
                acc.merge(chunks, false); // other volume elements are counted above
                continue;
            }
            acc.reserve(kind, count);
            let mut extra = Vec::new();
            for _ in 0..count {
                let epos = c.here();
                let tag = c.ascii_u64("an element tag")?;
                let t = read_ascii_nodes(c, acc, kind, nn, tag, epos, &mut extra)?;
                match kind {
                    Kind::Cell { code, .. } => acc.push_cell(code, t, &extra, tag),
                    Kind::Lower => acc.push_lower(ty, &extra, tag),
                    Kind::Volume(_) => acc.other_tags.push(tag),
                }
            }
        }
    }
    if seen != declared {
        return Err(c.fail_at(start, format!("$Elements declares {declared} elements but its blocks hold {seen}")));
    }
    Ok(())
}
