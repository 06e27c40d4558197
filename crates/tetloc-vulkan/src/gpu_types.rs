//! Rust mirror of `shaders/common/types.glsl`: binding numbers, specialization-constant ids,
//! modes, the push-constant block and the soft-bvh node. A test checks the GLSL #defines.

use bytemuck::{Pod, Zeroable};

pub const B_POINTS: u32 = 0;
pub const B_TETS: u32 = 1;
pub const B_FIELD: u32 = 2;
pub const B_QUERIES: u32 = 3;
pub const B_OUT: u32 = 4;
/// soft-bvh nodes, or the top-level acceleration structure.
pub const B_ACCEL: u32 = 5;
/// soft-bvh leaf prims, or the rt kernels' primitive -> tet table.
pub const B_PRIMS: u32 = 6;
pub const B_INSTANCES: u32 = 7;
pub const B_NEIGHBORS: u32 = 8;
/// soft-bvh entry grid.
pub const B_GRID: u32 = 9;
/// Volume ray marcher: parameters, transfer function, occupancy grid, per-pixel surface, pixels out.
pub const B_MARCH: u32 = 10;
pub const B_TF: u32 = 11;
pub const B_OCCUPANCY: u32 = 12;
pub const B_SURFACE: u32 = 13;
pub const B_PIXELS: u32 = 14;
/// Buffers 1.. of arrays split over several buffers (memory::Chunked), each binding an
/// array of MAX_CHUNKS - 1 buffers.
pub const B_POINTS_HI: u32 = 16;
pub const B_TETS_HI: u32 = 17;
pub const B_ACCEL_HI: u32 = 18;
pub const B_NEIGHBORS_HI: u32 = 19;
pub const MAX_CHUNKS: usize = 16;
/// soft-bvh with deferred exact tests: the samples the f32 pass could not decide.
pub const B_DEFER: u32 = 20;

pub const SAMPLE_HOST: i32 = 0;
pub const SAMPLE_UNIFORM: i32 = 1;
pub const SAMPLE_RANDOM: i32 = 2;
pub const SAMPLE_BBOX: i32 = 3;

pub const OUT_IDS: i32 = 0;
pub const OUT_VERTEX: i32 = 1;
pub const OUT_CELL: i32 = 2;

pub const LEAF: u32 = 0x8000_0000;
pub const EMPTY: u32 = 0xFFFF_FFFF;
/// Leaf references keep the first prim index in 29 bits.
pub const LEAF_FIRST_MAX: u32 = (1 << 29) - 1;

/// Specialization-constant ids.
pub const SC_SAMPLE_MODE: u32 = 0;
pub const SC_OUTPUT_MODE: u32 = 1;
pub const SC_RECORD_POINTS: u32 = 2;
pub const SC_ORIENT_ERR_BOUND: u32 = 3;
pub const SC_BARY_F32_TRUST: u32 = 4;
pub const SC_STACK_SIZE: u32 = 5;
pub const SC_WALK_MAX: u32 = 6;
pub const SC_WORKGROUP: u32 = 7;
pub const SC_RAY_FLAGS: u32 = 8;
pub const SC_RETRY_ON_MISS: u32 = 9;
pub const SC_DIRECT_LEAVES: u32 = 10;
pub const SC_GRID_START: u32 = 11;
pub const SC_WALK_START: u32 = 12;
pub const SC_F32_FIRST: u32 = 13;
/// Elements per buffer of split arrays (0: one buffer).
pub const SC_POINTS_CHUNK: u32 = 14;
pub const SC_TETS_CHUNK: u32 = 15;
pub const SC_NODES_CHUNK: u32 = 16;
pub const SC_NEIGHBORS_CHUNK: u32 = 17;
pub const SC_DEFER_EXACT: u32 = 18;
pub const SC_EXACT_PASS: u32 = 19;

/// The push-constant block.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct Params {
    /// Points in this launch, global index of its first point, number of tets, seed.
    pub counts: [u32; 4],
    /// Mesh bounding box min, ray tmin.
    pub lo_tmin: [f32; 4],
    /// Mesh bounding box max, ray tmax.
    pub hi_tmax: [f32; 4],
    /// Ray direction.
    pub dir: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<Params>() == 64);

/// A 4-wide BVH node with child boxes quantized to 8 bits per coordinate relative to the
/// node's box: child box = origin + q * scale (computed without FMA on both sides).
/// Read on the GPU as four uvec4.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct QNode4 {
    pub origin: [f32; 3],
    pub scale: [f32; 3],
    /// Per axis a lower and an upper word, one byte per child: lo_x, hi_x, lo_y, hi_y, lo_z, hi_z.
    pub q: [u32; 6],
    /// Child references: node index, `LEAF | (count - 1) << 29 | first prim`, or `EMPTY`.
    pub child: [u32; 4],
}
const _: () = assert!(std::mem::size_of::<QNode4>() == 64);

#[cfg(test)]
mod tests {
    use super::*;

    /// The GLSL #defines and specialization-constant ids must match the Rust constants.
    #[test]
    fn glsl_interface_matches() {
        let glsl = include_str!("../shaders/common/types.glsl");
        let define = |name: &str| -> i64 {
            let line = glsl
                .lines()
                .find(|l| l.split_whitespace().take(2).eq(["#define", name]))
                .unwrap_or_else(|| panic!("no #define {name} in types.glsl"));
            let v =
                line.split_whitespace().nth(2).unwrap().trim_end_matches('u').trim_matches(|c| c == '(' || c == ')');
            if let Some(hex) = v.strip_prefix("0x") {
                i64::from_str_radix(hex, 16).unwrap()
            } else {
                v.parse().unwrap()
            }
        };
        let constant_id = |name: &str| -> u32 {
            let line = glsl
                .lines()
                .find(|l| l.contains("constant_id") && l.contains(&format!(" {name} ")))
                .unwrap_or_else(|| panic!("no specialization constant {name} in types.glsl"));
            let after = line.split("constant_id = ").nth(1).unwrap();
            after[..after.find(')').unwrap()].parse().unwrap()
        };
        for (name, v) in [
            ("TL_B_POINTS", B_POINTS),
            ("TL_B_TETS", B_TETS),
            ("TL_B_FIELD", B_FIELD),
            ("TL_B_QUERIES", B_QUERIES),
            ("TL_B_OUT", B_OUT),
            ("TL_B_ACCEL", B_ACCEL),
            ("TL_B_PRIMS", B_PRIMS),
            ("TL_B_INSTANCES", B_INSTANCES),
            ("TL_B_NEIGHBORS", B_NEIGHBORS),
            ("TL_B_GRID", B_GRID),
            ("TL_B_MARCH", B_MARCH),
            ("TL_B_TF", B_TF),
            ("TL_B_OCCUPANCY", B_OCCUPANCY),
            ("TL_B_SURFACE", B_SURFACE),
            ("TL_B_PIXELS", B_PIXELS),
            ("TL_B_POINTS_HI", B_POINTS_HI),
            ("TL_B_TETS_HI", B_TETS_HI),
            ("TL_B_ACCEL_HI", B_ACCEL_HI),
            ("TL_B_NEIGHBORS_HI", B_NEIGHBORS_HI),
            ("TL_MAX_CHUNKS", MAX_CHUNKS as u32),
            ("TL_B_DEFER", B_DEFER),
            ("TL_LEAF", LEAF),
            ("TL_EMPTY", EMPTY),
        ] {
            assert_eq!(define(name), v as i64, "{name}");
        }
        for (name, v) in [
            ("TL_SAMPLE_HOST", SAMPLE_HOST),
            ("TL_SAMPLE_UNIFORM", SAMPLE_UNIFORM),
            ("TL_SAMPLE_RANDOM", SAMPLE_RANDOM),
            ("TL_SAMPLE_BBOX", SAMPLE_BBOX),
            ("TL_OUT_IDS", OUT_IDS),
            ("TL_OUT_VERTEX", OUT_VERTEX),
            ("TL_OUT_CELL", OUT_CELL),
        ] {
            assert_eq!(define(name), v as i64, "{name}");
        }
        for (name, id) in [
            ("SAMPLE_MODE", SC_SAMPLE_MODE),
            ("OUTPUT_MODE", SC_OUTPUT_MODE),
            ("RECORD_POINTS", SC_RECORD_POINTS),
            ("ORIENT_ERR_BOUND_F32", SC_ORIENT_ERR_BOUND),
            ("BARY_F32_TRUST", SC_BARY_F32_TRUST),
            ("STACK_SIZE", SC_STACK_SIZE),
            ("WALK_MAX", SC_WALK_MAX),
            ("RAY_FLAGS", SC_RAY_FLAGS),
            ("RETRY_ON_MISS", SC_RETRY_ON_MISS),
        ] {
            assert_eq!(constant_id(name), id, "{name}");
        }
        let comp = include_str!("../shaders/soft_bvh.comp");
        assert!(comp.contains(&format!("local_size_x_id = {SC_WORKGROUP}")));
        let traversal = include_str!("../shaders/common/soft_bvh.glsl");
        assert!(traversal.contains(&format!("constant_id = {SC_DIRECT_LEAVES}) const bool DIRECT_LEAVES")));
        assert!(traversal.contains(&format!("constant_id = {SC_GRID_START}) const bool GRID_START")));
        assert!(traversal.contains(&format!("constant_id = {SC_WALK_START}) const bool WALK_START")));
        let walk = include_str!("../shaders/common/walk.glsl");
        assert!(walk.contains(&format!("constant_id = {SC_F32_FIRST}) const bool F32_FIRST")));
        assert!(walk.contains(&format!("constant_id = {SC_NEIGHBORS_CHUNK}) const uint NEIGHBORS_CHUNK")));
        assert!(walk.contains(&format!("constant_id = {SC_DEFER_EXACT}) const bool DEFER_EXACT")));
        assert!(comp.contains(&format!("constant_id = {SC_EXACT_PASS}) const bool EXACT_PASS")));
        assert!(traversal.contains(&format!("constant_id = {SC_NODES_CHUNK}) const uint NODES_CHUNK")));
        let mesh = include_str!("../shaders/common/mesh.glsl");
        assert!(mesh.contains(&format!("constant_id = {SC_POINTS_CHUNK}) const uint POINTS_CHUNK")));
        assert!(mesh.contains(&format!("constant_id = {SC_TETS_CHUNK}) const uint TETS_CHUNK")));
    }
}
