// Transmittance by exact voxel traversal and exact (voxel-averaged) single scattering.
//
// The quantity: S1_i(s) = albedo * I / V * integral over voxel i of p(s . w(x)) T(x_l, x) / r^2
// (point source) or albedo * E * p(s . d) / V * integral over voxel i of T_sun(x) (sun).
// Three quadrature rules, chosen per box (a voxel or an octree sub-box of it):
//
//  * "inside" face rule, for a box whose closure contains the point source. In spherical
//    coordinates around the source the r^2 of the volume element cancels the 1/r^2, and with
//    constant density in the box the radial integral is analytic:
//        integral_box p T / r^2 dx = integral over directions p(s.w) (1 - e^{-sigma R(w)})/sigma dw,
//    R(w) the distance to the box boundary. The sphere of directions is split into the six
//    pyramids "source -> face"; each face is parametrized in polar coordinates (phi, u) around
//    the foot of the perpendicular from the source, u = cos(angle to the face normal), where
//    dw = du dphi exactly. phi is split at the corner directions (so the distance to the
//    face edge is smooth in each piece) and u is split geometrically (ratio <= 4), which
//    resolves the 1/u growth of R = a/u when the source sits close to a face plane.
//  * "outside" face rule, for a box near the source or optically thick: the same
//    parametrization over each face the source sees from outside, with the integrand
//    T(x_l, y) (1 - e^{-sigma l})/sigma, y the entry point on the face (DDA transmittance)
//    and l the chord through the box. The chord's kink (exit through the opposite face vs a
//    side face) is a known radius rho_k = rho_out * a / (a + depth) and is split exactly.
//    The radial integral is exact, so optically thick voxels are integrated correctly.
//  * tensor Gauss rule (order^3 nodes) for far, optically thin boxes, with exact DDA
//    transmittance to every node; boxes closer than 3 box sizes are split 2^3 (twice at most).
#include "transport/detail/kernels.h"
#include "transport/detail/traversal.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

namespace fulgur::transport {

// ---------------------------------------------------------------------------------------
// Gauss-Legendre rules

namespace detail {

GaussRule gauss_legendre(int n) {
    struct Table {
        std::array<std::array<double, kMaxGaussPoints>, kMaxGaussPoints + 1> x{}, w{};
        Table() {
            for (int m = 1; m <= kMaxGaussPoints; ++m) {
                for (int i = 0; i < m; ++i) {
                    // Newton on P_m from the Tricomi-like initial guess; descending roots.
                    double z = std::cos(std::numbers::pi * (double(i) + 0.75) / (double(m) + 0.5));
                    double dp = 1.0;
                    for (int it = 0; it < 100; ++it) {
                        double p0 = 1.0, p1 = 0.0;
                        for (int j = 1; j <= m; ++j) {
                            const double p2 = p1;
                            p1 = p0;
                            p0 = ((2.0 * j - 1.0) * z * p1 - (j - 1.0) * p2) / j;
                        }
                        dp = m * (z * p0 - p1) / (z * z - 1.0);
                        const double dz = p0 / dp;
                        z -= dz;
                        if (std::fabs(dz) < 1e-15) break;
                    }
                    // Recompute the derivative at the converged root for the weight.
                    double p0 = 1.0, p1 = 0.0;
                    for (int j = 1; j <= m; ++j) {
                        const double p2 = p1;
                        p1 = p0;
                        p0 = ((2.0 * j - 1.0) * z * p1 - (j - 1.0) * p2) / j;
                    }
                    dp = m * (z * p0 - p1) / (z * z - 1.0);
                    // Map [-1, 1] -> [0, 1]: z descends with i, so x = (1 - z)/2 ascends.
                    x[std::size_t(m)][std::size_t(i)] = 0.5 * (1.0 - z);
                    w[std::size_t(m)][std::size_t(i)] = 1.0 / ((1.0 - z * z) * dp * dp);  // 2/((1-z^2)P'^2) / 2
                }
            }
        }
    };
    static const Table t;
    FULGUR_ASSERT(n >= 1 && n <= kMaxGaussPoints, "Gauss-Legendre order out of range");
    return {std::span<const double>(t.x[std::size_t(n)].data(), std::size_t(n)),
            std::span<const double>(t.w[std::size_t(n)].data(), std::size_t(n))};
}

}  // namespace detail

// ---------------------------------------------------------------------------------------
// Validation and transmittance

void validate_medium(const LightingMedium& m) {
    core::validate_geometry(m.density.geom, "medium.density");
    if (m.density.data.size() != m.density.geom.cell_count())
        throw core::Error("medium.density", "has " + std::to_string(m.density.data.size()) + " values for " +
                                                std::to_string(m.density.geom.cell_count()) + " voxels");
    const Medium& o = m.optics;
    if (!std::isfinite(o.extinction) || o.extinction < 0.0)
        throw core::Error("medium.extinction",
                          "must be a finite value >= 0 (1/m), got " + std::to_string(o.extinction));
    if (!(o.albedo >= 0.0 && o.albedo <= 1.0))
        throw core::Error("medium.albedo", "must be in [0, 1], got " + std::to_string(o.albedo));
    if (!std::isfinite(o.g)) throw core::Error("medium.g", "must be finite (it is clamped to +-0.9999)");
    for (std::size_t c = 0; c < m.density.data.size(); ++c) {
        const float v = m.density.data[c];
        if (!(v >= 0.0f && v <= 1.0f)) {
            const core::Int3 ijk = m.density.geom.unindex(c);
            throw core::Error("medium.density[" + std::to_string(ijk.x) + "," + std::to_string(ijk.y) + "," +
                                  std::to_string(ijk.z) + "]",
                              "density must be in [0, 1], got " + std::to_string(v));
        }
    }
}

double optical_depth(const LightingMedium& m, const glm::dvec3& a, const glm::dvec3& b) noexcept {
    const glm::dvec3 d = b - a;
    const double len = glm::length(d);
    if (!(len > 0.0) || !std::isfinite(len)) return 0.0;
    return detail::optical_depth_along(m.density.geom, m.density.data.data(), m.optics.extinction, a, d / len, 0.0,
                                       len);
}

double transmittance(const LightingMedium& m, const glm::dvec3& a, const glm::dvec3& b) noexcept {
    return std::exp(-optical_depth(m, a, b));
}

double optical_depth_to_sun(const LightingMedium& m, const glm::dvec3& x, const glm::dvec3& direction) noexcept {
    const double len = glm::length(direction);
    if (!(len > 0.0) || !std::isfinite(len)) return 0.0;
    return detail::optical_depth_along(m.density.geom, m.density.data.data(), m.optics.extinction, x, -direction / len,
                                       0.0, detail::kInf);
}

// ---------------------------------------------------------------------------------------
// Single scattering

namespace {

using detail::chord_integral;
using detail::gauss_legendre;
using detail::GaussRule;

struct Box {
    glm::dvec3 lo, hi;
};

/// Collects weighted direction samples (w, omega) and reduces them to
/// acc[m] = sum w * p(s_m . omega). Samples are buffered in SoA form so the reduction over
/// samples vectorizes; for g == 0 only the sum of weights is kept.
class PhaseAccumulator {
public:
    PhaseAccumulator(std::span<const glm::dvec3> dirs, double g) : dirs_(dirs), hg_(g) {
        if (!hg_.isotropic) {
            w_.resize(kCap);
            x_.resize(kCap);
            y_.resize(kCap);
            z_.resize(kCap);
        }
        acc_.assign(dirs.size(), 0.0);
    }
    void reset() {
        std::fill(acc_.begin(), acc_.end(), 0.0);
        sum_ = 0.0;
        total_ = 0.0;
        n_ = 0;
    }
    void add(double w, const glm::dvec3& d) {
        if (!(w > 0.0)) return;
        total_ += w;
        if (hg_.isotropic) {
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
        if (hg_.isotropic) {
            std::fill(acc_.begin(), acc_.end(), sum_ * hg_.norm);
        } else {
            flush();
        }
        return acc_;
    }

private:
    static constexpr std::size_t kCap = 256;
    void flush() {
        // omp simd reduction: the vectorized summation order is fixed by the binary, so the
        // result is deterministic (and independent of the thread count).
        const std::size_t n = n_;
        const double* w = w_.data();
        const double* x = x_.data();
        const double* y = y_.data();
        const double* z = z_.data();
        const double a = hg_.one_minus_g_sq, b = hg_.two_g;
        for (std::size_t m = 0; m < dirs_.size(); ++m) {
            const double sx = dirs_[m].x, sy = dirs_[m].y, sz = dirs_[m].z;
            double s = 0.0;
#pragma omp simd reduction(+ : s)
            for (std::size_t q = 0; q < n; ++q) {
                double c = sx * x[q] + sy * y[q] + sz * z[q];
                c = c > 1.0 ? 1.0 : (c < -1.0 ? -1.0 : c);
                const double d = a + b * (1.0 - c);
                s += w[q] / (d * std::sqrt(d));
            }
            acc_[m] += s * hg_.norm;
        }
        n_ = 0;
    }

    std::span<const glm::dvec3> dirs_;
    detail::HgConstants hg_;
    std::vector<double> w_, x_, y_, z_, acc_;
    double total_ = 0.0;
    std::size_t n_ = 0;
    double sum_ = 0.0;
};

/// Insertion sort for the few breakpoints of a face (std::sort on such small arrays trips a
/// GCC 12 -Warray-bounds false positive under the sanitizer build).
void sort_small(double* a, int n) {
    for (int i = 1; i < n; ++i) {
        const double v = a[i];
        int j = i - 1;
        while (j >= 0 && a[j] > v) {
            a[j + 1] = a[j];
            --j;
        }
        a[j + 1] = v;
    }
}

/// Angular breakpoints (ascending) of the polar decomposition, around the foot point, of the
/// face rectangle [A0,A1]x[B0,B1] (coordinates relative to the foot point). Between two
/// consecutive breakpoints the ray from the foot point enters and leaves the rectangle (and,
/// for an entry face, the region whose rays leave through the opposite face, the rectangle
/// scaled by k = a/(a+depth) about the foot point) through fixed edges, so every radius is a
/// smooth function of the angle. Breakpoints are the corners of the rectangle and of its
/// intersection with the scaled rectangle, plus a geometric grading (x = 0, +-d, +-4d, ...)
/// along every edge line whose distance d to the foot point is small compared with the
/// rectangle: the radius d / sin(angle) to such an edge varies over orders of magnitude.
/// Returns the number of breakpoints (at most kMaxBreaks).
constexpr int kMaxBreaks = 96;
int polar_breakpoints(double A0, double A1, double B0, double B1, double k, double* phi) {
    const bool inside = A0 < 0.0 && A1 > 0.0 && B0 < 0.0 && B1 > 0.0;
    const double cx = 0.5 * (A0 + A1), cy = 0.5 * (B0 + B1);
    const double base = std::atan2(cy, cx);
    const double phi0 = std::atan2(B0, A0);  // inside: the decomposition starts at corner (A0,B0)
    // Angle of the point (x, y) in the decomposition's frame (no wrap inside the range).
    auto angle = [&](double x, double y) {
        if (inside) {
            double a = std::atan2(y, x);
            if (a < phi0) a += 2.0 * std::numbers::pi;
            return a;
        }
        return base + std::atan2(cx * y - cy * x, cx * x + cy * y);
    };
    int n = 0;
    auto corners = [&](double a0, double a1, double b0, double b1) {
        const double c[4][2] = {{a0, b0}, {a1, b0}, {a1, b1}, {a0, b1}};
        for (const auto& q : c)
            if (!(q[0] == 0.0 && q[1] == 0.0) && n < kMaxBreaks) phi[n++] = angle(q[0], q[1]);
    };
    corners(A0, A1, B0, B1);
    double lo_phi, hi_phi;
    if (inside) {
        lo_phi = phi0;
        hi_phi = phi0 + 2.0 * std::numbers::pi;
        phi[n++] = hi_phi;
    } else {
        lo_phi = *std::min_element(phi, phi + n);
        hi_phi = *std::max_element(phi, phi + n);
        if (k > 0.0) {
            const double i0 = std::max(A0, A0 * k), i1 = std::min(A1, A1 * k);
            const double j0 = std::max(B0, B0 * k), j1 = std::min(B1, B1 * k);
            if (i1 > i0 && j1 > j0) corners(i0, i1, j0, j1);
        }
    }
    // Grading toward edge lines close to the foot point.
    const double lines[4] = {A0, A1, B0, B1};
    for (int l = 0; l < 4; ++l) {
        const double e = lines[l];
        const double d = std::fabs(e);
        if (!(d > 0.0)) continue;
        const bool vertical = l < 2;  // the line u = e (else v = e)
        const double lo = vertical ? B0 : A0, hi = vertical ? B1 : A1;
        const double extent = std::max(std::fabs(lo), std::fabs(hi));
        if (!(d < 0.25 * extent)) continue;
        auto add = [&](double x) {
            if (x <= lo || x >= hi || n >= kMaxBreaks) return;
            const double a = vertical ? angle(e, x) : angle(x, e);
            if (a > lo_phi && a < hi_phi) phi[n++] = a;
        };
        add(0.0);
        for (double x = d; x < extent; x *= 4.0) {
            add(x);
            add(-x);
        }
    }
    sort_small(phi, n);
    return n;
}

/// Interval [rin, rout] of the ray from the origin along (cx, cy) inside [A0,A1]x[B0,B1].
inline bool slab2(double cx, double cy, double A0, double A1, double B0, double B1, double& rin, double& rout) {
    rin = 0.0;
    rout = detail::kInf;
    auto axis = [&](double c, double lo, double hi) {
        if (c == 0.0) return lo <= 0.0 && hi >= 0.0;
        double t0 = lo / c, t1 = hi / c;
        if (t0 > t1) std::swap(t0, t1);
        rin = std::max(rin, t0);
        rout = std::min(rout, t1);
        return true;
    };
    if (!axis(cx, A0, A1) || !axis(cy, B0, B1)) return false;
    return rout > rin;
}

/// Bounding box (world) of the voxels with non-zero density; density is 0 outside it, so
/// transmittance rays are clipped to it (exact). Empty grid: an empty box (lo > hi).
struct DensityBounds {
    glm::dvec3 lo{1.0}, hi{-1.0};
};

DensityBounds density_bounds(const LightingMedium& m) {
    const core::GridGeometry& g = m.density.geom;
    core::Int3 lo{g.dims.x, g.dims.y, g.dims.z}, hi{-1, -1, -1};
    for (int k = 0; k < g.dims.z; ++k)
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i)
                if (m.density.at(i, j, k) > 0.0f) {
                    lo = {std::min(lo.x, i), std::min(lo.y, j), std::min(lo.z, k)};
                    hi = {std::max(hi.x, i), std::max(hi.y, j), std::max(hi.z, k)};
                }
    DensityBounds b;
    if (hi.x < 0) return b;
    b.lo = g.origin + glm::dvec3(lo.x, lo.y, lo.z) * g.voxel_size;
    b.hi = g.origin + glm::dvec3(hi.x + 1, hi.y + 1, hi.z + 1) * g.voxel_size;
    return b;
}

constexpr int kMaxTensorOrder = 4;  // tensor Gauss rules use 1..4 points per axis
constexpr int kMaxDepth = 5;        // octree levels below a voxel
constexpr int kMaxCheckDepth = 2;   // a-posteriori transmittance checks stop below this level

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

/// Face rule for one face (normal axis ax, lower or upper) of box b, point source.
/// inside: the source is in the box's closure (rays start in the box, T = 1, chord = R);
/// otherwise the source sees the face from outside (entry face).
void face_rule_point(const PointCtx& c, const Box& b, double sigma, int ax, bool upper, bool inside, int n,
                     PhaseAccumulator& acc) {
    const int ua = (ax + 1) % 3, va = (ax + 2) % 3;
    const double plane = upper ? b.hi[ax] : b.lo[ax];
    const double a = std::fabs(plane - c.xl[ax]);
    if (!(a > 0.0)) return;  // face plane through the source: zero solid angle
    const double sgn = plane > c.xl[ax] ? 1.0 : -1.0;
    const double depth = b.hi[ax] - b.lo[ax];
    const double A0 = b.lo[ua] - c.xl[ua], A1 = b.hi[ua] - c.xl[ua];
    const double B0 = b.lo[va] - c.xl[va], B1 = b.hi[va] - c.xl[va];
    double phi[kMaxBreaks];
    const int nb = polar_breakpoints(A0, A1, B0, B1, inside ? 0.0 : a / (a + depth), phi);
    const GaussRule gr = gauss_legendre(n);
    for (int iv = 0; iv + 1 < nb; ++iv) {
        const double p0 = phi[iv], dp = phi[iv + 1] - phi[iv];
        if (!(dp > 1e-15)) continue;
        for (int jp = 0; jp < n; ++jp) {
            const double ph = p0 + dp * gr.x[std::size_t(jp)];
            const double wph = dp * gr.w[std::size_t(jp)];
            const double cph = std::cos(ph), sph = std::sin(ph);
            double rin, rout;
            if (!slab2(cph, sph, A0, A1, B0, B1, rin, rout)) continue;
            // Radial pieces: inside -> [0, rout]; outside -> exit through the opposite face
            // for rho <= rho_k, through the side face beyond.
            double pieces[3];
            int np;
            if (inside) {
                pieces[0] = rin;
                pieces[1] = rout;
                np = 2;
            } else {
                const double rk = std::clamp(rout * a / (a + depth), rin, rout);
                pieces[0] = rin;
                pieces[1] = rk;
                pieces[2] = rout;
                np = 3;
            }
            for (int ip = 0; ip + 1 < np; ++ip) {
                const double ra = pieces[ip], rb = pieces[ip + 1];
                if (!(rb > ra)) continue;
                const bool side = !inside && ip == 1;
                // Polar angle theta (from the face normal) limits; u = cos(theta).
                const double th_a = std::atan2(ra, a), th_b = std::atan2(rb, a);
                const double u_hi = std::cos(th_a), u_lo = std::cos(th_b);
                if (!(th_b > th_a)) continue;
                // Geometric grading in u (ratio <= 4 per sub-piece) resolves R = a/u growing
                // toward grazing directions; inside a sub-piece the variable is theta
                // (dw = sin(theta) dtheta dphi), which, unlike u, keeps the integrand smooth
                // at the pole theta = 0 (directions there depend on sqrt(1 - u^2)).
                const int nsub = std::max(1, int(std::ceil(std::log(u_hi / u_lo) / std::log(4.0) - 1e-9)));
                const double ratio = std::pow(u_hi / u_lo, 1.0 / nsub);
                double t_lo = th_b;  // sub-pieces from grazing (small u) toward the normal
                double u_edge = u_lo;
                for (int is = 0; is < nsub; ++is) {
                    u_edge *= ratio;
                    const double t_hi_piece = (is + 1 == nsub) ? th_a : std::acos(std::min(1.0, u_edge));
                    // Outside faces: the entry transmittance can fall by e^{-sigma_max dR} across
                    // the piece (light crossing the source's dense voxel): split so that each
                    // part spans at most 1.5 optical depths at the medium's largest extinction.
                    int nparts = 1;
                    if (!inside && c.sigma_max > 0.0) {
                        const double dR = a / std::cos(t_lo) - a / std::cos(t_hi_piece);
                        nparts = std::clamp(int(std::ceil(c.sigma_max * std::fabs(dR) / 1.5)), 1, 16);
                    }
                    const double t_lo_piece = t_lo;
                    for (int ip2 = 0; ip2 < nparts; ++ip2) {
                        const double t_hi = t_lo_piece - (t_lo_piece - t_hi_piece) * (ip2 + 1) / nparts;
                        t_lo = t_lo_piece - (t_lo_piece - t_hi_piece) * ip2 / nparts;
                        const double dth = t_lo - t_hi;  // > 0: t_hi < t_lo
                        for (int ju = 0; ju < n; ++ju) {
                            const double th = t_hi + dth * gr.x[std::size_t(ju)];
                            const double u = std::cos(th), sn = std::sin(th);
                            const double w = wph * dth * gr.w[std::size_t(ju)] * sn;
                            glm::dvec3 dir;
                            dir[ax] = sgn * u;
                            dir[ua] = sn * cph;
                            dir[va] = sn * sph;
                            const double R = a / u;
                            double value;
                            if (inside) {
                                value = chord_integral(sigma, R);
                            } else {
                                const double T = c.transmittance(dir, R);
                                if (T == 0.0) continue;
                                double len;
                                if (!side) {
                                    len = depth / u;
                                } else {
                                    const double rho = a * sn / u;
                                    len = rho > 0.0 ? R * std::max(0.0, rout - rho) / rho : 0.0;
                                }
                                value = T * chord_integral(sigma, len);
                            }
                            acc.add(w * value, dir);
                        }
                    }
                    t_lo = t_hi_piece;
                }
            }
        }
    }
}

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

struct Plan {
    double eps;  // tolerance
    int n_face;  // points per axis of each face-rule piece
    double k_g;  // phase-function variation bound
    double cutoff;
    std::array<double, kMaxTensorOrder + 1> geo_{}, att_{};  // a_n and c_n of the model
    Plan(double tolerance, double g, double cut) : eps(tolerance), cutoff(cut) {
        const double ag = std::min(std::fabs(g), kMaxAbsG);
        k_g = 1.5 * ag / (1.0 - ag);
        for (int n = 1; n <= kMaxTensorOrder; ++n) {
            const double lf = std::lgamma(n + 1.0), l2f = std::lgamma(2.0 * n + 1.0);
            geo_[std::size_t(n)] = std::exp(4.0 * lf - 2.0 * l2f);
            att_[std::size_t(n)] = std::exp(4.0 * lf - 3.0 * l2f) / (2.0 * n + 1.0);
        }
        // Face rule: ~1.5 digits per extra point per axis (measured, docs/transport.md).
        n_face = std::clamp(2 + int(std::ceil(-std::log10(tolerance) / 1.5)), 3, 12);
    }
    /// Largest residual of the upstream optical depth about its linear fit over a box's nodes
    /// (a kink) accepted by the tensor rule; calibrated against the Monte Carlo reference on the
    /// default storm cloud (docs/transport.md): 0.1 * sqrt(tol / 1e-3).
    double kink_limit() const { return 0.1 * std::sqrt(eps / 1e-3); }
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

/// Checks optical depths at the n^3 tensor nodes (x fastest) against the plan: returns 0 if
/// an order-n rule is adequate, otherwise the order the smooth part needs (> n) or -1 (a
/// kink, or no order suffices). Linear least-squares fit per axis, as described at
/// tensor_rule_point().
int check_nodes(const double* tau, int n, const Plan& plan) {
    const GaussRule gr = gauss_legendre(n);
    const int nn = n * n * n;
    double mean = 0.0;
    for (int q = 0; q < nn; ++q) mean += tau[q];
    mean /= nn;
    double su2 = 0.0;
    for (int i = 0; i < n; ++i) su2 += (gr.x[std::size_t(i)] - 0.5) * (gr.x[std::size_t(i)] - 0.5);
    double slope[3] = {0.0, 0.0, 0.0};
    for (int q = 0; q < nn; ++q) {
        const int ii[3] = {q % n, (q / n) % n, q / (n * n)};
        for (int a = 0; a < 3; ++a) slope[a] += tau[q] * (gr.x[std::size_t(ii[a])] - 0.5);
    }
    for (double& sl : slope) sl /= su2 * n * n;
    double resid = 0.0;
    for (int q = 0; q < nn; ++q) {
        const int ii[3] = {q % n, (q / n) % n, q / (n * n)};
        double fit = mean;
        for (int a = 0; a < 3; ++a) fit += slope[a] * (gr.x[std::size_t(ii[a])] - 0.5);
        resid = std::max(resid, std::fabs(tau[q] - fit));
    }
    if (resid > plan.kink_limit()) return -1;
    if (plan.smooth_ok(n, slope)) return 0;
    for (int m = n + 1; m <= kMaxTensorOrder; ++m)
        if (plan.smooth_ok(m, slope)) return m;
    return -1;
}

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
/// or a kink was found: split the box).
bool tensor_rule_point(const PointCtx& c, const Box& b, int n, const Plan* check, PhaseAccumulator& acc,
                       int* retry_order = nullptr) {
    const GaussRule gr = gauss_legendre(n);
    const glm::dvec3 ext = b.hi - b.lo;
    const double vol = ext.x * ext.y * ext.z;
    struct Node {
        double w;
        glm::dvec3 dir;
    };
    constexpr int kMaxNodes = kMaxTensorOrder * kMaxTensorOrder * kMaxTensorOrder;
    Node nodes[kMaxNodes];
    double up[kMaxNodes];
    int nn = 0;
    bool any_lit = false;
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const glm::dvec3 x(b.lo.x + ext.x * gr.x[std::size_t(i)], b.lo.y + ext.y * gr.x[std::size_t(j)],
                                   b.lo.z + ext.z * gr.x[std::size_t(k)]);
                const glm::dvec3 r = x - c.xl;
                const double r2 = glm::dot(r, r);
                const double R = std::sqrt(r2);
                const glm::dvec3 dir = r / R;
                const double tau = std::min(c.cutoff, c.optical_depth(dir, R));
                up[nn] = tau;
                any_lit = any_lit || tau < c.cutoff;
                const double T = tau >= c.cutoff ? 0.0 : std::exp(-tau);
                const double w = gr.w[std::size_t(i)] * gr.w[std::size_t(j)] * gr.w[std::size_t(k)] * vol;
                nodes[nn++] = {w * T / r2, dir};
            }
    if (check && n > 1 && any_lit) {
        const int verdict = check_nodes(up, n, *check);
        if (verdict != 0) {
            if (retry_order) *retry_order = std::max(verdict, 0);
            return false;
        }
    }
    for (int q = 0; q < nn; ++q) acc.add(nodes[q].w, nodes[q].dir);
    return true;
}

double box_distance(const Box& b, const glm::dvec3& p) {
    const glm::dvec3 q = glm::max(b.lo - p, glm::max(glm::dvec3(0.0), p - b.hi));
    return glm::length(q);
}

void split_box(const PointCtx& c, const Box& b, double sigma, int depth, const Plan& plan, PhaseAccumulator& acc);

void integrate_box_point(const PointCtx& c, const Box& b, double sigma, int depth, const Plan& plan,
                         PhaseAccumulator& acc) {
    const double s = b.hi.x - b.lo.x;
    const double dmin = box_distance(b, c.xl);
    if (dmin == 0.0) {
        for (int ax = 0; ax < 3; ++ax) {
            face_rule_point(c, b, sigma, ax, false, true, plan.n_face, acc);
            face_rule_point(c, b, sigma, ax, true, true, plan.n_face, acc);
        }
        return;
    }
    bool thick = false;
    int n = dmin < s ? 0 : plan.tensor_order(s, (1.0 + plan.k_g) / dmin, sigma, thick);
    // A one-node rule cannot see transmittance varying across the box (a shadow edge, rays
    // grazing a cloud base): it is only used when no ray from the source to the box can
    // meet density (the bounding box of source and box misses the density bounds, T == 1).
    if (n == 1) {
        const glm::dvec3 hlo = glm::min(b.lo, c.xl), hhi = glm::max(b.hi, c.xl);
        const bool clear = hhi.x <= c.bounds.lo.x || hhi.y <= c.bounds.lo.y || hhi.z <= c.bounds.lo.z ||
                           hlo.x >= c.bounds.hi.x || hlo.y >= c.bounds.hi.y || hlo.z >= c.bounds.hi.z;
        if (!clear) n = 2;
    }
    if (n > 0) {
        const Plan* check = depth < kMaxCheckDepth ? &plan : nullptr;
        int retry = 0;
        if (tensor_rule_point(c, b, n, check, acc, &retry)) return;
        // A steep but smooth transmittance gradient (rays grazing a cloud layer, deep shadow):
        // a higher order is much cheaper than a split. A kink (shadow edge): split.
        if (retry > n && tensor_rule_point(c, b, retry, check, acc)) return;
        split_box(c, b, sigma, depth, plan, acc);
        return;
    }
    if (dmin < s || thick) {
        // (A lower order for far faces halves the rays but raised the 99th-percentile
        // error from 5% to 22% in the calibration: the full face order is used.)
        const int nf = plan.n_face;
        for (int ax = 0; ax < 3; ++ax) {
            if (c.xl[ax] < b.lo[ax]) face_rule_point(c, b, sigma, ax, false, false, nf, acc);
            if (c.xl[ax] > b.hi[ax]) face_rule_point(c, b, sigma, ax, true, false, nf, acc);
        }
        return;
    }
    if (depth >= kMaxDepth) {
        tensor_rule_point(c, b, kMaxTensorOrder, nullptr, acc);
        return;
    }
    split_box(c, b, sigma, depth, plan, acc);
}

void split_box(const PointCtx& c, const Box& b, double sigma, int depth, const Plan& plan, PhaseAccumulator& acc) {
    const glm::dvec3 mid = 0.5 * (b.lo + b.hi);
    for (int o = 0; o < 8; ++o) {
        Box cb;
        cb.lo = glm::dvec3((o & 1) ? mid.x : b.lo.x, (o & 2) ? mid.y : b.lo.y, (o & 4) ? mid.z : b.lo.z);
        cb.hi = glm::dvec3((o & 1) ? b.hi.x : mid.x, (o & 2) ? b.hi.y : mid.y, (o & 4) ? b.hi.z : mid.z);
        integrate_box_point(c, cb, sigma, depth + 1, plan, acc);
    }
}

// Sun ------------------------------------------------------------------------------------

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

/// integral over box of T_sun, tensor rule of order n; with a plan, fails (returns false)
/// when check_nodes() rejects the nodes, setting *retry as check_nodes() does.
bool tensor_rule_sun(const SunCtx& c, const Box& b, int n, const Plan* check, double& result, int* retry) {
    const GaussRule gr = gauss_legendre(n);
    const glm::dvec3 ext = b.hi - b.lo;
    double tau[kMaxTensorOrder * kMaxTensorOrder * kMaxTensorOrder];
    int nn = 0;
    double s = 0.0;
    bool any_lit = false;
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const glm::dvec3 x(b.lo.x + ext.x * gr.x[std::size_t(i)], b.lo.y + ext.y * gr.x[std::size_t(j)],
                                   b.lo.z + ext.z * gr.x[std::size_t(k)]);
                const double t = std::min(c.cutoff, c.optical_depth(x));
                any_lit = any_lit || t < c.cutoff;
                tau[nn++] = t;
                const double T = t >= c.cutoff ? 0.0 : std::exp(-t);
                s += gr.w[std::size_t(i)] * gr.w[std::size_t(j)] * gr.w[std::size_t(k)] * T;
            }
    if (check && n > 1 && any_lit) {
        const int verdict = check_nodes(tau, n, *check);
        if (verdict != 0) {
            if (retry) *retry = verdict;
            return false;
        }
    }
    result = s * ext.x * ext.y * ext.z;
    return true;
}

/// integral over box of T_sun with the radial (along d) integral exact: sum over the entry
/// faces of |d . n| * integral_face T_in (1 - e^{-sigma l})/sigma dA. Each face is split into
/// axis-aligned sub-rectangles at the lines where the exit face changes.
double face_rule_sun(const SunCtx& c, const Box& b, double sigma, int n) {
    const GaussRule gr = gauss_legendre(n);
    double total = 0.0;
    for (int ax = 0; ax < 3; ++ax) {
        if (c.d[ax] == 0.0) continue;
        const int ua = (ax + 1) % 3, va = (ax + 2) % 3;
        const double depth = b.hi[ax] - b.lo[ax];
        const double plane = c.d[ax] > 0.0 ? b.lo[ax] : b.hi[ax];
        const double off_u = c.d[ua] / std::fabs(c.d[ax]) * depth, off_v = c.d[va] / std::fabs(c.d[ax]) * depth;
        auto cuts = [](double lo, double hi, double off, double* out) {
            double v[4] = {lo, hi, lo - off, hi - off};
            int n2 = 0;
            for (double x : v)
                if (x >= lo && x <= hi) out[n2++] = x;
            sort_small(out, n2);
            return n2;
        };
        double cu[4], cv[4];
        const int nu = cuts(b.lo[ua], b.hi[ua], off_u, cu), nv = cuts(b.lo[va], b.hi[va], off_v, cv);
        double face = 0.0;
        for (int iu = 0; iu + 1 < nu; ++iu) {
            const double u0 = cu[iu], du = cu[iu + 1] - cu[iu];
            if (!(du > 0.0)) continue;
            for (int iv = 0; iv + 1 < nv; ++iv) {
                const double v0 = cv[iv], dv = cv[iv + 1] - cv[iv];
                if (!(dv > 0.0)) continue;
                for (int q = 0; q < n; ++q)
                    for (int r = 0; r < n; ++r) {
                        glm::dvec3 y;
                        y[ax] = plane;
                        y[ua] = u0 + du * gr.x[std::size_t(q)];
                        y[va] = v0 + dv * gr.x[std::size_t(r)];
                        const double T = c.transmittance(y);
                        if (T == 0.0) continue;
                        // Chord from y along d through the box.
                        double len = detail::kInf;
                        for (int e = 0; e < 3; ++e) {
                            if (c.d[e] > 0.0) len = std::min(len, (b.hi[e] - y[e]) / c.d[e]);
                            if (c.d[e] < 0.0) len = std::min(len, (b.lo[e] - y[e]) / c.d[e]);
                        }
                        len = std::max(0.0, len);
                        face += gr.w[std::size_t(q)] * gr.w[std::size_t(r)] * du * dv * T * chord_integral(sigma, len);
                    }
            }
        }
        total += std::fabs(c.d[ax]) * face;
    }
    return total;
}

// Driver ---------------------------------------------------------------------------------

std::vector<glm::dvec3> checked_directions(std::span<const glm::dvec3> dirs) {
    if (dirs.empty()) throw core::Error("directions", "at least one output direction is needed");
    std::vector<glm::dvec3> out;
    out.reserve(dirs.size());
    for (std::size_t m = 0; m < dirs.size(); ++m) {
        const double len = glm::length(dirs[m]);
        if (!std::isfinite(len) || !(len > 0.0))
            throw core::Error("directions[" + std::to_string(m) + "]", "must be a finite non-zero vector");
        out.push_back(dirs[m] / len);
    }
    return out;
}

void check_options(const SingleScatteringOptions& o) {
    if (!(o.tolerance >= 1e-9 && o.tolerance <= 0.5))
        throw core::Error("single_scattering.tolerance", "must be in [1e-9, 0.5], got " + std::to_string(o.tolerance));
    if (!(o.optical_depth_cutoff > 0.0)) throw core::Error("single_scattering.optical_depth_cutoff", "must be > 0");
}

std::vector<unsigned char> needed_mask(const LightingMedium& m, bool skip_far_empty) {
    const core::GridGeometry& g = m.density.geom;
    std::vector<unsigned char> need(g.cell_count(), 1);
    if (!skip_far_empty) return need;
    const core::Int3 n = g.dims;
    core::parallel_for(0, n.z, [&](std::int64_t kk) {
        const int k = int(kk);
        for (int j = 0; j < n.y; ++j)
            for (int i = 0; i < n.x; ++i) {
                bool any = false;
                for (int c = std::max(0, k - 1); c <= std::min(n.z - 1, k + 1) && !any; ++c)
                    for (int b = std::max(0, j - 1); b <= std::min(n.y - 1, j + 1) && !any; ++b)
                        for (int a = std::max(0, i - 1); a <= std::min(n.x - 1, i + 1); ++a)
                            if (m.density.at(a, b, c) > 0.0f) {
                                any = true;
                                break;
                            }
                need[g.index(i, j, k)] = any ? 1 : 0;
            }
    });
    return need;
}

template <class PerVoxel>
void for_each_voxel(const LightingMedium& m, SourceField& out, const std::vector<unsigned char>& need, double g_phase,
                    core::Grid3<float>* fluence, double fluence_scale, PerVoxel&& fn) {
    if (fluence) *fluence = core::Grid3<float>(m.density.geom, 0.0f);
    const core::GridGeometry& g = m.density.geom;
    const std::size_t cells = g.cell_count();
    const std::int64_t rows = std::int64_t(g.dims.y) * g.dims.z;
    const std::size_t M = out.directions.size();
    core::parallel_for_dynamic(0, rows, [&](std::int64_t row) {
        const int j = int(row % g.dims.y), k = int(row / g.dims.y);
        PhaseAccumulator acc(out.directions, g_phase);
        for (int i = 0; i < g.dims.x; ++i) {
            const std::size_t cell = g.index(i, j, k);
            if (!need[cell]) {
                for (std::size_t mm = 0; mm < M; ++mm) out.data[mm * cells + cell] = 0.0f;
                continue;
            }
            Box b;
            b.lo = g.origin + glm::dvec3(i, j, k) * g.voxel_size;
            b.hi = g.origin + glm::dvec3(i + 1, j + 1, k + 1) * g.voxel_size;
            acc.reset();
            const double scale = fn(b, cell, acc);
            const std::vector<double>& r = acc.result();
            for (std::size_t mm = 0; mm < M; ++mm) out.data[mm * cells + cell] = float(scale * r[mm]);
            if (fluence) fluence->data[cell] = float(fluence_scale * acc.weight_sum());
        }
    });
}

void prepare_output(const LightingMedium& m, SourceField& out) {
    out.directions = checked_directions(out.directions);
    out.geom = m.density.geom;
    out.data.assign(out.geom.cell_count() * out.directions.size(), 0.0f);
}

}  // namespace

void single_scattering(const LightingMedium& medium, const PointSource& light, SourceField& out,
                       const SingleScatteringOptions& options) {
    validate_medium(medium);
    check_options(options);
    if (!std::isfinite(light.position.x) || !std::isfinite(light.position.y) || !std::isfinite(light.position.z))
        throw core::Error("light.position", "must be finite");
    if (!std::isfinite(light.intensity) || light.intensity < 0.0)
        throw core::Error("light.intensity", "must be finite and >= 0, got " + std::to_string(light.intensity));
    prepare_output(medium, out);
    const core::GridGeometry& g = medium.density.geom;
    const PointCtx ctx{
        &g,
        medium.density.data.data(),
        medium.optics.extinction,
        light.position,
        options.optical_depth_cutoff,
        density_bounds(medium),
        medium.optics.extinction * double(*std::max_element(medium.density.data.begin(), medium.density.data.end()))};
    const Plan plan(options.tolerance, medium.optics.g, options.optical_depth_cutoff);
    const double vol = g.voxel_size * g.voxel_size * g.voxel_size;
    const double factor = medium.optics.albedo * light.intensity / vol;
    const auto need = needed_mask(medium, options.skip_far_empty);
    for_each_voxel(medium, out, need, medium.optics.g, options.uncollided_fluence, light.intensity / vol,
                   [&](const Box& b, std::size_t cell, PhaseAccumulator& acc) {
                       integrate_box_point(ctx, b, medium.sigma_t(cell), 0, plan, acc);
                       return factor;
                   });
}

SourceField single_scattering(const LightingMedium& medium, const PointSource& light,
                              std::span<const glm::dvec3> directions, const SingleScatteringOptions& options) {
    SourceField f;
    f.directions.assign(directions.begin(), directions.end());
    single_scattering(medium, light, f, options);
    return f;
}

void single_scattering(const LightingMedium& medium, const DirectionalSource& sun, SourceField& out,
                       const SingleScatteringOptions& options) {
    validate_medium(medium);
    check_options(options);
    const double len = glm::length(sun.direction);
    if (!std::isfinite(len) || !(len > 0.0)) throw core::Error("sun.direction", "must be a finite non-zero vector");
    if (!std::isfinite(sun.irradiance) || sun.irradiance < 0.0)
        throw core::Error("sun.irradiance", "must be finite and >= 0, got " + std::to_string(sun.irradiance));
    prepare_output(medium, out);
    const core::GridGeometry& g = medium.density.geom;
    const SunCtx ctx{&g,
                     medium.density.data.data(),
                     medium.optics.extinction,
                     sun.direction / len,
                     options.optical_depth_cutoff,
                     density_bounds(medium)};
    const double vol = g.voxel_size * g.voxel_size * g.voxel_size;
    const double factor = medium.optics.albedo * sun.irradiance / vol;
    // The phase function is constant per voxel for the sun (one direction): only attenuation
    // decides the order.
    const Plan plan(options.tolerance, 0.0, options.optical_depth_cutoff);
    const auto need = needed_mask(medium, options.skip_far_empty);
    // p(s_m . d) is the same for every voxel: the accumulator receives one sample per voxel
    // (weight = integral of T over the voxel, direction d) and applies the phase function.
    for_each_voxel(medium, out, need, medium.optics.g, options.uncollided_fluence, sun.irradiance / vol,
                   [&](const Box& b, std::size_t cell, PhaseAccumulator& acc) {
                       const double sigma = medium.sigma_t(cell);
                       bool thick = false;
                       int n = plan.tensor_order(g.voxel_size, 0.0, sigma, thick);
                       if (n == 1) n = 2;  // a one-node rule cannot see transmittance varying across the box
                       double integral = 0.0;
                       int retry = 0;
                       const bool ok =
                           n > 0 && (tensor_rule_sun(ctx, b, n, &plan, integral, &retry) ||
                                     (retry > n && tensor_rule_sun(ctx, b, retry, &plan, integral, nullptr)));
                       if (!ok) integral = face_rule_sun(ctx, b, sigma, plan.n_face);
                       acc.add(integral, ctx.d);
                       return factor;
                   });
}

SourceField single_scattering(const LightingMedium& medium, const DirectionalSource& sun,
                              std::span<const glm::dvec3> directions, const SingleScatteringOptions& options) {
    SourceField f;
    f.directions.assign(directions.begin(), directions.end());
    single_scattering(medium, sun, f, options);
    return f;
}

}  // namespace fulgur::transport
