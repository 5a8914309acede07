// The Reconstructor (runtime.h): the sparse sum of the active lights' bases and the inverse
// Haar transform of Dobashi et al. 2007 (Eqs. 8-10), direction by direction.
#include "runtime/detail/internal.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace fulgur::runtime {

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

Reconstructor::Reconstructor(const BakedBases& bases) : impl_(std::make_unique<Impl>(bases_impl(bases))) {
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

}  // namespace fulgur::runtime
