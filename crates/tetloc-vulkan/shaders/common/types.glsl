// GPU-side types and interface numbers, mirrored in src/gpu_types.rs (a unit test there
// checks that the #defines below match the Rust constants).
#ifndef TL_TYPES_GLSL
#define TL_TYPES_GLSL

// Descriptor bindings (set 0).
#define TL_B_POINTS 0
#define TL_B_TETS 1
#define TL_B_FIELD 2
#define TL_B_QUERIES 3
#define TL_B_OUT 4
#define TL_B_ACCEL 5
#define TL_B_PRIMS 6
#define TL_B_INSTANCES 7
#define TL_B_NEIGHBORS 8
#define TL_B_GRID 9
// Volume ray marcher (march.glsl).
#define TL_B_MARCH 10
#define TL_B_TF 11
#define TL_B_OCCUPANCY 12
#define TL_B_SURFACE 13
#define TL_B_PIXELS 14
// Arrays split over several buffers (mesh.glsl): buffers 1.. of points, tets, soft-bvh
// nodes and neighbours, each binding an array of TL_MAX_CHUNKS - 1 buffers.
#define TL_B_POINTS_HI 16
#define TL_B_TETS_HI 17
#define TL_B_ACCEL_HI 18
#define TL_B_NEIGHBORS_HI 19
#define TL_MAX_CHUNKS 16
// soft-bvh with deferred exact tests: the samples the f32 pass could not decide.
#define TL_B_DEFER 20

// Where sample points come from (specialization constant SAMPLE_MODE).
#define TL_SAMPLE_HOST 0
#define TL_SAMPLE_UNIFORM 1
#define TL_SAMPLE_RANDOM 2
#define TL_SAMPLE_BBOX 3

// What a kernel writes per point (specialization constant OUTPUT_MODE).
#define TL_OUT_IDS 0
#define TL_OUT_VERTEX 1
#define TL_OUT_CELL 2

// soft-bvh child references: interior nodes are plain indices; leaves have bit 31 set,
// (count - 1) in bits 29..30 and the first index into the prims array in bits 0..28.
#define TL_LEAF 0x80000000u
#define TL_EMPTY 0xFFFFFFFFu

// Payload value for "the ray hit nothing" (distinct from -1, "hit, but outside").
#define TL_MISS (-2)

// Specialization constants shared by every kernel (ids match src/gpu_types.rs SC_*).
layout(constant_id = 0) const int SAMPLE_MODE = TL_SAMPLE_HOST;
layout(constant_id = 1) const int OUTPUT_MODE = TL_OUT_IDS;
// Also write each generated sample point to the queries buffer (tests check them on the CPU).
layout(constant_id = 2) const bool RECORD_POINTS = false;
// Set from tetloc_core::geom at pipeline creation, so the bits are the CPU's.
layout(constant_id = 3) const float ORIENT_ERR_BOUND_F32 = 4.2e-7;
layout(constant_id = 4) const float BARY_F32_TRUST = 1024.0;
// soft-bvh: traversal stack entries (3 x tree depth + 1, from the build).
layout(constant_id = 5) const uint STACK_SIZE = 64;
// rt-*-faces: most tets visited when the closest hit's tet is off by rounding.
layout(constant_id = 6) const int WALK_MAX = 16;
// rt raygen: ray flags, and whether a ray that hits nothing is retried in the opposite direction.
layout(constant_id = 8) const uint RAY_FLAGS = 0;
layout(constant_id = 9) const bool RETRY_ON_MISS = false;

// Push constants (src/gpu_types.rs `Params`, 64 bytes).
layout(push_constant) uniform Params {
    uvec4 counts;   // points in this launch, global index of its first point, tets, seed
    vec4 lo_tmin;   // mesh bounding box min, ray tmin
    vec4 hi_tmax;   // mesh bounding box max, ray tmax
    vec4 dir;       // ray direction (xyz)
} params;

#endif
