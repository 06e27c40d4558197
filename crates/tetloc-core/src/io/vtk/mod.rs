//! The VTK family: the XML reader ([`vtu`]), the legacy reader ([`legacy`]), the VTU writers
//! ([`write`]), and what they share: element types, cell types, XML and binary blocks.

pub(crate) mod blocks;
pub(crate) mod cells;
pub(crate) mod num;
pub(crate) mod xml;

pub mod legacy;
pub mod vti;
pub mod vtu;
pub mod write;

#[cfg(test)]
mod tests;

/// The bounded whole-file read every reader shares.
pub(crate) use super::read_file;
