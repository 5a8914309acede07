// The composite pass: the upsampled march over the background, plus the bolt and the glare,
// tone mapped into the caller's framebuffer.
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
    prepare_stars(u, !u.host && u.stars);
    const GLuint p = composite_program(u.host ? 2 : 0);
    glUseProgram(p);
    bind_composite_inputs(p);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(caller.fbo));
    glViewport(0, 0, u.width, u.height);
    if (u.host) {
        // A host's frame: dst = L + T dst (premultiplied radiance over the host's radiance); its alpha is kept.
        glEnable(GL_BLEND);
        glBlendFuncSeparate(GL_ONE, GL_SRC_ALPHA, GL_ZERO, GL_ONE);
    }
    glDrawArrays(GL_TRIANGLES, 0, 3);
    if (u.host) {
        glBlendFunc(GL_ONE, GL_ZERO);
        glDisable(GL_BLEND);
    }
    timer.end(kComposite);
}

void Renderer::Impl::prepare_stars(const FrameUniforms& u, bool stars) {
    composite_stars = 0;
    if (!stars) return;
    // What star_radiance reads: the camera's frame and lens, the output size, the stars' radiance
    // and the sky and ground switches.
    const detail::FrameBlock& f = u.block;
    std::vector<float> key;
    for (const glm::vec4* v : {&f.cam_pos, &f.cam_fwd, &f.cam_right, &f.cam_up, &f.sizes})
        detail::append_components(key, *v);
    detail::append_components(key, f.sky_params, 3);     // not its w: the exposure
    detail::append_components(key, f.ground_params, 3);  // not its w: the number of ground lights
    const bool still = key == star_previous;
    star_previous = key;
    if (!still) {
        composite_stars = 1;
        return;
    }
    if (key != star_key || !star_target.tex) {
        star_target.ensure(u.width, u.height);
        const GLuint p = program("stars", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "stars.frag"}});
        glUseProgram(p);
        glBindFramebuffer(GL_FRAMEBUFFER, star_target.fbo);
        glViewport(0, 0, u.width, u.height);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        star_key = key;
    }
    composite_stars = 2;
}

GLuint Renderer::Impl::composite_program(int output) {
    const std::string defines = "#define OUTPUT " + std::to_string(output) + "\n#define GLARE " +
                                (glare_ran ? "1" : "0") + "\n#define CORE " + (core_drawn ? "1" : "0") +
                                "\n#define STARS " + std::to_string(composite_stars) + "\n#define DITHER " +
                                (composite_dither ? "1" : "0") + "\n";
    return program("composite", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "composite.frag"}},
                   defines);
}

void Renderer::Impl::bind_composite_inputs(GLuint p) const {
    glUniform1f(glGetUniformLocation(p, "u_glare_keep"), glare_ran ? float(glare_fit.keep) : 1.0f);
    glBindTextureUnit(3, march_out->tex);
    glBindTextureUnit(4, core_target.tex);
    glBindTextureUnit(5, glare_ran ? glare_up[0].tex : march_out->tex);
    glBindTextureUnit(6, composite_stars == 2 ? star_target.tex : march_out->tex);
}

}  // namespace fulgur::render
