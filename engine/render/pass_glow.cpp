// The glow pass: additive quads along the bolt's strokes, textured with the radial profile
// of the air's single scattering around them, into the emission buffer the march attenuates.
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace fulgur::render {

using detail::FrameUniforms;
using detail::kGlow;
using detail::PassTimer;

namespace {

constexpr int kGlowProfileSize = 256;

}  // namespace

/// Quads along the strokes (a centre and a power each), rebuilt by prepare_frame() when the
/// glow radius or the bolt changed.
void Renderer::Impl::rebuild_glow_quads(double radius) {
    std::vector<glm::vec4> quads;
    const double spacing = std::max(radius / 4.0, 10.0);  // Riemann sum of the line integral
    for (const ChannelSegment& s : bolt.segments) {
        const double len = glm::length(glm::dvec3(s.b - s.a));
        if (s.intensity <= 0.0f || len <= 0.0) continue;
        const int n = std::max(1, int(std::ceil(len / spacing)));
        for (int i = 0; i < n; ++i) {
            const glm::vec3 c = s.a + (s.b - s.a) * float((i + 0.5) / n);
            quads.emplace_back(c, float(double(s.intensity) * len / n));
        }
    }
    glow_count = int(quads.size());
    glow_buf.upload(quads.data(), quads.size() * sizeof(glm::vec4));
    glow_built_radius = radius;
}

/// Radiance per unit source intensity at impact parameter b = rho R of the single
/// scattering by air of scattering coefficient sigma (isotropic phase) around a point
/// source: L = sigma I / (4 b) for a ray passing at distance b (integral of
/// sigma/(4 pi) I / r^2 along the ray), attenuated by exp(-sigma b), with b regularized
/// to sqrt(b^2 + b0^2) (b0 = 25 m: the glow's unresolved core) and tapered to zero at R
/// by (1 - rho^2)^2 so quads end without a seam.
void Renderer::Impl::rebuild_profile(double radius, double sigma) {
    std::vector<float> v(kGlowProfileSize);
    const double b0 = 25.0;
    for (int i = 0; i < kGlowProfileSize; ++i) {
        const double rho = (i + 0.5) / kGlowProfileSize, b = rho * radius;
        const double taper = (1.0 - rho * rho) * (1.0 - rho * rho);
        v[std::size_t(i)] = float(sigma / (4.0 * std::sqrt(b * b + b0 * b0)) * std::exp(-sigma * b) * taper);
    }
    if (!profile_tex) {
        glCreateTextures(GL_TEXTURE_1D, 1, &profile_tex);
        glTextureStorage1D(profile_tex, 1, GL_R32F, kGlowProfileSize);
        glTextureParameteri(profile_tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        glTextureParameteri(profile_tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTextureParameteri(profile_tex, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    }
    glTextureSubImage1D(profile_tex, 0, 0, kGlowProfileSize, GL_RED, GL_FLOAT, v.data());
    profile_radius = radius;
    profile_sigma = sigma;
}

/// Glow: additive quads along the strokes into the emission buffer at internal resolution
/// (bound to unit 2 for the march). A temporal plan that marches every grid-th pixel from its
/// phase reads the glow there only: the quads are drawn into a target of those pixels, each
/// fragment at its internal pixel's centre (the quads' clip coordinates mapped so), which
/// the march reads at its own fragment (march_pixel.glsl's GLOW_ON_GRID). The quads cover
/// the same pixels either way, each shaded as at full resolution (test_render_temporal: 1.1e-4
/// from a fresh render's glow there); at 1280x720 orbiting during a flash the pass went from
/// 2.4 to 1.1-1.3 ms (`fulgur-bench render`; what is left is the quads' vertices and the clear).
void Renderer::Impl::glow_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer, FrameStats& stats,
                               bool draw, const detail::TemporalPlan* plan) {
    const int grid = plan ? plan->grid() : 1;
    detail::Target& target = grid > 1 ? glow_grid_target : glow_target;
    if (u.glow && draw) {
        timer.begin(kGlow);
        if (profile_radius != st.glow_radius || profile_sigma != st.air_scattering)
            rebuild_profile(st.glow_radius, st.air_scattering);
        const int iw = u.internal_width, ih = u.internal_height;
        // Internal pixel phase + grid q + 0.5 at the target's pixel q + 0.5: x_ndc' = a x_ndc + b.
        glm::vec4 window(1.0f, 1.0f, 0.0f, 0.0f);
        if (grid > 1) {
            const glm::ivec2 phase = plan->phase;
            const glm::ivec2 marched = plan->marched_size(iw, ih);
            const int fw = marched.x, fh = marched.y;
            glow_grid_target.ensure(fw, fh);
            const auto map = [&](int size, int n, int first) {
                return glm::dvec2(double(size) / (grid * n), double(size - 2 * first - 1) / (grid * n) + 1.0 / n - 1.0);
            };
            const glm::dvec2 x = map(iw, fw, phase.x), y = map(ih, fh, phase.y);
            window = glm::vec4(float(x[0]), float(y[0]), float(x[1]), float(y[1]));
        }
        glBindFramebuffer(GL_FRAMEBUFFER, target.fbo);
        glViewport(0, 0, target.w, target.h);
        const float clear[4] = {0, 0, 0, 0};
        glClearNamedFramebufferfv(target.fbo, GL_COLOR, 0, clear);
        glEnable(GL_BLEND);
        glBlendEquation(GL_FUNC_ADD);
        glBlendFunc(GL_ONE, GL_ONE);
        const GLuint p = program("glow", {{GL_VERTEX_SHADER, "glow.vert"}, {GL_FRAGMENT_SHADER, "glow.frag"}});
        glUseProgram(p);
        glUniform4fv(glGetUniformLocation(p, "u_window"), 1, &window[0]);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, glow_buf.id);
        glBindTextureUnit(5, profile_tex);
        glDrawArrays(GL_TRIANGLES, 0, 6 * glow_count);
        glDisable(GL_BLEND);
        timer.end(kGlow);
        stats.glow_quads = glow_count;
    }
    glBindTextureUnit(2, target.tex);
}

}  // namespace fulgur::render
