// What S's baked output directions lose in a forward-scattering cloud.
//   directions: the day cumulus (g = 0.8) and the default storm (g = 0.6), the truth (Monte
//   Carlo through the full-resolution density) of each scene's sun or moon and of both ends of
//   its sky's gradient, tallied at the scene's baked directions and, in the same run, at test
//   directions: toward the orbit camera from its target, turned by 0-44 degrees in azimuth and
//   0 or 15 in elevation (the image's pixels see the cloud along these). At each test direction,
//   S interpolated from the baked directions as the renderer does (render::direction_weights)
//   against S tallied there: relative L2 over the cloud voxels and the ratio of totals, for what
//   the renderer takes from S (the sun's orders >= 2, its order 1 being drawn at full resolution
//   with the exact phase function; every order of the sky), and the ratio of totals weighted as
//   a camera along the test direction sees S (each cloud voxel's extinction times its
//   transmittance toward the camera, shared among the lighting-grid nodes a march interpolates
//   S from: mostly the cloud's lit surface and the empty nodes just outside it); the truth's own
//   noise beside them. The weighting is a guide at a surface, not the image: a march also reads
//   S where the trilinear density ramps down outside it (docs/blender.md measures the two on a
//   slab).
//   Outputs: directions.csv (one row per scene, light and test direction).
#include "study/study.h"

#if FULGUR_STUDY_HAS_RENDER

#include "core/core.h"
#include "render/render.h"
#include "scene/scene.h"
#include "sky/sky.h"
#include "solve/solve.h"
#include "transport/transport.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

using namespace fulgur;

FULGUR_STUDY(directions, "directions",
             "S interpolated between the baked output directions against S tallied at the directions the camera "
             "sees the cloud along (day cumulus's sun at g = 0.8, the storm's moon at g = 0.6), orders >= 2 of the sun "
             "or moon, every order of the sky") {
    const std::filesystem::path scenes = std::filesystem::path(FULGUR_SOURCE_DIR) / "content/scenes";
    struct Case {
        std::string file;
        std::uint64_t paths;
    };
    const std::uint64_t paths = ctx.quick ? 400'000ull : 4'000'000ull;
    std::vector<Case> cases = {{"day-cumulus.json", paths}, {"storm.json", paths}};
    // --only A.json,B.json: other scenes (paths, or names under content/scenes), e.g. the slab of
    // scripts/slab_check.py.
    if (!ctx.only.empty()) {
        cases.clear();
        std::string rest = ctx.only;
        for (std::size_t at; !rest.empty(); rest = at == std::string::npos ? "" : rest.substr(at + 1)) {
            at = rest.find(',');
            cases.push_back({rest.substr(0, at), paths});
        }
    }
    study::Csv rows(ctx.file("directions.csv"), {"scene", "light", "g", "azimuth_offset", "elevation_offset", "error",
                                                 "ratio", "seen_ratio", "truth_noise"});
    nlohmann::json out = nlohmann::json::array();
    for (const Case& c : cases) {
        const std::filesystem::path file =
            std::filesystem::exists(c.file) ? std::filesystem::path(c.file) : scenes / c.file;
        const scene::Scene s = scene::load_scene(file);
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
        std::fprintf(stderr, "directions: %s: truth of its %s and sky at %zu directions, %llu paths each\n",
                     c.file.c_str(), s.sun->name.c_str(), dirs.size(), static_cast<unsigned long long>(c.paths));
        const sky::TruthField sun = sky::sun_truth(media, s.sun->direction, dirs, to);
        const sky::SkyTruth sky = sky::sky_truth(media, false, dirs, to);
        // What the renderer takes from S for each light: the sun's orders >= 2 (its order 1 is
        // drawn at full resolution), the sky's every order (each end of its gradient).
        struct Part {
            std::string name;
            std::vector<float> s;  // [m][cell]
            double noise;
        };
        std::vector<Part> parts;
        parts.push_back({s.sun->name + " orders >= 2", sun.field.multiple.data, sun.noise.multiple});
        const auto whole = [](const sky::LightField& f) {
            std::vector<float> v = f.multiple.data;
            for (std::size_t i = 0; i < v.size() && i < f.single.data.size(); ++i) v[i] += f.single.data[i];
            return v;
        };
        parts.push_back({"sky zenith end, all orders", whole(sky.field.zenith), sky.noise.at(0).total});
        parts.push_back({"sky horizon end, all orders", whole(sky.field.horizon), sky.noise.at(1).total});
        const std::size_t cells = media.lighting.density.geom.cell_count();
        // What a camera far along each test direction sees of each lighting voxel's S: every
        // full-resolution voxel of cloud weighs its extinction times the transmittance from it
        // toward the camera (the density sampled every voxel to the grid's edge), shared among
        // the lighting-grid nodes around it by trilinear weights, as a march interpolates S
        // (so the empty nodes just outside a lit surface count too). An image sums S so.
        const core::Grid3<float>& full = media.full.density;
        const core::GridGeometry& lg = media.lighting.density.geom;
        const double step = full.geom.voxel_size;
        std::vector<std::vector<double>> seen(tests.size(), std::vector<double>(cells, 0.0));
        for (std::size_t k = 0; k < tests.size(); ++k) {
            const glm::dvec3& d = dirs[std::size_t(nbaked) + k];
            for (std::size_t f = 0; f < full.data.size(); ++f) {
                if (!(full.data[f] > 0.0f)) continue;
                const core::Int3 fi = full.geom.unindex(f);
                const glm::dvec3 p = full.geom.centre(fi.x, fi.y, fi.z);
                double tau = 0.0;
                for (glm::dvec3 x = p + 0.5 * step * d; full.geom.contains(x); x += step * d)
                    tau += s.medium.extinction * double(full.sample(x)) * step;
                const double wgt = s.medium.extinction * double(full.data[f]) * std::exp(-tau);
                const glm::dvec3 u = lg.to_voxel(p) - 0.5;
                const glm::ivec3 b = glm::ivec3(glm::floor(u));
                const glm::dvec3 t = u - glm::dvec3(b);
                for (int corner = 0; corner < 8; ++corner) {
                    const int ci = std::clamp(b.x + (corner & 1), 0, lg.dims.x - 1),
                              cj = std::clamp(b.y + ((corner >> 1) & 1), 0, lg.dims.y - 1),
                              ck = std::clamp(b.z + ((corner >> 2) & 1), 0, lg.dims.z - 1);
                    const double tw = ((corner & 1) ? t.x : 1.0 - t.x) * (((corner >> 1) & 1) ? t.y : 1.0 - t.y) *
                                      (((corner >> 2) & 1) ? t.z : 1.0 - t.z);
                    seen[k][lg.index(ci, cj, ck)] += wgt * tw;
                }
            }
        }
        for (const Part& part : parts)
            for (std::size_t k = 0; k < tests.size(); ++k) {
                const glm::dvec3& d = dirs[std::size_t(nbaked) + k];
                const render::DirectionWeights w = render::direction_weights(d, nbaked);
                const float* exact = part.s.data() + (std::size_t(nbaked) + k) * cells;
                double diff2 = 0.0, ref2 = 0.0, sum_i = 0.0, sum_e = 0.0, seen_i = 0.0, seen_e = 0.0;
                for (std::size_t i = 0; i < cells; ++i) {
                    const bool cloud = rho[i] > 0.0f, seen_here = seen[k][i] > 0.0;
                    if (!cloud && !seen_here) continue;
                    double v = 0.0;
                    for (int q = 0; q < w.count; ++q)
                        v += w.weight[q] * double(part.s[std::size_t(w.index[q]) * cells + i]);
                    if (cloud) {
                        diff2 += (v - exact[i]) * (v - exact[i]);
                        ref2 += double(exact[i]) * exact[i];
                        sum_i += v;
                        sum_e += exact[i];
                    }
                    seen_i += seen[k][i] * v;  // 0 where nothing is seen
                    seen_e += seen[k][i] * exact[i];
                }
                const double err = std::sqrt(diff2 / ref2), ratio = sum_i / sum_e, seen_ratio = seen_i / seen_e;
                rows << std::filesystem::path(c.file).stem().string() << part.name << s.medium.g << tests[k].daz
                     << tests[k].del << err << ratio << seen_ratio << part.noise;
                rows.end_row();
                std::fprintf(
                    stderr,
                    "directions: %s (g = %.2f) %s toward the camera %+.0f deg azimuth %+.0f deg elevation: "
                    "interpolated %.4f off, ratio of totals %.4f, as the camera sees them %.4f (truth noise %.4f)\n",
                    c.file.c_str(), s.medium.g, part.name.c_str(), tests[k].daz, tests[k].del, err, ratio, seen_ratio,
                    part.noise);
                out.push_back({{"scene", c.file},
                               {"light", part.name},
                               {"azimuth_offset", tests[k].daz},
                               {"elevation_offset", tests[k].del},
                               {"error", err},
                               {"ratio", ratio},
                               {"seen_ratio", seen_ratio}});
            }
    }
    ctx.summary("directions", {{"rows", out}});
}

#endif  // FULGUR_STUDY_HAS_RENDER: the renderer's direction weights (a build with OpenGL)
