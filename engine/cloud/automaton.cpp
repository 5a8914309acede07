// Dobashi et al. 2000's cellular automaton and the space-time smoothing to a density.
#include "cloud/detail/automaton.h"

#include <algorithm>
#include <cmath>

namespace fulgur::cloud::detail {

namespace {

// Random-stream tags: the automaton's rows and its initial state never share a stream with
// each other or with the layout.
constexpr std::uint64_t kStepTag = 0x43412d73746570ULL;  // "CA-step"
constexpr std::uint64_t kInitTag = 0x43412d696e6974ULL;  // "CA-init"

// Threshold on 16 random bits for an event of probability p * w, w = level / 255.
std::uint32_t threshold(double p, int level) {
    const double prob = p * double(level) / 255.0;
    return std::uint32_t(std::clamp(std::lround(prob * 65536.0), 0L, 65536L));
}

}  // namespace

Automaton::Automaton(core::Int3 dims, std::vector<std::uint8_t> weights, Probabilities p, std::uint64_t seed)
    : dims_(dims), weights_(std::move(weights)), seed_(seed) {
    FULGUR_ASSERT(dims.x >= 1 && dims.y >= 1 && dims.z >= 1, "automaton needs a non-empty grid");
    FULGUR_ASSERT(weights_.size() == dims.volume(), "one seed weight per cell");
    FULGUR_ASSERT(
        p.p_ext >= 0.0 && p.p_ext <= 1.0 && p.p_hum >= 0.0 && p.p_hum <= 1.0 && p.p_act >= 0.0 && p.p_act <= 1.0,
        "probabilities must be in [0, 1]");
    sy_ = std::size_t(dims.x + 2 * kPad);
    sz_ = sy_ * std::size_t(dims.y + 2 * kPad);
    cur_.assign(sz_ * std::size_t(dims.z + 2 * kPad), 0);
    next_ = cur_;
    for (int level = 0; level < 256; ++level) {
        thr_ext_[std::size_t(level)] = threshold(p.p_ext, 255 - level);
        thr_hum_[std::size_t(level)] = threshold(p.p_hum, level);
        thr_act_[std::size_t(level)] = threshold(p.p_act, level);
    }
    const std::size_t rows = std::size_t(dims.y) * std::size_t(dims.z);
    span_lo_.assign(rows, 0);
    span_hi_.assign(rows, 0);
    for (std::size_t r = 0; r < rows; ++r) {
        const std::uint8_t* w = weights_.data() + r * std::size_t(dims.x);
        int lo = 0, hi = dims.x;
        while (lo < hi && w[lo] == 0) ++lo;
        while (hi > lo && w[hi - 1] == 0) --hi;
        span_lo_[r] = lo;
        span_hi_[r] = hi;
    }
}

void Automaton::set(int i, int j, int k, std::uint8_t bits) noexcept {
    FULGUR_ASSERT(i >= 0 && j >= 0 && k >= 0 && i < dims_.x && j < dims_.y && k < dims_.z, "cell outside the grid");
    FULGUR_ASSERT((bits & ~(kHum | kAct | kCld)) == 0, "unknown state bits");
    const std::size_t q =
        std::size_t(i) + std::size_t(dims_.x) * (std::size_t(j) + std::size_t(dims_.y) * std::size_t(k));
    FULGUR_ASSERT(bits == 0 || weights_[q] > 0, "a cell with seed weight 0 must stay empty");
    cur_[padded(i, j, k)] = bits;
}

void Automaton::init_vapour() {
    const int nx = dims_.x, ny = dims_.y;
    const std::int64_t rows = std::int64_t(ny) * dims_.z;
    std::array<std::uint32_t, 256> thr_init{};
    for (int level = 0; level < 256; ++level) thr_init[std::size_t(level)] = threshold(1.0, level);
    core::parallel_for_dynamic(
        0, rows,
        [&](std::int64_t r) {
            const int j = int(r % ny), k = int(r / ny);
            core::Rng rng(core::hash_seed(seed_, kInitTag, std::uint64_t(r)));
            const std::uint8_t* w = weights_.data() + std::size_t(r) * std::size_t(nx);
            std::uint8_t* s = cur_.data() + padded(0, j, k);
            for (int i = span_lo_[std::size_t(r)]; i < span_hi_[std::size_t(r)]; ++i) {
                const std::uint32_t rnd = rng.next_u32() >> 16;
                s[i] = rnd < thr_init[w[i]] ? kHum : 0;
            }
        },
        16);
}

void Automaton::step(std::uint8_t* cld_counts) {
    const int nx = dims_.x, ny = dims_.y;
    const std::int64_t rows = std::int64_t(ny) * dims_.z;
    const std::ptrdiff_t sx = 1, sy = std::ptrdiff_t(sy_), sz = std::ptrdiff_t(sz_);
    const std::uint64_t step_seed = core::hash_seed(seed_, kStepTag, std::uint64_t(steps_));
    const std::uint8_t* cur = cur_.data();
    std::uint8_t* nxt = next_.data();
    core::parallel_for_dynamic(
        0, rows,
        [&](std::int64_t r) {
            const int lo = span_lo_[std::size_t(r)], hi = span_hi_[std::size_t(r)];
            if (lo >= hi) return;
            const int j = int(r % ny), k = int(r / ny);
            core::Rng rng(core::hash_seed(step_seed, std::uint64_t(r)));
            const std::uint8_t* w = weights_.data() + std::size_t(r) * std::size_t(nx);
            std::uint8_t* counts = cld_counts ? cld_counts + std::size_t(r) * std::size_t(nx) : nullptr;
            const std::size_t row0 = padded(0, j, k);
            for (int i = lo; i < hi; ++i) {
                const std::uint8_t* c = cur + row0 + std::size_t(i);
                const std::uint8_t s = c[0];
                const std::uint8_t neighbours =
                    std::uint8_t(c[-sx] | c[sx] | c[-sy] | c[sy] | c[-sz] | c[sz] | c[-2 * sx] | c[2 * sx] |
                                 c[-2 * sy] | c[2 * sy] | c[-2 * sz]);
                const bool hum = s & kHum, act = s & kAct, cld = s & kCld;
                const bool f_act = neighbours & kAct;
                // Growth.
                bool hum_n = hum && !act;
                bool cld_n = cld || act;
                bool act_n = !act && hum && f_act;
                // Extinction and supply: 16 random bits each, from two 32-bit draws.
                const std::uint32_t r1 = rng.next_u32(), r2 = rng.next_u32();
                const std::uint8_t level = w[i];
                cld_n = cld_n && (r1 & 0xffffu) >= thr_ext_[level];
                hum_n = hum_n || (r1 >> 16) < thr_hum_[level];
                act_n = act_n || (r2 & 0xffffu) < thr_act_[level];
                nxt[row0 + std::size_t(i)] = std::uint8_t((hum_n ? kHum : 0) | (act_n ? kAct : 0) | (cld_n ? kCld : 0));
                if (counts) counts[i] = std::uint8_t(counts[i] + (cld_n ? 1 : 0));
            }
        },
        8);
    cur_.swap(next_);
    ++steps_;
}

std::size_t Automaton::cloud_cells() const {
    return std::size_t(std::count_if(cur_.begin(), cur_.end(), [](std::uint8_t s) { return (s & kCld) != 0; }));
}

std::vector<float> smooth_density(core::Int3 dims, std::span<const std::uint8_t> counts, int window, int radius,
                                  int first_layer, double gain) {
    FULGUR_ASSERT(counts.size() == dims.volume(), "one count per cell");
    FULGUR_ASSERT(window >= 1 && radius >= 0 && gain > 0.0, "bad smoothing parameters");
    const int nx = dims.x, ny = dims.y, nz = dims.z;
    first_layer = std::clamp(first_layer, 0, nz);
    // Kernel (1 - (d/(r+1))^2)^3: the Wyvill field function Dobashi et al. use for their
    // metaballs, sampled per axis; positive at every |d| <= r.
    std::vector<double> kern(std::size_t(2 * radius + 1));
    double ksum = 0.0;
    for (int d = -radius; d <= radius; ++d) {
        const double u = double(d) / double(radius + 1);
        const double v = 1.0 - u * u;
        kern[std::size_t(d + radius)] = v * v * v;
        ksum += v * v * v;
    }
    for (double& v : kern) v /= ksum;

    const std::size_t sy = std::size_t(nx), sz = std::size_t(nx) * std::size_t(ny);
    std::vector<float> a(dims.volume()), b(dims.volume());
    const float inv_window = 1.0f / float(window);
    core::parallel_for(0, std::int64_t(dims.volume()),
                       [&](std::int64_t q) { a[std::size_t(q)] = float(counts[std::size_t(q)]) * inv_window; });
    // Pass along one axis: dst[q] = sum_d kern[d] src[q + d*stride], outside the grid = 0.
    auto pass = [&](const std::vector<float>& src, std::vector<float>& dst, int axis) {
        core::parallel_for(0, nz, [&](std::int64_t kk) {
            const int k = int(kk);
            for (int j = 0; j < ny; ++j)
                for (int i = 0; i < nx; ++i) {
                    const std::size_t q = std::size_t(i) + sy * std::size_t(j) + sz * std::size_t(k);
                    double sum = 0.0;
                    if (axis == 0) {
                        for (int d = std::max(-radius, -i); d <= std::min(radius, nx - 1 - i); ++d)
                            sum += kern[std::size_t(d + radius)] * src[q + std::size_t(std::ptrdiff_t(d))];
                    } else if (axis == 1) {
                        for (int d = std::max(-radius, -j); d <= std::min(radius, ny - 1 - j); ++d)
                            sum += kern[std::size_t(d + radius)] *
                                   src[std::size_t(std::ptrdiff_t(q) + d * std::ptrdiff_t(sy))];
                    } else {
                        if (k < first_layer) {
                            dst[q] = 0.0f;
                            continue;
                        }
                        // Normalized over the layers at or above the base: the base layer is
                        // as dense as the cloud just above it.
                        double wsum = 0.0;
                        for (int d = std::max(-radius, first_layer - k); d <= radius; ++d) {
                            wsum += kern[std::size_t(d + radius)];
                            if (k + d < nz)
                                sum += kern[std::size_t(d + radius)] *
                                       src[std::size_t(std::ptrdiff_t(q) + d * std::ptrdiff_t(sz))];
                        }
                        sum /= wsum;
                    }
                    dst[q] = float(sum);
                }
        });
    };
    pass(a, b, 0);
    pass(b, a, 1);
    pass(a, b, 2);
    core::parallel_for(0, std::int64_t(dims.volume()), [&](std::int64_t q) {
        const double v = double(b[std::size_t(q)]) * gain;
        b[std::size_t(q)] = float(std::clamp(v, 0.0, 1.0));
    });
    return b;
}

}  // namespace fulgur::cloud::detail
