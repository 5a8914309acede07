#include "support/synthetic_storm.h"

#include "transport/transport.h"

#include <glm/geometric.hpp>
#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fulgur::synthetic {

namespace {

double lattice_value(std::int64_t x, std::int64_t y, std::int64_t z, std::uint64_t seed) {
    const std::uint64_t h =
        core::hash_seed(std::uint64_t(x) * 0x9E3779B97F4A7C15ULL ^ std::uint64_t(y), std::uint64_t(z), seed);
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
    // Proportions of a cumulonimbus in a 12.8 x 12.8 x 9.6 km box (scaled with the box).
    const double base = 0.16 * H, anvil_lo = 0.78 * H, anvil_hi = 0.93 * H;
    core::Rng rng(seed, 1);
    std::vector<Blob> blobs;
    auto disc = [&](double radius) {  // uniform point in a disc
        const double a = rng.uniform() * 2.0 * std::numbers::pi, r = radius * std::sqrt(rng.uniform());
        return glm::dvec2(r * std::cos(a), r * std::sin(a));
    };
    // Lower body: a lumpy deck over a flat base, a little wider than the tower.
    for (int i = 0; i < 26; ++i) {
        const glm::dvec2 c = disc(0.22 * W);
        const double rad = (0.10 + 0.06 * rng.uniform()) * W;
        blobs.push_back({{c.x, c.y, base + (0.04 + 0.10 * rng.uniform()) * H}, {rad, rad, rad * 0.7}});
    }
    // Tower: convective cells stacked around a slightly leaning axis, bulging outwards.
    for (int i = 0; i < 70; ++i) {
        const double z = base + (0.12 + (anvil_lo - base) / H * 0.95 * rng.uniform()) * H;
        const double lean = 0.04 * W * (z - base) / (anvil_lo - base);
        const glm::dvec2 c = disc(0.11 * W);
        const double rad = (0.07 + 0.06 * rng.uniform()) * W;
        blobs.push_back({{c.x + lean, c.y, z}, {rad, rad, rad * 0.95}});
    }
    // Anvil: wide, flat and sheared downwind (+x), with an overshooting dome on top.
    for (int i = 0; i < 40; ++i) {
        glm::dvec2 c = disc(0.30 * W);
        c.x += 0.06 * W;
        const double rad = (0.08 + 0.05 * rng.uniform()) * W;
        const double z = anvil_lo + (anvil_hi - anvil_lo) * (0.35 + 0.4 * rng.uniform());
        blobs.push_back({{c.x, c.y, z}, {rad * 1.4, rad * 1.2, (anvil_hi - anvil_lo) * (0.45 + 0.2 * rng.uniform())}});
    }
    blobs.push_back({{0.05 * W, 0.0, anvil_hi - 0.02 * H}, {0.1 * W, 0.1 * W, 0.06 * H}});
    core::Grid3<float> out(g, 0.0f);
    const double scale = W / 12800.0;  // noise scales in metres for the reference box
    core::parallel_for(0, dims.z, [&](std::int64_t k) {
        for (int j = 0; j < dims.y; ++j)
            for (int i = 0; i < dims.x; ++i) {
                const glm::dvec3 p = g.centre(i, j, int(k));
                // Smooth union of the blobs (soft maximum of 1 - |q|).
                double acc = 0.0;
                for (const Blob& b : blobs) {
                    const glm::dvec3 q = (p - b.centre) / b.radius;
                    const double v = 1.0 - glm::dot(q, q);
                    if (v > -0.3) acc += std::exp(16.0 * v);
                }
                if (acc <= 0.0) continue;
                const double shape = std::log(acc) / 16.0;
                if (shape < -0.5) continue;
                // Billows: large-scale fbm displaces the surface, finer fbm roughens it.
                const double billow = fbm(p / (900.0 * scale), seed * 31 + 7, 3) - 0.5;
                const double detail = fbm(p / (260.0 * scale), seed * 31 + 11, 3) - 0.5;
                double v = shape + 0.55 * billow + 0.3 * detail;
                v *= std::clamp((p.z - base) / (150.0 * scale), 0.0, 1.0);                 // flat, sharp base
                v *= std::clamp((anvil_hi + 0.03 * H - p.z) / (300.0 * scale), 0.0, 1.0);  // flat anvil top
                if (v <= 0.0) continue;
                const double inner = 0.6 + 0.4 * fbm(p / (500.0 * scale), seed * 31 + 19, 2);
                const double rho = glm::smoothstep(0.0, 0.15, v) * inner;
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
                                      const core::GridGeometry& lighting, int direction_count, const glm::dvec3& light,
                                      double intensity, double albedo, double g) {
    const std::vector<glm::dvec3> dirs = transport::output_directions(direction_count);
    const std::size_t cells = lighting.cell_count();
    std::vector<float> S(cells * dirs.size(), 0.0f);
    const double r0 = lighting.voxel_size;  // regularizes 1/r^2 within a lighting voxel
    const double ell = 900.0;               // diffusion length of the stand-in multiple scattering
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
        const double ms =
            albedo * intensity * T_ms * std::exp(-r / ell) / (4.0 * std::numbers::pi * (r * ell + r0 * r0));
        const glm::dvec3 w = r > 0.0 ? v / r : glm::dvec3(0, 0, 1);
        for (std::size_t m = 0; m < dirs.size(); ++m) {
            const double p =
                direction_count == 1 ? 1.0 / (4.0 * std::numbers::pi) : transport::hg_phase(glm::dot(dirs[m], w), g);
            const double single = albedo * p * intensity * T / (r * r + r0 * r0);
            S[m * cells + std::size_t(c)] = float(single + 4.0 * ms);
        }
    });
    return S;
}

std::vector<float> bolt_source(const core::Grid3<float>& density, double extinction, const core::GridGeometry& lighting,
                               int direction_count, const render::LitChannel& bolt, double spacing, double albedo,
                               double g) {
    // Merge the bolt into point sources about `spacing` apart (power-weighted centroids).
    std::vector<std::pair<glm::dvec3, double>> points;
    glm::dvec3 acc(0.0);
    double power = 0.0, length = 0.0;
    for (const render::ChannelSegment& seg : bolt.segments) {
        const double len = glm::length(glm::dvec3(seg.b - seg.a));
        const double p = double(seg.intensity) * len;
        if (p <= 0.0) continue;
        acc += p * 0.5 * (glm::dvec3(seg.a) + glm::dvec3(seg.b));
        power += p;
        length += len;
        if (length >= spacing) {
            points.emplace_back(acc / power, power);
            acc = glm::dvec3(0.0);
            power = length = 0.0;
        }
    }
    if (power > 0.0) points.emplace_back(acc / power, power);
    std::vector<float> S(lighting.cell_count() * std::size_t(std::max(direction_count, 1)), 0.0f);
    for (const auto& [pos, intensity] : points) {
        const std::vector<float> one =
            point_flash_source(density, extinction, lighting, direction_count, pos, intensity, albedo, g);
        for (std::size_t i = 0; i < S.size(); ++i) S[i] += one[i];
    }
    return S;
}

render::LitChannel bolt(std::uint64_t seed, const glm::dvec3& start, double intensity, double radius) {
    render::LitChannel out;
    core::Rng rng(seed, 99);
    struct Channel {
        glm::dvec3 p, dir;
        double intensity;
        int depth;
        int max_segments;
    };
    std::vector<Channel> todo{{start, {0.0, 0.0, -1.0}, intensity, 0, 600}};
    const double mean_angle = glm::radians(16.0);
    while (!todo.empty() && out.segments.size() < 4000) {
        Channel ch = todo.back();
        todo.pop_back();
        for (int s = 0; s < ch.max_segments; ++s) {
            // Reed & Wyvill: turn by a normally distributed angle about a random axis; the main
            // channel is pulled toward the ground.
            glm::dvec3 t, b;
            core::orthonormal_basis(ch.dir, t, b);
            const double angle = std::abs(mean_angle + 0.5 * mean_angle * rng.normal());
            const double phi = 2.0 * std::numbers::pi * rng.uniform();
            glm::dvec3 nd = std::cos(angle) * ch.dir + std::sin(angle) * (std::cos(phi) * t + std::sin(phi) * b);
            if (ch.depth == 0)
                nd = glm::normalize(nd + glm::dvec3(0, 0, -0.25));
            else
                nd = glm::normalize(nd + glm::dvec3(0, 0, -0.18));
            const double len = 25.0 + 55.0 * rng.uniform();
            glm::dvec3 q = ch.p + nd * len;
            bool ground = false;
            if (q.z <= 0.0) {
                q = ch.p + nd * (ch.p.z / std::max(1e-6, -nd.z));
                q.z = 0.0;
                ground = true;
            }
            out.segments.push_back({glm::vec3(ch.p), glm::vec3(q), float(ch.intensity),
                                    float(radius * std::sqrt(ch.intensity / intensity))});
            if (ch.depth < 2 && rng.uniform() < (ch.depth == 0 ? 0.07 : 0.04)) {
                glm::dvec3 bt, bb;
                core::orthonormal_basis(nd, bt, bb);
                const glm::dvec3 bd = glm::normalize(nd + 0.9 * (rng.uniform() < 0.5 ? bt : -bt));
                todo.push_back({q, bd, ch.intensity * 0.3, ch.depth + 1, 8 + int(rng.uniform_below(24))});
            }
            ch.p = q;
            ch.dir = nd;
            if (ground) break;
        }
    }
    return out;
}

Storm storm(const core::Int3& dims, double voxel_size) {
    Storm st;
    st.density = cumulus(dims, voxel_size, 7);
    st.lighting = lighting_geometry(st.density.geom, 4);
    const glm::dvec3 start(300.0, -200.0, 6800.0);
    st.bolt = bolt(3, start, 1e6 / 3000.0);
    st.source = bolt_source(st.density, st.extinction, st.lighting, st.directions, st.bolt, 800.0);
    st.camera = render::Camera::orbit({0.0, 0.0, 4300.0}, 13500.0, -60.0, -6.0, 55.0);
    st.settings.exposure = 110.0;
    // A long-exposure night sky, visible behind the cloud: airglow, greyer at the horizon.
    st.settings.sky_zenith = 3e-5 * glm::dvec3(0.45, 0.6, 1.0);
    st.settings.sky_horizon = 3e-5 * glm::dvec3(2.4, 2.3, 2.6);
    st.settings.star_radiance = 2e-3;
    return st;
}

render::SourceUpload needed_upload(const render::Renderer& renderer, const Storm& storm) {
    render::SourceUpload up;
    up.geometry = storm.lighting;
    up.direction_count = storm.directions;
    const std::size_t cells = storm.lighting.cell_count();
    for (const render::DirectionUse& u : renderer.needed_directions(storm.camera, storm.lighting, storm.directions,
                                                                    storm.settings.direction_min_weight)) {
        up.directions.push_back(u.index);
        up.values.emplace_back(storm.source.data() + std::size_t(u.index) * cells, cells);
    }
    return up;
}

glm::dvec3 orbit_target(const Storm& storm) {
    const core::GridGeometry& g = storm.density.geom;
    return g.origin + 0.5 * g.extent() * glm::dvec3(1.0, 1.0, 0.7);
}

render::Camera orbit_camera(const Storm& storm, double azimuth_deg, double elevation_deg, double vertical_fov_deg) {
    const glm::dvec3 target = orbit_target(storm);
    return render::Camera::orbit(target, glm::length(storm.camera.position - target), azimuth_deg, elevation_deg,
                                 vertical_fov_deg);
}

}  // namespace fulgur::synthetic
