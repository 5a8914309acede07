// Test fixtures for fulgur::lightning: a synthetic storm cloud (until the cloud generator
// lands, and to keep the tests independent of it) and a Dobashi-style virtual-light grid.
#pragma once

#include "basis/basis.h"
#include "core/core.h"
#include "lightning/lightning.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

namespace fulgur::lightning::fixture {

/// A cumulonimbus-like density on a voxel grid centred on x = y = 0 with the ground at z = 0:
/// a tower (radius 2.5 km, base 1.5 km, top 9 km) under an anvil (radius 5 km, 7.5-9 km),
/// smooth edges and a deterministic ripple. Density in [0, 1]. `voxel` in metres.
inline core::Grid3<float> synthetic_storm(double voxel = 200.0) {
    core::GridGeometry g;
    g.voxel_size = voxel;
    g.dims = {int(std::lround(12800.0 / voxel)), int(std::lround(12800.0 / voxel)), int(std::lround(9600.0 / voxel))};
    g.origin = glm::dvec3(-6400.0, -6400.0, 0.0);
    core::Grid3<float> d(g);
    auto smooth = [](double e0, double e1, double x) {
        const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
        return t * t * (3.0 - 2.0 * t);
    };
    for (int k = 0; k < g.dims.z; ++k)
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) {
                const glm::dvec3 p = g.centre(i, j, k);
                const double r = std::hypot(p.x, p.y);
                const double ripple = 0.15 * std::sin(p.x / 700.0) * std::sin(p.y / 900.0) * std::sin(p.z / 800.0);
                const double tower = (1.0 - smooth(2000.0, 2600.0, r * (1.0 + ripple))) * smooth(1400.0, 1800.0, p.z) *
                                     (1.0 - smooth(8700.0, 9100.0, p.z));
                const double anvil = (1.0 - smooth(4000.0, 5000.0, r * (1.0 + ripple))) * smooth(7400.0, 7900.0, p.z) *
                                     (1.0 - smooth(8700.0, 9100.0, p.z));
                d.at(i, j, k) = float(std::clamp(std::max(tower, anvil) * (0.85 + ripple), 0.0, 1.0));
            }
    return d;
}

/// synthetic_storm(200 m), made once per process: the cloud the generator's and the schedule's
/// tests grow their bolts in.
inline const core::Grid3<float>& storm_200m() {
    static const core::Grid3<float> c = synthetic_storm(200.0);
    return c;
}

/// A bolt that is only its main channel's length: what the flash schedule reads of a bolt.
inline Bolt bolt_of_length(double main_length) {
    Bolt b;
    b.main_length = main_length;
    return b;
}

/// A rectilinear virtual-light grid like Dobashi section 5: horizontal spacing 400 m over
/// [-6400, 6400]; vertical spacing 400 m above the cloud base (1.5 km) and growing below it.
inline basis::VirtualLightGrid dobashi_grid() {
    basis::VirtualLightGrid v;
    for (double x = -6400.0; x <= 6400.0 + 1e-9; x += 400.0) v.x.push_back(x), v.y.push_back(x);
    v.z = {0.0, 700.0, 1100.0};
    for (double z = 1500.0; z <= 9500.0 + 1e-9; z += 400.0) v.z.push_back(z);
    return v;
}

inline bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

inline bool identical(const Bolt& a, const Bolt& b) {
    if (a.segments.size() != b.segments.size() || a.main_count != b.main_count) return false;
    for (std::size_t i = 0; i < a.segments.size(); ++i) {
        const Segment &x = a.segments[i], &y = b.segments[i];
        for (int c = 0; c < 3; ++c)
            if (!same_bits(x.a[c], y.a[c]) || !same_bits(x.b[c], y.b[c])) return false;
        if (!same_bits(x.intensity, y.intensity) || !same_bits(x.path_start, y.path_start) || x.parent != y.parent ||
            x.depth != y.depth)
            return false;
    }
    return same_bits(a.main_length, b.main_length);
}

}  // namespace fulgur::lightning::fixture
