#version 450 core
// S toward the camera on the lighting grid:
//   S_cam(x_i) = sum_m w_m(normalize(camera - x_i)) S_m(x_i) / sum_m w_m
// over the uploaded directions the view needs (the renormalization makes leaving out
// directions of negligible weight harmless). Up to 16 directions per dispatch, one sampler
// each (the first dispatch writes, later ones accumulate): separate samplers rather than an
// array, because a dynamically indexed sampler array makes a software rasterizer generate
// and JIT-compile a fetch path per element. With RGB defined the values are colours (the
// static light: sun, moon, sky), rgba32f, summed the same way. With GEOMETRIC defined (the
// rain's S, whose drops' forward lobe is narrower than the directions are apart) the values are
// interpolated geometrically, exp(sum_m w_m log S_m / sum_m w_m): a lobe's convex tail between
// two nodes is nearer their geometric than their arithmetic mean (HG 0.85 midway between 0 and
// 45 degrees: 1.7x the true value against 8.8x). Where a weighted S_m is not positive, or the
// view needs more directions than one dispatch takes (over 16: a camera among the nodes), the
// arithmetic mean.
#include "common.glsl"
#include "directions.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

// One work group per 8 x 8 x 1 tile of nodes holding a node near non-empty density, listed as
// (tz * tiles_y + ty) * tiles_x + tx; the other tiles keep S_cam's zeros.
layout(std430, binding = 4) readonly buffer Tiles { uint u_tiles[]; };
uniform ivec2 u_tile_counts;  // tiles along x and y

layout(binding = 0) uniform sampler3D u_src0;
layout(binding = 1) uniform sampler3D u_src1;
layout(binding = 2) uniform sampler3D u_src2;
layout(binding = 3) uniform sampler3D u_src3;
layout(binding = 4) uniform sampler3D u_src4;
layout(binding = 5) uniform sampler3D u_src5;
layout(binding = 6) uniform sampler3D u_src6;
layout(binding = 7) uniform sampler3D u_src7;
layout(binding = 8) uniform sampler3D u_src8;
layout(binding = 9) uniform sampler3D u_src9;
layout(binding = 10) uniform sampler3D u_src10;
layout(binding = 11) uniform sampler3D u_src11;
layout(binding = 12) uniform sampler3D u_src12;
layout(binding = 13) uniform sampler3D u_src13;
layout(binding = 14) uniform sampler3D u_src14;
layout(binding = 15) uniform sampler3D u_src15;
#ifdef RGB
layout(rgba32f, binding = 0) uniform image3D u_out;
#else
layout(r32f, binding = 0) uniform image3D u_out;
#endif

uniform ivec3 u_dims;
uniform ivec4 u_dirs[4];       // baked direction index per sampler (4 per vector), -1 = unused
uniform int u_samplers;        // samplers used by this dispatch (1..16)
uniform int u_accumulate;      // 0: first batch (write), 1: add to u_out
uniform int u_one_dispatch;    // 1: this dispatch holds every direction of the resolve
uniform float u_active[26];    // 1 for the directions of this resolve (for the weight sum)
uniform ivec3 u_fold_index[27];
uniform vec3 u_fold_fraction[27];

vec4 w_batch[4];
float w_sum;

void add_weight(int idx, float f) {
    if (idx < 0) return;
    w_sum += u_active[idx] * f;
    for (int q = 0; q < 4; ++q) w_batch[q] += vec4(equal(ivec4(idx), u_dirs[q])) * f;
}

void fold(int code, float w) {
    ivec3 fi = u_fold_index[code];
    vec3 ff = u_fold_fraction[code] * w;
    add_weight(fi.x, ff.x);
    add_weight(fi.y, ff.y);
    add_weight(fi.z, ff.z);
}

// Weighted sum of four directions' colours at cell c.
vec4 fetch4(vec4 w, sampler3D a, sampler3D b, sampler3D d, sampler3D e, ivec3 c) {
    return w.x * texelFetch(a, c, 0) + w.y * texelFetch(b, c, 0) + w.z * texelFetch(d, c, 0) + w.w * texelFetch(e, c, 0);
}

void main() {
    uint t = u_tiles[gl_WorkGroupID.x];
    uint per_layer = uint(u_tile_counts.x * u_tile_counts.y);
    ivec3 tile = ivec3(int(t % uint(u_tile_counts.x)), int((t % per_layer) / uint(u_tile_counts.x)), int(t / per_layer));
    ivec3 c = tile * ivec3(8, 8, 1) + ivec3(gl_LocalInvocationID);
    if (any(greaterThanEqual(c, u_dims))) return;
    vec3 x = lit_min.xyz + (vec3(c) + 0.5) * (lit_size.xyz / vec3(u_dims));
    vec3 d = cam_pos.xyz - x;
    // A camera exactly on a node: any direction is as good (same choice as the CPU: +z).
    d = dot(d, d) > 0.0 ? normalize(d) : vec3(0.0, 0.0, 1.0);
    ivec4 code;
    vec4 cw;
    cube_cell_weights(d, code, cw);
    for (int q = 0; q < 4; ++q) w_batch[q] = vec4(0.0);
    w_sum = 0.0;
    fold(code.x, cw.x);
    fold(code.y, cw.y);
    fold(code.z, cw.z);
    fold(code.w, cw.w);
    float inv = w_sum > 0.0 ? 1.0 / w_sum : 0.0;
#ifdef RGB
    vec4 s = fetch4(w_batch[0], u_src0, u_src1, u_src2, u_src3, c);
    if (u_samplers > 4) s += fetch4(w_batch[1], u_src4, u_src5, u_src6, u_src7, c);
    if (u_samplers > 8) s += fetch4(w_batch[2], u_src8, u_src9, u_src10, u_src11, c);
    if (u_samplers > 12) s += fetch4(w_batch[3], u_src12, u_src13, u_src14, u_src15, c);
    s *= inv;
    if (u_accumulate != 0) s += imageLoad(u_out, c);
    imageStore(u_out, c, s);
#else
    vec4 v[4];
    v[0] = vec4(texelFetch(u_src0, c, 0).r, texelFetch(u_src1, c, 0).r, texelFetch(u_src2, c, 0).r,
                texelFetch(u_src3, c, 0).r);
    v[1] = u_samplers > 4 ? vec4(texelFetch(u_src4, c, 0).r, texelFetch(u_src5, c, 0).r, texelFetch(u_src6, c, 0).r,
                                 texelFetch(u_src7, c, 0).r)
                          : vec4(0.0);
    v[2] = u_samplers > 8 ? vec4(texelFetch(u_src8, c, 0).r, texelFetch(u_src9, c, 0).r, texelFetch(u_src10, c, 0).r,
                                 texelFetch(u_src11, c, 0).r)
                          : vec4(0.0);
    v[3] = u_samplers > 12 ? vec4(texelFetch(u_src12, c, 0).r, texelFetch(u_src13, c, 0).r,
                                  texelFetch(u_src14, c, 0).r, texelFetch(u_src15, c, 0).r)
                           : vec4(0.0);
    float s = dot(w_batch[0], v[0]);
    if (u_samplers > 4) s += dot(w_batch[1], v[1]);
    if (u_samplers > 8) s += dot(w_batch[2], v[2]);
    if (u_samplers > 12) s += dot(w_batch[3], v[3]);
    s *= inv;
#ifdef GEOMETRIC
    if (u_one_dispatch != 0 && w_sum > 0.0) {
        // Directions of zero weight (and samplers not used) count as 1: log 1 = 0.
        float lg = 0.0;
        bool positive = true;
        for (int q = 0; q < 4; ++q) {
            vec4 x = mix(vec4(1.0), v[q], greaterThan(w_batch[q], vec4(0.0)));
            positive = positive && all(greaterThan(x, vec4(0.0)));
            lg += dot(w_batch[q], log(max(x, vec4(1e-30))));
        }
        if (positive) s = exp(lg * inv);
    }
#endif
    if (u_accumulate != 0) s += imageLoad(u_out, c).r;
    imageStore(u_out, c, vec4(s));
#endif
}
