#version 450 core
// Ray march for the temporal history (TEMPORAL 1): the light groups apart, on every
// u_grid.x-th pixel of the internal image from (u_grid.y, u_grid.z) on (stride 1: all of
// them; stride 2: the quarter of this frame's phase), one fragment per marched pixel.
#include "march_pixel.glsl"

uniform ivec3 u_grid;  // x stride, yz phase

layout(location = 0) out vec4 o_flash;
layout(location = 1) out vec4 o_statics;
layout(location = 2) out vec4 o_channel;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) * u_grid.x + u_grid.yz;
    if (p.x >= int(sizes.z) || p.y >= int(sizes.w)) {
        o_flash = vec4(0.0, 1.0, 0.0, -1.0);
        o_statics = o_channel = vec4(0.0);
        return;
    }
    shade_groups(vec2(p) + 0.5, o_flash, o_statics, o_channel);
}
