// The per-light solver (solve.h, docs/transport.md): exact single scattering summed over the
// sources, then the scene's multiple-scattering solver fed with it, on the transport grid and
// averaged onto the lighting grid.
#include "solve/solve.h"

#include "basis/fgb.h"

#include <numbers>
#include <string_view>

namespace fulgur::solve {

namespace {

void add_into(transport::SourceField& acc, const transport::SourceField& f) {
    if (acc.data.empty()) {
        acc = f;
        return;
    }
    for (std::size_t i = 0; i < acc.data.size(); ++i) acc.data[i] += f.data[i];
}

// A seed that depends on the sources themselves, so a solve is deterministic and two
// different sets of sources draw independent paths.
std::uint64_t sources_seed(std::uint64_t seed, std::span<const transport::PointSource> sources) noexcept {
    const std::string_view bytes(reinterpret_cast<const char*>(sources.data()),
                                 sources.size() * sizeof(transport::PointSource));
    return core::hash_seed(seed, basis::hash_description(bytes));
}

}  // namespace

transport::MonteCarloOptions order_two_options(std::uint64_t paths, std::uint64_t seed) {
    transport::MonteCarloOptions mo;
    mo.paths = paths;
    mo.batches = 4;
    mo.max_scatterings = 1;
    mo.expected_second_order = true;
    mo.tally_fluence = true;
    mo.seed = seed;
    return mo;
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

const transport::LightingMedium& traced_medium(const Media& m) noexcept {
    return m.traced.density.data.empty() ? m.full : m.traced;
}

Media make_media(const scene::Scene& s, const core::Grid3<float>& density) {
    return make_media(s, density, s.transport.refine, s.transport.lb_exact_orders == 2);
}

Media make_media(const scene::Scene& s, const core::Grid3<float>& density, int refine, bool full) {
    FULGUR_ASSERT(refine >= 1 && s.lighting_downsample % refine == 0,
                  "make_media: refine must divide lighting.downsample");
    Media m;
    m.lighting = scene::make_lighting_medium(s, density);
    m.refine = refine;
    if (refine == 1) {
        m.transport = m.lighting;
    } else {
        scene::Scene r = s;
        r.transport.refine = refine;
        m.transport = scene::make_transport_medium(r, density);
    }
    if (full) {
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
                  "solve::solve: media from make_media");
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
                              "solve::solve: exact_orders 2 needs make_media's full density");
                second = transport::monte_carlo(
                    media.full, sources, {}, geom, dirs,
                    order_two_options(s.transport.lb_order2_paths, sources_seed(s.transport.mc_seed, sources)));
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

}  // namespace fulgur::solve
