#version 450 core
// A still camera's glare from the history's light groups (glare_groups.glsl), for a frame whose
// temporal pass did not write it (render/pass_glare.cpp).
#include "glare_groups.glsl"

layout(binding = 0, rgba32f) readonly uniform image2D u_march;    // the march summed from the history
layout(binding = 1, rgba32f) readonly uniform image2D u_flash;    // the flash group's glare
layout(binding = 2, rgba32f) readonly uniform image2D u_statics;  // the static light's
layout(binding = 3, rgba32f) readonly uniform image2D u_channel;  // the channel's, with the core

uniform float u_keep;     // render::GlareFit::keep
uniform vec2 u_factors;   // the flash's and the channel's factors since the history

out vec4 o_radiance;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    o_radiance = glare_from_groups(imageLoad(u_march, p), imageLoad(u_flash, p).rgb, imageLoad(u_statics, p).rgb,
                                   imageLoad(u_channel, p).rgb, u_factors, u_keep);
}
