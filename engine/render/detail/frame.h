// Internal to fulgur::render: what the passes of one frame share — the std140 frame block
// and the host-side decisions taken with it, the caller's target restored at the end, and
// the per-pass timer.
#pragma once

#include "core/core.h"
#include "render/render.h"

#include <glad/gl.h>

#include <glm/glm.hpp>

#include <time.h>

#include <algorithm>
#include <cmath>

#include <vector>

namespace fulgur::render::detail {

/// The ground's point lights the frame block holds (ground_light[] in shaders/common.glsl).
inline constexpr int kMaxGroundLights = 8;

/// Mirror of the std140 block `Frame` in shaders/common.glsl (vec4/mat4 members only, so
/// the C++ layout equals std140).
struct FrameBlock {
    glm::mat4 view_proj{1.0f};
    glm::vec4 cam_pos{0.0f}, cam_fwd{0.0f}, cam_right{0.0f}, cam_up{0.0f};
    glm::vec4 vol_min{0.0f}, vol_size{0.0f}, lit_min{0.0f}, lit_size{1.0f};
    glm::vec4 march_params{0.0f}, sizes{0.0f}, ground_params{0.0f};
    glm::vec4 ground_light[kMaxGroundLights]{};
    glm::vec4 sky_params{0.0f}, glow_params{0.0f}, light_colour{0.0f};
    glm::ivec4 counts{0};
    glm::vec4 sky_zenith{0.0f}, sky_horizon{0.0f};
    glm::vec4 static_min{0.0f}, static_size{1.0f};
    glm::vec4 sun_dir{0.0f}, sun_rgb{0.0f}, sun_params{0.0f};
    glm::vec4 host_depth{0.0f};
    glm::vec4 detail{0.0f};
    glm::vec4 rain{0.0f};
    glm::vec4 rain_light[8]{};
    glm::vec4 rain_lights{0.0f};
    glm::vec4 ground_scatter{0.0f};
    glm::vec4 ground_static{0.0f};
};
static_assert(sizeof(FrameBlock) == 64 + 11 * 16 + 8 * 16 + 4 * 16 + 10 * 16 + 8 * 16 + 3 * 16,
              "FrameBlock must match std140");

/// Appends the first `n` components of `v` to `out` (keys made of frame-block fields).
inline void append_components(std::vector<float>& out, const glm::vec4& v, int n = 4) {
    for (int i = 0; i < n; ++i) out.push_back(v[i]);
}

/// Two keys of the same map made from the channel's lights: each component within 1e-5 of the
/// other, relative, with a floor at 1 (a channel's lights are the power centroids of its
/// stretches, which a flash dimming moves by float rounding, ~1e-7: 0.1 m at 10 km, far below
/// the maps' texels), the same length.
inline bool same_light_key(const std::vector<float>& a, const std::vector<float>& b) {
    if (a.size() != b.size()) return false;
    for (std::size_t i = 0; i < a.size(); ++i) {
        const float scale = std::max(std::max(std::abs(a[i]), std::abs(b[i])), 1.0f);
        if (!(std::abs(a[i] - b[i]) <= 1e-5f * scale)) return false;
    }
    return true;
}

/// The passes of a frame in the order render() runs them (the timer's slots).
enum Pass { kResolve, kGlow, kMarch, kMeter, kBolt, kGlare, kComposite, kPassCount };

/// Process CPU time (all threads, including a software rasterizer's), milliseconds.
inline double process_cpu_ms() noexcept {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return double(t.tv_sec) * 1e3 + double(t.tv_nsec) * 1e-6;
}

/// Everything the passes of one frame share, computed once before the first pass (as
/// Filament's PerViewUniforms): the std140 block the shaders read and the host-side
/// decisions taken from the same inputs.
struct FrameUniforms {
    FrameBlock block;
    int width = 0, height = 0;                    ///< output size (pixels)
    int internal_width = 0, internal_height = 0;  ///< ray-march resolution (pixels)
    bool lit = false;                             ///< the march samples S (source, cloud lighting, volume)
    bool statics = false;                         ///< the march samples the static light (sun, moon, sky)
    bool sun = false;                             ///< the march draws the sun's full-resolution single scattering
    bool detail = false;                          ///< the march erodes the density by the sub-voxel detail
    bool rain = false;                            ///< the march draws the rain (and the ground its shadow)
    int rain_lights = 0;                          ///< the rain's flash lights the march reads (rain_lights.x)
    bool rain_source = false;                     ///< the rain scatters the flash's light of orders >= 2 (u_scam's g)
    bool glow = false;                            ///< the glow pass runs
    bool host = false;                            ///< composited into a host's frame (render_into_host)
    bool stars = false;                           ///< the composite draws stars (sky on, star radiance > 0)
    bool ground_scatter = false;                  ///< the settings ask for the ground's scattered flash light
    bool ground_rain_map = false;                 ///< the ground reads its lights' rain transmittance from its map
};

/// The caller's draw and read framebuffers and viewport, restored when a frame or a read-back is
/// done (the passes bind GL_FRAMEBUFFER, which sets both: a host that reads or blits from its
/// target after render_into_host must find it still bound for reading).
struct CallerTarget {
    GLint fbo = 0, read_fbo = 0, viewport[4] = {};
    static CallerTarget save() {
        CallerTarget c;
        glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &c.fbo);
        glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &c.read_fbo);
        glGetIntegerv(GL_VIEWPORT, c.viewport);
        return c;
    }
    /// Unbinds the renderer's program and vertex array and rebinds the caller's framebuffers.
    void restore() const {
        glUseProgram(0);
        glBindVertexArray(0);
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(fbo));
        glBindFramebuffer(GL_READ_FRAMEBUFFER, GLuint(read_fbo));
        glViewport(viewport[0], viewport[1], viewport[2], viewport[3]);
    }
};

/// Per-pass times of one frame (Settings::timing): with Timing::Finish each pass is fenced by
/// glFinish and timed on the steady clock and in process CPU time; with Timing::Queries by GL
/// timer queries (read in finish()); Timing::Off times nothing.
class PassTimer {
public:
    PassTimer(Timing mode, const GLuint* queries) : mode_(mode), queries_(queries) {}
    void begin(Pass p) {
        ran_[p] = true;
        if (mode_ == Timing::Finish) {
            glFinish();
            clock_.reset();
            cpu0_ = process_cpu_ms();
        } else if (mode_ == Timing::Queries) {
            glBeginQuery(GL_TIME_ELAPSED, queries_[p]);
        }
    }
    void end(Pass p) {
        if (mode_ == Timing::Finish) {
            glFinish();
            wall_[p] += clock_.milliseconds();  // a pass may run twice (the two resolves)
            cpu_[p] += process_cpu_ms() - cpu0_;
        } else if (mode_ == Timing::Queries) {
            glEndQuery(GL_TIME_ELAPSED);
        }
    }
    /// Reads the timer queries of the passes that ran (waiting for them) and, unless timing
    /// is off, waits for the frame to finish.
    void finish() {
        if (mode_ == Timing::Queries) {
            for (int p = 0; p < kPassCount; ++p)
                if (ran_[p]) {
                    GLuint64 ns = 0;
                    glGetQueryObjectui64v(queries_[p], GL_QUERY_RESULT, &ns);
                    wall_[p] = double(ns) * 1e-6;
                }
        }
        if (mode_ != Timing::Off) glFinish();
    }
    /// The frame's times: the uploads since the previous frame, each pass, the whole call.
    PassTimes wall_times(double upload, double total) const noexcept { return times(wall_, upload, total); }
    PassTimes cpu_times(double upload, double total) const noexcept { return times(cpu_, upload, total); }

private:
    static PassTimes times(const double* pass, double upload, double total) noexcept {
        return {upload,      pass[kResolve], pass[kGlow],      pass[kMarch], pass[kMeter],
                pass[kBolt], pass[kGlare],   pass[kComposite], total};
    }
    Timing mode_;
    const GLuint* queries_;
    double wall_[kPassCount] = {}, cpu_[kPassCount] = {};
    bool ran_[kPassCount] = {};
    core::Stopwatch clock_;
    double cpu0_ = 0.0;
};

}  // namespace fulgur::render::detail
