//! The point-location kernels, one module each: `soft_bvh` (a compute shader), and under
//! `rt/` the ray-tracing kernels with their shared setup. Each kernel builds its search
//! structure on the device and returns a [`Plan`]: everything the locator, the volume marcher
//! and the benchmarks need to run it, so that none of them asks which kernel it is. A new
//! kernel is a new module and one line in `kernels!` below.

pub(crate) mod rt;
pub(crate) mod soft_bvh;

pub use rt::RtOptions;
pub use soft_bvh::{BuildOn, SoftBvhOptions, GRID_TETS_PER_CELL, PRESETS};

use crate::device::{Device, Split};
use crate::error::VkResult;
use crate::pipeline::{Binding, Program, Spec};
use rt::AsReport;
use std::str::FromStr;
use std::sync::Arc;
use tetloc_core::bvh::Aabb;
use tetloc_core::geom::Vec3;
use tetloc_core::mesh::Mesh;
use tetloc_core::named::Unknown;

/// A kernel as the registry knows it.
pub(crate) struct KernelDef {
    /// The name on the command line and in reports.
    pub name: &'static str,
    /// Needs ray-tracing pipelines; then it builds from the vertex buffer (uploaded with
    /// acceleration-structure build-input usage).
    pub ray_tracing: bool,
    /// On a mixed mesh, its BVH holds one box a cell (`CELL_BOXES`, [`n_prims`]): the
    /// locator uploads the cells' first tets for it.
    pub cell_boxes: bool,
    /// Builds the kernel's structure for a mesh on the device.
    pub plan: fn(&mut Device, &Inputs) -> VkResult<Plan>,
}

/// What a kernel builds from: the mesh, on the host and on the device, and the options.
pub(crate) struct Inputs<'a> {
    pub mesh: &'a Arc<Mesh>,
    pub points: &'a Split,
    pub tets: &'a Split,
    /// Bits a field of the packed tets (`crate::packed`; 0: u32x4 tets).
    pub tet_bits: u32,
    /// The mesh's descriptor bindings (vertices, tets, higher-order nodes).
    pub mesh_bindings: &'a [Binding],
    /// The options of each kernel family (a kernel reads its own).
    pub soft_bvh: &'a SoftBvhOptions,
    pub rt: &'a RtOptions,
    /// Ids packed (`LocatorOptions::pack_ids`): in at least this many bits a field.
    pub pack: Option<u32>,
    /// The point-in-tet test runs with its exact f64 fallback.
    pub f64: bool,
    /// The kernel takes one box a cell of this (mixed) mesh: `CELL_BOXES`.
    pub cell_boxes: bool,
}

/// The prims of the kernels that take one box a cell (`KernelDef::cell_boxes`: soft-bvh,
/// rt-bvh): a mixed mesh's cells, else its tets.
pub(crate) fn n_prims(mesh: &Mesh) -> usize {
    mesh.cells.as_ref().map_or(mesh.n_tets(), |c| c.len())
}

/// The tets of prim `p` ([`n_prims`]): tet `p`, or cell `p`'s decomposition tets (the host's
/// `tl_prim_tets`).
pub(crate) fn prim_tets(mesh: &Mesh, p: u32) -> std::ops::Range<usize> {
    match &mesh.cells {
        None => p as usize..p as usize + 1,
        Some(cells) => cells.tets_of(p as usize),
    }
}

/// The box of prim `p`: the union of its tets' boxes (the same min and max as the GPU build's
/// `tl_prim_box`, in any order).
pub(crate) fn prim_box(mesh: &Mesh, p: u32) -> Aabb {
    let tet_box = |t: usize| Aabb::of_tet(mesh.tets[t], &mesh.points);
    prim_tets(mesh, p).map(tet_box).reduce(|a, b| a.union(&b)).expect("a prim has tets")
}

/// Every prim's box, in parallel.
pub(crate) fn prim_boxes(mesh: &Mesh) -> Vec<Aabb> {
    use rayon::prelude::*;
    (0..n_prims(mesh) as u32).into_par_iter().map(|p| prim_box(mesh, p)).collect()
}

/// A kernel's structure on the device and how to run it.
pub(crate) struct Plan {
    /// What the structure owns (buffers, acceleration structures); only held: `bindings`
    /// name it.
    pub _owned: Box<dyn Send>,
    /// The structure's descriptor bindings (the mesh's, the field's and the queries' are the
    /// locator's).
    pub bindings: Vec<Binding>,
    /// The kernel's specialization constants, for the locate and the march pipelines.
    pub spec: Spec,
    /// The locate pipelines' own constants (on top of `spec`) ...
    pub locate_spec: Spec,
    /// ... and, with deferred exact tests, the exact second pass's, an indirect dispatch over
    /// the samples the first pass deferred (`DEFERRED`).
    pub exact_pass: Option<Spec>,
    /// The shaders that locate points, and the ones that march a frame.
    pub locate: Program,
    pub march: Program,
    /// The shader that traces particles (whole RK4 lines), where the kernel has one.
    pub stream: Option<Program>,
    /// The shader that locates points from a tet near each (a walk, then the search), where
    /// the kernel has one.
    pub hinted: Option<Program>,
    /// The march and stream shaders walk through tet neighbours, which `bindings` lacks: the
    /// marcher and the tracer must bind a table of their own.
    pub march_needs_neighbors: bool,
    /// The rays the rt kernels trace (push constants); unused by compute kernels.
    pub ray: Ray,
    /// Acceleration-structure sizes for the memory report.
    pub accel: Option<AsReport>,
    /// Wall seconds of each stage of the structure's build, in order (the build report).
    pub build_stages: Vec<(String, f64)>,
}

/// A ray's length and unit direction.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Ray {
    pub tmax: f32,
    pub dir: Vec3,
}

impl Ray {
    /// A ray of length `tmax` along `dir` (normalised here).
    pub fn new(tmax: f32, dir: Vec3) -> Ray {
        let norm = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
        Ray { tmax, dir: dir.map(|d| d / norm) }
    }
}

/// The largest extent of the mesh's bounding box (never 0).
pub(crate) fn extent(mesh: &Mesh) -> f32 {
    let (lo, hi) = (mesh.info.bounds_min, mesh.info.bounds_max);
    (0..3).map(|k| hi[k] - lo[k]).fold(0f32, f32::max).max(f32::MIN_POSITIVE)
}

/// Declares the kernels: the public enum and each one's [`KernelDef`], one line a kernel.
macro_rules! kernels {
    ($( $(#[doc = $doc:literal])* $variant:ident => $def:path, )*) => {
        /// The point-location kernels (the four of the paper).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum Kernel {
            $( $(#[doc = $doc])* $variant, )*
        }

        impl Kernel {
            pub const ALL: [Kernel; [$(stringify!($variant)),*].len()] = [$(Kernel::$variant),*];

            pub(crate) fn def(self) -> &'static KernelDef {
                match self {
                    $( Kernel::$variant => &$def, )*
                }
            }
        }
    };
}

kernels! {
    /// BVH traversal and point-in-tet in a compute shader (the paper's cuda-bvh).
    SoftBvh => soft_bvh::KERNEL,
    /// Ray-tracing BVH over one box per tet (or cell), point-in-tet in an intersection shader.
    RtBvh => rt::bvh::KERNEL,
    /// Four inward-facing triangles per tet, closest hit with back faces culled.
    RtRepFaces => rt::rep_faces::KERNEL,
    /// Each unique face once with its two tets, closest hit picks the side.
    RtSharedFaces => rt::shared_faces::KERNEL,
}

impl Kernel {
    pub fn name(self) -> &'static str {
        self.def().name
    }

    /// True for the kernels that need ray-tracing pipelines.
    pub fn needs_ray_tracing(self) -> bool {
        self.def().ray_tracing
    }
}

tetloc_core::display_name!(Kernel);

impl FromStr for Kernel {
    type Err = String;
    fn from_str(s: &str) -> Result<Kernel, String> {
        let unknown = || String::unknown("kernel", s, &Kernel::ALL.map(Kernel::name));
        Kernel::ALL.into_iter().find(|k| k.name() == s).ok_or_else(unknown)
    }
}
