// What the ray-tracing stages share: the payload, and the per-instance base index that
// turns (instance, primitive) into an index of the kernel's primitive table.
#ifndef TL_RT_GLSL
#define TL_RT_GLSL

// The value is interpolated by the ray generation shader (common/trace.glsl), not carried.
struct TlPayload {
    int tet; // containing tet, TL_OUTSIDE outside, TL_MISS when the ray hit nothing
    uint tie; // rt-bvh: 1 when the tet holds the point on its boundary (a tie: trace.glsl)
};

layout(std430, binding = TL_B_INSTANCES) readonly buffer TlInstances { uint tl_instance_base[]; };

#endif
