//! tetloc over MPI: a partitioned mesh (`.pvtu`, `.vtm`) located across ranks, each rank
//! holding some of its pieces and answering with any backend.
//!
//! **Setup.** Each rank loads a contiguous run of the pieces ([`launch::pieces_of`]), joins
//! them into its part of the mesh (cells keep their global ids), and builds a local locator
//! with any backend (GPU ranks choose their device by their rank on the node). Every step
//! that can fail on some ranks ends in an agreement among all ranks (`Cluster::agree`), so a
//! rank that cannot load or build makes every rank stop with an error that names it and its
//! cause. The ranks then allgather their regions ([`route::Region`]: bounding box and a 32³
//! occupancy grid).
//!
//! **A query** (collective, each rank with its own points): each point goes to every rank
//! whose region may hold it (one all-to-all of counts, one of points), those ranks answer
//! with their local locator (global cell id and values; in f32, or in f64 for the file's f64
//! points, `dist::Precision`), the answers go back the same way,
//! and the owner keeps, per point, the claim with the lowest global id ([`reduce`], which
//! says why that is the one-process answer). Unexpected errors and panics after setup call
//! MPI_Abort: the job ends, no rank is left waiting.
//!
//! Without the feature `mpi` this crate holds the parts that need no MPI (regions, routing,
//! the reduction, the launcher's environment), so the workspace builds and tests without it.

pub mod launch;
pub mod reduce;
pub mod route;

#[cfg(feature = "mpi")]
pub mod dist;
/// rsmpi, for callers that exchange their own data (the CLI scatters points and gathers answers).
#[cfg(feature = "mpi")]
pub use mpi;

/// What can stop a distributed run.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("MPI: {0}")]
    Init(String),
    /// Some ranks failed a step: each with its cause.
    #[error("{}", fmt_failed(step, *size, failed))]
    Ranks { step: String, size: usize, failed: Vec<(usize, String)> },
}

fn fmt_failed(step: &str, size: usize, failed: &[(usize, String)]) -> String {
    failed.iter().map(|(r, e)| format!("rank {r} of {size} failed to {step}: {e}")).collect::<Vec<_>>().join("; ")
}
