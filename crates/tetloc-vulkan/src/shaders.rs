//! SPIR-V compiled by build.rs from `shaders/`, embedded in the library.

macro_rules! spirv {
    ($name:literal) => {
        include_bytes!(concat!(env!("OUT_DIR"), "/", $name, ".spv"))
    };
}

/// One shader in its two precision variants (`TL_F64` defined, or the pure-f32 test).
pub(crate) struct Variants {
    pub f64: &'static [u8],
    pub f32: &'static [u8],
}

impl Variants {
    pub fn pick(&self, f64: bool) -> &'static [u8] {
        if f64 {
            self.f64
        } else {
            self.f32
        }
    }
}

pub(crate) const SOFT_BVH: Variants = Variants { f64: spirv!("soft_bvh_f64"), f32: spirv!("soft_bvh_f32") };
pub(crate) const RT_RGEN: &[u8] = spirv!("rt_rgen");
/// The volume ray marcher: soft-bvh with neighbour walks (compute), and the ray generation
/// shader that runs it on the rt kernels' hit groups.
pub(crate) const MARCH: Variants = Variants { f64: spirv!("march_f64"), f32: spirv!("march_f32") };
pub(crate) const MARCH_RGEN: &[u8] = spirv!("march_rgen");
pub(crate) const RT_RMISS: &[u8] = spirv!("rt_rmiss");
pub(crate) const RT_BVH_RINT: Variants = Variants { f64: spirv!("rt_bvh_rint_f64"), f32: spirv!("rt_bvh_rint_f32") };
pub(crate) const RT_BVH_RCHIT: &[u8] = spirv!("rt_bvh_rchit");
pub(crate) const RT_REP_RCHIT: Variants = Variants { f64: spirv!("rt_rep_rchit_f64"), f32: spirv!("rt_rep_rchit_f32") };
pub(crate) const RT_SHARED_RCHIT: Variants =
    Variants { f64: spirv!("rt_shared_rchit_f64"), f32: spirv!("rt_shared_rchit_f32") };
