// The point-in-tet test and interpolation: a line-by-line mirror of
// tetloc-core/src/geom/mod.rs (read that file's header for the why). Keep them in step.
//
// Watertightness needs every float operation that feeds a decision to be evaluated exactly
// as on the CPU: same operands, same order, and no FMA contraction. `precise` forbids
// contraction (SPIR-V NoContraction); Vulkan rounds +, -, * correctly. Two tets sharing a
// face therefore compute bit-identical determinants for it, and only the sign they expect
// differs: a point on a shared face is accepted by at least one of them.
//
// TL_F64 (defined when the device has shaderFloat64) enables the exact f64 fallback. Without
// it, the pure-f32 path lets the f32 determinant decide even within its error bound: still
// watertight (neighbours see the same value), but a point within rounding of a face may go
// to either side, and sliver barycentrics are only f32-accurate.
#ifndef TL_TET_GLSL
#define TL_TET_GLSL

#include "common/det.glsl"

// Determinant of (a-p, b-p, c-p) in f32 and its error bound (geom::orient_f32: the
// operations of det_and_permanent, in its order).
float tl_orient_f32(vec3 a, vec3 b, vec3 c, vec3 p, out float bound) {
    precise float permanent;
    precise float det = tl_det_and_permanent(a, b, c, p, permanent);
    bound = ORIENT_ERR_BOUND_F32 * permanent;
    return det;
}

#ifdef TL_F64
// The same determinant in f64 (geom::orient_f64).
double tl_orient_f64(vec3 a, vec3 b, vec3 c, vec3 p) {
    precise double adx = double(a.x) - double(p.x), ady = double(a.y) - double(p.y), adz = double(a.z) - double(p.z);
    precise double bdx = double(b.x) - double(p.x), bdy = double(b.y) - double(p.y), bdz = double(b.z) - double(p.z);
    precise double cdx = double(c.x) - double(p.x), cdy = double(c.y) - double(p.y), cdz = double(c.z) - double(p.z);
    precise double det = adx * (bdy * cdz - cdy * bdz) + bdx * (cdy * adz - ady * cdz) + cdx * (ady * bdz - bdy * adz);
    return det;
}
#endif

// geom::SORTED_FACES: for the face opposite ascending-order vertex i, its three vertices in
// ascending order and the sign with which orient() is positive towards vertex i when the
// ascending order is left-handed (orient(v0, v1, v2, v3) > 0).
const ivec3 TL_FACE[4] = ivec3[4](ivec3(1, 2, 3), ivec3(0, 2, 3), ivec3(0, 1, 3), ivec3(0, 1, 2));
const float TL_PARITY[4] = float[4](-1.0, 1.0, -1.0, 1.0);

// Set by tl_point_in_tet_stage when it answers inside: whether the point is on the tet's
// boundary (a face's determinant exactly 0: a zero weight), where other tets may hold it too
// (the tie rule, soft_bvh.glsl). A flag, not a test of the weights, so that kernels that
// want ids alone never divide for them.
bool tl_on_boundary = false;

// Answers of tl_point_in_tet_stage.
#define TL_TEST_OUTSIDE 0
#define TL_TEST_INSIDE 1
#define TL_TEST_UNDECIDED 2

// geom::point_in_tet. `ids` canonical. Inside: `bary` holds the weights of ids.xyzw.
// Outside: `exit_face` is the (ascending-order) face that p is outside of, the face across
// which a walk continues (0 for a zero-volume tet). With `f32_only` (a constant at every call
// site), the f32 stage alone: TL_TEST_UNDECIDED wherever the full test would turn to f64, so a
// caller can keep the f64 code off its hot path (walk.glsl `tl_test`).
int tl_point_in_tet_stage(uvec4 ids, vec3 p, bool f32_only, out vec4 bary, out int exit_face) {
    bary = vec4(0.0);
    exit_face = 0;
    // Ascending order: swap back the last two if canonical order swapped them.
    bool swapped = ids.w < ids.z;
    uvec4 asc = swapped ? ids.xywz : ids;
    // The ascending order is left-handed (orient > 0) exactly when canonical order swapped it.
    float orientation = swapped ? 1.0 : -1.0;
    vec3 v[4] = vec3[4](tl_vertex(asc.x), tl_vertex(asc.y), tl_vertex(asc.z), tl_vertex(asc.w));
    float d[4];
    precise float bound_sum = 0.0;
    bool exact = false;
    [[unroll]] for (int i = 0; i < 4; i++) {
        float sign = TL_PARITY[i] * orientation;
        float bound;
        precise float det = tl_orient_f32(v[TL_FACE[i].x], v[TL_FACE[i].y], v[TL_FACE[i].z], p, bound);
        precise float signed_det;
#ifdef TL_F64
        if (abs(det) > bound) {
            signed_det = sign * det;
        } else {
            if (f32_only) {
                return TL_TEST_UNDECIDED;
            }
            exact = true;
            precise double signed64 = double(sign) * tl_orient_f64(v[TL_FACE[i].x], v[TL_FACE[i].y], v[TL_FACE[i].z], p);
            if (signed64 < 0.0) {
                exit_face = (swapped && i >= 2) ? 5 - i : i;
                return TL_TEST_OUTSIDE;
            }
            signed_det = float(signed64);
        }
#else
        signed_det = sign * det;
#endif
        // -0.0 and +0.0 (on the face) both count as inside.
        if (signed_det < 0.0) {
            exit_face = (swapped && i >= 2) ? 5 - i : i; // ascending index -> stored index
            return TL_TEST_OUTSIDE;
        }
        d[i] = signed_det;
        bound_sum += bound;
    }
    precise float total = d[0] + d[1] + d[2] + d[3];
    tl_on_boundary = d[0] == 0.0 || d[1] == 0.0 || d[2] == 0.0 || d[3] == 0.0;
#ifdef TL_F64
    if (!exact && total > BARY_F32_TRUST * bound_sum) {
        bary = vec4(d[0], d[1], d[2], d[3]) / total;
    } else if (f32_only) {
        return TL_TEST_UNDECIDED;
    } else {
        // Sliver or point near a face: barycentrics in f64.
        double d64[4];
        [[unroll]] for (int i = 0; i < 4; i++) {
            d64[i] = double(TL_PARITY[i] * orientation) * tl_orient_f64(v[TL_FACE[i].x], v[TL_FACE[i].y], v[TL_FACE[i].z], p);
        }
        precise double total64 = d64[0] + d64[1] + d64[2] + d64[3];
        if (total64 <= 0.0) {
            return TL_TEST_OUTSIDE; // zero-volume tet: contains no point
        }
        tl_on_boundary = d64[0] <= 0.0 || d64[1] <= 0.0 || d64[2] <= 0.0 || d64[3] <= 0.0;
        bary = vec4(float(max(d64[0], 0.0) / total64), float(max(d64[1], 0.0) / total64),
                    float(max(d64[2], 0.0) / total64), float(max(d64[3], 0.0) / total64));
    }
#else
    if (!(total > 0.0)) {
        return TL_TEST_OUTSIDE; // zero-volume tet: contains no point
    }
    bary = vec4(d[0], d[1], d[2], d[3]) / total;
#endif
    // Weights from ascending order back to the stored (canonical) order.
    if (swapped) {
        bary = bary.xywz;
    }
    return TL_TEST_INSIDE;
}

// geom::predicates::orient3d_local: the determinant in f32 with the bound that also covers
// `delta`, the rounding of each input from the file's coordinates (Frame::delta): when
// |det| > bound, det has the sign of orient3d on the file's coordinates.
float tl_orient3d_local(vec3 a, vec3 b, vec3 c, vec3 p, float delta, out float bound) {
    precise float permanent;
    vec3 ad, bd, cd;
    precise float det = tl_det_and_permanent(a, b, c, p, permanent, ad, bd, cd);
    // Row norms, widened by the rounding of the inputs.
    precise float two_delta = 2.0 * delta;
    precise float ma = abs(ad.x) + abs(ad.y) + abs(ad.z) + two_delta;
    precise float mb = abs(bd.x) + abs(bd.y) + abs(bd.z) + two_delta;
    precise float mc = abs(cd.x) + abs(cd.y) + abs(cd.z) + two_delta;
    precise float inputs = delta * (ma * mb + mb * mc + mc * ma);
    bound = LOCAL_ORIENT_BOUND * permanent + inputs;
    return det;
}

// geom::holds_strictly_by_filter: whether p (working coordinates, rounded from the file's
// point) is strictly inside tet `ids` (canonical) on the file's data, proved by the f32
// filter with the copy's rounding `delta`; false where some face's sign is not proved.
bool tl_holds_strictly_by_filter(uvec4 ids, vec3 p, float delta) {
    bool swapped = ids.w < ids.z;
    uvec4 asc = swapped ? ids.xywz : ids;
    float orientation = swapped ? 1.0 : -1.0;
    vec3 v[4] = vec3[4](tl_vertex(asc.x), tl_vertex(asc.y), tl_vertex(asc.z), tl_vertex(asc.w));
    [[unroll]] for (int i = 0; i < 4; i++) {
        float bound;
        precise float det = tl_orient3d_local(v[TL_FACE[i].x], v[TL_FACE[i].y], v[TL_FACE[i].z], p, delta, bound);
        if (!(abs(det) > bound && TL_PARITY[i] * orientation * det > 0.0)) {
            return false;
        }
    }
    return true;
}

bool tl_point_in_tet(uvec4 ids, vec3 p, out vec4 bary, out int exit_face) {
    return tl_point_in_tet_stage(ids, p, false, bary, exit_face) == TL_TEST_INSIDE;
}

#include "common/high_order.glsl"

#ifdef TL_F64
// geom::refined_bary: on a mesh stored in f64 (REFINE_BARY), the barycentrics of p plus its
// residual r (working coordinates: a grid's f64 point is p + r, a host point has r = 0)
// in tet `ids` on the working copy plus each vertex's residual (the file's
// coordinates to about 2^-48), in f64 from sub-volumes relative to vertex 0, clamped to 0 and
// normalised; `bary` (the search's, on the f32 copy) for a tet of no volume there. Once per
// point, on the tet found: the search keeps its f32 test.
vec4 tl_refined_bary(uvec4 ids, vec3 p, vec3 r, vec4 bary) {
    dvec3 w0 = dvec3(tl_vertex(ids.x)) + dvec3(tl_residual(ids.x));
    precise dvec3 e1 = (dvec3(tl_vertex(ids.y)) + dvec3(tl_residual(ids.y))) - w0;
    precise dvec3 e2 = (dvec3(tl_vertex(ids.z)) + dvec3(tl_residual(ids.z))) - w0;
    precise dvec3 e3 = (dvec3(tl_vertex(ids.w)) + dvec3(tl_residual(ids.w))) - w0;
    precise dvec3 q = (dvec3(p) + dvec3(r)) - w0;
    // det(a, b, c) = a . (b x c): positive for canonical tets.
    precise double total = dot(e1, cross(e2, e3));
    precise double d1 = dot(q, cross(e2, e3)), d2 = dot(e1, cross(q, e3)), d3 = dot(e1, cross(e2, q));
    precise dvec4 d = max(dvec4(total - d1 - d2 - d3, d1, d2, d3), dvec4(0.0));
    precise double sum = d.x + d.y + d.z + d.w;
    if (total <= 0.0 || sum <= 0.0) {
        return bary;
    }
    return vec4(d / sum);
}
#endif

// The barycentrics a point's values are interpolated with: on a mesh stored in f64, refined
// on the file's coordinates (once a point, whatever its number of fields), at p + r (r: the
// point's residual, tl_sample_residual).
vec4 tl_value_bary_at(uvec4 ids, vec3 p, vec3 r, vec4 bary) {
#ifdef TL_F64
    if (REFINE_BARY) {
        return tl_refined_bary(ids, p, r, bary);
    }
#endif
    return bary;
}

// tl_value_bary_at of a point the kernel has exactly.
vec4 tl_value_bary(uvec4 ids, vec3 p, vec4 bary) {
    return tl_value_bary_at(ids, p, vec3(0.0), bary);
}

// Mesh::interpolate of field `f` (tl_fields[f]) in tet `tet` >= 0: per vertex
// (geom::interpolate for linear tets, the tet's own shape functions for higher-order ones) at
// `bary` (tl_value_bary's), or the per-cell value (`cell`). The one definition of a value on
// the GPU: every output mode and the marcher interpolate here.
float tl_field_value(uint f, bool cell, int tet, uvec4 ids, vec4 bary) {
    if (cell) {
        return tl_fields[f].v[tet];
    }
    if (HO_NODES > 0u) {
        return tl_ho_value(f, tet, ids, bary);
    }
    precise float v = bary.x * tl_fields[f].v[ids.x] + bary.y * tl_fields[f].v[ids.y]
        + bary.z * tl_fields[f].v[ids.z] + bary.w * tl_fields[f].v[ids.w];
    return v;
}

// The bound field's value (tl_fields[0], per vertex or per cell as OUTPUT_MODE says); NaN
// outside. `p`: the point (working frame), whose barycentrics are refined on a mesh stored in f64.
float tl_value(int tet, uvec4 ids, vec4 bary, vec3 p) {
    if (tet < 0) {
        return uintBitsToFloat(0x7fc00000u);
    }
    bool cell = OUTPUT_MODE == TL_OUT_CELL;
    return tl_field_value(0u, cell, tet, ids, cell ? bary : tl_value_bary(ids, p, bary));
}

#endif
