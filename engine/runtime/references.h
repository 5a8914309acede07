// fulgur::runtime — what a frame is measured against: the direct solve (the frame's sources
// through the bake's own solver) and the truth (Monte Carlo through the full-resolution density).
#pragma once

#include "core/core.h"
#include "lightning/lightning.h"
#include "runtime/reconstructor.h"
#include "scene/scene.h"
#include "solve/solve.h"
#include "transport/transport.h"

#include <cstdint>
#include <optional>
#include <span>

namespace fulgur::runtime {

/// The reference the basis method is measured against (paper Table 2, "previous method"):
/// the frame's point sources fed straight to exact single scattering plus the scene's
/// multiple-scattering solver, no virtual lights, no compression. Same units and layout
/// as the reconstruction (all directions). Runs solve::solve with the bake's settings (same
/// single-scattering tolerance, same lattice-Boltzmann settings, no light drop); a part the
/// scene does not simulate (effects.*_scattering false) is not added, as in the bake.
transport::SourceField direct_solve(const scene::Scene& scene, const solve::Media& media,
                                    std::span<const transport::PointSource> sources, const Components& components = {});

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
    /// Set: S toward this point (a still camera) from every voxel, one field copied into every
    /// output direction, as a strike solved toward the camera holds it (Quality::toward_camera).
    std::optional<glm::dvec3> toward;
    /// Set: also the light the cloud scatters onto this ground (Truth::ground; the cells a
    /// strike's solve tallies on: strike_ground()).
    std::optional<transport::GroundTally> ground;
};

/// The ground truth of a frame.
struct Truth {
    transport::SourceField single;    ///< order 1, voxel averages on the lighting grid
    transport::SourceField multiple;  ///< orders >= 2 (zero when not tallied)
    /// Relative L2 noise over the cloud voxels (transport::MonteCarloResult::Noise).
    transport::MonteCarloResult::Noise noise;
    /// The whole-cloud totals of single and multiple with their standard errors
    /// (transport::MonteCarloResult::CloudSums): the noise of a ratio of totals.
    transport::MonteCarloResult::CloudSums sums;
    /// With TruthOptions::ground: the irradiance of the cloud's scattered light on its cells
    /// (W/m^2), and the power they received with its standard error.
    transport::GroundIrradiance ground;
    transport::Estimate ground_power;
    std::uint64_t paths = 0;
    double seconds = 0.0;
    /// The components asked for, summed (a field like direct_solve's).
    transport::SourceField sum(const Components& c = {}) const;
    /// The light of orders >= 2 at the rain as runtime::Frame::rain holds it: `multiple` over
    /// the cloud's albedo, read by the renderer where the rain is. Empty (no data) unless the
    /// scene rains, the frame draws the multiple component and the cloud scatters (albedo > 0):
    /// the renderer's rain is then lit by the channel alone, as the frame's own would be.
    transport::SourceField rain_light(const scene::Scene& scene, const Components& drawn) const;
};

/// What every method is measured against: Monte Carlo of the frame's lit channel (its lit
/// stretches as exact line sources, plus any point sources) through the scene's
/// full-resolution density (not the lighting grid the bake and the direct solve see), S
/// tallied as voxel averages on the lighting grid for the scene's output directions, split
/// into single and multiple scattering, with a noise estimate from two independent halves.
/// Uses the scene's optics (exact Henyey-Greenstein), independent of its transport settings.
/// With rain, the rain is part of the medium as the strikes' solves see it
/// (sky::make_static_media: cloud of equal transport coefficient, S at its points with the
/// drops' phase function by each cell's share of rain). Offline: seconds to minutes.
Truth truth(const scene::Scene& scene, const core::Grid3<float>& density, std::span<const lightning::LitSegment> lit,
            std::span<const transport::PointSource> points = {}, const TruthOptions& options = {});

}  // namespace fulgur::runtime
