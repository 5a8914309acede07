#version 450 core
// The bolt's bright core: one screen-aligned ribbon per segment, at least bolt_min_width_px
// wide; a thinner channel is widened and dimmed by the same factor so its flux is conserved.
// At an end that meets another segment the ribbon reaches past the joint by the mitre's length,
// half its width x tan(turn / 2) on screen (at most half its width), so the two ribbons cover the
// bend's outer wedge and no more (MAX blending keeps their overlap single); a free end (the
// channel's foot, a branch's tip) stops where the channel does. So the core's flux is the
// channel's.
#include "common.glsl"

// Per segment: a.xyz, intensity | b.xyz, radius | the far end of the segment joined at a, w 1 (0:
// a free end) | the same at b.
layout(std430, binding = 1) readonly buffer Segments { vec4 seg[]; };
layout(std430, binding = 2) readonly buffer Endpoints { vec2 endpoint_t[]; };

uniform float u_min_width_px;
uniform float u_margin_px;  // the ribbon's outline pushed out by this (the composite's overlay; 0 here)

out float v_across;          // -1 .. 1 across the ribbon
out vec3 v_radiance;
noperspective out float v_inv_depth;  // 1 / eye depth: linear in screen space

void main() {
    // (end, side) per vertex of the two triangles
    const ivec2 corner[6] = ivec2[](ivec2(0, -1), ivec2(1, -1), ivec2(1, 1), ivec2(0, -1), ivec2(1, 1), ivec2(0, 1));
    int s = gl_VertexID / 6;
    ivec2 k = corner[gl_VertexID % 6];
    vec4 A = seg[4 * s], B = seg[4 * s + 1], J = seg[4 * s + 2 + k.x];
    vec4 ca = view_proj * vec4(A.xyz, 1.0), cb = view_proj * vec4(B.xyz, 1.0);
    const float w_near = 1e-2;  // clip against a plane just in front of the camera
    if (ca.w < w_near && cb.w < w_near) {
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // behind the camera: degenerate, outside
        v_across = 0.0;
        v_radiance = vec3(0.0);
        v_inv_depth = 0.0;
        return;
    }
    if (ca.w < w_near) ca = mix(ca, cb, (w_near - ca.w) / (cb.w - ca.w));
    if (cb.w < w_near) cb = mix(cb, ca, (w_near - cb.w) / (ca.w - cb.w));
    vec2 half_size = 0.5 * sizes.xy;
    vec2 pa = ca.xy / ca.w * half_size, pb = cb.xy / cb.w * half_size;  // pixels from the centre
    vec2 dir = pb - pa;
    float len = length(dir);
    dir = len > 1e-4 ? dir / len : vec2(1.0, 0.0);
    vec2 n = vec2(-dir.y, dir.x);
    float focal = half_size.y / cam_pos.w;                // pixels per unit of (size / distance)
    float w_clip = k.x == 0 ? ca.w : cb.w;
    float w_true = 2.0 * B.w * focal / w_clip;            // projected channel diameter, pixels
    float w = max(w_true, u_min_width_px);
    float wq = w + 2.0 * u_margin_px;
    // How far the ribbon reaches past this end: the mitre's length toward the joined segment.
    float past = u_margin_px;
    if (J.w > 0.0) {
        vec4 cj = view_proj * vec4(J.xyz, 1.0);
        vec2 end = k.x == 0 ? pa : pb;
        vec2 on = cj.w > w_near ? cj.xy / cj.w * half_size - end : vec2(0.0);
        float l = length(on);
        vec2 out_dir = k.x == 0 ? -dir : dir;
        float c = l > 1e-4 && len > 1e-4 ? clamp(dot(out_dir, on / l), -1.0, 1.0) : -1.0;
        // tan(turn / 2) = sqrt((1 - cos) / (1 + cos)); a hairpin (or a joint seen end-on) as before.
        float mitre = c > 0.0 ? 0.5 * wq * sqrt((1.0 - c) / (1.0 + c)) : 0.5 * wq;
        past = min(mitre, 0.5 * wq) + u_margin_px;
    }
    vec2 p = (k.x == 0 ? pa - dir * past : pb + dir * past) + float(k.y) * n * 0.5 * wq;
    gl_Position = vec4(p / half_size, 0.0, 1.0);
    float core = A.w / (2.0 * B.w) * (w_true / w);        // radiance of a cylinder seen side-on
    float T = k.x == 0 ? endpoint_t[s].x : endpoint_t[s].y;
    v_across = float(k.y);
    v_inv_depth = 1.0 / w_clip;
    v_radiance = core * T * light_colour.rgb;
}
