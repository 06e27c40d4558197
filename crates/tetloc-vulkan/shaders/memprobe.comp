#version 460
// Random reads over growing spans of device memory (issue 12: why random queries collapse on
// large meshes). The array is split over buffers exactly like the mesh's tets (device::Split,
// mesh.glsl): element i is a uvec4, a tet record, in buffer i / TETS_CHUNK. Modes
// (params.counts.w): MEMPROBE_INIT writes element i = uvec4(i); MEMPROBE_SEQUENTIAL reads
// coalesced (the bandwidth baseline); MEMPROBE_INDEPENDENT reads hashed addresses that do not
// depend on each other (throughput-bound, like many samples in flight); MEMPROBE_DEPENDENT
// takes each address from the value just read (latency-bound, like a walk's next tet).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_nonuniform_qualifier : require
#include "interface.glsl"

layout(local_size_x = 256) in;
layout(std430, binding = TL_B_TETS) buffer Part0 { uvec4 v[]; } part0;
layout(std430, binding = TL_B_TETS_HI) buffer PartHi { uvec4 v[]; } parts[TL_MAX_CHUNKS - 1];
layout(std430, binding = TL_B_OUT) writeonly buffer Sums { uint sums[]; };

// A 32-bit integer hash (lowbias32); memprobe.rs mirrors it for the tests.
uint tl_hash(uint x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

uvec4 load(uint i) {
    if (TETS_CHUNK == 0u || i < TETS_CHUNK) {
        return part0.v[i];
    }
    return parts[nonuniformEXT(i / TETS_CHUNK - 1u)].v[i % TETS_CHUNK];
}

void store(uint i, uvec4 x) {
    if (TETS_CHUNK == 0u || i < TETS_CHUNK) {
        part0.v[i] = x;
    } else {
        parts[nonuniformEXT(i / TETS_CHUNK - 1u)].v[i % TETS_CHUNK] = x;
    }
}

void main() {
    uint id = gl_GlobalInvocationID.x;
    uint n = params.counts.x, reads = params.counts.y, span = params.counts.z, mode = params.counts.w;
    if (mode == TL_MEMPROBE_INIT) {
        // Grid-stride over the span; the host keeps span + n below 2^32.
        for (uint i = id; i < span; i += n) {
            store(i, uvec4(i));
        }
        return;
    }
    if (id >= n) {
        return;
    }
    uint sum = 0u;
    uint i = mode == TL_MEMPROBE_SEQUENTIAL ? id % span : tl_hash(id) % span;
    for (uint k = 0u; k < reads; ++k) {
        uint v = load(i).x;
        sum += v;
        if (mode == TL_MEMPROBE_SEQUENTIAL) {
            i = (i + n) % span;
        } else if (mode == TL_MEMPROBE_DEPENDENT) {
            i = tl_hash(v + id * 0x9e3779b9u + k) % span;
        } else {
            i = tl_hash(id * reads + k + 1u) % span;
        }
    }
    sums[id] = sum;
}
