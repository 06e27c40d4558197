//! What users do with point location, as ParaView's filters do it: [`resample`] a mesh's
//! fields onto a regular image (vtkResampleToImage), [`probe`] one mesh's fields at another's
//! points (vtkResampleWithDataSet), and trace particles through a vector field
//! (vtkStreamTracer). Each works over any [`crate::BatchLocator`], so on every backend.

pub mod fields;
mod grid;
pub mod probe;
pub mod resample;
pub mod trace;

pub use fields::FieldGroup;
pub use grid::ImageGrid;

/// Points per batch handed to a locator: large enough to keep a GPU busy, small enough to
/// bound memory (a batch's points, ids and values) for any output size.
pub const CHUNK: usize = 1 << 22;
