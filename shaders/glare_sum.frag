#version 450 core
// A still camera's glare from the history's light groups (render/pass_glare.cpp): the glare is
// linear in the frame's light, which is the groups' sum with their factors since the history
// (temporal.frag, STRIDE 0), so it is the sum of each group's glare with the same factors. Writes
// what glare_up.frag's finest level would: keep x the march + the spread light, the march's
// transmittance.
layout(binding = 0, rgba32f) readonly uniform image2D u_march;    // the march summed from the history
layout(binding = 1, rgba32f) readonly uniform image2D u_flash;    // the flash group's glare
layout(binding = 2, rgba32f) readonly uniform image2D u_statics;  // the static light's
layout(binding = 3, rgba32f) readonly uniform image2D u_channel;  // the channel's, with the core

uniform float u_keep;     // render::GlareFit::keep
uniform vec2 u_factors;   // the flash's and the channel's factors since the history

out vec4 o_radiance;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 m = imageLoad(u_march, p);
    vec3 spread = u_factors.x * imageLoad(u_flash, p).rgb + imageLoad(u_statics, p).rgb +
                  u_factors.y * imageLoad(u_channel, p).rgb;
    o_radiance = vec4(u_keep * m.rgb + spread, m.a);
}
