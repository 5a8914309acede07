// fulgur::runtime — strikes lit right from the moment they are known: each strike's light
// traced by Monte Carlo a little at a time on a worker thread and published as it improves,
// with the error of the bases' frame estimated against it, so a frame can blend the two by
// their errors (the `instant` preset, docs/presets.md).
#pragma once

#include "core/core.h"
#include "lightning/lightning.h"
#include "runtime/baked_bases.h"
#include "runtime/near_field.h"
#include "runtime/strike_solver.h"
#include "scene/scene.h"
#include "solve/solve.h"

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

namespace fulgur::runtime {

/// A strike's light as far as its progressive solve has got: StrikeLight's fields (per
/// group, at unit glow), what they cost and how far they are from converged.
struct StrikeEstimate {
    StrikeLight light;  ///< light.noise: single, multiple and total relative L2 noise over the cloud
    /// Relative L2 error of the bases' S for the same strokes (the paper frame) over the cloud,
    /// estimated against this estimate with its own noise taken out; < 0: unknown (no bases).
    double bases_error = -1.0;
    /// The strokes at unit glow in both groups, single + multiple ([m][cell], every
    /// direction), and the bases' frame of the same (null: no bases): what a frame measures the
    /// change of its shown light with (FramePipeline's cross-fade).
    std::vector<float> total;
    std::shared_ptr<const std::vector<float>> bases;  ///< with the near-field correction, if any
    /// The same bases' frame per group ([0] the main channel, [1] the branches; empty: the
    /// group lights nothing), reconstructed with the default ReconstructOptions (both
    /// components, no ambient term): a frame adds its bases' share of the strokes from these
    /// instead of reconstructing them every build (null: no bases).
    std::shared_ptr<const std::array<std::vector<float>, 2>> bases_groups;
    std::uint64_t single_paths = 0, multiple_paths = 0;
    double worker_seconds = 0.0;  ///< wall time the worker spent tracing this strike so far
    double since_request = 0.0;   ///< wall time from the request to this estimate, seconds
    int round = 0;                ///< 1 for the first estimate
    bool final = false;           ///< the solve has stopped (target noise or path caps reached)
    /// How much of the strokes' light a frame takes from this estimate rather than the bases:
    /// inverse-variance weights, e_b^2 / (e_b^2 + noise^2); 1 when the bases' error is unknown
    /// or the bases' share would be under 1%.
    double weight() const noexcept;
    /// The same weight where the bases carry no light at all (the rain's points: their error
    /// is 100% there), 1 / (1 + noise^2), the estimate's noise over the cloud standing for its
    /// noise there; 1 when the bases' share would be under 1%.
    double rain_weight() const noexcept;
};

/// How the progressive solves run (instant_options: from a quality preset).
struct InstantOptions {
    std::uint64_t max_single_paths = 1'000'000, max_multiple_paths = 1'000'000;
    double target_noise = 0.02;  ///< a strike stops once its total noise is at most this
    /// The first round's paths: they set the first estimate's latency (docs/presets.md gives
    /// it for the default storm on 2 cores).
    std::uint64_t first_single_paths = 800, first_multiple_paths = 200;
    /// Later rounds take max(round_seconds, growth x the time spent so far): estimates at
    /// roughly geometric intervals, so publishing stays a small share of the work.
    double round_seconds = 0.015, growth = 0.5;
    std::uint64_t seed = 1;
    /// Rays per point of the near-field correction added to the bases' frame of the strokes
    /// (runtime::NearField); 0: none.
    int near_field_rays = 0;
    /// The correction: the strike's own light in place of the bases' (runtime::StrikeDiffusion:
    /// its points' rays for single scattering, a flux-limited diffusion solve for multiple),
    /// else NearField's local model with its kernel.
    bool diffusion_multiple = false;
    /// With diffusion_multiple: rays per point of the single scattering cast through the
    /// full-resolution density (StrikeDiffusionOptions::fine_rays); 0: the lighting grid's.
    int fine_rays = 0;
};

/// The instant preset's options (target_noise, path caps) from a quality preset.
InstantOptions instant_options(const scene::Quality& q);

/// The options of a strike's two tracers, two groups each (the main channel, the branches):
/// [0] order 1 alone, by expected-value emissions; [1] orders >= 2 alone, by whole paths that
/// leave order 1 to the other (far cheaper there).
std::array<transport::MonteCarloOptions, 2> instant_tracer_options();

/// Traces strikes progressively on one worker thread (its parallel regions on `threads`
/// threads), the strike that has had the least time first, so a new strike's first estimate
/// comes a round after its request whatever else is converging. Thread-safe.
class InstantStrikes {
public:
    /// Keeps references to `scene`, `density`, `media` and `bases` (may be null: no bases
    /// error); they must outlive it. `media` is the cloud's (solve::make_media). With a scene
    /// with rain, `rain_media` is what the strikes are traced through
    /// (sky::make_static_media(scene, density, refine, true): it must hold the full-resolution
    /// density; kept by reference), made here when null (~0.1 s on storm-full).
    InstantStrikes(const scene::Scene& scene, const core::Grid3<float>& density, const solve::Media& media,
                   const BakedBases* bases, const InstantOptions& options, int threads,
                   const solve::Media* rain_media = nullptr);
    ~InstantStrikes();
    InstantStrikes(const InstantStrikes&) = delete;
    InstantStrikes& operator=(const InstantStrikes&) = delete;

    /// Starts tracing the strike (identified by its seed and start time; its bolt is copied).
    /// No-op when it is known already.
    void request(std::uint64_t seed, double time, const lightning::Bolt& bolt);
    /// The strike's latest estimate, else null (never another strike's).
    std::shared_ptr<const StrikeEstimate> get(std::uint64_t seed, double time) const;
    /// The near-field correction of the strike's strokes at unit glow, per group ([0] the main
    /// channel, [1] the branches; empty: the group lights nothing), part of the bases' frame
    /// every estimate carries (StrikeEstimate::bases, bases_groups).
    /// Made on the first call, on the calling thread (the frame's, for a strike's first frame)
    /// or the worker's, and kept; null when the options ask for none, there are no bases, or
    /// the strike was not requested.
    std::shared_ptr<const std::array<NearFieldParts, 2>> near_field(std::uint64_t seed, double time) const;
    /// Blocks until the strike's solve has stopped (it must have been requested); rethrows its
    /// error.
    std::shared_ptr<const StrikeEstimate> wait_final(std::uint64_t seed, double time);
    /// S's output directions, every field's [m][cell] layout.
    std::size_t directions() const noexcept;
    /// Whether the estimates' multiple S holds the flash's light at the rain: the scene has
    /// rain, and the strikes are traced through the medium the truth traces (the rain as cloud
    /// of equal transport coefficient, S at its points with the drops' phase function). The
    /// near-field correction and the bases' error stay over the cloud alone.
    bool traces_rain() const noexcept;
    /// While paused the worker starts no round and a round that ends publishes nothing: what
    /// get() returns at the pause stays (the time a caller gives the solve is exact).
    void set_paused(bool paused);
    /// Stops tracing the strike (its flash is over: more paths would light nothing); its
    /// latest estimate stays. No-op for a strike not requested.
    void stop(std::uint64_t seed, double time);
    /// Drops strikes that started before `time` (their tracing stops).
    void forget_before(double time);

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace fulgur::runtime
