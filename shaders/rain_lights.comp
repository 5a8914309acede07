#version 450 core
// The rain's lights' extinction (render/pass_rain_lights.cpp): at each voxel with rain (u_lo to
// u_hi), the rain's mean extinction over rain_params.x along the segment from the voxel's
// centre p to the lights' centroid q: its optical depth inside the density's box over
// rain_params.x, over the segment's whole length, by the midpoint rule with one sample per
// density voxel (u_max_samples at most); into the density texture's alpha, its other channels
// kept. The paths read the rain (b), which this pass does not write.
#define HAS_RAIN 1
#include "common.glsl"
#include "volume.glsl"

#ifndef DENSITY_U8
#define DENSITY_U8 1
#endif

layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;
#if DENSITY_U8
layout(rgba8, binding = 0) uniform image3D u_volume;
#else
layout(rgba16f, binding = 0) uniform image3D u_volume;
#endif

uniform vec3 u_centroid;
uniform ivec3 u_lo, u_hi;
uniform int u_max_samples;

float mean_rain(vec3 p, vec3 q) {
    vec3 l = q - p;
    float len = length(l);
    if (len < 1e-3) return textureLod(u_density, (p - vol_min.xyz) / vol_size.xyz, 0.0).b;
    float t0, t1;
    if (!ray_box(p, l, vol_min.xyz, vol_min.xyz + vol_size.xyz, t0, t1)) return 0.0;
    return rain_depth(p, l, t0, min(t1, 1.0), vol_size.w, u_max_samples) / len;
}

void main() {
    ivec3 v = u_lo + ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(v, u_hi))) return;
    vec3 p = vol_min.xyz + (vec3(v) + 0.5) * vol_size.w;
    vec4 texel = imageLoad(u_volume, v);
    imageStore(u_volume, v, vec4(texel.rgb, clamp(mean_rain(p, u_centroid), 0.0, 1.0)));
}
