// fulgur::cloud — rain shafts: precipitation falling from the base of the cloud's raining
// columns to the ground, as an extinction field on the density grid.
//
// Where it falls (the footprint): the columns whose cloud is thick. Each column's cloud path
// W = sum of density x voxel over its height is compared with the thickest column's; the
// rain's weight is smoothstep(threshold, (1 + threshold) / 2, W / W_max), blurred over
// ~2 columns so the shaft's edge is soft. The rain's top is the cloud base over the footprint
// (the lowest voxel with density >= 0.1 among columns of weight > 1/2); rain thickens over
// the first 300 m below it (the drops' fall from the base) and reaches the ground.
//
// How it falls: with the wind's shear, the rain at height z left the base `shear` x
// (top - z) / 1000 m upwind (shear in metres of horizontal drift per km of fall), so the shaft
// leans downwind; fall streaks modulate it by a billow noise (cloud/subvoxel.h) stretched 8x
// along the vertical and carried with the drift: rate x (1 - s + 2 s b), s = streak strength.
//
// How much light it stops: Marshall & Palmer (1948) drop sizes, N(D) = N0 exp(-Lambda D),
// N0 = 8000 m^-3 mm^-1, Lambda = 4.1 R^-0.21 mm^-1 (R in mm/h), each drop far larger than the
// wavelength (extinction efficiency 2): sigma = pi N0 Lambda^-3 1e-6 1/m, i.e. 0.37 R^0.63
// per km (1 mm/h: 0.37 km^-1; 25 mm/h: 2.8 km^-1, a visibility of ~1 km, as heavy rain has).
// Its scattering: albedo 0.99 and a Henyey-Greenstein phase with g = 0.85 (diffraction by
// millimetre drops makes it strongly forward), drawn by the renderer (docs/render.md).
#pragma once

#include "core/core.h"

#include <glm/vec2.hpp>

#include <cstdint>

namespace fulgur::cloud {

/// The scene's "rain" object, by the same names.
struct RainParams {
    double rate = 20.0;            ///< mm/h under the footprint's heart (the rain the extinction follows)
    double threshold = 0.5;        ///< footprint: columns with at least this share of the thickest column's cloud rain
    glm::dvec2 shear{0.0};         ///< metres of horizontal drift per km of fall (x, y): the shaft leans downwind
    double streak_scale = 400.0;   ///< metres across the fall streaks
    double streak_strength = 0.5;  ///< 0: uniform rain; 1: the rate varies from 0 to twice the mean
    std::uint64_t seed = 1;        ///< the streaks' layout
    double g = 0.85;               ///< Henyey-Greenstein g of the drops
    double albedo = 0.99;          ///< single-scattering albedo of the drops
};

/// Checks the parameters; throws core::Error whose where() is the scene field ("rain.rate", ...).
void validate_rain(const RainParams& p);

/// Extinction (1/m) of rain falling at `rate` mm/h (Marshall-Palmer drops, efficiency 2).
double rain_extinction(double rate);

/// The rain of a cloud: its extinction on the cloud's density grid (0 where no rain falls).
struct RainField {
    core::Grid3<float> extinction;  ///< 1/m, on the density grid
    double top = 0.0;               ///< metres: the rain's top (the cloud base over the footprint)
    double max_extinction = 0.0;    ///< 1/m: the largest value of `extinction`
    double g = 0.85, albedo = 0.99;
};

/// Builds the rain under `density` (values in [0, 1], ground at z = 0). A cloud with no
/// column dense enough (no voxel >= 0.1) gets no rain (all zero). Deterministic whatever
/// core::thread_count() is. Validates `p` first.
RainField make_rain(const core::Grid3<float>& density, const RainParams& p);

}  // namespace fulgur::cloud
