// fulgur::runtime — per-frame reconstruction of the cloud's radiance from a baked scene
// (Dobashi et al. 2007, section 7).
//
//   strikes at time t (lightning::Storm) -> lit segments -> point sources -> splat -> e_l
//   -> H^(m) = sum_{l: e_l != 0} e_l B_l^(m)  (sparse, only the requested directions m)
//   -> inverse Haar -> S^(m) on the lighting grid (+ optional ambient) -> render upload.
//
// A frame with no active flash costs nothing (no accumulation, no transform). Only the
// directions the caller asks for are reconstructed (the renderer knows which the view
// needs: render::Renderer::needed_directions). Components: the bake may store the direct
// (single-scattering) and the multiple-scattering parts of each basis separately; the
// caller chooses which to sum (both linear, so both go into the same H, one transform).
//
// THIS HEADER IS THE CONTRACT between the run-time module and the apps (demo, shot tool,
// benchmarks). Changing it is fine when the implementation needs it; keep it small,
// documented, and free of GL / window-system types.
#pragma once

#include "bake/bake.h"
#include "basis/basis.h"
#include "core/core.h"
#include "lightning/lightning.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace fulgur::runtime {

/// Which parts of the baked radiance to sum.
struct Components {
    bool single = true;    ///< direct light (first scattering)
    bool multiple = true;  ///< orders >= 2 (present only if the scene baked them)
};

/// How the paper's ambient term (Eq. 10) is applied; see basis::ambient_rms for why the
/// default is None with an orthonormal transform.
enum class Ambient { None, Rms, Paper };

/// Per-stage wall times of one frame, milliseconds.
struct StageTimes {
    double bolt = 0.0;        ///< strike schedule, bolt generation, lit segments
    double sources = 0.0;     ///< point sources along lit segments
    double splat = 0.0;       ///< trilinear splat into virtual lights
    double accumulate = 0.0;  ///< sparse sum of basis coefficients (Eq. 9)
    double inverse_haar = 0.0;
    double strike_light = 0.0;  ///< solved strikes' light scaled by their glow and added
    double total() const noexcept { return bolt + sources + splat + accumulate + inverse_haar + strike_light; }
};

/// The baked bases in a layout for fast accumulation (loaded from a .fgb; validated).
/// Layout (docs/runtime.md): one pool of coefficients, per (light, basis) a contiguous run
/// [offset, next offset) of indices (uint16 when the lighting grid has <= 65536 cells, else
/// uint32) and float32 values (float16 files are expanded at load), in the file's order.
class BakedBases {
public:
    /// Loads and validates `fgb` (basis::load_fgb: every CRC, index and value). With the
    /// scene's key (bake::scene_key), a file baked from other parameters is rejected before
    /// its blocks are read: core::Error "stale bake" naming both hashes and the first scene
    /// parameter that changed (basis::FgbReader::check_key).
    static BakedBases load(const std::filesystem::path& fgb, const std::optional<basis::BakeKey>& expected = {});
    /// The same, checking the file's whole header against the scene's plan
    /// (basis::FgbReader::check_metadata: key, grids, directions, lights, compression).
    static BakedBases load(const std::filesystem::path& fgb, const basis::FgbMetadata& expected);

    const core::GridGeometry& lighting() const noexcept;
    const std::vector<glm::dvec3>& directions() const noexcept;
    const basis::VirtualLightGrid& lights() const noexcept;
    const basis::FgbMetadata& metadata() const noexcept;
    bool has_multiple() const noexcept;  ///< the multiple-scattering component was baked
    /// Single and multiple scattering are stored as separate bases (FgbMetadata::components
    /// == 2), so a reconstruction can show either alone.
    bool separate() const noexcept;
    std::size_t coefficient_count() const noexcept;  ///< all kept coefficients, all components
    std::size_t memory_bytes() const noexcept;       ///< bytes of the coefficient pool and offsets

    BakedBases(BakedBases&&) noexcept;
    BakedBases& operator=(BakedBases&&) noexcept;
    ~BakedBases();
    struct Impl;
    const Impl& impl() const noexcept { return *impl_; }

private:
    explicit BakedBases(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

/// S for a subset of the baked directions on the lighting grid (render::SourceUpload layout:
/// one float array of lighting().cell_count() values per listed direction, x fastest).
struct RadianceField {
    core::GridGeometry geometry;
    int direction_count = 1;      ///< size of the baked direction set
    std::vector<int> directions;  ///< indices of the reconstructed directions
    std::vector<std::vector<float>> values;
    /// What the values hold. Usually the request; it differs when the bake cannot separate
    /// the request (see Reconstructor::reconstruct).
    Components components;
};

struct ReconstructOptions {
    Components components;
    Ambient ambient = Ambient::None;
    /// Directions run on several threads only when the frame's work (coefficients to add +
    /// cells x directions to transform) reaches this: below it a fork/join costs more than it
    /// saves, and on a loaded machine a parallel region can cost a scheduler slice (ms).
    /// 0: always use core::thread_count() threads. docs/runtime.md has the measurement.
    std::size_t parallel_min_work = std::size_t(1) << 21;
    /// Presets that solve strikes (FramePipeline): wait for the solve of every active strike
    /// instead of falling back to the bases (offline frames: fulgur-shot, studies, tests).
    bool wait_for_strikes = false;
};

/// Eq. 8-10: sparse accumulation + inverse Haar. Owns its scratch (one Haar plan per
/// worker thread); not thread-safe itself: one Reconstructor per calling thread.
/// Directions are spread over core::thread_count() threads when the frame is big enough
/// (ReconstructOptions::parallel_min_work); each direction is an independent accumulation +
/// transform, so the result does not depend on the thread count.
/// Arithmetic is float32 (H and the inverse transform); docs/runtime.md gives the error
/// against a double reference.
class Reconstructor {
public:
    explicit Reconstructor(const BakedBases& bases);
    ~Reconstructor();
    /// Reconstructs the requested directions (all when `directions` is empty; an index
    /// outside the bake's set throws core::Error) for light weights `w` (over
    /// bases.lights()). Returns false and leaves `out` untouched when no light is active
    /// (times.accumulate and times.inverse_haar are set to 0). Else writes `out` (its
    /// buffers are reused from call to call) and the two stage times.
    /// Components: with separate bases each requested part is summed. A bake that stores
    /// one basis per direction (components == 1) holds its `content`: a request including
    /// a part it holds gets that basis (with single + multiple combined, asking for only
    /// one of them gets both: they cannot be separated); a request for only a part that
    /// was not baked gets zeros. out.components says what the values hold.
    bool reconstruct(const lightning::LightWeights& w, std::span<const int> directions,
                     const ReconstructOptions& options, RadianceField& out, StageTimes& times);

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

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

/// The reference the basis method is measured against (paper Table 2, "previous method"):
/// the frame's point sources fed straight to exact single scattering plus the scene's
/// multiple-scattering solver, no virtual lights, no compression. Same units and layout
/// as the reconstruction (all directions). Runs bake::solve with the bake's settings (same
/// single-scattering tolerance, same lattice-Boltzmann settings, no light drop); a part the
/// scene does not simulate (effects.*_scattering false) is not added, as in the bake.
transport::SourceField direct_solve(const scene::Scene& scene, const bake::Media& media,
                                    std::span<const transport::PointSource> sources, const Components& components = {});

// =======================================================================================
// Per-strike light: what the hybrid, per-strike and reference presets add to the bases.

/// The light of one strike's strokes at unit glow, on the lighting grid with all the scene's
/// output directions: [0] the main channel, [1] the branches. A frame scales them by the
/// flash's main and branch glow (lightning::FlashState); the leaders (dim, part of the
/// channel, a few ms) stay with the bases. `multiple` is empty when not solved.
struct StrikeLight {
    std::array<transport::SourceField, 2> single, multiple;
    transport::MonteCarloResult::Noise noise;  ///< of the Monte Carlo parts (relative L2 over the cloud)
    double seconds_single = 0.0, seconds_multiple = 0.0;
    bool has_multiple() const noexcept { return !multiple[0].data.empty(); }
};

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
};

/// The per-strike solve a quality preset asks for (its multiple-scattering solver and paths).
StrikeSolveOptions strike_solve_options(const scene::Quality& q);

/// Solves one strike's light (seconds; runs on the calling thread with core::thread_count()
/// threads). Throws core::Error on bad input.
StrikeLight solve_strike(const scene::Scene& scene, const core::Grid3<float>& density, const bake::Media& media,
                         const lightning::Bolt& bolt, const StrikeSolveOptions& options);

/// Solves strikes on a worker thread, in the order they are requested, keeping their lights
/// until forgotten. Thread-safe.
class StrikeSolver {
public:
    /// Keeps references to `scene`, `density` and `media`; they must outlive it. `threads`:
    /// the worker's share of the cores for each solve (>= 1).
    StrikeSolver(const scene::Scene& scene, const core::Grid3<float>& density, const bake::Media& media,
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

/// Options of truth().
struct TruthOptions {
    /// Photon paths. The noise (Truth::noise) falls like 1/sqrt(paths); docs/runtime.md gives
    /// paths, noise and time on the default storm.
    std::uint64_t paths = 8'000'000;
    int batches = 32;        ///< >= 4: two halves of >= 2 batches for the noise estimate
    std::uint64_t seed = 1;  ///< results depend only on (seed, paths, batches), not on threads
    bool multiple = true;    ///< tally orders >= 2 (false: order 1 only, much faster)
    /// Average S over each lighting voxel by volume, or weighted by extinction (see
    /// transport::MonteCarloOptions::TallyWeight).
    transport::MonteCarloOptions::TallyWeight weight = transport::MonteCarloOptions::TallyWeight::Volume;
};

/// The ground truth of a frame.
struct Truth {
    transport::SourceField single;    ///< order 1, voxel averages on the lighting grid
    transport::SourceField multiple;  ///< orders >= 2 (zero when not tallied)
    /// Relative L2 noise over the cloud voxels (transport::MonteCarloResult::Noise).
    transport::MonteCarloResult::Noise noise;
    std::uint64_t paths = 0;
    double seconds = 0.0;
    /// The components asked for, summed (a field like direct_solve's).
    transport::SourceField sum(const Components& c = {}) const;
};

/// What every method is measured against: Monte Carlo of the frame's lit channel (its lit
/// stretches as exact line sources, plus any point sources) through the scene's
/// full-resolution density (not the lighting grid the bake and the direct solve see), S
/// tallied as voxel averages on the lighting grid for the scene's output directions, split
/// into single and multiple scattering, with a noise estimate from two independent halves.
/// Uses the scene's optics (exact Henyey-Greenstein), independent of its transport settings.
/// Offline: seconds to minutes.
Truth truth(const scene::Scene& scene, const core::Grid3<float>& density, std::span<const lightning::LitSegment> lit,
            std::span<const transport::PointSource> points = {}, const TruthOptions& options = {});

}  // namespace fulgur::runtime
