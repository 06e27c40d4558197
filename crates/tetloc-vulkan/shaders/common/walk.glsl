// Walking through face neighbours towards a point (a visibility walk): leave each tet
// through the first face whose plane separates it from the point. The face kernels use it to
// correct a candidate that rounding put one tet off; exact and watertight like the test.
// Needs interface.glsl, mesh.glsl and tet.glsl first.
#ifndef TL_WALK_GLSL
#define TL_WALK_GLSL

// Neighbour of each tet across the face opposite its stored vertex i (-1: boundary), Mesh::neighbors().
layout(std430, binding = TL_B_NEIGHBORS) readonly buffer TlNeighbors { ivec4 tl_neighbors[]; };
// NEIGHBORS_CHUNK: tets per buffer when the neighbours are split over several (mesh.glsl), 0:
// one buffer.
layout(std430, binding = TL_B_NEIGHBORS_HI) readonly buffer TlNeighborsHi { ivec4 v[]; } tl_neighbors_hi[TL_MAX_CHUNKS - 1];

// NEIGHBOR_BITS != 0: packed (packed.glsl) in one buffer, each neighbour + 1.
uint tl_neighbor_word(uint w) {
    return uint(tl_neighbors[w >> 2u][w & 3u]);
}
TL_PACKED4_READER(tl_neighbors_packed, tl_neighbor_word, NEIGHBOR_BITS)

ivec4 tl_neighbors4(uint t) {
    if (NEIGHBOR_BITS != 0u) {
        return ivec4(tl_neighbors_packed(t)) - 1;
    }
    if (NEIGHBORS_CHUNK == 0u || t < NEIGHBORS_CHUNK) {
        return tl_neighbors[t];
    }
    uint c = t / NEIGHBORS_CHUNK - 1u, o = t % NEIGHBORS_CHUNK;
    TL_RETURN_HI(tl_neighbors_hi, c, o)
}

// F32_FIRST: decide in f32 first and run the full test (tet.glsl, with its f64 fallback) only
// when f32 cannot: a face within its error bound, or barycentrics the f32 values do not support.
// Same answers (the f32 prefix is the full test's own first steps); the point is that the
// hot path holds no f64 state (the CPU counts no f64 face on jets at all, NOTES.md).
// DEFER_EXACT (with F32_FIRST): never run the full test; an undecided test sets tl_undecided
// instead, and the caller gives the sample up (TL_DEFERRED) for a second, exact pass
// (soft_bvh.comp).
bool tl_undecided = false;

bool tl_test(uvec4 ids, vec3 p, out vec4 bary, out int exit_face) {
#ifdef TL_F64
    if (F32_FIRST) {
        int answer = tl_point_in_tet_stage(ids, p, true, bary, exit_face);
        if (answer != TL_TEST_UNDECIDED) {
            return answer == TL_TEST_INSIDE;
        }
        if (DEFER_EXACT) {
            tl_undecided = true;
            bary = vec4(0.0);
            exit_face = 0;
            return false;
        }
    }
#endif
    return tl_point_in_tet(ids, p, bary, exit_face);
}

// Tets visited by this invocation's walks so far (stream.comp reports it; shaders that never
// read it lose it to dead-code elimination).
uint tl_walk_visits = 0u;

// The tet containing p, found in at most `max_steps` tets from `tet`; TL_OUTSIDE when the walk
// leaves the mesh or runs out of steps (the point may still be inside: the caller decides);
// TL_DEFERRED only with DEFER_EXACT, when a test could not be decided in f32.
int tl_walk(int tet, vec3 p, int max_steps, out uvec4 ids, out vec4 bary) {
    for (int step = 0; step < max_steps && tet >= 0; step++) {
        ids = tl_tet(tet);
        tl_walk_visits++;
        ivec4 next = tl_neighbors4(tet); // loaded beside the tet: one memory latency a step, not two
        int exit_face;
        if (tl_test(ids, p, bary, exit_face)) {
            return tet;
        }
        if (DEFER_EXACT && tl_undecided) {
            return TL_DEFERRED;
        }
        tet = next[exit_face];
    }
    return TL_OUTSIDE;
}

// Most tets tl_lowest_holder visits: a vertex's star (about 24 tets on a conforming mesh).
#define TL_TIE_SEEN 128

// The tie rule (tetloc_core::geom::lowest_claim) for tet `tet`, which holds p with weights
// `bary`: the tets that hold p are found through the faces p lies on (a zero weight: the face
// opposite that vertex), from each holder to the next, and the lowest id among them is the
// answer. On a conforming mesh these are all the tets that hold p, as a search finds them; the
// ray-tracing kernels, which have no tet search to go on with, settle ties here.
int tl_lowest_holder(int tet, vec4 bary, vec3 p) {
    int seen[TL_TIE_SEEN];
    seen[0] = tet;
    int n = 1, lowest = tet;
    for (int head = 0; head < n; head++) {
        int exit_face;
        if (head > 0) {
            tl_point_in_tet(tl_tet(uint(seen[head])), p, bary, exit_face);
        }
        ivec4 next = tl_neighbors4(uint(seen[head]));
        for (int i = 0; i < 4; i++) {
            int u = next[i];
            bool known = bary[i] != 0.0 || u < 0 || n == TL_TIE_SEEN;
            for (int k = 0; k < n && !known; k++) {
                known = seen[k] == u;
            }
            vec4 held;
            if (!known && tl_point_in_tet(tl_tet(uint(u)), p, held, exit_face)) {
                seen[n++] = u;
                lowest = min(lowest, u);
            }
        }
    }
    return lowest;
}

#endif
