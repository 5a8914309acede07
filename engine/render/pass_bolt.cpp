// The bolt pass: the transmittance to each segment's endpoints, then the HDR core ribbons at
// full resolution.
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

#include <algorithm>
#include <limits>
#include <vector>

namespace fulgur::render {

using detail::FrameUniforms;
using detail::kBolt;
using detail::PassTimer;

namespace {

// The output pixels [x0, x1) x [y0, y1) the bolt's ribbons can cover this frame (empty: none).
glm::ivec4 ribbon_footprint(const std::vector<ChannelSegment>& segments, const glm::mat4& view_proj, float tan_half,
                            int width, int height, float min_width_px) {
    // bolt.vert's ribbons: each segment clipped to w >= 0.01, projected, widened to at least
    // min_width_px; its quad reaches half a width past each end and to each side.
    constexpr float kNear = 1e-2f;
    const glm::vec2 half(0.5f * float(width), 0.5f * float(height));
    const float focal = half.y / tan_half;
    glm::vec2 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    for (const ChannelSegment& s : segments) {
        glm::vec4 ca = view_proj * glm::vec4(s.a, 1.0f), cb = view_proj * glm::vec4(s.b, 1.0f);
        if (ca.w < kNear && cb.w < kNear) continue;
        if (ca.w < kNear) ca = glm::mix(ca, cb, (kNear - ca.w) / (cb.w - ca.w));
        if (cb.w < kNear) cb = glm::mix(cb, ca, (kNear - cb.w) / (ca.w - cb.w));
        const glm::vec2 pa = glm::vec2(ca) / ca.w * half, pb = glm::vec2(cb) / cb.w * half;
        const float w = std::max({2.0f * s.radius * focal / ca.w, 2.0f * s.radius * focal / cb.w, min_width_px});
        lo = glm::min(lo, glm::min(pa, pb) - w);
        hi = glm::max(hi, glm::max(pa, pb) + w);
    }
    if (!(lo.x <= hi.x && lo.y <= hi.y)) return glm::ivec4(0);
    // Two pixels of margin for the rasterizer's and float's rounding; clamped in float first
    // (a segment just in front of the camera projects far off screen).
    const glm::vec2 size{float(width), float(height)};
    const glm::vec2 a = glm::clamp(glm::floor(lo + half) - 2.0f, glm::vec2(0.0f), size);
    const glm::vec2 b = glm::clamp(glm::ceil(hi + half) + 2.0f, glm::vec2(0.0f), size);
    return glm::ivec4(int(a.x), int(a.y), int(b.x), int(b.y));
}

}  // namespace

/// Bolt: endpoint transmittances, then the HDR core ribbons at full resolution. A frame that
/// draws no channel neither clears nor reads the core target (core_drawn: the composite's CORE 0).
void Renderer::Impl::bolt_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer, FrameStats& stats) {
    core_drawn = st.bolt && seg_count > 0;
    core_scale = 1.0f;
    if (!core_drawn) {
        core_kept_key.clear();
        return;
    }
    // A still camera reusing its history, the channel's shape unchanged: the core drawn for it
    // times the channel's factor since. Its radiance is proportional to the segments'
    // intensities (the view, their geometry and transmittance unchanged), which the channel's
    // tracker holds proportional to within 1e-5, or the history is marched again.
    const detail::TemporalState& h = temporal;
    const bool reused = stats.temporal == TemporalStep::Reused && march_out == &h.march;
    std::vector<double> key = kept_channel_key(st, u);
    key.push_back(double(core_target.tex));
    if (reused && key == core_kept_key && core_kept_factor > 0.0) {
        core_scale = float(h.channel.rescale() / core_kept_factor);
        stats.bolt_segments = seg_count;
        return;
    }
    core_kept_key = reused ? key : std::vector<double>{};
    core_kept_factor = reused ? h.channel.rescale() : 0.0;
    timer.begin(kBolt);
    // The target is zero outside the last bolt's footprint (a new texture: everywhere cleared):
    // only that footprint is cleared (a full-resolution RGBA32F clear is 2-3 ms at 1280x720).
    const float clear[4] = {0, 0, 0, 0};
    const glm::ivec3 of(int(core_target.tex), u.width, u.height);
    const glm::ivec4 old = core_footprint_of == of ? core_footprint : glm::ivec4(0, 0, u.width, u.height);
    if (old.z > old.x && old.w > old.y) {
        glEnable(GL_SCISSOR_TEST);
        glScissor(old.x, old.y, old.z - old.x, old.w - old.y);
        glClearNamedFramebufferfv(core_target.fbo, GL_COLOR, 0, clear);
        glDisable(GL_SCISSOR_TEST);
    }
    core_footprint = ribbon_footprint(bolt.segments, u.block.view_proj, u.block.cam_pos.w, u.width, u.height,
                                      float(st.bolt_min_width_px));
    core_footprint_of = of;
    // The channel seen through the same detailed density the march draws.
    glUseProgram(
        program("bolt_t", {{GL_COMPUTE_SHADER, "bolt_transmittance.comp"}},
                std::string(u.detail ? "#define HAS_DETAIL 1\n" : "") + (u.rain ? "#define HAS_RAIN 1\n" : "")));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, seg_buf.id);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, endpoint_buf.id);
    glDispatchCompute(GLuint((seg_count + 63) / 64), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    const GLuint p = program("bolt", {{GL_VERTEX_SHADER, "bolt.vert"}, {GL_FRAGMENT_SHADER, "bolt.frag"}});
    glUseProgram(p);
    core_min_width_px = float(st.bolt_min_width_px);
    glUniform1f(glGetUniformLocation(p, "u_min_width_px"), core_min_width_px);
    glUniform1f(glGetUniformLocation(p, "u_margin_px"), 0.0f);
    glBindFramebuffer(GL_FRAMEBUFFER, core_target.fbo);
    glViewport(0, 0, u.width, u.height);
    glEnable(GL_BLEND);
    glBlendEquation(GL_MAX);  // overlapping caps/joints do not double the core
    glDrawArrays(GL_TRIANGLES, 0, 6 * seg_count);
    glBlendEquation(GL_FUNC_ADD);
    glDisable(GL_BLEND);
    timer.end(kBolt);
    stats.bolt_segments = seg_count;
}

}  // namespace fulgur::render
