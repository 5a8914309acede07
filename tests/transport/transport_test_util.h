// Shared helpers for the transport tests: test media and an independent reference for
// voxel-averaged single scattering in a homogeneous medium.
#pragma once

#include "transport/detail/kernels.h"
#include "transport/detail/lb_solver.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <cmath>
#include <functional>
#include <numbers>
#include <span>
#include <vector>

namespace fulgur::test {

/// A grid of `dims` voxels of size h at `origin`, filled with `rho`.
inline transport::LightingMedium uniform_medium(core::Int3 dims, double h, glm::dvec3 origin, float rho,
                                                transport::Medium optics) {
    core::GridGeometry g;
    g.dims = dims;
    g.voxel_size = h;
    g.origin = origin;
    transport::LightingMedium m;
    m.density = core::Grid3<float>(g, rho);
    m.optics = optics;
    return m;
}

/// Variance along x (voxels^2) of a lattice pulse started at x0: the density summed over the
/// y-z cross-section and over directions [q_begin, kQ) (0: with the rest direction), in
/// double. For the diffusion tests (variance grows by 2 D per step).
inline double pulse_variance_x(const transport::lb::Simulation& sim, const transport::lb::Problem& p, int x0,
                               int q_begin) {
    double m0 = 0.0, m1 = 0.0, m2 = 0.0;
    for (int x = 0; x < p.dims.x; ++x) {
        double rho = 0.0;
        for (int z = 0; z < p.dims.z; ++z)
            for (int y = 0; y < p.dims.y; ++y)
                for (int q = q_begin; q < transport::lb::kQ; ++q)
                    rho += double(sim.kernel().arriving(p.index(x, y, z), q));
        const double dx = double(x - x0);
        m0 += rho;
        m1 += rho * dx;
        m2 += rho * dx * dx;
    }
    const double mean = m1 / m0;
    return m2 / m0 - mean * mean;
}

/// Least-squares slope of y over x (same sizes, at least two distinct x).
inline double least_squares_slope(std::span<const double> x, std::span<const double> y) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    const double n = double(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) {
        sx += x[i];
        sy += y[i];
        sxx += x[i] * x[i];
        sxy += x[i] * y[i];
    }
    return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

/// A smooth synthetic cumulus: a flat-based dome with sinusoidal texture, zero outside.
inline transport::LightingMedium synthetic_cloud(core::Int3 dims, double h, transport::Medium optics) {
    core::GridGeometry g;
    g.dims = dims;
    g.voxel_size = h;
    g.origin = glm::dvec3(-0.5 * dims.x * h, -0.5 * dims.y * h, 0.0);
    transport::LightingMedium m;
    m.density = core::Grid3<float>(g, 0.0f);
    m.optics = optics;
    for (int k = 0; k < dims.z; ++k)
        for (int j = 0; j < dims.y; ++j)
            for (int i = 0; i < dims.x; ++i) {
                const double x = (i + 0.5) / dims.x - 0.5, y = (j + 0.5) / dims.y - 0.5, z = (k + 0.5) / dims.z;
                const double r = std::sqrt(x * x + y * y) / 0.35 + std::max(0.0, z - 0.3) * 0.9;
                if (z < 0.3 || r >= 1.0) continue;
                m.density.at(i, j, k) =
                    float((1.0 - r) * (0.75 + 0.25 * std::sin(9.0 * x + 3.0 * z) * std::cos(7.0 * y)));
            }
    return m;
}

// Adaptive tensor Gauss cubature on a rectangle (8x8 per cell, 2x2 refinement until the
// refined sum changes by less than tol * |estimate|).
namespace detail {
using F2 = std::function<double(double, double)>;
inline double g8(const F2& f, double u0, double v0, double du, double dv) {
    const auto gr = transport::detail::gauss_legendre(8);
    double s = 0.0;
    for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j)
            s += gr.w[std::size_t(i)] * gr.w[std::size_t(j)] *
                 f(u0 + du * gr.x[std::size_t(i)], v0 + dv * gr.x[std::size_t(j)]);
    return s * du * dv;
}
inline double adapt(const F2& f, double u0, double v0, double du, double dv, double coarse, double tol, int depth) {
    const double hu = du / 2, hv = dv / 2;
    const double c[4] = {g8(f, u0, v0, hu, hv), g8(f, u0 + hu, v0, hu, hv), g8(f, u0, v0 + hv, hu, hv),
                         g8(f, u0 + hu, v0 + hv, hu, hv)};
    const double fine = c[0] + c[1] + c[2] + c[3];
    if (std::fabs(fine - coarse) <= tol || depth > 30) return fine;
    return adapt(f, u0, v0, hu, hv, c[0], tol / 2, depth + 1) +
           adapt(f, u0 + hu, v0, hu, hv, c[1], tol / 2, depth + 1) +
           adapt(f, u0, v0 + hv, hu, hv, c[2], tol / 2, depth + 1) +
           adapt(f, u0 + hu, v0 + hv, hu, hv, c[3], tol / 2, depth + 1);
}
}  // namespace detail

/// Independent reference: integral over the box [lo, hi] of p(s . rhat) e^{-sigma r} / r^2 dx
/// around a point x_l, for a medium that is homogeneous along every segment from x_l into the
/// box. By the divergence theorem (div(rhat p(rhat) (1 - e^{-sigma r})/(sigma r^2)) equals the
/// integrand, and its flux through a small sphere around x_l vanishes) it is the surface
/// integral over the six faces of p(rhat) (1 - e^{-sigma r})/sigma (r . n) / r^3 dA, done here
/// with adaptive Cartesian cubature: no polar decomposition, no traversal, no Gauss orders of
/// the code under test.
inline double homogeneous_box_integral(glm::dvec3 lo, glm::dvec3 hi, glm::dvec3 xl, double sigma, double g,
                                       glm::dvec3 s, double rel_tol = 1e-10) {
    double total = 0.0;
    for (int ax = 0; ax < 3; ++ax)
        for (int side = 0; side < 2; ++side) {
            const int ua = (ax + 1) % 3, va = (ax + 2) % 3;
            const double plane = side ? hi[ax] : lo[ax];
            const double rn = (plane - xl[ax]) * (side ? 1.0 : -1.0);
            if (rn == 0.0) continue;
            detail::F2 f = [&](double u, double v) {
                glm::dvec3 y;
                y[ax] = plane;
                y[ua] = u;
                y[va] = v;
                const glm::dvec3 r = y - xl;
                const double R = glm::length(r);
                const double chord = sigma > 0.0 ? -std::expm1(-sigma * R) / sigma : R;
                return transport::hg_phase(glm::dot(s, r / R), g) * chord * rn / (R * R * R);
            };
            const double du = hi[ua] - lo[ua], dv = hi[va] - lo[va];
            const double c = detail::g8(f, lo[ua], lo[va], du, dv);
            total += detail::adapt(f, lo[ua], lo[va], du, dv, c, rel_tol * std::fabs(c) + 1e-300, 0);
        }
    return total;
}

/// A second independent reference for the same integral, for phase functions too peaked for
/// the face cubature above to finish: spherical coordinates about the light with the output
/// direction s as pole, dx = r^2 dr dw, so the integral is that over directions w of
/// p(s . w) (e^{-sigma r_in} - e^{-sigma r_out}) / sigma, [r_in, r_out] the ray's interval in
/// the box (slabs). The angle from s in 160 panels geometric from 1e-8 rad to pi, 12 Gauss
/// points each (the peak is smooth on that scale at any |g| < 1); the azimuth by the midpoint
/// rule at `azimuths` points (periodic, but kinked where the ray leaves the box by another
/// face: the rule's error there, ~1e-5 of a voxel's value at 2048, is the reference's own).
inline double peak_axis_box_integral(glm::dvec3 lo, glm::dvec3 hi, glm::dvec3 xl, double sigma, double g, glm::dvec3 s,
                                     int azimuths = 2048) {
    s = glm::normalize(s);
    const glm::dvec3 a = std::fabs(s.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    const glm::dvec3 e1 = glm::normalize(glm::cross(s, a)), e2 = glm::cross(s, e1);
    const auto gr = transport::detail::gauss_legendre(12);
    std::vector<double> cphi(static_cast<std::size_t>(azimuths)), sphi(static_cast<std::size_t>(azimuths));
    for (int j = 0; j < azimuths; ++j) {
        const double phi = (j + 0.5) * 2.0 * std::numbers::pi / azimuths;
        cphi[std::size_t(j)] = std::cos(phi);
        sphi[std::size_t(j)] = std::sin(phi);
    }
    constexpr int kPanels = 160;
    const double first = 1e-8, ratio = std::pow(std::numbers::pi / first, 1.0 / (kPanels - 1));
    double total = 0.0;
    for (int p = 0; p < kPanels; ++p) {
        const double t0 = p == 0 ? 0.0 : first * std::pow(ratio, p - 1), t1 = first * std::pow(ratio, p);
        for (std::size_t q = 0; q < gr.x.size(); ++q) {
            const double theta = t0 + (t1 - t0) * gr.x[q], w = (t1 - t0) * gr.w[q];
            double ring = 0.0;
            for (int j = 0; j < azimuths; ++j) {
                const glm::dvec3 d =
                    std::cos(theta) * s + std::sin(theta) * (cphi[std::size_t(j)] * e1 + sphi[std::size_t(j)] * e2);
                double rin = 0.0, rout = 1e300;
                for (int k = 0; k < 3; ++k) {
                    if (d[k] == 0.0) {
                        if (xl[k] < lo[k] || xl[k] > hi[k]) rout = -1.0;
                        continue;
                    }
                    const double u = (lo[k] - xl[k]) / d[k], v = (hi[k] - xl[k]) / d[k];
                    rin = std::max(rin, std::min(u, v));
                    rout = std::min(rout, std::max(u, v));
                }
                if (rout > rin)
                    ring += sigma > 0.0 ? (std::exp(-sigma * rin) - std::exp(-sigma * rout)) / sigma : rout - rin;
            }
            total += w * std::sin(theta) * transport::hg_phase(std::cos(theta), g) * ring;
        }
    }
    return total * 2.0 * std::numbers::pi / azimuths;
}

}  // namespace fulgur::test
