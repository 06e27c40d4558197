// Higher-order tets: a per-vertex field interpolated with the tet's own shape functions, the
// GPU side of tetloc-core's cell::lattice (LatticeCell::eval, families Tet and BezierTet) on
// the node rows of mesh::TetNodes. Tets are located by their corners; the barycentrics over
// the canonical corners are the shape functions' coordinates (λ0 = 1 - r - s - t, r, s, t).
//
// Node m of a tet of order p has the barycentric lattice index α_m (cell::barycentric_lattice,
// uploaded in tl_ho_lattice, one byte per corner) and its shape function is
//   Lagrange: Π_j Π_{q < α_mj} (p λ_j - q) / (q + 1)
//   Bezier:   p! / Π_j α_mj!  Π_j λ_j^α_mj
// Nodes 0..3 are the corners (ids.xyzw), nodes 4.. come from tl_ho_nodes (HO_NODES per tet).
// With HO_NODES == 0 (linear tets) everything here folds away.
#ifndef TL_HIGH_ORDER_GLSL
#define TL_HIGH_ORDER_GLSL

layout(std430, binding = TL_B_HO_NODES) readonly buffer TlHoNodes { uint tl_ho_nodes[]; };
layout(std430, binding = TL_B_HO_LATTICE) readonly buffer TlHoLattice { uint tl_ho_lattice[]; };

// The shape function of the node with lattice index `alpha` (packed) at barycentrics `bary`.
float tl_ho_shape(uint alpha, vec4 bary) {
    precise float w = 1.0;
    float p = float(HO_ORDER);
    for (int j = 0; j < 4; j++) {
        uint a = (alpha >> (8 * j)) & 0xFFu;
        float l = bary[j];
        for (uint q = 0u; q < a; q++) {
            if (HO_BEZIER) {
                w = w * l * ((p - float(q)) / float(q + 1u)); // p!/(α! (p - α)!) λ^α, factor by factor
            } else {
                w = w * (p * l - float(q)) / float(q + 1u);
            }
        }
        if (HO_BEZIER) {
            p -= float(a); // the multinomial p! / Π α_j! as a product of binomials
        }
    }
    return w;
}

// Field `f` at barycentrics `bary` of higher-order tet `tet` with canonical corners `ids`.
float tl_ho_value(uint f, int tet, uvec4 ids, vec4 bary) {
    precise float v = 0.0;
    for (uint m = 0u; m < 4u + HO_NODES; m++) {
        uint node = m < 4u ? ids[m] : tl_ho_nodes[uint(tet) * HO_NODES + (m - 4u)];
        v += tl_ho_shape(tl_ho_lattice[m], bary) * tl_fields[f].v[node];
    }
    return v;
}

#endif
