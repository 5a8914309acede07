// The march pass with the temporal history (Settings::temporal): the march of this frame's
// pixels, the light groups apart (march_groups.frag), then the history's resolve
// (temporal.frag) into the new history and the march result the later passes read.
#include "render/detail/renderer_impl.h"
#include "render/detail/temporal.h"

#include <glad/gl.h>

#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

namespace fulgur::render {

using detail::FrameUniforms;
using detail::kMarch;
using detail::PassTimer;

namespace {

// temporal.frag's inputs: this frame's marched groups (when it marched) and the history, each
// as a texture (bilinear reads) and as an image (reads at a texel: on llvmpipe an image load
// costs less than a texel fetch).
void bind_temporal_inputs(const detail::MultiTarget* fresh, const detail::MultiTarget& history) {
    for (int i = 0; i < 3; ++i) {
        const GLuint hist = history.tex[std::size_t(i)];
        glBindTextureUnit(GLuint(13 + i), hist);
        glBindImageTexture(GLuint(5 + i), hist, 0, GL_FALSE, 0, GL_READ_ONLY, GL_RGBA32F);
        if (!fresh) continue;
        const GLuint f = fresh->tex[std::size_t(i)];
        glBindTextureUnit(GLuint(10 + i), f);
        glBindImageTexture(GLuint(2 + i), f, 0, GL_FALSE, 0, GL_READ_ONLY, GL_RGBA32F);
    }
}

}  // namespace

namespace detail {

void MultiTarget::ensure(int width, int height, int count) {
    if (fbo && w == width && h == height && int(tex.size()) == count) return;
    release();
    w = width;
    h = height;
    glCreateFramebuffers(1, &fbo);
    std::vector<GLenum> draw;
    for (int i = 0; i < count; ++i) {
        tex.push_back(make_texture_2d(w, h));
        glNamedFramebufferTexture(fbo, GLenum(GL_COLOR_ATTACHMENT0 + i), tex.back(), 0);
        draw.push_back(GLenum(GL_COLOR_ATTACHMENT0 + i));
    }
    glNamedFramebufferDrawBuffers(fbo, GLsizei(draw.size()), draw.data());
    check_framebuffer(fbo, w, h);
}

void MultiTarget::release() {
    if (fbo) glDeleteFramebuffers(1, &fbo);
    for (GLuint& t : tex) delete_texture(t);
    tex.clear();
    fbo = 0;
    w = h = 0;
}

void TemporalState::release() {
    fresh.release();
    for (MultiTarget& t : history) t.release();
    march.release();
    ++history_version;
    for (GLuint& f : resolve_fbo) {
        if (f) glDeleteFramebuffers(1, &f);
        f = 0;
    }
    has_history = false;
}

bool TemporalState::flash_holds() const {
    if (!source.valid() || !rain_source.valid()) return false;
    if (rain_source.dark() && rain_source.rescale() == 1.0) return true;  // no rain light then or now
    const double a = source.rescale(), b = rain_source.rescale();
    return std::abs(a - b) <= ScaleTracker::kTolerance * std::max(std::abs(a), std::abs(b));
}

TemporalKey temporal_key(const FrameUniforms& u, const std::string& march_defines) {
    const FrameBlock& f = u.block;
    TemporalKey k;
    auto add = [&](const glm::vec4& v, int n = 4) { append_components(k.uniforms, v, n); };
    // Not the flash's lighting grid nor the channel's light counts: a flash going dark changes
    // them, and its light groups' trackers follow that.
    for (const glm::vec4* v : {&f.vol_min, &f.vol_size, &f.static_min, &f.static_size, &f.sun_dir, &f.sun_rgb,
                               &f.sun_params, &f.detail, &f.rain, &f.sky_zenith, &f.sky_horizon, &f.glow_params})
        add(*v);
    add(f.march_params, 3);   // not its w: the frame's jitter offset
    add(f.ground_params, 3);  // not its w: the number of ground lights
    add(f.sky_params, 3);     // not its w: the exposure
    add(f.light_colour, 3);   // not its w: the dither
    k.uniforms.push_back(float(f.counts.x));
    // The ground's scattered light as asked for, not its cells: the channel's tracker follows those.
    k.uniforms.push_back(u.ground_scatter ? 1.0f : 0.0f);
    k.defines = march_defines;
    k.width = u.width;
    k.height = u.height;
    k.internal_width = u.internal_width;
    k.internal_height = u.internal_height;
    return k;
}

bool camera_continues(const Camera& from, const Camera& to) {
    const glm::dvec3 f0 = glm::normalize(from.target - from.position), f1 = glm::normalize(to.target - to.position);
    const double distance = glm::length(to.target - to.position);
    return glm::dot(f0, f1) >= std::cos(glm::radians(kMaxTurnDeg)) &&
           glm::length(to.position - from.position) <= kMaxMove * distance &&
           std::abs(to.vertical_fov_deg - from.vertical_fov_deg) <= kMaxTurnDeg;
}

bool same_camera(const Camera& a, const Camera& b) {
    return a.position == b.position && a.target == b.target && a.up == b.up &&
           a.vertical_fov_deg == b.vertical_fov_deg && a.lens_shift == b.lens_shift;
}

}  // namespace detail

namespace {

// The order in which a moving camera marches the four pixels of each 2x2 block: diagonal
// first, so two consecutive frames cover both diagonals.
constexpr std::array<glm::ivec2, 4> kPhases = {glm::ivec2{0, 0}, {1, 1}, {1, 0}, {0, 1}};
// The same for the sixteen of a 4x4 block: the 4x4 Bayer matrix's order (each frame's pixel as
// far from the previous ones as the block allows; each 2x2 quarter of the block once in every 4 frames).
constexpr std::array<glm::ivec2, 16> kPhases16 = {glm::ivec2{0, 0}, {2, 2}, {2, 0}, {0, 2}, {1, 1}, {3, 3},
                                                  {3, 1},           {1, 3}, {1, 0}, {3, 2}, {3, 0}, {1, 2},
                                                  {0, 1},           {2, 3}, {2, 1}, {0, 3}};
// A history sample serves a pixel when its depth is within this fraction of the distance the
// pixel's depth predicts from the history's camera (1 degree of orbit moves a cloud's depth
// by well under 1%; a disoccluded background differs by tens of percent).
constexpr float kDepthTolerance = 0.05f;

}  // namespace

detail::TemporalPlan Renderer::Impl::plan_temporal(const Camera& camera, const Settings& st,
                                                   const FrameUniforms& u) const {
    const detail::TemporalState& h = temporal;
    detail::TemporalPlan plan;
    plan.defines = temporal_march_defines(st, u);
    // The key names the flash's S and the glow as the settings ask for them, not as present
    // this frame, and not the rain's flash lights: a flash going dark is the trackers' to
    // follow, a setting switched is not.
    const bool flash_on = st.cloud_lighting && st.flash_light && has_volume;
    const bool glow_on = st.glow && st.air_scattering > 0.0;
    plan.key = detail::temporal_key(
        u, march_defines(st.skip_empty, st.early_exit, flash_on, glow_on, u.statics, u.sun, u.detail, u.rain, -1, -1,
                         false, st.ground_rain_map && st.ground && u.rain, flash_on));
    // The cloud's group holds when nothing but the camera (within reprojection) and the light
    // groups changed; the flash's and the channel's when they changed only in intensity.
    const bool cloud_holds =
        h.has_history && !h.inputs_changed && plan.key == h.key && detail::camera_continues(h.camera, camera);
    const bool lights_hold = h.flash_holds() && h.channel.valid();
    const bool still = cloud_holds && detail::same_camera(camera, h.camera);
    // A block needs the march to be at least as wide and high: a march one pixel wide or high
    // marches every pixel, one under 4 pixels marches quarters. The 4x4 block while no flash or
    // channel lights the frame (between flashes), and during a flash only where the settings ask
    // (temporal_flash_block): there a sixteenth is twice a quarter's error from a fresh render
    // and three times as many display levels (docs/render.md).
    const int fits = std::min(u.internal_width, u.internal_height);
    const bool flash_dark = !u.lit && seg_count == 0;
    // A light that changed in shape, the cloud's group holding: a quarter marched, the light
    // groups upsampled from it (Settings::temporal_reshape).
    const bool reshaped = cloud_holds && !lights_hold && st.temporal_reshape == TemporalReshape::Quarter && fits >= 2;
    const int block = temporal_block(st.temporal_moving_block, camera.vertical_fov_deg, u.internal_height);
    plan.block = block == 4 && (flash_dark || st.temporal_flash_block == 4) && fits >= 4 && !reshaped ? 4 : 2;
    plan.stride = reshaped                        ? 2
                  : !(cloud_holds && lights_hold) ? 1
                  : still                         ? (h.unsettled > 0 ? 3 : 0)
                  : fits >= 2                     ? 2
                                                  : 1;
    plan.still_cloud = reshaped && still;
    plan.phase = plan.stride == 2 && plan.block == 4 ? kPhases16[h.frames % 16]
                 : plan.stride >= 2                  ? kPhases[h.frames % 4]
                                                     : glm::ivec2(0);
    // Upsampled or reprojected, by the same rule for every group: where the marched pixels are
    // close together on screen upsampling them is the nearer a fresh render for the cloud's group
    // too (docs/render.md). With no flash or channel light the light groups are zero either way:
    // the cheaper resolve.
    const bool upsample = temporal_upsamples(st.temporal_light, camera.vertical_fov_deg, u.internal_height);
    plan.reproject_light = !flash_dark && !upsample && !reshaped;
    plan.reproject_cloud = !upsample;
    return plan;
}

void Renderer::Impl::temporal_march_pass(const Camera& camera, detail::TemporalPlan plan, const FrameUniforms& u,
                                         PassTimer& timer, FrameStats& stats) {
    detail::TemporalState& h = temporal;
    const int stride = plan.stride;
    const glm::ivec2 phase = plan.phase;
    const std::string& defines = plan.defines;
    detail::TemporalKey& key = plan.key;
    stats.temporal = stride == 0 ? TemporalStep::Reused : stride == 1 ? TemporalStep::Full : TemporalStep::Quarter;
    stats.marched_share = 0.0;
    march_out = &h.march;
    // A still camera: the history stays as it was marched (the groups' trackers keep their
    // factors relative to it), and only the march the later passes read is summed again from it
    // with the groups' factors now (temporal.frag, STRIDE 0): one target written instead of the
    // history's three and the march. When the factors are those the march was summed with (a
    // moonlit or sunlit frame between flashes), not even that: the meter keeps its histogram of
    // that march too. (Stride 0 needs the history, which its march was written with.)
    if (stride == 0) {
        const glm::dvec2 scale(h.source.rescale(), h.channel.rescale());
        if (scale != h.march_scale) {
            timer.begin(kMarch);
            // With the glare's groups ready, the glare's sum too, into its finest level (the
            // glare pass then runs nothing).
            const bool glare =
                plan.glare_sum && !glare_up.empty() && glare_up[0].w == h.march.w && glare_up[0].h == h.march.h;
            const GLuint p =
                program("temporal", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "temporal.frag"}},
                        std::string("#define STRIDE 0\n#define GLARE_SUM ") + (glare ? "1" : "0") + "\n");
            glUseProgram(p);
            bind_temporal_inputs(nullptr, h.history[h.current]);
            glUniform2f(glGetUniformLocation(p, "u_rescale"), float(scale.x), float(scale.y));
            if (glare) {
                glUniform1f(glGetUniformLocation(p, "u_keep"), float(glare_groups_keep));
                for (int g = 0; g < 3; ++g)
                    glBindImageTexture(GLuint(2 + g), glare_groups[g].tex, 0, GL_FALSE, 0, GL_READ_ONLY, GL_RGBA32F);
                detail::attach_targets(glare_sum_fbo, {h.march.tex, glare_up[0].tex});
                glBindFramebuffer(GL_FRAMEBUFFER, glare_sum_fbo);
            } else {
                glBindFramebuffer(GL_FRAMEBUFFER, h.march.fbo);
            }
            glViewport(0, 0, h.march.w, h.march.h);
            glDrawArrays(GL_TRIANGLES, 0, 3);
            timer.end(kMarch);
            h.march_scale = scale;
            ++h.march_version;
            if (glare) glare_sum_version = h.march_version;
        }
        h.key = std::move(key);
        ++h.frames;
        return;
    }
    timer.begin(kMarch);
    const int grid = plan.grid();

    const int iw = u.internal_width, ih = u.internal_height;
    const glm::ivec2 marched = plan.marched_size(iw, ih);
    const int fw = marched.x, fh = marched.y;
    h.fresh.ensure(fw, fh, 3);
    ground_rain_pass(u);
    rain_lights_pass(u);
    // The glow pass drew only the marched pixels (glow_pass): the march reads them in place.
    const GLuint march =
        program("march_groups", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "march_groups.frag"}},
                defines + (grid > 1 ? "#define GLOW_ON_GRID 1\n" : ""));
    glUseProgram(march);
    glUniform3i(glGetUniformLocation(march, "u_grid"), grid, phase.x, phase.y);
    glBindFramebuffer(GL_FRAMEBUFFER, h.fresh.fbo);
    glViewport(0, 0, fw, fh);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    stats.marched_share = double(fw) * double(fh) / (double(iw) * double(ih));

    // The resolve into the other history buffer and the march target.
    const int next = 1 - h.current;
    for (detail::MultiTarget& t : h.history) t.ensure(iw, ih, 3);
    GLuint& fbo = h.resolve_fbo[next];
    h.march.ensure(iw, ih);
    const std::vector<GLuint>& hist = h.history[next].tex;
    detail::attach_targets(fbo, {hist[0], hist[1], hist[2], h.march.tex});
    detail::check_framebuffer(fbo, iw, ih);

    const GLuint p =
        program("temporal", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "temporal.frag"}},
                "#define STRIDE " + std::to_string(stride) + "\n" +
                    (stride == 2 ? std::string("#define REPROJECT_LIGHT ") + (plan.reproject_light ? "1" : "0") +
                                       "\n#define REPROJECT_CLOUD " + (plan.reproject_cloud ? "1" : "0") +
                                       "\n#define STILL_CLOUD " + (plan.still_cloud ? "1" : "0") + "\n#define BLOCK " +
                                       std::to_string(plan.block) + "\n"
                                 : std::string()));
    glUseProgram(p);
    bind_temporal_inputs(&h.fresh, h.history[h.current]);
    glUniform2i(glGetUniformLocation(p, "u_phase"), phase.x, phase.y);
    glUniformMatrix4fv(glGetUniformLocation(p, "u_prev_view_proj"), 1, GL_FALSE, glm::value_ptr(h.view_proj));
    const glm::vec3 prev(h.camera.position);
    glUniform4f(glGetUniformLocation(p, "u_prev_cam"), prev.x, prev.y, prev.z, 0.0f);
    glUniform2f(glGetUniformLocation(p, "u_rescale"), float(h.source.rescale()), float(h.channel.rescale()));
    glUniform1f(glGetUniformLocation(p, "u_depth_tolerance"), kDepthTolerance);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, iw, ih);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    timer.end(kMarch);

    h.current = next;
    ++h.march_version;
    ++h.history_version;
    h.march_scale = glm::dvec2(1.0);
    h.has_history = true;
    h.inputs_changed = false;
    h.key = std::move(key);
    h.camera = camera;
    h.view_proj = u.block.view_proj;
    h.source.written();
    h.rain_source.written();
    h.channel.written();
    // The phases count from the last frame that marched every pixel: what a sequence of frames
    // marches depends on the frames since then, not on how many the renderer drew before.
    h.frames = stride == 1 ? 0 : h.frames + 1;
    // A moving camera upsamples three pixels of each 2x2 block: once it stops, the next four
    // frames march the four phases in turn, after which every pixel is marched and rescaled. A
    // still camera's light that changed in shape marched one phase at this view already: three.
    // A frame whose ground was integrated per pixel, as a fresh frame's is not, settles none: four.
    h.unsettled = !plan.marched_as_fresh ? 4
                  : stride == 2          ? (plan.still_cloud ? 3 : 4)
                  : stride == 3          ? h.unsettled - 1
                                         : 0;
}

}  // namespace fulgur::render
