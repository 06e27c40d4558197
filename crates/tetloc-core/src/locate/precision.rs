//! The precision of the values of the f64 path ([`BatchLocator::query`] of f64 points): every
//! backend's own (`F32`: the GPU kernels' f32 values, widened; the CPU's are f64 anyway), or
//! the CPU's f64 values at the backend's ids (`F64`): [`F64Values`] asks the backend for ids
//! only (exact: the CPU's, or the GPU's certified ones) and computes the values on the host
//! with [`Mesh::values_at_ids64`], the one f64 definition, so that they equal the CPU's bit
//! for bit.

use super::{check_sample_lengths, BatchLocator, GridSampler, LineTracer, Points, Values};
use crate::error::Result;
use crate::mesh::Mesh;
use std::sync::Arc;

crate::named! {
    /// The values' precision on the f64 path.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
    pub enum Precision: "precision" {
        /// The backend's own values: f32 on the GPU (within 1e-6 of the field's range), widened.
        #[default]
        F32 => "f32",
        /// f64 values computed on the host from the backend's ids: the CPU's, bit for bit.
        F64 => "f64",
    }
}

/// Any backend with f64 values on its f64 path (see the module documentation). Everything
/// else passes through; so do mixed meshes, whose values [`super::CellLocator`] computes on
/// the host in f64 already (wrap it inside this).
pub struct F64Values<L> {
    inner: L,
    mesh: Arc<Mesh>,
}

impl<L: BatchLocator> F64Values<L> {
    /// `inner` must locate in `mesh`'s tets (or cells).
    pub fn new(inner: L, mesh: Arc<Mesh>) -> Self {
        F64Values { inner, mesh }
    }
    pub fn inner(&self) -> &L {
        &self.inner
    }
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }
    pub fn into_inner(self) -> L {
        self.inner
    }
}

/// `loc` with the values of `precision` on its f64 path.
pub fn with_precision<'a>(
    loc: Box<dyn BatchLocator + 'a>,
    mesh: Arc<Mesh>,
    precision: Precision,
) -> Box<dyn BatchLocator + 'a> {
    match precision {
        Precision::F32 => loc,
        Precision::F64 => Box::new(F64Values::new(loc, mesh)),
    }
}

impl<L: BatchLocator> BatchLocator for F64Values<L> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn take_fields(&mut self, mesh: &Arc<Mesh>) -> bool {
        super::layer_takes_fields(&mut self.mesh, &mut self.inner, mesh)
    }

    fn preferred_batch(&self) -> Option<usize> {
        self.inner.preferred_batch()
    }

    /// f64 points on a mesh of tets: the backend's ids, then the host's f64 values there.
    fn query(&mut self, points: Points<'_>, fields: &[&str], ids: &mut [i32], values: Values<'_>) -> Result<()> {
        let Points::F64(p) = points else { return self.inner.query(points, fields, ids, values) };
        if self.mesh.cells.is_some() {
            return self.inner.query(points, fields, ids, values);
        }
        check_sample_lengths(p.len(), fields.len(), ids.len(), values.len())?;
        let mesh = self.mesh.clone();
        let fields = fields.iter().map(|f| mesh.field(f)).collect::<Result<Vec<_>>>()?;
        self.inner.query(points, &[], ids, Values::none())?;
        match values {
            Values::F32(v) => mesh.values_at_ids64(p, ids, &fields, v),
            Values::F64(v) => mesh.values_at_ids64(p, ids, &fields, v),
        }
        Ok(())
    }

    fn grid_sampler(&mut self) -> Option<&mut dyn GridSampler> {
        self.inner.grid_sampler()
    }

    fn line_tracer(&mut self) -> Option<&mut dyn LineTracer> {
        self.inner.line_tracer()
    }
}
