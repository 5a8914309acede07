// Internal: the Monte Carlo photon-tracing core, templated on the medium, the emitter and
// the tally, so the SAME code runs on analytic media (homogeneous sphere, half-space,
// infinite medium: the oracle tests) and on the LightingMedium grid (real use).
//
// Concepts
//   Medium:  typename Walker;
//            bool start(Walker&, x, d) const      -- false: the ray never meets the medium
//            void segment(const Walker&, double& t0, double& t1, double& sigma_bar) const
//                                                  -- current majorant segment [t0, t1)
//            bool advance(Walker&) const           -- next segment; false when none is left
//            double sigma_t(const glm::dvec3& x, const Walker&) const  (<= sigma_bar)
//   Emitter: std::uint32_t emit(core::Rng&, glm::dvec3& x, glm::dvec3& d) const  -- returns the
//            path's source group (0 for single sources); double power() const
//   Tally:   void begin_path(std::uint32_t group)  -- the emitted path's source group
//            void uncollided(x, d, w)              -- once per emitted path (expected value)
//            void scattered_expected(x, d, w)      -- the second flight's expected value (when
//                                                     PathOptions::expected_second_order)
//            void flight(x, d, t0, t1, w, k)       -- a sampled flight after k scatterings
//
// Free flights use delta tracking (Woodcock): tentative collisions at rate sigma_bar of the
// current majorant segment, accepted with probability sigma_t(x) / sigma_bar; by the
// memorylessness of the exponential a segment boundary simply restarts the sampling.
// Collisions use implicit capture (weight *= albedo, the rest is tallied as absorbed) or
// analog absorption; Russian roulette below a weight threshold keeps the estimate unbiased.
#pragma once

#include "core/core.h"
#include "transport/detail/traversal.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <span>
#include <vector>

namespace fulgur::transport::detail {

/// Per-path options the core needs (derived from MonteCarloOptions + the medium's optics).
struct PathOptions {
    double albedo = 1.0;
    double g = 0.0;
    int max_scatterings = std::numeric_limits<int>::max();
    bool implicit_capture = true;
    double roulette_threshold = 0.05;
    std::uint64_t max_collisions = 100'000'000;
    bool uncollided_only = false;  ///< stop after the tally's uncollided() (counted as truncated)
    /// After the first scattering, hand the new direction to the tally's scattered_expected()
    /// (the second flight's expected-value estimate) and stop (counted as truncated).
    bool expected_second_order = false;
    /// A second scatterer in the medium (LightingMedium::path_mix; its share on the medium's
    /// grid): a collision is its with probability share, with its albedo and phase.
    const PathMix* mix = nullptr;
};

/// The share of PathMix `m` in the voxel holding x (clamped to the grid: a collision lies in
/// the medium's box, up to rounding at its faces).
inline double path_mix_share(const PathMix& m, const glm::dvec3& x) noexcept {
    const core::Int3 v = m.share.geom.clamped_voxel(x);
    return double(m.share.at(v.x, v.y, v.z));
}

/// Raw sums of one batch (watts, summed over the batch's paths).
struct EnergyBatch {
    double emitted = 0, absorbed = 0, escaped = 0, truncated = 0, roulette = 0;
    std::array<double, EnergyTally::kOrders> escaped_by_order{}, absorbed_by_order{};
    std::uint64_t collisions = 0, null_collisions = 0;
};

inline std::size_t order_bucket(int k) noexcept {
    return std::size_t(k < EnergyTally::kOrders - 1 ? k : EnergyTally::kOrders - 1);
}

/// Samples a free flight from x along d by delta tracking. Returns true with t_hit at a real
/// collision; false if the ray leaves the medium, with t_end the exit parameter (0 when it
/// never entered, +inf never happens for a path that can escape).
template <class Medium>
bool delta_track(const Medium& m, const glm::dvec3& x, const glm::dvec3& d, core::Rng& rng, double& t_hit,
                 double& t_end, EnergyBatch& e) {
    typename Medium::Walker w;
    t_end = 0.0;
    if (!m.start(w, x, d)) return false;
    do {
        double t0, t1, sb;
        m.segment(w, t0, t1, sb);
        t_end = t1;
        if (sb > 0.0) {
            double t = t0;
            for (;;) {
                t -= std::log1p(-rng.uniform()) / sb;  // u in [0,1): -ln(1-u) finite
                if (t >= t1) break;
                const double s = m.sigma_t(x + t * d, w);
                if (rng.uniform() * sb < s) {
                    t_hit = t;
                    return true;
                }
                ++e.null_collisions;
            }
        }
    } while (m.advance(w));
    return false;
}

/// Random stream of path number `path` (global index): every path's randomness depends only on
/// (seed, path), so results are independent of threads and batching, and two runs that differ
/// only in what they do after some event (e.g. max_scatterings) follow identical paths up to it.
inline core::Rng path_rng(std::uint64_t seed, std::uint64_t path) noexcept {
    return core::Rng(core::hash_seed(seed, path), path);
}

/// A randomly shifted Kronecker sequence in [0,1)^4 (Roberts' generalized golden ratio:
/// alpha_j = g^-j with g the root of x^5 = x + 1): point i is frac(shift + i alpha). Used for
/// what a path's emission draws (source, place, direction), it spreads a run's first flights
/// evenly where independent draws clump; each shift gives an unbiased estimate, two shifts
/// two independent ones (the noise estimate's halves).
struct KroneckerSequence {
    std::array<double, 4> shift{};
    explicit KroneckerSequence(std::uint64_t seed) noexcept {
        core::Rng r(core::hash_seed(seed, 0x9e3779b97f4a7c15ull), 7);
        for (double& v : shift) v = r.uniform();
    }
    std::array<double, 4> point(std::uint64_t i) const noexcept {
        static constexpr double kG = 1.1673039782614187;  // x^5 = x + 1
        static constexpr double kAlpha[4] = {1.0 / kG, 1.0 / (kG * kG), 1.0 / (kG * kG * kG),
                                             1.0 / (kG * kG * kG * kG)};
        std::array<double, 4> u{};
        const double di = double(i);
        for (std::size_t j = 0; j < 4; ++j) {
            const double v = shift[j] + di * kAlpha[j];
            u[j] = v - std::floor(v);
        }
        return u;
    }
};

/// Traces paths [first, first + n) from the emitter, accumulating into the tally and the
/// energy sums. With `emission` (and an emitter that can use it: emit_at), each path's
/// emission takes point first + p of that sequence instead of random numbers.
template <class Medium, class Emitter, class Tally>
void trace_paths(const Medium& med, const Emitter& em, const PathOptions& o, std::uint64_t seed, std::uint64_t first,
                 std::uint64_t n, Tally& tally, EnergyBatch& e, const KroneckerSequence* emission = nullptr) {
    const double w0 = em.power();
    const double w_rr = o.roulette_threshold * w0;
    for (std::uint64_t p = 0; p < n; ++p) {
        core::Rng rng = path_rng(seed, first + p);
        glm::dvec3 x, d;
        std::uint32_t group = 0;
        if constexpr (requires { em.emit_at(std::array<double, 4>{}, x, d); }) {
            group = emission ? em.emit_at(emission->point(first + p), x, d) : em.emit(rng, x, d);
        } else {
            group = em.emit(rng, x, d);
        }
        tally.begin_path(group);
        double w = w0;
        e.emitted += w;
        tally.uncollided(x, d, w);
        if (o.uncollided_only) {
            e.truncated += w;
            continue;
        }
        int k = 0;  // scatterings so far
        std::uint64_t ncol = 0;
        for (;;) {
            double t_hit = 0.0, t_end = 0.0;
            const bool hit = delta_track(med, x, d, rng, t_hit, t_end, e);
            // An escaped flight runs to infinity: the tally clips it to its own grid (which may
            // extend beyond the medium's box, where the medium is empty).
            tally.flight(x, d, 0.0, hit ? t_hit : kInf, w, k);
            if (!hit) {
                e.escaped += w;
                e.escaped_by_order[order_bucket(k)] += w;
                break;
            }
            x += t_hit * d;
            ++e.collisions;
            if (++ncol > o.max_collisions) {
                e.truncated += w;
                break;
            }
            // Which scatterer the collision is: the second one's share decides (a random number
            // only where the voxel holds both).
            double albedo = o.albedo, g = o.g;
            if (o.mix) {
                const double share = path_mix_share(*o.mix, x);
                if (share >= 1.0 || (share > 0.0 && rng.uniform() < share)) {
                    albedo = o.mix->albedo;
                    g = o.mix->g;
                }
            }
            if (o.implicit_capture) {
                const double wn = w * albedo;
                e.absorbed += w - wn;
                e.absorbed_by_order[order_bucket(k)] += w - wn;
                w = wn;
                if (!(w > 0.0)) break;
            } else if (rng.uniform() >= albedo) {
                e.absorbed += w;
                e.absorbed_by_order[order_bucket(k)] += w;
                break;
            }
            if (k >= o.max_scatterings) {
                e.truncated += w;
                break;
            }
            const double u1 = rng.uniform(), u2 = rng.uniform();
            d = hg_sample(d, g, u1, u2);
            ++k;
            if (o.expected_second_order) {
                tally.scattered_expected(x, d, w);
                e.truncated += w;
                break;
            }
            if (w < w_rr) {
                if (rng.uniform() * w_rr < w) {
                    e.roulette += w_rr - w;
                    w = w_rr;
                } else {
                    e.roulette -= w;
                    break;
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// Emitters

/// Uniform random direction on the unit sphere.
inline glm::dvec3 uniform_sphere(core::Rng& rng) noexcept {
    const double z = 1.0 - 2.0 * rng.uniform();
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double phi = 2.0 * std::numbers::pi * rng.uniform();
    return {r * std::cos(phi), r * std::sin(phi), z};
}

/// Isotropic point source of radiant intensity I: power 4 pi I.
struct PointEmitter {
    glm::dvec3 position{0.0};
    double intensity = 1.0;
    std::uint32_t emit(core::Rng& rng, glm::dvec3& x, glm::dvec3& d) const {
        x = position;
        d = uniform_sphere(rng);
        return 0;
    }
    double power() const noexcept { return 4.0 * std::numbers::pi * intensity; }
};

/// Isotropic point and line sources (a frame's lightning channel): each path starts on one
/// of them, chosen with probability proportional to its intensity (a line's: per metre times
/// its length), at a uniform position along a line, and carries the total power
/// 4 pi sum(I); emit() returns the source's group (points: 0). Random numbers are spent only
/// where there is a choice (several sources, a line of non-zero length), so one point source
/// traces exactly PointEmitter's paths.
struct SourceEmitter {
    std::vector<glm::dvec3> from, to;  // a point has from == to
    std::vector<std::uint32_t> group;
    std::vector<double> cumulative;  // running sums of the intensities (W/sr)
    double total = 0.0;
    SourceEmitter(std::span<const PointSource> points, std::span<const LineSource> lines) {
        for (const PointSource& s : points) add(s.position, s.position, s.intensity, 0);
        for (const LineSource& l : lines) add(l.a, l.b, l.intensity * glm::length(l.b - l.a), l.group);
    }
    std::uint32_t emit(core::Rng& rng, glm::dvec3& x, glm::dvec3& d) const {
        std::size_t i = 0;
        if (from.size() > 1) {
            const double u = rng.uniform() * total;
            i = std::size_t(std::upper_bound(cumulative.begin(), cumulative.end(), u) - cumulative.begin());
            i = std::min(i, from.size() - 1);
        }
        x = from[i];
        if (to[i] != from[i]) x += rng.uniform() * (to[i] - from[i]);
        d = uniform_sphere(rng);
        return group[i];
    }
    /// The same from a point of [0,1)^4: u[0] picks the source along the running sums (its
    /// fractional position inside the source's share places the point on a line, so lines
    /// are covered evenly), u[2], u[3] the direction. u[1] is unused.
    std::uint32_t emit_at(const std::array<double, 4>& u, glm::dvec3& x, glm::dvec3& d) const {
        const double v = u[0] * total;
        std::size_t i = std::size_t(std::upper_bound(cumulative.begin(), cumulative.end(), v) - cumulative.begin());
        i = std::min(i, from.size() - 1);
        const double lo = i == 0 ? 0.0 : cumulative[i - 1], share = cumulative[i] - lo;
        const double f = share > 0.0 ? std::clamp((v - lo) / share, 0.0, 1.0) : 0.5;
        x = from[i];
        if (to[i] != from[i]) x += f * (to[i] - from[i]);
        const double z = 1.0 - 2.0 * u[2];
        const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
        const double phi = 2.0 * std::numbers::pi * u[3];
        d = {r * std::cos(phi), r * std::sin(phi), z};
        return group[i];
    }
    double power() const noexcept { return 4.0 * std::numbers::pi * total; }
    bool empty() const noexcept { return from.empty(); }

private:
    void add(const glm::dvec3& a, const glm::dvec3& b, double intensity, std::uint32_t g) {
        if (!(intensity > 0.0)) return;
        from.push_back(a);
        to.push_back(b);
        group.push_back(g);
        total += intensity;
        cumulative.push_back(total);
    }
};

/// A collimated pencil beam of the given power.
struct BeamEmitter {
    glm::dvec3 position{0.0};
    glm::dvec3 direction{0.0, 0.0, -1.0};
    double beam_power = 1.0;
    std::uint32_t emit(core::Rng&, glm::dvec3& x, glm::dvec3& d) const {
        x = position;
        d = direction;
        return 0;
    }
    double power() const noexcept { return beam_power; }
};

/// Directional light of irradiance E entering a box through the faces that face it, spread
/// uniformly over the box's projected area A: power E * A.
struct BoxSunEmitter {
    glm::dvec3 lo{0.0}, hi{1.0};
    glm::dvec3 direction{0.0, 0.0, -1.0};  // unit
    double irradiance = 1.0;
    std::array<double, 3> cumulative{};  // cumulative projected areas per axis
    BoxSunEmitter(const glm::dvec3& lo_, const glm::dvec3& hi_, const glm::dvec3& dir, double e)
        : lo(lo_), hi(hi_), direction(dir), irradiance(e) {
        const glm::dvec3 ext = hi - lo;
        const double areas[3] = {ext.y * ext.z * std::fabs(dir.x), ext.x * ext.z * std::fabs(dir.y),
                                 ext.x * ext.y * std::fabs(dir.z)};
        cumulative[0] = areas[0];
        cumulative[1] = areas[0] + areas[1];
        cumulative[2] = areas[0] + areas[1] + areas[2];
    }
    std::uint32_t emit(core::Rng& rng, glm::dvec3& x, glm::dvec3& d) const {
        const double u = rng.uniform() * cumulative[2];
        const int ax = u < cumulative[0] ? 0 : (u < cumulative[1] ? 1 : 2);
        const int ua = (ax + 1) % 3, va = (ax + 2) % 3;
        x[ax] = direction[ax] > 0.0 ? lo[ax] : hi[ax];
        x[ua] = lo[ua] + (hi[ua] - lo[ua]) * rng.uniform();
        x[va] = lo[va] + (hi[va] - lo[va]) * rng.uniform();
        d = direction;
        return 0;
    }
    double power() const noexcept { return irradiance * cumulative[2]; }
};

/// A sky dome over the box: radiance L(u) from every direction above the horizon (u = sin of
/// the elevation of the direction the light comes from), uniform in azimuth, tabulated at
/// u_k = k / (n - 1) and linear between (transport::DomeSource). Light from direction
/// `toward` crosses the box's projected area A(-toward), so the power is
///   P = int L(u) A dOmega = int_0^1 L(u) [4 (A_yz + A_xz) sqrt(1 - u^2) + 2 pi A_xy u] du
/// (dOmega = du dphi; the azimuth integral of |cos phi| and |sin phi| is 4), integrated in
/// closed form per table interval. A path's direction is drawn with density L A / P, exactly:
/// a bin of (u, phi) by its bound Lmax Amax (L is linear and |cos phi|, |sin phi| monotone in
/// a bin, so the bounds are the ends' values), a point uniform in it, kept with probability
/// L A / (Lmax Amax); then a point on the faces the direction enters, as BoxSunEmitter does.
struct BoxDomeEmitter {
    static constexpr int kPhiBins = 64;  // multiple of 4: |cos|, |sin| kinks fall on bin edges
    glm::dvec3 lo{0.0}, hi{1.0};
    std::vector<double> table;  // L at u_k
    int u_bins = 0;
    double du = 0.0, total_power = 0.0;
    std::vector<double> cdf;    // running sums of the bins' bounds (u major, phi minor)
    std::vector<double> bound;  // Lmax Amax per bin
    double a_yz = 0.0, a_xz = 0.0, a_xy = 0.0;

    BoxDomeEmitter(const glm::dvec3& lo_, const glm::dvec3& hi_, std::span<const double> radiance)
        : lo(lo_), hi(hi_), table(radiance.begin(), radiance.end()) {
        const glm::dvec3 ext = hi - lo;
        a_yz = ext.y * ext.z;
        a_xz = ext.x * ext.z;
        a_xy = ext.x * ext.y;
        const int intervals = int(table.size()) - 1;
        // At least 128 bins in u, each inside one table interval (L linear in it).
        const int per = std::max(1, (128 + intervals - 1) / intervals);
        u_bins = intervals * per;
        du = 1.0 / double(u_bins);
        const double dphi = 2.0 * std::numbers::pi / kPhiBins;
        cdf.resize(std::size_t(u_bins) * kPhiBins);
        bound.resize(cdf.size());
        double run = 0.0;
        for (int i = 0; i < u_bins; ++i) {
            const double u0 = i * du, u1 = (i + 1) * du;
            const double lmax = std::max(radiance_at(u0), radiance_at(u1));
            const double cmax = std::sqrt(std::max(0.0, 1.0 - u0 * u0));
            for (int j = 0; j < kPhiBins; ++j) {
                const double p0 = j * dphi, p1 = (j + 1) * dphi;
                const double amax = a_yz * cmax * std::max(std::fabs(std::cos(p0)), std::fabs(std::cos(p1))) +
                                    a_xz * cmax * std::max(std::fabs(std::sin(p0)), std::fabs(std::sin(p1))) +
                                    a_xy * u1;
                const std::size_t b = std::size_t(i) * kPhiBins + std::size_t(j);
                bound[b] = lmax * amax;
                run += bound[b];
                cdf[b] = run;
            }
        }
        // The power, interval by interval: L = a + b u, with
        //   int sqrt(1-u^2) du = (u sqrt(1-u^2) + asin u) / 2,  int u sqrt(1-u^2) du = -(1-u^2)^1.5 / 3.
        const auto s0 = [](double u) { return 0.5 * (u * std::sqrt(1.0 - u * u) + std::asin(u)); };
        const auto s1 = [](double u) { return -std::pow(1.0 - u * u, 1.5) / 3.0; };
        double side = 0.0, top = 0.0;
        for (int k = 0; k < intervals; ++k) {
            const double u0 = double(k) / intervals, u1 = double(k + 1) / intervals;
            const double b = (table[std::size_t(k) + 1] - table[std::size_t(k)]) / (u1 - u0);
            const double a = table[std::size_t(k)] - b * u0;
            side += a * (s0(u1) - s0(u0)) + b * (s1(u1) - s1(u0));
            top += a * 0.5 * (u1 * u1 - u0 * u0) + b * (u1 * u1 * u1 - u0 * u0 * u0) / 3.0;
        }
        total_power = 4.0 * (a_yz + a_xz) * side + 2.0 * std::numbers::pi * a_xy * top;
    }
    double radiance_at(double u) const noexcept {
        const int intervals = int(table.size()) - 1;
        const double x = std::clamp(u, 0.0, 1.0) * intervals;
        const int k = std::min(int(x), intervals - 1);
        const double f = x - k;
        return table[std::size_t(k)] * (1.0 - f) + table[std::size_t(k) + 1] * f;
    }
    std::uint32_t emit(core::Rng& rng, glm::dvec3& x, glm::dvec3& d) const {
        glm::dvec3 toward{0.0, 0.0, 1.0};
        const double dphi = 2.0 * std::numbers::pi / kPhiBins;
        // A candidate is kept with probability L A / (Lmax Amax): about 1/2 in a bin where L
        // rises from 0, near 1 elsewhere, so 64 candidates all fail with probability < 2^-40;
        // then the last one is kept (bounded work whatever the table holds).
        for (int tries = 0; tries < 64 && cdf.back() > 0.0; ++tries) {
            const double v = rng.uniform() * cdf.back();
            const std::size_t b =
                std::min(std::size_t(std::upper_bound(cdf.begin(), cdf.end(), v) - cdf.begin()), cdf.size() - 1);
            const int i = int(b / kPhiBins), j = int(b % kPhiBins);
            const double u = (i + rng.uniform()) * du, phi = (j + rng.uniform()) * dphi;
            const double c = std::sqrt(std::max(0.0, 1.0 - u * u));
            toward = {c * std::cos(phi), c * std::sin(phi), u};
            const double a = a_yz * std::fabs(toward.x) + a_xz * std::fabs(toward.y) + a_xy * u;
            if (rng.uniform() * bound[b] <= radiance_at(u) * a) break;
        }
        return BoxSunEmitter(lo, hi, -toward, 1.0).emit(rng, x, d);
    }
    double power() const noexcept { return total_power; }
};

// ---------------------------------------------------------------------------------------
// Analytic media (oracles)

/// One majorant segment [t0, t1) with constant sigma: the walker of every homogeneous medium.
struct SingleSegmentWalker {
    double t0 = 0.0, t1 = 0.0;
};

/// What the analytic media share: one segment [t0, t1) of constant extinction sigma per ray.
struct HomogeneousSegments {
    using Walker = SingleSegmentWalker;
    double sigma = 1.0;
    void segment(const Walker& w, double& t0, double& t1, double& sb) const noexcept {
        t0 = w.t0;
        t1 = w.t1;
        sb = sigma;
    }
    bool advance(Walker&) const noexcept { return false; }
    double sigma_t(const glm::dvec3&, const Walker&) const noexcept { return sigma; }
};

struct HomogeneousSphere : HomogeneousSegments {
    glm::dvec3 centre{0.0};
    double radius = 1.0;
    bool start(Walker& w, const glm::dvec3& x, const glm::dvec3& d) const noexcept {
        const glm::dvec3 oc = x - centre;
        const double b = glm::dot(oc, d);
        const double c = glm::dot(oc, oc) - radius * radius;
        const double disc = b * b - c;
        if (!(disc > 0.0)) return false;
        const double sq = std::sqrt(disc);
        w.t0 = std::max(0.0, -b - sq);
        w.t1 = -b + sq;
        return w.t1 > w.t0;
    }
};

/// The half-space z <= 0 filled with a homogeneous medium.
struct HalfSpace : HomogeneousSegments {
    bool start(Walker& w, const glm::dvec3& x, const glm::dvec3& d) const noexcept {
        if (x.z > 0.0) {
            if (!(d.z < 0.0)) return false;
            w.t0 = -x.z / d.z;
            w.t1 = kInf;
            return true;
        }
        w.t0 = 0.0;
        w.t1 = d.z > 0.0 ? -x.z / d.z : kInf;
        return w.t1 > w.t0;
    }
};

/// An infinite homogeneous medium (nothing escapes; needs albedo < 1).
struct InfiniteMedium : HomogeneousSegments {
    bool start(Walker& w, const glm::dvec3&, const glm::dvec3&) const noexcept {
        w.t0 = 0.0;
        w.t1 = kInf;
        return true;
    }
};

/// The tally of energy-only runs.
struct NullTally {
    void begin_path(std::uint32_t) noexcept {}
    void uncollided(const glm::dvec3&, const glm::dvec3&, double) noexcept {}
    void scattered_expected(const glm::dvec3&, const glm::dvec3&, double) noexcept {}
    void flight(const glm::dvec3&, const glm::dvec3&, double, double, double, int) noexcept {}
};

// ---------------------------------------------------------------------------------------
// Batches

/// Welford accumulation of a scalar over batches (in batch order: deterministic).
struct ScalarStats {
    double mean = 0.0, m2 = 0.0;
    int n = 0;
    void add(double x) noexcept {
        ++n;
        const double d = x - mean;
        mean += d / n;
        m2 += d * (x - mean);
    }
    Estimate estimate() const noexcept {
        return {mean, n > 1 ? std::sqrt(std::max(0.0, m2) / (double(n) * double(n - 1))) : 0.0};
    }
};

struct EnergyStats {
    ScalarStats emitted, absorbed, escaped, truncated, roulette;
    std::array<ScalarStats, EnergyTally::kOrders> esc, abs;
    std::uint64_t collisions = 0, null_collisions = 0;
    /// Adds one batch (its sums divided by its path count: watts per path of power P).
    void add(const EnergyBatch& b, std::uint64_t paths) {
        const double k = 1.0 / double(paths);
        emitted.add(b.emitted * k);
        absorbed.add(b.absorbed * k);
        escaped.add(b.escaped * k);
        truncated.add(b.truncated * k);
        roulette.add(b.roulette * k);
        for (std::size_t i = 0; i < esc.size(); ++i) {
            esc[i].add(b.escaped_by_order[i] * k);
            abs[i].add(b.absorbed_by_order[i] * k);
        }
        collisions += b.collisions;
        null_collisions += b.null_collisions;
    }
    EnergyTally tally() const {
        EnergyTally t;
        t.emitted = emitted.estimate();
        t.absorbed = absorbed.estimate();
        t.escaped = escaped.estimate();
        t.truncated = truncated.estimate();
        t.roulette = roulette.estimate();
        for (std::size_t i = 0; i < esc.size(); ++i) {
            t.escaped_by_order[i] = esc[i].estimate();
            t.absorbed_by_order[i] = abs[i].estimate();
        }
        return t;
    }
};

/// Paths of batch b when `paths` are split over `batches` (remainder to the first batches).
inline std::uint64_t batch_paths(std::uint64_t paths, int batches, int b) noexcept {
    const std::uint64_t B = std::uint64_t(batches);
    return paths / B + (std::uint64_t(b) < paths % B ? 1 : 0);
}

/// First global path index of batch b.
inline std::uint64_t batch_first_path(std::uint64_t paths, int batches, int b) noexcept {
    const std::uint64_t B = std::uint64_t(batches), ub = std::uint64_t(b);
    return ub * (paths / B) + std::min(ub, paths % B);
}

/// Validates the options shared by every run; throws core::Error naming the field.
void check_mc_options(const MonteCarloOptions& o);

struct EnergyRun {
    EnergyTally energy;
    std::uint64_t collisions = 0, null_collisions = 0;
};

/// Energy-only Monte Carlo on any medium (the analytic oracles): batches run in groups of
/// thread_count() and are combined in batch order, so the result is deterministic per seed.
template <class Medium, class Emitter>
EnergyRun run_energy(const Medium& med, const Emitter& em, double albedo, double g, const MonteCarloOptions& o) {
    check_mc_options(o);
    PathOptions po;
    po.albedo = albedo;
    po.g = g;
    po.max_scatterings = o.max_scatterings;
    po.implicit_capture = o.implicit_capture;
    po.roulette_threshold = o.roulette_threshold;
    po.max_collisions = o.max_collisions;
    const int T = std::max(1, core::thread_count());
    EnergyStats stats;
    std::vector<EnergyBatch> group(static_cast<std::size_t>(T));
    for (int b0 = 0; b0 < o.batches; b0 += T) {
        const int nb = std::min(T, o.batches - b0);
        core::parallel_for(0, nb, [&](std::int64_t i) {
            const int b = b0 + int(i);
            NullTally tally;
            EnergyBatch e;
            trace_paths(med, em, po, o.seed, batch_first_path(o.paths, o.batches, b),
                        batch_paths(o.paths, o.batches, b), tally, e);
            group[std::size_t(i)] = e;
        });
        for (int i = 0; i < nb; ++i) stats.add(group[std::size_t(i)], batch_paths(o.paths, o.batches, b0 + i));
    }
    return {stats.tally(), stats.collisions, stats.null_collisions};
}

}  // namespace fulgur::transport::detail
