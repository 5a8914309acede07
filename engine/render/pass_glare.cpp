// The glare pass: the frame's light (march + bolt core) spread by the eye's point-spread
// function (render::glare_psf) through a pyramid: box downsamples, then tent upsamples that
// add each level with its fitted weight (render::fit_glare). The finest level's sum also holds
// GlareFit::keep of the march (the share left in place) and its transmittance: the composite
// reads it instead of the march and adds keep of the core.
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

#include <string>

#include <glm/trigonometric.hpp>

#include <algorithm>
#include <cmath>

namespace fulgur::render {

using detail::FrameUniforms;
using detail::kGlare;
using detail::PassTimer;

namespace {

// Levels down to a coarsest level of at least 2 texels on its short side (at most 10).
int glare_levels(int w, int h) {
    int n = 1;
    while (n < 10 && (std::min(w, h) >> n) >= 2) ++n;
    return n;
}

// The output pixels per march pixel when that is the same whole number 1 or 2 on both axes
// (internal scale 1 or 0.5 of an even size), else 0: glare_first.frag's fixed reads.
int core_block(const FrameUniforms& u) {
    for (int b : {1, 2})
        if (u.width == b * u.internal_width && u.height == b * u.internal_height) return b;
    return 0;
}

}  // namespace

void Renderer::Impl::glare_pass(const Camera& camera, const Settings& st, const FrameUniforms& u, PassTimer& timer,
                                FrameStats& stats) {
    glare_ran = false;
    if (!(st.glare && core_drawn)) return;  // the bolt pass ran first: the core it drew
    const int levels = glare_levels(u.internal_width, u.internal_height);
    // The fit depends on the view's pixel size and the levels only: kept while they stay.
    const double fov = camera.vertical_fov_deg;
    const double pixel_deg = fov / double(u.height);
    const double aspect = double(u.width) / double(u.height);
    const double half_diagonal =
        glm::degrees(std::atan(std::tan(glm::radians(0.5 * fov)) * std::sqrt(1.0 + aspect * aspect)));
    const double scale = double(u.internal_width) / double(u.width);
    // A frame a few pixels across, whose ray-march pixel is wider than the frame's half diagonal,
    // has no surround within it to spread light to: it is drawn as without the glare.
    if (!(half_diagonal > pixel_deg / scale)) return;
    if (!(glare_key[0] == pixel_deg && glare_key[1] == scale && glare_key[2] == half_diagonal &&
          int(glare_fit.weights.size()) == levels)) {
        glare_fit = fit_glare(pixel_deg, scale, levels, half_diagonal);
        glare_key[0] = pixel_deg, glare_key[1] = scale, glare_key[2] = half_diagonal;
    }
    timer.begin(kGlare);
    glare_down.resize(std::size_t(levels));
    glare_up.resize(std::size_t(levels));
    for (int k = 0; k < levels; ++k) {
        const int w = std::max(1, u.internal_width >> k), h = std::max(1, u.internal_height >> k);
        glare_down[std::size_t(k)].ensure(w, h);
        glare_up[std::size_t(k)].ensure(w, h);
    }
    // Level 0: march + core.
    glUseProgram(program("glare_first",
                         {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "glare_first.frag"}},
                         "#define BLOCK " + std::to_string(core_block(u)) + "\n"));
    glBindTextureUnit(3, march_out->tex);
    glBindTextureUnit(4, core_target.tex);
    glBindFramebuffer(GL_FRAMEBUFFER, glare_down[0].fbo);
    glViewport(0, 0, glare_down[0].w, glare_down[0].h);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    // Down.
    const GLuint down =
        program("glare_down", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "glare_down.frag"}});
    glUseProgram(down);
    for (int k = 1; k < levels; ++k) {
        const detail::Target& fine = glare_down[std::size_t(k - 1)];
        const detail::Target& dst = glare_down[std::size_t(k)];
        glBindTextureUnit(0, fine.tex);
        glUniform2f(glGetUniformLocation(down, "u_fine_texel"), 1.0f / float(fine.w), 1.0f / float(fine.h));
        glUniform2f(glGetUniformLocation(down, "u_size"), float(dst.w), float(dst.h));
        glBindFramebuffer(GL_FRAMEBUFFER, dst.fbo);
        glViewport(0, 0, dst.w, dst.h);
        glDrawArrays(GL_TRIANGLES, 0, 3);
    }
    // Up: each level weighted, plus the coarser sum.
    for (int k = levels - 1; k >= 0; --k) {
        const detail::Target& dst = glare_up[std::size_t(k)];
        const bool coarser = k + 1 < levels;
        const std::string defines = std::string("#define HAS_COARSE ") + (coarser ? "1" : "0") + "\n#define WIDE " +
                                    (k >= kGlareWideFrom ? "1" : "0") + "\n#define FOLD " + (k == 0 ? "1" : "0") + "\n";
        const GLuint up = program(
            "glare_up", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "glare_up.frag"}}, defines);
        glUseProgram(up);
        glBindTextureUnit(0, glare_down[std::size_t(k)].tex);
        glBindTextureUnit(1, coarser ? glare_up[std::size_t(k + 1)].tex : glare_down[std::size_t(k)].tex);
        glUniform1f(glGetUniformLocation(up, "u_weight"), float(glare_fit.weights[std::size_t(k)]));
        if (k == 0) {
            // The finest level holds what the composite reads at the march's resolution: keep x
            // the march + the spread light, and the march's transmittance (composite.frag).
            glUniform1f(glGetUniformLocation(up, "u_keep"), float(glare_fit.keep));
            glBindTextureUnit(3, march_out->tex);
        }
        if (coarser) {
            const detail::Target& c = glare_up[std::size_t(k + 1)];
            glUniform2f(glGetUniformLocation(up, "u_coarse_texel"), 1.0f / float(c.w), 1.0f / float(c.h));
        }
        glUniform2f(glGetUniformLocation(up, "u_size"), float(dst.w), float(dst.h));
        glBindFramebuffer(GL_FRAMEBUFFER, dst.fbo);
        glViewport(0, 0, dst.w, dst.h);
        glDrawArrays(GL_TRIANGLES, 0, 3);
    }
    glare_ran = true;
    stats.glare_keep = glare_fit.keep;
    timer.end(kGlare);
}

}  // namespace fulgur::render
