// The light the rain gets from above, and what a model of it from the ground's maps or the
// sky would draw.
//   rain-light: storm-full.json's rain under the default storm's cloud and under the day
//   cumulus (each with its static light: the sun at 45 degrees and a uniform sky, solved as the
//   cache solves them). At the rain's points (the static ground cells' centres where it rains,
//   at a quarter, half and three quarters of the rain's height) the truth is the light arriving
//   from above weighted by the rain's phase function toward a viewer (transport::ground_dome
//   with a lobe: the same rays and S as the ground's map), for a viewer level (toward +x, +y),
//   below at 30 degrees and above at 20 degrees. The models take the ground's map E
//   (cosine-weighted, at the ground) as a radiance from above: diffuse E / pi (x
//   transport::hg_from_above); overcast, (1 + 2 cos) / 3 in shape; cosine, proportional to cos;
//   a + b cos from E and the scalar flux at the ground; and, for the sky, three without a map:
//   half the dome at the horizon's radiance, the upper hemisphere at it, and the horizon's
//   radiance falling to none at the zenith, (1 - cos) (models the renderer drew before the rain
//   entered the static light's transport). The sun's cloud light: none of those. Relative L2
//   over the points and the ratio of totals, per cloud, light, height, view and model. The same
//   for a strike's flash (seed 1 at its return stroke, per_strike: the storm's bake, storm.fgb,
//   baked when stale) from its ground map, diffuse and cosine.
//   Outputs: rain_light.csv, rain_light_flash.csv. --quick: one height, 1024 rays.
#include "study/study.h"

#include "cloud/rain.h"
#include "core/core.h"
#include "scene/scene.h"
#include "sky/ground.h"
#include "sky/sky.h"
#include "transport/ground_dome.h"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <vector>

namespace fulgur::study {

namespace {

// A model against the truth, point by point: relative L2 and the ratio of totals.
struct Agreement {
    double d2 = 0.0, n2 = 0.0, model = 0.0, truth = 0.0;
    void add(double m, double t) {
        d2 += (m - t) * (m - t);
        n2 += t * t;
        model += m;
        truth += t;
    }
    double l2() const { return std::sqrt(d2 / n2); }
    double ratio() const { return model / truth; }
};

// A view of the rain: the scattered direction toward the camera w_s (the camera looks along -w_s).
struct View {
    const char* name;
    glm::dvec3 ws;
};

// Level (toward +x and +y), from below at 30 degrees, from above at 20 degrees.
std::array<View, 4> rain_views() {
    const double c30 = std::cos(std::numbers::pi / 6), c20 = std::cos(std::numbers::pi / 9);
    return {{{"level +x", {1.0, 0.0, 0.0}},
             {"level +y", {0.0, 1.0, 0.0}},
             {"from below 30 deg", {c30, 0.0, -0.5}},
             {"from above 20 deg", {0.0, c20, std::sin(std::numbers::pi / 9)}}}};
}

// The rain's points: the cells of `at` whose centres (at its height) are in the rain.
std::vector<std::size_t> raining_cells(const cloud::RainField& rain, const transport::GroundTally& at) {
    const core::GridGeometry& rg = rain.extinction.geom;
    const auto raining = [&](double x, double y, double z) {
        const glm::ivec3 v(glm::floor((glm::dvec3(x, y, z) - rg.origin) / rg.voxel_size));
        return v.x >= 0 && v.y >= 0 && v.z >= 0 && v.x < rg.dims.x && v.y < rg.dims.y && v.z < rg.dims.z &&
               rain.extinction.at(v.x, v.y, v.z) > 0.0f;
    };
    std::vector<std::size_t> out;
    for (int j = 0; j < at.ny; ++j)
        for (int i = 0; i < at.nx; ++i)
            if (raining(at.origin.x + (i + 0.5) * at.cell, at.origin.y + (j + 0.5) * at.cell, at.height))
                out.push_back(std::size_t(j) * std::size_t(at.nx) + std::size_t(i));
    return out;
}

// The rays that give what the rain scatters toward a view: its phase function as the lobe.
transport::DomeGroundOptions toward(const cloud::RainField& rain, const View& v, int rays) {
    return {.rays = rays,
            .lobe = [g = rain.g, ws = v.ws](const glm::dvec3& w) { return transport::hg_phase(-glm::dot(w, ws), g); }};
}

}  // namespace

FULGUR_STUDY(rain_light, "rain-light",
             "the rain's light from above under the default storm and the day cumulus (their static light): the "
             "phase-weighted light arriving at the rain's points against models from the ground's maps and the sky") {
    const std::filesystem::path scenes = std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes";
    // storm-full.json's rain (its rate, threshold, shear, streaks) under each cloud.
    const scene::Scene full = scene::load_scene(scenes / "storm-full.json");
    if (!full.rain) throw core::Error("storm-full.json", "the scene has no rain");
    const int rays = ctx.quick ? 1024 : 4096;
    const std::vector<double> shares = ctx.quick ? std::vector<double>{0.5} : std::vector<double>{0.25, 0.5, 0.75};
    const double pi = std::numbers::pi;
    const char* names[] = {"diffuse",      "overcast",           "cosine",      "a+b cos",
                           "half horizon", "horizon from above", "horizon band"};
    constexpr int kModels = 7;
    Csv csv(ctx.file("rain_light.csv"),
            {"cloud", "height_m", "view", "model", "points", "sun_l2", "sun_ratio", "sky_l2", "sky_ratio"});
    nlohmann::json j;
    for (const char* cloud_file : {"storm.json", "day-cumulus.json"}) {
        const scene::Scene s = scene::load_scene(scenes / cloud_file);
        const core::Grid3<float> density = scene::make_density(s);
        const solve::Media media = sky::static_media(s, density);
        const sky::SolveSettings st = sky::solve_settings(s, density);
        const auto dirs = transport::output_directions(s.effective_directions());
        const auto cells = sky::static_ground_cells(s, media.lighting.density.geom);
        if (!cells) throw core::Error(cloud_file, "the scene has no ground");
        const cloud::RainField rain = cloud::make_rain(density, *full.rain);

        // The sun at 45 degrees and a uniform sky, solved as the scene's cache solves them.
        const sky::StaticLight light = sky::solve_static(media, scene::sun_direction(45.0, -60.0), true, dirs, st);
        const sky::StaticGround ground = sky::static_ground(media, light, *cells);
        // The scalar flux at the ground (the lobe 1): with the irradiance, a radiance a + b cos.
        const sky::StaticGround flux =
            sky::static_ground(media, light, *cells, {.rays = rays, .lobe = [](const glm::dvec3&) { return 1.0; }});
        double worst[kModels][2] = {};
        // The rain's points: the cells' centres where it rains, at a quarter, half and three
        // quarters of the way from the ground up to the rain's top.
        for (const double share : shares) {
            transport::GroundTally at = *cells;
            at.height = cells->height + share * (rain.top - cells->height);
            const std::vector<std::size_t> points = raining_cells(rain, at);
            for (const View& v : rain_views()) {
                const sky::StaticGround exact = sky::static_ground(media, light, at, toward(rain, v, rays));
                const double f0 = transport::hg_from_above(v.ws.z, rain.g),
                             f1 = transport::hg_from_above(v.ws.z, rain.g, 1);
                // The ground's map E (and the scalar flux phi) as a radiance from above, through
                // the phase function's shares; the sky of radiance 1 as the renderer can draw it
                // without a map: half the dome at the horizon's radiance whatever the view (4),
                // the upper hemisphere at that radiance (5), or the horizon's radiance falling to
                // none at the zenith, (1 - cos) (6), each through the phase function. The sun's
                // cloud light has no such model (none drawn: 100%).
                const auto model = [&](int m, double E, double phi) {
                    switch (m) {
                        case 0:
                            return E / pi * f0;
                        case 1:
                            return 3.0 * E / (7.0 * pi) * (f0 + 2.0 * f1);
                        case 2:
                            return 1.5 * E / pi * f1;
                        case 3: {
                            const double bb = 3.0 * (2.0 * E - phi) / pi, aa = (2.0 * phi - 3.0 * E) / pi;
                            return aa * f0 + bb * f1;
                        }
                        default:
                            return 0.0;
                    }
                };
                const double horizon[] = {0.5, f0, f0 - f1};
                for (int m = 0; m < kModels; ++m) {
                    Agreement sun_a, sky_a;
                    for (const std::size_t c : points) {
                        sun_a.add(model(m, ground.sun[c], flux.sun[c]), exact.sun[c]);
                        sky_a.add(m >= 4 ? horizon[m - 4] : model(m, ground.uniform[c], flux.uniform[c]),
                                  exact.uniform[c]);
                    }
                    csv << cloud_file << at.height << v.name << names[m] << double(points.size()) << sun_a.l2()
                        << sun_a.ratio() << sky_a.l2() << sky_a.ratio();
                    csv.end_row();
                    worst[m][0] = std::max(worst[m][0], sun_a.l2());
                    worst[m][1] = std::max(worst[m][1], sky_a.l2());
                }
            }
        }
        for (int m = 0; m < kModels; ++m)
            j[cloud_file][names[m]] = {{"worst_sun_l2", worst[m][0]}, {"worst_sky_l2", worst[m][1]}};
    }
    // A strike's flash (seed 1, per_strike: its S single + lattice, its ground gathered by
    // rays from that S) at its return stroke: the cloud's flash light into the same rain, the
    // flash's ground map (the renderer's LitChannel::ground) as light from overhead (cosine)
    // or diffuse, against the phase-weighted light at the rain's points.
    const StrikeScene ss = strike_scene("storm.json");
    const cloud::RainField rain = cloud::make_rain(ss.density, *full.rain);
    runtime::FramePipeline pipe(ss.scene, ss.density, ss.bases, std::nullopt, scene::quality_preset("per_strike"));
    const std::size_t strike = pipe.strike_at(0.0, 1);
    runtime::ReconstructOptions wait;
    wait.wait_for_strikes = true;
    const runtime::Frame& f = pipe.build(pipe.storm().strike(strike).profile.stroke_onset.at(0) + 0.002, {}, wait);
    if (!f.lit || f.ground.empty()) throw core::Error("rain-light", "the strike's frame has no light or no ground");
    const transport::SourceField flash = runtime::every_direction(f.radiance);
    const std::vector<std::vector<const transport::SourceField*>> flash_group = {{&flash}};
    Csv flash_csv(ctx.file("rain_light_flash.csv"), {"height_m", "view", "model", "points", "l2", "ratio"});
    double worst_flash[2] = {};
    for (const double share : shares) {
        transport::GroundTally at = f.ground.cells;
        at.height = f.ground.cells.height + share * (rain.top - f.ground.cells.height);
        const std::vector<std::size_t> points = raining_cells(rain, at);
        for (const View& v : rain_views()) {
            const transport::GroundIrradiance exact =
                transport::ground_dome(ss.media.lighting, flash_group, {}, at, toward(rain, v, rays)).groups.at(0);
            const double f0 = transport::hg_from_above(v.ws.z, rain.g),
                         f1 = transport::hg_from_above(v.ws.z, rain.g, 1);
            for (int m = 0; m < 2; ++m) {
                Agreement flash_a;
                for (const std::size_t c : points) {
                    const double E = f.ground.data[c];
                    flash_a.add(m == 0 ? E / pi * f0 : 1.5 * E / pi * f1, exact.data[c]);
                }
                flash_csv << at.height << v.name << (m == 0 ? "diffuse" : "cosine") << double(points.size())
                          << flash_a.l2() << flash_a.ratio();
                flash_csv.end_row();
                worst_flash[m] = std::max(worst_flash[m], flash_a.l2());
            }
        }
    }
    j["flash"] = {{"worst_diffuse_l2", worst_flash[0]}, {"worst_cosine_l2", worst_flash[1]}};
    ctx.summary("rain-light", j);
}

}  // namespace fulgur::study
