// Internal to fulgur::render: the renderer's state (GL objects, the uploaded inputs, the
// caches derived from them) and its frame as a list of passes. The frame setup is in
// frame_setup.cpp, each pass in pass_<name>.cpp, the public API in renderer.cpp.
#pragma once

#include "core/core.h"
#include "render/detail/frame.h"
#include "render/detail/gl_program.h"
#include "render/detail/gl_resources.h"
#include "render/detail/temporal.h"
#include "render/render.h"

#include <glad/gl.h>

#include <glm/glm.hpp>

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace fulgur::render {

struct Renderer::Impl {
    std::filesystem::path shader_dir;
    std::map<std::string, GLuint> programs;
    int programs_built = 0;  // programs built since the count was last taken (FrameStats::programs_built)
    GLuint vao = 0, frame_ubo = 0, zero_tex = 0, profile_tex = 0;
    GLuint queries[detail::kPassCount] = {};

    // Volume
    bool has_volume = false;
    GLuint density_tex = 0;
    core::Grid3<float> density;          // CPU copy (clamped), for ground-light visibility
    std::vector<std::uint8_t> distance;  // Chebyshev distance field (voxels)
    double kappa = 0.0;
    GLuint detail_tex = 0;  // the billow tile (cloud::DetailNoise, R8, repeat); 0: no detail
    double detail_period = 0.0, detail_strength = 0.0;
    double detail_finest = 0.0;  // metres across the finest billows
    bool has_rain = false;       // the density texture's b channel holds rain (RGBA)
    double rain_max = 0.0, rain_g = 0.0, rain_albedo = 0.0, rain_top = 0.0;
    double rain_solved_share = 1.0;                 // VolumeDesc::rain_solved_share
    core::Int3 rain_lo{0, 0, 0}, rain_hi{0, 0, 0};  // the voxels with rain, a voxel wider: [lo, hi) (empty: none)
    bool density_u8 = false;                        // the density texture is RGBA8 (else RGBA16F)

    // Source: the flash's S and the static light's (colour)
    detail::SourceSet flash = detail::SourceSet(GL_R32F), statics = detail::SourceSet(GL_RGBA32F);
    // The flash's light of orders >= 2 at the rain's points (upload_rain_source), resolved as
    // `flash`, and packed with the flash's resolved S (pair_with_rain: RG32F on its grid).
    detail::SourceSet rain_flash = detail::SourceSet(GL_R32F);
    GLuint pair_tex = 0;
    core::Int3 pair_dims{0, 0, 0};
    GLuint pair_with_rain(GLuint scam, GLuint rain_scam);
    /// An upload of S into its set, noted by its light group's tracker, its time counted with
    /// the frame's uploads.
    void upload_tracked(detail::SourceSet& set, detail::ScaleTracker& tracker, const char* what, const SourceUpload& s);
    double static_albedo = 0.0;  // StaticUpload::albedo: the cloud's albedo the static S carries
    // The sun drawn at full resolution (set_sun)
    GLuint sun_tex = 0;  // transmittance to the sun on the density grid (R16F)
    bool has_sun = false, sun_fine = false, sun_scatter = false;
    glm::dvec3 sun_direction{0.0, 0.0, -1.0}, sun_rgb{0.0};
    double sun_albedo = 0.0, sun_g = 0.0;
    // Exposure metering
    detail::Buffer meter_buf;
    detail::Buffer resolve_tiles;  // the tile list of the grid being resolved
    double pending_upload_ms = 0.0, pending_upload_cpu_ms = 0.0;
    // The needed directions of one lighting grid: its nodes near non-empty density, and the
    // directions for the last (camera, count, threshold).
    struct NeededCache {
        bool used = false;  // holds a grid
        core::GridGeometry geom;
        bool active_valid = false;
        std::vector<std::uint8_t> active;
        /// The resolve's work groups: the 8 x 8 x 1 node tiles holding an active node, as
        /// (tz * tiles_y + ty) * tiles_x + tx (valid with `active`).
        std::vector<std::uint32_t> tiles;
        std::optional<glm::dvec3> camera;
        int count = 0;
        double min_weight = -1.0;
        std::vector<DirectionUse> needed;
    };
    // Three grids: the flash's, the static light's (which may be finer) and the flash's light
    // at the rain (the lighting grid, where the flash's may be the finer transport grid): a
    // frame resolves each, and fewer slots would recompute one every frame.
    mutable std::array<NeededCache, 3> needed_cache;
    mutable std::size_t needed_next = 0;  // the slot a third grid replaces
    NeededCache& needed_slot(const core::GridGeometry& lg) const;
    /// The active-node tiles of a lighting grid (cached with its active mask).
    const std::vector<std::uint32_t>& active_tiles(const core::GridGeometry& lg) const;
    void forget_needed() {
        for (NeededCache& c : needed_cache) c = {};
    }

    // Bolt
    LitChannel bolt;
    detail::Buffer seg_buf, endpoint_buf, glow_buf;
    int seg_count = 0, glow_count = 0;
    double glow_built_radius = -1.0;
    double profile_radius = -1.0, profile_sigma = -1.0;
    std::vector<glm::vec4> ground_lights;
    std::vector<glm::vec4> rain_lights;  // the channel below the rain's top as point lights (W/sr)
    int ground_lights_k = -1;            // -1: to rebuild
    double ground_lights_height = 0.0;
    // Each channel segment's transmittance straight down from its midpoint to the ground (the
    // ground lights' weights), kept while the channel's geometry, the ground and the volume
    // stay: a flash changes only the intensities from frame to frame.
    std::vector<double> segment_visibility;
    std::vector<float> visibility_geometry;
    double visibility_ground = 0.0;
    // The cloud's scattered flash light on the ground (LitChannel::ground): an R32F texture of
    // its cells, clamped to zero outside (1x1 zero while there is none), and where it lies.
    GLuint ground_scatter_tex = 0;
    // The ground lights' rain transmittance on polar maps around their feet (a 2D array texture,
    // a layer per light; pass_ground_rain.cpp), and what it was made from (empty: to make).
    GLuint ground_rain_tex = 0;
    std::vector<float> ground_rain_key;
    float ground_rain_share = 0.0f;       // the share of the rain's extinction the map was made at
    std::vector<float> ground_rain_last;  // the map's key the previous frame asked for (empty: none)
    // What the rain's lights' extinction in the density texture's alpha was made from
    // (pass_rain_lights.cpp; empty: to make).
    std::vector<float> rain_map_key;
    int ground_scatter_nx = 0, ground_scatter_ny = 0;  // the texture's size (0: the 1x1 zero)
    glm::vec4 ground_scatter_map{0.0f};                // FrameBlock::ground_scatter (zw 0: none)
    void set_ground_scatter(const LitChannel::GroundScatter& g);
    // The static light's ground (StaticUpload::ground): RGB32F, bound to unit 11.
    GLuint ground_static_tex = 0;
    int ground_static_nx = 0, ground_static_ny = 0;
    glm::vec4 ground_static_map{0.0f};  // FrameBlock::ground_static (zw 0: none)

    GLuint last_scam = 0;    // S_cam texture the last frame sampled (0: none)
    GLuint last_static = 0;  // the static light's S_cam the last frame sampled (0: none)

    // Targets
    detail::Target glow_target, march_target, core_target, hdr_target;
    detail::Target glow_grid_target;  // the glow at a temporal plan's marched pixels only
    detail::Target display_target;    // the march's frame as display values (RGBA8, internal size; pass_composite.cpp)
    std::vector<detail::Target> glare_down, glare_up;  // the glare pyramid's levels (pass_glare.cpp)
    GlareFit glare_fit;
    detail::TemporalState temporal;            // the temporal history (pass_temporal.cpp)
    double glare_key[3] = {-1.0, -1.0, -1.0};  // pixel size, internal scale, reach the fit was made for
    // A still camera's glare per light group of the history (pass_glare.cpp): the flash's, the
    // static light's, the channel's with the core, each the pyramid's finest sum, and what they
    // were made from (empty: none).
    detail::Target glare_groups[3];
    std::vector<double> glare_groups_key;
    double glare_groups_keep = 1.0;  // GlareFit::keep of the fit the groups were made with
    // The march version whose glare sum glare_up[0] holds (0: another glare), and the temporal
    // pass's framebuffer that writes the march and that sum at once.
    std::uint64_t glare_sum_version = 0;
    GLuint glare_sum_fbo = 0;
    // The march this frame's later passes read: march_target, or the temporal history's own
    // (TemporalState::march), which a frame rendered without the history leaves as it was.
    const detail::Target* march_out = &march_target;
    // The meter's last histogram, and the history's march it counted (version; 0: another)
    // with which stride (Settings::meter_stride).
    std::vector<std::uint32_t> meter_bins;
    std::uint64_t meter_version = 0;
    int meter_stride = 0;
    bool glare_ran = false;   // this frame's composite adds glare_up[0]
    bool core_drawn = false;  // this frame's bolt pass drew core_target
    // The core as kept for a still camera reusing its history (pass_bolt.cpp): what it was drawn
    // for (empty: not kept), the channel's factor then, and this frame's scale of it (1 when drawn).
    std::vector<double> core_kept_key;
    double core_kept_factor = 0.0;
    float core_scale = 1.0f;
    // The pixels of core_target that may hold a drawn bolt ([x0, x1) x [y0, y1)), and the
    // texture and size they are of: the next bolt pass clears only these.
    glm::ivec4 core_footprint{0};
    glm::ivec3 core_footprint_of{0};
    int composite_stars = 1;      // this frame's full-screen composite's stars: 0 none (or as points), 1 computed
    float star_guard = 0.0f;      // > 0: the stars drawn as points (star_points.vert) with this guard band (pixels)
    float max_point_size = 0.0f;  // GL_POINT_SIZE_RANGE's upper end (0: not asked yet)
    bool composite_dither = true;
    bool composite_overlays = true;  // Settings::composite_overlays
    bool display_upsample = true;    // Settings::display_upsample
    bool composite_display = false;  // this frame's composite upsamples display_target (composite.frag's DISPLAY)
    bool display_written = false;    // this frame's glare wrote display_target beside its finest sum (pass_glare.cpp)
    GLuint glare_display_fbo = 0;    // the glare's finest sum and the display values at once
    float core_min_width_px = 1.5f;  // the bolt pass's Settings::bolt_min_width_px (the core's overlay)
    // The cells of the stars' cube map that may hold a star (star_points.vert's vertices), made
    // at the first frame that draws the stars as points; star_cell_count of them.
    detail::Buffer star_cells;
    int star_cell_count = 0;
    int out_w = 0, out_h = 0;

    // ----------------------------------------------------------------------------------
    GLuint program(const std::string& key, const std::vector<detail::Stage>& stages, const std::string& defines = {}) {
        const std::string full = key + "|" + defines;
        if (auto it = programs.find(full); it != programs.end()) return it->second;
        const GLuint p = detail::build_program(shader_dir, stages, ground_look_defines() + defines);
        programs[full] = p;
        ++programs_built;
        return p;
    }

    /// GroundLook's constants for background.glsl, in every program.
    static std::string ground_look_defines() {
        using G = GroundLook;
        const auto num = [](double v) {  // a float literal, whole numbers included
            const std::string t = core::format_number(v, 9);
            return t.find_first_of(".e") == std::string::npos ? t + ".0" : t;
        };
        return "#define GROUND_CELL_M " + num(G::cell_m) + "\n#define GROUND_SEED " + std::to_string(G::seed) + "u" +
               "\n#define GROUND_LOW " + num(G::low) + "\n#define GROUND_SPAN " + num(G::span) +
               "\n#define GROUND_TINT vec3(" + num(G::tint_rgb[0]) + ", " + num(G::tint_rgb[1]) + ", " +
               num(G::tint_rgb[2]) + ")\n#define GROUND_HAZE_M " + num(G::haze_m) + "\n";
    }

    /// The march's switches; `rain_lights` >= 0 (with `rain`): the number of the rain's flash
    /// lights the march reads (volume.glsl's RAIN_LIGHTS; < 0: not stated, as in the temporal key);
    /// `ground_lights` >= 0: the ground's point lights and whether the cloud's scattered light on
    /// the ground is bound, each compiled away when absent (background.glsl's GROUND_LIGHTS 0,
    /// GROUND_SCATTER 0; < 0: not stated); `ground_rain_map`: the ground reads its lights' rain
    /// transmittance from the map (GROUND_RAIN_MAP 1).
    static std::string march_defines(bool skip, bool early, bool source, bool emission, bool statics = false,
                                     bool sun = false, bool detail = false, bool rain = false, int rain_lights = -1,
                                     int ground_lights = -1, bool ground_scattered = false,
                                     bool ground_rain_map = false, bool rain_source = false) {
        std::string d = std::string("#define SKIP_EMPTY ") + (skip ? "1" : "0") + "\n#define EARLY_EXIT " +
                        (early ? "1" : "0") + "\n#define HAS_SOURCE " + (source ? "1" : "0") +
                        "\n#define HAS_EMISSION " + (emission ? "1" : "0") + "\n";
        if (statics) d += "#define HAS_STATIC 1\n";
        if (sun) d += "#define HAS_SUN 1\n";
        if (detail) d += "#define HAS_DETAIL 1\n";
        if (rain) d += "#define HAS_RAIN 1\n";
        if (rain && rain_lights >= 0) d += "#define RAIN_LIGHTS " + std::to_string(rain_lights) + "\n";
        if (rain && rain_source) d += "#define HAS_RAIN_SOURCE 1\n";
        if (ground_lights == 0) d += "#define GROUND_LIGHTS 0\n";
        if (ground_lights >= 0 && !ground_scattered) d += "#define GROUND_SCATTER 0\n";
        if (ground_rain_map) d += "#define GROUND_RAIN_MAP 1\n";
        return d;
    }

    /// march_defines for this frame's march (march.frag, march_groups.frag): its switches as
    /// the settings and the frame set them, with the ground's lights and scattered light as
    /// the frame block holds them.
    static std::string frame_march_defines(const Settings& st, const detail::FrameUniforms& u) {
        return march_defines(st.skip_empty, st.early_exit, u.lit, u.glow, u.statics, u.sun, u.detail, u.rain,
                             u.rain_lights, int(u.block.ground_params.w), u.block.ground_scatter.z > 0.0f,
                             u.ground_rain_map, u.rain_source);
    }

    /// frame_march_defines for the temporal history's march (march_groups.frag).
    static std::string temporal_march_defines(const Settings& st, const detail::FrameUniforms& u) {
        return frame_march_defines(st, u) + "#define TEMPORAL 1\n";
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
        composite_program(0, Overlay::None, true, 1);
        program("glare_first", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "glare_first.frag"}});
        program("glare_down", {{GL_VERTEX_SHADER, "fullscreen.vert"}, {GL_FRAGMENT_SHADER, "glare_down.frag"}});
        march_program(MarchKernel::Fragment, march_defines(true, true, true, true));
    }

    void release_programs() {
        for (auto& [k, p] : programs) glDeleteProgram(p);
        programs.clear();
    }

    // ---- the view's needed directions (pass_resolve.cpp)
    /// Lighting nodes near non-empty density (all nodes without a volume), cached per grid.
    const std::vector<std::uint8_t>& active_mask(const core::GridGeometry& lg) const;
    /// The directions the view from `cam` needs, cached per camera, grid, count and threshold.
    const std::vector<DirectionUse>& needed_for(const glm::dvec3& cam, const core::GridGeometry& lg, int count,
                                                double min_weight) const;

    // ---- the glow's quads and radial profile (pass_glow.cpp)
    void rebuild_glow_quads(double radius);
    void rebuild_profile(double radius, double sigma);

    // ---- the ground lights (frame_setup.cpp)
    double vertical_transmittance(const glm::dvec3& p, double ground) const;
    void rebuild_ground_lights(int k, double ground);

    // ---- one frame: uniforms, then the passes in the order they run (renderer.cpp)
    FrameStats run_frame(const Camera& camera, const Settings& st, int width, int height, const HostFrame* host);
    // ---- a host's depth buffer (host.cpp): its projection into the uniforms, its texture on unit 8
    GLuint host_sampler = 0;
    void attach_host_depth(const HostFrame& host, detail::FrameUniforms& u);
    void detach_host_depth();
    detail::FrameUniforms prepare_frame(const Camera& camera, const Settings& st, int width, int height);
    void bind_frame(const detail::FrameUniforms& u);
    GLuint resolve_set(detail::SourceSet& set, const glm::dvec3& camera, const std::vector<int>& active,
                       bool must_resolve, detail::PassTimer& timer);
    /// `resolve` false: S toward the camera is not needed this frame (a reused history); the
    /// textures are bound, S stays to be resolved.
    void resolve_pass(const glm::dvec3& camera, const Settings& st, const detail::FrameUniforms& u,
                      detail::PassTimer& timer, FrameStats& stats, bool resolve = true);
    /// `draw` false: the glow is not needed this frame (a reused history holds it). With a
    /// temporal plan that marches a grid of the pixels, only those are drawn (glow_grid_target).
    void glow_pass(const Settings& st, const detail::FrameUniforms& u, detail::PassTimer& timer, FrameStats& stats,
                   bool draw = true, const detail::TemporalPlan* plan = nullptr);
    void march_pass(const Settings& st, const detail::FrameUniforms& u, detail::PassTimer& timer);
    /// The ground lights' rain transmittance map (FrameUniforms::ground_rain_map), made when the
    /// lights, the ground or the rain changed, bound on unit 12 for the march; the march's timer slot.
    void ground_rain_pass(const detail::FrameUniforms& u);
    /// Whether the ground lights moved since the previous frame and the map is not theirs
    /// (pass_ground_rain.cpp): a frame marching a fraction of its pixels then integrates their
    /// paths per pixel instead of making the map. Notes this frame's lights for the next.
    bool ground_lights_moving(const detail::FrameUniforms& u);
    /// The rain's mean extinction toward the rain's lights at each voxel with rain, in the density
    /// texture's alpha (volume.glsl's rain_flash reads it: FrameUniforms::rain_lights > 0), made
    /// when the lights, the volume or the rain changed.
    void rain_lights_pass(const detail::FrameUniforms& u);
    /// With the temporal history (Settings::temporal): what this frame does with it (before the
    /// resolve and glow passes, which a reused history skips), and the march in place of march_pass.
    detail::TemporalPlan plan_temporal(const Camera& camera, const Settings& st, const detail::FrameUniforms& u) const;
    void temporal_march_pass(const Camera& camera, detail::TemporalPlan plan, const detail::FrameUniforms& u,
                             detail::PassTimer& timer, FrameStats& stats);
    void meter_pass(const Settings& st, const detail::FrameUniforms& u, detail::PassTimer& timer, FrameStats& stats);
    void bolt_pass(const Settings& st, const detail::FrameUniforms& u, detail::PassTimer& timer, FrameStats& stats);
    /// What a still camera's kept channel light (its core, pass_bolt.cpp; the glare's light
    /// groups, pass_glare.cpp) depends on besides the channel's intensity: the history, the
    /// output size, the channel's segments and minimum width, the flash colour.
    std::vector<double> kept_channel_key(const Settings& st, const detail::FrameUniforms& u) const;
    /// The key of the glare's light groups for this frame (pass_glare.cpp), empty when the frame
    /// draws no glare.
    std::vector<double> glare_groups_key_of(const Camera& camera, const Settings& st,
                                            const detail::FrameUniforms& u) const;
    /// The glare's light groups were made for this frame's history and view.
    bool glare_groups_ready(const Camera& camera, const Settings& st, const detail::FrameUniforms& u) const {
        const std::vector<double> key = glare_groups_key_of(camera, st, u);
        return !key.empty() && key == glare_groups_key;
    }
    void glare_pass(const Camera& camera, const Settings& st, const detail::FrameUniforms& u, detail::PassTimer& timer,
                    FrameStats& stats);
    void composite_pass(const detail::FrameUniforms& u, const detail::CallerTarget& caller, detail::PassTimer& timer);
    /// The march's frame (with the glare when it ran) tone mapped at its own resolution into
    /// display_target (display.frag), for the composite to upsample.
    void display_pass(const detail::FrameUniforms& u);
    /// Whether this frame's composite upsamples display values (Settings::display_upsample):
    /// where the march is smaller than the output, and not into a host's frame (radiance, blended).
    bool wants_display(const detail::FrameUniforms& u) const {
        return display_upsample && !u.host && (u.internal_width != out_w || u.internal_height != out_h);
    }
    /// The stars for this frame's composite: drawn as points over it (`points`, when the view's
    /// spots fit GL's largest point) or computed at every pixel of it.
    void prepare_stars(const detail::FrameUniforms& u, bool stars, bool points);
    /// The composite with this frame's switches into the bound framebuffer: the full-screen
    /// pass, then the core's ribbons and the stars' points when they are drawn as overlays.
    void draw_composite(int output);
    /// The composite's program for `output` (composite.frag's OUTPUT: 0 tone mapped, 1 radiance,
    /// 2 a host's frame) with this frame's glare and dither: over the whole frame, or
    /// (`overlay`) as the core's ribbons or the stars' points, with its core and stars switches
    /// (composite.frag's CORE, STARS).
    enum class Overlay { None, Core, Stars };
    GLuint composite_program(int output, Overlay overlay, bool core, int stars);
    /// Binds what composite.frag reads (march, core, glare) to program `p`.
    void bind_composite_inputs(GLuint p) const;
    /// Binds the frame's radiance at the march's resolution, as composite.frag and display.frag
    /// read it: the march on unit 3, the glare's sum (the march without glare) on unit 5.
    void bind_frame_radiance() const;
};

}  // namespace fulgur::render
