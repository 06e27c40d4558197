#version 460
// The tets' face neighbours (src/build/neighbors.rs), as tetloc_core's mesh/neighbors.rs
// finds them: faces as sorted vertex triples, bucketed by their smallest vertex (a counting
// sort), matched within the bucket.
//   NB_COUNT    faces per smallest vertex (tl_scan, zeroed first);
//   NB_SCATTER  (after the scan) each face (other two vertices, 4 tet + local face) into its
//               bucket; tl_scan[v] ends as the end of vertex v's bucket;
//   NB_MATCH    each face's neighbour: the faces with the same vertices, in order of
//               4 tet + face, link their first two (a broken mesh's third and later get -1).
// params.counts: faces (4 tets).
#extension GL_GOOGLE_include_directive : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "build/build.glsl"

layout(local_size_x = TL_BUILD_GROUP) in;

// The face opposite local vertex f % 4 of tet f / 4, its vertices ascending.
uvec3 tl_face(uint f) {
    uvec4 t = tl_tet(f / 4u);
    uint k = f % 4u;
    uvec3 v = k == 0u ? t.yzw : k == 1u ? t.xzw : k == 2u ? t.xyw : t.xyz;
    uint a = min(v.x, min(v.y, v.z)), c = max(v.x, max(v.y, v.z));
    return uvec3(a, v.x + v.y + v.z - a - c, c);
}

void main() {
    uint f = tl_build_index();
    if (f >= params.counts.x) {
        return;
    }
    uvec3 v = tl_face(f);
    if (BUILD_PASS == TL_BUILD_NB_COUNT) {
        atomicAdd(tl_scan[v.x], 1u);
    } else if (BUILD_PASS == TL_BUILD_NB_SCATTER) {
        uint slot = atomicAdd(tl_scan[v.x], 1u);
        tl_face_rec_set(slot, TlFace(v.y, v.z, f));
    } else {
        uint first = v.x == 0u ? 0u : tl_scan[v.x - 1u], end = tl_scan[v.x];
        uint low = TL_EMPTY, second = TL_EMPTY; // the two lowest codes of this face
        for (uint j = first; j < end; j++) {
            TlFace r = tl_face_rec(j);
            if (r.b == v.y && r.c == v.z) {
                uint code = r.code;
                if (code < low) {
                    second = low;
                    low = code;
                } else if (code < second) {
                    second = code;
                }
            }
        }
        uint other = f == low ? second : f == second ? low : TL_EMPTY;
        int nb = other == TL_EMPTY ? -1 : int(other / 4u);
        tl_build_nb_parts[nonuniformEXT((f / 4u) / tl_build_nb_per)].v[(f / 4u) % tl_build_nb_per][f % 4u] = nb;
    }
}
