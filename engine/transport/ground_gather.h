// fulgur::transport — the light a cloud's S sends to the ground, gathered from S: the ground
// irradiance of any solver's source function (the lattice's, a reconstruction's), where Monte
// Carlo tallies it from its paths instead (MonteCarloOptions::ground).
#pragma once

#include "transport/transport.h"

#include <span>
#include <vector>

namespace fulgur::transport {

struct GroundGatherOptions {
    /// Each cell's irradiance is the mean over n x n points on it (n >= 1; 1: its centre). On
    /// the default storm cut small, per_strike's ground against the truth: 1 point 13.0%
    /// relative L2 over the cells, 2 x 2 points 11.6% for 4.3x the time (fulgur-bench
    /// ground_gather: one point 0.35 s a strike on one core).
    int points_per_side = 1;
    /// A voxel nearer to a point than this many voxel sizes is taken as q^3 sub-voxels
    /// (q = ceil(near_voxels * h / r), at most 4) instead of one point: the 1/r^2 and the
    /// transmittance vary across a voxel that close.
    double near_voxels = 8.0;
};

/// Irradiance on `cells` (W/m^2 per cell) from the light the medium scatters: every voxel v
/// with sigma_t > 0 emits sigma_t(v) S(v, toward p) V from its centre toward a ground point p,
/// dimmed by the transmittance through the piecewise-constant medium from the centre on
/// (optical_depth), times cos / r^2. In voxels several optical depths thick the light a voxel
/// sends down comes from its lower part, where S is below the voxel's mean: the half voxel the
/// centre's light crosses stands for that (test_ground_gather: 0.99 of the tallied power at
/// 3 optical depths a voxel, where a uniform S leaving through the voxel's faces gives 1.51).
/// The ground is black and does not shadow (as the Monte Carlo tally takes it), and voxels
/// under the plane send nothing. `fields`: summed, each on the medium's grid with the same
/// directions; S toward p is interpolated between them by direction_weights. A one-direction
/// field is taken as isotropic (g = 0): never pass S tallied toward a point.
/// Deterministic (each point's sum in one order, whatever the threads). Throws core::Error
/// naming the argument for mismatched fields or cells, S not finite where the medium scatters,
/// or work above 2^32 voxel-point pairs.
GroundIrradiance gather_ground(const LightingMedium& medium, std::span<const SourceField* const> fields,
                               const GroundTally& cells, const GroundGatherOptions& options = {});

/// The same for several groups of fields at once (a strike's main channel and branches): one
/// irradiance per group, each equal to gather_ground of that group alone, for the cost of
/// about one (the transmittance of each voxel-point pair is computed once). Every field of
/// every group must share one grid and one direction set; errors name `groups[g][f]`.
std::vector<GroundIrradiance> gather_ground(const LightingMedium& medium,
                                            std::span<const std::vector<const SourceField*>> groups,
                                            const GroundTally& cells, const GroundGatherOptions& options = {});

}  // namespace fulgur::transport
