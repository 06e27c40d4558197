#version 460
// The ray hit nothing: say so, so that the ray generation shader can retry.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_tracing : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/rt.glsl"

layout(location = 0) rayPayloadInEXT TlPayload pl;

void main() {
    pl.tet = TL_MISS;
}
