//! [`Locator::builder`]: one backend's search structure over a mesh, wrapped in the layers
//! every front end needs, the same way for all of them.

pub mod auto;

use crate::{contexts, Backend, Error, Result};
use auto::AutoChoice;
use std::collections::BTreeMap;
use std::io::Write as _;
use std::sync::Arc;
use std::time::Instant;
use tetloc_core::bvh::{BuildPreset, BvhNode};
use tetloc_core::locate::{CellLocator, F64Values, FiniteOnly, Precision, Tolerance, WithTolerance};
use tetloc_core::{BatchLocator, CpuLocator, Mesh};
use tetloc_vulkan::{Kernel, LocatorOptions, VulkanLocator};

/// The entry point: `Locator::builder(mesh)...build()`.
pub struct Locator;

impl Locator {
    /// A builder over `mesh`: backend `auto`, the best device, f32 values, no tolerance, the
    /// Vulkan kernels' default options, the CPU's search built now, `auto` said on stderr.
    pub fn builder(mesh: Arc<Mesh>) -> LocatorBuilder<'static> {
        LocatorBuilder {
            mesh,
            backend: Backend::Auto,
            device: None,
            precision: Precision::default(),
            tolerance: Tolerance::default(),
            vulkan: LocatorOptions::default(),
            defer_cpu_build: false,
            quiet: false,
            stages: None,
        }
    }
}

/// The options of one locator (see [`Locator::builder`]).
#[derive(Clone)]
pub struct LocatorBuilder<'a> {
    mesh: Arc<Mesh>,
    backend: Backend,
    device: Option<usize>,
    precision: Precision,
    tolerance: Tolerance,
    vulkan: LocatorOptions,
    defer_cpu_build: bool,
    quiet: bool,
    stages: Option<&'a dyn Fn(&'static str)>,
}

/// A wrapper around the backend, in the order they are stacked (each wraps the one before).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layer {
    /// Points with a NaN or infinite coordinate are answered -1 / NaN before any backend sees them.
    FiniteOnly,
    /// Answers in a mixed mesh's tet decomposition become answers on its cells.
    CellLocator,
    /// `precision` f64: the backend's cells, the values interpolated on the host in f64.
    F64Values,
    /// A boundary tolerance above 0: points just outside get the nearest boundary cell.
    WithTolerance,
}

impl Layer {
    pub fn name(self) -> &'static str {
        match self {
            Layer::FiniteOnly => "FiniteOnly",
            Layer::CellLocator => "CellLocator",
            Layer::F64Values => "F64Values",
            Layer::WithTolerance => "WithTolerance",
        }
    }
}

tetloc_core::display_name!(Layer);

/// Memory of a locator: device memory for the GPU kernels, host memory for `cpu`.
#[derive(Clone, Debug, Default)]
pub struct Memory {
    /// "device" or "host".
    pub on: &'static str,
    /// Resident after the build (mesh and search structure).
    pub final_bytes: u64,
    /// Most memory alive at once during the build (GPU: tracked by the backend; cpu: the final
    /// bytes, which a front end with a counting allocator may raise to what it measured).
    pub peak_bytes: u64,
    pub items: BTreeMap<String, u64>,
}

/// The backend itself, unwrapped: for the front ends that use what only it has (the GPU
/// marcher, the benchmarks, the CPU's per-particle tracer).
pub enum BareLocator {
    Cpu(Box<CpuLocator>),
    Vulkan(Box<VulkanLocator>),
}

impl BareLocator {
    pub fn boxed(self) -> Box<dyn BatchLocator + Send> {
        match self {
            BareLocator::Cpu(l) => l,
            BareLocator::Vulkan(l) => l,
        }
    }
}

/// A backend built, before the wrappers ([`LocatorBuilder::build_bare`]).
pub struct Bare {
    pub locator: BareLocator,
    /// The backend built (what `auto` chose, if asked).
    pub backend: Backend,
    /// What `auto` decided and why, when asked for `auto`.
    pub auto: Option<AutoChoice>,
    pub build_seconds: f64,
    pub memory: Memory,
}

/// A locator ready for queries ([`LocatorBuilder::build`]) and what front ends report about it.
pub struct Built {
    /// The backend inside its [`Layer`]s.
    pub locator: Box<dyn BatchLocator + Send>,
    pub backend: Backend,
    pub auto: Option<AutoChoice>,
    pub stack: Vec<Layer>,
    pub build_seconds: f64,
    pub memory: Memory,
}

impl Built {
    /// The backend and its layers, innermost first: `cpu > FiniteOnly > CellLocator`.
    pub fn describe(&self) -> String {
        describe(self.backend, &self.stack)
    }
}

fn describe(backend: Backend, stack: &[Layer]) -> String {
    std::iter::once(backend.name()).chain(stack.iter().map(|l| l.name())).collect::<Vec<_>>().join(" > ")
}

/// Builder methods that only store their argument in its field: `fn name(mut self, field)`.
macro_rules! setters {
    ($( $(#[doc = $doc:literal])* $name:ident($field:ident: $t:ty); )*) => {$(
        $(#[doc = $doc])*
        pub fn $name(mut self, $field: $t) -> Self {
            self.$field = $field;
            self
        }
    )*};
}

impl<'a> LocatorBuilder<'a> {
    setters! {
        backend(backend: Backend);
        /// The Vulkan device index (`None`: the best device).
        device(device: Option<usize>);
        precision(precision: Precision);
        tolerance(tolerance: Tolerance);
        /// The Vulkan kernels' options (presets, rt splits, query ordering, where soft-bvh builds).
        vulkan_options(vulkan: LocatorOptions);
        /// cpu: build the search on first need (a resample's grid may need none; a probe's
        /// batches need the BVH only for points on faces). The build's time and memory then
        /// fall in the first call, not in the build's report.
        defer_cpu_build(defer_cpu_build: bool);
        /// Do not say on stderr what `auto` chose.
        quiet(quiet: bool);
        /// The same options over another mesh (a distributed run's pieces).
        mesh(mesh: Arc<Mesh>);
    }

    /// `stage(name)` is called as each stage of the build starts (for progress bars).
    pub fn stages<'b>(self, stage: &'b dyn Fn(&'static str)) -> LocatorBuilder<'b> {
        LocatorBuilder { stages: Some(stage), ..self }
    }

    /// The layers [`Self::build`] puts around the backend, innermost first.
    pub fn stack(&self) -> Vec<Layer> {
        let mut layers = vec![Layer::FiniteOnly, Layer::CellLocator];
        if self.precision == Precision::F64 {
            layers.push(Layer::F64Values);
        }
        if self.tolerance.distance(&self.mesh) > 0.0 {
            layers.push(Layer::WithTolerance);
        }
        layers
    }

    fn stage(&self, name: &'static str) {
        if let Some(s) = self.stages {
            s(name);
        }
    }

    /// The backend to build: the one asked for, or what `auto` chooses here (and why).
    pub fn resolve(&self) -> Result<(Backend, Option<AutoChoice>)> {
        match self.backend {
            Backend::Auto => {
                self.stage("looking for a Vulkan device");
                let choice = auto::choose(self.device, &self.vulkan, self.quiet)?;
                Ok((choice.backend, Some(choice)))
            }
            b => Ok((b, None)),
        }
    }

    /// The backend alone, without the layers.
    pub fn build_bare(&self) -> Result<Bare> {
        let (backend, auto) = self.resolve()?;
        let (locator, build_seconds, memory) = match backend {
            Backend::Kernel(k) => {
                let loc = self.build_vulkan(k)?;
                let report = loc.memory_report();
                let mut items = BTreeMap::new();
                for item in &report.items {
                    *items.entry(item.name.clone()).or_default() += item.bytes;
                }
                let memory =
                    Memory { on: "device", final_bytes: report.final_bytes, peak_bytes: report.peak_bytes, items };
                let secs = loc.build_seconds();
                (BareLocator::Vulkan(Box::new(loc)), secs, memory)
            }
            _ => {
                let t0 = Instant::now();
                let (loc, memory) = self.build_cpu();
                (BareLocator::Cpu(Box::new(loc)), t0.elapsed().as_secs_f64(), memory)
            }
        };
        Ok(Bare { locator, backend, auto, build_seconds, memory })
    }

    /// The backend in its [`Layer`]s. With `TETLOC_EXPLAIN` set, the stack is said on stderr
    /// (`locator: cpu > FiniteOnly > CellLocator`).
    pub fn build(&self) -> Result<Built> {
        let built = self.build_unexplained()?;
        if std::env::var_os("TETLOC_EXPLAIN").is_some_and(|v| !v.is_empty() && v != "0") {
            let _ = writeln!(std::io::stderr(), "locator: {}", built.describe());
        }
        Ok(built)
    }

    /// [`Self::build`], said nowhere (`auto`'s own measurement).
    pub(crate) fn build_unexplained(&self) -> Result<Built> {
        let bare = self.build_bare()?;
        let stack = self.stack();
        let mesh = &self.mesh;
        let mut loc = bare.locator.boxed();
        for layer in &stack {
            loc = match layer {
                Layer::FiniteOnly => Box::new(FiniteOnly::new(loc)),
                Layer::CellLocator => Box::new(CellLocator::new(loc, mesh.clone())),
                Layer::F64Values => Box::new(F64Values::new(loc, mesh.clone())),
                Layer::WithTolerance => Box::new(WithTolerance::new(loc, mesh.clone(), self.tolerance)),
            };
        }
        Ok(Built {
            locator: loc,
            backend: bare.backend,
            auto: bare.auto,
            stack,
            build_seconds: bare.build_seconds,
            memory: bare.memory,
        })
    }

    /// The CPU's search (BVH, occupancy grid, face neighbours), now or on first need.
    fn build_cpu(&self) -> (CpuLocator, Memory) {
        let mesh = &self.mesh;
        let size = |n: usize, each: usize| (n * each) as u64;
        let mut items = BTreeMap::from([
            ("mesh points".to_string(), size(mesh.points.len(), 12)),
            ("mesh tets".to_string(), size(mesh.n_tets(), 16)),
        ]);
        let loc = if self.defer_cpu_build {
            CpuLocator::deferred(mesh.clone(), BuildPreset::Fast)
        } else {
            self.stage("BVH and face neighbours");
            let loc = CpuLocator::new(mesh.clone());
            items.insert("bvh nodes".to_string(), size(loc.bvh().nodes.len(), std::mem::size_of::<BvhNode>()));
            items.insert("bvh prims".to_string(), size(loc.bvh().prim_ids.len(), 4));
            items.insert("tet neighbours".to_string(), size(mesh.neighbors().len(), 16));
            loc
        };
        let final_bytes = items.values().sum();
        (loc, Memory { on: "host", final_bytes, peak_bytes: final_bytes, items })
    }

    fn build_vulkan(&self, kernel: Kernel) -> Result<VulkanLocator> {
        let backend = kernel.name();
        self.stage("opening the Vulkan device");
        let ctx = contexts::context(self.device).map_err(|e| Error::NoDevice { backend, reason: e.msg })?;
        if kernel.needs_ray_tracing() && !ctx.info().ray_tracing {
            return Err(Error::NoRayTracing { backend, device: ctx.info().name.clone() });
        }
        // No face neighbours on the host here: soft-bvh's default build makes them on the GPU.
        self.stage("search structure on the GPU");
        VulkanLocator::new(ctx, self.mesh.clone(), kernel, self.vulkan.clone())
            .map_err(|source| Error::Vulkan { backend, source })
    }
}
