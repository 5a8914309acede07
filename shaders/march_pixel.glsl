// One ray-march pixel (shared by march.frag and march.comp).
#include "common.glsl"
#include "volume.glsl"
#include "background.glsl"

// Glow emission at internal resolution: rgb radiance, a = sum of luminance * distance.
layout(binding = 2) uniform sampler2D u_glow;

// pixel: internal-resolution pixel centre (x + 0.5, y + 0.5), origin bottom-left.
// Returns rgb = in-scattered radiance * flash colour + the static light's and the sun's
//              in-scattered radiance + glow * T(camera, glow depth)
//              + smooth background (sky gradient or ground) * T,
// a = transmittance of the whole ray (the stars are added at full resolution).
vec4 shade_pixel(vec2 pixel) {
    vec2 ndc = pixel / sizes.zw * 2.0 - 1.0;
    vec3 d = camera_ray(ndc);
    float jitter = march_params.z > 0.5 ? fract(interleaved_gradient_noise(floor(pixel)) + march_params.w) : 0.5;
    float t_end = ground_distance(cam_pos.xyz, d);
    // A host's opaque surface ends the ray too (its eye depth over the ray's forward cosine).
    if (host_depth.w != 0.0) t_end = min(t_end, host_eye_depth(pixel * sizes.xy / sizes.zw) / max(dot(d, cam_fwd.xyz), 1e-6));
#if HAS_EMISSION
    vec4 e = texelFetch(u_glow, ivec2(pixel), 0);
    float y = luminance(e.rgb);
    float t_emit = y > 0.0 ? e.a / y : kBig;
    if (host_depth.w != 0.0 && t_emit > t_end) e = vec4(0.0);  // the glow behind the host's surface
#else
    vec4 e = vec4(0.0);
    float t_emit = kBig;
#endif
    MarchResult r = march_ray(cam_pos.xyz, d, t_end, jitter, t_emit);
    vec3 bg = background(cam_pos.xyz, d);
    return vec4(r.in_scattered * light_colour.rgb + r.in_static + r.t_emit * e.rgb + r.transmittance * bg,
                r.transmittance);
}
