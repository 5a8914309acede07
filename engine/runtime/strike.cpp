// Per-strike light (runtime.h, docs/presets.md): a strike's strokes solved once, as exact
// line sources, and the worker thread that solves strikes ahead of their frames.
#include "runtime/runtime.h"
#include "transport/ground_dome.h"

#include <glm/geometric.hpp>

#include <algorithm>
#include <condition_variable>
#include <exception>
#include <map>
#include <mutex>
#include <utility>

namespace fulgur::runtime {

namespace {

constexpr std::uint32_t kMain = 0, kBranch = 1;

transport::LightingMedium full_resolution(const scene::Scene& s, const core::Grid3<float>& density) {
    transport::LightingMedium m;
    m.density = density;
    m.optics = s.medium;
    return m;
}

}  // namespace

std::vector<transport::LineSource> strike_line_sources(const lightning::Bolt& bolt) {
    std::vector<transport::LineSource> lines;
    lines.reserve(bolt.segments.size());
    for (const lightning::Segment& g : bolt.segments)
        if (g.intensity > 0.0) lines.push_back({g.a, g.b, g.intensity, g.depth == 0 ? kMain : kBranch});
    return lines;
}

StrikeSolveOptions strike_solve_options(const scene::Quality& q) {
    StrikeSolveOptions o;
    o.single_paths = q.single_paths;
    o.multiple = q.multiple == "lattice"       ? StrikeSolveOptions::Multiple::Lattice
                 : q.multiple == "monte_carlo" ? StrikeSolveOptions::Multiple::MonteCarlo
                                               : StrikeSolveOptions::Multiple::None;
    o.multiple_paths = q.multiple_paths;
    o.keep_transport_grid = q.keep_transport_grid;
    return o;
}

std::optional<transport::GroundTally> strike_ground(const scene::Scene& scene, const core::GridGeometry& lighting) {
    return scene::strike_ground_cells(scene, lighting);
}

StrikeLight solve_strike(const scene::Scene& scene, const core::Grid3<float>& density, const solve::Media& media,
                         const lightning::Bolt& bolt, const StrikeSolveOptions& options) {
    StrikeLight out;
    const std::vector<glm::dvec3> dirs = transport::output_directions(scene.effective_directions());
    // Toward the camera: one field tallied (each voxel's own direction to the camera) and kept
    // as one; the frame adds it into every output direction (StrikeLight::direction), so
    // whatever direction the renderer interpolates toward the camera reads that field.
    const std::vector<glm::dvec3> one = transport::output_directions(1);
    const std::vector<glm::dvec3>& tallied_dirs = options.toward ? one : dirs;
    const core::GridGeometry& lighting = media.lighting.density.geom;
    const core::GridGeometry& grid = media.transport.density.geom;  // where the lattice runs
    const std::vector<transport::LineSource> lines = strike_line_sources(bolt);
    const bool lattice = options.multiple == StrikeSolveOptions::Multiple::Lattice && scene.effects.multiple_scattering;
    const bool mc = options.multiple == StrikeSolveOptions::Multiple::MonteCarlo && scene.effects.multiple_scattering;
    // The paths' medium: the media's own full-resolution one where they carry it (with rain,
    // the rain in it: sky::make_static_media), else the density. Where the paths are the light
    // (mc) the rain is traced as drops (solve::traced_medium); where they feed the lattice, as
    // the lattice carries it.
    const bool own_fine = media.full.density.data.empty();
    const transport::LightingMedium made = own_fine ? full_resolution(scene, density) : transport::LightingMedium{};
    const transport::LightingMedium& fine = own_fine ? made : mc ? solve::traced_medium(media) : media.full;
    FULGUR_ASSERT(!(options.toward && lattice),
                  "solve_strike: the lattice solves fixed directions, not toward a point");

    // Single scattering (and the uncollided fluence the lattice needs), per group, on the
    // transport grid.
    // With transport.lattice_boltzmann.exact_orders 2 the same paths also give order 2 (the
    // expected-value second flight) and its fluence: the lattice then solves orders >= 3.
    const bool order2 = lattice && scene.transport.lb_exact_orders == 2;
    transport::MonteCarloOptions so;
    so.paths = options.single_paths;
    so.seed = options.seed;
    so.max_scatterings = order2 ? 1 : 0;
    so.tally_multiple = order2;
    so.expected_second_order = order2;
    so.uncollided_only = !order2;
    so.groups = 2;
    so.batches = 8;  // each batch costs a pass over the fields: few, the halves need >= 4
    so.halves = true;
    so.tally_fluence = lattice;
    so.toward = options.toward;
    so.phase_mix = media.transport.phase_mix.get();  // the drops' phase function where it rains
    core::Stopwatch sw;
    transport::MonteCarloResult s1 = transport::monte_carlo(fine, {}, lines, grid, tallied_dirs, so);
    out.seconds_single = sw.seconds();
    out.noise.single = s1.noise.single;
    const bool empty = s1.groups.empty();  // no lit segment: all zero
    const bool keep = options.keep_transport_grid;
    const transport::SourceField zero = empty ? transport::SourceField(grid, tallied_dirs) : transport::SourceField{};
    for (std::uint32_t q = 0; q < 2; ++q) {
        const transport::SourceField& tallied = empty ? zero : s1.groups[q].single;
        out.single[q] = transport::block_average(tallied, media.refine);
        if (keep) out.fine_single[q] = tallied;
    }

    sw.reset();
    if (lattice) {
        for (std::uint32_t q = 0; q < 2; ++q) {
            const bool dark = empty || std::all_of(s1.groups[q].fluence.data.begin(), s1.groups[q].fluence.data.end(),
                                                   [](float v) { return v == 0.0f; });
            if (dark) {  // no branches, or no light reaches the cloud
                out.multiple[q] = transport::SourceField(lighting, dirs);
                if (keep) out.fine_multiple[q] = transport::SourceField(grid, dirs);
                continue;
            }
            const transport::MonteCarloResult::Group& part = s1.groups[q];
            transport::LbSources src;
            src.first_scattered = order2 ? &part.multiple : &part.single;
            src.first_scattered_fluence = order2 ? &part.fluence2 : &part.fluence;
            transport::LbResult r =
                transport::solve_lattice_boltzmann(media.transport, src, dirs, solve::lattice_settings(scene));
            if (order2)
                for (std::size_t i = 0; i < r.source.data.size(); ++i) r.source.data[i] += part.multiple.data[i];
            out.multiple[q] = transport::block_average(r.source, media.refine);
            if (keep) out.fine_multiple[q] = std::move(r.source);
        }
    } else if (mc) {
        transport::MonteCarloOptions mo;
        mo.paths = options.multiple_paths;
        mo.seed = core::hash_seed(options.seed, 2);
        mo.groups = 2;
        mo.batches = 8;
        mo.halves = true;
        // Tallied where it is kept: block averages of transport-grid tallies are the lighting
        // grid's tallies (the same paths, summed per lighting voxel).
        const core::GridGeometry& tally = keep ? grid : lighting;
        mo.toward = options.toward;
        mo.ground = options.ground;
        mo.phase_mix = (keep ? media.transport : media.lighting).phase_mix.get();
        const transport::MonteCarloResult r = transport::monte_carlo(fine, {}, lines, tally, tallied_dirs, mo);
        if (options.ground)
            for (std::uint32_t q = 0; q < 2; ++q)
                out.ground[q] = r.groups.empty()
                                    ? transport::GroundIrradiance{*options.ground,
                                                                  std::vector<float>(options.ground->cells(), 0.0f)}
                                    : r.groups[q].ground;
        for (std::uint32_t q = 0; q < 2; ++q) {
            transport::SourceField m =
                r.groups.empty() ? transport::SourceField(tally, tallied_dirs) : r.groups[q].multiple;
            if (!keep) {
                out.multiple[q] = std::move(m);
                continue;
            }
            out.multiple[q] = transport::block_average(m, media.refine);
            out.fine_multiple[q] = std::move(m);
        }
        out.noise.multiple = r.noise.multiple;  // per voxel of the tally's grid
    }
    out.seconds_multiple = sw.seconds();
    sw.reset();
    // Without a Monte Carlo of the multiple scattering to tally it, the ground's light is
    // gathered from the strike's S (rays up from each cell) where that S is all of it: the
    // lattice's (single + multiple) or single scattering alone in a scene without multiple
    // scattering. The hybrid preset's
    // strokes take their multiple scattering from the bases, which carry no ground: none then.
    // Not toward the camera either: that S is the light toward one point, not toward the ground.
    const bool complete = lattice || !scene.effects.multiple_scattering;
    if (options.ground && !mc && complete && !options.toward) {
        std::vector<std::vector<const transport::SourceField*>> groups(2);
        for (std::uint32_t q = 0; q < 2; ++q) {
            groups[q] = {&out.single[q]};
            if (out.has_multiple()) groups[q].push_back(&out.multiple[q]);
        }
        transport::DomeGround g = transport::ground_dome(media.lighting, groups, {}, *options.ground);
        for (std::uint32_t q = 0; q < 2; ++q) out.ground[q] = std::move(g.groups[q]);
    }
    out.seconds_ground = sw.seconds();
    return out;
}

// =======================================================================================
// StrikeSolver

struct StrikeSolver::Impl {
    using Key = std::pair<std::uint64_t, double>;
    struct Entry {
        std::shared_ptr<const StrikeLight> light;
        std::exception_ptr error;
        bool done = false;
        core::Stopwatch requested;
    };
    const scene::Scene& scene;
    const core::Grid3<float>& density;
    const solve::Media& media;
    StrikeSolveOptions options;

    mutable std::mutex mu;
    std::condition_variable done_cv;
    std::map<Key, Entry> entries;
    std::vector<double> latencies;
    core::Worker worker;  // last: its jobs use the members above until it is joined

    Impl(const scene::Scene& s, const core::Grid3<float>& d, const solve::Media& m, const StrikeSolveOptions& o, int t)
        : scene(s), density(d), media(m), options(o), worker(t) {}

    void solve(const Key& key, const lightning::Bolt& bolt) {
        std::shared_ptr<const StrikeLight> light;
        std::exception_ptr error;
        try {
            StrikeSolveOptions o = options;
            o.seed = core::hash_seed(options.seed, key.first);
            light = std::make_shared<const StrikeLight>(solve_strike(scene, density, media, bolt, o));
        } catch (...) {
            error = std::current_exception();
        }
        {
            std::lock_guard<std::mutex> lock(mu);
            const auto it = entries.find(key);
            if (it != entries.end()) {  // not forgotten meanwhile
                it->second.light = std::move(light);
                it->second.error = error;
                it->second.done = true;
                latencies.push_back(it->second.requested.seconds());
            }
        }
        done_cv.notify_all();
    }
};

StrikeSolver::StrikeSolver(const scene::Scene& scene, const core::Grid3<float>& density, const solve::Media& media,
                           const StrikeSolveOptions& options, int threads) {
    FULGUR_ASSERT(threads >= 1, "StrikeSolver: threads must be >= 1");
    impl_ = std::make_unique<Impl>(scene, density, media, options, threads);
}

StrikeSolver::~StrikeSolver() = default;

void StrikeSolver::request(std::uint64_t seed, double time, const lightning::Bolt& bolt) {
    Impl& im = *impl_;
    const Impl::Key key{seed, time};
    {
        std::lock_guard<std::mutex> lock(im.mu);
        if (im.entries.count(key)) return;
        im.entries[key];
    }
    im.worker.submit([&im, key, bolt] { im.solve(key, bolt); });
}

std::shared_ptr<const StrikeLight> StrikeSolver::get(std::uint64_t seed, double time) const {
    std::lock_guard<std::mutex> lock(impl_->mu);
    const auto it = impl_->entries.find({seed, time});
    return it == impl_->entries.end() ? nullptr : it->second.light;
}

std::shared_ptr<const StrikeLight> StrikeSolver::wait(std::uint64_t seed, double time) {
    Impl& im = *impl_;
    std::unique_lock<std::mutex> lock(im.mu);
    const auto it = im.entries.find({seed, time});
    FULGUR_ASSERT(it != im.entries.end(), "StrikeSolver::wait: the strike was not requested");
    im.done_cv.wait(lock, [&] { return it->second.done; });
    if (it->second.error) std::rethrow_exception(it->second.error);
    return it->second.light;
}

void StrikeSolver::set_paused(bool paused) { impl_->worker.set_paused(paused); }

void StrikeSolver::forget_before(double time) {
    std::lock_guard<std::mutex> lock(impl_->mu);
    for (auto it = impl_->entries.begin(); it != impl_->entries.end();)
        if (it->first.second < time && it->second.done)
            it = impl_->entries.erase(it);
        else
            ++it;
}

std::vector<double> StrikeSolver::latencies() const {
    std::lock_guard<std::mutex> lock(impl_->mu);
    return impl_->latencies;
}

}  // namespace fulgur::runtime
