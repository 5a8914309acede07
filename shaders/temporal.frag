#version 450 core
// The temporal history's resolve, at internal resolution: each pixel's light groups (see
// shade_groups in march_pixel.glsl) from this frame's march where it marched the pixel, else
// from the history: at the same pixel for a still camera, else reprojected from the previous
// camera, each group through its own depth, the flash's and the channel's groups scaled by
// how much their light changed since (u_rescale: the history keeps each group's shape, the
// frame its intensity). A group found nowhere in the history (disoccluded, off screen) comes
// from this frame's marched pixels, bilinearly upsampled. Writes the new history and the
// march result the later passes read (rgb radiance, a transmittance), summed as shade_pixel
// sums it.
//
// STRIDE (compile time; a software rasterizer runs both sides of a branch its lanes split on,
// so each case is its own program): 0 nothing marched (still camera): the history is kept as
// it is and only the march is written, its groups scaled by u_rescale, 1 every pixel marched,
// 2 one pixel of each BLOCK x BLOCK block marched, at (u_phase.x, u_phase.y) (a moving camera,
// or a flash or channel changed in shape: render::TemporalReshape::Quarter), 3
// one of each 2x2 block with the others from the history in place (a camera that stopped: in
// four frames every pixel is marched at its place).
#include "common.glsl"

#ifndef STRIDE
#define STRIDE 2
#endif
// REPROJECT_LIGHT (STRIDE 2): 1 the flash's and the channel's groups reprojected through their
// light depths; 0 upsampled from this frame's marched pixels (Settings::temporal_light).
#ifndef REPROJECT_LIGHT
#define REPROJECT_LIGHT 1
#endif
// REPROJECT_CLOUD (STRIDE 2): 1 the cloud's group (its transmittance and the static light)
// reprojected through the cloud's or the background's depth; 0 upsampled from this frame's
// marched pixels, as the light groups where Settings::temporal_light upsamples them.
#ifndef REPROJECT_CLOUD
#define REPROJECT_CLOUD 1
#endif
// STILL_CLOUD (STRIDE 2, REPROJECT_LIGHT 0): the camera did not move, the flash's or the
// channel's light changed in shape (Settings::temporal_reshape): the cloud's group from the
// history at this very pixel, the light groups upsampled.
#ifndef STILL_CLOUD
#define STILL_CLOUD 0
#endif
// BLOCK (STRIDE 2): 2 or 4 (Settings::temporal_moving_block).
#ifndef BLOCK
#define BLOCK 2
#endif

layout(binding = 10) uniform sampler2D u_fresh_flash;
layout(binding = 11) uniform sampler2D u_fresh_statics;
layout(binding = 12) uniform sampler2D u_fresh_channel;
layout(binding = 13) uniform sampler2D u_hist_flash;
layout(binding = 14) uniform sampler2D u_hist_statics;
layout(binding = 15) uniform sampler2D u_hist_channel;
// The same textures as images, for the reads at a texel (on llvmpipe an image load costs less
// than a texel fetch; render/pass_temporal.cpp binds both).
#if STRIDE != 0
layout(binding = 2, rgba32f) readonly uniform image2D i_fresh_flash;
layout(binding = 3, rgba32f) readonly uniform image2D i_fresh_statics;
layout(binding = 4, rgba32f) readonly uniform image2D i_fresh_channel;
#endif
layout(binding = 5, rgba32f) readonly uniform image2D i_hist_flash;
layout(binding = 6, rgba32f) readonly uniform image2D i_hist_statics;
layout(binding = 7, rgba32f) readonly uniform image2D i_hist_channel;

uniform ivec2 u_phase;           // the marched pixel of each block (STRIDE 2: BLOCK x BLOCK; 3: 2x2)
uniform mat4 u_prev_view_proj;   // the history's camera: world -> clip
uniform vec4 u_prev_cam;         // xyz the history's camera position
uniform vec2 u_rescale;          // x: the flash's S now / in the history, y: the channel's intensity now / in the history
uniform float u_depth_tolerance; // relative depth difference beyond which a history sample is disoccluded

#if STRIDE == 0
layout(location = 0) out vec4 o_march;
// GLARE_SUM (STRIDE 0): the glare of the march as well, from the light groups' glares with the
// same factors (glare_groups.glsl). One pass for both: the history's groups are read here already.
#ifndef GLARE_SUM
#define GLARE_SUM 0
#endif
#if GLARE_SUM
#include "glare_groups.glsl"
layout(location = 1) out vec4 o_glare;
layout(binding = 2, rgba32f) readonly uniform image2D i_glare_flash;
layout(binding = 3, rgba32f) readonly uniform image2D i_glare_statics;
layout(binding = 4, rgba32f) readonly uniform image2D i_glare_channel;
uniform float u_keep;  // render::GlareFit::keep
#endif
#else
layout(location = 0) out vec4 o_flash;
layout(location = 1) out vec4 o_statics;
layout(location = 2) out vec4 o_channel;
layout(location = 3) out vec4 o_march;
#endif

#if STRIDE == 2
// Where the history saw a point at depth z along this pixel's ray: its clip position is
// A + z B (A: this camera's position, B: the ray's direction, both in the history's clip
// space; z < 0: the sky, B alone). The candidate (when `valid`) wins over `best` when the
// history's own depth there (channel `which` of its textures) agrees with the distance from
// the history's camera, sqrt(z^2 + 2 z motion.x + motion.y) (motion: the ray's direction and
// the camera's own move since, dotted with that move), within u_depth_tolerance.
// Without branches or early returns: a software rasterizer runs every side of them anyway,
// and its masks for them cost more than the selects (the same pixels; 1280x720 orbiting, the
// march pass with this resolve 42.7-43.1 -> 37.9-38.0 ms during a flash with detail and rain).
struct Candidate {
    float err;
    vec2 uv;
    float depth;
};

void consider(inout Candidate best, bool valid, float z, vec4 A, vec4 B, vec2 motion, int which) {
    vec4 clip = z < 0.0 ? B : A + z * B;
    bool ahead = clip.w > 0.0;
    vec2 uv = clip.xy / (ahead ? clip.w : 1.0) * 0.5 + 0.5;
    bool inside = ahead && all(greaterThanEqual(uv, vec2(0.0))) && all(lessThanEqual(uv, vec2(1.0)));
    ivec2 texel = clamp(ivec2(uv * sizes.zw), ivec2(0), ivec2(sizes.zw) - 1);
    float seen = which == 0 ? imageLoad(i_hist_flash, texel).w
               : which == 1 ? imageLoad(i_hist_channel, texel).w : imageLoad(i_hist_statics, texel).w;
    float expected = sqrt(max(z * z + 2.0 * z * motion.x + motion.y, 1e-30));
    float err = z < 0.0 || seen < 0.0 ? (z < 0.0 && seen < 0.0 ? 0.0 : kBig) : abs(seen - expected) / expected;
    bool take = valid && inside && err <= u_depth_tolerance && err < best.err;
    best.err = take ? err : best.err;
    best.uv = take ? uv : best.uv;
    best.depth = take ? z : best.depth;
}
#endif

#if STRIDE == 2
// The flash's group at a pixel not marched, from the marched pixels' bilinear mean `fresh`
// (in-scattered S, T) and the pixel's own cloud transmittance `T` (kept or reprojected): the
// flash light a cloud of uniform S scatters is S (1 - T), so the marched pixels' S is upsampled
// and multiplied by this pixel's opacity (1 - T), which keeps the cloud's edges and billows
// where the flash changed in shape (a still camera's leader frames at 1280x720: 1.9% -> 1.2%
// from a fresh render, with detail and rain 2.9% -> 2.0%). Where the marched pixels see no cloud,
// their mean. Identical to the mean where the cloud's group is upsampled too (T is then theirs).
float upsampled_flash(vec4 fresh, float T) {
    float opacity = 1.0 - fresh.y;
    return opacity > 1e-3 ? fresh.x * (1.0 - T) / opacity : fresh.x;
}
#endif

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
#if STRIDE == 0
    vec4 o_flash = imageLoad(i_hist_flash, p);
    vec3 statics = imageLoad(i_hist_statics, p).rgb, channel = imageLoad(i_hist_channel, p).rgb;
    o_march = vec4(o_flash.x * u_rescale.x * light_colour.rgb + statics + channel * u_rescale.y, o_flash.y);
#if GLARE_SUM
    o_glare = glare_from_groups(o_march, imageLoad(i_glare_flash, p).rgb, imageLoad(i_glare_statics, p).rgb,
                                imageLoad(i_glare_channel, p).rgb, u_rescale, u_keep);
#endif
#elif STRIDE == 1
    o_flash = imageLoad(i_fresh_flash, p);
    o_statics = imageLoad(i_fresh_statics, p);
    o_channel = imageLoad(i_fresh_channel, p);
#elif STRIDE == 3
    if (all(equal(p & 1, u_phase))) {
        ivec2 q = p >> 1;
        o_flash = imageLoad(i_fresh_flash, q);
        o_statics = imageLoad(i_fresh_statics, q);
        o_channel = imageLoad(i_fresh_channel, q);
    } else {
        o_flash = imageLoad(i_hist_flash, p);
        o_statics = imageLoad(i_hist_statics, p);
        o_channel = imageLoad(i_hist_channel, p);
        o_flash.x *= u_rescale.x;
        o_channel.rgb *= u_rescale.y;
    }
#else
    if (all(equal(p % BLOCK, u_phase))) {
        ivec2 q = p / BLOCK;
        o_flash = imageLoad(i_fresh_flash, q);
        o_statics = imageLoad(i_fresh_statics, q);
        o_channel = imageLoad(i_fresh_channel, q);
    } else {
        vec2 pixel = vec2(p) + 0.5;
        vec2 fuv = ((pixel - vec2(u_phase) - 0.5) / float(BLOCK) + 0.5) / vec2(textureSize(u_fresh_flash, 0));
#if STILL_CLOUD
        o_flash = imageLoad(i_hist_flash, p);
        o_statics = imageLoad(i_hist_statics, p);
        vec4 fresh_channel = textureLod(u_fresh_channel, fuv, 0.0);
        o_flash.x = upsampled_flash(textureLod(u_fresh_flash, fuv, 0.0), o_flash.y);
        o_channel = fresh_channel;
        o_statics.w = textureLod(u_fresh_statics, fuv, 0.0).w;
#else
        vec3 d = camera_ray(pixel / sizes.zw * 2.0 - 1.0);
        vec4 A = u_prev_view_proj * vec4(cam_pos.xyz, 1.0), B = u_prev_view_proj * vec4(d, 0.0);
        vec3 moved = cam_pos.xyz - u_prev_cam.xyz;
        vec2 motion = vec2(dot(d, moved), dot(moved, moved));
        // The candidates: for the cloud's group the depths the four marched pixels around this
        // one found where they see cloud, and the pixel's own background (the ground plane's
        // distance, or the sky); for the flash's and the channel's, the light depths the marched
        // pixel of its own block found. The cloud's four, not only its own block's: at a cloud's
        // edge the depth that agrees with the history is often a neighbouring block's (between
        // flashes, orbiting, 160x90 marched: 11.4% -> 6.3% from a fresh render). The lights' four
        // measured 3.8% -> 3.7% at 1280x720 for +8-12 ms of this pass there: not taken.
        Candidate cloud = Candidate(kBig, vec2(0.0), 0.0), flash = cloud, channel = cloud;
#if REPROJECT_CLOUD
        ivec2 k0 = ivec2(floor((vec2(p) - vec2(u_phase)) / float(BLOCK)));
        for (int j = 0; j < 2; ++j)
            for (int i = 0; i < 2; ++i) {
                vec4 f = imageLoad(i_fresh_flash, clamp(k0 + ivec2(i, j), ivec2(0), textureSize(u_fresh_flash, 0) - 1));
                consider(cloud, f.y <= 0.9, f.w, A, B, motion, 0);
            }
#endif
#if REPROJECT_LIGHT
        ivec2 k = min(p / BLOCK, textureSize(u_fresh_flash, 0) - 1);
        float zf = imageLoad(i_fresh_channel, k).w, zc = imageLoad(i_fresh_statics, k).w;
        consider(flash, zf > 0.0, zf, A, B, motion, 1);
        consider(channel, zc > 0.0, zc, A, B, motion, 2);
#endif
        // The pixel's own background only where the cloud's depth found nothing: a sky that
        // the history saw in this direction agrees exactly (no depth to differ), so tried
        // first it would take every pixel of a cloud's edge that the history saw beside it.
#if REPROJECT_CLOUD
        float tg = ground_distance(cam_pos.xyz, d);
        consider(cloud, cloud.err >= kBig, tg < kBig ? tg : -1.0, A, B, motion, 0);
#endif
        // Each group from the history where its depth was found, else from the marched pixels.
        vec4 fresh_flash = textureLod(u_fresh_flash, fuv, 0.0);
        vec4 fresh_statics = textureLod(u_fresh_statics, fuv, 0.0);
        vec4 fresh_channel = textureLod(u_fresh_channel, fuv, 0.0);
        bool c_ok = cloud.err < kBig, f_ok = flash.err < kBig, ch_ok = channel.err < kBig;
        vec4 hf = textureLod(u_hist_flash, cloud.uv, 0.0), hs = textureLod(u_hist_statics, cloud.uv, 0.0);
        o_flash = c_ok ? vec4(hf.xyz, cloud.depth) : fresh_flash;
        o_statics = c_ok ? hs : fresh_statics;
        o_flash.x = f_ok ? textureLod(u_hist_flash, flash.uv, 0.0).x * u_rescale.x : upsampled_flash(fresh_flash, o_flash.y);
        o_channel = ch_ok ? textureLod(u_hist_channel, channel.uv, 0.0) * vec4(vec3(u_rescale.y), 1.0) : fresh_channel;
        // The light depths this pixel keeps: where they were found, else the marched pixels'.
        o_channel.w = f_ok ? flash.depth : fresh_channel.w;
        o_statics.w = ch_ok ? channel.depth : fresh_statics.w;
#endif
    }
#endif
#if STRIDE != 0
    o_march = vec4(o_flash.x * light_colour.rgb + o_statics.rgb + o_channel.rgb, o_flash.y);
#endif
}
