// What the ray-tracing stages share: the payload, and the per-instance base index that
// turns (instance, primitive) into an index of the kernel's primitive table.
#ifndef TL_RT_GLSL
#define TL_RT_GLSL

struct TlPayload {
    int tet;     // containing tet, TL_OUTSIDE outside, TL_MISS when the ray hit nothing
    float value; // field value when OUTPUT_MODE != TL_OUT_IDS
};

layout(std430, binding = TL_B_INSTANCES) readonly buffer TlInstances { uint tl_instance_base[]; };

#endif
