// The baker: plan, per-light solve + compression, checksummed file (bake.h, docs/bake.md).
#include "bake/bake.h"
#include "bake/detail/checkpoint.h"

#include <omp.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <exception>
#include <map>
#include <mutex>
#include <numbers>
#include <sstream>
#include <thread>

namespace fulgur::bake {

namespace {

// Bump when the bake's algorithm changes what it writes for the same scene (forces a rebake).
// 2: the lattice-Boltzmann thick-voxel mapping (transport.lattice_boltzmann.thick_voxels).
constexpr int kBakeAlgorithm = 2;

std::uint64_t hash_bytes(const void* data, std::size_t n) noexcept {
    return basis::hash_description(std::string_view(static_cast<const char*>(data), n));
}

void add_into(transport::SourceField& acc, const transport::SourceField& f) {
    if (acc.data.empty()) {
        acc = f;
        return;
    }
    for (std::size_t i = 0; i < acc.data.size(); ++i) acc.data[i] += f.data[i];
}

// Light l's stored bases from a solution: [single dirs][multiple dirs] when separate,
// else their sum (or the one part baked).
transport::SourceField stored_bases(const Plan& plan, Solution&& sol) {
    const std::size_t cells = plan.lighting.cell_count(), nd = plan.output_directions.size();
    if (plan.components == 2) {
        std::vector<glm::dvec3> dirs = plan.output_directions;
        dirs.insert(dirs.end(), plan.output_directions.begin(), plan.output_directions.end());
        transport::SourceField out(plan.lighting, std::move(dirs));
        if (!sol.single.data.empty()) std::copy(sol.single.data.begin(), sol.single.data.end(), out.data.begin());
        if (!sol.multiple.data.empty())
            std::copy(sol.multiple.data.begin(), sol.multiple.data.end(),
                      out.data.begin() + std::ptrdiff_t(cells * nd));
        return out;
    }
    transport::SourceField out(plan.lighting, plan.output_directions);
    if (plan.single && !sol.single.data.empty()) add_into(out, sol.single);
    if (plan.multiple && !sol.multiple.data.empty()) add_into(out, sol.multiple);
    return out;
}

// Squared L2 norm of the stored field and of (reconstruction - field) over all bases of a
// light; reconstruction by the same inverse transform the run time uses (in double).
void compression_error(const basis::CompressedLight& c, const transport::SourceField& f,
                       basis::HaarTransform<double>& plan, double& ref2, double& err2) {
    const std::size_t cells = f.cells();
    std::vector<double> buf(cells);
    for (std::size_t m = 0; m < c.directions.size(); ++m) {
        std::fill(buf.begin(), buf.end(), 0.0);
        const basis::CompressedBasis& b = c.directions[m];
        basis::accumulate(b, 1.0, std::span<double>(buf));  // values are stored already scaled
        plan.inverse(buf);
        const std::span<const float> x = f.direction(m);
        core::CompensatedSum r, e;
        for (std::size_t i = 0; i < cells; ++i) {
            r.add(double(x[i]) * double(x[i]));
            const double d = buf[i] - double(x[i]);
            e.add(d * d);
        }
        ref2 += r.value();
        err2 += e.value();
    }
}

int worker_threads(int requested) { return requested > 0 ? requested : core::thread_count(); }

}  // namespace

// ---------------------------------------------------------------------------------------

basis::BakeKey scene_key(const scene::Scene& s, const core::Grid3<float>& density) {
    std::ostringstream d;
    const bool multiple = s.effects.multiple_scattering;
    d << "bake.algorithm=" << kBakeAlgorithm << "\n";
    d << "density.dims=" << density.dims().x << "x" << density.dims().y << "x" << density.dims().z << "\n";
    d << "density.voxel_size=" << core::format_number(density.geom.voxel_size, 17) << "\n";
    d << "density.origin=" << core::format_number(density.geom.origin.x, 17) << ","
      << core::format_number(density.geom.origin.y, 17) << "," << core::format_number(density.geom.origin.z, 17)
      << "\n";
    char hx[24];
    std::snprintf(
        hx, sizeof hx, "%016llx",
        static_cast<unsigned long long>(hash_bytes(density.data.data(), density.data.size() * sizeof(float))));
    d << "density.hash=" << hx << "\n";
    d << "medium.extinction=" << core::format_number(s.medium.extinction, 17) << "\n";
    d << "medium.albedo=" << core::format_number(s.medium.albedo, 17) << "\n";
    d << "medium.g=" << core::format_number(s.medium.g, 17) << "\n";
    d << "lighting.downsample=" << s.lighting_downsample << "\n";
    d << "lighting.directions=" << s.effective_directions() << "\n";
    d << "effects.single_scattering=" << s.effects.single_scattering << "\n";
    d << "effects.multiple_scattering=" << multiple << "\n";
    d << "transport.single_scattering.tolerance=" << core::format_number(s.transport.ss_tolerance, 17) << "\n";
    if (s.transport.refine != 1) d << "transport.refine=" << s.transport.refine << "\n";
    if (multiple) {
        if (s.transport.solver == scene::TransportSettings::Solver::LatticeBoltzmann) {
            d << "transport.solver=lattice_boltzmann\n";
            d << "transport.lattice_boltzmann.collision=" << s.transport.lb_collision << "\n";
            d << "transport.lattice_boltzmann.absorption=" << s.transport.lb_absorption << "\n";
            d << "transport.lattice_boltzmann.thick_voxels=" << s.transport.lb_thick_voxels << "\n";
            d << "transport.lattice_boltzmann.tolerance=" << core::format_number(s.transport.lb_tolerance, 17) << "\n";
            d << "transport.lattice_boltzmann.max_iterations=" << s.transport.lb_max_iterations << "\n";
            if (s.transport.lb_exact_orders != 1)
                d << "transport.lattice_boltzmann.exact_orders=" << s.transport.lb_exact_orders
                  << "\ntransport.lattice_boltzmann.order2_paths=" << s.transport.lb_order2_paths << "\n";
        } else {
            d << "transport.solver=monte_carlo\n";
            d << "transport.monte_carlo.paths=" << s.transport.mc_paths << "\n";
            d << "transport.monte_carlo.seed=" << s.transport.mc_seed << "\n";
            d << "transport.monte_carlo.batches=" << s.transport.mc_batches << "\n";
        }
    }
    const basis::VirtualLightParams& v = s.virtual_lights;
    d << "virtual_lights.h_usr=" << core::format_number(v.h_usr, 17) << "\n";
    d << "virtual_lights.epsilon=" << core::format_number(v.epsilon, 17) << "\n";
    d << "virtual_lights.margin=" << core::format_number(v.margin, 17) << "\n";
    d << "virtual_lights.ground_height=" << core::format_number(v.ground_height, 17) << "\n";
    d << "virtual_lights.density_threshold=" << core::format_number(v.density_threshold, 17) << "\n";
    d << "virtual_lights.drop_below=" << core::format_number(s.drop_below, 17) << "\n";
    const basis::CompressionParams& c = s.compression;
    d << "compression.threshold=" << basis::to_string(c.mode) << "\n";
    d << "compression.xi=" << core::format_number(c.xi, 17) << "\n";
    d << "compression.precision=" << basis::to_string(c.precision) << "\n";
    d << "compression.decomposition=" << basis::to_string(c.decomposition) << "\n";
    d << "compression.entropy=" << basis::to_string(c.entropy) << "\n";
    d << "compression.components=" << (s.separate_components ? "separate" : "combined") << "\n";
    return basis::BakeKey::from_description(d.str());
}

transport::LbSettings lattice_settings(const scene::Scene& s) {
    transport::LbSettings lb;
    lb.collision = transport::parse_lb_collision(s.transport.lb_collision);
    lb.absorption = transport::parse_lb_absorption(s.transport.lb_absorption);
    lb.thick_voxels = transport::parse_lb_thick_voxels(s.transport.lb_thick_voxels);
    lb.tolerance = s.transport.lb_tolerance;
    lb.max_iterations = s.transport.lb_max_iterations;
    return lb;
}

Media make_media(const scene::Scene& s, const core::Grid3<float>& density) {
    Media m;
    m.lighting = scene::make_lighting_medium(s, density);
    m.refine = s.transport.refine;
    m.transport = m.refine == 1 ? m.lighting : scene::make_transport_medium(s, density);
    if (s.transport.lb_exact_orders == 2) {
        m.full.density = density;
        m.full.optics = s.medium;
    }
    return m;
}

transport::SingleScatteringOptions single_scattering_options(const scene::Scene& s) {
    transport::SingleScatteringOptions o;
    o.tolerance = s.transport.ss_tolerance;
    // S in an empty voxel with no cloud among its 26 neighbours never reaches an image (the
    // renderer weights S by density and interpolates trilinearly) and feeds no lattice
    // emission (sigma_t = 0): not computed.
    o.skip_far_empty = true;
    o.skip_block = s.transport.refine;  // every fine voxel of a needed lighting voxel is computed
    return o;
}

Solution solve(const scene::Scene& s, const Media& media, std::span<const transport::PointSource> sources,
               std::span<const glm::dvec3> directions, const SolveRequest& request) {
    Solution out;
    // Everything is solved on the transport grid and averaged onto the lighting grid at the end.
    const transport::LightingMedium& medium = media.transport;
    const core::GridGeometry& geom = medium.density.geom;
    FULGUR_ASSERT(media.refine >= 1 && media.lighting.density.geom.voxel_size == geom.voxel_size * media.refine,
                  "bake::solve: media from make_media");
    const std::vector<glm::dvec3> dirs(directions.begin(), directions.end());
    if (!request.single && !request.multiple) return out;

    // Exact single scattering, summed over the sources, and the uncollided fluence phi1
    // from the same quadrature (the lattice's first_scattered_fluence; the drop criterion).
    core::Stopwatch sw;
    transport::SingleScatteringOptions ss = single_scattering_options(s);
    transport::SourceField s1(geom, dirs), tmp(geom, dirs);
    core::Grid3<float> phi1(geom, 0.0f), phi_one;
    ss.uncollided_fluence = &phi_one;
    for (const transport::PointSource& p : sources) {
        if (p.intensity == 0.0) continue;
        transport::single_scattering(medium, p, tmp, ss);
        add_into(s1, tmp);
        for (std::size_t i = 0; i < phi1.size(); ++i) phi1.data[i] += phi_one.data[i];
    }
    {
        core::CompensatedSum p;
        const double vol = geom.voxel_size * geom.voxel_size * geom.voxel_size;
        for (std::size_t i = 0; i < phi1.size(); ++i)
            p.add(medium.optics.albedo * medium.sigma_t(i) * double(phi1.data[i]) * vol);
        out.first_scattered_power = p.value();
    }
    out.seconds_single = sw.seconds();

    double emitted = 0.0;
    for (const transport::PointSource& p : sources) emitted += 4.0 * std::numbers::pi * p.intensity;
    const bool skip = request.skip_below > 0.0 && out.first_scattered_power < request.skip_below * emitted;

    if (request.multiple && !skip) {
        sw.reset();
        if (s.transport.solver == scene::TransportSettings::Solver::LatticeBoltzmann) {
            transport::LbSources src;
            src.first_scattered = &s1;
            src.first_scattered_fluence = &phi1;
            transport::MonteCarloResult second;
            if (s.transport.lb_exact_orders == 2) {
                // Order 2 by the expected-value Monte Carlo of the second flight through the
                // full-resolution density, tallied on the lattice's grid; the lattice is fed
                // with it and solves orders >= 3. Seeded by the sources, so a solve is
                // deterministic.
                FULGUR_ASSERT(!media.full.density.data.empty(),
                              "bake::solve: exact_orders 2 needs make_media's full density");
                transport::MonteCarloOptions mo;
                mo.paths = s.transport.lb_order2_paths;
                mo.batches = 4;
                mo.max_scatterings = 1;
                mo.expected_second_order = true;
                mo.tally_fluence = true;
                mo.seed = core::hash_seed(s.transport.mc_seed,
                                          hash_bytes(sources.data(), sources.size() * sizeof(transport::PointSource)));
                second = transport::monte_carlo(media.full, sources, {}, geom, dirs, mo);
                src.first_scattered = &second.multiple;
                src.first_scattered_fluence = &second.fluence2;
            }
            transport::LbResult r = transport::solve_lattice_boltzmann(medium, src, dirs, lattice_settings(s));
            out.multiple = std::move(r.source);
            if (s.transport.lb_exact_orders == 2)
                for (std::size_t i = 0; i < out.multiple.data.size(); ++i)
                    out.multiple.data[i] += second.multiple.data[i];
            out.iterations = r.iterations;
            out.converged = r.converged;
        } else {
            out.multiple = transport::SourceField(geom, dirs);
            for (std::size_t q = 0; q < sources.size(); ++q) {
                if (sources[q].intensity == 0.0) continue;
                transport::MonteCarloOptions mo;
                mo.paths = s.transport.mc_paths;
                mo.batches = s.transport.mc_batches;
                mo.seed = core::hash_seed(s.transport.mc_seed, q);
                const transport::MonteCarloResult r = transport::monte_carlo(medium, sources[q], dirs, mo);
                add_into(out.multiple, r.multiple);
            }
        }
        out.seconds_multiple = sw.seconds();
    } else if (request.multiple) {
        out.multiple = transport::SourceField(geom, dirs);
    }
    if (request.single) out.single = std::move(s1);
    if (media.refine > 1) {
        if (!out.single.data.empty()) out.single = transport::block_average(out.single, media.refine);
        if (!out.multiple.data.empty()) out.multiple = transport::block_average(out.multiple, media.refine);
    }
    return out;
}

// ---------------------------------------------------------------------------------------

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
    o << "  time at least   " << core::format_seconds(cost.seconds) << " (from the grid sizes)\n";
    if (expected_bytes)
        o << "  expected file   " << core::format_bytes(double(expected_bytes)) << " (from " << sample_lights
          << " sample lights)\n";
    if (expected_seconds > 0.0)
        o << "  expected time   " << core::format_seconds(expected_seconds) << " (from " << sample_lights
          << " sample lights)\n";
    o << "  why:\n";
    for (const std::string& r : reasons) o << "    - " << r << "\n";
    return o.str();
}

Plan make_plan(const scene::Scene& s, const core::Grid3<float>& density, const PlanOptions& options) {
    if (!s.effects.lightning)
        throw core::Error(s.path.string() + ": effects.lightning",
                          "false: the scene has no lightning, so there are no virtual lights to bake");
    if (!s.effects.single_scattering && !s.effects.multiple_scattering)
        throw core::Error(s.path.string() + ": effects",
                          "single_scattering and multiple_scattering are both false: nothing to bake");
    Plan p;
    const Media media = make_media(s, density);
    p.lighting = media.lighting.density.geom;
    p.lights = basis::build_virtual_light_grid(density, s.virtual_lights);
    p.directions = s.effective_directions();
    p.output_directions = transport::output_directions(p.directions);
    p.single = s.effects.single_scattering;
    p.multiple = s.effects.multiple_scattering;
    p.components = (p.single && p.multiple && s.separate_components) ? 2u : 1u;
    p.solver = !p.multiple                                                                ? "none"
               : s.transport.solver == scene::TransportSettings::Solver::LatticeBoltzmann ? "lattice_boltzmann"
                                                                                          : "monte_carlo";
    p.threads = worker_threads(options.threads);
    // Memory and a lower bound on time, known from the grids and the light count: a scene
    // past its limits is refused here, before any light (even a sample) is solved.
    p.cost = scene::estimate_cost(s, p.lights.count(), p.threads);
    scene::check_cost(s, p.cost);

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

    if (options.estimate) {
        // Sample lights: 16 spread over the grid by a golden-ratio sequence in each axis
        // (inside, below and beside the cloud), each solved single-threaded as a bake worker
        // does. Light costs and sizes vary by ~3x between in-cloud and far lights. Fewer
        // (at least one) when their lower-bound cost passes a minute: on a large grid one
        // light can take minutes.
        constexpr double kSampleBudgetSeconds = 60.0;
        const int kSamples =
            int(std::clamp(kSampleBudgetSeconds / std::max(p.cost.seconds_per_light, 1e-9), 1.0, 16.0));
        p.sample_lights = kSamples;
        std::vector<std::uint32_t> samples;
        const basis::VirtualLightGrid& g = p.lights;
        for (int k = 0; k < kSamples; ++k) {
            auto pick = [&](double a, std::size_t n) {
                const double f = std::fmod(0.5 + k * a, 1.0);
                return std::min(n - 1, std::size_t(f * double(n)));
            };
            samples.push_back(std::uint32_t(g.index(pick(0.6180339887, g.x.size()), pick(0.7548776662, g.y.size()),
                                                    pick(0.5698402910, g.z.size()))));
        }
        const int saved = core::thread_count();
        core::set_thread_count(1);
        double seconds = 0.0, block_bytes = 0.0;
        basis::HaarTransform<double> haar(p.lighting.dims, s.compression.decomposition);
        try {
            for (std::uint32_t l : samples) {
                core::Stopwatch sw;
                const transport::SourceField f = solve_light(s, media, p, l);
                const basis::CompressedLight c = basis::compress_light(l, f, s.compression, haar);
                block_bytes += double(basis::encode_block(c, p.metadata).bytes.size());  // as the file will hold it
                seconds += sw.seconds();
            }
        } catch (...) {
            core::set_thread_count(saved);
            throw;
        }
        core::set_thread_count(saved);
        const double n = double(p.lights.count());
        const double ns = double(samples.size());
        p.expected_seconds = seconds / ns * n / double(p.threads);
        p.expected_bytes = std::uint64_t(block_bytes / ns * n);
        if (p.expected_seconds > s.limits.bake_seconds)
            throw core::Error((s.path.empty() ? std::string("scene") : s.path.string()) + ": limits.bake_hours",
                              "the bake would take about " + core::format_seconds(p.expected_seconds) + " (from " +
                                  std::to_string(samples.size()) + " sample light(s)), over the limit of " +
                                  core::format_seconds(s.limits.bake_seconds) +
                                  "; raise \"limits\": {\"bake_hours\": ...} or ask for less");
    }
    return p;
}

transport::SourceField solve_light(const scene::Scene& s, const Media& media, const Plan& plan, std::uint32_t light) {
    FULGUR_ASSERT(light < plan.lights.count(), "solve_light: light index out of range");
    const transport::PointSource src{plan.lights.position(light), 1.0};
    SolveRequest rq;
    rq.single = true;
    rq.multiple = plan.multiple;
    Solution sol = solve(s, media, std::span(&src, 1), plan.output_directions, rq);
    return stored_bases(plan, std::move(sol));
}

// ---------------------------------------------------------------------------------------

Report bake(const scene::Scene& s, const core::Grid3<float>& density, const std::filesystem::path& out,
            const Progress& progress) {
    PlanOptions po;
    po.estimate = false;
    return bake(s, density, make_plan(s, density, po), out, progress);
}

Report bake(const scene::Scene& s, const core::Grid3<float>& density, const Plan& plan,
            const std::filesystem::path& out, const Progress& progress) {
    return bake(s, density, plan, out, BakeOptions{}, progress);
}

std::filesystem::path checkpoint_path(const std::filesystem::path& out) { return out.string() + ".ckpt"; }

namespace {

// Light l solved, compressed and encoded on the calling thread: one job of the bake.
LightResult bake_one(const scene::Scene& s, const Media& media, const Plan& plan, basis::HaarTransform<double>& haar,
                     std::uint32_t l) {
    LightResult out;
    const transport::PointSource src{plan.lights.position(l), 1.0};
    SolveRequest rq;
    rq.single = true;
    rq.multiple = plan.multiple;
    rq.skip_below = s.drop_below;
    Solution sol = solve(s, media, std::span(&src, 1), plan.output_directions, rq);
    out.seconds_single = sol.seconds_single;
    out.seconds_multiple = sol.seconds_multiple;
    const double fraction = sol.first_scattered_power / (4.0 * std::numbers::pi);
    core::Stopwatch sw;
    basis::CompressedLight c;
    if (s.drop_below > 0.0 && fraction < s.drop_below) {
        c.light = l;
        c.directions.resize(plan.metadata.bases());
        out.dropped_fraction = fraction;
    } else {
        const int iterations = sol.iterations;
        const bool converged = sol.converged;
        const transport::SourceField f = stored_bases(plan, std::move(sol));
        c = basis::compress_light(l, f, s.compression, haar);
        compression_error(c, f, haar, out.ref2, out.err2);
        if (plan.multiple && plan.solver == "lattice_boltzmann") {
            out.iterations = iterations;
            out.converged = converged;
        }
    }
    out.coefficients = c.coefficient_count();
    out.seconds_compress = sw.seconds();
    out.block = basis::encode_block(c, plan.metadata);  // as the file stores it
    return out;
}

// The Report's sums over the lights' figures.
struct Totals {
    double single = 0.0, multiple = 0.0, compress = 0.0, ref2 = 0.0, err2 = 0.0, iterations = 0.0, max_iterations = 0.0,
           max_dropped = 0.0;
    std::size_t lattice_lights = 0, dropped = 0, unconverged = 0;
    std::uint64_t kept = 0;
    void add(const LightResult& r) {
        single += r.seconds_single;
        multiple += r.seconds_multiple;
        compress += r.seconds_compress;
        ref2 += r.ref2;
        err2 += r.err2;
        kept += r.coefficients;
        if (r.dropped_fraction >= 0.0) {
            ++dropped;
            max_dropped = std::max(max_dropped, r.dropped_fraction);
        }
        if (r.iterations >= 0) {
            ++lattice_lights;
            iterations += r.iterations;
            max_iterations = std::max(max_iterations, double(r.iterations));
            if (!r.converged) ++unconverged;
        }
    }
};

// Runs body(haar) on `threads` threads with the solvers' own parallel regions nested inside
// single-threaded (max-active-levels 1), each thread with its Haar plan; rethrows the first
// exception once all have stopped. `failed` tells the bodies to stop early. With `serve`,
// the calling thread (the team's thread 0) runs serve() instead, beside `threads` workers.
template <class Body, class Serve>
void run_team(const Plan& plan, const scene::Scene& s, int threads, std::atomic<bool>& failed, Body&& body,
              Serve* serve) {
    std::exception_ptr failure;
    std::mutex mu;
    const int saved_levels = omp_get_max_active_levels();
    omp_set_max_active_levels(1);
#pragma omp parallel num_threads(threads + (serve ? 1 : 0))
    {
        try {
            if (serve && omp_get_thread_num() == 0) {
                (*serve)();
            } else {
                basis::HaarTransform<double> haar(plan.lighting.dims, s.compression.decomposition);
                body(haar);
            }
        } catch (...) {
            std::lock_guard lock(mu);
            if (!failure) failure = std::current_exception();
            failed = true;
        }
    }
    omp_set_max_active_levels(saved_levels);
    if (failure) std::rethrow_exception(failure);
}

}  // namespace

std::vector<LightResult> bake_lights(const scene::Scene& s, const Media& media, const Plan& plan, std::uint32_t begin,
                                     std::uint32_t end) {
    FULGUR_ASSERT(begin <= end && end <= plan.lights.count(), "bake_lights: light range outside the plan");
    std::vector<LightResult> out(end - begin);
    std::atomic<std::uint32_t> next{begin};
    std::atomic<bool> failed{false};
    auto body = [&](basis::HaarTransform<double>& haar) {
        for (std::uint32_t l = next.fetch_add(1); l < end && !failed.load(); l = next.fetch_add(1))
            out[l - begin] = bake_one(s, media, plan, haar, l);
    };
    run_team(plan, s, plan.threads, failed, body, static_cast<std::function<void()>*>(nullptr));
    return out;
}

Report bake(const scene::Scene& s, const core::Grid3<float>& density, const Plan& plan,
            const std::filesystem::path& out, const BakeOptions& options, const Progress& progress) {
    core::Stopwatch total;
    Report rep;
    rep.threads = plan.threads;
    rep.lights = plan.lights.count();
    rep.raw_bytes = plan.raw_bytes;
    const Media media = make_media(s, density);
    // The output's lock for the whole bake, the checkpoint's removal included: one bake per
    // output, so one user of its checkpoint (the writer's own lock is then a no-op).
    const core::FileLock output_lock(out);
    basis::FgbWriter writer(out, plan.metadata);
    std::unique_ptr<detail::Checkpoint> checkpoint;
    if (!options.checkpoint.empty()) checkpoint = std::make_unique<detail::Checkpoint>(options.checkpoint, plan);

    // The chunks to solve: the lights the checkpoint lacks, cut into chunks small enough to
    // keep every worker busy to the end (light costs vary ~3x) and few enough to keep the
    // checkpoint's files and the messages few. Alone and without a checkpoint: one light.
    const std::uint32_t n = std::uint32_t(plan.lights.count());
    Totals totals;
    std::vector<Chunk> todo;
    {
        const std::uint32_t workers = std::uint32_t(plan.threads + (options.helpers ? options.helpers->threads() : 0));
        std::uint32_t size = options.chunk;
        if (size == 0)
            size = (!checkpoint && !options.helpers) ? 1u : std::clamp(n / (4u * std::max(workers, 1u)), 1u, 64u);
        std::uint32_t l = 0;
        auto cut = [&](std::uint32_t to) {
            for (; l < to; l = std::min(to, l + size)) todo.push_back({l, std::min(to, l + size)});
        };
        if (checkpoint)
            for (const detail::Checkpoint::Held& h : checkpoint->held()) {
                cut(h.chunk.begin);
                for (const LightResult& r : h.figures) totals.add(r);
                l = h.chunk.end;
            }
        cut(n);
        rep.lights_resumed = checkpoint ? checkpoint->lights() : 0;
    }

    std::mutex mu;  // guards totals, pending, done and the progress callback
    std::map<std::uint32_t, std::vector<LightResult>> pending;  // finished out of order (no checkpoint)
    std::uint32_t next_write = 0;
    std::size_t done = 0;
    const std::size_t to_do = n - rep.lights_resumed;
    auto advance = [&](std::size_t lights) {  // under mu
        done += lights;
        if (progress) progress(done, to_do, total.seconds());
    };
    // A finished chunk: into the checkpoint, or into the file once every light before it is
    // in (blocks go in light order: the file is the same however the work was split).
    auto deliver = [&](Chunk c, std::vector<LightResult>&& results) {
        if (checkpoint) checkpoint->add(c, results);
        std::lock_guard lock(mu);
        for (const LightResult& r : results) totals.add(r);
        if (checkpoint) {
            if (options.on_checkpoint) options.on_checkpoint(checkpoint->lights());
            return;
        }
        pending.emplace(c.begin, std::move(results));
        while (!pending.empty() && pending.begin()->first == next_write) {
            for (const LightResult& r : pending.begin()->second) writer.add(r.block);
            next_write += std::uint32_t(pending.begin()->second.size());
            pending.erase(pending.begin());
        }
    };
    std::atomic<std::size_t> next{0};
    std::atomic<bool> failed{false};
    auto take = [&]() -> std::optional<Chunk> {
        if (failed.load()) return std::nullopt;
        const std::size_t i = next.fetch_add(1);
        return i < todo.size() ? std::optional<Chunk>(todo[i]) : std::nullopt;
    };
    auto body = [&](basis::HaarTransform<double>& haar) {
        while (const std::optional<Chunk> c = take()) {
            std::vector<LightResult> results;
            results.reserve(c->size());
            for (std::uint32_t l = c->begin; l < c->end && !failed.load(); ++l) {
                results.push_back(bake_one(s, media, plan, haar, l));
                std::lock_guard lock(mu);
                advance(1);
            }
            if (failed.load()) break;
            deliver(*c, std::move(results));
        }
    };
    // The calling thread serves the helpers (a message layer such as MPI is then called from
    // one thread only), polling every millisecond when idle. After a failure here it goes on
    // serving until every helper is released (no chunk is handed out any more), so the other
    // processes end with this one; only a failure of the messages themselves ends it at once.
    std::exception_ptr delivery_failure;
    std::function<void()> serve = [&] {
        const std::function<std::optional<Chunk>()> next_chunk = take;
        const std::function<void(Chunk, std::vector<LightResult> &&)> remote = [&](Chunk c,
                                                                                   std::vector<LightResult>&& r) {
            if (failed.load()) return;
            try {
                deliver(c, std::move(r));
                std::lock_guard lock(mu);
                advance(c.size());
            } catch (...) {
                if (!delivery_failure) delivery_failure = std::current_exception();
                failed = true;
            }
        };
        for (bool released = false; !released;) {
            bool busy = false;
            released = options.helpers->poll(next_chunk, remote, busy);
            if (!busy) std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
    };
    run_team(plan, s, plan.threads, failed, body, options.helpers ? &serve : nullptr);
    if (delivery_failure) std::rethrow_exception(delivery_failure);

    // A bake that would render an unlit cloud is refused (no file is written): the settings
    // that made it so are named.
    const std::string where = s.path.empty() ? std::string("scene") : s.path.string();
    rep.lights_dropped = totals.dropped;
    rep.coefficients_kept = totals.kept;
    rep.unconverged = totals.unconverged;
    rep.max_dropped_fraction = totals.max_dropped;
    if (rep.lights_dropped == n)
        throw core::Error(where + ": virtual_lights.drop_below",
                          "every one of the " + std::to_string(n) + " virtual lights scatters less than " +
                              core::format_number(s.drop_below) +
                              " of its power (largest: " + core::format_number(rep.max_dropped_fraction) +
                              ") and was dropped; the bake would light nothing: lower drop_below");
    if (rep.coefficients_kept == 0)
        throw core::Error(where + ": compression.xi",
                          "the threshold keeps no coefficient of any basis; the bake would light nothing: lower xi");

    core::Stopwatch sw;
    if (checkpoint) checkpoint->copy_blocks(writer);
    writer.finish();
    if (checkpoint) checkpoint->remove();
    rep.seconds_write = sw.seconds();
    // Per-stage times are summed over the worker threads (CPU seconds); the total is wall time.
    rep.seconds_single = totals.single;
    rep.seconds_multiple = totals.multiple;
    rep.seconds_compress = totals.compress;
    rep.file_bytes = std::filesystem::file_size(out);
    rep.compression_ratio = rep.file_bytes ? double(rep.raw_bytes) / double(rep.file_bytes) : 0.0;
    rep.relative_l2_error = totals.ref2 > 0.0 ? std::sqrt(totals.err2 / totals.ref2) : 0.0;
    rep.mean_solver_iterations = totals.lattice_lights ? totals.iterations / double(totals.lattice_lights) : 0.0;
    rep.max_solver_iterations = totals.max_iterations;
    rep.seconds_total = total.seconds();
    return rep;
}

std::filesystem::path default_fgb_path(const scene::Scene& s) {
    if (s.path.empty()) return std::filesystem::path("scene.fgb");
    std::filesystem::path p = s.path;
    p.replace_extension(".fgb");
    return p;
}

basis::FgbMetadata expected_metadata(const scene::Scene& s, const core::Grid3<float>& density) {
    PlanOptions po;
    po.estimate = false;
    return make_plan(s, density, po).metadata;
}

bool up_to_date(const scene::Scene& s, const core::Grid3<float>& density, const std::filesystem::path& fgb,
                std::string* why) {
    auto fail = [&](const std::string& m) {
        if (why) *why = m;
        return false;
    };
    std::error_code ec;
    if (!std::filesystem::exists(fgb, ec)) return fail(fgb.string() + ": no baked file");
    try {
        basis::FgbReader r(fgb);
        if (r.partial()) return fail(fgb.string() + ": a partial file (one bake job's lights), not a complete bake");
        r.check_metadata(expected_metadata(s, density));
    } catch (const core::Error& e) {
        return fail(e.what());
    }
    return true;
}

std::optional<Report> bake_if_stale(const scene::Scene& s, const core::Grid3<float>& density,
                                    const std::filesystem::path& fgb, const Progress& progress,
                                    const std::function<void(const std::string& why)>& on_stale) {
    std::string why;
    if (up_to_date(s, density, fgb, &why)) return std::nullopt;
    // Another process may be baking the same file (two fulgur-shot runs of one scene): wait
    // for it, then look again before baking.
    const core::FileLock lock(fgb);
    if (up_to_date(s, density, fgb, &why)) return std::nullopt;
    if (on_stale) on_stale(why);
    return bake(s, density, fgb, progress);
}

}  // namespace fulgur::bake
