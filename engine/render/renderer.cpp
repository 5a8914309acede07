#include "render/render.h"

#include "render/detail/directions.h"
#include "render/detail/gl_program.h"
#include "render/detail/volume_prep.h"
#include "transport/transport.h"

#include <glad/gl.h>

#include <glm/geometric.hpp>
#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <numbers>
#include <optional>

#include <time.h>

namespace fulgur::render {

std::filesystem::path default_shader_dir() {
    if (const char* env = std::getenv("FULGUR_SHADER_DIR"); env && *env) return env;
    return FULGUR_SHADER_DIR;
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
};
static_assert(sizeof(FrameBlock) == 64 + 11 * 16 + 8 * 16 + 4 * 16, "FrameBlock must match std140");

constexpr int kMaxGroundLights = 8;
constexpr int kGlowProfileSize = 256;

enum Pass { kResolve, kGlow, kMarch, kBolt, kComposite, kPassCount };

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
    range(st.internal_scale, 0.0, 1.0, true, "internal_scale");
    range(st.step_voxels, 0.01, 64.0, false, "step_voxels");
    range(st.min_transmittance, 0.0, 0.5, false, "min_transmittance");
    range(st.ground_albedo, 0.0, 1.0, false, "ground_albedo");
    range(double(st.ground_lights), 0.0, 8.0, false, "ground_lights");
    range(st.sky_radiance, 0.0, inf, false, "sky_radiance");
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

/// Everything the passes of one frame share, computed once before the first pass (as
/// Filament's PerViewUniforms): the std140 block the shaders read and the host-side
/// decisions taken from the same inputs.
struct FrameUniforms {
    FrameBlock block;
    int width = 0, height = 0;                    ///< output size (pixels)
    int internal_width = 0, internal_height = 0;  ///< ray-march resolution (pixels)
    bool lit = false;                             ///< the march samples S (source, cloud lighting, volume)
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
            wall_[p] = clock_.milliseconds();
            cpu_[p] = process_cpu_ms() - cpu0_;
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
        return {upload, pass[kResolve], pass[kGlow], pass[kMarch], pass[kBolt], pass[kComposite], total};
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

    // Source
    core::GridGeometry lit_geom;
    int dir_count = 0;
    std::vector<GLuint> src_tex;  // one R32F 3D texture per baked direction
    std::vector<bool> present;
    GLuint scam_tex = 0;
    bool has_source = false;
    bool resolve_dirty = true;
    glm::dvec3 resolved_camera{std::nan("")};
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

    GLuint last_scam = 0;  // S_cam texture the last frame sampled (0: none)

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

    static std::string march_defines(bool skip, bool early, bool source, bool emission) {
        return std::string("#define SKIP_EMPTY ") + (skip ? "1" : "0") + "\n#define EARLY_EXIT " + (early ? "1" : "0") +
               "\n#define HAS_SOURCE " + (source ? "1" : "0") + "\n#define HAS_EMISSION " + (emission ? "1" : "0") +
               "\n";
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
    void resolve_pass(const glm::dvec3& camera, const Settings& st, const FrameUniforms& u, PassTimer& timer,
                      FrameStats& stats);
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
    m.scam_tex = 0;
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
    delete_texture(m.scam_tex);
    for (GLuint& t : m.src_tex) delete_texture(t);
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
    m.density = {};
    m.distance.clear();
    m.has_volume = false;
    m.lit_active_valid = false;
    m.needed_camera.reset();
    m.ground_lights_k = -1;
}

void Renderer::upload_source(const SourceUpload& s) {
    Impl& m = *impl_;
    core::Stopwatch sw;
    const double cpu0 = process_cpu_ms();
    core::validate_geometry(s.geometry, "upload_source: lighting grid");
    (void)transport::output_directions(s.direction_count);  // throws for a bad count
    if (s.directions.size() != s.values.size())
        throw core::Error("upload_source", std::to_string(s.directions.size()) + " directions but " +
                                               std::to_string(s.values.size()) + " value arrays");
    const std::size_t cells = s.geometry.cell_count();
    std::vector<bool> listed(std::size_t(s.direction_count), false);
    for (std::size_t k = 0; k < s.directions.size(); ++k) {
        const int dir = s.directions[k];
        const std::string where = "upload_source: direction " + std::to_string(dir);
        if (dir < 0 || dir >= s.direction_count)
            throw core::Error(where, "index out of range [0, " + std::to_string(s.direction_count) + ")");
        if (listed[std::size_t(dir)]) throw core::Error(where, "listed twice");
        listed[std::size_t(dir)] = true;
        if (s.values[k].size() != cells)
            throw core::Error(where, "has " + std::to_string(s.values[k].size()) + " values, the lighting grid " +
                                         std::to_string(cells) + " cells");
        for (std::size_t c = 0; c < cells; ++c)
            if (!std::isfinite(s.values[k][c]))
                throw core::Error(where, "value of cell " + std::to_string(c) + " is not finite");
    }
    bool fresh = false;
    if (!(m.lit_geom == s.geometry) || m.dir_count != s.direction_count || m.src_tex.empty()) {
        fresh = true;
        for (GLuint& t : m.src_tex) delete_texture(t);
        delete_texture(m.scam_tex);
        m.src_tex.assign(std::size_t(s.direction_count), 0);
        for (GLuint& t : m.src_tex) t = make_texture_3d(GL_R32F, s.geometry.dims);
        if (s.direction_count > 1) m.scam_tex = make_texture_3d(GL_R32F, s.geometry.dims);
        m.lit_geom = s.geometry;
        m.dir_count = s.direction_count;
    }
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    for (std::size_t k = 0; k < s.directions.size(); ++k)
        glTextureSubImage3D(m.src_tex[std::size_t(s.directions[k])], 0, 0, 0, 0, s.geometry.dims.x, s.geometry.dims.y,
                            s.geometry.dims.z, GL_RED, GL_FLOAT, s.values[k].data());
    if (s.keep_others && !fresh && m.present.size() == listed.size()) {
        for (std::size_t d = 0; d < listed.size(); ++d) m.present[d] = m.present[d] || listed[d];
    } else {
        m.present = listed;
    }
    m.has_source = std::find(m.present.begin(), m.present.end(), true) != m.present.end();
    m.resolve_dirty = true;
    m.pending_upload_ms += sw.milliseconds();
    m.pending_upload_cpu_ms += process_cpu_ms() - cpu0;
}

void Renderer::clear_source() {
    impl_->has_source = false;
    impl_->resolve_dirty = true;
}

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
    u.lit = has_source && st.cloud_lighting && has_volume;
    if (u.lit) {
        f.lit_min = glm::vec4(glm::vec3(lit_geom.origin), 1.0f);
        f.lit_size = glm::vec4(glm::vec3(lit_geom.extent()), 0.0f);
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
    f.sky_params = glm::vec4(float(st.sky_radiance), float(st.star_radiance), st.sky ? 1.0f : 0.0f, float(st.exposure));
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

/// Resolve: S toward the camera on the lighting grid (only when S or the camera changed;
/// with one direction S itself). Binds the density (unit 0) and S toward the camera (unit 1).
void Renderer::Impl::resolve_pass(const glm::dvec3& camera, const Settings& st, const FrameUniforms& u,
                                  PassTimer& timer, FrameStats& stats) {
    GLuint scam = zero_tex;
    if (u.lit) {
        const bool must_resolve = dir_count > 1 && (resolve_dirty || resolved_camera != camera);
        if (must_resolve) timer.begin(kResolve);  // includes the CPU work of finding the needed directions
        const std::vector<DirectionUse>& need = needed_for(camera, lit_geom, dir_count, st.direction_min_weight);
        stats.directions_used = int(need.size());
        std::vector<int> active;
        for (const DirectionUse& d : need) {
            if (present[std::size_t(d.index)])
                active.push_back(d.index);
            else
                stats.missing_weight = std::max(stats.missing_weight, d.max_weight);
        }
        if (dir_count == 1) {
            scam = src_tex[0];
        } else {
            scam = scam_tex;
            if (must_resolve) {
                const GLuint p = program("resolve", {{GL_COMPUTE_SHADER, "resolve.comp"}});
                glUseProgram(p);
                const detail::FoldTable ft = detail::fold_table(dir_count);
                GLint idx[27 * 3];
                GLfloat frac[27 * 3];
                for (int c = 0; c < 27; ++c)
                    for (int k = 0; k < 3; ++k) {
                        idx[c * 3 + k] = ft.index[std::size_t(c)][std::size_t(k)];
                        frac[c * 3 + k] = GLfloat(ft.fraction[std::size_t(c)][std::size_t(k)]);
                    }
                glUniform3iv(glGetUniformLocation(p, "u_fold_index"), 27, idx);
                glUniform3fv(glGetUniformLocation(p, "u_fold_fraction"), 27, frac);
                glUniform3i(glGetUniformLocation(p, "u_dims"), lit_geom.dims.x, lit_geom.dims.y, lit_geom.dims.z);
                glBindImageTexture(0, scam_tex, 0, GL_TRUE, 0, GL_READ_WRITE, GL_R32F);
                const GLint loc_dirs = glGetUniformLocation(p, "u_dirs"),
                            loc_acc = glGetUniformLocation(p, "u_accumulate");
                const GLint loc_n = glGetUniformLocation(p, "u_samplers");
                GLfloat active_mask[26] = {};
                for (int d : active) active_mask[d] = 1.0f;
                glUniform1fv(glGetUniformLocation(p, "u_active"), 26, active_mask);
                // Up to 16 directions per dispatch (unused samplers read the zero texture with
                // weight 0); at least one dispatch so S_cam is written (zeros) even without S.
                constexpr std::size_t kBatch = 16;
                for (std::size_t b = 0; b == 0 || b < active.size(); b += kBatch) {
                    GLint dirs[kBatch];
                    std::fill(std::begin(dirs), std::end(dirs), -1);
                    for (std::size_t k = 0; k < kBatch; ++k) {
                        const bool used = b + k < active.size();
                        if (used) dirs[k] = active[b + k];
                        glBindTextureUnit(GLuint(k), used ? src_tex[std::size_t(active[b + k])] : zero_tex);
                    }
                    glUniform4iv(loc_dirs, 4, dirs);
                    glUniform1i(loc_n, GLint(std::min(kBatch, std::max<std::size_t>(1, active.size() - b))));
                    glUniform1i(loc_acc, b == 0 ? 0 : 1);
                    if (b > 0) glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
                    glDispatchCompute(GLuint((lit_geom.dims.x + 7) / 8), GLuint((lit_geom.dims.y + 7) / 8),
                                      GLuint(lit_geom.dims.z));
                }
                glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT);
                timer.end(kResolve);
                resolve_dirty = false;
                resolved_camera = camera;
            }
        }
    }
    glBindTextureUnit(0, has_volume ? density_tex : zero_tex);
    glBindTextureUnit(1, scam);
    last_scam = u.lit ? scam : 0;
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
    const std::string defines = march_defines(st.skip_empty, st.early_exit, u.lit, u.glow);
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
    std::vector<float> v(m.lit_geom.cell_count());
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glGetTextureImage(m.last_scam, 0, GL_RED, GL_FLOAT, GLsizei(v.size() * sizeof(float)), v.data());
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
