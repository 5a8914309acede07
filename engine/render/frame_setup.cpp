// One frame's setup, before the passes: the targets at the frame's sizes, the frame
// uniforms (and the ground lights they carry), and the GL state every pass starts from.
#include "render/detail/renderer_impl.h"

#include <glad/gl.h>

#include <glm/geometric.hpp>
#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>
#include <span>

namespace fulgur::render {

using detail::FrameBlock;
using detail::FrameUniforms;

namespace {

// The channel below the rain's top as this many point lights (the rain's light per sample loops
// over them; 4 instead of 8 saves nothing measurable on fulgur-bench render: the rain's cost is
// its marched volume, where the dry march skipped empty space).
constexpr int kRainLights = 8;

}  // namespace

/// Transmittance straight down from p to the ground through the density.
double Renderer::Impl::vertical_transmittance(const glm::dvec3& p, double ground) const {
    if (!has_volume || p.z <= ground) return 1.0;
    const double h = 0.5 * density.geom.voxel_size;
    const double lo = std::max(ground, density.geom.origin.z), hi = std::min(p.z, density.geom.upper().z);
    if (hi <= lo) return 1.0;
    const int n = int(std::ceil((hi - lo) / h));
    double tau = 0.0;
    for (int i = 0; i < n; ++i) tau += double(density.sample({p.x, p.y, lo + (hi - lo) * (i + 0.5) / n}));
    return std::exp(-kappa * tau * (hi - lo) / n);
}

namespace {

// A stretch of channel: its ends in channel order (a where the previous stretch ended, as the
// channel's segments run) and its power. split_channel cuts runs along it from a: ends sorted
// by height instead put a run that spans two segments at the far ends of both (a light in
// the middle of nowhere, its neighbour doubled up).
struct Stretch {
    glm::dvec3 a, b;
    double power;
};

// The channel's segments clipped to z <= top, in channel order, each with its power (intensity
// x length) times its weight (empty: 1); those without power left out. `total`: their sum.
std::vector<Stretch> stretches_below(const LitChannel& bolt, double top, std::span<const double> weight,
                                     double& total) {
    std::vector<Stretch> out;
    total = 0.0;
    for (std::size_t i = 0; i < bolt.segments.size(); ++i) {
        const ChannelSegment& s = bolt.segments[i];
        glm::dvec3 a(s.a), b(s.b);
        if (a.z > top && b.z > top) continue;
        if (a.z > top) a = b + (a - b) * ((top - b.z) / (a.z - b.z));
        if (b.z > top) b = a + (b - a) * ((top - a.z) / (b.z - a.z));
        const double p = double(s.intensity) * glm::length(b - a) * (weight.empty() ? 1.0 : weight[i]);
        if (!(p > 0.0)) continue;
        out.push_back({a, b, p});
        total += p;
    }
    return out;
}

// The channel's stretches below `top` (stretches_below), as at most k point lights of equal weighted power in
// channel order: each at its stretches' weighted-power centroid, its radiant intensity (W/sr)
// their summed weighted power.
std::vector<glm::dvec4> cluster_channel(const LitChannel& bolt, int k, double top, std::span<const double> weight) {
    double total = 0.0;
    const std::vector<Stretch> pieces = stretches_below(bolt, top, weight, total);
    std::vector<glm::dvec4> out;
    if (total <= 0.0 || k <= 0) return out;
    const double per = total / k;
    double acc = 0.0, wsum = 0.0;
    glm::dvec3 centroid(0.0);
    for (std::size_t i = 0; i < pieces.size(); ++i) {
        centroid += pieces[i].power * 0.5 * (pieces[i].a + pieces[i].b);
        wsum += pieces[i].power;
        acc += pieces[i].power;
        if (acc >= per * double(out.size() + 1) - 1e-9 * total || i + 1 == pieces.size()) {
            out.emplace_back(centroid / wsum, wsum);
            centroid = glm::dvec3(0.0);
            wsum = 0.0;
            if (int(out.size()) == k) break;
        }
    }
    if (wsum > 0.0 && int(out.size()) < k) out.emplace_back(centroid / wsum, wsum);
    return out;
}

// The channel's stretches below `top` (as cluster_channel's) as exactly k point lights of equal
// power (none when no power is below `top`): the stretches in channel order cut into k runs of
// equal power, a segment cut where a run ends, each light at its run's power centroid. The
// rain's lights: the march compiles their count (volume.glsl RAIN_LIGHTS), so a channel that
// grows into the rain keeps one program, and a short stretch is k lights along it, not one.
std::vector<glm::dvec4> split_channel(const LitChannel& bolt, int k, double top) {
    double total = 0.0;
    const std::vector<Stretch> pieces = stretches_below(bolt, top, {}, total);
    std::vector<glm::dvec4> out;
    if (!(total > 0.0) || k <= 0) return out;
    const double per = total / k;
    glm::dvec3 moment(0.0);  // the run's power-weighted sum of positions
    double run = 0.0;        // the run's power so far
    for (const Stretch& piece : pieces) {
        double from = 0.0;  // the fraction of the piece taken by earlier runs
        while (from < 1.0) {
            const double left = (1.0 - from) * piece.power;
            const bool last = int(out.size()) == k - 1;
            const double take = last ? left : std::min(left, per - run);
            const double to = std::min(1.0, from + take / piece.power);
            moment += take * (piece.a + (piece.b - piece.a) * (0.5 * (from + to)));
            run += take;
            from = to;
            if (!last && run >= per * (1.0 - 1e-12)) {
                out.emplace_back(moment / run, run);
                moment = glm::dvec3(0.0);
                run = 0.0;
            }
        }
    }
    if (run > 0.0) out.emplace_back(moment / run, run);
    return out;
}

}  // namespace

/// Representative point lights for the ground: each segment's power dimmed by the cloud
/// straight below its midpoint (a stretch below the cloud's base keeps all of it, one inside
/// the cloud what reaches the ground beneath), then the channel split into k runs of equal
/// dimmed power, each light at its run's dimmed-power centroid. Dimming before clustering
/// matters: a run reaching from inside the cloud to below its base would otherwise be dimmed
/// as a whole by the cloud above its centroid.
void Renderer::Impl::rebuild_ground_lights(int k, double ground) {
    ground_lights.clear();
    ground_lights_k = k;
    ground_lights_height = ground;
    if (segment_visibility.size() != bolt.segments.size() || visibility_ground != ground) {
        segment_visibility.resize(bolt.segments.size());
        for (std::size_t i = 0; i < bolt.segments.size(); ++i)
            segment_visibility[i] =
                vertical_transmittance(0.5 * (glm::dvec3(bolt.segments[i].a) + glm::dvec3(bolt.segments[i].b)), ground);
        visibility_ground = ground;
    }
    for (glm::dvec4 l : cluster_channel(bolt, k, std::numeric_limits<double>::infinity(), segment_visibility)) {
        glm::dvec3 c(l);
        c.z = std::max(c.z, ground + 1.0);
        ground_lights.emplace_back(glm::vec3(c), float(l.w));
    }
    // The rain's: the channel below the rain's top (no cloud between them and the rain).
    rain_lights.clear();
    if (has_rain)
        for (glm::dvec4 l : split_channel(bolt, kRainLights, rain_top)) rain_lights.emplace_back(l);
}

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
    glm::dmat4 proj = glm::perspective(glm::radians(camera.vertical_fov_deg), aspect, 0.5, 1e6);
    proj[2][0] = camera.lens_shift.x;  // an off-centre projection (camera_ray shifts by the same)
    proj[2][1] = camera.lens_shift.y;
    f.view_proj = glm::mat4(proj * view);
    f.cam_pos = glm::vec4(glm::vec3(camera.position), float(tan_half));
    f.cam_fwd = glm::vec4(glm::vec3(fwd), float(aspect));
    f.cam_right = glm::vec4(glm::vec3(right), float(camera.lens_shift.x));
    f.cam_up = glm::vec4(glm::vec3(up), float(camera.lens_shift.y));
    // Volume and march step
    double step = 1.0;
    int max_steps = 1;
    u.detail = has_volume && detail_tex != 0 && st.detail;
    if (has_volume) {
        const core::GridGeometry& g = density.geom;
        step = st.step_voxels * g.voxel_size;
        // Billows finer than the step would alias: at most detail_step_billows of the finest.
        if (u.detail && st.detail_step_billows > 0.0) step = std::min(step, st.detail_step_billows * detail_finest);
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
        f.sun_params = glm::vec4(float(sun_g), sun_fine && has_volume ? 1.0f : 0.0f, u.sun ? 1.0f : 0.0f, 0.0f);
    }
    u.rain = has_volume && has_rain && st.rain;
    if (u.rain) {
        f.rain = glm::vec4(float(rain_max), float(rain_g), float(rain_top), float(rain_albedo));
    }
    if (u.detail) f.detail = glm::vec4(float(1.0 / detail_period), float(detail_strength), 0.0f, 0.0f);
    f.march_params = glm::vec4(float(step), float(st.min_transmittance), st.jitter ? 1.0f : 0.0f,
                               float(std::fmod(double(st.frame_index) * 0.6180339887498949, 1.0)));
    f.sizes = glm::vec4(float(width), float(height), float(iw), float(ih));
    // Ground (its point lights light the rain too, with the ground off)
    if (st.ground || u.rain) {
        if (ground_lights_k != st.ground_lights || ground_lights_height != st.ground_height)
            rebuild_ground_lights(st.ground_lights, st.ground_height);
        for (std::size_t i = 0; i < ground_lights.size() && i < std::size_t(detail::kMaxGroundLights); ++i)
            f.ground_light[i] = ground_lights[i];
        f.ground_params = glm::vec4(float(st.ground_height), float(st.ground_albedo / std::numbers::pi),
                                    st.ground ? 1.0f : 0.0f, float(ground_lights.size()));
        u.ground_scatter = st.ground && st.ground_scatter;
        u.ground_rain_map = st.ground_rain_map && st.ground && u.rain && !ground_lights.empty();
        if (u.ground_scatter) f.ground_scatter = ground_scatter_map;
        if (st.ground && statics.has && st.static_light) f.ground_static = ground_static_map;
        for (std::size_t i = 0; u.rain && i < rain_lights.size(); ++i) f.rain_light[i] = rain_lights[i];
        // The channel lights the rain when the flash lights the volume (its light is the
        // flash's). The rain scatters the static light's S by its own albedo: S carries the
        // cloud's, taken out here (an albedo of 0 leaves S at 0).
        const bool flash_lights_rain = st.cloud_lighting && st.flash_light;
        if (u.rain) {
            u.rain_lights = flash_lights_rain ? int(rain_lights.size()) : 0;
            u.rain_source = u.lit && rain_flash.has;
            f.rain_lights = glm::vec4(float(u.rain_lights), static_albedo > 0.0 ? float(1.0 / static_albedo) : 0.0f,
                                      float(rain_solved_share), 0.0f);
        }
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
    composite_dither = st.dither;
    u.stars = st.sky && st.star_radiance > 0.0;
    composite_overlays = st.composite_overlays;
    display_upsample = st.display_upsample;
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

}  // namespace fulgur::render
