//! `tetloc demo`: the main job on a built-in default mesh, on every available backend.

use crate::backend::BackendOptions;
use crate::{bench, mesh_arg};
use anyhow::{bail, Result};
use std::time::Instant;
use tetloc_core::gen::Shape;
use tetloc_core::queries::{self, QueryKind};
use tetloc_core::{geom, BatchLocator};
use tetloc_locator::{Backend, Kernel};

/// Host bytes a query point takes: its coordinates, its ids (and the reference's) and value.
pub const BYTES_PER_POINT: u128 = 12 + 4 + 4 + 4;

pub fn run(n_tets: usize, n_points: usize, seed: u64, all_backends: bool, opts: &BackendOptions) -> Result<()> {
    let mesh = std::sync::Arc::new(mesh_arg::generate(Shape::Fusion, n_tets, seed)?);
    println!("mesh: fusion-like torus, {} tets, {} vertices, field 'f' per vertex", mesh.n_tets(), mesh.points.len());
    let points = queries::generate(&mesh, QueryKind::Random, n_points, seed);
    println!("queries: {} random points inside random tets", points.len());
    let mut reference: Option<(String, Vec<i32>)> = None;
    let mut failures = 0;
    let mut names = tetloc_locator::available(opts.device);
    // On a Vulkan device that runs on the CPU (lavapipe) the ray-tracing kernels are emulated
    // twice over and take minutes on a million points: soft-bvh alone cross-checks the cpu.
    if let (Ok(ctx), false) = (tetloc_locator::context(opts.device), all_backends) {
        if ctx.info().device_type == "cpu" {
            names.retain(|n| matches!(n, Backend::Cpu | Backend::Kernel(Kernel::SoftBvh)));
            println!(
                "Vulkan device {} runs on the CPU: the rt kernels are skipped (--all-backends runs them)",
                ctx.info().name
            );
        }
    }
    for name in names {
        let t0 = Instant::now();
        let (_, builder) = opts.builder(&mesh, name.name())?;
        let mut loc: Box<dyn BatchLocator> = builder.build()?.locator;
        let build = t0.elapsed().as_secs_f64();
        let mut ids = vec![0; points.len()];
        let mut vals = vec![0f32; points.len()];
        // Warm-up: GPU backends compile each variant's pipeline and upload the field on first use.
        loc.locate(&points, &mut ids)?;
        loc.sample(&points, "f", &mut vals)?;
        let t = Instant::now();
        loc.locate(&points, &mut ids)?;
        let locate_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        loc.sample(&points, "f", &mut vals)?;
        let sample_s = t.elapsed().as_secs_f64();
        let outside = ids.iter().filter(|&&i| i < 0).count();
        print!(
            "{:<16} build {build:>6.2} s   locate {:>12}   sample {:>12}   outside {outside}",
            name,
            bench::fmt_rate(points.len() as f64 / locate_s),
            bench::fmt_rate(points.len() as f64 / sample_s)
        );
        if outside > 0 {
            failures += 1;
        }
        match &reference {
            None => {
                println!();
                reference = Some((name.to_string(), ids));
            }
            Some((rname, rids)) => {
                // A different tet is right only when the point is on the face between the two.
                let differ: Vec<usize> = (0..ids.len()).filter(|&i| ids[i] != rids[i]).collect();
                let wrong = differ
                    .iter()
                    .filter(|&&i| {
                        ids[i] < 0 || geom::point_in_tet(mesh.tets[ids[i] as usize], &mesh.points, points[i]).is_none()
                    })
                    .count();
                println!(
                    "   vs {rname}: {} differ ({} on shared faces, {wrong} wrong)",
                    differ.len(),
                    differ.len() - wrong
                );
                if wrong > 0 {
                    failures += 1;
                }
            }
        }
    }
    if failures > 0 {
        bail!("{failures} backend(s) disagreed or lost interior points");
    }
    println!("all backends agree");
    Ok(())
}
