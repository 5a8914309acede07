// fulgur::transport — multiple scattering by flux-limited diffusion through a cloud's own
// density, with an anisotropic source function rebuilt from the diffusion's flux.
//
// The light scattered once or more by a cloud (fluence phi, flux F) from a first-scattered
// emission q (W/m^3, e.g. a sigma_t phi1 of point sources, first_scattered_emission()) solves
//   -div(D grad phi) + sigma_a phi = q,   F = -D grad phi,
// on the grid's cells with density > 0. D is Levermore-Pomraning's flux-limited diffusivity
//   D = lambda(R) / sigma_tr,  R = |grad phi| / (sigma_tr phi),  lambda = (2 + R) / (6 + 3R + R^2),
// sigma_tr = sigma_t (1 - a g): 1 / (3 sigma_tr) where the light diffuses, and |F| <= phi where
// the cloud is thin and light streams (plain diffusion spreads it too far there). The limiter is
// lagged: a plain solve, then `limiter_passes` solves with R from the previous one. Faces toward
// a clear voxel or the grid's edge take Marshak's vacuum condition (phi 0 at 2D beyond the face).
// Finite volumes with the harmonic mean of D across a face; conjugate gradients with a Jacobi
// preconditioner on the cloud's cells only.
//
// The source function of that light in a direction w (diffusion_source()) is not isotropic: near
// a lightning channel it is dominated by the light streaming away from it. The radiance is taken
// as a Henyey-Greenstein lobe along F with mean cosine |F| / phi (which has exactly that flux),
// and the phase function applied to it (two HG lobes compose to one with the product of their
// g's, exactly in the first moment):
//   S(w) = a phi p_HG(w . F / |F|, g |F| / phi).
// On the default storm's strikes this is the step that matters: the truth's own multiple part
// made isotropic is 34% off itself, its best a + b . w fit 11% (docs/presets.md).
#pragma once

#include "transport/transport.h"

#include <glm/vec3.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace fulgur::transport {

/// Settings of solve_diffusion().
struct DiffusionOptions {
    /// Solves with the flux limiter after the plain one (0: plain diffusion). On the default
    /// storm's strikes (source function along F) 1, 2 and 4 passes give 27.8%, 28.1% and 28.7%
    /// worst in the instant path's first frame, 2 the best on dusk-storm and vdb-cloud (18.7%,
    /// 27.6%); the lagged limiter gains nothing from more (docs/presets.md).
    int limiter_passes = 2;
    /// Relative residual each conjugate-gradient solve stops at: 1e-3 and 1e-6 give the same
    /// errors against the truth to 0.1 points in half the iterations.
    double tolerance = 1e-3;
    /// Iterations allowed per solve (work bounded before it starts); a solve that reaches it
    /// reports converged = false.
    int max_iterations = 2000;
};

/// The diffused light on a medium's grid: fluence phi (W/m^2) and flux F = -D grad phi (W/m^2)
/// per cell, zero outside the cloud.
struct DiffusionField {
    core::GridGeometry geom;
    std::vector<float> fluence;
    std::vector<glm::vec3> flux;
    int iterations = 0;     ///< conjugate-gradient iterations over every solve
    bool converged = true;  ///< every solve reached the tolerance
};

/// The diffused light of `emission` (W/m^3 per cell of m's grid, cell-major; asserts its size).
/// Non-finite or negative emission counts as none. Deterministic.
DiffusionField solve_diffusion(const LightingMedium& m, std::span<const double> emission,
                               const DiffusionOptions& options = {});

/// Adds w x S of `field` (a phi p_HG(dir . F^, g |F| / phi); its mean over the sphere is
/// a phi / (4 pi)) in each of `directions` to `out` ([m][cell] on field's grid; asserts its size).
void add_diffusion_source(const LightingMedium& m, const DiffusionField& field, std::span<const glm::dvec3> directions,
                          double w, std::span<float> out);

/// The first-scattered emission a sigma_t phi1 (W/m^3 per cell) of point sources, phi1 their
/// uncollided fluence, by `rays` rays cast from each (a Fibonacci sphere turned by a rotation
/// hashed from `seed` and the source's index, so that neighbouring sources' rays do not run
/// parallel), marched in steps of a quarter voxel through the grid until their optical depth
/// passes 30: phi1's voxel average is I sum exp(-tau) dr dOmega / V. Added to `emission`
/// (sized here when empty). Sources with a non-finite position or intensity add nothing.
/// Asserts rays in [1, 65536]. Deterministic.
void add_first_scattered_emission(const LightingMedium& m, std::span<const PointSource> sources, int rays,
                                  std::uint64_t seed, std::vector<double>& emission);

/// The same cast adding also the sources' single scattering S1 in each of `directions` to
/// `single` ([m][cell], sized here when empty): its voxel average a I sum p(u . w) exp(-tau) dr
/// dOmega / V, the rays reaching as far as the emission's. With no lighting-grid bases beside it
/// this is the whole single scattering (docs/presets.md: 11-26% against the truth on the default
/// storm's strikes at 32 rays, where exact single scattering on the same grid gives 3-20%).
void add_point_scattering(const LightingMedium& m, std::span<const PointSource> sources, int rays, std::uint64_t seed,
                          std::span<const glm::dvec3> directions, std::vector<double>& emission,
                          std::vector<double>& single);

/// The same points' single scattering S1 and first-scattered emission a sigma_t phi1 on the
/// grid `onto`, by rays marched voxel by voxel through a finer density `fine` (the cloud at its
/// full resolution, same optics; exact transmittance of its piecewise-constant density) until
/// their optical depth passes 30, S1 and the emission averaged over each of `onto`'s cells by
/// volume, as the truth tallies S: a I sum p(u . w) exp(-tau) ds dOmega / V. Where a lighting
/// cell's density varies within it (the cloud's base and edges) the channel's light is cut off
/// where the cloud is, not where the cell's mean is: on the default storm's strikes 2.7-8.9%
/// single against the truth at 128 rays, where the lighting grid's own cast gives 4-21%
/// (docs/presets.md). Rays are marched inside `fine`'s box; `onto`'s cells outside it stay
/// unlit. Rays turned as add_first_scattered_emission's. `onto_density` (optional): the density
/// on `onto`, zero only where all of `fine`'s within the cell is (the lighting grid's box
/// average): on grids that nest, rays then cross its clear cells a cell at a time instead of
/// voxel by voxel, the same sums to round-off. Asserts rays in [1, 65536].
void add_point_scattering_fine(const LightingMedium& fine, const core::GridGeometry& onto,
                               std::span<const PointSource> sources, int rays, std::uint64_t seed,
                               std::span<const glm::dvec3> directions, std::vector<double>& emission,
                               std::vector<double>& single, const core::Grid3<float>* onto_density = nullptr);

}  // namespace fulgur::transport
