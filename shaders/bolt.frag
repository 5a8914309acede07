#version 450 core
#include "common.glsl"

in float v_across;
in vec3 v_radiance;
noperspective in float v_inv_depth;
out vec4 o_radiance;

void main() {
    // Behind a host's opaque surface (render_into_host): hidden.
    if (host_depth.w != 0.0 && v_inv_depth * host_eye_depth(gl_FragCoord.xy) < 1.0) discard;
    // Parabolic profile across the ribbon with mean 1: soft, anti-aliased edges.
    o_radiance = vec4(v_radiance * (1.5 * max(1.0 - v_across * v_across, 0.0)), 1.0);
}
