// How a light group's light changed between two frames (detail/scale_tracker.h).
#include "render/detail/scale_tracker.h"

#include <algorithm>
#include <cmath>

namespace fulgur::render::detail {

void ScaleTracker::note(std::span<const float> fixed, const std::vector<int>& keys,
                        const std::vector<std::span<const float>>& values, bool replace) {
    const bool comparable = fixed.size() == fixed_.size() && std::equal(fixed.begin(), fixed.end(), fixed_.begin());
    if (!comparable) {
        values_.clear();
        fixed_.assign(fixed.begin(), fixed.end());
    }
    // Least squares over the keys listed now and before: c = <now, then> / <then, then>.
    double tt = 0.0, nt = 0.0, nn = 0.0;
    int common = 0;
    for (std::size_t k = 0; k < keys.size(); ++k) {
        const std::span<const float> now = values[k];
        for (float v : now) nn += double(v) * double(v);
        const auto it = values_.find(keys[k]);
        if (it == values_.end() || it->second.size() != now.size()) continue;
        ++common;
        for (std::size_t i = 0; i < now.size(); ++i) {
            tt += double(it->second[i]) * double(it->second[i]);
            nt += double(now[i]) * double(it->second[i]);
        }
    }
    if (!(nn > 0.0) && !replace) {
        valid_ = false;  // a partial upload of zeros: not a change of intensity
    } else if (!(nn > 0.0)) {
        if (!dark_) rescale_ = 0.0;  // dark now: zero times the history
    } else if (dark_ || !comparable || (common == 0 && replace) || (common > 0 && !(tt > 0.0))) {
        valid_ = false;  // light where the history has none, or nothing to compare
    } else if (common > 0) {
        const double c = nt / tt;
        double residual = 0.0;
        for (std::size_t k = 0; k < keys.size(); ++k) {
            const auto it = values_.find(keys[k]);
            if (it == values_.end() || it->second.size() != values[k].size()) continue;
            for (std::size_t i = 0; i < values[k].size(); ++i) {
                const double e = double(values[k][i]) - c * double(it->second[i]);
                residual += e * e;
            }
        }
        // A partial upload leaves the keys it does not list as they were (a factor of 1): the
        // listed ones must then keep theirs too.
        bool others = false;
        if (!replace)
            for (const auto& [key, v] : values_)
                others = others || (std::find(keys.begin(), keys.end(), key) == keys.end() &&
                                    std::any_of(v.begin(), v.end(), [](float x) { return x != 0.0f; }));
        if (residual <= kTolerance * kTolerance * nn && (!others || std::abs(c - 1.0) <= kTolerance))
            rescale_ *= c;
        else
            valid_ = false;
    }
    if (replace) values_.clear();
    for (std::size_t k = 0; k < keys.size(); ++k) values_[keys[k]].assign(values[k].begin(), values[k].end());
    // The copy is bounded: beyond kMaxValues the next upload cannot be compared (a change of
    // shape: every pixel marched) and nothing is kept.
    std::size_t kept = 0;
    for (const auto& [key, v] : values_) kept += v.size();
    if (kept > kMaxValues) {
        values_.clear();
        fixed_.clear();
    }
    if (replace) dark_ = !(nn > 0.0);
}

void ScaleTracker::clear() {
    if (!dark_) rescale_ = 0.0;
    dark_ = true;
    values_.clear();
}

}  // namespace fulgur::render::detail
