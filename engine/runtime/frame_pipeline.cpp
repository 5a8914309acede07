// The FramePipeline (runtime.h): a storm's frame at time t, from the strike schedule to S on
// the lighting grid, by the bases alone (the paper preset) or with the strikes' own solved
// light where it is ready.
#include "runtime/runtime.h"
#include "sky/sky.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <utility>

namespace fulgur::runtime {

struct FramePipeline::Impl {
    lightning::Storm storm;
    lightning::Splatter splatter;
    Reconstructor reconstructor;
    Frame frame;
    scene::Quality quality;
    // Presets that solve strikes (the solver keeps references to the scene and the media).
    scene::Scene solve_scene;
    // `media` holds the rain when the scene declares it (sky::make_static_media, the rain as
    // cloud of equal transport coefficient, S at its points with the drops' phase function):
    // the strikes solved ahead light the rain (Frame::rain), and the rain scatters their light
    // back into the cloud and onto the ground. The instant path's near-field correction and its
    // blend with the bases, which hold no rain, are over the cloud alone (`dry_media`, only made
    // when `media` holds rain); its tracers trace the rain themselves
    // (InstantStrikes::traces_rain), so its strikes light the rain too.
    std::optional<solve::Media> media, dry_media;
    const solve::Media& instant_media() const { return dry_media ? *dry_media : *media; }
    std::unique_ptr<StrikeSolver> solver;
    std::unique_ptr<InstantStrikes> instant;
    std::set<std::pair<std::uint64_t, double>> unscheduled;  // strike_at(..., known_ahead = false)
    // The instant preset's shown light of each active strike's strokes: `light` (its own
    // estimate's share, at unit glow) plus `bases` x the bases' frame. Each frame moves it
    // toward the latest estimate (weight w: w M + (1 - w) bases) by at most
    // quality.max_change_per_frame of the shown light (relative L2 over the cloud).
    struct Shown {
        std::shared_ptr<const StrikeEstimate> target;
        std::shared_ptr<StrikeLight> light;  // null: nothing of the estimate yet
        std::vector<float> total;            // light's single + multiple over the groups, [m][cell]
        double bases = 1.0;
        bool settled = false;  // equal to the target's blend: nothing to move
    };
    std::map<std::pair<std::uint64_t, double>, Shown> shown;
    std::vector<lightning::LitSegment> basis_segments, multiple_segments;  // what the bases light
    std::vector<transport::PointSource> basis_sources, multiple_sources;
    lightning::LightWeights multiple_weights;
    RadianceField multiple_radiance;
    double forgotten_before = -1e300;
    bool keep_fine = false;  // solved strikes kept on a transport grid finer than the lighting grid

    const scene::Scene* scene;
    const core::Grid3<float>* density;

    const BakedBases* bases;

    Impl(const scene::Scene& s, const core::Grid3<float>& d, const BakedBases& b, std::optional<lightning::Box> domain,
         const scene::Quality& q)
        : storm(s.lightning, d, domain), splatter(b.lights()), reconstructor(b), scene(&s), density(&d), bases(&b) {
        set_quality(q);
    }

    void set_quality(const scene::Quality& q) {
        const scene::Scene& s = *scene;
        solver.reset();  // joins the workers: nothing refers to the old media any more
        instant.reset();
        shown.clear();
        media.reset();
        dry_media.reset();
        quality = q;
        keep_fine = false;
        if (q.preset == scene::Quality::Preset::Paper) return;
        solve_scene = s;  // the per-strike transport grid may be finer than the bake's
        solve_scene.transport.refine = scene::strike_refine(s, q);
        if (q.exact_orders > 0) solve_scene.transport.lb_exact_orders = q.exact_orders;
        media = solve::make_media(solve_scene, *density);
        // With rain, the strikes' media hold it, the instant way's too (its tracers'; made once).
        if (solve_scene.rain) {
            dry_media = std::move(media);
            media = sky::make_static_media(solve_scene, *density, solve_scene.transport.refine, true);
        }
        if (q.preset == scene::Quality::Preset::Instant) {
            make_instant(q);
            return;
        }
        // The worker takes one core less than the frame's share, at least one.
        // Keeping the strikes on the transport grid means something only where it is finer.
        keep_fine = q.keep_transport_grid && media->refine > 1;
        StrikeSolveOptions so = strike_solve_options(q);
        so.keep_transport_grid = keep_fine;
        so.toward = scene::strike_toward(s, q, density->geom);  // quality "directions": "camera"
        so.ground = strike_ground(s, media->lighting.density.geom);
        solver =
            std::make_unique<StrikeSolver>(solve_scene, *density, *media, so, std::max(1, core::thread_count() - 1));
        if (!unscheduled.empty()) make_instant(scene::quality_preset("instant"));
    }

    // The progressive solver (the instant preset's, or the one unscheduled strikes take under
    // a preset that solves ahead). Every core: a frame costs about a millisecond of the frame
    // thread, and the first estimate's latency is the first round's paths over the cores.
    void make_instant(const scene::Quality& q) {
        instant = std::make_unique<InstantStrikes>(solve_scene, *density, instant_media(), bases, instant_options(q),
                                                   core::thread_count(), dry_media ? &*media : nullptr);
    }

    // Whether the strike is lit the instant way.
    bool lit_instantly(const lightning::Strike& k) const {
        return instant && (quality.preset == scene::Quality::Preset::Instant || unscheduled.count({k.seed, k.time}));
    }

    // The frame's per-build fields reset; its buffers (segments, sources, weights, radiance)
    // kept for reuse.
    Frame& begin_frame(double t) {
        frame.time = t;
        frame.lit = false;
        frame.times = {};
        frame.strikes_solved = frame.strikes_fallback = frame.strikes_instant = 0;
        frame.instant_weight = 1.0;
        frame.ground.data.clear();
        frame.rain.values.clear();
        frame.rain.directions.clear();
        return frame;
    }
    // A solved strike's light in a frame, scaled by its glow (and, instant, by its weight).
    struct Lit {
        std::shared_ptr<const StrikeLight> light;
        double main = 0.0, branch = 0.0;
        bool rain = false;        // solved with the rain in its media: its multiple S lights the rain
        double rain_scale = 1.0;  // its multiple S at the rain is `light`'s times this
    };
    // The solved strikes' ground tallies, each group scaled by its glow, into the frame's
    // (every strike of the scene is tallied on the same cells: strike_ground()).
    static void add_ground(const std::vector<Lit>& solved, transport::GroundIrradiance& out) {
        for (const Lit& l : solved) {
            const double w[2] = {l.main, l.branch};
            for (std::size_t q = 0; q < 2; ++q) {
                const transport::GroundIrradiance& g = l.light->ground[q];
                if (g.empty() || !(w[q] != 0.0)) continue;
                if (out.empty()) out = {g.cells, std::vector<float>(g.data.size(), 0.0f)};
                FULGUR_ASSERT(out.data.size() == g.data.size(), "FramePipeline: strikes' ground tallies differ");
                for (std::size_t i = 0; i < g.data.size(); ++i) out.data[i] += float(w[q]) * g.data[i];
            }
        }
    }
    // An instant strike's bases' share of its strokes, from the bases' frame its worker made
    // once per group (StrikeEstimate::bases_groups), scaled by share x glow.
    struct BasesShare {
        std::shared_ptr<const std::array<std::vector<float>, 2>> groups;
        double main = 0.0, branch = 0.0;
    };
    std::vector<BasesShare> shares;
    // An instant strike's near-field correction (InstantStrikes::near_field: the part of its
    // bases' frame the splat cannot carry) where the frame does not take it from the worker's
    // bases' frame per group, scaled by the bases' share x glow; the components the frame asks.
    struct NearShare {
        std::shared_ptr<const std::array<NearFieldParts, 2>> parts;
        double main = 0.0, branch = 0.0;
    };
    std::vector<NearShare> near_shares;
    void add_instant(const lightning::Strike& k, const lightning::Bolt& bolt, double t,
                     const ReconstructOptions& options, std::vector<Lit>& solved);
    void move_toward_target(Shown& s, double step);
    const Frame& build_paper(double t, std::span<const int> directions, const ReconstructOptions& options);
    const Frame& build_solved(double t, std::span<const int> directions, const ReconstructOptions& options);
    void add_rain_light(const std::vector<Lit>& solved, const ReconstructOptions& options);
};

FramePipeline::FramePipeline(const scene::Scene& scene, const core::Grid3<float>& density, const BakedBases& bases,
                             std::optional<lightning::Box> domain, std::optional<scene::Quality> quality)
    : impl_(std::make_unique<Impl>(scene, density, bases, domain, quality ? *quality : scene.quality)) {}
FramePipeline::~FramePipeline() = default;

std::size_t FramePipeline::strike_at(double t, std::optional<std::uint64_t> seed, bool known_ahead) {
    Impl& im = *impl_;
    const std::size_t i = im.storm.strike_at(t, seed);
    if (!known_ahead && im.quality.preset != scene::Quality::Preset::Paper) {
        const lightning::Strike& k = im.storm.strike(i);
        im.unscheduled.insert({k.seed, k.time});
        if (!im.instant) im.make_instant(scene::quality_preset("instant"));
        // Known now: its tracing starts now, not at the next frame that lights it.
        im.instant->request(k.seed, k.time, im.storm.bolt(i));
    }
    return i;
}

lightning::Storm& FramePipeline::storm() noexcept { return impl_->storm; }
const scene::Quality& FramePipeline::quality() const noexcept { return impl_->quality; }
StrikeSolver* FramePipeline::strike_solver() noexcept { return impl_->solver.get(); }
InstantStrikes* FramePipeline::instant_strikes() noexcept { return impl_->instant.get(); }
void FramePipeline::set_quality(const scene::Quality& q) { impl_->set_quality(q); }

const Frame& FramePipeline::build(double t, std::span<const int> directions, const ReconstructOptions& options) {
    return impl_->solver || impl_->instant ? impl_->build_solved(t, directions, options)
                                           : impl_->build_paper(t, directions, options);
}

const Frame& FramePipeline::Impl::build_paper(double t, std::span<const int> directions,
                                              const ReconstructOptions& options) {
    Frame& f = begin_frame(t);
    core::Stopwatch sw;
    const bool glowing = storm.lit(t, f.segments);  // schedule (new bolts), active strikes, lit stretches
    f.times.bolt = sw.milliseconds();
    if (!glowing) {
        f.sources.clear();
        if (!f.weights.active.empty()) splatter.reset(f.weights);  // sparse: last frame's lights only
        return f;
    }
    // Storm::point_sources(t, spacing) is lit(t) + append_point_sources: the stretches are
    // already here, so only the second half runs (same sources, bit for bit).
    sw.reset();
    f.sources.clear();
    lightning::append_point_sources(f.segments, splatter.source_spacing(), f.sources);
    f.times.sources = sw.milliseconds();
    sw.reset();
    splatter.splat(f.sources, f.weights);
    f.times.splat = sw.milliseconds();
    f.lit = reconstructor.reconstruct(f.weights, directions, options, f.radiance, f.times);
    return f;
}

// The instant preset's strike: its strokes' light from its latest estimate with weight w (the
// estimate's against the bases, cross-faded from the previous estimate so the shown light
// changes by at most quality.max_change_per_frame per build while the strokes glow, at once
// while they are dark) and from the bases with 1 - w;
// its leaders from the bases. No estimate yet: the bases alone, as a strike whose solve is
// not ready.
void FramePipeline::Impl::add_instant(const lightning::Strike& k, const lightning::Bolt& bolt, double t,
                                      const ReconstructOptions& options, std::vector<Lit>& solved) {
    Frame& f = frame;
    const lightning::FlashState st = lightning::flash_state(k.profile, storm.params().timing, t - k.time);
    Shown& s = shown[{k.seed, k.time}];
    const std::shared_ptr<const StrikeEstimate> latest =
        options.wait_for_strikes ? instant->wait_final(k.seed, k.time) : instant->get(k.seed, k.time);
    if (latest && latest != s.target) {
        s.target = latest;
        s.settled = false;
    }
    // While the strokes are dark (the stepped leader before the first return stroke, the
    // leaders and gaps before later ones) the shown light is drawn at zero glow: it settles
    // on the latest estimate at once, and the next stroke starts from it with no visible step.
    const bool strokes_dark = !(st.main_glow > 0.0) && !(st.branch_glow > 0.0);
    if (s.target && !s.settled)
        move_toward_target(s, options.wait_for_strikes || strokes_dark ? 1e300 : quality.max_change_per_frame);
    if (!s.light) {
        lightning::lit_segments(bolt, st, basis_segments);
        // The bases' frame of the strokes as every estimate carries it: with its near-field
        // correction.
        if (auto near = instant->near_field(k.seed, k.time))
            near_shares.push_back({std::move(near), st.main_glow, st.branch_glow});
        ++f.strikes_fallback;
        f.instant_weight = 0.0;
        return;
    }
    ++f.strikes_solved;
    ++f.strikes_instant;
    f.instant_weight = std::min(f.instant_weight, 1.0 - s.bases);
    // At the rain the bases carry no light: there the estimates' light, which s.light holds
    // with their share 1 - s.bases, is weighed against none (StrikeEstimate::rain_weight). A
    // share under 1e-3 (the estimates discarded) is not scaled up: the rain is then unlit.
    const double estimates_share = 1.0 - s.bases;
    const double rain_scale = estimates_share >= 1e-3 ? s.target->rain_weight() / estimates_share : 0.0;
    solved.push_back({s.light, st.main_glow, st.branch_glow, instant->traces_rain(), rain_scale});
    // The strokes' share of the bases: from the worker's bases' frame of each group when it
    // holds what this frame asks for (both components, no ambient term: how it was made), so
    // the frame reconstructs only the leaders; else splatted and reconstructed with them.
    const auto& groups = s.target->bases_groups;
    if (groups && options.components.single && options.components.multiple && options.ambient == Ambient::None) {
        lightning::lit_segments(bolt, lightning::split_leaders(st).leaders, basis_segments);
        if (s.bases > 0.0) shares.push_back({groups, s.bases * st.main_glow, s.bases * st.branch_glow});
        return;
    }
    lightning::FlashState bases_part = st;  // the leaders, and the strokes' share of the bases
    bases_part.main_glow *= s.bases;
    bases_part.branch_glow *= s.bases;
    lightning::lit_segments(bolt, bases_part, basis_segments);
    if (s.bases > 0.0)
        if (auto near = instant->near_field(k.seed, k.time))
            near_shares.push_back({std::move(near), s.bases * st.main_glow, s.bases * st.branch_glow});
}

// One frame's step of a strike's shown light toward its target's blend w M + (1 - w) B: the
// whole way when the change is at most `step` of the target's norm, else that much of it.
void FramePipeline::Impl::move_toward_target(Shown& s, double step) {
    const StrikeEstimate& e = *s.target;
    const double w = e.weight();
    const std::vector<float>& rho = instant_media().lighting.density.data;
    const std::size_t cells = rho.size(), n = e.total.size();
    const std::vector<float>* B = e.bases && e.bases->size() == n ? e.bases.get() : nullptr;
    if (!s.light) {  // start from the bases alone
        s.light = std::make_shared<StrikeLight>(e.light);
        for (std::uint32_t q = 0; q < 2; ++q) {
            std::fill(s.light->single[q].data.begin(), s.light->single[q].data.end(), 0.0f);
            std::fill(s.light->multiple[q].data.begin(), s.light->multiple[q].data.end(), 0.0f);
            std::fill(s.light->ground[q].data.begin(), s.light->ground[q].data.end(), 0.0f);
        }
        s.total.assign(n, 0.0f);
        s.bases = 1.0;
    }
    // |target - shown| and |target| over the cloud, every direction.
    double d2 = 0.0, t2 = 0.0;
    for (std::size_t m0 = 0; m0 < n; m0 += cells)
        for (std::size_t c = 0; c < cells; ++c) {
            if (!(rho[c] > 0.0f)) continue;
            const std::size_t i = m0 + c;
            const double b = B ? double((*B)[i]) : 0.0;
            const double target = w * double(e.total[i]) + (1.0 - w) * b;
            const double shown_now = double(s.total[i]) + s.bases * b;
            d2 += (target - shown_now) * (target - shown_now);
            t2 += target * target;
        }
    const double a = d2 > 0.0 ? std::min(1.0, step * std::sqrt(t2 / d2)) : 1.0;
    const auto lerp = [a](std::vector<float>& x, const std::vector<float>& y, double wy) {
        for (std::size_t i = 0; i < x.size(); ++i) x[i] = float(double(x[i]) + a * (wy * double(y[i]) - double(x[i])));
    };
    for (std::uint32_t q = 0; q < 2; ++q) {
        lerp(s.light->single[q].data, e.light.single[q].data, w);
        lerp(s.light->multiple[q].data, e.light.multiple[q].data, w);
        // The ground's scattered light moves with the S it comes from (the bases carry none).
        if (s.light->ground[q].data.size() == e.light.ground[q].data.size())
            lerp(s.light->ground[q].data, e.light.ground[q].data, w);
    }
    lerp(s.total, e.total, w);
    s.bases += a * ((1.0 - w) - s.bases);
    s.settled = a >= 1.0;
}

namespace {

// Adds b's values into a (same directions), or copies b when a holds nothing yet.
void add_radiance(RadianceField& a, bool& a_valid, const RadianceField& b) {
    if (!a_valid) {
        a = b;
        a_valid = true;
        return;
    }
    for (std::size_t k = 0; k < a.values.size(); ++k)
        for (std::size_t i = 0; i < a.values[k].size(); ++i) a.values[k][i] += b.values[k][i];
}

}  // namespace

// A strike whose solve is ready lights the frame with its strokes' light scaled by the
// flash's glow; its leaders (and, in the hybrid preset, its strokes' multiple scattering)
// still come from the bases. A strike whose solve is not ready is lit by the bases entirely
// (the paper frame), never by another strike's light.
const Frame& FramePipeline::Impl::build_solved(double t, std::span<const int> directions,
                                               const ReconstructOptions& options) {
    Frame& f = begin_frame(t);
    core::Stopwatch sw;
    // Strikes starting soon are queued now, so their light is ready by their frames.
    const auto request = [&](std::size_t i) {
        const lightning::Strike& k = storm.strike(i);
        if (lit_instantly(k))
            instant->request(k.seed, k.time, storm.bolt(i));
        else
            solver->request(k.seed, k.time, storm.bolt(i));
    };
    for (const std::size_t i : storm.starting(t - 1.0, t + quality.lookahead)) {
        const lightning::Strike& k = storm.strike(i);
        if (k.end() > t)
            request(i);
        else if (lit_instantly(k))  // its flash is over: no more paths for it
            instant->stop(k.seed, k.time);
    }
    // Keep a minute of solved strikes; 5 s when each holds its light on the transport grid
    // (tens of MB a strike: scene::Cost::strike_light_bytes), still longer than any flash.
    const double keep_seconds = keep_fine ? 5.0 : 60.0;
    if (t - keep_seconds > forgotten_before) {
        forgotten_before = t - keep_seconds;
        if (instant) instant->forget_before(forgotten_before);
        if (solver) solver->forget_before(forgotten_before);
        const auto old = [&](const auto& key) { return key.second < forgotten_before; };
        std::erase_if(shown, [&](const auto& kv) { return old(kv.first); });
        std::erase_if(unscheduled, old);
    }
    const bool glowing = storm.lit(t, f.segments);
    f.sources.clear();
    basis_segments.clear();
    multiple_segments.clear();
    std::vector<Lit> solved;
    shares.clear();
    near_shares.clear();
    if (glowing) {
        const std::vector<std::size_t> active(storm.active(t).begin(), storm.active(t).end());
        for (const std::size_t i : active) {
            const lightning::Strike& k = storm.strike(i);
            request(i);
            if (lit_instantly(k)) {
                add_instant(k, storm.bolt(i), t, options, solved);
                continue;
            }
            std::shared_ptr<const StrikeLight> light =
                options.wait_for_strikes ? solver->wait(k.seed, k.time) : solver->get(k.seed, k.time);
            const lightning::FlashState st = lightning::flash_state(k.profile, storm.params().timing, t - k.time);
            if (!light) {
                lightning::lit_segments(storm.bolt(i), st, basis_segments);
                ++f.strikes_fallback;
                continue;
            }
            ++f.strikes_solved;
            solved.push_back({light, st.main_glow, st.branch_glow, dry_media.has_value()});
            const lightning::FlashParts parts = lightning::split_leaders(st);
            lightning::lit_segments(storm.bolt(i), parts.leaders, basis_segments);  // bases, both components
            if (!light->has_multiple())  // hybrid: the strokes' multiple scattering from the bases
                lightning::lit_segments(storm.bolt(i), parts.strokes, multiple_segments);
        }
    }
    add_ground(solved, f.ground);
    f.times.bolt = sw.milliseconds();
    if (!glowing) {
        if (!f.weights.active.empty()) splatter.reset(f.weights);
        return f;
    }
    sw.reset();
    lightning::append_point_sources(f.segments, splatter.source_spacing(), f.sources);  // the whole frame's
    basis_sources.clear();
    multiple_sources.clear();
    lightning::append_point_sources(basis_segments, splatter.source_spacing(), basis_sources);
    lightning::append_point_sources(multiple_segments, splatter.source_spacing(), multiple_sources);
    f.times.sources = sw.milliseconds();
    sw.reset();
    splatter.splat(basis_sources, f.weights);
    splatter.splat(multiple_sources, multiple_weights);
    f.times.splat = sw.milliseconds();

    bool valid = reconstructor.reconstruct(f.weights, directions, options, f.radiance, f.times);
    if (options.components.multiple && !multiple_weights.empty()) {
        ReconstructOptions mo = options;
        mo.components = {false, true};
        StageTimes mt;
        if (reconstructor.reconstruct(multiple_weights, directions, mo, multiple_radiance, mt))
            add_radiance(f.radiance, valid, multiple_radiance);
        f.times.accumulate += mt.accumulate;
        f.times.inverse_haar += mt.inverse_haar;
    }

    // The solved strikes' light and the bases' shares kept per strike, for the directions the
    // frame holds. `lighting_part`: the lighting grid holds light other than the strikes kept
    // on the transport grid (the bases', the shares', a strike's on the lighting grid).
    const bool lighting_part =
        valid || !shares.empty() || !near_shares.empty() ||
        std::any_of(solved.begin(), solved.end(), [](const Lit& l) { return !l.light->has_fine(); });
    sw.reset();
    if (!solved.empty() || !shares.empty() || !near_shares.empty()) {
        const core::GridGeometry& g = media->lighting.density.geom;
        const std::size_t cells = g.cell_count();
        // The frame holds all the scene's output directions, as the worker's estimates do; a
        // strike tallied toward the camera holds one, which serves them all (StrikeLight).
        const std::size_t nd = std::size_t(solve_scene.effective_directions());
        if (!valid) {  // nothing from the bases: start from zero on the requested directions
            f.radiance.geometry = g;
            f.radiance.direction_count = int(nd);
            f.radiance.directions.clear();
            if (directions.empty())
                for (std::size_t m = 0; m < nd; ++m) f.radiance.directions.push_back(int(m));
            else
                f.radiance.directions.assign(directions.begin(), directions.end());
            f.radiance.values.assign(f.radiance.directions.size(), std::vector<float>(cells, 0.0f));
            f.radiance.components = options.components;
            valid = true;
        }
        for (std::size_t k = 0; k < f.radiance.directions.size(); ++k) {
            const std::size_t m = std::size_t(f.radiance.directions[k]);
            float* out = f.radiance.values[k].data();
            const auto add = [out, cells](float w, const float* a) {
                if (w != 0.0f)
                    for (std::size_t i = 0; i < cells; ++i) out[i] += w * a[i];
            };
            for (const Lit& l : solved) {
                const StrikeLight& L = *l.light;
                if (L.has_fine()) continue;  // added below, on both grids
                const float w[2] = {float(l.main), float(l.branch)};
                for (std::size_t q = 0; q < 2; ++q) {
                    if (options.components.single) add(w[q], StrikeLight::direction(L.single[q], m).data());
                    if (options.components.multiple && L.has_multiple())
                        add(w[q], StrikeLight::direction(L.multiple[q], m).data());
                }
            }
            for (const BasesShare& b : shares) {
                const float w[2] = {float(b.main), float(b.branch)};
                for (std::size_t q = 0; q < 2; ++q)
                    if ((*b.groups)[q].size() == nd * cells) add(w[q], (*b.groups)[q].data() + m * cells);
            }
            for (const NearShare& n : near_shares) {
                const float w[2] = {float(n.main), float(n.branch)};
                for (std::size_t q = 0; q < 2; ++q) {
                    const NearFieldParts& part = (*n.parts)[q];
                    if (part.single.size() != nd * cells) continue;
                    if (options.components.single) add(w[q], part.single.data() + m * cells);
                    if (options.components.multiple) add(w[q], part.multiple.data() + m * cells);
                }
            }
        }
    }
    // The frame on the transport grid: everything so far (lighting grid) upsampled, then the
    // light of the strikes solved on that grid added on each grid.
    const bool fine = keep_fine && valid;
    if (fine) {
        const core::GridGeometry& from = media->lighting.density.geom;
        const core::GridGeometry& to = media->transport.density.geom;
        RadianceField& r = f.fine;
        r.geometry = to;
        r.direction_count = f.radiance.direction_count;
        r.directions = f.radiance.directions;
        r.components = f.radiance.components;
        r.values.resize(f.radiance.values.size());
        for (std::size_t k = 0; k < r.values.size(); ++k) {
            r.values[k].resize(to.cell_count());
            if (lighting_part)
                core::resample_trilinear(from, f.radiance.values[k], to, r.values[k]);
            else  // zeros upsampled are zeros
                std::fill(r.values[k].begin(), r.values[k].end(), 0.0f);
        }
    } else {
        f.fine.directions.clear();
        f.fine.values.clear();
    }
    const auto add_solved = [&](RadianceField& r, bool transport_grid) {
        for (std::size_t k = 0; k < r.directions.size(); ++k) {
            const std::size_t m = std::size_t(r.directions[k]);
            float* out = r.values[k].data();
            const std::size_t cells = r.values[k].size();
            const auto add = [out, cells, m](float w, const transport::SourceField& a) {
                FULGUR_ASSERT(a.geom.cell_count() == cells, "FramePipeline: a strike's light is on another grid");
                const float* v = StrikeLight::direction(a, m).data();
                if (w != 0.0f)
                    for (std::size_t i = 0; i < cells; ++i) out[i] += w * v[i];
            };
            for (const Lit& l : solved) {
                const StrikeLight& L = *l.light;
                if (!L.has_fine()) continue;  // in the lighting grid's part
                const float w[2] = {float(l.main), float(l.branch)};
                for (std::size_t q = 0; q < 2; ++q) {
                    if (options.components.single) add(w[q], transport_grid ? L.fine_single[q] : L.single[q]);
                    if (options.components.multiple && L.has_multiple())
                        add(w[q], transport_grid ? L.fine_multiple[q] : L.multiple[q]);
                }
            }
        }
    };
    if (std::any_of(solved.begin(), solved.end(), [](const Lit& l) { return l.light->has_fine(); })) {
        add_solved(f.radiance, false);
        if (fine) add_solved(f.fine, true);
    }
    if (valid) add_rain_light(solved, options);
    f.times.strike_light = sw.milliseconds();
    f.lit = valid;
    return f;
}

// Frame::rain: the multiple S of the strikes solved with the rain in their media, per unit
// albedo (S carries the cloud's), scaled by their glow; on the lighting grid (where the strikes'
// multiple S is kept, whichever grid the cloud's S is on), for the frame's directions.
void FramePipeline::Impl::add_rain_light(const std::vector<Lit>& solved, const ReconstructOptions& options) {
    const auto wet = [](const Lit& l) { return l.rain && l.light->has_multiple(); };
    const double albedo = solve_scene.medium.albedo;
    if (!options.components.multiple || !(albedo > 0.0) || std::none_of(solved.begin(), solved.end(), wet)) return;
    RadianceField& r = frame.rain;
    r.geometry = media->lighting.density.geom;
    r.direction_count = frame.radiance.direction_count;
    r.directions = frame.radiance.directions;
    r.components = {false, true};
    r.values.resize(r.directions.size());
    const std::size_t cells = r.geometry.cell_count();
    for (std::size_t k = 0; k < r.directions.size(); ++k) {
        std::vector<float>& out = r.values[k];
        out.assign(cells, 0.0f);
        const std::size_t m = std::size_t(r.directions[k]);
        for (const Lit& l : solved) {
            if (!wet(l)) continue;
            const float w[2] = {float(l.rain_scale * l.main / albedo), float(l.rain_scale * l.branch / albedo)};
            for (std::size_t q = 0; q < 2; ++q) {
                const std::span<const float> v = StrikeLight::direction(l.light->multiple[q], m);
                FULGUR_ASSERT(v.size() == cells, "FramePipeline: a strike's multiple S is not on the lighting grid");
                if (w[q] != 0.0f)
                    for (std::size_t i = 0; i < cells; ++i) out[i] += w[q] * v[i];
            }
        }
    }
}

transport::SourceField every_direction(const RadianceField& field) {
    transport::SourceField out(field.geometry, transport::output_directions(field.direction_count));
    for (std::size_t k = 0; k < field.directions.size(); ++k)
        std::copy(field.values[k].begin(), field.values[k].end(),
                  out.direction(std::size_t(field.directions[k])).begin());
    return out;
}

const Frame& build_since_known(FramePipeline& pipeline, double t, double since_known_ms,
                               std::span<const int> directions, const ReconstructOptions& options, SinceKnown* seen,
                               bool storm_time_runs) {
    FULGUR_ASSERT(std::isfinite(since_known_ms) && since_known_ms >= 0.0,
                  "build_since_known: since_known_ms must be finite and >= 0");
    FULGUR_ASSERT(!options.wait_for_strikes, "build_since_known: waiting for the strikes defeats the point");
    const core::Stopwatch known;
    constexpr double kFrameMs = 1000.0 / 60.0;
    std::vector<double> ms;
    for (int n = 0;; ++n) {
        const double next = double(n) * kFrameMs;  // this frame's slot since the strike became known
        if (next >= since_known_ms && n > 0) break;
        const double wait = std::min(next, since_known_ms) - known.milliseconds();
        if (wait > 0.0) std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(wait));
        const double at = storm_time_runs ? t - (since_known_ms - next) / 1000.0 : t;
        ms.push_back(pipeline.build(at, directions, options).times.total());
    }
    const double wait = since_known_ms - known.milliseconds();
    if (wait > 0.0) std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(wait));
    if (seen) {
        seen->frames = int(ms.size());
        std::vector<double> sorted = ms;
        std::sort(sorted.begin(), sorted.end());
        seen->median_frame_ms = sorted[sorted.size() / 2];
        seen->max_frame_ms = sorted.back();
    }
    return pipeline.build(t, directions, options);
}

}  // namespace fulgur::runtime
