// fulgur::view — one storm frame from a scene: scene + baked bases -> runtime::FramePipeline
// -> render::Renderer, in whatever GL context is current (as Filament's View: library code
// the apps drive). Shared by `fulgur` (demo), `fulgur-shot` and the golden-image tests.
// Also: finding (or baking) the scene's .fgb, the default camera, the direct solve of a frame
// as its reference. The scene's static light (sun or moon, sky: engine/sky) is its own term
// with its own colour, composed beside the lightning's; a scene without lightning has no
// .fgb and no pipeline at all.
#pragma once

#include "bake/bake.h"
#include "render/render.h"
#include "runtime/runtime.h"
#include "scene/scene.h"
#include "sky/ground.h"
#include "sky/sky.h"

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace fulgur::view {

/// The scene's .fgb: `explicit_fgb` when given (must exist), else bake::default_fgb_path,
/// baked first when missing or stale (bake::bake_if_stale). `on_bake(fgb, why)` is told
/// before such a bake starts, `progress` follows it.
std::filesystem::path ensure_baked(
    const scene::Scene& s, const core::Grid3<float>& density, const std::optional<std::filesystem::path>& explicit_fgb,
    const bake::Progress& progress = {},
    const std::function<void(const std::filesystem::path& fgb, const std::string& why)>& on_bake = {});

/// The .fgb a scene's frames use: ensure_baked when its plan bakes virtual lights; none when
/// it has no lightning (an explicit `explicit_fgb` is then an error naming it).
std::optional<std::filesystem::path> bases_for(
    const sky::ScenePlan& plan, const scene::Scene& s, const core::Grid3<float>& density,
    const std::optional<std::filesystem::path>& explicit_fgb, const bake::Progress& progress = {},
    const std::function<void(const std::filesystem::path& fgb, const std::string& why)>& on_bake = {});

/// A camera framing the scene's cloud from the side, slightly below its centre.
render::Camera default_camera(const core::Grid3<float>& density, double azimuth_deg = -90.0, double elevation_deg = 6.0,
                              double distance_factor = 1.1);

/// The scene's camera (its "camera" section, fulgur-shot's or the demo's --camera): an orbit's
/// unset target and distance are default_camera's; no camera at all is default_camera().
render::Camera scene_camera(const std::optional<scene::CameraSpec>& spec, const core::Grid3<float>& density);
/// The same camera as an orbit with every part explicit (target, distance, azimuth,
/// elevation): what the demo turns with the mouse and prints. A look-at camera becomes the
/// orbit around its target through its position (its `up` is dropped: an orbit's is +z).
scene::CameraSpec explicit_orbit(const std::optional<scene::CameraSpec>& spec, const core::Grid3<float>& density);

struct ViewOptions {
    /// Automatic exposure (render::Settings::auto_exposure); the manual exposure, when it is
    /// switched off, is 2^-3: the default storm's return-stroke peak (1e5 W/sr/m) then fills
    /// the tone map's shoulder (calibrated by eye on fulgur-shot frames).
    ViewOptions() {
        settings.auto_exposure = true;
        settings.exposure = 0.125;
        settings.glare = true;  // where the scene calls for it (effects.glare) and a channel is drawn
    }
    runtime::Components components;
    /// Run-time switches of the static light (the scene's effects must call for it too): off
    /// costs nothing per frame (no resolve, no texture fetch in the march).
    bool sun = true, sky = true;
    /// The sun's single scattering at full resolution (the silver lining); false: on the
    /// lighting grid with the rest of the static light.
    bool sun_full_resolution = true;
    render::Settings settings;  ///< bolt/glow/ground/exposure/internal scale (and the scene's effects)
    /// Radius (m) of the drawn lightning channel, the same for every lit segment
    /// (render::ChannelSegment::radius: the core radiance is intensity / (2 radius)). > 0.
    double bolt_radius = 2.0;
    /// Presets that solve strikes: wait for each active strike's solve (offline frames)
    /// instead of showing the bases until it is ready.
    bool wait_for_strikes = false;
};

struct FrameReport {
    runtime::StageTimes stages;  ///< CPU side: bolt, sources, splat, accumulate, inverse Haar
    render::FrameStats gpu;      ///< upload, ray march, ... (wall and CPU)
    bool lit = false;
    double wall_ms = 0.0;  ///< the whole frame: reconstruction + upload + render
};

/// How a view gets its static light, and its renderer's shaders.
struct StaticSetup {
    /// The renderer's shaders (empty: render::default_shader_dir()); an installed engine's
    /// users pass the package's Fulgur_SHADER_DIR.
    std::filesystem::path shader_dir;
    sky::CacheOptions cache;                      ///< where the sun's and the sky's solves are cached
    std::function<void(const std::string&)> say;  ///< told what is read or solved
    std::optional<sky::ScenePlan> plan;           ///< the scene's plan when already made (else made here)
    /// For a scene with sub-voxel detail: its density before the detail
    /// (scene::make_undetailed_density), which the renderer erodes per sample; when null it is
    /// generated or loaded again here. Only read during construction.
    const core::Grid3<float>* undetailed_density = nullptr;
};

/// Owns density, bases, pipeline and renderer for one scene.
class StormView {
public:
    /// `fgb`: the scene's bases (bases_for); none for a scene without lightning. The static
    /// light the plan calls for is read from its cache or solved here (seconds). `density` is
    /// scene::make_density's (with the detail's voxel means when the scene has detail).
    StormView(scene::Scene s, core::Grid3<float> density, const std::optional<std::filesystem::path>& fgb,
              render::GetProcAddress gl, const StaticSetup& setup = {});
    StormView(const StormView&) = delete;  // the pipeline refers to the members
    StormView& operator=(const StormView&) = delete;
    /// Builds the frame at time t and renders it into the bound framebuffer. With `source`
    /// (a field on the bases' lighting grid with all their directions, e.g. solve_direct's),
    /// the cloud is lit by that field instead of the reconstruction: the bolt, glow and
    /// ground still come from the frame at t, so two renders differ only in S. With `source`,
    /// `rain_source` (the same layout) is the flash's light of orders >= 2 at the rain per unit
    /// albedo (runtime::Frame::rain's, e.g. TruthSolve::rain); null or empty (no data): the
    /// channel alone lights the rain.
    FrameReport render(const render::Camera& camera, double t, int width, int height, const ViewOptions& options,
                       const transport::SourceField* source = nullptr,
                       const transport::SourceField* rain_source = nullptr);
    /// Compiles the renderer's programs a storm's frames will ask for, so that the first flash,
    /// the first camera move and the first leader do not stall the frames that show them (a
    /// software rasterizer compiles a program at its first draw: ~0.2-0.5 s a program without
    /// Mesa's shader cache). Renders a short sequence at a quarter of `width` x `height` (at
    /// least 64 pixels wide) into the bound framebuffer with `options`' settings and the fill a
    /// moving camera gets at the full size: the static light still and orbiting, then a
    /// synthetic flash (a vertical channel from the cloud's middle to the ground, S uniform)
    /// appearing, dimming, changing in shape, with the camera still and orbiting, with and
    /// without the cloud's scattered light on the ground. The channel and S are cleared after:
    /// the next render() shows its own, and the temporal history is forgotten
    /// (render::Renderer::reset_history): the frames after it are those a new view draws.
    /// Returns the wall time (ms).
    double warm_up(const render::Camera& camera, int width, int height, const ViewOptions& options);
    /// The frame at time t composited into a host engine's HDR target (bound as the draw
    /// framebuffer) with the host's camera and depth (render::Renderer::render_into_host): the
    /// storm's radiance before exposure over the host's, which keeps its own world, tone map
    /// and glare. The ground-lighting model is the host's: flash_lights() gives the flash as
    /// point lights for it, and last_frame()->ground the light the cloud scatters onto the
    /// ground (irradiance on cells of the ground plane, at this frame's glow; empty unless the
    /// preset traces the strike's paths).
    FrameReport render_into_host(const render::HostFrame& host, double t, int width, int height,
                                 const ViewOptions& options);
    /// The flash at time t as `k` representative point lights (render::Renderer::flash_lights:
    /// W/sr, grey, times scene().lightning_colour; dimmed straight down to the scene's ground),
    /// for a host lighting its own surfaces before it composites the storm; empty when no
    /// strike glows at t or the scene has no lightning. Sets the renderer's channel to t's.
    std::vector<render::Renderer::FlashLight> flash_lights(double t, int k, const ViewOptions& options = {});
    /// The renderer's settings render() uses with `options`: the scene's ground height, flash
    /// colour and sky, and the effects the scene switched off taken out.
    render::Settings frame_settings(const ViewOptions& options) const;

    /// The reference of the frame at time t (runtime::direct_solve of the frame's point
    /// sources: exact single scattering + the scene's solver, no virtual lights, no basis),
    /// all directions, on the lighting grid. Seconds to minutes: not for interactive frames.
    /// Also times the basis method on the same frame for all directions (median of 5
    /// builds: one build is at the mercy of page faults and the scheduler), so the two
    /// times compare like with like. last_frame() is then that all-direction frame.
    struct DirectSolve {
        transport::SourceField field;
        double seconds = 0.0;   ///< wall time of the direct solve
        double basis_ms = 0.0;  ///< the basis frame, all directions, median of 5
    };
    DirectSolve solve_direct(double t, const runtime::Components& components, bool wait_for_strikes = true);
    /// The truth of the frame at time t (runtime::truth: Monte Carlo of the frame's lit
    /// channel through the full-resolution density), the requested components summed, all
    /// directions; times the frame like solve_direct. `noise` is the truth's own estimate.
    struct TruthSolve {
        transport::SourceField field;
        /// With rain and the multiple component: the truth's multiple S over the cloud's albedo,
        /// the light of orders >= 2 at the rain as runtime::Frame::rain holds it (render()'s
        /// rain_source); empty otherwise.
        transport::SourceField rain;
        transport::MonteCarloResult::Noise noise;
        double seconds = 0.0, basis_ms = 0.0;
    };
    /// `wait_for_strikes` false: the basis frame is timed with what the strike solvers have
    /// (a caller that stopped them to show a frame as it was at some moment). The truth is
    /// tallied toward the point the pipeline's strikes are (scene::strike_toward), whatever
    /// options.toward says: like is checked against like.
    TruthSolve solve_truth(double t, const runtime::Components& components, const runtime::TruthOptions& options = {},
                           bool wait_for_strikes = true);
    /// The media the direct solve runs in (solve::make_media: the lighting grid and the transport grid).
    const solve::Media& media();
    /// The media the static light (sun, moon, sky) is solved in (sky::static_media: its own
    /// transport.static_light refinement and exact orders).
    const solve::Media& static_media();
    /// Relative L2 of the last frame's reconstruction against `reference` (a field like
    /// solve_direct's) over cloud voxels (lighting-grid density > 0), every direction the
    /// frame holds (after solve_direct: all). 0 when the last frame is dark.
    double reconstruction_error(const transport::SourceField& reference);

    /// New lightning parameters (bolt shape, schedule, seed): rebuilds the pipeline's storm,
    /// so bolts are regenerated; the bake is unchanged (it does not depend on them).
    void set_lightning(const lightning::LightningParams& p);
    /// Another quality preset (scene::Quality): the pipeline's strike solver changes; the
    /// storm and its strikes stay (the bake is shared).
    void set_quality(const scene::Quality& q);

    /// The sun's irradiance and colour from now on (no new solve); its direction is the last
    /// solve's until set_sun_solve() gives one for the new direction (the old field is shown
    /// until then). Needs a scene whose plan solves a sun.
    void set_sun(const scene::Sun& sun);
    /// A sun solved for a new direction (sky::SunResolver, sky::solve_sun).
    void set_sun_solve(sky::SunSolve&& solve);
    /// The direction the shown sun field was solved for.
    const glm::dvec3& sun_solved_direction() const noexcept { return static_.sun_direction; }
    /// The static light shown: the scene's solves (load_or_solve, set_sun_solve) or what
    /// set_static_light() gave.
    const sky::StaticLight& static_light() const noexcept { return static_; }
    /// The sun's irradiance and colour shown (set_sun; the scene's at first); none without a sun.
    const std::optional<scene::Sun>& shown_sun() const noexcept { return sun_; }
    /// Shows `light` as the static light from now on, e.g. its truth for a reference frame (the
    /// sun's full-resolution order 1 is unchanged: it is exact). It must hold what the plan
    /// solves, for the shown sun's direction; core::Error otherwise.
    void set_static_light(sky::StaticLight light);
    /// The truth of the static light shown (sky::static_truth: Monte Carlo of the sun along the
    /// shown direction and of the whole dome through the full-resolution density). Seconds to
    /// minutes. core::Error when the scene has no sun and no sky.
    struct StaticTruthSolve {
        sky::StaticLight light;
        std::vector<transport::MonteCarloResult::Noise> noise;  ///< sky::static_truth's
        double seconds = 0.0;
    };
    StaticTruthSolve solve_static_truth(const sky::TruthOptions& options = {});
    /// The static light in colour on the lighting grid (sky::compose with the shown sun and the
    /// scene's sky), every direction: `light` (default: the shown one) with `options`.
    sky::ColourField static_colour(const sky::ComposeOptions& options, const sky::StaticLight* light = nullptr) const;

    /// A scene without lightning has no bases and no pipeline: has_lightning() is false and
    /// pipeline() / bases() must not be called.
    bool has_lightning() const noexcept { return pipeline_ != nullptr; }
    runtime::FramePipeline& pipeline() noexcept { return *pipeline_; }
    render::Renderer& renderer() noexcept { return *renderer_; }
    const runtime::BakedBases& bases() const noexcept { return *bases_; }
    const sky::ScenePlan& plan() const noexcept { return plan_; }
    const scene::Scene& scene() const noexcept { return scene_; }
    const core::Grid3<float>& density() const noexcept { return density_; }
    /// The scene's rain as the renderer draws it (null: the scene has none).
    const cloud::RainField* rain() const noexcept { return rain_ ? &*rain_ : nullptr; }
    const runtime::Frame* last_frame() const noexcept { return last_; }

private:
    /// Builds the all-direction frame at t 5 times (waiting for strike solves); its median ms.
    double time_all_directions(double t, const runtime::Components& components, bool wait_for_strikes);
    void check_field(const transport::SourceField& f, const char* where) const;  // throws core::Error
    void update_static_light(const ViewOptions& options);                        // uploads what changed
    void render_lightning(const render::Camera& camera, double t, const ViewOptions& options,
                          const transport::SourceField* source, const transport::SourceField* rain_source,
                          FrameReport& rep);
    /// The frame at t into the renderer: its lightning (or none) and the static light.
    void upload_frame(const render::Camera& camera, double t, const ViewOptions& options,
                      const transport::SourceField* source, const transport::SourceField* rain_source,
                      FrameReport& rep);
    scene::Scene scene_;
    core::Grid3<float> density_;
    sky::ScenePlan plan_;
    std::optional<runtime::BakedBases> bases_;
    std::unique_ptr<runtime::FramePipeline> pipeline_;
    std::unique_ptr<render::Renderer> renderer_;
    const runtime::Frame* last_ = nullptr;
    std::optional<solve::Media> media_;         // built on first use (solve_direct)
    std::optional<solve::Media> static_media_;  // built on first use (the static light)
    // The static light: its solves, the sun's full-resolution transmittance, what is uploaded.
    sky::StaticLight static_;
    core::Grid3<float> sun_transmittance_;
    std::optional<cloud::RainField> rain_;  // the scene's rain (drawn by the renderer)
    std::optional<scene::Sun> sun_;         // irradiance and colour shown (direction: static_.sun_direction)
    struct Uploaded {
        bool valid = false, sun = false, sky = false, sun_single = false, single = false, multiple = false;
        std::uint64_t version = 0;
    } uploaded_, sun_uploaded_;
    std::uint64_t static_version_ = 1;  // bumped when the static light or the sun changes
    // The static light on the ground (sky::static_ground), for static_version_ ground_version_.
    sky::StaticGround ground_;
    std::uint64_t ground_version_ = 0;
};

/// Per-field medians of several frames' reports (lit taken from the last one).
FrameReport median_report(const std::vector<FrameReport>& reps);

}  // namespace fulgur::view
