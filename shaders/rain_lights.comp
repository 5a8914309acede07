#version 450 core
// The rain's lights' extinction map (render/pass_rain_lights.cpp): at each cell centre p of the
// grid over the density's box below the rain's top (rain_map_min, rain_map_size), for each light
// q of rain_light, the mean extinction along the segment from p to q (1/m): the rain's and the
// cloud's optical depth on it, the part inside the density's box, over the segment's whole
// length. The midpoint rule with one sample per density voxel of that part (u_max_samples at
// most). Lights 0-3 into u_out0, 4-7 into u_out1.
#define HAS_RAIN 1
#include "common.glsl"
#include "volume.glsl"

layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;
layout(rgba16f, binding = 0) writeonly uniform image3D u_out0;
layout(rgba16f, binding = 1) writeonly uniform image3D u_out1;

uniform int u_lights;  // how many of rain_light (<= 8)
uniform int u_max_samples;

float mean_extinction(vec3 p, vec3 q) {
    vec3 l = q - p;
    float len = length(l);
    if (len < 1e-3) {
        vec4 dv = textureLod(u_density, (p - vol_min.xyz) / vol_size.xyz, 0.0);
        return vol_min.w * dv.r + rain_params.x * dv.b;
    }
    float t0, t1;
    if (!ray_box(p, l, vol_min.xyz, vol_min.xyz + vol_size.xyz, t0, t1)) return 0.0;
    t1 = min(t1, 1.0);
    if (t1 <= t0) return 0.0;
    float inside = (t1 - t0) * len;
    int n = clamp(int(ceil(inside / vol_size.w)), 1, u_max_samples);
    float rho = 0.0, rain = 0.0;
    for (int k = 0; k < n; ++k) {
        vec3 x = p + (t0 + (float(k) + 0.5) / float(n) * (t1 - t0)) * l;
        vec4 dv = textureLod(u_density, (x - vol_min.xyz) / vol_size.xyz, 0.0);
        rho += dv.r;
        rain += dv.b;
    }
    return (vol_min.w * rho + rain_params.x * rain) * (inside / float(n)) / len;
}

void main() {
    ivec3 id = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(id, imageSize(u_out0)))) return;
    vec3 p = rain_map_min.xyz + (vec3(id) + 0.5) * rain_map_min.w;
    float m[8];
    for (int i = 0; i < 8; ++i) m[i] = i < u_lights ? mean_extinction(p, rain_light[i].xyz) : 0.0;
    imageStore(u_out0, id, vec4(m[0], m[1], m[2], m[3]));
    imageStore(u_out1, id, vec4(m[4], m[5], m[6], m[7]));
}
