//! soft-bvh (the paper's cuda-bvh): one compute-shader invocation per point traverses the
//! wide quantized BVH of `tetloc_core::bvh` (4 children a node, child boxes in a byte a
//! coordinate; its prims are the tets, or the cells of a mixed mesh, one box a cell), entered
//! through a uniform grid whose cells name a start tet for a walk through face neighbours and
//! a node for the exact traversal fallback (shaders/soft_bvh.comp,
//! shaders/common/soft_bvh.glsl). The volume marcher runs the same traversal (march.comp).

use super::{n_prims, prim_boxes, prim_tets, Inputs, KernelDef, Plan, Ray};
pub(crate) mod build;

use crate::device::{Device, Split};
use crate::error::{VkError, VkResult};
use crate::interface::{self, sc, B_ACCEL, B_ACCEL_HI, B_GRID, B_NEIGHBORS, B_NEIGHBORS_HI, B_PRIMS};
use crate::memory::MemKind;
use crate::packed;
use crate::pipeline::{Binding, Program, Spec};
use crate::shaders;
use ash::vk;
pub use build::BuildOn;
use build::Structure;
use rayon::prelude::*;
use std::time::Instant;
use tetloc_core::bvh::{wide, BuildPreset, Bvh, EntryGrid, WideBvh};
use tetloc_core::geom::{self, Vec3};
use tetloc_core::mesh::Mesh;

pub(crate) const KERNEL: KernelDef = KernelDef { name: "soft-bvh", ray_tracing: false, cell_boxes: true, plan };

/// Most tets a walk start visits before traversal takes over (jets: 1.7-2.6 on average from
/// a cell-centre start, NOTES.md).
const WALK_MAX: i32 = 32;

// The shaders decode tetloc_core's node format with the interface's constants.
const _: () = assert!(
    interface::LEAF == wide::LEAF
        && interface::EMPTY == wide::EMPTY
        && interface::LEAF_COUNT_SHIFT == wide::LEAF_COUNT_SHIFT
        && interface::LEAF_FIRST_MAX == wide::LEAF_FIRST_MAX
        && interface::OUTSIDE == tetloc_core::OUTSIDE
);

/// soft-bvh's options: the structure's layout, how a search starts, where the structure is
/// built. Named layouts (structure size against speed), measured on the H200 at jets 62M
/// (BENCHMARKS.md): [`Self::fast`], the default; [`Self::compact`]; [`Self::small`].
#[derive(Clone, Debug, PartialEq)]
pub struct SoftBvhOptions {
    /// Prims (tets, or a mixed mesh's cells) per BVH leaf: 1 (the paper's layout; the
    /// reference holds the prim id) or 4 (up to four, fewer nodes, an index list). 1 measured
    /// faster on the H100 (NOTES.md).
    pub leaf_size: usize,
    /// Invocations per workgroup.
    pub workgroup_size: u32,
    /// Start each traversal below the root, at the node an entry grid names for the point's
    /// cell (about `grid_tets_per_cell` tets per cell, 4 B per cell). Unmeasured on GPUs so
    /// far: off by default (NOTES.md).
    pub grid_start: bool,
    /// Walk through face neighbours from a start tet the entry grid names for the point's cell
    /// (the tet holding the cell's centre), traversal from the cell's node as the exact
    /// fallback; +4 B per cell and the neighbours (16 B per tet). Implies the grid. The
    /// default: on the H100 5.1x (uniform) and 2.0x (random) faster than traversal (NOTES.md).
    pub walk_start: bool,
    /// Entry grid resolution: about this many tets per cell (on a mixed mesh, as many prims as
    /// that many tets are, at least one: a grid cell per hex at 1).
    pub grid_tets_per_cell: usize,
    /// Decide the point-in-tet test in f32 first and enter the full test (with its f64
    /// fallback) only when f32 cannot; same answers, no f64 state on the hot path.
    pub f32_first: bool,
    /// Decide every test in f32 and defer the samples f32 cannot decide to a second, exact
    /// dispatch (indirect, over a list the first pass appends to); same answers, and the first
    /// pass holds no f64 code. Not yet measured on a GPU: off by default (NOTES.md).
    pub defer_exact: bool,
    /// Where the structure (BVH, entry grid, neighbours) is built: on the GPU (the default;
    /// meshes whose build arrays exceed one buffer fall back to the CPU) or with tetloc_core's
    /// CPU builder, the reference. Both give the same structure, bit for bit.
    pub build: BuildOn,
}

/// The names of [`SoftBvhOptions::preset`].
pub const PRESETS: [&str; 3] = ["fast", "compact", "small"];

impl SoftBvhOptions {
    /// Leaf 1, walk start, 1 tet a grid cell: 4.12 GiB at jets 62M, random 2.48 G/s, centres
    /// 25.9 G/s.
    pub fn fast() -> Self {
        SoftBvhOptions {
            leaf_size: 1,
            workgroup_size: 128,
            grid_start: false,
            walk_start: true,
            grid_tets_per_cell: GRID_TETS_PER_CELL,
            f32_first: false,
            defer_exact: false,
            build: BuildOn::Gpu,
        }
    }

    /// Leaf 4, walk start, 4 tets a cell (with packed ids: 2.48 GiB, random 2.38 G/s,
    /// centres 16.4 G/s).
    pub fn compact() -> Self {
        SoftBvhOptions { leaf_size: 4, grid_tets_per_cell: 4, ..Self::fast() }
    }

    /// Leaf 4, traversal from the entry grid's node, no neighbour table (with packed ids:
    /// 1.67 GiB, random 1.28 G/s, centres 3.5 G/s).
    pub fn small() -> Self {
        SoftBvhOptions { walk_start: false, grid_start: true, ..Self::compact() }
    }

    /// The layout named `name` ([`PRESETS`]), or `None` for an unknown name.
    pub fn preset(name: &str) -> Option<Self> {
        match name {
            "fast" => Some(Self::fast()),
            "compact" => Some(Self::compact()),
            "small" => Some(Self::small()),
            _ => None,
        }
    }

    /// What is wrong with these options, if anything.
    pub fn validate(&self) -> Result<(), String> {
        if ![1, 4].contains(&self.leaf_size) || self.workgroup_size == 0 || self.grid_tets_per_cell == 0 {
            return Err(format!(
                "soft-bvh: leaf_size {} (1 or 4), workgroup_size {} (> 0), grid_tets_per_cell {} (> 0)",
                self.leaf_size, self.workgroup_size, self.grid_tets_per_cell
            ));
        }
        Ok(())
    }
}

impl Default for SoftBvhOptions {
    fn default() -> Self {
        Self::fast()
    }
}

/// Entry grid resolution by default: about this many tets per cell (a 1M-tet jets mesh then
/// starts traversal at level 6-7 of 13 on median; walks from a cell's start take 1.7 tests
/// a sample on jets 12M, 2.1 at 2 tets a cell).
pub const GRID_TETS_PER_CELL: usize = 1;

fn plan(dev: &mut Device, input: &Inputs) -> VkResult<Plan> {
    let opts = input.soft_bvh;
    let want = build::Wanted {
        max_leaf: opts.leaf_size as u32,
        grid: opts.grid_start || opts.walk_start,
        walk: opts.walk_start,
        // The query shaders read the grid as one buffer: at a billion tets a cell holds more.
        prims_per_cell: build::prims_per_cell(
            n_prims(input.mesh),
            (input.mesh.info.bounds_min, input.mesh.info.bounds_max),
            grid_prims_per_cell(input.mesh, opts.grid_tets_per_cell),
            dev.device_max_buffer(),
        ),
        pack: input.pack.is_some(),
        pack_min_bits: input.pack.unwrap_or(0),
    };
    let built = match opts.build {
        BuildOn::Gpu => build::build(dev, input, want)?,
        BuildOn::Cpu => None,
    };
    let s = match built {
        Some(s) => s,
        None => {
            let mut s = cpu_structure(dev, input, want)?;
            if opts.build == BuildOn::Gpu {
                s.stages.insert(0, ("gpu build: the mesh is beyond what it addresses, built on the cpu".into(), 0.0));
            }
            s
        }
    };
    let (nodes, prims, grid, neighbors) = (s.nodes, s.prims, s.grid, s.neighbors);
    let (neighbor_bits, prim_bits) = (s.neighbor_bits, s.prim_bits);
    let stack_size = (3 * s.depth + 1) as u32;
    let unbound = dev.unbound();
    let mut bindings = vec![
        Binding::buffer(B_PRIMS, prims.as_ref().unwrap_or(unbound)),
        Binding::buffer(B_GRID, grid.as_ref().unwrap_or(unbound)),
    ];
    bindings.extend(Binding::split(B_ACCEL, B_ACCEL_HI, Some(&nodes), unbound));
    bindings.extend(Binding::split(B_NEIGHBORS, B_NEIGHBORS_HI, neighbors.as_ref(), unbound));
    let spec = Spec::default()
        .set(sc::NODES_CHUNK, nodes.per_chunk)
        .set(sc::NEIGHBORS_CHUNK, neighbors.as_ref().map_or(0, |n| n.per_chunk))
        .set(sc::WALK_MAX, WALK_MAX as u32)
        .set(sc::WALK_START, opts.walk_start as u32)
        .set(sc::STACK_SIZE, stack_size)
        .set(sc::DIRECT_LEAVES, s.direct as u32)
        .set(sc::GRID_START, grid.is_some() as u32)
        .set(sc::NEIGHBOR_BITS, neighbor_bits)
        .set(sc::PRIM_BITS, prim_bits);
    // Deferred exact tests need the f64 test to defer to.
    let defer = opts.defer_exact && input.f64;
    let pass = |defer: bool, exact: bool| {
        Spec::default()
            .set(sc::F32_FIRST, (opts.f32_first || defer) as u32)
            .set(sc::DEFER_EXACT, defer as u32)
            .set(sc::EXACT_PASS, exact as u32)
            .set(sc::WORKGROUP, opts.workgroup_size)
    };
    Ok(Plan {
        _owned: Box::new((nodes, prims, grid, neighbors)),
        bindings,
        spec,
        locate_spec: pass(defer, false),
        exact_pass: defer.then(|| pass(false, true)),
        locate: Program::Compute(shaders::SOFT_BVH),
        march: Program::Compute(shaders::MARCH),
        stream: Some(Program::Compute(shaders::STREAM)),
        hinted: Some(Program::Compute(shaders::HINTED)),
        // The marcher walks from sample to sample (march.comp), with or without the walk start.
        march_needs_neighbors: !opts.walk_start,
        ray: Ray::default(),
        accel: None,
        build_stages: s.stages,
    })
}

/// Prims a cell of the entry grid holds on average for `tets_per_cell` tets (the option): as
/// many as that many tets are, but at least one (a hex mesh's grid has a cell per hex, a sixth
/// of its decomposition's: centres' walks start farther, BENCHMARKS.md).
fn grid_prims_per_cell(mesh: &Mesh, tets_per_cell: usize) -> usize {
    (tets_per_cell * n_prims(mesh)).div_ceil(mesh.n_tets().max(1)).max(1)
}

/// The tree and entry grid that tetloc_core's builders make over the mesh's prims
/// (`kernels::n_prims`: tets, or a mixed mesh's cells, one box each): the reference the GPU
/// build matches bit for bit. A grid cell's walk start is a tet: with cells as prims, the
/// first tet of the start cell that holds the grid cell's centre (else its first tet), which
/// is the tet the build's traversal returns.
pub(crate) fn host_tree(
    mesh: &Mesh,
    want: &build::Wanted,
    timed: &mut dyn FnMut(&str, Instant),
) -> VkResult<(WideBvh, Option<EntryGrid>)> {
    let preset = if want.max_leaf == 1 { BuildPreset::SingleTetLeaves } else { BuildPreset::Fast };
    let t = Instant::now();
    let boxes = prim_boxes(mesh);
    let bvh = Bvh::build_boxes(&boxes, preset);
    timed("binary BVH", t);
    let t = Instant::now();
    let wide = WideBvh::collapse(&bvh).map_err(|e| VkError::Mesh(format!("soft-bvh: {e}")))?;
    drop(bvh);
    timed("collapse", t);
    if !want.grid {
        return Ok((wide, None));
    }
    let t = Instant::now();
    // Whether tet t holds p (strictly inside); a cell's claim is its first tet's that holds p.
    let claim = |t: usize, p: Vec3| match geom::test_point(mesh.tets[t], &mesh.points, p) {
        geom::TetTest::Inside(b) => Some(!b.contains(&0.0)),
        geom::TetTest::Outside { .. } => None,
    };
    let prim_claim: &(dyn Fn(u32, Vec3) -> Option<bool> + Sync) = &|c, p| prim_tets(mesh, c).find_map(|t| claim(t, p));
    let bounds = (mesh.info.bounds_min, mesh.info.bounds_max);
    let walk = want.walk.then_some(prim_claim);
    let mut grid = EntryGrid::new(&wide, boxes.len(), |p| boxes[p as usize], bounds, want.prims_per_cell, walk);
    if mesh.cells.is_some() {
        grid.starts = (0..grid.starts.len())
            .into_par_iter()
            .map(|i| match grid.starts[i] {
                wide::EMPTY => wide::EMPTY,
                c => {
                    let centre = grid.centre(i);
                    let tets = prim_tets(mesh, c);
                    tets.clone().find(|&t| claim(t, centre).is_some()).unwrap_or(tets.start) as u32
                }
            })
            .collect();
    }
    timed("entry grid", t);
    Ok((wide, Some(grid)))
}

/// The structure built on the host by tetloc_core (the reference), then uploaded.
fn cpu_structure(dev: &mut Device, input: &Inputs, want: build::Wanted) -> VkResult<Structure> {
    let mesh = input.mesh;
    let mut stages = vec![];
    let mut timed = |name: &str, t: Instant| stages.push((format!("cpu: {name}"), t.elapsed().as_secs_f64()));
    let (wide, grid) = host_tree(mesh, &want, &mut timed)?;
    let t = Instant::now();
    if want.walk {
        mesh.neighbors();
        timed("neighbours", t);
    }
    let t = Instant::now();
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let (n, direct) = (mesh.n_tets() as u64, wide.direct);
    let (neighbor_bits, prim_bits) =
        build::packed_bits(&want, n, n_prims(mesh) as u64, direct, dev.device_max_buffer());
    let nodes = dev.upload_split("bvh nodes", MemKind::Structure, storage, bytemuck::cast_slice(&wide.nodes), 64)?;
    let prims = if direct {
        None
    } else if prim_bits > 0 {
        Some(packed::upload(dev, "bvh prims (packed)", MemKind::Structure, &wide.prims, prim_bits)?)
    } else {
        Some(dev.upload("bvh prims", MemKind::Structure, storage, bytemuck::cast_slice(&wide.prims))?)
    };
    let grid = match grid {
        Some(g) => Some(dev.upload("entry grid", MemKind::Structure, storage, bytemuck::cast_slice(&g.words()))?),
        None => None,
    };
    let neighbors = if !want.walk {
        None
    } else if neighbor_bits > 0 {
        // Stored + 1, so that no neighbour (-1) is 0.
        let plus_one: Vec<u32> = mesh.neighbors().as_flattened().par_iter().map(|&t| (t + 1) as u32).collect();
        Some(Split::whole(packed::upload(
            dev,
            "tet neighbours (packed)",
            MemKind::Structure,
            &plus_one,
            neighbor_bits,
        )?))
    } else {
        let nb = bytemuck::cast_slice(mesh.neighbors());
        Some(dev.upload_split("tet neighbours", MemKind::Structure, storage, nb, 16)?)
    };
    timed("uploads", t);
    Ok(Structure { nodes, prims, direct, depth: wide.depth, grid, neighbors, neighbor_bits, prim_bits, stages })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What one CPU-mirrored location cost (NOTES.md "counts"): 4-wide nodes loaded,
    /// point-in-tet tests, faces decided in f64, walk steps (tets tested by the walk).
    #[derive(Clone, Copy, Debug, Default)]
    struct Cost {
        nodes: u32,
        tests: u32,
        f64_faces: u32,
        walk_steps: u32,
        /// The walk did not settle the point (left the mesh, ran out of steps, ended on a face).
        fallback: bool,
    }

    /// The point-in-tet test, counting tests and the faces whose sign the f64 fallback decides.
    fn test_counting(ids: [u32; 4], points: &[Vec3], p: Vec3, cost: &mut Cost) -> geom::TetTest {
        cost.tests += 1;
        let r = geom::test_point(ids, points, p);
        let evaluated = match r {
            geom::TetTest::Inside(_) => 4,
            geom::TetTest::Outside { face } => {
                let swapped = ids[3] < ids[2];
                // stored index -> ascending index (the same involution), +1 faces evaluated
                (if swapped && face >= 2 { 5 - face } else { face }) + 1
            }
        };
        for (f, _) in geom::ascending_faces(ids).iter().take(evaluated) {
            let v = f.map(|i| points[i as usize]);
            let (det, bound) = geom::orient_f32(v[0], v[1], v[2], p);
            if det.abs() <= bound {
                cost.f64_faces += 1;
            }
        }
        r
    }

    /// The CPU mirror of `tl_walk` (shaders/common/walk.glsl) with the walk-start rule of
    /// `tl_locate`: the answer counts only when the point is strictly inside.
    fn walk(mesh: &tetloc_core::Mesh, mut tet: i32, p: Vec3, max_steps: u32, cost: &mut Cost) -> Option<u32> {
        for _ in 0..max_steps {
            if tet < 0 {
                break;
            }
            cost.walk_steps += 1;
            match test_counting(mesh.tets[tet as usize], &mesh.points, p, cost) {
                geom::TetTest::Inside(b) if b.iter().all(|&w| w != 0.0) => return Some(tet as u32),
                geom::TetTest::Inside(_) => break,
                geom::TetTest::Outside { face } => tet = mesh.neighbors()[tet as usize][face],
            }
        }
        cost.fallback = true;
        None
    }

    /// The wide traversal from `start`, counting.
    fn traverse(
        q: &WideBvh,
        mesh: &tetloc_core::Mesh,
        p: Vec3,
        start: u32,
        stack: &mut Vec<u32>,
        cost: &mut Cost,
    ) -> Option<u32> {
        let mut tests = Cost::default();
        let found = q.traverse(p, start, stack, |t| {
            matches!(test_counting(mesh.tets[t as usize], &mesh.points, p, &mut tests), geom::TetTest::Inside(_))
        });
        cost.nodes += found.nodes;
        cost.tests += tests.tests;
        cost.f64_faces += tests.f64_faces;
        found.prim
    }

    /// shaders/common/samples.glsl's `random` generator (hash, fold), for the counts.
    fn random_sample(g: u32, seed: u32, points: &[Vec3], tets: &[[u32; 4]]) -> Vec3 {
        let hash = |x: u32| {
            let state = x.wrapping_mul(747796405).wrapping_add(2891336453);
            let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277803737);
            (word >> 22) ^ word
        };
        let mut st = hash(g ^ hash(seed));
        let t = tets[(hash(st) % tets.len() as u32) as usize];
        let mut unit = || {
            st = hash(st);
            (st >> 8) as f32 * (1.0 / 16777216.0)
        };
        let (a, b, c) = (unit(), unit(), unit());
        let [a, b, c] = tetloc_core::queries::fold_cube_into_tet(a, b, c);
        let w = 1.0 - a - b - c;
        let v = t.map(|i| points[i as usize]);
        std::array::from_fn(|k| w * v[0][k] + a * v[1][k] + b * v[2][k] + c * v[3][k])
    }

    /// Per-sample costs of three ways to locate (NOTES.md "Counts"): traversal from the root,
    /// from the entry grid's node, and a walk from the grid's start tet (BVH from the entry
    /// node as the fallback); averages per sample and, for SIMT, the mean over warps of 32
    /// consecutive samples of the longest lane's loop iterations.
    #[test]
    #[ignore = "measurement: TETLOC_COUNT_TETS=12000000 cargo test --release -p tetloc-vulkan --lib count_costs -- --ignored --nocapture"]
    fn count_costs() {
        let n: usize = std::env::var("TETLOC_COUNT_TETS").map_or(3_000_000, |v| v.parse().unwrap());
        let per_cell: usize = std::env::var("TETLOC_TETS_PER_CELL").map_or(2, |v| v.parse().unwrap());
        let max_steps: u32 = std::env::var("TETLOC_WALK_STEPS").map_or(32, |v| v.parse().unwrap());
        let mesh =
            tetloc_core::Mesh::new(tetloc_core::gen::generate(tetloc_core::gen::Shape::Jets, n, 1), "jets").unwrap();
        let (pts, tets) = (&mesh.points, &mesh.tets);
        let q = WideBvh::collapse(&Bvh::build(pts, tets, BuildPreset::SingleTetLeaves)).unwrap();
        let claim = |t: u32, p: Vec3| geom::point_in_tet(tets[t as usize], pts, p).map(|b| !b.contains(&0.0));
        let bounds = (mesh.info.bounds_min, mesh.info.bounds_max);
        let g = EntryGrid::new(
            &q,
            tets.len(),
            |t| tetloc_core::bvh::Aabb::of_tet(tets[t as usize], pts),
            bounds,
            per_cell,
            Some(&claim),
        );
        println!(
            "jets {} tets, {} nodes, depth {}, grid {:?} ({} tets/cell), walk <= {max_steps} steps",
            tets.len(),
            q.nodes.len(),
            q.depth,
            g.dims,
            per_cell
        );
        let warps = 20_000.min(tets.len() / 32);
        for mode in ["centers", "random"] {
            // [root, grid, walk] x [nodes, tests, f64 faces, walk steps, fallbacks, iterations, warp-max iterations]
            let sums = (0..warps)
                .into_par_iter()
                .map(|w| {
                    let mut acc = [[0f64; 7]; 3];
                    let mut warp_max = [0u32; 3];
                    let base = (w * (tets.len() / 32 / warps)) * 32;
                    for lane in 0..32 {
                        let i = base + lane;
                        let p =
                            if mode == "centers" { mesh.tet_center(i) } else { random_sample(i as u32, 1, pts, tets) };
                        let c = g.cell_of(p);
                        let mut costs = [Cost::default(); 3];
                        let stack = &mut vec![];
                        let a = traverse(&q, &mesh, p, 0, stack, &mut costs[0]);
                        let b = traverse(&q, &mesh, p, g.cells[c], stack, &mut costs[1]);
                        let walked = walk(&mesh, g.starts[c] as i32, p, max_steps, &mut costs[2]);
                        let w = walked.or_else(|| traverse(&q, &mesh, p, g.cells[c], stack, &mut costs[2]));
                        assert!(a.is_some(), "{mode} sample {i} {p:?} lost");
                        assert_eq!(a, b, "{mode} sample {i}: grid start changed the answer");
                        if walked.is_some() {
                            // strictly inside: the one tet that holds the point
                            assert_eq!(walked, a, "{mode} sample {i}: the walk found another tet");
                        }
                        assert!(w.is_some());
                        for (k, cost) in costs.iter().enumerate() {
                            let iters = cost.nodes + cost.tests;
                            let v =
                                [cost.nodes, cost.tests, cost.f64_faces, cost.walk_steps, cost.fallback as u32, iters];
                            for (j, x) in v.iter().enumerate() {
                                acc[k][j] += *x as f64;
                            }
                            warp_max[k] = warp_max[k].max(iters);
                        }
                    }
                    for k in 0..3 {
                        acc[k][6] = warp_max[k] as f64;
                    }
                    acc
                })
                .reduce(
                    || [[0f64; 7]; 3],
                    |mut x, y| {
                        for k in 0..3 {
                            for j in 0..7 {
                                x[k][j] += y[k][j];
                            }
                        }
                        x
                    },
                );
            let samples = (warps * 32) as f64;
            println!("{mode} ({} samples in warps of 32):", warps * 32);
            println!("  start      nodes  tests  f64-faces  walk-steps  fallback  iterations  warp-max-iterations");
            for (k, name) in ["root", "grid node", "grid walk"].iter().enumerate() {
                let m: Vec<f64> = sums[k][..6].iter().map(|x| x / samples).collect();
                println!(
                    "  {name:<10} {:>5.2} {:>6.2} {:>10.4} {:>11.2} {:>8.2}% {:>11.2} {:>20.2}",
                    m[0],
                    m[1],
                    m[2],
                    m[3],
                    100.0 * m[4],
                    m[5],
                    sums[k][6] / warps as f64
                );
            }
        }
    }
}
