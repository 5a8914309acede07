// Lattice-Boltzmann driver: builds the lattice problem from the physical medium and the
// light sources, steps a kernel to steady state and converts densities to radiance units.
#include "transport/detail/lb_solver.h"
#include "transport/detail/kernels.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

namespace fulgur::transport::lb {

Problem Problem::uniform(core::Int3 dims, const SiteCoefficients& c, const DiscretePhase& phase,
                         LbAbsorption absorption) {
    Problem p;
    p.dims = dims;
    p.absorption = absorption;
    p.albedo = c.albedo;
    p.phase = phase;
    p.ext_axis.assign(dims.volume(), float(c.extinction[kAxis]));
    p.ext_diag.assign(dims.volume(), float(c.extinction[kDiagonal]));
    return p;
}

std::array<double, kQ> Problem::add_source(std::size_t site, const std::array<double, kQ>& e,
                                           const SiteCoefficients& c) {
    // Emission spread uniformly over the voxel: along direction j it crosses on average half
    // the chord, so a fraction Tbar_j = (1 - exp(-tau_j)) / tau_j leaves uncollided; the rest
    // collides in the voxel (scattered with the lattice's phase, absorbed with 1 - albedo).
    std::array<double, kQ> out{}, track{};
    double absorbed = 0.0, raw = 0.0;
    for (int j = 1; j < kQ; ++j) {
        const double ej = e[std::size_t(j)];
        if (ej == 0.0) continue;
        FULGUR_ASSERT(std::isfinite(ej) && ej >= 0.0, "source emission must be finite and non-negative");
        raw += ej;
        const int k = dir_class(j);
        const double tau = c.sigma_t * c.hop[k];
        const double Tbar = tau > 1e-12 ? -std::expm1(-tau) / tau : 1.0 - 0.5 * tau;
        const double coll = (1.0 - Tbar) * ej;
        out[std::size_t(j)] += Tbar * ej;
        for (int i = 1; i < kQ; ++i) out[std::size_t(i)] += c.albedo * phase.P[std::size_t(i)][std::size_t(j)] * coll;
        absorbed += (1.0 - c.albedo) * coll;
        track[std::size_t(j)] = tau > 1e-12 ? coll / c.sigma_t : 0.5 * c.hop[k] * ej;
    }
    if (absorption == LbAbsorption::Conservative)
        out[0] += absorbed;
    else
        source_absorbed_per_step += absorbed;
    emission_per_step += raw;
    // The published phase does not conserve: count what actually leaves the site.
    if (phase.form != LbCollision::Corrected) {
        double sum = 0.0;
        for (double v : out) sum += v;
        emission_per_step += sum + (absorption == LbAbsorption::Conservative ? 0.0 : absorbed) - raw;
    }
    Source s{site, {}};
    for (int q = 0; q < kQ; ++q) s.out[std::size_t(q)] = float(out[std::size_t(q)]);
    sources.push_back(s);
    return track;
}

std::unique_ptr<Kernel> make_kernel(const Problem& p, LbKernel kind) {
    return kind == LbKernel::Naive ? make_naive_kernel(p) : make_fast_kernel(p);
}

Simulation::Simulation(const Problem& p, LbKernel kind) : problem_(p), kernel_(make_kernel(problem_, kind)) {
    injected_ = problem_.inflow_per_step;  // the first inflow is in place at t = 0
}

Simulation::Simulation(const Problem& p, std::unique_ptr<Kernel> kernel) : problem_(p), kernel_(std::move(kernel)) {
    injected_ = problem_.inflow_per_step;
}

void Simulation::step() {
    kernel_->step();
    injected_ += problem_.emission_per_step + problem_.inflow_per_step;
    absorbed_ += kernel_->last_absorbed();
    escaped_ += kernel_->last_escaped();
}

void Simulation::step_two(double* first_total) {
    Kernel::StepResult a, b;
    kernel_->two_steps(a, b);
    const double per_step = problem_.emission_per_step + problem_.inflow_per_step;
    injected_ += per_step;
    absorbed_ += a.absorbed;
    escaped_ += a.escaped;
    injected_ += per_step;
    absorbed_ += b.absorbed;
    escaped_ += b.escaped;
    if (first_total) *first_total = a.total;
}

bool Simulation::run(double tolerance, int max_steps, std::vector<double>* history) {
    max_steps += max_steps % 2;
    double prev2 = kernel_->last_total(), prev1 = prev2, prev_delta = 0.0;
    converged_ = false;
    const double per_step = problem_.emission_per_step + problem_.inflow_per_step;
    while (steps() < max_steps) {
        // Steps go in pairs from an even step (one sweep in the fast kernel); the test
        // below runs after even steps anyway.
        if (steps() % 2 == 0 && steps() + 2 <= max_steps) {
            double first = 0.0;
            step_two(&first);
            if (history) history->push_back(first);
            if (!std::isfinite(first)) break;
            prev1 = first;
        } else {
            step();
        }
        const double total = kernel_->last_total();
        if (history) history->push_back(total);
        if (!std::isfinite(total)) break;
        if (steps() % 2 != 0) {
            prev1 = total;
            continue;
        }
        // Change per step measured over two steps, so that a period-2 oscillation (the rest
        // ping-pong of the conservative model at sigma_t = 1, albedo 0) can neither hide
        // convergence nor fake it.
        const double delta = std::fabs(total - prev2);
        last_change_ = total != 0.0 ? delta / (2.0 * std::fabs(total)) : 0.0;
        // Geometric tail: with a per-step ratio r of successive increments the remaining
        // change is last_change * r / (1 - r); slow modes (strong back-scattering, thick
        // high-albedo media) would otherwise stop far from the steady state.
        double remaining = 0.0;
        if (prev_delta > 0.0 && delta > 0.0) {
            const double r = std::sqrt(delta / prev_delta);
            remaining = r < 1.0 ? last_change_ * r / (1.0 - r) : std::numeric_limits<double>::infinity();
        }
        estimated_remaining_ = remaining;
        prev_delta = delta;
        prev2 = total;
        (void)prev1;
        // float32 densities: the per-step balance carries ~1e-7 relative rounding of the
        // injected power, so changes below that floor are noise, not transport.
        const double floor = total != 0.0 ? 1e-6 * per_step / std::fabs(total) : 0.0;
        if (steps() >= 4 && (std::max(last_change_, remaining) < tolerance || last_change_ < floor)) {
            converged_ = true;
            break;
        }
    }
    return converged_;
}

}  // namespace fulgur::transport::lb

namespace fulgur::transport {

using namespace lb;

namespace {

// Index of the source-field direction equal to lattice direction q, or -1.
int match_direction(const SourceField& f, int q) {
    const Velocity& c = kVelocity[std::size_t(q)];
    const glm::dvec3 n = glm::dvec3(c.x, c.y, c.z) / hop_length(q);
    for (std::size_t m = 0; m < f.directions.size(); ++m)
        if (glm::dot(glm::normalize(f.directions[m]), n) > 1.0 - 1e-9) return int(m);
    return -1;
}

// Boundary inflow from a light outside the grid: for each face cell of an open face whose
// inward normal faces the light, the power crossing the cell (I times the cell's exact solid
// angle for a point, E * A * (L . n) for the sun) is spread over the in-links crossing that
// face with the Appendix A weights of the local light direction (towards the cell centre).
// The medium between an outside light and the grid is vacuum (density 0 outside).
void add_boundary_light(Problem& p, const core::GridGeometry& g, const glm::dvec3* point, double intensity,
                        const glm::dvec3* sun_dir, double irradiance) {
    const core::Int3 d = g.dims;
    const double h = g.voxel_size;
    const double area = h * h;
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side < 2; ++side) {
            if (p.boundary[std::size_t(axis)] == Boundary::Periodic) continue;  // no face to enter through
            glm::dvec3 n_in(0.0);
            n_in[axis] = side == 0 ? 1.0 : -1.0;
            const int u = (axis + 1) % 3, v = (axis + 2) % 3;
            const int du = (&d.x)[u], dv = (&d.x)[v];
            for (int b = 0; b < dv; ++b)
                for (int a = 0; a < du; ++a) {
                    int ijk[3];
                    ijk[axis] = side == 0 ? 0 : (&d.x)[axis] - 1;
                    ijk[u] = a;
                    ijk[v] = b;
                    glm::dvec3 fc = g.centre(ijk[0], ijk[1], ijk[2]);
                    fc[axis] = side == 0 ? g.origin[axis] : g.upper()[axis];
                    glm::dvec3 L;
                    double power;
                    if (point) {
                        // Exact solid angle of the face cell seen from the light (also for a
                        // light on the face plane, where it tends to 2 pi for the cell under it).
                        const double dist = (fc[axis] - (*point)[axis]) * n_in[axis];  // >= 0 if the light is outside
                        if (dist < 0.0) continue;
                        const double u0 = fc[u] - 0.5 * h - (*point)[u], u1 = u0 + h;
                        const double v0 = fc[v] - 0.5 * h - (*point)[v], v1 = v0 + h;
                        auto F = [dist](double p1, double p2) {
                            return std::atan2(p1 * p2, dist * std::sqrt(p1 * p1 + p2 * p2 + dist * dist));
                        };
                        const double omega = F(u1, v1) - F(u0, v1) - F(u1, v0) + F(u0, v0);
                        if (!(omega > 0.0)) continue;
                        power = intensity * omega;
                        const glm::dvec3 r = fc - *point;
                        L = glm::dot(r, r) > 0.0 ? glm::normalize(r) : n_in;
                        if (glm::dot(L, n_in) <= 0.0) L = n_in;  // grazing: enter along the normal
                    } else {
                        L = *sun_dir;
                        const double cosn = glm::dot(L, n_in);
                        if (cosn <= 0.0) continue;
                        power = irradiance * area * cosn;
                    }
                    auto f = resolve_direction(L);
                    double sum = 0.0;
                    std::array<bool, kQ> crossing{};
                    for (int q = 1; q < kQ; ++q) {
                        const Velocity& c = kVelocity[std::size_t(q)];
                        const int cn = axis == 0 ? c.x : (axis == 1 ? c.y : c.z);
                        crossing[std::size_t(q)] = (side == 0 ? cn : -cn) > 0;
                        if (crossing[std::size_t(q)]) sum += f[std::size_t(q)];
                    }
                    if (sum <= 0.0) {
                        // The decomposition of L uses no link crossing this face (L grazes it:
                        // e.g. (0.42, -0.32, -0.85) resolves onto (1,0,-1) and (0,0,-1), none
                        // entering through a y face): resolve L among this face's in-links, or
                        // the power crossing the face would be lost.
                        f = resolve_direction(L, crossing);
                        for (int q = 1; q < kQ; ++q)
                            if (crossing[std::size_t(q)]) sum += f[std::size_t(q)];
                    }
                    if (sum <= 0.0) continue;
                    const std::size_t site = p.index(ijk[0], ijk[1], ijk[2]);
                    for (int q = 1; q < kQ; ++q) {
                        const Velocity& c = kVelocity[std::size_t(q)];
                        const int cn = axis == 0 ? c.x : (axis == 1 ? c.y : c.z);
                        if ((side == 0 ? cn : -cn) <= 0 || f[std::size_t(q)] <= 0.0) continue;
                        const float val = float(power * f[std::size_t(q)] / sum);
                        p.inflow.push_back({site, q, val});
                        p.inflow_per_step += double(val);
                    }
                }
        }
}

void check_finite(double v, const char* where) {
    if (!std::isfinite(v)) throw core::Error(where, "must be finite");
}

}  // namespace

LbResult solve_lattice_boltzmann(const LightingMedium& medium, const LbSources& sources,
                                 std::span<const glm::dvec3> directions, const LbSettings& settings) {
    return lb::solve(medium, sources, directions, settings, {Boundary::Open, Boundary::Open, Boundary::Open});
}

}  // namespace fulgur::transport

namespace fulgur::transport::lb {

namespace {

/// Rejects an invalid medium, settings or output direction with an error naming the field.
void validate_inputs(const LightingMedium& medium, std::span<const glm::dvec3> directions, const LbSettings& settings) {
    const core::GridGeometry& g = medium.density.geom;
    core::validate_geometry(g, "lattice_boltzmann: lighting grid");
    if (medium.density.data.size() != g.cell_count())
        throw core::Error("lattice_boltzmann: density", "holds " + std::to_string(medium.density.data.size()) +
                                                            " values for " + std::to_string(g.cell_count()) +
                                                            " voxels");
    check_finite(medium.optics.extinction, "lattice_boltzmann: medium.extinction");
    check_finite(medium.optics.albedo, "lattice_boltzmann: medium.albedo");
    check_finite(medium.optics.g, "lattice_boltzmann: medium.g");
    if (medium.optics.extinction < 0.0) throw core::Error("lattice_boltzmann: medium.extinction", "must be >= 0");
    if (medium.optics.albedo < 0.0 || medium.optics.albedo > 1.0)
        throw core::Error("lattice_boltzmann: medium.albedo", "must be in [0, 1]");
    if (!(std::fabs(medium.optics.g) < 1.0)) throw core::Error("lattice_boltzmann: medium.g", "must be in (-1, 1)");
    if (!(settings.tolerance >= 0.0)) throw core::Error("lattice_boltzmann: tolerance", "must be >= 0");
    if (settings.max_iterations < 1) throw core::Error("lattice_boltzmann: max_iterations", "must be >= 1");
    for (const auto& d : directions)
        if (!(glm::length(d) > 0.0) || !std::isfinite(glm::length(d)))
            throw core::Error("lattice_boltzmann: directions", "output directions must be finite non-zero vectors");
}

/// The lattice problem of the medium (extinction per site, albedo, phase) and the
/// coefficients of each site (`coef`, one per voxel).
Problem make_problem(const LightingMedium& medium, const LbSettings& settings, std::array<Boundary, 3> boundary,
                     std::vector<SiteCoefficients>& coef) {
    const core::GridGeometry& g = medium.density.geom;
    const double h = g.voxel_size;
    const std::size_t n = g.cell_count();
    Problem p;
    p.dims = g.dims;
    p.boundary = boundary;
    p.absorption = settings.absorption;
    p.albedo = std::clamp(medium.optics.albedo, 0.0, 1.0);
    p.phase = make_phase(settings.collision, medium.optics.g);
    p.ext_axis.resize(n);
    p.ext_diag.resize(n);
    const ThickVoxelModel thick = make_thick_voxel_model(settings.thick_voxels, p.phase, p.albedo, settings.absorption);
    coef = std::vector<SiteCoefficients>(n);
    for (std::size_t i = 0; i < n; ++i) {
        const float rho = medium.density.data[i];
        if (!std::isfinite(rho) || rho < 0.0f)
            throw core::Error("lattice_boltzmann: density",
                              "voxel " + std::to_string(i) + " is negative or not finite");
        coef[i] = site_coefficients(medium.optics, h, double(rho), thick);
        p.ext_axis[i] = float(coef[i].extinction[kAxis]);
        p.ext_diag[i] = float(coef[i].extinction[kDiagonal]);
    }
    return p;
}

/// Own-voxel tracks of the sources (m * W per direction), for the fluence: (site, tracks).
using SourceTracks = std::vector<std::pair<std::size_t, std::array<double, kQ>>>;

/// The light sources' emission, accumulated per site and lattice direction before it enters
/// the problem: point lights inside the grid and the first-scattered source emit at sites;
/// point lights outside the grid and the sun enter as boundary inflow.
struct Emission {
    Problem& p;
    const core::GridGeometry& g;
    std::vector<std::array<double, kQ>> emission;  // accumulated raw emission per site
    std::vector<std::int64_t> emission_index;

    Emission(Problem& problem, const core::GridGeometry& grid)
        : p(problem), g(grid), emission_index(grid.cell_count(), -1) {}

    void emit(std::size_t site, int q, double power) {
        if (emission_index[site] < 0) {
            emission_index[site] = std::int64_t(emission.size());
            emission.push_back({});
        }
        emission[std::size_t(emission_index[site])][std::size_t(q)] += power;
    }

    void add_point_lights(const std::vector<PointSource>& points) {
        for (std::size_t li = 0; li < points.size(); ++li) {
            const PointSource& L = points[li];
            check_finite(L.intensity, "lattice_boltzmann: point light intensity");
            check_finite(L.position.x + L.position.y + L.position.z, "lattice_boltzmann: point light position");
            if (L.intensity < 0.0) throw core::Error("lattice_boltzmann: point light intensity", "must be >= 0");
            if (L.intensity == 0.0) continue;
            if (g.contains(L.position)) {
                // Trilinear weights over the 8 nearest voxel centres (clamped at the faces).
                const glm::dvec3 u = g.to_voxel(L.position) - 0.5;
                int i0[3];
                double fr[3];
                const int dd[3] = {g.dims.x, g.dims.y, g.dims.z};
                for (int a = 0; a < 3; ++a) {
                    const double v = std::clamp(u[a], 0.0, double(dd[a] - 1));
                    i0[a] = std::min(int(std::floor(v)), dd[a] - 1);
                    fr[a] = v - double(i0[a]);
                }
                const double power = 4.0 * std::numbers::pi * L.intensity;
                for (int c = 0; c < 8; ++c) {
                    int ijk[3];
                    double wgt = 1.0;
                    for (int a = 0; a < 3; ++a) {
                        const int bit = (c >> a) & 1;
                        ijk[a] = std::min(i0[a] + bit, dd[a] - 1);
                        wgt *= bit ? fr[a] : 1.0 - fr[a];
                    }
                    if (wgt <= 0.0) continue;
                    const std::size_t site = p.index(ijk[0], ijk[1], ijk[2]);
                    for (int q = 1; q < kQ; ++q) emit(site, q, wgt * power * weight(q));
                }
            } else {
                add_boundary_light(p, g, &L.position, L.intensity, nullptr, 0.0);
            }
        }
    }

    void add_sun(const DirectionalSource& sun) {
        const glm::dvec3 dir = sun.direction;
        check_finite(sun.irradiance, "lattice_boltzmann: sun irradiance");
        if (!(glm::length(dir) > 0.0) || !std::isfinite(glm::length(dir)))
            throw core::Error("lattice_boltzmann: sun direction", "must be a finite non-zero vector");
        const glm::dvec3 L = glm::normalize(dir);
        add_boundary_light(p, g, nullptr, 0.0, &L, sun.irradiance);
    }

    /// First-scattered source: emission sigma_t S1 h^3 4 pi w_q per lattice direction (V = h^3),
    /// rescaled to sigma_s phi1 V per site when the uncollided fluence phi1 is given.
    void add_first_scattered(const SourceField& S1, const core::Grid3<float>* phi1,
                             const std::vector<SiteCoefficients>& coef, double V) {
        const std::size_t n = g.cell_count();
        if (!(S1.geom == g))
            throw core::Error("lattice_boltzmann: first_scattered", "source field grid differs from the lighting grid");
        if (S1.data.size() != S1.cells() * S1.directions.size() || S1.directions.empty())
            throw core::Error("lattice_boltzmann: first_scattered",
                              "source field data size does not match its directions");
        int map[kQ] = {};
        const bool iso = S1.directions.size() == 1;
        for (int q = 1; q < kQ; ++q) {
            map[q] = iso ? 0 : match_direction(S1, q);
            if (map[q] < 0)
                throw core::Error("lattice_boltzmann: first_scattered",
                                  "needs 1 direction or one equal to each lattice direction (the 18 or 26 set), got " +
                                      std::to_string(S1.directions.size()));
        }
        if (phi1 && !(phi1->geom == g && phi1->data.size() == n))
            throw core::Error("lattice_boltzmann: first_scattered_fluence", "grid differs from the lighting grid");
        for (std::size_t i = 0; i < n; ++i) {
            const double st = coef[i].sigma_t;
            if (st <= 0.0) continue;
            std::array<double, kQ> e{};
            double sum = 0.0;
            for (int q = 1; q < kQ; ++q) {
                const float s = S1.direction(std::size_t(map[q]))[i];
                if (!std::isfinite(s) || s < 0.0f)
                    throw core::Error("lattice_boltzmann: first_scattered",
                                      "voxel " + std::to_string(i) + " holds a negative or non-finite value");
                e[std::size_t(q)] = st * V * 4.0 * std::numbers::pi * weight(q) * double(s);
                sum += e[std::size_t(q)];
            }
            if (sum <= 0.0) continue;
            if (phi1) {
                const double target = p.albedo * st * double(phi1->data[i]) * V;  // sigma_s phi1 V
                for (double& v : e) v *= target / sum;
            }
            for (int q = 1; q < kQ; ++q) emit(i, q, e[std::size_t(q)]);
        }
    }

    /// Adds the accumulated emission to the problem as sources, in site order; returns their
    /// own-voxel tracks.
    SourceTracks add_to_problem(const std::vector<SiteCoefficients>& coef) {
        SourceTracks source_tracks;
        for (std::size_t i = 0; i < emission_index.size(); ++i)
            if (emission_index[i] >= 0)
                source_tracks.emplace_back(i, p.add_source(i, emission[std::size_t(emission_index[i])], coef[i]));
        return source_tracks;
    }
};

/// Steps `sim` to steady state (an even number of steps) and records the iteration and the
/// energy balance in `res` (`watch` started before the kernel was built).
void iterate(Simulation& sim, const Problem& p, const LbSettings& settings, const core::Stopwatch& watch,
             LbResult& res) {
    sim.run(settings.tolerance, std::max(2, settings.max_iterations),
            settings.record_history ? &res.total_density : nullptr);
    if (sim.steps() % 2) sim.step();  // (run() already stops on even steps)
    res.seconds = watch.seconds();
    res.iterations = sim.steps();
    res.converged = sim.converged();
    res.final_change = sim.last_change();
    res.estimated_remaining = sim.estimated_remaining();
    res.injected_per_step = p.emission_per_step + p.inflow_per_step;
    res.absorbed_last_step = sim.kernel().last_absorbed();
    res.escaped_last_step = sim.kernel().last_escaped();
    res.injected_total = sim.injected_total();
    res.absorbed_total = sim.absorbed_total();
    res.escaped_total = sim.escaped_total();
}

/// The fast kernel's stored() (after an even step) from every site's arriving densities
/// (index site * kQ + q): the same terms added in the same order (direction by direction, rows
/// in z, y order, each row's sum first), so the same double bit for bit.
double stored_of(std::span<const float> arriving, const Problem& p) {
    const int q0 = p.absorption == LbAbsorption::Conservative ? 0 : 1;
    const std::size_t nx = std::size_t(p.dims.x), rows = std::size_t(p.dims.y) * std::size_t(p.dims.z);
    double total = 0.0;
    for (int q = q0; q < kQ; ++q)
        for (std::size_t r = 0; r < rows; ++r) {
            const float* a = &arriving[r * nx * kQ + std::size_t(q)];
            double row = 0.0;
            for (std::size_t x = 0; x < nx; ++x) row += double(a[x * kQ]);
            total += row;
        }
    return total;
}

/// Densities -> tracks -> fluence and S (docs/lattice-boltzmann.md, "Units"), into `res`.
/// `arriving(site, q)`: the lattice's arriving density.
template <class Arriving>
void read_out(const Arriving& arriving, const Problem& p, const LightingMedium& medium,
              std::span<const glm::dvec3> directions, const std::vector<SiteCoefficients>& coef,
              const SourceTracks& source_tracks, double V, LbResult& res) {
    const core::GridGeometry& g = medium.density.geom;
    const std::size_t n = g.cell_count();
    std::vector<std::array<double, kQ>> out_phase(directions.size());
    for (std::size_t m = 0; m < directions.size(); ++m) out_phase[m] = output_phase(directions[m], medium.optics.g);
    // A second scatterer's phase (PhaseMix): S's read-out in a cell is linear in the phase, so
    // the two read-outs are mixed by the cell's share.
    const PhaseMix* mix = medium.phase_mix.get();
    std::vector<std::array<double, kQ>> mix_phase(mix ? directions.size() : 0);
    for (std::size_t m = 0; m < mix_phase.size(); ++m) mix_phase[m] = output_phase(directions[m], mix->g);
    res.source = SourceField(g, std::vector<glm::dvec3>(directions.begin(), directions.end()));
    for (auto& d : res.source.directions) d = glm::normalize(d);
    res.fluence = core::Grid3<float>(g, 0.0f);
    std::vector<std::int64_t> track_index(n, -1);
    for (std::size_t k = 0; k < source_tracks.size(); ++k) track_index[source_tracks[k].first] = std::int64_t(k);
    const double inv_V = 1.0 / V;
    const std::int64_t total = std::int64_t(n);
    core::parallel_for(0, total, [&](std::int64_t ii) {
        const std::size_t i = std::size_t(ii);
        const SiteCoefficients& c = coef[i];
        double T[kQ] = {};
        double phi = 0.0;
        for (int q = 1; q < kQ; ++q) {
            T[q] = double(arriving(i, q)) * c.track[dir_class(q)];
            if (track_index[i] >= 0) T[q] += source_tracks[std::size_t(track_index[i])].second[std::size_t(q)];
            phi += T[q];
        }
        res.fluence.data[i] = float(phi * inv_V);
        const double share = mix ? double(mix->share.data[i]) : 0.0;
        for (std::size_t m = 0; m < directions.size(); ++m) {
            double s = 0.0;
            for (int q = 1; q < kQ; ++q) s += out_phase[m][std::size_t(q)] * T[q];
            if (share > 0.0) {
                double s2 = 0.0;
                for (int q = 1; q < kQ; ++q) s2 += mix_phase[m][std::size_t(q)] * T[q];
                s = transport::detail::mixed_phase(s, s2, share);
            }
            res.source.data[m * n + i] = float(p.albedo * s * inv_V);
        }
    });
}

}  // namespace

LbResult solve(const LightingMedium& medium, const LbSources& sources, std::span<const glm::dvec3> directions,
               const LbSettings& settings, std::array<Boundary, 3> boundary) {
    validate_inputs(medium, directions, settings);
    const core::GridGeometry& g = medium.density.geom;
    const double h = g.voxel_size;
    const double V = h * h * h;
    std::vector<SiteCoefficients> coef;
    Problem p = make_problem(medium, settings, boundary, coef);

    Emission emission(p, g);
    emission.add_point_lights(sources.points);
    if (sources.sun) emission.add_sun(*sources.sun);
    if (sources.first_scattered)
        emission.add_first_scattered(*sources.first_scattered, sources.first_scattered_fluence, coef, V);
    const SourceTracks source_tracks = emission.add_to_problem(coef);

    LbResult res;
    core::Stopwatch watch;
    // A kernel made elsewhere (a slab of the lattice decomposed over processes) stands in for
    // the fast kernel: it steps bit-identically and gathers the lattice for the read-out.
    const bool elsewhere = settings.make_kernel && settings.kernel == LbKernel::Fast;
    Simulation sim = elsewhere ? Simulation(p, settings.make_kernel(p)) : Simulation(p, settings.kernel);
    iterate(sim, p, settings, watch, res);
    const std::vector<float> all = sim.kernel().gather_all();
    if (all.empty()) {
        res.stored = sim.kernel().stored();
        const Kernel& K = sim.kernel();
        read_out([&K](std::size_t i, int q) { return K.arriving(i, q); }, p, medium, directions, coef, source_tracks, V,
                 res);
    } else {
        FULGUR_ASSERT(all.size() == p.sites() * std::size_t(kQ), "lb::solve: a gathered lattice of another size");
        res.stored = stored_of(all, p);
        read_out([&all](std::size_t i, int q) { return all[i * kQ + std::size_t(q)]; }, p, medium, directions, coef,
                 source_tracks, V, res);
    }
    return res;
}

}  // namespace fulgur::transport::lb
