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
#include <span>
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

}  // namespace fulgur::transport
