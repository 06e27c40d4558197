//! Commands written against one locator (`resample`, `probe`) run distributed: rank 0 runs
//! the command with a [`Driven`] locator, whose every call is announced to the other ranks,
//! which [`serve`] it; the points are scattered, located collectively (`DistLocator::query`)
//! and the answers gathered back on rank 0, which alone writes the output.

use super::{gather, scatter};
use tetloc_core::locate::{check_sample_lengths, Points, Values};
use tetloc_core::BatchLocator;
use tetloc_mpi::dist::{Cluster, DistLocator, Precision};
use tetloc_mpi::mpi::traits::*;

/// The length that ends [`serve`]'s loop instead of announcing a call.
const DONE: u64 = u64::MAX;

/// Rank 0's locator: one batch call of the command is one collective query of all ranks.
pub struct Driven<'c> {
    cluster: &'c Cluster,
    loc: DistLocator<'c, Box<dyn BatchLocator>>,
    name: String,
}

impl<'c> Driven<'c> {
    pub fn new(cluster: &'c Cluster, loc: DistLocator<'c, Box<dyn BatchLocator>>) -> Driven<'c> {
        let local = loc.local().map_or("-".to_string(), |l| l.name().to_string());
        let name = format!("{local} on {} ranks", cluster.size);
        Driven { cluster, loc, name }
    }

    /// Ends the other ranks' [`serve`] loops (the command is done, or failed on rank 0).
    pub fn finish(self) {
        announce(self.cluster, None);
    }

    /// One collective call: `points` located and sampled by the ranks, in their precision
    /// (announced first, so that every rank calls in it), into `ids` (global) and `values`.
    fn call<T: Precision>(
        &mut self,
        points: &[[T; 3]],
        fields: &[&str],
        ids: &mut [i32],
        values: Values<'_>,
    ) -> Result<(), tetloc_core::Error> {
        announce(self.cluster, Some((fields, T::WIDE)));
        let mine = scatter(self.cluster, points);
        let got = self.loc.query(&mine, fields);
        let (all_ids, all_values) = (gather(self.cluster, &got.ids), gather(self.cluster, &got.values));
        for (out, &g) in ids.iter_mut().zip(&all_ids) {
            *out = i32::try_from(g).map_err(|_| {
                tetloc_core::Error::Invalid(format!("global cell id {g} does not fit the int32 outputs"))
            })?;
        }
        T::put(values, &all_values)
    }
}

impl BatchLocator for Driven<'_> {
    fn name(&self) -> &str {
        &self.name
    }

    /// f32 points, or f64 points (the ranks exchange and answer them in f64).
    fn query(
        &mut self,
        points: Points<'_>,
        fields: &[&str],
        ids: &mut [i32],
        values: Values<'_>,
    ) -> Result<(), tetloc_core::Error> {
        // Checked before the collective call: every rank must take part in it or none.
        check_sample_lengths(points.len(), fields.len(), ids.len(), values.len())?;
        match points {
            Points::F32(points) => self.call(points, fields, ids, values),
            Points::F64(points) => self.call(points, fields, ids, values),
        }
    }
}

/// On every rank but 0: answers rank 0's calls until it says it is done.
pub fn serve(cluster: &Cluster, loc: &mut DistLocator<'_, Box<dyn BatchLocator>>) {
    fn answer<T: Precision>(cluster: &Cluster, loc: &mut DistLocator<'_, Box<dyn BatchLocator>>, names: &[&str]) {
        let mine = scatter::<T>(cluster, &[]);
        let got = loc.query(&mine, names);
        gather(cluster, &got.ids);
        gather(cluster, &got.values);
    }
    while let Some((fields, wide)) = announcement(cluster) {
        let names: Vec<&str> = fields.iter().map(String::as_str).collect();
        match wide {
            true => answer::<f64>(cluster, loc, &names),
            false => answer::<f32>(cluster, loc, &names),
        }
    }
}

/// Rank 0 tells the others what comes next: a call sampling `fields` with points in f64
/// (`true`) or f32, or the end (`None`).
fn announce(cluster: &Cluster, call: Option<(&[&str], bool)>) {
    let root = cluster.world.process_at_rank(0);
    let text = call.map(|(f, _)| f.join("\n"));
    let mut len = text.as_ref().map_or(DONE, |t| t.len() as u64);
    root.broadcast_into(&mut len);
    if let (Some(t), Some((_, wide))) = (text, call) {
        // The precision first, then the names: a buffer of at least one byte (an empty one
        // points at 0x1, which OpenMPI reads as MPI_IN_PLACE).
        let mut bytes = vec![u8::from(wide)];
        bytes.extend_from_slice(t.as_bytes());
        root.broadcast_into(&mut bytes[..]);
    }
}

/// The other side of [`announce`]: the fields of the next call and whether its points are
/// f64, or `None` at the end.
fn announcement(cluster: &Cluster) -> Option<(Vec<String>, bool)> {
    let root = cluster.world.process_at_rank(0);
    let mut len = 0u64;
    root.broadcast_into(&mut len);
    if len == DONE {
        return None;
    }
    let mut bytes = vec![0u8; len as usize + 1];
    root.broadcast_into(&mut bytes[..]);
    let text = String::from_utf8_lossy(&bytes[1..]);
    let fields = if text.is_empty() { Vec::new() } else { text.split('\n').map(str::to_string).collect() };
    Some((fields, bytes[0] == 1))
}
