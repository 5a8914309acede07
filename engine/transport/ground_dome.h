// fulgur::transport — the ground's irradiance from the light arriving over its dome: for each
// cell, rays from the ground up through the medium in many directions, each gathering the
// radiance the medium scatters toward the ground (from any solver's S: the lattice's, a
// reconstruction's, where Monte Carlo tallies it from its paths instead,
// MonteCarloOptions::ground) and what is left of a sky behind the medium.
#pragma once

#include "transport/transport.h"

#include <functional>
#include <span>
#include <vector>

namespace fulgur::transport {

struct DomeGroundOptions {
    /// Rays per cell (from its centre) over the upper hemisphere, cosine-weighted (a Fibonacci
    /// spiral in the disc the hemisphere projects to), so the irradiance is pi times their mean
    /// radiance. In [16, 65536].
    int rays = 1024;
    /// Each cell's irradiance is the mean over n x n points on it (n in [1, 16]; 1: its centre).
    int points_per_side = 1;
    /// What a ray takes from a voxel it crosses for a length l: Uniform, S constant through
    /// the voxel, T_in S (1 - exp(-sigma_t l)) (exact for that model); Centre, the voxel's
    /// light as from the middle of the crossing, T_in S sigma_t l exp(-sigma_t l / 2) (the
    /// midpoint rule). Where voxels are optically thin they agree; where one is several optical
    /// depths thick its S falls toward the faces the light leaves by, which Uniform does not
    /// see and the midpoint's deeper dimming stands for (test_ground_dome: in voxels three
    /// optical depths thick lit from within, Uniform 1.26 of the tallied power, Centre 1.18;
    /// on the default storm's 750 m voxels, the sun's light on the ground 1.10 and 1.00 of the
    /// truth's, a strike's 1.09 and 0.95).
    enum class Within { Uniform, Centre };
    Within within = Within::Centre;
    /// Set: instead of the irradiance, the integral over the upper hemisphere of lobe(w) L(w)
    /// dw (w the unit direction a ray looks in, up; lobe per steradian, finite and >= 0). With
    /// a phase function toward a viewer it is the radiance a medium at the cells' height
    /// scatters toward the viewer per unit sigma_s, of the light arriving from above. The
    /// rays are then of equal solid angle (a Fibonacci spiral, z uniform), each weighted by
    /// the lobe: a lobe toward a horizontal viewer peaks at the horizon, where cosine-weighted
    /// rays are sparse.
    std::function<double(const glm::dvec3&)> lobe = {};
};

/// A sky's radiance (W m^-2 sr^-1) as a function of sin(elevation) in [0, 1].
using DomeProfile = std::function<double(double sin_elevation)>;

/// Irradiance on `cells` (W/m^2 per cell, over its points) of:
///  * `groups[q]`: the light the medium scatters, S summed over the group's fields (each on the
///    medium's grid with the same directions; S toward the ground interpolated between them by
///    direction_weights, one direction taken as isotropic). Along a ray the medium and S are
///    constant in each voxel; its radiance is the sum over the voxels it crosses of what
///    DomeGroundOptions::within takes from each.
///  * `skies[k]`: a sky behind the medium, L = T(ray) profile(sin elevation): what of that sky
///    the cloud lets through, without the light the cloud scatters (a group's part).
/// The ground is black and does not shadow; rays start on the plane. Deterministic whatever
/// the threads. Throws core::Error naming the argument (`ground_dome.groups[q][f]`, `.cells`,
/// `.rays`, `.points_per_side`, `.skies[k]`, `.lobe`) for mismatched fields, S not finite where
/// the medium scatters, a profile or lobe giving a negative or non-finite value, or work above 2^33
/// voxel visits (the cells' points x rays x the cloud's box across, in voxels: about a minute
/// on one core).
struct DomeGround {
    std::vector<GroundIrradiance> groups;  ///< one per group of fields
    std::vector<GroundIrradiance> skies;   ///< one per profile
};
DomeGround ground_dome(const LightingMedium& medium, std::span<const std::vector<const SourceField*>> groups,
                       std::span<const DomeProfile> skies, const GroundTally& cells,
                       const DomeGroundOptions& options = {});

}  // namespace fulgur::transport
