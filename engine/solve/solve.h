// fulgur::solve — the per-light solver layer: S of light sources in a scene's medium, on
// the scene's lighting grid, by exact single scattering plus the scene's multiple-scattering
// solver. The bake (one virtual light at a time), the run time's direct solve and per-strike
// light, and the sun and sky all go through it, so every method is measured against the same
// solver and the same settings (docs/design.md#solvers).
#pragma once

#include "core/core.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <span>

namespace fulgur::solve {

/// S of point sources in the scene's medium, split into its two parts: the exact single
/// scattering (transport::single_scattering, voxel averages) and the multiple scattering
/// by the scene's solver (lattice-Boltzmann fed with the exact S1 as its first-scattered
/// source, or Monte Carlo orders >= 2). This is the one function the bake (per virtual
/// light), the run time's direct solve and per-strike lattice (per frame or strike, all
/// sources at once) and the sky use, so they are comparable by construction.
struct Solution {
    transport::SourceField single;    ///< order 1 (empty data when not requested)
    transport::SourceField multiple;  ///< orders >= 2 (empty data when not requested)
    /// Power scattered once by the cloud, sum over voxels of sigma_s phi1 h^3 (W), where
    /// phi1 is the uncollided fluence: the drop criterion for virtual lights.
    double first_scattered_power = 0.0;
    int iterations = 0;  ///< lattice steps (0 for Monte Carlo or no solve)
    bool converged = true;
    double seconds_single = 0.0, seconds_multiple = 0.0;
};
struct SolveRequest {
    bool single = true;    ///< return S1 (it is computed anyway when multiple is requested)
    bool multiple = true;  ///< run the scene's multiple-scattering solver
    /// Skip the multiple-scattering solve when first_scattered_power is below this fraction
    /// of the sources' emitted power (the bake's drop test; 0 never skips).
    double skip_below = 0.0;
};
/// The media a solve runs in: `lighting`, the grid S is stored on, and `transport`, the grid
/// the solvers run on: the lighting grid refined by the scene's transport.refine (the same
/// grid when refine is 1), S averaged back onto the lighting grid.
struct Media {
    transport::LightingMedium lighting;
    transport::LightingMedium transport;
    int refine = 1;
    /// The full-resolution density (for the Monte Carlo order 2 of
    /// transport.lattice_boltzmann.exact_orders 2; empty otherwise).
    transport::LightingMedium full;
    /// With rain (sky::make_static_media with full): the full-resolution medium Monte Carlo
    /// paths trace to be tallied as the light itself, the rain at its own extinction and with
    /// its own albedo and phase (transport::PathMix), where `full` holds it as cloud of equal
    /// transport coefficient for what feeds the lattice. Empty otherwise: paths trace `full`.
    transport::LightingMedium traced;
};

/// The medium the Monte Carlo's paths trace: Media::traced when it is set, else Media::full.
const transport::LightingMedium& traced_medium(const Media& m) noexcept;
Media make_media(const scene::Scene& s, const core::Grid3<float>& density);
/// The same with its own refinement of the lighting grid (a divisor of lighting.downsample)
/// and, with `full`, the full-resolution density (for an order-2 Monte Carlo): the static
/// light's media (sky::static_media).
Media make_media(const scene::Scene& s, const core::Grid3<float>& density, int refine, bool full);

/// The Monte Carlo of exactly order 2 a lattice with exact orders 2 is fed with: the
/// expected-value second flight (paths stop after it), its S and fluence tallied, 4 batches.
transport::MonteCarloOptions order_two_options(std::uint64_t paths, std::uint64_t seed);

/// The scene's lattice-Boltzmann settings (transport.lattice_boltzmann).
transport::LbSettings lattice_settings(const scene::Scene& s);

/// Single-scattering settings the bake and the direct solve share (scene's tolerance,
/// far-empty voxels skipped; part of the scene key).
transport::SingleScatteringOptions single_scattering_options(const scene::Scene& s);
Solution solve(const scene::Scene& s, const Media& media, std::span<const transport::PointSource> sources,
               std::span<const glm::dvec3> directions, const SolveRequest& request = {});

}  // namespace fulgur::solve
