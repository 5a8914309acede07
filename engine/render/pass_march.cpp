// The march pass: the ray march at internal resolution (fragment or compute kernel, its
// program chosen by the frame's switches).
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

#include <string>

namespace fulgur::render {

using detail::FrameUniforms;
using detail::kMarch;
using detail::PassTimer;

/// Ray march at internal resolution: in-scattered radiance + attenuated glow, and T.
void Renderer::Impl::march_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer) {
    timer.begin(kMarch);
    march_out = &march_target;
    ground_rain_pass(u);
    rain_lights_pass(u);
    const std::string defines = frame_march_defines(st, u);
    const GLuint p = march_program(st.kernel, defines);
    glUseProgram(p);
    if (st.kernel == MarchKernel::Fragment) {
        glBindFramebuffer(GL_FRAMEBUFFER, march_target.fbo);
        glViewport(0, 0, u.internal_width, u.internal_height);
        glDrawArrays(GL_TRIANGLES, 0, 3);
    } else {
        glBindImageTexture(0, march_target.tex, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
        glDispatchCompute(GLuint((u.internal_width + 7) / 8), GLuint((u.internal_height + 7) / 8), 1);
        glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT);
    }
    timer.end(kMarch);
}

}  // namespace fulgur::render
