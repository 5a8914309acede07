// The composite pass: the upsampled march over the background, plus the bolt and the glare,
// tone mapped into the caller's framebuffer.
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

#include <cmath>
#include <cstdint>
#include <vector>

namespace fulgur::render {

using detail::CallerTarget;
using detail::FrameUniforms;
using detail::kComposite;
using detail::PassTimer;

/// Composite: upsampled march + background (sky, stars, ground) * T + bolt, tone mapped
/// into the caller's framebuffer.
void Renderer::Impl::composite_pass(const FrameUniforms& u, const CallerTarget& caller, PassTimer& timer) {
    timer.begin(kComposite);
    prepare_stars(u, !u.host && u.stars, composite_overlays);
    // Display values are upsampled only where there is something to upsample, and never into a
    // host's frame (radiance, blended); the glare's finest level may have written them already.
    composite_display = wants_display(u);
    if (composite_display && !display_written) display_pass(u);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(caller.fbo));
    if (u.host) {
        // A host's frame: dst = L + T dst (premultiplied radiance over the host's radiance); its alpha is kept.
        glEnable(GL_BLEND);
        glBlendFuncSeparate(GL_ONE, GL_SRC_ALPHA, GL_ZERO, GL_ONE);
    }
    draw_composite(u.host ? 2 : 0);
    if (u.host) {
        glBlendFunc(GL_ONE, GL_ZERO);
        glDisable(GL_BLEND);
    }
    timer.end(kComposite);
}

void Renderer::Impl::display_pass(const FrameUniforms& u) {
    display_target.ensure(u.internal_width, u.internal_height, GL_RGBA8);
    const std::string defines = std::string("#define GLARE ") + (glare_ran ? "1" : "0") + "\n#define DITHER " +
                                (composite_dither ? "1" : "0") + "\n";
    const GLuint p =
        program("display", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "display.frag"}}, defines);
    glUseProgram(p);
    bind_frame_radiance();
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, display_target.fbo);
    glViewport(0, 0, display_target.w, display_target.h);
    glDrawArrays(GL_TRIANGLES, 0, 3);
}

namespace {

// background.glsl's kStarSpot: a star's spot is cut at this radius (pixels at the view's centre).
constexpr double kStarSpotPixels = 3.0;

// The widest point star_points.vert asks for in a frame (pixels): a spot's half-width on screen
// is at most its reach on the cube face, 3 kStarSpot pixel angles (1 + |uv|^2 <= 3; an angle is
// at most its distance in face coordinates), times 1 + t^2 pixels per pixel angle at a direction
// t (tangent) off the view axis, taken at the frame's corner; sqrt 2 and a quarter more are
// margins (the box of the spot's ellipse, spots centred off the frame), plus a pixel.
double widest_star_point(const detail::FrameBlock& f) {
    const double tan_half = f.cam_pos.w, aspect = f.cam_fwd.w;
    const double tx = tan_half * aspect * (1.0 + std::abs(double(f.cam_right.w)));
    const double ty = tan_half * (1.0 + std::abs(double(f.cam_up.w)));
    return 2.0 * (1.25 * std::sqrt(2.0) * 3.0 * kStarSpotPixels * (1.0 + tx * tx + ty * ty) + 1.0);
}

// common.glsl's hash_u32 (PCG's output permutation of an LCG step) and its three-word form.
std::uint32_t hash_u32(std::uint32_t v) {
    const std::uint32_t state = v * 747796405u + 2891336453u;
    const std::uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}
std::uint32_t hash_u32(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
    return hash_u32(x ^ hash_u32(y ^ hash_u32(z)));
}

// The cells of background.glsl's star cube map (kStarCells per face edge) that may hold a star,
// as star_points.vert numbers them (face, row, column): star_draws() puts one where its
// presence byte / 255 < kStarProbability = 0.07, a byte of at most 17; the list takes 18 as well,
// a margin for the shader's float arithmetic, whose own test decides. 7% of the cells, so the
// vertex shader runs for them only.
std::vector<std::uint32_t> star_cell_list() {
    constexpr std::uint32_t edge = 160;  // background.glsl's kStarCells
    std::vector<std::uint32_t> cells;
    for (std::uint32_t face = 0; face < 6; ++face)
        for (std::uint32_t y = 0; y < edge; ++y)
            for (std::uint32_t x = 0; x < edge; ++x)
                if ((hash_u32(x, y, face) & 255u) <= 18u) cells.push_back((face * edge + y) * edge + x);
    return cells;
}

}  // namespace

void Renderer::Impl::prepare_stars(const FrameUniforms& u, bool stars, bool points) {
    composite_stars = 0;
    star_guard = 0.0f;
    if (!stars) return;
    // The stars as points over the composite without them (finding every pixel's star cell is
    // ~5 ms of a 1280x720 composite on llvmpipe; a few percent of the pixels are near a star),
    // unless the view is so wide that a spot needs a wider point than GL draws.
    if (max_point_size == 0.0f) {
        float range[2] = {1.0f, 1.0f};
        glGetFloatv(GL_POINT_SIZE_RANGE, range);
        max_point_size = range[1];
    }
    const double widest = widest_star_point(u.block);
    if (points && widest <= double(max_point_size))
        star_guard = float(std::ceil(0.5 * widest));
    else
        composite_stars = 1;
}

void Renderer::Impl::draw_composite(int output) {
    // The core as an overlay: not into a host's frame (its blend would add the ribbons' pixels twice).
    const bool core_overlay = core_drawn && composite_overlays && output != 2;
    const bool star_overlay = star_guard > 0.0f;
    const GLuint p = composite_program(output, Overlay::None, core_drawn && !core_overlay, composite_stars);
    glUseProgram(p);
    bind_composite_inputs(p);
    glViewport(0, 0, out_w, out_h);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    // Each overlay's pixels get the whole composite: the core's with the stars, the stars' with the core.
    if (core_overlay) {
        const GLuint q = composite_program(output, Overlay::Core, true, star_overlay || composite_stars == 1 ? 1 : 0);
        glUseProgram(q);
        bind_composite_inputs(q);
        // bolt.vert's ribbons as the bolt pass drew them, 2 pixels wider on every side: a superset of
        // the pixels they wrote, whatever the rounding of a program compiled apart.
        glUniform1f(glGetUniformLocation(q, "u_min_width_px"), core_min_width_px);
        glUniform1f(glGetUniformLocation(q, "u_margin_px"), 2.0f);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, seg_buf.id);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, endpoint_buf.id);
        glDrawArrays(GL_TRIANGLES, 0, 6 * seg_count);
    }
    if (!star_overlay) return;
    const GLuint q = composite_program(output, Overlay::Stars, core_drawn, 1);
    glUseProgram(q);
    bind_composite_inputs(q);
    glUniform1f(glGetUniformLocation(q, "u_guard"), star_guard);
    const int g = int(star_guard);
    glViewport(-g, -g, out_w + 2 * g, out_h + 2 * g);
    glEnable(GL_PROGRAM_POINT_SIZE);
    if (star_cell_count == 0) {
        const std::vector<std::uint32_t> cells = star_cell_list();
        star_cells.upload(cells.data(), cells.size() * sizeof(std::uint32_t));
        star_cell_count = int(cells.size());
    }
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, star_cells.id);
    glDrawArrays(GL_POINTS, 0, star_cell_count);
    glDisable(GL_PROGRAM_POINT_SIZE);
    glViewport(0, 0, out_w, out_h);
}

GLuint Renderer::Impl::composite_program(int output, Overlay overlay, bool core, int stars) {
    const std::string defines = "#define OUTPUT " + std::to_string(output) + "\n#define GLARE " +
                                (glare_ran ? "1" : "0") + "\n#define CORE " + (core ? "1" : "0") + "\n#define STARS " +
                                std::to_string(stars) + "\n#define DITHER " + (composite_dither ? "1" : "0") +
                                "\n#define DISPLAY " + (output == 0 && composite_display ? "1" : "0") + "\n";
    const char* vertex = overlay == Overlay::Core    ? "bolt.vert"
                         : overlay == Overlay::Stars ? "star_points.vert"
                                                     : "fullscreen.vert";
    const char* name = overlay == Overlay::Core    ? "composite_core"
                       : overlay == Overlay::Stars ? "composite_stars"
                                                   : "composite";
    return program(name, {{GL_VERTEX_SHADER, vertex}, {GL_FRAGMENT_SHADER, "composite.frag"}}, defines);
}

void Renderer::Impl::bind_frame_radiance() const {
    glBindTextureUnit(3, march_out->tex);
    glBindTextureUnit(5, glare_ran ? glare_up[0].tex : march_out->tex);
}

void Renderer::Impl::bind_composite_inputs(GLuint p) const {
    glUniform1f(glGetUniformLocation(p, "u_glare_keep"), glare_ran ? float(glare_fit.keep) : 1.0f);
    glUniform1f(glGetUniformLocation(p, "u_core_scale"), core_scale);
    bind_frame_radiance();
    // The full-resolution core read at its own pixel, as an image: on llvmpipe an image load
    // costs less than a texel fetch (at 1280x720, ~0.9 ms of a 12 ms composite for one target).
    glBindImageTexture(0, core_target.tex, 0, GL_FALSE, 0, GL_READ_ONLY, GL_RGBA32F);
    if (composite_display) glBindTextureUnit(6, display_target.tex);
}

}  // namespace fulgur::render
