// The quadrature of exact single scattering: Gauss-Legendre rules and the per-box rules
// (detail/quadrature.h). The quantity: S1_i(s) = albedo * I / V * integral over voxel i of
// p(s . w(x)) T(x_l, x) / r^2 (point source) or albedo * E * p(s . d) / V * integral over
// voxel i of T_sun(x) (sun). Three rules, chosen per box (a voxel or an octree sub-box of it):
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
#include "transport/detail/quadrature.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

namespace fulgur::transport::detail {

// ---------------------------------------------------------------------------------------
// Gauss-Legendre rules

GaussRule gauss_legendre(int n) {
    struct Table {
        std::array<std::array<double, kMaxGaussPoints>, kMaxGaussPoints + 1> x{}, w{};
        Table() {
            // P_m(z) into p (three-term recurrence); returns P_m'(z).
            auto legendre = [](int m, double z, double& p) {
                double p0 = 1.0, p1 = 0.0;
                for (int j = 1; j <= m; ++j) {
                    const double p2 = p1;
                    p1 = p0;
                    p0 = ((2.0 * j - 1.0) * z * p1 - (j - 1.0) * p2) / j;
                }
                p = p0;
                return m * (z * p0 - p1) / (z * z - 1.0);
            };
            for (int m = 1; m <= kMaxGaussPoints; ++m) {
                for (int i = 0; i < m; ++i) {
                    // Newton on P_m from the Tricomi-like initial guess; descending roots.
                    double z = std::cos(std::numbers::pi * (double(i) + 0.75) / (double(m) + 0.5));
                    double p = 0.0, dp = 1.0;
                    for (int it = 0; it < 100; ++it) {
                        dp = legendre(m, z, p);
                        const double dz = p / dp;
                        z -= dz;
                        if (std::fabs(dz) < 1e-15) break;
                    }
                    // Recompute the derivative at the converged root for the weight.
                    dp = legendre(m, z, p);
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

namespace {

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
/// With `peaks` (x, y, step): also each peak's azimuth angle(x, y) and the angles step x
/// kPeakRatio^j either side of it (a peaked phase function, face_rule_point).
/// Returns the number of breakpoints (at most kMaxBreaks).
constexpr int kMaxBreaks = 512;
// The peaks' geometric grading ratio: 2 was more accurate than the tolerance asks (g = 0.99 at
// 1e-3: 9e-6 against 4e-4 with 4, the tests' lights) for 1.7x the time on the tests' grids.
constexpr double kPeakRatio = 4.0;
int polar_breakpoints(double A0, double A1, double B0, double B1, double k, double* phi,
                      std::span<const glm::dvec3> peaks = {}) {
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
    // Grading toward the peaks' azimuths (inside, the range is a whole turn: an angle past
    // either end is taken a turn back).
    const double turn = 2.0 * std::numbers::pi;
    auto add_angle = [&](double a) {
        if (inside) a = a < lo_phi ? a + turn : (a >= hi_phi ? a - turn : a);
        if (a > lo_phi && a < hi_phi && n < kMaxBreaks) phi[n++] = a;
    };
    for (const glm::dvec3& q : peaks) {
        if ((q.x == 0.0 && q.y == 0.0) || !(q.z > 0.0)) continue;
        const double a = angle(q.x, q.y);
        add_angle(a);
        for (double s = q.z; s < 0.5 * turn; s *= kPeakRatio) {
            add_angle(a + s);
            add_angle(a - s);
        }
    }
    sort_small(phi, n);
    return n;
}

/// The angle between two unit vectors.
inline double angle_between(const glm::dvec3& x, const glm::dvec3& y) {
    return std::acos(std::clamp(glm::dot(x, y), -1.0, 1.0));
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

}  // namespace

// ---------------------------------------------------------------------------------------
// Point source

void face_rule_point(const PointCtx& c, const Box& b, double sigma, int ax, bool upper, bool inside, int n,
                     PhaseAccumulator& acc, const Plan* peaks) {
    const int ua = (ax + 1) % 3, va = (ax + 2) % 3;
    const double plane = upper ? b.hi[ax] : b.lo[ax];
    const double a = std::fabs(plane - c.xl[ax]);
    if (!(a > 0.0)) return;  // face plane through the source: zero solid angle
    const double sgn = plane > c.xl[ax] ? 1.0 : -1.0;
    const double depth = b.hi[ax] - b.lo[ax];
    const double A0 = b.lo[ua] - c.xl[ua], A1 = b.hi[ua] - c.xl[ua];
    const double B0 = b.lo[va] - c.xl[va], B1 = b.hi[va] - c.xl[va];
    // A peaked phase function: the peak directions in the face's frame (normal component
    // first) and, for the azimuths, each one's grading step: the peak's width over the sine of
    // its angle from the normal (its circle of azimuths' radius). A peak more than twice the
    // face's cone (about the direction to the face's centre, out to its corners) from the
    // centre is smooth over the face and left out.
    constexpr std::size_t kMaxPeaks = 64;
    glm::dvec3 peak_dir[kMaxPeaks], peak_xy[kMaxPeaks];
    std::size_t np_peaks = 0;
    const double width = peaks && peaks->graded() ? peaks->peak_width() : 0.0;
    if (width > 0.0) {
        const glm::dvec3 centre = glm::normalize(glm::dvec3(a, 0.5 * (A0 + A1), 0.5 * (B0 + B1)));
        double cone = 0.0;
        for (const double x : {A0, A1})
            for (const double y : {B0, B1})
                cone = std::max(cone, angle_between(centre, glm::normalize(glm::dvec3(a, x, y))));
        for (std::size_t m = 0; m < peaks->direction_count() && np_peaks < kMaxPeaks; ++m) {
            const glm::dvec3 d = peaks->peak(m);
            const glm::dvec3 f(sgn * d[ax], d[ua], d[va]);
            if (angle_between(f, centre) > 2.0 * cone) continue;
            const double sin_polar = std::hypot(f.y, f.z);
            peak_dir[np_peaks] = f;
            peak_xy[np_peaks] = glm::dvec3(f.y, f.z, sin_polar > 0.0 ? width / sin_polar : 0.0);
            ++np_peaks;
        }
    }
    double phi[kMaxBreaks];
    const int nb = polar_breakpoints(A0, A1, B0, B1, inside ? 0.0 : a / (a + depth), phi,
                                     std::span<const glm::dvec3>(peak_xy, np_peaks));
    const GaussRule gr = gauss_legendre(n);
    // Polar-angle breakpoints of one radial piece, descending (from grazing toward the normal).
    constexpr int kMaxThetaBreaks = 512;
    double tb[kMaxThetaBreaks];
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
                int nt = 0;
                tb[nt++] = th_b;
                double u_edge = u_lo;
                for (int is = 0; is + 1 < nsub && nt + 1 < kMaxThetaBreaks; ++is) {
                    u_edge *= ratio;
                    tb[nt++] = std::acos(std::min(1.0, u_edge));
                }
                tb[nt++] = th_a;
                // A peak along this azimuth: the direction at polar angle theta has cosine
                // A cos(theta) + B sin(theta) = C cos(theta - theta0) with the peak, closest at
                // theta0 and there delta = acos(C) from it; grade toward theta0 from the
                // peak's width widened by delta.
                if (np_peaks > 0) {
                    const int ungraded = nt;
                    for (std::size_t q = 0; q < np_peaks; ++q) {
                        const double A = peak_dir[q].x, B = peak_dir[q].y * cph + peak_dir[q].z * sph;
                        const double C = std::hypot(A, B);
                        const double theta0 = std::atan2(B, A);
                        const double step = std::hypot(width, std::acos(std::min(1.0, C)));
                        auto add = [&](double x) {
                            if (x > th_a && x < th_b && nt < kMaxThetaBreaks) tb[nt++] = x;
                        };
                        add(theta0);
                        for (double s = step; s < std::numbers::pi; s *= kPeakRatio) {
                            add(theta0 + s);
                            add(theta0 - s);
                        }
                    }
                    if (nt > ungraded) {
                        sort_small(tb, nt);
                        std::reverse(tb, tb + nt);
                    }
                }
                double t_lo = th_b;  // sub-pieces from grazing (small u) toward the normal
                for (int is = 0; is + 1 < nt; ++is) {
                    const double t_hi_piece = tb[is + 1];
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

bool tensor_rule_point(const PointCtx& c, const Box& b, int n, const Plan* check, PhaseAccumulator& acc,
                       int* retry_order, double check_above, double* weight) {
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
    double sum = 0.0;
    for (int q = 0; q < nn; ++q) sum += nodes[q].w;
    if (weight) *weight = sum;
    if (check && n > 1 && any_lit && sum >= check_above) {
        const int verdict = check_nodes(up, n, *check);
        if (verdict != 0) {
            if (retry_order) *retry_order = std::max(verdict, 0);
            return false;
        }
    }
    for (int q = 0; q < nn; ++q) acc.add(nodes[q].w, nodes[q].dir);
    return true;
}

// ---------------------------------------------------------------------------------------
// Sun

namespace {

// One piece of an entry face of a box for the sun: the rectangle [u0, u0 + du] x [v0, v0 + dv]
// of the plane x[ax] = plane, between the lines where the exit face changes (so the chord
// through the box is linear across it).
struct SunPiece {
    int ax, ua, va;
    double plane, u0, du, v0, dv;
};

// Integral over the rectangle [u0, u0 + du] x [v0, v0 + dv] of piece `p`'s plane of T_in
// (1 - e^{-sigma l}) / sigma, by an n x n Gauss-Legendre rule.
double sun_piece_rule(const SunCtx& c, const Box& b, double sigma, const GaussRule& gr, int n, const SunPiece& p,
                      double u0, double du, double v0, double dv) {
    double sum = 0.0;
    for (int q = 0; q < n; ++q)
        for (int r = 0; r < n; ++r) {
            glm::dvec3 y;
            y[p.ax] = p.plane;
            y[p.ua] = u0 + du * gr.x[std::size_t(q)];
            y[p.va] = v0 + dv * gr.x[std::size_t(r)];
            const double T = c.transmittance(y);
            if (T == 0.0) continue;
            // Chord from y along d through the box.
            double len = detail::kInf;
            for (int e = 0; e < 3; ++e) {
                if (c.d[e] > 0.0) len = std::min(len, (b.hi[e] - y[e]) / c.d[e]);
                if (c.d[e] < 0.0) len = std::min(len, (b.lo[e] - y[e]) / c.d[e]);
            }
            sum += gr.w[std::size_t(q)] * gr.w[std::size_t(r)] * T * chord_integral(sigma, std::max(0.0, len));
        }
    return sum * du * dv;
}

// The same integral refined adaptively: the rectangle's quarters by the same rule, kept where
// they agree with `whole` (the rectangle's own rule) within `eps`, else each quarter refined
// with a quarter of eps, to `depth` more levels.
double sun_piece_adaptive(const SunCtx& c, const Box& b, double sigma, const GaussRule& gr, int n, const SunPiece& p,
                          double u0, double du, double v0, double dv, double whole, double eps, int depth) {
    const double hu = 0.5 * du, hv = 0.5 * dv;
    const double qu[4] = {u0, u0 + hu, u0, u0 + hu}, qv[4] = {v0, v0, v0 + hv, v0 + hv};
    double q[4];
    for (int i = 0; i < 4; ++i) q[i] = sun_piece_rule(c, b, sigma, gr, n, p, qu[i], hu, qv[i], hv);
    const double fine = (q[0] + q[1]) + (q[2] + q[3]);
    if (depth <= 0 || std::fabs(fine - whole) <= eps) return fine;
    for (int i = 0; i < 4; ++i)
        q[i] = sun_piece_adaptive(c, b, sigma, gr, n, p, qu[i], hu, qv[i], hv, q[i], 0.25 * eps, depth - 1);
    return (q[0] + q[1]) + (q[2] + q[3]);
}

}  // namespace

double face_rule_sun(const SunCtx& c, const Box& b, double sigma, int n, double tol, int depth) {
    const GaussRule gr = gauss_legendre(n);
    // The entry faces' pieces, each with its own rule's estimate.
    SunPiece pieces[3 * 9];
    double whole[3 * 9];
    int count = 0;
    double total = 0.0, projected = 0.0;
    for (int ax = 0; ax < 3; ++ax) {
        if (c.d[ax] == 0.0) continue;
        const int ua = (ax + 1) % 3, va = (ax + 2) % 3;
        const double depth_ax = b.hi[ax] - b.lo[ax];
        const double plane = c.d[ax] > 0.0 ? b.lo[ax] : b.hi[ax];
        const double off_u = c.d[ua] / std::fabs(c.d[ax]) * depth_ax, off_v = c.d[va] / std::fabs(c.d[ax]) * depth_ax;
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
        projected += std::fabs(c.d[ax]) * (b.hi[ua] - b.lo[ua]) * (b.hi[va] - b.lo[va]);
        for (int iu = 0; iu + 1 < nu; ++iu) {
            const double du = cu[iu + 1] - cu[iu];
            if (!(du > 0.0)) continue;
            for (int iv = 0; iv + 1 < nv; ++iv) {
                const double dv = cv[iv + 1] - cv[iv];
                if (!(dv > 0.0)) continue;
                const SunPiece p{ax, ua, va, plane, cu[iu], du, cv[iv], dv};
                pieces[count] = p;
                whole[count] = sun_piece_rule(c, b, sigma, gr, n, p, p.u0, p.du, p.v0, p.dv);
                total += std::fabs(c.d[ax]) * whole[count];
                ++count;
            }
        }
    }
    if (!(tol > 0.0) || depth <= 0 || !(projected > 0.0)) return total;
    // The error allowed: tol of the voxel's integral (at least of 1e-3 of its unshadowed bound,
    // the box's volume: a voxel in deep shadow is not refined for digits no one sees), shared
    // among the pieces by their area seen from the sun.
    const double vol = (b.hi.x - b.lo.x) * (b.hi.y - b.lo.y) * (b.hi.z - b.lo.z);
    const double allowed = tol * std::max(total, kSunRefineFloor * vol);
    double refined = 0.0;
    for (int i = 0; i < count; ++i) {
        const SunPiece& p = pieces[i];
        const double w = std::fabs(c.d[p.ax]);
        const double eps = allowed * p.du * p.dv / projected;  // in face-integral units, times w below
        refined += w * sun_piece_adaptive(c, b, sigma, gr, n, p, p.u0, p.du, p.v0, p.dv, whole[i], eps, depth);
    }
    return refined;
}

}  // namespace fulgur::transport::detail
