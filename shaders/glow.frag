#version 450 core
#include "common.glsl"

// Radiance per unit source intensity at impact distance b = rho * R (1/m^2 * sr^-1 ...),
// rho in [0, 1]; built by the renderer (see make_glow_profile in renderer.cpp).
layout(binding = 5) uniform sampler1D u_profile;

in vec2 v_local;
in float v_intensity;
in float v_distance;
out vec4 o_emission;

void main() {
    float rho = length(v_local);
    if (rho >= 1.0) discard;
    vec3 c = (texture(u_profile, rho).r * v_intensity) * light_colour.rgb;
    // Additive: rgb sums the glow, a sums luminance * distance (-> luminance-weighted depth).
    o_emission = vec4(c, luminance(c) * v_distance);
}
