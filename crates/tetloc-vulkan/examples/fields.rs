//! One location for k fields (issue 28), measured: for 0, 1, 3 and 5 fields (`f`; the flow
//! vector `v`'s 3 components; `f`, `cellval` and `v`), the ids and values of host points end
//! to end (samples/s, the host clock, transfers included) in one launch a batch (what
//! `query` runs) and in the k + 1 launches it replaced (`sample_per_field`), and the kernel
//! time of random points generated in the kernel (GPU timestamps): the one launch, against the
//! ids' launch plus a launch a field. Also checks, on the host points, that both give the
//! same ids and values bit for bit. One JSON object a row on stdout, a table on stderr.
//!
//! cargo run --release -p tetloc-vulkan --example fields -- --tets 12000000
//!
//! Options: --tets N (jets, default 1M), --n N (host points, default one a tet), --kernels
//! a,b (default soft-bvh and every rt kernel the device runs), --repeats R (default 5),
//! --device I, --ks 0,1,3,5.

mod common;

use common::num;
use std::sync::Arc;
use tetloc_core::gen::{flow, generate, Shape};
use tetloc_core::queries::{self, QueryKind};
use tetloc_core::{BatchLocator, Mesh};
use tetloc_vulkan::{BenchOptions, BenchResult, Context, Kernel, LocatorOptions, VulkanLocator};

struct Args {
    tets: usize,
    n: Option<usize>,
    kernels: Option<Vec<Kernel>>,
    repeats: usize,
    device: Option<usize>,
    ks: Vec<usize>,
}

fn parse() -> Result<Args, String> {
    let mut a = Args { tets: 1_000_000, n: None, kernels: None, repeats: 5, device: None, ks: vec![0, 1, 3, 5] };
    common::each_flag(|flag, val| {
        match flag {
            "--tets" => a.tets = num(val()?)?,
            "--n" => a.n = Some(num(val()?)?),
            "--kernels" => a.kernels = Some(val()?.split(',').map(|k| k.parse()).collect::<Result<_, _>>()?),
            "--repeats" => a.repeats = num(val()?)?.max(1),
            "--device" => a.device = Some(num(val()?)?),
            "--ks" => a.ks = val()?.split(',').map(|k| num(k.into())).collect::<Result<_, _>>()?,
            _ => return Err(format!("unknown option {flag} (see the header of examples/fields.rs)")),
        }
        Ok(())
    })?;
    Ok(a)
}

/// The fields of a row of k fields.
fn fields_of(k: usize) -> Vec<String> {
    let all = ["f", "cellval", "v[0]", "v[1]", "v[2]"];
    match k {
        3 => all[2..].iter().map(|s| s.to_string()).collect(),
        k => all.iter().cycle().take(k).map(|s| s.to_string()).collect(),
    }
}

fn row(kernel: &str, k: usize, what: &str, path: &str, r: &BenchResult, bytes: f64) {
    println!(
        "{{\"kernel\":\"{kernel}\",\"fields\":{k},\"what\":\"{what}\",\"path\":\"{path}\",\"samples\":{},\
         \"samples_per_s\":{:.1},\"median_s\":{:.6},\"timing\":\"{}\",\"ordered\":{},\"host_bytes_per_query\":{bytes},\
         \"device\":\"{}\",\"driver\":\"{}\"}}",
        r.samples, r.samples_per_second, r.seconds, r.timing, r.ordered, r.device, r.driver
    );
    eprintln!(
        "{kernel:<16} k={k} {what:<7} {path:<10} {:>10} samples/s  {:>9.3} ms{}",
        tetloc_vulkan::si(r.samples_per_second),
        r.seconds * 1e3,
        if r.ordered { "  (ordered)" } else { "" }
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args = parse()?;
    let ctx = Context::new(args.device)?;
    eprintln!("using [{}] {} ({})", ctx.info().index, ctx.info().name, ctx.info().driver);
    let mut raw = generate(Shape::Jets, args.tets, 1);
    raw.fields.extend(flow::vector_fields(Shape::Jets, &raw.points));
    let mesh = Arc::new(Mesh::new(raw, "jets")?);
    let n = args.n.unwrap_or(mesh.n_tets());
    eprintln!("jets: {} tets, {} vertices; {n} host points", mesh.n_tets(), mesh.points.len());
    println!("{{\"mesh\":\"jets\",\"tets\":{},\"vertices\":{},\"host_points\":{n}}}", mesh.n_tets(), mesh.points.len());
    let host = queries::generate(&mesh, QueryKind::Host, n, 1);
    let kernels = args.kernels.clone().unwrap_or_else(|| {
        Kernel::ALL.into_iter().filter(|k| ctx.info().ray_tracing || !k.needs_ray_tracing()).collect()
    });
    for kernel in kernels {
        let mut loc = VulkanLocator::new(ctx.clone(), mesh.clone(), kernel, LocatorOptions::default())?;
        let name = kernel.name();
        let bench = |loc: &mut VulkanLocator, mode, field: Option<&str>, fields: &[String], per_field| {
            let o = BenchOptions {
                mode,
                field: field.map(String::from),
                fields: fields.to_vec(),
                per_field,
                samples: Some(n),
                repeats: args.repeats,
                ..Default::default()
            };
            loc.bench(&o, Some(&host))
        };
        // The kernel time of a launch a field, reused by every k.
        let ids_kernel = bench(&mut loc, QueryKind::Random, None, &[], false)?;
        let mut single = std::collections::HashMap::new();
        for k in args.ks.iter().copied() {
            let fields = fields_of(k);
            let names: Vec<&str> = fields.iter().map(String::as_str).collect();
            // Host points, end to end.
            let one = bench(&mut loc, QueryKind::Host, None, &fields, false)?;
            row(name, k, "host", "one", &one, (12 + 4 + 4 * k) as f64);
            if k > 0 {
                let per = bench(&mut loc, QueryKind::Host, None, &fields, true)?;
                row(name, k, "host", "per-field", &per, ((k + 1) * 16) as f64);
                // The same answers, bit for bit (on the first million points).
                let m = host.len().min(1 << 20);
                let (mut a, mut va) = (vec![0i32; m], vec![0f32; m * k]);
                let (mut b, mut vb) = (vec![0i32; m], vec![0f32; m * k]);
                loc.sample_many(&host[..m], &names, &mut a, &mut va)?;
                loc.sample_per_field(&host[..m], &names, &mut b, &mut vb)?;
                let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count()
                    + va.iter().zip(&vb).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
                eprintln!("{name:<16} k={k} one launch vs per field on {m} points: {differ} answers differ");
                println!("{{\"kernel\":\"{name}\",\"fields\":{k},\"check_points\":{m},\"answers_differ\":{differ}}}");
            }
            // Random points in the kernel, GPU timestamps.
            let one = match k {
                0 => ids_kernel.clone(),
                _ => bench(&mut loc, QueryKind::Random, None, &fields, false)?,
            };
            row(name, k, "kernel", "one", &one, 0.0);
            if k > 0 {
                let mut seconds = ids_kernel.seconds;
                for f in &fields {
                    if !single.contains_key(f) {
                        single.insert(f.clone(), bench(&mut loc, QueryKind::Random, Some(f), &[], false)?.seconds);
                    }
                    seconds += single[f];
                }
                let per = BenchResult { seconds, samples_per_second: one.samples as f64 / seconds, ..one.clone() };
                row(name, k, "kernel", "per-field", &per, 0.0);
            }
        }
        if ctx.validation_enabled() {
            eprintln!("validation errors: {}", ctx.validation_errors());
        }
    }
    Ok(())
}
