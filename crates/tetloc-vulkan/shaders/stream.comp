#version 460
// Stream tracing on soft-bvh (tetloc_core::ops::trace on the GPU): one invocation per particle
// runs its line, vtkStreamTracer's loop with a fixed RK4 step, in the order of operations of
// tetloc_core::ops::trace::particle: in f64 as there (TL_F64, devices with shaderFloat64),
// else in f32; in the mesh's working frame. Lookups are f32, as the locators take points. Every lookup
// first walks through face neighbours from the particle's last tet (its hint: a step moves a
// fraction of a tet, so the walk is short); only when the walk fails does the entry grid and
// BVH search run. A point the walk puts on a face of its tet is searched afresh too, so ties
// follow the locator's rule.
//
// Lines come out in segments: a launch advances each particle until it has written
// counts.y points (or ended), saves its state, and the host reads the segment and launches
// the next.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "interface.glsl" // generated from src/interface.rs (build.rs)
#include "common/mesh.glsl"
#include "common/tet.glsl"
#include "common/soft_bvh.glsl"
#include "common/walk.glsl"

layout(local_size_x_id = TL_SC_WORKGROUP) in;

layout(std430, binding = TL_B_STREAM) readonly buffer TlStream { TlStreamParams sp; };
// x, y, z of each vertex (OUT_VERTEX) or tet (OUT_CELL).
layout(std430, binding = TL_B_STREAM_VECTOR) readonly buffer TlVector { float tl_vector[]; };
layout(std430, binding = TL_B_STREAM_PARTICLES) buffer TlParticles { TlStreamParticle tl_particles[]; };
// Per particle counts.y slots: position (working frame), integration time.
layout(std430, binding = TL_B_STREAM_LINES) writeonly buffer TlLines { vec4 tl_lines[]; };
// The tet of each of those points: the one its velocity came from.
layout(std430, binding = TL_B_STREAM_TETS) writeonly buffer TlLineTets { int tl_line_tets[]; };
// FIELD_COUNT line fields at each of those points.
layout(std430, binding = TL_B_STREAM_VALUES) writeonly buffer TlLineValues { float tl_line_values[]; };

// The last lookup that found a tet: its point, corners and barycentrics.
vec3 tl_found_p;
uvec4 tl_found_ids;
vec4 tl_found_bary;

// Records point x at integration time t, found in tet `tet` by the last lookup (at x), with
// the line fields there as OUT_FIELDS samples them (answer.glsl).
void tl_record_point(uint at, vec3 x, float t, int tet) {
    tl_lines[at] = vec4(x, t);
    tl_line_tets[at] = tet;
    if (FIELD_COUNT > 0u) {
        vec4 b = tl_value_bary(tl_found_ids, tl_found_p, tl_found_bary);
        for (uint f = 0u; f < FIELD_COUNT; f++) {
            bool cell = ((FIELD_CELLS >> f) & 1u) != 0u;
            tl_line_values[at * FIELD_COUNT + f] =
                tl_field_value(f, cell, tet, tl_found_ids, cell ? tl_found_bary : b);
        }
    }
}

uint tl_lookups = 0u, tl_fallbacks = 0u;

// The integrator's numbers: f64 where the device has it (as the CPU integrates), else f32;
// stored in StreamParticle as bit pairs.
#ifdef TL_F64
#define treal double
#define tvec3 dvec3
treal tl_real(uint lo, uint hi) { return packDouble2x32(uvec2(lo, hi)); }
uvec2 tl_bits(treal x) { return unpackDouble2x32(x); }
#define TL_SIXTH (1.0lf / 6.0lf)
#define TL_THIRD (1.0lf / 3.0lf)
#else
#define treal float
#define tvec3 vec3
treal tl_real(uint lo, uint hi) { return uintBitsToFloat(lo); }
uvec2 tl_bits(treal x) { return uvec2(floatBitsToUint(x), 0u); }
#define TL_SIXTH (1.0 / 6.0)
#define TL_THIRD (1.0 / 3.0)
#endif

vec3 tl_vector3(uint i) {
    return vec3(tl_vector[3u * i], tl_vector[3u * i + 1u], tl_vector[3u * i + 2u]);
}

// The raw velocity at p (false: p is outside the mesh), from the tet of the last lookup.
bool tl_velocity(tvec3 at, inout int hint, out vec3 v) {
    vec3 p = vec3(at); // the locators' f32 point
    uvec4 ids;
    vec4 bary;
    int tet = TL_OUTSIDE;
    tl_lookups++;
    if (STREAM_HINT && hint >= 0) {
        tet = tl_walk(hint, p, WALK_MAX, ids, bary);
        // Strictly inside: the only tet holding p, the one the fresh search would find too.
        if (tet >= 0 && !all(greaterThan(bary, vec4(0.0)))) {
            tet = TL_OUTSIDE;
        }
    }
    if (tet < 0) {
        tl_fallbacks++;
        tet = tl_locate(p, ids, bary);
    }
    if (tet < 0) {
        v = vec3(0.0);
        return false;
    }
    hint = tet;
    tl_found_p = p;
    tl_found_ids = ids;
    tl_found_bary = bary;
    if (OUTPUT_MODE == TL_OUT_CELL) {
        v = tl_vector3(uint(tet));
    } else {
        precise vec3 w = bary.x * tl_vector3(ids.x) + bary.y * tl_vector3(ids.y)
            + bary.z * tl_vector3(ids.z) + bary.w * tl_vector3(ids.w);
        v = w;
    }
    return true;
}

treal tl_norm(tvec3 v) {
    precise treal sq = v.x * v.x + v.y * v.y + v.z * v.z;
    return sqrt(sq);
}

// The unit vector (zero stays zero, as vtkMath::Normalize leaves it).
tvec3 tl_unit_or_zero(vec3 raw) {
    tvec3 v = tvec3(raw);
    treal n = tl_norm(v);
    precise tvec3 u = v / n;
    return n == 0.0 ? v : u;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= sp.counts.x) {
        return;
    }
    TlStreamParticle q = tl_particles[i];
    int hint = q.state.x, steps = q.state.y, status = q.state.z, points = q.state.w;
    vec3 v = q.v.xyz;
    tvec3 x = tvec3(tl_real(q.x_xy.x, q.x_xy.y), tl_real(q.x_xy.z, q.x_xy.w), tl_real(q.x_z_t.x, q.x_z_t.y));
    treal t = tl_real(q.x_z_t.z, q.x_z_t.w), len = tl_real(q.len_walk.x, q.len_walk.y);
    treal sign = q.counts.y != 0u ? -1.0 : 1.0;
#ifdef TL_F64
    treal step = tl_real(sp.limits64_a.x, sp.limits64_a.y), max_length = tl_real(sp.limits64_a.z, sp.limits64_a.w);
    treal max_time = tl_real(sp.limits64_b.x, sp.limits64_b.y), terminal = tl_real(sp.limits64_b.z, sp.limits64_b.w);
#else
    treal step = sp.limits.x, max_length = sp.limits.y, max_time = sp.limits.z, terminal = sp.limits.w;
#endif
    treal scale = treal(sp.frame.x);
    uint seg = sp.counts.y, base = i * seg, written = 0u;

    // One lookup a turn of the loop, at `at`, and `stage` says what it is for: the seed's,
    // RK4's second to fourth stage, or the step's end. One call site of tl_velocity, so the
    // walk and the search are compiled once, not five times (the pipeline's compile time).
    const int START = 0, SEED = 1, K2 = 2, K3 = 3, K4 = 4, END = 5;
    int stage = START;
    precise tvec3 at = x;
    precise treal trial = 0.0, h = 0.0;
    treal speed = 0.0;
    tvec3 k1 = tvec3(0.0), k2 = tvec3(0.0), k3 = tvec3(0.0);
    int limit = 0;
    if (status == TL_STREAM_SEED) {
        x = tvec3(q.seed.xyz);
        t = 0.0;
        len = 0.0;
        at = x;
        stage = SEED;
    }
    while (true) {
        if (stage == START) {
            // At a recorded point x with velocity v: one step, while the segment has room.
            if (status != TL_STREAM_LIVE || written >= seg) {
                break;
            }
            speed = tl_norm(tvec3(v));
            if (points > 1 && (speed == 0.0 || speed <= terminal)) {
                status = TL_REASON_STAGNATION;
                break;
            }
            // The top of vtkStreamTracer's loop: the limits, then the step.
            if (len >= max_length) {
                status = TL_REASON_OUT_OF_LENGTH;
            } else if (abs(t) >= max_time) {
                status = TL_REASON_OUT_OF_TIME;
            } else if (uint(steps) > sp.counts.z) {
                status = TL_REASON_OUT_OF_STEPS;
            } else if (speed == 0.0 || speed <= terminal) {
                status = TL_REASON_STAGNATION;
            }
            if (status != TL_STREAM_LIVE) {
                break;
            }
            steps++;
            // A step that would pass the length or the time limit is shortened to land on it.
            trial = sign * step;
            limit = 0;
            if (len + abs(trial) > max_length) {
                trial = sign * (max_length - len);
                limit = TL_REASON_OUT_OF_LENGTH;
            }
            if (abs(t) + abs(trial) / speed > max_time) {
                trial = sign * (max_time - abs(t)) * speed;
                limit = TL_REASON_OUT_OF_TIME;
            }
            h = trial * scale; // the step in working-frame lengths (exact: scale is a power of 2)
            k1 = tl_unit_or_zero(v);
            at = x + h * (0.5 * k1);
            stage = K2;
        }
        vec3 w;
        bool inside = tl_velocity(at, hint, w);
        if (stage == SEED) {
            v = w;
            if (inside) {
                tl_record_point(base + written++, vec3(x), float(t), hint);
                points = 1;
                status = TL_STREAM_LIVE;
            } else {
                status = TL_REASON_OUT_OF_DOMAIN; // no line: the seed is outside
            }
            stage = START;
            continue;
        }
        if (!inside) {
            if (stage == END) {
                v = w; // the step's end is outside: not recorded
            }
            status = TL_REASON_OUT_OF_DOMAIN;
            break;
        }
        if (stage == K2) {
            k2 = tl_unit_or_zero(w);
            at = x + h * (0.5 * k2);
            stage = K3;
        } else if (stage == K3) {
            k3 = tl_unit_or_zero(w);
            at = x + h * k3;
            stage = K4;
        } else if (stage == K4) {
            tvec3 k4 = tl_unit_or_zero(w);
            precise tvec3 next = x + h * (((TL_SIXTH * k1 + TL_THIRD * k2) + TL_THIRD * k3) + TL_SIXTH * k4);
            treal moved = tl_norm(next - x) / scale;
            if (trial == 0.0 || moved / abs(trial) <= terminal) {
                status = TL_REASON_STAGNATION;
                break;
            }
            t += trial / speed;
            len += abs(trial);
            // Landed on a limit: exactly on it, so the loop ends there.
            if (limit == TL_REASON_OUT_OF_LENGTH) {
                len = max_length;
            } else if (limit == TL_REASON_OUT_OF_TIME) {
                t = sign * max_time;
            }
            x = next;
            at = x;
            stage = END;
        } else {
            v = w;
            tl_record_point(base + written++, vec3(x), float(t), hint);
            points++;
            stage = START;
        }
    }
    q.v = vec4(v, 0.0);
    q.x_xy = uvec4(tl_bits(x.x), tl_bits(x.y));
    q.x_z_t = uvec4(tl_bits(x.z), tl_bits(t));
    q.len_walk = uvec4(tl_bits(len), q.len_walk.z + tl_walk_visits, 0u);
    q.state = ivec4(hint, steps, status, points);
    q.counts = uvec4(written, q.counts.y, q.counts.z + tl_lookups, q.counts.w + tl_fallbacks);
    tl_particles[i] = q;
}
