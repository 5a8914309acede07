#version 450 core
// The flash's S toward the camera (r) and its light at the rain toward the camera (g) in one
// texture on S's grid, so the march reads both with one fetch: g sampled trilinearly from its
// own grid at each node's centre (the same grid as S's, or a coarser one when S is kept on
// the transport grid).
#include "common.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(binding = 0) uniform sampler3D u_flash;  // S toward the camera (r)
layout(binding = 1) uniform sampler3D u_rain;   // the light at the rain toward the camera (r)
layout(rg32f, binding = 0) uniform writeonly image3D u_out;

uniform ivec3 u_dims;      // S's grid
uniform vec3 u_rain_min;   // the rain's grid: lower corner (m)
uniform vec3 u_rain_size;  // and extent (m)

void main() {
    ivec3 c = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(c, u_dims))) return;
    vec3 x = lit_min.xyz + (vec3(c) + 0.5) * (lit_size.xyz / vec3(u_dims));
    float s = texelFetch(u_flash, c, 0).r;
    float r = textureLod(u_rain, (x - u_rain_min) / u_rain_size, 0.0).r;
    imageStore(u_out, c, vec4(s, r, 0.0, 0.0));
}
