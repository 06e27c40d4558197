#version 460
// rt-bvh: hands the intersection shader's result to the ray generation shader.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_tracing : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/rt.glsl"

layout(location = 0) rayPayloadInEXT TlPayload pl;
hitAttributeEXT TlPayload hit;

void main() {
    pl = hit;
}
