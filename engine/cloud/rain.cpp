// Rain shafts (rain.h): the footprint from the cloud's columns, the drift and streaks, the
// Marshall-Palmer extinction.
#include "cloud/rain.h"

#include "cloud/subvoxel.h"
#include "core/error.h"
#include "core/format.h"
#include "core/parallel.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

namespace fulgur::cloud {

namespace {

std::string rain_field(const char* name) { return std::string("rain.") + name; }

double smoothstep(double a, double b, double x) {
    const double t = std::clamp((x - a) / (b - a), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

// One pass of a 3-wide box blur along x and y of an nx x ny map (edges clamped).
void blur(std::vector<double>& m, int nx, int ny) {
    std::vector<double> t(m.size());
    auto at = [&](const std::vector<double>& v, int i, int j) {
        return v[std::size_t(std::clamp(i, 0, nx - 1)) + std::size_t(nx) * std::size_t(std::clamp(j, 0, ny - 1))];
    };
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i)
            t[std::size_t(i) + std::size_t(nx) * std::size_t(j)] =
                (at(m, i - 1, j) + at(m, i, j) + at(m, i + 1, j)) / 3.0;
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i)
            m[std::size_t(i) + std::size_t(nx) * std::size_t(j)] =
                (at(t, i, j - 1) + at(t, i, j) + at(t, i, j + 1)) / 3.0;
}

constexpr float kBaseDensity = 0.1f;    // a column's base: its lowest voxel at least this dense
constexpr double kFallDepth = 300.0;    // metres below the base over which the rain thickens
constexpr double kStreakStretch = 8.0;  // the streaks' vertical elongation

}  // namespace

void validate_rain(const RainParams& p) {
    // 1000 mm/h is beyond any rain recorded (the world record is ~300 mm in an hour).
    if (!(p.rate > 0.0 && p.rate <= 1000.0))
        throw core::Error(rain_field("rate"), "must be in (0, 1000] mm/h, got " + core::format_number(p.rate, 8));
    if (!(p.threshold >= 0.0 && p.threshold < 1.0))
        throw core::Error(rain_field("threshold"), "must be in [0, 1), got " + core::format_number(p.threshold, 8));
    for (int c = 0; c < 2; ++c)
        if (!(std::abs(p.shear[c]) <= 5000.0))
            throw core::Error(rain_field("shear"), "must be within +-5000 m of drift per km of fall, got " +
                                                       core::format_number(p.shear[c], 8));
    if (!(p.streak_scale >= 1.0 && p.streak_scale <= 1e5))
        throw core::Error(rain_field("streak_scale"),
                          "must be 1 to 100000 metres, got " + core::format_number(p.streak_scale, 8));
    if (!(p.streak_strength >= 0.0 && p.streak_strength <= 1.0))
        throw core::Error(rain_field("streak_strength"),
                          "must be 0 to 1, got " + core::format_number(p.streak_strength, 8));
    if (!(std::abs(p.g) < 1.0))
        throw core::Error(rain_field("g"), "must be in (-1, 1), got " + core::format_number(p.g, 8));
    if (!(p.albedo >= 0.0 && p.albedo <= 1.0))
        throw core::Error(rain_field("albedo"), "must be 0 to 1, got " + core::format_number(p.albedo, 8));
}

double rain_extinction(double rate) {
    constexpr double n0 = 8000.0;                       // m^-3 mm^-1
    const double lambda = 4.1 * std::pow(rate, -0.21);  // mm^-1
    // sigma = int 2 (pi D^2 / 4) N(D) dD = pi N0 / Lambda^3 (mm^2 m^-3) -> 1/m
    return std::numbers::pi * n0 / (lambda * lambda * lambda) * 1e-6;
}

RainField make_rain(const core::Grid3<float>& density, const RainParams& p) {
    validate_rain(p);
    const core::GridGeometry& g = density.geom;
    const int nx = g.dims.x, ny = g.dims.y, nz = g.dims.z;
    RainField r;
    r.extinction = core::Grid3<float>(g, 0.0f);
    r.g = p.g;
    r.albedo = p.albedo;
    // The columns' cloud paths and bases.
    std::vector<double> path(std::size_t(nx) * std::size_t(ny), 0.0);
    std::vector<int> base(path.size(), -1);
    for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
            double w = 0.0;
            int b = -1;
            for (int k = 0; k < nz; ++k) {
                const float v = density.at(i, j, k);
                w += double(v);
                if (b < 0 && v >= kBaseDensity) b = k;
            }
            path[std::size_t(i) + std::size_t(nx) * std::size_t(j)] = w * g.voxel_size;
            base[std::size_t(i) + std::size_t(nx) * std::size_t(j)] = b;
        }
    const double w_max = *std::max_element(path.begin(), path.end());
    if (!(w_max > 0.0)) return r;
    std::vector<double> weight(path.size());
    for (std::size_t c = 0; c < path.size(); ++c)
        weight[c] = base[c] < 0 ? 0.0 : smoothstep(p.threshold, 0.5 * (1.0 + p.threshold), path[c] / w_max);
    blur(weight, nx, ny);
    blur(weight, nx, ny);
    int lowest = nz;
    for (std::size_t c = 0; c < path.size(); ++c)
        if (weight[c] > 0.5 && base[c] >= 0) lowest = std::min(lowest, base[c]);
    if (lowest == nz || lowest == 0) return r;  // nothing rains, or the cloud touches the ground
    r.top = g.origin.z + double(lowest) * g.voxel_size;

    SubvoxelDetail streaks;
    streaks.seed = p.seed;
    streaks.scale = p.streak_scale;
    streaks.octaves = 2;
    const DetailNoise noise(streaks);
    const double sigma = rain_extinction(p.rate);
    // The weight map at a horizontal point (bilinear between column centres, edges clamped).
    auto weight_at = [&](double x, double y) {
        const double u = (x - g.origin.x) / g.voxel_size - 0.5, v = (y - g.origin.y) / g.voxel_size - 0.5;
        const double fu = std::clamp(u, 0.0, double(nx - 1)), fv = std::clamp(v, 0.0, double(ny - 1));
        const int i0 = std::min(int(fu), nx - 1), j0 = std::min(int(fv), ny - 1);
        const int i1 = std::min(i0 + 1, nx - 1), j1 = std::min(j0 + 1, ny - 1);
        const double a = fu - i0, b = fv - j0;
        auto w = [&](int i, int j) { return weight[std::size_t(i) + std::size_t(nx) * std::size_t(j)]; };
        return (1 - a) * (1 - b) * w(i0, j0) + a * (1 - b) * w(i1, j0) + (1 - a) * b * w(i0, j1) + a * b * w(i1, j1);
    };
    core::parallel_for(0, lowest, [&](std::int64_t k) {
        for (int j = 0; j < ny; ++j)
            for (int i = 0; i < nx; ++i) {
                const glm::dvec3 c = g.centre(i, j, int(k));
                const double below = r.top - c.z;
                if (below <= 0.0) continue;
                const double drift = below / 1000.0;
                const double sx = c.x - p.shear.x * drift, sy = c.y - p.shear.y * drift;
                const double w = weight_at(sx, sy);
                if (w <= 0.0) continue;
                const double streak = noise.sample({sx, sy, c.z / kStreakStretch});
                const double m = 1.0 - p.streak_strength + 2.0 * p.streak_strength * streak;
                r.extinction.at(i, j, int(k)) = float(sigma * w * m * smoothstep(0.0, kFallDepth, below));
            }
    });
    r.max_extinction = double(*std::max_element(r.extinction.data.begin(), r.extinction.data.end()));
    return r;
}

}  // namespace fulgur::cloud
