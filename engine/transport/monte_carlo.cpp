// Monte Carlo reference solver on the LightingMedium grid: the grid medium (macro-cell
// majorants for delta tracking), the voxel tallies of S (track-length and expected-value
// estimators), and the batch driver (deterministic per seed for any thread count).
#include "transport/detail/kernels.h"
#include "transport/detail/monte_carlo_core.h"
#include "transport/detail/traversal.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace fulgur::transport {

namespace detail {

void check_mc_options(const MonteCarloOptions& o) {
    if (o.batches < 2)
        throw core::Error("monte_carlo.batches", "must be >= 2 (standard errors), got " + std::to_string(o.batches));
    if (o.paths < std::uint64_t(o.batches))
        throw core::Error("monte_carlo.paths",
                          "must be >= batches (" + std::to_string(o.batches) + "), got " + std::to_string(o.paths));
    if (!(o.roulette_threshold > 0.0 && o.roulette_threshold <= 1.0))
        throw core::Error("monte_carlo.roulette_threshold",
                          "must be in (0, 1], got " + std::to_string(o.roulette_threshold));
    if (o.max_scatterings < 0)
        throw core::Error("monte_carlo.max_scatterings", "must be >= 0, got " + std::to_string(o.max_scatterings));
    if (o.macro_cell < 0)
        throw core::Error("monte_carlo.macro_cell", "must be >= 0, got " + std::to_string(o.macro_cell));
    if (o.max_collisions < 1) throw core::Error("monte_carlo.max_collisions", "must be >= 1");
}

namespace {

/// The LightingMedium as a delta-tracking medium: the majorant is constant per macro-cell
/// (F^3 voxels, the max of sigma_t inside it); density lookups are clamped to the current
/// macro-cell so round-off at a macro-cell face can never exceed its majorant.
class GridMedium {
public:
    struct Walker {
        DdaWalker macro;
    };

    GridMedium(const LightingMedium& m, int macro_cell)
        : g_(m.density.geom), rho_(m.density.data.data()), kappa_(m.optics.extinction) {
        const core::Int3 n = g_.dims;
        F_ = macro_cell <= 0 ? std::max({n.x, n.y, n.z}) : macro_cell;
        macro_.dims = {(n.x + F_ - 1) / F_, (n.y + F_ - 1) / F_, (n.z + F_ - 1) / F_};
        macro_.voxel_size = g_.voxel_size * F_;
        macro_.origin = g_.origin;
        majorant_.assign(macro_.cell_count(), 0.0);
        for (int k = 0; k < n.z; ++k)
            for (int j = 0; j < n.y; ++j)
                for (int i = 0; i < n.x; ++i) {
                    double& mj = majorant_[macro_.index(i / F_, j / F_, k / F_)];
                    mj = std::max(mj, kappa_ * double(rho_[g_.index(i, j, k)]));
                }
    }

    bool start(Walker& w, const glm::dvec3& x, const glm::dvec3& d) const noexcept {
        double t0 = 0.0, t1 = kInf;
        if (!core::clip_ray_to_box(x, d, g_.origin, g_.upper(), t0, t1)) return false;
        return w.macro.start(macro_, x, d, t0, t1);
    }
    void segment(const Walker& w, double& t0, double& t1, double& sb) const noexcept {
        t0 = w.macro.t;
        t1 = w.macro.t_next();
        sb = majorant_[std::size_t(w.macro.cell)];
    }
    bool advance(Walker& w) const noexcept { return w.macro.advance(); }
    double sigma_t(const glm::dvec3& x, const Walker& w) const noexcept {
        const glm::dvec3 u = (x - g_.origin) / g_.voxel_size;
        const int mi[3] = {w.macro.i, w.macro.j, w.macro.k};
        const int n[3] = {g_.dims.x, g_.dims.y, g_.dims.z};
        int idx[3];
        for (int a = 0; a < 3; ++a) {
            const int lo = mi[a] * F_, hi = std::min(n[a], lo + F_) - 1;
            const double f = std::floor(u[a]);
            idx[a] = int(std::clamp(f, double(lo), double(hi)));
        }
        return kappa_ * double(rho_[g_.index(idx[0], idx[1], idx[2])]);
    }

private:
    core::GridGeometry g_;
    const float* rho_;
    double kappa_;
    int F_ = 1;
    core::GridGeometry macro_;
    std::vector<double> majorant_;
};

/// Voxel tallies of the integral of p(s_m . w) L dw dx (S without albedo / V), split into
/// order 1 and orders >= 2; layout [cell][m] so one voxel's directions are contiguous.
class GridTally {
public:
    GridTally(const LightingMedium& m, std::span<const glm::dvec3> dirs, bool expected_single, bool track_single,
              bool tally_multiple, double cutoff, double* single, double* multiple)
        : g_(&m.density.geom),
          rho_(m.density.data.data()),
          kappa_(m.optics.extinction),
          dirs_(dirs),
          hg_(m.optics.g),
          M_(dirs.size()),
          expected_single_(expected_single),
          track_single_(track_single),
          tally_multiple_(tally_multiple),
          cutoff_(cutoff),
          single_(single),
          multiple_(multiple),
          p_(dirs.size()) {}

    void uncollided(const glm::dvec3& x, const glm::dvec3& d, double w) {
        if (!expected_single_) return;
        phase(d);
        DdaWalker wk;
        if (!wk.start(*g_, x, d, 0.0, kInf)) return;
        double tau = 0.0;
        do {
            const double len = wk.t_next() - wk.t;
            const double sigma = kappa_ * double(rho_[wk.cell]);
            const double c = w * std::exp(-tau) * chord_integral(sigma, len);
            double* a = single_ + std::size_t(wk.cell) * M_;
            for (std::size_t m = 0; m < M_; ++m) a[m] += c * p_[m];
            tau += sigma * len;
            if (tau > cutoff_) break;
        } while (wk.advance());
    }

    void flight(const glm::dvec3& x, const glm::dvec3& d, double t0, double t1, double w, int k) {
        if (k == 0 ? !track_single_ : !tally_multiple_) return;
        if (!(t1 > t0)) return;
        phase(d);
        double* base = k == 0 ? single_ : multiple_;
        DdaWalker wk;
        if (!wk.start(*g_, x, d, t0, t1)) return;
        do {
            const double c = w * (wk.t_next() - wk.t);
            double* a = base + std::size_t(wk.cell) * M_;
            for (std::size_t m = 0; m < M_; ++m) a[m] += c * p_[m];
        } while (wk.advance());
    }

private:
    void phase(const glm::dvec3& d) {
        for (std::size_t m = 0; m < M_; ++m) p_[m] = hg_(glm::dot(dirs_[m], d));
    }

    const core::GridGeometry* g_;
    const float* rho_;
    double kappa_;
    std::span<const glm::dvec3> dirs_;
    HgConstants hg_;
    std::size_t M_;
    bool expected_single_, track_single_, tally_multiple_;
    double cutoff_;
    double* single_;
    double* multiple_;
    std::vector<double> p_;
};

/// Welford accumulation of a field over batches, element-wise, in batch order.
struct FieldStats {
    std::vector<double> mean, m2;
    int n = 0;
    void init(std::size_t size) {
        mean.assign(size, 0.0);
        m2.assign(size, 0.0);
    }
    void add(const std::vector<double>& x, double scale) {
        ++n;
        const double inv_n = 1.0 / n;
        const std::int64_t size = std::int64_t(mean.size());
        constexpr std::int64_t kChunk = 1 << 14;
        core::parallel_for(0, (size + kChunk - 1) / kChunk, [&](std::int64_t c) {
            const std::int64_t e = std::min(size, (c + 1) * kChunk);
            for (std::int64_t i = c * kChunk; i < e; ++i) {
                const double v = x[std::size_t(i)] * scale;
                const double dlt = v - mean[std::size_t(i)];
                mean[std::size_t(i)] += dlt * inv_n;
                m2[std::size_t(i)] += dlt * (v - mean[std::size_t(i)]);
            }
        });
    }
    /// Writes mean and SE into fields laid out [m][cell] from the [cell][m] accumulators.
    void write(SourceField& mean_out, SourceField& se_out) const {
        const std::size_t cells = mean_out.cells(), M = mean_out.directions.size();
        const double k = n > 1 ? 1.0 / (double(n) * double(n - 1)) : 0.0;
        for (std::size_t c = 0; c < cells; ++c)
            for (std::size_t m = 0; m < M; ++m) {
                mean_out.data[m * cells + c] = float(mean[c * M + m]);
                se_out.data[m * cells + c] = float(std::sqrt(std::max(0.0, m2[c * M + m]) * k));
            }
    }
};

template <class Emitter>
MonteCarloResult run_grid(const LightingMedium& medium, const Emitter& em, std::span<const glm::dvec3> directions,
                          const MonteCarloOptions& o) {
    validate_medium(medium);
    check_mc_options(o);
    if (directions.empty()) throw core::Error("directions", "at least one output direction is needed");
    std::vector<glm::dvec3> dirs;
    for (std::size_t m = 0; m < directions.size(); ++m) {
        const double len = glm::length(directions[m]);
        if (!std::isfinite(len) || !(len > 0.0))
            throw core::Error("directions[" + std::to_string(m) + "]", "must be a finite non-zero vector");
        dirs.push_back(directions[m] / len);
    }
    core::Stopwatch clock;
    const core::GridGeometry& g = medium.density.geom;
    const std::size_t cells = g.cell_count(), M = dirs.size(), size = cells * M;
    const GridMedium gm(medium, o.macro_cell);
    PathOptions po;
    po.albedo = medium.optics.albedo;
    po.g = medium.optics.g;
    po.max_scatterings = o.max_scatterings;
    po.implicit_capture = o.implicit_capture;
    po.roulette_threshold = o.roulette_threshold;
    po.max_collisions = o.max_collisions;
    const bool expected = o.single_estimator == MonteCarloOptions::SingleEstimator::ExpectedValue;
    const bool multiple = o.tally_multiple && o.max_scatterings > 0;
    constexpr double kCutoff = 104.0;  // same optical-depth cutoff as single_scattering's default

    const int T = std::max(1, core::thread_count());
    struct Buffer {
        std::vector<double> single, multiple;
        EnergyBatch energy;
    };
    std::vector<Buffer> bufs(static_cast<std::size_t>(T));
    FieldStats s1, sm;
    s1.init(size);
    if (multiple) sm.init(size);
    EnergyStats es;
    const double vol = g.voxel_size * g.voxel_size * g.voxel_size;
    for (int b0 = 0; b0 < o.batches; b0 += T) {
        const int nb = std::min(T, o.batches - b0);
        core::parallel_for(0, nb, [&](std::int64_t i) {
            Buffer& buf = bufs[std::size_t(i)];
            buf.single.assign(size, 0.0);
            if (multiple) buf.multiple.assign(size, 0.0);
            buf.energy = EnergyBatch{};
            const int b = b0 + int(i);
            GridTally tally(medium, dirs, expected, !expected, multiple, kCutoff, buf.single.data(),
                            multiple ? buf.multiple.data() : nullptr);
            trace_paths(gm, em, po, o.seed, batch_first_path(o.paths, o.batches, b), batch_paths(o.paths, o.batches, b),
                        tally, buf.energy);
        });
        for (int i = 0; i < nb; ++i) {
            const std::uint64_t np = batch_paths(o.paths, o.batches, b0 + i);
            const double scale = medium.optics.albedo / (vol * double(np));
            s1.add(bufs[std::size_t(i)].single, scale);
            if (multiple) sm.add(bufs[std::size_t(i)].multiple, scale);
            es.add(bufs[std::size_t(i)].energy, np);
        }
    }
    MonteCarloResult r;
    r.single = SourceField(g, dirs);
    r.single_se = SourceField(g, dirs);
    r.multiple = SourceField(g, dirs);
    r.multiple_se = SourceField(g, dirs);
    s1.write(r.single, r.single_se);
    if (multiple) sm.write(r.multiple, r.multiple_se);
    r.energy = es.tally();
    r.paths = o.paths;
    r.collisions = es.collisions;
    r.null_collisions = es.null_collisions;
    r.seconds = clock.seconds();
    return r;
}

}  // namespace
}  // namespace detail

MonteCarloResult monte_carlo(const LightingMedium& medium, const PointSource& light,
                             std::span<const glm::dvec3> directions, const MonteCarloOptions& options) {
    if (!std::isfinite(light.position.x) || !std::isfinite(light.position.y) || !std::isfinite(light.position.z))
        throw core::Error("light.position", "must be finite");
    if (!std::isfinite(light.intensity) || light.intensity < 0.0)
        throw core::Error("light.intensity", "must be finite and >= 0, got " + std::to_string(light.intensity));
    const detail::PointEmitter em{light.position, light.intensity};
    return detail::run_grid(medium, em, directions, options);
}

MonteCarloResult monte_carlo(const LightingMedium& medium, const DirectionalSource& sun,
                             std::span<const glm::dvec3> directions, const MonteCarloOptions& options) {
    const double len = glm::length(sun.direction);
    if (!std::isfinite(len) || !(len > 0.0)) throw core::Error("sun.direction", "must be a finite non-zero vector");
    if (!std::isfinite(sun.irradiance) || sun.irradiance < 0.0)
        throw core::Error("sun.irradiance", "must be finite and >= 0, got " + std::to_string(sun.irradiance));
    const core::GridGeometry& g = medium.density.geom;
    const detail::BoxSunEmitter em(g.origin, g.upper(), sun.direction / len, sun.irradiance);
    return detail::run_grid(medium, em, directions, options);
}

}  // namespace fulgur::transport
