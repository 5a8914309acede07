#version 450 core
// One step up the glare pyramid: this level weighted (its share of the point-spread
// function, render::fit_glare) plus the coarser levels' sum, upsampled by a tent: four
// bilinear taps half a coarser texel either side onto the finest levels, nine taps a whole
// texel either side onto the coarser ones (render::glare_wide_from). The finest level also
// adds the share of the march the glare keeps in place and carries the march's transmittance,
// so the composite reads one texture where it would read two (render/pass_glare.cpp); and,
// where the composite upsamples display values, writes them too (display.frag's, from the
// same sum: the display pass is not run).
#include "common.glsl"
#include "tonemap.glsl"
layout(binding = 0) uniform sampler2D u_level;   // this level (the way down)
layout(binding = 1) uniform sampler2D u_coarse;  // the coarser levels' weighted sum
layout(binding = 3) uniform sampler2D u_march;   // the march (FOLD)

// Compile-time switches (a software rasterizer runs both sides of a uniform branch):
//   HAS_COARSE 1: a coarser level's sum to add (all but the coarsest level)
//   WIDE       1: nine taps (a tent a coarser texel either side); 0: four taps half a texel off
//   FOLD       1: the finest level: + u_keep x the march's radiance, alpha its transmittance
//   DISPLAY    1 (FOLD): also its display values into o_display (display.frag's); DITHER as there
#ifndef HAS_COARSE
#define HAS_COARSE 1
#endif
#ifndef WIDE
#define WIDE 0
#endif
#ifndef FOLD
#define FOLD 0
#endif
#ifndef DISPLAY
#define DISPLAY 0
#endif
#ifndef DITHER
#define DITHER 1
#endif

uniform float u_weight;
uniform float u_keep;  // render::GlareFit::keep (FOLD)
uniform vec2 u_coarse_texel;  // 1 / coarser size
uniform vec2 u_size;          // this level's size

layout(location = 0) out vec4 o_radiance;
#if DISPLAY
layout(location = 1) out vec4 o_display;
#endif

void main() {
    vec3 s = u_weight * texelFetch(u_level, ivec2(gl_FragCoord.xy), 0).rgb;
#if HAS_COARSE
    vec2 uv = gl_FragCoord.xy / u_size;
#if WIDE
    // A [1 2 1] tent over the coarser level's texels: smooth where they are large on
    // screen (the coarsest levels' linear ramps would show their kinks in a dark sky).
    vec3 t = vec3(0.0);
    for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i)
            t += float((2 - abs(i)) * (2 - abs(j))) * textureLod(u_coarse, uv + vec2(i, j) * u_coarse_texel, 0.0).rgb;
    s += t * (1.0 / 16.0);
#else
    vec2 o = 0.5 * u_coarse_texel;
    s += 0.25 * (textureLod(u_coarse, uv + vec2(-o.x, -o.y), 0.0).rgb + textureLod(u_coarse, uv + vec2(o.x, -o.y), 0.0).rgb +
                 textureLod(u_coarse, uv + vec2(-o.x, o.y), 0.0).rgb + textureLod(u_coarse, uv + vec2(o.x, o.y), 0.0).rgb);
#endif
#endif
#if FOLD
    vec4 m = texelFetch(u_march, ivec2(gl_FragCoord.xy), 0);
    o_radiance = vec4(s + u_keep * m.rgb, m.a);
#if DISPLAY
    o_display = vec4(display_encode(o_radiance.rgb, sky_params.w, DITHER == 1, uvec2(gl_FragCoord.xy)), 1.0);
#endif
#else
    o_radiance = vec4(s, 1.0);
#endif
}
