//! The seam every backend plugs into: a batch locator takes points and returns tet ids, or
//! values of a field. The CPU implementation lives here; the Vulkan backend implements the
//! same trait in `tetloc-vulkan`.

mod cpu;
#[cfg(test)]
use cpu::is_coherent;
#[cfg(test)]
mod tests;

pub use cpu::CpuLocator;

use crate::error::Result;
use crate::geom::Vec3;

/// Id returned for a point outside every tet.
pub const OUTSIDE: i32 = -1;

/// A backend that locates batches of points in one mesh.
///
/// `locate` writes the containing tet id (0-based, file order) or [`OUTSIDE`] for each
/// point; `sample` writes the field's value there: per-vertex fields are interpolated
/// barycentrically, per-cell fields looked up, NaN outside. A point on a face shared by two
/// tets may go to either, but always to the same one for the same backend.
pub trait BatchLocator {
    /// The backend's name as used on the command line (`cpu`, `soft-bvh`, ...).
    fn name(&self) -> &str;
    fn locate(&mut self, points: &[Vec3], ids: &mut [i32]) -> Result<()>;
    fn sample(&mut self, points: &[Vec3], field: &str, values: &mut [f32]) -> Result<()>;
    /// Ids and values together; backends that can do both in one pass override this.
    fn locate_and_sample(&mut self, points: &[Vec3], field: &str, ids: &mut [i32], values: &mut [f32]) -> Result<()> {
        self.locate(points, ids)?;
        self.sample(points, field, values)
    }
}

pub(crate) fn check_lengths(points: usize, out: usize) -> Result<()> {
    if points != out {
        return Err(crate::Error::Invalid(format!("{points} points but an output buffer for {out}")));
    }
    Ok(())
}
