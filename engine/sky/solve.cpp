// The sun's and the sky's light through the lattice (sky.h, docs/sky.md).
#include "sky/sky.h"

#include "cloud/rain.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numbers>
#include <optional>

namespace fulgur::sky {

namespace {

void add_scaled(transport::SourceField& acc, const transport::SourceField& f, double w) {
    for (std::size_t i = 0; i < acc.data.size(); ++i) acc.data[i] += float(w * double(f.data[i]));
}

void add_scaled(core::Grid3<float>& acc, const core::Grid3<float>& f, double w) {
    for (std::size_t i = 0; i < acc.data.size(); ++i) acc.data[i] += float(w * double(f.data[i]));
}

void check_light(const transport::DirectionalSource& l) {
    const double len = glm::length(l.direction);
    if (!std::isfinite(len) || !(len > 0.0)) throw core::Error("sun.direction", "must be a finite non-zero vector");
    if (!std::isfinite(l.irradiance) || l.irradiance < 0.0)
        throw core::Error("sun.irradiance", "must be finite and >= 0, got " + std::to_string(l.irradiance));
}

/// The first-scattered light of a set of directional lights (each weighted): S1 and the
/// uncollided fluence phi1 on the transport grid; with exact orders 2 also order 2 (S2, phi2).
struct FirstScattered {
    transport::SourceField s1;
    core::Grid3<float> phi1;
    double seconds = 0.0;
    transport::SourceField s2;  ///< empty unless exact orders 2
    core::Grid3<float> phi2;
};

/// Zero fields on the transport grid, with order 2 when `order2`.
FirstScattered zeros(const core::GridGeometry& geom, const std::vector<glm::dvec3>& dirs, bool order2) {
    FirstScattered f{transport::SourceField(geom, dirs), core::Grid3<float>(geom, 0.0f), 0.0, {}, {}};
    if (order2) {
        f.s2 = transport::SourceField(geom, dirs);
        f.phi2 = core::Grid3<float>(geom, 0.0f);
    }
    return f;
}

/// The processes the settings spread a solve over, or null for this process alone.
const Processes* spread(const SolveSettings& settings) {
    return settings.processes && settings.processes->size() > 1 ? settings.processes.get() : nullptr;
}

/// Process `root`'s fields of `fs` into `fs` on every process (each holds fields of the same
/// sizes: order 2 on all or none).
void share(const Processes& procs, FirstScattered& fs, int root) {
    procs.share(fs.s1.data, root);
    procs.share(fs.phi1.data, root);
    if (!fs.s2.data.empty()) {
        procs.share(fs.s2.data, root);
        procs.share(fs.phi2.data, root);
    }
}

/// acc += w f, every field f holds (order 2 only when both hold it).
void add_scaled(FirstScattered& acc, const FirstScattered& f, double w) {
    add_scaled(acc.s1, f.s1, w);
    add_scaled(acc.phi1, f.phi1, w);
    if (!acc.s2.data.empty() && !f.s2.data.empty()) {
        add_scaled(acc.s2, f.s2, w);
        add_scaled(acc.phi2, f.phi2, w);
    }
}

/// Order 2 of directional lights by the expected-value Monte Carlo of the second flight through
/// the full-resolution density, tallied on the transport grid (as solve::solve does for point
/// lights): each light `paths` paths, seeded by `seed` and its index.
void second_order(const solve::Media& media, std::span<const transport::DirectionalSource> lights,
                  std::span<const glm::dvec3> directions, std::uint64_t paths, std::uint64_t seed, FirstScattered& fs) {
    FULGUR_ASSERT(!media.full.density.data.empty(), "sky: exact orders 2 needs static_media's full density");
    core::Stopwatch sw;
    const core::GridGeometry& geom = media.transport.density.geom;
    const std::vector<glm::dvec3> dirs(directions.begin(), directions.end());
    fs.s2 = transport::SourceField(geom, dirs);
    fs.phi2 = core::Grid3<float>(geom, 0.0f);
    for (std::size_t i = 0; i < lights.size(); ++i) {
        if (lights[i].irradiance == 0.0) continue;
        transport::MonteCarloOptions mo = solve::order_two_options(paths, core::hash_seed(seed, i));
        mo.phase_mix = media.transport.phase_mix.get();
        const transport::MonteCarloResult r = transport::monte_carlo(media.full, lights[i], geom, dirs, mo);
        add_scaled(fs.s2, r.multiple, 1.0);
        add_scaled(fs.phi2, r.fluence2, 1.0);
    }
    fs.seconds += sw.seconds();
}

/// The dome's orders 1 and 2 by Monte Carlo from the whole dome (`dome`: one basis), tallied on
/// the transport grid with the expected-value estimators (order 1's S and uncollided fluence,
/// order 2's S and fluence: what first_scattered and second_order give for directions), through
/// the full-resolution density. Without order 2 exact only order 1 is traced.
FirstScattered dome_first_scattered(const solve::Media& media, const transport::DomeSource& dome,
                                    std::span<const glm::dvec3> directions, bool two, std::uint64_t paths,
                                    std::uint64_t seed) {
    FULGUR_ASSERT(!media.full.density.data.empty(), "sky: the dome's Monte Carlo needs static_media's full density");
    core::Stopwatch sw;
    transport::MonteCarloOptions mo = solve::order_two_options(paths, seed);
    mo.phase_mix = media.transport.phase_mix.get();
    if (!two) {
        mo.expected_second_order = false;
        mo.max_scatterings = 0;
        mo.tally_multiple = false;
        mo.uncollided_only = true;
    }
    transport::MonteCarloResult r =
        transport::monte_carlo(media.full, dome, media.transport.density.geom, directions, mo);
    FirstScattered f{std::move(r.single), std::move(r.fluence), 0.0, {}, {}};
    if (two) {
        f.s2 = std::move(r.multiple);
        f.phi2 = std::move(r.fluence2);
    }
    f.seconds = sw.seconds();
    return f;
}

FirstScattered first_scattered(const transport::LightingMedium& medium,
                               std::span<const transport::DirectionalSource> lights,
                               std::span<const glm::dvec3> directions, const SolveSettings& settings) {
    core::Stopwatch sw;
    const core::GridGeometry& geom = medium.density.geom;
    const std::vector<glm::dvec3> dirs(directions.begin(), directions.end());
    FirstScattered out{transport::SourceField(geom, dirs), core::Grid3<float>(geom, 0.0f), 0.0, {}, {}};
    transport::SourceField tmp(geom, dirs);
    core::Grid3<float> phi_one;
    transport::SingleScatteringOptions ss = settings.single_options;
    ss.uncollided_fluence = &phi_one;
    for (const transport::DirectionalSource& l : lights) {
        check_light(l);
        if (l.irradiance == 0.0) continue;
        transport::single_scattering(medium, l, tmp, ss);
        add_scaled(out.s1, tmp, 1.0);
        add_scaled(out.phi1, phi_one, 1.0);
    }
    out.seconds = sw.seconds();
    return out;
}

double first_scattered_power(const transport::LightingMedium& medium, const core::Grid3<float>& phi1) {
    const core::GridGeometry& g = medium.density.geom;
    const double vol = g.voxel_size * g.voxel_size * g.voxel_size;
    core::CompensatedSum p;  // ~10^5 terms of very different sizes
    for (std::size_t i = 0; i < phi1.size(); ++i)
        p.add(medium.optics.albedo * medium.sigma_t(i) * double(phi1.data[i]) * vol);
    return p.value();
}

void take_lattice(LightField& out, transport::LbResult&& r) {
    out.multiple = std::move(r.source);
    out.iterations = r.iterations;
    out.converged = r.converged;
    out.injected_per_step = r.injected_per_step;
    out.injected_total = r.injected_total;
    out.absorbed_total = r.absorbed_total;
    out.escaped_total = r.escaped_total;
    out.stored = r.stored;
    out.seconds_multiple = r.seconds;
}

/// Hybrid: S1 kept (when asked) and the lattice fed with it for orders >= 2, or with S2 for
/// orders >= 3 (S2 then added) when fs holds order 2.
LightField hybrid(const solve::Media& media, FirstScattered&& fs, std::span<const glm::dvec3> directions,
                  const SolveSettings& settings) {
    const transport::LightingMedium& medium = media.transport;
    LightField out;
    out.seconds_single = fs.seconds;
    out.first_scattered_power = first_scattered_power(medium, fs.phi1);
    if (settings.multiple) {
        const bool two = !fs.s2.data.empty();
        transport::LbSources src;
        src.first_scattered = two ? &fs.s2 : &fs.s1;
        src.first_scattered_fluence = two ? &fs.phi2 : &fs.phi1;
        take_lattice(out, transport::solve_lattice_boltzmann(medium, src, directions, settings.lattice));
        if (two) add_scaled(out.multiple, fs.s2, 1.0);
    }
    if (settings.single) out.single = std::move(fs.s1);
    return out;
}

void average_onto_lighting(LightField& f, int refine) {
    if (refine <= 1) return;
    if (!f.single.data.empty()) f.single = transport::block_average(f.single, refine);
    if (!f.multiple.data.empty()) f.multiple = transport::block_average(f.multiple, refine);
}

void check_media(const solve::Media& media, const SolveSettings& settings) {
    FULGUR_ASSERT(media.refine >= 1 &&
                      media.lighting.density.geom.voxel_size == media.transport.density.geom.voxel_size * media.refine,
                  "sky: media from solve::make_media");
    FULGUR_ASSERT(media.refine == (settings.keep_transport_grid ? 1 : settings.refine),
                  "sky: the media's refine must be the settings' (static_media)");
    FULGUR_ASSERT(!settings.toward || settings.method == Method::MonteCarlo,
                  "sky: S toward a point is solved by Monte Carlo only (solve_settings)");
}

bool exact_two(const SolveSettings& settings) { return settings.multiple && settings.exact_orders == 2; }

void scale_light(LightField& f, double w) {
    for (float& v : f.single.data) v = float(w * double(v));
    for (float& v : f.multiple.data) v = float(w * double(v));
}

// A Monte Carlo solve holds the parts a Hybrid solve with these settings would: order 1 only
// with `single`, orders >= 2 only with `multiple`.
void keep_solved_parts(LightField& f, const SolveSettings& settings) {
    if (!settings.single) f.single = {};
    if (!settings.multiple) f.multiple = {};
}

}  // namespace

Method parse_method(std::string_view s, std::string_view where) {
    if (s == "hybrid") return Method::Hybrid;
    if (s == "lattice") return Method::Lattice;
    if (s == "monte_carlo") return Method::MonteCarlo;
    throw core::Error(std::string(where),
                      "\"" + std::string(s) + "\" is not one of \"hybrid\", \"lattice\", \"monte_carlo\"");
}

std::string_view to_string(Method m) noexcept {
    return m == Method::Hybrid ? "hybrid" : m == Method::Lattice ? "lattice" : "monte_carlo";
}

int static_refine_for(const scene::Scene& s, const core::Grid3<float>& density) {
    // The lattice's error grows with a hop's optical depth (docs/lattice-boltzmann.md): the
    // smallest refinement that makes a transport voxel of density 1 at most one optical depth
    // thick, else the full resolution (the static-frontier study: on the default storm, 750 m
    // lighting voxels of 3 optical depths, refine 3 takes the total error from 21-25% to 5%).
    const double tau = s.medium.extinction * density.geom.voxel_size * s.lighting_downsample;
    for (int r = 1; r <= s.lighting_downsample; ++r)
        if (s.lighting_downsample % r == 0 && tau / r <= 1.0) return r;
    return s.lighting_downsample;
}

SolveSettings solve_settings(const scene::Scene& s, const core::Grid3<float>& density) {
    SolveSettings st;
    st.single = s.effects.single_scattering;
    st.multiple = s.effects.multiple_scattering;
    st.single_options = solve::single_scattering_options(s);
    st.lattice = solve::lattice_settings(s);
    st.refine = s.transport.static_refine > 0 ? s.transport.static_refine : static_refine_for(s, density);
    st.keep_transport_grid = s.transport.static_keep_transport_grid;
    st.exact_orders = s.transport.static_exact_orders > 0 ? s.transport.static_exact_orders : 2;
    st.order2_paths = s.transport.static_order2_paths;
    st.sky_samples = s.transport.static_sky_samples;
    st.sky_paths = s.transport.static_sky_paths;
    st.seed = s.transport.mc_seed;
    if (s.transport.static_monte_carlo) {
        st.method = Method::MonteCarlo;
        st.truth_paths = s.transport.static_paths;
        st.toward = scene::static_toward(s, density.geom);  // directions "camera"; none at g = 0
    }
    // Every fine voxel of a needed lighting voxel is computed (as the bake's single scattering),
    // whichever grid S is kept on: the two differ only by the final average.
    st.single_options.skip_block = st.refine;
    return st;
}

int static_direction_count(const scene::Scene& s, const SolveSettings& settings) {
    return settings.toward ? 1 : s.effective_directions();
}

namespace {

// The density with the rain as cloud: (rho + per_extinction x sigma_rain) / divisor per voxel,
// summed in double.
core::Grid3<float> density_with_rain(const core::Grid3<float>& density, const cloud::RainField& rain,
                                     double per_extinction, double divisor = 1.0) {
    core::Grid3<float> out(density.geom, 0.0f);
    for (std::size_t i = 0; i < out.data.size(); ++i)
        out.data[i] = float((double(density.data[i]) + double(rain.extinction.data[i]) * per_extinction) / divisor);
    return out;
}

// The cloud's density with the rain as `per_extinction` density per unit of its extinction, in
// [0, 1]: where the sum passes 1 it is divided by the largest sum, `raise`, by which the medium's
// extinction is multiplied so that sigma_t is kept.
struct RaisedDensity {
    core::Grid3<float> density;
    double raise = 1.0;
};
RaisedDensity raised_density_with_rain(const core::Grid3<float>& density, const cloud::RainField& rain,
                                       double per_extinction) {
    double peak = 1.0;
    for (std::size_t i = 0; i < density.data.size(); ++i)
        peak = std::max(peak, double(density.data[i]) + double(rain.extinction.data[i]) * per_extinction);
    return {density_with_rain(density, rain, per_extinction, peak), peak};
}

// The drops' phase function in S (transport::PhaseMix): the rain's part of each cell's
// scattering coefficient, albedo x extinction of the rain against the cloud's own (not the
// similarity density the transport sees), on grids coarser than the density.
class RainPhaseMix {
public:
    RainPhaseMix(const scene::Scene& s, const core::Grid3<float>& density, const cloud::RainField& rain)
        : g_(s.rain->g), cloud_(density.geom, 0.0f), rain_(density.geom, 0.0f) {
        for (std::size_t i = 0; i < density.data.size(); ++i) {
            cloud_.data[i] = float(s.medium.albedo * s.medium.extinction * double(density.data[i]));
            rain_.data[i] = float(s.rain->albedo * double(rain.extinction.data[i]));
        }
    }
    /// The mix on the grid coarser than the density by `factor`.
    std::shared_ptr<const transport::PhaseMix> on(int factor) const {
        auto mix = std::make_shared<transport::PhaseMix>();
        mix->g = g_;
        const core::Grid3<float> c = factor > 1 ? core::downsample(cloud_, factor) : cloud_;
        mix->share = factor > 1 ? core::downsample(rain_, factor) : rain_;
        for (std::size_t i = 0; i < mix->share.data.size(); ++i) {
            const double r = double(mix->share.data[i]), sum = r + double(c.data[i]);
            mix->share.data[i] = sum > 0.0 ? float(std::min(1.0, r / sum)) : 0.0f;
        }
        return mix;
    }

private:
    double g_;
    core::Grid3<float> cloud_, rain_;  // scattering coefficients per density voxel (1/m)
};

// The full-resolution medium the Monte Carlo's paths trace when it rains: the rain at its own
// extinction (density per unit of the cloud's kappa, raised as make_static_media raises it
// where the sum passes 1) and, in each voxel, its share of the extinction, albedo and phase
// (transport::PathMix): the drops scatter as drops, not as cloud of equal transport coefficient.
transport::LightingMedium traced_rain(const scene::Scene& s, const core::Grid3<float>& density,
                                      const cloud::RainField& rain) {
    const double kappa = s.medium.extinction;
    RaisedDensity raised = raised_density_with_rain(density, rain, 1.0 / kappa);
    transport::LightingMedium m;
    m.optics = s.medium;
    m.optics.extinction = kappa * raised.raise;
    m.density = std::move(raised.density);
    auto mix = std::make_shared<transport::PathMix>();
    mix->g = s.rain->g;
    mix->albedo = s.rain->albedo;
    mix->share = core::Grid3<float>(density.geom, 0.0f);
    for (std::size_t i = 0; i < density.data.size(); ++i) {
        const double r = double(rain.extinction.data[i]), sum = r + kappa * double(density.data[i]);
        mix->share.data[i] = sum > 0.0 ? float(std::min(1.0, r / sum)) : 0.0f;
    }
    m.path_mix = std::move(mix);
    return m;
}

}  // namespace

// The cloud and, when the scene declares rain, the rain as cloud of the same transport
// coefficient (rain_media_density). Where the sum passes 1 the medium's extinction is raised
// to the largest sum and every density divided by it, so sigma_t is kept.
solve::Media make_static_media(const scene::Scene& s, const core::Grid3<float>& density, int refine, bool full,
                               const cloud::RainField* rain) {
    if (!s.rain) return solve::make_media(s, density, refine, full);
    std::optional<cloud::RainField> made;
    if (!rain) rain = &made.emplace(cloud::make_rain(density, *s.rain));
    const RaisedDensity wet = raised_density_with_rain(density, *rain, rain_media_density(s.medium, *s.rain));
    scene::Scene raised = s;
    raised.medium.extinction = s.medium.extinction * wet.raise;
    solve::Media m = solve::make_media(raised, wet.density, refine, full);
    const RainPhaseMix mix(s, density, *rain);
    m.transport.phase_mix = mix.on(s.lighting_downsample / refine);
    m.lighting.phase_mix = refine == 1 ? m.transport.phase_mix : mix.on(s.lighting_downsample);
    if (full) m.traced = traced_rain(s, density, *rain);
    return m;
}

namespace {

// The static light's media for settings `st` (solve_settings of the scene).
solve::Media media_for(const scene::Scene& s, const core::Grid3<float>& density, const SolveSettings& st, bool full,
                       const cloud::RainField* rain = nullptr) {
    solve::Media m = make_static_media(s, density, st.refine, full, rain);
    if (st.keep_transport_grid) {
        m.lighting = m.transport;
        m.refine = 1;
    }
    return m;
}

}  // namespace

double rain_media_density(const transport::Medium& cloud, const cloud::RainParams& rain) {
    FULGUR_ASSERT(cloud.extinction > 0.0, "rain_media_density: the cloud's extinction must be positive");
    return (1.0 - rain.albedo * rain.g) / (cloud.extinction * (1.0 - cloud.albedo * cloud.g));
}

solve::Media static_media(const scene::Scene& s, const core::Grid3<float>& density, bool full) {
    return media_for(s, density, solve_settings(s, density), full);
}

solve::Media static_media(const scene::Scene& s, const core::Grid3<float>& density, const cloud::RainField* rain) {
    const SolveSettings st = solve_settings(s, density);
    return media_for(s, density, st, exact_two(st) || (s.sky && st.sky_paths > 0) || st.method == Method::MonteCarlo,
                     rain);
}

LightField solve_directional(const solve::Media& media, std::span<const transport::DirectionalSource> lights,
                             std::span<const glm::dvec3> directions, const SolveSettings& settings) {
    check_media(media, settings);
    for (const transport::DirectionalSource& l : lights) check_light(l);
    LightField out;
    if (settings.method == Method::MonteCarlo) {
        // The truth's estimator per light, scaled by its irradiance and summed (linear).
        TruthOptions to;
        to.paths = settings.truth_paths;
        to.seed = settings.seed;
        to.toward = settings.toward;
        for (const transport::DirectionalSource& l : lights) {
            if (l.irradiance == 0.0) continue;
            TruthField t = sun_truth(media, l.direction, directions, to);
            if (out.empty()) {
                out = std::move(t.field);
                scale_light(out, l.irradiance);
            } else {
                add_scaled(out.single, t.field.single, l.irradiance);
                add_scaled(out.multiple, t.field.multiple, l.irradiance);
                out.seconds_single += t.field.seconds_single;
                out.seconds_multiple += t.field.seconds_multiple;
            }
        }
        keep_solved_parts(out, settings);
        return out;
    }
    if (settings.method == Method::Lattice && settings.multiple) {
        // Geist et al.: each light injected at the boundary (Appendix A), every order from
        // the lattice; several lights are solved one by one and summed (the lattice is linear).
        for (const transport::DirectionalSource& l : lights) {
            if (l.irradiance == 0.0) continue;
            transport::LbSources src;
            src.sun = l;
            transport::LbResult r =
                transport::solve_lattice_boltzmann(media.transport, src, directions, settings.lattice);
            if (out.multiple.data.empty()) {
                take_lattice(out, std::move(r));
                continue;
            }
            add_scaled(out.multiple, r.source, 1.0);
            out.iterations = std::max(out.iterations, r.iterations);
            out.converged = out.converged && r.converged;
            out.injected_per_step += r.injected_per_step;
            out.injected_total += r.injected_total;
            out.absorbed_total += r.absorbed_total;
            out.escaped_total += r.escaped_total;
            out.stored += r.stored;
            out.seconds_multiple += r.seconds;
        }
    } else {
        FirstScattered fs;
        const Processes* procs = spread(settings);
        if (procs && exact_two(settings)) {
            // Over several processes the single scattering (process 0) and the order-2 Monte
            // Carlo (process 1) run at once, each exactly as alone, and are exchanged.
            core::Stopwatch sw;
            const std::vector<glm::dvec3> dirs(directions.begin(), directions.end());
            const core::GridGeometry& geom = media.transport.density.geom;
            fs = procs->rank() == 0 ? first_scattered(media.transport, lights, directions, settings)
                                    : zeros(geom, dirs, false);
            if (procs->rank() == 1)
                second_order(media, lights, directions, settings.order2_paths, settings.seed, fs);
            else {
                fs.s2 = transport::SourceField(geom, dirs);
                fs.phi2 = core::Grid3<float>(geom, 0.0f);
            }
            procs->share(fs.s1.data, 0);
            procs->share(fs.phi1.data, 0);
            procs->share(fs.s2.data, 1);
            procs->share(fs.phi2.data, 1);
            fs.seconds = sw.seconds();
        } else {
            fs = first_scattered(media.transport, lights, directions, settings);
            if (exact_two(settings)) second_order(media, lights, directions, settings.order2_paths, settings.seed, fs);
        }
        out = hybrid(media, std::move(fs), directions, settings);
    }
    average_onto_lighting(out, media.refine);
    return out;
}

std::vector<DomeSample> dome_samples(int count) {
    FULGUR_ASSERT(count >= 1, "dome_samples: count must be >= 1");
    std::vector<DomeSample> out(static_cast<std::size_t>(count));
    const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
    for (int k = 0; k < count; ++k) {
        // z uniform in (0, 1): equal solid angles (Archimedes); azimuths on the golden spiral.
        const double z = 1.0 - (k + 0.5) / count, r = std::sqrt(std::max(0.0, 1.0 - z * z));
        const double phi = golden_angle * k;
        out[std::size_t(k)] = {{r * std::cos(phi), r * std::sin(phi), z}, 2.0 * std::numbers::pi / count};
    }
    return out;
}

SkyField solve_sky(const solve::Media& media, bool uniform, std::span<const glm::dvec3> directions,
                   const SolveSettings& settings) {
    check_media(media, settings);
    if (settings.method == Method::MonteCarlo) {
        TruthOptions to;
        to.paths = settings.truth_paths;
        to.seed = settings.seed;
        to.toward = settings.toward;
        SkyField f = sky_truth(media, uniform, directions, to).field;
        for (LightField* l : {&f.zenith, &f.horizon, &f.uniform})
            if (!l->empty()) keep_solved_parts(*l, settings);
        return f;
    }
    const std::vector<DomeSample> samples = dome_samples(settings.sky_paths > 0 ? 1 : settings.sky_samples);
    const bool two = exact_two(settings);
    // The dome's order 2: the sun's paths shared by the samples (equal solid angles).
    const std::uint64_t paths2 = std::max<std::uint64_t>(1000, settings.order2_paths / std::uint64_t(samples.size()));
    const core::GridGeometry& geom = media.transport.density.geom;
    const std::vector<glm::dvec3> dirs(directions.begin(), directions.end());
    // Each sample's exact single scattering once; both bases are weighted sums of them.
    FirstScattered z = zeros(geom, dirs, two), h = zeros(geom, dirs, two);
    auto solve_sample = [&](std::size_t k) {
        const DomeSample& d = samples[k];
        // Radiance L over a solid angle dOmega arriving from `toward`: a directional light
        // of irradiance L dOmega travelling along -toward.
        const transport::DirectionalSource light{-d.toward, d.solid_angle};
        FirstScattered one = first_scattered(media.transport, std::span(&light, 1), directions, settings);
        if (two) second_order(media, std::span(&light, 1), directions, paths2, core::hash_seed(settings.seed, k), one);
        return one;
    };
    auto add_sample = [&](std::size_t k, const FirstScattered& one) {
        const double w = uniform ? 1.0 : scene::SkyDome::zenith_weight(samples[k].toward.z);
        add_scaled(z, one, w);
        z.seconds += one.seconds;
        if (!uniform) add_scaled(h, one, 1.0 - w);
    };
    if (settings.sky_paths > 0) {
        // The dome's orders 1 and 2 by its own Monte Carlo, one run per basis. Over several
        // processes each basis runs on its own process, all at once, then they are exchanged.
        const Processes* procs = spread(settings);
        FirstScattered* out[2] = {&z, &h};
        const DomeBasis bases[2] = {uniform ? DomeBasis::Uniform : DomeBasis::Zenith, DomeBasis::Horizon};
        const std::size_t n = uniform ? 1 : 2;
        const auto owner = [&](std::size_t b) { return procs ? int(b % std::size_t(procs->size())) : 0; };
        core::Stopwatch sw;
        for (std::size_t b = 0; b < n; ++b)
            if (!procs || procs->rank() == owner(b))
                *out[b] = dome_first_scattered(media, dome_basis(bases[b]), directions, two, settings.sky_paths,
                                               core::hash_seed(settings.seed, 1000 + b));
        if (procs)
            for (std::size_t b = 0; b < n; ++b) share(*procs, *out[b], owner(b));
        // Wall time of both bases (the zenith's field carries the sky's first-scattered time).
        z.seconds = sw.seconds();
        h.seconds = 0.0;
    } else if (const Processes* procs = spread(settings)) {
        // Over p processes the samples go round by round: in each, process r solves sample
        // k0 + r, then every process receives the round's samples and adds them in sample
        // order, exactly the one-process sums.
        core::Stopwatch sw;
        const std::size_t p = std::size_t(procs->size()), me = std::size_t(procs->rank());
        std::vector<FirstScattered> batch(p);  // the other processes' samples: received into, reused
        for (std::size_t k0 = 0; k0 < samples.size(); k0 += p) {
            const std::size_t n = std::min(p, samples.size() - k0);
            for (std::size_t j = 0; j < n; ++j) {
                if (j == me)
                    batch[j] = solve_sample(k0 + j);
                else if (batch[j].s1.data.empty())
                    batch[j] = zeros(geom, dirs, two);
                batch[j].seconds = 0.0;
            }
            for (std::size_t j = 0; j < n; ++j) {
                share(*procs, batch[j], int(j));
                add_sample(k0 + j, batch[j]);
            }
        }
        z.seconds = sw.seconds();  // wall time, the exchanges included
    } else {
        for (std::size_t k = 0; k < samples.size(); ++k) add_sample(k, solve_sample(k));
    }
    SkyField out;
    LightField& first = uniform ? out.uniform : out.zenith;
    first = hybrid(media, std::move(z), directions, settings);
    average_onto_lighting(first, media.refine);
    if (!uniform) {
        out.horizon = hybrid(media, std::move(h), directions, settings);
        average_onto_lighting(out.horizon, media.refine);
    }
    return out;
}

core::Grid3<float> sun_transmittance(const core::Grid3<float>& density, double extinction,
                                     const glm::dvec3& direction) {
    const double len = glm::length(direction);
    if (!std::isfinite(len) || !(len > 0.0))
        throw core::Error("sun_transmittance: direction", "must be a finite non-zero vector");
    if (!std::isfinite(extinction) || extinction < 0.0)
        throw core::Error("sun_transmittance: extinction", "must be finite and >= 0");
    const glm::dvec3 d = direction / len;
    transport::LightingMedium m;
    m.density = density;
    m.optics.extinction = extinction;
    const core::GridGeometry& g = density.geom;
    const core::Int3 n = g.dims;
    core::Grid3<float> out(g, 1.0f);
    // Voxels the renderer reads: within one voxel of density, or on a face of the grid.
    std::vector<std::uint8_t> need(g.cell_count(), 0);
    for (int k = 0; k < n.z; ++k)
        for (int j = 0; j < n.y; ++j)
            for (int i = 0; i < n.x; ++i) {
                const bool face = i == 0 || j == 0 || k == 0 || i == n.x - 1 || j == n.y - 1 || k == n.z - 1;
                if (face) need[g.index(i, j, k)] = 1;
                if (density.at(i, j, k) <= 0.0f) continue;
                for (int c = std::max(0, k - 1); c <= std::min(n.z - 1, k + 1); ++c)
                    for (int b = std::max(0, j - 1); b <= std::min(n.y - 1, j + 1); ++b)
                        for (int a = std::max(0, i - 1); a <= std::min(n.x - 1, i + 1); ++a) need[g.index(a, b, c)] = 1;
            }
    core::parallel_for_dynamic(0, std::int64_t(n.y) * n.z, [&](std::int64_t row) {
        const int j = int(row % n.y), k = int(row / n.y);
        for (int i = 0; i < n.x; ++i) {
            const std::size_t c = g.index(i, j, k);
            if (need[c]) out.data[c] = float(std::exp(-transport::optical_depth_to_sun(m, g.centre(i, j, k), d)));
        }
    });
    return out;
}

core::Grid3<float> sun_transmittance(const scene::Scene& s, const core::Grid3<float>& density,
                                     const glm::dvec3& direction, const cloud::RainField* rain) {
    if (!s.rain) return sun_transmittance(density, s.medium.extinction, direction);
    std::optional<cloud::RainField> made;
    if (!rain) rain = &made.emplace(cloud::make_rain(density, *s.rain));
    // Rain as density of the same extinction per unit (extinction > 0: the scene's range).
    return sun_transmittance(density_with_rain(density, *rain, 1.0 / s.medium.extinction), s.medium.extinction,
                             direction);
}

StaticLight solve_static(const solve::Media& media, const glm::dvec3& sun_direction, bool sky_uniform,
                         std::span<const glm::dvec3> directions, const SolveSettings& settings) {
    const transport::DirectionalSource unit{sun_direction, 1.0};
    StaticLight out;
    out.sun = solve_directional(media, std::span(&unit, 1), directions, settings);
    out.sun_direction = sun_direction;
    out.sky = solve_sky(media, sky_uniform, directions, settings);
    return out;
}

}  // namespace fulgur::sky
