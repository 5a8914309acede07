#version 450 core
// The glare pyramid's first level, at the ray march's resolution: the march's radiance plus
// the bolt core's full-resolution pixels this pixel covers, averaged (the light the eye's
// point-spread function spreads).
#include "common.glsl"

layout(binding = 3) uniform sampler2D u_march;  // internal res: rgb radiance, a transmittance
layout(binding = 4) uniform sampler2D u_core;   // full res: bolt core radiance

out vec4 o_radiance;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 c = texelFetch(u_march, p, 0).rgb;
    vec2 ratio = sizes.xy / sizes.zw;  // output pixels per internal pixel, per axis
    ivec2 lo = ivec2(floor(vec2(p) * ratio));
    ivec2 hi = min(max(ivec2(ceil(vec2(p + 1) * ratio)), lo + 1), ivec2(sizes.xy));
    hi = min(hi, lo + 8);  // internal_scale >= 1/8 covers every output pixel
    vec3 core = vec3(0.0);
    for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) core += texelFetch(u_core, ivec2(x, y), 0).rgb;
    ivec2 n = max(hi - lo, ivec2(1));
    o_radiance = vec4(c + core / float(n.x * n.y), 1.0);
}
