// The virtual-light grid (Dobashi et al. 2007, section 5): uniform h_usr horizontally over
// the cloud's footprint plus a margin, uniform h_usr from the cloud base through the cloud's
// full height, and the Eq. 4 spacing below the base down to the ground.
#include "basis/virtual_lights.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace fulgur::basis {

namespace {

void check_field(bool ok, std::string_view where, const char* field, double v, const char* expected) {
    if (!ok)
        throw core::Error(std::string(where) + "." + field,
                          "must be " + std::string(expected) + ", got " + core::format_number(v));
}

// Nodes spaced exactly h, centred on [lo, hi] and covering it; at least two.
std::vector<double> uniform_cover(double lo, double hi, double h, const char* axis) {
    const double intervals_real = std::ceil((hi - lo) / h);
    if (!(intervals_real <= double(kMaxVirtualLights)))
        throw core::Error("virtual_lights.h_usr", std::string("the ") + axis + " extent " +
                                                      core::format_number(hi - lo) + " m over h_usr " +
                                                      core::format_number(h) + " m needs too many virtual lights");
    const std::size_t intervals = std::max<std::size_t>(1, std::size_t(intervals_real));
    const double centre = 0.5 * (lo + hi);
    std::vector<double> v(intervals + 1);
    for (std::size_t i = 0; i <= intervals; ++i) v[i] = centre + (double(i) - 0.5 * double(intervals)) * h;
    return v;
}

}  // namespace

void validate(const VirtualLightParams& p, std::string_view where) {
    check_field(std::isfinite(p.h_usr) && p.h_usr > 0.0 && p.h_usr <= 1e6, where, "h_usr", p.h_usr,
                "a finite spacing in (0, 1e6] m");
    check_field(std::isfinite(p.epsilon) && p.epsilon >= 0.0, where, "epsilon", p.epsilon, "finite and >= 0 (1/m^2)");
    check_field(std::isfinite(p.margin) && p.margin >= 0.0 && p.margin <= 1e7, where, "margin", p.margin,
                "in [0, 1e7] m");
    check_field(std::isfinite(p.ground_height) && std::fabs(p.ground_height) <= 1e6, where, "ground_height",
                p.ground_height, "a finite height in [-1e6, 1e6] m");
    check_field(std::isfinite(p.density_threshold) && p.density_threshold >= 0.0 && p.density_threshold < 1.0, where,
                "density_threshold", p.density_threshold, "in [0, 1)");
}

VirtualLightGrid build_virtual_light_grid(const core::Grid3<float>& density, const VirtualLightParams& p) {
    validate(p, "virtual_lights");
    core::validate_geometry(density.geom, "virtual-light grid: cloud density");
    FULGUR_ASSERT(density.data.size() == density.geom.cell_count(), "density data size does not match its dims");

    const core::Int3 n = density.dims();
    const float thr = float(p.density_threshold);
    int i0 = n.x, i1 = -1, j0 = n.y, j1 = -1, k0 = n.z, k1 = -1;
    float max_density = 0.0f;
    for (int k = 0; k < n.z; ++k)
        for (int j = 0; j < n.y; ++j)
            for (int i = 0; i < n.x; ++i) {
                const float d = density.at(i, j, k);
                if (d > max_density) max_density = d;  // NaN never compares greater
                if (d > thr) {
                    i0 = std::min(i0, i), i1 = std::max(i1, i);
                    j0 = std::min(j0, j), j1 = std::max(j1, j);
                    k0 = std::min(k0, k), k1 = std::max(k1, k);
                }
            }
    if (i1 < 0)
        throw core::Error("virtual_lights", "the cloud is empty: no voxel of the " + std::to_string(n.x) + "x" +
                                                std::to_string(n.y) + "x" + std::to_string(n.z) +
                                                " density grid exceeds density_threshold " +
                                                core::format_number(p.density_threshold) + " (largest density " +
                                                core::format_number(max_density) + "); there is nothing to light");

    const core::GridGeometry& g = density.geom;
    const double vs = g.voxel_size, h = p.h_usr;
    VirtualLightGrid grid;
    grid.x = uniform_cover(g.origin.x + i0 * vs - p.margin, g.origin.x + (i1 + 1) * vs + p.margin, h, "x");
    grid.y = uniform_cover(g.origin.y + j0 * vs - p.margin, g.origin.y + (j1 + 1) * vs + p.margin, h, "y");
    const double z_cld = g.origin.z + k0 * vs;
    const double z_top = g.origin.z + (k1 + 1) * vs;
    grid.cloud_base = z_cld;
    grid.cloud_top = z_top;

    // Below the base: distances r measured downward from z_cld.
    const double depth = z_cld - p.ground_height;
    const double tiny = 1e-9 * std::max({1.0, std::fabs(z_cld), std::fabs(p.ground_height)});
    if (depth < -tiny)
        throw core::Error("virtual_lights.ground_height",
                          "the ground (" + core::format_number(p.ground_height) + " m) is above the cloud base (" +
                              core::format_number(z_cld) +
                              " m); virtual lights go from the ground up through the cloud");
    std::vector<double> below;  // r values, increasing
    if (depth > tiny) {
        if (depth <= h) {
            below.push_back(depth);  // the base is within h_usr of the ground: one layer there
        } else {
            double r = h;  // Eq. 4 is undefined at r_0 = 0 (1/0); the first step is h_usr
            while (r < depth) {
                below.push_back(r);
                if (below.size() > kMaxVirtualLights)
                    throw core::Error("virtual_lights.epsilon", "too many layers below the cloud base");
                const double inv = 1.0 / (r * r) - p.epsilon;
                const double eq4 = inv > 0.0 ? 1.0 / std::sqrt(inv) : std::numeric_limits<double>::infinity();
                r = std::max(r + h, eq4);
            }
            // The ground is the last layer; keep every spacing >= h_usr.
            if (depth - below.back() < h) below.pop_back();
            below.push_back(depth);
        }
    }

    const double above_real = std::max(1.0, std::ceil((z_top - z_cld) / h));
    if (!(above_real <= double(kMaxVirtualLights)))
        throw core::Error("virtual_lights.h_usr", "the cloud's height needs too many virtual-light layers");
    const std::size_t above = std::size_t(above_real);
    for (auto it = below.rbegin(); it != below.rend(); ++it) grid.z.push_back(z_cld - *it);
    grid.base_layer = grid.z.size();
    for (std::size_t k = 0; k <= above; ++k) grid.z.push_back(z_cld + double(k) * h);

    const double total = double(grid.x.size()) * double(grid.y.size()) * double(grid.z.size());
    if (total > double(kMaxVirtualLights))
        throw core::Error("virtual_lights.h_usr", "the grid would have " + core::format_number(total) +
                                                      " virtual lights (" + std::to_string(grid.x.size()) + "x" +
                                                      std::to_string(grid.y.size()) + "x" +
                                                      std::to_string(grid.z.size()) + "), more than " +
                                                      std::to_string(kMaxVirtualLights) + "; increase h_usr");
    return grid;
}

}  // namespace fulgur::basis
