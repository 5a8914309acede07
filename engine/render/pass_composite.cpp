// The composite pass: the upsampled march over the background, plus the bolt, tone mapped
// into the caller's framebuffer.
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

namespace fulgur::render {

using detail::CallerTarget;
using detail::FrameUniforms;
using detail::kComposite;
using detail::PassTimer;

/// Composite: upsampled march + background (sky, stars, ground) * T + bolt, tone mapped
/// into the caller's framebuffer.
void Renderer::Impl::composite_pass(const FrameUniforms& u, const CallerTarget& caller, PassTimer& timer) {
    timer.begin(kComposite);
    const GLuint p =
        program("composite", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "composite.frag"}});
    glUseProgram(p);
    glUniform1i(glGetUniformLocation(p, "u_hdr_output"), 0);
    glBindTextureUnit(3, march_target.tex);
    glBindTextureUnit(4, core_target.tex);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(caller.fbo));
    glViewport(0, 0, u.width, u.height);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    timer.end(kComposite);
}

}  // namespace fulgur::render
