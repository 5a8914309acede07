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
#include <numbers>
#include <string>
#include <vector>

namespace fulgur::transport {

namespace detail {

void check_mc_options(const MonteCarloOptions& o) {
    if (o.halves && o.batches < 4)
        throw core::Error("monte_carlo.batches",
                          "must be >= 4 for a noise estimate from two halves, got " + std::to_string(o.batches));
    if (o.batches < 2)
        throw core::Error("monte_carlo.batches", "must be >= 2 (standard errors), got " + std::to_string(o.batches));
    if (o.expected_second_order && (o.single_estimator != MonteCarloOptions::SingleEstimator::ExpectedValue ||
                                    o.max_scatterings < 1 || !o.tally_multiple || o.uncollided_only))
        throw core::Error("monte_carlo.expected_second_order",
                          "needs the expected-value estimator, max_scatterings >= 1 and the multiple tally");
    if (o.uncollided_only && (o.single_estimator != MonteCarloOptions::SingleEstimator::ExpectedValue ||
                              o.max_scatterings != 0 || o.tally_multiple))
        throw core::Error("monte_carlo.uncollided_only",
                          "needs the expected-value estimator, max_scatterings 0 and no multiple tally");
    if (o.groups < 1 || o.groups > 4096)
        throw core::Error("monte_carlo.groups", "must be in [1, 4096], got " + std::to_string(o.groups));
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
    if (o.toward && !(std::isfinite(o.toward->x) && std::isfinite(o.toward->y) && std::isfinite(o.toward->z)))
        throw core::Error("monte_carlo.toward", "must be a finite point");
    if (o.ground) {
        validate_ground_tally(*o.ground);
        if (o.uncollided_only || o.expected_second_order)
            throw core::Error("monte_carlo.ground",
                              "tallies scattered light: needs paths traced past their first scattering (not "
                              "uncollided_only nor expected_second_order)");
    }
}

namespace {

constexpr double kPathCutoff = 104.0;  // same optical-depth cutoff as single_scattering's default

/// The albedo a Monte Carlo run's S is scaled by at the end: the medium's, or where the
/// medium scatters nothing and a path mix's second scatterer does, the second's (GridTally
/// weighs each voxel's deposits by its own albedo over this one).
double tally_albedo(const LightingMedium& m) noexcept {
    return m.path_mix && !(m.optics.albedo > 0.0) ? m.path_mix->albedo : m.optics.albedo;
}

/// Where S is tallied: the medium's own grid, or a coarsening of it by an integer factor with
/// the same origin (the truth of a frame: the full-resolution density, S on the lighting
/// grid). The coarse box may extend past the medium's (a trailing partial block); the medium
/// is empty there. What a tally cell holds is the average of S over the cell weighted by
/// `weight` (MonteCarloOptions::TallyWeight): by volume, or by extinction (cells without
/// any density fall back to volume).
struct TallyGrid {
    core::GridGeometry geom;
    bool coarse = false;              ///< tallied on a coarsening of the medium's grid
    std::vector<std::uint8_t> cloud;  ///< tally cell holds some medium density > 0
    bool extinction = false;          ///< weight by extinction
    std::vector<double> weight;       ///< per medium cell, when extinction: sigma_t, or 1 off the cloud
    std::vector<double> inv_norm;     ///< per tally cell: 1 / integral of the weight over the cell
    /// The medium's density in 8^3 bricks (brick-major, x fastest within and across bricks):
    /// a ray's walk reads it from a few kilobytes per brick instead of a plane apart per step
    /// in z, which decides the speed of the expected-value walks on a large grid.
    std::vector<float> bricked;
    /// Per axis, medium index -> its part of a linear index: of the tally cell (`tally_axis`)
    /// and of the bricked density (`brick_axis`). Summing three table entries replaces a
    /// per-cell lookup table (one more cache miss per step) and integer divisions.
    std::vector<std::size_t> tally_axis[3], brick_axis[3];
    /// With a path mix whose albedo is not the medium's: a voxel's deposits to S are weighed by
    /// f = albedo_f0 + albedo_f1 e (its own albedo over tally_albedo(), e the second's share of
    /// its extinction), and albedo_mean holds f's volume mean per tally cell (what a track-length
    /// walk on the tally grid, which sees cells and not voxels, weighs by). Empty otherwise.
    double albedo_f0 = 1.0, albedo_f1 = 0.0;
    std::vector<double> albedo_mean;

    TallyGrid(const LightingMedium& m, const core::GridGeometry* coarse_grid, MonteCarloOptions::TallyWeight w) {
        const core::GridGeometry& g = m.density.geom;
        geom = coarse_grid ? *coarse_grid : g;
        coarse = coarse_grid != nullptr;
        extinction = w == MonteCarloOptions::TallyWeight::Extinction;
        const int f = coarse ? int(std::lround(coarse_grid->voxel_size / g.voxel_size)) : 1;
        const int n[3] = {g.dims.x, g.dims.y, g.dims.z};
        const std::size_t tstride[3] = {1, std::size_t(geom.dims.x), std::size_t(geom.dims.x) * geom.dims.y};
        const std::size_t nb[3] = {std::size_t(n[0] + 7) / 8, std::size_t(n[1] + 7) / 8, std::size_t(n[2] + 7) / 8};
        const std::size_t bstride[3] = {1, nb[0], nb[0] * nb[1]}, inner[3] = {1, 8, 64};
        for (int a = 0; a < 3; ++a) {
            tally_axis[a].resize(std::size_t(n[a]));
            brick_axis[a].resize(std::size_t(n[a]));
            for (int i = 0; i < n[a]; ++i) {
                tally_axis[a][std::size_t(i)] = std::size_t(i / f) * tstride[a];
                brick_axis[a][std::size_t(i)] = std::size_t(i / 8) * bstride[a] * 512 + std::size_t(i % 8) * inner[a];
            }
        }
        bricked.assign(nb[0] * nb[1] * nb[2] * 512, 0.0f);
        cloud.assign(geom.cell_count(), 0);
        for (int k = 0; k < g.dims.z; ++k)
            for (int j = 0; j < g.dims.y; ++j)
                for (int i = 0; i < g.dims.x; ++i) {
                    const float rho = m.density.data[g.index(i, j, k)];
                    bricked[brick_index(i, j, k)] = rho;
                    if (rho > 0.0f) cloud[tally_cell(i, j, k)] = 1;
                }
        if (m.path_mix && m.path_mix->albedo != m.optics.albedo) {
            const double a = m.optics.albedo, at = tally_albedo(m);
            albedo_f0 = a / at;
            albedo_f1 = (m.path_mix->albedo - a) / at;
            const double per_cell = double(f) * double(f) * double(f);
            albedo_mean.assign(geom.cell_count(), albedo_f0);
            for (int k = 0; k < g.dims.z; ++k)
                for (int j = 0; j < g.dims.y; ++j)
                    for (int i = 0; i < g.dims.x; ++i)
                        albedo_mean[tally_cell(i, j, k)] +=
                            albedo_f1 * double(m.path_mix->share.data[g.index(i, j, k)]) / per_cell;
        }
        const double vc = geom.voxel_size * geom.voxel_size * geom.voxel_size;
        inv_norm.assign(geom.cell_count(), 1.0 / vc);
        if (!extinction) return;
        weight.resize(g.cell_count());
        std::vector<double> norm(geom.cell_count(), 0.0);
        const double vf = g.voxel_size * g.voxel_size * g.voxel_size;
        for (std::size_t c = 0; c < g.cell_count(); ++c) {
            const core::Int3 v = g.unindex(c);
            const std::size_t t = tally_cell(v.x, v.y, v.z);
            weight[c] = cloud[t] ? m.sigma_t(c) : 1.0;
            norm[t] += weight[c] * vf;
        }
        for (std::size_t t = 0; t < norm.size(); ++t)
            if (cloud[t]) inv_norm[t] = 1.0 / norm[t];
    }
    bool same() const noexcept { return !coarse; }
    /// The tally cell of medium voxel (i, j, k).
    std::size_t tally_cell(int i, int j, int k) const noexcept {
        return tally_axis[0][std::size_t(i)] + tally_axis[1][std::size_t(j)] + tally_axis[2][std::size_t(k)];
    }
    /// Density of medium voxel (i, j, k), from the bricked copy.
    float density(int i, int j, int k) const noexcept { return bricked[brick_index(i, j, k)]; }
    std::size_t brick_index(int i, int j, int k) const noexcept {
        return brick_axis[0][std::size_t(i)] + brick_axis[1][std::size_t(j)] + brick_axis[2][std::size_t(k)];
    }
};

/// The LightingMedium as a delta-tracking medium: the majorant is constant per macro-cell
/// (F^3 voxels, the max of sigma_t inside it); density lookups are clamped to the current
/// macro-cell so round-off at a macro-cell face can never exceed its majorant.
class GridMedium {
public:
    struct Walker {
        DdaWalker macro;
    };

    /// `bricks`: the tally grid built over the same medium, whose bricked copy of the density
    /// the lookups read (the same values, a few kilobytes per brick instead of a plane apart
    /// per step in z).
    GridMedium(const LightingMedium& m, int macro_cell, const TallyGrid& bricks)
        : g_(m.density.geom), kappa_(m.optics.extinction), bricks_(&bricks) {
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
                    mj = std::max(mj, kappa_ * double(m.density.data[g_.index(i, j, k)]));
                }
    }

    bool start(Walker& w, const glm::dvec3& x, const glm::dvec3& d) const noexcept {
        double t0 = 0.0, t1 = kInf;
        if (!core::clip_ray_to_box(x, d, g_.origin, g_.upper(), t0, t1)) return false;
        return w.macro.start_clipped(macro_, x, d, t0, t1);  // the majorant grid covers the medium's box
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
        return kappa_ * double(bricks_->density(idx[0], idx[1], idx[2]));
    }

private:
    core::GridGeometry g_;
    double kappa_;
    const TallyGrid* bricks_;
    int F_ = 1;
    core::GridGeometry macro_;
    std::vector<double> majorant_;
};

/// Voxel tallies of the (weighted) integral of p(s_m . w) L dw dx (S without albedo and
/// normalization), split into order 1 and orders >= 2; layout [cell][m] so one voxel's
/// directions are contiguous. With a path mix whose albedo is not the medium's, a voxel's
/// deposits to S are weighed by its own albedo, (1 - e) a + e a2 for its extinction share e of
/// the second scatterer, over tally_albedo(): S is albedo x sigma_t x the in-scattered
/// radiance, and the two scatterers' albedos differ. The fluences are not weighed.
class GridTally {
public:
    /// `single`, `multiple` (and `fluence`, the expected-value uncollided fluence, optional)
    /// hold one block per source group: [group][cell][m] ([group][cell]).
    GridTally(const LightingMedium& m, const TallyGrid& tg, std::span<const glm::dvec3> dirs, bool expected_single,
              bool track_single, bool tally_multiple, double cutoff, double* single, double* multiple,
              double* fluence = nullptr, double* fluence2 = nullptr, const glm::dvec3* toward = nullptr)
        : g_(&m.density.geom),
          tg_(&tg),
          kappa_(m.optics.extinction),
          hg_(m.optics.g),
          M_(dirs.size()),
          expected_single_(expected_single),
          track_single_(track_single),
          tally_multiple_(tally_multiple),
          cutoff_(cutoff),
          single0_(single),
          multiple0_(multiple),
          fluence0_(fluence),
          fluence20_(fluence2),
          single_(single),
          multiple_(multiple),
          fluence_(fluence),
          fluence2_(fluence2),
          p_(dirs.size()) {
        if (!tg.albedo_mean.empty()) {
            share_ = m.path_mix->share.data.data();
            f0_ = tg.albedo_f0;
            f1_ = tg.albedo_f1;
        }
        if (toward) {
            FULGUR_ASSERT(M_ == 1, "GridTally: S toward a point is one field");
            toward_ = *toward;
            toward_on_ = true;
        }
        for (const glm::dvec3& s : dirs) {
            sx_.push_back(s.x);
            sy_.push_back(s.y);
            sz_.push_back(s.z);
        }
    }

    /// Also tally the scattered light reaching `ground` into `sums` ([group][cell], watts per
    /// path summed; MonteCarloOptions::ground).
    void set_ground(const GroundTally* ground, double* sums) {
        ground_ = ground;
        ground0_ = ground_cur_ = sums;
    }

    /// Tally S with a second phase function by each tally cell's share (PhaseMix, on the tally
    /// grid; nullptr: the medium's alone).
    void set_mix(const PhaseMix* mix) {
        mix_ = mix ? mix->share.data.data() : nullptr;
        if (mix) {
            FULGUR_ASSERT(mix->share.geom == tg_->geom, "GridTally: the phase mix lies on the tally grid");
            hg2_ = HgConstants(mix->g);
            p2_.assign(M_, 0.0);
        }
    }

    void begin_path(std::uint32_t group) {
        crossed_ = false;
        if (ground0_) ground_cur_ = ground0_ + std::size_t(group) * ground_->cells();
        const std::size_t cells = tg_->geom.cell_count();
        if (single0_) single_ = single0_ + std::size_t(group) * cells * M_;
        if (multiple0_) multiple_ = multiple0_ + std::size_t(group) * cells * M_;
        if (fluence0_) fluence_ = fluence0_ + std::size_t(group) * cells;
        if (fluence20_) fluence2_ = fluence20_ + std::size_t(group) * cells;
    }

    /// Expected-value estimator of the uncollided light: the ray deposits its expected track
    /// T_in (1 - e^{-sigma l}) / sigma in every medium voxel it crosses (and its transmitted
    /// length in the empty parts of a tally box larger than the medium's).
    void uncollided(const glm::dvec3& x, const glm::dvec3& d, double w) {
        if (!expected_single_) return;
        phase(d);
        deposit(single_, x, d, 0.0, kInf, w, true);
    }

    /// Expected-value estimator of the flight after the first scattering (order 2), from the
    /// collision at x in the new direction d: into `multiple` (and the order-2 fluence).
    void scattered_expected(const glm::dvec3& x, const glm::dvec3& d, double w) {
        phase(d);
        deposit(multiple_, x, d, 0.0, kInf, w, true);
    }

    /// Track-length estimator of a sampled flight after k scatterings (t1 = infinity for a
    /// flight that escaped the medium).
    void flight(const glm::dvec3& x, const glm::dvec3& d, double t0, double t1, double w, int k) {
        if (ground0_) ground_crossing(x, d, t1, w, k);
        if (k == 0 ? !track_single_ : !tally_multiple_) return;
        if (!(t1 > t0)) return;
        phase(d);
        double* base = k == 0 ? single_ : multiple_;
        if (!tg_->extinction) {  // the track length per tally cell: walk the tally grid
            walk_tally(base, x, d, t0, t1, w, false);
            return;
        }
        deposit(base, x, d, t0, t1, w, false);
    }

private:
    /// The ground tally of a flight from x along d ending at t1 (infinity: escaped): its first
    /// downward crossing of the plane in the path, deposited when the path has scattered (the
    /// uncollided light's crossing only marks the path, as a black ground would have stopped it).
    void ground_crossing(const glm::dvec3& x, const glm::dvec3& d, double t1, double w, int k) {
        const GroundTally& g = *ground_;
        if (crossed_ || !(d.z < 0.0) || !(x.z > g.height)) return;
        const double t = (g.height - x.z) / d.z;
        if (!(t < t1)) return;
        crossed_ = true;
        if (k == 0) return;
        const double gx = (x.x + t * d.x - g.origin.x) / g.cell, gy = (x.y + t * d.y - g.origin.y) / g.cell;
        if (!(gx >= 0.0 && gy >= 0.0 && gx < double(g.nx) && gy < double(g.ny))) return;
        ground_cur_[std::size_t(gy) * std::size_t(g.nx) + std::size_t(gx)] += w;
    }

    /// p(s_m . d) for every output direction: once per flight, so the directions are kept
    /// as three arrays and the loop runs on whole vector registers (the same operations in
    /// the same order as glm::dot, so the same bits).
    void phase(const glm::dvec3& d) {
        if (toward_on_) {  // the phase depends on the cell: add() evaluates it
            d_ = d;
            return;
        }
        const double x = d.x, y = d.y, z = d.z;
        const double *sx = sx_.data(), *sy = sy_.data(), *sz = sz_.data();
        double* p = p_.data();
        for (std::size_t m = 0; m < M_; ++m) p[m] = hg_(sx[m] * x + sy[m] * y + sz[m] * z);
        if (mix_) {
            double* p2 = p2_.data();
            for (std::size_t m = 0; m < M_; ++m) p2[m] = hg2_(sx[m] * x + sy[m] * y + sz[m] * z);
        }
    }
    /// Adds c to the cell's S (times the phase per direction) and c_fluence to its fluence.
    void add(double* base, std::size_t tally_cell, double c, double c_fluence) {
        double* a = base + tally_cell * M_;
        const double share = mix_ ? double(mix_[tally_cell]) : 0.0;
        if (toward_on_)
            a[0] += c * toward_phase(tally_cell, share);
        else if (share > 0.0)
            for (std::size_t m = 0; m < M_; ++m) a[m] += c * mixed_phase(p_[m], p2_[m], share);
        else
            for (std::size_t m = 0; m < M_; ++m) a[m] += c * p_[m];
        // Fluence (no phase): of the uncollided light, and of the second order when its
        // flights are expected-value estimates.
        if (fluence_ && base == single_) fluence_[tally_cell] += c_fluence;
        if (fluence2_ && base == multiple_) fluence2_[tally_cell] += c_fluence;
    }
    /// p(w . d) for the flight's direction d, w the unit vector from the cell's centre toward
    /// the point (normalized and dotted as unit_directions and phase() do a fixed direction, so
    /// a cell gives the bits a run along its own direction gives).
    double toward_phase(std::size_t cell, double share) const {
        const core::GridGeometry& g = tg_->geom;
        const std::size_t nx = std::size_t(g.dims.x), ny = std::size_t(g.dims.y);
        const std::size_t i = cell % nx, j = (cell / nx) % ny, k = cell / (nx * ny);
        const glm::dvec3 w = toward_ - g.centre(int(i), int(j), int(k));
        const double len = glm::length(w);
        // A camera standing on the cell's centre looks at it from no one direction: the phase
        // averaged over directions, 1 / (4 pi), as an isotropic field would hold.
        if (!(len > 0.0)) return 1.0 / (4.0 * std::numbers::pi);
        const glm::dvec3 u = w / len;
        const double cos_theta = u.x * d_.x + u.y * d_.y + u.z * d_.z;
        const double p = hg_(cos_theta);
        return share > 0.0 ? mixed_phase(p, hg2_(cos_theta), share) : p;
    }
    /// w * (weighted) length on the tally grid over [t0, t1], outside the medium (empty:
    /// weight 1, and nothing into cloud cells when weighting by extinction).
    void walk_tally(double* base, const glm::dvec3& x, const glm::dvec3& d, double t0, double t1, double w,
                    bool empty_only) {
        DdaWalker wk;
        if (!wk.start(tg_->geom, x, d, t0, t1)) return;
        do {
            if (!(empty_only && tg_->extinction && tg_->cloud[std::size_t(wk.cell)])) {
                // Empty space holds no second scatterer: its weight is f0.
                const double c = w * (wk.t_next() - wk.t);
                const double f = !share_ ? 1.0 : empty_only ? f0_ : tg_->albedo_mean[std::size_t(wk.cell)];
                add(base, std::size_t(wk.cell), c * f, c);
            }
        } while (wk.advance());
    }
    /// Deposits along x + t d, t in [t0, t1], w times the integral of the tally weight (times
    /// the uncollided transmittance from t0 when `attenuate`) into the tally cells: the medium
    /// part on the medium's grid, the parts of the tally box outside it as empty space.
    void deposit(double* base, const glm::dvec3& x, const glm::dvec3& d, double t0, double t1, double w,
                 bool attenuate) {
        const bool same = tg_->same();
        double ta = t0, tb = t1;
        if (!same && !core::clip_ray_to_box(x, d, tg_->geom.origin, tg_->geom.upper(), ta, tb)) return;
        DdaWalker wk;
        if (!wk.start(*g_, x, d, t0, t1)) {
            if (!same) walk_tally(base, x, d, ta, tb, w, true);
            return;
        }
        if (!same) walk_tally(base, x, d, ta, wk.t, w, true);
        // Consecutive medium voxels of one tally cell are summed before the (per direction)
        // deposit: a coarse tally cell is crossed in one run of fine voxels.
        // T = exp(-tau) is carried along: one exponential per voxel with density.
        double tau = 0.0, T = 1.0, pending = 0.0, pending_fluence = 0.0;
        std::size_t pending_cell = tg_->tally_cell(wk.i, wk.j, wk.k);
        bool cut = false;
        do {
            const double len = wk.t_next() - wk.t;
            const std::size_t t = tg_->tally_cell(wk.i, wk.j, wk.k);
            const double sigma = kappa_ * double(tg_->density(wk.i, wk.j, wk.k));
            double c;
            double decay = 1.0;  // exp(-sigma len)
            if (!attenuate) {
                c = w * len;
            } else if (sigma * len < 1e-12) {
                c = w * T * len * (1.0 - 0.5 * sigma * len);  // chord_integral's small-argument form
                decay = 1.0 - sigma * len;
            } else {
                decay = std::exp(-sigma * len);
                c = w * T * (1.0 - decay) / sigma;
            }
            if (tg_->extinction) c *= tg_->weight[std::size_t(wk.cell)];
            if (t != pending_cell) {
                add(base, pending_cell, pending, pending_fluence);
                pending = pending_fluence = 0.0;
                pending_cell = t;
            }
            pending += share_ ? c * (f0_ + f1_ * double(share_[std::size_t(wk.cell)])) : c;
            pending_fluence += c;
            if (attenuate) {
                tau += sigma * len;
                T *= decay;
                if (tau > cutoff_) {
                    cut = true;
                    break;
                }
            }
        } while (wk.advance());
        add(base, pending_cell, pending, pending_fluence);
        if (!same && !cut) walk_tally(base, x, d, wk.t_end, tb, w * T, true);
    }

    const core::GridGeometry* g_;
    const TallyGrid* tg_;
    double kappa_;
    HgConstants hg_;
    HgConstants hg2_{0.0};        // the mix's phase (set_mix)
    const float* mix_ = nullptr;  // the mix's share per tally cell
    // The path mix's albedo weight of a voxel's deposits to S, f0_ + f1_ e (share_: e per
    // medium voxel; null when both scatterers have one albedo): TallyGrid::albedo_f0, _f1.
    const float* share_ = nullptr;
    double f0_ = 1.0, f1_ = 0.0;
    std::vector<double> p2_;  // hg2_ per output direction, as p_
    std::size_t M_;
    bool expected_single_, track_single_, tally_multiple_;
    double cutoff_;
    const GroundTally* ground_ = nullptr;
    double *ground0_ = nullptr, *ground_cur_ = nullptr;      // group 0, the current path's group
    bool crossed_ = false;                                   // the path has crossed the ground downward
    double *single0_, *multiple0_, *fluence0_, *fluence20_;  // group 0
    double *single_, *multiple_, *fluence_, *fluence2_;      // the current path's group
    std::vector<double> p_;
    std::vector<double> sx_, sy_, sz_;  // the output directions, one array per axis
    glm::dvec3 toward_{0.0}, d_{0.0};   // S toward a point: the point, the current flight's direction
    bool toward_on_ = false;
};

/// Sums of the batch estimates of the first and the second half of the batches (a noise
/// estimate that needs no per-voxel variance model: two independent estimates).
struct HalfSums {
    std::vector<double> a, b;
    std::int64_t na = 0, nb = 0;  ///< batches (ProgressiveMonteCarlo: paths) summed into a, b
    void init(std::size_t size) {
        a.assign(size, 0.0);
        b.assign(size, 0.0);
    }
    void add(const std::vector<double>& x, double scale, bool first) {
        std::vector<double>& h = first ? a : b;
        (first ? na : nb) += 1;
        for (std::size_t i = 0; i < h.size(); ++i) h[i] += x[i] * scale;
    }
};

/// Relative L2 noise of the mean of all batches over the tally cells `cells` marks (non-zero),
/// for the sum over the groups of s1 (when use_single) and sm, [group][cell][m] layout, from
/// the two half means A, B: ||A - B|| sqrt(na nb) / (na + nb) / ||mean||.
double half_noise(const HalfSums& s1, const HalfSums* sm, const std::vector<std::uint8_t>& cells, std::size_t M,
                  std::size_t groups, bool use_single) {
    core::CompensatedSum diff2, ref2;
    const double ka = 1.0 / double(std::max<std::int64_t>(1, s1.na)),
                 kb = 1.0 / double(std::max<std::int64_t>(1, s1.nb));
    const double kall = 1.0 / double(std::max<std::int64_t>(1, s1.na + s1.nb));
    const std::size_t size = cells.size() * M;
    for (std::size_t c = 0; c < cells.size(); ++c) {
        if (!cells[c]) continue;
        for (std::size_t m = 0; m < M; ++m) {
            double a = 0.0, b = 0.0;
            for (std::size_t g = 0; g < groups; ++g) {
                const std::size_t i = g * size + c * M + m;
                if (use_single) {
                    a += s1.a[i];
                    b += s1.b[i];
                }
                if (sm) {
                    a += sm->a[i];
                    b += sm->b[i];
                }
            }
            const double d = a * ka - b * kb, mean = (a + b) * kall;
            diff2.add(d * d);
            ref2.add(mean * mean);
        }
    }
    if (!(ref2.value() > 0.0)) return 0.0;
    const double na = double(s1.na), nb = double(s1.nb);
    return std::sqrt(diff2.value() / ref2.value()) * std::sqrt(na * nb) / (na + nb);
}

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
    /// Writes mean and SE of group `group` into fields laid out [m][cell] from the
    /// [group][cell][m] accumulators (se_out may be null).
    void write(SourceField& mean_out, SourceField* se_out, std::size_t group = 0) const {
        const std::size_t cells = mean_out.cells(), M = mean_out.directions.size(), off = group * cells * M;
        const double k = n > 1 ? 1.0 / (double(n) * double(n - 1)) : 0.0;
        for (std::size_t c = 0; c < cells; ++c)
            for (std::size_t m = 0; m < M; ++m) {
                mean_out.data[m * cells + c] = float(mean[off + c * M + m]);
                if (se_out) se_out->data[m * cells + c] = float(std::sqrt(std::max(0.0, m2[off + c * M + m]) * k));
            }
    }
};

/// The sum of a batch's tally (any group, cell, direction: [group][cell][m]) over the cloud
/// cells, times `scale`.
double cloud_sum(const std::vector<double>& x, const TallyGrid& tg, std::size_t M, double scale) {
    core::CompensatedSum s;
    const std::size_t cells = tg.cloud.size(), G = x.size() / (cells * M);
    for (std::size_t q = 0; q < G; ++q)
        for (std::size_t c = 0; c < cells; ++c)
            if (tg.cloud[c])
                for (std::size_t m = 0; m < M; ++m) s.add(x[(q * cells + c) * M + m]);
    return s.value() * scale;
}

/// run_grid's output directions, normalized, after validating the medium, the options and
/// the directions.
std::vector<glm::dvec3> unit_directions(const LightingMedium& medium, std::span<const glm::dvec3> directions,
                                        const MonteCarloOptions& o) {
    validate_medium(medium);
    check_mc_options(o);
    if (directions.empty()) throw core::Error("directions", "at least one output direction is needed");
    if (o.toward && directions.size() != 1)
        throw core::Error("directions", "S toward a point (monte_carlo.toward) is one field: one direction, got " +
                                            std::to_string(directions.size()));
    std::vector<glm::dvec3> dirs;
    for (std::size_t m = 0; m < directions.size(); ++m) {
        const double len = glm::length(directions[m]);
        if (!std::isfinite(len) || !(len > 0.0))
            throw core::Error("directions[" + std::to_string(m) + "]", "must be a finite non-zero vector");
        dirs.push_back(directions[m] / len);
    }
    return dirs;
}

/// The path tracer's options: the medium's albedo and phase, the options' scattering limits.
PathOptions path_options(const LightingMedium& medium, const MonteCarloOptions& o) {
    return {.albedo = medium.optics.albedo,
            .g = medium.optics.g,
            .max_scatterings = o.max_scatterings,
            .implicit_capture = o.implicit_capture,
            .roulette_threshold = o.roulette_threshold,
            .max_collisions = o.max_collisions,
            .uncollided_only = o.uncollided_only,
            .expected_second_order = o.expected_second_order,
            .mix = medium.path_mix.get()};
}

/// What run_grid accumulated over its batches: the statistics of S single and multiple
/// ([group][cell][m]) and of the fluences ([group][cell]), and the half sums of the noise
/// estimate; and which of them were tallied.
struct BatchTallies {
    const FieldStats &s1, &sm, &fl, &fl2;
    const HalfSums &h1, &hm;
    bool multiple, fluence, fluence2;
};

/// Per group, and their sum (no per-voxel SE for the sum: see MonteCarloResult).
void write_groups(const BatchTallies& t, const core::GridGeometry& g, const std::vector<glm::dvec3>& dirs,
                  std::size_t G, MonteCarloResult& r) {
    const std::size_t cells = g.cell_count(), M = dirs.size();
    const auto write_fluence = [&](const FieldStats& stats, core::Grid3<float>& out, std::size_t q) {
        out = core::Grid3<float>(g, 0.0f);
        for (std::size_t c = 0; c < cells; ++c) out.data[c] = float(stats.mean[q * cells + c]);
    };
    r.groups.resize(G);
    std::vector<double> sum(cells * M, 0.0), sum_m(cells * M, 0.0);
    for (std::size_t q = 0; q < G; ++q) {
        MonteCarloResult::Group& grp = r.groups[q];
        grp.single = SourceField(g, dirs);
        grp.multiple = SourceField(g, dirs);
        t.s1.write(grp.single, nullptr, q);
        if (t.multiple) t.sm.write(grp.multiple, nullptr, q);
        if (t.fluence) write_fluence(t.fl, grp.fluence, q);
        if (t.fluence2) write_fluence(t.fl2, grp.fluence2, q);
        for (std::size_t i = 0; i < cells * M; ++i) {
            sum[i] += t.s1.mean[q * cells * M + i];
            if (t.multiple) sum_m[i] += t.sm.mean[q * cells * M + i];
        }
    }
    for (std::size_t c = 0; c < cells; ++c)
        for (std::size_t m = 0; m < M; ++m) {
            r.single.data[m * cells + c] = float(sum[c * M + m]);
            r.multiple.data[m * cells + c] = float(sum_m[c * M + m]);
        }
}

/// run_grid's result without the energy balance: S single and multiple with their standard
/// errors (per group and summed with groups), the fluences and the noise of the halves.
MonteCarloResult grid_result(const BatchTallies& t, const TallyGrid& tg, const std::vector<glm::dvec3>& dirs,
                             const MonteCarloOptions& o) {
    const core::GridGeometry& g = tg.geom;
    const std::size_t G = std::size_t(o.groups);
    const std::size_t cells = g.cell_count(), M = dirs.size();
    MonteCarloResult r;
    r.single = SourceField(g, dirs);
    r.single_se = SourceField(g, dirs);
    r.multiple = SourceField(g, dirs);
    r.multiple_se = SourceField(g, dirs);
    const auto sum_fluence = [&](const FieldStats& stats, core::Grid3<float>& out) {
        out = core::Grid3<float>(g, 0.0f);
        for (std::size_t c = 0; c < cells; ++c) {
            double v = 0.0;
            for (std::size_t q = 0; q < G; ++q) v += stats.mean[q * cells + c];
            out.data[c] = float(v);
        }
    };
    if (G == 1) {
        t.s1.write(r.single, &r.single_se);
        if (t.multiple) t.sm.write(r.multiple, &r.multiple_se);
    } else {
        write_groups(t, g, dirs, G, r);
    }
    if (t.fluence) sum_fluence(t.fl, r.fluence);
    if (t.fluence2) sum_fluence(t.fl2, r.fluence2);
    if (o.halves) {
        r.noise.single = half_noise(t.h1, nullptr, tg.cloud, M, G, true);
        if (t.multiple) {
            r.noise.multiple = half_noise(t.hm, nullptr, tg.cloud, M, G, true);
            r.noise.total = half_noise(t.h1, &t.hm, tg.cloud, M, G, true);
        } else {
            r.noise.total = r.noise.single;
        }
    }
    return r;
}

/// The ground tally's means ([group][cell]) as irradiance: summed over the groups into
/// r.ground, and per group into r.groups (when there are several).
void write_ground(std::span<const double> mean, const GroundTally& cells, std::size_t G, MonteCarloResult& r) {
    const std::size_t n = cells.cells();
    r.ground = {cells, std::vector<float>(n, 0.0f)};
    for (std::size_t c = 0; c < n; ++c) {
        double v = 0.0;
        for (std::size_t q = 0; q < G; ++q) v += mean[q * n + c];
        r.ground.data[c] = float(v);
    }
    if (G == 1) return;
    r.groups.resize(G);
    for (std::size_t q = 0; q < G; ++q) {
        r.groups[q].ground = {cells, std::vector<float>(n, 0.0f)};
        for (std::size_t c = 0; c < n; ++c) r.groups[q].ground.data[c] = float(mean[q * n + c]);
    }
}

template <class Emitter>
MonteCarloResult run_grid(const LightingMedium& medium, const Emitter& em, std::span<const glm::dvec3> directions,
                          const MonteCarloOptions& o, const core::GridGeometry* tally_grid = nullptr) {
    const std::vector<glm::dvec3> dirs = unit_directions(medium, directions, o);
    core::Stopwatch clock;
    const TallyGrid tg(medium, tally_grid, o.tally_weight);
    if (o.phase_mix) validate_phase_mix(*o.phase_mix, tg.geom);
    const core::GridGeometry& g = tg.geom;
    const std::size_t G = std::size_t(o.groups);
    const std::size_t cells = g.cell_count(), M = dirs.size(), size = cells * M * G;
    const bool fluence = o.tally_fluence && o.single_estimator == MonteCarloOptions::SingleEstimator::ExpectedValue;
    const bool fluence2 = fluence && o.expected_second_order;
    const GridMedium gm(medium, o.macro_cell, tg);
    const PathOptions po = path_options(medium, o);
    const bool expected = o.single_estimator == MonteCarloOptions::SingleEstimator::ExpectedValue;
    const bool multiple = o.tally_multiple && o.max_scatterings > 0;

    const int T = std::max(1, core::thread_count());
    const std::size_t ground_cells = o.ground ? o.ground->cells() * G : 0;
    struct Buffer {
        std::vector<double> single, multiple, fluence, fluence2, ground;
        EnergyBatch energy;
    };
    std::vector<Buffer> bufs(static_cast<std::size_t>(T));
    FieldStats s1, sm, fl, fl2, gs;
    ScalarStats ground_power;
    if (o.ground) gs.init(ground_cells);
    s1.init(size);
    if (multiple) sm.init(size);
    if (fluence) fl.init(cells * G);
    if (fluence2) fl2.init(cells * G);
    HalfSums h1, hm;
    if (o.halves) {
        h1.init(size);
        if (multiple) hm.init(size);
    }
    EnergyStats es;
    ScalarStats sum1, summ;  // the cloud sums of single and multiple, per batch
    const double vol = g.voxel_size * g.voxel_size * g.voxel_size;
    for (int b0 = 0; b0 < o.batches; b0 += T) {
        const int nb = std::min(T, o.batches - b0);
        core::parallel_for(0, nb, [&](std::int64_t i) {
            Buffer& buf = bufs[std::size_t(i)];
            buf.single.assign(size, 0.0);
            if (multiple) buf.multiple.assign(size, 0.0);
            if (fluence) buf.fluence.assign(cells * G, 0.0);
            if (fluence2) buf.fluence2.assign(cells * G, 0.0);
            if (o.ground) buf.ground.assign(ground_cells, 0.0);
            buf.energy = EnergyBatch{};
            const int b = b0 + int(i);
            GridTally tally(medium, tg, dirs, expected, !expected, multiple, kPathCutoff, buf.single.data(),
                            multiple ? buf.multiple.data() : nullptr, fluence ? buf.fluence.data() : nullptr,
                            fluence2 ? buf.fluence2.data() : nullptr, o.toward ? &*o.toward : nullptr);
            if (o.ground) tally.set_ground(&*o.ground, buf.ground.data());
            tally.set_mix(o.phase_mix);
            trace_paths(gm, em, po, o.seed, batch_first_path(o.paths, o.batches, b), batch_paths(o.paths, o.batches, b),
                        tally, buf.energy);
            if (tg.extinction)  // per-cell normalization (volume: the constant in `scale`)
                for (std::size_t q = 0; q < G; ++q)
                    for (std::size_t c = 0; c < cells; ++c) {
                        const double k = tg.inv_norm[c] * vol;
                        for (std::size_t m = 0; m < M; ++m) {
                            buf.single[(q * cells + c) * M + m] *= k;
                            if (multiple) buf.multiple[(q * cells + c) * M + m] *= k;
                        }
                        if (fluence) buf.fluence[q * cells + c] *= k;
                        if (fluence2) buf.fluence2[q * cells + c] *= k;
                    }
        });
        for (int i = 0; i < nb; ++i) {
            const std::uint64_t np = batch_paths(o.paths, o.batches, b0 + i);
            const double scale = tally_albedo(medium) / (vol * double(np));
            s1.add(bufs[std::size_t(i)].single, scale);
            if (multiple) sm.add(bufs[std::size_t(i)].multiple, scale);
            if (fluence) fl.add(bufs[std::size_t(i)].fluence, 1.0 / (vol * double(np)));
            if (fluence2) fl2.add(bufs[std::size_t(i)].fluence2, 1.0 / (vol * double(np)));  // w holds albedo already
            if (o.halves) {
                const bool first = 2 * (b0 + i) < o.batches;
                h1.add(bufs[std::size_t(i)].single, scale, first);
                if (multiple) hm.add(bufs[std::size_t(i)].multiple, scale, first);
            }
            es.add(bufs[std::size_t(i)].energy, np);
            if (o.ground) {
                gs.add(bufs[std::size_t(i)].ground, 1.0 / (double(np) * o.ground->cell * o.ground->cell));
                core::CompensatedSum p;
                for (const double v : bufs[std::size_t(i)].ground) p.add(v);
                ground_power.add(p.value() / double(np));
            }
            sum1.add(cloud_sum(bufs[std::size_t(i)].single, tg, M, scale));
            if (multiple) summ.add(cloud_sum(bufs[std::size_t(i)].multiple, tg, M, scale));
        }
    }
    MonteCarloResult r = grid_result({s1, sm, fl, fl2, h1, hm, multiple, fluence, fluence2}, tg, dirs, o);
    r.sums = {sum1.estimate(), summ.estimate()};
    if (o.ground) {
        write_ground(gs.mean, *o.ground, G, r);
        r.ground_power = ground_power.estimate();
    }
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

namespace detail {
namespace {

/// The emitter of a checked sun over the medium's box.
BoxSunEmitter checked_sun(const LightingMedium& medium, const DirectionalSource& sun) {
    const double len = glm::length(sun.direction);
    if (!std::isfinite(len) || !(len > 0.0)) throw core::Error("sun.direction", "must be a finite non-zero vector");
    if (!std::isfinite(sun.irradiance) || sun.irradiance < 0.0)
        throw core::Error("sun.irradiance", "must be finite and >= 0, got " + std::to_string(sun.irradiance));
    const core::GridGeometry& g = medium.density.geom;
    return BoxSunEmitter(g.origin, g.upper(), sun.direction / len, sun.irradiance);
}

int check_sources(const LightingMedium& medium, std::span<const PointSource> points, std::span<const LineSource> lines,
                  const core::GridGeometry& tally_grid, const MonteCarloOptions& options);

}  // namespace
}  // namespace detail

MonteCarloResult monte_carlo(const LightingMedium& medium, const DirectionalSource& sun,
                             std::span<const glm::dvec3> directions, const MonteCarloOptions& options) {
    return detail::run_grid(medium, detail::checked_sun(medium, sun), directions, options);
}

MonteCarloResult monte_carlo(const LightingMedium& medium, const DirectionalSource& sun,
                             const core::GridGeometry& tally_grid, std::span<const glm::dvec3> directions,
                             const MonteCarloOptions& options) {
    const int f = detail::check_sources(medium, {}, {}, tally_grid, options);
    return detail::run_grid(medium, detail::checked_sun(medium, sun), directions, options,
                            f == 1 ? nullptr : &tally_grid);
}

MonteCarloResult monte_carlo(const LightingMedium& medium, const DomeSource& sky, const core::GridGeometry& tally_grid,
                             std::span<const glm::dvec3> directions, const MonteCarloOptions& options) {
    const std::size_t n = sky.radiance.size();
    if (n < 2 || n > (std::size_t(1) << 20))
        throw core::Error("sky.radiance",
                          "needs 2 to 2^20 values (sin of the elevation 0 .. 1), got " + std::to_string(n));
    for (std::size_t k = 0; k < n; ++k)
        if (!std::isfinite(sky.radiance[k]) || sky.radiance[k] < 0.0)
            throw core::Error("sky.radiance[" + std::to_string(k) + "]",
                              "must be finite and >= 0, got " + std::to_string(sky.radiance[k]));
    const int f = detail::check_sources(medium, {}, {}, tally_grid, options);
    const core::GridGeometry& g = medium.density.geom;
    const detail::BoxDomeEmitter em(g.origin, g.upper(), sky.radiance);
    return detail::run_grid(medium, em, directions, options, f == 1 ? nullptr : &tally_grid);
}

namespace detail {
namespace {

/// Validates a frame's sources and the tally grid (a coarsening of the medium's grid by an
/// integer factor); returns the factor.
int check_sources(const LightingMedium& medium, std::span<const PointSource> points, std::span<const LineSource> lines,
                  const core::GridGeometry& tally_grid, const MonteCarloOptions& options) {
    const auto finite = [](const glm::dvec3& v) {
        return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
    };
    const auto check_intensity = [](double v, const std::string& where) {
        if (!std::isfinite(v) || v < 0.0)
            throw core::Error(where + ".intensity", "must be finite and >= 0, got " + std::to_string(v));
    };
    for (std::size_t i = 0; i < points.size(); ++i) {
        const std::string where = "points[" + std::to_string(i) + "]";
        if (!finite(points[i].position)) throw core::Error(where + ".position", "must be finite");
        check_intensity(points[i].intensity, where);
    }
    for (std::size_t i = 0; i < lines.size(); ++i) {
        const std::string where = "lines[" + std::to_string(i) + "]";
        if (!finite(lines[i].a) || !finite(lines[i].b)) throw core::Error(where, "end points must be finite");
        if (lines[i].group >= std::uint32_t(options.groups))
            throw core::Error(where + ".group", "must be < monte_carlo.groups (" + std::to_string(options.groups) +
                                                    "), got " + std::to_string(lines[i].group));
        check_intensity(lines[i].intensity, where);
    }
    const core::GridGeometry& g = medium.density.geom;
    core::validate_geometry(tally_grid, "tally_grid");
    const double ratio = tally_grid.voxel_size / g.voxel_size;
    const int f = int(std::lround(ratio));
    const auto ceil_div = [f](int n) { return (n + f - 1) / f; };
    if (f < 1 || std::fabs(ratio - f) > 1e-9 * ratio || tally_grid.origin != g.origin ||
        tally_grid.dims != core::Int3{ceil_div(g.dims.x), ceil_div(g.dims.y), ceil_div(g.dims.z)})
        throw core::Error("tally_grid",
                          "must coarsen the medium's grid by an integer factor (same origin, dims "
                          "rounded up), as the lighting grid does");
    return f;
}

/// The emitter of already checked sources, refused when their total intensity overflows.
SourceEmitter checked_emitter(std::span<const PointSource> points, std::span<const LineSource> lines) {
    SourceEmitter em(points, lines);
    if (!std::isfinite(em.power())) throw core::Error("sources", "total intensity overflows");
    return em;
}

}  // namespace
}  // namespace detail

MonteCarloResult monte_carlo(const LightingMedium& medium, std::span<const PointSource> points,
                             std::span<const LineSource> lines, const core::GridGeometry& tally_grid,
                             std::span<const glm::dvec3> directions, const MonteCarloOptions& options) {
    const int f = detail::check_sources(medium, points, lines, tally_grid, options);
    const detail::SourceEmitter em = detail::checked_emitter(points, lines);
    if (em.empty()) {  // no light: S is zero everywhere, with no noise
        MonteCarloResult r;
        const std::vector<glm::dvec3> dirs(directions.begin(), directions.end());
        r.single = r.multiple = r.single_se = r.multiple_se = SourceField(tally_grid, dirs);
        return r;
    }
    return detail::run_grid(medium, em, directions, options, f == 1 ? nullptr : &tally_grid);
}

// =======================================================================================
// MonteCarloMedium, ProgressiveMonteCarlo

struct MonteCarloMedium::Impl {
    const LightingMedium& medium;
    core::GridGeometry tally_grid;
    detail::TallyGrid tg;
    detail::GridMedium gm;
    Impl(const LightingMedium& m, const core::GridGeometry& t, int f, int macro_cell)
        : medium(m),
          tally_grid(t),
          tg(m, f == 1 ? nullptr : &t, MonteCarloOptions::TallyWeight::Volume),
          gm(m, macro_cell, tg) {}
};

MonteCarloMedium::MonteCarloMedium(const LightingMedium& medium, const core::GridGeometry& tally_grid, int macro_cell) {
    validate_medium(medium);
    if (macro_cell < 0) throw core::Error("monte_carlo.macro_cell", "must be >= 0, got " + std::to_string(macro_cell));
    const int f = detail::check_sources(medium, {}, {}, tally_grid, MonteCarloOptions{});
    impl_ = std::make_unique<Impl>(medium, tally_grid, f, macro_cell);
}
MonteCarloMedium::~MonteCarloMedium() = default;
const LightingMedium& MonteCarloMedium::medium() const noexcept { return impl_->medium; }
const core::GridGeometry& MonteCarloMedium::tally_grid() const noexcept { return impl_->tally_grid; }
const std::vector<std::uint8_t>& MonteCarloMedium::cloud() const noexcept { return impl_->tg.cloud; }

struct ProgressiveMonteCarlo::Impl {
    const MonteCarloMedium::Impl& med;
    MonteCarloOptions o;
    std::vector<glm::dvec3> dirs;
    detail::SourceEmitter em;
    detail::PathOptions po;
    bool multiple = false, fluence = false, fluence2 = false;
    std::size_t G = 1, cells = 0, M = 0, size = 0;
    // Raw tallies of each half (the deposits' sums; scaled in result()), with its path counts.
    detail::HalfSums h1, hm, hf, hf2, hg;  // hg: the ground tally ([group][cell]; MonteCarloOptions::ground)
    std::size_t ground_cells = 0;
    std::uint64_t traced = 0;

    Impl(const MonteCarloMedium::Impl& m, std::span<const PointSource> points, std::span<const LineSource> lines,
         std::span<const glm::dvec3> directions, const MonteCarloOptions& opt)
        : med(m),
          o(opt),
          dirs(detail::unit_directions(m.medium, directions, batch_free(opt))),
          em(detail::checked_emitter(points, lines)),
          po(detail::path_options(m.medium, opt)) {
        multiple = o.tally_multiple && o.max_scatterings > 0;
        fluence = o.tally_fluence && o.single_estimator == MonteCarloOptions::SingleEstimator::ExpectedValue;
        fluence2 = fluence && o.expected_second_order;
        G = std::size_t(o.groups);
        cells = med.tg.geom.cell_count();
        M = dirs.size();
        size = cells * M * G;
        ground_cells = o.ground ? o.ground->cells() * G : 0;
        if (!o.tally_single && !multiple)
            throw core::Error("monte_carlo.tally_single", "false needs the multiple tally: nothing would be estimated");
        if (o.phase_mix) validate_phase_mix(*o.phase_mix, med.tg.geom);
        if (o.noise_cells && o.noise_cells->size() != cells)
            throw core::Error("monte_carlo.noise_cells", "must hold one value per tally cell (" +
                                                             std::to_string(cells) + "), got " +
                                                             std::to_string(o.noise_cells->size()));
        reset(o.seed);
    }

    // Zero tallies and counts, new seeds (the allocations stay).
    void reset(std::uint64_t seed) {
        o.seed = seed;
        if (o.tally_single) h1.init(size);
        if (multiple) hm.init(size);
        if (fluence) hf.init(cells * G);
        if (fluence2) hf2.init(cells * G);
        if (o.ground) hg.init(ground_cells);
        for (detail::HalfSums* h : {&h1, &hm, &hf, &hf2, &hg}) h->na = h->nb = 0;
        traced = 0;
        for (std::size_t h = 0; h < 2; ++h) {
            half_seed[h] = core::hash_seed(seed, h);
            half_traced[h] = 0;
            emission[h] = detail::KroneckerSequence(half_seed[h]);
        }
    }
    // The batch settings are advance()'s business: only the options that shape paths are checked.
    static MonteCarloOptions batch_free(MonteCarloOptions o) {
        o.paths = 4;
        o.batches = 4;
        o.halves = true;
        o.macro_cell = 0;
        return o;
    }

    // Each half is its own run: its own seed, its own shifted emission sequence, its own count.
    std::array<std::uint64_t, 2> half_seed{}, half_traced{};
    std::array<detail::KroneckerSequence, 2> emission{detail::KroneckerSequence(0), detail::KroneckerSequence(0)};

    // Each half's thread deposits straight into its half's sums (raw: scaled in result()).
    void advance(std::uint64_t n) {
        const std::uint64_t half[2] = {n / 2, n - n / 2};
        const bool expected = o.single_estimator == MonteCarloOptions::SingleEstimator::ExpectedValue;
        const auto sums = [](detail::HalfSums& h, bool used, std::size_t half_index) {
            return used ? (half_index == 0 ? h.a.data() : h.b.data()) : nullptr;
        };
        core::parallel_for(0, 2, [&](std::int64_t hi) {
            const std::size_t h = std::size_t(hi);
            detail::EnergyBatch energy;  // not reported: the energy balance is monte_carlo()'s
            detail::GridTally tally(med.medium, med.tg, dirs, expected && o.tally_single, !expected && o.tally_single,
                                    multiple, detail::kPathCutoff, sums(h1, o.tally_single, h), sums(hm, multiple, h),
                                    sums(hf, fluence, h), sums(hf2, fluence2, h), o.toward ? &*o.toward : nullptr);
            if (o.ground) tally.set_ground(&*o.ground, sums(hg, true, h));
            tally.set_mix(o.phase_mix);
            detail::trace_paths(med.gm, em, po, half_seed[h], half_traced[h], half[h], tally, energy, &emission[h]);
        });
        for (std::size_t h = 0; h < 2; ++h) {
            half_traced[h] += half[h];
            for (detail::HalfSums* s : {&h1, &hm, &hf, &hf2, &hg}) (h == 0 ? s->na : s->nb) += std::int64_t(half[h]);
        }
        traced += n;
    }

    MonteCarloResult result() const {
        const core::GridGeometry& g = med.tg.geom;
        MonteCarloResult r;
        r.paths = traced;
        const bool traced_any = traced > 0 && !em.empty();
        // Raw sums per path -> S (albedo / voxel volume) and fluence (1 / voxel volume).
        const double vol = g.voxel_size * g.voxel_size * g.voxel_size;
        const double ks = traced_any ? detail::tally_albedo(med.medium) / (vol * double(traced)) : 0.0;
        const double kf = traced_any ? 1.0 / (vol * double(traced)) : 0.0;
        const auto mean = [&](const detail::HalfSums& h, std::size_t i) { return (h.a[i] + h.b[i]) * ks; };
        const auto mean_fluence = [&](const detail::HalfSums& h, std::size_t i) { return (h.a[i] + h.b[i]) * kf; };
        // A part not tallied (tally_single, tally_multiple) stays empty: building and summing
        // its zeros cost ~1 ms of an instant strike's round on the default storm.
        const bool single = o.tally_single;
        if (single) r.single = SourceField(g, dirs);
        if (multiple) r.multiple = SourceField(g, dirs);
        if (G > 1) r.groups.resize(G);
        for (std::size_t q = 0; q < G; ++q) {
            SourceField* s1 = G > 1 ? &r.groups[q].single : &r.single;
            SourceField* sm = G > 1 ? &r.groups[q].multiple : &r.multiple;
            if (G > 1 && single) *s1 = SourceField(g, dirs);
            if (G > 1 && multiple) *sm = SourceField(g, dirs);
            // Direction-major output from cell-major sums, in blocks of cells whose sums fit in
            // the L1 cache (a direction at a time over all cells would stream the sums M times).
            constexpr std::size_t kBlock = 64;
            core::parallel_for(0, std::int64_t((cells + kBlock - 1) / kBlock), [&](std::int64_t bi) {
                const std::size_t c0 = std::size_t(bi) * kBlock, c1 = std::min(cells, c0 + kBlock);
                for (std::size_t m = 0; m < M; ++m)
                    for (std::size_t c = c0; c < c1; ++c) {
                        const std::size_t i = (q * cells + c) * M + m;
                        if (single) s1->data[m * cells + c] = float(mean(h1, i));
                        if (multiple) sm->data[m * cells + c] = float(mean(hm, i));
                    }
            });
            if (G > 1) {
                if (single)
                    for (std::size_t i = 0; i < s1->data.size(); ++i) r.single.data[i] += s1->data[i];
                if (multiple)
                    for (std::size_t i = 0; i < sm->data.size(); ++i) r.multiple.data[i] += sm->data[i];
            }
            const auto write_fluence = [&](const detail::HalfSums& h, core::Grid3<float>& out) {
                out = core::Grid3<float>(g, 0.0f);
                for (std::size_t c = 0; c < cells; ++c) out.data[c] = float(mean_fluence(h, q * cells + c));
            };
            if (G > 1 && fluence) write_fluence(hf, r.groups[q].fluence);
            if (G > 1 && fluence2) write_fluence(hf2, r.groups[q].fluence2);
        }
        if (o.ground) {
            // Irradiance: the halves' summed weights per path over the cell's area; the power's
            // standard error from the two halves' difference.
            const double cell2 = o.ground->cell * o.ground->cell;
            const double kg = traced_any ? 1.0 / (double(traced) * cell2) : 0.0;
            std::vector<double> ground_mean(ground_cells);
            core::CompensatedSum pa, pb;
            for (std::size_t i = 0; i < ground_cells; ++i) {
                ground_mean[i] = (hg.a[i] + hg.b[i]) * kg;
                pa.add(hg.a[i]);
                pb.add(hg.b[i]);
            }
            detail::write_ground(ground_mean, *o.ground, G, r);
            if (traced_any && hg.na > 0 && hg.nb > 0) {
                const double a = pa.value() / double(hg.na), b = pb.value() / double(hg.nb);
                const double na = double(hg.na), nb = double(hg.nb);
                r.ground_power = {(pa.value() + pb.value()) / double(traced),
                                  std::abs(a - b) * std::sqrt(na * nb) / (na + nb)};
            }
        }
        if (traced_any) {
            const std::vector<std::uint8_t>& noise_cells = o.noise_cells ? *o.noise_cells : med.tg.cloud;
            if (o.tally_single) r.noise.single = detail::half_noise(h1, nullptr, noise_cells, M, G, true);
            if (multiple) r.noise.multiple = detail::half_noise(hm, nullptr, noise_cells, M, G, true);
            r.noise.total = !multiple         ? r.noise.single
                            : !o.tally_single ? r.noise.multiple
                                              : detail::half_noise(h1, &hm, noise_cells, M, G, true);
        }
        return r;
    }
};

ProgressiveMonteCarlo::ProgressiveMonteCarlo(const MonteCarloMedium& medium, std::span<const PointSource> points,
                                             std::span<const LineSource> lines, std::span<const glm::dvec3> directions,
                                             const MonteCarloOptions& options) {
    detail::check_sources(medium.medium(), points, lines, medium.tally_grid(), options);
    impl_ = std::make_unique<Impl>(*medium.impl_, points, lines, directions, options);
}

ProgressiveMonteCarlo::~ProgressiveMonteCarlo() = default;

void ProgressiveMonteCarlo::restart(std::span<const PointSource> points, std::span<const LineSource> lines,
                                    std::uint64_t seed) {
    Impl& im = *impl_;
    detail::check_sources(im.med.medium, points, lines, im.med.tally_grid, im.o);
    im.em = detail::checked_emitter(points, lines);
    im.reset(seed);
}

void ProgressiveMonteCarlo::advance(std::uint64_t paths) {
    FULGUR_ASSERT(paths >= 2, "ProgressiveMonteCarlo::advance: at least one path per half");
    if (impl_->em.empty()) {  // no light: nothing to trace, S stays zero
        impl_->traced += paths;
        return;
    }
    impl_->advance(paths);
}

std::uint64_t ProgressiveMonteCarlo::paths() const noexcept { return impl_->traced; }

MonteCarloResult ProgressiveMonteCarlo::result() const { return impl_->result(); }

}  // namespace fulgur::transport
