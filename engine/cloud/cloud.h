// fulgur::cloud — cloud density: the storm-cloud generator and density import/export.
//
// The generator follows Dobashi et al. 2000 ("A Simple, Efficient Method for Realistic
// Animation of Clouds"): a cellular automaton with three boolean states per cell
// (hum: vapour, act: phase-transition activation, cld: cloud), the growth rules
//   hum' = hum & !act,  cld' = cld | act,  act' = !act & hum & f_act(neighbours),
// stochastic extinction (cld' = cld & rnd > p_ext) and supply (hum' |= rnd < p_hum,
// act' |= rnd < p_act) whose probabilities are shaped by seed ellipsoids, then space-time
// averaging and smoothing to a continuous density in [0, 1]. The ellipsoids are placed to
// build a cumulonimbus: a flat base, a tall convective tower and an optional anvil.
// Deterministic for a given seed. Coordinates: z up, ground at z = 0, the grid centred
// horizontally on x = y = 0.
#pragma once

#include "core/core.h"

#include <cstdint>
#include <filesystem>

namespace fulgur::cloud {

struct CumulonimbusParams {
    std::uint64_t seed = 1;
    core::Int3 grid{128, 128, 96};  ///< density voxels
    double voxel_size = 100.0;      ///< metres

    // Shape (metres)
    double base_height = 1500.0;    ///< flat cloud base above the ground
    double top_height = 9000.0;     ///< top of the tower (anvil top if anvil)
    double tower_radius = 2500.0;   ///< horizontal radius of the convective tower
    bool anvil = true;
    double anvil_radius = 5000.0;   ///< horizontal radius of the anvil
    double anvil_thickness = 1500.0;
    int cells = 24;                 ///< seed ellipsoids (convective cells) making the tower

    // Cellular automaton (Dobashi 2000)
    int steps = 40;                 ///< CA iterations
    double p_ext = 0.1;             ///< cloud extinction probability outside ellipsoids
    double p_hum = 0.1;             ///< vapour supply probability at an ellipsoid centre
    double p_act = 0.01;            ///< activation probability at an ellipsoid centre
    int average_steps = 4;          ///< time window (steps) of the space-time average
    int smoothing_radius = 2;       ///< smoothing kernel radius, voxels
};

/// Grid geometry of a generated cloud: dims and voxel size from params, centred on x=y=0,
/// ground at z=0.
core::GridGeometry cumulonimbus_geometry(const CumulonimbusParams& p);

/// Generates the density (values in [0, 1]). Throws core::Error on inconsistent
/// parameters (e.g. base above top, shape outside the grid), naming the parameter.
core::Grid3<float> generate_cumulonimbus(const CumulonimbusParams& p);

/// Loads a density NRRD and validates it (3D float32, values in [0, 1]); errors name the
/// file and the offending voxel or field.
core::Grid3<float> load_density(const std::filesystem::path& path);

/// Saves a density as NRRD (float32), loadable by load_density, ParaView and 3D Slicer.
void save_density(const std::filesystem::path& path, const core::Grid3<float>& density);

/// Height (z, metres) of the lowest voxel layer whose maximum density exceeds `threshold`;
/// the grid's top if none does.
double cloud_base_height(const core::Grid3<float>& density, float threshold = 0.05f);

}  // namespace fulgur::cloud
