//! `$NodeData` and `$ElementData`: one view (a named field at one time step) per section,
//! read into vertex or cell fields. Values are matched to vertices by node tag and to
//! tetrahedra by element tag; values on other elements are dropped, and what a view gives no
//! value stays NaN. Of one view name, the lowest time step is read (the highest up to the
//! step asked for, when the file is read as a time series); sections of the same step
//! (partitions) are merged. Every section's step and time (its first real tag) are noted.

use super::tags::TagMap;
use super::Parser;
use crate::cursor::{get_f64, get_i32};
use tetloc_core::error::Result;
use tetloc_core::mesh::{Field, FieldLocation};

/// Gmsh allows 1 (scalar), 3 (vector) and 9 (tensor) components.
const MAX_COMPONENTS: usize = 9;

/// One view being read: values interleaved by component, NaN where none was given.
pub(super) struct FieldAcc {
    name: String,
    location: FieldLocation,
    step: i64,
    ncomp: usize,
    /// The file's values (f64 in every Gmsh file); fields keep them where f32 cannot.
    values: Vec<f64>,
    /// Whether a section of this step gave the row a value: a second, different one is an error.
    given: Vec<bool>,
}

impl FieldAcc {
    /// The view as fields: itself if scalar, else `NAME[k]` per component.
    pub fn into_fields(self) -> Vec<Field> {
        let FieldAcc { name, location, ncomp, values, .. } = self;
        if ncomp == 1 {
            return vec![Field::from_f64(name, location, values)];
        }
        (0..ncomp)
            .map(|k| {
                Field::from_f64(
                    format!("{name}[{k}]"),
                    location,
                    values.iter().skip(k).step_by(ncomp).copied().collect(),
                )
            })
            .collect()
    }
}

impl Parser<'_> {
    pub(super) fn read_data(&mut self, location: FieldLocation, start: usize) -> Result<()> {
        let what = match location {
            FieldLocation::Vertex => "$NodeData",
            FieldLocation::Cell => "$ElementData",
        };
        let n_items = match location {
            FieldLocation::Vertex => self.nodes.as_ref().map(|n| n.points.len()),
            FieldLocation::Cell => self.cells.as_ref().map(|c| c.data_tags().len()),
        };
        let Some(n_items) = n_items else {
            return Err(self.c.fail_at(start, format!("{what} comes before the mesh it refers to")));
        };
        let c = &mut self.c;

        // The header is ASCII even in binary files.
        let n_str = c.ascii_u64("the number of string tags")?;
        c.check_room(n_str, 3, "string tags")?;
        let mut name = None;
        for _ in 0..n_str {
            c.skip_ws();
            let tag = c.line().unwrap_or_default().trim_ascii();
            let tag = tag.strip_prefix(b"\"").and_then(|t| t.strip_suffix(b"\"")).unwrap_or(tag);
            name.get_or_insert_with(|| String::from_utf8_lossy(tag).into_owned());
        }
        let name = name.unwrap_or_else(|| "unnamed".to_string());
        let n_real = c.ascii_u64("the number of real tags")?;
        let mut time = None;
        for _ in 0..n_real {
            let t = c.ascii_f64("a real tag")?;
            time.get_or_insert(t); // the first real tag is the step's time
        }
        let n_int = c.ascii_u64("the number of integer tags")?;
        if n_int < 3 {
            return Err(
                c.fail(format!("{what} '{name}' has {n_int} integer tags; it needs 3 (step, components, count)"))
            );
        }
        let step = c.ascii_i64("the time step")?;
        let ncomp = c.ascii_u64("the number of components")?;
        let count = c.ascii_u64("the number of values")?;
        for _ in 3..n_int {
            c.ascii_i64("an integer tag")?;
        }
        c.line(); // binary data starts on the next line
        if !(1..=MAX_COMPONENTS as u64).contains(&ncomp) {
            return Err(c.fail(format!("{what} '{name}' has {ncomp} components; Gmsh allows 1 to {MAX_COMPONENTS}")));
        }
        let ncomp = ncomp as usize;
        let record = if c.binary { 4 + 8 * ncomp } else { 2 + 2 * ncomp };
        let count = c.check_room(count, record, &format!("values of {what} '{name}'"))?;

        self.step_times.push((step, time));
        // Where this section's values go: a fresh view, merged into the same step, or nowhere.
        // A snapshot keeps each view's first step (as Exodus and .pvd series do); step k of a
        // series, each view's last step up to k.
        let existing = self.fields.iter().position(|f| f.location == location && f.name == name);
        let keep_old = |old: i64| match self.step_limit {
            None => old < step,
            Some(_) => old > step,
        };
        let slot = match existing {
            _ if self.step_limit.is_some_and(|last| step > last) => None,
            Some(i) if keep_old(self.fields[i].step) => None,
            Some(i) if self.fields[i].step == step => {
                if self.fields[i].ncomp != ncomp {
                    return Err(c.fail(format!("{what} '{name}' step {step} changes its number of components")));
                }
                Some(i)
            }
            _ => {
                let len = n_items * ncomp;
                // Many small views over a big mesh could otherwise allocate far more than the
                // file holds; real files stay well inside this bound.
                self.field_values += len;
                if self.field_values > 64 * c.buf.len() + (1 << 20) {
                    return Err(c.fail(format!("too many field values for the file's size at {what} '{name}'")));
                }
                let acc = FieldAcc {
                    name: name.clone(),
                    location,
                    step,
                    ncomp,
                    values: vec![f64::NAN; len],
                    given: vec![false; n_items],
                };
                match existing {
                    Some(i) => {
                        self.fields[i] = acc;
                        Some(i)
                    }
                    None => {
                        self.fields.push(acc);
                        Some(self.fields.len() - 1)
                    }
                }
            }
        };

        // Entity tag → row in the field (None: drop the value).
        let cells = &mut self.cells;
        if location == FieldLocation::Cell {
            let cells = cells.as_mut().expect("checked above");
            if cells.map.is_none() {
                let map = TagMap::new(&cells.data_tags())
                    .map_err(|t| c.fail(format!("element tag {t} appears twice in $Elements")))?;
                cells.map = Some(map);
            }
        }
        let nodes = &self.nodes;
        let lookup = |tag: i64| -> Result<Option<usize>, String> {
            let t = u64::try_from(tag).map_err(|_| format!("negative tag {tag}"))?;
            match location {
                FieldLocation::Vertex => match nodes.as_ref().and_then(|n| n.map.get(t)) {
                    Some(i) => Ok(Some(i as usize)),
                    None => Err(format!("{what} '{name}' gives a value for node {t}, which is not in $Nodes")),
                },
                // Values on surface or line elements are dropped; a tag of no element in
                // $Elements is an error, as a node tag is.
                FieldLocation::Cell => {
                    let cells = cells.as_ref().expect("checked above");
                    match cells.map.as_ref().and_then(|m| m.get(t)) {
                        Some(i) => Ok(Some(i as usize)),
                        None if cells.other_tags.binary_search(&t).is_ok() => Ok(None),
                        None => {
                            Err(format!("{what} '{name}' gives a value for element {t}, which is not in $Elements"))
                        }
                    }
                }
            }
        };
        let mut acc = slot.map(|i| &mut self.fields[i]);
        let entity = if location == FieldLocation::Vertex { "node" } else { "element" };
        // Partitions may repeat a shared node's value; a different one would be lost silently.
        let mut store = |tag: i64, row: Option<usize>, v: &[f64]| -> Result<(), String> {
            let (Some(row), Some(acc)) = (row, acc.as_deref_mut()) else { return Ok(()) };
            let old = &mut acc.values[row * ncomp..(row + 1) * ncomp];
            if acc.given[row] && old.iter().zip(v).any(|(a, b)| a.to_bits() != b.to_bits()) {
                return Err(format!("{what} '{name}' step {step} gives {entity} {tag} two values: {old:?} and {v:?}"));
            }
            old.copy_from_slice(v);
            acc.given[row] = true;
            Ok(())
        };
        let mut record_values = [0f64; MAX_COMPONENTS];
        if c.binary {
            let big = c.big_endian;
            let data = c.take_records(count as u64, record, &format!("values of {what} '{name}'"))?;
            for (i, r) in data.chunks_exact(record).enumerate() {
                let tag = get_i32(r, big) as i64;
                let row = lookup(tag).map_err(|m| c.fail(m))?;
                for (k, v) in record_values[..ncomp].iter_mut().enumerate() {
                    *v = get_f64(&r[4 + 8 * k..], big);
                }
                store(tag, row, &record_values[..ncomp]).map_err(|m| c.fail(format!("record {i}: {m}")))?;
            }
        } else {
            for _ in 0..count {
                let tag_pos = c.here();
                let tag = c.ascii_i64("an entity tag")?;
                let row = lookup(tag).map_err(|m| c.fail_at(tag_pos, m))?;
                for v in &mut record_values[..ncomp] {
                    *v = c.ascii_f64("a field value")?;
                }
                store(tag, row, &record_values[..ncomp]).map_err(|m| c.fail_at(tag_pos, m))?;
            }
        }
        Ok(())
    }
}
