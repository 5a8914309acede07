// The bolt pass: the transmittance to each segment's endpoints, then the HDR core ribbons at
// full resolution.
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

namespace fulgur::render {

using detail::FrameUniforms;
using detail::kBolt;
using detail::PassTimer;

/// Bolt: endpoint transmittances, then the HDR core ribbons at full resolution. A frame that
/// draws no channel neither clears nor reads the core target (core_drawn: the composite's CORE 0).
void Renderer::Impl::bolt_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer, FrameStats& stats) {
    core_drawn = st.bolt && seg_count > 0;
    if (!core_drawn) return;
    timer.begin(kBolt);
    const float clear[4] = {0, 0, 0, 0};
    glClearNamedFramebufferfv(core_target.fbo, GL_COLOR, 0, clear);
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
    glUniform1f(glGetUniformLocation(p, "u_min_width_px"), float(st.bolt_min_width_px));
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
