// Walking through face neighbours towards a point (a visibility walk): leave each tet
// through the first face whose plane separates it from the point. The face kernels use it to
// correct a candidate that rounding put one tet off; exact and watertight like the test.
// Needs types.glsl, mesh.glsl and tet.glsl first.
#ifndef TL_WALK_GLSL
#define TL_WALK_GLSL

// Neighbour of each tet across the face opposite its stored vertex i (-1: boundary), Mesh::neighbors().
layout(std430, binding = TL_B_NEIGHBORS) readonly buffer TlNeighbors { ivec4 tl_neighbors[]; };

// The tet containing p, found in at most `max_steps` tets from `tet`; -1 when the walk
// leaves the mesh or runs out of steps (the point may still be inside: the caller decides).
int tl_walk(int tet, vec3 p, int max_steps, out uvec4 ids, out vec4 bary) {
    for (int step = 0; step < max_steps && tet >= 0; step++) {
        ids = tl_tets[tet];
        ivec4 next = tl_neighbors[tet]; // loaded beside the tet: one memory latency a step, not two
        int exit_face;
        if (tl_point_in_tet(ids, p, bary, exit_face)) {
            return tet;
        }
        tet = next[exit_face];
    }
    return -1;
}

#endif
