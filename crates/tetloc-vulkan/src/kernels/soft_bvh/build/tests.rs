//! The GPU build against tetloc_core's CPU builder, on lavapipe in CI: the same nodes, leaf
//! prims, depth, entry-grid words and neighbours, bit for bit, on meshes of several shapes
//! (a jittered grid, a regular one with many equal codes, a mixed mesh with one box a cell,
//! one tet, tets that all have the same box), with one and four prims a leaf; the GPU tree also
//! passes `WideBvh::validate` on its own; and locators built both ways answer alike.

use super::*;
use crate::context::{test_context, Context};
use crate::kernels::SoftBvhOptions;
use crate::locator::{LocatorOptions, MeshOnDevice, TestHooks};
use crate::packed;
use crate::Kernel;
use crate::VulkanLocator;
use std::sync::Arc;
use tetloc_core::bvh::{QNode4, WideBvh};
use tetloc_core::gen::{self, CellKind, Shape};
use tetloc_core::mesh::{Mesh, RawMesh};
use tetloc_core::queries::{self, QueryKind};
use tetloc_core::BatchLocator;

fn meshes() -> Vec<Mesh> {
    let spec = gen::Spec { shape: Shape::Fusion, cells: CellKind::Hybrid };
    let tet = RawMesh {
        points: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        tets: vec![[0, 1, 2, 3]],
        ..Default::default()
    };
    // Five copies of one tet: every box, centre and Morton code the same.
    let same = RawMesh { tets: vec![[0, 1, 2, 3]; 5], ..tet.clone() };
    vec![
        Mesh::new(gen::generate(Shape::Jets, 20_000, 3), "jets").unwrap(),
        tetloc_testdata::KuhnGrid::new(8).mesh("regular grid"),
        Mesh::new(gen::generate_spec(spec, 3_000, 1, &|_| {}), "fusion-hybrid").unwrap(),
        Mesh::new(tet, "one tet").unwrap(),
        Mesh::new(same, "five equal tets").unwrap(),
    ]
}

/// Builds `mesh`'s structure on the GPU and reads it back: nodes, prims, grid words, neighbours.
#[allow(clippy::type_complexity)]
/// `max_buffer`: the test hook that splits every array larger than it over several buffers.
fn gpu_build(
    ctx: &Arc<Context>,
    mesh: &Arc<Mesh>,
    want: Wanted,
    max_buffer: Option<u64>,
) -> (WideBvh, Option<Vec<u32>>, Option<Vec<[i32; 4]>>, usize) {
    let mut dev = Device::new(ctx, 1 << 20, max_buffer).unwrap();
    // Packed layouts get packed tets too, so that every build pass reads them.
    let pack = want.pack.then_some(want.pack_min_bits);
    let on_device = MeshOnDevice::upload(&mut dev, mesh, false, pack, true).unwrap();
    let mesh_bindings = on_device.bindings(dev.unbound());
    let opts = LocatorOptions::default();
    let input = on_device.inputs(mesh, &mesh_bindings, &opts, ctx.info().float64);
    let s = build(&mut dev, &input, want).unwrap().expect("small meshes fit");
    let words = |dev: &mut Device, buf: &Buffer| {
        let mut w = vec![0u32; (buf.size / 4) as usize];
        dev.download(buf, 0, bytemuck::cast_slice_mut(&mut w)).unwrap();
        w
    };
    // A split array's buffers hold whole elements: their words in order are the array's.
    let split_words = |dev: &mut Device, a: &Split| a.parts.iter().flat_map(|p| words(dev, p)).collect::<Vec<u32>>();
    let node_words = split_words(&mut dev, &s.nodes);
    let nodes: Vec<QNode4> = bytemuck::cast_slice(&node_words).to_vec();
    // Packed arrays read back field by field as the shaders read them (crate::packed).
    let (n, n_tets) = (crate::kernels::n_prims(mesh), mesh.n_tets());
    let unpack = |w: &[u32], fields: usize, bits: u32| (0..fields).map(|j| packed::get(w, j as u64, bits)).collect();
    assert_eq!(want.pack, s.neighbor_bits + s.prim_bits > 0, "packed as asked");
    let prims = s.prims.as_ref().map_or(vec![], |p| match s.prim_bits {
        0 => words(&mut dev, p)[..n].to_vec(),
        bits => unpack(&words(&mut dev, p), n, bits),
    });
    let wide = WideBvh::from_parts(nodes, prims, s.direct, s.depth);
    let grid = s.grid.as_ref().map(|g| words(&mut dev, g));
    let neighbors = s.neighbors.as_ref().map(|nb| {
        let w = split_words(&mut dev, nb);
        match s.neighbor_bits {
            0 => bytemuck::cast_slice::<u32, [i32; 4]>(&w)[..n_tets].to_vec(),
            bits => {
                let plus_one: Vec<u32> = unpack(&w, 4 * n_tets, bits);
                plus_one.chunks(4).map(|c| std::array::from_fn(|k| c[k] as i32 - 1)).collect()
            }
        }
    });
    let parts = s.nodes.parts.len().max(s.neighbors.as_ref().map_or(0, |n| n.parts.len()));
    (wide, grid, neighbors, parts)
}

/// Every mesh, both leaf sizes, with and without walk starts, with packed ids (every pass on
/// packed tets; neighbours and prims packed by the GPU read back as the shaders read them; 27
/// bits a field: records of five words): the CPU's structure, bit for bit.
#[test]
fn gpu_build_is_the_cpu_build() {
    let Some(ctx) = test_context("gpu_build_is_the_cpu_build") else { return };
    let layouts = [(1, true, None), (4, true, None), (4, false, None), (4, true, Some(0)), (1, true, Some(27))];
    for mesh in meshes() {
        let mesh = Arc::new(mesh);
        for (max_leaf, walk, pack) in layouts {
            assert_builds_like_cpu(&ctx, &mesh, Layout { max_leaf, walk, pack }, None);
        }
    }
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors (printed above)");
}

/// What a test builds: tets a leaf, walk starts (the neighbours), packed ids (at least this
/// many bits a field).
#[derive(Clone, Copy)]
struct Layout {
    max_leaf: u32,
    walk: bool,
    pack: Option<u32>,
}

/// Builds `mesh` on the GPU (arrays split at `max_buffer` bytes when given) and compares it
/// with the CPU builder's structure, bit for bit; returns the most buffers an output array
/// was split over.
fn assert_builds_like_cpu(ctx: &Arc<Context>, mesh: &Arc<Mesh>, layout: Layout, max_buffer: Option<u64>) -> usize {
    let Layout { max_leaf, walk, pack } = layout;
    let (pack_min_bits, pack) = (pack.unwrap_or(0), pack.is_some());
    let boxes = crate::kernels::prim_boxes(mesh);
    let label = format!(
        "{} ({} tets), leaf {max_leaf}, walk {walk}, pack {pack}, buffers of {max_buffer:?} B",
        mesh.info.source,
        mesh.n_tets()
    );
    let want = Wanted { max_leaf, grid: true, walk, prims_per_cell: if walk { 1 } else { 4 }, pack, pack_min_bits };
    let (wide, grid, neighbors, parts) = gpu_build(ctx, mesh, want, max_buffer);
    wide.validate(&boxes).unwrap_or_else(|e| panic!("{label}: the GPU tree is invalid: {e}"));

    let (cpu, cpu_grid) = crate::kernels::soft_bvh::host_tree(mesh, &want, &mut |_, _| {}).unwrap();
    assert_eq!((wide.direct, wide.depth), (cpu.direct, cpu.depth), "{label}");
    assert_eq!(wide.nodes.len(), cpu.nodes.len(), "{label}: node count");
    if let Some(i) = (0..cpu.nodes.len()).find(|&i| wide.nodes[i] != cpu.nodes[i]) {
        panic!("{label}: node {i} differs:\n gpu {:?}\n cpu {:?}", wide.nodes[i], cpu.nodes[i]);
    }
    assert_eq!(wide.prims, cpu.prims, "{label}: leaf prims");
    let cpu_grid = cpu_grid.expect("asked for");
    let words = cpu_grid.words();
    let grid = grid.expect("asked for");
    assert_eq!(grid.len(), words.len(), "{label}: grid size");
    if let Some(i) = (0..words.len()).find(|&i| grid[i] != words[i]) {
        panic!("{label}: grid word {i} of {}: gpu {} cpu {}", words.len(), grid[i], words[i]);
    }
    if walk {
        assert_eq!(neighbors.as_deref(), Some(mesh.neighbors()), "{label}: neighbours");
    }
    parts
}

/// Streamed uploads: split buffers and chunked batches give the same answers. With buffers
/// of a few KiB (a test hook), every build array that grows with the mesh is split over
/// several buffers, as at a billion tets on a 4 GiB-buffer device: the GPU build still makes
/// the CPU's structure bit for bit, and a locator built that way (mesh, structure and its
/// build split, host batches in small chunks) answers as the CPU-built one with whole buffers.
#[test]
fn streamed_uploads_split_buffers_and_chunked_batches_give_the_same_answers() {
    let Some(ctx) = test_context("streamed_uploads_split_buffers_and_chunked_batches_give_the_same_answers") else {
        return;
    };
    let meshes = [
        Mesh::new(gen::generate(Shape::Jets, 12_000, 5), "jets").unwrap(),
        Mesh::new(
            gen::generate_spec(gen::Spec { shape: Shape::Fusion, cells: CellKind::Hybrid }, 2_000, 1, &|_| {}),
            "fusion-hybrid",
        )
        .unwrap(),
    ];
    for mesh in meshes {
        let mesh = Arc::new(mesh);
        // About 6 B a tet a buffer: the binary boxes (48 B a prim) and faces (48 B a tet) in
        // about 8 buffers, keys (16) in 3, nodes and neighbours (16) in 3: within MAX_CHUNKS
        // (the mixed mesh's per-prim arrays, a prim a cell, are smaller still).
        let limit = (6 * mesh.n_tets() as u64).next_multiple_of(192);
        for (max_leaf, walk) in [(1, true), (4, true)] {
            let parts = assert_builds_like_cpu(&ctx, &mesh, Layout { max_leaf, walk, pack: None }, Some(limit));
            assert!(parts >= 2, "{}: the structure was not split ({parts} buffers)", mesh.info.source);
        }
    }

    let mesh = Arc::new(Mesh::new(gen::generate(Shape::Agulhas, 8_000, 4), "agulhas").unwrap());
    let mut points = queries::generate(&mesh, QueryKind::Bbox, 12_000, 99);
    points.extend(mesh.points.iter().copied());
    let split = LocatorOptions {
        chunk_points: 1000,
        test_hooks: TestHooks {
            max_buffer_bytes: Some((6 * mesh.n_tets() as u64).next_multiple_of(192)),
            ..LocatorOptions::default().test_hooks
        },
        ..LocatorOptions::default()
    };
    let whole = LocatorOptions {
        soft_bvh: SoftBvhOptions { build: BuildOn::Cpu, ..LocatorOptions::default().soft_bvh },
        ..LocatorOptions::default()
    };
    let mut answers = vec![];
    for opts in [split, whole] {
        let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), Kernel::SoftBvh, opts.clone()).unwrap();
        let on_gpu = loc.build_stages().iter().all(|(s, _)| !s.starts_with("gpu build:") && !s.starts_with("cpu:"));
        assert_eq!(on_gpu, opts.soft_bvh.build == BuildOn::Gpu, "{:?}", loc.build_stages());
        let split_parts = |name: &str| loc.memory_report().items.iter().filter(|m| m.name.starts_with(name)).count();
        if opts.soft_bvh.build == BuildOn::Gpu {
            assert!(split_parts("bvh nodes") > 1 && split_parts("tet neighbours") > 1, "the structure is not split");
        }
        let mut ids = vec![0; points.len()];
        loc.locate(&points, &mut ids).unwrap();
        answers.push(ids);
    }
    assert!(answers[0].iter().filter(|&&t| t >= 0).count() > points.len() / 3, "too few points inside");
    assert_eq!(answers[0], answers[1], "ids with split buffers and chunks against whole buffers");
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors (printed above)");
}

/// Locators built on the GPU and on the CPU give the same ids and values on random points,
/// tet centres and every vertex (points on faces and edges included).
#[test]
fn gpu_built_locator_answers_like_cpu_built() {
    let Some(ctx) = test_context("gpu_built_locator_answers_like_cpu_built") else { return };
    let mesh = Arc::new(Mesh::new(gen::generate(Shape::Agulhas, 15_000, 2), "agulhas").unwrap());
    let mut points = queries::generate(&mesh, QueryKind::Bbox, 20_000, 12345);
    points.extend((0..mesh.n_tets()).step_by(3).map(|t| mesh.tet_center(t)));
    points.extend(mesh.points.iter().copied());
    let field = mesh.fields.first().map(|f| f.name.clone());
    let mut answers = vec![];
    for build in [BuildOn::Gpu, BuildOn::Cpu] {
        let mut opts = LocatorOptions::default();
        opts.soft_bvh.build = build;
        let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), Kernel::SoftBvh, opts).unwrap();
        let built_on = |on: BuildOn| loc.build_stages().iter().any(|(s, _)| s.starts_with(&format!("{on}:")));
        assert!(built_on(build) && !built_on(if build == BuildOn::Gpu { BuildOn::Cpu } else { BuildOn::Gpu }));
        let mut ids = vec![0; points.len()];
        loc.locate(&points, &mut ids).unwrap();
        let mut values = vec![0f32; points.len()];
        if let Some(f) = &field {
            loc.sample(&points, f, &mut values).unwrap();
        }
        answers.push((ids, values));
    }
    let inside = answers[0].0.iter().filter(|&&t| t >= 0).count();
    assert!(inside > points.len() / 3, "{inside} of {} points inside: the test needs more", points.len());
    assert_eq!(answers[0].0, answers[1].0, "ids of GPU-built and CPU-built soft-bvh");
    let same = answers[0].1.iter().zip(&answers[1].1).all(|(a, b)| a.to_bits() == b.to_bits());
    assert!(same, "values of GPU-built and CPU-built soft-bvh");
    assert_eq!(ctx.validation_errors(), 0, "Vulkan validation errors (printed above)");
}
