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

// The view's quantities the glare's fit depends on.
struct GlareView {
    int levels = 0;
    double pixel_deg = 0.0, half_diagonal = 0.0, scale = 0.0;
    // A frame a few pixels across, whose ray-march pixel is wider than the frame's half diagonal,
    // has no surround within it to spread light to: it is drawn as without the glare.
    bool spreads() const { return half_diagonal > pixel_deg / scale; }
};

GlareView glare_view(const Camera& camera, const FrameUniforms& u) {
    GlareView v;
    v.levels = glare_levels(u.internal_width, u.internal_height);
    const double fov = camera.vertical_fov_deg;
    v.pixel_deg = fov / double(u.height);
    const double aspect = double(u.width) / double(u.height);
    v.half_diagonal = glm::degrees(std::atan(std::tan(glm::radians(0.5 * fov)) * std::sqrt(1.0 + aspect * aspect)));
    v.scale = double(u.internal_width) / double(u.width);
    return v;
}

}  // namespace

std::vector<double> Renderer::Impl::kept_channel_key(const Settings& st, const FrameUniforms& u) const {
    const glm::vec4 colour = u.block.light_colour;
    return {double(temporal.history_version),
            double(u.width),
            double(u.height),
            double(float(st.bolt_min_width_px)),
            double(seg_count),
            double(colour.x),
            double(colour.y),
            double(colour.z)};
}

std::vector<double> Renderer::Impl::glare_groups_key_of(const Camera& camera, const Settings& st,
                                                        const FrameUniforms& u) const {
    const GlareView v = glare_view(camera, u);
    if (!(st.glare && st.bolt && seg_count > 0 && v.spreads())) return {};
    // Besides the channel's kept light (the core is in the channel's group, the flash group's S
    // is before the flash colour): the fit.
    std::vector<double> key = kept_channel_key(st, u);
    key.insert(key.end(), {v.pixel_deg, v.scale, v.half_diagonal, double(v.levels)});
    return key;
}

void Renderer::Impl::glare_pass(const Camera& camera, const Settings& st, const FrameUniforms& u, PassTimer& timer,
                                FrameStats& stats) {
    glare_ran = false;
    display_written = false;
    if (!(st.glare && core_drawn)) return;  // the bolt pass ran first: the core it drew
    const GlareView view = glare_view(camera, u);
    const int levels = view.levels;
    const double pixel_deg = view.pixel_deg, half_diagonal = view.half_diagonal, scale = view.scale;
    if (!view.spreads()) return;
    // The fit depends on the view's pixel size and the levels only: kept while they stay.
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
    // Level 0: the light `input` holds (glare_first.frag's GROUP) + the core target times `core_factor`.
    const auto first_level = [&](int group, GLuint input, float core_factor) {
        const GLuint p = program(
            "glare_first", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "glare_first.frag"}},
            "#define BLOCK " + std::to_string(core_block(u)) + "\n#define GROUP " + std::to_string(group) + "\n");
        glUseProgram(p);
        glUniform1f(glGetUniformLocation(p, "u_core_scale"), core_factor);
        glBindTextureUnit(3, input);
        glBindTextureUnit(4, core_target.tex);
        glBindFramebuffer(GL_FRAMEBUFFER, glare_down[0].fbo);
        glViewport(0, 0, glare_down[0].w, glare_down[0].h);
        glDrawArrays(GL_TRIANGLES, 0, 3);
    };
    // Down from level 0, then up, the finest sum into `out` (with the march's share: `fold`;
    // then also the display values the composite upsamples, when it does).
    const bool display = wants_display(u);
    const auto down_and_up = [&](const detail::Target& out, bool fold) {
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
            const detail::Target& dst = k == 0 ? out : glare_up[std::size_t(k)];
            const bool coarser = k + 1 < levels;
            const bool folded = k == 0 && fold, with_display = folded && display;
            const std::string defines = std::string("#define HAS_COARSE ") + (coarser ? "1" : "0") + "\n#define WIDE " +
                                        (k >= kGlareWideFrom ? "1" : "0") + "\n#define FOLD " + (folded ? "1" : "0") +
                                        "\n#define DISPLAY " + (with_display ? "1" : "0") + "\n#define DITHER " +
                                        (composite_dither ? "1" : "0") + "\n";
            const GLuint up = program(
                "glare_up", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "glare_up.frag"}}, defines);
            glUseProgram(up);
            glBindTextureUnit(0, glare_down[std::size_t(k)].tex);
            glBindTextureUnit(1, coarser ? glare_up[std::size_t(k + 1)].tex : glare_down[std::size_t(k)].tex);
            glUniform1f(glGetUniformLocation(up, "u_weight"), float(glare_fit.weights[std::size_t(k)]));
            if (folded) {
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
            if (with_display) {
                display_target.ensure(dst.w, dst.h, GL_RGBA8);
                detail::attach_targets(glare_display_fbo, {dst.tex, display_target.tex});
                glBindFramebuffer(GL_FRAMEBUFFER, glare_display_fbo);
            } else {
                glBindFramebuffer(GL_FRAMEBUFFER, dst.fbo);
            }
            glViewport(0, 0, dst.w, dst.h);
            glDrawArrays(GL_TRIANGLES, 0, 3);
            display_written = display_written || with_display;
        }
    };
    // A still camera whose frame is the history's groups with their factors (nothing marched):
    // the glare is linear in the light, so it is each group's glare with the same factors. The
    // groups' glares are made once from the history (three pyramids) and summed each frame,
    // while the history, the view and the channel's shape stay. The core is in the channel's
    // group: its light scales with the channel's (the channel's tracker holds the segments'
    // intensities proportional to within 1e-5, or the history is marched again). Made when the
    // channel is lit: the core now over the channel's factor is the core at the history's
    // intensity.
    const detail::TemporalState& h = temporal;
    const bool reused = stats.temporal == TemporalStep::Reused && march_out == &h.march;
    const glm::dvec2 factors = h.march_scale;
    const std::vector<double> groups_key = glare_groups_key_of(camera, st, u);
    if (reused && glare_groups_key != groups_key && factors.y > 0.0) {
        const GLuint* hist = h.history[h.current].tex.data();  // flash, statics, channel (temporal.frag)
        for (int g = 0; g < 3; ++g) {
            detail::Target& out = glare_groups[g];
            out.ensure(u.internal_width, u.internal_height);
            first_level(g + 1, hist[g], float(double(core_scale) / factors.y));
            down_and_up(out, false);
        }
        glare_groups_key = groups_key;
        glare_groups_keep = glare_fit.keep;
    }
    if (reused && glare_groups_key == groups_key) {
        // Unless the temporal pass summed it with the march (TemporalPlan::glare_sum).
        if (glare_sum_version != h.march_version) {
            const GLuint p =
                program("glare_sum", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "glare_sum.frag"}});
            glUseProgram(p);
            glUniform1f(glGetUniformLocation(p, "u_keep"), float(glare_fit.keep));
            glUniform2f(glGetUniformLocation(p, "u_factors"), float(factors.x), float(factors.y));
            glBindImageTexture(0, h.march.tex, 0, GL_FALSE, 0, GL_READ_ONLY, GL_RGBA32F);
            for (int g = 0; g < 3; ++g)
                glBindImageTexture(GLuint(1 + g), glare_groups[g].tex, 0, GL_FALSE, 0, GL_READ_ONLY, GL_RGBA32F);
            glBindFramebuffer(GL_FRAMEBUFFER, glare_up[0].fbo);
            glViewport(0, 0, glare_up[0].w, glare_up[0].h);
            glDrawArrays(GL_TRIANGLES, 0, 3);
            glare_sum_version = h.march_version;
        }
    } else {
        first_level(0, march_out->tex, core_scale);
        down_and_up(glare_up[0], true);
        glare_sum_version = 0;
    }
    glare_ran = true;
    stats.glare_keep = glare_fit.keep;
    timer.end(kGlare);
}

}  // namespace fulgur::render
