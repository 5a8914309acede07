// Sub-voxel detail (subvoxel.h): the billow tile, the erosion and the voxel means the solvers see.
#include "cloud/subvoxel.h"

#include "core/error.h"
#include "core/format.h"
#include "core/parallel.h"
#include "core/rng.h"

#include <glm/common.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace fulgur::cloud {

namespace {

std::string detail_field(const char* name) { return std::string("cloud.detail.") + name; }

int wrap(int i, int n) noexcept {
    const int r = i % n;
    return r < 0 ? r + n : r;
}

// The feature point of cell `cell` (wrapped into [0, cells)^3) of octave `octave`: an offset
// in [0, 1)^3 within the cell, from a hash of the seed, the octave and the cell.
glm::dvec3 feature_offset(std::uint64_t seed, int octave, const core::Int3& cell, int cells) {
    const std::uint64_t h =
        core::hash_seed(seed, std::uint64_t(octave), std::uint64_t(cell.x + cells * (cell.y + cells * cell.z)));
    constexpr double k21 = 1.0 / double(1u << 21);
    return {double(h & 0x1fffff) * k21, double((h >> 21) & 0x1fffff) * k21, double((h >> 42) & 0x1fffff) * k21};
}

// Inverted cellular noise of one octave at tile position q in [0, 1)^3: 1 - (distance to the
// nearest feature point, in cells), clamped at 0; periodic with the tile.
double billow_octave(std::uint64_t seed, int octave, const glm::dvec3& q) {
    const int cells = 2 << octave;
    const glm::dvec3 p = q * double(cells);
    const core::Int3 c{int(std::floor(p.x)), int(std::floor(p.y)), int(std::floor(p.z))};
    double nearest2 = 1e30;
    for (int dz = -1; dz <= 1; ++dz)
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                const core::Int3 n{c.x + dx, c.y + dy, c.z + dz};
                const core::Int3 w{wrap(n.x, cells), wrap(n.y, cells), wrap(n.z, cells)};
                const glm::dvec3 f = glm::dvec3(n.x, n.y, n.z) + feature_offset(seed, octave, w, cells);
                const glm::dvec3 d = p - f;
                nearest2 = std::min(nearest2, d.x * d.x + d.y * d.y + d.z * d.z);
            }
    return std::max(0.0, 1.0 - std::sqrt(nearest2));
}

}  // namespace

void validate_subvoxel_detail(const SubvoxelDetail& d) {
    // Billows under a metre or beyond 100 km are a unit mistake, not a cloud's detail.
    if (!(d.scale >= 1.0 && d.scale <= 1e5))
        throw core::Error(detail_field("scale"), "must be 1 to 100000 metres, got " + core::format_number(d.scale, 8));
    if (d.octaves < 1 || d.octaves > kMaxDetailOctaves)
        throw core::Error(detail_field("octaves"), "must be 1 to " + std::to_string(kMaxDetailOctaves) + " (the " +
                                                       std::to_string(kDetailTile) + "^3 tile's finest billows are " +
                                                       std::to_string(kDetailTile >> kMaxDetailOctaves) +
                                                       " texels across), got " + std::to_string(d.octaves));
    if (!(d.strength >= 0.0 && d.strength <= 1.0))
        throw core::Error(detail_field("strength"), "must be 0 to 1, got " + core::format_number(d.strength, 8));
}

DetailNoise::DetailNoise(const SubvoxelDetail& d) : params_(d) {
    validate_subvoxel_detail(d);
    constexpr int n = kDetailTile;
    std::vector<double> b(std::size_t(n) * n * n);
    double weight_sum = 0.0;
    for (int o = 0; o < d.octaves; ++o) weight_sum += std::ldexp(1.0, -o);
    core::parallel_for(0, n, [&](std::int64_t k) {
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const glm::dvec3 q = (glm::dvec3(i, j, double(k)) + 0.5) / double(n);
                double v = 0.0;
                for (int o = 0; o < d.octaves; ++o) v += std::ldexp(1.0, -o) * billow_octave(d.seed, o, q);
                b[std::size_t(i) + std::size_t(n) * (std::size_t(j) + std::size_t(n) * std::size_t(k))] =
                    v / weight_sum;
            }
    });
    // Stretched to the full [0, 1] so that `strength` means the same for any octave count.
    const auto [lo, hi] = std::minmax_element(b.begin(), b.end());
    const double low = *lo, range = std::max(*hi - *lo, 1e-12);
    texels_.resize(b.size());
    for (std::size_t i = 0; i < b.size(); ++i)
        texels_[i] = std::uint8_t(std::lround(std::clamp((b[i] - low) / range, 0.0, 1.0) * 255.0));
}

float DetailNoise::sample(const glm::dvec3& world) const noexcept {
    constexpr int n = kDetailTile;
    const glm::dvec3 s = world / period() * double(n) - 0.5;
    const glm::dvec3 fl = glm::floor(s);
    const glm::vec3 f = glm::vec3(s - fl);
    const int x0 = wrap(int(fl.x) % n, n), y0 = wrap(int(fl.y) % n, n), z0 = wrap(int(fl.z) % n, n);
    const int x1 = (x0 + 1) % n, y1 = (y0 + 1) % n, z1 = (z0 + 1) % n;
    auto at = [&](int x, int y, int z) {
        return float(texels_[std::size_t(x) + std::size_t(n) * (std::size_t(y) + std::size_t(n) * std::size_t(z))]) *
               (1.0f / 255.0f);
    };
    auto lerp = [](float a, float b, float t) { return a + (b - a) * t; };
    const float c00 = lerp(at(x0, y0, z0), at(x1, y0, z0), f.x), c10 = lerp(at(x0, y1, z0), at(x1, y1, z0), f.x);
    const float c01 = lerp(at(x0, y0, z1), at(x1, y0, z1), f.x), c11 = lerp(at(x0, y1, z1), at(x1, y1, z1), f.x);
    return lerp(lerp(c00, c10, f.y), lerp(c01, c11, f.y), f.z);
}

float detailed_at(const core::Grid3<float>& density, const DetailNoise& noise, const glm::dvec3& world) noexcept {
    return erode(density.sample(world), noise.sample(world), float(noise.params().strength));
}

core::Grid3<float> detailed_density(const core::Grid3<float>& density, const DetailNoise& noise) {
    const core::GridGeometry& g = density.geom;
    core::Grid3<float> out(g, 0.0f);
    const float strength = float(noise.params().strength);
    constexpr int m = kDetailSupersamples;
    core::parallel_for_dynamic(0, g.dims.z, [&](std::int64_t k) {
        for (int j = 0; j < g.dims.y; ++j)
            for (int i = 0; i < g.dims.x; ++i) {
                const float raw = density.at(i, j, int(k));
                if (!(raw > 0.0f)) continue;
                const glm::dvec3 lower = g.origin + glm::dvec3(i, j, double(k)) * g.voxel_size;
                double kept = 0.0, total = 0.0;
                for (int c = 0; c < m; ++c)
                    for (int b = 0; b < m; ++b)
                        for (int a = 0; a < m; ++a) {
                            const glm::dvec3 x = lower + (glm::dvec3(a, b, c) + 0.5) / double(m) * g.voxel_size;
                            const float rho = density.sample(x);
                            total += double(rho);
                            kept += double(erode(rho, noise.sample(x), strength));
                        }
                out.at(i, j, int(k)) = total > 0.0 ? float(double(raw) * (kept / total)) : raw;
            }
    });
    return out;
}

core::Grid3<float> detailed_on_finer_grid(const core::Grid3<float>& density, const DetailNoise& noise, int refine) {
    FULGUR_ASSERT(refine >= 1, "a refinement of at least 1");
    const core::GridGeometry& g = density.geom;
    core::GridGeometry fine = g;
    fine.dims = {g.dims.x * refine, g.dims.y * refine, g.dims.z * refine};
    fine.voxel_size = g.voxel_size / double(refine);
    core::Grid3<float> out(fine, 0.0f);
    const float strength = float(noise.params().strength);
    core::parallel_for_dynamic(0, fine.dims.z, [&](std::int64_t k) {
        for (int j = 0; j < fine.dims.y; ++j)
            for (int i = 0; i < fine.dims.x; ++i) {
                const glm::dvec3 x = fine.centre(i, j, int(k));
                const float rho = density.sample(x);
                if (rho > 0.0f) out.at(i, j, int(k)) = erode(rho, noise.sample(x), strength);
            }
    });
    return out;
}

int detail_refinement(const core::GridGeometry& g, const SubvoxelDetail& d, std::uint64_t max_voxels) noexcept {
    const double finest = d.scale / double(1 << std::clamp(d.octaves - 1, 0, kMaxDetailOctaves - 1));
    // At most 64 (so the count below cannot overflow): a grid that coarse against its billows
    // is far past any budget anyway.
    int refine = int(std::clamp(std::ceil(g.voxel_size / (0.5 * finest) - 1e-9), 1.0, 64.0));
    const auto voxels = [&](int r) {
        return std::uint64_t(g.cell_count()) * std::uint64_t(r) * std::uint64_t(r) * std::uint64_t(r);
    };
    while (refine > 1 && voxels(refine) > max_voxels) --refine;
    return refine;
}

}  // namespace fulgur::cloud
