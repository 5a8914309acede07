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

#include "basis/basis.h"
#include "core/core.h"
#include "lightning/lightning.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <cstdint>
#include <filesystem>
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
    double total() const noexcept { return bolt + sources + splat + accumulate + inverse_haar; }
};

/// The baked bases in a layout for fast accumulation (loaded from a .fgb; validated).
class BakedBases {
public:
    /// Loads and validates `fgb`. If `expected_hash` is given and differs from the file's,
    /// throws core::Error explaining what changed (stale bake).
    static BakedBases load(const std::filesystem::path& fgb, std::optional<std::uint64_t> expected_hash = {});

    const core::GridGeometry& lighting() const noexcept;
    const std::vector<glm::dvec3>& directions() const noexcept;
    const basis::VirtualLightGrid& lights() const noexcept;
    bool has_multiple() const noexcept;   ///< the multiple-scattering component was baked
    std::size_t coefficient_count() const noexcept;  ///< all kept coefficients, all components

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
    int direction_count = 1;            ///< size of the baked direction set
    std::vector<int> directions;        ///< indices of the reconstructed directions
    std::vector<std::vector<float>> values;
};

struct ReconstructOptions {
    Components components;
    Ambient ambient = Ambient::None;
};

/// Eq. 8-10: sparse accumulation + inverse Haar. Owns its scratch; one per thread of use.
class Reconstructor {
public:
    explicit Reconstructor(const BakedBases& bases);
    ~Reconstructor();
    /// Reconstructs the requested directions for light weights `w` (over bases.lights()).
    /// Returns false and leaves `out` untouched when no light is active.
    bool reconstruct(const lightning::LightWeights& w, std::span<const int> directions,
                     const ReconstructOptions& options, RadianceField& out, StageTimes& times);

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// One frame's lightning state and radiance.
struct Frame {
    double time = 0.0;
    bool lit = false;                                ///< a flash is active: radiance is valid
    std::vector<lightning::LitSegment> segments;     ///< for the renderer's bolt and glow
    std::vector<lightning::PointSource> sources;
    lightning::LightWeights weights;
    RadianceField radiance;
    StageTimes times;
};

/// Drives a storm over a baked scene: schedule -> bolt -> sources -> splat -> reconstruct.
class FramePipeline {
public:
    FramePipeline(const scene::Scene& scene, const core::Grid3<float>& density, const BakedBases& bases);
    ~FramePipeline();
    /// Schedules a strike at time t (demo "strike now"); returns its index.
    std::size_t strike_at(double t, std::optional<std::uint64_t> seed = {});
    /// Builds the frame at time t for the requested directions (all when empty).
    const Frame& build(double t, std::span<const int> directions, const ReconstructOptions& options = {});
    lightning::Storm& storm() noexcept;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// The reference the basis method is measured against (paper Table 2, "previous method"):
/// the frame's point sources fed straight to exact single scattering plus the scene's
/// multiple-scattering solver, no virtual lights, no compression. Same units and layout
/// as the reconstruction (all directions).
transport::SourceField direct_solve(const scene::Scene& scene, const transport::LightingMedium& medium,
                                    std::span<const lightning::PointSource> sources, const Components& components = {});

}  // namespace fulgur::runtime
