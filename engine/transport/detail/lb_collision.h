// Internal: collision matrices of the lattice-Boltzmann solver and the mapping from the
// physical medium to per-step lattice coefficients. Tests include this header.
//
// Notation (Geist et al. 2004, Eqs. 3-6): Theta[i][j] is the fraction of density arriving
// at a site in direction j that leaves it in direction i after the collision. For the
// moving directions i, j = 1..18:
//     Theta_ij = (1 - e_j) delta_ij + albedo * e_j * P_ij
// where e_j is the extinction probability of a packet arriving along direction j (the
// paper's sigma_t, here per direction class, see site_coefficients()) and P_ij the
// discrete phase function: the fraction of density scattered out of direction j that goes
// to direction i. Rest direction 0: conservative model Theta_0j = (1 - albedo) e_j (the
// absorbed part waits in the rest direction) and Theta_i0 = w_i (re-emitted isotropically
// next step); physical model Theta_0j = 0 (absorbed density leaves the system).
#pragma once

#include "transport/detail/lb_lattice.h"
#include "transport/transport.h"

#include <array>

namespace fulgur::transport::lb {

using Matrix19 = std::array<std::array<double, kQ>, kQ>;

/// Discrete phase function P[i][j] on directions 1..18 (index 0 unused, kept zero so that
/// indices match the lattice table).
struct DiscretePhase {
    Matrix19 P{};
    double g = 0.0;  ///< the medium's asymmetry parameter
    LbCollision form = LbCollision::Corrected;
    // Parameters of the corrected construction (see corrected_phase()).
    double g_fit = 0.0;                         ///< HG parameter of the smooth part
    double scale_axis = 1.0, scale_diag = 1.0;  ///< symmetric class scalings s_A, s_D
    double delta_diag = 0.0;                    ///< forward (g >= 0) or backward (g < 0) delta weight, diagonal class
};

/// Unnormalized Henyey-Greenstein kernel (1 - g^2) / (1 - 2 g c + g^2)^{3/2}, written
/// without cancellation near c = 1, g = 1.
double hg_kernel(double cos_theta, double g) noexcept;

/// The paper's anisotropic form: P_ij = w_i p_ij / (sum_{k=1}^{18} p_ik / 18), p the HG
/// kernel at n_i . n_j (a row normalization: the column sums are not 1 for g != 0).
DiscretePhase published_phase(double g);

/// The corrected form (default): P_ij = w_i K_ij with K symmetric, fitted so that every
/// column sums to 1 (energy conserved), isotropic radiance stays isotropic, the mean cosine
/// is g for every incoming direction, and P_ij = w_i at g = 0 (docs/lattice-boltzmann.md,
/// "The corrected form").
DiscretePhase corrected_phase(double g);

DiscretePhase make_phase(LbCollision form, double g);

/// Per-site, per-step lattice coefficients derived from the physical medium.
struct SiteCoefficients {
    double sigma_t = 0.0;  ///< physical extinction kappa * rho, 1/m
    double albedo = 1.0;
    double extinction[3] = {0, 0, 0};  ///< per direction class (rest, axis, diagonal): e_c
    double track[3] = {0, 0, 0};       ///< mean track length (m) in the voxel per arriving unit
    double hop[3] = {0, 0, 0};         ///< hop length (m): 0, h, sqrt(2) h
};

/// THE mapping from the physical medium to lattice coefficients (docs/design.md#lattice-coefficients): per direction
/// class, interaction probability e_j = 1 - exp(-kappa rho l_j) over the hop length l_j
/// (h or sqrt(2) h) and collision-estimator track e_j / sigma_t (m; l_j when rho = 0).
/// docs/lattice-boltzmann.md, "Physical mapping".
SiteCoefficients site_coefficients(const Medium& optics, double voxel_size, double density) noexcept;

/// Thick-voxel correction (LbThickVoxels::DiffusionMatched): scales the chord extinctions by
/// k >= 1 so that the lattice's diffusion coefficient per unit track is the medium's
/// 1 / (3 tau_tr); k is capped so that Omega's eigenvalues stay >= -2 kStabilityMargin.
/// Built once per solve from the discrete phase and the albedo; the derivation (a 2x2
/// first-moment solve, a quadratic in k) is in docs/lattice-boltzmann.md, "Thick voxels".
struct ThickVoxelModel {
    LbThickVoxels mode = LbThickVoxels::Saturate;
    double albedo = 1.0;
    double g = 0.0;               ///< the medium's asymmetry (for sigma_tr)
    double first_moment[2][2]{};  ///< P restricted to span{axis c_x, diagonal c_x}
    double p_min = 0.0;           ///< smallest eigenvalue of P (directions 1..18)
    double e_max = 1.0;           ///< stability cap on every e_j
    /// Physical asymptotic decay constant per unit optical depth, diffusion approximation
    /// sqrt(3 (1 - albedo)(1 - albedo g)) capped at 1 (pure absorber).
    double nu = 0.0;
};
/// Omega's eigenvalues stay >= -2 * kStabilityMargin under the diffusion-matched mapping.
inline constexpr double kStabilityMargin = 0.95;
/// The correction fades out (k -> 1, the chord mapping) between nu tau = kTaperStart and
/// kTaperEnd: voxels thicker than the diffusion length 1 / nu (site_coefficients()).
inline constexpr double kTaperStart = 1.0, kTaperEnd = 1.5;
/// The published collision form always gets the chord mapping (Saturate): the analysis needs
/// the corrected form's conserving, reversible P, and over-relaxing the published one diverges.
/// With the conservative model the cap is also (2 kStabilityMargin - 1) / (1 - albedo): its
/// rest direction gives Theta the eigenvalue -(1 - albedo) e in the isotropic mode.
ThickVoxelModel make_thick_voxel_model(LbThickVoxels mode, const DiscretePhase& phase, double albedo,
                                       LbAbsorption absorption = LbAbsorption::Physical);
/// Smallest eigenvalue of the discrete phase function P (directions 1..18; Jacobi on the
/// symmetrized W^-1/2 P W^1/2, exact for the corrected form, whose K is symmetric).
double phase_min_eigenvalue(const DiscretePhase& phase);
/// The lattice's diffusion coefficient (h^2 per step, per axis; for rho = sum_j f_j) and the
/// mean track per packet per step in units of h (for track_j = e_j / sigma_t: 1 / (Z tau_A)),
/// for uniform extinctions e_A, e_D in (0, 2) and hop optical depth tau_A = sigma_t h > 0.
struct LatticeDiffusion {
    double D = 0.0;
    double mean_track = 0.0;
};
LatticeDiffusion lattice_diffusion(const ThickVoxelModel& m, double eA, double eD, double tau_axis);
/// site_coefficients() with the thick-voxel model: Saturate gives exactly the exact-chord
/// mapping above; DiffusionMatched scales e_j (and the collision-estimator track
/// e_j / sigma_t with it) by k >= 1 as described at ThickVoxelModel.
SiteCoefficients site_coefficients(const Medium& optics, double voxel_size, double density,
                                   const ThickVoxelModel& thick) noexcept;

/// The paper's lattice units: one extinction probability sigma_t in [0, 1] for every
/// direction (clamped), h = 1, track = hop length. Used to reproduce Eqs. 4-6 and Eq. 19.
SiteCoefficients lattice_unit_coefficients(double sigma_t, double albedo) noexcept;

/// The full 19x19 collision matrix Theta for one site.
Matrix19 collision_matrix(const DiscretePhase& phase, const SiteCoefficients& c, LbAbsorption absorption);

/// The 14 distinct values of albedo * P_ij (float) used by the factored collision:
/// P_ij depends only on the classes of i and j and on c_i . c_j.
struct FactoredPhase {
    // output axis, input axis: same, opposite, perpendicular
    float aa_same, aa_opp, aa_perp;
    // output axis, input diagonal: c_i.c_j = +1, 0, -1
    float ad_pos, ad_zero, ad_neg;
    // output diagonal, input axis: +1, 0, -1
    float da_pos, da_zero, da_neg;
    // output diagonal, input diagonal: same (+2), opposite (-2), +1, 0, -1
    float dd_same, dd_opp, dd_pos, dd_zero, dd_neg;
};
/// Extracts and checks the factored values (asserts that P has the cubic structure) and
/// nudges the "same" entries so that the float column sums equal albedo * (double column
/// sum) as closely as float allows (no systematic energy drift in float32 kernels).
FactoredPhase factor_phase(const DiscretePhase& phase, double albedo);

/// Appendix A: resolves a unit light direction into lattice directions 1..18 (weights sum
/// to 1): repeatedly take the unused direction with the largest dot product n_i . L and
/// give it min(dot, remaining); stop when nothing remains. Uses normalized directions.
std::array<double, kQ> resolve_direction(const glm::dvec3& L);
/// The same among the directions q with allowed[q] only (e.g. the in-links of one face).
std::array<double, kQ> resolve_direction(const glm::dvec3& L, const std::array<bool, kQ>& allowed);

/// Discrete phase for an arbitrary output direction s: q_j = HG(s . n_j; g_s) /
/// (4 pi sum_k w_k HG(s . n_k; g_s)), so that sum_j 4 pi w_j q_j = 1, with g_s fitted so that
/// the discrete mean cosine sum_j 4 pi w_j q_j (s . n_j) equals g where the lattice can
/// represent it (saturates for directions between lattice directions at large |g|).
/// Then S(x, s) = albedo * sum_j q_j(s) T_j(x) / h^3, T_j the track of direction j.
std::array<double, kQ> output_phase(const glm::dvec3& s, double g);

}  // namespace fulgur::transport::lb
