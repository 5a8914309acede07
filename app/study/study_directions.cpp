// What S's baked output directions lose in a forward-scattering cloud.
//   directions: the day cumulus's sun (g = 0.8) and the default storm's moon (g = 0.6), each
//   light's truth (Monte Carlo through the full-resolution density) tallied at the scene's
//   baked directions and, in the same run, at test directions: toward the scene's camera from
//   the cloud's centre, turned by 0-44 degrees in azimuth and 0 or 15 in elevation (the image's
//   pixels see the cloud along these). At each test direction, S interpolated from the baked
//   directions as the renderer does (render::direction_weights) against S tallied there:
//   relative L2 over the cloud voxels of orders >= 2 (the renderer draws the sun's and moon's
//   single scattering at full resolution with the exact phase function) and the ratio of their
//   totals; the truth's own noise beside them.
//   Outputs: directions.csv (one row per scene and test direction).
#include "study/study.h"

#if FULGUR_STUDY_HAS_RENDER

#include "core/core.h"
#include "render/render.h"
#include "scene/scene.h"
#include "sky/sky.h"
#include "solve/solve.h"
#include "transport/transport.h"

#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

using namespace fulgur;

FULGUR_STUDY(directions, "directions",
             "S interpolated between the baked output directions against S tallied at the directions the camera "
             "sees the cloud along (day cumulus's sun at g = 0.8, the storm's moon at g = 0.6), orders >= 2") {
    const std::filesystem::path scenes = std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes";
    struct Case {
        std::string file;
        std::uint64_t paths;
    };
    const std::vector<Case> cases = {{"day-cumulus.json", ctx.quick ? 400'000ull : 4'000'000ull},
                                     {"storm.json", ctx.quick ? 400'000ull : 4'000'000ull}};
    study::Csv rows(ctx.file("directions.csv"), {"scene", "g", "azimuth_offset", "elevation_offset", "multiple_error",
                                                 "multiple_ratio", "truth_noise_multiple"});
    nlohmann::json out = nlohmann::json::array();
    for (const Case& c : cases) {
        const scene::Scene s = scene::load_scene(scenes / c.file);
        if (!s.sun) throw core::Error(c.file, "has no sun or moon");
        if (!s.camera || s.camera->kind != scene::CameraSpec::Kind::Orbit)
            throw core::Error(c.file, "camera: not an orbit");
        const core::Grid3<float> density = scene::make_density(s);
        const solve::Media media = solve::make_media(s, density, s.lighting_downsample, true);
        const std::vector<float>& rho = media.lighting.density.data;
        const std::vector<glm::dvec3> baked = transport::output_directions(s.effective_directions());
        const int nbaked = int(baked.size());

        // Toward the orbit camera from its target, then turned.
        const double az0 = glm::radians(s.camera->azimuth_deg), el0 = glm::radians(s.camera->elevation_deg);
        struct Test {
            double daz, del;
        };
        std::vector<Test> tests;
        for (const double del : {0.0, 15.0})
            for (const double daz : {0.0, 11.0, 22.0, 33.0, 44.0}) tests.push_back({daz, del});
        std::vector<glm::dvec3> dirs = baked;
        for (const Test& t : tests) {
            const double az = az0 + glm::radians(t.daz), el = el0 + glm::radians(t.del);
            dirs.push_back({std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)});
        }

        sky::TruthOptions to;
        to.paths = c.paths;
        std::fprintf(stderr, "directions: %s: truth of its %s at %zu directions, %llu paths\n", c.file.c_str(),
                     s.sun->name.c_str(), dirs.size(), static_cast<unsigned long long>(c.paths));
        const sky::TruthField truth = sky::sun_truth(media, s.sun->direction, dirs, to);
        const transport::SourceField& m = truth.field.multiple;
        const std::size_t cells = m.cells();
        for (std::size_t k = 0; k < tests.size(); ++k) {
            const glm::dvec3& d = dirs[std::size_t(nbaked) + k];
            const render::DirectionWeights w = render::direction_weights(d, nbaked);
            const std::span<const float> exact = m.direction(std::size_t(nbaked) + k);
            double diff2 = 0.0, ref2 = 0.0, sum_i = 0.0, sum_e = 0.0;
            for (std::size_t i = 0; i < cells; ++i) {
                if (!(rho[i] > 0.0f)) continue;
                double v = 0.0;
                for (int q = 0; q < w.count; ++q) v += w.weight[q] * double(m.direction(std::size_t(w.index[q]))[i]);
                diff2 += (v - exact[i]) * (v - exact[i]);
                ref2 += double(exact[i]) * exact[i];
                sum_i += v;
                sum_e += exact[i];
            }
            const double err = std::sqrt(diff2 / ref2), ratio = sum_i / sum_e;
            rows << std::filesystem::path(c.file).stem().string() << s.medium.g << tests[k].daz << tests[k].del << err
                 << ratio << truth.noise.multiple;
            rows.end_row();
            std::fprintf(stderr,
                         "directions: %s (g = %.2f) toward the camera %+.0f deg azimuth %+.0f deg elevation: orders >= "
                         "2 interpolated %.4f off, ratio of totals %.4f (truth noise %.4f)\n",
                         c.file.c_str(), s.medium.g, tests[k].daz, tests[k].del, err, ratio, truth.noise.multiple);
            out.push_back({{"scene", c.file},
                           {"azimuth_offset", tests[k].daz},
                           {"elevation_offset", tests[k].del},
                           {"multiple_error", err},
                           {"multiple_ratio", ratio}});
        }
    }
    ctx.summary("directions", {{"rows", out}});
}

#endif  // FULGUR_STUDY_HAS_RENDER: the renderer's direction weights (a build with OpenGL)
