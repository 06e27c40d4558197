#version 460
// Locate once, interpolate many, on the GPU (issue 32; src/weights.rs): out = W · values for a
// batch of steps, W the CSR map of tetloc_core::ops::Weights (row i: the weights of point i's
// cell over the mesh's vertices; empty outside, whose values are NaN). One invocation a point.
// With TL_F64 the weights are f64 and each sum runs in f64 from -0.0, product after product,
// as Weights::apply's does (the same values, bit for bit); without it, in f32.
// params.counts: points, vertices, components a value (k), steps in this batch.
#extension GL_GOOGLE_include_directive : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)

layout(local_size_x = 256) in;

layout(std430, binding = TL_B_WEIGHTS_ROWS) readonly buffer TlRows { uint tl_rows[]; };
layout(std430, binding = TL_B_WEIGHTS_COLS) readonly buffer TlCols { uint tl_cols[]; };
#ifdef TL_F64
layout(std430, binding = TL_B_WEIGHTS_VALUES) readonly buffer TlWeights { double tl_w[]; };
#else
layout(std430, binding = TL_B_WEIGHTS_VALUES) readonly buffer TlWeights { float tl_w[]; };
#endif
// The batch's steps, each n_vertices x k values (vertex after vertex), and their products, each
// n_points x k.
layout(std430, binding = TL_B_STEP_VALUES) readonly buffer TlStepValues { float tl_values[]; };
layout(std430, binding = TL_B_STEP_OUT) writeonly buffer TlStepOut { float tl_products[]; };

void main() {
    uint i = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
    uint n = params.counts.x, nv = params.counts.y, k = params.counts.z;
    if (i >= n) {
        return;
    }
    uint a = tl_rows[i], b = tl_rows[i + 1u];
    for (uint s = 0u; s < params.counts.w; s++) {
        for (uint c = 0u; c < k; c++) {
#ifdef TL_F64
            precise double sum = -0.0LF;
            for (uint e = a; e < b; e++) {
                precise double t = tl_w[e] * double(tl_values[(s * nv + tl_cols[e]) * k + c]);
                sum = sum + t;
            }
#else
            precise float sum = -0.0;
            for (uint e = a; e < b; e++) {
                precise float t = tl_w[e] * tl_values[(s * nv + tl_cols[e]) * k + c];
                sum = sum + t;
            }
#endif
            tl_products[(s * n + i) * k + c] = a == b ? uintBitsToFloat(0x7fc00000u) : float(sum);
        }
    }
}
