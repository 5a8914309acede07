// The run time (runtime.h, docs/runtime.md): baked bases in an accumulation layout, the
// sparse sum + inverse Haar of Dobashi et al. 2007 (Eqs. 8-10), the per-frame pipeline and
// the direct solve it is measured against.
#include "runtime/detail/internal.h"

#include "bake/bake.h"

#if defined(__F16C__)
#include <immintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace fulgur::runtime {

// =======================================================================================
// BakedBases

namespace {

// Exact binary16 -> binary32: the F16C instruction where the build targets it, else the
// portable bit-level conversion (same result).
inline float half_to_float_fast(std::uint16_t h) noexcept {
#if defined(__F16C__)
    return _cvtsh_ss(h);
#else
    return basis::half_to_float(h);
#endif
}

// The file in the accumulation layout, streamed light by light (each block validated by
// FgbReader::read_light, as basis::load_fgb does), so the peak memory is the pool plus one
// light. Runs keep the file's order (by index in deflated files, by decreasing magnitude
// in plain ones): the order was measured to change the accumulation time by < 5% on the
// default storm (H in L1), and sorting costs load time.
std::unique_ptr<BakedBases::Impl> build_layout(basis::FgbReader& reader) {
    if (reader.partial())
        throw core::Error(reader.name(), "holds only lights [" + std::to_string(reader.light_begin()) + ", " +
                                             std::to_string(reader.light_end()) + ") of " +
                                             std::to_string(reader.metadata().light_count()) +
                                             " (a partial bake); merge the parts first");
    auto impl = std::make_unique<BakedBases::Impl>();
    BakedBases::Impl& b = *impl;
    b.meta = reader.metadata();
    b.bases_per_light = b.meta.bases();
    const std::size_t lights = b.meta.light_count(), runs = lights * b.bases_per_light;
    b.narrow = b.meta.cells() <= 65536;
    b.half = b.meta.compression.precision == basis::Precision::Float16;
    b.offset.assign(runs + 1, 0);
    b.gamma.assign(runs, 0.0);
    if (b.half) b.scale_exp.assign(runs, 0);
    // The exact coefficient count from the blocks' tables (CRC-checked, each count bounded
    // by the cells), reserved once: a deflated file gives no bound from its size.
    std::size_t bound = 0;
    for (std::uint32_t l = 0; l < lights; ++l) bound += std::size_t(reader.coefficient_count(l));
    if (b.narrow)
        b.index16.reserve(bound);
    else
        b.index32.reserve(bound);
    if (b.half)
        b.value16.reserve(bound);
    else
        b.value.reserve(bound);
    for (std::uint32_t l = 0; l < lights; ++l) {
        // Order::Any: each index occurs once per basis, so the accumulation's result does
        // not depend on the order within a basis (and the deflated files store them by index).
        const basis::CompressedLight cl = reader.read_light(l, basis::FgbReader::Order::Any);
        FULGUR_ASSERT(cl.directions.size() == b.bases_per_light, "FgbReader returned a light without all its bases");
        for (std::size_t k = 0; k < b.bases_per_light; ++k) {
            const std::size_t r = b.run(l, k);
            const basis::CompressedBasis& cb = cl.directions[k];
            b.offset[r] = b.values();
            b.gamma[r] = cb.gamma;
            // read_light has checked every index against the cell count.
            if (b.narrow)
                for (const std::uint32_t i : cb.index) b.index16.push_back(std::uint16_t(i));
            else
                b.index32.insert(b.index32.end(), cb.index.begin(), cb.index.end());
            if (b.half) {
                // Back to the file's half bits: exact (every stored value is half * 2^scale_exp).
                b.scale_exp[r] = cb.scale_exp;
                for (const float v : cb.value) b.value16.push_back(basis::float_to_half(std::ldexp(v, -cb.scale_exp)));
            } else {
                b.value.insert(b.value.end(), cb.value.begin(), cb.value.end());
            }
        }
    }
    b.offset[runs] = b.values();
    return impl;
}

}  // namespace

BakedBases::BakedBases(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
BakedBases::BakedBases(BakedBases&&) noexcept = default;
BakedBases& BakedBases::operator=(BakedBases&&) noexcept = default;
BakedBases::~BakedBases() = default;

BakedBases BakedBases::load(const std::filesystem::path& fgb, const std::optional<basis::BakeKey>& expected) {
    basis::FgbReader reader(fgb);
    if (expected) reader.check_key(*expected);
    return BakedBases(build_layout(reader));
}

BakedBases BakedBases::load(const std::filesystem::path& fgb, const basis::FgbMetadata& expected) {
    basis::FgbReader reader(fgb);
    reader.check_metadata(expected);
    return BakedBases(build_layout(reader));
}

const core::GridGeometry& BakedBases::lighting() const noexcept { return impl_->meta.lighting; }
const std::vector<glm::dvec3>& BakedBases::directions() const noexcept { return impl_->meta.directions; }
const basis::VirtualLightGrid& BakedBases::lights() const noexcept { return impl_->meta.lights; }
const basis::FgbMetadata& BakedBases::metadata() const noexcept { return impl_->meta; }
bool BakedBases::has_multiple() const noexcept {
    return (impl_->meta.content & basis::FgbMetadata::kContentMultiple) != 0;
}
bool BakedBases::separate() const noexcept { return impl_->meta.components == 2; }
std::size_t BakedBases::coefficient_count() const noexcept { return std::size_t(impl_->offset.back()); }
std::size_t BakedBases::memory_bytes() const noexcept {
    const Impl& b = *impl_;
    return b.offset.size() * sizeof(std::uint64_t) + b.index16.size() * sizeof(std::uint16_t) +
           b.index32.size() * sizeof(std::uint32_t) + b.value.size() * sizeof(float) +
           b.value16.size() * sizeof(std::uint16_t) + b.scale_exp.size() * sizeof(std::int32_t) +
           b.gamma.size() * sizeof(double);
}

float BakedBases::Impl::value_at(std::size_t r, std::size_t k) const noexcept {
    const std::size_t q = std::size_t(offset[r]) + k;
    return half ? std::ldexp(half_to_float_fast(value16[q]), scale_exp[r]) : value[q];
}

// =======================================================================================
// Reconstructor

namespace {

// Which stored components a request sums, and what the sum holds (runtime.h).
struct Selection {
    std::size_t component[2] = {0, 0};
    int count = 0;
    Components holds{false, false};
};

Selection select(const basis::FgbMetadata& m, const Components& want) {
    Selection s;
    if (m.components == 2) {  // content is single | multiple (validated by the loader)
        if (want.single) s.component[s.count++] = 0;
        if (want.multiple) s.component[s.count++] = 1;
        s.holds = {want.single, want.multiple};
        return s;
    }
    const bool has_single = (m.content & basis::FgbMetadata::kContentSingle) != 0;
    const bool has_multiple = (m.content & basis::FgbMetadata::kContentMultiple) != 0;
    if ((want.single && has_single) || (want.multiple && has_multiple)) {
        s.component[s.count++] = 0;
        s.holds = {has_single, has_multiple};
    }
    return s;
}

// H += w * B over one run: the inner loop of Eq. 9 (scattered adds; H is L1/L2-resident).
template <class I>
inline void add_run(const I* __restrict idx, const float* __restrict val, std::size_t n, float w,
                    float* __restrict h) noexcept {
    for (std::size_t k = 0; k < n; ++k) h[idx[k]] += w * val[k];
}
// The same over float16 values; w already carries the run's 2^scale_exp, so each term is
// w * half * 2^scale_exp rounded once, as with the expanded float value (both scalings by a
// power of two are exact for normal numbers).
template <class I>
inline void add_run(const I* __restrict idx, const std::uint16_t* __restrict val, std::size_t n, float w,
                    float* __restrict h) noexcept {
    for (std::size_t k = 0; k < n; ++k) h[idx[k]] += w * half_to_float_fast(val[k]);
}

}  // namespace

struct Reconstructor::Impl {
    const BakedBases::Impl& bases;
    std::vector<std::unique_ptr<basis::HaarTransform<float>>> haar;  ///< one per worker thread
    std::vector<int> dirs;
    std::vector<std::uint32_t> lights;  ///< active lights with a float weight != 0
    std::vector<float> weight;
    std::vector<double> ambient;  ///< per requested direction

    explicit Impl(const BakedBases::Impl& b) : bases(b) {}

    void ensure_plans(int n) {
        while (int(haar.size()) < n)
            haar.push_back(std::make_unique<basis::HaarTransform<float>>(bases.meta.lighting.dims,
                                                                         bases.meta.compression.decomposition));
    }

    // fn(thread, i) for i in [0, n), contiguous blocks of directions per thread.
    template <class F>
    void for_directions(int threads, std::size_t n, F&& fn) {
        if (threads <= 1) {
            for (std::size_t i = 0; i < n; ++i) fn(0, i);
            return;
        }
        core::parallel_for(0, threads, [&](std::int64_t t) {
            const std::size_t a = n * std::size_t(t) / std::size_t(threads),
                              b = n * std::size_t(t + 1) / std::size_t(threads);
            for (std::size_t i = a; i < b; ++i) fn(int(t), i);
        });
    }

    void accumulate_direction(std::size_t m, const Selection& sel, float* h) const {
        const BakedBases::Impl& b = bases;
        std::fill(h, h + b.meta.cells(), 0.0f);
        const std::uint64_t* off = b.offset.data();
        for (std::size_t a = 0; a < lights.size(); ++a) {
            const std::size_t l = lights[a];
            for (int c = 0; c < sel.count; ++c) {
                const std::size_t r = b.run(l, b.meta.basis_index(sel.component[c], m));
                const std::uint64_t o = off[r], n = off[r + 1] - o;
                if (b.half)
                    add_typed(b.value16.data() + o, std::ldexp(weight[a], b.scale_exp[r]), o, n, h);
                else
                    add_typed(b.value.data() + o, weight[a], o, n, h);
            }
        }
    }

    template <class V>
    void add_typed(const V* val, float w, std::uint64_t o, std::uint64_t n, float* h) const {
        if (bases.narrow)
            add_run(bases.index16.data() + o, val, n, w, h);
        else
            add_run(bases.index32.data() + o, val, n, w, h);
    }
};

Reconstructor::Reconstructor(const BakedBases& bases) : impl_(std::make_unique<Impl>(bases.impl())) {
    impl_->ensure_plans(1);
}
Reconstructor::~Reconstructor() = default;

bool Reconstructor::reconstruct(const lightning::LightWeights& w, std::span<const int> directions,
                                const ReconstructOptions& options, RadianceField& out, StageTimes& times) {
    times.accumulate = times.inverse_haar = 0.0;
    if (w.active.empty()) return false;
    Impl& im = *impl_;
    const BakedBases::Impl& b = im.bases;
    const basis::FgbMetadata& meta = b.meta;
    const std::size_t nd = meta.directions.size(), cells = meta.cells();
    FULGUR_ASSERT(w.e.size() == meta.light_count(), "LightWeights are not over this bake's virtual-light grid");

    core::Stopwatch sw;
    im.dirs.clear();
    if (directions.empty()) {
        for (std::size_t m = 0; m < nd; ++m) im.dirs.push_back(int(m));
    } else {
        for (const int m : directions) {
            if (m < 0 || std::size_t(m) >= nd)
                throw core::Error("runtime::reconstruct", "direction " + std::to_string(m) +
                                                              " does not exist (the bake has " + std::to_string(nd) +
                                                              " directions)");
            im.dirs.push_back(m);
        }
    }
    const Selection sel = select(meta, options.components);
    // Float weights; a weight that underflows float contributes nothing and is skipped.
    im.lights.clear();
    im.weight.clear();
    for (const std::uint32_t l : w.active) {
        const float f = float(w.e[l]);
        if (f == 0.0f) continue;
        im.lights.push_back(l);
        im.weight.push_back(f);
    }

    const std::size_t n = im.dirs.size();
    out.geometry = meta.lighting;
    out.direction_count = int(nd);
    out.directions = im.dirs;
    out.components = sel.holds;
    out.values.resize(n);
    for (std::vector<float>& v : out.values) v.resize(cells);

    // Ambient (Eq. 10), per direction, in double: sum_l e_l gamma_l (Paper) or the per-cell
    // RMS of the dropped detail, sum_l e_l gamma_l / sqrt(N) (Rms).
    im.ambient.assign(n, 0.0);
    if (options.ambient != Ambient::None) {
        const double scale = options.ambient == Ambient::Rms ? 1.0 / std::sqrt(double(cells)) : 1.0;
        for (std::size_t i = 0; i < n; ++i) {
            double a = 0.0;
            for (const std::uint32_t l : w.active)
                for (int c = 0; c < sel.count; ++c)
                    a += w.e[l] * b.gamma[b.run(l, meta.basis_index(sel.component[c], std::size_t(im.dirs[i])))];
            im.ambient[i] = a * scale;
        }
    }

    // Work estimate: coefficients to add plus samples to transform.
    std::size_t work = n * cells;
    if (options.parallel_min_work > 0 && core::thread_count() > 1)
        for (std::size_t i = 0; i < n && work < options.parallel_min_work; ++i)
            for (const std::uint32_t l : im.lights)
                for (int c = 0; c < sel.count; ++c) {
                    const std::size_t r = b.run(l, meta.basis_index(sel.component[c], std::size_t(im.dirs[i])));
                    work += std::size_t(b.offset[r + 1] - b.offset[r]);
                }
    const bool parallel = core::thread_count() > 1 && work >= options.parallel_min_work;
    const int threads = parallel ? int(std::min<std::size_t>(std::size_t(core::thread_count()), n)) : 1;
    im.ensure_plans(threads);
    im.for_directions(threads, n, [&](int, std::size_t i) {
        im.accumulate_direction(std::size_t(im.dirs[i]), sel, out.values[i].data());
    });
    times.accumulate = sw.milliseconds();

    sw.reset();
    im.for_directions(threads, n, [&](int t, std::size_t i) {
        std::vector<float>& v = out.values[i];
        im.haar[std::size_t(t)]->inverse(v);
        if (im.ambient[i] != 0.0) {
            const float a = float(im.ambient[i]);
            for (float& x : v) x += a;
        }
    });
    times.inverse_haar = sw.milliseconds();
    return true;
}

// =======================================================================================
// FramePipeline

struct FramePipeline::Impl {
    lightning::Storm storm;
    lightning::Splatter splatter;
    Reconstructor reconstructor;
    Frame frame;
    scene::Quality quality;
    // Presets that solve strikes (the solver keeps references to the scene and the media).
    scene::Scene solve_scene;
    std::optional<bake::Media> media;
    std::unique_ptr<StrikeSolver> solver;
    std::vector<lightning::LitSegment> basis_segments, multiple_segments;  // what the bases light
    std::vector<transport::PointSource> basis_sources, multiple_sources;
    lightning::LightWeights multiple_weights;
    RadianceField multiple_radiance;
    double forgotten_before = -1e300;

    const scene::Scene* scene;
    const core::Grid3<float>* density;

    Impl(const scene::Scene& s, const core::Grid3<float>& d, const BakedBases& bases,
         std::optional<lightning::Box> domain, const scene::Quality& q)
        : storm(s.lightning, d, domain), splatter(bases.lights()), reconstructor(bases), scene(&s), density(&d) {
        set_quality(q);
    }

    void set_quality(const scene::Quality& q) {
        const scene::Scene& s = *scene;
        solver.reset();  // joins the worker: nothing refers to the old media any more
        media.reset();
        quality = q;
        if (q.preset == scene::Quality::Preset::Paper) return;
        solve_scene = s;  // the per-strike transport grid may be finer than the bake's
        // At least the bake's refinement; a preset's default applies where it divides the
        // lighting grid's downsample (a scene's own quality.refine is checked when read).
        if (q.refine > s.transport.refine && s.lighting_downsample % q.refine == 0)
            solve_scene.transport.refine = q.refine;
        if (q.exact_orders > 0) solve_scene.transport.lb_exact_orders = q.exact_orders;
        media = bake::make_media(solve_scene, *density);
        // The worker takes one core less than the frame's share, at least one.
        solver = std::make_unique<StrikeSolver>(solve_scene, *density, *media, strike_solve_options(q),
                                                std::max(1, core::thread_count() - 1));
    }

    // The frame's per-build fields reset; its buffers (segments, sources, weights, radiance)
    // kept for reuse.
    Frame& begin_frame(double t) {
        frame.time = t;
        frame.lit = false;
        frame.times = {};
        frame.strikes_solved = frame.strikes_fallback = 0;
        return frame;
    }
    const Frame& build_paper(double t, std::span<const int> directions, const ReconstructOptions& options);
    const Frame& build_solved(double t, std::span<const int> directions, const ReconstructOptions& options);
};

FramePipeline::FramePipeline(const scene::Scene& scene, const core::Grid3<float>& density, const BakedBases& bases,
                             std::optional<lightning::Box> domain, std::optional<scene::Quality> quality)
    : impl_(std::make_unique<Impl>(scene, density, bases, domain, quality ? *quality : scene.quality)) {}
FramePipeline::~FramePipeline() = default;

std::size_t FramePipeline::strike_at(double t, std::optional<std::uint64_t> seed) {
    return impl_->storm.strike_at(t, seed);
}

lightning::Storm& FramePipeline::storm() noexcept { return impl_->storm; }
const scene::Quality& FramePipeline::quality() const noexcept { return impl_->quality; }
StrikeSolver* FramePipeline::strike_solver() noexcept { return impl_->solver.get(); }
void FramePipeline::set_quality(const scene::Quality& q) { impl_->set_quality(q); }

const Frame& FramePipeline::build(double t, std::span<const int> directions, const ReconstructOptions& options) {
    return impl_->solver ? impl_->build_solved(t, directions, options) : impl_->build_paper(t, directions, options);
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
    for (const std::size_t i : storm.starting(t - 1.0, t + quality.lookahead)) {
        const lightning::Strike& k = storm.strike(i);
        if (k.end() > t) solver->request(k.seed, k.time, storm.bolt(i));
    }
    if (t - 60.0 > forgotten_before) {  // keep a minute of solved strikes
        forgotten_before = t - 60.0;
        solver->forget_before(forgotten_before);
    }
    const bool glowing = storm.lit(t, f.segments);
    f.sources.clear();
    basis_segments.clear();
    multiple_segments.clear();
    struct Lit {
        std::shared_ptr<const StrikeLight> light;
        double main = 0.0, branch = 0.0;
    };
    std::vector<Lit> solved;
    if (glowing) {
        const std::vector<std::size_t> active(storm.active(t).begin(), storm.active(t).end());
        for (const std::size_t i : active) {
            const lightning::Strike& k = storm.strike(i);
            solver->request(k.seed, k.time, storm.bolt(i));
            std::shared_ptr<const StrikeLight> light =
                options.wait_for_strikes ? solver->wait(k.seed, k.time) : solver->get(k.seed, k.time);
            const lightning::FlashState st = lightning::flash_state(k.profile, storm.params().timing, t - k.time);
            if (!light) {
                lightning::lit_segments(storm.bolt(i), st, basis_segments);
                ++f.strikes_fallback;
                continue;
            }
            ++f.strikes_solved;
            solved.push_back({light, st.main_glow, st.branch_glow});
            lightning::FlashState leader = st;  // the leaders: bases, both components
            leader.main_glow = leader.branch_glow = 0.0;
            lightning::lit_segments(storm.bolt(i), leader, basis_segments);
            if (!light->has_multiple()) {  // hybrid: the strokes' multiple scattering from the bases
                lightning::FlashState strokes = st;
                strokes.leader_glow = 0.0;
                lightning::lit_segments(storm.bolt(i), strokes, multiple_segments);
            }
        }
    }
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

    // The solved strikes' light, for the directions the frame holds.
    sw.reset();
    if (!solved.empty()) {
        const StrikeLight& first = *solved.front().light;
        const core::GridGeometry& g = first.single[0].geom;
        const std::size_t cells = g.cell_count(), nd = first.single[0].directions.size();
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
            for (const Lit& l : solved) {
                const StrikeLight& L = *l.light;
                const float w[2] = {float(l.main), float(l.branch)};
                for (int q = 0; q < 2; ++q) {
                    if (w[q] == 0.0f) continue;
                    if (options.components.single) {
                        const float* a = L.single[std::size_t(q)].direction(m).data();
                        for (std::size_t i = 0; i < cells; ++i) out[i] += w[q] * a[i];
                    }
                    if (options.components.multiple && L.has_multiple()) {
                        const float* a = L.multiple[std::size_t(q)].direction(m).data();
                        for (std::size_t i = 0; i < cells; ++i) out[i] += w[q] * a[i];
                    }
                }
            }
        }
    }
    f.times.strike_light = sw.milliseconds();
    f.lit = valid;
    return f;
}

// =======================================================================================
// Direct solve

transport::SourceField direct_solve(const scene::Scene& scene, const bake::Media& media,
                                    std::span<const transport::PointSource> sources, const Components& components) {
    const std::vector<glm::dvec3> dirs = transport::output_directions(scene.effective_directions());
    transport::SourceField out(media.lighting.density.geom, dirs);
    bake::SolveRequest rq;
    rq.single = components.single && scene.effects.single_scattering;
    rq.multiple = components.multiple && scene.effects.multiple_scattering;
    rq.skip_below = 0.0;  // the reference never drops light
    if (!rq.single && !rq.multiple) return out;
    std::vector<transport::PointSource> pts;
    pts.reserve(sources.size());
    for (const transport::PointSource& q : sources) {
        // As the splat: non-finite sources are skipped; zero ones add nothing.
        if (!std::isfinite(q.position.x) || !std::isfinite(q.position.y) || !std::isfinite(q.position.z) ||
            !std::isfinite(q.intensity) || q.intensity == 0.0)
            continue;
        pts.push_back(q);
    }
    if (pts.empty()) return out;
    const bake::Solution s = bake::solve(scene, media, pts, dirs, rq);
    auto add = [&](const transport::SourceField& f) {
        if (f.data.empty()) return;
        for (std::size_t i = 0; i < out.data.size(); ++i) out.data[i] += f.data[i];
    };
    if (rq.single) add(s.single);
    if (rq.multiple) add(s.multiple);
    return out;
}

// =======================================================================================
// Truth

transport::SourceField Truth::sum(const Components& c) const {
    transport::SourceField out(single.geom, single.directions);
    for (std::size_t i = 0; i < out.data.size(); ++i)
        out.data[i] = (c.single ? single.data[i] : 0.0f) + (c.multiple ? multiple.data[i] : 0.0f);
    return out;
}

Truth truth(const scene::Scene& scene, const core::Grid3<float>& density, std::span<const lightning::LitSegment> lit,
            std::span<const transport::PointSource> points, const TruthOptions& options) {
    transport::LightingMedium fine;
    fine.density = density;
    fine.optics = scene.medium;
    core::GridGeometry lighting = density.geom;
    const int f = scene.lighting_downsample;
    lighting.voxel_size *= f;
    lighting.dims = {(density.dims().x + f - 1) / f, (density.dims().y + f - 1) / f, (density.dims().z + f - 1) / f};
    const std::vector<transport::PointSource> pts(points.begin(), points.end());
    std::vector<transport::LineSource> lines;
    for (const lightning::LitSegment& s : lit) lines.push_back({s.a, s.b, s.intensity});
    transport::MonteCarloOptions mc;
    mc.paths = options.paths;
    mc.batches = options.batches;
    mc.seed = options.seed;
    mc.halves = true;
    mc.tally_weight = options.weight;
    mc.tally_multiple = options.multiple;
    if (!options.multiple) mc.max_scatterings = 0;
    const std::vector<glm::dvec3> dirs = transport::output_directions(scene.effective_directions());
    transport::MonteCarloResult r = transport::monte_carlo(fine, pts, lines, lighting, dirs, mc);
    Truth t;
    t.single = std::move(r.single);
    t.multiple = std::move(r.multiple);
    t.noise = r.noise;
    t.paths = r.paths;
    t.seconds = r.seconds;
    return t;
}

}  // namespace fulgur::runtime
