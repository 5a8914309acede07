// InstantStrikes (instant_strikes.h): progressive Monte Carlo of each strike's strokes, from
// the moment the strike is known, published round by round with its noise and the bases'
// estimated error.
#include "runtime/instant_strikes.h"

#include "runtime/near_field.h"
#include "runtime/reconstructor.h"
#include "runtime/strike_diffusion.h"
#include "sky/sky.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

namespace fulgur::runtime {

double StrikeEstimate::weight() const noexcept {
    if (bases_error < 0.0) return 1.0;
    const double eb2 = bases_error * bases_error, n2 = light.noise.total * light.noise.total;
    const double w = eb2 + n2 > 0.0 ? eb2 / (eb2 + n2) : 1.0;
    // A bases share under 1% means noise < e_b / 10: dropping it moves S by less than the
    // estimate's own noise, and spares the frame adding the bases' frame of the strokes.
    return w > 0.99 ? 1.0 : w;
}

double StrikeEstimate::rain_weight() const noexcept {
    const double w = 1.0 / (1.0 + light.noise.total * light.noise.total);
    return w > 0.99 ? 1.0 : w;
}

InstantOptions instant_options(const scene::Quality& q) {
    InstantOptions o;
    o.max_single_paths = q.single_paths;
    o.max_multiple_paths = q.multiple_paths;
    o.target_noise = q.target_noise;
    o.near_field_rays = q.near_field_rays;
    o.diffusion_multiple = q.near_field_multiple == "diffusion";
    o.fine_rays = q.near_field_fine_rays;
    return o;
}

std::array<transport::MonteCarloOptions, 2> instant_tracer_options() {
    std::array<transport::MonteCarloOptions, 2> o;
    o[0].groups = 2;
    o[0].max_scatterings = 0;
    o[0].tally_multiple = false;
    o[0].uncollided_only = true;
    o[1].groups = 2;
    o[1].tally_single = false;
    return o;
}

namespace {

// Sums over the cloud cells (every direction) of a field's square, and of a difference's.
struct CloudNorms {
    const std::vector<std::uint8_t>& cloud;
    // Direction-major fields ([m][cell]); one double sum per direction, then added: a few
    // thousand terms each, of one sign, so plain double sums lose nothing that matters here.
    double norm2(const std::vector<float>& a, const std::vector<float>* b = nullptr) const {
        const std::size_t cells = cloud.size();
        double total = 0.0;
        for (std::size_t m0 = 0; m0 < a.size(); m0 += cells) {
            double s = 0.0;
            for (std::size_t c = 0; c < cells; ++c) {
                const double v = double(a[m0 + c]) - (b ? double((*b)[m0 + c]) : 0.0);
                s += cloud[c] ? v * v : 0.0;
            }
            total += s;
        }
        return total;
    }
};

}  // namespace

struct InstantStrikes::Impl {
    using Key = std::pair<std::uint64_t, double>;
    struct Entry {
        std::uint64_t seed = 0;
        lightning::Bolt bolt;
        core::Stopwatch requested;
        // The worker's alone (touched only while it traces this entry).
        std::unique_ptr<transport::ProgressiveMonteCarlo> single, multiple;
        std::uint64_t next_single = 0, next_multiple = 0;
        double seconds_single = 0.0, seconds_multiple = 0.0;
        int round = 0;
        double bases_error = -1.0;
        std::shared_ptr<const std::vector<float>> bases_frame;                  // [m][cell], the strokes at unit glow
        std::shared_ptr<const std::array<std::vector<float>, 2>> bases_groups;  // the same per group
        // The near-field correction of the strokes per group (NearField::strokes), made once by
        // whichever thread asks first.
        std::once_flag near_once;
        std::shared_ptr<const std::array<NearFieldParts, 2>> near;
        // Under the mutex.
        double seconds = 0.0;  // the worker's time on it: who goes next
        std::shared_ptr<const StrikeEstimate> estimate;
        std::exception_ptr error;
        bool final = false;
    };

    const scene::Scene& scene;
    const solve::Media& media;
    const BakedBases* bases;
    InstantOptions options;
    int threads;
    transport::LightingMedium fine;       // the full-resolution density (the cloud's)
    transport::MonteCarloMedium tracing;  // the cloud's: its cells are what the estimates' norms are over
    // With rain, the medium the truth traces (runtime::truth) and the strikes solved ahead by
    // paths see: the rain at its own extinction, scattering as drops (solve::Media::traced), S at
    // its points with the drops' phase function. Both tracers trace it: the channel's light
    // reaches the cloud through the rain, and the estimates' multiple S holds the flash's light
    // at the rain (Frame::rain). (With the cloud's medium instead, a rain scene's S was 21% off
    // its truth: order 1 52% high.)
    std::optional<solve::Media> own_wet;  // made here when the caller has none
    const solve::Media* wet = nullptr;
    std::optional<transport::MonteCarloMedium> wet_tracing;
    const transport::MonteCarloMedium& traced() const { return wet_tracing ? *wet_tracing : tracing; }
    std::vector<glm::dvec3> dirs;
    std::unique_ptr<NearField> near;             // null: no near-field correction
    std::unique_ptr<StrikeDiffusion> diffusion;  // null: NearField's own multiple model

    mutable std::mutex mu;
    std::condition_variable cv;  // work to do, an estimate published, stop
    std::map<Key, std::shared_ptr<Entry>> entries;
    bool paused = false, stop = false, warm = false;
    std::thread worker;  // started in the constructor's body, once the members above exist

    Impl(const scene::Scene& s, const core::Grid3<float>& density, const solve::Media& m, const BakedBases* b,
         const InstantOptions& o, int t, const solve::Media* rain_media)
        : scene(s),
          media(m),
          bases(b),
          options(o),
          threads(t),
          fine{density, s.medium},
          tracing(fine, m.lighting.density.geom),
          dirs(transport::output_directions(s.effective_directions())) {
        if (s.rain) {
            wet = rain_media ? rain_media : &own_wet.emplace(sky::make_static_media(s, density, 1, true));
            const transport::LightingMedium& traced = solve::traced_medium(*wet);
            FULGUR_ASSERT(traced.density.data.size() == density.data.size(),
                          "InstantStrikes: rain_media must hold the full-resolution density");
            wet_tracing.emplace(traced, m.lighting.density.geom);
        }
        if (bases && o.near_field_rays > 0) {
            if (o.diffusion_multiple) {
                StrikeDiffusionOptions so;
                so.rays = o.near_field_rays;
                so.fine_rays = o.fine_rays;
                so.seed = o.seed;
                diffusion = std::make_unique<StrikeDiffusion>(m.lighting, *bases, dirs, so, &fine);
                if (!diffusion->separable()) diffusion.reset();
            }
            NearFieldOptions no;
            no.rays = o.near_field_rays;
            no.multiple = !diffusion;
            near = std::make_unique<NearField>(m.lighting, bases->lights(), dirs, no);
        }
        spare.push_back(spare_tracers());  // the first strike's memory, touched before it comes
        worker = std::thread([this] { run(); });
        // Returns once the worker has made its first rounds' memory ready (warm_up) and the
        // lights' near-field models, so that a strike requested right after construction does
        // not wait for them.
        std::unique_lock<std::mutex> lock(mu);
        cv.wait(lock, [&] { return warm; });
    }

    ~Impl() {
        {
            std::lock_guard<std::mutex> lock(mu);
            stop = true;
        }
        cv.notify_all();
        worker.join();
    }

    // The entry's near-field correction, made on the first call (std::call_once orders the
    // write before every caller's read).
    std::shared_ptr<const std::array<NearFieldParts, 2>> near_of(Entry& e) const {
        std::call_once(e.near_once, [&] {
            auto groups = std::make_shared<std::array<NearFieldParts, 2>>();
            if (!diffusion) {
                for (std::size_t q = 0; q < 2; ++q) (*groups)[q] = near->strokes(e.bolt, q);
            } else {
                // The two groups at once, one per core (their casts are of similar cost: the
                // branches carry as many points as the main channel); a cast inside runs on its
                // group's core alone.
                core::parallel_for_dynamic(0, 2, [&](std::int64_t q) {
                    const std::vector<transport::PointSource> src = near->stroke_sources(e.bolt, std::size_t(q));
                    NearFieldParts& part = (*groups)[std::size_t(q)];
                    if (src.empty()) return;
                    if (!diffusion->replaces_single()) near->add(src, part);
                    diffusion->add(src, part);
                });
            }
            e.near = std::move(groups);
        });
        return e.near;
    }

    // The unfinished entry that has had the least of the worker's time (null: none).
    std::shared_ptr<Entry> next() const {
        std::shared_ptr<Entry> best;
        for (const auto& [key, e] : entries)
            if (!e->final && (!best || e->seconds < best->seconds)) best = e;
        return best;
    }

    // A strike's two tracers (instant_tracer_options).
    struct Tracers {
        std::unique_ptr<transport::ProgressiveMonteCarlo> single, multiple;
    };
    std::vector<Tracers> spare;  // the worker's: tracers of finished strikes, their memory kept

    Tracers spare_tracers() {
        if (!spare.empty()) {
            Tracers t = std::move(spare.back());
            spare.pop_back();
            return t;
        }
        std::array<transport::MonteCarloOptions, 2> o = instant_tracer_options();
        o[1].ground = strike_ground(scene, media.lighting.density.geom);  // the paths that scatter reach the ground
        if (wet) {
            o[0].phase_mix = o[1].phase_mix = wet->lighting.phase_mix.get();
            // The noise over the cloud, where the norms, the bases' error and the blend are: the
            // rain's cells around the channel hold S far above the cloud's (order 1, where the
            // frame draws the channel's light itself), and their noise would count as the
            // estimate's.
            o[0].noise_cells = o[1].noise_cells = &tracing.cloud();
        }
        const std::span<const transport::LineSource> none;
        return {std::make_unique<transport::ProgressiveMonteCarlo>(traced(), std::span<const transport::PointSource>{},
                                                                   none, dirs, o[0]),
                std::make_unique<transport::ProgressiveMonteCarlo>(traced(), std::span<const transport::PointSource>{},
                                                                   none, dirs, o[1])};
    }

    // Tracers of strikes that will not be traced again go back to the pool, up to two pairs
    // (~25 MB each on the default storm); the others are freed. Under the lock; only the
    // worker touches tracers.
    void recycle() {
        for (auto& [key, e] : entries)
            if (e->final && e->single) {
                if (spare.size() < 2) spare.push_back({std::move(e->single), std::move(e->multiple)});
                e->single.reset();
                e->multiple.reset();
            }
    }

    // A strike's first rounds without fresh memory. Each round builds both tracers' results
    // and an estimate of a dozen ~1 MB fields (default storm) while the previous estimate is
    // still shown; the first time, every page of them is new to the process (the allocator maps
    // large blocks afresh until it has freed one), and page faults made the first estimate's
    // bookkeeping 40 ms where later rounds take 3 (fulgur-bench instant). Building two rounds'
    // worth on the worker's own thread and freeing them leaves that memory with its allocator.
    void warm_up() {
        if (spare.empty()) return;
        const Tracers& t = spare.back();
        struct Round {
            transport::MonteCarloResult single, multiple;
            std::vector<transport::SourceField> estimate;
            std::vector<float> total;
        };
        std::array<Round, 2> rounds;
        for (Round& r : rounds) {
            r.single = t.single->result();
            r.multiple = t.multiple->result();
            for (const auto& g : r.single.groups) r.estimate.push_back(g.single);
            for (const auto& g : r.multiple.groups) r.estimate.push_back(g.multiple);
            r.total = r.single.single.data;
        }
    }

    void run() {
        const core::ScopedThreadCount share(threads);
        // The bases' frame of a strike's strokes, for their estimated error (worker's own).
        std::unique_ptr<lightning::Splatter> splatter;
        std::unique_ptr<Reconstructor> reconstructor;
        if (bases) {
            splatter = std::make_unique<lightning::Splatter>(bases->lights());
            reconstructor = std::make_unique<Reconstructor>(*bases);
        }
        try {
            warm_up();
        } catch (...) {
            // Only a cost: without it the first round allocates afresh, as before.
        }
        // The lights' near-field models, on every core before the first strike can come: a
        // strike's first correction then pays only for its own points (docs/presets.md: the
        // default storm's 968 lights take 11-19 ms on 2 cores, once).
        if (near && !diffusion)
            core::parallel_for_dynamic(
                0, std::int64_t(near->light_count()), [&](std::int64_t l) { near->keep_light(std::size_t(l)); }, 16);
        {
            std::lock_guard<std::mutex> lock(mu);
            warm = true;
        }
        cv.notify_all();
        for (;;) {
            std::shared_ptr<Entry> e;
            {
                std::unique_lock<std::mutex> lock(mu);
                cv.wait(lock, [&] { return stop || (!paused && next()); });
                if (stop) return;
                recycle();
                e = next();
            }
            core::Stopwatch sw;
            std::shared_ptr<const StrikeEstimate> estimate;
            std::exception_ptr error;
            try {
                estimate = round(*e, splatter.get(), reconstructor.get());
            } catch (...) {
                error = std::current_exception();
            }
            {
                std::lock_guard<std::mutex> lock(mu);
                e->seconds += sw.seconds();
                // Paused meanwhile: what exists at the pause is what is shown (the round's paths
                // stay in the tracers and count in the next estimate).
                if (estimate && !paused) {
                    e->estimate = estimate;
                    e->final = e->final || estimate->final;  // stop() meanwhile stays stopped
                }
                if (error) {
                    e->error = error;
                    e->final = true;
                }
            }
            cv.notify_all();
        }
    }

    // One round of an entry: more paths for each part (the first round fixed, later ones sized
    // by time and split between the parts to shrink the total noise fastest), then the
    // estimate.
    std::shared_ptr<const StrikeEstimate> round(Entry& e, lightning::Splatter* splatter, Reconstructor* rec) {
        if (!e.single) {
            // The near-field correction first (on every core, a few ms): the frame that shows
            // the strike before its first estimate waits for it rather than making it alone,
            // and the first estimate's bases' frame carries it.
            if (near) near_of(e);
            const std::vector<transport::LineSource> lines = strike_line_sources(e.bolt);
            const std::uint64_t seed = core::hash_seed(options.seed, e.seed);
            Tracers t = spare_tracers();
            t.single->restart({}, lines, core::hash_seed(seed, 1));
            t.multiple->restart({}, lines, core::hash_seed(seed, 2));
            e.single = std::move(t.single);
            e.multiple = std::move(t.multiple);
            e.next_single = options.first_single_paths;
            e.next_multiple = scene.effects.multiple_scattering ? options.first_multiple_paths : 0;
        }
        const auto advance = [](transport::ProgressiveMonteCarlo& p, std::uint64_t n, std::uint64_t cap, double& s) {
            n = std::min(n, cap > p.paths() ? cap - p.paths() : 0);
            if (n < 2) return;
            core::Stopwatch sw;
            p.advance(n);
            s += sw.seconds();
        };
        advance(*e.single, e.next_single, options.max_single_paths, e.seconds_single);
        advance(*e.multiple, e.next_multiple, options.max_multiple_paths, e.seconds_multiple);
        ++e.round;

        // The results' fields are moved into the estimate (copying them took ~1.2 ms of a round
        // on the default storm's strikes, fulgur-bench instant).
        transport::MonteCarloResult rs = e.single->result(), rm = e.multiple->result();
        auto est = std::make_shared<StrikeEstimate>();
        StrikeLight& L = est->light;
        for (std::size_t q = 0; q < 2; ++q) {
            L.single[q] = std::move(rs.groups[q].single);
            L.multiple[q] = scene.effects.multiple_scattering ? std::move(rm.groups[q].multiple)
                                                              : transport::SourceField(rs.single.geom, dirs);
            if (scene.effects.multiple_scattering) L.ground[q] = std::move(rm.groups[q].ground);
        }
        L.seconds_single = e.seconds_single;
        L.seconds_multiple = e.seconds_multiple;
        est->single_paths = e.single->paths();
        est->multiple_paths = e.multiple->paths();
        est->worker_seconds = e.seconds_single + e.seconds_multiple;
        est->since_request = e.requested.seconds();
        est->round = e.round;

        // Noise of the sum: the parts are independent, so their absolute noises add in
        // quadrature. The norms and the noises are over the cloud (with rain too).
        const CloudNorms norms{tracing.cloud()};
        const bool with_multiple = scene.effects.multiple_scattering;
        const double n1 = norms.norm2(rs.single.data), nm = with_multiple ? norms.norm2(rm.multiple.data) : 0.0;
        std::vector<float> total = std::move(rs.single.data);
        if (with_multiple)
            for (std::size_t i = 0; i < total.size(); ++i) total[i] += rm.multiple.data[i];
        const double nt = norms.norm2(total);
        L.noise.single = rs.noise.single;
        L.noise.multiple = with_multiple ? rm.noise.multiple : 0.0;
        const double abs1 = L.noise.single * std::sqrt(n1), absm = L.noise.multiple * std::sqrt(nm);
        L.noise.total = nt > 0.0 ? std::sqrt(abs1 * abs1 + absm * absm) / std::sqrt(nt) : 0.0;

        // The bases' frame of the strokes is made once; their error against the estimate barely
        // moves once the estimate is within a few tens of percent: two rounds measure it.
        if (splatter && rec && e.round == 1) {
            auto groups = std::make_shared<std::array<std::vector<float>, 2>>();
            for (std::size_t q = 0; q < 2; ++q) (*groups)[q] = bases_frame(e.bolt, q, *splatter, *rec);
            if (near) {  // the bases' frame a frame shows: with its near-field correction
                const auto nf = near_of(e);
                for (std::size_t q = 0; q < 2; ++q) {
                    const NearFieldParts& n = (*nf)[q];
                    std::vector<float>& b = (*groups)[q];
                    if (n.empty() || b.size() != n.single.size()) continue;
                    for (std::size_t i = 0; i < b.size(); ++i) b[i] += n.single[i] + n.multiple[i];
                }
            }
            std::vector<float> b(total.size(), 0.0f);
            bool lit = false;
            for (const std::vector<float>& g : *groups)
                if (g.size() == b.size()) {
                    for (std::size_t i = 0; i < b.size(); ++i) b[i] += g[i];
                    lit = true;
                } else if (!g.empty()) {
                    lit = false;  // not the estimate's layout: no bases error, no cached frame
                    break;
                }
            if (lit) {
                e.bases_frame = std::make_shared<const std::vector<float>>(std::move(b));
                e.bases_groups = std::move(groups);
            }
        }
        if (e.bases_frame && nt > 0.0 && e.round <= 2)
            e.bases_error =
                std::sqrt(std::max(0.0, norms.norm2(*e.bases_frame, &total) / nt - L.noise.total * L.noise.total));
        est->bases_error = e.bases_error;
        est->total = std::move(total);
        est->bases = e.bases_frame;
        est->bases_groups = e.bases_groups;

        const bool capped = e.single->paths() >= options.max_single_paths &&
                            (!with_multiple || e.multiple->paths() >= options.max_multiple_paths);
        est->final = capped || nt == 0.0 || (L.noise.total > 0.0 && L.noise.total <= options.target_noise);

        // The next round: max(round_seconds, growth x time so far), split between the parts in
        // proportion to noise x norm x sqrt(time spent) (what minimizes the total noise for a
        // given time when each part's variance falls like 1/paths).
        const double budget = std::max(options.round_seconds, options.growth * est->worker_seconds);
        const double xs = abs1 * std::sqrt(e.seconds_single),
                     xm = with_multiple ? absm * std::sqrt(e.seconds_multiple) : 0.0;
        const double share = xs + xm > 0.0 ? xs / (xs + xm) : 0.5;
        const auto paths_for = [&](double seconds, const transport::ProgressiveMonteCarlo& p, double spent) {
            const double per_path = spent / double(std::max<std::uint64_t>(1, p.paths()));
            return per_path > 0.0 ? std::uint64_t(std::clamp(seconds / per_path, 2.0, 1e9)) : std::uint64_t(2);
        };
        // Each part keeps at least a tenth of the round: a noise estimate that happens to be
        // low early cannot starve its part.
        const double s1 = std::clamp(share, 0.1, 0.9);
        e.next_single = paths_for(budget * s1, *e.single, e.seconds_single);
        e.next_multiple = with_multiple ? paths_for(budget * (1.0 - s1), *e.multiple, e.seconds_multiple) : 0;
        return est;
    }

    // The bases' S of one group of the strokes (0: the main channel, 1: the branches) at unit
    // glow, every direction ([m][cell]); empty when the bases show nothing of it.
    static std::vector<float> bases_frame(const lightning::Bolt& bolt, std::size_t group, lightning::Splatter& splatter,
                                          Reconstructor& rec) {
        lightning::FlashState unit;
        (group == 0 ? unit.main_glow : unit.branch_glow) = 1.0;
        std::vector<lightning::LitSegment> lit;
        lightning::lit_segments(bolt, unit, lit);
        std::vector<transport::PointSource> sources;
        lightning::append_point_sources(lit, splatter.source_spacing(), sources);
        lightning::LightWeights w;
        splatter.splat(sources, w);
        RadianceField r;
        StageTimes times;
        ReconstructOptions o;
        // On the worker's threads, whatever the work: the tracing waits for it (the first
        // estimate's two reconstructions 3.55 -> 2.84 ms on the default storm, 2 threads).
        o.parallel_min_work = 0;
        std::vector<float> b;
        if (!rec.reconstruct(w, {}, o, r, times)) return b;
        for (const std::vector<float>& d : r.values) b.insert(b.end(), d.begin(), d.end());
        return b;
    }
};

InstantStrikes::InstantStrikes(const scene::Scene& scene, const core::Grid3<float>& density, const solve::Media& media,
                               const BakedBases* bases, const InstantOptions& options, int threads,
                               const solve::Media* rain_media) {
    FULGUR_ASSERT(threads >= 1, "InstantStrikes: threads must be >= 1");
    FULGUR_ASSERT(options.first_single_paths >= 2 && options.first_multiple_paths >= 2,
                  "InstantStrikes: the first round needs at least two paths per part");
    impl_ = std::make_unique<Impl>(scene, density, media, bases, options, threads, rain_media);
}

InstantStrikes::~InstantStrikes() = default;

void InstantStrikes::request(std::uint64_t seed, double time, const lightning::Bolt& bolt) {
    {
        std::lock_guard<std::mutex> lock(impl_->mu);
        std::shared_ptr<Impl::Entry>& e = impl_->entries[{seed, time}];
        if (e) return;
        e = std::make_shared<Impl::Entry>();
        e->seed = seed;
        e->bolt = bolt;
    }
    impl_->cv.notify_all();
}

std::shared_ptr<const StrikeEstimate> InstantStrikes::get(std::uint64_t seed, double time) const {
    std::lock_guard<std::mutex> lock(impl_->mu);
    const auto it = impl_->entries.find({seed, time});
    return it == impl_->entries.end() ? nullptr : it->second->estimate;
}

std::shared_ptr<const std::array<NearFieldParts, 2>> InstantStrikes::near_field(std::uint64_t seed, double time) const {
    const Impl& im = *impl_;
    if (!im.near) return nullptr;
    std::shared_ptr<Impl::Entry> e;
    {
        std::lock_guard<std::mutex> lock(im.mu);
        const auto it = im.entries.find({seed, time});
        if (it == im.entries.end()) return nullptr;
        e = it->second;
    }
    return im.near_of(*e);
}

std::size_t InstantStrikes::directions() const noexcept { return impl_->dirs.size(); }
bool InstantStrikes::traces_rain() const noexcept { return impl_->wet_tracing.has_value(); }

std::shared_ptr<const StrikeEstimate> InstantStrikes::wait_final(std::uint64_t seed, double time) {
    Impl& im = *impl_;
    std::unique_lock<std::mutex> lock(im.mu);
    const auto it = im.entries.find({seed, time});
    FULGUR_ASSERT(it != im.entries.end(), "InstantStrikes::wait_final: the strike was not requested");
    const std::shared_ptr<Impl::Entry> e = it->second;
    FULGUR_ASSERT(!im.paused, "InstantStrikes::wait_final: the solver is paused");
    im.cv.wait(lock, [&] { return e->final; });
    if (e->error) std::rethrow_exception(e->error);
    return e->estimate;
}

void InstantStrikes::set_paused(bool paused) {
    {
        std::lock_guard<std::mutex> lock(impl_->mu);
        impl_->paused = paused;
    }
    impl_->cv.notify_all();
}

void InstantStrikes::stop(std::uint64_t seed, double time) {
    {
        std::lock_guard<std::mutex> lock(impl_->mu);
        const auto it = impl_->entries.find({seed, time});
        if (it != impl_->entries.end()) it->second->final = true;
    }
    impl_->cv.notify_all();
}

void InstantStrikes::forget_before(double time) {
    std::lock_guard<std::mutex> lock(impl_->mu);
    std::erase_if(impl_->entries, [time](const auto& kv) { return kv.first.second < time; });
}

}  // namespace fulgur::runtime
