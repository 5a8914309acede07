#version 450 core
// Full-resolution composite: bilinear upsampling of the ray-march result (cloud, glow and
// smooth background), the stars through the cloud's transmittance, the bolt core, the glare; then
// exposure, the filmic tone map and the sRGB encoding (tonemap.glsl). With DISPLAY the march's
// frame arrives tone mapped at its own resolution, and only the core's and the stars' pixels
// are tone mapped here.
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
//   DISPLAY 1 (OUTPUT 0): the frame's display values, tone mapped at the march's resolution
//           (display.frag), upsampled bilinearly wherever the core and the stars add nothing;
//           the pixels they light get the whole composite at their own resolution
#include "common.glsl"
#include "background.glsl"
#include "tonemap.glsl"

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
#ifndef DISPLAY
#define DISPLAY 0
#endif

layout(binding = 3) uniform sampler2D u_march;   // internal res: rgb radiance, a transmittance
layout(binding = 0, rgba32f) readonly uniform image2D u_core;   // full res: bolt core radiance
layout(binding = 5) uniform sampler2D u_glare_sum;  // internal res: keep x the march + the spread light, T (GLARE)
layout(binding = 6) uniform sampler2D u_display;    // internal res: display.frag's display values (DISPLAY)

uniform float u_glare_keep;  // the share of march + core left in place (render::GlareFit::keep)
uniform float u_core_scale;  // the core target's factor this frame (1 but for a kept core: pass_bolt.cpp)

out vec4 o_colour;

void main() {
    vec2 pixel = gl_FragCoord.xy;
    vec2 uv = pixel / sizes.xy;
#if DISPLAY && !CORE && STARS == 0
    // Nothing at this resolution adds light: the display values upsampled, all of it.
    o_colour = textureLod(u_display, uv, 0.0);
    return;
#endif
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
#if DISPLAY
    // Where neither the core nor the stars add light, the pixel is the upsampled display values,
    // as on the pixels around it that the full-screen pass drew.
    if (all(equal(core, vec3(0.0))) && all(equal(stars, vec3(0.0)))) {
        o_colour = textureLod(u_display, uv, 0.0);
        return;
    }
#endif
    o_colour = vec4(display_encode(hdr, sky_params.w, DITHER == 1, uvec2(pixel)), 1.0);
#endif
#endif
}
