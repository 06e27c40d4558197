// Where a kernel's points come from and where its answers go: host points from the
// queries buffer, or samples generated in the kernel as in the paper (`uniform`: the centre
// of every tet; `random`: a random point in a random tet) plus `bbox` (uniform in the
// mesh's bounding box) and `grid` (a regular grid's points, x fastest). Generated points
// use only +, -, * (precise), so the CPU can reproduce them; RECORD_POINTS writes them out
// for the tests.
#ifndef TL_SAMPLES_GLSL
#define TL_SAMPLES_GLSL

layout(std430, binding = TL_B_QUERIES) buffer TlQueries { float tl_queries[]; };
layout(std430, binding = TL_B_OUT) writeonly buffer TlOut { uint tl_out[]; };
// With ORDERED, a launch locates the points order.comp sorted along the Morton curve and
// writes each answer at the point's original index.
layout(std430, binding = TL_B_ORDER_POINTS) buffer TlOrderPoints { float tl_order_points[]; };
layout(std430, binding = TL_B_ORDER_PERM) buffer TlOrderPerm { uint tl_order_perm[]; };
// The grid's coordinates per axis (x values, then y, then z), computed on the host as
// ops::ImageGrid::point64 does and rounded to the working frame: the points a query of the
// grid's points sends (then, for a grid of f64 points, each coordinate's residual).
layout(std430, binding = TL_B_GRID_AXES) readonly buffer TlGridAxes { float tl_grid_axes[]; };

// PCG hash (O'Neill's RXS-M-XS output of one LCG step): cheap and well mixed.
uint tl_hash(uint x) {
    uint state = x * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// A uniform float in [0, 1) with 24 random bits; advances the state.
float tl_unit(inout uint s) {
    s = tl_hash(s);
    return float(s >> 8) * (1.0 / 16777216.0);
}

// The random state of random sample `i` of this launch (by its global index: chunked
// launches give the same points), and the tet that state picks (the point is made in it).
uint tl_random_state(uint i) {
    return tl_hash((params.counts.y + i) ^ tl_hash(params.counts.w));
}
uint tl_random_tet(uint s) {
    return tl_hash(s) % params.counts.z;
}

// The sample point for point `i` of this launch.
vec3 tl_sample(uint i) {
    uint g = params.counts.y + i; // global sample index: chunked launches give the same points
    if (ORDERED) {
        return vec3(tl_order_points[3 * i], tl_order_points[3 * i + 1], tl_order_points[3 * i + 2]);
    } else if (SAMPLE_MODE == TL_SAMPLE_HOST) {
        return vec3(tl_queries[3 * i], tl_queries[3 * i + 1], tl_queries[3 * i + 2]);
    } else if (SAMPLE_MODE == TL_SAMPLE_CENTERS) {
        // Mesh::tet_center: the vertices summed in order, then scaled.
        uvec4 t = tl_tet(g);
        precise vec3 c = (((tl_vertex(t.x) + tl_vertex(t.y)) + tl_vertex(t.z)) + tl_vertex(t.w)) * 0.25;
        return c;
    } else if (SAMPLE_MODE == TL_SAMPLE_RANDOM) {
        uint s = tl_random_state(i);
        uvec4 t = tl_tet(tl_random_tet(s));
        precise float a = tl_unit(s), b = tl_unit(s), c = tl_unit(s);
        // Fold the unit cube into the tet's parameter domain (Rocchini & Cignoni).
        if (a + b > 1.0) {
            a = 1.0 - a;
            b = 1.0 - b;
        }
        if (b + c > 1.0) {
            float tmp = c;
            c = 1.0 - a - b;
            b = 1.0 - tmp;
        } else if (a + b + c > 1.0) {
            float tmp = c;
            c = a + b + c - 1.0;
            a = 1.0 - b - tmp;
        }
        precise float w = 1.0 - a - b - c;
        precise vec3 p = w * tl_vertex(t.x) + a * tl_vertex(t.y) + b * tl_vertex(t.z) + c * tl_vertex(t.w);
        return p;
    } else if (SAMPLE_MODE == TL_SAMPLE_GRID) {
        uint nx = params.grid.x, ny = params.grid.y;
        uint z = params.grid.z + g / (nx * ny);
        return vec3(tl_grid_axes[g % nx], tl_grid_axes[nx + (g / nx) % ny], tl_grid_axes[nx + ny + z]);
    } else {
        uint s = tl_hash(g ^ tl_hash(params.counts.w ^ 0x9e3779b9u));
        precise vec3 u = vec3(tl_unit(s), tl_unit(s), tl_unit(s));
        precise vec3 p = params.lo_tmin.xyz + u * (params.hi_tmax.xyz - params.lo_tmin.xyz);
        return p;
    }
}

// The residual of point i of this launch: what its coordinates lack in f32 (working frame).
// A grid of f64 points (params.grid.w: where its residual axes start, after the axes; 0 for
// none) keeps each coordinate's residual beside it; every other point is exact (0).
vec3 tl_sample_residual(uint i) {
    if (SAMPLE_MODE != TL_SAMPLE_GRID || ORDERED || params.grid.w == 0u) {
        return vec3(0.0);
    }
    uint g = params.counts.y + i;
    uint nx = params.grid.x, ny = params.grid.y, at = params.grid.w;
    uint z = params.grid.z + g / (nx * ny);
    return vec3(tl_grid_axes[at + g % nx], tl_grid_axes[at + nx + (g / nx) % ny], tl_grid_axes[at + nx + ny + z]);
}

void tl_record(uint i, vec3 p) {
    if (RECORD_POINTS) {
        tl_queries[3 * i] = p.x;
        tl_queries[3 * i + 1] = p.y;
        tl_queries[3 * i + 2] = p.z;
    }
}

// The answer for point i: the tet id (TL_OUTSIDE outside) or the field value (NaN outside).
void tl_store(uint i, int tet, float value) {
    if (ORDERED) {
        i = tl_order_perm[i];
    }
    tl_out[i] = OUTPUT_MODE == TL_OUT_IDS ? uint(tet) : floatBitsToUint(value);
}

#endif
