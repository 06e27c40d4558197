// The sample-based volume ray marcher (paper, section 6.3) that every marcher stage shares:
// the camera ray of a pixel, clipping to the mesh box, samples at t = t0 + (k + 1/2) step,
// the transfer function, front-to-back compositing to 99 % opacity, exact empty-space
// skipping, and the surface that ends a ray. A line-by-line mirror of tetloc-render's host
// marcher (render.rs, camera.rs, skip.rs, tf.rs), so both give the same image.
//
// The stage defines `float tl_march_sample(vec3 p)`: the field value at p, NaN outside.
// Needs interface.glsl first (TlMarchParams, TlPixel, TL_MARCH_*).
#ifndef TL_MARCH_GLSL
#define TL_MARCH_GLSL

layout(std430, binding = TL_B_MARCH) readonly buffer TlMarch { TlMarchParams tl_m; };
// Linear RGB and step alpha, linearly filtered (tf.rs TfTable).
layout(std430, binding = TL_B_TF) readonly buffer TlTf { vec4 tl_tf[]; };
// One bit per cell, then one bit per block (skip.rs OccupancyGrid).
layout(std430, binding = TL_B_OCCUPANCY) readonly buffer TlOcc { uint tl_occ[]; };
// Per pixel: where the surface is hit (+inf: nowhere) and its shaded linear colour.
layout(std430, binding = TL_B_SURFACE) readonly buffer TlSurface { vec4 tl_surface[]; };
layout(std430, binding = TL_B_PIXELS) writeonly buffer TlPixels { TlPixel tl_pixels[]; };
// The same buffer with TL_MARCH_RGBA8: one packed 8-bit sRGB RGBA per pixel.
layout(std430, binding = TL_B_PIXELS) writeonly buffer TlPixels8 { uint tl_pixels8[]; };

// tetloc-render's colorspace::linear_to_srgb.
vec3 tl_linear_to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, c * 12.92, lessThanEqual(c, vec3(0.0031308)));
}

float tl_march_sample(vec3 p);

bool tl_bit(uint i) {
    return (tl_occ[i >> 5] & (1u << (i & 31u))) != 0u;
}

// OccupancyGrid::cell_of: false outside the bounds (NaN included).
bool tl_occ_cell(vec3 p, out uvec3 c) {
    c = uvec3(0u);
    if (!(all(greaterThanEqual(p, tl_m.occ_lo_margin.xyz)) && all(lessThanEqual(p, tl_m.occ_hi.xyz)))) {
        return false;
    }
    precise vec3 s = (p - tl_m.occ_lo_margin.xyz) * tl_m.occ_inv.xyz;
    c = min(uvec3(s), tl_m.occ_dims.xyz - 1u);
    return true;
}

bool tl_occupied(uvec3 c) {
    uvec3 d = tl_m.occ_dims.xyz;
    return tl_bit((c.z * d.y + c.y) * d.x + c.x);
}

bool tl_block_occupied(uvec3 c) {
    uvec3 b = c / tl_m.occ_blocks.w;
    uvec3 d = tl_m.occ_blocks.xyz;
    return tl_bit(32u * tl_m.occ_dims.w + (b.z * d.y + b.y) * d.x + b.x);
}

// OccupancyGrid::skip_to: for p = o + t d in empty cell c, a parameter before which the ray
// stays in that empty cell (or its empty block).
float tl_skip_to(vec3 o, vec3 d, float t, uvec3 c) {
    bool block_empty = !tl_block_occupied(c);
    uint width = block_empty ? tl_m.occ_blocks.w : 1u;
    uvec3 first = block_empty ? c / width * width : c;
    precise vec3 lo = tl_m.occ_lo_margin.xyz + vec3(first) * tl_m.occ_cell.xyz;
    precise vec3 hi = lo + float(width) * tl_m.occ_cell.xyz;
    float t_exit = 1.0 / 0.0;
    [[unroll]] for (int k = 0; k < 3; k++) {
        if (d[k] != 0.0) {
            float plane = d[k] > 0.0 ? hi[k] : lo[k];
            t_exit = min(t_exit, (plane - o[k]) / d[k]);
        }
    }
    precise vec3 end = o + t_exit * d;
    float scale = max(abs(t_exit), max(abs(end.x), max(abs(end.y), abs(end.z))));
    return t_exit - tl_m.occ_lo_margin.w - 1e-5 * scale;
}

// TfTable::lookup.
vec4 tl_tf_lookup(float v) {
    uint n = tl_m.size.w;
    float u = clamp((v - tl_m.box_lo_tf_lo.w) * tl_m.box_hi_tf_inv.w, 0.0, 1.0) * float(n - 1u);
    uint i = min(uint(u), n - 2u);
    float f = u - float(i);
    vec4 a = tl_tf[i], b = tl_tf[i + 1u];
    return a + (b - a) * f;
}

// camera::clip_to_box: [t0, t1] inside the box with t >= 0; false when the ray misses. An
// axis the ray is parallel to constrains nothing, unless the ray lies outside its slab.
bool tl_clip(vec3 o, vec3 d, out float t0, out float t1) {
    t0 = 0.0;
    t1 = 1.0 / 0.0;
    [[unroll]] for (int k = 0; k < 3; k++) {
        float lo = tl_m.box_lo_tf_lo[k], hi = tl_m.box_hi_tf_inv[k];
        if (d[k] == 0.0) {
            if (!(o[k] >= lo && o[k] <= hi)) {
                return false;
            }
            continue;
        }
        float inv = 1.0 / d[k];
        float a = (lo - o[k]) * inv, b = (hi - o[k]) * inv;
        t0 = max(t0, min(a, b));
        t1 = min(t1, max(a, b));
    }
    return t0 <= t1;
}

// Marches the ray of `pixel` and writes its colour and sample counts.
void tl_march(uvec2 pixel) {
    uint w = tl_m.size.x, h = tl_m.size.y;
    if (pixel.x >= w || pixel.y >= h) {
        return;
    }
    uint index = pixel.y * w + pixel.x;
    // Camera::ray: through the pixel centre, y = 0 at the top.
    float tan_y = tl_m.fwd_tan.w;
    float aspect = float(w) / float(h);
    float u = ((float(pixel.x) + 0.5) / float(w) * 2.0 - 1.0) * tan_y * aspect;
    float v = (1.0 - (float(pixel.y) + 0.5) / float(h) * 2.0) * tan_y;
    vec3 o = tl_m.eye_step.xyz;
    vec3 d = normalize(tl_m.fwd_tan.xyz + (tl_m.right_cutoff.xyz * u + tl_m.up.xyz * v));

    bool surface = (tl_m.size.z & TL_MARCH_SURFACE) != 0u;
    bool skip = (tl_m.size.z & TL_MARCH_SKIP) != 0u;
    vec4 shade = surface ? tl_surface[index] : vec4(1.0 / 0.0, 0.0, 0.0, 0.0);
    vec4 acc = vec4(0.0);
    uint samples = 0u, in_mesh = 0u;
    float step = tl_m.eye_step.w, cutoff = tl_m.right_cutoff.w;
    float t0, t1;
    if (tl_clip(o, d, t0, t1)) {
        t1 = min(t1, shade.x);
        uint n = uint(clamp(ceil((t1 - t0) / step - 0.5), 0.0, 4294967040.0));
        uint k = 0u;
        while (k < n) {
            precise float t = t0 + (float(k) + 0.5) * step;
            precise vec3 p = o + t * d;
            uvec3 c;
            if (skip && !(tl_occ_cell(p, c) && tl_occupied(c))) {
                // Empty cell (or outside the bounds, where tl_skip_to's cell is unused: the
                // host returns t there, and so do we by stepping one sample).
                if (tl_occ_cell(p, c)) {
                    float next = ceil((tl_skip_to(o, d, t, c) - t0) / step - 0.5);
                    k = next > float(k + 1u) ? uint(min(next, float(n))) : k + 1u;
                } else {
                    k++;
                }
                continue;
            }
            k++;
            samples++;
            float value = tl_march_sample(p);
            if (isnan(value)) {
                continue; // outside every tet: transparent
            }
            in_mesh++;
            vec4 c4 = tl_tf_lookup(value);
            float wgt = (1.0 - acc.a) * c4.a;
            acc += vec4(wgt * c4.rgb, wgt);
            if (acc.a >= cutoff) {
                break;
            }
        }
    }
    if (!isinf(shade.x)) {
        acc = vec4(acc.rgb + (1.0 - acc.a) * shade.yzw, 1.0);
    }
    if ((tl_m.size.z & TL_MARCH_RGBA8) != 0u) {
        // Renderer::render's background, then Image::to_srgb8's encoding (round to nearest).
        vec3 c = acc.rgb + (1.0 - acc.a) * tl_m.background.rgb;
        tl_pixels8[index] = packUnorm4x8(vec4(tl_linear_to_srgb(c), 1.0));
        return;
    }
    tl_pixels[index].rgba = acc;
    tl_pixels[index].count = uvec4(samples, in_mesh, 0u, 0u);
}

#endif
