// fulgur-preview: a look at a scene's cloud and transport without a bake. Builds the scene's
// cloud, writes its density and the single-scattering field of the scene's first point
// light (and the sun, when enabled) as NRRD, plus PNG slices; optionally the Monte Carlo
// reference (orders 1 and >= 2). docs/transport.md's first figure is made with it.
#include "cloud/cloud.h"
#include "common/cli.h"
#include "core/core.h"
#include "scene/scene.h"
#include "transport/transport.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace {

using namespace fulgur;

constexpr const char* kDescription =
    "Builds the scene's cloud and writes into DIR:\n"
    "  density.nrrd                  the cloud density (full resolution, float32)\n"
    "  single_scattering.nrrd        S1 of the scene's first point light on the lighting grid,\n"
    "                                averaged over the scene's output directions (W m^-2 sr^-1)\n"
    "  single_scattering_sun.nrrd    the same for the sun (when the scene enables it)\n"
    "  density_slice.png             vertical slice through the light (x-z plane)\n"
    "  single_scattering_slice.png   the same slice of S1, log-scaled pseudo-colour (8 decades)\n"
    "With --mc PATHS also the Monte Carlo reference of the point light: mc_single.nrrd,\n"
    "mc_multiple.nrrd (orders >= 2), mc_multiple_se.nrrd and mc_multiple_slice.png.";

struct Args {
    std::filesystem::path scene, out;
    double tolerance = 1e-3;
    std::uint64_t mc_paths = 0;
    int threads = 0;
    bool help = false;
};

void declare(app::CommandLine& cli, Args& a) {
    CLI::App& app = cli.app();
    app.add_option("SCENE.json", a.scene, "the scene (JSON)")
        ->type_name("FILE")
        ->required()
        ->check(app::existing_file());
    app.add_option("-o,--output", a.out, "output directory")->type_name("DIR")->required();
    cli.number("--tolerance", a.tolerance, "single-scattering quadrature tolerance (default 1e-3)", 1e-9, 0.5);
    cli.number("--mc", a.mc_paths, "also run the Monte Carlo reference with PATHS photon paths", std::uint64_t(1000),
               std::uint64_t(10'000'000'000ULL));
    cli.number("--threads", a.threads, "worker threads (default: all cores)", 1, 1024);
}

Args parse(const std::vector<std::string>& args) {
    return app::parse_args<Args>("fulgur-preview", kDescription, args, declare);
}
std::string usage() { return app::usage_of<Args>("fulgur-preview", kDescription, declare); }

/// Mean over the output directions, as a scalar grid.
core::Grid3<float> direction_mean(const transport::SourceField& f) {
    core::Grid3<float> g(f.geom);
    const std::size_t n = f.cells(), M = f.directions.size();
    for (std::size_t c = 0; c < n; ++c) {
        double s = 0.0;
        for (std::size_t m = 0; m < M; ++m) s += f.data[m * n + c];
        g.data[c] = float(s / double(M));
    }
    return g;
}

/// Writes the x-z slice at world y of a grid as a PNG, nearest-neighbour upscaled by `scale`,
/// values mapped to [0,1] by `map`; the light's position is marked with a white cross.
template <class Map>
void write_slice(const std::filesystem::path& path, const core::Grid3<float>& g, double y, int scale, Map map,
                 const glm::dvec3* marker) {
    core::check_finite(g, path.string());  // an infinite field would map to a plausible colour
    const core::Int3 d = g.dims();
    const int j = std::clamp(int(std::floor((y - g.geom.origin.y) / g.geom.voxel_size)), 0, d.y - 1);
    const int W = d.x * scale, H = d.z * scale;
    std::vector<std::uint8_t> px(std::size_t(W) * std::size_t(H) * 3);
    for (int row = 0; row < H; ++row)
        for (int col = 0; col < W; ++col) {
            const int i = col / scale, k = d.z - 1 - row / scale;  // z up: top row is the highest layer
            std::uint8_t rgb[3];
            const double t = map(double(g.at(i, j, k)));
            if (t < 0.0) {
                rgb[0] = rgb[1] = rgb[2] = 0;
            } else {
                core::pseudo_colour(std::clamp(t, 0.0, 1.0), rgb);
            }
            std::copy(rgb, rgb + 3, px.begin() + (std::ptrdiff_t(row) * W + col) * 3);
        }
    if (marker) {
        const double u = (marker->x - g.geom.origin.x) / g.geom.voxel_size * scale;
        const double v = H - (marker->z - g.geom.origin.z) / g.geom.voxel_size * scale;
        const int cx = int(std::lround(u)), cy = int(std::lround(v));
        for (int o = -6; o <= 6; ++o)
            for (const auto& [x, yy] : {std::pair{cx + o, cy}, std::pair{cx, cy + o}})
                if (x >= 0 && x < W && yy >= 0 && yy < H)
                    std::fill_n(px.begin() + (std::ptrdiff_t(yy) * W + x) * 3, 3, std::uint8_t(255));
    }
    core::write_png(path, W, H, 3, px);
}

/// Log-scaled map of a positive field: the top 8 decades below the maximum -> [0, 1]; zero
/// (or below the range) -> black.
auto log_map(const core::Grid3<float>& g) {
    const double mx = *std::max_element(g.data.begin(), g.data.end());
    const double top = mx > 0.0 ? std::log10(mx) : 0.0;
    return [top, mx](double v) { return (mx > 0.0 && v > 0.0) ? (std::log10(v) - (top - 8.0)) / 8.0 : -1.0; };
}

void write_field(const std::filesystem::path& path, const core::Grid3<float>& g, const std::string& content) {
    core::write_nrrd(path, g, content);
}

}  // namespace

int main(int argc, char** argv) {
    Args args;
    if (const std::optional<int> status = app::start(argc, argv, args, parse, usage)) return *status;
    try {
        if (args.threads > 0) core::set_thread_count(args.threads);
        core::Stopwatch total;
        const scene::Scene sc = scene::load_scene(args.scene);
        {
            // The files this tool may write into DIR never replace the scene or its cloud.
            std::vector<core::NamedPath> inputs{{"scene", args.scene}};
            if (sc.cloud.kind != scene::CloudSource::Kind::Generator) inputs.push_back({"cloud file", sc.cloud.file});
            std::vector<core::NamedPath> outputs;
            for (const char* n : {"density.nrrd", "density_slice.png", "single_scattering.nrrd",
                                  "single_scattering_slice.png", "mc_single.nrrd", "mc_multiple.nrrd",
                                  "mc_multiple_se.nrrd", "mc_multiple_slice.png", "single_scattering_sun.nrrd"})
                outputs.push_back({std::string("output ") + n, args.out / n});
            core::check_distinct_files(inputs, outputs);
        }
        std::filesystem::create_directories(args.out);

        core::Stopwatch w;
        const core::Grid3<float> density = scene::make_density(sc);
        const double t_cloud = w.seconds();
        const transport::LightingMedium medium = scene::make_lighting_medium(sc, density);
        std::size_t cloud_voxels = 0;
        for (float v : medium.density.data) cloud_voxels += v > 0.0f;
        w.reset();
        cloud::save_density(args.out / "density.nrrd", density);
        const double t_write = w.seconds();

        const core::Int3 dd = density.dims(), ld = medium.density.dims();
        std::printf("scene      %s (%s)\n", args.scene.string().c_str(), sc.name.c_str());
        std::printf("cloud      %dx%dx%d voxels of %g m in %.2f s; base at %.0f m\n", dd.x, dd.y, dd.z,
                    density.geom.voxel_size, t_cloud, cloud::cloud_base_height(density));
        std::printf("lighting   %dx%dx%d voxels of %g m (%zu with cloud); %d output directions%s\n", ld.x, ld.y, ld.z,
                    medium.density.geom.voxel_size, cloud_voxels, sc.effective_directions(),
                    sc.medium.g == 0.0 ? " (isotropic scattering)" : "");
        std::printf("medium     extinction %g /m, albedo %g, g %g\n", sc.medium.extinction, sc.medium.albedo,
                    sc.medium.g);

        const auto dirs = transport::output_directions(sc.effective_directions());
        transport::SingleScatteringOptions so;
        so.tolerance = args.tolerance;
        const double slice_y = sc.point_lights.empty() ? 0.0 : sc.point_lights[0].position.y;
        const glm::dvec3* marker = sc.point_lights.empty() ? nullptr : &sc.point_lights[0].position;
        {
            const double dmax = std::max(1e-6, double(*std::max_element(density.data.begin(), density.data.end())));
            write_slice(
                args.out / "density_slice.png", density, slice_y, 4, [dmax](double v) { return v / dmax; }, marker);
        }
        if (!sc.effects.single_scattering) {
            std::printf("single     skipped: the scene turns single scattering off\n");
        } else if (sc.point_lights.empty()) {
            std::printf("single     skipped: the scene has no point light\n");
        } else {
            const auto& pl = sc.point_lights[0];
            w.reset();
            const transport::SourceField S =
                transport::single_scattering(medium, transport::PointSource{pl.position, pl.intensity}, dirs, so);
            const double t_ss = w.seconds();
            const core::Grid3<float> mean = direction_mean(S);
            write_field(
                args.out / "single_scattering.nrrd", mean,
                "single scattering S1, mean over " + std::to_string(dirs.size()) + " output directions, W/m^2/sr");
            write_slice(args.out / "single_scattering_slice.png", mean, slice_y, 16, log_map(mean), &pl.position);
            const float smax = *std::max_element(mean.data.begin(), mean.data.end());
            std::printf(
                "single     point light at (%g, %g, %g), I = %g W/sr: %.3f s (%.0f voxels/s, %d threads, "
                "tolerance %g); max S1 %.3e W/m^2/sr\n",
                pl.position.x, pl.position.y, pl.position.z, pl.intensity, t_ss,
                double(medium.density.geom.cell_count()) / t_ss, core::thread_count(), so.tolerance, smax);
            if (args.mc_paths) {
                transport::MonteCarloOptions mo;
                mo.paths = args.mc_paths;
                mo.seed = sc.transport.mc_seed;
                mo.batches = sc.transport.mc_batches;
                const transport::MonteCarloResult r =
                    transport::monte_carlo(medium, transport::PointSource{pl.position, pl.intensity}, dirs, mo);
                const core::Grid3<float> m1 = direction_mean(r.single), mm = direction_mean(r.multiple),
                                         mse = direction_mean(r.multiple_se);
                write_field(args.out / "mc_single.nrrd", m1, "Monte Carlo S order 1, direction mean");
                write_field(args.out / "mc_multiple.nrrd", mm, "Monte Carlo S orders >= 2, direction mean");
                write_field(args.out / "mc_multiple_se.nrrd", mse,
                            "standard error of mc_multiple (direction mean of SEs)");
                write_slice(args.out / "mc_multiple_slice.png", mm, slice_y, 16, log_map(mm), &pl.position);
                const auto& e = r.energy;
                std::printf(
                    "mc         %llu paths in %.2f s (%.0f paths/s): absorbed %.4f, escaped %.4f of emitted "
                    "(uncollided %.4f); max S(>=2) %.3e W/m^2/sr\n",
                    static_cast<unsigned long long>(r.paths), r.seconds, double(r.paths) / r.seconds,
                    e.absorbed.mean / e.emitted.mean, e.escaped.mean / e.emitted.mean,
                    e.escaped_by_order[0].mean / e.emitted.mean,
                    double(*std::max_element(mm.data.begin(), mm.data.end())));
            }
        }
        if (sc.effects.sun && sc.sun) {
            w.reset();
            const transport::SourceField S = transport::single_scattering(
                medium, transport::DirectionalSource{sc.sun->direction, sc.sun->irradiance}, dirs, so);
            write_field(args.out / "single_scattering_sun.nrrd", direction_mean(S),
                        "single scattering S1 of the sun, mean over output directions, W/m^2/sr");
            std::printf("sun        direction (%g, %g, %g), E = %g W/m^2: %.3f s\n", sc.sun->direction.x,
                        sc.sun->direction.y, sc.sun->direction.z, sc.sun->irradiance, w.seconds());
        } else {
            std::printf("sun        not simulated (the scene does not enable it)\n");
        }
        std::printf("output     %s (density written in %.2f s); total %.2f s\n", args.out.string().c_str(), t_write,
                    total.seconds());
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fulgur-preview: %s\n", e.what());
        return app::kExitFailure;
    }
    return 0;
}
