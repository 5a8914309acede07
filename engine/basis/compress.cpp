// Thresholding of Haar coefficients (Dobashi et al. 2007, section 6) in three forms, the
// paper's gamma, magnitude ordering and storage precision.
#include "basis/compression.h"
#include "basis/half.h"

#include "basis/detail/internal.h"

#include <algorithm>
#include <bit>
#include <cfloat>
#include <cmath>
#include <limits>
#include <string>

namespace fulgur::basis {

namespace {

// Float16 values are stored as half * 2^scale_exp. The exponent puts the largest kept
// magnitude in [2^14, 2^15): 15 binades of headroom below half's maximum (65504) and 28
// binades of normal (full relative precision) range below the largest coefficient. The
// clamp keeps every half * 2^scale_exp exactly representable as a float (so decoding and
// re-encoding is bit-exact): half values are k * 2^-24 with k < 2^16, hence the product
// is a multiple of 2^(scale_exp - 24) >= 2^-149 and below 2^(16 + scale_exp) <= 2^128.
constexpr int kMinScaleExp = -125;
constexpr int kMaxScaleExp = 112;

int float16_scale_exp(double max_magnitude) {
    if (!(max_magnitude > 0.0)) return 0;
    const int e = std::ilogb(max_magnitude);  // 2^e <= max < 2^(e+1)
    return std::clamp(e - 14, kMinScaleExp, kMaxScaleExp);
}

}  // namespace

std::string_view to_string(ThresholdMode m) noexcept {
    switch (m) {
        case ThresholdMode::Absolute:
            return "absolute";
        case ThresholdMode::RelativeL2:
            return "relative_l2";
        case ThresholdMode::Energy:
            return "energy";
    }
    return "unknown";
}

std::string_view to_string(Decomposition d) noexcept {
    switch (d) {
        case Decomposition::Standard:
            return "standard";
        case Decomposition::NonStandard:
            return "nonstandard";
    }
    return "unknown";
}

std::string_view to_string(Entropy e) noexcept {
    switch (e) {
        case Entropy::None:
            return "none";
        case Entropy::Deflate:
            return "deflate";
    }
    return "unknown";
}

void sort_canonical(CompressedBasis& b) {
    FULGUR_ASSERT(b.index.size() == b.value.size(), "sort_canonical: index and value counts differ");
    const std::size_t n = b.size();
    // One 64-bit key per coefficient, sorted as integers: high word = the complement of the
    // magnitude's bits (IEEE order of non-negative floats is their integer order, so
    // ascending keys = decreasing magnitude), low word = index * 2 + sign (indices are
    // unique and < 2^31, so ties go by index and the sign just rides along).
    std::vector<std::uint64_t> key(n);
    bool sorted = true;
    for (std::size_t k = 0; k < n; ++k) {
        const std::uint32_t bits = std::bit_cast<std::uint32_t>(b.value[k]);
        FULGUR_ASSERT(b.index[k] < (1u << 31), "sort_canonical: index beyond 2^31");
        key[k] =
            (std::uint64_t(0x7fffffffu - (bits & 0x7fffffffu)) << 32) | (std::uint64_t(b.index[k]) << 1) | (bits >> 31);
        sorted = sorted && (k == 0 || key[k - 1] < key[k]);
    }
    if (sorted) return;
    std::sort(key.begin(), key.end());
    for (std::size_t k = 0; k < n; ++k) {
        const std::uint32_t magnitude = 0x7fffffffu - std::uint32_t(key[k] >> 32);
        const std::uint32_t sign = std::uint32_t(key[k] & 1u) << 31;
        b.value[k] = std::bit_cast<float>(magnitude | sign);
        b.index[k] = std::uint32_t((key[k] & 0xffffffffu) >> 1);
    }
}

std::string_view to_string(Precision p) noexcept {
    switch (p) {
        case Precision::Float32:
            return "float32";
        case Precision::Float16:
            return "float16";
    }
    return "unknown";
}

void validate(const CompressionParams& p, std::string_view where) {
    const std::string w = std::string(where) + ".xi";
    if (p.mode != ThresholdMode::Absolute && p.mode != ThresholdMode::RelativeL2 && p.mode != ThresholdMode::Energy)
        throw core::Error(std::string(where) + ".threshold", "unknown threshold mode");
    if (p.precision != Precision::Float32 && p.precision != Precision::Float16)
        throw core::Error(std::string(where) + ".precision", "unknown precision");
    if (p.decomposition != Decomposition::Standard && p.decomposition != Decomposition::NonStandard)
        throw core::Error(std::string(where) + ".decomposition", "unknown Haar decomposition");
    if (p.entropy != Entropy::None && p.entropy != Entropy::Deflate)
        throw core::Error(std::string(where) + ".entropy", "unknown entropy coding");
    if (!std::isfinite(p.xi) || p.xi < 0.0)
        throw core::Error(w, "must be finite and >= 0, got " + core::format_number(p.xi, 9));
    if (p.mode == ThresholdMode::Energy && p.xi > 1.0)
        throw core::Error(w, "is the fraction of energy kept with threshold \"energy\": must be in [0, 1], got " +
                                 core::format_number(p.xi, 9));
}

std::size_t CompressedLight::coefficient_count() const noexcept {
    std::size_t n = 0;
    for (const CompressedBasis& b : directions) n += b.size();
    return n;
}

CompressedBasis compress_coefficients(std::span<const double> c, const CompressionParams& p, std::string_view where) {
    validate(p, "compression");
    FULGUR_ASSERT(c.size() <= std::size_t(std::numeric_limits<std::uint32_t>::max()),
                  "a basis has at most 2^32 - 1 coefficients");
    core::CompensatedSum total;
    for (std::size_t i = 0; i < c.size(); ++i) {
        if (!std::isfinite(c[i]))
            throw core::Error(std::string(where), "Haar coefficient " + std::to_string(i) + " is not finite (" +
                                                      core::format_number(c[i], 9) +
                                                      "); the basis holds NaN or infinity");
        total.add(c[i] * c[i]);
    }
    CompressedBasis out;
    out.norm = std::sqrt(std::max(0.0, total.value()));

    // Candidates sorted by decreasing magnitude, ties by increasing index.
    struct Item {
        double mag;
        std::uint32_t idx;
    };
    std::vector<Item> items;
    auto by_magnitude = [](const Item& a, const Item& b) { return a.mag != b.mag ? a.mag > b.mag : a.idx < b.idx; };
    core::CompensatedSum dropped;
    if (p.mode == ThresholdMode::Energy) {
        for (std::size_t i = 0; i < c.size(); ++i)
            if (c[i] != 0.0) items.push_back({std::fabs(c[i]), std::uint32_t(i)});
        // Drop from the smallest up while the dropped energy stays within (1 - xi) of the
        // total: the dropped set is the longest prefix of the ascending order whose energy
        // fits the budget. Found by quickselect on cumulative energy (expected O(n)); only
        // the kept part (a few percent to a few tens of percent) is then sorted. Same set as
        // sorting everything; the energy sums are compensated, so only ulp-level ties at the
        // budget could differ from a fully sorted summation order.
        const double budget = (1.0 - p.xi) * total.value();
        std::size_t keep = items.size();
        if (p.xi == 0.0) {
            for (const Item& it : items) dropped.add(it.mag * it.mag);
            keep = 0;
        } else {
            // Ascending order = reverse of by_magnitude (a strict total order: ties by index).
            auto ascending = [&](const Item& a, const Item& b) { return by_magnitude(b, a); };
            std::size_t lo = 0, hi = items.size();  // items[0, lo) dropped; the boundary lies in [lo, hi]
            while (lo < hi) {
                const std::size_t mid = lo + (hi - lo) / 2;
                std::nth_element(items.begin() + std::ptrdiff_t(lo), items.begin() + std::ptrdiff_t(mid),
                                 items.begin() + std::ptrdiff_t(hi), ascending);
                core::CompensatedSum part;
                for (std::size_t k = lo; k <= mid; ++k) part.add(items[k].mag * items[k].mag);
                if (dropped.value() + part.value() <= budget) {
                    for (std::size_t k = lo; k <= mid; ++k) dropped.add(items[k].mag * items[k].mag);
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            keep = items.size() - lo;
            // Kept items first, in the file's order (decreasing magnitude, ties by index).
            items.erase(items.begin(), items.begin() + std::ptrdiff_t(lo));
            std::sort(items.begin(), items.end(), by_magnitude);
        }
        items.resize(keep);
    } else {
        const double t = p.mode == ThresholdMode::Absolute ? p.xi : p.xi * out.norm;
        for (std::size_t i = 0; i < c.size(); ++i) {
            const double m = std::fabs(c[i]);
            if (m > t)
                items.push_back({m, std::uint32_t(i)});
            else
                dropped.add(m * m);
        }
        std::sort(items.begin(), items.end(), by_magnitude);
    }
    out.gamma = std::sqrt(std::max(0.0, dropped.value()));

    out.index.resize(items.size());
    out.value.resize(items.size());
    if (p.precision == Precision::Float32) {
        for (std::size_t k = 0; k < items.size(); ++k) {
            const double v = c[items[k].idx];
            if (std::fabs(v) > double(FLT_MAX))
                throw core::Error(std::string(where), "Haar coefficient " + std::to_string(items[k].idx) + " (" +
                                                          core::format_number(v, 9) + ") exceeds the float32 range");
            out.index[k] = items[k].idx;
            out.value[k] = float(v);
        }
    } else {
        out.scale_exp = items.empty() ? 0 : float16_scale_exp(items.front().mag);
        for (std::size_t k = 0; k < items.size(); ++k) {
            const double v = c[items[k].idx];
            const std::uint16_t h = double_to_half(std::ldexp(v, -out.scale_exp));
            if ((h & 0x7c00u) == 0x7c00u)
                throw core::Error(std::string(where), "Haar coefficient " + std::to_string(items[k].idx) + " (" +
                                                          core::format_number(v, 9) +
                                                          ") overflows float16 even scaled by 2^" +
                                                          std::to_string(out.scale_exp) + "; use float32");
            out.index[k] = items[k].idx;
            out.value[k] = std::ldexp(half_to_float(h), out.scale_exp);
        }
    }
    // Rounding can make neighbours in the double order equal: restore the canonical order
    // of the stored values (ties by index), which is what a reader reconstructs.
    sort_canonical(out);
    return out;
}

CompressedLight compress_light(std::uint32_t light, const transport::SourceField& field, const CompressionParams& p,
                               HaarTransform<double>& plan) {
    FULGUR_ASSERT(plan.dims() == field.geom.dims, "compress_light: the Haar plan does not match the field's grid");
    FULGUR_ASSERT(plan.decomposition() == p.decomposition, "compress_light: the Haar plan has another decomposition");
    FULGUR_ASSERT(field.data.size() == field.cells() * field.directions.size(), "compress_light: field size mismatch");
    CompressedLight out;
    out.light = light;
    out.directions.reserve(field.directions.size());
    std::vector<double> buf(field.cells());
    for (std::size_t m = 0; m < field.directions.size(); ++m) {
        const std::string where = "light " + std::to_string(light) + " direction " + std::to_string(m);
        const std::span<const float> s = field.direction(m);
        for (std::size_t i = 0; i < s.size(); ++i) {
            if (!std::isfinite(s[i]))
                throw core::Error(where, "cell " + std::to_string(i) + " of the basis is not finite (" +
                                             core::format_number(s[i], 9) + ")");
            buf[i] = double(s[i]);
        }
        plan.forward(buf);
        out.directions.push_back(compress_coefficients(buf, p, where));
    }
    return out;
}

void retruncate(CompressedBasis& b, ThresholdMode mode, double xi) {
    CompressionParams p;
    p.mode = mode;
    p.xi = xi;
    validate(p, "retruncate");
    std::size_t keep = b.size();
    core::CompensatedSum dropped;
    dropped.add(b.gamma * b.gamma);
    if (mode == ThresholdMode::Energy) {
        const double total = b.norm * b.norm;
        const double budget = (1.0 - xi) * total;
        if (xi == 0.0) {
            keep = 0;
            for (float v : b.value) dropped.add(double(v) * double(v));
        } else {
            while (keep > 0) {
                const double e = double(b.value[keep - 1]) * double(b.value[keep - 1]);
                if (dropped.value() + e > budget) break;
                dropped.add(e);
                --keep;
            }
        }
    } else {
        const double t = mode == ThresholdMode::Absolute ? xi : xi * b.norm;
        while (keep > 0 && std::fabs(double(b.value[keep - 1])) <= t) {
            dropped.add(double(b.value[keep - 1]) * double(b.value[keep - 1]));
            --keep;
        }
    }
    if (keep == b.size()) return;
    b.index.resize(keep);
    b.value.resize(keep);
    b.gamma = std::sqrt(std::max(0.0, dropped.value()));
    if (keep == 0) b.scale_exp = 0;
}

void accumulate(const CompressedBasis& b, float weight, std::span<float> coefficients) {
    const std::uint32_t* idx = b.index.data();
    const float* val = b.value.data();
    float* out = coefficients.data();
    const std::size_t n = b.size();
    for (std::size_t k = 0; k < n; ++k) out[idx[k]] += weight * val[k];
}

void accumulate(const CompressedBasis& b, double weight, std::span<double> coefficients) {
    const std::size_t n = b.size();
    for (std::size_t k = 0; k < n; ++k) coefficients[b.index[k]] += weight * double(b.value[k]);
}

}  // namespace fulgur::basis
