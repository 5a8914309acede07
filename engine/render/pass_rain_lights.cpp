// The rain's lights' extinction map (shaders/rain_lights.comp): for each of the channel's point
// lights below the rain's top, the mean extinction (rain and cloud, 1/m) along the straight path
// from it to each point of the rain, on a grid over the density's box below the rain's top. The
// march multiplies each light's contribution at a rain sample by exp(-mean extinction x the
// sample's exact distance to it): the light's attenuation on its way to the drops that scatter it.
//
// The mean, not the transmittance, is tabulated: it is smooth where the transmittance has a kink
// (at the light, exp(-sigma r) falls off linearly in r) and exact in uniform rain, so the grid can
// be coarse. It depends on the lights' positions, the density's box and the rain, not on the
// lights' intensities: a flash's decay and restrikes keep it; a leader's growing channel or
// another strike makes it again.
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace fulgur::render {

using detail::FrameBlock;
using detail::FrameUniforms;

namespace {

// One sample per density voxel of a path's length, at most kMaxSamples (a path of 8 km or more
// at 125 m voxels is sampled coarser), as the ground lights' map.
constexpr int kMaxSamples = 64;

// What the map is made from: the lights' positions, the density's box and extinction, the rain,
// the map's grid.
std::vector<float> map_key(const FrameUniforms& u) {
    const FrameBlock& f = u.block;
    std::vector<float> key;
    key.push_back(float(u.rain_lights));
    for (int i = 0; i < u.rain_lights; ++i) detail::append_components(key, f.rain_light[i], 3);
    detail::append_components(key, f.vol_min);
    detail::append_components(key, f.vol_size);
    detail::append_components(key, f.rain, 3);
    detail::append_components(key, f.rain_map_min);
    detail::append_components(key, f.rain_map_size, 3);
    return key;
}

// Two keys of the same map: the lights' positions within 1e-5 of themselves (a flash dimming
// moves their power centroids by float rounding, ~1e-7; the cells are 250 m), the rest alike.
bool same_map(const std::vector<float>& a, const std::vector<float>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i)
        if (!(std::abs(a[i] - b[i]) <= 1e-5f * std::max({std::abs(a[i]), std::abs(b[i]), 1.0f}))) return false;
    return true;
}

}  // namespace

void Renderer::Impl::rain_lights_pass(const FrameUniforms& u) {
    if (!(u.rain && u.rain_lights > 0)) return;
    const FrameBlock& f = u.block;
    const float cell = f.rain_map_min.w;
    const core::Int3 dims{int(std::lround(f.rain_map_size.x / cell)), int(std::lround(f.rain_map_size.y / cell)),
                          int(std::lround(f.rain_map_size.z / cell))};
    if (!(dims == rain_map_dims) || !rain_map_tex[0]) {
        for (GLuint& t : rain_map_tex) {
            detail::delete_texture(t);
            t = detail::make_texture_3d(GL_RGBA16F, dims);
        }
        rain_map_dims = dims;
        rain_map_key.clear();
    }
    std::vector<float> key = map_key(u);
    if (!same_map(key, rain_map_key)) {
        const GLuint p = program("rain_lights", {{GL_COMPUTE_SHADER, "rain_lights.comp"}});
        glUseProgram(p);
        glUniform1i(glGetUniformLocation(p, "u_lights"), u.rain_lights);
        glUniform1i(glGetUniformLocation(p, "u_max_samples"), kMaxSamples);
        glBindTextureUnit(0, density_tex);
        glBindImageTexture(0, rain_map_tex[0], 0, GL_TRUE, 0, GL_WRITE_ONLY, GL_RGBA16F);
        glBindImageTexture(1, rain_map_tex[1], 0, GL_TRUE, 0, GL_WRITE_ONLY, GL_RGBA16F);
        glDispatchCompute(GLuint((dims.x + 3) / 4), GLuint((dims.y + 3) / 4), GLuint((dims.z + 3) / 4));
        glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
        rain_map_key = std::move(key);
    }
    glBindTextureUnit(16, rain_map_tex[0]);
    glBindTextureUnit(17, rain_map_tex[1]);
}

}  // namespace fulgur::render
