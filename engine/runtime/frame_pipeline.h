// fulgur::runtime — one storm frame at time t: schedule -> bolt -> sources -> splat ->
// reconstruct, with the strikes' own solved light where a preset asks for it.
#pragma once

#include "core/core.h"
#include "lightning/lightning.h"
#include "runtime/instant_strikes.h"
#include "runtime/reconstructor.h"
#include "runtime/strike_solver.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace fulgur::runtime {

/// `field` (some of the baked directions) as a field of every baked direction, the others 0:
/// what a renderer or a comparison with the truth (Truth::sum) reads.
transport::SourceField every_direction(const RadianceField& field);

/// One frame's lightning state and radiance.
struct Frame {
    double time = 0.0;
    /// Some virtual light is active (a flash glows at t with non-zero intensity): radiance
    /// is valid. When false, radiance holds stale buffers and must not be shown.
    bool lit = false;
    std::vector<lightning::LitSegment> segments;  ///< for the renderer's bolt and glow
    std::vector<transport::PointSource> sources;
    lightning::LightWeights weights;
    RadianceField radiance;
    /// Quality that keeps solved strikes on the transport grid (scene::Quality::
    /// keep_transport_grid): the same frame's S on that grid, for the renderer: `radiance`'s
    /// bases, leaders and unsolved strikes trilinearly upsampled (what the renderer would
    /// sample of them), plus the solved strikes' own light at the transport grid's resolution.
    /// Same directions as `radiance`. Empty (no values) otherwise; valid when `lit`.
    /// `radiance` stays on the lighting grid, where the truth is tallied.
    RadianceField fine;
    /// The light the cloud scatters onto the ground at this instant (W/m^2): the solved strikes'
    /// ground tallies (StrikeLight::ground) scaled by their glow, as their S is. Empty when no
    /// strike lighting the frame carries one (the bases' frames, hybrid, no ground).
    transport::GroundIrradiance ground;
    /// A scene with rain, under a preset that solves its strikes (not the paper preset, not the
    /// hybrid's strokes): the light of orders >= 2 the strikes' solves hold at the rain's
    /// points, per unit albedo (S / the cloud's albedo), scaled by their glow. Their media hold
    /// the rain (sky::make_static_media), so it is the flash-lit cloud's light sent down into
    /// the rain and the rain's own multiple scattering, read out with the drops' phase function
    /// by each cell's share of rain. A strike lit the instant way contributes its estimates'
    /// light weighed against none (the bases carry no light at the rain:
    /// StrikeEstimate::rain_weight), not their share of the cloud's; nothing before its first
    /// estimate. The renderer's rain scatters it by the rain's albedo and draws the
    /// channel's own light (its first order, attenuated by the rain on its way) from the
    /// channel itself.
    /// On the lighting grid, the directions of `radiance`; empty (no values) otherwise.
    RadianceField rain;
    StageTimes times;
    /// Presets that solve strikes: active strikes whose own solve lit this frame, and those
    /// shown by the bases because their solve was not ready (0 and 0 for the paper preset).
    std::size_t strikes_solved = 0, strikes_fallback = 0;
    /// Of strikes_solved, those lit the instant way (the instant preset's, and unscheduled
    /// strikes under the presets that solve ahead): their estimates are paths that carry the
    /// rain's drops at their own extinction, whatever the preset's own solves carry.
    std::size_t strikes_instant = 0;
    /// The instant preset: the smallest weight any active strike's own estimate had against the
    /// bases in this frame (StrikeEstimate::weight, cross-fades included; 1 for other presets).
    double instant_weight = 1.0;
};

class StrikeSolver;

/// Drives a storm over a baked scene: schedule -> bolt -> sources -> splat -> reconstruct.
class FramePipeline {
public:
    /// Keeps references to `scene`, `density` (bolt start points) and `bases`; they must
    /// outlive it.
    /// `domain`: the bolts' box (lightning::BoltGenerator; default: the density's box down
    /// to the ground). `quality`: how frames are lit (default: the scene's); presets other
    /// than paper solve strikes on a worker thread (StrikeSolver) ahead of their frames, the
    /// instant preset from the moment they are known (InstantStrikes), blended with the
    /// bases by their estimated errors and cross-faded (quality.max_change_per_frame per build).
    FramePipeline(const scene::Scene& scene, const core::Grid3<float>& density, const BakedBases& bases,
                  std::optional<lightning::Box> domain = {}, std::optional<scene::Quality> quality = {});
    ~FramePipeline();
    /// Schedules a strike at time t; returns its index. `known_ahead` false: nobody knew it
    /// was coming (a game event, the demo's "Strike now"): under a preset that solves strikes
    /// ahead of their frames (hybrid, per_strike, per_strike_mc) it is lit the instant
    /// preset's way (InstantStrikes, traced from this call on, not from the first frame that
    /// lights it), since its own solve would be ready only most of a flash later. The paper
    /// preset lights every strike alike.
    std::size_t strike_at(double t, std::optional<std::uint64_t> seed = {}, bool known_ahead = true);
    /// Builds the frame at time t for the requested directions (all when empty). A dark
    /// frame (no strike glows at t) costs the strike lookup only: no sources, no splat, no
    /// reconstruction. The returned frame is valid until the next build().
    const Frame& build(double t, std::span<const int> directions, const ReconstructOptions& options = {});
    lightning::Storm& storm() noexcept;
    const scene::Quality& quality() const noexcept;
    /// Another preset: the strike solver is rebuilt (solved strikes are dropped); the storm,
    /// its strikes and the bases stay.
    void set_quality(const scene::Quality& q);
    /// The strike solver (null for the paper and instant presets).
    StrikeSolver* strike_solver() noexcept;
    /// The progressive strike solver (the instant preset, or unscheduled strikes under a preset
    /// that solves ahead; else null).
    InstantStrikes* instant_strikes() noexcept;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// What build_since_known() saw while the strike's light was being solved.
struct SinceKnown {
    int frames = 0;                ///< builds before the one returned (at 60 fps)
    double median_frame_ms = 0.0;  ///< their median StageTimes::total(), the frame thread's cost
    double max_frame_ms = 0.0;
};

/// The frame at storm time t as a strike nobody scheduled shows it `since_known_ms` of wall
/// time after it became known: `pipeline` (fresh: never built, its quality's lookahead 0, so
/// the strike becomes known at the first build that lights it) is built at t once, then at
/// 60 fps (sleeping in between, as a frame loop would) until since_known_ms have passed, and
/// once more; that last frame is returned (valid until the next build). The per-strike work
/// runs meanwhile on its worker; what is not ready by then is not shown. `seen` (optional)
/// gets the frames' cost.
/// With `storm_time_runs`, the frames before the last are built at the storm time of their
/// slot, t - since_known_ms + slot (a frame loop whose storm clock runs with the wall clock)
/// instead of at t: with since_known_ms = t minus the strike's time, the strike is triggered
/// at its leader's start and frame t is what the loop shows when the flash reaches t.
const Frame& build_since_known(FramePipeline& pipeline, double t, double since_known_ms,
                               std::span<const int> directions, const ReconstructOptions& options = {},
                               SinceKnown* seen = nullptr, bool storm_time_runs = false);

}  // namespace fulgur::runtime
