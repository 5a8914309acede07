#version 450 core
// The stars of every output pixel (background.glsl's star_radiance, before the cloud's
// transmittance), kept while the camera stays still: the composite then reads them instead of
// finding each pixel's star cell again.
#include "common.glsl"
#include "background.glsl"

out vec4 o_stars;

void main() {
    vec2 uv = gl_FragCoord.xy / sizes.xy;
    vec3 d = camera_ray(uv * 2.0 - 1.0);
    float pixel_angle = 2.0 * cam_pos.w / sizes.y;
    o_stars = vec4(star_radiance(cam_pos.xyz, d, pixel_angle), 0.0);
}
