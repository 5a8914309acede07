#version 450 core
// The rain's transmittance between the ground and each ground light, tabulated on a polar map
// around the light's foot (background.glsl's ground_light_rain reads it; the map's layout is
// described there). Made when the lights move or the rain changes (render/pass_ground_rain.cpp),
// so the ground pays one fetch per light instead of integrating each path.
//
// Each texel integrates the rain along the segment from its ground point to the light, the part
// inside the density's box and below the rain's top, by the midpoint rule with one sample per
// u_voxels_per_sample density voxels of its length (u_max_samples at most): finer than the
// per-pixel integral's 4 samples, which miss a shaft's edges on a path of several kilometres.
#define HAS_RAIN 1
#include "common.glsl"
#include "volume.glsl"
#include "background.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(r32f, binding = 0) writeonly uniform image2DArray u_out;

uniform int u_max_samples;
uniform float u_voxels_per_sample;

void main() {
    ivec3 id = ivec3(gl_GlobalInvocationID);
    ivec3 size = imageSize(u_out);
    if (any(greaterThanEqual(id, size))) return;
    vec3 q = ground_light[id.z].xyz;
    float azimuth = 6.2831853 * (float(id.x) + 0.5) / float(size.x);
    float v = (float(id.y) + 0.5) / float(size.y);
    float r = ground_rain_scale(q) * v / (1.0 - v);
    vec3 p = vec3(q.xy + r * vec2(cos(azimuth), sin(azimuth)), ground_params.x);
    // The segment p + t (q - p), t in [0, 1], clipped to the density's box and the rain's top.
    vec3 l = q - p;
    float t0, t1;
    ray_box(p, l, vol_min.xyz, vol_min.xyz + vol_size.xyz, t0, t1);
    t1 = min(t1, 1.0);
    if (l.z > 1e-3) t1 = min(t1, (rain_params.z - p.z) / l.z);
    float tau = rain_depth(p, l, t0, t1, u_voxels_per_sample * vol_size.w, u_max_samples);
    imageStore(u_out, id, vec4(exp(-rain_params.x * rain_lights.z * tau)));  // as background.glsl's
}
