#version 450 core
// S toward the camera on the lighting grid:
//   S_cam(x_i) = sum_m w_m(normalize(camera - x_i)) S_m(x_i) / sum_m w_m
// over the uploaded directions the view needs (the renormalization makes leaving out
// directions of negligible weight harmless). Eight directions per dispatch, one sampler each
// (the first dispatch writes, later ones accumulate): separate samplers rather than an
// array, because a dynamically indexed sampler array makes a software rasterizer generate
// and JIT-compile a fetch path per element.
#include "common.glsl"
#include "directions.glsl"

layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;

layout(binding = 0) uniform sampler3D u_src0;
layout(binding = 1) uniform sampler3D u_src1;
layout(binding = 2) uniform sampler3D u_src2;
layout(binding = 3) uniform sampler3D u_src3;
layout(binding = 4) uniform sampler3D u_src4;
layout(binding = 5) uniform sampler3D u_src5;
layout(binding = 6) uniform sampler3D u_src6;
layout(binding = 7) uniform sampler3D u_src7;
layout(r32f, binding = 0) uniform image3D u_out;

uniform ivec3 u_dims;
uniform ivec4 u_dirs_lo;       // baked direction index per sampler 0-3, -1 = unused
uniform ivec4 u_dirs_hi;       // samplers 4-7
uniform int u_accumulate;      // 0: first batch (write), 1: add to u_out
uniform float u_active[26];    // 1 for the directions of this resolve (for the weight sum)
uniform ivec3 u_fold_index[27];
uniform vec3 u_fold_fraction[27];

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
    // One pass over the (at most 4 x 3) folded contributions: the weight of each of this
    // batch's directions and the sum over all active directions.
    vec4 w_lo = vec4(0.0), w_hi = vec4(0.0);
    float wsum = 0.0;
    for (int n = 0; n < 4; ++n)
        for (int k = 0; k < 3; ++k) {
            int idx = u_fold_index[code[n]][k];
            if (idx < 0) continue;
            float f = cw[n] * u_fold_fraction[code[n]][k];
            wsum += u_active[idx] * f;
            w_lo += vec4(equal(ivec4(idx), u_dirs_lo)) * f;
            w_hi += vec4(equal(ivec4(idx), u_dirs_hi)) * f;
        }
    float inv = wsum > 0.0 ? 1.0 / wsum : 0.0;
    vec4 s_lo = vec4(texelFetch(u_src0, c, 0).r, texelFetch(u_src1, c, 0).r, texelFetch(u_src2, c, 0).r,
                     texelFetch(u_src3, c, 0).r);
    vec4 s_hi = u_dirs_hi.x < 0 ? vec4(0.0)
                                : vec4(texelFetch(u_src4, c, 0).r, texelFetch(u_src5, c, 0).r,
                                       texelFetch(u_src6, c, 0).r, texelFetch(u_src7, c, 0).r);
    float s = (dot(w_lo, s_lo) + dot(w_hi, s_hi)) * inv;
    if (u_accumulate != 0) s += imageLoad(u_out, c).r;
    imageStore(u_out, c, vec4(s));
}
