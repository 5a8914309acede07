#include "render/synthetic.h"

#include "transport/transport.h"

#include <glm/geometric.hpp>
#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fulgur::render::synthetic {

namespace {

double lattice_value(std::int64_t x, std::int64_t y, std::int64_t z, std::uint64_t seed) {
    const std::uint64_t h = core::hash_seed(std::uint64_t(x) * 0x9E3779B97F4A7C15ULL ^ std::uint64_t(y),
                                            std::uint64_t(z), seed);
    return double(h >> 11) * 0x1p-53;
}

double value_noise(const glm::dvec3& p, std::uint64_t seed) {
    const glm::dvec3 f = glm::floor(p);
    glm::dvec3 t = p - f;
    t = t * t * (3.0 - 2.0 * t);
    const auto ix = std::int64_t(f.x), iy = std::int64_t(f.y), iz = std::int64_t(f.z);
    double c[2][2][2];
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < 2; ++j)
            for (int i = 0; i < 2; ++i) c[k][j][i] = lattice_value(ix + i, iy + j, iz + k, seed);
    auto lerp = [](double a, double b, double u) { return a + (b - a) * u; };
    const double x00 = lerp(c[0][0][0], c[0][0][1], t.x), x10 = lerp(c[0][1][0], c[0][1][1], t.x);
    const double x01 = lerp(c[1][0][0], c[1][0][1], t.x), x11 = lerp(c[1][1][0], c[1][1][1], t.x);
    return lerp(lerp(x00, x10, t.y), lerp(x01, x11, t.y), t.z);
}

double fbm(glm::dvec3 p, std::uint64_t seed, int octaves) {
    double sum = 0.0, amp = 0.5, norm = 0.0;
    for (int o = 0; o < octaves; ++o) {
        sum += amp * value_noise(p, seed + std::uint64_t(o));
        norm += amp;
        p = p * 2.03 + glm::dvec3(17.1, -3.7, 9.3);
        amp *= 0.5;
    }
    return sum / norm;
}

struct Blob {
    glm::dvec3 centre;
    glm::dvec3 radius;  // ellipsoid semi-axes
};

}  // namespace

core::Grid3<float> cumulus(const core::Int3& dims, double voxel_size, std::uint64_t seed) {
    core::GridGeometry g;
    g.dims = dims;
    g.voxel_size = voxel_size;
    g.origin = {-0.5 * dims.x * voxel_size, -0.5 * dims.y * voxel_size, 0.0};
    core::validate_geometry(g, "synthetic::cumulus");
    const glm::dvec3 ext = g.extent();
    const double H = ext.z, W = std::min(ext.x, ext.y);
    core::Rng rng(seed, 1);
    std::vector<Blob> blobs;
    // Base layer: a ragged flat-bottomed deck.
    for (int i = 0; i < 28; ++i) {
        const double a = rng.uniform() * 2.0 * std::numbers::pi, r = 0.30 * W * std::sqrt(rng.uniform());
        const double rad = (0.07 + 0.05 * rng.uniform()) * W;
        blobs.push_back({{r * std::cos(a), r * std::sin(a), 0.24 * H + 0.06 * H * rng.uniform()},
                         {rad, rad, rad * 0.55}});
    }
    // Tower: convective cells stacked up the middle.
    for (int i = 0; i < 22; ++i) {
        const double z = (0.3 + 0.55 * rng.uniform()) * H;
        const double a = rng.uniform() * 2.0 * std::numbers::pi, r = 0.08 * W * rng.uniform();
        const double rad = (0.09 + 0.05 * rng.uniform()) * W * (1.0 - 0.3 * z / H);
        blobs.push_back({{r * std::cos(a), r * std::sin(a), z}, {rad, rad, rad * 0.9}});
    }
    // Anvil: wide and flat near the top, offset downwind (+x).
    for (int i = 0; i < 14; ++i) {
        const double a = rng.uniform() * 2.0 * std::numbers::pi, r = 0.22 * W * std::sqrt(rng.uniform());
        const double rad = (0.10 + 0.06 * rng.uniform()) * W;
        blobs.push_back({{0.06 * W + r * std::cos(a), r * std::sin(a), 0.83 * H + 0.03 * H * rng.uniform()},
                         {rad * 1.3, rad, rad * 0.28}});
    }
    core::Grid3<float> out(g, 0.0f);
    const double base = 0.2 * H;  // flat cloud base
    core::parallel_for(0, dims.z, [&](std::int64_t k) {
        for (int j = 0; j < dims.y; ++j)
            for (int i = 0; i < dims.x; ++i) {
                const glm::dvec3 p = g.centre(i, j, int(k));
                double shape = -1.0;
                for (const Blob& b : blobs) {
                    const glm::dvec3 q = (p - b.centre) / b.radius;
                    shape = std::max(shape, 1.0 - glm::length(q));
                }
                if (shape < -0.4) continue;
                const double n = fbm(p / 900.0, seed * 31 + 7, 4);
                double v = shape + 0.55 * (n - 0.5);
                v *= std::clamp((p.z - base) / 250.0, 0.0, 1.0);  // flat base, soft
                const double rho = glm::smoothstep(0.0, 0.35, v) * (0.55 + 0.45 * fbm(p / 400.0, seed * 31 + 19, 3));
                out.at(i, j, int(k)) = float(std::clamp(rho, 0.0, 1.0));
            }
    });
    return out;
}

core::GridGeometry lighting_geometry(const core::GridGeometry& density, int downsample) {
    FULGUR_ASSERT(downsample >= 1, "downsample >= 1");
    core::GridGeometry l;
    l.dims = {(density.dims.x + downsample - 1) / downsample, (density.dims.y + downsample - 1) / downsample,
              (density.dims.z + downsample - 1) / downsample};
    l.voxel_size = density.voxel_size * downsample;
    l.origin = density.origin;
    return l;
}

std::vector<float> point_flash_source(const core::Grid3<float>& density, double extinction,
                                      const core::GridGeometry& lighting, int direction_count,
                                      const glm::dvec3& light, double intensity, double albedo, double g) {
    const std::vector<glm::dvec3> dirs = transport::output_directions(direction_count);
    const std::size_t cells = lighting.cell_count();
    std::vector<float> S(cells * dirs.size(), 0.0f);
    const double r0 = lighting.voxel_size;        // regularizes 1/r^2 within a lighting voxel
    const double ell = 1200.0;                     // diffusion length of the stand-in multiple scattering
    const double step = 0.5 * density.geom.voxel_size;
    core::parallel_for(0, std::int64_t(cells), [&](std::int64_t c) {
        const core::Int3 ijk = lighting.unindex(std::size_t(c));
        const glm::dvec3 x = lighting.centre(ijk.x, ijk.y, ijk.z);
        const glm::dvec3 v = x - light;
        const double r = glm::length(v);
        // Optical depth from the light to x (midpoint rule on the full-resolution density).
        const int n = std::max(1, int(std::ceil(r / step)));
        double tau = 0.0;
        for (int s = 0; s < n; ++s) tau += double(density.sample(light + v * ((s + 0.5) / n)));
        tau *= extinction * r / n;
        const double T = std::exp(-tau), T_ms = std::exp(-0.25 * tau);
        const double here = double(density.sample(x));
        const double ms = albedo * intensity * T_ms * std::exp(-r / ell) / (4.0 * std::numbers::pi * (r * ell + r0 * r0));
        const glm::dvec3 w = r > 0.0 ? v / r : glm::dvec3(0, 0, 1);
        for (std::size_t m = 0; m < dirs.size(); ++m) {
            const double p = direction_count == 1 ? 1.0 / (4.0 * std::numbers::pi) : transport::hg_phase(glm::dot(dirs[m], w), g);
            const double single = albedo * p * intensity * T / (r * r + r0 * r0);
            S[m * cells + std::size_t(c)] = float((single + 6.0 * ms) * (here > 0.0 ? 1.0 : 0.5));
        }
    });
    return S;
}

Bolt bolt(std::uint64_t seed, const glm::dvec3& start, double intensity, double radius) {
    Bolt out;
    core::Rng rng(seed, 99);
    struct Channel {
        glm::dvec3 p, dir;
        double intensity;
        int depth;
        int max_segments;
    };
    std::vector<Channel> todo{{start, {0.0, 0.0, -1.0}, intensity, 0, 400}};
    const double mean_angle = glm::radians(16.0);
    while (!todo.empty() && out.segments.size() < 4000) {
        Channel ch = todo.back();
        todo.pop_back();
        for (int s = 0; s < ch.max_segments; ++s) {
            // Reed & Wyvill: turn by a normally distributed angle about a random axis; the main
            // channel is pulled toward the ground.
            glm::dvec3 t, b;
            transport::orthonormal_basis(ch.dir, t, b);
            const double angle = std::abs(mean_angle + 0.5 * mean_angle * rng.normal());
            const double phi = 2.0 * std::numbers::pi * rng.uniform();
            glm::dvec3 nd = std::cos(angle) * ch.dir + std::sin(angle) * (std::cos(phi) * t + std::sin(phi) * b);
            if (ch.depth == 0) nd = glm::normalize(nd + glm::dvec3(0, 0, -0.35));
            else nd = glm::normalize(nd + glm::dvec3(0, 0, -0.1));
            const double len = 40.0 + 80.0 * rng.uniform();
            glm::dvec3 q = ch.p + nd * len;
            bool ground = false;
            if (q.z <= 0.0) {
                q = ch.p + nd * (ch.p.z / std::max(1e-6, -nd.z));
                q.z = 0.0;
                ground = true;
            }
            out.segments.push_back({glm::vec3(ch.p), glm::vec3(q), float(ch.intensity),
                                    float(radius * std::sqrt(ch.intensity / intensity))});
            if (ch.depth < 2 && rng.uniform() < (ch.depth == 0 ? 0.06 : 0.03)) {
                glm::dvec3 bt, bb;
                transport::orthonormal_basis(nd, bt, bb);
                const glm::dvec3 bd = glm::normalize(nd + 1.2 * (rng.uniform() < 0.5 ? bt : -bt));
                todo.push_back({q, bd, ch.intensity * 0.25, ch.depth + 1, 15 + int(rng.uniform_below(35))});
            }
            ch.p = q;
            ch.dir = nd;
            if (ground) break;
        }
    }
    return out;
}

}  // namespace fulgur::render::synthetic
