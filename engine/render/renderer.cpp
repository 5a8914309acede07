#include "render/render.h"

#include "render/detail/directions.h"
#include "render/detail/exposure.h"
#include "render/detail/gl_program.h"
#include "render/detail/volume_prep.h"
#include "transport/transport.h"

#include <glad/gl.h>

#include <glm/geometric.hpp>
#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <limits>
#include <map>
#include <numbers>
#include <optional>

#include <time.h>

namespace fulgur::render {

std::filesystem::path default_shader_dir() {
    if (const char* env = std::getenv("FULGUR_SHADER_DIR"); env && *env) return env;
    // The source tree's shaders while it exists (the build tree's tools and tests), else
    // where `cmake --install` put them (an installed engine used from another project).
    std::error_code ec;
    if (std::filesystem::is_directory(FULGUR_SHADER_DIR, ec)) return FULGUR_SHADER_DIR;
    return FULGUR_INSTALLED_SHADER_DIR;
}

namespace {

/// Mirror of the std140 block `Frame` in shaders/common.glsl (vec4/mat4 members only, so
/// the C++ layout equals std140).
struct FrameBlock {
    glm::mat4 view_proj{1.0f};
    glm::vec4 cam_pos{0.0f}, cam_fwd{0.0f}, cam_right{0.0f}, cam_up{0.0f};
    glm::vec4 vol_min{0.0f}, vol_size{0.0f}, lit_min{0.0f}, lit_size{1.0f};
    glm::vec4 march_params{0.0f}, sizes{0.0f}, ground_params{0.0f};
    glm::vec4 ground_light[8]{};
    glm::vec4 sky_params{0.0f}, glow_params{0.0f}, light_colour{0.0f};
    glm::ivec4 counts{0};
    glm::vec4 sky_zenith{0.0f}, sky_horizon{0.0f};
    glm::vec4 static_min{0.0f}, static_size{1.0f};
    glm::vec4 sun_dir{0.0f}, sun_rgb{0.0f}, sun_params{0.0f};
};
static_assert(sizeof(FrameBlock) == 64 + 11 * 16 + 8 * 16 + 4 * 16 + 7 * 16, "FrameBlock must match std140");

constexpr int kMaxGroundLights = 8;
constexpr int kGlowProfileSize = 256;

enum Pass { kResolve, kGlow, kMarch, kMeter, kBolt, kComposite, kPassCount };

// Exposure metering: log2 bins of the march's luminance, from 2^-40 to 2^24 (night sky to a
// lightning channel seen through a thin cloud), a quarter stop each.
constexpr int kMeterBins = 256;
constexpr float kMeterLog2Min = -40.0f, kMeterBinWidth = 0.25f;

/// Process CPU time (all threads, including a software rasterizer's), milliseconds.
double process_cpu_ms() noexcept {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return double(t.tv_sec) * 1e3 + double(t.tv_nsec) * 1e-6;
}

/// Rejects out-of-range settings with an error naming the field.
void validate_settings(const Settings& st) {
    auto range = [](double v, double lo, double hi, bool lo_open, const char* field) {
        const bool ok = std::isfinite(v) && (lo_open ? v > lo : v >= lo) && v <= hi;
        if (!ok)
            throw core::Error(std::string("render: settings.") + field,
                              "must be in " + std::string(lo_open ? "(" : "[") + std::to_string(lo) + ", " +
                                  std::to_string(hi) + "], got " + std::to_string(v));
    };
    const double inf = std::numeric_limits<double>::max();
    range(st.exposure, 0.0, inf, false, "exposure");
    range(st.exposure_compensation, -20.0, 20.0, false, "exposure_compensation");
    range(st.previous_exposure, 0.0, inf, false, "previous_exposure");
    range(st.adaptation_seconds, 0.0, 1e6, false, "adaptation_seconds");
    range(st.brighten_seconds, 0.0, 1e6, false, "brighten_seconds");
    range(st.darken_seconds, 0.0, 1e6, false, "darken_seconds");
    range(st.highlight_fraction, 0.0, 0.5, true, "highlight_fraction");
    range(st.internal_scale, 0.0, 1.0, true, "internal_scale");
    range(st.step_voxels, 0.01, 64.0, false, "step_voxels");
    range(st.min_transmittance, 0.0, 0.5, false, "min_transmittance");
    range(st.ground_albedo, 0.0, 1.0, false, "ground_albedo");
    range(double(st.ground_lights), 0.0, 8.0, false, "ground_lights");
    for (int c = 0; c < 3; ++c) {
        range(st.sky_zenith[c], 0.0, inf, false, "sky_zenith");
        range(st.sky_horizon[c], 0.0, inf, false, "sky_horizon");
    }
    range(st.star_radiance, 0.0, inf, false, "star_radiance");
    range(st.air_scattering, 0.0, 1.0, false, "air_scattering");
    range(st.glow_radius, 0.0, 1e6, true, "glow_radius");
    range(st.bolt_min_width_px, 0.0, 64.0, true, "bolt_min_width_px");
    range(st.ground_height, -1e6, 1e6, false, "ground_height");
    for (int c = 0; c < 3; ++c) range(st.flash_colour[c], 0.0, inf, false, "flash_colour");
    range(st.direction_min_weight, 0.0, 0.5, false, "direction_min_weight");
}

void check_finite(double v, const std::string& where, const std::string& what) {
    if (!std::isfinite(v)) throw core::Error(where, what + " must be finite");
}

GLuint make_texture_3d(GLenum format, const core::Int3& dims) {
    GLuint t = 0;
    glCreateTextures(GL_TEXTURE_3D, 1, &t);
    glTextureStorage3D(t, 1, format, dims.x, dims.y, dims.z);
    glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(t, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(t, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glTextureParameteri(t, GL_TEXTURE_WRAP_R, GL_CLAMP_TO_EDGE);
    return t;
}

void delete_texture(GLuint& t) {
    if (t) glDeleteTextures(1, &t);
    t = 0;
}

struct Target {  // a colour texture + framebuffer
    GLuint tex = 0, fbo = 0;
    int w = 0, h = 0;
    void ensure(int width, int height) {
        if (tex && w == width && h == height) return;
        release();
        w = width;
        h = height;
        glCreateTextures(GL_TEXTURE_2D, 1, &tex);
        glTextureStorage2D(tex, 1, GL_RGBA32F, w, h);
        glTextureParameteri(tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        glTextureParameteri(tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTextureParameteri(tex, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
        glTextureParameteri(tex, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
        glCreateFramebuffers(1, &fbo);
        glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT0, tex, 0);
        if (glCheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
            throw core::Error(
                "render", "RGBA32F framebuffer of " + std::to_string(w) + "x" + std::to_string(h) + " is not complete");
    }
    void release() {
        if (fbo) glDeleteFramebuffers(1, &fbo);
        delete_texture(tex);
        fbo = 0;
        w = h = 0;
    }
};

struct Buffer {
    GLuint id = 0;
    std::size_t capacity = 0;
    void upload(const void* data, std::size_t bytes) {
        if (bytes == 0) bytes = 16;  // never bind an empty buffer
        if (!id || capacity < bytes) {
            if (id) glDeleteBuffers(1, &id);
            glCreateBuffers(1, &id);
            capacity = std::max<std::size_t>(bytes, 1024);
            glNamedBufferData(id, GLsizeiptr(capacity), nullptr, GL_DYNAMIC_DRAW);
        }
        if (data) glNamedBufferSubData(id, 0, GLsizeiptr(bytes), data);
    }
    void release() {
        if (id) glDeleteBuffers(1, &id);
        id = 0;
        capacity = 0;
    }
};

/// The source function on a lighting grid, one 3D texture per baked direction, and its
/// resolve toward the camera: the flash's S (R32F) and the static light's (sun, moon, sky;
/// RGBA32F, colour). Only the directions listed by the latest upload are present.
struct SourceSet {
    explicit SourceSet(GLenum f) : format(f) {}
    GLenum format = GL_R32F;
    core::GridGeometry geom;
    int dir_count = 0;
    std::vector<GLuint> tex;  ///< per baked direction
    std::vector<bool> present;
    GLuint cam_tex = 0;  ///< S toward the camera (more than one direction)
    bool has = false;    ///< some direction is present
    bool dirty = true;   ///< S changed since the last resolve
    glm::dvec3 resolved_camera{std::nan("")};

    /// Textures for this grid and direction count (new ones, empty, when either changed).
    /// Returns true when it (re)allocated.
    bool ensure(const core::GridGeometry& g, int count) {
        if (geom == g && dir_count == count && !tex.empty()) return false;
        release();
        tex.assign(std::size_t(count), 0);
        for (GLuint& t : tex) t = make_texture_3d(format, g.dims);
        if (count > 1) cam_tex = make_texture_3d(format, g.dims);
        geom = g;
        dir_count = count;
        return true;
    }
    void release() {
        for (GLuint& t : tex) delete_texture(t);
        tex.clear();
        delete_texture(cam_tex);
        present.clear();
        has = false;
        dirty = true;
        dir_count = 0;
    }
};

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
    bool glow = false;                            ///< the glow pass runs
};

/// The caller's draw framebuffer and viewport, restored when a frame or a read-back is done.
struct CallerTarget {
    GLint fbo = 0, viewport[4] = {};
    static CallerTarget save() {
        CallerTarget c;
        glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &c.fbo);
        glGetIntegerv(GL_VIEWPORT, c.viewport);
        return c;
    }
    /// Unbinds the renderer's program and vertex array and rebinds the caller's target.
    void restore() const {
        glUseProgram(0);
        glBindVertexArray(0);
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(fbo));
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
        return {upload, pass[kResolve], pass[kGlow], pass[kMarch], pass[kMeter], pass[kBolt], pass[kComposite], total};
    }
    Timing mode_;
    const GLuint* queries_;
    double wall_[kPassCount] = {}, cpu_[kPassCount] = {};
    bool ran_[kPassCount] = {};
    core::Stopwatch clock_;
    double cpu0_ = 0.0;
};

/// Rejects an empty output, out-of-range settings or a degenerate camera with an error
/// naming the field.
void validate_frame(const Camera& camera, const Settings& st, int width, int height) {
    if (width <= 0 || height <= 0)
        throw core::Error("render",
                          "output size must be positive, got " + std::to_string(width) + "x" + std::to_string(height));
    validate_settings(st);
    const glm::dvec3 fwd_raw = camera.target - camera.position;
    if (!(glm::length(fwd_raw) > 0.0) || !(camera.vertical_fov_deg > 0.0 && camera.vertical_fov_deg < 179.0) ||
        !(glm::length(glm::cross(fwd_raw, camera.up)) > 0.0))
        throw core::Error("render: camera", "needs target != position, up not parallel to the view and 0 < fov < 179");
}

}  // namespace

struct Renderer::Impl {
    std::filesystem::path shader_dir;
    std::map<std::string, GLuint> programs;
    GLuint vao = 0, frame_ubo = 0, zero_tex = 0, profile_tex = 0;
    GLuint queries[kPassCount] = {};

    // Volume
    bool has_volume = false;
    GLuint density_tex = 0;
    core::Grid3<float> density;          // CPU copy (clamped), for ground-light visibility
    std::vector<std::uint8_t> distance;  // Chebyshev distance field (voxels)
    double kappa = 0.0;

    // Source: the flash's S and the static light's (colour)
    SourceSet flash = SourceSet(GL_R32F), statics = SourceSet(GL_RGBA32F);
    // The sun drawn at full resolution (set_sun)
    GLuint sun_tex = 0;  // transmittance to the sun on the density grid (R16F)
    bool has_sun = false, sun_fine = false, sun_scatter = false;
    glm::dvec3 sun_direction{0.0, 0.0, -1.0}, sun_rgb{0.0};
    double sun_albedo = 0.0, sun_g = 0.0;
    // Exposure metering
    Buffer meter_buf;
    double pending_upload_ms = 0.0, pending_upload_cpu_ms = 0.0;
    // Cache of the needed directions for (camera, lighting grid, count).
    mutable std::optional<glm::dvec3> needed_camera;
    mutable core::GridGeometry needed_geom;
    mutable int needed_count = 0;
    mutable double needed_min_weight = -1.0;
    mutable std::vector<DirectionUse> needed;
    mutable std::vector<std::uint8_t> lit_active;  // lighting nodes near non-empty density
    mutable core::GridGeometry lit_active_geom;
    mutable bool lit_active_valid = false;

    // Bolt
    Bolt bolt;
    Buffer seg_buf, endpoint_buf, glow_buf;
    int seg_count = 0, glow_count = 0;
    double glow_built_radius = -1.0;
    double profile_radius = -1.0, profile_sigma = -1.0;
    std::vector<glm::vec4> ground_lights;
    int ground_lights_k = -1;  // -1: to rebuild
    double ground_lights_height = 0.0;

    GLuint last_scam = 0;    // S_cam texture the last frame sampled (0: none)
    GLuint last_static = 0;  // the static light's S_cam the last frame sampled (0: none)

    // Targets
    Target glow_target, march_target, core_target, hdr_target;
    int out_w = 0, out_h = 0;

    // ----------------------------------------------------------------------------------
    GLuint program(const std::string& key, const std::vector<detail::Stage>& stages, const std::string& defines = {}) {
        const std::string full = key + "|" + defines;
        if (auto it = programs.find(full); it != programs.end()) return it->second;
        const GLuint p = detail::build_program(shader_dir, stages, defines);
        programs[full] = p;
        return p;
    }

    static std::string march_defines(bool skip, bool early, bool source, bool emission, bool statics = false,
                                     bool sun = false) {
        std::string d = std::string("#define SKIP_EMPTY ") + (skip ? "1" : "0") + "\n#define EARLY_EXIT " +
                        (early ? "1" : "0") + "\n#define HAS_SOURCE " + (source ? "1" : "0") +
                        "\n#define HAS_EMISSION " + (emission ? "1" : "0") + "\n";
        if (statics) d += "#define HAS_STATIC 1\n";
        if (sun) d += "#define HAS_SUN 1\n";
        return d;
    }

    GLuint march_program(MarchKernel kernel, const std::string& defines) {
        if (kernel == MarchKernel::Fragment)
            return program("march.frag", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "march.frag"}},
                           defines);
        return program("march.comp", {{GL_COMPUTE_SHADER, "march.comp"}}, defines);
    }

    void build_default_programs() {
        program("resolve", {{GL_COMPUTE_SHADER, "resolve.comp"}});
        program("bolt_t", {{GL_COMPUTE_SHADER, "bolt_transmittance.comp"}});
        program("glow", {{GL_VERTEX_SHADER, "glow.vert"}, {GL_FRAGMENT_SHADER, "glow.frag"}});
        program("bolt", {{GL_VERTEX_SHADER, "bolt.vert"}, {GL_FRAGMENT_SHADER, "bolt.frag"}});
        program("composite", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "composite.frag"}});
        march_program(MarchKernel::Fragment, march_defines(true, true, true, true));
    }

    void release_programs() {
        for (auto& [k, p] : programs) glDeleteProgram(p);
        programs.clear();
    }

    // ----------------------------------------------------------------------------------
    const std::vector<std::uint8_t>& active_mask(const core::GridGeometry& lg) const {
        if (lit_active_valid && lit_active_geom == lg) return lit_active;
        lit_active.assign(lg.cell_count(), 1);
        if (has_volume) {
            const core::GridGeometry& dg = density.geom;
            // A lighting node is read by samples within one lighting voxel of it; those
            // samples see density within one more density voxel.
            const int reach = int(std::ceil(lg.voxel_size / dg.voxel_size)) + 1;
            for (std::size_t c = 0; c < lit_active.size(); ++c) {
                const core::Int3 n = lg.unindex(c);
                const glm::dvec3 v = dg.to_voxel(lg.centre(n.x, n.y, n.z));
                const int i = std::clamp(int(std::floor(v.x)), 0, dg.dims.x - 1);
                const int j = std::clamp(int(std::floor(v.y)), 0, dg.dims.y - 1);
                const int k = std::clamp(int(std::floor(v.z)), 0, dg.dims.z - 1);
                // Outside the density grid, the distance to the grid adds to the reach.
                const glm::dvec3 outside =
                    glm::max(glm::dvec3(0.0), glm::max(-v, v - glm::dvec3(dg.dims.x, dg.dims.y, dg.dims.z)));
                const double extra = std::max({outside.x, outside.y, outside.z});
                lit_active[c] = double(distance[dg.index(i, j, k)]) <= reach + 1.0 - extra ? 1 : 0;
            }
        }
        lit_active_geom = lg;
        lit_active_valid = true;
        return lit_active;
    }

    const std::vector<DirectionUse>& needed_for(const glm::dvec3& cam, const core::GridGeometry& lg, int count,
                                                double min_weight) const {
        if (needed_camera && *needed_camera == cam && needed_geom == lg && needed_count == count &&
            needed_min_weight == min_weight)
            return needed;
        needed = view_directions(cam, lg, count, active_mask(lg), min_weight);
        needed_min_weight = min_weight;
        needed_camera = cam;
        needed_geom = lg;
        needed_count = count;
        return needed;
    }

    // ----------------------------------------------------------------------------------
    void rebuild_glow_quads(double radius) {
        std::vector<glm::vec4> quads;
        const double spacing = std::max(radius / 4.0, 10.0);  // Riemann sum of the line integral
        for (const Segment& s : bolt.segments) {
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
    void rebuild_profile(double radius, double sigma) {
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

    /// Transmittance straight down from p to the ground through the density.
    double vertical_transmittance(const glm::dvec3& p, double ground) const {
        if (!has_volume || p.z <= ground) return 1.0;
        const double h = 0.5 * density.geom.voxel_size;
        const double lo = std::max(ground, density.geom.origin.z), hi = std::min(p.z, density.geom.upper().z);
        if (hi <= lo) return 1.0;
        const int n = int(std::ceil((hi - lo) / h));
        double tau = 0.0;
        for (int i = 0; i < n; ++i) tau += double(density.sample({p.x, p.y, lo + (hi - lo) * (i + 0.5) / n}));
        return std::exp(-kappa * tau * (hi - lo) / n);
    }

    /// Representative point lights for the ground: the bolt split into k runs of equal
    /// power (sum of intensity x length, in segment order); each light sits at its run's
    /// power-weighted centroid with the run's intensity, times its visibility.
    void rebuild_ground_lights(int k, double ground) {
        ground_lights.clear();
        ground_lights_k = k;
        ground_lights_height = ground;
        double total = 0.0;
        for (const Segment& s : bolt.segments) total += double(s.intensity) * glm::length(glm::dvec3(s.b - s.a));
        if (total <= 0.0 || k <= 0) return;
        const double per = total / k;
        double acc = 0.0, wsum = 0.0;
        glm::dvec3 centroid(0.0);
        for (const Segment& s : bolt.segments) {
            const double p = double(s.intensity) * glm::length(glm::dvec3(s.b - s.a));
            if (p <= 0.0) continue;
            centroid += p * 0.5 * (glm::dvec3(s.a) + glm::dvec3(s.b));
            wsum += p;
            acc += p;
            if (acc >= per * double(ground_lights.size() + 1) - 1e-9 * total || &s == &bolt.segments.back()) {
                glm::dvec3 c = centroid / wsum;
                c.z = std::max(c.z, ground + 1.0);
                ground_lights.emplace_back(glm::vec3(c), float(wsum * vertical_transmittance(c, ground)));
                centroid = glm::dvec3(0.0);
                wsum = 0.0;
                if (int(ground_lights.size()) == k) break;
            }
        }
        if (wsum > 0.0 && int(ground_lights.size()) < k) {
            glm::dvec3 c = centroid / wsum;
            c.z = std::max(c.z, ground + 1.0);
            ground_lights.emplace_back(glm::vec3(c), float(wsum * vertical_transmittance(c, ground)));
        }
    }

    // ---- one frame: uniforms, then the passes in order (defined below)
    FrameUniforms prepare_frame(const Camera& camera, const Settings& st, int width, int height);
    void bind_frame(const FrameUniforms& u);
    GLuint resolve_set(SourceSet& set, const glm::dvec3& camera, const std::vector<int>& active, bool must_resolve,
                       PassTimer& timer);
    void resolve_pass(const glm::dvec3& camera, const Settings& st, const FrameUniforms& u, PassTimer& timer,
                      FrameStats& stats);
    void meter_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer, FrameStats& stats);
    void glow_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer, FrameStats& stats);
    void march_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer);
    void bolt_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer, FrameStats& stats);
    void composite_pass(const FrameUniforms& u, const CallerTarget& caller, PassTimer& timer);
};

// ---------------------------------------------------------------------------------------

Renderer::Renderer(GetProcAddress get_proc_address, std::filesystem::path shader_dir)
    : impl_(std::make_unique<Impl>()) {
    FULGUR_ASSERT(get_proc_address != nullptr, "Renderer needs a get-proc-address");
    const int version = gladLoadGL(reinterpret_cast<GLADloadfunc>(get_proc_address));
    if (!version) throw core::Error("render", "cannot load OpenGL functions (is a context current?)");
    if (GLAD_VERSION_MAJOR(version) < 4 || (GLAD_VERSION_MAJOR(version) == 4 && GLAD_VERSION_MINOR(version) < 5))
        throw core::Error("render", "OpenGL 4.5 core is required, the context provides " +
                                        std::to_string(GLAD_VERSION_MAJOR(version)) + "." +
                                        std::to_string(GLAD_VERSION_MINOR(version)));
    Impl& m = *impl_;
    m.shader_dir = std::move(shader_dir);
    if (!std::filesystem::is_directory(m.shader_dir))
        throw core::Error(m.shader_dir.string(), "shader directory does not exist");
    glCreateVertexArrays(1, &m.vao);
    glCreateBuffers(1, &m.frame_ubo);
    glNamedBufferData(m.frame_ubo, sizeof(FrameBlock), nullptr, GL_DYNAMIC_DRAW);
    glCreateQueries(GL_TIME_ELAPSED, kPassCount, m.queries);
    const float zero = 0.0f;
    m.zero_tex = make_texture_3d(GL_R32F, {1, 1, 1});
    glTextureSubImage3D(m.zero_tex, 0, 0, 0, 0, 1, 1, 1, GL_RED, GL_FLOAT, &zero);
    try {
        m.build_default_programs();
    } catch (...) {
        m.release_programs();
        glDeleteVertexArrays(1, &m.vao);
        glDeleteBuffers(1, &m.frame_ubo);
        glDeleteQueries(kPassCount, m.queries);
        delete_texture(m.zero_tex);
        throw;
    }
}

Renderer::~Renderer() {
    Impl& m = *impl_;
    m.release_programs();
    glDeleteVertexArrays(1, &m.vao);
    glDeleteBuffers(1, &m.frame_ubo);
    glDeleteQueries(kPassCount, m.queries);
    delete_texture(m.zero_tex);
    delete_texture(m.profile_tex);
    delete_texture(m.density_tex);
    m.flash.release();
    m.statics.release();
    delete_texture(m.sun_tex);
    m.meter_buf.release();
    m.seg_buf.release();
    m.endpoint_buf.release();
    m.glow_buf.release();
    m.glow_target.release();
    m.march_target.release();
    m.core_target.release();
    m.hdr_target.release();
}

void Renderer::reload_shaders() {
    Impl& m = *impl_;
    std::map<std::string, GLuint> old;
    old.swap(m.programs);
    try {
        m.build_default_programs();
    } catch (...) {
        m.release_programs();
        m.programs.swap(old);
        throw;
    }
    for (auto& [k, p] : old) glDeleteProgram(p);
}

std::string Renderer::gl_description() const {
    return std::string(reinterpret_cast<const char*>(glGetString(GL_RENDERER))) + " | " +
           reinterpret_cast<const char*>(glGetString(GL_VERSION));
}

void Renderer::set_volume(const VolumeDesc& v) {
    Impl& m = *impl_;
    if (!v.density) throw core::Error("set_volume", "density is null");
    core::validate_geometry(v.density->geom, "set_volume: density grid");
    if (v.density->data.size() != v.density->geom.cell_count())
        throw core::Error("set_volume: density", "has " + std::to_string(v.density->data.size()) + " values for " +
                                                     std::to_string(v.density->geom.cell_count()) + " voxels");
    if (!std::isfinite(v.extinction) || v.extinction < 0.0)
        throw core::Error("set_volume: extinction", "must be finite and >= 0, got " + std::to_string(v.extinction));
    GLint max3d = 0;
    glGetIntegerv(GL_MAX_3D_TEXTURE_SIZE, &max3d);
    const core::Int3 d = v.density->geom.dims;
    if (d.x > max3d || d.y > max3d || d.z > max3d)
        throw core::Error("set_volume: density grid",
                          "dimensions exceed GL_MAX_3D_TEXTURE_SIZE " + std::to_string(max3d));
    const std::size_t n = v.density->data.size();
    core::Grid3<float> copy(v.density->geom);
    std::vector<std::uint8_t> occupied(n);
    for (std::size_t i = 0; i < n; ++i) {
        const float rho = v.density->data[i];
        if (!std::isfinite(rho)) {
            const core::Int3 c = v.density->geom.unindex(i);
            throw core::Error("set_volume: density", "voxel (" + std::to_string(c.x) + ", " + std::to_string(c.y) +
                                                         ", " + std::to_string(c.z) + ") is not finite");
        }
        copy.data[i] = std::clamp(rho, 0.0f, 1.0f);
        occupied[i] =
            v.precision == DensityPrecision::U8 ? detail::quantize_density(copy.data[i]) > 0 : copy.data[i] > 0.0f;
    }
    std::vector<std::uint8_t> dist = detail::chebyshev_distance(occupied, d);
    delete_texture(m.density_tex);
    if (v.precision == DensityPrecision::U8) {
        m.density_tex = make_texture_3d(GL_RG8, d);
        std::vector<std::uint8_t> packed(2 * n);
        for (std::size_t i = 0; i < n; ++i) {
            packed[2 * i] = detail::quantize_density(copy.data[i]);
            packed[2 * i + 1] = dist[i];
        }
        glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
        glTextureSubImage3D(m.density_tex, 0, 0, 0, 0, d.x, d.y, d.z, GL_RG, GL_UNSIGNED_BYTE, packed.data());
    } else {
        m.density_tex = make_texture_3d(GL_RG16F, d);
        std::vector<float> packed(2 * n);
        for (std::size_t i = 0; i < n; ++i) {
            packed[2 * i] = copy.data[i];
            packed[2 * i + 1] = float(dist[i]) / 255.0f;
        }
        glTextureSubImage3D(m.density_tex, 0, 0, 0, 0, d.x, d.y, d.z, GL_RG, GL_FLOAT, packed.data());
    }
    if (m.sun_tex && !(m.density.geom == v.density->geom)) {
        delete_texture(m.sun_tex);  // on the old grid
        m.sun_fine = false;
    }
    m.density = std::move(copy);
    m.distance = std::move(dist);
    m.kappa = v.extinction;
    m.has_volume = true;
    m.lit_active_valid = false;
    m.needed_camera.reset();
    m.ground_lights_k = -1;  // visibility depends on the volume
}

void Renderer::clear_volume() {
    Impl& m = *impl_;
    delete_texture(m.density_tex);
    delete_texture(m.sun_tex);
    m.sun_fine = false;
    m.density = {};
    m.distance.clear();
    m.has_volume = false;
    m.lit_active_valid = false;
    m.needed_camera.reset();
    m.ground_lights_k = -1;
}

namespace {

/// Validates an upload of `channels` floats per cell and writes it into `set` (see
/// SourceUpload: the listed directions replace the set, or are added with keep_others).
void upload_into(SourceSet& set, const char* what, const core::GridGeometry& geometry, int direction_count,
                 const std::vector<int>& directions, const std::vector<std::span<const float>>& values, int channels,
                 bool keep_others) {
    const std::string name(what);
    core::validate_geometry(geometry, name + ": lighting grid");
    (void)transport::output_directions(direction_count);  // throws for a bad count
    if (directions.size() != values.size())
        throw core::Error(name, std::to_string(directions.size()) + " directions but " + std::to_string(values.size()) +
                                    " value arrays");
    const std::size_t cells = geometry.cell_count(), n = cells * std::size_t(channels);
    std::vector<bool> listed(std::size_t(direction_count), false);
    for (std::size_t k = 0; k < directions.size(); ++k) {
        const int dir = directions[k];
        const std::string where = name + ": direction " + std::to_string(dir);
        if (dir < 0 || dir >= direction_count)
            throw core::Error(where, "index out of range [0, " + std::to_string(direction_count) + ")");
        if (listed[std::size_t(dir)]) throw core::Error(where, "listed twice");
        listed[std::size_t(dir)] = true;
        if (values[k].size() != n)
            throw core::Error(where, "has " + std::to_string(values[k].size()) + " values, the lighting grid " +
                                         std::to_string(cells) + " cells" +
                                         (channels > 1 ? " x " + std::to_string(channels) : std::string()));
        for (std::size_t c = 0; c < n; ++c)
            if (!std::isfinite(values[k][c]))
                throw core::Error(where, "value of cell " + std::to_string(c / std::size_t(channels)) +
                                             (channels > 1 ? " channel " + std::to_string(c % std::size_t(channels))
                                                           : std::string()) +
                                             " is not finite");
    }
    const bool fresh = set.ensure(geometry, direction_count);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    for (std::size_t k = 0; k < directions.size(); ++k)
        glTextureSubImage3D(set.tex[std::size_t(directions[k])], 0, 0, 0, 0, geometry.dims.x, geometry.dims.y,
                            geometry.dims.z, channels == 1 ? GL_RED : GL_RGB, GL_FLOAT, values[k].data());
    if (keep_others && !fresh && set.present.size() == listed.size()) {
        for (std::size_t d = 0; d < listed.size(); ++d) set.present[d] = set.present[d] || listed[d];
    } else {
        set.present = listed;
    }
    set.has = std::find(set.present.begin(), set.present.end(), true) != set.present.end();
    set.dirty = true;
}

}  // namespace

void Renderer::upload_source(const SourceUpload& s) {
    Impl& m = *impl_;
    core::Stopwatch sw;
    const double cpu0 = process_cpu_ms();
    upload_into(m.flash, "upload_source", s.geometry, s.direction_count, s.directions, s.values, 1, s.keep_others);
    m.pending_upload_ms += sw.milliseconds();
    m.pending_upload_cpu_ms += process_cpu_ms() - cpu0;
}

void Renderer::clear_source() {
    impl_->flash.has = false;
    impl_->flash.dirty = true;
}

void Renderer::upload_static(const StaticUpload& s) {
    Impl& m = *impl_;
    core::Stopwatch sw;
    const double cpu0 = process_cpu_ms();
    std::vector<int> all(s.rgb.size());
    for (std::size_t k = 0; k < all.size(); ++k) all[k] = int(k);
    if (int(s.rgb.size()) != s.direction_count)
        throw core::Error("upload_static", "needs all " + std::to_string(s.direction_count) + " directions, got " +
                                               std::to_string(s.rgb.size()));
    upload_into(m.statics, "upload_static", s.geometry, s.direction_count, all, s.rgb, 3, false);
    m.pending_upload_ms += sw.milliseconds();
    m.pending_upload_cpu_ms += process_cpu_ms() - cpu0;
}

void Renderer::clear_static() {
    impl_->statics.has = false;
    impl_->statics.dirty = true;
}

void Renderer::set_sun(const SunDesc& sun) {
    Impl& m = *impl_;
    const double len = glm::length(sun.direction);
    if (!std::isfinite(len) || !(len > 0.0))
        throw core::Error("set_sun: direction", "must be a finite non-zero vector");
    for (int c = 0; c < 3; ++c)
        if (!std::isfinite(sun.irradiance_rgb[c]) || sun.irradiance_rgb[c] < 0.0)
            throw core::Error("set_sun: irradiance_rgb", "must be finite and >= 0");
    if (!(sun.albedo >= 0.0 && sun.albedo <= 1.0)) throw core::Error("set_sun: albedo", "must be in [0, 1]");
    if (!(sun.g > -1.0 && sun.g < 1.0)) throw core::Error("set_sun: g", "must be in (-1, 1)");
    m.sun_direction = sun.direction / len;
    m.sun_rgb = sun.irradiance_rgb;
    m.sun_albedo = sun.albedo;
    m.sun_g = sun.g;
    m.has_sun = true;
    m.sun_fine = false;
    m.sun_scatter = sun.scatter;
    if (sun.transmittance) {
        const core::Grid3<float>& t = *sun.transmittance;
        if (!m.has_volume || !(t.geom == m.density.geom) || t.data.size() != t.geom.cell_count())
            throw core::Error("set_sun: transmittance", "must be on the density grid of set_volume()");
        for (std::size_t i = 0; i < t.data.size(); ++i)
            if (!(t.data[i] >= 0.0f && t.data[i] <= 1.0f))
                throw core::Error("set_sun: transmittance", "value " + std::to_string(i) + " is outside [0, 1]");
        if (!m.sun_tex) m.sun_tex = make_texture_3d(GL_R16F, t.geom.dims);
        glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
        glTextureSubImage3D(m.sun_tex, 0, 0, 0, 0, t.geom.dims.x, t.geom.dims.y, t.geom.dims.z, GL_RED, GL_FLOAT,
                            t.data.data());
        m.sun_fine = true;
    }
}

void Renderer::clear_sun() { impl_->has_sun = impl_->sun_fine = false; }

void Renderer::set_bolt(const Bolt& bolt) {
    Impl& m = *impl_;
    std::vector<glm::vec4> segs;
    segs.reserve(bolt.segments.size() * 2);
    for (std::size_t i = 0; i < bolt.segments.size(); ++i) {
        const Segment& s = bolt.segments[i];
        const std::string where = "set_bolt: segment " + std::to_string(i);
        for (int a = 0; a < 3; ++a) {
            check_finite(s.a[a], where, "endpoint a");
            check_finite(s.b[a], where, "endpoint b");
        }
        if (!std::isfinite(s.intensity) || s.intensity < 0.0f)
            throw core::Error(where, "intensity must be finite and >= 0, got " + std::to_string(s.intensity));
        if (!std::isfinite(s.radius) || s.radius <= 0.0f)
            throw core::Error(where, "radius must be finite and > 0, got " + std::to_string(s.radius));
        segs.emplace_back(s.a, s.intensity);
        segs.emplace_back(s.b, s.radius);
    }
    m.bolt = bolt;
    m.seg_count = int(bolt.segments.size());
    m.seg_buf.upload(segs.data(), segs.size() * sizeof(glm::vec4));
    m.endpoint_buf.upload(nullptr, std::max<std::size_t>(1, bolt.segments.size()) * 2 * sizeof(float));
    m.glow_built_radius = -1.0;
    m.ground_lights_k = -1;
}

std::vector<DirectionUse> Renderer::needed_directions(const Camera& camera, const core::GridGeometry& lighting,
                                                      int direction_count, double min_weight) const {
    core::validate_geometry(lighting, "needed_directions: lighting grid");
    if (!(min_weight >= 0.0 && min_weight < 1.0))
        throw core::Error("needed_directions: min_weight", "must be in [0, 1), got " + std::to_string(min_weight));
    return impl_->needed_for(camera.position, lighting, direction_count, min_weight);
}

// ---------------------------------------------------------------------------------------
// One frame

/// Targets at the frame's sizes, and the frame uniforms: camera, volume and march step,
/// lighting grid, ground lights, sky, glow and bolt switches. Rebuilds the ground lights
/// and glow quads when their settings changed.
FrameUniforms Renderer::Impl::prepare_frame(const Camera& camera, const Settings& st, int width, int height) {
    FrameUniforms u;
    u.width = width;
    u.height = height;
    u.internal_width = std::max(1, int(std::lround(width * st.internal_scale)));
    u.internal_height = std::max(1, int(std::lround(height * st.internal_scale)));
    const int iw = u.internal_width, ih = u.internal_height;
    out_w = width;
    out_h = height;
    glow_target.ensure(iw, ih);
    march_target.ensure(iw, ih);
    core_target.ensure(width, height);

    FrameBlock& f = u.block;
    // Camera
    const glm::dvec3 fwd = glm::normalize(camera.target - camera.position);
    const glm::dvec3 right = glm::normalize(glm::cross(fwd, camera.up));
    const glm::dvec3 up = glm::cross(right, fwd);
    const double tan_half = std::tan(glm::radians(camera.vertical_fov_deg) * 0.5);
    const double aspect = double(width) / double(height);
    const glm::dmat4 view = glm::lookAt(camera.position, camera.target, up);
    const glm::dmat4 proj = glm::perspective(glm::radians(camera.vertical_fov_deg), aspect, 0.5, 1e6);
    f.view_proj = glm::mat4(proj * view);
    f.cam_pos = glm::vec4(glm::vec3(camera.position), float(tan_half));
    f.cam_fwd = glm::vec4(glm::vec3(fwd), float(aspect));
    f.cam_right = glm::vec4(glm::vec3(right), 0.0f);
    f.cam_up = glm::vec4(glm::vec3(up), 0.0f);
    // Volume and march step
    double step = 1.0;
    int max_steps = 1;
    if (has_volume) {
        const core::GridGeometry& g = density.geom;
        step = st.step_voxels * g.voxel_size;
        max_steps = int(std::ceil(glm::length(g.extent()) / step)) + 2;
        f.vol_min = glm::vec4(glm::vec3(g.origin), float(kappa));
        f.vol_size = glm::vec4(glm::vec3(g.extent()), float(g.voxel_size));
    }
    // Lighting grid
    u.lit = flash.has && st.cloud_lighting && st.flash_light && has_volume;
    if (u.lit) {
        f.lit_min = glm::vec4(glm::vec3(flash.geom.origin), 1.0f);
        f.lit_size = glm::vec4(glm::vec3(flash.geom.extent()), 0.0f);
    }
    // The static light and the sun at full resolution (each switched off costs nothing: no
    // resolve, no texture fetch in the march)
    u.statics = statics.has && st.cloud_lighting && st.static_light && has_volume;
    if (u.statics) {
        f.static_min = glm::vec4(glm::vec3(statics.geom.origin), 1.0f);
        f.static_size = glm::vec4(glm::vec3(statics.geom.extent()), 0.0f);
    }
    const bool sun_on = has_sun && st.sun_light;
    u.sun = sun_on && sun_fine && sun_scatter && st.cloud_lighting && has_volume;
    if (sun_on) {
        f.sun_dir = glm::vec4(glm::vec3(sun_direction), 1.0f);
        f.sun_rgb = glm::vec4(glm::vec3(sun_rgb), float(sun_albedo));
        f.sun_params = glm::vec4(float(sun_g), sun_fine && has_volume ? 1.0f : 0.0f, 0.0f, 0.0f);
    }
    f.march_params = glm::vec4(float(step), float(st.min_transmittance), st.jitter ? 1.0f : 0.0f,
                               float(std::fmod(double(st.frame_index) * 0.6180339887498949, 1.0)));
    f.sizes = glm::vec4(float(width), float(height), float(iw), float(ih));
    // Ground
    if (st.ground) {
        if (ground_lights_k != st.ground_lights || ground_lights_height != st.ground_height)
            rebuild_ground_lights(st.ground_lights, st.ground_height);
        for (std::size_t i = 0; i < ground_lights.size() && i < kMaxGroundLights; ++i)
            f.ground_light[i] = ground_lights[i];
        f.ground_params = glm::vec4(float(st.ground_height), float(st.ground_albedo / std::numbers::pi), 1.0f,
                                    float(ground_lights.size()));
    } else {
        f.ground_params = glm::vec4(float(st.ground_height), 0.0f, 0.0f, 0.0f);
    }
    // Sky, glow, bolt, tone map
    f.sky_params = glm::vec4(0.0f, float(st.star_radiance), st.sky ? 1.0f : 0.0f, float(st.exposure));
    f.sky_zenith = glm::vec4(glm::vec3(st.sky_zenith), 0.0f);
    f.sky_horizon = glm::vec4(glm::vec3(st.sky_horizon), 0.0f);
    f.glow_params =
        glm::vec4(float(st.glow_radius), float(st.air_scattering), st.glow ? 1.0f : 0.0f, st.bolt ? 1.0f : 0.0f);
    f.light_colour = glm::vec4(glm::vec3(st.flash_colour), st.dither ? 1.0f : 0.0f);
    u.glow = st.glow && seg_count > 0 && st.air_scattering > 0.0;
    if (u.glow && glow_built_radius != st.glow_radius) rebuild_glow_quads(st.glow_radius);
    f.counts = glm::ivec4(max_steps, int(st.frame_index & 0x7fffffff), u.glow ? glow_count : 0, seg_count);
    return u;
}

/// Uploads the frame uniforms (binding 0) and sets the state every pass starts from.
void Renderer::Impl::bind_frame(const FrameUniforms& u) {
    glNamedBufferSubData(frame_ubo, 0, sizeof(FrameBlock), &u.block);
    glBindBufferBase(GL_UNIFORM_BUFFER, 0, frame_ubo);
    glBindVertexArray(vao);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    glDisable(GL_SCISSOR_TEST);
    glDisable(GL_BLEND);
}

/// Resolves a source set toward the camera (only when it or the camera changed): returns the
/// texture the march samples (the set's own texture with one direction).
GLuint Renderer::Impl::resolve_set(SourceSet& set, const glm::dvec3& camera, const std::vector<int>& active,
                                   bool must_resolve, PassTimer& timer) {
    if (set.dir_count == 1) return set.tex[0];
    if (!must_resolve) return set.cam_tex;
    const bool rgb = set.format != GL_R32F;
    const GLuint p = rgb ? program("resolve_rgb", {{GL_COMPUTE_SHADER, "resolve.comp"}}, "#define RGB 1\n")
                         : program("resolve", {{GL_COMPUTE_SHADER, "resolve.comp"}});
    glUseProgram(p);
    const detail::FoldTable ft = detail::fold_table(set.dir_count);
    GLint idx[27 * 3];
    GLfloat frac[27 * 3];
    for (int c = 0; c < 27; ++c)
        for (int k = 0; k < 3; ++k) {
            idx[c * 3 + k] = ft.index[std::size_t(c)][std::size_t(k)];
            frac[c * 3 + k] = GLfloat(ft.fraction[std::size_t(c)][std::size_t(k)]);
        }
    const core::GridGeometry& g = set.geom;
    glUniform3iv(glGetUniformLocation(p, "u_fold_index"), 27, idx);
    glUniform3fv(glGetUniformLocation(p, "u_fold_fraction"), 27, frac);
    glUniform3i(glGetUniformLocation(p, "u_dims"), g.dims.x, g.dims.y, g.dims.z);
    glBindImageTexture(0, set.cam_tex, 0, GL_TRUE, 0, GL_READ_WRITE, rgb ? GL_RGBA32F : GL_R32F);
    const GLint loc_dirs = glGetUniformLocation(p, "u_dirs"), loc_acc = glGetUniformLocation(p, "u_accumulate");
    const GLint loc_n = glGetUniformLocation(p, "u_samplers");
    GLfloat active_mask[26] = {};
    for (int d : active) active_mask[d] = 1.0f;
    glUniform1fv(glGetUniformLocation(p, "u_active"), 26, active_mask);
    // Up to 16 directions per dispatch (unused samplers read the zero texture with weight 0);
    // at least one dispatch so S_cam is written (zeros) even without S.
    constexpr std::size_t kBatch = 16;
    for (std::size_t b = 0; b == 0 || b < active.size(); b += kBatch) {
        GLint dirs[kBatch];
        std::fill(std::begin(dirs), std::end(dirs), -1);
        for (std::size_t k = 0; k < kBatch; ++k) {
            const bool used = b + k < active.size();
            if (used) dirs[k] = active[b + k];
            glBindTextureUnit(GLuint(k), used ? set.tex[std::size_t(active[b + k])] : zero_tex);
        }
        glUniform4iv(loc_dirs, 4, dirs);
        glUniform1i(loc_n, GLint(std::min(kBatch, std::max<std::size_t>(1, active.size() - b))));
        glUniform1i(loc_acc, b == 0 ? 0 : 1);
        if (b > 0) glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
        glDispatchCompute(GLuint((g.dims.x + 7) / 8), GLuint((g.dims.y + 7) / 8), GLuint(g.dims.z));
    }
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
    timer.end(kResolve);
    set.dirty = false;
    set.resolved_camera = camera;
    return set.cam_tex;
}

/// Resolve: S toward the camera on the lighting grid, for the flash and for the static light
/// (only when S or the camera changed; with one direction S itself). Binds the density (unit
/// 0), the flash's S toward the camera (unit 1), the static light's (unit 6) and the sun's
/// transmittance (unit 7).
void Renderer::Impl::resolve_pass(const glm::dvec3& camera, const Settings& st, const FrameUniforms& u,
                                  PassTimer& timer, FrameStats& stats) {
    GLuint scam = zero_tex, stat = zero_tex;
    if (u.lit) {
        const bool must_resolve = flash.dir_count > 1 && (flash.dirty || flash.resolved_camera != camera);
        if (must_resolve) timer.begin(kResolve);  // includes the CPU work of finding the needed directions
        const std::vector<DirectionUse>& need =
            needed_for(camera, flash.geom, flash.dir_count, st.direction_min_weight);
        stats.directions_used = int(need.size());
        std::vector<int> active;
        for (const DirectionUse& d : need) {
            if (flash.present[std::size_t(d.index)])
                active.push_back(d.index);
            else
                stats.missing_weight = std::max(stats.missing_weight, d.max_weight);
        }
        scam = resolve_set(flash, camera, active, must_resolve, timer);
    }
    if (u.statics) {
        // Every direction is present (upload_static); the view's needed ones are resolved.
        const bool must_resolve = statics.dir_count > 1 && (statics.dirty || statics.resolved_camera != camera);
        if (must_resolve) timer.begin(kResolve);
        std::vector<int> active;
        for (const DirectionUse& d : needed_for(camera, statics.geom, statics.dir_count, st.direction_min_weight))
            active.push_back(d.index);
        stat = resolve_set(statics, camera, active, must_resolve, timer);
    }
    glBindTextureUnit(0, has_volume ? density_tex : zero_tex);
    glBindTextureUnit(1, scam);
    glBindTextureUnit(6, stat);
    glBindTextureUnit(7, sun_fine ? sun_tex : zero_tex);
    last_scam = u.lit ? scam : 0;
    last_static = u.statics ? stat : 0;
}

/// Glow: additive quads along the strokes into the emission buffer at internal resolution
/// (bound to unit 2 for the march).
void Renderer::Impl::glow_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer, FrameStats& stats) {
    if (u.glow) {
        timer.begin(kGlow);
        if (profile_radius != st.glow_radius || profile_sigma != st.air_scattering)
            rebuild_profile(st.glow_radius, st.air_scattering);
        glBindFramebuffer(GL_FRAMEBUFFER, glow_target.fbo);
        glViewport(0, 0, u.internal_width, u.internal_height);
        const float clear[4] = {0, 0, 0, 0};
        glClearNamedFramebufferfv(glow_target.fbo, GL_COLOR, 0, clear);
        glEnable(GL_BLEND);
        glBlendEquation(GL_FUNC_ADD);
        glBlendFunc(GL_ONE, GL_ONE);
        glUseProgram(program("glow", {{GL_VERTEX_SHADER, "glow.vert"}, {GL_FRAGMENT_SHADER, "glow.frag"}}));
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, glow_buf.id);
        glBindTextureUnit(5, profile_tex);
        glDrawArrays(GL_TRIANGLES, 0, 6 * glow_count);
        glDisable(GL_BLEND);
        timer.end(kGlow);
        stats.glow_quads = glow_count;
    }
    glBindTextureUnit(2, glow_target.tex);
}

/// Ray march at internal resolution: in-scattered radiance + attenuated glow, and T.
void Renderer::Impl::march_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer) {
    timer.begin(kMarch);
    const std::string defines = march_defines(st.skip_empty, st.early_exit, u.lit, u.glow, u.statics, u.sun);
    const GLuint p = march_program(st.kernel, defines);
    glUseProgram(p);
    if (st.kernel == MarchKernel::Fragment) {
        glBindFramebuffer(GL_FRAMEBUFFER, march_target.fbo);
        glViewport(0, 0, u.internal_width, u.internal_height);
        glDrawArrays(GL_TRIANGLES, 0, 3);
    } else {
        glBindImageTexture(0, march_target.tex, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
        glDispatchCompute(GLuint((u.internal_width + 7) / 8), GLuint((u.internal_height + 7) / 8), 1);
        glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT);
    }
    timer.end(kMarch);
}

/// Meter (automatic exposure): a log2 luminance histogram of the march, read back; the chosen
/// exposure replaces the frame's (the composite reads it from the frame block).
void Renderer::Impl::meter_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer, FrameStats& stats) {
    stats.exposure = st.exposure;
    if (!st.auto_exposure) return;
    timer.begin(kMeter);
    const GLuint p = program("meter", {{GL_COMPUTE_SHADER, "meter.comp"}});
    glUseProgram(p);
    const std::vector<std::uint32_t> zero(kMeterBins, 0u);
    meter_buf.upload(zero.data(), zero.size() * sizeof(std::uint32_t));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, meter_buf.id);
    glBindTextureUnit(3, march_target.tex);
    glUniform1i(glGetUniformLocation(p, "u_bins"), kMeterBins);
    glUniform1f(glGetUniformLocation(p, "u_log2_min"), kMeterLog2Min);
    glUniform1f(glGetUniformLocation(p, "u_bin_width"), kMeterBinWidth);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
    glDispatchCompute(GLuint((u.internal_width + 7) / 8), GLuint((u.internal_height + 7) / 8), 1);
    glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    std::vector<std::uint32_t> bins(kMeterBins);
    glGetNamedBufferSubData(meter_buf.id, 0, GLsizeiptr(bins.size() * sizeof(std::uint32_t)), bins.data());
    const detail::ExposureChoice c = detail::choose_exposure(bins, kMeterLog2Min, kMeterBinWidth, st);
    stats.metered_exposure = c.metered;
    stats.exposure = c.applied;
    const float e = float(c.applied);
    glNamedBufferSubData(frame_ubo, GLintptr(offsetof(FrameBlock, sky_params) + 3 * sizeof(float)), sizeof(float), &e);
    timer.end(kMeter);
}

/// Bolt: endpoint transmittances, then the HDR core ribbons at full resolution (the core
/// target is cleared even when no bolt is drawn).
void Renderer::Impl::bolt_pass(const Settings& st, const FrameUniforms& u, PassTimer& timer, FrameStats& stats) {
    const float clear[4] = {0, 0, 0, 0};
    glClearNamedFramebufferfv(core_target.fbo, GL_COLOR, 0, clear);
    if (!(st.bolt && seg_count > 0)) return;
    timer.begin(kBolt);
    glUseProgram(program("bolt_t", {{GL_COMPUTE_SHADER, "bolt_transmittance.comp"}}));
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, seg_buf.id);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, endpoint_buf.id);
    glDispatchCompute(GLuint((seg_count + 63) / 64), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    const GLuint p = program("bolt", {{GL_VERTEX_SHADER, "bolt.vert"}, {GL_FRAGMENT_SHADER, "bolt.frag"}});
    glUseProgram(p);
    glUniform1f(glGetUniformLocation(p, "u_min_width_px"), float(st.bolt_min_width_px));
    glBindFramebuffer(GL_FRAMEBUFFER, core_target.fbo);
    glViewport(0, 0, u.width, u.height);
    glEnable(GL_BLEND);
    glBlendEquation(GL_MAX);  // overlapping caps/joints do not double the core
    glDrawArrays(GL_TRIANGLES, 0, 6 * seg_count);
    glBlendEquation(GL_FUNC_ADD);
    glDisable(GL_BLEND);
    timer.end(kBolt);
    stats.bolt_segments = seg_count;
}

/// Composite: upsampled march + background (sky, stars, ground) * T + bolt, tone mapped
/// into the caller's framebuffer.
void Renderer::Impl::composite_pass(const FrameUniforms& u, const CallerTarget& caller, PassTimer& timer) {
    timer.begin(kComposite);
    const GLuint p =
        program("composite", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "composite.frag"}});
    glUseProgram(p);
    glUniform1i(glGetUniformLocation(p, "u_hdr_output"), 0);
    glBindTextureUnit(3, march_target.tex);
    glBindTextureUnit(4, core_target.tex);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, GLuint(caller.fbo));
    glViewport(0, 0, u.width, u.height);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    timer.end(kComposite);
}

FrameStats Renderer::render(const Camera& camera, const Settings& st, int width, int height) {
    Impl& m = *impl_;
    core::Stopwatch total;
    const double total_cpu0 = process_cpu_ms();
    validate_frame(camera, st, width, height);
    const CallerTarget caller = CallerTarget::save();

    const FrameUniforms u = m.prepare_frame(camera, st, width, height);
    m.bind_frame(u);
    FrameStats stats;
    stats.internal_width = u.internal_width;
    stats.internal_height = u.internal_height;
    PassTimer timer(st.timing, m.queries);
    m.resolve_pass(camera.position, st, u, timer, stats);
    m.glow_pass(st, u, timer, stats);
    m.march_pass(st, u, timer);
    m.meter_pass(st, u, timer, stats);
    m.bolt_pass(st, u, timer, stats);
    m.composite_pass(u, caller, timer);
    timer.finish();
    caller.restore();

    stats.wall = timer.wall_times(m.pending_upload_ms, total.milliseconds());
    stats.cpu = timer.cpu_times(m.pending_upload_cpu_ms, process_cpu_ms() - total_cpu0);
    m.pending_upload_ms = m.pending_upload_cpu_ms = 0.0;
    return stats;
}

std::vector<float> Renderer::read_hdr() const {
    Impl& m = *impl_;
    FULGUR_ASSERT(m.out_w > 0, "read_hdr before render");
    const CallerTarget caller = CallerTarget::save();
    m.hdr_target.ensure(m.out_w, m.out_h);
    const GLuint p =
        m.program("composite", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "composite.frag"}});
    glUseProgram(p);
    glUniform1i(glGetUniformLocation(p, "u_hdr_output"), 1);
    glBindBufferBase(GL_UNIFORM_BUFFER, 0, m.frame_ubo);
    glBindVertexArray(m.vao);
    glBindTextureUnit(3, m.march_target.tex);
    glBindTextureUnit(4, m.core_target.tex);
    glDisable(GL_BLEND);
    glBindFramebuffer(GL_FRAMEBUFFER, m.hdr_target.fbo);
    glViewport(0, 0, m.out_w, m.out_h);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    std::vector<float> rgba(std::size_t(m.out_w) * std::size_t(m.out_h) * 4);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glGetTextureImage(m.hdr_target.tex, 0, GL_RGBA, GL_FLOAT, GLsizei(rgba.size() * sizeof(float)), rgba.data());
    caller.restore();
    std::vector<float> rgb(std::size_t(m.out_w) * std::size_t(m.out_h) * 3);
    for (int y = 0; y < m.out_h; ++y)
        for (int x = 0; x < m.out_w; ++x)
            for (int c = 0; c < 3; ++c)
                rgb[(std::size_t(y) * std::size_t(m.out_w) + std::size_t(x)) * 3 + std::size_t(c)] =
                    rgba[(std::size_t(m.out_h - 1 - y) * std::size_t(m.out_w) + std::size_t(x)) * 4 + std::size_t(c)];
    return rgb;
}

std::vector<float> Renderer::read_resolved_source() const {
    const Impl& m = *impl_;
    if (!m.last_scam) return {};
    std::vector<float> v(m.flash.geom.cell_count());
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glGetTextureImage(m.last_scam, 0, GL_RED, GL_FLOAT, GLsizei(v.size() * sizeof(float)), v.data());
    return v;
}

std::vector<float> Renderer::read_resolved_static() const {
    const Impl& m = *impl_;
    if (!m.last_static) return {};
    std::vector<float> v(m.statics.geom.cell_count() * 3);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glGetTextureImage(m.last_static, 0, GL_RGB, GL_FLOAT, GLsizei(v.size() * sizeof(float)), v.data());
    return v;
}

std::vector<float> Renderer::read_march(int& width, int& height) const {
    const Impl& m = *impl_;
    FULGUR_ASSERT(m.march_target.tex != 0, "read_march before render");
    width = m.march_target.w;
    height = m.march_target.h;
    std::vector<float> rgba(std::size_t(width) * std::size_t(height) * 4), out(rgba.size());
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glGetTextureImage(m.march_target.tex, 0, GL_RGBA, GL_FLOAT, GLsizei(rgba.size() * sizeof(float)), rgba.data());
    const std::size_t row = std::size_t(width) * 4;
    for (int y = 0; y < height; ++y)
        std::copy_n(rgba.begin() + std::ptrdiff_t(std::size_t(height - 1 - y) * row), row,
                    out.begin() + std::ptrdiff_t(std::size_t(y) * row));
    return out;
}

}  // namespace fulgur::render
