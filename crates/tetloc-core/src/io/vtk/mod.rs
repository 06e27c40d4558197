//! Parts shared by the VTK readers ([`super::vtu`], [`super::vtk_legacy`]) and the VTU
//! writers ([`super::vtu_write`]): element types, cell types, XML and binary blocks.

pub(crate) mod blocks;
pub(crate) mod cells;
pub(crate) mod num;
pub(crate) mod xml;

#[cfg(test)]
mod tests;
