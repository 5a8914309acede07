// Internal to fulgur::render: the temporal history (Settings::temporal). The march's light is
// kept per light group — the flash's S, the channel's direct light (rain and ground), the
// static light (sun, moon, sky) — with the transmittances and a depth, so that a frame whose
// groups changed only in intensity rescales the history instead of marching again: a still
// camera re-marches nothing through a return stroke's decay, a moving one marches a quarter
// of the pixels and reprojects the rest. A flash or channel group whose light changed in shape
// (a leader's front, another stroke) is upsampled from a quarter of the pixels marched, the
// cloud's group kept (Settings::temporal_reshape); a new static light or other settings start
// the history again.
#pragma once

#include "render/detail/frame.h"
#include "render/detail/gl_resources.h"
#include "render/detail/scale_tracker.h"
#include "render/render.h"

#include <glad/gl.h>

#include <glm/glm.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace fulgur::render::detail {

/// `count` RGBA32F colour textures of one size on one framebuffer (attachments 0..count-1).
struct MultiTarget {
    std::vector<GLuint> tex;
    GLuint fbo = 0;
    int w = 0, h = 0;
    void ensure(int width, int height, int count);
    void release();
};

/// What decides whether the history can serve a frame: everything the march reads except the
/// camera and the light groups' intensities (those are reprojected and rescaled).
struct TemporalKey {
    std::vector<float> uniforms;
    std::string defines;
    int width = 0, height = 0, internal_width = 0, internal_height = 0;
    bool operator==(const TemporalKey&) const = default;
};

/// What a frame's march does with the history (Renderer::Impl::plan_temporal): `stride` 0 reuses
/// it (nothing marched, no resolve, no glow: the march summed from it), 1 marches every pixel,
/// 2 the pixel `phase` of each `block` x `block` block of a moving camera (or of any camera whose
/// flash or channel changed in shape: reproject_light false), 3 the pixel `phase` of
/// each 2x2 block for a camera that stopped while the history still holds pixels a moving camera
/// upsampled (the others kept in place); the march's defines and the frame's key.
struct TemporalPlan {
    int stride = 1;
    int block = 2;  // stride 2's block (Settings::temporal_moving_block, less where the march is smaller)
    glm::ivec2 phase{0};
    bool reproject_light = true;  // !temporal_upsamples(Settings::temporal_light, ...) during a flash
    bool reproject_cloud = true;  // !temporal_upsamples(Settings::temporal_light, ...)
    // Stride 2 for a light group that changed in shape (Settings::temporal_reshape Quarter) with
    // a still camera: the cloud's group kept from the history at the same pixel, the light groups
    // upsampled (temporal.frag STILL_CLOUD).
    bool still_cloud = false;
    // This frame's marched pixels are what a fresh render of the frame marches there (false: the
    // ground integrated its rain per pixel while its lights moved, where a fresh render reads the
    // map): a still camera's settling then marches them again.
    bool marched_as_fresh = true;
    // Stride 0 with the glare's light groups ready (Renderer::Impl::glare_groups_ready): the
    // sum of the march also writes the glare's (glare_sum.frag's work, temporal.frag GLARE_SUM).
    bool glare_sum = false;
    std::string defines;
    TemporalKey key;
    /// Every grid()-th pixel of each row and column is marched, from `phase` (strides 2 and 3;
    /// 1: every pixel).
    int grid() const { return stride == 3 ? 2 : stride == 2 ? block : 1; }
    /// The marched pixels of a march `width` x `height`: a grid() x grid() block's pixel each.
    glm::ivec2 marched_size(int width, int height) const {
        const int g = grid();
        return {(width - phase.x + g - 1) / g, (height - phase.y + g - 1) / g};
    }
};

struct TemporalState {
    MultiTarget fresh;       // this frame's marched pixels (flash, statics, channel)
    MultiTarget history[2];  // ping-pong: history[current] is the last one written
    GLuint resolve_fbo[2] = {0, 0};
    // The march of history[current] (attachment 3 of the resolve, written with it: valid while
    // has_history), the flash's and the channel's factors it was summed with (1 after a
    // resolve; a still camera's frame sums it again from the history with the trackers'
    // factors), and how many times it has been written: the meter's histogram of it is kept
    // while the version stays.
    Target march;
    glm::dvec2 march_scale{1.0};
    std::uint64_t march_version = 0;
    // How many times the history itself has been written or released: what is derived from its
    // groups (the glare's per-group pyramids, pass_glare.cpp) is kept while it stays.
    std::uint64_t history_version = 0;
    int current = 0;
    bool has_history = false;
    bool inputs_changed = true;  // the volume, the static light or the sun changed since
    TemporalKey key;
    Camera camera;
    glm::mat4 view_proj{1.0f};
    std::uint32_t frames = 0;  // temporal frames since every pixel was last marched (the quarter's phase)
    int unsettled = 0;         // still-camera quarters left before every pixel of the history is marched
    // The light groups: the flash's S, with its light at the rain (`rain_source`, rescaled with
    // it: flash_holds), and the channel's direct light.
    ScaleTracker source, rain_source, channel;
    /// The flash's group changed only in intensity: its S and its light at the rain by the same
    /// factor (or the rain dark, now as when the history was written).
    bool flash_holds() const;
    void release();
};

/// The key of a frame (FrameBlock fields the march and the background read, besides the
/// camera, the jitter offset, the frame index, the exposure and the channel's lights).
TemporalKey temporal_key(const FrameUniforms& u, const std::string& march_defines);

/// A camera move the history can follow by reprojection: the view turned by at most
/// kMaxTurnDeg, the position moved by at most kMaxMove of the distance to the target, the field
/// of view changed by at most kMaxTurnDeg. Beyond (a cut, a jump) most of the history would be
/// disoccluded or seen at other angles: every pixel is marched.
inline constexpr double kMaxTurnDeg = 5.0, kMaxMove = 0.1;
bool camera_continues(const Camera& from, const Camera& to);

/// Cameras equal in every field (the history's pixels are this frame's).
bool same_camera(const Camera& a, const Camera& b);

}  // namespace fulgur::render::detail
