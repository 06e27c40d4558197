// The mesh as the GPU sees it: f32 vertices (3 floats each, tightly packed), canonical
// u32x4 tets, and the scalar field being sampled (per vertex or per cell).
#ifndef TL_MESH_GLSL
#define TL_MESH_GLSL

layout(std430, binding = TL_B_POINTS) readonly buffer TlPoints { float tl_points[]; };
layout(std430, binding = TL_B_TETS) readonly buffer TlTets { uvec4 tl_tets[]; };
layout(std430, binding = TL_B_FIELD) readonly buffer TlField { float tl_field[]; };

vec3 tl_vertex(uint i) {
    return vec3(tl_points[3 * i], tl_points[3 * i + 1], tl_points[3 * i + 2]);
}

#endif
