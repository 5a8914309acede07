#version 450 core
// Transmittance from the camera to both endpoints of every bolt segment (the bolt core is
// attenuated per vertex: segments are short, so T varies little along one).
#include "common.glsl"
#include "volume.glsl"

layout(local_size_x = 64) in;

layout(std430, binding = 1) readonly buffer Segments { vec4 seg[]; };  // 4 per segment (bolt.vert)
layout(std430, binding = 2) writeonly buffer Endpoints { vec2 endpoint_t[]; };

void main() {
    int s = int(gl_GlobalInvocationID.x);
    if (s >= counts.w) return;
    endpoint_t[s] = vec2(transmittance_to(seg[4 * s].xyz), transmittance_to(seg[4 * s + 1].xyz));
}
