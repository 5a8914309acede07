// fulgur::transport — light transport in the cloud, following DESIGN.md's physics contract.
//
// Physical parameterization (the only one in Fulgur):
//   density rho(x) in [0,1] on a voxel grid of spacing h (metres), piecewise constant per
//   voxel for every transport solver (so single scattering, Monte Carlo and the lattice see
//   exactly the same medium); sigma_t = kappa * rho (1/m), sigma_s = albedo * sigma_t;
//   Henyey-Greenstein phase function with parameter g.
//
// Stored quantity: the source function
//   S(x_i, s_m) = albedo * integral p(s_m . w') L(x_i, w') dw'        [W m^-2 sr^-1]
// on the lighting grid, for a set of output directions s_m. S_i is the *average over the
// voxel* centred at node i (a finite-volume value): this is what the lattice computes per
// site and what a Monte Carlo track-length estimator measures, and it regularizes the
// 1/r^2 singularity of a point light inside or next to a voxel (see single_scattering()).
// A unit virtual light is an isotropic point source of radiant intensity 1 W/sr
// (power 4*pi W).
#pragma once

#include "core/core.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace fulgur::transport {

/// Optical properties of the cloud material.
struct Medium {
    double extinction = 0.02;  ///< kappa: extinction per unit density, 1/m
    double albedo = 0.99;      ///< single-scattering albedo sigma_s / sigma_t, [0, 1]
    double g = 0.0;            ///< Henyey-Greenstein asymmetry, (-1, 1)
};

/// The medium every solver sees: piecewise-constant density on the lighting grid plus optics.
struct LightingMedium {
    core::Grid3<float> density;  ///< values in [0, 1]
    Medium optics;
    double sigma_t(std::size_t cell) const noexcept { return optics.extinction * double(density.data[cell]); }
};

// ---------------------------------------------------------------------------------------
// Henyey-Greenstein

/// Largest |g| the phase function is evaluated with. |g| = 1 is a delta distribution that
/// no finite sampling of directions can represent; inputs beyond the limit are clamped to
/// +-kMaxAbsG (documented behaviour, never NaN/Inf). Scene files reject |g| >= 1.
inline constexpr double kMaxAbsG = 0.9999;

/// HG phase function per steradian, normalized over the sphere:
///   p(cos) = (1 - g^2) / (4 pi ((1-g)^2 + 2g(1 - cos))^{3/2})
/// The denominator is written as (1-g)^2 + 2g(1-cos), which has no cancellation for
/// g -> 1 and cos -> 1 (unlike 1 + g^2 - 2g cos).
double hg_phase(double cos_theta, double g) noexcept;

/// Samples cos(theta) from HG exactly (inverse CDF, stable form), u in [0,1).
double hg_sample_cos(double g, double u) noexcept;

/// Samples a new propagation direction around `forward` (unit) with HG(g).
glm::dvec3 hg_sample(const glm::dvec3& forward, double g, double u1, double u2) noexcept;

/// Builds an orthonormal basis (t, b) perpendicular to unit n (Duff et al. 2017).
void orthonormal_basis(const glm::dvec3& n, glm::dvec3& t, glm::dvec3& b) noexcept;

// ---------------------------------------------------------------------------------------
// Output directions

/// The output directions s_m for S. Supported counts: 1 (isotropic scattering: S does not
/// depend on direction, the single direction is +z by convention), 6 (cube faces),
/// 18 (faces + edges), 26 (faces, edges and corners of a cube, as in Dobashi 2007).
/// Order: faces (+x,-x,+y,-y,+z,-z), then edges, then corners. Throws Error otherwise.
std::vector<glm::dvec3> output_directions(int count);

// ---------------------------------------------------------------------------------------
// Fields

/// S(x_i, s_m) on the lighting grid: data[m * cell_count + cell], float32, cell x-fastest.
struct SourceField {
    core::GridGeometry geom;
    std::vector<glm::dvec3> directions;
    std::vector<float> data;

    SourceField() = default;
    SourceField(const core::GridGeometry& g, std::vector<glm::dvec3> dirs)
        : geom(g), directions(std::move(dirs)), data(g.cell_count() * directions.size(), 0.0f) {}

    std::size_t cells() const noexcept { return geom.cell_count(); }
    std::span<float> direction(std::size_t m) noexcept { return {data.data() + m * cells(), cells()}; }
    std::span<const float> direction(std::size_t m) const noexcept { return {data.data() + m * cells(), cells()}; }
};

// =======================================================================================
// Lattice-Boltzmann (Geist et al. 2004): multiple scattering on a D3Q19 lattice whose
// sites are the voxels of the lighting grid. docs/lattice-boltzmann.md explains the model,
// the energy-conserving ("corrected") anisotropic collision, the physical mapping (see
// lb::site_coefficients in lb_collision.h) and the calibration of lattice densities to
// radiance. Results are in the same units as the Monte Carlo reference.
// =======================================================================================

/// Anisotropic collision normalization. Corrected (default): every column of the collision
/// matrix sums to 1 (energy is conserved exactly), isotropic radiance stays isotropic, and
/// the discrete mean cosine equals g for every incoming direction. Published: the paper's
/// row-sum normalization, kept for comparison; it creates energy for g != 0.
enum class LbCollision { Corrected, Published };

/// Where absorbed density goes. Physical (default): it leaves the system (what Monte Carlo
/// solves). Conservative: the paper's model, it enters the rest direction and is re-emitted
/// isotropically on the next step, so total density is conserved.
enum class LbAbsorption { Physical, Conservative };

/// Fast: in-place (AA-pattern) SoA float32 kernel with a factored collision, OpenMP.
/// Naive: the paper's Appendix B (dense 19x19 collision, separate streaming pass).
enum class LbKernel { Fast, Naive };

/// "corrected" | "published"; throws core::Error naming `where` otherwise.
LbCollision parse_lb_collision(std::string_view s, std::string_view where = "transport.lattice_boltzmann.collision");
/// "physical" | "conservative"; throws core::Error naming `where` otherwise.
LbAbsorption parse_lb_absorption(std::string_view s, std::string_view where = "transport.lattice_boltzmann.absorption");

struct LbSettings {
    LbCollision collision = LbCollision::Corrected;
    LbAbsorption absorption = LbAbsorption::Physical;
    LbKernel kernel = LbKernel::Fast;
    /// Steady state: stop when the relative change of the total lattice density per step
    /// (measured over two steps) and the change still to come (geometric extrapolation from
    /// successive increments) are both below this, or when the change reaches the float32
    /// noise floor (~1e-7 of the injected power). Because sources are constant and the
    /// lattice starts empty, every density grows monotonically, so the change of the total
    /// is also the relative L1 change of the whole field.
    double tolerance = 1e-4;
    int max_iterations = 4000;   ///< step cap (rounded up to an even number)
    bool record_history = false; ///< keep the total lattice density after every step
};

/// Isotropic point light of radiant intensity `intensity` (W/sr). Inside the grid it is
/// injected at the 8 nearest sites (trilinear weights); outside, as boundary inflow.
struct LbPointLight {
    glm::dvec3 position{0.0};
    double intensity = 1.0;
};

/// Directional light (sun): propagation direction (unit) and irradiance perpendicular to
/// it (W/m^2). Injected at the boundary, direction resolved into lattice directions with
/// the paper's Appendix A.
struct LbDirectionalLight {
    glm::dvec3 direction{0.0, 0.0, -1.0};
    double irradiance = 1.0;
};

struct LbSources {
    std::vector<LbPointLight> points;
    std::optional<LbDirectionalLight> sun;
    /// First-scattered source S1 on the lighting grid (same geometry): the lattice is fed
    /// with the volume emission of once-scattered light, sigma_t(x) * S1(x, s), and so
    /// computes orders >= 2 only. S1 needs 1 direction (isotropic) or one matching each of
    /// the 18 lattice directions (the 18- and 26-direction sets do).
    const SourceField* first_scattered = nullptr;
    /// Optional uncollided (direct) fluence phi1 (W/m^2) on the same grid. When given, the
    /// emitted power per voxel is made exactly sigma_s * phi1 * h^3 (the 18-direction
    /// quadrature of a peaked phase function is off by up to ~35% for g = 0.6).
    const core::Grid3<float>* first_scattered_fluence = nullptr;
};

struct LbResult {
    SourceField source;          ///< S(x_i, s_m) in W m^-2 sr^-1, voxel averages
    core::Grid3<float> fluence;  ///< phi(x_i) = integral L dw, W m^-2, voxel averages
    int iterations = 0;          ///< lattice steps taken
    bool converged = false;      ///< relative change fell below the tolerance
    double final_change = 0.0;   ///< relative change of the total density per step at the end
    double estimated_remaining = 0.0;  ///< extrapolated relative change still to come
    /// Energy bookkeeping in lattice units (W per step; stored: W * step), double sums:
    double injected_per_step = 0.0, absorbed_last_step = 0.0, escaped_last_step = 0.0;
    double injected_total = 0.0, absorbed_total = 0.0, escaped_total = 0.0, stored = 0.0;
    std::vector<double> total_density;  ///< per step, if settings.record_history
    double seconds = 0.0;               ///< wall time of the iteration
};

/// Solves multiple scattering on the lighting grid with the lattice-Boltzmann method and
/// returns S for `directions` (any unit vectors) and the fluence, calibrated to radiance
/// units (docs/lattice-boltzmann.md, "Units"). Throws core::Error on bad input (a source
/// field on another grid, non-finite parameters).
LbResult solve_lattice_boltzmann(const LightingMedium& medium, const LbSources& sources,
                                 std::span<const glm::dvec3> directions, const LbSettings& settings = {});

}  // namespace fulgur::transport
