// The static light on the ground (ground.h): the cloud's scattered sun and sky light and the
// sky seen through the cloud, by rays up from each cell (transport::ground_dome).
#include "sky/ground.h"

#include "core/parallel.h"

#include <algorithm>
#include <cmath>

namespace fulgur::sky {

std::optional<transport::GroundTally> static_ground_cells(const scene::Scene& s, const core::GridGeometry& lighting) {
    if (!s.effects.ground) return std::nullopt;
    // At most 128 cells a side, and few enough that transport::ground_dome's work bound (2^33
    // voxel visits: cells x rays x the voxels a ray can cross) holds whatever the cloud.
    const double crossing = double(lighting.dims.x + lighting.dims.y + lighting.dims.z) + 3.0;
    const double most_cells = double(std::uint64_t(1) << 33) / (transport::DomeGroundOptions{}.rays * crossing);
    const int max_side = std::clamp(int(std::floor(std::sqrt(most_cells))), 1, 128);
    return transport::ground_cells_around(lighting, s.lightning.bolt.ground_height, 20000.0, max_side);
}

StaticGround static_ground(const solve::Media& media, const StaticLight& light, const transport::GroundTally& cells,
                           const transport::DomeGroundOptions& options) {
    core::Stopwatch sw;
    StaticGround out;
    out.cells = cells;
    std::vector<std::vector<const transport::SourceField*>> groups;
    std::vector<transport::DomeProfile> skies;
    std::vector<std::vector<float>*> group_out, sky_out;
    // A light without S (its effects off) still sees the sky through the cloud; the fields a
    // group holds are summed.
    const auto add_group = [&](const LightField& f, std::vector<float>& dst) {
        std::vector<const transport::SourceField*> fields;
        for (const transport::SourceField* p : {&f.single, &f.multiple})
            if (!p->data.empty()) fields.push_back(p);
        if (fields.empty()) return;
        groups.push_back(std::move(fields));
        group_out.push_back(&dst);
    };
    if (light.sun) add_group(*light.sun, out.sun);
    if (light.sky) {
        const auto basis = [&](const LightField& f, std::vector<float>& dst, transport::DomeProfile profile) {
            add_group(f, dst);
            skies.push_back(std::move(profile));
            sky_out.push_back(&dst);
        };
        // A uniform sky was solved as one basis; otherwise (or with no S at all) the gradient's
        // two ends, which compose_ground colours for a uniform sky and a gradient alike.
        if (!light.sky->uniform.empty())
            basis(light.sky->uniform, out.uniform, [](double) { return 1.0; });
        else {
            basis(light.sky->zenith, out.zenith, [](double s) { return scene::SkyDome::zenith_weight(s); });
            basis(light.sky->horizon, out.horizon, [](double s) { return 1.0 - scene::SkyDome::zenith_weight(s); });
        }
    }
    if (groups.empty() && skies.empty()) return out;
    const transport::DomeGround d = transport::ground_dome(media.lighting, groups, skies, cells, options);
    for (std::size_t q = 0; q < groups.size(); ++q) *group_out[q] = d.groups[q].data;
    for (std::size_t k = 0; k < skies.size(); ++k) {
        std::vector<float>& dst = *sky_out[k];
        if (dst.empty()) dst.assign(d.skies[k].data.size(), 0.0f);
        for (std::size_t c = 0; c < dst.size(); ++c) dst[c] += d.skies[k].data[c];
    }
    out.seconds = sw.seconds();
    return out;
}

std::vector<float> compose_ground(const StaticGround& g, const std::optional<scene::Sun>& sun,
                                  const std::optional<scene::SkyDome>& sky, bool use_sun, bool use_sky) {
    const std::size_t n = g.cells.cells();
    std::vector<float> rgb;
    const auto add = [&](const std::vector<float>& part, const glm::dvec3& colour) {
        if (part.empty()) return;
        FULGUR_ASSERT(part.size() == n, "compose_ground: a part of another size than the cells");
        if (rgb.empty()) rgb.assign(3 * n, 0.0f);
        for (std::size_t c = 0; c < n; ++c)
            for (int k = 0; k < 3; ++k) rgb[3 * c + std::size_t(k)] += float(double(part[c]) * colour[k]);
    };
    if (use_sun && sun) add(g.sun, sun->irradiance * sun->colour);
    if (use_sky && sky) {
        add(g.uniform, sky->zenith());  // a uniform sky: both ends equal
        add(g.zenith, sky->zenith());
        add(g.horizon, sky->horizon());
    }
    return rgb;
}

}  // namespace fulgur::sky
