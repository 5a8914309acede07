// The rain's lights' extinction (shaders/rain_lights.comp): at each voxel with rain, the rain's
// mean extinction along the straight path from the voxel to the channel's lights below the
// rain's top (their centroid), over the rain's largest, in the density texture's alpha, which
// the march reads with the fetch it already makes. The march multiplies each light's
// contribution at a rain sample by exp(-that mean x the sample's distance to the light): the
// light's attenuation by the rain on its way to the drops that scatter it. The cloud is left
// out: the lights and the rain are below the lowest cloud base over the rain.
//
// The mean, not the transmittance, is stored: it is smooth where the transmittance has a kink (at
// a light in the rain, exp(-sigma r) falls off linearly in r) and exact in uniform rain, so the
// voxel's resolution and 8 bits hold it (2 km from a light in rain of the largest extinction,
// half a step is an optical depth of 0.011). One mean for the 8 lights, toward their centroid:
// a map per light (or pair of lights) costs a fetch per rain sample, which cost the march 14 ms
// of its 82 at 1280x720 with detail and rain (docs/render.md). It depends on the lights'
// positions, the volume and the rain, not on the lights' intensities: a flash's decay and
// restrikes keep it; a leader's growing channel or another strike makes it again.
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace fulgur::render {

using detail::FrameUniforms;

namespace {

// One sample per density voxel of a path's length, at most kMaxLightSamples (a path of 8 km or more
// at 125 m voxels is sampled coarser), as the ground lights' map.
constexpr int kMaxLightSamples = 64;

// The lights' centroid (they carry equal power: split_channel).
glm::vec3 centroid(const FrameUniforms& u) {
    glm::dvec3 c(0.0);
    for (int i = 0; i < u.rain_lights; ++i) c += glm::dvec3(u.block.rain_light[i]);
    return glm::vec3(c / double(std::max(u.rain_lights, 1)));
}

// What the extinction is made from besides the volume and the rain (set_volume, which makes a
// new texture, clears the key): the lights' centroid.
std::vector<float> map_key(const FrameUniforms& u) {
    const glm::vec3 c = centroid(u);
    return {c.x, c.y, c.z};
}

}  // namespace

void Renderer::Impl::rain_lights_pass(const FrameUniforms& u) {
    if (!(u.rain && u.rain_lights > 0)) return;
    const core::Int3 n{rain_hi.x - rain_lo.x, rain_hi.y - rain_lo.y, rain_hi.z - rain_lo.z};
    if (n.x <= 0 || n.y <= 0 || n.z <= 0) return;
    std::vector<float> key = map_key(u);
    if (detail::same_light_key(key, rain_map_key)) return;
    const GLenum format = density_u8 ? GL_RGBA8 : GL_RGBA16F;
    const GLuint p = program("rain_lights", {{GL_COMPUTE_SHADER, "rain_lights.comp"}},
                             std::string("#define DENSITY_U8 ") + (density_u8 ? "1" : "0") + "\n");
    glUseProgram(p);
    const glm::vec3 c = centroid(u);
    glUniform3f(glGetUniformLocation(p, "u_centroid"), c.x, c.y, c.z);
    glUniform3i(glGetUniformLocation(p, "u_lo"), rain_lo.x, rain_lo.y, rain_lo.z);
    glUniform3i(glGetUniformLocation(p, "u_hi"), rain_hi.x, rain_hi.y, rain_hi.z);
    glUniform1i(glGetUniformLocation(p, "u_max_samples"), kMaxLightSamples);
    glBindTextureUnit(0, density_tex);
    glBindImageTexture(0, density_tex, 0, GL_TRUE, 0, GL_READ_WRITE, format);
    glDispatchCompute(GLuint((n.x + 3) / 4), GLuint((n.y + 3) / 4), GLuint((n.z + 3) / 4));
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
    rain_map_key = std::move(key);
}

}  // namespace fulgur::render
