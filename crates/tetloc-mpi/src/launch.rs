//! What the launcher (mpirun) tells a process through its environment, read before MPI is
//! initialised: whether it runs as one rank of several; and which pieces a rank loads.

/// The number of ranks when this process was started by an MPI launcher (OpenMPI's mpirun,
/// MPICH's Hydra, a PMIx launcher), `None` otherwise. (Slurm's `SLURM_NTASKS` is not asked:
/// it is set in every step of a batch script, also where tetloc runs as one plain process.)
pub fn world_size() -> Option<usize> {
    ["OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"].iter().find_map(|k| std::env::var(k).ok()?.trim().parse().ok())
}

/// The pieces rank `rank` of `size` loads: a contiguous run (RCB numbers neighbouring pieces
/// consecutively, so a rank's pieces are close together), the first `n % size` ranks one more.
pub fn pieces_of(n_pieces: usize, size: usize, rank: usize) -> std::ops::Range<usize> {
    let (q, r) = (n_pieces / size, n_pieces % size);
    let start = rank * q + rank.min(r);
    start..start + q + usize::from(rank < r)
}

/// A fault to inject, for the tests of failure handling: `TETLOC_MPI_FAULT=KIND:RANK` makes
/// rank RANK `panic` or `abort` (die on a signal, as a killed process) at its first query.
pub fn fault(rank: usize) -> Option<String> {
    let v = std::env::var("TETLOC_MPI_FAULT").ok()?;
    let (kind, r) = v.split_once(':')?;
    (r.trim().parse() == Ok(rank)).then(|| kind.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_are_spread_contiguously() {
        for (n, size) in [(8, 3), (2, 4), (5, 5), (12, 1)] {
            let runs: Vec<_> = (0..size).map(|r| pieces_of(n, size, r)).collect();
            assert_eq!(runs.first().unwrap().start, 0);
            assert_eq!(runs.last().unwrap().end, n);
            assert!(runs.windows(2).all(|w| w[0].end == w[1].start));
            assert!(runs.iter().all(|r| r.len().abs_diff(n / size) <= 1), "{runs:?}");
        }
    }
}
