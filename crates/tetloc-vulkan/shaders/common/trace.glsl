// Locating one point by tracing a ray from it through the kernel's hit groups (rt-bvh,
// rt-rep-faces, rt-shared-faces): what the ray generation shaders share. Needs
// interface.glsl and rt.glsl first.
#ifndef TL_TRACE_GLSL
#define TL_TRACE_GLSL

#include "common/mesh.glsl"
#include "common/tet.glsl"
#include "common/walk.glsl"

layout(binding = TL_B_ACCEL) uniform accelerationStructureEXT tl_tlas;
layout(location = 0) rayPayloadEXT TlPayload pl;

// The tet containing p (TL_OUTSIDE outside) and, unless OUTPUT_MODE is ids, its vertices and
// p's barycentrics there (for the values).
int tl_trace(vec3 p, out uvec4 ids, out vec4 bary) {
    pl.tet = TL_MISS;
    pl.tie = 0u;
    traceRayEXT(tl_tlas, RAY_FLAGS, 0xff, 0, 0, 0, p, params.lo_tmin.w, params.dir.xyz, params.hi_tmax.w, 0);
    // No tet found: outside the mesh, or a ray that leaked through an edge (a hardware
    // triangle test that is not watertight) or hit one of two coincident faces (a seam of
    // duplicated vertices). The opposite direction meets other edges and faces.
    if (RETRY_ON_MISS && pl.tet == TL_MISS) {
        traceRayEXT(tl_tlas, RAY_FLAGS, 0xff, 0, 0, 0, p, params.lo_tmin.w, -params.dir.xyz, params.hi_tmax.w, 0);
    }
    int tet = max(pl.tet, TL_OUTSIDE);
    ids = uvec4(0u);
    bary = vec4(0.0);
    if (tet >= 0 && pl.tie != 0u) {
        // rt-bvh found p on the boundary of its tet, where others may hold it too: the tie
        // rule through the neighbours (the face kernels' hit shader settles its ties itself).
        int exit_face;
        tl_point_in_tet(tl_tet(uint(tet)), p, bary, exit_face);
        tet = tl_lowest_holder(tet, bary, p);
    }
    // The values are interpolated by the caller, after the traversal, and not in the hit
    // shaders: there the f64 refinement (REFINE_BARY) raised the registers of the whole
    // traversal (rt-bvh, random points, f64 jets 12M, H200 2026-12-05: 18 % slower than
    // unrefined). The barycentrics are the hit shader's, computed again by the same test.
    if (OUTPUT_MODE != TL_OUT_IDS && tet >= 0) {
        ids = tl_tet(uint(tet));
        int exit_face;
        tl_point_in_tet(ids, p, bary, exit_face);
    }
    return tet;
}

#endif
