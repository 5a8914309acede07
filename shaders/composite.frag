#version 450 core
// Full-resolution composite: bilinear upsampling of the ray-march result (cloud, glow and
// smooth background), the stars through the cloud's transmittance, the bolt core, the glare; then
// exposure, the filmic tone map and the sRGB encoding.
//
// Compile-time switches (a software rasterizer runs both sides of a branch, uniform or not,
// so each variant is its own program; render/pass_composite.cpp):
//   OUTPUT  0: tone-mapped sRGB; 1: the radiance (read-back); 2: a host's frame, (L, T)
//           blended as L + T dst
//   GLARE   1: the frame's light spread by the eye's point-spread function
//   CORE    1: the bolt core's pixels (0 when the frame draws no channel: they would add 0)
//   STARS   1: the stars (0 when the sky or its stars are off, they would add exactly 0, or
//           drawn as points: star_points.vert)
//   DITHER  1: +-1 LSB triangular dither before 8-bit output
#include "common.glsl"
#include "background.glsl"

#ifndef OUTPUT
#define OUTPUT 0
#endif
#ifndef GLARE
#define GLARE 0
#endif
#ifndef CORE
#define CORE 1
#endif
#ifndef STARS
#define STARS 1
#endif
#ifndef DITHER
#define DITHER 1
#endif

layout(binding = 3) uniform sampler2D u_march;   // internal res: rgb radiance, a transmittance
layout(binding = 0, rgba32f) readonly uniform image2D u_core;   // full res: bolt core radiance
layout(binding = 5) uniform sampler2D u_glare_sum;  // internal res: keep x the march + the spread light, T (GLARE)

uniform float u_glare_keep;  // the share of march + core left in place (render::GlareFit::keep)
uniform float u_core_scale;  // the core target's factor this frame (1 but for a kept core: pass_bolt.cpp)

out vec4 o_colour;

// ACES filmic tone curve, Stephen Hill's fit of the RRT + ODT (sRGB, 100 nits): linear
// sRGB -> the fit's space (input matrix: the RRT's saturation and gamut, grey kept), the
// rational curve, back (output matrix). Its shoulder is soft: display white (0.996 linear,
// 8-bit 255) is reached only at ~20x the exposed grey level 1, 2 stops beyond a plain
// Reinhard-like clip, so bright cloud near the channel keeps its falloff instead of a white
// plateau. Matrices are column-major (GLSL), Hill's rows transposed.
const mat3 kAcesInput = mat3(0.59719, 0.07600, 0.02840, 0.35458, 0.90834, 0.13383, 0.04823, 0.01566, 0.83777);
const mat3 kAcesOutput = mat3(1.60475, -0.10208, -0.00327, -0.53108, 1.10813, -0.07276, -0.07367, -0.00605, 1.07602);

vec3 aces_fitted(vec3 x) {
    // Past 1e4 the curve is white to 4e-5 (its limit is 1.0165, clamped to 1); without this a
    // radiance times exposure beyond ~1e19 would square past float32 and divide inf by inf.
    vec3 v = kAcesInput * min(x, vec3(1e4));
    vec3 a = v * (v + 0.0245786) - 0.000090537;
    vec3 b = v * (0.983729 * v + 0.4329510) + 0.238081;
    return clamp(kAcesOutput * (a / b), 0.0, 1.0);
}

// sRGB encoding. The power 1/2.4 is approximated with three square roots (Ian Taylor's
// fit; max error 0.4 of an 8-bit level over [0, 1]; pow() costs a log2 and an
// exp2 per channel on a software rasterizer).
vec3 srgb_encode(vec3 c) {
    vec3 s1 = sqrt(c), s2 = sqrt(s1), s3 = sqrt(s2);
    vec3 curve = 0.585122381 * s1 + 0.783140355 * s2 - 0.368262736 * s3;
    return mix(12.92 * c, curve, step(0.0031308, c));
}

void main() {
    vec2 pixel = gl_FragCoord.xy;
    vec2 uv = pixel / sizes.xy;
#if GLARE && OUTPUT != 2
    // The glare's sum holds keep x the march's radiance and its transmittance (glare_up.frag):
    // one bilinear read for both (bilinear filtering is linear).
    vec4 m = textureLod(u_glare_sum, uv, 0.0);
#else
    vec4 m = textureLod(u_march, uv, 0.0);
#endif
#if CORE
    vec3 core = imageLoad(u_core, ivec2(pixel)).rgb * u_core_scale;
#else
    const vec3 core = vec3(0.0);
#endif
#if OUTPUT == 2
    o_colour = vec4(m.rgb + core, m.a);
#else
#if STARS == 1
    vec3 d = camera_ray(uv * 2.0 - 1.0);
    float pixel_angle = 2.0 * cam_pos.w / sizes.y;
    vec3 stars = m.a * star_radiance(cam_pos.xyz, d, pixel_angle);
#else
    const vec3 stars = vec3(0.0);
#endif
#if GLARE
    vec3 hdr = m.rgb + u_glare_keep * core + stars;
#else
    vec3 hdr = m.rgb + stars + core;
#endif
#if OUTPUT == 1
    o_colour = vec4(hdr, 1.0);
#else
    vec3 c = srgb_encode(aces_fitted(hdr * sky_params.w));
#if DITHER
    // Triangular dither of +-1 LSB (sum of two 16-bit uniforms from one hash), deterministic per frame.
    uint h = hash_u32(uvec3(uvec2(pixel), uint(counts.y)));
    float n = float(h & 0xffffu) * (1.0 / 65535.0) + float(h >> 16u) * (1.0 / 65535.0) - 1.0;
    c += n / 255.0;
#endif
    o_colour = vec4(c, 1.0);
#endif
#endif
}
