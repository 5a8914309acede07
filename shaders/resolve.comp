#version 450 core
// S toward the camera on the lighting grid:
//   S_cam(x_i) = sum_m w_m(normalize(camera - x_i)) S_m(x_i) / sum_m w_m
// over the uploaded directions the view needs (u_active; the renormalization makes leaving
// out directions of negligible weight harmless), four directions per dispatch (one sampler
// per direction; the first dispatch writes, later ones accumulate). Four separate samplers
// rather than an array of 26: a dynamically indexed sampler array makes software
// rasterizers generate (and JIT-compile) a fetch path per array element.
#include "common.glsl"
#include "directions.glsl"

layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;

layout(binding = 0) uniform sampler3D u_src0;
layout(binding = 1) uniform sampler3D u_src1;
layout(binding = 2) uniform sampler3D u_src2;
layout(binding = 3) uniform sampler3D u_src3;
layout(r32f, binding = 0) uniform image3D u_out;

uniform ivec3 u_dims;
uniform ivec4 u_dirs;        // baked direction index per sampler, -1 = unused
uniform int u_accumulate;    // 0: first batch (write), 1: add to u_out
uniform int u_active_count;  // all directions of this resolve (for the weight sum)
uniform int u_active[26];
uniform ivec3 u_fold_index[27];
uniform vec3 u_fold_fraction[27];

// Weight of baked direction m for unit direction d.
float weight_of(int m, ivec4 code, vec4 cw) {
    float w = 0.0;
    for (int n = 0; n < 4; ++n)
        for (int k = 0; k < 3; ++k)
            if (u_fold_index[code[n]][k] == m) w += cw[n] * u_fold_fraction[code[n]][k];
    return w;
}

void main() {
    ivec3 c = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(c, u_dims))) return;
    vec3 x = lit_min.xyz + (vec3(c) + 0.5) * (lit_size.xyz / vec3(u_dims));
    vec3 d = cam_pos.xyz - x;
    // A camera exactly on a node: any direction is as good (same choice as the CPU: +z).
    d = dot(d, d) > 0.0 ? normalize(d) : vec3(0.0, 0.0, 1.0);
    ivec4 code;
    vec4 cw;
    cube_cell_weights(d, code, cw);
    float wsum = 0.0;
    for (int k = 0; k < u_active_count; ++k) wsum += weight_of(u_active[k], code, cw);
    float inv = wsum > 0.0 ? 1.0 / wsum : 0.0;
    float s = u_accumulate != 0 ? imageLoad(u_out, c).r : 0.0;
    if (u_dirs.x >= 0) s += weight_of(u_dirs.x, code, cw) * inv * texelFetch(u_src0, c, 0).r;
    if (u_dirs.y >= 0) s += weight_of(u_dirs.y, code, cw) * inv * texelFetch(u_src1, c, 0).r;
    if (u_dirs.z >= 0) s += weight_of(u_dirs.z, code, cw) * inv * texelFetch(u_src2, c, 0).r;
    if (u_dirs.w >= 0) s += weight_of(u_dirs.w, code, cw) * inv * texelFetch(u_src3, c, 0).r;
    imageStore(u_out, c, vec4(s));
}
