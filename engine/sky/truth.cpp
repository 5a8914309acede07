// The static light's truth (sky.h, docs/sky.md "The static light against its truth"): the
// sun and the sky dome by Monte Carlo from the grid's boundary through the full-resolution
// density, tallied on the lighting grid, in the fields a solve gives.
#include "sky/sky.h"

#include <cmath>
#include <optional>

namespace fulgur::sky {

namespace {

// The paths' medium: with rain, the rain at its own extinction, scattering as drops.
const transport::LightingMedium& full_medium(const solve::Media& media) {
    if (media.full.density.data.empty())
        throw core::Error("sky truth", "needs the full-resolution density (solve::make_media with full)");
    return solve::traced_medium(media);
}

/// The truth's options for one run; S tallied on the lighting grid, with the rain's phase
/// where it has rain (the media's PhaseMix on that grid).
transport::MonteCarloOptions truth_options(const TruthOptions& o, std::uint64_t stream, const solve::Media& media) {
    if (o.paths < 1000 || o.paths > (std::uint64_t(1) << 34))
        throw core::Error("truth paths", "must be in [1000, 2^34], got " + std::to_string(o.paths));
    transport::MonteCarloOptions mo;
    mo.paths = o.paths;
    mo.seed = core::hash_seed(o.seed, stream);
    mo.halves = true;
    mo.toward = o.toward;
    mo.ground = o.ground;
    mo.phase_mix = media.lighting.phase_mix.get();
    return mo;
}

TruthField as_field(transport::MonteCarloResult&& r) {
    TruthField t;
    t.field.single = std::move(r.single);
    t.field.multiple = std::move(r.multiple);
    t.noise = r.noise;
    t.sums = r.sums;
    t.seconds = r.seconds;
    t.ground = std::move(r.ground);
    t.ground_power = r.ground_power;
    return t;
}

}  // namespace

transport::DomeSource dome_basis(DomeBasis which, int table) {
    FULGUR_ASSERT(table >= 2, "dome_basis: a table of at least 2 values");
    if (which == DomeBasis::Uniform) return transport::DomeSource{{1.0, 1.0}};
    // Linear between the values: zenith_weight's steepest stretch (sqrt near the horizon)
    // differs from its chord by at most 1/(8 sqrt(n)) over the first interval, a solid angle of
    // 2 pi / n; 1025 values make the profile's integral exact to ~1e-5.
    transport::DomeSource d;
    d.radiance.resize(std::size_t(table));
    for (int k = 0; k < table; ++k) {
        const double w = scene::SkyDome::zenith_weight(double(k) / (table - 1));
        d.radiance[std::size_t(k)] = which == DomeBasis::Zenith ? w : 1.0 - w;
    }
    return d;
}

TruthField sun_truth(const solve::Media& media, const glm::dvec3& direction, std::span<const glm::dvec3> directions,
                     const TruthOptions& options) {
    const transport::DirectionalSource sun{direction, 1.0};
    return as_field(transport::monte_carlo(full_medium(media), sun, media.lighting.density.geom, directions,
                                           truth_options(options, 0, media)));
}

SkyTruth sky_truth(const solve::Media& media, bool uniform, std::span<const glm::dvec3> directions,
                   const TruthOptions& options) {
    if (options.table < 2 || options.table > (1 << 20))
        throw core::Error("truth table", "must be in [2, 2^20], got " + std::to_string(options.table));
    const transport::LightingMedium& full = full_medium(media);
    const core::GridGeometry& lighting = media.lighting.density.geom;
    SkyTruth out;
    if (uniform) {
        TruthField t = as_field(transport::monte_carlo(full, dome_basis(DomeBasis::Uniform), lighting, directions,
                                                       truth_options(options, 1, media)));
        out.field.uniform = std::move(t.field);
        out.noise.push_back(t.noise);
        out.sums.push_back(t.sums);
        out.seconds = t.seconds;
        out.ground.push_back(std::move(t.ground));
        out.ground_power.push_back(t.ground_power);
        return out;
    }
    const transport::DomeSource zenith = dome_basis(DomeBasis::Zenith, options.table),
                                horizon = dome_basis(DomeBasis::Horizon, options.table);
    TruthField z =
        as_field(transport::monte_carlo(full, zenith, lighting, directions, truth_options(options, 2, media)));
    TruthField h =
        as_field(transport::monte_carlo(full, horizon, lighting, directions, truth_options(options, 3, media)));
    out.field.zenith = std::move(z.field);
    out.field.horizon = std::move(h.field);
    out.noise = {z.noise, h.noise};
    out.sums = {z.sums, h.sums};
    out.seconds = z.seconds + h.seconds;
    out.ground = {std::move(z.ground), std::move(h.ground)};
    out.ground_power = {z.ground_power, h.ground_power};
    return out;
}

StaticLight static_truth(const ScenePlan& plan, const solve::Media& media, const glm::dvec3& sun_direction,
                         std::span<const glm::dvec3> directions, const TruthOptions& options,
                         std::vector<transport::MonteCarloResult::Noise>* noise) {
    StaticLight light;
    light.sun_direction = sun_direction;
    TruthOptions o = options;  // toward the plan's camera when its solves are
    o.toward = plan.settings.toward;
    if (plan.sun) {
        TruthField t = sun_truth(media, sun_direction, directions, o);
        light.sun = std::move(t.field);
        if (noise) noise->push_back(t.noise);
    }
    if (plan.sky) {
        SkyTruth t = sky_truth(media, plan.sky_uniform, directions, o);
        light.sky = std::move(t.field);
        if (noise) noise->insert(noise->end(), t.noise.begin(), t.noise.end());
    }
    return light;
}

void keep_parts(StaticLight& light, const StaticLight& like) {
    const auto match = [](LightField& f, const LightField& l) {
        if (l.single.data.empty()) f.single = {};
        if (l.multiple.data.empty()) f.multiple = {};
    };
    if (light.sun && like.sun) match(*light.sun, *like.sun);
    if (light.sky && like.sky) {
        match(light.sky->zenith, like.sky->zenith);
        match(light.sky->horizon, like.sky->horizon);
        match(light.sky->uniform, like.sky->uniform);
    }
}

StaticLight truth_of(const scene::Scene& s, const core::Grid3<float>& density, const ScenePlan& plan,
                     const solve::Media& media, const StaticLight& solved, std::span<const glm::dvec3> directions,
                     const TruthOptions& options, std::vector<transport::MonteCarloResult::Noise>* noise) {
    std::optional<solve::Media> own;
    const solve::Media* m = &media;
    // The truth tallies on the grid the solves' S is kept on (static_media's lighting grid); on
    // the lighting grid it needs no transport grid.
    if (m->full.density.data.empty())
        m = &own.emplace(solve_settings(s, density).keep_transport_grid ? static_media(s, density, true)
                                                                        : make_static_media(s, density, 1, true));
    StaticLight truth = static_truth(plan, *m, solved.sun_direction, directions, options, noise);
    keep_parts(truth, solved);
    return truth;
}

}  // namespace fulgur::sky
