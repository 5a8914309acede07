// The ground lights' rain transmittance map (shaders/ground_rain.comp): per light, the rain's
// transmittance between it and every point of the ground, on a polar map around its foot. The
// ground's flash light reads it once per light and pixel, where it integrated each path through
// the rain (4 density reads per light). It depends on the lights' positions, the ground's
// height, the rain and the density's box, not on the lights' intensities: a flash's decay and
// restrikes keep it; a leader's growing channel or another strike makes it again.
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace fulgur::render {

using detail::FrameBlock;
using detail::FrameUniforms;

namespace {

// The map's texels per light: azimuths x distances from the foot. At a distance r from a foot
// R below the light a texel spans 2 pi r / kAzimuths across and R / (kRadii (1 - u)^2) along
// (u = r / (r + R)); with R = 1.5 km: 16 m along at the foot, 49 m across and 63 m along at
// 1.5 km, 150 m and 250 m at 4.5 km. Near the foot the paths are steep and the rain's edges
// sharp on the ground; farther out a path runs kilometres through the rain and its
// transmittance varies slowly. On storm-full's flash (640x360, the ground's light against
// paths integrated at 8 samples per voxel) 256 x 128 texels erred by 0.10% on average over the
// lit half of the ground (99th percentile 2.7%), 192 x 96 by 0.18% (5.2%), 128 x 64 by 0.41%
// (11%), each the same with a sample per voxel or per two; 4 samples per path and pixel by
// 5.9% (180%). Across a shaft's soft edge (test_render_rain) the samples count: a sample per
// voxel 0.09%, per two voxels 0.31%, 4 per path 2.6%. Made again every frame, 192 x 96 with a
// sample per voxel costs ~7 ms at 1280x720, what the per-pixel integral costs there; a frame
// that keeps it saves that (docs/render.md).
constexpr int kAzimuths = 192;
constexpr int kRadii = 96;
// One sample per kVoxelsPerSample density voxels of a path's length within the rain, at most
// kMaxGroundSamples (a path of 6.4 km or more of rain below its top is sampled coarser).
constexpr int kVoxelsPerSample = 1;
constexpr int kMaxGroundSamples = 64;

// What the map is made from besides the share of the rain's extinction it is drawn at
// (ground_rain_share): the lights' positions, the density's box, the rain, the ground.
std::vector<float> map_key(const FrameBlock& f) {
    std::vector<float> key;
    for (int i = 0; i < int(f.ground_params.w); ++i) detail::append_components(key, f.ground_light[i], 3);
    detail::append_components(key, f.vol_min, 3);
    detail::append_components(key, f.vol_size, 4);
    detail::append_components(key, f.rain, 3);
    key.push_back(f.ground_params.x);
    return key;
}

}  // namespace

bool Renderer::Impl::ground_lights_moving(const FrameUniforms& u) {
    // The share is not compared: it changes once when it does (a preset's or a strike's solve),
    // not frame after frame as a leader's lights move, so a new share alone makes the map again
    // at once (ground_rain_pass).
    std::vector<float> key = map_key(u.block);
    const bool moving = !detail::same_light_key(key, ground_rain_key) && !detail::same_light_key(key, ground_rain_last);
    ground_rain_last = std::move(key);
    return moving;
}

void Renderer::Impl::ground_rain_pass(const FrameUniforms& u) {
    if (!u.ground_rain_map) return;
    const FrameBlock& f = u.block;
    const int lights = int(f.ground_params.w);
    std::vector<float> key = map_key(f);
    if (!ground_rain_tex) {
        glCreateTextures(GL_TEXTURE_2D_ARRAY, 1, &ground_rain_tex);
        glTextureStorage3D(ground_rain_tex, 1, GL_R32F, kAzimuths, kRadii, detail::kMaxGroundLights);
        glTextureParameteri(ground_rain_tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        glTextureParameteri(ground_rain_tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTextureParameteri(ground_rain_tex, GL_TEXTURE_WRAP_S, GL_REPEAT);  // the azimuth goes round
        glTextureParameteri(ground_rain_tex, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
        ground_rain_key.clear();
    }
    const float share = f.rain_lights.z;
    if (!detail::same_light_key(key, ground_rain_key) || !detail::same_light_key({share}, {ground_rain_share})) {
        const GLuint p = program("ground_rain", {{GL_COMPUTE_SHADER, "ground_rain.comp"}});
        glUseProgram(p);
        glUniform1i(glGetUniformLocation(p, "u_max_samples"), kMaxGroundSamples);
        glUniform1f(glGetUniformLocation(p, "u_voxels_per_sample"), float(kVoxelsPerSample));
        glBindTextureUnit(0, density_tex);
        glBindImageTexture(0, ground_rain_tex, 0, GL_TRUE, 0, GL_WRITE_ONLY, GL_R32F);
        glDispatchCompute(GLuint(kAzimuths / 8), GLuint(kRadii / 8), GLuint(lights));
        glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
        ground_rain_key = std::move(key);
        ground_rain_share = share;
    }
    glBindTextureUnit(12, ground_rain_tex);
}

}  // namespace fulgur::render
