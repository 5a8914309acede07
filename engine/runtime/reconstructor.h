// fulgur::runtime — per-frame reconstruction: the sparse sum of the active lights' bases and
// the inverse Haar transform (Dobashi et al. 2007, Eqs. 8-10), for the directions asked for.
#pragma once

#include "core/core.h"
#include "lightning/lightning.h"
#include "runtime/baked_bases.h"

#include <memory>
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

}  // namespace fulgur::runtime
