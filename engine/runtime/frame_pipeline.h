// fulgur::runtime — one storm frame at time t: schedule -> bolt -> sources -> splat ->
// reconstruct, with the strikes' own solved light where a preset asks for it.
#pragma once

#include "core/core.h"
#include "lightning/lightning.h"
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
    StageTimes times;
    /// Presets that solve strikes: active strikes whose own solve lit this frame, and those
    /// shown by the bases because their solve was not ready (0 and 0 for the paper preset).
    std::size_t strikes_solved = 0, strikes_fallback = 0;
};

class StrikeSolver;

/// Drives a storm over a baked scene: schedule -> bolt -> sources -> splat -> reconstruct.
class FramePipeline {
public:
    /// Keeps references to `scene`, `density` (bolt start points) and `bases`; they must
    /// outlive it.
    /// `domain`: the bolts' box (lightning::BoltGenerator; default: the density's box down
    /// to the ground). `quality`: how frames are lit (default: the scene's); presets other
    /// than paper solve strikes on a worker thread (StrikeSolver) ahead of their frames.
    FramePipeline(const scene::Scene& scene, const core::Grid3<float>& density, const BakedBases& bases,
                  std::optional<lightning::Box> domain = {}, std::optional<scene::Quality> quality = {});
    ~FramePipeline();
    /// Schedules a strike at time t (demo "strike now"); returns its index.
    std::size_t strike_at(double t, std::optional<std::uint64_t> seed = {});
    /// Builds the frame at time t for the requested directions (all when empty). A dark
    /// frame (no strike glows at t) costs the strike lookup only: no sources, no splat, no
    /// reconstruction. The returned frame is valid until the next build().
    const Frame& build(double t, std::span<const int> directions, const ReconstructOptions& options = {});
    lightning::Storm& storm() noexcept;
    const scene::Quality& quality() const noexcept;
    /// Another preset: the strike solver is rebuilt (solved strikes are dropped); the storm,
    /// its strikes and the bases stay.
    void set_quality(const scene::Quality& q);
    /// The strike solver (null for the paper preset).
    StrikeSolver* strike_solver() noexcept;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace fulgur::runtime
