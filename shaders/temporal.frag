#version 450 core
// The temporal history's resolve, at internal resolution: each pixel's light groups (see
// shade_groups in march_pixel.glsl) from this frame's march where it marched the pixel, else
// from the history: at the same pixel for a still camera, else reprojected from the previous
// camera through the pixel's depth, the flash's and the channel's groups scaled by how much
// their light changed since (u_rescale: the history keeps each group's shape, the frame its
// intensity). A history sample whose depth disagrees (disocclusion) or that left the screen
// gives way to this frame's marched pixels, bilinearly upsampled. Writes the new history and
// the march result the later passes read (rgb radiance, a transmittance), summed as
// shade_pixel sums it.
#include "common.glsl"

layout(binding = 2) uniform sampler2D u_glow;
layout(binding = 10) uniform sampler2D u_fresh_flash;
layout(binding = 11) uniform sampler2D u_fresh_statics;
layout(binding = 12) uniform sampler2D u_fresh_channel;
layout(binding = 13) uniform sampler2D u_hist_flash;
layout(binding = 14) uniform sampler2D u_hist_statics;
layout(binding = 15) uniform sampler2D u_hist_channel;

uniform ivec3 u_grid;            // x: stride of the marched pixels (0: none marched), yz: their phase
uniform mat4 u_prev_view_proj;   // the history's camera: world -> clip
uniform vec4 u_prev_cam;         // xyz the history's camera position
uniform vec2 u_rescale;          // x: the flash's S now / in the history, y: the channel's intensity now / in the history
uniform float u_depth_tolerance; // relative depth difference beyond which a history sample is disoccluded
uniform int u_glow_on;

layout(location = 0) out vec4 o_flash;
layout(location = 1) out vec4 o_statics;
layout(location = 2) out vec4 o_channel;
layout(location = 3) out vec4 o_march;

// Fresh texel k is internal pixel k * stride + phase: the fresh texture's uv at a pixel centre.
vec2 fresh_uv(vec2 pixel) {
    return ((pixel - vec2(u_grid.yz) - 0.5) * 0.5 + 0.5) / vec2(textureSize(u_fresh_flash, 0));
}

// Where the history's camera saw this pixel's point (ray d). The candidates for its depth are
// the four marched pixels around it (a 2x2 block of the marched grid) and, for the cloud's
// depth, the pixel's own background (the ground plane's distance, or the sky: -1). A candidate
// wins when the history's own depth at the point it predicts agrees within u_depth_tolerance
// (the closest agreement wins). `light`: the flash's light depth (the channel texture's w; 0:
// no light there) instead of the cloud's (the flash texture's w).
bool reproject(ivec2 p, vec3 d, bool light, out vec2 uv, out float depth) {
    ivec2 k0 = (p - u_grid.yz - 1) >> 1;
    ivec2 last = textureSize(u_fresh_flash, 0) - 1;
    float tg = ground_distance(cam_pos.xyz, d);
    float best = kBig;
    for (int n = 0; n < 5; ++n) {
        float z;
        if (n < 4) {
            ivec2 k = clamp(k0 + ivec2(n & 1, n >> 1), ivec2(0), last);
            if (light) {
                z = texelFetch(u_fresh_channel, k, 0).w;
                if (z <= 0.0) continue;
            } else {
                vec4 f = texelFetch(u_fresh_flash, k, 0);
                if (f.y > 0.9) continue;  // it sees the background: the fifth candidate
                z = f.w;
            }
        } else {
            if (light) break;
            z = tg < kBig ? tg : -1.0;
        }
        vec4 clip = z < 0.0 ? u_prev_view_proj * vec4(d, 0.0) : u_prev_view_proj * vec4(cam_pos.xyz + z * d, 1.0);
        if (clip.w <= 0.0) continue;
        vec2 q = clip.xy / clip.w * 0.5 + 0.5;
        if (any(lessThan(q, vec2(0.0))) || any(greaterThan(q, vec2(1.0)))) continue;
        ivec2 texel = clamp(ivec2(q * sizes.zw), ivec2(0), ivec2(sizes.zw) - 1);
        float seen = light ? texelFetch(u_hist_channel, texel, 0).w : texelFetch(u_hist_flash, texel, 0).w;
        float err;
        if (z < 0.0 || seen < 0.0) {
            err = z < 0.0 && seen < 0.0 ? 0.0 : kBig;
        } else {
            float expected = length(cam_pos.xyz + z * d - u_prev_cam.xyz);
            err = abs(seen - expected) / expected;
        }
        if (err <= u_depth_tolerance && err < best) {
            best = err;
            uv = q;
            depth = z;
        }
    }
    return best < kBig;
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec2 pixel = vec2(p) + 0.5;
    if (u_grid.x == 1 || (u_grid.x == 2 && all(equal(p & 1, u_grid.yz)))) {
        ivec2 q = u_grid.x == 1 ? p : p >> 1;
        o_flash = texelFetch(u_fresh_flash, q, 0);
        o_statics = texelFetch(u_fresh_statics, q, 0);
        o_channel = texelFetch(u_fresh_channel, q, 0);
    } else if (u_grid.x == 0) {
        o_flash = texelFetch(u_hist_flash, p, 0);
        o_statics = texelFetch(u_hist_statics, p, 0);
        o_channel = texelFetch(u_hist_channel, p, 0);
        o_flash.x *= u_rescale.x;
        o_channel.rgb *= u_rescale.y;
    } else {
        // The cloud, the static light and the channel's direct light by the cloud's depth; the
        // flash's light by its own depth. Either found nowhere in the history (disoccluded,
        // off screen) comes from this frame's marched pixels, bilinearly upsampled. The
        // history is rescaled, not clamped to the marched neighbours' range: at a quarter of
        // the pixels that range misses the peaks of a channel's light.
        vec3 d = camera_ray(pixel / sizes.zw * 2.0 - 1.0);
        vec2 fuv = fresh_uv(pixel), uv;
        float depth;
        if (reproject(p, d, false, uv, depth)) {
            o_flash = textureLod(u_hist_flash, uv, 0.0);
            o_statics = textureLod(u_hist_statics, uv, 0.0);
            o_channel = textureLod(u_hist_channel, uv, 0.0);
            o_channel.rgb *= u_rescale.y;
        } else {
            o_flash = textureLod(u_fresh_flash, fuv, 0.0);
            o_statics = textureLod(u_fresh_statics, fuv, 0.0);
            o_channel = textureLod(u_fresh_channel, fuv, 0.0);
            depth = o_flash.w;
        }
        o_flash.w = depth;
        float light_depth;
        if (reproject(p, d, true, uv, light_depth)) {
            o_flash.x = textureLod(u_hist_flash, uv, 0.0).x * u_rescale.x;
            o_channel.w = light_depth;
        } else {
            o_flash.x = textureLod(u_fresh_flash, fuv, 0.0).x;
            o_channel.w = textureLod(u_fresh_channel, fuv, 0.0).w;
        }
    }
    vec3 e = u_glow_on != 0 ? texelFetch(u_glow, p, 0).rgb : vec3(0.0);
    o_march = vec4(o_flash.x * light_colour.rgb + o_statics.rgb + o_channel.rgb + o_flash.z * e, o_flash.y);
}
