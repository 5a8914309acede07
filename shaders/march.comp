#version 450 core
// Ray march, compute-shader variant. An 8x8 work group is walked in 4x2 pixel blocks so the
// SIMD lanes of a software rasterizer (8 wide) march neighbouring, coherent rays.
#include "march_pixel.glsl"

layout(local_size_x = 64) in;
layout(rgba32f, binding = 0) uniform writeonly image2D u_out;

void main() {
    uint i = gl_LocalInvocationIndex;
    uint block = i >> 3u, lane = i & 7u;
    ivec2 local = ivec2((block & 1u) * 4u + (lane & 3u), (block >> 1u) * 2u + (lane >> 2u));
    ivec2 pixel = ivec2(gl_WorkGroupID.xy) * 8 + local;
    if (pixel.x >= int(sizes.z) || pixel.y >= int(sizes.w)) return;
    imageStore(u_out, pixel, shade_pixel(vec2(pixel) + 0.5));
}
