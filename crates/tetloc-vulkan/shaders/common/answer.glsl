// A located point's answer as OUTPUT_MODE asks: its tet id (OUT_IDS), the bound field's value
// (OUT_VERTEX, OUT_CELL), its tet id and FIELD_COUNT fields' values in one launch
// (OUT_FIELDS: the cell's nodes are read once for all of them), or its tet id with the nodes
// and weights its values are interpolated with (OUT_WEIGHTS). Every locate kernel ends here.
#ifndef TL_ANSWER_GLSL
#define TL_ANSWER_GLSL

#include "common/mesh.glsl"
#include "common/tet.glsl"
#include "common/samples.glsl"

// The id answer for the host: `tet`, or -2 - tet where the kernels decide on a copy of the
// file's data (CERTIFY_DELTA >= 0) and the filter does not prove the point strictly inside it
// there (the host then checks it; almost every point is proved).
int tl_id_answer(int tet, uvec4 ids, vec3 p) {
    if (CERTIFY_DELTA < 0.0 || tet < 0 || tl_holds_strictly_by_filter(ids, p, CERTIFY_DELTA)) {
        return tet;
    }
    return -2 - tet;
}

// Point i of this launch is in `tet` (TL_OUTSIDE: none) with vertices `ids` and barycentrics
// `bary` (read only for values inside).
void tl_answer(uint i, int tet, uvec4 ids, vec4 bary, vec3 p) {
    if (OUTPUT_MODE == TL_OUT_WEIGHTS) {
        // Unordered launches only (the zero-copy path).
        uint n = params.counts.x;
        bool inside = tet >= 0;
        vec4 b = inside ? tl_value_bary_at(ids, p, tl_sample_residual(i), bary) : vec4(0.0);
        tl_out[i] = uint(tet);
        for (uint j = 0u; j < 4u; j++) {
            tl_out[TL_WEIGHTS_NODES_AT * n + 4u * i + j] = inside ? ids[j] : 0u;
            tl_out[TL_WEIGHTS_AT * n + 4u * i + j] = floatBitsToUint(b[j]);
        }
        return;
    }
    if (OUTPUT_MODE != TL_OUT_FIELDS) {
        if (OUTPUT_MODE == TL_OUT_IDS) {
            tl_store(i, tl_id_answer(tet, ids, p), 0.0);
        } else {
            tl_store(i, tet, tl_value(tet, ids, bary, p));
        }
        return;
    }
    vec3 r = tl_sample_residual(i);
    if (ORDERED) {
        i = tl_order_perm[i];
    }
    tl_out[i] = uint(tl_id_answer(tet, ids, p));
    uint at = params.counts.x + i * FIELD_COUNT;
    if (tet < 0) {
        for (uint f = 0u; f < FIELD_COUNT; f++) {
            tl_out[at + f] = 0x7fc00000u;
        }
        return;
    }
    vec4 b = tl_value_bary_at(ids, p, r, bary);
    for (uint f = 0u; f < FIELD_COUNT; f++) {
        bool cell = ((FIELD_CELLS >> f) & 1u) != 0u;
        tl_out[at + f] = floatBitsToUint(tl_field_value(f, cell, tet, ids, cell ? bary : b));
    }
}

#endif
