// The bake's plan (bake.h, docs/bake.md): what a bake will simulate and why, its cost and the
// file's metadata, checked against the scene's limits before any light is solved.
#include "bake/bake.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace fulgur::bake {

std::string Plan::to_text() const {
    std::ostringstream o;
    o << "bake plan\n";
    o << "  lighting grid   " << lighting.dims.x << " x " << lighting.dims.y << " x " << lighting.dims.z << " cells of "
      << lighting.voxel_size << " m\n";
    o << "  virtual lights  " << lights.x.size() << " x " << lights.y.size() << " x " << lights.z.size() << " = "
      << lights.count() << " (cloud base " << lights.cloud_base << " m, top " << lights.cloud_top << " m)\n";
    o << "  directions      " << directions << "\n";
    o << "  components      " << (single ? "single" : "") << (single && multiple ? " + " : "")
      << (multiple ? "multiple" : "") << (components == 2 ? " (stored separately)" : "") << "\n";
    o << "  solver          " << solver << "\n";
    o << "  threads         " << threads << "\n";
    o << "  raw size        " << core::format_bytes(double(raw_bytes))
      << " (float32, every light, direction and component)\n";
    o << "  memory          " << core::format_bytes(double(cost.memory_bytes)) << " estimated peak (" << cost.threads
      << " worker(s) x " << core::format_bytes(double(cost.per_thread_bytes)) << ")\n";
    if (single_measured)
        o << "  time about      " << core::format_seconds(cost.seconds)
          << " (the single scattering measured on a sample of one light's voxels)\n";
    else
        o << "  time at least   " << core::format_seconds(cost.seconds) << " (from the grid sizes)\n";
    if (expected_bytes)
        o << "  expected file   " << core::format_bytes(double(expected_bytes)) << " (from " << sample_lights
          << " sample lights)\n";
    if (expected_seconds > 0.0 && sample_lights > 0)
        o << "  expected time   " << core::format_seconds(expected_seconds) << " (from " << sample_lights
          << " sample lights)\n";
    else if (expected_seconds > 0.0)
        o << "  expected time   " << core::format_seconds(expected_seconds)
          << (single_measured ? " (the single scattering's measured cost: no sample light)\n"
                              : " (the lower bound: no sample light)\n");
    o << "  why:\n";
    for (const std::string& r : reasons) o << "    - " << r << "\n";
    return o.str();
}

namespace {

// One line per decision the plan makes, in the order the printed plan lists them.
void explain(const scene::Scene& s, const solve::Media& media, Plan& p) {
    auto& why = p.reasons;
    if (s.cloud.kind == scene::CloudSource::Kind::Vdb)
        why.push_back("cloud from " + s.cloud.file.filename().string() + ": " + scene::inspect_vdb_cloud(s).describe());
    if (s.medium.g == 0.0)
        why.push_back("g = 0 (isotropic scattering): S does not depend on direction, 1 output direction instead of " +
                      std::to_string(s.directions));
    else
        why.push_back("g = " + core::format_number(s.medium.g) + ": " + std::to_string(p.directions) +
                      " output directions");
    if (!p.multiple)
        why.push_back(
            "effects.multiple_scattering = false: no transport solve, bases hold the exact single scattering");
    else if (p.solver == "lattice_boltzmann")
        why.push_back("multiple scattering by lattice-Boltzmann (" + s.transport.lb_collision + " collision, " +
                      s.transport.lb_absorption + " absorption, " + s.transport.lb_thick_voxels +
                      " thick voxels, tolerance " + core::format_number(s.transport.lb_tolerance) +
                      ") fed with the exact single scattering");
    else
        why.push_back("multiple scattering by Monte Carlo (reference quality, " + std::to_string(s.transport.mc_paths) +
                      " paths per light)");
    if (p.multiple && p.solver == "lattice_boltzmann" && s.transport.lb_exact_orders == 2)
        why.push_back(
            "transport.lattice_boltzmann.exact_orders = 2: order 2 by Monte Carlo through the full density (" +
            std::to_string(s.transport.lb_order2_paths) +
            " paths per light), the lattice for orders >= 3 (its angular error falls on dimmer, smoother light)");
    if (s.transport.refine > 1)
        why.push_back("transport.refine = " + std::to_string(s.transport.refine) + ": single scattering and the " +
                      (p.multiple ? p.solver : std::string("direct term")) + " run on " +
                      core::format_number(media.transport.density.geom.voxel_size, 6) + " m voxels (" +
                      std::to_string(media.transport.density.dims().x) + " x " +
                      std::to_string(media.transport.density.dims().y) + " x " +
                      std::to_string(media.transport.density.dims().z) +
                      "), averaged onto the lighting grid: thick voxels and the coarse medium cost less accuracy");
    {
        const scene::Quality& q = s.quality;
        const std::string name(scene::to_string(q.preset));
        if (q.preset == scene::Quality::Preset::Paper) {
            why.push_back("quality = paper: every frame from the bases (the splat onto virtual lights)");
        } else {
            const int refine =
                q.refine > s.transport.refine && s.lighting_downsample % q.refine == 0 ? q.refine : s.transport.refine;
            const int orders = q.exact_orders > 0 ? q.exact_orders : s.transport.lb_exact_orders;
            std::string solve = "single scattering by " + std::to_string(q.single_paths) + " paths";
            if (q.multiple == "none")
                solve += ", multiple scattering from the bases";
            else if (q.multiple == "lattice")
                solve += ", the lattice (exact orders " + std::to_string(orders) + ")";
            else
                solve += ", multiple scattering by " + std::to_string(q.multiple_paths) + " Monte Carlo paths";
            why.push_back("quality = " + name + ": each strike solved once on a worker thread " +
                          core::format_number(q.lookahead) + " s ahead (" + solve + ", on " +
                          core::format_number(p.lighting.voxel_size / double(refine), 6) +
                          " m voxels); the bases light its frames until it is ready");
        }
    }
    if (!p.single)
        why.push_back(
            "effects.single_scattering = false: the direct term is solved (it feeds the solver) but not stored");
    if (p.components == 2)
        why.push_back(
            "compression.components = separate: single and multiple parts stored apart (run time can toggle them)");
    else if (p.single && p.multiple)
        why.push_back("compression.components = combined: one basis per direction holds single + multiple");
    if (s.compression.mode == basis::ThresholdMode::Energy) {
        // Keeping a fraction xi of a basis' energy bounds its relative L2 error by sqrt(1 - xi);
        // past a quarter the bases no longer resemble what was solved (xi 1e-300 bakes ~99% off).
        const double bound = std::sqrt(std::max(0.0, 1.0 - s.compression.xi));
        why.push_back(std::string(bound > 0.25 ? "warning: " : "") +
                      "compression.xi = " + core::format_number(s.compression.xi, 9) +
                      " (energy): each basis keeps that fraction of its energy, so it is at most " +
                      core::format_number(100.0 * bound, 3) + "% off what was solved (relative L2)" +
                      (bound > 0.25 ? "; 0.9999 keeps within 1%" : ""));
    }
    if (s.effects.sun || s.sun)
        why.push_back("the sun is not part of the virtual-light bake (it does not change per frame)");
    if (s.drop_below > 0.0)
        why.push_back("lights scattering less than " + core::format_number(s.drop_below) +
                      " of their power in the cloud are dropped (the count is reported)");
    why.push_back(std::to_string(p.lights.count()) + " virtual lights: h_usr " +
                  core::format_number(s.virtual_lights.h_usr) + " m over the footprint + " +
                  core::format_number(s.virtual_lights.margin) + " m margin, " +
                  std::to_string(p.lights.z.size() - p.lights.base_layer) + " layers from the cloud base up, " +
                  std::to_string(p.lights.base_layer) + " below (Eq. 4, epsilon " +
                  core::format_number(s.virtual_lights.epsilon) + ")");
}

// What the file will hold (key, grids, directions, content, lights, compression) and its raw size.
void describe_file(const scene::Scene& s, const core::Grid3<float>& density, Plan& p) {
    p.metadata.key = scene_key(s, density);
    p.metadata.lighting = p.lighting;
    p.metadata.directions = p.output_directions;
    p.metadata.content =
        (p.single ? basis::FgbMetadata::kContentSingle : 0u) | (p.multiple ? basis::FgbMetadata::kContentMultiple : 0u);
    p.metadata.components = p.components;
    p.metadata.lights = p.lights;
    p.metadata.compression = s.compression;
    basis::validate(p.metadata, "bake plan");

    p.raw_bytes = std::uint64_t(p.lights.count()) * p.metadata.bases() * p.lighting.cell_count() * sizeof(float);
}

// The bake's time and file size from sample lights solved and compressed as a worker would;
// refused when the time passes the scene's limit.
void estimate_from_samples(const scene::Scene& s, const solve::Media& media, Plan& p, const PlanOptions& options) {
    auto tell = [&](const std::string& line) {
        if (options.on_progress) options.on_progress(line);
    };
    // Sample lights: 16 spread over the grid by a golden-ratio sequence in each axis
    // (inside, below and beside the cloud), each solved single-threaded as a bake worker
    // does. Light costs and sizes vary by ~3x between in-cloud and far lights. Fewer
    // (at least one) when their lower-bound cost passes a minute: on a large grid one
    // light can take minutes.
    constexpr double kSampleBudgetSeconds = 60.0;
    const basis::VirtualLightGrid& g = p.lights;
    const double light_count = double(p.lights.count());
    // The single scattering's quadrature refines by the tolerance and g (at 1e-9 and g 0.9 a
    // voxel near the light takes thousands of sub-boxes), which no grid-size bound sees: it
    // is measured on a sample of the central light's voxels, at most 2 s (within 0.84-1.49x
    // of the full solve from 1e-9 to 1e-3 and g 0 to 0.99: fulgur-bench ss_cost).
    if (p.cost.seconds_per_light <= kSampleBudgetSeconds) {
        const transport::PointSource centre{
            g.position(std::uint32_t(g.index(g.x.size() / 2, g.y.size() / 2, g.z.size() / 2))), 1.0};
        const transport::SingleScatteringCost ss = transport::single_scattering_cost(
            media.transport, centre, p.output_directions, solve::single_scattering_options(s), 2.0);
        if (ss.seconds > p.cost.seconds_per_light) {
            p.cost.seconds_per_light = ss.seconds;
            p.single_measured = true;
            p.cost.seconds = ss.seconds * light_count / double(std::min(std::size_t(p.threads), p.lights.count()));
        }
        if (ss.seconds > 0.25 * kSampleBudgetSeconds || !ss.complete)
            p.reasons.push_back("single scattering at tolerance " + core::format_number(s.transport.ss_tolerance) +
                                " and g = " + core::format_number(s.medium.g) + ": about " +
                                core::format_seconds(ss.seconds) + " per light on one thread (measured on " +
                                std::to_string(ss.measured) + " of the central light's " + std::to_string(ss.voxels) +
                                " voxels)");
        if (p.cost.seconds > s.limits.bake_seconds)
            throw core::Error(s.file_name() + ": limits.bake_hours",
                              "the bake would take about " + core::format_seconds(p.cost.seconds) + " (" +
                                  std::to_string(p.lights.count()) + " light(s) x " + core::format_seconds(ss.seconds) +
                                  " of single scattering at tolerance " +
                                  core::format_number(s.transport.ss_tolerance) +
                                  " and g = " + core::format_number(s.medium.g) + ", measured on " +
                                  std::to_string(ss.measured) + " voxels, on " + std::to_string(p.threads) +
                                  " thread(s)), over the limit of " + core::format_seconds(s.limits.bake_seconds) +
                                  "; raise transport.single_scattering.tolerance, \"limits\": {\"bake_hours\": "
                                  "...}, or ask for less");
    }
    if (p.cost.seconds_per_light > kSampleBudgetSeconds) {
        // Not even one sample fits the budget: a plan (and --dry-run) must not run for minutes
        // with no output, so the estimate is the lower bound itself, said to be one.
        p.sample_lights = 0;
        p.expected_seconds = p.cost.seconds;
        p.reasons.push_back("no sample light solved: one light's " +
                            std::string(p.single_measured ? "measured cost, " : "lower bound, ") +
                            core::format_seconds(p.cost.seconds_per_light) + ", is over the " +
                            core::format_seconds(kSampleBudgetSeconds) +
                            " the plan may spend on samples; the expected time is from it");
        return;
    }
    const int kSamples = int(std::clamp(kSampleBudgetSeconds / std::max(p.cost.seconds_per_light, 1e-9), 1.0, 16.0));
    p.sample_lights = kSamples;
    std::vector<std::uint32_t> samples;
    for (int k = 0; k < kSamples; ++k) {
        auto pick = [&](double a, std::size_t n) {
            const double f = std::fmod(0.5 + k * a, 1.0);
            return std::min(n - 1, std::size_t(f * double(n)));
        };
        samples.push_back(std::uint32_t(
            g.index(pick(0.6180339887, g.x.size()), pick(0.7548776662, g.y.size()), pick(0.5698402910, g.z.size()))));
    }
    double seconds = 0.0, block_bytes = 0.0;
    basis::HaarTransform<double> haar(p.lighting.dims, s.compression.decomposition);
    // Sampling that may take more than a few seconds says what it is doing, light by light.
    const bool long_sampling = p.cost.seconds_per_light * double(samples.size()) > 5.0;
    if (long_sampling)
        tell("plan: solving " + std::to_string(samples.size()) + " sample light(s), about " +
             core::format_seconds(p.cost.seconds_per_light) + " each, to estimate the bake");
    {
        const core::ScopedThreadCount one_thread(1);  // as a bake worker solves a light
        for (std::size_t k = 0; k < samples.size(); ++k) {
            const std::uint32_t l = samples[k];
            core::Stopwatch sw;
            const transport::SourceField f = solve_light(s, media, p, l);
            const basis::CompressedLight c = basis::compress_light(l, f, s.compression, haar);
            block_bytes += double(basis::encode_block(c, p.metadata).bytes.size());  // as the file will hold it
            seconds += sw.seconds();
            if (long_sampling)
                tell("plan: sample light " + std::to_string(k + 1) + " of " + std::to_string(samples.size()) +
                     " solved in " + core::format_seconds(sw.seconds()));
        }
    }
    const double ns = double(samples.size());
    p.expected_seconds = seconds / ns * light_count / double(p.threads);
    p.expected_bytes = std::uint64_t(block_bytes / ns * light_count);
    if (p.expected_seconds > s.limits.bake_seconds)
        throw core::Error(s.file_name() + ": limits.bake_hours",
                          "the bake would take about " + core::format_seconds(p.expected_seconds) + " (from " +
                              std::to_string(samples.size()) + " sample light(s)), over the limit of " +
                              core::format_seconds(s.limits.bake_seconds) +
                              "; raise \"limits\": {\"bake_hours\": ...} or ask for less");
}

}  // namespace

Plan make_plan(const scene::Scene& s, const core::Grid3<float>& density, const PlanOptions& options) {
    if (!s.effects.lightning)
        throw core::Error(s.path.string() + ": effects.lightning",
                          "false: the scene has no lightning, so there are no virtual lights to bake");
    if (!s.effects.single_scattering && !s.effects.multiple_scattering)
        throw core::Error(s.path.string() + ": effects",
                          "single_scattering and multiple_scattering are both false: nothing to bake");
    Plan p;
    const solve::Media media = solve::make_media(s, density);
    p.lighting = media.lighting.density.geom;
    try {
        p.lights = basis::build_virtual_light_grid(density, s.virtual_lights);
    } catch (const core::Error& e) {
        // The grid's errors (an empty cloud, a ground above the cloud base) name the field: the
        // file too.
        if (s.path.empty()) throw;
        throw core::Error(s.path.string() + ": " + e.where(), e.reason());
    }
    p.directions = s.effective_directions();
    p.output_directions = transport::output_directions(p.directions);
    p.single = s.effects.single_scattering;
    p.multiple = s.effects.multiple_scattering;
    p.components = (p.single && p.multiple && s.separate_components) ? 2u : 1u;
    p.solver = !p.multiple                                                                ? "none"
               : s.transport.solver == scene::TransportSettings::Solver::LatticeBoltzmann ? "lattice_boltzmann"
                                                                                          : "monte_carlo";
    p.threads = options.threads > 0 ? options.threads : core::thread_count();
    // Memory and a lower bound on time, known from the grids and the light count: a scene
    // past its limits is refused here, before any light (even a sample) is solved.
    p.cost = scene::estimate_cost(s, p.lights.count(), p.threads);
    scene::check_cost(s, p.cost);

    explain(s, media, p);
    describe_file(s, density, p);
    if (options.estimate) estimate_from_samples(s, media, p, options);
    return p;
}

basis::FgbMetadata expected_metadata(const scene::Scene& s, const core::Grid3<float>& density) {
    PlanOptions po;
    po.estimate = false;
    return make_plan(s, density, po).metadata;
}

}  // namespace fulgur::bake
