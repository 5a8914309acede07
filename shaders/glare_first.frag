#version 450 core
// The glare pyramid's first level, at the ray march's resolution: the march's radiance plus
// the bolt core's full-resolution pixels this pixel covers, averaged (the light the eye's
// point-spread function spreads).
#include "common.glsl"

// Compile-time switches (render/pass_glare.cpp): BLOCK 1 or 2 when the output is exactly that
// many times the march's size on both axes, 0 otherwise. The general loop has per-pixel
// bounds, which a software rasterizer runs at about three times the cost of the fixed reads.
// GROUP: what u_march holds: 0 the march (rgb radiance); a group of the temporal history, 1
// the flash's (x: S, times the flash colour), 2 the static light's (rgb), 3 the channel's (rgb),
// the only group the core is added to. The core is the target's times u_core_scale (a kept
// core's factor; for the channel's group, the core at the history's intensity).
#ifndef BLOCK
#define BLOCK 0
#endif
#ifndef GROUP
#define GROUP 0
#endif

uniform float u_core_scale;

layout(binding = 3) uniform sampler2D u_march;  // internal res: rgb radiance, a transmittance
layout(binding = 4) uniform sampler2D u_core;   // full res: bolt core radiance (bilinear)

out vec4 o_radiance;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
#if GROUP == 1
    o_radiance = vec4(texelFetch(u_march, p, 0).x * light_colour.rgb, 1.0);
    return;
#elif GROUP == 2
    o_radiance = vec4(texelFetch(u_march, p, 0).rgb, 1.0);
    return;
#endif
    vec3 c = texelFetch(u_march, p, 0).rgb;
#if BLOCK == 1
    vec3 core = texelFetch(u_core, p, 0).rgb;
#elif BLOCK == 2
    // One bilinear tap at the corner the 2x2 core pixels share weighs each by exactly 1/4.
    vec3 core = textureLod(u_core, (vec2(p) + 0.5) / sizes.zw, 0.0).rgb;
#else
    // The core's pixels under this pixel's footprint [a, b), each weighed by the share of it
    // that the footprint covers: the footprint's mean radiance, so the core's energy is kept
    // whatever the ratio (a plain mean of the pixels touched counts a pixel on a boundary twice).
    vec2 ratio = sizes.xy / sizes.zw;  // output pixels per internal pixel, per axis
    vec2 a = vec2(p) * ratio, b = vec2(p + 1) * ratio;
    ivec2 lo = ivec2(floor(a));
    // internal_scale >= 1/8 with rounding: a footprint spans at most 10 output pixels.
    ivec2 hi = min(ivec2(ceil(b)), min(ivec2(sizes.xy), lo + 10));
    vec3 core = vec3(0.0);
    for (int y = lo.y; y < hi.y; ++y) {
        float wy = min(float(y + 1), b.y) - max(float(y), a.y);
        for (int x = lo.x; x < hi.x; ++x) {
            float wx = min(float(x + 1), b.x) - max(float(x), a.x);
            core += (wx * wy) * texelFetch(u_core, ivec2(x, y), 0).rgb;
        }
    }
    core /= ratio.x * ratio.y;
#endif
    core *= u_core_scale;
    o_radiance = vec4(c + core, 1.0);
}
