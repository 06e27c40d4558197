// geom::predicates::det_and_permanent: the 3x3 determinant of the rows a - d, b - d, c - d,
// its permanent (the sum of its products' magnitudes, which the error bounds scale) and the
// rows. One text for f32 (tl_orient_f32, tl_orient3d_local) and f64 (tl_orient3d_stage_a),
// as the Rust is one generic: one order of operations (geom::orient_f32's too).
#ifndef TL_DET_GLSL
#define TL_DET_GLSL

// tl_det_and_permanent for scalar T and vector V (GLSL has no generics), with the rows and
// without.
#define TL_DET_AND_PERMANENT(T, V) \
T tl_det_and_permanent(V a, V b, V c, V d, out T permanent, out V ad, out V bd, out V cd) { \
    precise T adx = a.x - d.x, ady = a.y - d.y, adz = a.z - d.z; \
    precise T bdx = b.x - d.x, bdy = b.y - d.y, bdz = b.z - d.z; \
    precise T cdx = c.x - d.x, cdy = c.y - d.y, cdz = c.z - d.z; \
    precise T bc = bdy * cdz, cb = cdy * bdz; \
    precise T ca = cdy * adz, ac = ady * cdz; \
    precise T ab = ady * bdz, ba = bdy * adz; \
    precise T det = adx * (bc - cb) + bdx * (ca - ac) + cdx * (ab - ba); \
    precise T perm = (abs(bc) + abs(cb)) * abs(adx) + (abs(ca) + abs(ac)) * abs(bdx) + (abs(ab) + abs(ba)) * abs(cdx); \
    permanent = perm; \
    ad = V(adx, ady, adz); \
    bd = V(bdx, bdy, bdz); \
    cd = V(cdx, cdy, cdz); \
    return det; \
} \
T tl_det_and_permanent(V a, V b, V c, V d, out T permanent) { \
    V ad, bd, cd; \
    return tl_det_and_permanent(a, b, c, d, permanent, ad, bd, cd); \
}

TL_DET_AND_PERMANENT(float, vec3)
#ifdef TL_F64
TL_DET_AND_PERMANENT(double, dvec3)
#endif

#endif
