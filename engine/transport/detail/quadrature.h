// Internal: the per-box quadrature rules of exact single scattering (single_scattering.cpp
// picks one per voxel or octree sub-box from the tolerance; quadrature.cpp implements them):
//  * face rules, radial integral exact: "inside" (the source in the box's closure) and
//    "outside" (a box near the source, or optically thick), over the faces the source sees;
//  * tensor Gauss rules with exact DDA transmittance to every node (far, optically thin
//    boxes), checked a posteriori against the error model (Plan).
// docs/transport.md, "Quadrature rules", gives the rules and their measured errors.
#pragma once

#include "transport/detail/kernels.h"
#include "transport/detail/traversal.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <optional>
#include <span>
#include <vector>

namespace fulgur::transport::detail {

struct Box {
    glm::dvec3 lo, hi;
};

/// Collects weighted direction samples (w, omega) and reduces them to
/// acc[m] = sum w * p(s_m . omega). Samples are buffered in SoA form so the reduction over
/// samples vectorizes; for g == 0 only the sum of weights is kept.
class PhaseAccumulator {
public:
    /// With `mix_g`, a cell's samples are also weighted by HG(mix_g) and the two sums mixed by
    /// the share set_share() gives (PhaseMix).
    PhaseAccumulator(std::span<const glm::dvec3> dirs, double g, std::optional<double> mix_g = std::nullopt)
        : dirs_(dirs), hg_(g), hg2_(mix_g.value_or(0.0)), mixed_(mix_g.has_value()) {
        if (!hg_.isotropic || mixed_) {
            w_.resize(kCap);
            x_.resize(kCap);
            y_.resize(kCap);
            z_.resize(kCap);
        }
        acc_.assign(dirs.size(), 0.0);
    }
    void reset() {
        std::fill(acc_.begin(), acc_.end(), 0.0);
        share_ = 0.0;
        sum_ = 0.0;
        total_ = 0.0;
        n_ = 0;
    }
    /// The second phase function's share of the samples added until the next reset().
    void set_share(double share) {
        FULGUR_ASSERT(mixed_ && n_ == 0 && share >= 0.0 && share <= 1.0, "PhaseAccumulator: share of a mix, per cell");
        share_ = share;
    }
    void add(double w, const glm::dvec3& d) {
        if (!(w > 0.0)) return;
        total_ += w;
        if (hg_.isotropic && !mixed_) {
            sum_ += w;
            return;
        }
        w_[n_] = w;
        x_[n_] = d.x;
        y_[n_] = d.y;
        z_[n_] = d.z;
        if (++n_ == kCap) flush();
    }
    /// Sum of the weights without the phase function (the uncollided fluence integral).
    double weight_sum() const noexcept { return total_; }
    /// Reduces and returns acc[m] (for every output direction).
    const std::vector<double>& result() {
        if (hg_.isotropic && !mixed_) {
            std::fill(acc_.begin(), acc_.end(), sum_ * hg_.norm);
        } else {
            flush();
        }
        return acc_;
    }

private:
    static constexpr std::size_t kCap = 256;
    void flush() {
        for (std::size_t m = 0; m < dirs_.size(); ++m) {
            const double s = phase_sum(hg_, dirs_[m]);
            acc_[m] += share_ > 0.0 ? mixed_phase(s, phase_sum(hg2_, dirs_[m]), share_) : s;
        }
        n_ = 0;
    }
    /// The pending samples' weights times p(s . d) for HG h.
    double phase_sum(const detail::HgConstants& h, const glm::dvec3& dir) const {
        // omp simd reduction: the vectorized summation order is fixed by the binary, so the
        // result is deterministic (and independent of the thread count).
        const std::size_t n = n_;
        const double* w = w_.data();
        const double* x = x_.data();
        const double* y = y_.data();
        const double* z = z_.data();
        const double a = h.one_minus_g_sq, b = h.two_g;
        const double sx = dir.x, sy = dir.y, sz = dir.z;
        double s = 0.0;
#pragma omp simd reduction(+ : s)
        for (std::size_t q = 0; q < n; ++q) {
            double c = sx * x[q] + sy * y[q] + sz * z[q];
            c = c > 1.0 ? 1.0 : (c < -1.0 ? -1.0 : c);
            const double d = a + b * (1.0 - c);
            s += w[q] / (d * std::sqrt(d));
        }
        return s * h.norm;
    }

    std::span<const glm::dvec3> dirs_;
    detail::HgConstants hg_, hg2_;
    bool mixed_ = false;
    double share_ = 0.0;
    std::vector<double> w_, x_, y_, z_, acc_;
    double total_ = 0.0;
    std::size_t n_ = 0;
    double sum_ = 0.0;
};

/// Bounding box (world) of the voxels with non-zero density; density is 0 outside it, so
/// transmittance rays are clipped to it (exact). Empty grid: an empty box (lo > hi).
struct DensityBounds {
    glm::dvec3 lo{1.0}, hi{-1.0};
};

constexpr int kMaxTensorOrder = 4;  // tensor Gauss rules use 1..4 points per axis
constexpr int kMaxDepth = 5;        // octree levels below a voxel
constexpr int kMaxCheckDepth = 2;   // below this level only boxes holding much of their voxel's light are checked
/// A sub-box below kMaxCheckDepth whose light (its nodes' sum of w T / r^2) is at least this
/// many times the tolerance of its voxel's is still checked for kinks and steep gradients: a
/// shadow edge or rays grazing a cloud base across the bright part of a voxel, which the checks
/// of the two levels above leave at up to 12% at tolerance 1e-5 (the storm, against the
/// brute-force reference, docs/transport.md), while the many sub-boxes that hold little of the
/// voxel's light are accepted unchecked. 100 against 10: at tolerance 1e-3 the largest error
/// 2.4% against 1.3% for 0.65 against 1.03 s per light.
inline constexpr double kDeepCheckShare = 100.0;
/// At tolerances at or below this a tensor rule on a box some ray to which meets density has
/// three nodes per axis at least, and sub-boxes below kMaxCheckDepth are checked by their
/// share of the voxel's light (Plan::checks_shadows).
inline constexpr double kShadowTolerance = 1e-3;

struct PointCtx {
    const core::GridGeometry* g;
    const float* rho;
    double kappa;
    glm::dvec3 xl;
    double cutoff;
    DensityBounds bounds;
    double sigma_max;  // largest extinction in the grid
    double optical_depth(const glm::dvec3& dir, double len) const noexcept {
        return detail::optical_depth_along(*g, rho, kappa, xl, dir, 0.0, len, cutoff, bounds.lo, bounds.hi);
    }
    double transmittance(const glm::dvec3& dir, double len) const noexcept {
        const double tau = optical_depth(dir, len);
        return tau > cutoff ? 0.0 : std::exp(-tau);
    }
};

/// Per-box choice of the quadrature rule from the tolerance (the accuracy knob).
///
/// Error model of an n-point Gauss-Legendre rule per axis on a box of size s (relative):
///   geometry: a_n (s / L)^{2n}, a_n = (n!)^4 / ((2n)!)^2 (the Gauss error bound for 1/x^2
///             on [d, d + s] is a_n (s/d)^{2n}), L = d_min / (1 + k_g), where
///             k_g = 1.5|g|/(1-|g|) approximates max |d ln p / d theta| of HG (2.8 at g=0.6);
///   attenuation inside the box: c_n (sigma s)^{2n}, c_n = (n!)^4 / ((2n+1) ((2n)!)^3),
///             the Gauss error for e^{-x} on [0, sigma s];
/// added. (Calibrated against the divergence-theorem reference in the tests: the measured
/// error stays below the tolerance.) The smallest n <= kMaxTensorOrder meeting the tolerance is
/// used; if attenuation alone cannot meet it the box is optically thick and gets the face
/// rule (exact radial integral); if geometry cannot, the box is split 2^3.

///
/// k_g bounds the phase function's variation over all scattering angles; near |g| = 1 it
/// grows as 1.5/(1-|g|) (150 at g = 0.99) and would split every box near the source to the
/// deepest level. phase_variation() bounds it over the angles a box actually presents: the
/// box is seen from the source within a cone, and for each output direction the scattering
/// angle stays in [theta_m - alpha, theta_m + alpha]; only boxes whose cone holds a direction's
/// forward peak (a thin pencil along each output direction) keep the full bound.
struct Plan {
    double eps;  // tolerance
    int n_face;  // points per axis of each face-rule piece
    double k_g;  // phase-function variation bound
    double cutoff;
    double g_ = 0.0;                                         // phase asymmetry (clamped to kMaxAbsG)
    double f_max_ = 0.0;                                     // max over theta of |d ln p / d theta| = 3|g|/(1-g^2)
    std::span<const glm::dvec3> dirs_;                       // unit output directions (empty: the global bound)
    std::array<double, kMaxTensorOrder + 1> geo_{}, att_{};  // a_n and c_n of the model
    Plan(double tolerance, double g, double cut, std::span<const glm::dvec3> directions = {})
        : eps(tolerance), cutoff(cut), dirs_(directions) {
        const double ag = std::min(std::fabs(g), kMaxAbsG);
        k_g = 1.5 * ag / (1.0 - ag);
        g_ = std::clamp(g, -kMaxAbsG, kMaxAbsG);
        f_max_ = 3.0 * ag / (1.0 - ag * ag);
        for (int n = 1; n <= kMaxTensorOrder; ++n) {
            const double lf = std::lgamma(n + 1.0), l2f = std::lgamma(2.0 * n + 1.0);
            geo_[std::size_t(n)] = std::exp(4.0 * lf - 2.0 * l2f);
            att_[std::size_t(n)] = std::exp(4.0 * lf - 3.0 * l2f) / (2.0 * n + 1.0);
        }
        // Face rule: ~1.5 digits per extra point per axis (measured, docs/transport.md).
        n_face = std::clamp(2 + int(std::ceil(-std::log10(tolerance) / 1.5)), 3, 12);
    }
    /// |d ln p / d theta| of HG at scattering angle theta (|g|; theta from the peak).
    double phase_slope(double theta) const noexcept {
        const double ag = std::fabs(g_);
        return 3.0 * ag * std::sin(theta) / (1.0 + ag * ag - 2.0 * ag * std::cos(theta));
    }
    /// The model's phase-variation constant for a box seen from the source within a cone of
    /// half-angle alpha about the unit vector `axis`: k_g scaled by the largest slope over
    /// the scattering angles the box presents to any output direction, relative to the
    /// largest slope over all angles (k_g itself when a direction's steepest angle is inside).
    double phase_variation(const glm::dvec3& axis, double alpha) const noexcept {
        if (g_ == 0.0 || dirs_.empty() || !(alpha < 0.5 * std::numbers::pi)) return k_g;
        const double ag = std::fabs(g_), steepest = std::acos(2.0 * ag / (1.0 + ag * ag));
        double worst = 0.0;
        for (const glm::dvec3& d : dirs_) {
            // For g < 0 the peak is backward: HG(theta; g) = HG(pi - theta; -g).
            const double c = std::clamp((g_ > 0.0 ? 1.0 : -1.0) * glm::dot(d, axis), -1.0, 1.0);
            const double theta = std::acos(c);
            const double lo = std::max(0.0, theta - alpha), hi = std::min(std::numbers::pi, theta + alpha);
            const double f = (lo <= steepest && steepest <= hi) ? f_max_ : std::max(phase_slope(lo), phase_slope(hi));
            worst = std::max(worst, f);
            if (worst >= f_max_) break;
        }
        return k_g * std::min(1.0, worst / f_max_);
    }
    /// Whether the face rules grade their angles toward the phase function's peak in every
    /// output direction (face_rule_point), and a box that no split within kMaxDepth would bring
    /// within the model is integrated by them: whenever the phase function has a peak (g != 0)
    /// and the output directions are known (docs/transport.md, "A peaked phase function").
    bool graded() const noexcept { return g_ != 0.0 && !dirs_.empty(); }
    /// The peak's angular scale in radians, 1 - |g|: HG's half width at half maximum is
    /// 0.77 (1 - |g|) / sqrt(|g|) near |g| = 1, its steepest log-slope at about 1 - |g|.
    double peak_width() const noexcept { return 1.0 - std::fabs(g_); }
    /// The direction of the peak for output direction m: along it for g > 0, against it for g < 0.
    glm::dvec3 peak(std::size_t m) const noexcept { return g_ > 0.0 ? dirs_[m] : -dirs_[m]; }
    std::size_t direction_count() const noexcept { return dirs_.size(); }
    /// Largest residual of the upstream optical depth about its linear fit over a box's nodes
    /// (a kink) accepted by the tensor rule; calibrated against the Monte Carlo reference on the
    /// default storm cloud (docs/transport.md): 0.1 * sqrt(tol / 1e-3).
    double kink_limit() const { return 0.1 * std::sqrt(eps / 1e-3); }
    /// Whether the quadrature looks for shadow edges beyond its first checks (tolerances down
    /// from kShadowTolerance): tensor rules on boxes some ray to which meets density get three
    /// nodes per axis, the fewest on which the check's linear fit of the optical depth has a
    /// residual along an axis (min_shadowed_order), and sub-boxes below kMaxCheckDepth holding
    /// kDeepCheckShare x tol of their voxel's light are checked too. At looser tolerances
    /// neither: at 1e-2 three nodes cost a bake about twice the time (the default storm 40 ->
    /// 76 s, the paper's configuration 27 -> 60 s) to bring single scattering's L1 error from
    /// 1e-3 to 3e-4, under the bake's compression error, and the deep checks doubled the paper's
    /// configuration's single scattering, whose lights graze a flat layer (docs/transport.md).
    bool checks_shadows() const { return eps <= kShadowTolerance; }
    /// The fewest nodes per axis of a tensor rule on a box some ray to which meets density.
    int min_shadowed_order() const { return checks_shadows() ? 3 : 2; }
    /// Whether a linear optical-depth variation with per-axis changes y[3] across the box is
    /// integrated to the tolerance by an order-n tensor rule: e^{-(y.x)} is separable, and the
    /// tensor rule's relative error is the sum of the per-axis errors c_n y_a^{2n}.
    bool smooth_ok(int n, const double* y) const {
        double e = 0.0;
        for (int a = 0; a < 3; ++a) e += att_[std::size_t(n)] * std::pow(std::fabs(y[a]), 2.0 * n);
        return e <= eps;
    }
    /// Smallest adequate tensor order, or 0 (thick set when attenuation is the obstacle).
    int tensor_order(double s, double inv_len, double sigma, bool& thick) const {
        const double x = s * inv_len, y = sigma * s;
        double x2 = x * x, y2 = y * y, xp = 1.0, yp = 1.0;
        for (int n = 1; n <= kMaxTensorOrder; ++n) {
            xp *= x2;
            yp *= y2;
            if (geo_[std::size_t(n)] * xp + att_[std::size_t(n)] * yp <= eps) return n;
        }
        thick = att_[kMaxTensorOrder] * yp > eps;
        return 0;
    }
};

// ---- point source ----------------------------------------------------------------------

/// Face rule for one face (normal axis ax, lower or upper) of box b, point source.
/// inside: the source is in the box's closure (rays start in the box, T = 1, chord = R);
/// otherwise the source sees the face from outside (entry face). With a plan whose phase
/// function is peaked (Plan::graded), the face's angles are also split geometrically toward
/// every output direction's peak, from its width (1 - |g|) outward, in azimuth and, along
/// each azimuth, in polar angle: a Gauss rule then sees the peak as a smooth function.
void face_rule_point(const PointCtx& c, const Box& b, double sigma, int ax, bool upper, bool inside, int n,
                     PhaseAccumulator& acc, const Plan* peaks = nullptr);

/// Tensor rule of order n on box b. Returns false without accumulating anything when the
/// transmittance to the nodes is not what an order-n Gauss rule integrates to the tolerance:
/// the optical depth over the nodes is fitted by a linear function (on a tensor grid the
/// least-squares fit decouples per axis);
///  * the fit's variation across the box, y_a per axis, is a smooth (separable) exponential:
///    it must pass the attenuation model, sum_a c_n y_a^{2n} <= tol (behind a cloud the
///    optical depth can vary across a box much more than the box's own sigma * s);
///  * the largest residual (a kink: a shadow edge of an upstream voxel crossing the box,
///    which Gauss rules integrate poorly) must stay below plan.kink_limit().
/// On failure, *retry_order is the order the measured smooth variation needs (0: none does,
/// or a kink was found: split the box). The check is made only when the nodes' estimate of
/// the box's uncollided weight, sum w T / r^2, is at least `check_above` (a box holding too
/// small a share of its voxel's light for its error to matter is accepted as it is); that
/// estimate is written to *weight whether the rule is accepted or not.
bool tensor_rule_point(const PointCtx& c, const Box& b, int n, const Plan* check, PhaseAccumulator& acc,
                       int* retry_order = nullptr, double check_above = 0.0, double* weight = nullptr);

// ---- sun -------------------------------------------------------------------------------

struct SunCtx {
    const core::GridGeometry* g;
    const float* rho;
    double kappa;
    glm::dvec3 d;  // propagation direction, unit
    double cutoff;
    DensityBounds bounds;
    double optical_depth(const glm::dvec3& x) const noexcept {
        return detail::optical_depth_along(*g, rho, kappa, x, -d, 0.0, detail::kInf, cutoff, bounds.lo, bounds.hi);
    }
    double transmittance(const glm::dvec3& x) const noexcept {
        const double tau = optical_depth(x);
        return tau > cutoff ? 0.0 : std::exp(-tau);
    }
};

/// A voxel's sun integral is refined to tol of itself, or of this share of its volume (its
/// integral unshadowed is at most the volume) where it is darker (face_rule_sun).
inline constexpr double kSunRefineFloor = 1e-3;
/// The sun's face rule: 3 x 3 Gauss-Legendre nodes per piece, whose quarters are compared with
/// it and refined at most 4 levels further (a piece quartered at most 5 times: 1024 sub-pieces,
/// 12285 transmittances at most). Measured against the brute-force reference on the default
/// storm (docs/transport.md, "The sun"): 2 nodes took as long for larger errors, 4 nodes longer
/// for the same; 6 levels took up to 2x the time at 1e-4 for no measured gain.
inline constexpr int kSunFaceOrder = 3;
inline constexpr int kSunRefineDepth = 4;
/// The tightest tolerance the sun's refinement works to: at 1e-4 it is within 1e-5 (L1) and
/// 0.04% of the brute-force reference, that reference's own resolution; a tighter knob would
/// refine every piece to the depth limit for digits nothing can check.
inline constexpr double kSunFinestTolerance = 1e-5;

/// integral over box of T_sun with the radial (along d) integral exact: sum over the entry
/// faces of |d . n| * integral_face T_in (1 - e^{-sigma l})/sigma dA. Each face is split into
/// axis-aligned sub-rectangles at the lines where the exit face changes, each integrated by an
/// n x n Gauss-Legendre rule, then refined adaptively (quartered where its quarters disagree
/// with it) to `depth` levels, the error allowed tol of the voxel's integral (kSunRefineFloor)
/// shared by area: T_in has kinks along the projections of the upstream voxels' edges, which a
/// fixed rule integrates only to a few percent. tol <= 0 or depth <= 0: the fixed rule alone.
double face_rule_sun(const SunCtx& c, const Box& b, double sigma, int n, double tol, int depth);

}  // namespace fulgur::transport::detail
