//! Options that must not change answers: pre-splitting, compaction, chunking, leaf size; and
//! the pure-f32 test, which may differ only at points within rounding of a face.

mod common;

use std::sync::Arc;
use tetloc_core::geom::Vec3;
use tetloc_core::{BatchLocator, CpuLocator, Mesh};
use tetloc_testdata::{query_sets, require_data};
use tetloc_vulkan::{
    BuildOn, Kernel, LocatorOptions, MemKind, QueryKind, RtOptions, SoftBvhOptions, TestHooks, VulkanLocator,
};

fn answers(loc: &mut VulkanLocator, points: &[Vec3]) -> (Vec<i32>, Vec<u32>) {
    let mut ids = vec![0; points.len()];
    loc.locate(points, &mut ids).unwrap();
    let mut f = vec![0f32; points.len()];
    loc.sample(points, "f", &mut f).unwrap();
    (ids, f.iter().map(|v| v.to_bits()).collect())
}

/// Random points in random tets plus points in the bounding box (many outside).
fn test_points(mesh: &Mesh, n: usize) -> Vec<Vec3> {
    let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
    let mut s = 12345u64;
    let mut unit = || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..n)
        .map(|i| {
            if i % 2 == 0 {
                let c = mesh.tet_center(i * 7919 % mesh.n_tets());
                let t = mesh.tets[i * 104729 % mesh.n_tets()];
                let v = mesh.points[t[i % 4] as usize];
                let w = unit();
                std::array::from_fn(|k| c[k] * (1.0 - w) + v[k] * w * 0.999)
            } else {
                std::array::from_fn(|k| lo[k] + (hi[k] - lo[k]) * (unit() * 1.2 - 0.1))
            }
        })
        .collect()
}

#[test]
fn split_compaction_chunks_and_leaves_do_not_change_answers() {
    let name = "split_compaction_chunks_and_leaves_do_not_change_answers";
    let Some(ctx) = common::context(name) else { return };
    let mesh = common::jets(20_000, 3);
    let points = test_points(&mesh, 30_000);
    let mut cpu = vec![0; points.len()];
    CpuLocator::new(mesh.clone()).locate(&points, &mut cpu).unwrap();
    for k in common::kernels(&ctx, name) {
        let base = LocatorOptions::default();
        let mut variants = vec![
            ("default", base.clone()),
            ("chunks of 997 points", LocatorOptions { chunk_points: 997, ..base.clone() }),
        ];
        if k == Kernel::SoftBvh {
            variants.push((
                "up to four tets per leaf",
                common::soft_bvh(SoftBvhOptions { leaf_size: 4, ..base.clone().soft_bvh }),
            ));
            variants.push((
                "traversal from the root",
                common::soft_bvh(SoftBvhOptions { walk_start: false, ..base.clone().soft_bvh }),
            ));
            variants.push((
                "entry grid",
                common::soft_bvh(SoftBvhOptions { grid_start: true, walk_start: false, ..base.clone().soft_bvh }),
            ));
            let grid4 = common::soft_bvh(SoftBvhOptions {
                grid_start: true,
                walk_start: false,
                leaf_size: 4,
                ..base.clone().soft_bvh
            });
            variants.push(("entry grid, four per leaf", grid4));
            let coarse = LocatorOptions {
                chunk_points: 997,
                soft_bvh: SoftBvhOptions { walk_start: true, grid_tets_per_cell: 3, ..base.clone().soft_bvh },
                ..base.clone()
            };
            variants.push(("walk start, 3 tets a cell, chunks of 997", coarse));
            // The named layouts (compact: walk start, four per leaf, 4 tets a cell; both pack
            // their ids), packed ids on their own (direct leaves: no prims) and built on the CPU.
            for p in ["compact", "small"] {
                variants.push((p, LocatorOptions::preset(p).expect("a preset")));
            }
            variants.push(("packed ids", LocatorOptions { pack_ids: true, ..base.clone() }));
            // 27 bits a field: tets and neighbours read as five-word records.
            let wide = LocatorOptions {
                pack_ids: true,
                test_hooks: TestHooks { pack_min_bits: 27, ..LocatorOptions::preset("compact").unwrap().test_hooks },
                ..LocatorOptions::preset("compact").unwrap()
            };
            variants.push(("compact, 27-bit ids", wide));
            let compact_cpu = LocatorOptions {
                soft_bvh: SoftBvhOptions { build: BuildOn::Cpu, ..LocatorOptions::preset("compact").unwrap().soft_bvh },
                ..LocatorOptions::preset("compact").unwrap()
            };
            variants.push(("compact, built on the CPU", compact_cpu));
            variants.push((
                "walk start, f32 first",
                common::soft_bvh(SoftBvhOptions { walk_start: true, f32_first: true, ..base.clone().soft_bvh }),
            ));
            variants.push((
                "root, f32 first",
                common::soft_bvh(SoftBvhOptions { walk_start: false, f32_first: true, ..base.clone().soft_bvh }),
            ));
            variants.push((
                "deferred exact tests",
                common::soft_bvh(SoftBvhOptions { defer_exact: true, ..base.clone().soft_bvh }),
            ));
            let defer_root = LocatorOptions {
                chunk_points: 997,
                soft_bvh: SoftBvhOptions { defer_exact: true, walk_start: false, ..base.clone().soft_bvh },
                ..base.clone()
            };
            variants.push(("deferred exact tests, root, chunks of 997", defer_root));
        } else {
            variants.push((
                "split 5000, compacted",
                LocatorOptions { rt: RtOptions { split: Some(5000), ..base.clone().rt }, ..base.clone() },
            ));
            variants.push((
                "split 5000, not compacted",
                LocatorOptions { rt: RtOptions { split: Some(5000), compact: false }, ..base.clone() },
            ));
            variants.push((
                "one BLAS, not compacted",
                LocatorOptions { rt: RtOptions { split: None, compact: false }, ..base.clone() },
            ));
            variants.push(("packed ids", LocatorOptions { pack_ids: true, ..base.clone() }));
            variants.push((
                "31-bit ids",
                LocatorOptions {
                    pack_ids: true,
                    test_hooks: TestHooks { pack_min_bits: 31, ..base.clone().test_hooks },
                    ..base.clone()
                },
            ));
        }
        let mut first: Option<(Vec<i32>, Vec<u32>)> = None;
        for (label, opts) in variants {
            let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), k, opts.clone()).unwrap();
            let got = answers(&mut loc, &points);
            common::check_ids(&format!("{k} {label}"), &mesh, &points, &got.0, &cpu);
            let m = loc.memory_report();
            assert!(
                m.final_bytes > 0 && m.final_bytes <= m.peak_bytes,
                "{k} {label}: final {} peak {}",
                m.final_bytes,
                m.peak_bytes
            );
            let tets = if opts.pack_ids { "mesh tets (packed)" } else { "mesh tets" };
            assert!(m.items.iter().any(|i| i.name == tets && i.kind == MemKind::Mesh), "{k} {label}: no {tets}");
            if opts.pack_ids && k == Kernel::SoftBvh && opts.soft_bvh.walk_start {
                assert!(m.items.iter().any(|i| i.name == "tet neighbours (packed)"), "{k} {label}");
            }
            if let Some(a) = m.accel {
                // rep-faces keeps a tet's four triangles together: groups hold split / 4 tets.
                let per_item = if k == Kernel::RtRepFaces { 4 } else { 1 };
                let want_blas = opts.rt.split.map_or(1, |s| (a.primitives / per_item).div_ceil(s / per_item));
                assert_eq!(a.blas_count, want_blas, "{k} {label}");
                assert!(a.blas_bytes <= a.blas_bytes_built && a.tlas_bytes > 0, "{k} {label}: {a:?}");
                if !opts.rt.compact {
                    assert_eq!(a.blas_bytes, a.blas_bytes_built);
                }
                // The uncompacted structures and the build scratch were alive at the peak.
                assert!(m.peak_bytes >= m.final_bytes + a.blas_bytes_built - a.blas_bytes, "{k} {label}");
            }
            println!("{k} {label}: final {} B, peak {} B, accel {:?}", m.final_bytes, m.peak_bytes, m.accel);
            match &first {
                None => first = Some(got),
                Some(f) => {
                    assert!(f.0 == got.0, "{k} {label}: ids differ from the default options");
                    assert!(f.1 == got.1, "{k} {label}: values differ from the default options");
                }
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}

/// The pure-f32 test (for devices without shaderFloat64) agrees with the oracle except at
/// points within rounding of a face, and loses no point inside the mesh.
#[test]
fn pure_f32_test_agrees_outside_ambiguous_points() {
    let name = "pure_f32_test_agrees_outside_ambiguous_points";
    let Some(dir) = require_data(name) else { return };
    let Some(ctx) = common::context(name) else { return };
    let sets: Vec<_> = query_sets(&dir).into_iter().filter(|s| s.label.starts_with("delaunay_s.")).collect();
    let mesh = Arc::new(tetloc_io::read_mesh(&sets[0].mesh_path, None).unwrap());
    for k in common::kernels(&ctx, name) {
        let mut loc =
            VulkanLocator::new(ctx.clone(), mesh.clone(), k, LocatorOptions { float64: false, ..Default::default() })
                .unwrap();
        assert!(!loc.uses_float64());
        for s in &sets {
            let mut ids = vec![0; s.points.len()];
            loc.locate(&s.points, &mut ids).unwrap();
            let wrong = (0..ids.len()).filter(|&i| ids[i] != s.cell[i] && !s.ambiguous(i)).count();
            assert_eq!(wrong, 0, "{k} {}: {wrong} unambiguous points differ from the oracle", s.label);
            if !s.label.ends_with(".bbox") {
                assert!(ids.iter().all(|&t| t >= 0), "{k} {}: a point inside came back outside", s.label);
            }
        }
    }
    common::assert_no_validation_errors(&ctx);
}

#[test]
fn bad_input_gives_errors() {
    let name = "bad_input_gives_errors";
    let Some(ctx) = common::context(name) else { return };
    let mesh = common::jets(2000, 1);
    let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), Kernel::SoftBvh, LocatorOptions::default()).unwrap();
    let pts = [[0.5f32; 3]; 4];
    let mut ids = vec![0; 3];
    assert!(matches!(loc.locate(&pts, &mut ids), Err(tetloc_core::Error::Invalid(_))));
    let mut v = vec![0f32; 4];
    assert!(matches!(loc.sample(&pts, "no such field", &mut v), Err(tetloc_core::Error::NoSuchField { .. })));
    loc.locate(&[], &mut []).unwrap();
    let bad = LocatorOptions { chunk_points: 0, ..Default::default() };
    assert!(VulkanLocator::new(ctx.clone(), mesh, Kernel::SoftBvh, bad).is_err());
    assert!(matches!(tetloc_vulkan::Context::new(Some(1000)), Err(tetloc_vulkan::VkError::BadDeviceIndex { .. })));
    assert_eq!("rt-shared-faces".parse::<Kernel>(), Ok(Kernel::RtSharedFaces));
    assert!("rt-faces".parse::<Kernel>().unwrap_err().contains("soft-bvh, rt-bvh, rt-rep-faces, rt-shared-faces"));
    let e: tetloc_core::Error = tetloc_vulkan::VkError::NoDevice.into();
    assert!(matches!(e, tetloc_core::Error::Backend { .. }) && e.to_string().starts_with("vulkan: "));
    common::assert_no_validation_errors(&ctx);
}

/// Arrays larger than the device's buffer limit are split over several buffers: forced here
/// with a tiny limit (`max_buffer_bytes`), answers and generated samples must not change.
#[test]
fn arrays_split_over_buffers_give_the_same_answers() {
    let name = "arrays_split_over_buffers_give_the_same_answers";
    let Some(ctx) = common::context(name) else { return };
    let mesh = common::jets(20_000, 3);
    let points = test_points(&mesh, 20_000);
    let point_bytes = mesh.points.len() as u64 * 12;
    for k in common::kernels(&ctx, name) {
        // soft-bvh: every array split, the points in two; rt: the points must stay whole.
        let max = if k == Kernel::SoftBvh { point_bytes * 9 / 10 } else { point_bytes + 64 };
        let mut variants = vec![("default", LocatorOptions::default())];
        if k == Kernel::SoftBvh {
            variants.extend([
                ("root traversal", common::soft_bvh(SoftBvhOptions { walk_start: false, ..Default::default() })),
                ("four per leaf", common::soft_bvh(SoftBvhOptions { leaf_size: 4, ..Default::default() })),
            ]);
        }
        for (label, opts) in variants {
            let mut whole = VulkanLocator::new(ctx.clone(), mesh.clone(), k, opts.clone()).unwrap();
            let split_opts = LocatorOptions {
                test_hooks: TestHooks { max_buffer_bytes: Some(max), ..opts.test_hooks.clone() },
                ..opts
            };
            let mut split = VulkanLocator::new(ctx.clone(), mesh.clone(), k, split_opts).unwrap();
            let names: Vec<String> = split.memory_report().items.iter().map(|i| i.name.clone()).collect();
            let parts = |array: &str| names.iter().filter(|n| n.starts_with(array)).count();
            assert!(parts("mesh tets") >= 5, "{k} {label}: tets in {} buffers: {names:?}", parts("mesh tets"));
            if k == Kernel::SoftBvh {
                assert_eq!(parts("mesh points"), 2, "{k} {label}: {names:?}");
                assert!(parts("bvh nodes") >= 2, "{k} {label}: {names:?}");
            }
            assert!(
                answers(&mut whole, &points) == answers(&mut split, &points),
                "{k} {label}: answers changed by splitting"
            );
            for mode in [QueryKind::Centers, QueryKind::Random] {
                let a = whole.locate_generated(mode, 5000, 11).unwrap();
                let b = split.locate_generated(mode, 5000, 11).unwrap();
                assert!(a == b, "{k} {label}: {} samples changed by splitting", mode.name());
                assert!(b.1.iter().all(|&t| t >= 0), "{k} {label}: a {} sample was lost", mode.name());
            }
        }
        // Too large even for 16 buffers: a clear error, not a crash.
        let tiny = LocatorOptions {
            test_hooks: TestHooks { max_buffer_bytes: Some(1024), ..Default::default() },
            ..Default::default()
        };
        let e =
            VulkanLocator::new(ctx.clone(), mesh.clone(), k, tiny).err().expect("1 KiB buffers cannot hold the mesh");
        assert!(e.to_string().contains("16 buffers"), "{k}: {e}");
    }
    common::assert_no_validation_errors(&ctx);
}
