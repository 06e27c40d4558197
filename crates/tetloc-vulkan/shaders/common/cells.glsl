// Volume cells: the GLSL side of tetloc-core/src/cell (read cell/mod.rs and cell/decompose.rs
// for the why). Doubles where the Rust uses f64; `precise` everywhere a value feeds a decision,
// so that the CPU and every kernel take the same decisions (no FMA contraction).
//
// Not yet compiled by build.rs: phase B includes it from the kernels, and generates the tables
// below (corners, faces, bounds, lattices) from the Rust shapes (cell::{tet,pyramid,wedge,hex}
// ::SHAPE and the node tables) through the generated interface instead of repeating them here.
//
// Needs shaderFloat64 (TL_F64). Shapes are numbered TL_SHAPE_*; a cell's corners are passed as
// dvec3 x[8] (the first TL_CORNERS[shape] used), its corner ids as uint ids[8].
#ifndef TL_CELLS_GLSL
#define TL_CELLS_GLSL
#ifdef TL_F64

#define TL_SHAPE_TET 0
#define TL_SHAPE_PYRAMID 1
#define TL_SHAPE_WEDGE 2
#define TL_SHAPE_HEX 3

const int TL_CORNERS[4] = int[4](4, 5, 6, 8);
const int TL_N_FACES[4] = int[4](4, 5, 5, 6);

// Shape::faces: local corners in VTK's order, outward by the right hand; -1 pads triangles.
// Face f of shape s is TL_FACES[6 * s + f].
const ivec4 TL_FACES[24] = ivec4[24](
    ivec4(0, 1, 3, -1), ivec4(1, 2, 3, -1), ivec4(2, 0, 3, -1), ivec4(0, 2, 1, -1), ivec4(-1), ivec4(-1),
    ivec4(0, 3, 2, 1), ivec4(0, 1, 4, -1), ivec4(1, 2, 4, -1), ivec4(2, 3, 4, -1), ivec4(3, 0, 4, -1), ivec4(-1),
    ivec4(0, 2, 1, -1), ivec4(3, 4, 5, -1), ivec4(0, 1, 4, 3), ivec4(1, 2, 5, 4), ivec4(2, 0, 3, 5), ivec4(-1),
    ivec4(0, 4, 7, 3), ivec4(1, 2, 6, 5), ivec4(0, 1, 5, 4), ivec4(3, 7, 6, 2), ivec4(0, 3, 2, 1), ivec4(4, 5, 6, 7));

// Shape::domain: bound b of shape s is TL_BOUNDS[6 * s + b] = (normal, offset): the point is
// inside when offset + normal · pc >= 0. TL_BOUND_FACE names the face each bound is (-1: the
// pyramid's apex, t <= 1, which is a point).
const int TL_N_BOUNDS[4] = int[4](4, 6, 5, 6);
const dvec4 TL_BOUNDS[24] = dvec4[24](
    dvec4(0, 1, 0, 0), dvec4(-1, -1, -1, 1), dvec4(1, 0, 0, 0), dvec4(0, 0, 1, 0), dvec4(0), dvec4(0),
    dvec4(0, 0, 1, 0), dvec4(0, 1, 0, 0), dvec4(-1, 0, 0, 1), dvec4(0, -1, 0, 1), dvec4(1, 0, 0, 0), dvec4(0, 0, -1, 1),
    dvec4(0, 0, 1, 0), dvec4(0, 0, -1, 1), dvec4(0, 1, 0, 0), dvec4(-1, -1, 0, 1), dvec4(1, 0, 0, 0), dvec4(0),
    dvec4(1, 0, 0, 0), dvec4(-1, 0, 0, 1), dvec4(0, 1, 0, 0), dvec4(0, -1, 0, 1), dvec4(0, 0, 1, 0), dvec4(0, 0, -1, 1));
const int TL_BOUND_FACE[24] = int[24](
    0, 1, 2, 3, -1, -1,
    0, 1, 2, 3, 4, -1,
    0, 1, 2, 3, 4, -1,
    0, 1, 2, 3, 4, 5);

// Shape::center: where Newton's method starts.
const dvec3 TL_CENTER[4] = dvec3[4](
    dvec3(0.25lf), dvec3(0.5lf, 0.5lf, 0.2lf), dvec3(1.0lf / 3.0lf, 1.0lf / 3.0lf, 0.5lf), dvec3(0.5lf));

// The hex's corners in parametric space (hex::SHAPE.corners).
const ivec3 TL_HEX_CORNER[8] = ivec3[8](
    ivec3(0, 0, 0), ivec3(1, 0, 0), ivec3(1, 1, 0), ivec3(0, 1, 0),
    ivec3(0, 0, 1), ivec3(1, 0, 1), ivec3(1, 1, 1), ivec3(0, 1, 1));

// ---------------------------------------------------------------------------------------------
// Linear shape functions with their derivatives (the Rust derives these from the functions by
// dual numbers; here they are written out): w[i] = N_i(pc), d[i] = dN_i/d(r, s, t).

void tl_linear_shape(int shape, dvec3 pc, out double w[8], out dvec3 d[8]) {
    precise double r = pc.x, s = pc.y, t = pc.z;
    for (int i = 0; i < 8; i++) {
        w[i] = 0.0lf;
        d[i] = dvec3(0.0lf);
    }
    if (shape == TL_SHAPE_TET) {
        // tet.rs
        w[0] = 1.0lf - r - s - t; w[1] = r; w[2] = s; w[3] = t;
        d[0] = dvec3(-1.0lf); d[1] = dvec3(1, 0, 0); d[2] = dvec3(0, 1, 0); d[3] = dvec3(0, 0, 1);
    } else if (shape == TL_SHAPE_PYRAMID) {
        // pyramid.rs
        precise double rm = 1.0lf - r, sm = 1.0lf - s, tm = 1.0lf - t;
        w[0] = rm * sm * tm; w[1] = r * sm * tm; w[2] = r * s * tm; w[3] = rm * s * tm; w[4] = t;
        d[0] = dvec3(-sm * tm, -rm * tm, -rm * sm);
        d[1] = dvec3(sm * tm, -r * tm, -r * sm);
        d[2] = dvec3(s * tm, r * tm, -r * s);
        d[3] = dvec3(-s * tm, rm * tm, -rm * s);
        d[4] = dvec3(0, 0, 1);
    } else if (shape == TL_SHAPE_WEDGE) {
        // wedge.rs
        precise double u = 1.0lf - r - s, tm = 1.0lf - t;
        w[0] = u * tm; w[1] = r * tm; w[2] = s * tm; w[3] = u * t; w[4] = r * t; w[5] = s * t;
        d[0] = dvec3(-tm, -tm, -u); d[1] = dvec3(tm, 0, -r); d[2] = dvec3(0, tm, -s);
        d[3] = dvec3(-t, -t, u); d[4] = dvec3(t, 0, r); d[5] = dvec3(0, t, s);
    } else {
        // hex.rs: N_i = prod_k (x_k or 1 - x_k), by corner i's parametric coordinates.
        for (int i = 0; i < 8; i++) {
            ivec3 c = TL_HEX_CORNER[i];
            precise double f0 = c.x == 1 ? r : 1.0lf - r;
            precise double f1 = c.y == 1 ? s : 1.0lf - s;
            precise double f2 = c.z == 1 ? t : 1.0lf - t;
            double g0 = c.x == 1 ? 1.0lf : -1.0lf, g1 = c.y == 1 ? 1.0lf : -1.0lf, g2 = c.z == 1 ? 1.0lf : -1.0lf;
            w[i] = f0 * f1 * f2;
            d[i] = dvec3(g0 * f1 * f2, f0 * g1 * f2, f0 * f1 * g2);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// newton.rs

#define TL_NEWTON_MAX_ITERATIONS 50
#define TL_NEWTON_STEP_TOL 1e-13lf
#define TL_NEWTON_DIVERGED 1e6lf
#define TL_F64_EPSILON 2.220446049250313e-16lf

double tl_det3(dvec3 a, dvec3 b, dvec3 c) {
    precise double det = a.x * (b.y * c.z - b.z * c.y) - a.y * (b.x * c.z - b.z * c.x) + a.z * (b.x * c.y - b.y * c.x);
    return det;
}

// cell::invert for a linear cell (what every cell is located by): the parametric coordinates
// of p, fully converged in f64, from the shape's centre. False when the Jacobian is singular,
// the iterates diverge, or they do not converge (InverseError).
bool tl_invert(int shape, dvec3 x[8], dvec3 p, out dvec3 pc) {
    int n = TL_CORNERS[shape];
    double scale = max(max(abs(p.x), abs(p.y)), abs(p.z));
    for (int i = 0; i < n; i++) {
        scale = max(scale, max(max(abs(x[i].x), abs(x[i].y)), abs(x[i].z)));
    }
    double residual_tol = 8.0lf * TL_F64_EPSILON * scale;
    pc = TL_CENTER[shape];
    for (int it = 0; it < TL_NEWTON_MAX_ITERATIONS; it++) {
        double w[8];
        dvec3 d[8];
        tl_linear_shape(shape, pc, w, d);
        precise dvec3 at = dvec3(0.0lf);
        for (int i = 0; i < n; i++) {
            at += w[i] * x[i];
        }
        precise dvec3 f = at - p;
        if (abs(f.x) <= residual_tol && abs(f.y) <= residual_tol && abs(f.z) <= residual_tol) {
            return true;
        }
        // Columns of the Jacobian: dx/dr, dx/ds, dx/dt.
        precise dvec3 cr = dvec3(0.0lf), cs = dvec3(0.0lf), ct = dvec3(0.0lf);
        for (int i = 0; i < n; i++) {
            cr += d[i].x * x[i];
            cs += d[i].y * x[i];
            ct += d[i].z * x[i];
        }
        precise double det = tl_det3(cr, cs, ct);
        if (det == 0.0lf || isnan(det) || isinf(det)) {
            return false;
        }
        precise dvec3 step = dvec3(tl_det3(f, cs, ct) / det, tl_det3(cr, f, ct) / det, tl_det3(cr, cs, f) / det);
        pc -= step;
        if (isnan(pc.x) || isnan(pc.y) || isnan(pc.z) || any(greaterThan(abs(pc), dvec3(TL_NEWTON_DIVERGED)))) {
            return false;
        }
        if (all(lessThan(abs(step), dvec3(TL_NEWTON_STEP_TOL)))) {
            return true;
        }
    }
    return false;
}

// Shape::margin: >= 0 inside (the boundary included), how far outside otherwise.
double tl_margin(int shape, dvec3 pc) {
    dvec4 first = TL_BOUNDS[6 * shape];
    precise double m = first.w + first.x * pc.x + first.y * pc.y + first.z * pc.z;
    for (int b = 1; b < TL_N_BOUNDS[shape]; b++) {
        dvec4 bound = TL_BOUNDS[6 * shape + b];
        precise double mb = bound.w + bound.x * pc.x + bound.y * pc.y + bound.z * pc.z;
        m = min(m, mb);
    }
    return m;
}

// Shape::violated: the faces whose bounds pc violates, most violated first (the apex bound
// reports face -1). Returns their count.
int tl_violated(int shape, dvec3 pc, out int faces[6]) {
    double margins[6];
    int count = 0;
    for (int b = 0; b < TL_N_BOUNDS[shape]; b++) {
        dvec4 bound = TL_BOUNDS[6 * shape + b];
        precise double mb = bound.w + bound.x * pc.x + bound.y * pc.y + bound.z * pc.z;
        if (mb < 0.0lf) {
            // Insertion in ascending order of margin (stable, like the Rust sort).
            int k = count;
            while (k > 0 && margins[k - 1] > mb) {
                margins[k] = margins[k - 1];
                faces[k] = faces[k - 1];
                k--;
            }
            margins[k] = mb;
            faces[k] = TL_BOUND_FACE[6 * shape + b];
            count++;
        }
    }
    return count;
}

// ---------------------------------------------------------------------------------------------
// decompose.rs: the conforming decomposition. Each quad splits along the diagonal through its
// smallest global id; the cell is the cone from its corner of smallest global id (the apex,
// the first on ties) over the triangles of the faces without it.

// face_split: the triangles of face `face` (local corners), returns 1 or 2.
int tl_face_split(ivec4 face, uint ids[8], out ivec3 tris[2]) {
    if (face.w < 0) {
        tris[0] = face.xyz;
        return 1;
    }
    int smallest = 0;
    for (int k = 1; k < 4; k++) {
        if (ids[face[k]] < ids[face[smallest]]) {
            smallest = k;
        }
    }
    if (smallest % 2 == 0) {
        tris[0] = ivec3(face.x, face.y, face.z);
        tris[1] = ivec3(face.x, face.z, face.w);
    } else {
        tris[0] = ivec3(face.y, face.z, face.w);
        tris[1] = ivec3(face.y, face.w, face.x);
    }
    return 2;
}

// decompose: the cell's tets as local corners, right-handed for a valid cell; returns their
// count (1 tet, 2 pyramid, 3 wedge, 6 hex).
int tl_decompose(int shape, uint ids[8], out ivec4 tets[6]) {
    int apex = 0;
    for (int k = 1; k < TL_CORNERS[shape]; k++) {
        if (ids[k] < ids[apex]) {
            apex = k;
        }
    }
    int count = 0;
    for (int f = 0; f < TL_N_FACES[shape]; f++) {
        ivec4 face = TL_FACES[6 * shape + f];
        if (face.x == apex || face.y == apex || face.z == apex || face.w == apex) {
            continue;
        }
        ivec3 tris[2];
        int n = tl_face_split(face, ids, tris);
        for (int j = 0; j < n; j++) {
            // (a, b, c) faces outward, so the apex lies behind it: (a, c, b, apex) is right-handed.
            tets[count] = ivec4(tris[j].x, tris[j].z, tris[j].y, apex);
            count++;
        }
    }
    return count;
}

// ---------------------------------------------------------------------------------------------
// Interpolation weights of the quadratic cells (values only: location is by the corners).
// Node orders are VTK's; w has one weight per node.

// lattice.rs: the 1-D Lagrange polynomial of node a on 0, 1/p, ..., 1, and the simplex factor
// prod_{m<a} (p lambda - m)/(m + 1).
double tl_line(int p, int a, double x) {
    precise double v = 1.0lf;
    for (int m = 0; m <= p; m++) {
        if (m != a) {
            v = (x * double(p) - double(m)) * v * (1.0lf / (double(a) - double(m)));
        }
    }
    return v;
}

double tl_simplex(int p, int a, double lambda) {
    precise double v = 1.0lf;
    for (int m = 0; m < a; m++) {
        v = (lambda * double(p) - double(m)) * v * (1.0lf / double(m + 1));
    }
    return v;
}

// The order-2 lattices (lattice::vtk_tet(2), vtk_wedge(2), vtk_hex(2)): node i at lattice / 2.
const ivec3 TL_TET10[10] = ivec3[10](
    ivec3(0, 0, 0), ivec3(2, 0, 0), ivec3(0, 2, 0), ivec3(0, 0, 2), ivec3(1, 0, 0),
    ivec3(1, 1, 0), ivec3(0, 1, 0), ivec3(0, 0, 1), ivec3(1, 0, 1), ivec3(0, 1, 1));
const ivec3 TL_WEDGE18[18] = ivec3[18](
    ivec3(0, 0, 0), ivec3(2, 0, 0), ivec3(0, 2, 0), ivec3(0, 0, 2), ivec3(2, 0, 2), ivec3(0, 2, 2),
    ivec3(1, 0, 0), ivec3(1, 1, 0), ivec3(0, 1, 0), ivec3(1, 0, 2), ivec3(1, 1, 2), ivec3(0, 1, 2),
    ivec3(0, 0, 1), ivec3(2, 0, 1), ivec3(0, 2, 1), ivec3(1, 0, 1), ivec3(1, 1, 1), ivec3(0, 1, 1));
const ivec3 TL_HEX27[27] = ivec3[27](
    ivec3(0, 0, 0), ivec3(2, 0, 0), ivec3(2, 2, 0), ivec3(0, 2, 0), ivec3(0, 0, 2), ivec3(2, 0, 2),
    ivec3(2, 2, 2), ivec3(0, 2, 2), ivec3(1, 0, 0), ivec3(2, 1, 0), ivec3(1, 2, 0), ivec3(0, 1, 0),
    ivec3(1, 0, 2), ivec3(2, 1, 2), ivec3(1, 2, 2), ivec3(0, 1, 2), ivec3(0, 0, 1), ivec3(2, 0, 1),
    ivec3(2, 2, 1), ivec3(0, 2, 1), ivec3(0, 1, 1), ivec3(2, 1, 1), ivec3(1, 0, 1), ivec3(1, 2, 1),
    ivec3(1, 1, 0), ivec3(1, 1, 2), ivec3(1, 1, 1));

// LatticeCell::eval for the quadratic tet (VTK 24): simplex factors in (r, s, t, 1 - r - s - t).
void tl_quadratic_tet(dvec3 pc, out double w[27]) {
    precise double u = 1.0lf - pc.x - pc.y - pc.z;
    for (int i = 0; i < 10; i++) {
        ivec3 l = TL_TET10[i];
        w[i] = tl_simplex(2, l.x, pc.x) * tl_simplex(2, l.y, pc.y) * tl_simplex(2, l.z, pc.z) * tl_simplex(2, 2 - l.x - l.y - l.z, u);
    }
}

// LatticeCell::eval for the biquadratic-quadratic wedge (VTK 32): triangle times line.
void tl_biquadratic_wedge(dvec3 pc, out double w[27]) {
    precise double u = 1.0lf - pc.x - pc.y;
    for (int i = 0; i < 18; i++) {
        ivec3 l = TL_WEDGE18[i];
        w[i] = tl_simplex(2, l.x, pc.x) * tl_simplex(2, l.y, pc.y) * tl_simplex(2, 2 - l.x - l.y, u) * tl_line(2, l.z, pc.z);
    }
}

// LatticeCell::eval for the triquadratic hex (VTK 29).
void tl_triquadratic_hex(dvec3 pc, out double w[27]) {
    for (int i = 0; i < 27; i++) {
        ivec3 l = TL_HEX27[i];
        w[i] = tl_line(2, l.x, pc.x) * tl_line(2, l.y, pc.y) * tl_line(2, l.z, pc.z);
    }
}

// quadratic_hex.rs (VTK 25): the serendipity hex in xi = 2 pc - 1; node i of the 20 is the
// order-2 lattice point TL_HEX27[i], so c = lattice - 1 is -1, 0 or 1.
void tl_quadratic_hex(dvec3 pc, out double w[27]) {
    precise dvec3 x = pc * 2.0lf - 1.0lf;
    for (int i = 0; i < 20; i++) {
        dvec3 c = dvec3(TL_HEX27[i] - ivec3(1));
        precise dvec3 lin = 1.0lf + x * c;
        if (c.x == 0.0lf) {
            w[i] = (1.0lf - x.x * x.x) * lin.y * lin.z * 0.25lf;
        } else if (c.y == 0.0lf) {
            w[i] = (1.0lf - x.y * x.y) * lin.z * lin.x * 0.25lf;
        } else if (c.z == 0.0lf) {
            w[i] = (1.0lf - x.z * x.z) * lin.x * lin.y * 0.25lf;
        } else {
            w[i] = lin.x * lin.y * lin.z * (x.x * c.x + x.y * c.y + x.z * c.z - 2.0lf) * 0.125lf;
        }
    }
}

// quadratic_wedge.rs (VTK 26).
void tl_quadratic_wedge(dvec3 pc, out double w[27]) {
    precise double r = pc.x, s = pc.y, t = pc.z;
    precise double u = 1.0lf - r - s, tm = 1.0lf - t;
    w[0] = u * tm * (0.5lf - r - s - t) * 2.0lf;
    w[1] = r * tm * (r - t - 0.5lf) * 2.0lf;
    w[2] = s * tm * (s - t - 0.5lf) * 2.0lf;
    w[3] = u * t * (t - r - s - 0.5lf) * 2.0lf;
    w[4] = r * t * (r + t - 1.5lf) * 2.0lf;
    w[5] = s * t * (s + t - 1.5lf) * 2.0lf;
    w[6] = r * u * tm * 4.0lf;
    w[7] = r * s * tm * 4.0lf;
    w[8] = u * s * tm * 4.0lf;
    w[9] = r * u * t * 4.0lf;
    w[10] = r * s * t * 4.0lf;
    w[11] = u * s * t * 4.0lf;
    w[12] = u * t * tm * 4.0lf;
    w[13] = r * t * tm * 4.0lf;
    w[14] = s * t * tm * 4.0lf;
}

// quadratic_pyramid.rs (VTK 27, current VTK's functions) in xi = 2 pc - 1.
void tl_quadratic_pyramid(dvec3 pc, out double w[27]) {
    precise double x = pc.x * 2.0lf - 1.0lf, y = pc.y * 2.0lf - 1.0lf, z = pc.z * 2.0lf - 1.0lf;
    precise double xm = 1.0lf - x, xp = 1.0lf + x, ym = 1.0lf - y, yp = 1.0lf + y, zm = 1.0lf - z;
    precise double x2 = 1.0lf - x * x, y2 = 1.0lf - y * y, z2 = 1.0lf - z * z;
    w[0] = -(xm * ym * zm) * (4.0lf + x * 3.0lf + y * 3.0lf + x * y * 2.0lf + z * 2.0lf + x * z + y * z + x * y * z * 2.0lf) * (1.0lf / 16.0lf);
    w[1] = -(xp * ym * zm) * (4.0lf - x * 3.0lf + y * 3.0lf - x * y * 2.0lf + z * 2.0lf - x * z + y * z - x * y * z * 2.0lf) * (1.0lf / 16.0lf);
    w[2] = -(xp * yp * zm) * (4.0lf - x * 3.0lf - y * 3.0lf + x * y * 2.0lf + z * 2.0lf - x * z - y * z + x * y * z * 2.0lf) * (1.0lf / 16.0lf);
    w[3] = -(xm * yp * zm) * (4.0lf + x * 3.0lf - y * 3.0lf - x * y * 2.0lf + z * 2.0lf + x * z - y * z - x * y * z * 2.0lf) * (1.0lf / 16.0lf);
    w[4] = z * (1.0lf + z) * 0.5lf;
    w[5] = x2 * ym * zm * (2.0lf + y + y * z) * 0.125lf;
    w[6] = xp * y2 * zm * (2.0lf - x - x * z) * 0.125lf;
    w[7] = x2 * yp * zm * (2.0lf - y - y * z) * 0.125lf;
    w[8] = xm * y2 * zm * (2.0lf + x + x * z) * 0.125lf;
    w[9] = xm * ym * z2 * 0.25lf;
    w[10] = xp * ym * z2 * 0.25lf;
    w[11] = xp * yp * z2 * 0.25lf;
    w[12] = xm * yp * z2 * 0.25lf;
}

#endif // TL_F64
#endif // TL_CELLS_GLSL
