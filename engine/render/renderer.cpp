// The Renderer's public API: construction (GL loading, the default programs), the uploads
// of its inputs, render() as the list of the frame's passes, and the read-backs.
#include "render/render.h"

#include "render/detail/frame.h"
#include "render/detail/gl_resources.h"
#include "render/detail/renderer_impl.h"
#include "render/detail/volume_prep.h"

#include <glad/gl.h>

#include <glm/geometric.hpp>
#include <glm/glm.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <limits>
#include <optional>
#include <string>

namespace fulgur::render {

using detail::CallerTarget;
using detail::delete_texture;
using detail::FrameBlock;
using detail::FrameUniforms;
using detail::kPassCount;
using detail::make_texture_3d;
using detail::PassTimer;
using detail::process_cpu_ms;
using detail::upload_into;

std::filesystem::path default_shader_dir() {
    if (const char* env = std::getenv("FULGUR_SHADER_DIR"); env && *env) return env;
    // The source tree's shaders while it exists (the build tree's tools and tests), else
    // where `cmake --install` put them (an installed engine used from another project).
    std::error_code ec;
    if (std::filesystem::is_directory(FULGUR_SHADER_DIR, ec)) return FULGUR_SHADER_DIR;
    return FULGUR_INSTALLED_SHADER_DIR;
}

namespace {

/// Rejects out-of-range settings with an error naming the field.
void validate_settings(const Settings& st) {
    auto range = [](double v, double lo, double hi, bool lo_open, const char* field) {
        const bool ok = std::isfinite(v) && (lo_open ? v > lo : v >= lo) && v <= hi;
        if (!ok)
            throw core::Error(std::string("render: settings.") + field,
                              "must be in " + std::string(lo_open ? "(" : "[") + core::format_number(lo, 9) + ", " +
                                  core::format_number(hi, 9) + "], got " + core::format_number(v, 9));
    };
    const double inf = std::numeric_limits<double>::max();
    // The exposure reaches the shaders as a float32: 1e38 is the largest power of ten it holds.
    constexpr double kMaxExposure = 1e38;
    range(st.exposure, 0.0, kMaxExposure, false, "exposure");
    range(st.exposure_compensation, -20.0, 20.0, false, "exposure_compensation");
    range(st.previous_exposure, 0.0, kMaxExposure, false, "previous_exposure");
    range(st.adaptation_seconds, 0.0, 1e6, false, "adaptation_seconds");
    range(st.brighten_seconds, 0.0, 1e6, false, "brighten_seconds");
    range(st.darken_seconds, 0.0, 1e6, false, "darken_seconds");
    range(st.highlight_fraction, 0.0, 0.5, true, "highlight_fraction");
    range(st.internal_scale, 0.0, 1.0, true, "internal_scale");
    range(st.step_voxels, 0.01, 64.0, false, "step_voxels");
    range(st.detail_step_billows, 0.0, 64.0, false, "detail_step_billows");
    range(st.min_transmittance, 0.0, 0.5, false, "min_transmittance");
    range(st.ground_albedo, 0.0, 1.0, false, "ground_albedo");
    range(double(st.ground_lights), 0.0, double(detail::kMaxGroundLights), false, "ground_lights");
    for (int c = 0; c < 3; ++c) {
        range(st.sky_zenith[c], 0.0, inf, false, "sky_zenith");
        range(st.sky_horizon[c], 0.0, inf, false, "sky_horizon");
    }
    range(st.star_radiance, 0.0, inf, false, "star_radiance");
    range(st.air_scattering, 0.0, 1.0, false, "air_scattering");
    range(st.glow_radius, 0.0, 1e6, true, "glow_radius");
    range(st.bolt_min_width_px, 0.0, 64.0, true, "bolt_min_width_px");
    // Glare: the pyramid's first level averages at most 8x8 output pixels per internal one.
    if (st.glare) range(st.internal_scale, 0.125, 1.0, false, "internal_scale (with glare)");
    range(st.ground_height, -1e6, 1e6, false, "ground_height");
    for (int c = 0; c < 3; ++c) range(st.flash_colour[c], 0.0, inf, false, "flash_colour");
    range(st.direction_min_weight, 0.0, 0.5, false, "direction_min_weight");
    if (st.meter_stride < 1 || st.meter_stride > 8)
        throw core::Error("render", "settings.meter_stride: must be 1 to 8, got " + std::to_string(st.meter_stride));
    // The enumerations, as a caller that casts an integer could set them.
    const auto one_of = [](int v, int count, const char* field) {
        if (v < 0 || v >= count)
            throw core::Error("render", std::string("settings.") + field + ": not a value of its enumeration, got " +
                                            std::to_string(v));
    };
    one_of(int(st.temporal_light), 3, "temporal_light");
    one_of(int(st.temporal_reshape), 2, "temporal_reshape");
    one_of(int(st.kernel), 2, "kernel");
    one_of(int(st.timing), 3, "timing");
    if (st.temporal_moving_block != 0 && st.temporal_moving_block != 2 && st.temporal_moving_block != 4)
        throw core::Error("render", "settings.temporal_moving_block: must be 0 (auto), 2 or 4, got " +
                                        std::to_string(st.temporal_moving_block));
    if (st.temporal_flash_block != 2 && st.temporal_flash_block != 4)
        throw core::Error(
            "render", "settings.temporal_flash_block: must be 2 or 4, got " + std::to_string(st.temporal_flash_block));
}

void check_finite(double v, const std::string& where, const std::string& what) {
    if (!std::isfinite(v)) throw core::Error(where, what + " must be finite");
}

/// Rejects an empty output, out-of-range settings or a degenerate camera with an error
/// naming the field.
void validate_frame(const Camera& camera, const Settings& st, int width, int height) {
    if (width <= 0 || height <= 0)
        throw core::Error("render",
                          "output size must be positive, got " + std::to_string(width) + "x" + std::to_string(height));
    validate_settings(st);
    const glm::dvec3 fwd_raw = camera.target - camera.position;
    if (!(glm::length(fwd_raw) > 0.0) || !(camera.vertical_fov_deg > 0.0 && camera.vertical_fov_deg < 179.0) ||
        !(glm::length(glm::cross(fwd_raw, camera.up)) > 0.0) || !std::isfinite(camera.lens_shift.x) ||
        !std::isfinite(camera.lens_shift.y))
        throw core::Error("render: camera", "needs target != position, up not parallel to the view and 0 < fov < 179");
}

}  // namespace

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
    m.ground_scatter_tex = detail::make_texture_2d(1, 1, GL_R32F, GL_CLAMP_TO_BORDER);
    glTextureSubImage2D(m.ground_scatter_tex, 0, 0, 0, 1, 1, GL_RED, GL_FLOAT, &zero);
    try {
        m.build_default_programs();
    } catch (...) {
        m.release_programs();
        glDeleteVertexArrays(1, &m.vao);
        glDeleteBuffers(1, &m.frame_ubo);
        glDeleteQueries(kPassCount, m.queries);
        delete_texture(m.zero_tex);
        delete_texture(m.ground_scatter_tex);
        throw;
    }
}

void Renderer::Impl::set_ground_scatter(const LitChannel::GroundScatter& g) {
    if (g.irradiance.empty()) {
        ground_scatter_map = glm::vec4(0.0f);
        return;
    }
    if (g.nx != ground_scatter_nx || g.ny != ground_scatter_ny) {
        delete_texture(ground_scatter_tex);
        ground_scatter_tex = detail::make_texture_2d(g.nx, g.ny, GL_R32F, GL_CLAMP_TO_BORDER);
        ground_scatter_nx = g.nx;
        ground_scatter_ny = g.ny;
    }
    glTextureSubImage2D(ground_scatter_tex, 0, 0, 0, g.nx, g.ny, GL_RED, GL_FLOAT, g.irradiance.data());
    ground_scatter_map =
        glm::vec4(float(g.origin.x), float(g.origin.y), float(1.0 / (g.cell * g.nx)), float(1.0 / (g.cell * g.ny)));
}

Renderer::~Renderer() {
    Impl& m = *impl_;
    m.release_programs();
    glDeleteVertexArrays(1, &m.vao);
    glDeleteBuffers(1, &m.frame_ubo);
    glDeleteQueries(kPassCount, m.queries);
    delete_texture(m.zero_tex);
    delete_texture(m.ground_scatter_tex);
    delete_texture(m.ground_rain_tex);
    delete_texture(m.ground_static_tex);
    delete_texture(m.profile_tex);
    delete_texture(m.density_tex);
    delete_texture(m.detail_tex);
    m.flash.release();
    m.rain_flash.release();
    delete_texture(m.pair_tex);
    m.statics.release();
    delete_texture(m.sun_tex);
    m.meter_buf.release();
    m.star_cells.release();
    m.star_cell_count = 0;
    m.resolve_tiles.release();
    m.seg_buf.release();
    m.endpoint_buf.release();
    m.glow_buf.release();
    m.glow_target.release();
    m.glow_grid_target.release();
    m.march_target.release();
    m.core_target.release();
    m.hdr_target.release();
    m.display_target.release();
    for (detail::Target& t : m.glare_down) t.release();
    for (detail::Target& t : m.glare_up) t.release();
    for (detail::Target& t : m.glare_groups) t.release();
    m.glare_groups_key.clear();
    m.glare_sum_version = 0;
    if (m.glare_sum_fbo) glDeleteFramebuffers(1, &m.glare_sum_fbo);
    m.glare_sum_fbo = 0;
    if (m.glare_display_fbo) glDeleteFramebuffers(1, &m.glare_display_fbo);
    m.glare_display_fbo = 0;
    m.temporal.release();
}

double Renderer::rain_solved_share() const noexcept { return impl_->rain_solved_share; }

namespace {

void check_rain_solved_share(double share, const char* where) {
    if (!std::isfinite(share) || !(share > 0.0))
        throw core::Error(std::string(where) + ": rain_solved_share",
                          "must be finite and > 0, got " + core::format_number(share, 8));
}

}  // namespace

void Renderer::set_rain_solved_share(double share) {
    check_rain_solved_share(share, "set_rain_solved_share");
    Impl& m = *impl_;
    if (!m.has_rain || share == m.rain_solved_share) return;
    m.rain_solved_share = share;
    // What the history holds of the ground's flash light (the channel's group) crossed the old
    // share; nothing else in it depends on the share. That light changes by the rain's
    // transmittance at the share's change (3.6e-3 of a small storm's frame), so the history is
    // kept and marched a quarter at a time at its own pixels, as a still camera settles after a
    // move (four frames, each pixel marched once, then exact), not marched whole. A dark
    // channel's group holds nothing the share changes.
    detail::TemporalState& h = m.temporal;
    if (h.has_history && !h.channel.dark()) h.unsettled = 4;
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
    check_rain_solved_share(v.rain_solved_share, "set_volume");
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
    // Rain rides in the same texture (b = extinction / its maximum): one fetch per sample
    // gives the density, the empty-space distance and the rain; its voxels count as occupied.
    const cloud::RainField* rain = v.rain && v.rain->max_extinction > 0.0 ? v.rain : nullptr;
    if (rain) {
        if (!(rain->extinction.geom == v.density->geom))
            throw core::Error("set_volume: rain", "is not on the density grid");
        core::Int3 lo{d.x, d.y, d.z}, hi{-1, -1, -1};
        for (std::size_t i = 0; i < n; ++i) {
            const float r = rain->extinction.data[i];
            if (!std::isfinite(r) || r < 0.0f)
                throw core::Error("set_volume: rain",
                                  "extinction must be finite and >= 0 at voxel " + std::to_string(i));
            occupied[i] = occupied[i] || r > 0.0f;
            if (r > 0.0f) {
                const core::Int3 c = v.density->geom.unindex(i);
                lo = {std::min(lo.x, c.x), std::min(lo.y, c.y), std::min(lo.z, c.z)};
                hi = {std::max(hi.x, c.x), std::max(hi.y, c.y), std::max(hi.z, c.z)};
            }
        }
        // Their box a voxel wider: the march filters the alpha trilinearly at the rain's edge.
        m.rain_lo = {std::max(lo.x - 1, 0), std::max(lo.y - 1, 0), std::max(lo.z - 1, 0)};
        m.rain_hi = {std::min(hi.x + 2, d.x), std::min(hi.y + 2, d.y), std::min(hi.z + 2, d.z)};
    }
    std::vector<std::uint8_t> dist = detail::chebyshev_distance(occupied, d);
    delete_texture(m.density_tex);
    const std::size_t channels = rain ? 4 : 2;
    const GLenum layout = rain ? GL_RGBA : GL_RG;
    auto rain_share = [&](std::size_t i) { return float(double(rain->extinction.data[i]) / rain->max_extinction); };
    if (v.precision == DensityPrecision::U8) {
        m.density_tex = make_texture_3d(rain ? GL_RGBA8 : GL_RG8, d);
        std::vector<std::uint8_t> packed(channels * n, 0);
        for (std::size_t i = 0; i < n; ++i) {
            packed[channels * i] = detail::quantize_density(copy.data[i]);
            packed[channels * i + 1] = dist[i];
            if (rain)
                packed[channels * i + 2] = std::uint8_t(std::lround(255.0f * std::clamp(rain_share(i), 0.0f, 1.0f)));
        }
        glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
        glTextureSubImage3D(m.density_tex, 0, 0, 0, 0, d.x, d.y, d.z, layout, GL_UNSIGNED_BYTE, packed.data());
    } else {
        m.density_tex = make_texture_3d(rain ? GL_RGBA16F : GL_RG16F, d);
        std::vector<float> packed(channels * n, 0.0f);
        for (std::size_t i = 0; i < n; ++i) {
            packed[channels * i] = copy.data[i];
            packed[channels * i + 1] = float(dist[i]) / 255.0f;
            if (rain) packed[channels * i + 2] = rain_share(i);
        }
        glTextureSubImage3D(m.density_tex, 0, 0, 0, 0, d.x, d.y, d.z, layout, GL_FLOAT, packed.data());
    }
    m.has_rain = rain != nullptr;
    m.density_u8 = v.precision == DensityPrecision::U8;
    m.rain_map_key.clear();  // a new texture: its alpha is 0
    if (!rain) m.rain_lo = m.rain_hi = {0, 0, 0};
    if (rain) {
        m.rain_max = rain->max_extinction;
        m.rain_g = rain->g;
        m.rain_albedo = rain->albedo;
        m.rain_top = rain->top;
    }
    m.rain_solved_share = rain ? v.rain_solved_share : 1.0;
    if (m.sun_tex && !(m.density.geom == v.density->geom)) {
        delete_texture(m.sun_tex);  // on the old grid
        m.sun_fine = false;
    }
    delete_texture(m.detail_tex);
    if (v.detail) {
        const cloud::DetailNoise noise(*v.detail);
        constexpr int tile = cloud::kDetailTile;
        m.detail_tex = make_texture_3d(GL_R8, {tile, tile, tile});
        for (GLenum wrap : {GL_TEXTURE_WRAP_S, GL_TEXTURE_WRAP_T, GL_TEXTURE_WRAP_R})
            glTextureParameteri(m.detail_tex, wrap, GL_REPEAT);
        glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
        glTextureSubImage3D(m.detail_tex, 0, 0, 0, 0, tile, tile, tile, GL_RED, GL_UNSIGNED_BYTE,
                            noise.texels().data());
        m.detail_period = noise.period();
        m.detail_finest = std::ldexp(v.detail->scale, 1 - v.detail->octaves);
        m.detail_strength = v.detail->strength;
    }
    m.density = std::move(copy);
    m.distance = std::move(dist);
    m.kappa = v.extinction;
    m.has_volume = true;
    m.temporal.inputs_changed = true;
    m.forget_needed();
    m.ground_lights_k = -1;  // visibility depends on the volume
    m.ground_rain_key.clear();
    m.segment_visibility.clear();
}

void Renderer::clear_volume() {
    Impl& m = *impl_;
    delete_texture(m.density_tex);
    delete_texture(m.detail_tex);
    delete_texture(m.sun_tex);
    m.sun_fine = false;
    m.has_rain = false;
    m.density = {};
    m.distance.clear();
    m.has_volume = false;
    m.temporal.inputs_changed = true;
    m.forget_needed();
    m.ground_lights_k = -1;
    m.ground_rain_key.clear();
    m.segment_visibility.clear();
}

void Renderer::Impl::upload_tracked(detail::SourceSet& set, detail::ScaleTracker& tracker, const char* what,
                                    const SourceUpload& s) {
    core::Stopwatch sw;
    const double cpu0 = process_cpu_ms();
    upload_into(set, what, s.geometry, s.direction_count, s.directions, s.values, 1, s.keep_others);
    const core::GridGeometry& g = s.geometry;
    const float fixed[8] = {float(g.origin.x), float(g.origin.y), float(g.origin.z), float(g.voxel_size),
                            float(g.dims.x),   float(g.dims.y),   float(g.dims.z),   float(s.direction_count)};
    tracker.note(fixed, s.directions, s.values, !s.keep_others);
    pending_upload_ms += sw.milliseconds();
    pending_upload_cpu_ms += process_cpu_ms() - cpu0;
}

void Renderer::upload_source(const SourceUpload& s) {
    impl_->upload_tracked(impl_->flash, impl_->temporal.source, "upload_source", s);
}

void Renderer::clear_source() {
    impl_->temporal.source.clear();
    impl_->flash.has = false;
    impl_->flash.dirty = true;
    clear_rain_source();  // the flash's light at the rain goes with it
}

void Renderer::upload_rain_source(const SourceUpload& s) {
    impl_->upload_tracked(impl_->rain_flash, impl_->temporal.rain_source, "upload_rain_source", s);
}

void Renderer::clear_rain_source() {
    impl_->temporal.rain_source.clear();
    impl_->rain_flash.has = false;
    impl_->rain_flash.dirty = true;
}

void Renderer::reset_history() {
    detail::TemporalState& h = impl_->temporal;
    h.release();
    h.frames = 0;
    h.unsettled = 0;
    h.inputs_changed = true;
    h.source = {};
    h.channel = {};
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
    if (!(s.albedo >= 0.0 && s.albedo <= 1.0))
        throw core::Error("upload_static: albedo", "must be in [0, 1], got " + core::format_number(s.albedo, 8));
    const StaticUpload::Ground& g = s.ground;
    if (!g.rgb.empty()) {
        if (g.nx < 1 || g.nx > 4096 || g.ny < 1 || g.ny > 4096)
            throw core::Error("upload_static: ground.nx, ny",
                              "need 1 to 4096 cells each, got " + std::to_string(g.nx) + " x " + std::to_string(g.ny));
        if (!(std::isfinite(g.cell) && g.cell > 0.0))
            throw core::Error("upload_static: ground.cell", "must be finite and > 0");
        if (!std::isfinite(g.origin.x) || !std::isfinite(g.origin.y))
            throw core::Error("upload_static: ground.origin", "must be finite");
        if (g.rgb.size() != 3 * std::size_t(g.nx) * std::size_t(g.ny))
            throw core::Error("upload_static: ground.rgb",
                              "holds " + std::to_string(g.rgb.size()) + " values, not 3 per cell");
        for (std::size_t i = 0; i < g.rgb.size(); ++i)
            if (!std::isfinite(g.rgb[i]) || g.rgb[i] < 0.0f)
                throw core::Error("upload_static: ground.rgb[" + std::to_string(i) + "]",
                                  "irradiance must be finite and >= 0");
    }
    upload_into(m.statics, "upload_static", s.geometry, s.direction_count, all, s.rgb, 3, false);
    m.static_albedo = s.albedo;
    if (g.rgb.empty()) {
        m.ground_static_map = glm::vec4(0.0f);
    } else {
        if (g.nx != m.ground_static_nx || g.ny != m.ground_static_ny) {
            delete_texture(m.ground_static_tex);
            m.ground_static_tex = detail::make_texture_2d(g.nx, g.ny, GL_RGB32F, GL_CLAMP_TO_EDGE);
            m.ground_static_nx = g.nx;
            m.ground_static_ny = g.ny;
        }
        glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
        glTextureSubImage2D(m.ground_static_tex, 0, 0, 0, g.nx, g.ny, GL_RGB, GL_FLOAT, g.rgb.data());
        m.ground_static_map =
            glm::vec4(float(g.origin.x), float(g.origin.y), float(1.0 / (g.cell * g.nx)), float(1.0 / (g.cell * g.ny)));
    }
    m.temporal.inputs_changed = true;
    m.pending_upload_ms += sw.milliseconds();
    m.pending_upload_cpu_ms += process_cpu_ms() - cpu0;
}

void Renderer::clear_static() {
    impl_->temporal.inputs_changed = true;
    impl_->ground_static_map = glm::vec4(0.0f);
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
    m.temporal.inputs_changed = true;
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

void Renderer::clear_sun() {
    impl_->temporal.inputs_changed = true;
    impl_->has_sun = impl_->sun_fine = false;
}

namespace {

// For each end of each segment (2 i: a, 2 i + 1: b), the far end of the segment it joins (xyz)
// and w = 1, or w = 0 for a free end (the channel's foot, a branch's tip). The channel's
// stretches share their joints exactly (they are cut from one polyline); where several meet (a
// branch point), the one that turns least from this segment's own direction. A far end at the
// joint itself makes bolt.vert reach half the ribbon's width past it.
constexpr std::size_t kMaxEndsAtJoint = 16;

std::vector<glm::vec4> joined_ends(const std::vector<ChannelSegment>& segments) {
    std::vector<std::pair<std::array<float, 3>, std::size_t>> ends;
    ends.reserve(2 * segments.size());
    for (std::size_t i = 0; i < segments.size(); ++i) {
        ends.push_back({{segments[i].a.x, segments[i].a.y, segments[i].a.z}, 2 * i});
        ends.push_back({{segments[i].b.x, segments[i].b.y, segments[i].b.z}, 2 * i + 1});
    }
    std::sort(ends.begin(), ends.end());
    const auto point = [&](std::size_t e) { return e % 2 == 0 ? segments[e / 2].a : segments[e / 2].b; };
    const auto other = [&](std::size_t e) { return e % 2 == 0 ? segments[e / 2].b : segments[e / 2].a; };
    std::vector<glm::vec4> joined(ends.size(), glm::vec4(0.0f));
    std::vector<float> best(ends.size(), -2.0f);
    for (std::size_t lo = 0, hi; lo < ends.size(); lo = hi) {
        for (hi = lo + 1; hi < ends.size() && ends[hi].first == ends[lo].first; ++hi) {}
        if (hi - lo > kMaxEndsAtJoint) {
            // More ends at one point than a channel makes (a caller's): joined, each ribbon
            // reaching half its width past it, without the pairwise search.
            for (std::size_t x = lo; x < hi; ++x) joined[ends[x].second] = glm::vec4(point(ends[x].second), 1.0f);
            continue;
        }
        for (std::size_t x = lo; x < hi; ++x)
            for (std::size_t y = lo; y < hi; ++y) {
                const std::size_t e = ends[x].second, f = ends[y].second;
                if (e / 2 == f / 2) continue;
                // The way this segment leaves through end e, and the way the other goes on.
                const glm::vec3 out = point(e) - other(e), on = other(f) - point(f);
                const float l = glm::length(out) * glm::length(on);
                const float c = l > 0.0f ? glm::dot(out, on) / l : -1.0f;
                if (c > best[e]) {
                    best[e] = c;
                    joined[e] = glm::vec4(other(f), 1.0f);
                }
            }
    }
    return joined;
}

}  // namespace

void Renderer::set_channel(const LitChannel& bolt) {
    Impl& m = *impl_;
    const std::vector<glm::vec4> joined = joined_ends(bolt.segments);
    std::vector<glm::vec4> segs;
    segs.reserve(bolt.segments.size() * 4);
    for (std::size_t i = 0; i < bolt.segments.size(); ++i) {
        const ChannelSegment& s = bolt.segments[i];
        const std::string where = "set_bolt: segment " + std::to_string(i);
        for (int a = 0; a < 3; ++a) {
            check_finite(s.a[a], where, "endpoint a");
            check_finite(s.b[a], where, "endpoint b");
        }
        if (!std::isfinite(s.intensity) || s.intensity < 0.0f)
            throw core::Error(where, "intensity must be finite and >= 0, got " + std::to_string(s.intensity));
        if (!std::isfinite(s.radius) || s.radius <= 0.0f)
            throw core::Error(where, "radius must be finite and > 0, got " + std::to_string(s.radius));
        // bolt.vert's layout: a, intensity | b, radius | the segment joined at a | at b.
        segs.emplace_back(s.a, s.intensity);
        segs.emplace_back(s.b, s.radius);
        segs.push_back(joined[2 * i]);
        segs.push_back(joined[2 * i + 1]);
    }
    const LitChannel::GroundScatter& gs = bolt.ground;
    if (!gs.irradiance.empty()) {
        const std::string where = "set_channel: ground";
        check_finite(gs.origin.x, where, "origin");
        check_finite(gs.origin.y, where, "origin");
        if (!std::isfinite(gs.cell) || !(gs.cell > 0.0))
            throw core::Error(where + ".cell", "must be finite and > 0, got " + std::to_string(gs.cell));
        if (gs.nx < 1 || gs.ny < 1 || gs.nx > 4096 || gs.ny > 4096 ||
            gs.irradiance.size() != std::size_t(gs.nx) * std::size_t(gs.ny))
            throw core::Error(where, "needs 1-4096 cells along x and y and nx * ny values, got " +
                                         std::to_string(gs.nx) + " x " + std::to_string(gs.ny) + " and " +
                                         std::to_string(gs.irradiance.size()));
        for (std::size_t i = 0; i < gs.irradiance.size(); ++i)
            if (!std::isfinite(gs.irradiance[i]) || gs.irradiance[i] < 0.0f)
                throw core::Error(where + ".irradiance[" + std::to_string(i) + "]", "must be finite and >= 0");
    }
    // The channel's light in the temporal history: its geometry fixed, its intensities compared
    // (with the cloud's scattered light on the ground, which follows the same glow).
    std::vector<float> fixed, intensity;
    for (const ChannelSegment& c : bolt.segments) {
        fixed.insert(fixed.end(), {c.a.x, c.a.y, c.a.z, c.b.x, c.b.y, c.b.z, c.radius});
        intensity.push_back(c.intensity);
    }
    if (fixed != m.visibility_geometry) {
        m.segment_visibility.clear();
        m.visibility_geometry = fixed;
    }
    std::vector<float> fixed_all = fixed;
    if (!gs.irradiance.empty()) {
        fixed_all.insert(fixed_all.end(),
                         {float(gs.origin.x), float(gs.origin.y), float(gs.cell), float(gs.nx), float(gs.ny)});
        intensity.insert(intensity.end(), gs.irradiance.begin(), gs.irradiance.end());
    }
    m.temporal.channel.note(fixed_all, {0}, {intensity}, true);
    m.set_ground_scatter(gs);
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
// One frame: the setup (frame_setup.cpp), then the passes in order (pass_<name>.cpp).

FrameStats Renderer::render(const Camera& camera, const Settings& st, int width, int height) {
    validate_frame(camera, st, width, height);
    return impl_->run_frame(camera, st, width, height, nullptr);
}

FrameStats Renderer::render_into_host(const HostFrame& host, const Settings& settings, int width, int height) {
    if (width <= 0 || height <= 0)
        throw core::Error("render: host frame",
                          "output size must be positive, got " + std::to_string(width) + "x" + std::to_string(height));
    const Camera camera = camera_from_matrices(host.view, host.projection, double(width) / double(height));
    if (host.depth_texture != 0 && !glIsTexture(host.depth_texture))
        throw core::Error("render: host frame",
                          "depth_texture " + std::to_string(host.depth_texture) + " is not a texture of this context");
    Settings st = settings;
    st.sky = st.ground = st.glare = st.auto_exposure = false;  // the host's world, tone map and glare
    st.star_radiance = 0.0;
    validate_frame(camera, st, width, height);
    return impl_->run_frame(camera, st, width, height, &host);
}

FrameStats Renderer::Impl::run_frame(const Camera& camera, const Settings& st, int width, int height,
                                     const HostFrame* host) {
    Impl& m = *this;
    core::Stopwatch total;
    const double total_cpu0 = process_cpu_ms();
    const CallerTarget caller = CallerTarget::save();
    m.programs_built = 0;

    FrameUniforms u = m.prepare_frame(camera, st, width, height);
    if (host) m.attach_host_depth(*host, u);
    m.bind_frame(u);
    FrameStats stats;
    stats.internal_width = u.internal_width;
    stats.internal_height = u.internal_height;
    PassTimer timer(st.timing, m.queries);
    std::optional<detail::TemporalPlan> plan;
    if (st.temporal && !host) plan = m.plan_temporal(camera, st, u);
    // A frame that marches a fraction of its pixels while the ground lights move (a leader's
    // channel growing) integrates the rain along their paths at those pixels (~a quarter of
    // the map's ~7 ms at 1280x720) instead of making a map the next frame would not keep; the
    // map is made once the lights hold for a frame.
    const bool lights_moving = u.ground_rain_map && m.ground_lights_moving(u);
    if (plan && plan->stride >= 2 && lights_moving) {
        u.ground_rain_map = false;
        plan->defines = Impl::temporal_march_defines(st, u);
        plan->marched_as_fresh = false;
    }
    const bool reuse = plan && plan->stride == 0;  // the history holds the march, the glow in it
    if (reuse) plan->glare_sum = m.glare_groups_ready(camera, st, u);
    m.resolve_pass(camera.position, st, u, timer, stats, !reuse);
    m.glow_pass(st, u, timer, stats, !reuse, plan ? &*plan : nullptr);
    if (plan)
        m.temporal_march_pass(camera, std::move(*plan), u, timer, stats);
    else
        m.march_pass(st, u, timer);
    m.meter_pass(st, u, timer, stats);
    m.bolt_pass(st, u, timer, stats);
    m.glare_pass(camera, st, u, timer, stats);
    m.composite_pass(u, caller, timer);
    timer.finish();
    if (host) m.detach_host_depth();
    caller.restore();

    stats.wall = timer.wall_times(m.pending_upload_ms, total.milliseconds());
    stats.cpu = timer.cpu_times(m.pending_upload_cpu_ms, process_cpu_ms() - total_cpu0);
    m.pending_upload_ms = m.pending_upload_cpu_ms = 0.0;
    stats.programs_built = m.programs_built;
    return stats;
}

std::vector<float> Renderer::read_hdr() const {
    Impl& m = *impl_;
    FULGUR_ASSERT(m.out_w > 0, "read_hdr before render");
    const CallerTarget caller = CallerTarget::save();
    m.hdr_target.ensure(m.out_w, m.out_h);
    glBindBufferBase(GL_UNIFORM_BUFFER, 0, m.frame_ubo);
    glBindVertexArray(m.vao);
    glDisable(GL_BLEND);
    glBindFramebuffer(GL_FRAMEBUFFER, m.hdr_target.fbo);
    m.draw_composite(1);
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

namespace {

// `values` floats of texture `tex`'s level 0 in `format` (GL_RED, GL_GREEN: one per texel).
std::vector<float> read_texture(GLuint tex, GLenum format, std::size_t values) {
    std::vector<float> v(values);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glGetTextureImage(tex, 0, format, GL_FLOAT, GLsizei(v.size() * sizeof(float)), v.data());
    return v;
}

}  // namespace

std::vector<float> Renderer::read_resolved_source() const {
    const Impl& m = *impl_;
    if (!m.last_scam) return {};
    return read_texture(m.last_scam, GL_RED, m.flash.geom.cell_count());
}

std::vector<float> Renderer::read_resolved_rain_source() const {
    const Impl& m = *impl_;
    if (!m.last_scam || m.last_scam != m.pair_tex) return {};
    return read_texture(m.last_scam, GL_GREEN, m.flash.geom.cell_count());
}

std::vector<float> Renderer::read_resolved_static() const {
    const Impl& m = *impl_;
    if (!m.last_static) return {};
    return read_texture(m.last_static, GL_RGB, m.statics.geom.cell_count() * 3);
}

std::vector<float> Renderer::read_march(int& width, int& height) const {
    const Impl& m = *impl_;
    FULGUR_ASSERT(m.march_out->tex != 0, "read_march before render");
    width = m.march_out->w;
    height = m.march_out->h;
    std::vector<float> rgba(std::size_t(width) * std::size_t(height) * 4), out(rgba.size());
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glGetTextureImage(m.march_out->tex, 0, GL_RGBA, GL_FLOAT, GLsizei(rgba.size() * sizeof(float)), rgba.data());
    const std::size_t row = std::size_t(width) * 4;
    for (int y = 0; y < height; ++y)
        std::copy_n(rgba.begin() + std::ptrdiff_t(std::size_t(height - 1 - y) * row), row,
                    out.begin() + std::ptrdiff_t(std::size_t(y) * row));
    return out;
}

}  // namespace fulgur::render
