// Exact predicates on the file's f64 coordinates and the tie rule: a line-by-line mirror of
// tetloc-core/src/geom/predicates/ (expansion.rs, orient.rs, local.rs, tet.rs). Read
// predicates/mod.rs for the why: the stages, the domain of coordinates, the error bounds
// and the tie rule (a point belongs to the tet that p + (e, e^2, e^3) lies in). Keep them
// in step.
//
// What an including shader must provide:
// - doubles (shaderFloat64) and TL_F64 defined, as the f64 variants have it (det.glsl's f64
//   determinant);
// - round-to-nearest for 64-bit floats: two-sum and two-product are exact only then, and
//   Vulkan leaves the rounding mode to the device unless the shader declares one. This
//   file declares RoundingModeRTE for 64-bit floats (the device must report
//   shaderRoundingModeRTEFloat64); define TL_EXACT_NO_RTE_MODE to declare it elsewhere.
//   The error bounds hold in any correctly rounded mode (they use the machine epsilon);
// - `vec3 tl_vertex(uint i)`: vertex i in local f32 coordinates (LocalFrame::to_local), and
//   `dvec3 tl_vertex64(uint i)`: vertex i as the file has it, read only where f32 cannot
//   decide.
// Every variable that takes part in a decision is `precise`: no contraction into FMA, no
// reassociation.
#ifndef TL_EXACT_GLSL
#define TL_EXACT_GLSL

#ifndef TL_EXACT_NO_RTE_MODE
#extension GL_EXT_spirv_intrinsics : require
spirv_execution_mode(capabilities = [4467], 4462, 64); // capability and mode RoundingModeRTE, 64-bit
#endif

#include "common/det.glsl"

// ---------------------------------------------------------------- expansion.rs

// a + b = x + y exactly, x = fl(a + b) (Knuth's two-sum).
void tl_two_sum(double a, double b, out double x, out double y) {
    precise double s = a + b;
    precise double b_virtual = s - a;
    precise double a_virtual = s - b_virtual;
    precise double r = (a - a_virtual) + (b - b_virtual);
    x = s;
    y = r;
}

// 2^27 + 1: splits a 53-bit significand into halves of at most 26 bits.
const double TL_SPLITTER = 134217729.0lf;

// a = hi + lo exactly, each with at most 26 significant bits (Veltkamp).
void tl_split(double a, out double hi, out double lo) {
    precise double c = TL_SPLITTER * a;
    precise double big = c - a;
    precise double h = c - big;
    hi = h;
    lo = a - h;
}

// a * b = x + y exactly, x = fl(a * b) (Dekker; no FMA).
void tl_two_product(double a, double b, out double x, out double y) {
    precise double p = a * b;
    double a_hi, a_lo, b_hi, b_lo;
    tl_split(a, a_hi, a_lo);
    tl_split(b, b_hi, b_lo);
    precise double err1 = p - a_hi * b_hi;
    precise double err2 = err1 - a_lo * b_hi;
    precise double err3 = err2 - a_hi * b_lo;
    precise double r = a_lo * b_lo - err3;
    x = p;
    y = r;
}

// An exact sum of f64 components, nonoverlapping, smallest first, none zero. 96 is the most
// the exact orient3d's terms produce (each add grows it by at most one).
#define TL_EXPANSION_MAX 96
struct TlExpansion {
    double c[TL_EXPANSION_MAX];
    int n;
};

// Expansion::add: b carried up through the components by two-sum (GROW-EXPANSION), the
// round-offs written back in place, zeros dropped.
void tl_expansion_add(inout TlExpansion e, double b) {
    precise double q = b;
    int m = 0;
    for (int i = 0; i < e.n; i++) {
        double sum, round_off;
        tl_two_sum(q, e.c[i], sum, round_off);
        q = sum;
        if (round_off != 0.0lf) {
            e.c[m] = round_off;
            m++;
        }
    }
    if (q != 0.0lf) {
        e.c[m] = q;
        m++;
    }
    e.n = m;
}

// Expansion::add_product: sign * x * y exactly.
void tl_expansion_add_product(inout TlExpansion e, double sign, double x, double y) {
    double h, l;
    tl_two_product(sign * x, y, h, l);
    tl_expansion_add(e, l);
    tl_expansion_add(e, h);
}

// Expansion::add_triple_product: sign * x * y * z exactly, as (h + l) * z.
void tl_expansion_add_triple_product(inout TlExpansion e, double sign, double x, double y, double z) {
    double h, l, hh, hl, lh, ll;
    tl_two_product(sign * x, y, h, l);
    tl_two_product(h, z, hh, hl);
    tl_two_product(l, z, lh, ll);
    tl_expansion_add(e, ll);
    tl_expansion_add(e, lh);
    tl_expansion_add(e, hl);
    tl_expansion_add(e, hh);
}

// Expansion::sign: the sign of the largest component, exact.
double tl_expansion_sign(TlExpansion e) {
    return e.n == 0 ? 0.0lf : sign(e.c[e.n - 1]);
}

// Expansion::value: the components summed smallest first, or the largest component should
// that sum ever lose the exact sign.
double tl_expansion_value(TlExpansion e) {
    precise double sum = 0.0lf;
    for (int i = 0; i < e.n; i++) {
        sum += e.c[i];
    }
    return (sum * tl_expansion_sign(e) > 0.0lf || e.n == 0) ? sum : e.c[e.n - 1];
}

// ---------------------------------------------------------------- orient.rs

// The machine epsilon 2^-52: the bounds hold in any correctly rounded mode.
const double TL_EPS64 = 2.220446049250313080847263336181640625e-16lf;
const double TL_ORIENT3D_BOUND = 9.0lf * TL_EPS64;
const double TL_ORIENT2D_BOUND = 5.0lf * TL_EPS64;

// orient3d_stage_a: det[a - d; b - d; c - d] in f64 and its error bound.
double tl_orient3d_stage_a(dvec3 a, dvec3 b, dvec3 c, dvec3 d, out double bound) {
    precise double permanent;
    precise double det = tl_det_and_permanent(a, b, c, d, permanent);
    bound = TL_ORIENT3D_BOUND * permanent;
    return det;
}

// The six permutations of three axes and their signs.
const ivec3 TL_PERMUTATIONS_3[6] = ivec3[6](ivec3(0, 1, 2), ivec3(0, 2, 1), ivec3(1, 0, 2), ivec3(1, 2, 0), ivec3(2, 0, 1), ivec3(2, 1, 0));
const double TL_PERMUTATION_SIGNS_3[6] = double[6](1.0lf, -1.0lf, -1.0lf, 1.0lf, 1.0lf, -1.0lf);
// Rows of the 3x3 determinants: the four points less the omitted one.
const ivec3 TL_ROWS_OMITTING[4] = ivec3[4](ivec3(1, 2, 3), ivec3(0, 2, 3), ivec3(0, 1, 3), ivec3(0, 1, 2));

// orient3d_exact: det[a 1; b 1; c 1; d 1] = -|bcd| + |acd| - |abd| + |abc|, every triple
// product entering the expansion exactly.
TlExpansion tl_orient3d_exact(dvec3 a, dvec3 b, dvec3 c, dvec3 d) {
    dvec3 pts[4] = dvec3[4](a, b, c, d);
    TlExpansion sum;
    sum.n = 0;
    for (int omitted = 0; omitted < 4; omitted++) {
        double cofactor = omitted % 2 == 0 ? -1.0lf : 1.0lf;
        dvec3 p = pts[TL_ROWS_OMITTING[omitted].x], q = pts[TL_ROWS_OMITTING[omitted].y], r = pts[TL_ROWS_OMITTING[omitted].z];
        for (int s = 0; s < 6; s++) {
            ivec3 ax = TL_PERMUTATIONS_3[s];
            tl_expansion_add_triple_product(sum, cofactor * TL_PERMUTATION_SIGNS_3[s], p[ax.x], q[ax.y], r[ax.z]);
        }
    }
    return sum;
}

// orient3d: positive when d is below the plane through a, b, c (counter-clockwise from
// above). Exact sign, approximate magnitude.
double tl_orient3d(dvec3 a, dvec3 b, dvec3 c, dvec3 d) {
    double bound;
    precise double det = tl_orient3d_stage_a(a, b, c, d, bound);
    if (abs(det) > bound) {
        return det;
    }
    return tl_expansion_value(tl_orient3d_exact(a, b, c, d));
}

// orient2d: (a - c) x (b - c), positive counter-clockwise. Exact sign.
double tl_orient2d(dvec2 a, dvec2 b, dvec2 c) {
    precise double acx = a.x - c.x, acy = a.y - c.y;
    precise double bcx = b.x - c.x, bcy = b.y - c.y;
    precise double left = acx * bcy, right = acy * bcx;
    precise double det = left - right;
    precise double bound = TL_ORIENT2D_BOUND * (abs(left) + abs(right));
    if (abs(det) > bound) {
        return det;
    }
    // ax*by - ax*cy - bx*ay + bx*cy + cx*ay - cx*by, exactly.
    TlExpansion sum;
    sum.n = 0;
    tl_expansion_add_product(sum, 1.0lf, a.x, b.y);
    tl_expansion_add_product(sum, -1.0lf, a.x, c.y);
    tl_expansion_add_product(sum, -1.0lf, b.x, a.y);
    tl_expansion_add_product(sum, 1.0lf, b.x, c.y);
    tl_expansion_add_product(sum, 1.0lf, c.x, a.y);
    tl_expansion_add_product(sum, -1.0lf, c.x, b.y);
    return tl_expansion_value(sum);
}

// THE TIE RULE (orient3d_sos): the sign (-1, 0, 1) of orient3d(a, b, c, p + (e, e^2, e^3)) for
// small e > 0. On the plane, the first non-zero of -n.x, -n.y, -n.z decides, n = (b - a) x (c - a),
// each component an orient2d of the face projected on the other two axes. 0 only for a
// degenerate face.
int tl_orient3d_sos(dvec3 a, dvec3 b, dvec3 c, dvec3 p) {
    double det = tl_orient3d(a, b, c, p);
    if (det != 0.0lf) {
        return int(sign(det));
    }
    const ivec2 axes[3] = ivec2[3](ivec2(1, 2), ivec2(2, 0), ivec2(0, 1)); // n.x on (y, z), n.y on (z, x), n.z on (x, y)
    for (int i = 0; i < 3; i++) {
        int u = axes[i].x, v = axes[i].y;
        double n = tl_orient2d(dvec2(a[u], a[v]), dvec2(b[u], b[v]), dvec2(c[u], c[v]));
        if (n != 0.0lf) {
            return -int(sign(n));
        }
    }
    return 0;
}

// ---------------------------------------------------------------- local.rs

// The machine epsilon 2^-23.
const float TL_EPS32 = 1.0 / 8388608.0;
// C1 = 9 eps for the f32 arithmetic; FILTER_DELTA = 2^-25 (1 + 2^-18) for the rounding of
// vertex - point to local coordinates (LocalFrame: 25-bit fixed point, |x| <= 1/2).
const float TL_LOCAL_ORIENT_BOUND = 9.0 * TL_EPS32;
const float TL_FILTER_DELTA = (1.0 + 1.0 / 262144.0) / 33554432.0;
const double TL_LOCAL_STEPS = 33554432.0lf; // 2^25 steps per local unit

// LocalFrame::to_local: round((x - origin) * scale) to the 2^-25 grid; `inside` false when
// outside the box |fl(x - origin) * scale| <= 1/2, that is outside every tet.
vec3 tl_to_local(dvec3 x, dvec3 origin, double scale, out bool inside) {
    precise dvec3 y = (x - origin) * scale;
    inside = all(lessThanEqual(abs(y), dvec3(0.5lf)));
    return vec3(roundEven(y * TL_LOCAL_STEPS) * (1.0lf / TL_LOCAL_STEPS));
}

// orient3d_local: orient3d in f32 on local coordinates, with the bound that covers the f32
// arithmetic and (delta: TL_FILTER_DELTA) the rounding of the file's coordinates.
// |det| > bound proves the sign of orient3d on the file's coordinates.
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
    bound = TL_LOCAL_ORIENT_BOUND * permanent + inputs;
    return det;
}

// ---------------------------------------------------------------- tet.rs

// FACES: face i of a right-handed tet, opposite stored vertex i, ordered so that
// orient3d(face, p) > 0 for p strictly inside.
const ivec3 TL_EXACT_FACES[4] = ivec3[4](ivec3(1, 2, 3), ivec3(0, 3, 2), ivec3(0, 1, 3), ivec3(0, 2, 1));

// Side::Inside; otherwise the answer is the exit face (0..3).
#define TL_SIDE_INSIDE (-1)

// side_of_tet: the test on f64 coordinates alone.
int tl_side_of_tet(dvec3 v[4], dvec3 p) {
    for (int i = 0; i < 4; i++) {
        ivec3 f = TL_EXACT_FACES[i];
        if (tl_orient3d_sos(v[f.x], v[f.y], v[f.z], p) != 1) {
            return i;
        }
    }
    return TL_SIDE_INSIDE;
}

// side_of_tet_staged: each face in f32 on local coordinates where the bound decides, else
// exactly on the file's coordinates (tl_vertex64, read only then).
int tl_side_of_tet_staged(uvec4 ids, vec3 p_local, dvec3 p_file) {
    vec3 v[4] = vec3[4](tl_vertex(ids.x), tl_vertex(ids.y), tl_vertex(ids.z), tl_vertex(ids.w));
    for (int i = 0; i < 4; i++) {
        ivec3 f = TL_EXACT_FACES[i];
        float bound;
        precise float det = tl_orient3d_local(v[f.x], v[f.y], v[f.z], p_local, TL_FILTER_DELTA, bound);
        bool inside;
        if (det > bound) {
            inside = true;
        } else if (det < -bound) {
            inside = false;
        } else {
            inside = tl_orient3d_sos(tl_vertex64(ids[f.x]), tl_vertex64(ids[f.y]), tl_vertex64(ids[f.z]), p_file) == 1;
        }
        if (!inside) {
            return i;
        }
    }
    return TL_SIDE_INSIDE;
}

// barycentrics: f64 weights of v0..v3 for a point inside under the tie rule; exact signs, so
// exactly 0 on a face and never negative.
dvec4 tl_barycentrics(dvec3 v[4], dvec3 p) {
    dvec4 d;
    for (int i = 0; i < 4; i++) {
        ivec3 f = TL_EXACT_FACES[i];
        d[i] = max(tl_orient3d(v[f.x], v[f.y], v[f.z], p), 0.0lf);
    }
    precise double total = d.x + d.y + d.z + d.w;
    return d / total;
}

// test_point_exact: TL_SIDE_INSIDE with the weights in `bary`, or the exit face.
int tl_test_point_exact(uvec4 ids, vec3 p_local, dvec3 p_file, out dvec4 bary) {
    bary = dvec4(0.0lf);
    int side = tl_side_of_tet_staged(ids, p_local, p_file);
    if (side == TL_SIDE_INSIDE) {
        dvec3 v[4] = dvec3[4](tl_vertex64(ids.x), tl_vertex64(ids.y), tl_vertex64(ids.z), tl_vertex64(ids.w));
        bary = tl_barycentrics(v, p_file);
    }
    return side;
}

#endif
