//! The distributed locator over MPI (feature `mpi`): setup (load, build, agree, exchange
//! regions) and the collective query (route, answer, return, reduce).

use crate::reduce::{reduce, Reduced};
use crate::route::{Region, Routes};
use crate::{launch, Error};
use mpi::collective::SystemOperation;
use mpi::datatype::{Partition, PartitionMut};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use rayon::prelude::*;
use std::io::Write as _;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;
use tetloc_core::locate::{Points, Values};
use tetloc_core::{BatchLocator, Mesh, Vec3};
use tetloc_io::{parts, vtk::pieces};

/// This process's place in the job: the world communicator, its rank and its node's ranks.
pub struct Cluster {
    _universe: mpi::environment::Universe,
    pub world: SimpleCommunicator,
    pub rank: usize,
    pub size: usize,
    /// Rank and number of ranks on this node (an MPI shared-memory split): GPU ranks take
    /// device `local_rank` modulo the devices there are.
    pub local_rank: usize,
    pub local_size: usize,
}

impl Cluster {
    /// Starts MPI. A panic on any rank from here on aborts the whole job (MPI_Abort), so no
    /// rank waits for one that is gone; CPU threads are shared out among the node's ranks.
    pub fn init() -> Result<Cluster, Error> {
        let universe = mpi::initialize().ok_or_else(|| Error::Init("MPI was already initialised".into()))?;
        let world = universe.world();
        let local = world.split_shared(world.rank());
        let cluster = Cluster {
            rank: world.rank() as usize,
            size: world.size() as usize,
            local_rank: local.rank() as usize,
            local_size: local.size() as usize,
            world,
            _universe: universe,
        };
        let (rank, size) = (cluster.rank, cluster.size);
        let default_hook = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let _ = writeln!(std::io::stderr(), "tetloc: rank {rank} of {size} panicked; aborting the job");
            default_hook(info);
            SimpleCommunicator::world().abort(101);
        }));
        if std::env::var_os("RAYON_NUM_THREADS").is_none() {
            let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
            let threads = (cores / cluster.local_size).max(1);
            let _ = rayon::ThreadPoolBuilder::new().num_threads(threads).build_global();
        }
        Ok(cluster)
    }

    pub fn is_root(&self) -> bool {
        self.rank == 0
    }

    /// Every rank's string, in rank order (collective).
    pub fn all_gather_strings(&self, s: &str) -> Vec<String> {
        let len = s.len() as Count;
        let mut lens = vec![0 as Count; self.size];
        self.world.all_gather_into(&len, &mut lens[..]);
        let displs = displacements(&lens);
        // Buffers with a real address even when empty: an empty byte slice points at 0x1,
        // which OpenMPI reads as MPI_IN_PLACE.
        let total: usize = lens.iter().map(|&l| l as usize).sum();
        let mut bytes = Vec::with_capacity(total.max(1));
        bytes.resize(total, 0u8);
        let mut send = Vec::with_capacity(s.len().max(1));
        send.extend_from_slice(s.as_bytes());
        {
            let mut part = PartitionMut::new(&mut bytes[..], &lens[..], &displs[..]);
            self.world.all_gather_varcount_into(&send[..], &mut part);
        }
        (0..self.size)
            .map(|r| String::from_utf8_lossy(&bytes[displs[r] as usize..(displs[r] + lens[r]) as usize]).into_owned())
            .collect()
    }

    /// Collective: `Ok` on every rank when every rank's step succeeded, otherwise the same
    /// error on every rank, naming each rank that failed and why. Every step that can fail
    /// on some ranks (loading, building) ends here before any other collective, so a failure
    /// ends the job on all ranks instead of leaving the others waiting.
    pub fn agree<T>(&self, step: &str, r: Result<T, String>) -> Result<T, Error> {
        let mine = match &r {
            Ok(_) => String::new(),
            Err(e) if e.is_empty() => "failed".into(),
            Err(e) => e.clone(),
        };
        let failed: Vec<(usize, String)> =
            self.all_gather_strings(&mine).into_iter().enumerate().filter(|(_, e)| !e.is_empty()).collect();
        if failed.is_empty() {
            return Ok(r.unwrap_or_else(|_| unreachable!("every rank succeeded")));
        }
        Err(Error::Ranks { step: step.to_string(), size: self.size, failed })
    }

    /// Ends the whole job from one rank after an error that the others cannot know of (they
    /// may be waiting in a collective): says which rank and why, then MPI_Abort.
    pub fn abort(&self, msg: &str) -> ! {
        let _ = writeln!(std::io::stderr(), "error: rank {} of {}: {msg}", self.rank, self.size);
        self.world.abort(1)
    }

    /// The largest of every rank's value (collective).
    pub fn max_u64(&self, x: u64) -> u64 {
        let mut out = 0u64;
        self.world.all_reduce_into(&x, &mut out, SystemOperation::max());
        out
    }

    /// The largest of every rank's value (collective).
    pub fn max_f64(&self, x: f64) -> f64 {
        let mut out = 0f64;
        self.world.all_reduce_into(&x, &mut out, SystemOperation::max());
        out
    }

    /// The sum of every rank's value (collective).
    pub fn sum_u64(&self, x: u64) -> u64 {
        let mut out = 0u64;
        self.world.all_reduce_into(&x, &mut out, SystemOperation::sum());
        out
    }
}

fn displacements(counts: &[Count]) -> Vec<Count> {
    counts
        .iter()
        .scan(0 as Count, |acc, &c| {
            let d = *acc;
            *acc += c;
            Some(d)
        })
        .collect()
}

/// One rank's part of a partitioned mesh: its pieces joined, and the global id of each cell.
pub struct Part {
    pub mesh: Arc<Mesh>,
    pub global_ids: Vec<u64>,
    pub pieces: std::ops::Range<usize>,
}

/// Loads this rank's pieces of `listing` (collective; `None` for a rank with no piece): a
/// `.pvtu`/`.vtm`'s `.vtu` files or a decomposed OpenFOAM case's processors (`tetloc_io::parts`).
pub fn load_part(cluster: &Cluster, listing: &Path) -> Result<Option<Part>, Error> {
    let read = || -> Result<_, String> {
        let files = parts::list(listing).map_err(|e| e.to_string())?;
        let range = launch::pieces_of(files.len(), cluster.size, cluster.rank);
        let read = range
            .clone()
            .map(|k| parts::read_piece(listing, k, &files[k]).map(|p| (k, p)))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| e.to_string())?;
        Ok((files.len(), range, read))
    };
    let (n_pieces, range, read) = cluster.agree("load", read())?;
    // Piece sizes and whether they carry global ids, everywhere: the default global ids are
    // the cells of the pieces before.
    let mut counts = vec![0u64; n_pieces];
    for (k, p) in &read {
        counts[*k] = p.n_cells() as u64;
    }
    let mut all = vec![0u64; n_pieces];
    cluster.world.all_reduce_into(&counts[..], &mut all[..], SystemOperation::sum());
    let first_ids: Vec<u64> = all.iter().scan(0, |a, &c| Some(std::mem::replace(a, *a + c))).collect();
    let signature = read.first().map_or(String::new(), |(_, p)| {
        let f: Vec<String> = p.raw.fields.iter().map(|f| format!("{}:{:?}", f.name, f.location)).collect();
        format!("[{}] ids:{}", f.join(","), p.global_ids.is_some())
    });
    let build = || -> Result<Option<Part>, String> {
        let sigs = cluster.all_gather_strings(&signature);
        if let Some((r, s)) =
            sigs.iter().enumerate().find(|(_, s)| !s.is_empty() && **s != signature && !signature.is_empty())
        {
            return Err(format!(
                "rank {r}'s pieces carry {s}, this rank's {signature}: the pieces differ in their arrays"
            ));
        }
        if read.is_empty() {
            return Ok(None);
        }
        let (raw, ids) = pieces::join(listing, read, &first_ids[range.clone()]).map_err(|e| e.to_string())?;
        let name = format!("{} (pieces {}..{})", listing.display(), range.start, range.end);
        let mesh = Mesh::new(raw, name).map_err(|e| e.to_string())?;
        Ok(Some(Part { mesh: Arc::new(mesh), global_ids: ids, pieces: range.clone() }))
    };
    let part = build();
    cluster.agree("load", part)
}

/// What a distributed query measured on this rank.
#[derive(Clone, Copy, Debug, Default)]
pub struct Stats {
    /// Points this rank's locator answered (sent to it by any rank).
    pub answered: u64,
    /// Seconds this rank's locator spent on them.
    pub local_secs: f64,
    /// Points this rank owns that more than one rank claimed.
    pub ties: u64,
}

/// The precision in which the ranks exchange points and answer them: f32, or f64 (the
/// file's own points, for a mesh stored in f64 or far from the origin), with values in the
/// same precision.
pub trait Precision: tetloc_core::geom::Real + Equivalence + bytemuck::Pod + Default {
    /// The f32 point a point is routed by: its rounding to nearest. Routing by it is
    /// conservative: rounding is monotone, and the regions' boxes are rounded outward
    /// (`route`), so a point inside a cell rounds into the cell's rounded box.
    fn routed(p: [Self; 3]) -> Vec3;
    /// f64's (as a call announces its precision to the ranks).
    const WIDE: bool;
    fn points(p: &[[Self; 3]]) -> Points<'_>;
    fn values(v: &mut [Self]) -> Values<'_>;
    /// Copies `from` into `to`, of either precision (rounded where it is the other).
    fn put(to: Values<'_>, from: &[Self]) -> Result<(), tetloc_core::Error>;
}

impl Precision for f32 {
    fn routed(p: Vec3) -> Vec3 {
        p
    }
    const WIDE: bool = false;
    fn points(p: &[Vec3]) -> Points<'_> {
        Points::F32(p)
    }
    fn values(v: &mut [f32]) -> Values<'_> {
        Values::F32(v)
    }
    fn put(to: Values<'_>, from: &[f32]) -> Result<(), tetloc_core::Error> {
        to.via_f32(|v| {
            v.copy_from_slice(from);
            Ok(())
        })
    }
}

impl Precision for f64 {
    fn routed(p: [f64; 3]) -> Vec3 {
        p.map(|c| c as f32)
    }
    const WIDE: bool = true;
    fn points(p: &[[f64; 3]]) -> Points<'_> {
        Points::F64(p)
    }
    fn values(v: &mut [f64]) -> Values<'_> {
        Values::F64(v)
    }
    fn put(to: Values<'_>, from: &[f64]) -> Result<(), tetloc_core::Error> {
        to.via_f64(|v| {
            v.copy_from_slice(from);
            Ok(())
        })
    }
}

/// Any backend on each rank, queried collectively: every rank hands in its own points and
/// gets their answers, in their order, as one process would give them on the whole mesh.
pub struct DistLocator<'c, L> {
    cluster: &'c Cluster,
    local: Option<L>,
    global_ids: Vec<u64>,
    regions: Vec<Region>,
    pub stats: Stats,
}

/// Points a rank routes per round: bounds the send buffers and keeps MPI's 32-bit counts
/// (values per rank pair) in range.
const ROUND: usize = 1 << 22;

impl<'c, L: BatchLocator> DistLocator<'c, L> {
    /// Builds every rank's locator with `build` and exchanges the regions (collective). A
    /// rank whose build fails fails the job on every rank, with its cause.
    pub fn new(
        cluster: &'c Cluster,
        part: Option<&Part>,
        build: impl FnOnce(&Arc<Mesh>) -> Result<L, String>,
    ) -> Result<DistLocator<'c, L>, Error> {
        let local = match part {
            Some(p) => build(&p.mesh).map(Some),
            None => Ok(None),
        };
        let local = cluster.agree("build", local)?;
        let region = part.map_or_else(Region::empty, |p| Region::of_mesh(&p.mesh));
        let mut words = vec![0u64; Region::WORDS * cluster.size];
        cluster.world.all_gather_into(&region.to_words()[..], &mut words[..]);
        let regions = words.chunks_exact(Region::WORDS).map(Region::from_words).collect();
        let global_ids = part.map_or_else(Vec::new, |p| p.global_ids.clone());
        Ok(DistLocator { cluster, local, global_ids, regions, stats: Stats::default() })
    }

    pub fn regions(&self) -> &[Region] {
        &self.regions
    }

    pub fn local(&self) -> Option<&L> {
        self.local.as_ref()
    }

    /// Collective: the global cell id (-1: none) and the values of `fields` (NaN: none) for
    /// each of this rank's points, f32 or f64 ([`Precision`]). Every rank must call it, with
    /// any number of points, in the same precision.
    pub fn query<T: Precision>(&mut self, points: &[[T; 3]], fields: &[&str]) -> Reduced<T> {
        if let Some(kind) = launch::fault(self.cluster.rank) {
            match kind.as_str() {
                "abort" => std::process::abort(),
                _ => panic!("fault injected by TETLOC_MPI_FAULT"),
            }
        }
        let k = fields.len();
        let rounds = self.cluster.max_u64(points.len().div_ceil(ROUND) as u64) as usize;
        let mut out =
            Reduced { ids: Vec::with_capacity(points.len()), values: Vec::with_capacity(points.len() * k), ties: 0 };
        for r in 0..rounds {
            let chunk = &points[(r * ROUND).min(points.len())..((r + 1) * ROUND).min(points.len())];
            let got = self.round(chunk, fields);
            out.ids.extend_from_slice(&got.ids);
            out.values.extend_from_slice(&got.values);
            out.ties += got.ties;
        }
        self.stats.ties += out.ties as u64;
        out
    }

    fn round<T: Precision>(&mut self, points: &[[T; 3]], fields: &[&str]) -> Reduced<T> {
        let (world, k) = (&self.cluster.world, fields.len());
        // Out: each point to every rank whose region may hold it.
        let routed: Vec<Vec3> = points.par_iter().map(|&p| T::routed(p)).collect();
        let routes = Routes::plan(&routed, &self.regions);
        let send = routes.gather(points);
        let send_counts: Vec<Count> = routes.counts.iter().map(|&c| c as Count).collect();
        let mut recv_counts = vec![0 as Count; self.cluster.size];
        world.all_to_all_into(&send_counts[..], &mut recv_counts[..]);
        let recv_points = exchange(world, bytemuck::cast_slice::<[T; 3], T>(&send), &send_counts, &recv_counts, 3);
        let recv_points: &[[T; 3]] = bytemuck::cast_slice(&recv_points);

        // Answer what was sent here.
        let n = recv_points.len();
        let (mut ids, mut values) = (vec![-1i32; n], vec![T::NAN; n * k]);
        if let (Some(local), true) = (&mut self.local, n > 0) {
            let t = Instant::now();
            if let Err(e) = local.query(T::points(recv_points), fields, &mut ids, T::values(&mut values)) {
                self.cluster.abort(&format!("locating {n} points: {e}"));
            }
            self.stats.local_secs += t.elapsed().as_secs_f64();
            self.stats.answered += n as u64;
        }
        let global: Vec<i64> =
            ids.par_iter().map(|&i| if i < 0 { -1 } else { self.global_ids[i as usize] as i64 }).collect();

        // Back: the answers to the ranks that asked, in the order they asked.
        let back_ids = exchange(world, &global, &recv_counts, &send_counts, 1);
        let back_values = exchange(world, &values, &recv_counts, &send_counts, k);
        reduce(points.len(), &routes.index, &back_ids, &back_values, k)
    }
}

/// An all-to-all of `per` values per counted item: `send` holds `send_counts[r]·per` values
/// for rank r, rank after rank; returns what the ranks sent here, rank after rank.
fn exchange<T: Equivalence + Copy + Default>(
    world: &SimpleCommunicator,
    send: &[T],
    send_counts: &[Count],
    recv_counts: &[Count],
    per: usize,
) -> Vec<T> {
    let scale = |c: &[Count]| -> Vec<Count> { c.iter().map(|&x| x * per as Count).collect() };
    let (sc, rc) = (scale(send_counts), scale(recv_counts));
    let (sd, rd) = (displacements(&sc), displacements(&rc));
    let mut recv = vec![T::default(); rc.iter().map(|&c| c as usize).sum()];
    if per == 0 {
        return recv;
    }
    {
        let send = Partition::new(send, &sc[..], &sd[..]);
        let mut part = PartitionMut::new(&mut recv[..], &rc[..], &rd[..]);
        world.all_to_all_varcount_into(&send, &mut part);
    }
    recv
}
