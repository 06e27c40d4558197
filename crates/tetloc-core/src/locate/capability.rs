//! What a backend may do beyond the query, each a small trait that the backend hands out
//! through a hook of [`BatchLocator`] (`grid_sampler`, `line_tracer`): `ops` asks for it and
//! falls back to plain queries where the backend has none. Their words (grids, streamlines)
//! live below the locators, in `geom` and `streamline`.

use super::{query_grid_points, BatchLocator};
use crate::error::Result;
use crate::geom::{ImageGrid, Vec3};
use crate::streamline::{Line, TraceOptions};
use std::ops::Range;

/// A backend that samples a grid's points its own way, with the answers of a query of them
/// ([`query_grid_points`]: the f64 points or their f32 rounding, as the grid asks).
pub trait GridSampler {
    /// Ids and values (`fields.len()` a point) at points `range` of `grid` (x fastest,
    /// [`ImageGrid::point64`]): `resample`'s chunks.
    fn sample_grid(
        &mut self,
        grid: &ImageGrid,
        range: Range<usize>,
        fields: &[&str],
        ids: &mut [i32],
        values: &mut [f32],
    ) -> Result<()>;
}

/// A backend that locates points faster from a tet near each (a walk through face
/// neighbours from it), with the answers of [`BatchLocator::locate`].
pub trait HintedLocator {
    /// The tet of each of `points` (f32, the file's coordinates; -1 outside), starting from
    /// `hints` (a tet near each point, such as a particle's last; negative: none).
    fn locate_from(&mut self, points: &[Vec3], hints: &[i32], ids: &mut [i32]) -> Result<()>;
}

/// [`HintedLocator::locate_from`] through `loc`'s own hinted locator, else `loc.locate`
/// (the hints unused).
pub fn locate_from(
    loc: &mut (impl BatchLocator + ?Sized),
    points: &[Vec3],
    hints: &[i32],
    ids: &mut [i32],
) -> Result<()> {
    match loc.hinted_locator() {
        Some(h) => h.locate_from(points, hints, ids),
        None => loc.locate(points, ids),
    }
}

/// A backend that traces whole streamlines itself.
pub trait LineTracer {
    /// The lines from `seeds` (in VTK's order), or `None` where it has no tracer for these
    /// options. Where it can, the tracer also samples the field components `fields` at each
    /// line point ([`Line::values`]). `progress` gets the number of lines done so far.
    fn trace_lines(
        &mut self,
        seeds: &[Vec3],
        o: &TraceOptions,
        vector: [&str; 3],
        fields: &[&str],
        progress: &mut dyn FnMut(usize) -> Result<()>,
    ) -> Result<Option<Vec<Line>>>;
}

/// [`GridSampler::sample_grid`] through `loc`'s own sampler, or a query of the grid's points.
pub fn sample_grid(
    loc: &mut (impl BatchLocator + ?Sized),
    grid: &ImageGrid,
    range: Range<usize>,
    fields: &[&str],
    ids: &mut [i32],
    values: &mut [f32],
) -> Result<()> {
    if let Some(g) = loc.grid_sampler() {
        return g.sample_grid(grid, range, fields, ids, values);
    }
    query_grid_points(loc, grid, range, fields, ids, values)
}

/// [`LineTracer::trace_lines`] through `loc`'s own tracer, `None` where it has none.
pub fn trace_lines(
    loc: &mut (impl BatchLocator + ?Sized),
    seeds: &[Vec3],
    o: &TraceOptions,
    vector: [&str; 3],
    fields: &[&str],
    progress: &mut dyn FnMut(usize) -> Result<()>,
) -> Result<Option<Vec<Line>>> {
    match loc.line_tracer() {
        Some(t) => t.trace_lines(seeds, o, vector, fields, progress),
        None => Ok(None),
    }
}
