#version 450 core
// Glow around the strokes (after Dobashi, Yamamoto & Nishita 2001): camera-facing quads of
// radius R centred on points along the channel, textured with the radial profile of the
// light the rain-laden air scatters toward the camera.
#include "common.glsl"

layout(std430, binding = 0) readonly buffer Quads { vec4 quads[]; };  // xyz centre, w intensity (W/sr)
// x' = u_window.xy x + u_window.zw in normalized device coordinates: (1, 1, 0, 0) draws at the
// march's resolution; otherwise into a temporal plan's marched pixels (render/pass_glow.cpp).
uniform vec4 u_window;

out vec2 v_local;       // position on the quad, in units of R
out float v_intensity;
out float v_distance;   // camera -> quad centre (m), the depth the glow is attenuated to

void main() {
    const vec2 corners[6] = vec2[](vec2(-1, -1), vec2(1, -1), vec2(1, 1), vec2(-1, -1), vec2(1, 1), vec2(-1, 1));
    vec4 q = quads[gl_VertexID / 6];
    vec2 k = corners[gl_VertexID % 6];
    vec3 to = q.xyz - cam_pos.xyz;
    float dist = max(length(to), 1e-3);
    vec3 f = to / dist;
    vec3 r = normalize(cross(f, abs(f.z) < 0.999 ? vec3(0.0, 0.0, 1.0) : vec3(0.0, 1.0, 0.0)));
    vec3 u = cross(r, f);
    vec3 p = q.xyz + glow_params.x * (k.x * r + k.y * u);
    gl_Position = view_proj * vec4(p, 1.0);
    gl_Position.xy = u_window.xy * gl_Position.xy + u_window.zw * gl_Position.w;
    v_local = k;
    v_intensity = q.w;
    v_distance = dist;
}
