#version 460
// The ray hit nothing: say so, so that the ray generation shader can retry.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_tracing : require
#include "common/types.glsl"
#include "common/rt.glsl"

layout(location = 0) rayPayloadInEXT TlPayload pl;

void main() {
    pl.tet = TL_MISS;
}
