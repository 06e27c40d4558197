//! The VTK family: the XML reader ([`vtu`]), partitioned meshes ([`pieces`], listed by [`pvtu`]
//! and [`vtm`]), the legacy reader ([`legacy`]), the VTU writers
//! ([`write`](mod@write)), and what they share: element types, cell types, XML and binary blocks.

pub(crate) mod blocks;
pub(crate) mod cells;
pub(crate) mod num;
pub(crate) mod xml;

pub mod legacy;
pub mod pieces;
pub mod pvd;
pub mod pvtu;
pub mod vti;
pub mod vtm;
pub mod vtu;
pub mod write;
pub mod write_pieces;

/// Cell lists from arrays (Python's `Mesh`), checked and split as the readers' are.
pub use cells::{from_cell_list, Extracted};

#[cfg(test)]
mod tests;

/// The bounded whole-file read every reader shares.
pub(crate) use super::read_file;
