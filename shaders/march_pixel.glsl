// One ray-march pixel (shared by march.frag and march.comp).
#include "common.glsl"
#include "volume.glsl"
#include "background.glsl"

// Glow emission at internal resolution: rgb radiance, a = sum of luminance * distance.
// GLOW_ON_GRID 1 (march_groups.frag, a temporal plan marching a grid of the pixels): it holds
// only the marched pixels, each at the marching fragment's own coordinates.
layout(binding = 2) uniform sampler2D u_glow;
#ifndef GLOW_ON_GRID
#define GLOW_ON_GRID 0
#endif

// The march of one pixel: its ray, its jitter, where it ends (the ground, a host's surface),
// the glow at it (e; t_emit its depth) and the march itself.
struct PixelMarch {
    vec3 d;
    float t_end;
    vec4 e;
    MarchResult r;
};

PixelMarch march_pixel(vec2 pixel) {
    PixelMarch m;
    vec2 ndc = pixel / sizes.zw * 2.0 - 1.0;
    m.d = camera_ray(ndc);
    float jitter = march_params.z > 0.5 ? fract(interleaved_gradient_noise(floor(pixel)) + march_params.w) : 0.5;
    m.t_end = ground_distance(cam_pos.xyz, m.d);
    // A host's opaque surface ends the ray too (its eye depth over the ray's forward cosine).
    if (host_depth.w != 0.0) m.t_end = min(m.t_end, host_eye_depth(pixel * sizes.xy / sizes.zw) / max(dot(m.d, cam_fwd.xyz), 1e-6));
#if HAS_EMISSION
#if GLOW_ON_GRID
    m.e = texelFetch(u_glow, ivec2(gl_FragCoord.xy), 0);
#else
    m.e = texelFetch(u_glow, ivec2(pixel), 0);
#endif
    float y = luminance(m.e.rgb);
    float t_emit = y > 0.0 ? m.e.a / y : kBig;
    if (host_depth.w != 0.0 && t_emit > m.t_end) m.e = vec4(0.0);  // the glow behind the host's surface
#else
    m.e = vec4(0.0);
    float t_emit = kBig;
#endif
    m.r = march_ray(cam_pos.xyz, m.d, m.t_end, jitter, t_emit);
    return m;
}

// pixel: internal-resolution pixel centre (x + 0.5, y + 0.5), origin bottom-left.
// Returns rgb = in-scattered radiance * flash colour + the static light's and the sun's
//              in-scattered radiance + glow * T(camera, glow depth)
//              + smooth background (sky gradient or ground) * T,
// a = transmittance of the whole ray (the stars are added at full resolution).
vec4 shade_pixel(vec2 pixel) {
    PixelMarch m = march_pixel(pixel);
    vec3 bg = background(cam_pos.xyz, m.d);
    return vec4(m.r.in_scattered * light_colour.rgb + m.r.in_static + m.r.t_emit * m.e.rgb + m.r.transmittance * bg,
                m.r.transmittance);
}

#if TEMPORAL
// The same pixel's terms kept apart by light group, for the temporal history (temporal.frag
// sums them into shade_pixel's result):
//   flash   = (the flash's in-scattered S before its colour, T, 0 (unused), depth)
//   statics = (the static light: in-scattered sun, moon and sky + the background they light * T;
//              the channel's light depth)
//   channel = (the channel's direct light: the rain it lights + the ground it lights * T + the
//              glow in the air around it * T to the glow, in colour; the flash's light depth)
// depth: the cloud's opacity-weighted distance where it hides at least 10% of the background,
// else the background's distance (-1: the sky, infinitely far). A light depth: the distance
// the group's light comes from on average (the flash lights the cloud from within, behind its
// near side; the channel lights the rain below the cloud, the ground behind it and the air
// around itself: each reprojected by the cloud's depth would slide), 0: no such light.
void shade_groups(vec2 pixel, out vec4 flash, out vec4 statics, out vec4 channel) {
    PixelMarch m = march_pixel(pixel);
    vec3 rest, lit;
    background_parts(cam_pos.xyz, m.d, rest, lit);
    float T = m.r.transmittance;
    float depth = T <= 0.9 ? m.r.depth : (m.t_end < kBig ? m.t_end : -1.0);
    flash = vec4(m.r.in_scattered, T, 0.0, depth);
    vec3 rain_lit = m.r.in_rain_flash * light_colour.rgb, glow = m.r.t_emit * m.e.rgb;
    float wr = luminance(rain_lit), wg = luminance(T * lit), we = luminance(glow);
    float glow_depth = we > 0.0 ? m.e.a / luminance(m.e.rgb) : 0.0;
    float w = wr + wg + we;
    float channel_depth = w > 0.0 ? (wr * m.r.rain_depth + wg * (m.t_end < kBig ? m.t_end : 0.0) + we * glow_depth) / w : 0.0;
    statics = vec4(m.r.in_static + T * rest, channel_depth);
    channel = vec4(rain_lit + T * lit + glow, m.r.light_depth);
}
#endif
