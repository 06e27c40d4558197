#version 460
// The ray hit nothing: the payload keeps TL_MISS from the ray generation shader.
#extension GL_EXT_ray_tracing : require
struct TlPayload {
    int tet;
    float value;
};
layout(location = 0) rayPayloadInEXT TlPayload pl;

void main() {
    pl.tet = -2; // TL_MISS
}
