#version 460
// Packs the built neighbours (each + 1, so that -1 is 0) or leaf prims into an id array of
// NEIGHBOR_BITS or PRIM_BITS bits a field (src/packed.rs, src/build/pack.rs): one invocation
// a field ORs its bits into the zeroed words it covers.
//   PACK_NEIGHBORS  field j: neighbour j % 4 of tet j / 4 (tl_build_nb);
//   PACK_PRIMS      field j: leaf prim j.
// params.counts: fields.
#extension GL_GOOGLE_include_directive : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "build/build.glsl"

layout(local_size_x = TL_BUILD_GROUP) in;

layout(std430, binding = TL_B_PRIMS) readonly buffer TlPackPrims { uint tl_pack_prims[]; };
layout(std430, binding = TL_B_PACKED) buffer TlPacked { uint tl_packed[]; };

void main() {
    uint j = tl_build_index();
    if (j >= params.counts.x) {
        return;
    }
    bool neighbors = BUILD_PASS == TL_BUILD_PACK_NEIGHBORS;
    uint bits = neighbors ? NEIGHBOR_BITS : PRIM_BITS;
    uint v = neighbors ? uint(tl_build_nb(j / 4u)[j % 4u] + 1) : tl_pack_prims[j];
    uint w, s;
    tl_packed_at(j, bits, w, s);
    atomicOr(tl_packed[w], v << s);
    if (s + bits > 32u) {
        atomicOr(tl_packed[w + 1u], v >> (32u - s));
    }
}
