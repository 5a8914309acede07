// fulgur::transport — light transport in the cloud, following the physics contract
// (docs/design.md#physics-contract).
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
#include "transport/sources.h"

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fulgur::transport {

/// Optical properties of the cloud material.
struct Medium {
    double extinction = 0.02;  ///< kappa: extinction per unit density, 1/m
    double albedo = 0.99;      ///< single-scattering albedo sigma_s / sigma_t, [0, 1]
    double g = 0.0;            ///< Henyey-Greenstein asymmetry, (-1, 1)
};

/// A second scatterer mixed into some cells (rain drops under a cloud) whose own phase function
/// S is read out with. Light is transported with Medium::g everywhere (the second scatterer
/// enters the density as cloud of the same transport coefficient: sky::rain_media_density);
/// what it changes is the last scattering, toward the viewer: in each cell S takes
///   (1 - share) p(s . w, Medium::g) + share p(s . w, g)
/// for the phase function. share is the second scatterer's part of the cell's scattering
/// coefficient, in [0, 1], on the grid S is computed (tallied) on.
struct PhaseMix {
    double g = 0.0;
    core::Grid3<float> share;
};

/// Throws core::Error naming the field when a mix is unusable: g not finite, a share that is
/// not finite or outside [0, 1] (names the cell), or a grid that is not `geom`.
void validate_phase_mix(const PhaseMix& mix, const core::GridGeometry& geom);

/// A second scatterer the Monte Carlo's paths carry exactly (rain drops under a cloud): the
/// medium's density holds it at its own extinction, and a collision in a voxel is the second
/// scatterer's with probability `share` (its part of the voxel's extinction), which then
/// weighs the path by its `albedo` and turns it with its phase function (HG `g`); otherwise
/// the medium's own optics. Where the share is 0 or 1 no random number is drawn, so a mix of
/// share 0 traces the paths of the medium alone and a mix of share 1 those of a medium with
/// the second's optics. The tally's S takes each voxel's albedo, (1 - share) medium's + share
/// `albedo` (PhaseMix gives its phase).
struct PathMix {
    double g = 0.0;
    double albedo = 1.0;
    core::Grid3<float> share;  ///< on the medium's own grid, in [0, 1]
};

/// Throws core::Error naming the field when a path mix is unusable: g or albedo not finite,
/// albedo outside [0, 1], a share outside [0, 1] (names the cell), or a grid that is not `geom`.
void validate_path_mix(const PathMix& mix, const core::GridGeometry& geom);

/// The medium every solver sees: piecewise-constant density on the lighting grid plus optics.
struct LightingMedium {
    core::Grid3<float> density;  ///< values in [0, 1]
    Medium optics;
    /// Set: S is read out with this second phase function where its share is > 0 (on this
    /// medium's grid): the lattice's read-out and single_scattering() honour it; a Monte Carlo
    /// run takes it as MonteCarloOptions::phase_mix, on its tally grid.
    std::shared_ptr<const PhaseMix> phase_mix = nullptr;
    /// Set: the Monte Carlo's paths scatter as PathMix says (the density then holds the second
    /// scatterer at its own extinction); the other solvers ignore it.
    std::shared_ptr<const PathMix> path_mix = nullptr;
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

/// The share of HG scattering into a direction whose z-component is `mu` that light arriving
/// from above (travelling downward) provides: the integral of hg_phase(w_i . w_s, g) over the
/// incident directions w_i with w_i.z < 0, for any w_s with w_s.z = mu; with `cos_power` n,
/// each incident direction weighted by |w_i.z|^n. A medium lit by a diffuse radiance L from
/// above scatters sigma_s L hg_from_above(mu, g) toward w_s (by L cos: hg_from_above(mu, g, 1)). By
/// symmetry hg_from_above(mu) + hg_from_above(-mu) = 1 and hg_from_above(0) = 1/2; g = 0 gives
/// 1/2 everywhere, g -> 1 a step (1 for mu < 0) (for n = 0). The azimuth is integrated in closed form (a
/// complete elliptic integral of the second kind), the incident zenith by composite Simpson
/// on 2048 intervals (within 1e-8 of a fine double sum for |g| <= 0.85, test_hg). mu is
/// clamped to [-1, 1]; cos_power must be in [0, 8].
double hg_from_above(double mu, double g, int cos_power = 0);

/// Samples cos(theta) from HG exactly (inverse CDF, stable form), u in [0,1).
double hg_sample_cos(double g, double u) noexcept;

/// Samples a new propagation direction around `forward` (unit) with HG(g).
glm::dvec3 hg_sample(const glm::dvec3& forward, double g, double u1, double u2) noexcept;

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

/// Block average of a field onto the grid coarser by `factor` per axis (same origin, dims
/// rounded up; a trailing partial block averages the voxels it has, as core::downsample).
SourceField block_average(const SourceField& fine, int factor);
/// A one-direction field (S toward a point: MonteCarloOptions::toward) copied into every one of
/// `directions`: whichever directions a renderer interpolates toward that point, it reads the
/// field itself.
SourceField in_every_direction(const SourceField& one, std::span<const glm::dvec3> directions);

// =======================================================================================
// Transmittance, single scattering and the Monte Carlo reference
//
// Light sources: PointSource and DirectionalSource (transport/sources.h).

/// Throws core::Error naming the field when the medium is unusable: extinction not finite
/// or < 0, albedo outside [0, 1], g not finite, a density that is not finite or outside
/// [0, 1] (names the voxel), or an invalid grid geometry. Every solver calls it.
void validate_medium(const LightingMedium& medium);

/// Optical depth integral(sigma_t) along the segment a -> b through the piecewise-constant
/// LightingMedium (density 0 outside the grid), by exact voxel traversal (3D DDA). Robust for
/// axis-parallel segments, endpoints on faces, edges or corners, endpoints outside the grid
/// and a == b (0). See engine/transport/detail/traversal.h for the conventions.
double optical_depth(const LightingMedium& medium, const glm::dvec3& a, const glm::dvec3& b) noexcept;

/// exp(-optical_depth(a, b)).
double transmittance(const LightingMedium& medium, const glm::dvec3& a, const glm::dvec3& b) noexcept;

/// Optical depth from x back to where a directional source's light enters the grid: along
/// -direction from x to the grid boundary (direction = propagation direction, unit).
double optical_depth_to_sun(const LightingMedium& medium, const glm::dvec3& x, const glm::dvec3& direction) noexcept;

/// Accuracy/time knobs of single_scattering(). docs/transport.md tabulates error vs time.
struct SingleScatteringOptions {
    /// THE accuracy knob: target relative quadrature error per voxel. Each voxel (or octree
    /// sub-box) gets the cheapest rule an a-priori error model says meets it: a tensor
    /// Gauss rule of order 1..4 (far, optically thin boxes; 1 node where nothing varies),
    /// a 2^3 split (boxes close to the source), or the exact-radial face rule (the voxels
    /// touching the source, and optically thick voxels) with more points per piece for a
    /// smaller tolerance. Range [1e-9, 0.5]. Shadow edges of upstream voxels are not in the
    /// model: docs/transport.md reports the error actually measured. The sun's: each voxel's
    /// entry faces refined adaptively until their pieces agree to tolerance x the voxel's
    /// integral (exact along the sun's direction), so the error follows the knob there too
    /// (to 1e-5: tighter acts as 1e-5).
    double tolerance = 1e-3;
    /// Transmittance is set to 0 once the optical depth exceeds this (e^-104 < 1e-45, the
    /// smallest float32: results are stored as float, so the default loses nothing for
    /// intensities up to ~1).
    double optical_depth_cutoff = 104.0;
    /// Skip (write 0 to) voxels with zero density whose 26 neighbours all have zero density:
    /// the renderer multiplies S by sigma_t and interpolates S trilinearly, so such voxels
    /// never reach an image. Off by default (the full radiance field is computed).
    bool skip_far_empty = false;
    /// With skip_far_empty: the emptiness test is made on blocks of this many voxels per axis
    /// (aligned with the grid's origin): a voxel is skipped when its block and the 26
    /// neighbouring blocks hold no density. 1: per voxel. A grid that refines a coarser one
    /// by r uses r, so every voxel of a coarse voxel that is computed is computed. [1, 64].
    int skip_block = 1;
    /// When set, also receives the voxel-averaged uncollided fluence phi1 (W/m^2) from the
    /// same quadrature (the weights without the phase function; no extra cost). Resized to
    /// the medium's grid. The lattice-Boltzmann solver takes it as first_scattered_fluence.
    core::Grid3<float>* uncollided_fluence = nullptr;
};

/// Exact single scattering (docs/design.md#direct-term) from a point source,
///   S1(x, s) = albedo * p(s . w_lx) * I * T(x_l, x) / |x - x_l|^2   [W m^-2 sr^-1],
/// averaged over each voxel: the voxel average is finite everywhere, including the voxel
/// holding the source (docs/transport.md, "The regularization of 1/r^2 is the voxel
/// average", and "Quadrature rules"). Writes S for out.directions into out (out.geom must
/// equal the medium's grid; data is resized). Parallel over voxels (core::thread_count()).
void single_scattering(const LightingMedium& medium, const PointSource& light, SourceField& out,
                       const SingleScatteringOptions& options = {});
SourceField single_scattering(const LightingMedium& medium, const PointSource& light,
                              std::span<const glm::dvec3> directions, const SingleScatteringOptions& options = {});

/// A brute-force reference for single_scattering() of a point source in one voxel, for tests
/// and benches: S averaged over `voxel` for each direction, the voxel cut into cells^3 equal
/// cells, each integrated by the same 3-point Gauss-Legendre tensor rule with exact DDA
/// transmittance to every node, cells near the light halved until they are far for their
/// size. Nothing of single_scattering()'s planning is shared, so it sees what that planning
/// misses (shadow edges crossing a voxel); it converges as the cells shrink (the difference
/// between `cells` and 2 `cells` bounds its own error). Cost: ~27 cells^3 rays, more in the
/// light's neighbourhood. Throws on a medium with a phase_mix, a voxel outside the grid or
/// cells outside [1, 256].
std::vector<double> single_scattering_reference(const LightingMedium& medium, const PointSource& light,
                                                std::span<const glm::dvec3> directions, core::Int3 voxel, int cells);
/// The same for the sun (no cells near a light to refine): the voxel's mean transmittance
/// toward the sun by the cells' Gauss nodes, times albedo E p(s . d) per direction s.
std::vector<double> single_scattering_reference(const LightingMedium& medium, const DirectionalSource& sun,
                                                std::span<const glm::dvec3> directions, core::Int3 voxel, int cells);

/// What single_scattering() of a point source would cost on one thread, measured on a sample
/// of its voxels (the quadrature's work per voxel depends on the tolerance, g and the density
/// near the light in ways no closed form bounds: at tolerance 1e-9 and g 0.9 a voxel can take
/// 8^5 sub-boxes). The sample: up to 1024 voxels evenly spaced in distance from the light
/// (which decides most of a voxel's cost), measured coarse to fine so a sample cut short by
/// `max_seconds` still spans every distance; the estimate is their mean times the voxels.
/// Deterministic in which voxels it measures; one voxel's work is bounded by the octree depth.
struct SingleScatteringCost {
    double seconds = 0.0;      ///< estimated time of the whole field on one thread
    std::size_t voxels = 0;    ///< voxels the field computes
    std::size_t measured = 0;  ///< voxels integrated to estimate it
    bool complete = true;      ///< false: max_seconds ran out before the whole sample was measured
};
SingleScatteringCost single_scattering_cost(const LightingMedium& medium, const PointSource& light,
                                            std::span<const glm::dvec3> directions,
                                            const SingleScatteringOptions& options, double max_seconds);

/// Single scattering of a directional source, voxel-averaged:
///   S1(x, s) = albedo * p(s . d) * E * T_sun(x),
/// T_sun the transmittance from where the light enters the grid to x.
void single_scattering(const LightingMedium& medium, const DirectionalSource& sun, SourceField& out,
                       const SingleScatteringOptions& options = {});
SourceField single_scattering(const LightingMedium& medium, const DirectionalSource& sun,
                              std::span<const glm::dvec3> directions, const SingleScatteringOptions& options = {});

// ---------------------------------------------------------------------------------------
// Monte Carlo reference solver

/// A Monte Carlo estimate and its standard error (from independent batches).
struct Estimate {
    double mean = 0.0;
    double se = 0.0;
};

/// Energy bookkeeping of a Monte Carlo run, in watts (means over batches, with SE).
/// Per path and exactly: emitted + roulette = absorbed + escaped + truncated.
struct EnergyTally {
    static constexpr int kOrders = 10;  ///< entries 0..8 are exact orders, entry 9 is ">= 9"
    Estimate emitted;                   ///< power the source sent (into all directions, hitting the grid or not)
    Estimate absorbed;                  ///< absorbed in the medium
    Estimate escaped;                   ///< left the medium (including light that never entered it)
    Estimate truncated;                 ///< weight of paths stopped by max_scatterings / max_collisions
    Estimate roulette;                  ///< net weight Russian roulette added (expectation 0)
    /// Escaped after exactly k scatterings (k = 0: uncollided).
    std::array<Estimate, kOrders> escaped_by_order{};
    /// Absorbed at the (k+1)-th collision, i.e. after exactly k scatterings.
    std::array<Estimate, kOrders> absorbed_by_order{};

    /// Mean power scattered at least once: truncated + sum over k >= 1 of absorbed and
    /// escaped after k scatterings. What a multiple-scattering solver fed with the
    /// first-scattered light must be given (the lattice's injected power is checked against it).
    double scattered_mean() const noexcept {
        double p = truncated.mean;
        for (std::size_t k = 1; k < std::size_t(kOrders); ++k)
            p += absorbed_by_order[k].mean + escaped_by_order[k].mean;
        return p;
    }
    /// Mean power that escaped after at least one scattering.
    double escaped_scattered_mean() const noexcept {
        double p = 0.0;
        for (std::size_t k = 1; k < std::size_t(kOrders); ++k) p += escaped_by_order[k].mean;
        return p;
    }
};

/// A horizontal ground plane and the square cells on it where Monte Carlo tallies the light
/// that reaches the plane after scattering at least once (MonteCarloOptions::ground): what the
/// cloud's own scattered light gives the ground under a flash. The ground is taken as black
/// for the transport (a path is tallied where it first crosses the plane downward, and its
/// tracing goes on as if the plane were not there).
struct GroundTally {
    double height = 0.0;     ///< z of the plane (m)
    glm::dvec2 origin{0.0};  ///< lower corner (x, y) of cell (0, 0), metres
    double cell = 1000.0;    ///< cell size (m)
    int nx = 0, ny = 0;      ///< cells along x and y, each in [1, 4096]; at most 2^22 in all
    std::size_t cells() const noexcept { return std::size_t(std::max(nx, 0)) * std::size_t(std::max(ny, 0)); }
};

/// Throws core::Error naming the bad field (`where`.height, .origin, .cell, .nx, .ny).
void validate_ground_tally(const GroundTally& g, const std::string& where = "monte_carlo.ground");

/// Square cells of the plane z = `height` under the footprint of `lighting` and `margin`
/// metres around it: two lighting voxels wide (the light a cloud base a kilometre or more up
/// sends down varies over kilometres), or wider where that would take more than `max_side`
/// (in [1, 4096]) cells along a side. Always covers the footprint and margin.
GroundTally ground_cells_around(const core::GridGeometry& lighting, double height, double margin, int max_side);

/// Irradiance on a GroundTally's cells: W/m^2 averaged over each cell, x fastest ([j nx + i]).
struct GroundIrradiance {
    GroundTally cells;
    std::vector<float> data;
    bool empty() const noexcept { return data.empty(); }
    /// The power the cells receive, W (compensated sum of irradiance x cell area).
    double power() const noexcept;
};

struct MonteCarloOptions {
    std::uint64_t paths = 1'000'000;  ///< photon paths in total (split evenly over batches)
    int batches = 32;                 ///< independent batches (>= 2) for standard errors
    std::uint64_t seed = 1;           ///< results depend only on (seed, paths, batches), not on threads
    /// Order-1 estimator. ExpectedValue: each emitted ray deposits its *expected* uncollided
    /// track length T_in (1 - e^{-sigma l}) / sigma in every voxel it crosses (no zero
    /// estimates behind thick voxels; an angular Monte Carlo quadrature of single
    /// scattering). TrackLength: the analog flight sampled by delta tracking deposits its
    /// length (validates delta tracking; noisier).
    enum class SingleEstimator { ExpectedValue, TrackLength };
    SingleEstimator single_estimator = SingleEstimator::ExpectedValue;
    /// Scattering events followed per path. The flight after the last allowed scattering is
    /// still traced, so S up to order max_scatterings + 1 and escape after exactly
    /// max_scatterings scatterings are complete; the remaining weight is `truncated`.
    /// 0: only uncollided light (order-1 S). Default: unlimited.
    int max_scatterings = std::numeric_limits<int>::max();
    /// Implicit capture: every collision scatters with weight *= albedo and deposits
    /// weight * (1 - albedo) as absorbed (lower variance); false: analog absorption.
    bool implicit_capture = true;
    /// Russian roulette below this fraction of the emitted weight: survive with probability
    /// weight / threshold and continue with weight = threshold (unbiased).
    double roulette_threshold = 0.05;
    /// Delta-tracking majorant per macro-cell of this many voxels per axis; 0 = one majorant
    /// for the whole grid. Empty macro-cells are skipped without sampling.
    int macro_cell = 4;
    /// Safety stop per path (counted as `truncated`; never reached in practice).
    std::uint64_t max_collisions = 100'000'000;
    /// Estimate orders >= 2 (the `multiple` field). false: only order 1 is tallied
    /// (ProgressiveMonteCarlo::result() then leaves `multiple` empty, in each group too).
    bool tally_multiple = true;
    /// Estimate order 1 (the `single` field). false: a run for orders >= 2 only, whose paths
    /// then skip order 1's expected-value deposit (about a third of a path's cost in a storm
    /// cloud), and whose result() leaves `single` empty, in each group too. Only
    /// ProgressiveMonteCarlo honours it; monte_carlo() always tallies order 1.
    bool tally_single = true;
    /// Also estimate the noise of the result from two independent halves of the batches
    /// (MonteCarloResult::noise; needs batches >= 4; two more fields of memory).
    bool halves = false;
    /// What a tally cell's S averages over: its Volume (the finite-volume value every solver
    /// stores), or its Extinction, sigma_t-weighted (the emission sigma_t S a renderer draws
    /// from the cell, when the tally grid is coarser than the medium; equal to Volume where
    /// density is uniform in the cell; cells with no density fall back to Volume).
    enum class TallyWeight { Volume, Extinction };
    TallyWeight tally_weight = TallyWeight::Volume;
    /// Source groups tallied apart (MonteCarloResult::groups; line sources name theirs). 1: one.
    int groups = 1;
    /// Also tally the uncollided fluence phi1 (W/m^2, voxel averages; expected-value estimator
    /// only), what the lattice takes as first_scattered_fluence.
    bool tally_fluence = false;
    /// Only the expected-value order-1 estimate: paths are not traced past their emission
    /// (their weight is counted as truncated). Needs max_scatterings 0 and tally_multiple false.
    bool uncollided_only = false;
    /// Orders 1 and 2 only, both by the expected-value estimator: after the first scattering
    /// the path's next flight deposits its expected track (no second collision is sampled)
    /// into `multiple`, which then holds exactly order 2, and the path stops (its weight
    /// counted as truncated). With tally_fluence, `fluence2` receives the order-2 fluence.
    /// Needs the expected-value estimator and tally_multiple. For a lattice fed with order 2.
    bool expected_second_order = false;
    /// Set: S toward this point (metres) instead of along fixed directions. Each tally cell's
    /// one output direction is from its centre to the point, so a camera standing there reads S
    /// with no interpolation between directions (a still shot's exact S_cam). `directions` must
    /// then hold exactly one direction, which the result's fields carry as their label (the
    /// renderer takes a one-direction field as S toward the camera). The point must be finite.
    std::optional<glm::dvec3> toward;
    /// Set: also tally the light that reaches this ground plane after scattering at least once
    /// (MonteCarloResult::ground, analog: each path deposits its weight where it first crosses
    /// the plane downward, after one scattering or more). The uncollided light is left out: a
    /// renderer lights the ground with the channel directly. Needs paths traced past their first
    /// scattering (not uncollided_only nor expected_second_order).
    std::optional<GroundTally> ground;
    /// Set: S is tallied with this second phase function where its share is > 0 (PhaseMix; the
    /// share on the tally grid). The paths still scatter with the medium's g.
    const PhaseMix* phase_mix = nullptr;
    /// ProgressiveMonteCarlo: the tally cells its noise is measured over (non-zero: measured;
    /// one per tally cell), e.g. the cloud's alone where the medium also holds rain. Null: the
    /// cells holding density (MonteCarloMedium::cloud). monte_carlo() ignores it.
    const std::vector<std::uint8_t>* noise_cells = nullptr;
};

struct MonteCarloResult {
    SourceField single;       ///< order 1: S from unscattered light, voxel-averaged
    SourceField multiple;     ///< orders >= 2
    SourceField single_se;    ///< standard error of `single`, per voxel and direction
    SourceField multiple_se;  ///< standard error of `multiple`
    EnergyTally energy;
    std::uint64_t paths = 0;
    std::uint64_t collisions = 0;       ///< real collisions (scattering or absorption events)
    std::uint64_t null_collisions = 0;  ///< rejected tentative collisions of delta tracking
    double seconds = 0.0;
    /// With MonteCarloOptions::halves: relative L2 noise of single, multiple and their sum
    /// over the cloud voxels (tally cells holding density > 0) and all directions, from the
    /// means A, B of the two halves of the batches: ||A - B|| sqrt(na nb) / (na + nb) / ||mean||
    /// (the standard error of the mean of all batches). 0 otherwise.
    struct Noise {
        double single = 0.0, multiple = 0.0, total = 0.0;
    } noise;
    /// The sums of `single` and of `multiple` over the cloud (tally cells holding density > 0)
    /// and every direction, each with its standard error from the batches: the noise of a
    /// whole-cloud total (a ratio of totals), which the relative L2 noise overstates.
    /// monte_carlo() only (zero from ProgressiveMonteCarlo).
    struct CloudSums {
        Estimate single, multiple;
    } sums;
    /// With MonteCarloOptions::tally_fluence: the uncollided fluence (sum over the groups),
    /// and with expected_second_order the order-2 fluence (W/m^2, voxel averages).
    core::Grid3<float> fluence, fluence2;
    /// With MonteCarloOptions::groups > 1: each group's part (single, multiple, fluence), in
    /// group order; `single` and `multiple` above are their sums, and the per-voxel SE fields
    /// stay zero (paths are shared out between groups at random: use `noise`).
    /// With MonteCarloOptions::ground: the irradiance of the scattered light on the ground's
    /// cells (sum over the groups), and the power the cells received with its standard error
    /// from the batches.
    GroundIrradiance ground;
    Estimate ground_power;
    struct Group {
        SourceField single, multiple;
        core::Grid3<float> fluence, fluence2;
        GroundIrradiance ground;
    };
    std::vector<Group> groups;
};

/// Monte Carlo photon tracing in the LightingMedium (delta tracking with macro-cell
/// majorants, exact HG sampling, implicit capture + Russian roulette, track-length
/// estimators). Multithreaded over batches; deterministic per seed for any thread count.
MonteCarloResult monte_carlo(const LightingMedium& medium, const PointSource& light,
                             std::span<const glm::dvec3> directions, const MonteCarloOptions& options = {});
MonteCarloResult monte_carlo(const LightingMedium& medium, const DirectionalSource& sun,
                             std::span<const glm::dvec3> directions, const MonteCarloOptions& options = {});
/// The sun's light through `medium` (the full-resolution density: the truth of static light)
/// tallied as voxel averages on `tally_grid`, a coarsening of the medium's grid by an integer
/// factor (as the frame overload below). With tally_grid equal to the medium's grid this is the
/// overload above (same paths, same numbers); on a coarser grid each cell is the volume average
/// of the fine cells' tallies.
MonteCarloResult monte_carlo(const LightingMedium& medium, const DirectionalSource& sun,
                             const core::GridGeometry& tally_grid, std::span<const glm::dvec3> directions,
                             const MonteCarloOptions& options = {});
/// The sky dome's light, as the sun's above: every path enters the grid's box from a direction
/// drawn with probability proportional to the dome's radiance times the box's area seen from
/// it (exactly, by rejection from tabulated bounds), on the faces that direction sees.
MonteCarloResult monte_carlo(const LightingMedium& medium, const DomeSource& sky, const core::GridGeometry& tally_grid,
                             std::span<const glm::dvec3> directions, const MonteCarloOptions& options = {});

/// The truth of a set of sources (a frame's lightning channel): Monte Carlo through `medium`
/// at full resolution (the scene's density grid, not the lighting grid), S tallied as voxel
/// averages on `tally_grid`, a coarsening of the medium's grid by an integer factor with the
/// same origin and dims rounded up (the lighting grid; its box may extend past the medium's,
/// where the medium is empty). Line sources are sampled exactly (uniformly along their
/// length), not as points. Paths start on a source chosen with probability proportional to
/// its intensity. Sources of intensity 0 are skipped; none left: all zero. With one point
/// source and tally_grid equal to the medium's grid this is exactly the single-source
/// overload (same paths, same numbers).
MonteCarloResult monte_carlo(const LightingMedium& medium, std::span<const PointSource> points,
                             std::span<const LineSource> lines, const core::GridGeometry& tally_grid,
                             std::span<const glm::dvec3> directions, const MonteCarloOptions& options = {});

/// A medium made ready for tracing frames' sources onto a tally grid (ProgressiveMonteCarlo):
/// its delta-tracking majorants and the map from its voxels to the tally grid's, built once
/// (a pass over the full-resolution density) and shared by every run over it. Keeps a
/// reference to `medium` (it must outlive this and every run made from it).
class MonteCarloMedium {
public:
    /// `tally_grid` as for monte_carlo(medium, points, lines, tally_grid, ...): a coarsening of
    /// the medium's grid by an integer factor. Throws core::Error naming the bad field.
    MonteCarloMedium(const LightingMedium& medium, const core::GridGeometry& tally_grid, int macro_cell = 4);
    ~MonteCarloMedium();
    MonteCarloMedium(const MonteCarloMedium&) = delete;
    MonteCarloMedium& operator=(const MonteCarloMedium&) = delete;
    const LightingMedium& medium() const noexcept;
    const core::GridGeometry& tally_grid() const noexcept;
    /// Tally cells holding some density (where noise and errors are measured).
    const std::vector<std::uint8_t>& cloud() const noexcept;

private:
    friend class ProgressiveMonteCarlo;
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Monte Carlo of a set of sources traced a little at a time, for an estimate that improves
/// while it is shown (a strike nobody scheduled: runtime::InstantStrikes). The tallies of
/// monte_carlo(medium, points, lines, tally_grid, ...), with four differences: the noise's two
/// halves are two independent runs (own seeds), each advance() adding half its paths to each,
/// so result().noise exists after the first call; tallies are pooled over all paths so far
/// (every path weighs the same, whatever the call that traced it); each half's emissions
/// (source, place along a line, direction) follow a randomly shifted low-discrepancy sequence
/// (detail::KroneckerSequence) rather than independent draws, unbiased and far less noisy for
/// order 1, whose deposit is a deterministic function of the emission; the result depends on
/// the seed and the sequence of advance() sizes, not on the thread count. Volume-weighted
/// tallies only. Keeps a reference to `medium`; copies the sources.
class ProgressiveMonteCarlo {
public:
    /// Validates like monte_carlo() (core::Error names the bad field); options.paths,
    /// batches, halves, tally_weight and macro_cell are not used (advance() says how many
    /// paths; the medium holds the majorants).
    ProgressiveMonteCarlo(const MonteCarloMedium& medium, std::span<const PointSource> points,
                          std::span<const LineSource> lines, std::span<const glm::dvec3> directions,
                          const MonteCarloOptions& options);
    ~ProgressiveMonteCarlo();
    ProgressiveMonteCarlo(const ProgressiveMonteCarlo&) = delete;
    ProgressiveMonteCarlo& operator=(const ProgressiveMonteCarlo&) = delete;
    /// Starts over with other sources and seed (same medium, directions and options), keeping
    /// the memory: what a solver that traces one strike after another reuses (a fresh run
    /// touches ~tens of MB for the first time, which costs more than its first paths).
    void restart(std::span<const PointSource> points, std::span<const LineSource> lines, std::uint64_t seed);
    /// Traces `paths` more paths (>= 2): two batches, over core::thread_count() threads.
    void advance(std::uint64_t paths);
    std::uint64_t paths() const noexcept;
    /// The estimate from every path so far: groups (with options.groups > 1; all of them, zero
    /// where no source emits), single and multiple, and their noise from the two halves; no
    /// per-voxel standard errors (single_se, multiple_se empty). All zero before the first
    /// advance() or when nothing emits.
    MonteCarloResult result() const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

// =======================================================================================
// Lattice-Boltzmann (Geist et al. 2004): multiple scattering on a D3Q19 lattice whose
// sites are the voxels of the lighting grid. docs/lattice-boltzmann.md explains the model,
// the energy-conserving ("corrected") anisotropic collision, the physical mapping (see
// lb::site_coefficients in detail/lb_collision.h) and the calibration of lattice densities to
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

/// How the lattice treats voxels thicker than a mean free path (docs/lattice-boltzmann.md,
/// "Thick voxels"). Saturate: the exact-chord mapping e_j = 1 - exp(-sigma_t l_j), which
/// saturates at one collision per voxel crossing (light diffuses out of optically thick
/// voxels too fast). DiffusionMatched (default): e_j scaled up by k >= 1 (over-relaxation
/// where needed, capped so that Omega's eigenvalues stay >= -1.9) so that the lattice's
/// diffusion coefficient per unit track equals the physical 1 / (3 sigma_tr); the
/// collision-estimator track e_j / sigma_t keeps absorption per unit track exact.
enum class LbThickVoxels { Saturate, DiffusionMatched };

/// Fast: in-place (AA-pattern) SoA float32 kernel with a factored collision, OpenMP.
/// Naive: the paper's Appendix B (dense 19x19 collision, separate streaming pass).
enum class LbKernel { Fast, Naive };

/// "corrected" | "published"; throws core::Error naming `where` otherwise.
LbCollision parse_lb_collision(std::string_view s, std::string_view where = "transport.lattice_boltzmann.collision");
/// "physical" | "conservative"; throws core::Error naming `where` otherwise.
LbAbsorption parse_lb_absorption(std::string_view s, std::string_view where = "transport.lattice_boltzmann.absorption");
/// "saturate" | "diffusion_matched"; throws core::Error naming `where` otherwise.
LbThickVoxels parse_lb_thick_voxels(std::string_view s,
                                    std::string_view where = "transport.lattice_boltzmann.thick_voxels");

namespace lb {
class Kernel;  // transport/detail/lb_solver.h (internal)
struct Problem;
}  // namespace lb

struct LbSettings {
    LbCollision collision = LbCollision::Corrected;
    LbAbsorption absorption = LbAbsorption::Physical;
    LbThickVoxels thick_voxels = LbThickVoxels::DiffusionMatched;
    LbKernel kernel = LbKernel::Fast;
    /// Steady state: stop when the relative change of the total lattice density per step
    /// (measured over two steps) and the change still to come (geometric extrapolation from
    /// successive increments) are both below this, or when the change reaches the float32
    /// noise floor (~1e-7 of the injected power). Because sources are constant and the
    /// lattice starts empty, every density grows monotonically, so the change of the total
    /// is also the relative L1 change of the whole field.
    double tolerance = 1e-4;
    int max_iterations = 4000;    ///< step cap (rounded up to an even number)
    bool record_history = false;  ///< keep the total lattice density after every step
    /// Makes the kernel that steps the lattice in place of the fast one (kernel Fast only):
    /// one process's part of a lattice decomposed over several (distributed::
    /// static_light_settings). It must step bit-identically to the fast kernel and report the
    /// whole lattice's figures (lb::Kernel::gather_all). Unset: the fast kernel of this process.
    std::function<std::unique_ptr<lb::Kernel>(const lb::Problem&)> make_kernel;
};

struct LbSources {
    /// Point sources: inside the grid each is injected at the 8 nearest sites (trilinear
    /// weights); outside, as boundary inflow.
    std::vector<PointSource> points;
    /// The sun: injected at the boundary, its direction resolved into lattice directions with
    /// the paper's Appendix A.
    std::optional<DirectionalSource> sun;
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
    SourceField source;                ///< S(x_i, s_m) in W m^-2 sr^-1, voxel averages
    core::Grid3<float> fluence;        ///< phi(x_i) = integral L dw, W m^-2, voxel averages
    int iterations = 0;                ///< lattice steps taken
    bool converged = false;            ///< relative change fell below the tolerance
    double final_change = 0.0;         ///< relative change of the total density per step at the end
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
