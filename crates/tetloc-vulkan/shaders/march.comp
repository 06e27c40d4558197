#version 460
// The volume ray marcher on soft-bvh, one invocation per pixel in 8x8 tiles. Consecutive
// samples along a ray are about a tet apart, so each sample is found by a short walk through
// face neighbours from the previous sample's tet; only when the walk fails (the ray left the
// mesh, or the walk ran out of steps) does the full BVH traversal run. Both end in the same
// watertight point-in-tet test, so the answer is exact either way.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "common/tet.glsl"
#include "common/soft_bvh.glsl"
#include "common/walk.glsl"
#include "common/march.glsl"

layout(local_size_x = TL_MARCH_TILE, local_size_y = TL_MARCH_TILE) in;

// The tet of this ray's previous sample (TL_OUTSIDE: none, or outside the mesh).
int tl_prev_tet = TL_OUTSIDE;

float tl_march_sample(vec3 p) {
    uvec4 ids;
    vec4 bary;
    int tet = tl_prev_tet >= 0 ? tl_walk(tl_prev_tet, p, WALK_MAX, ids, bary) : TL_OUTSIDE;
    // On a face: the search's tie rule (a cell field differs between the tets).
    if (tet < 0 || !all(greaterThan(bary, vec4(0.0)))) {
        tet = tl_locate(p, ids, bary);
    }
    tl_prev_tet = tet;
    return tl_value(tet, ids, bary, p);
}

void main() {
    tl_march(gl_GlobalInvocationID.xy);
}
