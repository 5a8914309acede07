// A host engine's frame: its camera from its matrices, its depth buffer bound for the march and
// the channel's core, and the storm composited into its HDR target (Renderer::render_into_host).
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

#include <glm/gtc/matrix_access.hpp>

#include <cmath>
#include <string>

namespace fulgur::render {

namespace {

std::string entry(const char* matrix, int col, int row) {
    return std::string(matrix) + "[" + std::to_string(col) + "][" + std::to_string(row) + "]";
}

void check_finite(const glm::dmat4& m, const char* matrix) {
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
            if (!std::isfinite(m[c][r]))
                throw core::Error("render: host frame", entry(matrix, c, r) + " is not finite");
}

}  // namespace

Camera camera_from_matrices(const glm::dmat4& view, const glm::dmat4& projection, double aspect) {
    check_finite(view, "view");
    check_finite(projection, "projection");
    // A rigid motion: orthonormal rotation (det +1), bottom row (0, 0, 0, 1).
    const glm::dmat3 rot(view);
    const glm::dmat3 gram = glm::transpose(rot) * rot;
    for (int c = 0; c < 3; ++c) {
        if (view[c][3] != 0.0)
            throw core::Error("render: host frame", entry("view", c, 3) + " must be 0 (a rigid motion)");
        for (int r = 0; r < 3; ++r)
            if (std::abs(gram[c][r] - (c == r ? 1.0 : 0.0)) > 1e-5)
                throw core::Error("render: host frame", "view is not a rotation and translation (scaled or sheared)");
    }
    if (view[3][3] != 1.0 || glm::determinant(rot) < 0.0)
        throw core::Error("render: host frame", "view is not a rotation and translation (mirrored or projective)");
    // A perspective projection: w_clip = -z_eye, no x/y skew or translation, positive scales.
    const double p00 = projection[0][0], p11 = projection[1][1];
    const bool perspective = projection[0][3] == 0.0 && projection[1][3] == 0.0 && projection[2][3] == -1.0 &&
                             projection[3][3] == 0.0 && projection[1][0] == 0.0 && projection[0][1] == 0.0 &&
                             projection[3][0] == 0.0 && projection[3][1] == 0.0 && projection[0][2] == 0.0 &&
                             projection[1][2] == 0.0;
    if (!perspective)
        throw core::Error("render: host frame",
                          "projection is not a perspective projection (row 3 must be (0, 0, -1, 0), no skew)");
    if (!(p00 > 0.0) || !(p11 > 0.0))
        throw core::Error("render: host frame", "projection's " + entry("projection", 0, 0) + " and " +
                                                    entry("projection", 1, 1) + " must be positive");
    const double own = p11 / p00;
    if (!(aspect > 0.0) || std::abs(own / aspect - 1.0) > 1e-3)
        throw core::Error("render: host frame", "projection's aspect ratio " + core::format_number(own, 6) +
                                                    " differs from the target's " + core::format_number(aspect, 6));
    const glm::dmat4 inv = glm::inverse(view);
    Camera c;
    c.position = glm::dvec3(inv[3]);
    c.target = c.position - glm::dvec3(inv[2]);  // the camera looks down its -z
    c.up = glm::dvec3(inv[1]);
    c.vertical_fov_deg = glm::degrees(2.0 * std::atan(1.0 / p11));
    c.lens_shift = {projection[2][0], projection[2][1]};
    return c;
}

std::vector<Renderer::FlashLight> Renderer::flash_lights(int k, double ground_height) {
    FULGUR_ASSERT(k >= 0 && std::isfinite(ground_height), "flash_lights needs k >= 0 and a finite ground height");
    Impl& m = *impl_;
    m.rebuild_ground_lights(k, ground_height);
    std::vector<FlashLight> out;
    for (const glm::vec4& l : m.ground_lights) out.push_back({glm::dvec3(glm::vec3(l)), double(l.w)});
    return out;
}

void Renderer::Impl::attach_host_depth(const HostFrame& host, detail::FrameUniforms& u) {
    u.host = true;
    if (host.depth_texture == 0) return;
    u.block.host_depth = glm::vec4(float(host.projection[2][2]), float(host.projection[3][2]),
                                   host.depth_zero_to_one ? 1.0f : 0.0f, host.reversed_z ? -1.0f : 1.0f);
    if (!host_sampler) {
        // Depth values as numbers, whatever the texture's own comparison mode and filter.
        glCreateSamplers(1, &host_sampler);
        glSamplerParameteri(host_sampler, GL_TEXTURE_COMPARE_MODE, GL_NONE);
        glSamplerParameteri(host_sampler, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glSamplerParameteri(host_sampler, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    }
    glBindTextureUnit(8, host.depth_texture);
    glBindSampler(8, host_sampler);
}

void Renderer::Impl::detach_host_depth() {
    glBindSampler(8, 0);
    glBindTextureUnit(8, 0);
}

}  // namespace fulgur::render
