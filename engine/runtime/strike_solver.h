// fulgur::runtime — per-strike light: a strike's strokes solved once (what the hybrid,
// per-strike and reference presets add to the bases), and the worker that solves strikes
// ahead of their frames.
#pragma once

#include "core/core.h"
#include "lightning/lightning.h"
#include "scene/scene.h"
#include "solve/solve.h"
#include "transport/transport.h"

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace fulgur::runtime {

/// The light of one strike's strokes at unit glow, on the lighting grid with all the scene's
/// output directions: [0] the main channel, [1] the branches. A frame scales them by the
/// flash's main and branch glow (lightning::FlashState); the leaders (dim, part of the
/// channel, a few ms) stay with the bases. `multiple` is empty when not solved. A strike
/// tallied toward the camera (StrikeSolveOptions::toward) holds one direction instead, which
/// serves every output direction (direction()): 1/26 of the memory.
struct StrikeLight {
    std::array<transport::SourceField, 2> single, multiple;
    /// With StrikeSolveOptions::keep_transport_grid, the same light on the transport grid the
    /// solve tallied on (`single` and `multiple` are its block averages); else empty.
    std::array<transport::SourceField, 2> fine_single, fine_multiple;
    bool has_fine() const noexcept { return !fine_single[0].data.empty(); }
    /// With StrikeSolveOptions::ground: the irradiance the cloud's scattered light gives the
    /// ground at unit glow, per group (W/m^2). Tallied by Monte Carlo multiple scattering's
    /// paths; gathered from S (transport::ground_dome) where the lattice solves it, or where
    /// single scattering is all (no multiple scattering in the scene). Empty otherwise: the
    /// hybrid preset (its multiple scattering is the bases'), S tallied toward the camera.
    std::array<transport::GroundIrradiance, 2> ground;
    transport::MonteCarloResult::Noise noise;  ///< of the Monte Carlo parts (relative L2 over the cloud)
    double seconds_single = 0.0, seconds_multiple = 0.0;
    double seconds_ground = 0.0;  ///< of the gather from S (a Monte Carlo tally costs nothing apart)
    bool has_multiple() const noexcept { return !multiple[0].data.empty(); }
    /// Output direction m of `f` (one of this light's fields): its one field when it holds one.
    static std::span<const float> direction(const transport::SourceField& f, std::size_t m) noexcept {
        return f.direction(f.directions.size() == 1 ? 0 : m);
    }
};

/// The bolt's segments at unit glow as exact line sources, in StrikeLight's groups: 0 the
/// main channel, 1 the branches.
std::vector<transport::LineSource> strike_line_sources(const lightning::Bolt& bolt);

/// How a strike's light is solved.
struct StrikeSolveOptions {
    /// Single scattering: expected-value Monte Carlo of the channel's segments as exact line
    /// sources through the full-resolution density (the truth's estimator), tallied on the
    /// transport grid. Noise falls like 1/sqrt(paths).
    std::uint64_t single_paths = 250'000;
    /// Multiple scattering: none (the bases give it: the hybrid preset), the scene's lattice on
    /// the transport grid fed with that single scattering, or Monte Carlo through the
    /// full-resolution density (unbiased, noisy: multiple_paths).
    enum class Multiple { None, Lattice, MonteCarlo };
    Multiple multiple = Multiple::Lattice;
    std::uint64_t multiple_paths = 200'000;
    std::uint64_t seed = 1;
    /// Keep the light on the transport grid as well (StrikeLight::fine_*; quality.grid
    /// "transport"). Monte Carlo's multiple scattering is then tallied there too.
    bool keep_transport_grid = false;
    /// Set (quality "directions": "camera"): S tallied toward this point (the scene's camera)
    /// from every voxel, one field that serves every output direction (Quality::toward_camera).
    std::optional<glm::dvec3> toward;
    /// Set: the light the cloud scatters onto this ground (StrikeLight::ground; strike_ground()),
    /// tallied by Monte Carlo's multiple-scattering paths or gathered from the lattice's S.
    std::optional<transport::GroundTally> ground;
};

/// The ground cells a strike's solve tallies the cloud's scattered light on: the scene's ground
/// plane (its lightning's ground height) under the lighting grid `lighting` and 20 km around
/// it (a camera at the storm's distance sees the ground that far out), in cells of two
/// lighting voxels (the light a cloud base a kilometre or more up sends down varies over
/// kilometres; each cell then gathers enough crossings), wider where that would take more
/// than 2048 a side (transport::ground_cells_around). None when the scene draws no ground or
/// no lightning.
std::optional<transport::GroundTally> strike_ground(const scene::Scene& scene, const core::GridGeometry& lighting);

/// The per-strike solve a quality preset asks for (its multiple-scattering solver and paths).
StrikeSolveOptions strike_solve_options(const scene::Quality& q);

/// Solves one strike's light (seconds; runs on the calling thread with core::thread_count()
/// threads). Throws core::Error on bad input.
StrikeLight solve_strike(const scene::Scene& scene, const core::Grid3<float>& density, const solve::Media& media,
                         const lightning::Bolt& bolt, const StrikeSolveOptions& options);

/// Solves strikes on a worker thread, in the order they are requested, keeping their lights
/// until forgotten. Thread-safe.
class StrikeSolver {
public:
    /// Keeps references to `scene`, `density` and `media`; they must outlive it. `threads`:
    /// the worker's share of the cores for each solve (>= 1).
    StrikeSolver(const scene::Scene& scene, const core::Grid3<float>& density, const solve::Media& media,
                 const StrikeSolveOptions& options, int threads);
    ~StrikeSolver();
    StrikeSolver(const StrikeSolver&) = delete;
    StrikeSolver& operator=(const StrikeSolver&) = delete;

    /// Queues the strike (identified by its seed and start time; its bolt is copied). No-op
    /// when it is queued, being solved or solved already.
    void request(std::uint64_t seed, double time, const lightning::Bolt& bolt);
    /// The strike's light once solved, else null (never another strike's).
    std::shared_ptr<const StrikeLight> get(std::uint64_t seed, double time) const;
    /// Blocks until the strike is solved (it must have been requested); rethrows its error.
    std::shared_ptr<const StrikeLight> wait(std::uint64_t seed, double time);
    /// While paused the worker starts no new solve (a caller that needs the cores, or a test
    /// that needs a strike to be unsolved); requests still queue.
    void set_paused(bool paused);
    /// Drops the lights of strikes that started before `time` (memory: ~3.5 MB each).
    void forget_before(double time);
    /// Wall time from request to ready of the strikes solved so far, seconds (in order).
    std::vector<double> latencies() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace fulgur::runtime
