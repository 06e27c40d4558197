//! tetloc-core: which tetrahedron of this mesh contains this point, and what is the field
//! value there? The GPU-free core: mesh model, generators, BVH and the CPU locator. Files are
//! read and written by `tetloc-io`, which sits above it.

mod buckets;
pub mod bvh;
pub mod cache;
pub mod cell;
pub mod error;
pub mod gen;
pub mod geom;
pub mod locate;
pub mod memory;
pub mod mesh;
pub mod named;
pub mod ops;
pub mod par;
pub mod partition;
mod prefetch;
pub mod queries;
pub mod streamline;
#[cfg(test)]
mod test_support;

pub use error::{Error, Result};
pub use geom::Vec3;
pub use locate::{BatchLocator, CpuLocator, OUTSIDE};
pub use mesh::{Field, FieldLocation, Mesh, MeshInfo, RawMesh};
