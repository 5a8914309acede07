#version 450 core
// The march's frame as display values at its own (internal) resolution: each texel's radiance
// (with the glare when it ran) exposed, tone mapped, sRGB-encoded and dithered into an RGBA8
// target, which composite.frag (DISPLAY 1) then upsamples to the output. The tone curve runs
// on a quarter of the output's pixels, and the upsampling reads 8-bit texels instead of RGBA32F
// (render/pass_composite.cpp; Settings::display_upsample).
//
// Compile-time switches (render/pass_composite.cpp): GLARE 1: read the glare's sum (keep x the
// march + the spread light) instead of the march; DITHER 1: the +-1 LSB dither.
#include "common.glsl"
#include "tonemap.glsl"

#ifndef GLARE
#define GLARE 0
#endif
#ifndef DITHER
#define DITHER 1
#endif

layout(binding = 3) uniform sampler2D u_march;      // internal res: rgb radiance, a transmittance
layout(binding = 5) uniform sampler2D u_glare_sum;  // internal res: keep x the march + the spread light (GLARE)

out vec4 o_colour;

void main() {
    ivec2 texel = ivec2(gl_FragCoord.xy);
#if GLARE
    vec3 hdr = texelFetch(u_glare_sum, texel, 0).rgb;
#else
    vec3 hdr = texelFetch(u_march, texel, 0).rgb;
#endif
    o_colour = vec4(display_encode(hdr, sky_params.w, DITHER == 1, uvec2(texel)), 1.0);
}
