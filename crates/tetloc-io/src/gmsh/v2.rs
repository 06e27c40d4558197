//! Format 2.2: `$Nodes` as one list of `tag x y z` records, `$Elements` as one list of
//! `tag type ntags tags... nodes...` records (in binary files: blocks of one element type,
//! each behind a header of type, count and number of tags). Binary numbers are 4-byte ints
//! and 8-byte doubles.

use super::cells::{read_ascii_nodes, Chunk, ElementSink};
use super::elements::{check_line, element_type, unknown_type, Kind};
use crate::cursor::{get_f64, get_i32, Cursor};
use tetloc_core::error::Result;

pub(super) fn read_nodes(c: &mut Cursor, min_parallel: usize) -> Result<(Vec<[f64; 3]>, Vec<u64>)> {
    let declared = c.ascii_u64("the number of nodes")?;
    c.line(); // binary data starts on the next line
    let n = c.check_room(declared, if c.binary { 28 } else { 8 }, "nodes")?;
    let mut points = Vec::with_capacity(n);
    let mut tags = Vec::with_capacity(n);
    if c.binary {
        let big = c.big_endian;
        let data = c.take_records(declared, 28, "nodes")?;
        for r in data.chunks_exact(28) {
            let tag = get_i32(r, big);
            if tag < 0 {
                return Err(c.fail(format!("negative node tag {tag}")));
            }
            tags.push(tag as u64);
            points.push([get_f64(&r[4..], big), get_f64(&r[12..], big), get_f64(&r[20..], big)]);
        }
    } else if let Some(chunks) = c.par_lines(n, min_parallel, |t, s: &mut (Vec<u64>, Vec<[f64; 3]>)| {
        s.0.push(t.u64()?);
        s.1.push([t.f64()?, t.f64()?, t.f64()?]);
        Some(())
    }) {
        for (t, p) in chunks {
            tags.extend(t);
            points.extend(p);
        }
    } else {
        for _ in 0..n {
            tags.push(c.ascii_u64("a node tag")?);
            points.push([c.ascii_f64("x")?, c.ascii_f64("y")?, c.ascii_f64("z")?]);
        }
    }
    Ok((points, tags))
}

pub(super) fn read_elements(c: &mut Cursor, acc: &mut ElementSink, min_parallel: usize) -> Result<()> {
    let declared = c.ascii_u64("the number of elements")?;
    c.line(); // binary data starts on the next line
    if c.binary {
        // Blocks of elements of one type: header (type, count, number of tags), then for each
        // element its tag, its tags and its nodes, all 4-byte ints.
        c.check_room(declared, 16, "elements")?;
        let big = c.big_endian;
        let mut seen = 0u64;
        while seen < declared {
            let pos = c.pos;
            let h = c.take(12, "an element block header")?;
            let (ty, count, ntags) = (get_i32(h, big) as i64, get_i32(&h[4..], big), get_i32(&h[8..], big));
            let (nn, kind) = element_type(ty).ok_or_else(|| unknown_type(c, pos, ty))?;
            if count < 0 || ntags < 0 || count as u64 > declared - seen {
                return Err(c.fail_at(pos, format!("bad element block header: {count} elements with {ntags} tags")));
            }
            let record = 4 * (1 + ntags as usize + nn);
            let data = c.take_records(count as u64, record, "elements")?;
            seen += count as u64;
            acc.reserve(kind, count as usize);
            // A negative tag becomes a huge one, which no node or data section matches.
            let first = 4 * (1 + ntags as usize);
            let int = move |b: &[u8]| get_i32(b, big) as i64 as u64;
            let node = |r: &[u8], k: usize| int(&r[first + 4 * k..]);
            match kind {
                Kind::Lower => acc.add_binary_lower(data, record, ty, nn, int, node).map_err(|m| c.fail_at(pos, m))?,
                Kind::Volume(name) => {
                    acc.other(name, nn, count as usize);
                    acc.other_tags.extend(data.chunks_exact(record).map(int));
                }
                Kind::Cell { code, .. } => {
                    acc.add_binary_cells(data, record, code, nn, int, node).map_err(|m| c.fail_at(pos, m))?;
                }
            }
        }
    } else {
        let n = c.check_room(declared, 8, "elements")?;
        let map = &acc.nodes.map;
        // Kept lower elements are read in the sequential loop below.
        let min_parallel = if acc.lower.is_some() { usize::MAX } else { min_parallel };
        if let Some(chunks) = c.par_lines(n, min_parallel, |t, s: &mut Chunk| {
            let tag = t.u64()?;
            let (nn, kind) = element_type(t.i64()?)?;
            for _ in 0..t.u64()? {
                t.next_word()?;
            }
            s.element(t, map, tag, kind, nn)
        }) {
            acc.merge(chunks, true);
            return Ok(());
        }
        let mut extra = Vec::new();
        for _ in 0..n {
            let pos = c.here();
            let tag = c.ascii_u64("an element tag")?;
            let ty = c.ascii_i64("an element type")?;
            let (nn, kind) = element_type(ty).ok_or_else(|| unknown_type(c, pos, ty))?;
            let ntags = c.ascii_u64("the number of element tags")?;
            for _ in 0..ntags {
                c.token("an element tag")?;
            }
            check_line(c, pos, tag, ty, nn)?;
            acc.reserve(kind, 1);
            let t = read_ascii_nodes(c, acc, kind, nn, tag, pos, &mut extra)?;
            match kind {
                Kind::Lower => acc.push_lower(ty, &extra, tag),
                Kind::Volume(name) => {
                    acc.other(name, nn, 1);
                    acc.other_tags.push(tag);
                }
                Kind::Cell { code, .. } => acc.push_cell(code, t, &extra, tag),
            }
        }
    }
    Ok(())
}
