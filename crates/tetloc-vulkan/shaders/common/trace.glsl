// Locating one point by tracing a ray from it through the kernel's hit groups (rt-bvh,
// rt-rep-faces, rt-shared-faces): what the ray generation shaders share. Needs
// interface.glsl and rt.glsl first.
#ifndef TL_TRACE_GLSL
#define TL_TRACE_GLSL

layout(binding = TL_B_ACCEL) uniform accelerationStructureEXT tl_tlas;
layout(location = 0) rayPayloadEXT TlPayload pl;

// The tet containing p (TL_OUTSIDE outside) and, unless OUTPUT_MODE is ids, the field value there
// (NaN outside).
int tl_trace(vec3 p, out float value) {
    pl.tet = TL_MISS;
    pl.value = uintBitsToFloat(0x7fc00000u);
    traceRayEXT(tl_tlas, RAY_FLAGS, 0xff, 0, 0, 0, p, params.lo_tmin.w, params.dir.xyz, params.hi_tmax.w, 0);
    // No tet found: outside the mesh, or a ray that leaked through an edge (a hardware
    // triangle test that is not watertight) or hit one of two coincident faces (a seam of
    // duplicated vertices). The opposite direction meets other edges and faces.
    if (RETRY_ON_MISS && pl.tet == TL_MISS) {
        traceRayEXT(tl_tlas, RAY_FLAGS, 0xff, 0, 0, 0, p, params.lo_tmin.w, -params.dir.xyz, params.hi_tmax.w, 0);
    }
    value = pl.tet >= 0 ? pl.value : uintBitsToFloat(0x7fc00000u);
    return max(pl.tet, TL_OUTSIDE);
}

#endif
